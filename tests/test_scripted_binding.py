"""Issue #26, item 7: a scripted policy of ``agents`` built without ``config=`` follows the task it runs on
(it used to act with GearSpeed-v0's conventions, a change of omega, on every task); where no task is given it
is GearSpeed-v1's; one built for another task is refused, as ``SpeedSchedule`` is."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gear_env  # noqa: F401  (registers the tasks)
from agents.baselines import ConstantSpeed, HillClimber, SlowRamp
from agents.envs import GEAR_ENV_ID, make_config
from gear_env.envs.env_config import task_config
from gear_env.evaluation.episodes import run_episode

FAST = {"max_steps": 6, "steps_per_period": 32, "warmup_periods": 16}


def _env(env_id):
    return gym.make(env_id, **FAST)


def test_no_task_given_means_gearspeed_v1():
    assert GEAR_ENV_ID == "GearSpeed-v1"
    assert make_config(GEAR_ENV_ID, None) == task_config("GearSpeed-v1")
    p = ConstantSpeed(1.0)
    v1 = task_config("GearSpeed-v1")
    assert (p.action_mode, p.max_domega, p.reference_filter) == (v1.action_mode, v1.max_domega, v1.reference_filter)
    assert not p.bound and ConstantSpeed(1.0, config=v1).bound


@pytest.mark.parametrize("env_id", ["GearSpeed-v0", "GearSpeed-v1"])
def test_unbound_policy_scores_as_the_one_built_for_the_task(env_id):
    """Same episode, same return as the policy built with the environment's own config (on GearSpeed-v0 the
    v1 default would send target-mode actions that v0 reads as changes of omega: another return)."""
    env = _env(env_id)
    cfg = env.unwrapped.config
    for make in (lambda c=None: ConstantSpeed(1.3, c), lambda c=None: SlowRamp(target=1.6, config=c)):
        free, built = run_episode(env, make(), seed=5), run_episode(env, make(cfg), seed=5)
        assert free.ret == built.ret and free.omega == built.omega
    assert make_config(GEAR_ENV_ID, None) != cfg  # the env's settings differ from the default: a rebuild happened


def test_bind_rebuilds_with_the_same_arguments():
    v0 = _env("GearSpeed-v0").unwrapped.config
    p = SlowRamp(1.6, rate_fraction=0.5, name="mine")
    q = p.bind(v0)
    assert q is not p and q.bound and q.config is v0 and not p.bound
    assert (q.target, q.rate, q.name, q.action_mode) == (1.6, 0.5 * v0.max_domega, "mine", "delta")
    assert p.bind(task_config(GEAR_ENV_ID)) is p  # already the default task: nothing to rebuild
    h = HillClimber(task_config("GearSpeed-v1"))
    assert h.bind(task_config("GearSpeed-v1", {"max_steps": 7})) is h  # same action meaning: kept


def test_a_policy_built_for_another_task_is_refused():
    v1 = task_config("GearSpeed-v1")
    with pytest.raises(ValueError, match=r"action_mode 'target' vs 'delta'.*config="):
        run_episode(_env("GearSpeed-v0"), ConstantSpeed(1.0, config=v1), seed=0)
    with pytest.raises(ValueError, match="action_delay"):
        ConstantSpeed(1.0, config=v1).bind(task_config("GearSpeed-v1", {"action_delay": 1}))


def test_unbound_actions_follow_the_task():
    obs = np.zeros((1, 11), np.float32)  # omega at the middle of the range
    v0, v1 = task_config("GearSpeed-v0"), task_config("GearSpeed-v1")
    mid = 0.5 * (v0.omega_min + v0.omega_max)
    w = mid - 0.01  # a small step down: inside the rate limit of both tasks
    a_v1, _ = ConstantSpeed(w).predict(obs, episode_start=np.ones(1, bool))
    a_v0, _ = ConstantSpeed(w).bind(v0).predict(obs, episode_start=np.ones(1, bool))
    assert a_v0[0, 0] == pytest.approx(-0.01 / v0.max_domega, rel=1e-5)  # delta mode: the change of omega
    ref = mid - 0.01 / v1.reference_filter  # target mode: the set-point whose filtered step lands on w
    assert a_v1[0, 0] == pytest.approx(2 * (ref - v1.omega_min) / (v1.omega_max - v1.omega_min) - 1, rel=1e-5)


def test_evaluate_policies_binds_an_unbound_policy_to_its_task():
    from gear_env.evaluation import evaluate_policies

    cfg = task_config("GearSpeed-v0", FAST)
    rep = evaluate_policies({"free": ConstantSpeed(1.3), "built": ConstantSpeed(1.3, cfg)}, cfg, episodes=2, seed=3)
    assert [e.ret for e in rep.episodes["free"]] == [e.ret for e in rep.episodes["built"]]
