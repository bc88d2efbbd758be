"""The environment's terms are declared once (gear_env/envs/env_terms.py): config fields, info keys, the
reward sum, the kernels' formulas, the observation names and the docs tables follow the table."""

from __future__ import annotations

import dataclasses
import inspect
import re
from pathlib import Path

import numpy as np
import pytest

from gear_env.envs import env_kernels as EK
from gear_env.envs import env_terms as ET
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig
from gear_env.envs.env_core import INFO_KEYS, REWARD_KEYS
from gear_env.envs.vector_env import GearSpeedVectorEnv

FAST = dict(max_steps=6, periods_per_step=8, warmup_periods=16)
V0 = ET.task("GearSpeed-v0")
DOCS = Path(__file__).resolve().parents[1] / "docs" / "ENVIRONMENT.md"


def assert_env_follows_table(env, terms: ET.TaskTerms, steps: int = 6, seed: int = 0) -> None:
    """Config fields, info keys and types, and the reward as the sum of the terms, against ``terms``."""
    cfg = env.config
    assert type(cfg).field_names() == list(terms.field_names)
    for t in (*terms.rewards, *terms.costs):
        assert t.weight_name in terms.field_names
    expected = terms.info_keys
    assert list(expected) == [*terms.reward_keys, *terms.cost_keys, *(["cost"] if terms.costs else [])] + [
        i.name for i in terms.infos
    ]
    obs, info = env.reset(seed=seed)
    assert list(info) == list(expected)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, r, te, tr, info = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
        assert list(info) == list(expected)
        assert all(type(info[k]) is t for k, t in expected.items())
        total = 0.0
        for k in terms.reward_keys:  # the kernel's order: bit for bit
            total += info[k]
        assert r == total
        if terms.costs:
            cost = 0.0
            for k in terms.cost_keys:
                assert info[k] >= 0.0
                cost += info[k]
            assert info["cost"] == cost
        if te or tr:
            break


def test_gear_speed_v0_follows_its_table():
    for extra in ({}, {"demand": "steps"}, {"observation": "full", "action_mode": "target"}):
        assert_env_follows_table(GearSpeedEnv(**FAST, **extra), V0)


def test_the_check_fails_when_env_and_table_disagree():
    """The agreement check is not vacuous: a table with one term less, one more, or two terms in
    another order is caught."""
    env = GearSpeedEnv(demand="steps", **FAST)
    fewer = dataclasses.replace(V0, rewards=V0.rewards[:-1])
    more = dataclasses.replace(V0, rewards=(*V0.rewards, ET.Term("speed", 1.0, "w_speed * omega", "speed")))
    swapped = dataclasses.replace(V0, rewards=(V0.rewards[1], V0.rewards[0], *V0.rewards[2:]))
    no_setting = dataclasses.replace(V0, settings=V0.settings[1:])
    for bad in (fewer, more, swapped, no_setting):
        with pytest.raises(AssertionError):
            assert_env_follows_table(env, bad)


def test_module_level_keys_are_the_table():
    assert INFO_KEYS == V0.info_keys
    assert REWARD_KEYS == tuple(f"reward_{t.name}" for t in ET.REWARDS)
    assert EK.INFO_COLUMNS == tuple(k for k, _ in ET.INFO_COLUMNS)
    assert list(GearSpeedConfig.field_names()) == [s.name for s in ET.all_settings()]
    # defaults come from the table
    cfg = GearSpeedConfig()
    for s in V0.settings:
        if s.name != "params":
            assert getattr(cfg, s.name) == s.default, s.name


def test_vector_env_info_keys_are_the_table():
    venv = GearSpeedVectorEnv(3, **FAST)
    _, info = venv.reset(seed=0)
    _, r, _, _, info = venv.step(np.zeros((3, 1), np.float32))
    assert [k for k in info if not k.startswith("_")] == list(V0.info_keys)
    total = np.zeros(3)
    for k in V0.reward_keys:
        total = total + info[k]
    np.testing.assert_array_equal(r, total)


@pytest.mark.parametrize("term", [t.name for t in ET.REWARDS if t.name != "divergence"])
def test_each_weight_scales_only_its_own_term(term):
    """Doubling one weight doubles that term exactly (a power of two) and leaves every other info
    value unchanged: weight setting, settings slot and info column are wired to the same term."""
    t = next(x for x in ET.REWARDS if x.name == term)
    base = dict(demand=[(0.0, 2.5)], initial_omega=1.6, **FAST)  # demand above omega: every term non-zero
    a = GearSpeedEnv(**base)
    b = GearSpeedEnv(**{**base, t.weight_name: 2.0 * t.default})
    a.reset(seed=1)
    b.reset(seed=1)
    seen = 0.0
    for k in range(6):
        act = np.array([1.0 if k % 2 else -1.0], np.float32)
        ia, ib = a.step(act)[4], b.step(act)[4]
        key = f"reward_{term}"
        assert ib[key] == 2.0 * ia[key]
        seen = max(seen, abs(ia[key]))
        for other in ia:
            if other not in (key, "episode_return"):
                assert ia[other] == ib[other], other
    assert seen > 0.0, f"reward_{term} stayed 0: no formula line for it?"


def test_every_entry_has_its_formula_line():
    """Each reward and cost term writes its column, each observation feature its column, in
    ``env_kernels.post_step`` (a term declared without a formula is caught here)."""
    src = inspect.getsource(EK.post_step.py_func)
    for t in ET.REWARDS:
        assert re.search(rf"I\[r, R\.{t.name}\] = ", src), t.name
        assert f"S[P.{t.weight_name}]" in src, t.weight_name
    for t in ET.COSTS:
        assert re.search(rf"I\[r, C\.{t.name}\] = ", src), t.name
    from gear_env.envs import env_core

    core_src = inspect.getsource(env_core.GearSpeedCore)
    for o in ET.OBSERVATIONS:
        if o.when is ET._full_state:
            continue  # the hidden state is copied in one loop from F.X_p on
        if o.name in ET.CORE_OBSERVATIONS:  # written by the environment's core around the kernel, once each
            assert len(re.findall(rf"(F\.{o.name}\]|c\[\"{o.name}\"\]\]) = ", core_src)) == 1, o.name
            continue
        assert re.search(rf"f\[F\.{o.name}\] = ", src), o.name
    for i in ET.INFOS:
        assert re.search(rf"I\[r, IX\.{i.name}\] = ", src), i.name
    for s in ET.all_settings():
        if s.kernel is not None:
            assert s.name in ET.P._fields


def test_observation_names_and_bounds_follow_the_table():
    for extra, n in (({}, 10), ({"demand": "steps"}, 11), ({"observation": "full"}, 20)):
        env = GearSpeedEnv(**FAST, **extra)
        entries = [o for o in ET.OBSERVATIONS if o.when is None or o.when(env.config)]
        assert env.observation_names == tuple(o.name for o in entries)
        assert len(env.observation_names) == n == env.observation_space.shape[0]
        np.testing.assert_array_equal(env.observation_space.low, np.array([o.low for o in entries], np.float32))
        np.testing.assert_array_equal(env.observation_space.high, np.array([o.high for o in entries], np.float32))
        venv = GearSpeedVectorEnv(2, **FAST, **extra)
        assert venv.observation_names == env.observation_names
    env = GearSpeedEnv(demand="steps", **FAST)
    obs, info = env.reset(seed=0)
    names = env.observation_names
    lo, hi = env.config.omega_min, env.config.omega_max
    assert obs[names.index("omega")] == np.float32(2 * (info["omega"] - lo) / (hi - lo) - 1)
    assert obs[names.index("contact_loss")] == np.float32(info["contact_loss"])


def test_docs_tables_are_generated_from_the_table():
    text = DOCS.read_text(encoding="utf-8")
    for which in ("settings", "rewards", "info", "observations"):
        assert f"<!-- table:GearSpeed-v0:{which} -->" in text
    assert ET.update_docs(text) == text, "run: python -m gear_env.envs.env_terms docs/ENVIRONMENT.md"
    # and a changed declaration changes the generated text
    assert "w_throughput" in V0.markdown("rewards") and "| omega |" in V0.markdown("observations")


def test_settings_vector_slots():
    cfg = GearSpeedConfig(w_chaos=0.25, max_domega=0.04, demand="ramp")
    S = V0.settings_vector(cfg)
    assert S.shape == (ET.N_SETTINGS,)
    assert S[ET.P.w_chaos] == 0.25 and S[ET.P.max_domega] == 0.04 and S[ET.P.demand] == 1.0
    assert V0.settings_vector(GearSpeedConfig())[ET.P.demand] == 0.0


def test_a_term_with_a_cost_is_declared_like_a_reward():
    """The derived names of a cost term (the shipped cost terms belong to every task, v0 included)."""
    c = ET.Term("overspeed", 0.5, "w_overspeed * max(0, omega - 2)", "time above omega = 2")
    assert c.weight_name == "w_overspeed"
    (w,) = c.settings()
    assert w.name == "w_overspeed" and w.default == 0.5 and w.kernel is float
    with pytest.raises(ValueError, match=r"X\.w_overspeed must be in \[0, 1e\+06\]"):
        w.check("X.w_overspeed", -1.0, None)
    assert V0.cost_keys == ("cost_nonperiodic", "cost_separation", "cost_impacts") and "cost" in V0.info_keys


def test_unknown_task_and_table_kind_are_refused():
    with pytest.raises(ValueError, match="task_id must be one of"):
        ET.task("GearSpeed-v9")
    with pytest.raises(ValueError, match="which must be"):
        V0.markdown("nope")


def test_clashing_or_unknown_names_are_refused(monkeypatch):
    ET._check_names()  # the shipped table is clean
    monkeypatch.setattr(ET, "REWARDS", (*ET.REWARDS, ET.Term("chaos", 1.0, "x", "a second chaos term")))
    with pytest.raises(ValueError, match=r"setting name\(s\) \['w_chaos'\] repeated"):
        ET._check_names()
    monkeypatch.setattr(ET, "REWARDS", (*ET.REWARDS[:-1], ET.Term("x", 1.0, "x", "x", tasks=("GearSpeed-v9",))))
    with pytest.raises(ValueError, match="unknown task"):
        ET._check_names()
