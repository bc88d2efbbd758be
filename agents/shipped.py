"""Shipped policies without pickles: weights as a torch state dict, normalisation as JSON.

A shipped policy is a folder (``gear_env/data/policies/<ENV_ID>/``) with

* ``policy.json``  - env id, environment settings, observation names, spaces, network (net_arch,
  activation), the VecNormalize observation statistics (mean, var, epsilon, clip_obs), the training
  summary (seed, steps, wall time, hyper-parameters) and the evaluation that chose it;
* ``policy.pt``    - the SB3 ``ActorCriticPolicy`` state dict, read with ``torch.load(weights_only=True)``
  (tensors only: loading it runs no code).

:func:`export_policy` writes one from a run folder's model; :func:`load_policy` returns an object
with the common ``predict(observation, state, episode_start, deterministic)``.
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from gear_env.errors import FileFormatError

from .policy import BasePolicy

FORMAT = "gear-env-policy/1"
ACTIVATIONS = ("Tanh", "ReLU")
POLICY_KEYS = (
    "format", "env_id", "env_config", "observation_space", "action_space", "net_arch", "activation",
    "log_std_init", "obs_normalization", "summary",
)  # fmt: skip
"""The keys of policy.json (any other key is refused)."""
MAX_POLICY_JSON_BYTES = 4 * 1024 * 1024
"""Largest policy.json read (bytes)."""
MAX_STATE_DICT_BYTES = 64 * 1024 * 1024
"""Largest policy.pt read (bytes, on disk and declared inside)."""
MAX_POLICY_PARAMETERS = 4_000_000
"""Most weights of a shipped network (actor + critic), checked before it is built."""
MAX_OBS_DIM = 4096
"""Most observation features of a shipped policy."""


def read_policy_json(path: str | Path) -> dict[str, Any]:
    """policy.json with every field checked (known keys, types, ranges, sizes consistent with the spaces).

    The env id must be a Gymnasium id; the network (``net_arch``: a list, or a dict of ``pi``
    and ``vf`` lists) at most :data:`MAX_POLICY_PARAMETERS` weights for the spaces given, checked before
    anything is built. FileFormatError naming the file and the field otherwise."""
    from gear_env.io import parse_json_text
    from gear_env.untrusted import (
        check_keys,
        layer_sizes,
        mlp_parameters,
        read_regular,
        refuse,
        want_num,
        want_numbers,
        want_str,
    )

    p = str(path)
    try:
        raw = read_regular(p, "policy description", MAX_POLICY_JSON_BYTES)
        meta = parse_json_text(raw.decode("utf-8-sig"), f"policy description {p!r}")
    except UnicodeDecodeError as exc:
        raise refuse(p, None, f"not UTF-8 text ({exc})") from None
    except FileFormatError:
        raise
    except ValueError as exc:
        raise FileFormatError(str(exc), p) from None
    check_keys(meta, POLICY_KEYS, p, "", required=POLICY_KEYS[:7])
    want_str(meta["format"], p, "format", choices=(FORMAT,))
    want_str(meta["env_id"], p, "env_id", max_len=128, pattern=r"[A-Za-z0-9_.:/-]+")
    check_keys(meta["env_config"], meta["env_config"].keys() if isinstance(meta["env_config"], dict) else (), p,
               "env_config")  # fmt: skip
    dims = {}
    for k in ("observation_space", "action_space"):
        sp = check_keys(meta[k], ("low", "high"), p, k, required=("low", "high"))
        lo = want_numbers(sp["low"], p, f"{k}.low", max_len=MAX_OBS_DIM)
        hi = want_numbers(sp["high"], p, f"{k}.high", length=len(lo))
        if len(lo) == 0 or np.any(lo > hi):
            raise refuse(p, k, "needs low <= high and at least one entry")
        dims[k] = len(lo)
    if dims["action_space"] != 1:
        raise refuse(p, "action_space", f"must have 1 entry (the speed action), has {dims['action_space']}")
    arch = meta["net_arch"]
    if isinstance(arch, dict):
        check_keys(arch, ("pi", "vf"), p, "net_arch", required=("pi", "vf"))
        pi, vf = layer_sizes(arch["pi"], p, "net_arch.pi"), layer_sizes(arch["vf"], p, "net_arch.vf")
    else:
        pi = vf = layer_sizes(arch, p, "net_arch")
    n = mlp_parameters(dims["observation_space"], pi, 1) + mlp_parameters(dims["observation_space"], vf, 1)
    if n > MAX_POLICY_PARAMETERS:
        raise refuse(p, "net_arch", f"a network of {n:,} weights; the limit is {MAX_POLICY_PARAMETERS:,}")
    want_str(meta["activation"], p, "activation", choices=ACTIVATIONS)
    if "log_std_init" in meta:
        want_num(meta["log_std_init"], -20.0, 5.0, p, "log_std_init")
    norm = meta.get("obs_normalization")
    if norm is not None:
        check_keys(norm, ("mean", "var", "epsilon", "clip_obs"), p, "obs_normalization",
                   required=("mean", "var", "epsilon", "clip_obs"))  # fmt: skip
        d = dims["observation_space"]
        want_numbers(norm["mean"], p, "obs_normalization.mean", length=d)
        want_numbers(norm["var"], p, "obs_normalization.var", length=d, lo=0.0)
        want_num(norm["epsilon"], 0.0, 1.0, p, "obs_normalization.epsilon", lo_open=True)
        want_num(norm["clip_obs"], 0.0, 1e6, p, "obs_normalization.clip_obs", lo_open=True)
    if "summary" in meta and not isinstance(meta["summary"], dict):
        raise refuse(p, "summary", "must be a JSON object")
    return meta


def _space(space: Any) -> dict[str, Any]:
    return {"low": np.asarray(space.low, float).tolist(), "high": np.asarray(space.high, float).tolist()}


def export_policy(
    model: Any,
    vecnorm: Any,
    env_id: str,
    env_config: dict[str, Any],
    out_dir: str | Path,
    summary: dict[str, Any] | None = None,
) -> Path:
    """Write ``policy.json`` + ``policy.pt`` for an SB3 PPO ``model`` and its ``VecNormalize`` (or None).

    Refuses to overwrite anything but a previous export (a folder holding only these two files)."""
    import torch

    from gear_env.io import atomic_write, atomic_write_text

    out = Path(out_dir)
    if out.exists() and (not out.is_dir() or set(p.name for p in out.iterdir()) - {"policy.json", "policy.pt"}):
        raise ValueError(f"{str(out)!r} exists and is not a previous policy export; choose another folder")
    out.mkdir(parents=True, exist_ok=True)
    pol = model.policy
    act = type(pol.activation_fn()).__name__ if isinstance(pol.activation_fn, type) else "Tanh"
    if act not in ACTIVATIONS:
        raise ValueError(f"activation {act!r} not supported; one of {ACTIVATIONS}")
    norm = None
    if vecnorm is not None and getattr(vecnorm, "norm_obs", False):
        rms = vecnorm.obs_rms
        norm = {
            "mean": np.asarray(rms.mean, float).tolist(),
            "var": np.asarray(rms.var, float).tolist(),
            "epsilon": float(vecnorm.epsilon),
            "clip_obs": float(vecnorm.clip_obs),
        }
    meta = {
        "format": FORMAT,
        "env_id": env_id,
        "env_config": env_config,
        "observation_space": _space(model.observation_space),
        "action_space": _space(model.action_space),
        "net_arch": pol.net_arch if isinstance(pol.net_arch, (list, dict)) else [64, 64],
        "activation": act,
        "log_std_init": float(getattr(pol, "log_std_init", 0.0)),
        "obs_normalization": norm,
        "summary": summary or {},
    }
    state = {k: v.detach().cpu() for k, v in pol.state_dict().items()}
    atomic_write(out / "policy.pt", lambda tmp: torch.save(state, tmp))
    atomic_write_text(out / "policy.json", json.dumps(meta, indent=1))
    return out


class ShippedPolicy(BasePolicy):
    """A shipped policy: frozen observation normalisation + the SB3 actor-critic network.

    ``action_adapter`` (set by :meth:`adapt_to`): re-expresses the network's actions for a task configuration
    whose actions mean something else than those it was trained on (:class:`agents.trained.ActionAdapter`).
    A loaded policy acts on its task's defaults (``gym.make(env_id)``): one trained with other action settings
    (GearSpeedDemand-v0's, which learned a speed limit) is adapted to them at load; :meth:`adapt_to` retargets it."""

    action_adapter: Any = None

    def __init__(self, folder: str | Path, name: str = "pretrained"):
        import torch
        from gymnasium import spaces
        from stable_baselines3.common.policies import ActorCriticPolicy

        self.folder = Path(folder)
        self.name = name
        meta = read_policy_json(self.folder / "policy.json")
        self.meta = meta
        self.env_id = meta["env_id"]
        ob, ac = meta["observation_space"], meta["action_space"]
        self.observation_space = spaces.Box(np.array(ob["low"], np.float32), np.array(ob["high"], np.float32))
        self.action_space = spaces.Box(np.array(ac["low"], np.float32), np.array(ac["high"], np.float32))
        act = {"Tanh": torch.nn.Tanh, "ReLU": torch.nn.ReLU}[meta["activation"]]
        self.policy = ActorCriticPolicy(
            self.observation_space,
            self.action_space,
            lambda _: 0.0,
            net_arch=meta["net_arch"],
            activation_fn=act,
            log_std_init=meta.get("log_std_init", 0.0),
        )
        pt = self.folder / "policy.pt"
        try:
            from gear_env.untrusted import open_zip, read_regular

            raw = read_regular(pt, "state dict", MAX_STATE_DICT_BYTES)
            open_zip(raw, "state dict", max_member=MAX_STATE_DICT_BYTES, max_total=MAX_STATE_DICT_BYTES,
                     stored_only=True, path=str(pt)).close()  # fmt: skip
            state = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
            expected = {k: tuple(v.shape) for k, v in self.policy.state_dict().items()}
            if not isinstance(state, dict) or set(state) != set(expected):
                raise ValueError("its tensors are not those of this network")
            for k, v in state.items():
                if not isinstance(v, torch.Tensor) or tuple(v.shape) != expected[k] or not torch.isfinite(v).all():
                    raise ValueError(f"tensor {k!r} is not a finite tensor of shape {expected[k]}")
            self.policy.load_state_dict(state)
        except Exception as exc:  # a corrupt or foreign file: one clear message
            raise FileFormatError(
                f"{str(pt)!r} is not a valid state dict of this network: {type(exc).__name__}: {exc}", str(pt)
            ) from None
        self.policy.set_training_mode(False)
        n = meta.get("obs_normalization")
        self.norm = None
        if n is not None:
            self.norm = (
                np.asarray(n["mean"], np.float64),
                np.asarray(n["var"], np.float64),
                float(n["epsilon"]),
                float(n["clip_obs"]),
            )
        from .envs import GEAR_ENV_IDS

        if self.env_id in GEAR_ENV_IDS:  # act on gym.make(env_id) as it is
            from .envs import make_config

            self.adapt_to(make_config(self.env_id, None))

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """The observation as the network saw it in training (VecNormalize, frozen)."""
        obs = np.asarray(obs, np.float64)
        if self.norm is None:
            return obs.astype(np.float32)
        mean, var, eps, clip = self.norm
        return np.clip((obs - mean) / np.sqrt(var + eps), -clip, clip).astype(np.float32)

    def predict_batch(
        self, observations: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        """Actions (n, 1) for observations (n, obs_dim); ``state`` is passed through."""
        obs = np.asarray(observations, np.float64)
        if obs.shape[-1] != self.observation_space.shape[0]:
            raise ValueError(
                f"policy {self.name!r} ({self.env_id}) takes {self.observation_space.shape[0]} observation features, "
                f"got {obs.shape[-1]}"
            )
        a, _ = self.policy.predict(self.normalize(obs), deterministic=deterministic)
        if self.action_adapter is not None:
            a = self.action_adapter(obs, a)
        return a, state

    def adapt_to(self, config: Any) -> ShippedPolicy:
        """Drive the task configuration ``config`` (a ``GearSpeedConfig`` of this policy's task): when its action
        settings (mode, ranges, rate, reference filter) differ from ``env_config`` of policy.json, the actions
        go through an :class:`agents.trained.ActionAdapter` (same next omega). Returns self."""
        from .envs import make_config
        from .trained import ActionAdapter

        trained = make_config(self.env_id, self.meta["env_config"])
        self.action_adapter = ActionAdapter(trained, config) if ActionAdapter.needed(trained, config) else None
        return self


def load_policy(folder: str | Path, name: str = "pretrained") -> ShippedPolicy:
    """The shipped policy in ``folder`` (see the module docstring)."""
    return ShippedPolicy(folder, name)


def export_run(run_dir: str | Path, env_id: str, out_dir: str | Path, use_best: bool = True) -> Path:
    """Export a training run (its best evaluated model by default) as a shipped policy of ``env_id``."""
    from .runs import RunFolder
    from .trained import load_ppo_model, load_vecnormalize

    run = RunFolder(run_dir)
    cfg = run.read_config()
    metrics = run.read_metrics()
    stem = "best_model" if use_best else "model"
    model = load_ppo_model(Path(run_dir) / f"{stem}.zip")
    vn = load_vecnormalize(Path(run_dir) / ("best_vecnormalize.npz" if use_best else "vecnormalize.npz"))
    summary = {
        "run": Path(run_dir).name,
        "trained_as": cfg.get("env_id"),
        "train": cfg.get("train"),
        "command": cfg.get("command"),
        "model": stem,
        "ppo": cfg.get("ppo"),
        **({"distill": cfg["distill"]} if "distill" in cfg else {}),
        "metrics": metrics,
    }
    return export_policy(model, vn, env_id, cfg["env_config"], out_dir, summary)


__all__ = ["FORMAT", "ShippedPolicy", "export_policy", "export_run", "load_policy"]
