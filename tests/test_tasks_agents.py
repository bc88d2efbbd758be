"""Baselines of the tasks (oracle / fixed-best planners, hill-climber with a demand), the rl-zoo3
hyper-parameter reader and the pickle-free shipped policy format."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from agents.episode_oracle import EpisodePlanner
from agents.hyperparams import load_zoo_entry
from gear_env.envs.env_config import task_config


def _planner(cost_rows, demand, **settings):
    cfg = task_config("GearSpeedDemand-v0", {"max_steps": len(cost_rows), **settings})
    w = np.linspace(cfg.omega_min, cfg.omega_max, 30)
    return EpisodePlanner(cfg, w, np.array([np.interp(w, *c) for c in cost_rows]), demand), cfg


def test_planner_is_optimal_against_brute_force():
    """On a small synthetic problem the DP path is at least as good as every path of grid moves."""
    rng = np.random.default_rng(0)
    T = 4
    pts = np.linspace(0.1, 3.0, 7)
    rows = [(pts, rng.uniform(-1.0, 0.2, 7)) for _ in range(T)]
    demand = rng.uniform(0.1, 3.0, T + 1)
    pl, cfg = _planner(rows, demand, max_domega=0.5)
    best = pl.path_return(pl.path(1.5))
    moves = np.linspace(-1, 1, 5) * cfg.max_domega
    for seq in itertools.product(moves, repeat=T):
        w = [1.5]
        for m in seq:
            w.append(float(np.clip(w[-1] + m, cfg.omega_min, cfg.omega_max)))
        assert pl.path_return(np.array(w)) <= best + 1e-9


def test_planner_follows_a_reachable_quiet_demand():
    """Flat zero cost: the plan delivers the demand (throughput is paid only up to it)."""
    T = 12
    flat = (np.array([0.1, 3.0]), np.zeros(2))
    demand = np.full(T + 1, 1.0)
    pl, _ = _planner([flat] * T, demand)
    path = pl.path(0.5)
    assert path[6] == pytest.approx(1.0, abs=0.011) and path[-1] == pytest.approx(1.0, abs=0.011)


def test_zoo_entry(tmp_path):
    f = tmp_path / "ppo.yml"
    f.write_text(
        "base: &b\n  n_envs: 4\n  n_timesteps: !!float 2e3\n  policy: 'MlpPolicy'\n  normalize: true\n  gamma: 0.99\n"
        '  policy_kwargs: "dict(log_std_init=-1.0, net_arch=[32, 32])"\n  env_kwargs:\n    max_steps: 7\n'
        "GearSpeed-v1:\n  <<: *b\n  ent_coef: 0.0\n"
    )
    e = load_zoo_entry(f, "GearSpeed-v1")
    assert e["n_envs"] == 4 and e["n_timesteps"] == 2000 and e["env_kwargs"] == {"max_steps": 7}
    assert e["ppo"] == {"gamma": 0.99, "ent_coef": 0.0, "log_std_init": -1.0, "net_arch": [32, 32]}
    with pytest.raises(ValueError, match="no entry"):
        load_zoo_entry(f, "GearSpeedDemand-v0")
    f.write_text("GearSpeed-v1:\n  policy_kwargs: \"dict(x=__import__('os'))\"\n")
    with pytest.raises(ValueError, match="policy_kwargs"):
        load_zoo_entry(f, "GearSpeed-v1")
    f.write_text("GearSpeed-v1:\n  gama: 0.9\n")
    with pytest.raises(ValueError, match="gama"):
        load_zoo_entry(f, "GearSpeed-v1")


def test_shipped_policy_roundtrip(tmp_path):
    """export -> load gives the same deterministic actions, without unpickling anything."""
    pytest.importorskip("stable_baselines3")
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.shipped import export_policy, load_policy

    torch.set_num_threads(1)
    venv = VecNormalize(make_vec_env("Pendulum-v1", n_envs=2, seed=0))
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=64,
        batch_size=64,
        n_epochs=1,
        seed=0,
        device="cpu",
        policy_kwargs={"net_arch": [16, 16], "log_std_init": -1.0},
    )
    model.learn(128)
    venv.training = False
    out = export_policy(model, venv, "Pendulum-v1", {}, tmp_path / "pol")
    assert sorted(p.name for p in out.iterdir()) == ["policy.json", "policy.pt"]
    pol = load_policy(out)
    obs = np.random.default_rng(0).normal(size=(5, 3)).astype(np.float32)
    want, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
    got, _ = pol.predict(obs)
    assert np.allclose(got, want, atol=1e-6)
    with pytest.raises(ValueError, match="observation features"):
        pol.predict(np.zeros((1, 4), np.float32))
    # a foreign file is refused with a message, never unpickled
    (out / "policy.pt").write_bytes(b"not a state dict")
    with pytest.raises(ValueError, match="policy.pt"):
        load_policy(out)
    meta = json.loads((out / "policy.json").read_text())
    meta["format"] = "something/else"
    (out / "policy.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="policy.json"):
        load_policy(out)
    # export refuses a folder that holds other files
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="not a previous policy export"):
        export_policy(model, venv, "Pendulum-v1", {}, tmp_path / "busy")


def test_shipped_demand_policy_acts_on_the_task_as_registered():
    """GearSpeedDemand-v0's shipped policy learned a speed limit over [1.15, 1.8] (no reference filter). Loaded
    alone (``load_policy``), it drives ``gym.make("GearSpeedDemand-v0")`` as ``--policy pretrained`` does: its
    actions are adapted to the task's set-point action (filter 0.1) at load, and on the limit environment it
    was trained on (``adapt_to``) the same episode reaches the same speeds."""
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    import gear_env  # noqa: F401  (registers the ids)
    from agents.envs import make_config
    from agents.registry import pretrained_dir, resolve_policy
    from agents.shipped import load_policy

    env_id = "GearSpeedDemand-v0"
    pol = load_policy(pretrained_dir(env_id))
    assert pol.meta["env_config"]["action_mode"] == "limit" and pol.action_adapter is not None
    via_registry = resolve_policy("pretrained", make_config(env_id, None), env_id=env_id)
    limit_cfg = make_config(env_id, {k: pol.meta["env_config"][k] for k in ("action_mode", "action_range",
                                                                             "reference_filter")})  # fmt: skip
    native = load_policy(pretrained_dir(env_id)).adapt_to(limit_cfg)
    assert native.action_adapter is None
    small = {"max_steps": 12}
    envs = [gym.make(env_id, **small), gym.make(env_id, **small),
            gym.make(env_id, **small, **{k: limit_cfg.__dict__[k] for k in ("action_mode", "action_range",
                                                                            "reference_filter")})]  # fmt: skip
    omegas = []
    for env, p in zip(envs, (pol, via_registry, native)):
        obs, _ = env.reset(seed=700_007)  # a worn pair: the limit holds the floor 1.150
        w = []
        for _ in range(12):
            a, _ = p.predict(obs, deterministic=True)
            obs, _r, term, trunc, info = env.step(a)
            w.append(info["omega"])
        omegas.append(np.array(w))
    assert np.array_equal(omegas[0], omegas[1])
    assert omegas[2] == pytest.approx(omegas[0], abs=1e-6)
    assert omegas[0][-1] == pytest.approx(1.15, abs=1e-6)
