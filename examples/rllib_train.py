"""Train PPO with RLlib on the gear speed-scheduling task and compare it with the SB3 agent.

RLlib builds each EnvRunner's environments with ``gym.make_vec(env_id, num_envs,
vectorization_mode=...)``; with ``gym_env_vectorize_mode="vector_entry_point"`` that is the
package's native vector env (``gear_env.envs.vector_env.GearSpeedVectorEnv``: every sub-environment of a
runner advanced in one numba call), not a ``SyncVectorEnv`` of single envs. The env id is given as
``gear_env:<env id>``, so Gymnasium imports ``gear_env`` (which registers the id) in every Ray
worker, on every node.

The task is ``GearSpeed-v1`` by default (``--env-id`` for another), and RLlib's PPO takes the values of
that task's entry in ``agents/hyperparams/ppo.yml``, the file the SB3 agent is trained from
(:func:`ppo_settings`), so the two agents differ in their library, not in their settings.

After training, the deterministic RLlib policy (the mean of its Gaussian) and an SB3 policy (default:
the shipped ``pretrained`` one) are rolled out by ``gear_env.evaluation.evaluate_policies`` on the
same episode seeds, and everything is written to one JSON file.

Run it in a Python environment with ``pip install -e '.[rllib]'`` (RLlib pins its own Gymnasium
version; docs/TRAINING.md, "RLlib"):

    python examples/rllib_train.py --timesteps 200000 --num-env-runners 2 --num-envs-per-runner 8 \\
        --out runs/rllib_ppo.json

    # on a running Ray cluster (ray start --head ... / ray start --address=HEAD:6379 on the workers)
    python examples/rllib_train.py --address auto --num-env-runners 8 --out runs/rllib_ppo.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

ENV_ID = "GearSpeed-v1"
"""The task trained by default (the well-posed default task; ``--env-id`` takes any registered one)."""

HYPERPARAMS = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "agents", "hyperparams", "ppo.yml")
"""rl-zoo3 hyper-parameter file whose entry for the task gives RLlib's PPO settings (one source for both)."""

_RLLIB_NAMES = {
    "learning_rate": "lr",
    "gamma": "gamma",
    "gae_lambda": "lambda_",
    "clip_range": "clip_param",
    "ent_coef": "entropy_coeff",
    "vf_coef": "vf_loss_coeff",
    "max_grad_norm": "grad_clip",
    "n_epochs": "num_epochs",
    "batch_size": "minibatch_size",
}
"""SB3 / rl-zoo3 PPO names -> RLlib ``PPOConfig.training`` names."""


def ppo_settings(env_id: str = ENV_ID, hyperparams: str | os.PathLike = HYPERPARAMS) -> dict[str, Any]:
    """RLlib PPO settings from the task's entry of the rl-zoo3 file (the values the SB3 agent trains with).

    Returns ``{"training": {lr, gamma, lambda_, clip_param, entropy_coeff, vf_loss_coeff, grad_clip,
    num_epochs, minibatch_size}, "fcnet_hiddens": [...]}``. Not carried over: SB3's ``n_steps`` (the
    batch comes from the runners, see :func:`build_config`) and ``log_std_init`` (RLlib's default
    model has no initial log-std setting: its std starts at 1)."""
    from agents.hyperparams import load_zoo_entry

    ppo = load_zoo_entry(hyperparams, env_id)["ppo"]
    training = {_RLLIB_NAMES[k]: ppo[k] for k in _RLLIB_NAMES if k in ppo}
    return {"training": training, "fcnet_hiddens": list(ppo.get("net_arch", [64, 64]))}


ENV_CONFIG: dict[str, Any] = {}
"""Settings overriding the task's registered ones, for training and evaluation (none by default)."""


def eval_config(env_id: str, env_config: Mapping[str, Any] | None = None) -> Any:
    """The validated configuration both policies are evaluated on: the task's settings + ``env_config``."""
    from gear_env.envs.env_config import task_config

    return task_config(env_id, env_config)


class RLlibPolicy:
    """A trained RLlib RLModule behind SB3's ``predict`` interface (what gear-env's evaluation takes).

    ``predict(obs)`` with ``obs`` of shape (n, n_obs) returns actions of shape (n, 1) in [-1, 1]:
    with ``deterministic=True`` the mean of the action distribution, else a sample."""

    def __init__(self, module: Any, name: str = "rllib-ppo"):
        self.module = module
        self.name = name

    def predict(
        self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[np.ndarray, Any]:
        import torch
        from ray.rllib.core.columns import Columns

        obs = np.asarray(observation, dtype=np.float32)
        if obs.ndim == 1:
            obs = obs[None, :]
        with torch.no_grad():
            out = self.module.forward_inference({Columns.OBS: torch.from_numpy(obs)})
            dist = self.module.get_inference_action_dist_cls().from_logits(out[Columns.ACTION_DIST_INPUTS])
            if deterministic:
                dist = dist.to_deterministic()
            act = dist.sample().cpu().numpy()
        return np.clip(act.reshape(obs.shape[0], -1), -1.0, 1.0).astype(np.float32), state


def build_config(
    env_id: str = ENV_ID,
    env_config: Mapping[str, Any] | None = None,
    num_env_runners: int = 1,
    num_envs_per_runner: int = 8,
    rollout_fragment_length: int = 256,
    seed: int = 0,
    ppo: Mapping[str, Any] | None = None,
) -> Any:
    """The RLlib ``PPOConfig`` (new API stack, torch, CPU) for ``env_id``.

    ``num_env_runners = 0`` samples in the driver process; each runner steps
    ``num_envs_per_runner`` sub-environments of the native vector env. One update uses
    ``max(1, num_env_runners) * num_envs_per_runner * rollout_fragment_length`` env steps."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    for name, v, lo in (
        ("num_env_runners", num_env_runners, 0),
        ("num_envs_per_runner", num_envs_per_runner, 1),
        ("rollout_fragment_length", rollout_fragment_length, 1),
    ):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
    base = ppo_settings(env_id)
    settings = {**base["training"], **dict(ppo or {})}
    batch = max(1, num_env_runners) * num_envs_per_runner * rollout_fragment_length
    settings["minibatch_size"] = min(int(settings["minibatch_size"]), batch)
    return (
        PPOConfig()
        .framework("torch")
        .environment(env=env_id if ":" in env_id else f"gear_env:{env_id}", env_config=dict(env_config or {}))
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=num_envs_per_runner,
            gym_env_vectorize_mode="vector_entry_point",
            rollout_fragment_length=rollout_fragment_length,
            num_cpus_per_env_runner=1,
        )
        .learners(num_learners=0)
        .training(train_batch_size_per_learner=batch, **settings)
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=base["fcnet_hiddens"], fcnet_activation="tanh"))
        .debugging(seed=seed)
    )


def _ray_init(address: str | None, num_cpus: int | None) -> None:
    import ray

    # workers see the environment of the `ray start` (or, locally, of this process) that spawned them:
    # NUMBA_CACHE_DIR / GEAR_ENV_CACHE are per node and deliberately not forwarded from the driver
    kw: dict[str, Any] = {
        "runtime_env": {"env_vars": {"OMP_NUM_THREADS": "1"}},
        "include_dashboard": False,
        "log_to_driver": False,
    }
    if address:
        ray.init(address=address, **kw)
        return
    # a local instance: Ray waits a fixed 30 s for its raylet, which a heavily loaded machine can
    # miss; start again (up to 3 times) before giving up
    for attempt in range(3):
        try:
            ray.init(num_cpus=num_cpus, **kw)
            return
        except Exception as exc:  # ray raises a bare Exception for this time-out
            if "timed out during startup" not in str(exc) or attempt == 2:
                raise
            print(f"[rllib] the local Ray node did not start in time ({exc}); trying again", flush=True)
            ray.shutdown()


def train_and_compare(
    env_id: str = ENV_ID,
    env_config: Mapping[str, Any] | None = None,
    timesteps: int = 200_000,
    num_env_runners: int = 1,
    num_envs_per_runner: int = 8,
    rollout_fragment_length: int = 256,
    seed: int = 0,
    eval_episodes: int = 10,
    eval_seed: int = 0,
    sb3_policy: str = "pretrained",
    address: str | None = None,
    num_cpus: int | None = None,
    checkpoint: str | None = None,
    verbose: bool = True,
) -> dict[str, Any]:
    """Train RLlib PPO for at least ``timesteps`` env steps, then evaluate it and ``sb3_policy`` (an
    ``agents.registry`` spec: ``pretrained``, a run folder, ``oracle``...) on the episode seeds
    ``eval_seed + k``, k < ``eval_episodes``. Returns the JSON-ready result (see ``main``).

    ``address``: a running Ray cluster (``"auto"`` or ``HOST:6379``); None starts a local one with
    ``num_cpus`` CPUs (None = all). ``checkpoint``: a folder for RLlib's algorithm checkpoint."""
    import ray
    import torch

    from agents.registry import resolve_policy
    from gear_env.evaluation import evaluate_policies

    if isinstance(timesteps, bool) or not isinstance(timesteps, int) or timesteps < 1:
        raise ValueError(f"timesteps must be an integer >= 1, got {timesteps!r}")
    if isinstance(eval_episodes, bool) or not isinstance(eval_episodes, int) or eval_episodes < 1:
        raise ValueError(f"eval_episodes must be an integer >= 1, got {eval_episodes!r}")
    env_config = dict(ENV_CONFIG if env_config is None else env_config)
    config = build_config(env_id, env_config, num_env_runners, num_envs_per_runner, rollout_fragment_length, seed)
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    _ray_init(address, num_cpus)
    try:
        resources = {k: float(v) for k, v in ray.cluster_resources().items() if k in ("CPU", "GPU", "memory")}
        nodes = sum(1 for n in ray.nodes() if n.get("Alive"))
        algo = config.build_algo()
        t_built = time.perf_counter()
        vec_env_classes = _vector_env_classes(algo)
        history: list[dict[str, Any]] = []
        sampled = 0
        while sampled < timesteps:
            res = algo.train()
            sampled = int(res.get("num_env_steps_sampled_lifetime", 0) or 0)
            er = res.get("env_runners", {})
            row = {
                "iteration": int(res.get("training_iteration", len(history) + 1)),
                "env_steps": sampled,
                "episode_return_mean": _num(er.get("episode_return_mean")),
                "wall_seconds": round(time.perf_counter() - t_built, 3),
            }
            history.append(row)
            if verbose:
                print(
                    f"[rllib] iter {row['iteration']} steps {sampled:,}/{timesteps:,} "
                    f"return {row['episode_return_mean']}",
                    flush=True,
                )
        t_trained = time.perf_counter()
        if checkpoint:
            algo.save_to_path(os.path.abspath(checkpoint))
        module = algo.get_module()
        algo.stop()
    finally:
        ray.shutdown()
    cfg = eval_config(env_id, env_config)
    policies = {
        "rllib-ppo": RLlibPolicy(module),
        f"sb3-{sb3_policy}": resolve_policy(sb3_policy, cfg, env_id=env_id),
    }
    report = evaluate_policies(policies, cfg, episodes=eval_episodes, seed=eval_seed)
    t_end = time.perf_counter()
    out = report.to_json_dict()
    out.update(
        {
            "format": "gear-env-rllib/1",
            "env_id": env_id,
            "eval_episodes": eval_episodes,
            "eval_seeds": [eval_seed + k for k in range(eval_episodes)],
            "rllib": {
                "timesteps": sampled,
                "iterations": len(history),
                "num_env_runners": num_env_runners,
                "num_envs_per_runner": num_envs_per_runner,
                "rollout_fragment_length": rollout_fragment_length,
                "vector_env_classes": vec_env_classes,
                "ppo": {  # the values the algorithm ran with (read back from its config, not recomputed)
                    **{name: getattr(config, name) for name in _RLLIB_NAMES.values()},
                    "train_batch_size_per_learner": config.train_batch_size_per_learner,
                },
                "seed": seed,
                "history": history,
            },
            "ray": {"address": address or "local", "nodes": nodes, "resources": resources},
            "wall_seconds": {
                "setup": round(t_built - t0, 3),
                "train": round(t_trained - t_built, 3),
                "evaluate": round(t_end - t_trained, 3),
            },
            "versions": _versions(),
        }
    )
    return out


def _vector_env_classes(algo: Any) -> list[str]:
    """Classes of the vector envs of all EnvRunners (the driver's and the remote ones)."""

    def cls(runner: Any) -> str | None:
        env = getattr(runner, "env", None)
        if env is None:
            return None
        u = env.unwrapped
        return f"{type(u).__module__}.{type(u).__qualname__}"

    found = algo.env_runner_group.foreach_env_runner(cls, local_env_runner=True)
    return sorted({c for c in found if c is not None})


def load_module(checkpoint: str | os.PathLike) -> Any:
    """The trained RLModule (policy network) from a checkpoint folder written by ``--checkpoint``."""
    from ray.rllib.core import COMPONENT_LEARNER, COMPONENT_LEARNER_GROUP, COMPONENT_RL_MODULE, DEFAULT_MODULE_ID
    from ray.rllib.core.rl_module.rl_module import RLModule

    path = os.path.join(
        os.path.abspath(checkpoint), COMPONENT_LEARNER_GROUP, COMPONENT_LEARNER, COMPONENT_RL_MODULE, DEFAULT_MODULE_ID
    )
    if not os.path.isdir(path):
        raise ValueError(f"{str(checkpoint)!r} is not an RLlib checkpoint of this script (no {path!r})")
    return RLModule.from_checkpoint(path)


def _num(v: Any) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if np.isfinite(f) else None


def _versions() -> dict[str, str]:
    import gymnasium
    import ray
    import torch

    import gear_env

    return {
        "python": sys.version.split()[0],
        "gear_env": gear_env.__version__,
        "ray": ray.__version__,
        "gymnasium": gymnasium.__version__,
        "torch": torch.__version__,
        "numpy": np.__version__,
    }


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--env-id", default=ENV_ID, help=f"Gymnasium id (default {ENV_ID})")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="environment setting (JSON value)")
    p.add_argument("--timesteps", type=int, default=200_000, help="env steps to train (at least; whole updates)")
    p.add_argument("--num-env-runners", type=int, default=1, help="Ray actors that sample (0 = the driver)")
    p.add_argument("--num-envs-per-runner", type=int, default=8, help="sub-envs of each runner's native vector env")
    p.add_argument("--rollout-fragment-length", type=int, default=256, help="steps per sub-env per update")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--eval-episodes", type=int, default=10)
    p.add_argument("--eval-seed", type=int, default=0, help="episode k of every policy uses seed EVAL_SEED + k")
    p.add_argument("--sb3-policy", default="pretrained", help="policy spec to compare with (gear-env evaluate)")
    p.add_argument("--address", default=None, help="Ray cluster to join ('auto' or HOST:PORT); default: local")
    p.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray instance (default: all)")
    p.add_argument("--checkpoint", default=None, help="folder for the RLlib checkpoint")
    p.add_argument("--out", required=True, help="JSON file to write (refused if it exists, unless --overwrite)")
    p.add_argument("--overwrite", action="store_true")
    a = p.parse_args(argv)
    from gear_env.io import atomic_write_text

    if os.path.lexists(a.out) and not (a.overwrite and os.path.isfile(a.out)):
        p.error(f"--out {a.out!r} exists (give --overwrite to replace a regular file)")
    env_config = dict(ENV_CONFIG)
    for item in a.set:
        key, sep, val = item.partition("=")
        if not sep:
            p.error(f"--set {item!r}: expected KEY=VALUE")
        try:
            env_config[key.strip()] = json.loads(val)
        except json.JSONDecodeError:
            p.error(f"--set {item!r}: VALUE must be JSON (strings in double quotes)")
    result = train_and_compare(
        env_id=a.env_id,
        env_config=env_config,
        timesteps=a.timesteps,
        num_env_runners=a.num_env_runners,
        num_envs_per_runner=a.num_envs_per_runner,
        rollout_fragment_length=a.rollout_fragment_length,
        seed=a.seed,
        eval_episodes=a.eval_episodes,
        eval_seed=a.eval_seed,
        sb3_policy=a.sb3_policy,
        address=a.address,
        num_cpus=a.num_cpus,
        checkpoint=a.checkpoint,
    )
    atomic_write_text(a.out, json.dumps(result, indent=2) + "\n")
    for name, s in result["policies"].items():
        print(
            f"{name:>16}: return {s['return_mean']:.2f} ± {s['return_ci95']:.2f}, "
            f"settled omega {s['settled_omega_mean']:.3f}"
        )
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
