"""A trained PPO model as a policy with the common SB3-style ``predict`` interface.

The observation normalisation learnt during training (``VecNormalize``) is applied here, frozen
(``training=False``; rewards are not normalised at evaluation), so the policy takes the raw
environment observation like every scripted baseline does.
"""

from __future__ import annotations

import os
import pickle
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gear_env.io import parse_json_text

from .policy import BasePolicy
from .runs import RunFolder, RunFolderError, check_space_compatible, read_vecnormalize_stats, space_from_dict


class TrainedPolicy(BasePolicy):
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

    def predict_batch(
        self, observations: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        """Actions (n, act_dim) of the network for raw observations (n, obs_dim)."""
        actions, state = self.model.predict(
            self.normalize(observations), state=state, episode_start=episode_start, deterministic=deterministic
        )
        if self.action_adapter is not None:
            actions = self.action_adapter(observations, actions)
        return actions, state


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


def load_vecnormalize(path: str | os.PathLike, venv: Any = None) -> Any:
    """VecNormalize statistics from a ``.npz`` (never a pickle); frozen unless ``venv`` is given.

    Without ``venv``: an object that only normalises observations (``training=False``,
    ``norm_reward=False``) for evaluation. With ``venv``: a ``VecNormalize`` around it carrying
    the stored statistics and settings (for ``train --resume``). :class:`RunFolderError` if the
    file is missing, pickled, corrupt or does not fit ``venv``."""
    from stable_baselines3.common.running_mean_std import RunningMeanStd
    from stable_baselines3.common.vec_env import VecNormalize

    st = read_vecnormalize_stats(path)

    def rms(mean: np.ndarray, var: np.ndarray, count: float) -> RunningMeanStd:
        r = RunningMeanStd(shape=mean.shape)
        r.mean, r.var, r.count = mean.copy(), var.copy(), count
        return r

    if venv is None:
        vn = VecNormalize.__new__(VecNormalize)
        vn.norm_obs_keys = None
    else:
        if tuple(venv.observation_space.shape) != st["obs_mean"].shape:
            raise RunFolderError(
                f"normalisation statistics {str(path)!r} have shape {st['obs_mean'].shape}, "
                f"the environment's observations {tuple(venv.observation_space.shape)}"
            )
        vn = VecNormalize(
            venv,
            norm_obs=st["norm_obs"],
            norm_reward=st["norm_reward"],
            clip_obs=st["clip_obs"],
            clip_reward=st["clip_reward"],
            gamma=st["gamma"],
            epsilon=st["epsilon"],
        )
    vn.obs_rms = rms(st["obs_mean"], st["obs_var"], st["obs_count"])
    vn.ret_rms = rms(st["ret_mean"], st["ret_var"], st["ret_count"])
    vn.clip_obs, vn.clip_reward, vn.epsilon, vn.gamma = st["clip_obs"], st["clip_reward"], st["epsilon"], st["gamma"]
    vn.norm_obs = st["norm_obs"]
    if venv is None:
        vn.training = False
        vn.norm_reward = False
    else:
        vn.norm_reward = st["norm_reward"]
    return vn


MAX_MODEL_DATA = 8 * 1024 * 1024
"""Largest ``data`` entry (the JSON of attributes) of a model zip that is read (bytes)."""

SAFE_ENTRIES = (
    "policy_class",
    "observation_space",
    "action_space",
    "lr_schedule",
    "clip_range",
    "rollout_buffer_class",
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
)
"""The pickled entries of a PPO zip that gear-env replaces with its own objects (none is unpickled).
Any other pickled entry is refused."""


def _safe_custom_objects(path: Path, run_config: Mapping[str, Any]) -> dict[str, Any]:
    """``custom_objects`` for ``PPO.load`` covering every cloudpickled entry of the zip's ``data``.

    The policy class, spaces, schedules and buffer class are rebuilt from ``run_config`` (the run
    folder's config.json); transient training state (last observation, episode buffers) becomes None
    and is rebuilt by SB3. A zip with any other pickled entry raises :class:`RunFolderError`."""
    from stable_baselines3.common.buffers import RolloutBuffer
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.utils import FloatSchedule

    try:
        with zipfile.ZipFile(path) as z:
            info = z.getinfo("data")
            if info.file_size > MAX_MODEL_DATA:
                raise RunFolderError(f"model file {str(path)!r}: its data entry is {info.file_size:,} bytes, too large")
            text = z.read("data").decode("utf-8")
    except (zipfile.BadZipFile, KeyError, OSError, UnicodeDecodeError, EOFError) as exc:
        raise RunFolderError(f"corrupt model file {str(path)!r}: {type(exc).__name__}: {exc}") from exc
    try:
        data = parse_json_text(text, f"model file {str(path)!r}")
    except ValueError as exc:
        raise RunFolderError(str(exc)) from None
    if not isinstance(data, dict):
        raise RunFolderError(f"corrupt model file {str(path)!r}: its data entry is not a JSON object")
    pickled = sorted(k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v)
    unknown = [k for k in pickled if k not in SAFE_ENTRIES]
    if unknown:
        raise RunFolderError(
            f"model file {str(path)!r} holds pickled entries {unknown} that gear-env does not load "
            f"(a pickle can run code); only models trained by gear-env are accepted"
        )
    if data.get("policy_class", {}).get("__module__", "stable_baselines3.common.policies") != (
        "stable_baselines3.common.policies"
    ):
        raise RunFolderError(f"model file {str(path)!r} was not trained with SB3's MlpPolicy (ActorCriticPolicy)")
    ppo = dict(run_config.get("ppo") or {})
    clip = ppo.get("clip_range", 0.2)
    lr = data.get("learning_rate", ppo.get("learning_rate", 3e-4))
    for name, v in (("clip_range", clip), ("learning_rate", lr)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise RunFolderError(f"model file {str(path)!r}: {name} must be a number, got {v!r}")
    return {
        "policy_class": ActorCriticPolicy,
        "observation_space": space_from_dict(run_config["observation_space"]),
        "action_space": space_from_dict(run_config["action_space"]),
        "lr_schedule": FloatSchedule(float(lr)),
        "clip_range": float(clip),
        "rollout_buffer_class": RolloutBuffer,
        "_last_obs": None,
        "_last_episode_starts": None,
        "_last_original_obs": None,
        "ep_info_buffer": None,
        "ep_success_buffer": None,
    }


def load_ppo_model(path: str | os.PathLike, device: str = "cpu", run_config: Mapping[str, Any] | None = None) -> Any:
    """Load an SB3 PPO zip without unpickling anything from it.

    Every cloudpickled entry of the zip is replaced (``custom_objects``) by an object rebuilt from
    ``run_config`` (the run folder's config.json; read from the zip's folder, or its parent for a
    checkpoint, when None); the network weights are read by SB3 with ``torch.load(weights_only=True)``.
    :class:`RunFolderError` (a ValueError) if the file is missing, corrupt or holds other pickles."""
    from stable_baselines3 import PPO

    p = Path(path)
    if not p.is_file():
        raise RunFolderError(f"model file {str(p)!r} is missing")
    if run_config is None:
        folder = p.parent.parent if p.parent.name == "checkpoints" else p.parent
        run_config = RunFolder(folder).read_config()
    custom = _safe_custom_objects(p, run_config)
    try:
        return PPO.load(str(p), device=device, custom_objects=custom)
    except (zipfile.BadZipFile, EOFError, KeyError, ValueError, RuntimeError, pickle.UnpicklingError) as exc:
        raise RunFolderError(f"corrupt model file {str(p)!r}: {type(exc).__name__}: {exc}") from exc


def load_trained_policy(
    run_dir: str | os.PathLike, env_config: Any = None, name: str | None = None, model_file: str = "model.zip"
) -> TrainedPolicy:
    """Load the policy of a run folder (model.zip + vecnormalize.npz + config.json); nothing is unpickled.

    ``model_file`` picks another model of the folder: ``best_model.zip`` (the best evaluation during
    training, with ``best_vecnormalize.pkl``) or a checkpoint ``checkpoints/ckpt_<steps>.zip`` (with
    its ``_vecnormalize.npz``). If ``env_config`` is given, the environment it describes must have
    the observation and action spaces the model was trained on; otherwise a
    :class:`RunFolderError` explains the mismatch. A model trained in the other action mode (or
    with another omega range or rate) is wrapped in an :class:`ActionAdapter`."""
    import torch

    torch.set_num_threads(1)
    run = RunFolder(run_dir)
    cfg = run.read_config()
    mpath = run.path / model_file
    if not mpath.resolve().is_relative_to(run.path.resolve()):
        raise RunFolderError(f"model file {model_file!r} is outside the run folder {str(run.path)!r}; not loaded")
    if model_file == "model.zip":
        vpath = run.vecnorm_path
    elif model_file == "best_model.zip":
        vpath = run.path / "best_vecnormalize.npz"
    else:
        vpath = mpath.with_name(mpath.stem + "_vecnormalize.npz")
    if model_file == "model.zip" and not mpath.is_file() and (run.checkpoint_dir / "latest.json").is_file():
        raise RunFolderError(
            f"{str(run.path)!r} has no model.zip (training did not finish); evaluate its last checkpoint "
            f"({str(run.checkpoint_dir)}/ckpt_<steps>.zip) or continue it with "
            f"`gear-env train --out {run.path} --resume`"
        )
    model = load_ppo_model(mpath, run_config=cfg)
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
