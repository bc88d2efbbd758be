"""Read rl-zoo3 hyper-parameter files (``agents/hyperparams/ppo.yml``) for ``gear-env train --hyperparams``.

The format is rl-baselines3-zoo's: one entry per Gymnasium id with SB3 PPO keyword names plus the
zoo's own keys ``n_envs``, ``n_timesteps``, ``normalize``, ``policy``, ``policy_kwargs`` (a Python
expression ``dict(...)``, read here without evaluating code: only literal values are accepted) and
``env_kwargs``. YAML anchors and merge keys (``<<: *base``) work (``yaml.safe_load``).
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

ZOO_ONLY = ("n_envs", "n_timesteps", "normalize", "policy", "policy_kwargs", "env_kwargs", "callback")
DISTILL_CALLBACK = "agents.distill.DistillCallback"
"""The one rl-zoo3 callback ``gear-env train --hyperparams`` understands: it becomes ``--distill``."""
"""rl-zoo3 keys that are not PPO keywords."""


def _policy_kwargs(text: Any, where: str) -> dict[str, Any]:
    if isinstance(text, dict):
        return dict(text)
    try:
        node = ast.parse(str(text), mode="eval").body
        if not (
            isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args
        ):
            raise ValueError
        return {kw.arg: ast.literal_eval(kw.value) for kw in node.keywords if kw.arg}
    except (SyntaxError, ValueError):
        raise ValueError(f"{where}: policy_kwargs must be dict(key=literal, ...), got {text!r}") from None


def _zoo_callback(value: Any, where: str) -> dict[str, Any]:
    """The keyword arguments of the entry's ``callback`` (only :data:`DISTILL_CALLBACK`, alone)."""
    items = value if isinstance(value, list) else [value]
    if len(items) != 1:
        raise ValueError(f"{where}: callback: gear-env train runs only {DISTILL_CALLBACK}, got {value!r}")
    item = items[0]
    name, kwargs = next(iter(item.items())) if isinstance(item, dict) and len(item) == 1 else (item, {})
    if name != DISTILL_CALLBACK or not isinstance(kwargs, dict):
        raise ValueError(f"{where}: callback: gear-env train runs only {DISTILL_CALLBACK}, got {value!r}")
    return dict(kwargs)


MAX_YAML_DEPTH = 64
"""Deepest nesting of sequences and mappings in a ``--hyperparams`` file (as :data:`gear_env.io.MAX_JSON_DEPTH`)."""
MAX_YAML_NODES = 100_000
"""Most values of a ``--hyperparams`` file with its aliases expanded (a "billion laughs" file has 10^9)."""


def _check_nesting(events: Any, path: Path) -> None:
    """ValueError if the YAML event stream nests deeper than :data:`MAX_YAML_DEPTH` (PyYAML's parser is not
    recursive, its composer is: a 100,000-level file would end in a RecursionError)."""
    import yaml

    depth = 0
    for ev in events:
        if isinstance(ev, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            depth += 1
            if depth > MAX_YAML_DEPTH:
                raise ValueError(f"--hyperparams {str(path)!r} is nested deeper than {MAX_YAML_DEPTH} levels")
        elif isinstance(ev, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            depth -= 1


def _check_expanded(data: Any, path: Path) -> None:
    """ValueError if ``data`` with its YAML aliases expanded has more than :data:`MAX_YAML_NODES` values or
    nests deeper than :data:`MAX_YAML_DEPTH` (an alias to an enclosing node makes it endless)."""
    stack = [(data, 1)]
    n = 0
    while stack:
        obj, depth = stack.pop()
        n += 1
        if n > MAX_YAML_NODES or depth > MAX_YAML_DEPTH:
            raise ValueError(
                f"--hyperparams {str(path)!r}: its aliases expand to more than {MAX_YAML_NODES:,} values or "
                f"{MAX_YAML_DEPTH} levels (an alias to itself or a 'billion laughs' file); refused"
            )
        if isinstance(obj, dict):
            stack.extend((v, depth + 1) for kv in obj.items() for v in kv)
        elif isinstance(obj, list):
            stack.extend((v, depth + 1) for v in obj)


def load_zoo_entry(path: str | Path, env_id: str) -> dict[str, Any]:
    """The entry of ``env_id`` as {"ppo": {...PPO_DEFAULTS keys}, "env_kwargs", "n_envs", "n_timesteps"}, and
    "distill" (the keyword arguments of its :data:`DISTILL_CALLBACK`) when it has one."""
    import yaml

    from .ppo import PPO_DEFAULTS

    p = Path(path)
    try:
        from gear_env.io import read_limited

        text = read_limited(p, "--hyperparams", 1024 * 1024).decode("utf-8")
        _check_nesting(yaml.parse(text, Loader=yaml.SafeLoader), p)  # before safe_load, which recurses
        data = yaml.safe_load(text)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ValueError(f"--hyperparams: cannot read {str(p)!r}: {exc}") from None
    _check_expanded(data, p)
    if not isinstance(data, dict) or env_id not in data or not isinstance(data[env_id], dict):
        have = sorted(data) if isinstance(data, dict) else []
        raise ValueError(f"--hyperparams: {str(p)!r} has no entry for {env_id!r} (entries: {have})")
    entry = dict(data[env_id])
    where = f"{p}:{env_id}"
    if entry.get("policy", "MlpPolicy") != "MlpPolicy" or entry.get("normalize", True) is not True:
        raise ValueError(
            f"{where}: gear-env train runs MlpPolicy with VecNormalize (policy: MlpPolicy, normalize: true)"
        )
    ppo = {k: v for k, v in entry.items() if k not in ZOO_ONLY}
    ppo.update(_policy_kwargs(entry.get("policy_kwargs", "dict()"), where))
    unknown = sorted(set(ppo) - set(PPO_DEFAULTS))
    if unknown:
        raise ValueError(f"{where}: unknown PPO hyper-parameter(s) {unknown}; valid: {sorted(PPO_DEFAULTS)}")
    env_kwargs = entry.get("env_kwargs") or {}
    if not isinstance(env_kwargs, dict):
        raise ValueError(f"{where}: env_kwargs must be a mapping of environment settings")
    out: dict[str, Any] = {"ppo": ppo, "env_kwargs": dict(env_kwargs)}
    if entry.get("callback") is not None:
        out["distill"] = _zoo_callback(entry["callback"], where)
    for k in ("n_envs", "n_timesteps"):
        if k in entry:
            v = entry[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or v < 1 or v != int(v):
                raise ValueError(f"{where}: {k} must be a positive integer, got {v!r}")
            out[k] = int(v)
    return out


__all__ = ["load_zoo_entry"]
