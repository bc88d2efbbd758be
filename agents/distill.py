"""Privileged-teacher distillation (DAgger) of the episode oracle into the PPO actor.

Why (issue #23, docs/TRAINING.md "Distillation"): on ``GearSpeedDemand-v0`` the information a sensor-only
policy needs is in the observation (short scripts that read it close 94-96 % of the gap between fixed-best and
the oracle), but PPO from scratch stops near 55 %: near a worn pair's cliff the return of a speed is
asymmetric and the plant draw dominates the spread of the returns, so the policy gradient settles on a
conservative hold near the family's mean. A teacher that *knows* the pair removes both problems: the
episode oracle (:class:`agents.episode_oracle.EpisodeOracle`) gives the optimal next speed from any state, and
supervised learning of that map from what is sensed is an easy regression.

The algorithm is DAgger (Ross, Gordon & Bagnell 2011), as in teacher-student training of legged robots (Lee
et al. 2020, "Learning quadrupedal locomotion over challenging terrain"):

1. iteration 0: the teacher drives ``episodes`` training episodes; every visited observation is labelled with
   the teacher's action; the observation statistics (``VecNormalize``) are fitted to these observations and
   then kept;
2. iteration i >= 1: the *student* (the deterministic PPO actor) drives ``episodes`` new training episodes and
   the teacher labels the states the student visits (this is what plain behaviour cloning lacks: the student
   learns to recover from its own mistakes);
3. after every iteration the actor's mean (``mlp_extractor.policy_net`` + ``action_net``) is fitted to all
   labels so far (mean squared error, Adam), and the run's usual in-training evaluation scores it.

The student sees only the observation: the teacher's privileged knowledge (the plant, the future demand and
duty cycle) enters only through the labels, and only on training episodes (episode seeds ``seed + k``,
``k < iterations x episodes``, inside :data:`agents.protocol.TRAIN_ENV_SEEDS` for the reported runs).
The result is an ordinary PPO model in an ordinary run folder: ``gear-env evaluate --policy RUN_DIR``, the
export to a shipped policy and further PPO training (``--timesteps`` beyond the distillation's steps) work
unchanged.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .distill_config import DISTILL_DEFAULTS, MAX_EPISODES, MAX_ITERATIONS, check_distill  # noqa: F401  (re-exported)


def teacher_for(env_id: str, cfg: Any) -> Any:
    """The teacher of a task: its ``oracle`` policy (:func:`agents.registry.resolve_policy`). On a task with an
    episode scenario (GearSpeedDemand-v0) that is the episode oracle, privileged (it knows the plant, the demand
    and the duty cycle); on GearSpeed-v0/v1 the oracle of the steady reward map of the one plant."""
    from .registry import resolve_policy

    return resolve_policy("oracle", cfg, env_id=env_id)


def sent(state: Any, action: float) -> Any:
    """The teacher's ``state`` after the driver (the student) sent ``action``: with an actuator dead time the
    teacher's Smith predictor must hold the action actually on its way, not its own label
    (:meth:`agents.baselines.ScriptedPolicy.predict_batch`)."""
    if isinstance(state, dict) and "pending" in state:
        state["pending"][:, -1] = float(np.float32(action))
    return state


def _actor_mean(policy: Any, obs: Any) -> Any:
    """The actor's mean action for normalised observations (a torch tensor; differentiable)."""
    return policy.get_distribution(obs).distribution.mean


def _loss(pred: Any, label: Any, quantile: float | None) -> Any:
    """Squared error (the teacher's mean action given the observation) or, with ``quantile`` q, the pinball loss
    mean(max(q u, (q - 1) u)), u = label - pred, whose minimiser is the labels' q-quantile (Koenker & Bassett
    1978)."""
    import torch

    if quantile is None:
        return torch.mean((pred - label) ** 2)
    u = label - pred
    return torch.mean(torch.maximum(quantile * u, (quantile - 1.0) * u))


def distill(
    model: Any,
    vecnorm: Any,
    env_id: str,
    env_config: Any,
    iterations: int,
    params: dict[str, Any] | None = None,
    seed: int = 0,
    on_iteration: Callable[[int, int], None] | None = None,
    verbose: int = 1,
) -> int:
    """Fit the actor of the PPO ``model`` to the teacher by DAgger (module docstring); returns the environment
    steps it took (the caller adds them to ``model.num_timesteps``).

    ``vecnorm`` is the run's ``VecNormalize``: its observation statistics are set from iteration 0 and frozen.
    ``on_iteration(i, steps)`` runs after each iteration (the training run evaluates and saves there)."""
    import torch

    from gear_env.envs.env import GearSpeedEnv

    from .envs import make_config

    p = {**DISTILL_DEFAULTS, **(params or {})}
    check_distill(iterations, p)
    cfg = make_config(env_id, env_config)
    env = GearSpeedEnv(cfg)
    teacher = teacher_for(env_id, cfg)
    policy = model.policy
    rng_torch = torch.Generator().manual_seed(int(seed))
    actor_params = [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters()]
    opt = torch.optim.Adam(actor_params, lr=float(p["learning_rate"]))
    clip = float(vecnorm.clip_obs)
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    steps, k = 0, 0
    mean = var = None

    def normalised(o: np.ndarray) -> np.ndarray:
        return np.clip((o - mean) / np.sqrt(var + vecnorm.epsilon), -clip, clip)

    def student(o: np.ndarray) -> float:
        z = normalised(o)
        with torch.no_grad():
            a = _actor_mean(policy, torch.as_tensor(z[None], dtype=torch.float32))
        return float(np.clip(a.numpy()[0, 0], -1.0, 1.0))

    try:
        for it in range(iterations):
            t0 = time.perf_counter()
            if verbose:
                who = "teacher" if it == 0 else "student"
                print(f"[distill] iteration {it + 1}/{iterations}: {p['episodes']} episodes driven by the {who}, "
                      "labelled by the teacher", flush=True)  # fmt: skip
            obs_it, lab_it = [], []
            for _ in range(p["episodes"]):
                obs, _info = env.reset(seed=int(seed) + k)
                k += 1
                if env.episode is not None and hasattr(teacher, "observe_episode"):
                    teacher.observe_episode(env.episode)
                state, start = None, np.array([True])
                while True:
                    label, state = teacher.predict(obs[None], state, start, deterministic=True)
                    start = np.array([False])
                    obs_it.append(obs.astype(np.float64))
                    lab_it.append(float(label[0, 0]))
                    act = float(label[0, 0]) if it == 0 else student(obs.astype(np.float64))
                    state = sent(state, act)
                    obs, _r, term, trunc, _info = env.step(np.array([act], np.float32))
                    steps += 1
                    if term or trunc:
                        break
            xs.append(np.asarray(obs_it))
            ys.append(np.asarray(lab_it))
            if it == 0:  # the statistics the student will always see its inputs through
                x0 = xs[0]
                mean, var = x0.mean(axis=0), x0.var(axis=0)
                vecnorm.obs_rms.mean = mean.copy()
                vecnorm.obs_rms.var = var.copy()
                vecnorm.obs_rms.count = float(len(x0))
            X = np.concatenate(xs)
            Xt = torch.as_tensor(normalised(X), dtype=torch.float32)
            Yt = torch.as_tensor(np.concatenate(ys)[:, None], dtype=torch.float32)
            policy.set_training_mode(True)
            loss = torch.zeros(())
            for epoch in range(p["epochs"]):
                frac = 1.0 - (1.0 - float(p["final_lr_fraction"])) * epoch / max(1, p["epochs"] - 1)
                for group in opt.param_groups:
                    group["lr"] = float(p["learning_rate"]) * frac
                perm = torch.randperm(len(Xt), generator=rng_torch)
                for i in range(0, len(Xt), p["batch_size"]):
                    j = perm[i : i + p["batch_size"]]
                    loss = _loss(_actor_mean(policy, Xt[j]), Yt[j], p["quantile"])
                    opt.zero_grad()
                    loss.backward()
                    opt.step()
            policy.set_training_mode(False)
            if verbose:
                print(f"[distill] iteration {it + 1}/{iterations}: {len(Xt):,} labels, last batch loss "
                      f"{float(loss.detach()):.4f}, {time.perf_counter() - t0:.1f} s", flush=True)  # fmt: skip
            if on_iteration is not None:
                on_iteration(it, steps)
    finally:
        env.close()
    if verbose and iterations:
        print(f"[distill] done: {steps:,} environment steps", flush=True)
    return steps


def _callback_base() -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    return BaseCallback


class DistillCallback(_callback_base()):  # type: ignore[misc]
    """The distillation as an SB3 callback, for rl-zoo3 (``callback:`` in agents/hyperparams/ppo.yml) and any
    SB3 training loop: at the start of ``learn()`` it runs :func:`distill` on the model's actor, keeps the round
    that scored best on ``eval_episodes`` in-training evaluation episodes (seeds ``seed + 1_000_003 + i``, as
    ``gear-env train``), and with ``stop=True`` (default) ends ``learn()`` at its first step, so the saved model
    is the distilled one; with ``stop=False`` PPO continues from it.

    The training env must be the task's environment behind ``VecNormalize`` (rl-zoo3's ``normalize: true``)."""

    def __init__(self, iterations: int = 12, stop: bool = True, eval_episodes: int = 20, verbose: int = 1,
                 **params: Any):  # fmt: skip
        super().__init__(verbose)
        check_distill(iterations, params)
        if not isinstance(stop, bool):
            raise ValueError(f"stop must be True or False, got {stop!r}")
        if isinstance(eval_episodes, bool) or not isinstance(eval_episodes, int) or not 1 <= eval_episodes <= 10_000:
            raise ValueError(f"eval_episodes must be an integer in [1, 10000], got {eval_episodes!r}")
        self.iterations, self.stop, self.eval_episodes, self.params = iterations, stop, eval_episodes, dict(params)
        self.steps = 0

    def _on_training_start(self) -> None:
        import copy

        from stable_baselines3.common.vec_env import VecNormalize

        from .envs import config_to_dict, make_sb3_vec_env
        from .protocol import IN_TRAINING_EVAL_SEEDS
        from .trained import evaluate_model

        venv = self.model.get_env()
        if not isinstance(venv, VecNormalize):
            raise ValueError("DistillCallback needs the training env behind VecNormalize (rl-zoo3: normalize: true)")
        env_id = venv.get_attr("spec")[0].id
        env_config = config_to_dict(venv.get_attr("config")[0])
        seed = int(self.model.seed or 0)
        eval_venv = make_sb3_vec_env(env_id, env_config, min(self.eval_episodes, 8), None)
        best: dict[str, Any] = {"ret": -np.inf}

        def after(it: int, steps: int) -> None:
            self.model.num_timesteps = steps
            # gear-env train's in-training evaluation: the same episodes, the statistics frozen
            row = evaluate_model(
                self.model, venv, eval_venv, self.eval_episodes, seed=seed + IN_TRAINING_EVAL_SEEDS.start
            )
            ret = row["return_mean"]
            if self.verbose:
                print(f"[distill] round {it + 1}: evaluation return {ret:.3f}", flush=True)
            if ret > best["ret"]:
                best.update(ret=ret, it=it, actor=copy.deepcopy(self.model.policy.state_dict()))

        try:
            self.steps = distill(self.model, venv, env_id, env_config, self.iterations, self.params, seed=seed,
                                 on_iteration=after, verbose=self.verbose)  # fmt: skip
        finally:
            eval_venv.close()
        if "actor" in best:
            self.model.policy.load_state_dict(best["actor"])
            if self.verbose:
                print(f"[distill] kept round {best['it'] + 1} (evaluation return {best['ret']:.3f})", flush=True)
        self.model.num_timesteps = self.steps
        if self.stop:
            venv.training = False  # the statistics stay those of the distillation

    def _on_step(self) -> bool:
        return not self.stop


__all__ = ["DISTILL_DEFAULTS", "DistillCallback", "check_distill", "distill", "teacher_for"]
