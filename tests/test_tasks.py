"""GearSpeed-v1 and GearSpeedDemand-v0: registration, episode scenarios, validation, rewards, costs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gear_env  # noqa: F401  (registers the tasks)
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig, task_config
from gear_env.envs.tasks import DEMAND_SETTINGS, TASK_SETTINGS, V1_SETTINGS, DutyCycle, PlantFamily
from gear_env.sim.params import GearParams

SHORT = {"max_steps": 6, "periods_per_step": 8, "warmup_periods": 16}  # cheap episodes for the tests


def test_tasks_registered_with_their_settings():
    for env_id, settings in TASK_SETTINGS.items():
        spec = gym.spec(env_id)
        assert spec.max_episode_steps == task_config(env_id).max_steps
        env = gym.make(env_id)
        cfg = env.unwrapped.config
        for k, v in settings.items():
            got = getattr(cfg, k)
            got = got.to_dict() if hasattr(got, "to_dict") else got
            want = {a: list(b) if isinstance(b, tuple) else b for a, b in v.items()} if isinstance(v, dict) else v
            assert (list(got) if isinstance(got, tuple) else got) == (
                list(want) if isinstance(want, tuple) else want
            ), k
    # v0 keeps every default of GearSpeedConfig: reproducible
    assert gym.make("GearSpeed-v0").unwrapped.config == GearSpeedConfig()
    assert V1_SETTINGS["action_mode"] == "target" and DEMAND_SETTINGS["demand"] == "random"


def test_v0_unchanged_by_the_new_settings():
    """The scenario machinery is inert for v0: a rollout equals the plain env's, bit for bit."""
    a = gym.make("GearSpeed-v0", **SHORT).unwrapped
    b = GearSpeedEnv(**SHORT)
    oa, _ = a.reset(seed=3)
    ob, _ = b.reset(seed=3)
    assert np.array_equal(oa, ob)
    for _ in range(SHORT["max_steps"]):
        ra = a.step(np.array([0.3], np.float32))
        rb = b.step(np.array([0.3], np.float32))
        assert np.array_equal(ra[0], rb[0]) and ra[1] == rb[1]


@pytest.mark.parametrize("n", [3, 9])
def test_max_episode_steps_truncates_at_n(n):
    env = gym.make("GearSpeed-v1", max_episode_steps=n, periods_per_step=8, warmup_periods=16)
    env.reset(seed=0)
    for k in range(1, n + 1):
        _, _, term, trunc, info = env.step(np.array([0.0], np.float32))
        assert not term
        assert trunc == (k == n), k
    assert info["episode_steps"] == n


def test_max_steps_keyword_still_truncates_and_longer_is_refused():
    env = gym.make("GearSpeed-v1", max_steps=4, periods_per_step=8, warmup_periods=16)
    env.reset(seed=0)
    ends = [env.step(np.array([0.0], np.float32))[3] for _ in range(4)]
    assert ends == [False, False, False, True]
    env = gym.make("GearSpeed-v1", max_steps=150)  # above the registered limit: the wrapper would cut at 100
    with pytest.raises(ValueError, match="max_episode_steps=150"):
        env.reset(seed=0)


def test_demand_episode_is_seeded_and_hidden():
    env = gym.make("GearSpeedDemand-v0", **SHORT).unwrapped
    o1, _ = env.reset(seed=11)
    e1 = env.episode
    o2, _ = env.reset(seed=11)
    e2 = env.episode
    assert e1.factors == e2.factors and np.array_equal(e1.demand, e2.demand) and np.array_equal(o1, o2)
    env.reset(seed=12)
    assert env.episode.factors != e1.factors
    fam = env.config.plant_family
    assert fam.load[0] <= e1.factors["load"] <= fam.load[1] and fam.e_m1[0] <= e1.factors["e_m1"] <= fam.e_m1[1]
    # the observation holds the sensors, the demand and the memory of past sensors (memory_steps > 0), never
    # the plant
    from gear_env.envs.env_core import FULL_STATE_NAMES, SENSOR_NAMES

    memory = ("trouble_omega", "trouble_recency", "prev_force_rms", "prev_contact_loss")
    assert env.observation_names == (*SENSOR_NAMES, "demand", *memory)
    assert not set(FULL_STATE_NAMES) & set(env.observation_names)
    # demand levels lie in the speed range and are piecewise constant
    assert np.all((e1.demand >= env.config.omega_min) & (e1.demand <= env.config.omega_max))


def test_demand_plant_is_simulated():
    """The drawn plant's consts are what the core integrates (load and e_m1 scaled)."""
    env = gym.make("GearSpeedDemand-v0", duty_cycle=None, **SHORT).unwrapped
    env.reset(seed=5)
    f = env.episode.factors
    p = GearParams()
    want = p.replace(T_p=p.T_p * f["load"], T_g=p.T_g * f["load"], e_m1=p.e_m1 * f["e_m1"])
    assert np.array_equal(env._core.C[0], want.consts)


@pytest.mark.parametrize("env_id", ["GearSpeedDemand-v0", "GearSpeedDemandHard-v0"])
def test_duty_cycle_switches_the_load(env_id):
    """At every step the row simulates its episode's pair at that step's load (and wear): the constants, the static
    reference and the stable omega that the environment keeps per row and level (a level it returns to is not
    derived again) are those of a pair made fresh, also in the next episode (another pair: nothing carried over)."""
    from gear_env.sim import kernels as K
    from gear_env.sim.linear import stability_frequency

    cfg = dict(SHORT, max_steps=12, duty_cycle={"levels": [1.0, 0.5], "segment_steps": [2, 3]})
    if env_id.startswith("GearSpeedDemandHard"):
        cfg["wear"] = {"factors": [0.5, 2.0], "at_step": [4, 8]}
    env = gym.make(env_id, **cfg).unwrapped
    core = env._core
    for seed in (2, 3):
        env.reset(seed=seed)
        lf = env.episode.load_factor
        assert set(np.unique(lf)) <= {1.0, 0.5} and len(np.unique(lf)) == 2
        for t in range(12):
            env.step(np.array([0.0], np.float32))
            p = env.episode.params_at(t)
            assert np.array_equal(core.C[0], p.consts), (seed, t)
            x0 = np.zeros(K.NSTATE)
            K.static_equilibrium(K.readonly(np.array(p.consts)), core.code, 0.0, x0)
            assert core.tr_ref[0] == np.sqrt(max(0.5 * float(np.sum(x0[:4] ** 2)), 1e-300)), (seed, t)
            assert core.w_stab[0] == stability_frequency(p) and core.beta[0] == p.newmark_beta
        assert 2 <= len(core._plants[0]) <= 4  # one entry per level visited, dropped at the next reset


def test_delivered_throughput_and_cost():
    env = gym.make("GearSpeedDemand-v0", **SHORT).unwrapped
    env.reset(seed=1)
    for _ in range(SHORT["max_steps"]):
        _, r, _, _, info = env.step(np.array([0.5], np.float32))
        cfg = env.config
        want = cfg.w_throughput * min(info["omega_mean"], info["demand"]) / cfg.omega_max
        assert info["reward_throughput"] == pytest.approx(want, abs=1e-12)
        assert r == pytest.approx(sum(v for k, v in info.items() if k.startswith("reward_")), abs=1e-12)
        assert info["cost"] >= 0.0
        assert info["cost"] == pytest.approx(sum(v for k, v in info.items() if k.startswith("cost_")), abs=1e-12)


@pytest.mark.parametrize(
    ("settings", "match"),
    [
        ({"plant_family": {"load": [0.5, 0.2]}}, "plant_family.load"),
        ({"plant_family": {"e_m1": [1.0, 1e4]}}, "plant_family.e_m1"),
        ({"plant_family": {"mass": [1.0, 2.0]}}, "plant_family key"),
        ({"params": {"T_p": 1e6, "T_g": 1e6}, "plant_family": {"load": [1.0, 50.0]}}, "valid range"),
        ({"duty_cycle": {"levels": [1.0, 0.0]}}, "duty_cycle.levels"),
        ({"duty_cycle": {"segment_steps": [5, 2]}}, "duty_cycle.segment_steps"),
        ({"demand_segment_steps": [0, 3]}, "demand_segment_steps"),
        ({"throughput": "all-of-it"}, "throughput"),
        ({"demand": None}, "throughput"),
    ],
)
def test_bad_task_settings_name_the_field(settings, match):
    with pytest.raises(ValueError, match=match):
        task_config("GearSpeedDemand-v0", settings)


def test_family_draws_inside_the_box():
    fam = PlantFamily(load=(0.5, 0.7), e_m1=(1.0, 1.0))
    rng = np.random.default_rng(0)
    draws = [fam.draw(rng) for _ in range(50)]
    assert all(0.5 <= d["load"] <= 0.7 and d["e_m1"] == 1.0 for d in draws)
    duty = DutyCycle(levels=(1.0,), segment_steps=(1, 1)).draw(rng, 7)
    assert np.array_equal(duty, np.ones(7))


def test_task_config_unknown_id():
    with pytest.raises(ValueError, match="GearSpeed-v1"):
        task_config("GearSpeed-v9")
