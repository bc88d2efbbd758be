"""GearSpeedDemandHard-v0: sensor noise, actuator dead time and a wear change within the episode."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import gear_env  # noqa: F401  (registers the tasks)
from gear_env.envs.env_config import task_config
from gear_env.envs.env_core import NOISY_SENSORS
from gear_env.envs.tasks import DEMAND_HARD_SETTINGS, DEMAND_SETTINGS, WearChange
from gear_env.envs.vector_env import GearSpeedVectorEnv

SHORT = {"max_steps": 8, "periods_per_step": 8, "warmup_periods": 16}


def _rollout(env_id: str, seed: int, actions, **kw):
    env = gym.make(env_id, **SHORT, **kw).unwrapped
    obs, _ = env.reset(seed=seed)
    out = [(obs.copy(), None)]
    for a in actions:
        o, r, te, tr, info = env.step(np.array([a], np.float32))
        out.append((o.copy(), info))
    return env, out


def test_v1_is_v0_plus_three_settings():
    extra = {k: v for k, v in DEMAND_HARD_SETTINGS.items() if DEMAND_SETTINGS.get(k, object()) != v}
    assert set(extra) == {"sensor_noise", "action_delay", "wear"}
    env = gym.make("GearSpeedDemandHard-v0")
    check_env(env.unwrapped, skip_render_check=True)


def test_noise_moves_only_the_observation():
    """Same seed, noise on and off: identical physics, rewards and info; the noisy entries differ by the
    configured scale and the others not at all; memory copies repeat the previous step's noisy reading."""
    acts = [0.2, 0.5, -0.3, 0.8, 0.0, 0.1]
    _, clean = _rollout("GearSpeedDemand-v0", 4, acts)
    env, noisy = _rollout("GearSpeedDemand-v0", 4, acts, sensor_noise=0.05)
    names = env.observation_names
    idx = [names.index(k) for k in NOISY_SENSORS]
    other = [i for i in range(len(names)) if i not in idx and not names[i].startswith("prev_")]
    diffs = []
    for (oc, ic), (on, inn) in zip(clean, noisy):
        assert np.array_equal(oc[other], on[other])
        if ic is not None:
            assert ic == inn
        diffs.append(on[idx] - oc[idx])
    d = np.concatenate(diffs)
    assert np.count_nonzero(d) > 0.8 * d.size
    assert 0.02 < np.std(d) < 0.08  # clipping at the bounds only shrinks it
    pf = names.index("prev_force_rms")
    for t in range(1, len(noisy)):
        assert noisy[t][0][pf] == pytest.approx(noisy[t - 1][0][names.index("force_rms")], abs=1e-6)


def test_action_delay_applies_the_previous_action():
    acts = [0.9, -0.5, 0.4, 0.0]
    _, direct = _rollout("GearSpeedDemand-v0", 7, acts)
    _, late = _rollout("GearSpeedDemand-v0", 7, [*acts, 0.0], action_delay=1)
    # with a dead time of one step, the first step holds the initial speed and every later step applies the
    # action sent one step before
    assert late[1][1]["domega"] == pytest.approx(0.0, abs=1e-12)
    for t in range(1, len(acts) + 1):
        assert late[t + 1][1]["omega"] == pytest.approx(direct[t][1]["omega"], abs=1e-12)


def test_wear_changes_the_pair_once():
    env = gym.make("GearSpeedDemandHard-v0", **SHORT, wear={"factors": [2.0], "at_step": [3, 5]}).unwrapped
    env.reset(seed=11)
    w = env.episode.wear_factor
    at = int(np.argmax(w != 1.0))
    assert 3 <= at <= 5 and np.all(w[:at] == 1.0) and np.all(w[at:] == 2.0)
    base = env.episode.params
    for t in range(SHORT["max_steps"]):
        env.step(np.array([0.0], np.float32))
        want = env.episode.params_at(t)
        assert np.array_equal(env._core.C[0], want.consts), t
        assert want.e_m1 == pytest.approx(base.e_m1 * w[t])


def test_v1_single_and_vector_agree_bit_for_bit():
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (SHORT["max_steps"] + 3, 3)).astype(np.float32)
    venv = GearSpeedVectorEnv(3, task_config("GearSpeedDemandHard-v0", SHORT))
    vo, _ = venv.reset(seed=[21, 22, 23])
    singles = [gym.make("GearSpeedDemandHard-v0", **SHORT).unwrapped for _ in range(3)]
    so = [e.reset(seed=21 + i)[0] for i, e in enumerate(singles)]
    assert np.array_equal(vo, np.array(so))
    for a in acts[: SHORT["max_steps"]]:
        vo, vr, _, _, _ = venv.step(a)
        for i, e in enumerate(singles):
            o, r, *_ = e.step(a[i : i + 1])
            assert np.array_equal(vo[i], o) and vr[i] == r


@pytest.mark.parametrize(
    "settings, match",
    [
        ({"sensor_noise": -0.1}, "sensor_noise"),
        ({"sensor_noise": 2.0}, "sensor_noise"),
        ({"action_delay": 11}, "action_delay"),
        ({"action_delay": 0.5}, "action_delay"),
        ({"wear": {"factors": []}}, "wear.factors"),
        ({"wear": {"factors": [0.0]}}, "wear.factors"),
        ({"wear": {"at_step": [5, 2]}}, "wear.at_step"),
        ({"wear": {"bogus": 1}}, r"unknown GearSpeedConfig.wear key"),
    ],
)
def test_bad_v1_settings_name_the_field(settings, match):
    with pytest.raises(ValueError, match=match):
        gym.make("GearSpeedDemandHard-v0", **settings)


def test_wear_draw_is_seeded():
    w = WearChange(factors=(0.5, 2.0), at_step=(2, 4))
    a = w.draw(np.random.default_rng(5), 10)
    b = w.draw(np.random.default_rng(5), 10)
    assert np.array_equal(a, b) and set(np.unique(a)) <= {1.0, 0.5, 2.0}


def test_oracle_plans_with_the_wear():
    """The oracle's per-step maps follow the wear change (a different map after the change)."""
    from agents.episode_oracle import EpisodeOracle

    env = gym.make("GearSpeedDemandHard-v0", wear={"factors": [2.0], "at_step": [40, 40]}).unwrapped
    env.reset(seed=3)
    o = EpisodeOracle(env.config)
    _, costs = o.maps_for(env.episode, "plant")
    lv = env.episode.load_factor
    same_load = [t for t in range(39) if lv[t] == lv[40]]
    assert same_load and not np.allclose(costs[same_load[-1]], costs[40])


def test_pending_action_is_observed_and_scripts_predict_the_dead_time():
    """The observation carries the action on its way; a scripted policy's Smith predictor (omega_ahead)
    equals the omega the environment then reaches."""
    from agents.registry import resolve_policy

    env = gym.make("GearSpeedDemandHard-v0", **SHORT).unwrapped
    names = env.observation_names
    assert names[-1] == "pending_action"
    pol = resolve_policy("sensor-servo", env.config, env_id="GearSpeedDemandHard-v0")
    obs, _ = env.reset(seed=5)
    state, start = None, np.array([True])
    for _ in range(SHORT["max_steps"]):
        a, state = pol.predict(obs[None], state=state, episode_start=start, deterministic=True)
        start = np.array([False])
        ahead = float(state["omega_ahead"][0])
        obs, _, _, _, info = env.step(a.reshape(1))
        assert obs[-1] == pytest.approx(float(a.reshape(-1)[0]), abs=1e-6)
        assert info["omega"] == pytest.approx(ahead, abs=1e-6)  # omega is read from a float32 observation


def test_filtered_follow_identifies_a_pair_through_the_noise():
    """On one fixed pair (no duty cycle, no wear) the averaged q of ``filtered-follow`` lands near the pair's
    true q = e_m1 factor / load factor (single readings there spread over about +-0.3 in log q)."""
    from agents.registry import resolve_policy

    kw = {"duty_cycle": None, "wear": None, "plant_family": {"load": [1.0, 1.0], "e_m1": [0.5, 0.5]}}
    env = gym.make("GearSpeedDemandHard-v0", **kw).unwrapped
    pol = resolve_policy("filtered-follow", env.config, env_id="GearSpeedDemandHard-v0")
    assert pol.name == "filtered-follow" and pol.window == 8 and pol.margin == pytest.approx(0.2)
    obs, _ = env.reset(seed=2)
    state, start = None, np.array([True])
    for _ in range(30):
        a, state = pol.predict(obs[None], state=state, episode_start=start, deterministic=True)
        start = np.array([False])
        obs, *_ = env.step(a.reshape(1))
    assert state["count"][0] >= 8
    assert abs(np.log(state["q"][0]) - np.log(0.5)) < 0.25


@pytest.mark.parametrize(
    "spec",
    ["filtered-follow:x", "filtered-follow:0", "filtered-follow:-3", "filtered-follow:6:x", "filtered-follow:6:0.6",
     "filtered-follow:6:nan", "filtered-follow:6:-inf", "filtered-follow:6:", "filtered-follow::0.1"],
)  # fmt: skip
def test_filtered_follow_spec_errors(spec):
    from agents.registry import resolve_policy

    with pytest.raises(ValueError, match="filtered-follow"):
        resolve_policy(spec, gym.make("GearSpeedDemandHard-v0").unwrapped.config, env_id="GearSpeedDemandHard-v0")


def test_filtered_follow_spec_with_a_shift_moves_the_hold_speed():
    """``filtered-follow:N:S``: the window N and the hold speed shifted by S (omega units), named by its spec."""
    from agents.registry import resolve_policy

    cfg = gym.make("GearSpeedDemandHard-v0").unwrapped.config
    base = resolve_policy("filtered-follow:6", cfg, env_id="GearSpeedDemandHard-v0")
    tuned = resolve_policy("filtered-follow:6:-0.02", cfg, env_id="GearSpeedDemandHard-v0")
    assert (base.name, tuned.name) == ("filtered-follow:6", "filtered-follow:6:-0.02")
    assert tuned.window == 6 and tuned.shift == -0.02 and base.shift == 0.0
    logq = np.array([-1.0, 0.0, 0.5, np.nan])
    fin = np.isfinite(logq)
    assert np.allclose(tuned.edge(logq)[fin], base.edge(logq)[fin] - 0.02)
    assert tuned.edge(logq)[~fin] == base.edge(logq)[~fin]  # an unknown pair: the floor either way
    assert resolve_policy("filtered-follow:8:0", cfg, env_id="GearSpeedDemandHard-v0").name == "filtered-follow"


def test_the_shipped_policy_runs_on_the_task():
    """``--policy pretrained`` on GearSpeedDemandHard-v0: the shipped network reads the task's 16 entries."""
    from agents.registry import resolve_policy

    env = gym.make("GearSpeedDemandHard-v0", **SHORT).unwrapped
    pol = resolve_policy("pretrained", env.config, env_id="GearSpeedDemandHard-v0")
    obs, _ = env.reset(seed=800)
    assert obs.shape == (16,)
    acts = []
    for _ in range(SHORT["max_steps"]):
        a, _ = pol.predict(obs, deterministic=True)
        acts.append(float(np.asarray(a).reshape(-1)[0]))
        obs, *_ = env.step(np.asarray(a, np.float32).reshape(1))
    assert all(-1.0 <= x <= 1.0 for x in acts) and len(set(acts)) > 1
