"""Scripted baselines, the oracle and the policy registry (agents/)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from agents.baselines import ConstantSpeed, HillClimber, SlowRamp
from agents.oracle import OraclePolicy, QuasiStaticModel, plan_return
from agents.registry import resolve_policy
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig
from gear_env.evaluation import evaluate_policies

# a cheap configuration: coarse integration, short steps and episodes (same physics and reward)
FAST = {"steps_per_period": 32, "periods_per_step": 12, "max_steps": 40, "warmup_periods": 16}


@pytest.fixture(scope="module")
def fast_cfg():
    # the oracle's reward map of this configuration is cached in memory (and in the user's cache
    # folder, keyed by the configuration), so only the first test pays for it (~1 s)
    return GearSpeedConfig.from_kwargs(FAST)


def test_omega_read_from_observation_matches_env(fast_cfg):
    env = GearSpeedEnv(fast_cfg)
    pol = ConstantSpeed(1.0, fast_cfg)
    obs, info = env.reset(seed=3)
    for _ in range(5):
        assert pol.omega_from_obs(obs[None])[0] == pytest.approx(env.omega, abs=1e-5)
        obs, *_ = env.step(np.array([0.7], np.float32))


@pytest.mark.parametrize("mode", ["delta", "target"])
def test_constant_speed_reaches_target_at_max_rate(fast_cfg, mode):
    cfg = fast_cfg.replace(action_mode=mode, initial_omega=0.5)
    env = GearSpeedEnv(cfg)
    pol = ConstantSpeed(1.2, cfg)
    obs, _ = env.reset(seed=0)
    omegas = []
    state, start = None, np.array([True])
    for _ in range(20):
        a, state = pol.predict(obs, state, start)
        start = np.array([False])
        obs, *_, info = env.step(a)
        omegas.append(info["omega"])
    # 0.7 at 0.05 per step: exactly 14 steps, then it holds
    assert omegas[13] == pytest.approx(1.2, abs=1e-5)
    assert omegas[12] == pytest.approx(1.15, abs=1e-5)
    assert np.allclose(omegas[13:], 1.2, atol=1e-5)


def test_ramp_is_slow_and_monotone(fast_cfg):
    pol = SlowRamp(1.2, fast_cfg, rate_fraction=0.25)
    lo, hi = fast_cfg.omega_min, fast_cfg.omega_max
    obs = np.zeros((1, 10), np.float32)
    obs[0, 0] = 2 * (0.6 - lo) / (hi - lo) - 1
    a, _ = pol.predict(obs)
    assert a.shape == (1, 1) and a[0, 0] == pytest.approx(0.25, abs=1e-5)


def test_hill_climber_climbs_when_clean_and_backs_off_on_trouble(fast_cfg):
    pol = HillClimber(fast_cfg)
    lo, hi = fast_cfg.omega_min, fast_cfg.omega_max
    obs = np.zeros((2, 10), np.float32)
    obs[:, 0] = 2 * (1.0 - lo) / (hi - lo) - 1
    obs[1, 7] = 0.3  # contact loss in env 1
    a, state = pol.predict(obs, None, np.array([True, True]))
    assert a[0, 0] == pytest.approx(0.5) and a[1, 0] == pytest.approx(-1.0)
    assert np.isinf(state["ceiling"][0]) and state["ceiling"][1] == pytest.approx(1.0, abs=1e-6)
    # env 1 clean again just below its ceiling: it does not climb back into trouble
    obs[1, 7] = 0.0
    obs[1, 0] = 2 * (0.95 - lo) / (hi - lo) - 1
    a, state = pol.predict(obs, state, np.array([False, False]))
    assert a[1, 0] <= 0.0
    # a new episode forgets the ceiling
    _, state = pol.predict(obs, state, np.array([False, True]))
    assert np.isinf(state["ceiling"][1])


def test_baseline_evaluation_is_deterministic_under_a_seed(fast_cfg):
    pols = {"hill": HillClimber(fast_cfg), "ramp": SlowRamp(1.2, fast_cfg)}
    r1 = evaluate_policies(pols, fast_cfg, episodes=2, seed=11)
    r2 = evaluate_policies(pols, fast_cfg, episodes=2, seed=11)
    for name in pols:
        for e1, e2 in zip(r1.episodes[name], r2.episodes[name]):
            assert e1.ret == e2.ret
            assert e1.omega == e2.omega
    r3 = evaluate_policies(pols, fast_cfg, episodes=2, seed=12)
    assert r3.episodes["hill"][0].omega != r1.episodes["hill"][0].omega


# ------------------------------------------------------------------------------------------- oracle
def _synthetic_model():
    w = np.linspace(0.1, 3.0, 59)
    # two humps (a local optimum at 0.8, the global one at 2.0) and a deep valley between
    r = (
        0.3 * np.exp(-(((w - 0.8) / 0.15) ** 2))
        + 0.5 * np.exp(-(((w - 2.0) / 0.2) ** 2))
        - 0.4 * ((w > 1.1) & (w < 1.6))
    )
    return QuasiStaticModel(w, r, max_domega=0.05, w_rate=0.02)


def _oracle_on(model, max_steps):
    return OraclePolicy(GearSpeedConfig.from_kwargs(FAST, max_steps=max_steps), model=model)


def test_oracle_dynamic_programming_matches_brute_force():
    model = _synthetic_model()
    pol = _oracle_on(model, max_steps=4)
    levels = np.linspace(-1, 1, 5)  # a coarse action set inside the oracle's 41 levels
    for w0 in (0.7, 1.05, 1.9):
        best = -np.inf
        for seq in itertools.product(levels, repeat=4):
            path = [w0]
            for a in seq:
                path.append(float(np.clip(path[-1] + a * 0.05, 0.1, 3.0)))
            best = max(best, plan_return(model, np.array(path)))
        got = plan_return(model, pol.plan(w0, 4))
        assert got >= best - 1e-9


def test_oracle_crosses_a_valley_only_when_it_pays():
    model = _synthetic_model()
    long_ = _oracle_on(model, max_steps=200).plan(0.8)
    assert long_[-1] == pytest.approx(2.0, abs=0.03)  # 200 steps: worth crossing the valley
    assert np.allclose(np.diff(long_[:24]), 0.05)  # 0.8 -> 2.0 at the full rate: 24 steps
    short = _oracle_on(model, max_steps=10).plan(0.8)
    assert np.allclose(short, 0.8, atol=0.01)  # 10 steps: stay on the local optimum


def test_plan_return_rejects_too_fast_paths():
    with pytest.raises(ValueError, match="faster than max_domega"):
        plan_return(_synthetic_model(), np.array([1.0, 1.2]))


def test_oracle_beats_or_ties_every_baseline_on_its_reward_map(fast_cfg):
    oracle = OraclePolicy(fast_cfg)
    model = oracle.model
    assert oracle.best_omega == pytest.approx(model.omegas[np.argmax(model.reward)], abs=0.01)
    baselines = {
        "constant-best": resolve_policy("constant-best", fast_cfg),
        "ramp": resolve_policy("ramp", fast_cfg),
        "hill-climber": resolve_policy("hill-climber", fast_cfg),
        "constant:0.8": resolve_policy("constant:0.8", fast_cfg),
    }
    # the baselines' real omega paths (from the environment), scored on the oracle's model
    report = evaluate_policies(baselines, fast_cfg, episodes=3, seed=5)
    env = GearSpeedEnv(fast_cfg)
    for k in range(3):
        _, info = env.reset(seed=5 + k)
        w0 = info["omega"]
        best = plan_return(model, oracle.plan(w0))
        for name, eps in report.episodes.items():
            other = plan_return(model, np.array([w0] + eps[k].omega))
            # ties within the discretisation of the oracle's omega grid (0.005) count as ties
            assert best >= other - 1e-3 * fast_cfg.max_steps, (name, k, best, other)


# ----------------------------------------------------------------------------------------- registry
def test_registry_specs_and_errors(fast_cfg):
    assert resolve_policy("constant:1.2", fast_cfg).omega == 1.2
    assert resolve_policy("ramp:1.0:0.5", fast_cfg).rate == pytest.approx(0.025)
    assert resolve_policy("hill-climber", fast_cfg).name == "hill-climber"
    with pytest.raises(ValueError, match="unknown policy 'nonsense'.*oracle"):
        resolve_policy("nonsense", fast_cfg)
    with pytest.raises(ValueError, match="not a number"):
        resolve_policy("constant:fast", fast_cfg)
    with pytest.raises(ValueError, match=r"must be in \[0.1, 3\]"):
        resolve_policy("constant:7", fast_cfg)
    with pytest.raises(ValueError, match="does not exist"):
        resolve_policy("no/such/run", fast_cfg)


def test_action_adapter_gives_the_same_next_omega_in_either_mode(fast_cfg):
    from agents.trained import ActionAdapter

    tgt, dlt = fast_cfg.replace(action_mode="target"), fast_cfg
    lo, hi = fast_cfg.omega_min, fast_cfg.omega_max
    obs = np.zeros((3, 10), np.float32)
    obs[:, 0] = 2 * (1.0 - lo) / (hi - lo) - 1  # omega = 1.0
    setpoints = np.array([1.25, 1.02, 0.3])
    a_target = (2 * (setpoints - lo) / (hi - lo) - 1).reshape(3, 1)
    a_delta = ActionAdapter(tgt, dlt)(obs, a_target)
    assert np.allclose(a_delta[:, 0], [1.0, 0.4, -1.0], atol=1e-4)
    # and back: delta actions re-expressed as set-points reach the same omega through the env
    env_t, env_d = GearSpeedEnv(tgt), GearSpeedEnv(dlt)
    ot, _ = env_t.reset(seed=2, options={"omega": 1.0})
    od, _ = env_d.reset(seed=2, options={"omega": 1.0})
    back = ActionAdapter(dlt, tgt)
    for a in (0.3, -1.0, 0.7):
        od, *_, info_d = env_d.step(np.array([a], np.float32))
        ot, *_, info_t = env_t.step(back(ot, np.array([a], np.float32)))
        assert info_t["omega"] == pytest.approx(info_d["omega"], abs=1e-5)


def test_action_adapter_carries_a_limit_policy_across_reference_filters():
    """A policy trained on GearSpeedDemand-v0 with a speed-limit action and no reference filter drives the default
    task (set-point, filter 0.1) to the same omega, step by step: its holds land exactly, its descents run at the
    full rate (the adapter inverts the evaluation's filter; it used to pass the set-point through unfiltered)."""
    from agents.envs import make_config
    from agents.trained import ActionAdapter

    small = {"steps_per_period": 16, "periods_per_step": 4, "warmup_periods": 8, "max_steps": 12}
    ev = make_config("GearSpeedDemand-v0", small)
    tr = ev.replace(action_mode="limit", action_range=(1.15, 1.8), reference_filter=1.0)
    assert ev.reference_filter == 0.1 and ActionAdapter.needed(tr, ev)
    env_t, env_e = GearSpeedEnv(tr), GearSpeedEnv(ev)
    ot, _ = env_t.reset(seed=3, options={"omega": 2.0})
    oe, _ = env_e.reset(seed=3, options={"omega": 2.0})
    adapt = ActionAdapter(tr, ev)
    for a in (-1.0, -1.0, -0.5, -1.0, 1.0, -0.2):
        ot, *_, info_t = env_t.step(np.array([a], np.float32))
        oe, *_, info_e = env_e.step(adapt(oe, np.array([a], np.float32)))
        assert info_e["omega"] == pytest.approx(info_t["omega"], abs=1e-5)
    assert info_t["omega"] != pytest.approx(2.0, abs=0.3)  # it moved: the descent was at the full rate
    # under a dead time the next speed is not known to a stateless adapter: refused, naming the setting
    with pytest.raises(ValueError, match="action_delay 1 in training, 1 here"):
        ActionAdapter(tr.replace(action_delay=1), ev.replace(action_delay=1))


def test_oracle_with_a_demand_meets_it_when_the_shortfall_costs_more():
    # synthetic map peaked at omega = 1: R = -0.5 (w - 1)^2; the demand steps from 1.0 to 1.5 at
    # step 10. Shortfall costs w_demand/omega_max = 2/3 per unit of omega, more than the map loses
    # up to 1.5 (R' = -(w - 1) > -2/3 there), so the optimum is to meet the demand exactly.
    w = np.linspace(0.1, 3.0, 581)
    model = QuasiStaticModel(w, -0.5 * (w - 1.0) ** 2, max_domega=0.05, w_rate=0.0)
    cfg = GearSpeedConfig.from_kwargs(FAST, max_steps=40, demand=[(0, 1.0), (10, 1.0), (10, 1.5), (40, 1.5)])
    path = OraclePolicy(cfg, model=model).plan(1.0)
    assert np.allclose(path[25:-1], 1.5, atol=0.01)
    assert path[10] > 1.05  # it starts early: arriving at 1.5 takes 10 steps at the full rate
    still = OraclePolicy(cfg.replace(demand=None), model=model).plan(1.0)
    assert np.allclose(still, 1.0, atol=0.01)  # no demand: it stays on the map's optimum
