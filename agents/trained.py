"""A trained PPO model as a policy with the common SB3-style ``predict`` interface.

The observation normalisation learnt during training (``VecNormalize``) is applied here, frozen
(``training=False``; rewards are not normalised at evaluation), so the policy takes the raw
environment observation like every scripted baseline does.
"""

from __future__ import annotations

import os
import pickle
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from .runs import RunFolder, RunFolderError, check_space_compatible


class TrainedPolicy:
    """A PPO model plus its observation normaliser; ``predict(obs, state, episode_start, deterministic)``.

    ``model`` is an SB3 algorithm, ``vecnorm`` a ``VecNormalize`` (or None: no normalisation).
    Observations are normalised with the stored running mean/variance, never updated here."""

    def __init__(
        self,
        model: Any,
        vecnorm: Any = None,
        name: str = "ppo",
        run_config: dict | None = None,
        action_adapter: ActionAdapter | None = None,
    ):
        self.model = model
        self.vecnorm = vecnorm
        self.name = name
        self.run_config = run_config or {}
        self.action_adapter = action_adapter
        self.observation_space = model.observation_space
        self.action_space = model.action_space

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """The observation as the network saw it in training (clipped, standardised), float32."""
        obs = np.asarray(obs, dtype=np.float32)
        if self.vecnorm is None or not getattr(self.vecnorm, "norm_obs", True):
            return obs
        return np.asarray(self.vecnorm.normalize_obs(obs), dtype=np.float32)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Actions for a batch (or a single) observation; same signature as SB3's ``predict``."""
        actions, state = self.model.predict(
            self.normalize(observation), state=state, episode_start=episode_start, deterministic=deterministic
        )
        if self.action_adapter is not None:
            actions = self.action_adapter(observation, actions)
        return actions, state

    def __repr__(self) -> str:
        return f"TrainedPolicy(name={self.name!r})"


class ActionAdapter:
    """Re-express actions meant for one action mode in another (same plant, same next omega).

    A policy trained with ``action_mode="target"`` (its action is a speed set-point) drives an
    environment in ``"delta"`` mode (or the reverse): the intended next omega is computed with the
    training settings and converted to the action that gives the same next omega under the
    evaluation settings. Omega is read from the raw observation (entry 0)."""

    def __init__(self, train_cfg: Any, eval_cfg: Any):
        self.tr = train_cfg
        self.ev = eval_cfg

    @staticmethod
    def needed(train_cfg: Any, eval_cfg: Any) -> bool:
        keys = ("action_mode", "omega_min", "omega_max", "max_domega")
        return any(getattr(train_cfg, k) != getattr(eval_cfg, k) for k in keys)

    def __call__(self, observation: np.ndarray, actions: np.ndarray) -> np.ndarray:
        obs = np.asarray(observation, float)
        single = obs.ndim == 1
        obs2 = obs[None, :] if single else obs
        a = np.clip(np.asarray(actions, float).reshape(len(obs2)), -1.0, 1.0)
        tr, ev = self.tr, self.ev
        w = ev.omega_min + 0.5 * (obs2[:, 0] + 1.0) * (ev.omega_max - ev.omega_min)
        if tr.action_mode == "delta":
            target = w + a * tr.max_domega
        else:
            target = tr.omega_min + 0.5 * (a + 1.0) * (tr.omega_max - tr.omega_min)
            target = np.clip(target, w - tr.max_domega, w + tr.max_domega)
        target = np.clip(target, ev.omega_min, ev.omega_max)
        if ev.action_mode == "delta":
            out = (target - w) / ev.max_domega
        else:
            out = 2.0 * (target - ev.omega_min) / (ev.omega_max - ev.omega_min) - 1.0
        out = np.clip(out, -1.0, 1.0).astype(np.float32).reshape(-1, 1)
        return out[0] if single else out


def load_vecnormalize(path: str | os.PathLike) -> Any:
    """Unpickle VecNormalize statistics without an environment, frozen (training=False, norm_reward=False)."""
    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(path, "rb") as fh:
            vn = pickle.load(fh)
    except FileNotFoundError as exc:
        raise RunFolderError(f"normalisation statistics {str(path)!r} are missing") from exc
    except Exception as exc:  # pickle raises many types on a corrupt file
        raise RunFolderError(f"corrupt normalisation statistics {str(path)!r}: {type(exc).__name__}: {exc}") from exc
    if not isinstance(vn, VecNormalize):
        raise RunFolderError(f"{str(path)!r} does not hold VecNormalize statistics (found {type(vn).__name__})")
    vn.training = False
    vn.norm_reward = False
    return vn


def load_ppo_model(path: str | os.PathLike, device: str = "cpu") -> Any:
    """Load an SB3 PPO zip with a clear :class:`RunFolderError` if missing or corrupt."""
    from stable_baselines3 import PPO

    p = Path(path)
    if not p.is_file():
        raise RunFolderError(f"model file {str(p)!r} is missing")
    try:
        return PPO.load(str(p), device=device)
    except (zipfile.BadZipFile, EOFError, KeyError, ValueError, RuntimeError, pickle.UnpicklingError) as exc:
        raise RunFolderError(f"corrupt model file {str(p)!r}: {type(exc).__name__}: {exc}") from exc


def load_trained_policy(
    run_dir: str | os.PathLike, env_config: Any = None, name: str | None = None, model_file: str = "model.zip"
) -> TrainedPolicy:
    """Load the policy of a run folder (model.zip + vecnormalize.pkl + config.json).

    ``model_file`` picks another model of the folder: ``best_model.zip`` (the best evaluation during
    training, with ``best_vecnormalize.pkl``) or a checkpoint ``checkpoints/ckpt_<steps>.zip`` (with
    its ``_vecnormalize.pkl``). If ``env_config`` is given, the environment it describes must have
    the observation and action spaces the model was trained on; otherwise a
    :class:`RunFolderError` explains the mismatch. A model trained in the other action mode (or
    with another omega range or rate) is wrapped in an :class:`ActionAdapter`."""
    import torch

    torch.set_num_threads(1)
    run = RunFolder(run_dir)
    cfg = run.read_config()
    mpath = run.path / model_file
    if model_file == "model.zip":
        vpath = run.vecnorm_path
    elif model_file == "best_model.zip":
        vpath = run.path / "best_vecnormalize.pkl"
    else:
        vpath = mpath.with_name(mpath.stem + "_vecnormalize.pkl")
    if model_file == "model.zip" and not mpath.is_file() and (run.checkpoint_dir / "latest.json").is_file():
        raise RunFolderError(
            f"{str(run.path)!r} has no model.zip (training did not finish); evaluate its last checkpoint "
            f"({str(run.checkpoint_dir)}/ckpt_<steps>.zip) or continue it with "
            f"`gear-env train --out {run.path} --resume`"
        )
    model = load_ppo_model(mpath)
    vecnorm = load_vecnormalize(vpath) if cfg.get("vecnormalize", True) else None
    check_space_compatible(cfg["observation_space"], model.observation_space, "observation", run_dir)
    if vecnorm is not None and tuple(vecnorm.obs_rms.mean.shape) != tuple(model.observation_space.shape):
        raise RunFolderError(
            f"corrupt run folder {str(run_dir)!r}: normalisation statistics have shape "
            f"{tuple(vecnorm.obs_rms.mean.shape)}, the model expects {tuple(model.observation_space.shape)}"
        )
    adapter = None
    if env_config is not None:
        from .envs import GEAR_ENV_IDS, make_config, make_env

        env = make_env(cfg["env_id"], env_config)
        try:
            check_space_compatible(cfg["observation_space"], env.observation_space, "observation", run_dir)
            check_space_compatible(cfg["action_space"], env.action_space, "action", run_dir)
        finally:
            env.close()
        if cfg["env_id"] in GEAR_ENV_IDS:
            tr, ev = make_config(cfg["env_id"], cfg["env_config"]), make_config(cfg["env_id"], env_config)
            if ActionAdapter.needed(tr, ev):
                adapter = ActionAdapter(tr, ev)
    return TrainedPolicy(model, vecnorm, name=name or Path(run_dir).name, run_config=cfg, action_adapter=adapter)


__all__ = ["ActionAdapter", "TrainedPolicy", "load_ppo_model", "load_trained_policy", "load_vecnormalize"]
