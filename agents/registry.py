"""Policy specs -> policy objects with the SB3 ``predict`` interface (used by ``gear-env evaluate``).

Specs (case-sensitive):

==========================  ===========================================================================
``pretrained``              the small PPO policy shipped in ``gear_env/data/pretrained/``
``RUN_DIR`` (a folder)      a training run folder (model.zip + vecnormalize.pkl + config.json)
``RUN_DIR/best_model.zip``  the best evaluation of a run (also ``RUN_DIR/checkpoints/ckpt_N.zip``)
``oracle``                  dynamic-programming schedule on the simulator's steady reward map
``constant-best``           go to the omega of best steady reward and hold it
``constant:W``              go to omega = W and hold it (e.g. ``constant:1.2``)
``ramp`` / ``ramp:W[:F]``   slow ramp to the best omega (or W) at fraction F of the max rate (0.25)
``hill-climber``            greedy vibration-feedback controller
``random[:SEED]``           uniform random actions (seeded; a sanity floor)
``delayed-oracle:K``        (GearSpeedDemand-v0) fixed-best for K steps, then the oracle that knows the pair
``identify-follow``         (GearSpeedDemand-v0) sensor-only: identify the pair, follow the demand to its edge
``sensor-servo``            (GearSpeedDemand-v0) sensor-only memoryless servo on the sensed force level
``filtered-follow[:N[:S]]`` (GearSpeedDemandHard-v0) sensor-only: the sensed pair averaged over N clean steps,
                            the hold speed shifted by S (omega units)
==========================  ===========================================================================

The last three are built from ``DEMAND_SCRIPTS`` (name -> factory, help line; agents/demand_scripts.py).

A trained model is checked against the environment it is evaluated on: a model trained on another
observation layout raises a clear ``ValueError``.
"""

from __future__ import annotations

import math
import os
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .policy import BasePolicy

NAMES = (
    "pretrained",
    "oracle",
    "fixed-best",
    "constant-best",
    "constant:W",
    "ramp",
    "ramp:W[:F]",
    "hill-climber",
    "random[:SEED]",
    "delayed-oracle:K",
    "identify-follow",
    "sensor-servo",
    "filtered-follow[:N[:S]]",
)


def _delayed_oracle(arg: str | None, config: Any) -> Any:
    from .demand_scripts import DelayedOracle

    if arg is None or not arg.strip().lstrip("-").isdigit():
        raise ValueError(
            f"policy spec 'delayed-oracle:{arg or ''}': K must be an integer number of steps (delayed-oracle:10)"
        )
    return DelayedOracle(config, int(arg))


def _filtered_follow(arg: str | None, config: Any) -> Any:
    from .demand_scripts import FilteredFollow

    if arg is None:
        return FilteredFollow(config)
    window, sep, shift = arg.partition(":")
    if not window.strip().isdigit():
        raise ValueError(
            f"policy spec 'filtered-follow:{arg}': N must be an integer window in steps (filtered-follow:8, "
            "filtered-follow:6:-0.02)"
        )
    if not sep:
        return FilteredFollow(config, int(window))
    try:
        value = float(shift)  # its range is FilteredFollow's to check
    except ValueError:
        raise ValueError(
            f"policy spec 'filtered-follow:{arg}': S must be a number (omega units added to the hold speed, e.g. "
            f"filtered-follow:6:-0.02), got {shift!r}"
        ) from None
    return FilteredFollow(config, int(window), value)


def _no_arg(cls_name: str) -> Any:
    def make(arg: str | None, config: Any) -> Any:
        from . import demand_scripts

        cls = getattr(demand_scripts, cls_name)
        if arg is not None:
            raise ValueError(f"policy spec {cls.name!r} takes no argument, got {cls.name}:{arg}")
        return cls(config)

    return make


DEMAND_SCRIPTS: dict[str, tuple[Any, str]] = {
    "delayed-oracle": (
        _delayed_oracle,
        "fixed-best for K steps, then the oracle that knows the pair (delayed-oracle:K)",
    ),
    "identify-follow": (
        _no_arg("IdentifyFollow"),
        "identify the pair from the sensed force, follow the demand to its edge",
    ),
    "sensor-servo": (_no_arg("SensorServo"), "memoryless servo: step towards the edge level of the sensed force"),
    "filtered-follow": (
        _filtered_follow,
        "noisy sensors: average the sensed pair over N clean steps, follow the demand to its edge shifted by S "
        "(filtered-follow:N[:S])",
    ),
}
"""The baselines of GearSpeedDemand-v0 (agents/demand_scripts.py): spec name -> (factory(arg, config), help line)."""


def pretrained_dir(env_id: str = "GearSpeed-v0") -> Path:
    """Folder of the policy shipped for ``env_id``: GearSpeed-v0's is a run folder without checkpoints
    (``data/pretrained``), the others ``policy.json`` + ``policy.pt`` (``data/policies/<env_id>``). A Fox-Goodwin
    task shares the policy of the task it integrates differently (``gear_env.envs.tasks.base_task``)."""
    from gear_env.envs.tasks import base_task

    env_id = base_task(env_id)
    if env_id == "GearSpeed-v0":
        return Path(str(resources.files("gear_env") / "data" / "pretrained"))
    return Path(str(resources.files("gear_env") / "data" / "policies" / env_id))


def shipped_policy_dir(env_id: str) -> Path:
    """:func:`pretrained_dir` of a task other than GearSpeed-v0, checked: ``ValueError`` if no policy is shipped
    for ``env_id`` (its folder has no ``policy.json``)."""
    d = pretrained_dir(env_id)
    if not (d / "policy.json").is_file():
        raise ValueError(f"no pretrained policy is shipped for {env_id!r} ({str(d)!r} has no policy.json)")
    return d


class RandomPolicy(BasePolicy):
    """Uniform random actions in [-1, 1] (seeded; ``deterministic`` is ignored)."""

    name = "random"

    def __init__(self, seed: int = 0):
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**63:
            raise ValueError(f"random policy seed must be an integer in [0, 2**63), got {seed!r}")
        self.rng = np.random.default_rng(int(seed))

    def predict_batch(
        self, observations: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        """Random actions (n, 1)."""
        return self.rng.uniform(-1.0, 1.0, size=(len(observations), 1)).astype(np.float32), state


def _has_scenario(config: Any) -> bool:
    """True when episodes draw their plant, load or demand (the oracle then plans per episode)."""
    return config is not None and (
        getattr(config, "plant_family", None) is not None
        or getattr(config, "duty_cycle", None) is not None
        or getattr(config, "demand", None) == "random"
    )


def _float(text: str, spec: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"policy spec {spec!r}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"policy spec {spec!r}: {text!r} is not a finite number")
    return v


def _seed(text: str, spec: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise ValueError(f"policy spec {spec!r}: the seed {text!r} is not an integer (random:SEED)") from None
    if not 0 <= v < 2**63:
        raise ValueError(f"policy spec {spec!r}: the seed must be an integer in [0, 2**63), got {v}")
    return v


def _run_location(spec: str) -> tuple[Path, str] | None:
    """(run folder, model file inside it) of a trained-policy spec; None for names and scripted specs."""
    s = spec.strip()
    if not (os.path.isdir(s) or os.sep in s or s.endswith(".zip")):
        return None
    path, model_file = Path(s), "model.zip"
    if path.suffix == ".zip":  # RUN_DIR/best_model.zip or RUN_DIR/checkpoints/ckpt_<steps>.zip
        if path.parent.name == "checkpoints":
            path, model_file = path.parent.parent, f"checkpoints/{path.name}"
        else:
            path, model_file = path.parent, path.name
    return path, model_file


def trained_env_id(spec: str) -> str | None:
    """The task a run-folder spec was trained on (``env_id`` of its ``config.json``); None for every other
    spec (``pretrained`` is shipped per task, scripted policies fit any task) and for a folder that is not
    a readable run (resolving it then reports why)."""
    loc = _run_location(spec) if isinstance(spec, str) else None
    if loc is None:
        return None
    from .runs import RunFolder, RunFolderError

    try:
        env_id = RunFolder(loc[0]).read_config().get("env_id")
    except (RunFolderError, OSError, ValueError):
        return None
    return env_id if isinstance(env_id, str) else None


def resolve_policy(spec: str, config: Any = None, env_id: str | None = None, allow_other_env: bool = False) -> Any:
    """The policy named by ``spec`` for the environment ``config`` (GearSpeedConfig, dict or None).

    Returns an object with ``predict(observation, state=None, episode_start=None,
    deterministic=True) -> (actions, state)`` and a ``name``. Raises ``ValueError`` for an unknown
    spec (listing the valid ones), a missing/corrupt run folder, a model whose observation or
    action space does not match the environment, or a run trained on another task than ``env_id``
    (its ``config.json`` names it; ``allow_other_env=True`` evaluates it there anyway)."""
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"policy spec must be a non-empty string, got {spec!r}; valid: {', '.join(NAMES)} or RUN_DIR")
    s = spec.strip()
    from .baselines import ConstantSpeed, HillClimber, SlowRamp
    from .oracle import OraclePolicy, best_constant_omega

    scenario = _has_scenario(config)
    head, sep, arg = s.partition(":")
    if head in DEMAND_SCRIPTS:
        if not scenario or getattr(config, "demand", None) is None:
            raise ValueError(f"policy {head!r} needs a task with a demand and a plant family (GearSpeedDemand-v0)")
        return DEMAND_SCRIPTS[head][0](arg if sep else None, config)
    if s == "oracle":
        if scenario:
            from .episode_oracle import EpisodeOracle

            return EpisodeOracle(config)
        return OraclePolicy(config)
    if s == "fixed-best":
        if scenario:
            from .episode_oracle import FixedBest

            return FixedBest(config)
        return ConstantSpeed(best_constant_omega(config), config, name="fixed-best")
    if s == "constant-best":
        return ConstantSpeed(best_constant_omega(config), config, name="constant-best")
    if s.startswith("constant:"):
        return ConstantSpeed(_float(s.split(":", 1)[1], s), config)
    if s == "ramp" or s.startswith("ramp:"):
        parts = s.split(":")[1:]
        if len(parts) > 2:
            raise ValueError(f"policy spec {s!r}: expected ramp, ramp:W or ramp:W:F")
        target = _float(parts[0], s) if parts else best_constant_omega(config)
        frac = _float(parts[1], s) if len(parts) > 1 else 0.25
        return SlowRamp(target, config, rate_fraction=frac, name="ramp" if not parts else None)
    if s in ("hill-climber", "hillclimber", "hill_climber"):
        return HillClimber(config)
    if s == "random" or s.startswith("random:"):
        return RandomPolicy(_seed(s.split(":", 1)[1], s) if ":" in s else 0)
    from gear_env._extras import require

    if s == "pretrained" or os.path.isdir(s) or os.sep in s or s.endswith(".zip"):
        for module in ("torch", "stable_baselines3"):
            require(module, f"policy {s!r} (a trained network)")
    from gear_env.envs.tasks import base_task

    from .trained import load_trained_policy

    if s == "pretrained" and env_id not in (None, "GearSpeed-v0"):
        from .shipped import load_policy

        d = shipped_policy_dir(env_id)
        pol = load_policy(d, name="pretrained")
        if pol.env_id != base_task(env_id):
            raise ValueError(f"{str(d / 'policy.json')!r}: env_id: the policy is for {pol.env_id!r}, not {env_id!r}")
        if config is not None:
            from gear_env.envs.env import GearSpeedEnv

            n_obs = GearSpeedEnv(config).observation_space.shape[0]
            if n_obs != pol.observation_space.shape[0]:
                raise ValueError(
                    f"the pretrained policy of {env_id!r} takes {pol.observation_space.shape[0]} observation "
                    f"features, this configuration gives {n_obs}"
                )
            pol.adapt_to(config)
        return pol
    if s == "pretrained":
        d = pretrained_dir()
        if not (d / "model.zip").is_file():
            raise ValueError(f"the pretrained policy is not installed ({str(d)!r} has no model.zip)")
        return load_trained_policy(d, config if config is not None else _stored_config(d), name="pretrained")
    loc = _run_location(s)
    if loc is not None:
        path, model_file = loc
        trained = trained_env_id(s)
        same = env_id is None or trained is None or base_task(trained) == base_task(env_id)  # the scheme may differ
        if not same and not allow_other_env:
            raise ValueError(
                f"policy {spec!r} was trained on {trained} ({str(path / 'config.json')!r}), not on {env_id}: its "
                f"scores there would judge it on another task. Evaluate it with --env {trained}, or pass "
                "--allow-other-env (allow_other_env=True) to run it on this task anyway"
            )
        cfg = config if config is not None else _stored_config(path)
        return load_trained_policy(path, cfg, name=Path(s).name or s, model_file=model_file)
    raise ValueError(f"unknown policy {spec!r}; valid: {', '.join(NAMES)}, or a run folder (RUN_DIR)")


def _stored_config(run_dir: Path) -> Any:
    from .runs import RunFolder

    return RunFolder(run_dir).read_config()["env_config"]


__all__ = ["NAMES", "RandomPolicy", "pretrained_dir", "resolve_policy", "shipped_policy_dir", "trained_env_id"]
