"""GearSpeed-v0 single environment: API conformance, determinism, reward bookkeeping, errors."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import gear_env  # noqa: F401  (registers GearSpeed-v0)
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig
from gear_env.envs.env_core import INFO_KEYS, REWARD_KEYS, periodicity_defect
from gear_env.evaluation import steady_reward_map
from gear_env.sim import kernels as K

FAST = dict(max_steps=6, periods_per_step=8, warmup_periods=16)


def rollout(env, seed, n, actions=None):
    obs, info = env.reset(seed=seed)
    out = [(obs.copy(), 0.0, False, False, info)]
    rng = np.random.default_rng(123)
    for k in range(n):
        a = actions[k] if actions is not None else rng.uniform(-1, 1, 1).astype(np.float32)
        obs, r, te, tr, info = env.step(a)
        out.append((obs.copy(), r, te, tr, info))
        if te or tr:
            obs, info = env.reset()
            out.append((obs.copy(), 0.0, False, False, info))
    return out


def assert_same(a, b):
    assert len(a) == len(b)
    for (o1, r1, te1, tr1, i1), (o2, r2, te2, tr2, i2) in zip(a, b):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2 and te1 == te2 and tr1 == tr2
        assert i1 == i2


def test_gymnasium_and_sb3_checkers_pass_without_warnings():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # Gymnasium's own notice that a newer version of an id exists (GearSpeed-v1 for v0, GearSpeed-v2 for v1)
        # is not a warning about the env
        warnings.filterwarnings("ignore", message=".*is out of date.*")
        check_env(gym.make("GearSpeed-v0", **FAST).unwrapped)
        check_env(gym.make("GearSpeed-v1", **FAST).unwrapped)
        check_env(gym.make("GearSpeedDemand-v0", **FAST).unwrapped)
        check_env(gym.make("GearSpeed-v0", render_mode="rgb_array", **FAST).unwrapped)
        check_env(gym.make("GearSpeed-v0", observation="full", demand="steps", action_mode="target", **FAST).unwrapped)
        sb3_check_env(GearSpeedEnv(**FAST))
    assert [str(w.message) for w in caught] == []


def test_spaces_and_observation_bounds():
    env = GearSpeedEnv(**FAST)
    assert env.action_space == gym.spaces.Box(-1, 1, (1,), np.float32)
    assert env.observation_space.shape == (10,)
    assert env.observation_space.dtype == np.float32
    assert GearSpeedEnv(observation="full", **FAST).observation_space.shape == (20,)
    assert GearSpeedEnv(demand="ramp", **FAST).observation_space.shape == (11,)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    # omega entry decodes the physical omega
    lo, hi = env.config.omega_min, env.config.omega_max
    assert lo + (obs[0] + 1) / 2 * (hi - lo) == pytest.approx(info["omega"], abs=1e-6)


def test_determinism_same_seed_identical_trajectories_and_infos():
    a = rollout(GearSpeedEnv(**FAST), 7, 15)
    b = rollout(GearSpeedEnv(**FAST), 7, 15)
    assert_same(a, b)
    c = rollout(GearSpeedEnv(**FAST), 8, 15)
    assert not np.array_equal(a[0][0], c[0][0])


def test_randomized_params_are_seeded():
    cfg = dict(randomize_params=True, **FAST)
    a = rollout(GearSpeedEnv(**cfg), 4, 8)
    b = rollout(GearSpeedEnv(**cfg), 4, 8)
    assert_same(a, b)
    env = GearSpeedEnv(**cfg)
    env.reset(seed=1)
    c1 = env._core.C[0].copy()
    env.reset(seed=2)
    assert not np.array_equal(c1, env._core.C[0])


def test_pickle_round_trip_continues_identically():
    env = GearSpeedEnv(render_mode="rgb_array", **FAST)
    env.reset(seed=11)
    env.step(np.array([0.5], np.float32))
    env.render()
    clone = pickle.loads(pickle.dumps(env))
    for a in (0.3, -1.0, 1.0):
        o1, r1, te1, tr1, i1 = env.step(np.array([a], np.float32))
        o2, r2, te2, tr2, i2 = clone.step(np.array([a], np.float32))
        np.testing.assert_array_equal(o1, o2)
        assert (r1, te1, tr1, i1) == (r2, te2, tr2, i2)


def test_reward_terms_add_up_and_info_keys_stable():
    env = GearSpeedEnv(demand="steps", max_steps=8, periods_per_step=8, warmup_periods=16)
    obs, info = env.reset(seed=0, options={"omega": 1.5})
    assert set(info) == set(INFO_KEYS)
    rng = np.random.default_rng(0)
    for _ in range(8):
        obs, r, te, tr, info = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
        assert set(info) == set(INFO_KEYS)
        assert r == pytest.approx(sum(info[k] for k in REWARD_KEYS), abs=1e-12)
        assert np.isfinite(r) and np.all(np.isfinite(obs))
    assert tr and not te
    assert info["episode_steps"] == 8
    assert info["episode_time_s"] == pytest.approx(info["episode_time_periodic_s"] + info["episode_time_nonperiodic_s"])


def test_throughput_and_rate_terms_follow_the_action():
    env = GearSpeedEnv(**FAST)
    env.reset(seed=0, options={"omega": 1.0})
    _, _, _, _, info = env.step(np.array([1.0], np.float32))
    cfg = env.config
    assert info["omega"] == pytest.approx(1.0 + cfg.max_domega)
    assert info["omega_mean"] == pytest.approx(1.0 + cfg.max_domega / 2)
    assert info["reward_throughput"] == pytest.approx(cfg.w_throughput * (1.0 + cfg.max_domega / 2) / cfg.omega_max)
    assert info["reward_rate"] == pytest.approx(-cfg.w_rate)
    # target mode: far target is rate limited; clipped at the bounds
    env = GearSpeedEnv(action_mode="target", **FAST)
    env.reset(seed=0, options={"omega": 2.99})
    _, _, _, _, info = env.step(np.array([1.0], np.float32))
    assert info["omega"] == pytest.approx(3.0)
    _, _, _, _, info = env.step(np.array([-1.0], np.float32))
    assert info["omega"] == pytest.approx(3.0 - cfg.max_domega)


def test_episode_totals_match_step_infos():
    env = GearSpeedEnv(**FAST)
    env.reset(seed=5)
    infos = []
    done = False
    ret = 0.0
    while not done:
        _, r, te, tr, info = env.step(np.array([0.7], np.float32))
        ret += r
        infos.append(info)
        done = te or tr
    last = infos[-1]
    assert last["episode_return"] == pytest.approx(ret)
    assert last["episode_throughput"] == pytest.approx(np.mean([i["omega_mean"] for i in infos]))
    assert last["episode_impacts"] == sum(i["drive_impacts"] + i["back_impacts"] for i in infos)
    assert last["episode_steps_nonperiodic"] == sum(i["nonperiodic"] for i in infos)
    assert last["episode_time_s"] == pytest.approx(sum(i["step_time_s"] for i in infos))


def test_step_time_matches_physical_time_of_mesh_periods():
    """At constant omega a step lasts periods_per_step mesh periods: 2 pi P / (omega omega_n) seconds."""
    env = GearSpeedEnv(**FAST)
    env.reset(seed=0, options={"omega": 1.2})
    _, _, _, _, info = env.step(np.array([0.0], np.float32))
    wn = env.config.params.omega_n
    assert info["step_time_s"] == pytest.approx(2 * np.pi * 8 / (1.2 * wn), rel=1e-12)


@pytest.mark.parametrize(
    "bad",
    [np.array([np.nan], np.float32), np.array([np.inf], np.float32), np.zeros(2, np.float32), np.zeros((1, 1)), "x"],
)
def test_bad_actions_raise(bad):
    env = GearSpeedEnv(**FAST)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(bad)


def test_out_of_range_action_is_clipped():
    env = GearSpeedEnv(**FAST)
    env.reset(seed=0, options={"omega": 1.0})
    _, _, _, _, info = env.step(np.array([7.0], np.float32))
    assert info["omega"] == pytest.approx(1.05)


def test_step_before_reset_raises():
    with pytest.raises(RuntimeError, match="reset"):
        GearSpeedEnv(**FAST).step(np.zeros(1, np.float32))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"bogus": 1}, "valid keys"),
        ({"periods_per_step": 0}, "periods_per_step"),
        ({"omega_min": 2.0, "omega_max": 1.0}, "omega_max"),
        ({"max_domega": -0.1}, "max_domega"),
        ({"action_mode": "speed"}, "action_mode"),
        ({"model": "elastic"}, "model"),
        ({"w_chaos": -1.0}, "w_chaos"),
        ({"initial_omega": 5.0}, "initial_omega"),
        ({"demand": [(0, 1.0), (-1, 1.0)]}, "demand"),
        ({"demand": "sine"}, "demand"),
        ({"params": {"kappa": 2.0}}, "kappa"),
        ({"params": {"nope": 1}}, "valid fields"),
        ({"steps_per_period": 4}, "steps_per_period"),
    ],
)
def test_bad_config_raises(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make("GearSpeed-v0", **kwargs)


def test_config_round_trip_and_params_dict():
    cfg = GearSpeedConfig(params={"kappa": 0.3}, demand=[(0, 1.0), (10, 1.2)], initial_omega=(1.0, 1.5))
    again = GearSpeedConfig.from_kwargs(cfg.to_dict())
    assert again == cfg
    assert cfg.params.kappa == 0.3
    assert cfg.demand_at(5) == pytest.approx(1.1)


def test_divergence_terminates_with_penalty_and_finite_obs(monkeypatch):
    env = GearSpeedEnv(**FAST)
    obs0, _ = env.reset(seed=0, options={"omega": 1.0})
    state_before = env.state

    def broken(x, a, *args):
        x[:] = np.nan  # what a blown-up integration leaves behind
        return K.DIVERGED, 0, 0.0

    monkeypatch.setattr(K, "integrate_stats_lazy", broken)  # the single-system entry
    obs, r, te, tr, info = env.step(np.array([1.0], np.float32))
    assert te and not tr
    assert info["diverged"] is True
    assert r == -env.config.divergence_penalty == info["reward_divergence"]
    assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
    np.testing.assert_array_equal(obs, obs0)
    np.testing.assert_array_equal(env.state, state_before)
    assert env.omega == 1.0
    assert r == pytest.approx(sum(info[k] for k in REWARD_KEYS))


def test_real_divergence_with_absurd_params_is_finite():
    """An undamped, strongly modulated pair really blows up: terminated with the penalty, finite obs."""
    params = {"xi_m": 0.0, "xi_p": 0.0, "xi_g": 0.0, "kappa": 0.95, "e_m1": 5e-4}
    env = GearSpeedEnv(params=params, max_steps=10, periods_per_step=8, warmup_periods=16)
    obs, info = env.reset(seed=0, options={"omega": 1.0})
    assert np.all(np.isfinite(obs)) and not info["diverged"]
    for _ in range(10):
        obs, r, te, tr, info = env.step(np.array([1.0], np.float32))
        assert np.all(np.isfinite(obs)) and np.isfinite(r) and env.observation_space.contains(obs)
        if te or tr:
            break
    assert te and info["diverged"] and r == -env.config.divergence_penalty
    assert np.all(np.isfinite(env.state))
    # a warm-up that diverges still gives a finite first observation, flagged in info
    obs, info = env.reset(seed=0, options={"omega": 2.9})
    assert info["diverged"] and np.all(np.isfinite(obs))


def test_periodicity_defect_recognises_period_n_and_chaos():
    k = np.arange(16)
    p1 = np.full((16, 2), 0.3)
    p3 = np.stack([np.sin(2 * np.pi * k / 3), np.cos(2 * np.pi * k / 3)], 1)
    qp = np.stack([np.sin(2 * np.pi * k * 0.3183), np.cos(2 * np.pi * k * 0.3183)], 1)  # irrational rotation
    d, period = periodicity_defect(np.stack([p1, p3, qp]), 0.02)
    assert period.tolist()[:2] == [1, 3]
    assert d[0] == 0 and d[1] < 1e-12
    assert d[2] > 0.02 and period[2] == 0


def test_render_rgb_array_frame():
    env = GearSpeedEnv(render_mode="rgb_array", **FAST)
    env.reset(seed=0)
    env.step(np.zeros(1, np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 0
    env.close()


def test_steady_reward_map_prefers_the_quiet_window():
    """The default weights make omega ~1.2 the best constant speed; the chaotic band and the
    impacting high-speed branch are worse (both backlash models)."""
    w = np.array([0.8, 1.2, 2.0, 2.8])
    for model in ("dynamic", "constant"):
        m = steady_reward_map({"model": model}, w, settle_steps=4, average_steps=3)
        assert m.best_omega == 1.2
        assert m.terms["chaos"][2] > 0.5  # omega = 2 is non-periodic
        assert m.terms["contact_loss"][3] > 0.6  # omega = 2.8 loses contact most of the time
        assert m.terms["contact_loss"][1] == 0.0


def test_defect_kernel_matches_numpy_reference():
    from gear_env.envs.env_kernels import defect_of

    rng = np.random.default_rng(0)
    hist = rng.normal(size=(5, 16, 2)) * np.array([1e-3, 1.0, 0.01, 0.02, 3.0])[:, None, None]
    hist[1] = np.tile(hist[1, :2], (8, 1))  # period 2
    d_ref, p_ref = periodicity_defect(hist, 0.02)
    for i in range(5):
        d, p = defect_of(hist[i], 0.02)
        assert d == d_ref[i] and p == p_ref[i]
    assert p_ref[1] == 2


def test_step_features_match_an_independent_recorded_trajectory():
    """Contact loss, impacts and peak force of a step equal those of the simulator's full record
    (integrate_record) over the same interval from the same state."""
    from gear_env.sim.simulator import GearSimulator

    env = GearSpeedEnv(periods_per_step=8, warmup_periods=16, max_steps=10)
    env.reset(seed=0, options={"omega": 1.45})  # period-1 with ~45 % contact loss, one impact per period
    x0 = env.state
    _, _, _, _, info = env.step(np.array([0.6], np.float32))
    sim = GearSimulator(env.config.params, "dynamic", 64, omega=1.45, initial_state=x0)
    traj = sim.record(8, omega_end=1.45 + 0.6 * 0.05)
    assert info["contact_loss"] == pytest.approx(traj.contact_loss_fraction, abs=1e-9)
    assert info["contact_loss"] > 0.2
    region = traj["region"]
    assert info["drive_impacts"] == int(np.sum((region[1:] == 1) & (region[:-1] == 0)))
    fs = env.config.params.dimensionless()["F_s"]
    assert info["force_peak"] == pytest.approx(traj["force"][1:].max() / fs, rel=1e-6)  # Newton tol 1e-10
    assert info["omega"] == pytest.approx(traj.omega[-1])


@pytest.mark.parametrize("options", ["str", [1], 5, ("omega", 1.0), {"omgea": 1.0}])
def test_reset_options_must_be_a_dict_of_known_keys(options):
    env = GearSpeedEnv(**FAST)
    with pytest.raises(ValueError, match=r"reset options must be a dict or None|unknown reset option"):
        env.reset(seed=0, options=options)
    obs, info = env.reset(seed=0, options={"omega": 1.0})  # the env is usable after the refusal
    assert info["omega"] == 1.0


@pytest.mark.parametrize("seed", [True, False, -1, 1.5, "3", np.bool_(True)])
def test_reset_seed_must_be_a_non_negative_integer(seed):
    env = GearSpeedEnv(**FAST)
    with pytest.raises(ValueError, match="seed must be None or an integer >= 0"):
        env.reset(seed=seed)
    a, _ = env.reset(seed=np.int64(3))  # a numpy integer is an integer
    b, _ = GearSpeedEnv(**FAST).reset(seed=3)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("how", ["pickle", "deepcopy"])
def test_copied_env_with_random_params_keeps_drawing_new_physics(how):
    """Issue 15 item 7: the kernels read the constants through a read-only view of the core's
    constants; a copy used to turn that view into a frozen array, so after unpickling every episode
    ran with the physics of the moment of pickling."""
    import copy

    cfg = dict(randomize_params=True, randomize_scale=0.3, **FAST)
    env = GearSpeedEnv(**cfg)
    env.reset(seed=0)
    clone = pickle.loads(pickle.dumps(env)) if how == "pickle" else copy.deepcopy(env)
    fresh = GearSpeedEnv(**cfg)
    firsts = []
    for seed in (1, 2, 3):
        ref = rollout(fresh, seed, 4)
        assert_same(rollout(clone, seed, 4), ref)
        assert_same(rollout(env, seed, 4), ref)
        np.testing.assert_array_equal(clone._core._C_ro, clone._core.C)
        firsts.append(ref[1])
    # the physics differ between episodes: the same omega and action give other features
    assert len({r[0].tobytes() for r in firsts}) == 3
