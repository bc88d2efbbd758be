"""The Fox-Goodwin tasks (GearSpeed-v2, GearSpeedDemand-v1, ...): the older task with Newmark beta 1/12 and the
velocity correction.

A new id is the older id plus ``scheme="fox-goodwin-vc"``: its config equals the older one's with that scheme, an
episode equals one of the older id made with that scheme (bit for bit), the ``scheme`` setting wins over the beta
of whatever pair a user passes, and the shipped policy and recipe of the older id serve the new one.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gear_env  # noqa: F401  (registers the tasks)
from gear_env import GearSimulator
from gear_env.envs.env_config import task_config
from gear_env.envs.tasks import FOX_GOODWIN_TASKS, TASK_SETTINGS, base_task
from gear_env.sim.integration import CONTACT_STEPS, contact_steps
from gear_env.sim.params import FOX_GOODWIN_BETA, NEWMARK_BETA, GearParams
from gear_env.sim.reference import reference_poincare

SHORT = {"max_steps": 4, "periods_per_step": 8, "warmup_periods": 16}


@pytest.mark.parametrize("new, old", sorted(FOX_GOODWIN_TASKS.items()))
def test_new_id_is_the_older_task_with_fox_goodwin(new, old):
    assert new in TASK_SETTINGS and gym.spec(new).max_episode_steps == gym.spec(old).max_episode_steps
    a, b = task_config(new), task_config(old)
    assert a.scheme == "fox-goodwin-vc" and b.scheme is None
    assert a.steps_per_period == b.steps_per_period == 64
    assert a.params.newmark_beta == FOX_GOODWIN_BETA and b.params.newmark_beta == NEWMARK_BETA
    assert a.params.velocity_correction and not b.params.velocity_correction
    assert a.params == b.params.replace(newmark_beta=FOX_GOODWIN_BETA, velocity_correction=True)
    differ = [k for k in a.field_names() if k not in ("scheme", "params") and getattr(a, k) != getattr(b, k)]
    assert differ == []
    assert base_task(new) == old and base_task(old) == old


@pytest.mark.parametrize("new, old", sorted(FOX_GOODWIN_TASKS.items()))
def test_a_fox_goodwin_episode_equals_the_older_id_with_beta_one_twelfth_and_the_correction(new, old):
    env_a = gym.make(new, **SHORT)
    env_b = gym.make(old, params={"newmark_beta": 1 / 12, "velocity_correction": True}, **SHORT)
    env_c = gym.make(old, **SHORT)
    oa, _ = env_a.reset(seed=11)
    ob, _ = env_b.reset(seed=11)
    oc, _ = env_c.reset(seed=11)
    assert np.array_equal(oa, ob)
    moved = not np.array_equal(oa, oc)
    for k in range(SHORT["max_steps"]):
        act = np.array([0.4 - 0.2 * k], np.float32)
        ra, rb, rc = env_a.step(act), env_b.step(act), env_c.step(act)
        assert np.array_equal(ra[0], rb[0]) and ra[1] == rb[1]
        moved = moved or not np.array_equal(ra[0], rc[0])
    assert moved  # the scheme changes the dynamics (why the id is new)


def test_the_scheme_wins_over_the_beta_of_a_passed_pair():
    kappa = 0.5 * GearParams().kappa
    for params in ({"kappa": kappa}, GearParams(kappa=kappa), GearParams(kappa=kappa, newmark_beta=0.2)):
        cfg = gym.make("GearSpeed-v2", params=params).unwrapped.config
        assert cfg.params.newmark_beta == FOX_GOODWIN_BETA and cfg.params.kappa == kappa
    assert gym.make("GearSpeed-v2", scheme="paper").unwrapped.config.params.newmark_beta == NEWMARK_BETA
    cfg = gym.make("GearSpeed-v2", scheme=None, params={"newmark_beta": 0.2}).unwrapped.config
    assert cfg.params.newmark_beta == 0.2
    cfg = gym.make("GearSpeed-v1", scheme="fox-goodwin-vc").unwrapped.config
    assert cfg == task_config("GearSpeed-v2")
    # the round trip through a dict (a run folder's config.json) keeps the scheme
    assert type(cfg).from_kwargs(cfg.to_dict()) == cfg


@pytest.mark.parametrize("bad", ["fox_goodwin", "Paper", 1, True])
def test_a_bad_scheme_is_refused_naming_the_field_and_the_choices(bad):
    with pytest.raises(ValueError, match=r"scheme must be None or one of \['paper', 'fox-goodwin', 'fox-goodwin-vc'\]"):
        task_config("GearSpeed-v2", {"scheme": bad})


def test_a_params_dict_naming_another_beta_than_the_scheme_is_refused():
    """A config file's params.newmark_beta on a Fox-Goodwin id would otherwise be dropped without a word."""
    for beta in (0.25, 1 / 6):
        with pytest.raises(ValueError, match=r"params.newmark_beta = .* conflicts with scheme='fox-goodwin-vc'"):
            task_config("GearSpeedDemand-v1", {"params": {"newmark_beta": beta}})
    # the same beta as the scheme's, the scheme changed with it, or no scheme: accepted
    assert task_config("GearSpeedDemand-v1", {"params": {"newmark_beta": 0.0833333}}).params.newmark_beta == 1 / 12
    cfg = task_config("GearSpeedDemand-v1", {"params": {"newmark_beta": 0.25}, "scheme": "paper"})
    assert cfg.params.newmark_beta == 0.25
    assert (
        task_config("GearSpeedDemand-v1", {"params": {"newmark_beta": 0.2}, "scheme": None}).params.newmark_beta == 0.2
    )
    # a config's own dict round-trips, and a changed scheme is taken over a GearParams (documented)
    cfg = task_config("GearSpeedDemand-v1")
    assert type(cfg).from_kwargs(cfg.to_dict()) == cfg
    assert cfg.replace(scheme="paper").params.newmark_beta == 0.25


def test_tol_on_a_fox_goodwin_task_names_the_scheme():
    with pytest.raises(ValueError, match=r"tol .*scheme='fox-goodwin-vc'.*scheme=\"paper\""):
        task_config("GearSpeedDemand-v1", {"tol": 1e-3})
    assert task_config("GearSpeedDemand-v1", {"tol": 1e-3, "scheme": "paper"}).tol == 1e-3


def test_the_vector_env_of_a_new_id_matches_its_single_env():
    venv = gym.make_vec("GearSpeed-v2", num_envs=2, vectorization_mode="vector_entry_point", **SHORT)
    env = gym.make("GearSpeed-v2", **SHORT)
    ov, _ = venv.reset(seed=[5, 6])
    os_, _ = env.reset(seed=5)
    assert np.array_equal(ov[0], os_)
    for k in range(3):
        a = np.full((2, 1), 0.3 * (-1) ** k, np.float32)
        rv = venv.step(a)
        rs = env.step(a[0])
        assert np.array_equal(rv[0][0], rs[0]) and rv[1][0] == rs[1]


def test_the_older_ids_recipe_and_policy_serve_the_new_id():
    from pathlib import Path

    import yaml

    import agents
    from agents.envs import GEAR_ENV_IDS
    from agents.registry import pretrained_dir

    assert set(GEAR_ENV_IDS) == set(TASK_SETTINGS)
    conf = yaml.safe_load((Path(agents.__file__).parent / "hyperparams" / "ppo.yml").read_text())
    for new, old in FOX_GOODWIN_TASKS.items():
        assert conf[new] == conf[old]
        assert pretrained_dir(new) == pretrained_dir(old)


def test_the_shipped_policy_runs_on_a_new_id():
    pytest.importorskip("torch")
    from agents.registry import resolve_policy

    cfg = task_config("GearSpeedDemand-v1", SHORT)
    pol = resolve_policy("pretrained", cfg, env_id="GearSpeedDemand-v1")
    env = gym.make("GearSpeedDemand-v1", **SHORT)
    obs, _ = env.reset(seed=0)
    a = np.asarray(pol.predict(obs, deterministic=True)[0], np.float32).reshape(1)
    assert np.all(np.abs(a) <= 1.0) and np.isfinite(env.step(a)[1])


def test_auto_steps_with_the_papers_beta_are_64_bit_for_bit():
    """steps_per_period="auto" with the paper's beta is 64 fixed steps: GearSpeed-v2 with scheme="paper" is v1."""
    a = gym.make("GearSpeed-v2", scheme="paper", steps_per_period="auto", **SHORT)
    b = gym.make("GearSpeed-v1", **SHORT)
    oa, _ = a.reset(seed=4)
    ob, _ = b.reset(seed=4)
    assert np.array_equal(oa, ob)
    for k in range(SHORT["max_steps"]):
        act = np.array([0.5 - 0.3 * k], np.float32)
        ra, rb = a.step(act), b.step(act)
        assert np.array_equal(ra[0], rb[0]) and ra[1] == rb[1]
    assert set(a.unwrapped._core.n_steps.tolist()) == {64}


def test_contact_steps_classes_and_bad_steps_refused():
    assert [contact_steps(f) for f in (0.0, 0.2, 0.2000001, 0.5, 0.51, 1.0, float("nan"))] == [
        48,
        48,
        64,
        64,
        80,
        80,
        80,
    ]
    assert contact_steps(np.array([0.1, 0.3, 0.9])).tolist() == list(CONTACT_STEPS)
    # not periodic: at most the tasks' 64 (the rule is calibrated on period-1 orbits)
    assert [contact_steps(f, False) for f in (0.1, 0.3, 0.9)] == [48, 64, 64]
    assert contact_steps(np.array([0.1, 0.9, 0.9]), np.array([False, False, True])).tolist() == [48, 64, 80]
    # kinks corrected (correct_kinks): the third class is 64
    assert [contact_steps(f, corrected=True) for f in (0.0, 0.2, 0.21, 0.9, float("nan"))] == [32, 32, 64, 64, 64]
    assert contact_steps(np.array([0.1, 0.3, 0.9]), True, corrected=True).tolist() == [32, 64, 64]
    for bad in ("Auto", 15, 1025, 64.0, True):
        with pytest.raises(ValueError, match=r'steps_per_period must be an integer in \[16, 1024\] or "auto"'):
            task_config("GearSpeed-v2", {"steps_per_period": bad})


def test_auto_steps_vector_env_with_mixed_counts_matches_the_single_envs():
    """Sub-environments at different speeds take different step counts in one vector step (one SIMD call, each lane
    at its own count); each row's count depends only on its own past, so every row equals a single env bit for
    bit."""
    n = 6
    kw = dict(SHORT, max_steps=5, action_mode="target", initial_omega=None)
    kw["steps_per_period"] = "auto"
    venv = gym.make_vec("GearSpeed-v2", num_envs=n, vectorization_mode="vector_entry_point", **kw)
    seeds = list(range(20, 20 + n))
    ov, _ = venv.reset(seed=seeds)
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (kw["max_steps"], n, 1)).astype(np.float32)
    seen = set()
    outs = []
    for t in range(kw["max_steps"]):
        seen |= set(venv.unwrapped._core.n_steps.tolist())
        outs.append(venv.step(acts[t]))
    assert len(seen) >= 2, seen  # the grouped path ran
    for i, sd in enumerate(seeds):
        env = gym.make("GearSpeed-v2", **kw)
        o, _ = env.reset(seed=sd)
        assert np.array_equal(o, ov[i])
        for t in range(kw["max_steps"]):
            r = env.step(acts[t, i])
            assert np.array_equal(r[0], outs[t][0][i]) and r[1] == outs[t][1][i], (i, t)


@pytest.mark.parametrize("omega, model", [(1.49, "dynamic"), (1.42, "constant")])
def test_contact_steps_bring_the_orbits_64_steps_miss_within_1e_3(omega, model):
    """On the period-1 orbits where 64 Fox-Goodwin steps err by more than 1e-3 b0 against the event-located
    reference, the teeth are apart most of the time, the rule takes 80 steps and the error is below 1e-3."""
    fg = GearParams(newmark_beta=FOX_GOODWIN_BETA)
    start = GearSimulator(GearParams(), model, 512, omega)
    start.advance(300)
    x0 = start.state
    ref = reference_poincare(omega, model, None, 0, 10, initial_state=x0).states
    sim = GearSimulator(fg, model, 64, omega, x0)
    iv = sim.advance(10)
    err = {64: float(np.max(np.abs(iv.poincare[:, :10] - ref)))}
    sep = iv.separation_fraction
    n = contact_steps(sep)
    err[n] = float(np.max(np.abs(GearSimulator(fg, model, n, omega, x0).advance(10).poincare[:, :10] - ref)))
    assert n == 80 and err[64] > 1e-3 and err[80] < 1e-3, (sep, err)


def _demand_protocol():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from demand_protocol import main

    return main


def test_demand_protocol_refuses_before_any_rollout(capsys):
    """--against-base needs a Fox-Goodwin id; a task without a shipped policy is refused before any rollout
    when the default policies include it (it failed after five rollouts)."""
    main = _demand_protocol()
    with pytest.raises(ValueError, match="no pretrained policy is shipped for 'GearSpeedDemandLimit-v1'"):
        main(["--env", "GearSpeedDemandLimit-v1", "--set", "seeds:800000-800001"])
    with pytest.raises(SystemExit):
        main(["--env", "GearSpeedDemand-v0", "--set", "seeds:800000-800001", "--against-base"])
    assert "--against-base compares" in capsys.readouterr().err


@pytest.mark.slow
def test_demand_protocol_against_base_pairs_the_new_id_with_the_older(capsys):
    """demand_protocol --against-base: the change table pairs each policy on a Fox-Goodwin id with the same
    policy on the older id (about a minute with an empty map cache: the oracle's maps of both schemes)."""
    main = _demand_protocol()
    argv = ["--env", "GearSpeedDemand-v1", "--set", "seeds:800000-800001", "--policy", "sensor-servo"]
    assert main([*argv, "--reference", "sensor-servo", "--against-base"]) == 0
    out = capsys.readouterr().out
    assert "| policy | return, GearSpeedDemand-v0 | return, GearSpeedDemand-v1 | paired change" in out
    assert "| sensor-servo |" in out


def test_scheme_none_stays_out_of_the_config_dict():
    """Run folders written before the setting existed have no "scheme": their configs still compare equal (a
    --resume check), and an older id's config file carries no scheme null over a Fox-Goodwin id's scheme."""
    d = task_config("GearSpeedDemand-v0").to_dict()
    assert "scheme" not in d
    assert type(task_config("GearSpeedDemand-v0")).from_kwargs(d) == task_config("GearSpeedDemand-v0")
    assert task_config("GearSpeedDemand-v1").to_dict()["scheme"] == "fox-goodwin-vc"
    assert task_config("GearSpeedDemand-v1", d).params.newmark_beta == FOX_GOODWIN_BETA


def test_auto_steps_survive_an_empty_reset_mask_and_keep_64_below_the_stable_omega(monkeypatch):
    from gear_env.envs.env_core import GearSpeedCore

    kw = dict(SHORT, steps_per_period="auto", action_mode="target")
    venv = gym.make_vec("GearSpeed-v2", num_envs=2, vectorization_mode="vector_entry_point", **kw)
    venv.reset(seed=[1, 2])
    venv.reset(options={"reset_mask": np.zeros(2, bool)})  # no rows: nothing to integrate
    seen = []
    real = GearSpeedCore._integrate_n

    def spy(self, rows, w0, w1, periods, nsp):
        seen.append((float(np.min(np.minimum(w0, w1))) if len(rows) else 9.0, nsp))
        return real(self, rows, w0, w1, periods, nsp)

    monkeypatch.setattr(GearSpeedCore, "_integrate_n", spy)
    env = gym.make("GearSpeed-v2", initial_omega=0.12, **kw)
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.array([-1.0], np.float32))  # stay at the bottom of the range, where 48 steps are unstable
    floor48 = env.unwrapped._core.w_floor[0] / 48
    assert env.unwrapped._core.n_steps[0] == 48  # the rule asks for 48 (little contact loss) ...
    assert floor48 > 0.12 and seen and all(n >= 64 for w, n in seen if w < floor48), seen  # ... 64 are taken
