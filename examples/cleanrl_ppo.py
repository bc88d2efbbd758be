"""PPO on a gear speed-scheduling task as a CleanRL user writes it: one file, Gymnasium's own wrappers.

This is the structure and the default hyper-parameters of CleanRL's ``ppo_continuous_action.py``
(https://docs.cleanrl.dev/rl-algorithms/ppo/#ppo_continuous_actionpy): a ``gym.vector.SyncVectorEnv`` of
``gym.make(env_id)`` environments, each wrapped in ``RecordEpisodeStatistics``, ``ClipAction``,
``NormalizeObservation``, ``TransformObservation`` (clip to +-10), ``NormalizeReward`` and
``TransformReward`` (clip to +-10); separate 64-64 tanh actor and critic, a state-independent log-std
starting at 0, Adam with a linearly annealed learning rate, GAE, clipped surrogate and value losses.
Nothing from gear-env is used to train: the environment is reached only through ``gym.make``.

After training, the deterministic policy (the actor's mean, the observation normalised with the first
environment's running statistics, frozen) is evaluated by ``gear_env.evaluation.evaluate_policies`` on
the same episode seeds as the oracle and fixed-best, and the result is printed and optionally written
as JSON (refused if the file exists).

    python examples/cleanrl_ppo.py --env-id GearSpeed-v1 --total-timesteps 200000 --seed 0 --json out.json
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np


def make_env(env_id: str, gamma: float):
    """CleanRL's ``make_env`` for continuous actions (Gymnasium 1.x wrappers)."""

    def thunk() -> gym.Env:
        import gear_env  # noqa: F401  (registers the tasks; CleanRL users pass --env-id only)

        env = gym.make(env_id)
        env = gym.wrappers.RecordEpisodeStatistics(env)
        env = gym.wrappers.ClipAction(env)
        env = gym.wrappers.NormalizeObservation(env)
        env = gym.wrappers.TransformObservation(env, lambda obs: np.clip(obs, -10, 10), None)
        env = gym.wrappers.NormalizeReward(env, gamma=gamma)
        env = gym.wrappers.TransformReward(env, lambda reward: np.clip(reward, -10, 10))
        return env

    return thunk


def build_agent(obs_dim: int, act_dim: int, log_std_init: float = 0.0) -> Any:
    """CleanRL's ``Agent``: orthogonal init (gain sqrt 2, 1 for the critic's head, 0.01 for the actor's)."""
    import torch
    from torch import nn

    def layer_init(layer: nn.Linear, std: float = float(np.sqrt(2)), bias_const: float = 0.0) -> nn.Linear:
        nn.init.orthogonal_(layer.weight, std)
        nn.init.constant_(layer.bias, bias_const)
        return layer

    class Agent(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.critic = nn.Sequential(
                layer_init(nn.Linear(obs_dim, 64)), nn.Tanh(), layer_init(nn.Linear(64, 64)), nn.Tanh(),
                layer_init(nn.Linear(64, 1), std=1.0),
            )  # fmt: skip
            self.actor_mean = nn.Sequential(
                layer_init(nn.Linear(obs_dim, 64)), nn.Tanh(), layer_init(nn.Linear(64, 64)), nn.Tanh(),
                layer_init(nn.Linear(64, act_dim), std=0.01),
            )  # fmt: skip
            self.actor_logstd = nn.Parameter(torch.full((1, act_dim), float(log_std_init)))

        def get_value(self, x: Any) -> Any:
            return self.critic(x)

        def get_action_and_value(self, x: Any, action: Any = None) -> tuple[Any, Any, Any, Any]:
            mean = self.actor_mean(x)
            std = torch.exp(self.actor_logstd.expand_as(mean))
            dist = torch.distributions.Normal(mean, std)
            if action is None:
                action = dist.sample()
            return action, dist.log_prob(action).sum(1), dist.entropy().sum(1), self.critic(x)

    return Agent()


class FrozenPolicy:
    """The trained actor's mean behind the ``predict`` interface gear-env's evaluation takes."""

    def __init__(self, agent: Any, obs_mean: np.ndarray, obs_var: np.ndarray, epsilon: float = 1e-8):
        self.agent, self.mean, self.var, self.epsilon = agent, obs_mean.copy(), obs_var.copy(), epsilon

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        import torch

        obs = np.asarray(observation, np.float64)
        single = obs.ndim == 1
        obs = np.clip((np.atleast_2d(obs) - self.mean) / np.sqrt(self.var + self.epsilon), -10, 10)
        with torch.no_grad():
            a = self.agent.actor_mean(torch.as_tensor(obs, dtype=torch.float32)).numpy()
        a = np.clip(a, -1.0, 1.0).astype(np.float32)
        return (a[0] if single else a), state


def train(args: argparse.Namespace) -> tuple[FrozenPolicy, dict[str, Any]]:
    """CleanRL's PPO loop; returns the frozen policy and the training log."""
    import torch
    from torch import nn, optim

    torch.set_num_threads(1)
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    torch.backends.cudnn.deterministic = True
    batch_size = args.num_envs * args.num_steps
    minibatch_size = batch_size // args.num_minibatches
    num_iterations = max(1, args.total_timesteps // batch_size)

    envs = gym.vector.SyncVectorEnv([make_env(args.env_id, args.gamma) for _ in range(args.num_envs)])
    assert isinstance(envs.single_action_space, gym.spaces.Box), "only continuous action space is supported"
    obs_dim = int(np.prod(envs.single_observation_space.shape))
    act_dim = int(np.prod(envs.single_action_space.shape))
    agent = build_agent(obs_dim, act_dim, args.log_std_init)
    optimizer = optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)

    obs = torch.zeros((args.num_steps, args.num_envs, obs_dim))
    actions = torch.zeros((args.num_steps, args.num_envs, act_dim))
    logprobs = torch.zeros((args.num_steps, args.num_envs))
    rewards = torch.zeros((args.num_steps, args.num_envs))
    dones = torch.zeros((args.num_steps, args.num_envs))
    values = torch.zeros((args.num_steps, args.num_envs))

    global_step, log = 0, []
    t0 = time.perf_counter()
    next_obs_np, _ = envs.reset(seed=args.seed)
    next_obs = torch.as_tensor(next_obs_np, dtype=torch.float32)
    next_done = torch.zeros(args.num_envs)
    for iteration in range(1, num_iterations + 1):
        if args.anneal_lr:
            optimizer.param_groups[0]["lr"] = (1.0 - (iteration - 1.0) / num_iterations) * args.learning_rate
        returns_seen = []
        for step in range(args.num_steps):
            global_step += args.num_envs
            obs[step], dones[step] = next_obs, next_done
            with torch.no_grad():
                action, logprob, _, value = agent.get_action_and_value(next_obs)
                values[step] = value.flatten()
            actions[step], logprobs[step] = action, logprob
            next_obs_np, reward, terminations, truncations, infos = envs.step(action.numpy())
            next_done = torch.as_tensor(np.logical_or(terminations, truncations), dtype=torch.float32)
            rewards[step] = torch.as_tensor(reward, dtype=torch.float32).view(-1)
            next_obs = torch.as_tensor(next_obs_np, dtype=torch.float32)
            if "episode" in infos:
                returns_seen += [float(r) for r, m in zip(infos["episode"]["r"], infos["_episode"]) if m]

        with torch.no_grad():  # GAE
            next_value = agent.get_value(next_obs).reshape(1, -1)
            advantages = torch.zeros_like(rewards)
            lastgaelam = 0
            for t in reversed(range(args.num_steps)):
                if t == args.num_steps - 1:
                    nextnonterminal, nextvalues = 1.0 - next_done, next_value
                else:
                    nextnonterminal, nextvalues = 1.0 - dones[t + 1], values[t + 1]
                delta = rewards[t] + args.gamma * nextvalues * nextnonterminal - values[t]
                advantages[t] = lastgaelam = delta + args.gamma * args.gae_lambda * nextnonterminal * lastgaelam
            returns = advantages + values

        b_obs, b_logprobs = obs.reshape((-1, obs_dim)), logprobs.reshape(-1)
        b_actions, b_advantages = actions.reshape((-1, act_dim)), advantages.reshape(-1)
        b_returns, b_values = returns.reshape(-1), values.reshape(-1)
        b_inds = np.arange(batch_size)
        for _epoch in range(args.update_epochs):
            np.random.shuffle(b_inds)
            for start in range(0, batch_size, minibatch_size):
                mb = b_inds[start : start + minibatch_size]
                _, newlogprob, entropy, newvalue = agent.get_action_and_value(b_obs[mb], b_actions[mb])
                ratio = (newlogprob - b_logprobs[mb]).exp()
                mb_adv = b_advantages[mb]
                if args.norm_adv:
                    mb_adv = (mb_adv - mb_adv.mean()) / (mb_adv.std() + 1e-8)
                pg_loss = torch.max(
                    -mb_adv * ratio, -mb_adv * torch.clamp(ratio, 1 - args.clip_coef, 1 + args.clip_coef)
                ).mean()
                newvalue = newvalue.view(-1)
                v_unclipped = (newvalue - b_returns[mb]) ** 2
                v_clipped = b_values[mb] + torch.clamp(newvalue - b_values[mb], -args.clip_coef, args.clip_coef)
                v_loss = 0.5 * torch.max(v_unclipped, (v_clipped - b_returns[mb]) ** 2).mean()
                loss = pg_loss - args.ent_coef * entropy.mean() + v_loss * args.vf_coef
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()
        row = {
            "iteration": iteration,
            "global_step": global_step,
            "episodic_return_mean": float(np.mean(returns_seen)) if returns_seen else None,
            "std": float(agent.actor_logstd.detach().exp().mean()),
            "wall_s": round(time.perf_counter() - t0, 2),
        }
        log.append(row)
        if not args.quiet:
            r = "-" if row["episodic_return_mean"] is None else f"{row['episodic_return_mean']:.2f}"
            print(f"iter {iteration}/{num_iterations}  step {global_step:,}  episodic return {r}  std {row['std']:.3f}")
    rms = envs.envs[0].get_wrapper_attr("obs_rms")  # the first environment's statistics (each env has its own)
    envs.close()
    return FrozenPolicy(agent, np.asarray(rms.mean), np.asarray(rms.var)), {
        "log": log,
        "wall_s": time.perf_counter() - t0,
    }


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env-id", default="GearSpeed-v1")
    p.add_argument("--seed", type=int, default=1, help="CleanRL's default seed is 1")
    p.add_argument("--total-timesteps", type=int, default=200_000, help="CleanRL's default is 1,000,000")
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--num-envs", type=int, default=1)
    p.add_argument("--num-steps", type=int, default=2048)
    p.add_argument("--anneal-lr", type=lambda s: s.lower() in ("1", "true", "yes"), default=True)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--num-minibatches", type=int, default=32)
    p.add_argument("--update-epochs", type=int, default=10)
    p.add_argument("--norm-adv", type=lambda s: s.lower() in ("1", "true", "yes"), default=True)
    p.add_argument("--clip-coef", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--log-std-init", type=float, default=0.0, help="initial log-std of the actor (CleanRL: 0)")
    p.add_argument("--eval-episodes", type=int, default=20)
    p.add_argument("--eval-seed", type=int, default=9001, help="episode k uses seed EVAL_SEED + k (every policy)")
    p.add_argument("--json", default=None, help="result file to write (refused if it exists)")
    p.add_argument("--quiet", action="store_true")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    for name in ("total_timesteps", "num_envs", "num_steps", "num_minibatches", "update_epochs", "eval_episodes"):
        if getattr(args, name) < 1:
            raise SystemExit(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    if (args.num_envs * args.num_steps) % args.num_minibatches:
        raise SystemExit("--num-envs x --num-steps must be a multiple of --num-minibatches")
    if args.json and os.path.lexists(args.json):
        raise SystemExit(f"{args.json} exists; choose another --json path (results are never overwritten)")

    import gear_env  # noqa: F401
    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies

    policy, info = train(args)
    cfg = task_config(args.env_id)
    policies = {
        "cleanrl-ppo": policy,
        "oracle": resolve_policy("oracle", cfg),
        "fixed-best": resolve_policy("fixed-best", cfg),
    }
    rep = evaluate_policies(policies, cfg, episodes=args.eval_episodes, seed=args.eval_seed)
    res = {k: [e.ret for e in v] for k, v in rep.episodes.items()}
    o = float(np.mean(res["oracle"]))
    out = {
        "env_id": args.env_id,
        "args": vars(args),
        "train_wall_s": info["wall_s"],
        "log": info["log"],
        "eval_seeds": [args.eval_seed + k for k in range(args.eval_episodes)],
        "returns": res,
        "settled_omega": {k: [e.settled_omega for e in v] for k, v in rep.episodes.items()},
        "omega": {k: [e.omega for e in v] for k, v in rep.episodes.items()},
        "pct_of_oracle": {k: 100 * float(np.mean(v)) / o for k, v in res.items()},
    }
    for k, v in res.items():
        w = np.mean([e.settled_omega for e in rep.episodes[k]])
        print(
            f"{k:>12}: return {np.mean(v):7.2f} = {out['pct_of_oracle'][k]:6.1f} % of the oracle, settled omega {w:.3f}"
        )
    print(f"trained {args.total_timesteps:,} steps in {info['wall_s']:.0f} s wall")
    if args.json:
        from gear_env.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(out, indent=1))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
