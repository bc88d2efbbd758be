"""GearSpeedVectorEnv and the SB3 adapter: equivalence with single envs, autoreset, SB3 training."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import gear_env  # noqa: F401
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_core import INFO_KEYS
from gear_env.envs.sb3_adapter import SB3VecEnvAdapter
from gear_env.envs.vector_env import GearSpeedVectorEnv
from gear_env.sim import batch_kernels as BK
from gear_env.sim import kernels as K

FAST = dict(max_steps=5, periods_per_step=8, warmup_periods=16)
N = 3


def actions_for(T, n, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, (T, n, 1)).astype(np.float32)


def single_rollouts(seed, acts, **cfg):
    """N single envs seeded seed+i, auto-reset NEXT_STEP style (the step after done is a reset)."""
    T, n, _ = acts.shape
    envs = [GearSpeedEnv(**cfg) for _ in range(n)]
    first = [e.reset(seed=seed + i) for i, e in enumerate(envs)]
    obs = [np.stack([f[0] for f in first])]
    rewards, terms, truncs, infos = [], [], [], []
    pending = [False] * n
    for t in range(T):
        o_t, r_t, te_t, tr_t, i_t = [], [], [], [], []
        for i, e in enumerate(envs):
            if pending[i]:
                o, info = e.reset()
                r, te, tr = 0.0, False, False
            else:
                o, r, te, tr, info = e.step(acts[t, i])
            pending[i] = te or tr
            o_t.append(o)
            r_t.append(r)
            te_t.append(te)
            tr_t.append(tr)
            i_t.append(info)
        obs.append(np.stack(o_t))
        rewards.append(r_t)
        terms.append(te_t)
        truncs.append(tr_t)
        infos.append(i_t)
    return obs, np.array(rewards), np.array(terms), np.array(truncs), infos


def test_vector_equals_single_envs_exactly():
    T = 13  # crosses two episode ends (max_steps 5) with NEXT_STEP autoreset
    acts = actions_for(T, N)
    s_obs, s_r, s_te, s_tr, s_info = single_rollouts(42, acts, **FAST)
    venv = GearSpeedVectorEnv(N, **FAST)
    o, info = venv.reset(seed=42)
    np.testing.assert_array_equal(o, s_obs[0])
    for t in range(T):
        o, r, te, tr, info = venv.step(acts[t])
        np.testing.assert_array_equal(o, s_obs[t + 1])
        np.testing.assert_array_equal(r, s_r[t])
        np.testing.assert_array_equal(te, s_te[t])
        np.testing.assert_array_equal(tr, s_tr[t])
        for i in range(N):
            assert {k: INFO_KEYS[k](info[k][i]) for k in INFO_KEYS} == s_info[t][i]
            assert all(info["_" + k][i] for k in INFO_KEYS)
    assert s_tr.sum() == 2 * N


def test_make_vec_vector_entry_point_declares_autoreset():
    venv = gym.make_vec("GearSpeed-v0", num_envs=2, vectorization_mode="vector_entry_point", **FAST)
    assert isinstance(venv.unwrapped, GearSpeedVectorEnv)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, info = venv.reset(seed=0)
    assert venv.observation_space.shape == (2, 10) and venv.action_space.shape == (2, 1)
    assert venv.observation_space.contains(obs)
    venv.close()


def test_same_step_autoreset_puts_final_obs_in_info():
    venv = GearSpeedVectorEnv(2, autoreset_mode=AutoresetMode.SAME_STEP, **FAST)
    ref = GearSpeedVectorEnv(2, autoreset_mode=AutoresetMode.NEXT_STEP, **FAST)
    venv.reset(seed=1)
    ref.reset(seed=1)
    a = np.zeros((2, 1), np.float32)
    for _ in range(4):
        venv.step(a)
        ref.step(a)
    o, r, te, tr, info = venv.step(a)
    o_ref, r_ref, _, _, info_ref = ref.step(a)
    assert tr.all() and info["_final_obs"].all()
    np.testing.assert_array_equal(np.stack(info["final_obs"]), o_ref)
    np.testing.assert_array_equal(r, r_ref)
    assert info["final_info"]["episode_steps"].tolist() == [5, 5]
    o_next, _, _, _, _ = ref.step(a)  # NEXT_STEP: this is the reset
    np.testing.assert_array_equal(o, o_next)


def test_disabled_autoreset_needs_masked_reset():
    venv = GearSpeedVectorEnv(2, autoreset_mode="Disabled", **dict(FAST, max_steps=1))
    venv.reset(seed=0)
    venv.step(np.zeros((2, 1), np.float32))
    with pytest.raises(RuntimeError, match="reset_mask"):
        venv.step(np.zeros((2, 1), np.float32))
    venv.reset(options={"reset_mask": np.array([True, True])})
    venv.step(np.zeros((2, 1), np.float32))


def test_vector_bad_actions_raise():
    venv = GearSpeedVectorEnv(2, **FAST)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((3, 1), np.float32))
    with pytest.raises(ValueError, match="finite"):
        venv.step(np.array([[0.0], [np.nan]], np.float32))
    with pytest.raises(ValueError, match="num_envs"):
        GearSpeedVectorEnv(0)


def patch_batch_kernels(monkeypatch, after):
    """Make both batch kernels (scalar and SIMD lanes) call ``after(X, n_periods, status)`` after
    integrating, to inject failures."""
    for mod, name in ((K, "integrate_stats_batch"), (BK, "integrate_stats_lanes")):
        real = getattr(mod, name)

        def patched(X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter, tol,
                    real=real):  # fmt: skip
            real(X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter, tol)
            after(X, n_periods, status)

        monkeypatch.setattr(mod, name, patched)


def test_vector_divergence_only_hits_the_bad_row(monkeypatch):
    venv = GearSpeedVectorEnv(3, **FAST)
    obs0, _ = venv.reset(seed=0)

    def fail_row_1(X, n_periods, status):
        status[1] = K.NEWTON_FAILED
        X[1] = np.nan

    patch_batch_kernels(monkeypatch, fail_row_1)
    obs, r, te, tr, info = venv.step(np.zeros((3, 1), np.float32))
    assert te.tolist() == [False, True, False]
    assert info["diverged"].tolist() == [False, True, False]
    assert r[1] == -venv.config.divergence_penalty
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(r))
    np.testing.assert_array_equal(obs[1], obs0[1])
    assert np.all(np.isfinite(venv._core.X))


def test_vector_pickle_round_trip():
    venv = GearSpeedVectorEnv(2, **FAST)
    venv.reset(seed=9)
    clone = pickle.loads(pickle.dumps(venv))
    a = actions_for(6, 2, seed=3)
    for t in range(6):
        o1, r1, *_ = venv.step(a[t])
        o2, r2, *_ = clone.step(a[t])
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)


def test_sb3_adapter_terminal_observation_and_truncation():
    env = SB3VecEnvAdapter(2, seed=5, **FAST)
    ref = GearSpeedVectorEnv(2, autoreset_mode=AutoresetMode.NEXT_STEP, **FAST)
    obs = env.reset()
    obs_ref, _ = ref.reset(seed=5)
    np.testing.assert_array_equal(obs, obs_ref)
    a = np.zeros((2, 1), np.float32)
    for _ in range(5):
        env.step_async(a)
        obs, rew, dones, infos = env.step_wait()
        o_ref, r_ref, *_ = ref.step(a)
        np.testing.assert_allclose(rew, r_ref.astype(np.float32))
    assert dones.all()
    for i in range(2):
        np.testing.assert_array_equal(infos[i]["terminal_observation"], o_ref[i])
        assert infos[i]["TimeLimit.truncated"] is True
        assert infos[i]["episode"]["l"] == 5
    o_next, *_ = ref.step(a)
    np.testing.assert_array_equal(obs, o_next)  # auto-reset observation
    assert env.get_attr("render_mode") == [None, None]
    assert len(env.get_attr("omega")) == 2
    assert env.env_is_wrapped(gym.Wrapper) == [False, False]
    assert env.seed(3) == [3, 4]
    env.set_options([{"omega": 1.2}, {"omega": 2.0}])
    env.reset()
    assert env.get_attr("omega") == [1.2, 2.0]
    env.set_options({"omega": 0.7})
    env.reset()
    assert env.get_attr("omega") == [0.7, 0.7]
    env.close()


def test_sb3_adapter_divergence_is_not_truncation(monkeypatch):
    env = SB3VecEnvAdapter(2, seed=0, **FAST)
    env.reset()

    def diverge_row_0(X, n_periods, status):
        if n_periods == FAST["periods_per_step"]:
            status[0] = K.DIVERGED

    patch_batch_kernels(monkeypatch, diverge_row_0)
    env.step_async(np.zeros((2, 1), np.float32))
    _, _, dones, infos = env.step_wait()
    assert dones.tolist() == [True, False]
    assert infos[0]["TimeLimit.truncated"] is False and infos[0]["diverged"] is True


def test_sb3_ppo_runs_through_adapter_and_make_vec_env():
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    torch.set_num_threads(1)
    cfg = dict(max_steps=50, periods_per_step=8, warmup_periods=16)
    venv = SB3VecEnvAdapter(4, seed=0, **cfg)
    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=256, n_epochs=1, seed=0, device="cpu")
    model.learn(2048)
    assert model.num_timesteps >= 2048
    mean, _ = evaluate_policy(model, venv, n_eval_episodes=2)
    assert np.isfinite(mean)
    env2 = make_vec_env(lambda: gym.make("GearSpeed-v0", **cfg), n_envs=2, seed=0)
    model2 = PPO("MlpPolicy", env2, n_steps=128, batch_size=128, n_epochs=1, seed=0, device="cpu")
    model2.learn(256)
    assert model2.num_timesteps >= 256


def test_vector_render_rgb_array():
    venv = GearSpeedVectorEnv(2, render_mode="rgb_array", **FAST)
    venv.reset(seed=0)
    venv.step(np.zeros((2, 1), np.float32))
    frame = venv.render()
    assert frame.dtype == np.uint8 and frame.shape[2] == 3
    adapter = SB3VecEnvAdapter(2, render_mode="rgb_array", **FAST)
    adapter.reset()
    assert adapter.render().shape[2] == 3
    venv.close()


@pytest.mark.parametrize("options", ["str", [1], 5, {"omgea": 1.0}])
def test_vector_reset_options_must_be_a_dict_of_known_keys(options):
    venv = GearSpeedVectorEnv(2, **FAST)
    with pytest.raises(ValueError, match=r"reset options must be a dict or None|unknown reset option"):
        venv.reset(seed=0, options=options)


@pytest.mark.parametrize("seed", [True, -1, 1.5, [0, True], [0, -2]])
def test_single_and_vector_env_refuse_the_same_seeds(seed):
    """Issue 15 item 14: ``reset(seed=True)`` was accepted by the single env (as seed 1) and refused
    by the vector env; both now refuse bools, negative and non-integer seeds alike."""
    venv = GearSpeedVectorEnv(2, **FAST)
    venv.reset(seed=0)
    rngs = [r.bit_generator.state for r in venv._rngs]
    with pytest.raises(ValueError, match="seed"):
        venv.reset(seed=seed)
    assert [r.bit_generator.state for r in venv._rngs] == rngs  # refused before anything changed
    if not isinstance(seed, list):
        with pytest.raises(ValueError, match="seed"):
            GearSpeedEnv(**FAST).reset(seed=seed)


@pytest.mark.parametrize("how", ["pickle", "deepcopy"])
def test_copied_vector_env_with_random_params_keeps_drawing_new_physics(how):
    import copy

    cfg = dict(randomize_params=True, randomize_scale=0.3, **FAST)
    venv = GearSpeedVectorEnv(N, **cfg)
    venv.reset(seed=0)
    clone = pickle.loads(pickle.dumps(venv)) if how == "pickle" else copy.deepcopy(venv)
    fresh = GearSpeedVectorEnv(N, **cfg)
    acts = actions_for(4, N)
    firsts = []
    for seed in (10, 20):
        outs = []
        for e in (fresh, clone, venv):
            o, _ = e.reset(seed=seed)
            seq = [o] + [e.step(a)[0] for a in acts]
            outs.append(np.stack(seq))
        np.testing.assert_array_equal(outs[1], outs[0])
        np.testing.assert_array_equal(outs[2], outs[0])
        firsts.append(outs[0][1])
    assert not np.array_equal(firsts[0], firsts[1])
    assert len({row.tobytes() for row in firsts[0]}) == N  # each sub-env its own physics


def test_same_step_final_keys_follow_sync_vector_env():
    """Issue 15 item 16: with SAME_STEP autoreset, ``final_obs``/``final_info`` (and their masks)
    appear only on a step where an episode ended, exactly as in Gymnasium's SyncVectorEnv over
    single envs, with the same values where the masks are set."""
    cfg = dict(FAST, max_steps=3)
    ours = GearSpeedVectorEnv(2, autoreset_mode=AutoresetMode.SAME_STEP, **cfg)
    sync = gym.vector.SyncVectorEnv([lambda: GearSpeedEnv(**cfg)] * 2, autoreset_mode=AutoresetMode.SAME_STEP)
    o1, i1 = ours.reset(seed=4)
    o2, i2 = sync.reset(seed=4)
    np.testing.assert_array_equal(o1, o2)
    ended = 0
    for a in actions_for(7, 2, seed=3):
        o1, r1, te1, tr1, i1 = ours.step(a)
        o2, r2, te2, tr2, i2 = sync.step(a)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        assert set(i1) == set(i2)
        done = te1 | tr1
        assert ("final_obs" in i1) == done.any()
        if done.any():
            ended += 1
            np.testing.assert_array_equal(i1["_final_obs"], i2["_final_obs"])
            np.testing.assert_array_equal(i1["_final_info"], i2["_final_info"])
            for k in range(2):
                if done[k]:
                    np.testing.assert_array_equal(i1["final_obs"][k], i2["final_obs"][k])
                else:
                    assert i1["final_obs"][k] is None and i2["final_obs"][k] is None
            f1, f2 = i1["final_info"], i2["final_info"]
            assert set(f1) == set(f2)
            for key in INFO_KEYS:
                np.testing.assert_array_equal(f1[key], f2[key])
                np.testing.assert_array_equal(f1["_" + key], f2["_" + key])
        for key in INFO_KEYS:
            np.testing.assert_array_equal(i1[key], i2[key])
    assert ended >= 2
