"""Drive GearSpeed-v0 with a hand-written speed profile: no RL library involved.

    python examples/standalone_schedule.py                 # the built-in profile below
    python examples/standalone_schedule.py --plot run.png  # and a figure of omega(t) and vibration

The profile starts the gear pair at omega = 0.5 (inside the period-doubling band), moves it up to
the quiet window at omega = 1.2, holds it, then tries omega = 2.0 (the chaotic band) and comes back.
Each line printed is one control step (24 mesh periods); the totals at the end are the episode
summary the environment returns in ``info`` on its last step.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import gear_env  # noqa: F401  (registers GearSpeed-v0)

# (time in env steps, omega): piecewise linear, held after the last point
PROFILE = [(0, 0.5), (20, 1.2), (80, 1.2), (100, 2.0), (140, 2.0), (160, 1.2)]


def target_omega(t: float) -> float:
    """The hand-written profile at env step t."""
    ts, ws = zip(*PROFILE)
    return float(np.interp(t, ts, ws))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200, help="episode length in env steps (default 200)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plot", metavar="PNG", help="write omega(t), chaos indicator and peak force")
    args = ap.parse_args()

    # target mode: the action is the wanted omega mapped onto [-1, 1]; the env limits the rate
    env = gym.make("GearSpeed-v0", action_mode="target", max_steps=args.steps)
    cfg = env.unwrapped.config
    lo, hi = cfg.omega_min, cfg.omega_max
    obs, info = env.reset(seed=args.seed, options={"omega": PROFILE[0][1]})
    rows = []
    t = 0
    done = False
    while not done:
        want = target_omega(t + 1)
        action = np.array([2.0 * (want - lo) / (hi - lo) - 1.0], dtype=np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        t += 1
        done = terminated or truncated
        rows.append((t, info["omega"], reward, info["chaos"], info["contact_loss"], info["force_peak"]))
        if t % 10 == 0 or done:
            print(
                f"step {t:3d}  omega {info['omega']:.3f}  reward {reward:+.3f}  chaos {info['chaos']:.2f}  "
                f"contact loss {info['contact_loss']:.2f}  peak force {info['force_peak']:.1f} F_s  "
                f"period {info['period'] or '-'}"
            )
    print(
        f"\nepisode: return {info['episode_return']:.2f}, throughput (mean omega) {info['episode_throughput']:.3f}, "
        f"{info['episode_time_s'] * 1e3:.1f} ms of gear time, "
        f"non-periodic {info['episode_time_nonperiodic_s'] / info['episode_time_s']:.0%} of the time, "
        f"{info['episode_impacts']} impacts, contact loss {info['episode_contact_loss']:.1%}"
    )
    if args.plot:
        from gear_env.plots.common import new_figure, save_figure

        a = np.array(rows)
        fig = new_figure(8, 5)
        ax1, ax2 = fig.subplots(2, 1, sharex=True)
        ax1.plot(a[:, 0], a[:, 1], "k-", label="omega")
        ax1.plot(a[:, 0], [target_omega(x) for x in a[:, 0]], "b--", lw=0.8, label="profile")
        ax1.set_ylabel("omega")
        ax1.legend()
        ax2.plot(a[:, 0], a[:, 3], label="chaos indicator c")
        ax2.plot(a[:, 0], a[:, 4], label="contact loss")
        ax2.plot(a[:, 0], a[:, 5] / 10, label="peak force / 10 F_s")
        ax2.set_xlabel("env step")
        ax2.legend(fontsize=7)
        save_figure(fig, args.plot)
        print(f"wrote {args.plot}")
    env.close()


if __name__ == "__main__":
    main()
