"""The memory features of the observation (``memory_steps`` > 0): validation, values, determinism, vector env."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import gear_env  # noqa: F401
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig, task_config
from gear_env.envs.env_core import GearSpeedCore
from gear_env.envs.env_terms import TROUBLE_CONTACT
from gear_env.envs.vector_env import GearSpeedVectorEnv
from gear_env.sim import kernels as K

MEMORY = ("trouble_omega", "trouble_recency", "prev_force_rms", "prev_contact_loss")
FAST = dict(max_steps=6, periods_per_step=8, warmup_periods=16)


@pytest.mark.parametrize("bad", [-1.0, 1000.5, math.nan, math.inf, "20", True, None])
def test_bad_memory_steps_names_the_field_and_range(bad):
    with pytest.raises(ValueError, match=r"memory_steps must (be in \[0, 1000\]|be a real number)"):
        GearSpeedConfig(memory_steps=bad)


def test_off_by_default_and_appended_when_on():
    for env_id in ("GearSpeed-v0", "GearSpeed-v1"):
        env = GearSpeedEnv(config=task_config(env_id))
        assert not set(MEMORY) & set(env.observation_names)
    on = GearSpeedEnv(memory_steps=5.0, demand="steps", action_mode="target")
    off = GearSpeedEnv(memory_steps=0.0, demand="steps", action_mode="target")
    assert on.observation_names == (*off.observation_names, *MEMORY)  # earlier indices unchanged
    assert on.observation_space.shape == (len(off.observation_names) + 4,)


def _stats(contact=0.0, impacts=0, frms=0.0, fs=1.0):
    """Synthetic step statistics (K.ST_*): unit time, a contact-loss fraction, drive impacts, a force RMS."""
    st = np.zeros((1, K.N_STATS))
    st[0, K.ST_TIME] = 1.0
    st[0, K.ST_SEP_TIME] = contact
    st[0, K.ST_DRIVE_IMPACTS] = impacts
    st[0, K.ST_F_SUM] = 0.0
    st[0, K.ST_F_SQ] = (frms * fs) ** 2
    return st


def test_feature_values_on_a_hand_made_sequence():
    """A reset and five steps with chosen omegas and sensor statistics through the kernel (the Poincare
    window stays zero, so c = 0): the memory features follow their documented definitions."""
    tau = 4.0
    cfg = GearSpeedConfig(memory_steps=tau, action_mode="target")
    core = GearSpeedCore(cfg, 1, single=True)
    names = core.observation_names
    col = {n: names.index(n) for n in MEMORY}
    fs = float(core.fs[0])
    rows = np.array([0])

    def scaled(w):
        return 2 * (w - cfg.omega_min) / (cfg.omega_max - cfg.omega_min) - 1

    def post(w0, w1, contact=0.0, impacts=0, frms=0.0, reset=False):
        core._post(rows, _stats(contact, impacts, frms, fs), np.array([True]), np.ones(1), np.array([w0]),
                   np.array([w1]), reset)  # fmt: skip
        return {n: float(core.obs[0, col[n]]) for n in MEMORY}

    f = post(1.0, 1.0, frms=0.5, reset=True)  # clean warm-up
    assert f == pytest.approx({"trouble_omega": 1.0, "trouble_recency": 0.0,
                               "prev_force_rms": math.log1p(0.5), "prev_contact_loss": 0.0}, abs=1e-6)  # fmt: skip
    f = post(1.0, 1.2, contact=0.1, frms=0.8)  # trouble begins at the step's mean omega 1.1
    assert f["trouble_omega"] == pytest.approx(scaled(1.1), abs=1e-6)
    assert f["trouble_recency"] == 1.0
    assert f["prev_force_rms"] == pytest.approx(math.log1p(0.5), abs=1e-6)
    f = post(1.2, 1.0, impacts=3, frms=0.9)  # the spell goes on at a lower mean omega (1.1): kept the lowest
    assert f["trouble_omega"] == pytest.approx(scaled(1.1), abs=1e-6)
    assert f["prev_contact_loss"] == pytest.approx(0.1, abs=1e-6)
    f = post(1.0, 0.9, contact=0.5)  # still in trouble, lower: 0.95
    assert f["trouble_omega"] == pytest.approx(scaled(0.95), abs=1e-6)
    f = post(0.9, 0.9, contact=TROUBLE_CONTACT / 2)  # clean (below the contact threshold): decays
    assert f["trouble_omega"] == pytest.approx(scaled(0.95), abs=1e-6)
    assert f["trouble_recency"] == pytest.approx(math.exp(-1 / tau), rel=1e-6)
    f = post(0.9, 0.9)
    assert f["trouble_recency"] == pytest.approx(math.exp(-2 / tau), rel=1e-6)
    assert f["prev_contact_loss"] == pytest.approx(TROUBLE_CONTACT / 2, abs=1e-7)
    f = post(0.9, 1.3, contact=0.2)  # a new spell begins higher up: replaces the old omega
    assert f["trouble_omega"] == pytest.approx(scaled(1.1), abs=1e-6)
    assert f["trouble_recency"] == 1.0
    f = post(1.5, 1.5, contact=0.3, reset=True)  # a troubled warm-up: trouble begins at the start omega
    assert f == pytest.approx({"trouble_omega": scaled(1.5), "trouble_recency": 1.0,
                               "prev_force_rms": 0.0, "prev_contact_loss": 0.3}, abs=1e-6)  # fmt: skip


def test_memory_features_agree_with_the_info_of_the_previous_step():
    env = gym.make("GearSpeedDemand-v0", memory_steps=10.0).unwrapped
    names = env.observation_names
    obs, info = env.reset(seed=5)
    rng = np.random.default_rng(0)
    seen_trouble = False
    for _ in range(25):
        prev = info
        obs, _, _, _, info = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
        v = dict(zip(names, obs.tolist()))
        assert v["prev_force_rms"] == pytest.approx(math.log1p(prev["force_rms"]), rel=1e-6)
        assert v["prev_contact_loss"] == pytest.approx(prev["contact_loss"], rel=1e-6, abs=1e-7)
        trouble = info["contact_loss"] > TROUBLE_CONTACT or info["drive_impacts"] + info["back_impacts"] > 0
        trouble = trouble or info["chaos"] > 0.5
        seen_trouble |= trouble
        assert (v["trouble_recency"] == 1.0) == trouble
        assert env.observation_space.contains(obs)
    assert seen_trouble


def test_determinism_and_checkers():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    def roll(seed):
        env = gym.make("GearSpeedDemand-v0", memory_steps=8.0, **FAST).unwrapped
        out = [env.reset(seed=seed)[0]]
        for a in np.linspace(-1, 1, 12):
            o, r, te, tr, _ = env.step(np.array([a], np.float32))
            out.append(np.append(o, r))
            if te or tr:
                out.append(env.reset()[0])
        return out

    a, b = roll(11), roll(11)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", message=".*is out of date.*")  # Gymnasium's notice: GearSpeedDemand-v1 exists
        check_env(gym.make("GearSpeedDemand-v0", memory_steps=8.0, **FAST).unwrapped)
        sb3_check_env(GearSpeedEnv(config=task_config("GearSpeedDemand-v0", {"memory_steps": 8.0, **FAST})))
    assert [str(w.message) for w in caught] == []


def test_vector_env_equals_single_envs_with_memory():
    """NEXT_STEP autoreset across two episode ends: the memory restarts at each reset in both."""
    n, T = 3, 15
    settings = {"memory_steps": 3.0, **FAST}
    acts = np.random.default_rng(4).uniform(-1, 1, (T, n, 1)).astype(np.float32)
    envs = [gym.make("GearSpeedDemand-v0", **settings).unwrapped for _ in range(n)]
    single = [np.stack([e.reset(seed=70 + i)[0] for i, e in enumerate(envs)])]
    pending = [False] * n
    for t in range(T):
        row = []
        for i, e in enumerate(envs):
            if pending[i]:
                o, _ = e.reset()
                pending[i] = False
            else:
                o, _, te, tr, _ = e.step(acts[t, i])
                pending[i] = te or tr
            row.append(o)
        single.append(np.stack(row))
    venv = GearSpeedVectorEnv(n, config=task_config("GearSpeedDemand-v0", settings))
    o, _ = venv.reset(seed=70)
    np.testing.assert_array_equal(o, single[0])
    for t in range(T):
        o, *_ = venv.step(acts[t])
        np.testing.assert_array_equal(o, single[t + 1])
    assert venv.observation_names == envs[0].observation_names
