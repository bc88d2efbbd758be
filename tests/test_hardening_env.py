"""Hardening of the GearSpeed-v0 environment: hostile configurations, actions and schedule files
(property-based, hypothesis), extreme but valid physics, and cross-process reproducibility.

Each input either works or raises ``ValueError`` whose message names the culprit; no observation,
reward or info value is ever NaN or infinite. Example counts are fixed and ``derandomize=True``
makes every run draw the same examples (see docs/RELIABILITY.md for the counts)."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import gear_env  # noqa: F401  (registers GearSpeed-v0)
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig
from gear_env.envs.schedules import SpeedSchedule
from gear_env.envs.vector_env import GearSpeedVectorEnv

# cheap physics: a step is a few mesh periods at 16 Newmark steps
TINY = dict(periods_per_step=2, steps_per_period=16, warmup_periods=0, poincare_window=9)
FIELDS = [f for f in GearSpeedConfig.field_names() if f != "params"]
SETTINGS = dict(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])

hostile = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(2**70), 2**70),
    st.sampled_from([0, 1, -1, 16, 1024, 0.5, 1e-300, 1e300, float("nan"), float("inf"), -float("inf")]),
    st.sampled_from([True, False, None, "", "dynamic", "delta", "sensors", "steps", "1.0", b"x"]),
    st.sampled_from([np.float32(np.nan), np.int64(24), np.float64(1.5), np.bool_(True)]),
    st.lists(st.floats(0, 3), max_size=3).map(tuple),
    st.lists(st.tuples(st.floats(-1, 10), st.floats(-1, 4)), max_size=3),
)


def all_finite_info(info: dict) -> bool:
    return all(math.isfinite(float(v)) for v in info.values())


def check_step_output(space, obs, reward, info) -> None:
    assert np.all(np.isfinite(obs)) and space.contains(np.asarray(obs, np.float32)), obs
    assert math.isfinite(reward)
    assert all_finite_info(info), {k: v for k, v in info.items() if not math.isfinite(float(v))}


# ---------------------------------------------------------------------------------- configuration
@settings(max_examples=400, **SETTINGS)
@given(field=st.sampled_from(FIELDS), value=hostile)
def test_config_field_accepts_or_names_the_field(field, value):
    try:
        cfg = GearSpeedConfig.from_kwargs(**{field: value})
    except ValueError as exc:
        assert field in str(exc), (field, value, str(exc))
        return
    # accepted: the stored value is clean and survives the JSON round trip
    stored = getattr(cfg, field)
    for v in np.ravel(np.asarray(stored if stored is not None else 0.0, dtype=object)):
        if isinstance(v, (int, float)):
            assert math.isfinite(v), (field, value, stored)
    assert GearSpeedConfig.from_kwargs(json.loads(json.dumps(cfg.to_dict()))) == cfg


@settings(max_examples=60, **SETTINGS)
@given(key=st.text(min_size=1, max_size=12).filter(lambda k: k not in GearSpeedConfig.field_names()))
def test_unknown_keys_are_refused_by_name(key):
    with pytest.raises(ValueError, match="unknown GearSpeedConfig key") as exc:
        GearSpeedConfig.from_kwargs(**{key: 1})
    assert repr(key) in str(exc.value)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"bogus": 1}, "bogus"),
        ({"max_domega": float("nan")}, "max_domega"),
        ({"omega_max": float("inf")}, "omega_max"),
        # a narrow range refuses the default max_domega: the message names the setting the user changed too
        ({"omega_max": 0.125}, r"max_domega must be in \(0, 0.025\].*omega_max - omega_min = 0.125 - 0.1"),
        ({"omega_min": 2.99}, r"max_domega .*omega_max - omega_min = 3 - 2.99"),
        ({"steps_per_period": 64.0}, "steps_per_period"),
        ({"initial_omega": (2.0, 1.0)}, "initial_omega"),
        ({"demand": [(0, 1.0), (-1, 1.0)]}, "demand"),
        ({"params": {"kappa": float("nan")}}, "kappa"),
        ({"params": {"T_p": 0.0, "T_g": 0.0}}, "T_p"),  # unloaded mesh: forces / F_s would be inf
    ],
)
def test_gym_make_reports_bad_settings(kwargs, word):
    with pytest.raises(ValueError, match=word):
        gym.make("GearSpeed-v0", **kwargs)


@st.composite
def valid_configs(draw):
    lo = draw(st.floats(0.05, 2.0))
    hi = draw(st.floats(lo + 0.1, min(lo + 3.0, 20.0)))
    return dict(
        model=draw(st.sampled_from(["dynamic", "constant"])),
        steps_per_period=draw(st.sampled_from([16, 24, 32])),
        periods_per_step=draw(st.integers(1, 4)),
        poincare_window=draw(st.integers(9, 12)),
        warmup_periods=draw(st.integers(0, 8)),
        omega_min=lo,
        omega_max=hi,
        max_domega=draw(st.floats(1e-6, 1.0)) * (hi - lo),
        action_mode=draw(st.sampled_from(["delta", "target"])),
        observation=draw(st.sampled_from(["sensors", "full"])),
        demand=draw(st.sampled_from([None, "steps", "ramp", [(0.0, lo), (2.0, hi)]])),
        randomize_params=draw(st.booleans()),
        randomize_scale=draw(st.floats(0.0, 0.5)),
        max_steps=draw(st.integers(1, 4)),
        w_chaos=draw(st.floats(0.0, 1e6)),
        divergence_penalty=draw(st.floats(0.0, 1e6)),
    )


@settings(max_examples=40, **SETTINGS)
@given(kw=valid_configs(), seed=st.integers(0, 2**31 - 1), actions=st.lists(st.floats(-1.5, 1.5), min_size=4))
def test_valid_configs_run_with_finite_outputs(kw, seed, actions):
    env = gym.make("GearSpeed-v0", **kw).unwrapped
    obs, info = env.reset(seed=seed)
    check_step_output(env.observation_space, obs, 0.0, info)
    cfg = env.config
    for a in actions[:4]:
        w_before = env.omega
        obs, r, te, tr, info = env.step(np.array([a], np.float32))
        check_step_output(env.observation_space, obs, r, info)
        assert cfg.omega_min <= env.omega <= cfg.omega_max
        # the change is at most max_domega, up to the rounding of omega itself (a few ulps of omega)
        assert abs(env.omega - w_before) <= cfg.max_domega * (1 + 1e-12) + 8 * np.spacing(max(abs(w_before), 1.0))
        if te:
            assert info["diverged"] and r == -cfg.divergence_penalty
        if te or tr:
            break


# ---------------------------------------------------------------------------------- actions
def action_is_valid(action, n: int | None) -> bool:
    """Independent oracle of what ``check_action`` must accept."""
    if np.iscomplexobj(action):
        return False
    try:
        raw = np.asarray(action)
        if raw.dtype.kind in "SUVb" or (
            raw.dtype.kind == "O" and any(isinstance(x, (str, bytes, bool, np.bool_)) for x in raw.flat)
        ):
            return False  # text is refused, also when it spells a number, and bools (issue 25)
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    shapes = [(1,), ()] if n is None else [(n, 1), (n,)]
    return a.shape in shapes and bool(np.all(np.isfinite(a)))


def actions(n: int):
    """Hostile actions for ``n`` envs (n = 0: single env)."""
    m = max(n, 1)
    shapes = st.sampled_from([(), (1,), (m,), (m, 1), (1, m), (m, 2), (0,), (2,), (m + 1, 1)])
    dtypes = st.sampled_from([np.float16, np.float32, np.float64, np.int8, np.int64, np.bool_])
    weird = st.floats(allow_nan=True, allow_infinity=True, width=64)

    def build(shape, dtype, vals):
        a = np.resize(np.asarray(vals, np.float64), shape)
        if np.dtype(dtype).kind != "f" and not np.all(np.isfinite(a)):
            return a  # NaN/inf have no integer form
        with np.errstate(over="ignore", invalid="ignore"):
            return a.astype(dtype)

    arrays = st.builds(build, shapes, dtypes, st.lists(weird, min_size=1, max_size=3))
    return st.one_of(
        arrays,
        weird,  # python floats
        st.sampled_from([1e300, -1e300, 0, True, None, "0.1", "x", 1 + 2j, np.array([1 + 0j]), [[0.1]]]),
        st.lists(weird, min_size=0, max_size=m + 1),
    )


@pytest.fixture(scope="module")
def single_env():
    env = GearSpeedEnv(max_steps=10**6, **TINY)
    env.reset(seed=0, options={"omega": 1.0})
    return env


@settings(max_examples=150, **SETTINGS)
@given(action=actions(0))
def test_single_env_actions(single_env, action):
    env = single_env
    w0 = env.omega
    valid = action_is_valid(action, None)
    try:
        obs, r, te, tr, info = env.step(action)
    except ValueError as exc:
        assert not valid, (action, exc)
        assert "action" in str(exc)
        assert env.omega == w0  # a refused action changes nothing
        return
    assert valid, action
    check_step_output(env.observation_space, obs, r, info)
    # the applied change is the clipped action times max_domega (delta mode)
    a = float(np.clip(np.asarray(action, np.float64).reshape(-1)[0], -1, 1))
    expected = min(max(w0 + a * env.config.max_domega, env.config.omega_min), env.config.omega_max)
    assert env.omega == pytest.approx(expected, abs=1e-12)
    if te or tr:
        env.reset(seed=1, options={"omega": 1.0})


N_VEC = 3


@pytest.fixture(scope="module")
def vector_env():
    venv = GearSpeedVectorEnv(N_VEC, max_steps=10**6, **TINY)
    venv.reset(seed=0, options={"omega": 1.0})
    return venv


@settings(max_examples=100, **SETTINGS)
@given(action=actions(N_VEC))
def test_vector_env_actions(vector_env, action):
    venv = vector_env
    valid = action_is_valid(action, N_VEC)
    try:
        obs, r, te, tr, info = venv.step(action)
    except ValueError as exc:
        assert not valid, (action, exc)
        assert "action" in str(exc)
        return
    assert valid, action
    assert np.all(np.isfinite(obs)) and venv.observation_space.contains(obs)
    assert np.all(np.isfinite(r))
    assert all(np.all(np.isfinite(np.asarray(v, float))) for k, v in info.items())


@pytest.fixture(scope="module")
def sb3_env():
    from gear_env.envs.sb3_adapter import SB3VecEnvAdapter

    venv = SB3VecEnvAdapter(N_VEC, seed=0, max_steps=10**6, **TINY)
    venv.reset()
    return venv


@settings(max_examples=60, **SETTINGS)
@given(action=actions(N_VEC))
def test_sb3_adapter_actions(sb3_env, action):
    venv = sb3_env
    a = np.asarray(action) if not isinstance(action, np.ndarray) else action
    # SB3 hands step_async an array; the adapter accepts any array of num_envs finite numbers
    valid = action_is_valid(a.reshape(-1, 1) if a.size == N_VEC else a, N_VEC)
    try:
        venv.step_async(a)
        obs, r, dones, infos = venv.step_wait()
    except ValueError as exc:
        assert not valid, (action, exc)
        assert "action" in str(exc)
        return
    assert valid, action
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(r))
    for d in infos:
        assert all(math.isfinite(float(v)) for k, v in d.items() if k not in ("terminal_observation", "episode"))


@pytest.mark.parametrize("options", [{"omega": "x"}, {"omega": [1.0]}, {"omega": float("nan")}, {"omega": True}])
def test_reset_option_omega_is_named(options):
    env = GearSpeedEnv(**TINY)
    with pytest.raises(ValueError, match="omega"):
        env.reset(seed=0, options=options)


@pytest.mark.parametrize("seed", [True, 1.5, "ab", [1, 2]])
def test_vector_seed_errors_name_the_seed(seed):
    venv = GearSpeedVectorEnv(N_VEC, **TINY)
    with pytest.raises(ValueError, match="seed"):
        venv.reset(seed=seed)


# ---------------------------------------------------------------------------------- schedule files
GOOD_T = st.floats(0, 500, allow_nan=False).map(lambda x: round(x, 3))
GOOD_W = st.floats(0.1, 3.0).map(lambda x: round(x, 4))
BAD_CELLS = ["1.2.3", "--1", "nan", "inf", "-inf", "1e999", "-5", "7.5"]  # no letters-only cells: see _is_header


def cell_value(c: str) -> float | None:
    try:
        v = float(c)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def first_problem(rows: list[tuple[str, str]]) -> int | None:
    """Index of the first invalid row (None if the schedule is valid); independent of the loader."""
    if not rows:
        return -1
    prev = -math.inf
    for i, (tc, wc) in enumerate(rows):
        t, w = cell_value(tc), cell_value(wc)
        if t is None or w is None or t < 0 or t < prev or not 0.1 <= w <= 3.0:
            return i
        prev = t
    return None


row_st = st.tuples(
    st.one_of(GOOD_T.map(repr), st.sampled_from(BAD_CELLS)), st.one_of(GOOD_W.map(repr), st.sampled_from(BAD_CELLS))
)


@settings(max_examples=150, **SETTINGS)
@given(
    rows=st.one_of(st.lists(st.tuples(GOOD_T.map(repr), GOOD_W.map(repr)), max_size=6), st.lists(row_st, max_size=6)),
    sort=st.booleans(),
    header=st.booleans(),
    bom=st.booleans(),
    pad=st.sampled_from(["", " ", "\t", "  "]),
    crlf=st.booleans(),
    comments=st.booleans(),
)
def test_csv_schedule_files(tmp_path_factory, rows, sort, header, bom, pad, crlf, comments):
    if sort:
        rows = sorted(rows, key=lambda r: cell_value(r[0]) or 0.0)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\r\n" if crlf else "\n")
    lines = []
    if header:
        writer.writerow(["time", "omega"])
        lines.append(None)
    if comments:
        writer.writerow(["# written by a hostile user"])
        lines.append(None)
    for tc, wc in rows:
        writer.writerow([pad + tc + pad, pad + wc])
        lines.append((tc, wc))
    path = tmp_path_factory.mktemp("csv") / "sched.csv"
    path.write_text(("\ufeff" if bom else "") + buf.getvalue(), encoding="utf-8", newline="")
    bad = first_problem(rows)
    try:
        s = SpeedSchedule.from_file(path)
    except ValueError as exc:
        msg = str(exc)
        assert bad is not None, (rows, msg)
        assert "sched.csv" in msg
        if bad >= 0:
            lineno = [i for i, x in enumerate(lines) if x is not None][bad] + 1
            assert f"row {lineno}:" in msg, (rows, msg)
        else:
            assert "empty" in msg
        return
    assert bad is None, (rows, s.points)
    np.testing.assert_array_equal(s.points, [[float(t), float(w)] for t, w in rows])
    assert np.all(np.isfinite(s.omega_at(np.linspace(-5, 600, 50))))


json_value = st.one_of(
    GOOD_T, GOOD_W, st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(["x", "1.0", None, True, [1]])
)


@settings(max_examples=150, **SETTINGS)
@given(
    points=st.one_of(
        st.lists(st.tuples(GOOD_T, GOOD_W).map(list), max_size=6),
        st.lists(st.lists(json_value, min_size=1, max_size=3), max_size=5),
    ),
    layout=st.sampled_from(["list", "points", "columns"]),
    bom=st.booleans(),
)
def test_json_schedule_files(tmp_path_factory, points, layout, bom):
    if layout == "points":
        data: object = {"points": points}
    elif layout == "columns":
        data = {"time": [p[0] for p in points], "omega": [p[-1] for p in points]}
        points = [[p[0], p[-1]] for p in points]
    else:
        data = points
    path = tmp_path_factory.mktemp("json") / "sched.json"
    path.write_text(("\ufeff" if bom else "") + json.dumps(data), encoding="utf-8")

    def num(v):  # numbers, or strings holding one (the loader accepts "1.0" like a CSV cell)
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            return None
        return cell_value(v) if isinstance(v, str) else (float(v) if math.isfinite(v) else None)

    def ok(v):
        return num(v) is not None

    bad: int | None = -1 if not points else None
    prev = -math.inf
    for i, p in enumerate(points):
        if bad is not None:
            break
        if len(p) != 2 or not ok(p[0]) or not ok(p[1]) or num(p[0]) < 0 or num(p[0]) < prev:
            bad = i
        elif not 0.1 <= num(p[1]) <= 3.0:
            bad = i
        else:
            prev = num(p[0])
    try:
        s = SpeedSchedule.from_file(path)
    except ValueError as exc:
        msg = str(exc)
        assert bad is not None, (points, msg)
        assert "sched.json" in msg
        assert f"point {bad}:" in msg if bad >= 0 else "empty" in msg, msg
        return
    assert bad is None, (points, s.points)
    np.testing.assert_array_equal(s.points, [[num(t), num(w)] for t, w in points])


@pytest.mark.parametrize(
    "content, word",
    [
        (b"\xff\xfe0\x00,\x001\x00", "not UTF-8"),  # UTF-16 from a spreadsheet
        (b"\x00\x01\x02binary", "empty"),  # taken for a header row, then nothing is left
        (b"time;omega\n0;1\n", "row 2"),  # wrong delimiter
        (b"omega,time\n1.0,0\n", "row 2"),  # swapped columns: omega 0 out of range
        (b"time\n0\n", "row 2"),  # missing column
    ],
)
def test_odd_csv_files_name_file_and_row(tmp_path, content, word):
    p = tmp_path / "odd.csv"
    p.write_bytes(content)
    with pytest.raises(ValueError, match=word) as exc:
        SpeedSchedule.from_file(p)
    assert "odd.csv" in str(exc.value)


def test_huge_schedule_files_load(tmp_path):
    t = np.arange(100_000)
    w = 1.0 + 0.5 * np.sin(t / 300.0)
    p = tmp_path / "big.csv"
    p.write_text("time,omega\n" + "".join(f"{a},{b!r}\n" for a, b in zip(t.tolist(), w.tolist())))
    s = SpeedSchedule.from_file(p)
    np.testing.assert_array_equal(s.points[:, 1], w)
    pj = tmp_path / "big.json"
    pj.write_text(json.dumps({"time": t.tolist(), "omega": w.tolist()}))
    np.testing.assert_array_equal(SpeedSchedule.from_file(pj).points, s.points)


def test_config_json_with_byte_order_mark(tmp_path):
    p = tmp_path / "cfg.json"
    p.write_text("\ufeff" + json.dumps({"max_steps": 7}), encoding="utf-8")
    assert GearSpeedConfig.from_json(str(p)).max_steps == 7
    p.write_bytes(b"\xff\xfe{\x00}\x00")
    with pytest.raises(ValueError, match="cfg.json"):
        GearSpeedConfig.from_json(str(p))


# ---------------------------------------------------------------------------------- extremes
EXTREME_PARAMS = {
    "undamped": dict(xi_m=0.0, xi_p=0.0, xi_g=0.0),
    "overdamped": dict(xi_m=9.99, xi_p=9.99, xi_g=9.99),
    "stiff bearings": dict(k_p=1e14, k_g=1e14),
    "soft bearings": dict(k_p=1.0, k_g=1.0),
    "large transmission error": dict(e_m1=1e-2),
    "strong stiffness modulation": dict(kappa=0.99),
    "light pinion and gear": dict(m_p=1e-6, m_g=1e-6),
    "tiny torque": dict(T_p=1e-3, T_g=1.36e-3),
    "huge torque": dict(T_p=7.3e6, T_g=1e7),
    "undamped and modulated": dict(xi_m=0.0, xi_p=0.0, xi_g=0.0, kappa=0.95, e_m1=5e-4),
}


@settings(max_examples=60, **SETTINGS)
@given(
    name=st.sampled_from(sorted(EXTREME_PARAMS)),
    steps=st.sampled_from([16, 1024]),
    omega=st.sampled_from([0.1, 3.0, 0.3, 1.5]),
    model=st.sampled_from(["dynamic", "constant"]),
    action=st.sampled_from([-1.0, 0.0, 1.0]),
)
def test_extreme_parameters_finite_or_clean_termination(name, steps, omega, model, action):
    env = GearSpeedEnv(params=EXTREME_PARAMS[name], model=model, max_steps=4, **{**TINY, "steps_per_period": steps})
    obs, info = env.reset(seed=0, options={"omega": omega})
    check_step_output(env.observation_space, obs, 0.0, info)
    for _ in range(4):
        obs, r, te, tr, info = env.step(np.array([action]))
        check_step_output(env.observation_space, obs, r, info)
        assert np.all(np.isfinite(env.state))
        if info["diverged"]:
            assert te and not tr and r == -env.config.divergence_penalty == info["reward_divergence"]
        if te or tr:
            break


def test_vector_env_keeps_running_the_sub_envs_that_do_not_diverge():
    """Four sub-envs with the undamped, strongly modulated pair: at omega 0.3 and 1.5 they blow up,
    at 0.1 and 1.0 they do not. The diverged ones terminate with the penalty and auto-reset; the
    others run on bit-identical to single envs."""
    kw = dict(params=EXTREME_PARAMS["undamped and modulated"], max_steps=6, periods_per_step=8, warmup_periods=16)
    kw["steps_per_period"] = 16
    omegas = [0.1, 0.3, 1.0, 1.5]
    venv = GearSpeedVectorEnv(len(omegas), **kw)
    venv.reset(seed=5)
    for i, w in enumerate(omegas):
        obs, info = venv.reset(options={"omega": w, "reset_mask": np.arange(len(omegas)) == i})
    singles = [GearSpeedEnv(**kw) for _ in omegas]
    s_obs = [e.reset(seed=100 + i, options={"omega": w})[0] for i, (e, w) in enumerate(zip(singles, omegas))]
    np.testing.assert_array_equal(obs, np.stack(s_obs))
    diverged_seen = np.zeros(len(omegas), bool)
    alive = np.ones(len(omegas), bool)
    for _ in range(6):
        obs, r, te, tr, info = venv.step(np.zeros((len(omegas), 1)))
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(r)) and venv.observation_space.contains(obs)
        assert all(np.all(np.isfinite(np.asarray(v, float))) for v in info.values())
        stepped = info["step"] > 0  # the others were auto-reset in this call (reward 0; a warm-up may diverge)
        d = info["diverged"] & stepped
        assert np.array_equal(te, d) and np.all(r[d] == -venv.config.divergence_penalty)
        assert np.all(r[~stepped] == 0.0)
        diverged_seen |= d
        for i in np.flatnonzero(alive):
            o1, r1, te1, tr1, i1 = singles[i].step(np.zeros(1))
            np.testing.assert_array_equal(obs[i], o1)
            assert r[i] == r1 and te[i] == te1 and tr[i] == tr1
            if te1 or tr1:
                alive[i] = False
    assert diverged_seen.tolist() == [False, True, False, True]
    assert not te[[0, 2]].any() and tr[[0, 2]].all()  # the others ran to the time limit


# ---------------------------------------------------------------------------------- reproducibility
ROLLOUT = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    from gear_env.envs.env import GearSpeedEnv
    from gear_env.envs.vector_env import GearSpeedVectorEnv

    def rollout():
        kw = dict(max_steps=5, periods_per_step=6, warmup_periods=12, randomize_params=True)
        env = GearSpeedEnv(**kw)
        out = []
        obs, info = env.reset(seed=11)
        out.append([obs.tolist(), info])
        acts = np.random.default_rng(3).uniform(-1, 1, (8, 1))
        for a in acts:
            obs, r, te, tr, info = env.step(a)
            out.append([obs.tolist(), r, te, tr, info])
            if te or tr:
                obs, info = env.reset()
                out.append([obs.tolist(), info])
        venv = GearSpeedVectorEnv(3, **kw)
        obs, _ = venv.reset(seed=11)
        out.append(obs.tolist())
        for a in acts:
            obs, r, te, tr, _ = venv.step(np.repeat(a[None], 3, axis=0))
            out.append([obs.tolist(), r.tolist(), te.tolist(), tr.tolist()])
        return out

    if __name__ == "__main__":
        print(json.dumps(rollout()))
    """
)


def test_same_seed_same_numbers_in_another_process(tmp_path):
    """A rollout (single env and vector env, randomised parameters, auto-resets) in a fresh
    interpreter equals the same rollout in this process bit for bit (JSON floats round-trip exactly)."""
    script = tmp_path / "rollout.py"
    script.write_text(ROLLOUT)
    proc = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, env={**os.environ}
    )
    assert proc.returncode == 0, proc.stderr
    ns: dict = {}
    exec(compile(ROLLOUT, str(script), "exec"), ns)
    here = json.loads(json.dumps(ns["rollout"]()))
    assert json.loads(proc.stdout) == here
