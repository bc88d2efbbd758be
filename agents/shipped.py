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

import json
from pathlib import Path
from typing import Any

import numpy as np

from .policy import BasePolicy

FORMAT = "gear-env-policy/1"
ACTIVATIONS = ("Tanh", "ReLU")


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
    """A shipped policy: frozen observation normalisation + the SB3 actor-critic network."""

    def __init__(self, folder: str | Path, name: str = "pretrained"):
        import torch
        from gymnasium import spaces
        from stable_baselines3.common.policies import ActorCriticPolicy

        self.folder = Path(folder)
        self.name = name
        try:
            meta = json.loads((self.folder / "policy.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ValueError(f"{str(self.folder / 'policy.json')!r} is missing or not JSON: {exc}") from None
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise ValueError(f"{str(self.folder / 'policy.json')!r} is not a {FORMAT} policy description")
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
        try:
            state = torch.load(self.folder / "policy.pt", map_location="cpu", weights_only=True)
            self.policy.load_state_dict(state)
        except Exception as exc:  # a corrupt or foreign file: one clear message
            raise ValueError(
                f"{str(self.folder / 'policy.pt')!r} is not a valid state dict of this network: {exc}"
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
        return a, state


def load_policy(folder: str | Path, name: str = "pretrained") -> ShippedPolicy:
    """The shipped policy in ``folder`` (see the module docstring)."""
    return ShippedPolicy(folder, name)


def export_run(run_dir: str | Path, env_id: str, out_dir: str | Path, use_best: bool = True) -> Path:
    """Export a training run (its best evaluated model by default) as a shipped policy of ``env_id``."""
    from .runs import RunFolder
    from .trained import load_ppo_model, load_vecnormalize

    run = RunFolder(run_dir)
    cfg = run.read_config()
    metrics = {}
    mpath = Path(run_dir) / "metrics.json"
    if mpath.is_file():
        metrics = json.loads(mpath.read_text(encoding="utf-8"))
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
        "metrics": metrics,
    }
    return export_policy(model, vn, env_id, cfg["env_config"], out_dir, summary)


__all__ = ["FORMAT", "ShippedPolicy", "export_policy", "export_run", "load_policy"]
