"""Issue 25, second probe: the holes an independent hostile probe found after the first fixes.

Each test fails on the code before its fix (see docs/RELIABILITY.md, "second probe")."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from gear_env.cli import main as cli
from gear_env.io import atomic_write_text, check_outputs, hold_outputs

ROOT = Path(__file__).resolve().parents[1]
KEEP = '{"keep": true}'


def test_steady_map_command_refuses_an_alias_in_one_line(tmp_path, capsys):
    from gear_env.cli.steady import main

    (tmp_path / "a.json").write_text(KEEP)
    os.symlink(tmp_path / "a.json", tmp_path / "l.png")
    rc = main(["--json", str(tmp_path / "a.json"), "--plot", str(tmp_path / "l.png")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "same file" in err[0]
    assert (tmp_path / "a.json").read_text() == KEEP


@pytest.mark.parametrize("argv", [["--step", "0"], ["--steps-per-period", "4"], ["--models", "x"]])
def test_steady_map_command_checks_its_numbers(argv, capsys):
    from gear_env.cli.steady import main

    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and argv[0] in capsys.readouterr().err


@pytest.mark.parametrize("command", ["simulate", "stability", "continuation", "sweep"])
@pytest.mark.parametrize("option", ["--params", "--pair"])
def test_an_output_equal_to_the_params_or_pair_input_is_refused(tmp_path, capsys, command, option):
    """``simulate --params p.json --json p.json`` used to replace the parameters by the results."""
    p = tmp_path / "p.json"
    p.write_text("{}")
    link = tmp_path / "l.json"
    os.link(p, link)
    extra = ["--omega", "1.0"] if command == "simulate" else []
    rc = cli([command, *extra, option, str(p), "--json", str(link)])
    err = capsys.readouterr().err
    assert rc == 2 and "same file" in err and option in err
    assert p.read_text() == "{}"


def test_an_output_may_not_be_a_file_of_an_input_run_folder(tmp_path):
    run = tmp_path / "run"
    shutil.copytree(ROOT / "gear_env" / "data" / "pretrained", run)
    (run / "checkpoints").mkdir()
    (run / "checkpoints" / "latest.json").write_text("{}")
    for name in ("model.zip", "config.json", "vecnormalize.npz", "checkpoints/latest.json"):
        with pytest.raises(ValueError, match="of the input --policy"):
            check_outputs({"--json": run / name}, {"--policy": [str(run)]})
        with pytest.raises(ValueError, match="of the input --policy"):  # NAME=RUN specs too
            check_outputs({"--json": run / name}, {"--policy": [f"mine={run}"]})
    check_outputs({"--json": run / "my_evaluation.json"}, {"--policy": [str(run)]})  # a new file there is fine


def test_evaluate_refuses_to_write_over_the_model_it_reads(tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(ROOT / "gear_env" / "data" / "pretrained", run)
    before = (run / "model.zip").read_bytes()
    rc = cli(["evaluate", "--policy", str(run), "--env", "GearSpeed-v0", "--json", str(run / "model.zip")])
    assert rc == 2 and "model.zip of the input --policy" in capsys.readouterr().err
    assert (run / "model.zip").read_bytes() == before


def test_a_link_planted_in_an_output_folder_never_leads_a_write_out_of_it(tmp_path):
    (tmp_path / "precious.txt").write_text(KEEP)
    out = tmp_path / "D"
    out.mkdir()
    os.symlink(tmp_path / "precious.txt", out / "report.md")
    (tmp_path / "elsewhere").mkdir()
    os.symlink(tmp_path / "elsewhere", out / "sub")
    (out / "mine.md").write_text("old")
    os.symlink("mine.md", out / "alias.md")  # a link inside the folder stays allowed
    with hold_outputs({}, folders={"--out": out}):
        with pytest.raises(OSError, match="out of the output folder"):
            atomic_write_text(out / "report.md", "new")
        with pytest.raises(OSError, match="out of the output folder"):
            atomic_write_text(out / "sub" / "x.md", "new")
        atomic_write_text(out / "alias.md", "new")
    assert (tmp_path / "precious.txt").read_text() == KEEP
    assert not os.listdir(tmp_path / "elsewhere")
    assert (out / "mine.md").read_text() == "new"
    atomic_write_text(out / "report.md", "through")  # outside a command's life: the link is the user's choice
    assert (tmp_path / "precious.txt").read_text() == "through"


def test_report_does_not_write_through_a_link_out_of_its_folder(tmp_path, capsys):
    (tmp_path / "precious.txt").write_text(KEEP)
    out = tmp_path / "D"
    out.mkdir()
    os.symlink(tmp_path / "precious.txt", out / "rl_report.md")
    rc = cli(["report", "--policy", "constant:1.0", "--episodes", "1", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and "out of the output folder" in err[-1]
    assert (tmp_path / "precious.txt").read_text() == KEEP
    assert json.loads(KEEP)


def _demand_protocol():  # type: ignore[no-untyped-def]
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import demand_protocol

    return demand_protocol


def test_demand_protocol_cache_is_read_bounded_and_checked(tmp_path, capsys):
    """``benchmarks/demand_protocol.py --cache DIR``: a crafted cache file is refused (and recomputed), never
    taken as results, and never hangs or raises a traceback."""
    dp = _demand_protocol()
    seeds = range(0, 3)
    cache = tmp_path / "cache"
    (cache / "s").mkdir(parents=True)
    path = cache / "s" / "oracle.json"
    good = [{"seed": s, "return": 1.5, "delivered": 1.0, "shortfall": -0.1, "cost": -0.2, "settled_omega": 1.2}
            for s in seeds]  # fmt: skip

    def put(obj):  # type: ignore[no-untyped-def]
        path.write_text(obj if isinstance(obj, str) else json.dumps(obj))

    put({"spec": "oracle", "seeds": [0, 3], "episodes": good})
    assert dp.read_cache(path, cache, "oracle", seeds) == good
    assert dp.read_cache(path, cache, "fixed-best", seeds) is None  # another policy's file: not used
    bad = [
        "[" * 100_000 + "]" * 100_000,
        {"spec": "oracle", "seeds": [0, 3], "episodes": [{**r, "return": 1e300} for r in good]},
        {"spec": "oracle", "seeds": [0, 3], "episodes": good[:2]},
        {"spec": "oracle", "seeds": [0, 3], "episodes": [{**r, "seed": 7} for r in good]},
        {"spec": "oracle", "seeds": [0, 3], "episodes": [{**r, "extra": 1} for r in good]},
        {"spec": "oracle", "seeds": [0, 3], "episodes": good, "more": 1},
    ]
    for obj in bad:
        put(obj)
        assert dp.read_cache(path, cache, "oracle", seeds) is None
        assert "refused" in capsys.readouterr().err
    path.unlink()
    os.mkfifo(path)  # never waited on
    assert dp.read_cache(path, cache, "oracle", seeds) is None
    path.unlink()
    (tmp_path / "elsewhere.json").write_text(json.dumps({"spec": "oracle", "seeds": [0, 3], "episodes": good}))
    os.symlink(tmp_path / "elsewhere.json", path)  # leaves the cache folder
    assert dp.read_cache(path, cache, "oracle", seeds) is None
    assert "leaves the folder" in capsys.readouterr().err


LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(8)
)


@pytest.mark.parametrize(
    "text",
    [
        "GearSpeed-v1: " + "[" * 100_000 + "]" * 100_000,  # was a RecursionError in yaml.safe_load
        LAUGHS + "GearSpeed-v1:\n  env_kwargs:\n    demand: *i\n",  # 10^9 values once expanded
        LAUGHS + "GearSpeed-v1:\n  policy_kwargs:\n    net_arch: *i\n",
        "a: &a [*a]\nGearSpeed-v1:\n  env_kwargs: {demand: *a}\n",  # an alias to itself
        "GearSpeed-v1: &x\n  env_kwargs: {demand: *x}\n",
    ],
    ids=["deep", "laughs-env", "laughs-net", "self-list", "self-map"],
)
def test_hyperparams_yaml_depth_and_alias_expansion_are_bounded(tmp_path, text):
    from agents.hyperparams import load_zoo_entry

    (tmp_path / "h.yml").write_text(text)
    with pytest.raises(ValueError, match="h.yml"):
        load_zoo_entry(tmp_path / "h.yml", "GearSpeed-v1")


def test_the_shipped_hyperparams_still_load():
    from agents.hyperparams import load_zoo_entry

    for env_id in ("GearSpeed-v0", "GearSpeed-v1", "GearSpeedDemand-v0", "GearSpeedDemandHard-v0"):
        assert load_zoo_entry(ROOT / "agents" / "hyperparams" / "ppo.yml", env_id)["ppo"]


@pytest.mark.parametrize("value", [0, -2, float("nan"), 1.5, True, "7", 10**30])
def test_make_vec_refuses_an_odd_time_limit(value):
    """``gym.make_vec(ID, max_episode_steps=...)`` was silently ignored (the registered max_steps won), so 0,
    NaN and 1.5 were accepted and 7 ran episodes of the task's own length."""
    import gymnasium as gym

    import gear_env  # noqa: F401 - registers the tasks

    with pytest.raises(ValueError, match="max_episode_steps"):
        gym.make_vec("GearSpeedDemandHard-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     max_episode_steps=value)  # fmt: skip


def test_make_vec_time_limit_sets_the_episode_length():
    import gymnasium as gym
    import numpy as np

    import gear_env  # noqa: F401

    env = gym.make_vec("GearSpeed-v1", num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=3,
                       periods_per_step=8, warmup_periods=16)  # fmt: skip
    env.reset(seed=0)
    ends = [bool(np.any(env.step(np.zeros((2, 1), np.float32))[3])) for _ in range(3)]
    assert ends == [False, False, True]
    assert gym.make_vec("GearSpeed-v1", num_envs=2, vectorization_mode="vector_entry_point").unwrapped.config.max_steps
    with pytest.raises(ValueError, match="differ"):
        gym.make_vec("GearSpeed-v1", num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=7,
                     max_steps=9)  # fmt: skip


def test_make_refuses_a_numpy_time_limit_with_a_value_error():
    """``gym.make(ID, max_episode_steps=np.int64(5))`` passed the package's check, then Gymnasium raised its own
    TypeError."""
    import gymnasium as gym
    import numpy as np

    import gear_env  # noqa: F401

    with pytest.raises(ValueError, match="max_episode_steps"):
        gym.make("GearSpeed-v1", max_episode_steps=np.int64(5))


def test_a_netcdf_file_of_another_kind_is_refused_before_its_data_is_inflated(tmp_path):
    """A 1 MiB .nc whose zlib variable inflates to 900 MiB was loaded whole (1.1 GiB peak) before its missing
    format attribute was noticed; the attributes are now checked first (here: 40 MiB of zeros, traced)."""
    import tracemalloc

    import netCDF4

    from gear_env.analysis.results import ResultsFileError, SweepResult

    p = tmp_path / "other.nc"
    with netCDF4.Dataset(p, "w") as f:
        f.createDimension("omega", 5)
        f.createDimension("k", 2**20)
        v = f.createVariable("poincare", "f8", ("omega", "k"), zlib=True, chunksizes=(1, 2**18))
        v[:] = 0.0
        f.setncattr("format", "[" * 10_000)
    with pytest.raises(FileNotFoundError):
        SweepResult.load(str(tmp_path / "missing.nc"))  # imports xarray outside the traced window
    tracemalloc.start()
    try:
        with pytest.raises(ResultsFileError, match="not a gear-env sweep file"):
            SweepResult.load(str(p))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 8 * 2**20  # 80 MiB before the fix


@pytest.mark.parametrize("kind", ["fifo", "dir", "missing", "empty"])
def test_train_demand_file_refusals_name_the_file(tmp_path, capsys, kind):
    p = tmp_path / "demand.csv"
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "dir":
        p.mkdir()
    elif kind == "empty":
        p.write_text("t_steps,omega\n")
    rc = cli(["train", "--out", str(tmp_path / "D"), "--demand", str(p), "--timesteps", "64"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "demand.csv" in err[0] and "--demand" in err[0]
    assert not (tmp_path / "D").exists()


@pytest.mark.parametrize("env_id", ["GearSpeed-v1", "GearSpeedDemandHard-v0"])
def test_bool_actions_are_refused_like_text(env_id):
    """``env.step(np.array([True]))`` was taken as 1.0 (full acceleration); numbers in an object array stay fine."""
    import gymnasium as gym
    import numpy as np

    import gear_env  # noqa: F401

    env = gym.make(env_id)
    env.reset(seed=0)
    for a in (np.array([True]), [True], np.array([np.bool_(False)], dtype=object)):
        with pytest.raises(ValueError, match="action must be a float array"):
            env.step(a)
    env.step(np.array([0.1], dtype=object))


def test_pretrained_policy_of_another_task_is_refused(tmp_path, monkeypatch):
    """A shipped policy.json whose env_id names another task (same spaces) was loaded for the asked task."""
    import agents.registry as reg
    from gear_env.envs.env_config import task_config

    d = tmp_path / "GearSpeedDemandHard-v0"
    shutil.copytree(ROOT / "gear_env" / "data" / "policies" / "GearSpeedDemandHard-v0", d)
    meta = json.loads((d / "policy.json").read_text())
    meta["env_id"] = "GearSpeed-v1"
    (d / "policy.json").write_text(json.dumps(meta))
    monkeypatch.setattr(reg, "pretrained_dir", lambda env_id="GearSpeed-v0": d)
    cfg = task_config("GearSpeedDemandHard-v0")
    with pytest.raises(ValueError, match="env_id: the policy is for 'GearSpeed-v1'"):
        reg.resolve_policy("pretrained", cfg, env_id="GearSpeedDemandHard-v0")


def test_a_run_folder_of_an_unknown_task_is_refused_naming_its_config(tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(ROOT / "gear_env" / "data" / "pretrained", run)
    cfg = json.loads((run / "config.json").read_text())
    cfg["env_id"] = "gymnasium.envs.classic_control:CartPole-v1"  # gym.make would import a module
    (run / "config.json").write_text(json.dumps(cfg))
    rc = cli(["evaluate", "--policy", str(run), "--episodes", "1"])
    err = capsys.readouterr().err
    assert rc == 2 and "config.json" in err and "env_id" in err


def test_overwrite_does_not_take_a_stub_config_for_an_old_run(tmp_path):
    """A folder with ``config.json = {"format": "gear-env-run/1"}`` and the user's model.zip passed for a run of
    an earlier release, so ``train --overwrite`` deleted the model.zip."""
    from agents.runs import is_run_folder

    d = tmp_path / "D"
    d.mkdir()
    (d / "config.json").write_text('{"format": "gear-env-run/1"}')
    (d / "model.zip").write_text(KEEP)
    assert not is_run_folder(d)
    rc = cli(["train", "--out", str(d), "--overwrite", "--timesteps", "64", "--no-progress", "--quiet"])
    assert rc == 2 and (d / "model.zip").read_text() == KEEP
    assert is_run_folder(ROOT / "gear_env" / "data" / "pretrained")  # an earlier release's run still is one
