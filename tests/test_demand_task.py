"""GearSpeedDemand-v0's demand band and family: validation, draws inside the band, refusal before training; every
task's reset(seed) determines its episode whatever the env ran before (the reset observation's demand)."""

from __future__ import annotations

import numpy as np
import pytest

from gear_env.envs.env_config import task_config
from gear_env.envs.tasks import DEMAND_SETTINGS, TASK_SETTINGS, PlantFamily, random_demand


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ((1.8, 1.2), r"demand_range must be \(low, high\) with low <= high"),
        ((0.05, 1.0), r"demand_range must lie in \[0.1, 3\]"),
        ((1.0, 3.5), r"demand_range must lie in \[0.1, 3\]"),
        ((1.0,), r"demand_range must be a pair"),
        ("1.2-1.8", r"demand_range must be a pair"),
        ((1.0, float("nan")), r"demand_range must be a pair"),
    ],
)
def test_bad_demand_range_names_the_field_and_range(value, match):
    with pytest.raises(ValueError, match=match):
        task_config("GearSpeedDemand-v0", {"demand_range": value})


def test_demand_range_follows_omega_bounds():
    cfg = task_config("GearSpeedDemand-v0", {"omega_max": 2.0, "demand_range": (1.2, 1.8)})
    assert cfg.demand_range == (1.2, 1.8)
    with pytest.raises(ValueError, match=r"demand_range must lie in \[0.1, 1.5\]"):
        task_config("GearSpeedDemand-v0", {"omega_max": 1.5, "demand_range": (1.2, 1.8)})


def test_random_demand_stays_in_the_band_and_default_is_unchanged():
    import gymnasium as gym

    env = gym.make("GearSpeedDemand-v0").unwrapped
    lo, hi = DEMAND_SETTINGS["demand_range"]
    seen = []
    for seed in range(5):
        env.reset(seed=seed)
        d = env.episode.demand
        assert lo <= d.min() and d.max() <= hi
        seen.append(d)
    assert np.ptp(np.concatenate(seen)) > 0.5 * (hi - lo)  # levels spread over the band
    # demand_range=None draws over [omega_min, omega_max] with the same random calls as before the setting
    full = gym.make("GearSpeedDemand-v0", demand_range=None).unwrapped
    full.reset(seed=3)
    d = full.episode.demand
    assert d.min() >= full.config.omega_min and d.max() <= full.config.omega_max
    assert d.max() - d.min() > hi - lo  # wider than the band


def test_random_demand_is_the_documented_draw():
    rng_a, rng_b = np.random.default_rng(7), np.random.default_rng(7)
    a = random_demand(rng_a, 40, 1.2, 1.8, (10, 30))
    n = int(rng_b.integers(10, 31))
    assert np.all(a[:n] == rng_b.uniform(1.2, 1.8))
    assert len(a) == 41


def test_shipped_family_is_inside_the_simulator_range_and_unloading_is_refused():
    cfg = task_config("GearSpeedDemand-v0")
    assert isinstance(cfg.plant_family, PlantFamily)
    assert cfg.plant_family.e_m1 == (0.25, 2.0) and cfg.plant_family.load == (0.4, 1.5)
    with pytest.raises(ValueError, match=r"plant_family.load must lie in \[0.001, 100\]"):
        task_config("GearSpeedDemand-v0", {"plant_family": {"load": (0.0, 1.5), "e_m1": (0.25, 2.0)}})


def test_a_family_leaving_the_range_is_refused_before_training(tmp_path):
    """`gear-env train` refuses the family before it creates the run folder or builds an environment."""
    from agents.ppo import train
    from gear_env.cli.train import build_parser, options_from_args

    out = tmp_path / "run"
    argv = ["--env", "GearSpeedDemand-v0", "--out", str(out), "--timesteps", "4096", "--quiet", "--no-progress"]
    argv += ["--set", 'plant_family={"load": [0.4, 1.5], "e_m1": [0.25, 200.0]}']
    with pytest.raises(ValueError, match=r"plant_family.e_m1 must lie in \[0, 100\]"):
        train(options_from_args(build_parser().parse_args(argv)))
    assert not out.exists()


def test_learned_window_plot_draws_fixed_best_beside_the_policy():
    """The figure's fixed-best line (one speed for every plant) is drawn when given, and only then."""
    from gear_env.plots.tasks import plot_learned_window

    curve = {"label": "p", "demand": [1.2, 1.5, 1.8], "delivered": [1.2, 1.4, 1.5], "quiet": [(1.0, 1.6)]}
    labels = lambda fig: [ln.get_label() for ln in fig.axes[0].get_lines()]  # noqa: E731
    with_fixed = plot_learned_window([{**curve, "fixed": [1.15, 1.15, 1.15], "oracle": [1.2, 1.5, 1.6]}])
    assert "fixed-best (same for every plant)" in labels(with_fixed) and "oracle" in labels(with_fixed)
    line = next(ln for ln in with_fixed.axes[0].get_lines() if ln.get_label().startswith("fixed-best"))
    assert list(line.get_ydata()) == [1.15, 1.15, 1.15]
    assert not any(lb.startswith("fixed-best") for lb in labels(plot_learned_window([curve])))


NO_DEMAND = {"max_steps": 5, "periods_per_step": 8, "warmup_periods": 16}
SHORT = {**NO_DEMAND, "demand_segment_steps": (2, 3)}


def _scaled_demand(cfg, value: float) -> float:
    """The observation's demand entry for a required omega (scaled like omega)."""
    return float(np.clip(2.0 * (value - cfg.omega_min) / (cfg.omega_max - cfg.omega_min) - 1.0, -1.0, 1.0))


@pytest.mark.parametrize("env_id", list(TASK_SETTINGS))
def test_reset_seed_alone_determines_the_episode_of_a_used_env(env_id):
    """reset(seed) after a finished episode gives what a fresh env gives (every registered task), the reset
    observation's demand (the demand of step 0) included: before the fix it showed the new demand at the step the
    last episode ended at."""
    import gymnasium as gym

    kw = SHORT if "demand" in TASK_SETTINGS[env_id] else NO_DEMAND
    used = gym.make(env_id, **kw).unwrapped
    used.action_space.seed(0)
    used.reset(seed=101)
    done = False
    while not done:
        _, _, term, trunc, _ = used.step(used.action_space.sample())
        done = term or trunc
    fresh = gym.make(env_id, **kw).unwrapped
    obs_u, info_u = used.reset(seed=7)
    obs_f, info_f = fresh.reset(seed=7)
    np.testing.assert_array_equal(obs_u, obs_f)
    assert info_u == info_f
    if kw is SHORT:
        k = list(used.observation_names).index("demand")
        assert obs_u[k] == pytest.approx(_scaled_demand(used.config, used.episode.demand[0]), abs=1e-6)
        assert used.episode.demand[0] != used.episode.demand[SHORT["max_steps"]]  # the old bug would show
        assert info_u["demand"] == used.episode.demand[0]
    for a in (0.3, -0.5, 0.9):
        out_u, out_f = used.step(np.array([a], np.float32)), fresh.step(np.array([a], np.float32))
        np.testing.assert_array_equal(out_u[0], out_f[0])
        assert out_u[1:] == out_f[1:]  # reward, terminated, truncated, info


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_a_fixed_demand_profile_starts_at_step_0_after_a_used_reset(mode):
    """The bug was not only the Demand ids': any task with a demand profile (here a fixed one on GearSpeed-v2) showed
    the demand of the previous episode's last step in its reset observation and info, vector autoresets included."""
    import gymnasium as gym

    kw = {**NO_DEMAND, "demand": [(0, 1.0), (2, 1.0), (3, 1.6)]}  # 1.0 at step 0, 1.6 from step 3 on
    used, fresh = gym.make("GearSpeed-v2", **kw).unwrapped, gym.make("GearSpeed-v2", **kw).unwrapped
    k = list(used.observation_names).index("demand")
    used.reset(seed=1)
    for _ in range(NO_DEMAND["max_steps"]):
        used.step(np.array([0.1], np.float32))
    (obs_u, info_u), (obs_f, info_f) = used.reset(seed=2), fresh.reset(seed=2)
    np.testing.assert_array_equal(obs_u, obs_f)
    assert info_u["demand"] == info_f["demand"] == 1.0
    assert obs_u[k] == pytest.approx(_scaled_demand(used.config, 1.0), abs=1e-6)
    venv = gym.make_vec("GearSpeed-v2", num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kw)
    venv.reset(seed=5)
    seen = 0
    for _ in range(2 * NO_DEMAND["max_steps"] + 2):
        obs, _, term, trunc, info = venv.step(np.full((2, 1), 0.1, np.float32))
        if mode == "SameStep" and (term | trunc).any():  # the reset observation replaces the final one at once
            r = np.flatnonzero(term | trunc)
        elif mode == "NextStep":
            r = np.flatnonzero(venv.unwrapped._core.steps == 0)
        else:
            continue
        assert np.allclose(obs[r, k], _scaled_demand(used.config, 1.0), atol=1e-6)
        assert np.all(info["demand"][r] == 1.0)
        seen += len(r)
    assert seen >= 2
    venv.close()


def test_vector_autoreset_shows_the_demand_of_step_0():
    import gymnasium as gym

    venv = gym.make_vec("GearSpeedDemand-v1", num_envs=3, vectorization_mode="vector_entry_point", **SHORT)
    core = venv.unwrapped._core
    k = list(core.observation_names).index("demand")
    obs, _ = venv.reset(seed=3)
    starts = changed = 0
    for _ in range(3 * SHORT["max_steps"] + 2):
        obs, _, term, trunc, _ = venv.step(np.full((3, 1), 0.2, np.float32))
        fresh = core.steps == 0  # rows whose observation is a reset's (NEXT_STEP autoreset)
        for r in np.flatnonzero(fresh):
            assert obs[r, k] == pytest.approx(_scaled_demand(core.config, core._dem[r, 0]), abs=1e-6)
            starts += 1
            changed += core._dem[r, 0] != core._dem[r, SHORT["max_steps"]]
    assert starts >= 6 and changed >= 3  # rows where the old bug would show
    venv.close()


class _FollowDemandReading:
    """Commands the speed the observation's demand entry shows (a policy that acts on that reading at once)."""

    def __init__(self, k: int) -> None:
        self.k = k

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.asarray(obs)[:, self.k : self.k + 1].astype(np.float32), state


def test_an_evaluation_episode_does_not_depend_on_the_episodes_before_it():
    """evaluate_policies reuses one env; each episode's return must equal that of the same seed in a fresh env."""
    import gymnasium as gym

    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies, run_episode

    cfg = task_config("GearSpeedDemand-v1", {**SHORT, "action_mode": "target"})
    probe = gym.make("GearSpeedDemand-v1", **SHORT, action_mode="target").unwrapped
    pol = _FollowDemandReading(list(probe.observation_names).index("demand"))
    # the same policy twice: the second one's episodes run on the env the first one has used
    report = evaluate_policies({"first": pol, "follow": pol}, cfg, episodes=4, seed=40)
    for name in ("first", "follow"):
        for k, ep in enumerate(report.episodes[name]):
            alone = run_episode(gym.make("GearSpeedDemand-v1", **SHORT, action_mode="target"), pol, 40 + k)
            assert ep.ret == alone.ret, (name, k)
