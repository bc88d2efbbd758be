"""A trained PPO model as a policy with the common SB3-style ``predict`` interface.

The observation normalisation learnt during training (``VecNormalize``) is applied here, frozen
(``training=False``; rewards are not normalised at evaluation), so the policy takes the raw
environment observation like every scripted baseline does.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gear_env.envs.env_terms import action_bounds
from gear_env.io import parse_json_text

from .baselines import OBS_DEMAND
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
    environment in ``"delta"`` mode (or the reverse), or one trained with a speed limit, another omega or
    action range, rate limit or reference filter drives the task's defaults: the intended next omega is
    computed with the training settings (filter and rate limit included) and converted to the action that
    gives the same next omega under the evaluation settings (the set-point whose filtered step lands on it).
    Omega and the demand are read from the raw observation."""

    def __init__(self, train_cfg: Any, eval_cfg: Any):
        if train_cfg.action_mode == "limit" and eval_cfg.demand is None:
            raise ValueError(
                'a policy trained with action_mode "limit" sets a speed limit under a demand: evaluate it on a task '
                "with a demand (the evaluation configuration has demand None)"
            )
        if "limit_rate" in (train_cfg.action_mode, eval_cfg.action_mode):
            raise ValueError(
                'actions cannot be re-expressed to or from action_mode "limit_rate" (the action moves a speed limit '
                f"the adapter does not see; action_mode {train_cfg.action_mode!r} in training, "
                f"{eval_cfg.action_mode!r} here): evaluate the policy with the action settings it was trained with"
            )
        delays = (getattr(train_cfg, "action_delay", 0), getattr(eval_cfg, "action_delay", 0))
        if any(delays):
            raise ValueError(
                f"actions cannot be re-expressed across action settings under an actuator dead time (action_delay "
                f"{delays[0]} in training, {delays[1]} here): an action reaches the drive steps later, from a speed "
                "the adapter does not know; evaluate the policy with the action settings it was trained with"
            )
        from gear_env.envs.env_terms import ACTION_CODES

        self.tr = train_cfg
        self.ev = eval_cfg
        self.settings = train_cfg.TERMS.settings_vector(train_cfg)  # for env_kernels.decode_actions
        self.mode = ACTION_CODES[train_cfg.action_mode]

    @staticmethod
    def needed(train_cfg: Any, eval_cfg: Any) -> bool:
        keys = ("action_mode", "omega_min", "omega_max", "max_domega", "action_range", "reference_filter", "limit_rate")
        return any(getattr(train_cfg, k) != getattr(eval_cfg, k) for k in keys)

    def __call__(self, observation: np.ndarray, actions: np.ndarray) -> np.ndarray:
        obs = np.asarray(observation, float)
        single = obs.ndim == 1
        obs2 = obs[None, :] if single else obs
        from gear_env.envs.env_kernels import decode_actions

        a = np.clip(np.asarray(actions, float).reshape(len(obs2)), -1.0, 1.0)
        tr, ev = self.tr, self.ev
        w = ev.omega_min + 0.5 * (obs2[:, 0] + 1.0) * (ev.omega_max - ev.omega_min)
        # the next omega the action means under the training settings: the environment's own decoder
        if tr.action_mode == "limit":  # a speed limit: the drive follows the demand (observed) under it
            demand = ev.omega_min + 0.5 * (obs2[:, OBS_DEMAND] + 1.0) * (ev.omega_max - ev.omega_min)
        else:
            demand = np.full_like(w, tr.omega_max)
        nxt = np.empty_like(w)
        decode_actions(w, a, demand, self.settings, self.mode, nxt)
        nxt = np.clip(nxt, ev.omega_min, ev.omega_max)
        # ... and the action that moves there under the evaluation settings (the set-point whose filtered step
        # lands on it)
        if ev.action_mode == "delta":
            out = (nxt - w) / ev.max_domega
        else:
            elo, ehi = action_bounds(ev)
            out = 2.0 * (w + (nxt - w) / ev.reference_filter - elo) / (ehi - elo) - 1.0
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
MAX_MODEL_MEMBER = 64 * 1024 * 1024
"""Largest declared uncompressed size of any other member of a model zip (bytes)."""
MAX_MODEL_BYTES = 128 * 1024 * 1024
"""Largest model zip (on disk, and its members' declared uncompressed total; bytes)."""
MAX_ROLLOUT_STEPS = 2**21
"""Most ``n_steps * n_envs`` of a loaded model (its rollout buffer is allocated on load)."""
MAX_POLICY_PARAMETERS = 4_000_000
"""Most weights of a loaded policy network (actor + critic), checked before it is built."""
MODEL_MEMBERS = (
    "data",
    "pytorch_variables.pth",
    "policy.pth",
    "policy.optimizer.pth",
    "_stable_baselines3_version",
    "system_info.txt",
)
"""The members of an SB3 PPO zip; any other member is refused."""

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


def _opt(check: Any) -> Any:
    """A field check that also accepts null."""
    return lambda v, p, f: None if v is None else check(v, p, f)


def _serialized(v: Any, p: str, f: str) -> None:
    from gear_env.untrusted import refuse

    if not (isinstance(v, dict) and ":serialized:" in v) and v is not None:
        raise refuse(p, f, "must be a serialised entry (it is replaced, never unpickled)")


def _policy_kwargs(v: Any, p: str, f: str) -> None:
    from gear_env.untrusted import check_keys, layer_sizes, want_num

    check_keys(v, ("net_arch", "log_std_init", "optimizer_kwargs"), p, f)
    arch = v.get("net_arch", [64, 64])
    if isinstance(arch, dict):
        check_keys(arch, ("pi", "vf"), p, f"{f}.net_arch", required=("pi", "vf"))
        layer_sizes(arch["pi"], p, f"{f}.net_arch.pi")
        layer_sizes(arch["vf"], p, f"{f}.net_arch.vf")
    else:
        layer_sizes(arch, p, f"{f}.net_arch")
    if "log_std_init" in v:
        want_num(v["log_std_init"], -20.0, 5.0, p, f"{f}.log_std_init")
    if "optimizer_kwargs" in v:
        ok = check_keys(v["optimizer_kwargs"], ("eps", "weight_decay"), p, f"{f}.optimizer_kwargs")
        for k in ok:
            want_num(ok[k], 0.0, 1.0, p, f"{f}.optimizer_kwargs.{k}")


def _model_fields() -> dict[str, Any]:
    """The known keys of a PPO zip's ``data`` and the check of each (anything else is refused)."""
    from gear_env.untrusted import refuse, want_bool, want_int, want_num, want_str

    big = 2**62

    def num(lo: float, hi: float, lo_open: bool = False) -> Any:
        return lambda v, p, f: want_num(v, lo, hi, p, f, lo_open)

    def integer(lo: int, hi: int) -> Any:
        return lambda v, p, f: want_int(v, lo, hi, p, f)

    def empty_dict(v: Any, p: str, f: str) -> None:
        if v != {}:
            raise refuse(p, f, "must be an empty object")

    def null(v: Any, p: str, f: str) -> None:
        if v is not None:
            raise refuse(p, f, "must be null")

    fields: dict[str, Any] = {k: _serialized for k in SAFE_ENTRIES}
    fields.update(
        verbose=integer(0, 2), policy_kwargs=_policy_kwargs, num_timesteps=integer(0, big),
        _total_timesteps=integer(0, big), _num_timesteps_at_start=integer(0, big),
        seed=_opt(integer(0, 2**32 - 1)), action_noise=null, start_time=integer(0, big),
        learning_rate=num(0.0, 1.0, True), tensorboard_log=_opt(lambda v, p, f: want_str(v, p, f, max_len=4096)),
        _episode_num=integer(0, big), use_sde=lambda v, p, f: want_bool(v, p, f),
        sde_sample_freq=integer(-1, 1_000_000), _current_progress_remaining=num(-10.0, 1.0),
        _stats_window_size=integer(1, 100_000), _n_updates=integer(0, big), n_envs=integer(1, 1024),
        n_steps=integer(1, MAX_ROLLOUT_STEPS), gamma=num(0.0, 1.0), gae_lambda=num(0.0, 1.0),
        ent_coef=num(0.0, 100.0), vf_coef=num(0.0, 100.0), max_grad_norm=num(0.0, 1e6, True),
        rollout_buffer_kwargs=empty_dict, batch_size=integer(1, MAX_ROLLOUT_STEPS), n_epochs=integer(1, 10_000),
        clip_range_vf=_opt(num(0.0, 10.0, True)), normalize_advantage=lambda v, p, f: want_bool(v, p, f),
        target_kl=_opt(num(0.0, 100.0, True)),
    )  # fmt: skip
    return fields


def check_model_zip(path: str | os.PathLike) -> tuple[bytes, dict[str, Any]]:
    """(the zip's bytes, its ``data`` attributes) after every check of an untrusted SB3 PPO zip.

    The archive: at most :data:`MAX_MODEL_BYTES` on disk and declared in all, known members only
    (:data:`MODEL_MEMBERS`), each member's declared size bounded before it is inflated; the torch
    archives inside it stored (uncompressed) and bounded the same way. The ``data`` attributes:
    known keys only, each type and range checked (an unknown ``policy_kwargs`` key is refused, not
    passed on; ``n_steps * n_envs`` at most :data:`MAX_ROLLOUT_STEPS`, the network at most
    :data:`MAX_POLICY_PARAMETERS` weights for the spaces it declares is checked by the loader).
    :class:`RunFolderError` naming the file and the field otherwise."""
    from gear_env.untrusted import open_zip, read_member, read_regular, refuse

    p = os.fspath(path)
    raw = read_regular(p, "model file", MAX_MODEL_BYTES)
    try:
        z = open_zip(
            raw, "model file", allowed=MODEL_MEMBERS, required=("data", "policy.pth"),
            max_member=MAX_MODEL_MEMBER, max_total=MAX_MODEL_BYTES, path=p,
        )  # fmt: skip
        with z:
            if z.getinfo("data").file_size > MAX_MODEL_DATA:
                raise refuse(p, "data", f"{z.getinfo('data').file_size:,} bytes; the limit is {MAX_MODEL_DATA:,}")
            text = read_member(z, "data", p)
            for member in ("policy.pth", "policy.optimizer.pth", "pytorch_variables.pth"):
                if member in z.namelist():
                    inner = read_member(z, member, p)
                    open_zip(
                        inner, "torch archive", max_member=MAX_MODEL_MEMBER, max_total=MAX_MODEL_MEMBER,
                        stored_only=True, path=f"{p}:{member}",
                    ).close()  # fmt: skip
        data = parse_json_text(text.decode("utf-8"), f"model file {p!r}: data")
    except UnicodeDecodeError as exc:
        raise RunFolderError(f"corrupt model file {p!r}: data: not UTF-8 text ({exc})") from None
    except ValueError as exc:
        raise RunFolderError(f"corrupt model file {exc}") from None
    if not isinstance(data, dict):
        raise RunFolderError(f"corrupt model file {p!r}: data: not a JSON object")
    fields = _model_fields()
    unknown = sorted(k for k in data if k not in fields)
    if unknown:
        pickled = [k for k in unknown if isinstance(data[k], dict) and ":serialized:" in data[k]]
        if pickled:
            raise RunFolderError(
                f"model file {p!r} holds pickled entries {pickled} that gear-env does not load "
                f"(a pickle can run code); only models trained by gear-env are accepted"
            )
        raise RunFolderError(f"corrupt model file {p!r}: data.{unknown[0]}: unknown attribute of a PPO model; refused")
    try:
        for k, v in data.items():
            fields[k](v, p, f"data.{k}")
        for k in ("observation_space", "action_space", "policy_class"):
            if k not in data:
                raise refuse(p, f"data.{k}", "missing")
    except ValueError as exc:
        raise RunFolderError(f"corrupt model file {exc}") from None
    pc = data.get("policy_class") or {}
    if pc.get("__module__", "stable_baselines3.common.policies") != "stable_baselines3.common.policies":
        raise RunFolderError(f"model file {p!r} was not trained with SB3's MlpPolicy (ActorCriticPolicy)")
    n_steps, n_envs = data.get("n_steps", 1), data.get("n_envs", 1)
    if n_steps * n_envs > MAX_ROLLOUT_STEPS:
        raise RunFolderError(
            f"corrupt model file {p!r}: data.n_steps: n_steps x n_envs = {n_steps} x {n_envs} exceeds "
            f"{MAX_ROLLOUT_STEPS:,} (the rollout buffer is allocated on load)"
        )
    return raw, data


def _check_network_size(path: str, data: Mapping[str, Any], obs_space: Any, act_space: Any) -> None:
    """Refuse a network of more than :data:`MAX_POLICY_PARAMETERS` weights before it is built."""
    from gear_env.untrusted import mlp_parameters

    arch = (data.get("policy_kwargs") or {}).get("net_arch", [64, 64])
    pi, vf = (arch["pi"], arch["vf"]) if isinstance(arch, dict) else (arch, arch)
    n_in, n_out = int(np.prod(obs_space.shape)), int(np.prod(act_space.shape))
    n = mlp_parameters(n_in, pi, n_out) + mlp_parameters(n_in, vf, 1)
    if n > MAX_POLICY_PARAMETERS:
        raise RunFolderError(
            f"corrupt model file {path!r}: data.policy_kwargs.net_arch: a network of {n:,} weights; "
            f"the limit is {MAX_POLICY_PARAMETERS:,}"
        )


def _safe_custom_objects(path: Path, run_config: Mapping[str, Any], data: Mapping[str, Any]) -> dict[str, Any]:
    """``custom_objects`` for ``PPO.load`` covering every cloudpickled entry of the zip's ``data``.

    The policy class, spaces, schedules and buffer class are rebuilt from ``run_config`` (the run
    folder's config.json); transient training state (last observation, episode buffers) becomes None
    and is rebuilt by SB3; the TensorBoard folder named in the file is dropped (it could point
    anywhere). ``data`` was checked by :func:`check_model_zip`."""
    from stable_baselines3.common.buffers import RolloutBuffer
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.utils import FloatSchedule

    ppo = dict(run_config.get("ppo") or {})
    clip = ppo.get("clip_range", 0.2)
    lr = data.get("learning_rate", ppo.get("learning_rate", 3e-4))
    for name, v in (("clip_range", clip), ("learning_rate", lr)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise RunFolderError(f"model file {str(path)!r}: {name} must be a number, got {v!r}")
    obs_space = space_from_dict(run_config["observation_space"])
    act_space = space_from_dict(run_config["action_space"])
    _check_network_size(str(path), data, obs_space, act_space)
    return {
        "policy_class": ActorCriticPolicy,
        "observation_space": obs_space,
        "action_space": act_space,
        "lr_schedule": FloatSchedule(float(lr)),
        "clip_range": float(clip),
        "rollout_buffer_class": RolloutBuffer,
        "_last_obs": None,
        "_last_episode_starts": None,
        "_last_original_obs": None,
        "ep_info_buffer": None,
        "ep_success_buffer": None,
        "tensorboard_log": None,
    }


def load_ppo_model(path: str | os.PathLike, device: str = "cpu", run_config: Mapping[str, Any] | None = None) -> Any:
    """Load an SB3 PPO zip without unpickling anything from it.

    The zip is checked first (:func:`check_model_zip`: archive sizes, known members and attributes,
    bounded network); every cloudpickled entry is replaced (``custom_objects``) by an object rebuilt
    from ``run_config`` (the run folder's config.json; read from the zip's folder, or its parent for
    a checkpoint, when None); the network weights are read by SB3 with ``torch.load(weights_only=True)``
    from the bytes that were checked. :class:`RunFolderError` (a ValueError) if the file is missing,
    corrupt, holds other pickles or an unknown or out-of-range field."""
    import io

    from stable_baselines3 import PPO

    p = Path(path)
    if not p.is_file():
        raise RunFolderError(f"model file {str(p)!r} is missing")
    if device not in ("cpu", "auto"):
        raise ValueError(f"device must be 'cpu' or 'auto', got {device!r}")
    if run_config is None:
        folder = p.parent.parent if p.parent.name == "checkpoints" else p.parent
        run_config = RunFolder(folder).read_config()
    raw, data = check_model_zip(p)
    custom = _safe_custom_objects(p, run_config, data)
    try:
        return PPO.load(io.BytesIO(raw), device="cpu", custom_objects=custom)
    except Exception as exc:  # checked above; whatever SB3 or torch still objects to is a corrupt file
        raise RunFolderError(f"corrupt model file {str(p)!r}: {type(exc).__name__}: {exc}") from None


def load_trained_policy(
    run_dir: str | os.PathLike, env_config: Any = None, name: str | None = None, model_file: str = "model.zip"
) -> TrainedPolicy:
    """Load the policy of a run folder (model.zip + vecnormalize.npz + config.json); nothing is unpickled.

    ``model_file`` picks another model of the folder: ``best_model.zip`` (the best evaluation during
    training, with ``best_vecnormalize.pkl``) or a checkpoint ``checkpoints/ckpt_<steps>.zip`` (with
    its ``_vecnormalize.npz``). If ``env_config`` is given, the environment it describes must have
    the observation and action spaces the model was trained on; otherwise a
    :class:`RunFolderError` explains the mismatch. A model trained in the other action mode (or
    with another omega range, rate or reference filter) is wrapped in an :class:`ActionAdapter`."""
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
    run.confined(mpath, model_file)
    run.confined(vpath, vpath.name)
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


def evaluate_model(
    model: Any, train_vecnorm: Any, eval_venv: Any, episodes: int, seed: int | None = None
) -> dict[str, Any]:
    """Deterministic evaluation of ``model`` on ``eval_venv`` with the (frozen) observation
    statistics of ``train_vecnorm``; mean/std of the raw episode return and of the settled omega.

    ``seed`` reseeds the evaluation environments first, so every evaluation sees the same episodes."""
    from stable_baselines3.common.vec_env import VecNormalize

    from .rollout import run_episodes

    vn = train_vecnorm if isinstance(train_vecnorm, VecNormalize) else None
    policy = TrainedPolicy(model, _frozen_copy(vn) if vn is not None else None)
    if seed is not None:
        eval_venv.seed(int(seed))
    eps = run_episodes(policy, eval_venv, episodes, deterministic=True)
    rets = np.array([e["return"] for e in eps])
    row: dict[str, Any] = {
        "timesteps": int(model.num_timesteps),
        "return_mean": float(rets.mean()),
        "return_std": float(rets.std()),
        "episodes": len(eps),
    }
    so = [e["settled_omega"] for e in eps if e["settled_omega"] is not None]
    if so:
        row["settled_omega_mean"] = float(np.mean(so))
        row["settled_omega_std"] = float(np.std(so))
    cf = [e["chaotic_fraction"] for e in eps if e["chaotic_fraction"] is not None]
    if cf:
        row["chaotic_fraction_mean"] = float(np.mean(cf))
    return row


def _frozen_copy(vn: Any) -> Any:
    """A detached copy of the observation statistics of a VecNormalize (not updated by evaluation)."""
    import copy

    from stable_baselines3.common.vec_env import VecNormalize

    c = VecNormalize.__new__(VecNormalize)
    c.obs_rms = copy.deepcopy(vn.obs_rms)
    c.clip_obs = vn.clip_obs
    c.epsilon = vn.epsilon
    c.norm_obs = vn.norm_obs
    c.norm_obs_keys = getattr(vn, "norm_obs_keys", None)
    c.training = False
    c.norm_reward = False
    return c


__all__ = [
    "ActionAdapter",
    "TrainedPolicy",
    "evaluate_model",
    "load_ppo_model",
    "load_trained_policy",
    "load_vecnormalize",
]
