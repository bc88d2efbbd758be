"""``action_mode="limit_rate"`` (the action moves a speed limit), the ``force_level`` observation entries and the
task that combines them, ``GearSpeedDemandLimit-v0``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gear_env  # noqa: F401  (registers the tasks)
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig, task_config
from gear_env.envs.force_level import force_level, step_mean_omega
from gear_env.envs.vector_env import GearSpeedVectorEnv

SHORT = {"periods_per_step": 8, "warmup_periods": 16, "max_steps": 40}


def _omega(cfg, x):
    return cfg.omega_min + 0.5 * (float(x) + 1.0) * (cfg.omega_max - cfg.omega_min)


def test_the_limit_moves_by_the_rate_and_the_drive_follows_the_demand_under_it():
    """Step by step: L(t+1) = clip(L(t) + a limit_rate, 1.15, 1.8) from L = 1.15, observed as speed_limit (scaled
    like omega), and the speed moves towards min(demand, L) at most max_domega per step (no reference filter)."""
    cfg = task_config("GearSpeedDemandLimit-v0", SHORT)
    env = GearSpeedEnv(cfg)
    i = env.observation_names.index("speed_limit")
    obs, info = env.reset(seed=5, options={"omega": 1.2})
    assert _omega(cfg, obs[i]) == pytest.approx(1.15, abs=1e-6)
    limit, w = 1.15, info["omega"]
    rng = np.random.default_rng(0)
    for t in range(SHORT["max_steps"]):
        a = float(rng.uniform(-1.5, 1.5)) if t > 25 else 1.0
        demand = env.unwrapped._core.demand(env.unwrapped._core.steps[:1], np.array([0]))[0]
        obs, _, term, trunc, info = env.step(np.array([a], np.float32))
        limit = min(max(limit + np.clip(a, -1, 1) * 0.03, 1.15), 1.8)
        assert _omega(cfg, obs[i]) == pytest.approx(limit, abs=1e-6)
        want = min(demand, limit)
        w = min(max(want, w - cfg.max_domega), w + cfg.max_domega)
        assert info["omega"] == pytest.approx(w, abs=1e-9)
        if term or trunc:
            break
    assert limit == pytest.approx(1.8) or t > 25  # the limit reached the top of its band on the way


def test_bad_limit_rate_settings_are_refused_by_name():
    with pytest.raises(ValueError, match=r'action_mode "limit_rate".*needs a demand'):
        GearSpeedConfig(action_mode="limit_rate")
    with pytest.raises(ValueError, match=r"limit_rate"):
        task_config("GearSpeedDemandLimit-v0", {"limit_rate": 0.0})
    with pytest.raises(ValueError, match=r"limit_rate"):
        task_config("GearSpeedDemandLimit-v0", {"limit_rate": 0.66})  # wider than the band [1.15, 1.8]
    with pytest.raises(ValueError, match=r"action_delay must be 0 with action_mode \"limit_rate\""):
        task_config("GearSpeedDemandLimit-v0", {"action_delay": 1})
    with pytest.raises(ValueError, match=r"force_level must be"):
        task_config("GearSpeedDemandLimit-v0", {"force_level": 1})


def test_other_tasks_keep_their_observation():
    """The new entries appear only where asked for: GearSpeedDemand-v0 keeps its 15 entries."""
    names = GearSpeedEnv(task_config("GearSpeedDemand-v0", SHORT)).observation_names
    assert len(names) == 15 and "speed_limit" not in names and "force_level" not in names
    v1 = GearSpeedEnv(task_config("GearSpeedDemandLimit-v0", SHORT)).observation_names
    assert v1[:15] == names  # the scripts read the same columns on both
    assert v1[15:] == (
        "speed_limit", "force_level", "force_level_known", "steady_force_level", "steady_force_level_known"
    )  # fmt: skip


def test_force_level_is_the_scaled_observation_and_the_steady_copy_keeps_clean_steady_steps():
    """force_level = log(expm1(force_rms)) - log h(step mean speed) from the observation itself (the scripts'
    log q); steady_force_level changes only on clean, steady steps inside the table and holds otherwise."""
    from agents.demand_scripts import _trouble, log_q

    cfg = task_config("GearSpeedDemandLimit-v0", SHORT)
    env = GearSpeedEnv(cfg)
    n = env.observation_names
    c = {k: n.index(k) for k in ("force_level", "force_level_known", "steady_force_level", "steady_force_level_known")}
    seen_known, seen_hold = False, False
    for seed in range(8):
        obs, _ = env.reset(seed=seed, options={"omega": 0.5})
        steady, known_steady = 0.0, 0.0
        for t in range(SHORT["max_steps"]):
            w = np.array([_omega(cfg, obs[0])])
            q = log_q(w, obs[None].astype(float), cfg.max_domega)[0]
            known = np.isfinite(q)
            assert obs[c["force_level_known"]] == float(known)
            assert obs[c["force_level"]] == pytest.approx(np.clip(q, -5, 5) if known else 0.0, abs=1e-5)
            if known and not _trouble(obs[None])[0] and abs(obs[1]) <= 0.3:
                steady, known_steady, seen_known = float(obs[c["force_level"]]), 1.0, True
            elif known_steady:
                seen_hold = True
            assert obs[c["steady_force_level"]] == pytest.approx(steady, abs=1e-6)
            assert obs[c["steady_force_level_known"]] == known_steady
            obs, _, term, trunc, _ = env.step(np.array([1.0 if t % 5 else -1.0], np.float32))
            if term or trunc:
                break
    assert seen_known and seen_hold  # both branches ran, so the test could fail
    w_mid = step_mean_omega(np.array([1.0, 2.5]), np.array([0.0, 0.0]), 0.1)
    assert np.isfinite(force_level(w_mid, np.array([0.5, 0.5]))[0]).tolist() == [True, False]


@pytest.mark.parametrize(
    "task, settings, steps",
    [("GearSpeedDemandLimit-v0", SHORT, 12),
     ("GearSpeedDemandHard-v0", {**SHORT, "force_level": True, "level_window": 4}, 20)],  # + the level_window entries
)  # fmt: skip
def test_vector_env_is_the_single_env_bit_for_bit(task, settings, steps):
    cfg = task_config(task, settings)
    vec = GearSpeedVectorEnv(3, config=cfg)
    singles = [GearSpeedEnv(cfg) for _ in range(3)]
    vo, _ = vec.reset(seed=[1, 2, 3])
    so = [e.reset(seed=s)[0] for e, s in zip(singles, [1, 2, 3])]
    np.testing.assert_array_equal(vo, np.stack(so))
    rng = np.random.default_rng(4)
    for _ in range(steps):
        a = rng.uniform(-1, 1, (3, 1)).astype(np.float32)
        vo, vr, *_ = vec.step(a)
        outs = [e.step(a[k]) for k, e in enumerate(singles)]
        np.testing.assert_array_equal(vo, np.stack([o[0] for o in outs]))
        np.testing.assert_array_equal(vr, np.array([o[1] for o in outs]))


def test_gymnasium_and_sb3_checkers_pass():
    from gymnasium.utils.env_checker import check_env

    check_env(gym.make("GearSpeedDemandLimit-v0", **SHORT).unwrapped)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3.check_env(gym.make("GearSpeedDemandLimit-v0", **SHORT), warn=True)


def test_scripts_move_the_limit_to_their_speed():
    """A scripted constant speed on a limit_rate task never sets the observed limit above its speed, and the drive
    delivers min(demand, speed) on most steps (the limit climbs at limit_rate per step where needed)."""
    from agents.baselines import ConstantSpeed

    cfg = task_config("GearSpeedDemandLimit-v0", SHORT)
    env = GearSpeedEnv(cfg)
    pol = ConstantSpeed(1.4, config=cfg)
    i = env.observation_names.index("speed_limit")
    obs, _ = env.reset(seed=2, options={"omega": 1.2})
    limits, hit = [], []
    for _ in range(SHORT["max_steps"]):
        a, _ = pol.predict(obs)
        obs, _, term, trunc, info = env.step(a)
        limits.append(_omega(cfg, obs[i]))
        hit.append(abs(info["omega"] - min(info["demand"], 1.4)) < 1e-6)
        if term or trunc:
            break
    assert max(limits) <= 1.4 + 1e-5 and max(limits) > 1.2
    assert np.mean(hit) > 0.6, np.mean(hit)
