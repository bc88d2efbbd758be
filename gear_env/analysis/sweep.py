"""Frequency sweeps of the gear model: warm-started steady states, classification, Lyapunov.

A sweep visits the meshing frequencies in the sweep direction (``forward``: increasing omega,
``reverse``: decreasing), starting each one from the last state of the previous one, as a slowly
swept machine would. At each omega it discards ``transient`` mesh periods, records ``periods``
mesh periods (Poincare samples, amplitudes, contact loss) while a perturbed copy gives the largest
Lyapunov exponent, classifies the motion and, unless it is a converged period-1 orbit, confirms
the label on a further window of ``periods`` mesh periods (up to ``max_extend`` windows while the
orbit is still converging).

Parallel sweeps split the grid (in sweep order) into contiguous chunks of about equal cost. A
coarse pass (a continuous omega ramp through the grid, ``coarse_periods`` mesh periods per grid
step, in the parent process) provides the start state of every chunk, so each chunk starts on the
branch a slow sweep would be on; the chunks then run on any ``concurrent.futures.Executor``.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..sim import kernels as K
from ..sim.params import GearParams, model_code, refuse_extensions
from ..sim.simulator import (
    GearSimulator,
    auto_steps_rule,
    check_count,
    check_omega,
    check_stable_steps,
    check_steps,
    default_steps_per_period,
)
from .checkpoint import Checkpoint
from .classify import (
    DEFAULT_LYAP_TOL,
    DEFAULT_MAX_PERIOD,
    DEFAULT_TOL,
    classify_motion,
    lyapunov_tolerance,
    same_orbit,
)
from .lyapunov import DEFAULT_D0, default_skip, lyapunov_record, start_direction
from .results import PointResult, SweepResult, assemble

DIRECTIONS = ("forward", "reverse")


def steps_for(omega: float, base: int | None = None, adaptive: bool = False, params: GearParams | None = None) -> int:
    """Newmark steps per mesh period used at ``omega``.

    ``base=None`` (the default): the simulator's :func:`~gear_env.sim.simulator.default_steps_per_period`
    of ``params``' scheme (192, more below omega ~ 0.27; Fox-Goodwin 88; with the velocity correction 68). A fixed
    ``base`` is used as is, or with
    ``adaptive=True`` as
    ``max(base, ceil(base * 0.5 / omega))`` (the natural-time step ``h = 2 pi / (omega N)`` capped at
    its value at omega = 0.5).
    """
    if base is None:
        return default_steps_per_period(omega, params)
    if not adaptive:
        return int(base)
    return int(max(base, math.ceil(base * 0.5 / omega)))


@dataclass(frozen=True)
class SweepConfig:
    """Settings shared by every point of a sweep (picklable; sent to the workers)."""

    model: str
    direction: str
    transient: int
    periods: int
    params: GearParams
    steps_per_period: int | None
    adaptive_steps: bool
    lyapunov: bool
    tol: float = DEFAULT_TOL
    max_period: int = DEFAULT_MAX_PERIOD
    lyap_tol: float = DEFAULT_LYAP_TOL
    max_extend: int = 4
    d0: float = DEFAULT_D0

    def __post_init__(self) -> None:
        refuse_extensions(self.params, "sweep")

    def steps(self, omega: float) -> int:
        return steps_for(omega, self.steps_per_period, self.adaptive_steps, self.params)

    def fingerprint(self) -> dict[str, Any]:
        """JSON-ready identity of the sweep (a checkpoint must match it to be resumed)."""
        return {
            "model": self.model,
            "direction": self.direction,
            "transient": self.transient,
            "periods": self.periods,
            "params": self.params.to_dict(),
            "steps_per_period": self.steps_per_period,
            "adaptive_steps": self.adaptive_steps,
            "lyapunov": self.lyapunov,
            "tol": self.tol,
            "max_period": self.max_period,
            "lyap_tol": self.lyap_tol,
            "max_extend": self.max_extend,
            "d0": self.d0,
        } | ({} if (rule := auto_steps_rule(self.params)) == auto_steps_rule() else {"auto_steps": rule})


CHAOS_MARGIN = 10.0
"""A chaotic label whose pooled exponent is below this many zero bands (``lyapunov_tolerance``) is
re-examined over up to :data:`CHAOS_WINDOWS` more windows with the perturbed copy running."""
CHAOS_WINDOWS = 12
"""Extra windows (of ``periods`` mesh periods) at most for a marginal chaotic label."""


def run_point(cfg: SweepConfig, omega: float, state: np.ndarray | None) -> PointResult:
    """Steady motion at one omega from ``state`` (None: static equilibrium); see the module doc.

    The exponent is pooled over every window it was computed on (the first, and the confirmation
    windows of non-periodic motions), and the zero band shrinks as 2/T with the pooled time T
    (``classify.lyapunov_tolerance``).
    """
    n = cfg.steps(omega)
    code = model_code(cfg.model)
    sim = GearSimulator(cfg.params, cfg.model, n, omega, state)
    sim.advance(cfg.transient)
    acc = [0.0, 0.0]  # sum of log(d/d0), averaging time
    wins: list[tuple[float, float]] = []  # the same per window
    # the perturbed copy's direction, continued across consecutive Lyapunov windows (a fresh copy in
    # every window would add the stretch of its realignment, O(1) per window, which reads as weak
    # chaos on a torus); ``live`` is False before the first one and after a window without the copy
    u = start_direction(K.NSTATE)
    live = False

    def window(with_lyap: bool) -> tuple[np.ndarray, np.ndarray]:
        nonlocal live
        if with_lyap:
            x = sim.state
            if not live:
                u[:] = start_direction(K.NSTATE)
            skip = None if live else default_skip(cfg.periods)
            _, pc, stats, _, sl, tc = lyapunov_record(
                x, omega, cfg.periods, n, cfg.params.consts, code, cfg.d0, direction=u, skip=skip
            )
            live = True
            acc[0] += sl
            acc[1] += tc
            wins.append((sl, tc))
            sim.reset(initial_state=x, omega=omega)
            return pc, stats
        live = False
        iv = sim.advance(cfg.periods)
        return iv.poincare, iv.stats

    def classify(pc: np.ndarray) -> Any:
        lam = acc[0] / acc[1] if acc[1] > 0 else None
        ltol = lyapunov_tolerance(acc[1], cfg.lyap_tol) if acc[1] > 0 else cfg.lyap_tol
        return classify_motion(pc[:, : K.NSTATE], lam, cfg.tol, cfg.max_period, ltol)

    pc, stats = window(cfg.lyapunov)
    lam_out = None
    chain_state = None
    cls = classify(pc)
    confirmed = cls.label == "period-1" and cls.converged
    extend = 0
    while not confirmed and extend < cfg.max_extend:
        # confirm the label (the count, or the sign of the exponent) on a longer run
        pc2, stats2 = window(cfg.lyapunov and not cls.periodic)
        extend += 1
        new = classify(pc2)
        confirmed = new.label == cls.label and new.converged
        if confirmed and new.periodic:
            confirmed = same_orbit(pc[:, : K.NSTATE], pc2[:, : K.NSTATE], new.period, cfg.tol)
        cls, pc, stats = new, pc2, stats2
    if cfg.lyapunov and cls.label == "chaotic":
        # a chaotic label from an exponent within CHAOS_MARGIN bands of zero: a finite-time effect
        # of a torus (whose accumulated stretch stays bounded) or weak chaos (whose stretch grows
        # with time)? Keep the perturbed copy running: the pooled time T grows, the band ~1/T
        # shrinks, and the pooled exponent decides (a torus's falls into the band). If it is still
        # chaotic after them, the exponent of the later half of the windows alone decides: a torus's
        # accumulated stretch stops growing after a transient, weak chaos's keeps growing.
        # The sweep's chain goes on from the state before these windows (``final_state``), so that
        # the re-examination changes this point's label and samples only, never the next points'.
        chain_state = sim.state
        more = 0
        while more < CHAOS_WINDOWS and acc[0] < CHAOS_MARGIN * acc[1] * lyapunov_tolerance(acc[1], cfg.lyap_tol):
            pc2, stats2 = window(True)
            more += 1
            cls, pc, stats = classify(pc2), pc2, stats2
            if cls.label != "chaotic":
                confirmed = cls.converged
                break
        if more == CHAOS_WINDOWS and cls.label == "chaotic":
            late = wins[len(wins) // 2 :]
            t_late = sum(w[1] for w in late)
            lam_late = sum(w[0] for w in late) / t_late
            ltol = lyapunov_tolerance(t_late, cfg.lyap_tol)
            if lam_late <= ltol:
                cls = classify_motion(pc[:, : K.NSTATE], lam_late, cfg.tol, cfg.max_period, ltol)
                confirmed = cls.converged
                lam_out = lam_late
    label, period = cls.label, cls.period
    if not cls.converged and cls.residual > 10.0 * cfg.tol:
        # attracting (lam < 0) but no recurrence within max_period after every window: a torus
        # phase-locked at a higher order, reported as quasi-periodic (converged=False flags it)
        label, period = "quasi-periodic", 0
    return PointResult(
        omega=float(omega),
        regime=label,
        period=period,
        lyapunov=(lam_out if lam_out is not None else acc[0] / acc[1]) if cfg.lyapunov else None,
        poincare=pc,
        stats=stats,
        final_state=sim.state if chain_state is None else chain_state,
        steps_per_period=n,
        n_clusters=cls.n_clusters,
        converged=bool(cls.converged and confirmed),
        periods_recorded=cfg.periods,
    )


def run_chunk(cfg: SweepConfig, omegas: Sequence[float], state: np.ndarray | None) -> list[PointResult]:
    """Run consecutive omegas (in sweep order), each warm-started from the previous one.

    Top-level so that process pools and Dask can pickle it.
    """
    out = []
    x = None if state is None else np.asarray(state, float)
    for w in omegas:
        r = run_point(cfg, float(w), x)
        out.append(r)
        x = r.final_state
    return out


def coarse_pass(
    cfg: SweepConfig, omegas: np.ndarray, targets: Sequence[int], coarse_periods: int = 10
) -> dict[int, np.ndarray]:
    """Start states for the chunk heads ``targets`` (indices into ``omegas``, which are in sweep
    order): a continuous ramp through the grid, ``coarse_periods`` mesh periods per grid step,
    after ``cfg.transient`` periods at ``omegas[0]``. Returns index -> state."""
    want = set(int(t) for t in targets)
    out: dict[int, np.ndarray] = {}
    if 0 in want:
        out[0] = None  # type: ignore[assignment]
    last = max(want) if want else 0
    if last == 0:
        return out
    sim = GearSimulator(cfg.params, cfg.model, cfg.steps(omegas[0]), float(omegas[0]))
    sim.advance(cfg.transient)
    for k in range(1, last + 1):
        w0, w1 = float(omegas[k - 1]), float(omegas[k])
        n = cfg.steps(min(w0, w1))
        if n != sim.steps_per_period:
            sim = GearSimulator(cfg.params, cfg.model, n, w0, sim.state)
        if w1 != w0:
            sim.advance(coarse_periods, omega_end=w1)
        if k in want:
            out[k] = sim.state
    return out


def _check_grid(omegas: Any) -> np.ndarray:
    if omegas is None or np.asarray(omegas).dtype == bool:  # asarray(None, float) would be NaN, True 1.0
        raise ValueError(f"omegas must be a 1-D sequence of numbers, got {omegas!r}")
    try:
        w = np.asarray(omegas, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"omegas must be a 1-D sequence of numbers, got {omegas!r}") from exc
    if w.ndim == 0:
        w = w.reshape(1)
    if w.ndim != 1:
        raise ValueError(f"omegas must be 1-D, got shape {w.shape}")
    if w.size == 0:
        raise ValueError("omegas must not be empty")
    if not np.all(np.isfinite(w)):
        raise ValueError("omegas must be finite (found NaN or inf)")
    for v in w:
        check_omega(float(v), "omegas")
    return w


def _split_cost(cost: np.ndarray, n_chunks: int) -> list[tuple[int, int]]:
    """Contiguous [start, stop) ranges of about equal total cost."""
    n = len(cost)
    n_chunks = max(1, min(n_chunks, n))
    cum = np.concatenate([[0.0], np.cumsum(cost)])
    cuts = [0]
    for j in range(1, n_chunks):
        c = int(np.searchsorted(cum, cum[-1] * j / n_chunks))
        c = min(max(c, cuts[-1] + 1), n - (n_chunks - j))
        cuts.append(c)
    cuts.append(n)
    return [(cuts[i], cuts[i + 1]) for i in range(n_chunks) if cuts[i + 1] > cuts[i]]


class _Progress:
    """tqdm if installed, else a simple stderr line."""

    def __init__(self, total: int, enabled: bool, desc: str):
        self.total, self.enabled, self.n = total, enabled, 0
        self.bar = None
        self.t0 = time.perf_counter()
        self._last = 0.0
        if enabled:
            try:
                from tqdm.auto import tqdm

                self.bar = tqdm(total=total, desc=desc, unit="pt", file=sys.stderr)
            except ImportError:
                self.desc = desc

    def update(self, k: int) -> None:
        self.n += k
        if not self.enabled:
            return
        if self.bar is not None:
            self.bar.update(k)
            return
        now = time.perf_counter()
        if now - self._last > 0.5 or self.n >= self.total:
            self._last = now
            print(f"\r{self.desc}: {self.n}/{self.total} points, {now - self.t0:.1f} s", end="", file=sys.stderr)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.enabled:
            print(file=sys.stderr)


def sweep(
    omegas: Any,
    model: str = "dynamic",
    direction: str = "forward",
    transient: int = 300,
    periods: int = 200,
    params: GearParams | None = None,
    steps_per_period: int | None = None,
    lyapunov: bool = True,
    workers: int = 1,
    executor: Executor | str | None = None,
    progress: bool = True,
    checkpoint: str | None = None,
    *,
    scheduler: str | None = None,
    chunks: int | None = None,
    adaptive_steps: bool = False,
    coarse_periods: int = 10,
    tol: float = DEFAULT_TOL,
    max_period: int = DEFAULT_MAX_PERIOD,
    lyap_tol: float = DEFAULT_LYAP_TOL,
    max_extend: int = 4,
    keep_checkpoint: bool = False,
    _on_point: Callable[[int], None] | None = None,
) -> SweepResult:
    """Sweep the meshing frequency and record the steady motion at each omega.

    Args:
        omegas: grid of meshing frequencies Omega/omega_n (finite, > 0, non-empty). Results
            come back in this order; the sweep visits them sorted in ``direction``.
        model: ``"constant"`` or ``"dynamic"`` backlash.
        direction: ``"forward"`` (increasing omega) or ``"reverse"`` (decreasing).
        transient: mesh periods discarded at each omega (positive integer).
        periods: mesh periods recorded at each omega (>= 4).
        params: physical parameters (default Table 1).
        steps_per_period: Newmark steps per mesh period; None (default): the simulator's
            ``default_steps_per_period(omega)`` at each point. A fixed value is raised at low omega
            by ``adaptive_steps``.
        lyapunov: compute the largest Lyapunov exponent (a perturbed copy runs alongside the
            recorded window: about +40 % of the cost with the default windows).
        workers: parallel workers; 1 with no ``executor`` runs serially in this process.
        executor: None/``"local"`` (process pool of ``workers`` when workers > 1), ``"dask"``
            (needs ``scheduler``), or any ``concurrent.futures.Executor`` (not shut down here).
        progress: show a progress bar on stderr (tqdm if installed).
        checkpoint: file to save progress to (atomically, after every chunk, or every point at
            most every 2 s in a serial sweep, and on interruption); if it exists and matches
            this sweep, finished points are reused. Deleted after success unless ``keep_checkpoint``.
        scheduler: Dask scheduler address (``tcp://host:port``) for ``executor="dask"``.
        chunks: number of chunks of a parallel sweep (default 8 per worker).
        adaptive_steps: with a fixed ``steps_per_period``, use :func:`steps_for` with ``adaptive=True``.
        coarse_periods: mesh periods per grid step of the coarse ramp that starts the chunks.
        tol, max_period, lyap_tol: classification settings (:func:`classify_motion`).
        max_extend: extra windows of ``periods`` used to confirm a label.
        keep_checkpoint: write the checkpoint complete and keep it after success, for a caller
            that deletes it only once the result is safely saved (the command line does).

    Returns:
        :class:`SweepResult`.

    Raises:
        ValueError: invalid arguments (the message names the argument).
        SimulationDivergedError: the model blew up at some omega.
    """
    job = _prepare(
        omegas, model, direction, transient, periods, params, steps_per_period, lyapunov, checkpoint,
        adaptive_steps, tol, max_period, lyap_tol, max_extend, _on_point,
    )  # fmt: skip
    workers = check_count(workers, "workers", 1)
    coarse_periods = check_count(coarse_periods, "coarse_periods", 1)
    parallel = workers > 1 or executor is not None
    _execute([job], parallel, workers, executor, scheduler, chunks, coarse_periods, progress)
    return _finish(job, parallel, coarse_periods, keep_checkpoint=bool(keep_checkpoint))


def sweep_many(
    specs: Sequence[dict[str, Any]],
    workers: int = 2,
    executor: Executor | str | None = None,
    progress: bool = True,
    *,
    scheduler: str | None = None,
    chunks: int | None = None,
    coarse_periods: int = 10,
) -> list[SweepResult]:
    """Run several sweeps (models, directions, parameter sets) on one executor at once.

    Each spec holds keyword arguments of :func:`sweep` (``omegas`` required; ``model``,
    ``direction``, ``transient``, ``periods``, ``params``, ``steps_per_period``, ``lyapunov``,
    ``checkpoint``, ``adaptive_steps``, ``tol``, ``max_period``, ``lyap_tol``, ``max_extend``).
    The chunks of all sweeps share the workers, so short and long sweeps balance out.
    Returns the results in the order of ``specs``.
    """
    allowed = {"omegas", "model", "direction", "transient", "periods", "params", "steps_per_period", "lyapunov",
               "checkpoint", "adaptive_steps", "tol", "max_period", "lyap_tol", "max_extend"}  # fmt: skip
    jobs = []
    for k, spec in enumerate(specs):
        bad = set(spec) - allowed
        if bad or "omegas" not in spec:
            raise ValueError(f"specs[{k}] must hold sweep() keyword arguments with 'omegas'; bad keys {sorted(bad)}")
        sp = dict(spec)
        jobs.append(
            _prepare(
                sp.pop("omegas"),
                sp.get("model", "dynamic"),
                sp.get("direction", "forward"),
                sp.get("transient", 300),
                sp.get("periods", 200),
                sp.get("params"),
                sp.get("steps_per_period"),
                sp.get("lyapunov", True),
                sp.get("checkpoint"),
                sp.get("adaptive_steps", False),
                sp.get("tol", DEFAULT_TOL),
                sp.get("max_period", DEFAULT_MAX_PERIOD),
                sp.get("lyap_tol", DEFAULT_LYAP_TOL),
                sp.get("max_extend", 4),
                None,
            )  # fmt: skip
        )
    if not jobs:
        raise ValueError("specs must not be empty")
    workers = check_count(workers, "workers", 1)
    coarse_periods = check_count(coarse_periods, "coarse_periods", 1)
    parallel = workers > 1 or executor is not None
    _execute(jobs, parallel, workers, executor, scheduler, chunks, coarse_periods, progress)
    return [_finish(j, parallel, coarse_periods) for j in jobs]


@dataclass
class _Job:
    """One sweep in progress."""

    cfg: SweepConfig
    w: np.ndarray  # grid as given
    order: np.ndarray  # indices of w in sweep order
    ws: np.ndarray  # grid in sweep order
    ck: Checkpoint | None
    done: dict[int, PointResult]
    on_point: Callable[[int], None] | None

    def record(self, i: int, r: PointResult) -> None:
        self.done[i] = r
        if self.ck:
            self.ck.add(i, r)
        if self.on_point is not None:
            self.on_point(len(self.done))


def _prepare(
    omegas, model, direction, transient, periods, params, steps_per_period, lyapunov, checkpoint,
    adaptive_steps, tol, max_period, lyap_tol, max_extend, on_point,
) -> _Job:  # fmt: skip
    w = _check_grid(omegas)
    model_code(model)
    if direction not in DIRECTIONS:
        raise ValueError(f"direction must be 'forward' or 'reverse', got {direction!r}")
    transient = check_count(transient, "transient", 1)
    periods = check_count(periods, "periods", 4)
    steps_per_period = None if steps_per_period is None else check_steps(steps_per_period)
    max_extend = check_count(max_extend, "max_extend", 0)
    params = GearParams() if params is None else params
    if not isinstance(params, GearParams):
        raise ValueError(f"params must be a GearParams or None, got {type(params).__name__}")
    # the classification settings are checked here, not only when the first point is classified
    real = (int, float, np.integer, np.floating)
    if isinstance(tol, bool) or not isinstance(tol, real) or not 0.0 < tol < 0.5:
        raise ValueError(f"tol must be in (0, 0.5), got {tol!r}")
    max_period = check_count(max_period, "max_period", 1)
    if isinstance(lyap_tol, bool) or not isinstance(lyap_tol, real) or not (math.isfinite(lyap_tol) and lyap_tol > 0):
        raise ValueError(f"lyap_tol must be a finite number > 0, got {lyap_tol!r}")
    for wi in w:  # a conditionally stable Newmark beta (GearParams.newmark_beta): refused before any work
        check_stable_steps(params, steps_for(float(wi), steps_per_period, bool(adaptive_steps), params), float(wi))
    cfg = SweepConfig(
        model, direction, transient, periods, params, steps_per_period, bool(adaptive_steps), bool(lyapunov),
        float(tol), int(max_period), float(lyap_tol), max_extend,
    )  # fmt: skip
    order = np.argsort(w, kind="stable")
    if direction == "reverse":
        order = order[::-1]
    ws = w[order]
    ck = Checkpoint.open(checkpoint, cfg.fingerprint(), ws) if checkpoint else None
    return _Job(cfg, w, order, ws, ck, dict(ck.done) if ck else {}, on_point)


def _finish(job: _Job, parallel: bool, coarse_periods: int, keep_checkpoint: bool = False) -> SweepResult:
    cfg = job.cfg
    points: list[Any] = [None] * len(job.w)
    for i, idx in enumerate(job.order):
        points[idx] = job.done[i]
    meta = {
        "steps_per_period_base": cfg.steps_per_period, "adaptive_steps": cfg.adaptive_steps, "parallel": parallel,
        "coarse_periods": coarse_periods if parallel else 0, "tol": cfg.tol, "max_period": cfg.max_period,
        "lyap_tol": cfg.lyap_tol, "max_extend": cfg.max_extend,
    }  # fmt: skip
    res = assemble(job.w, points, cfg.model, cfg.direction, cfg.params, cfg.transient, cfg.periods, cfg.lyapunov, meta)  # type: ignore[arg-type]
    if job.ck:
        if keep_checkpoint:
            job.ck.save(force=True)  # complete: every point, for the caller to delete once it saved the result
        else:
            job.ck.remove()
    return res


def _execute(
    jobs: list[_Job],
    parallel: bool,
    workers: int,
    executor: Executor | str | None,
    scheduler: str | None,
    chunks: int | None,
    coarse_periods: int,
    progress: bool,
) -> None:
    if chunks is not None:  # checked even where it is not used (a serial sweep), so a typo is not ignored
        check_count(chunks, "chunks", 1)
    total = sum(len(j.ws) for j in jobs)
    desc = f"sweep {jobs[0].cfg.model} {jobs[0].cfg.direction}" if len(jobs) == 1 else f"{len(jobs)} sweeps"
    bar = _Progress(total, progress, desc)
    bar.update(sum(len(j.done) for j in jobs))
    try:
        if not parallel:
            for job in jobs:
                x = None
                for i, om in enumerate(job.ws):
                    if i in job.done:
                        x = job.done[i].final_state
                        continue
                    r = run_point(job.cfg, float(om), x)
                    job.record(i, r)
                    bar.update(1)
                    if job.ck:
                        job.ck.save(force=False)
                    x = r.final_state
        else:
            n_chunks = check_count(chunks, "chunks", 1) if chunks is not None else 8 * workers
            _run_parallel(jobs, bar, workers, executor, scheduler, n_chunks, coarse_periods)
    except BaseException:
        for job in jobs:
            if job.ck:
                job.ck.save(force=True)
        raise
    finally:
        bar.close()


def _plan(job: _Job, n_chunks: int) -> list[tuple[int, int, np.ndarray | None, bool]]:
    """Chunks still to run: (first index, stop, start state, state is final?)."""
    cost = np.array([job.cfg.steps(float(v)) for v in job.ws], float)
    todo: list[tuple[int, int, np.ndarray | None, bool]] = []
    for a, b in _split_cost(cost, n_chunks):
        idx = [i for i in range(a, b) if i not in job.done]
        if not idx:
            continue
        first = idx[0]
        if first > a:  # continue a partly finished chunk from its last finished point
            todo.append((first, b, job.done[first - 1].final_state, True))
        elif first == 0:  # the sweep's first point starts from the static equilibrium
            todo.append((first, b, None, True))
        else:  # start from the coarse pass
            todo.append((first, b, None, False))
    return todo


_WARM = False


def warm_numba_cache() -> None:
    """Compile/load every kernel a sweep uses (tiny inputs); idempotent per process.

    Run in the parent before a local pool starts and in each worker as its initializer
    (:func:`gear_env.analysis.executors.get_executor`'s ``warm``), so the workers only read the
    on-disk numba cache and never race to write it.
    """
    global _WARM
    if _WARM:
        return
    p = GearParams()
    for model in ("constant", "dynamic"):
        x = np.zeros(10)
        K.static_equilibrium(p.consts, model_code(model), 0.0, x)
        lyapunov_record(x, 1.0, 4, 8, p.consts, model_code(model), 1e-8)
        run_point(SweepConfig(model, "forward", 1, 4, p, 8, False, False, max_extend=0), 1.0, None)
    _WARM = True


def _run_parallel(
    jobs: list[_Job],
    bar: _Progress,
    workers: int,
    executor: Executor | str | None,
    scheduler: str | None,
    n_chunks: int,
    coarse_periods: int,
) -> None:
    from concurrent.futures import FIRST_COMPLETED, wait

    from .executors import get_executor

    with get_executor(executor, workers, scheduler, warm=warm_numba_cache) as ex:
        pending: dict[Any, tuple[str, int, Any]] = {}

        def submit_chunk(jid: int, first: int, stop: int, state: np.ndarray | None) -> None:
            job = jobs[jid]
            f = ex.submit(run_chunk, job.cfg, [float(v) for v in job.ws[first:stop]], state)
            pending[f] = ("chunk", jid, first)

        for jid, job in enumerate(jobs):
            todo = _plan(job, n_chunks)
            waiting = [(first, stop) for first, stop, _, ready in todo if not ready]
            for first, stop, state, ready in todo:
                if ready:
                    submit_chunk(jid, first, stop, state)
            if waiting:
                # the coarse ramp runs as a task too, alongside the first chunk
                cf = ex.submit(coarse_pass, job.cfg, job.ws, [a for a, _ in waiting], coarse_periods)
                pending[cf] = ("coarse", jid, waiting)
        while pending:
            finished, _ = wait(list(pending), return_when=FIRST_COMPLETED)
            for f in finished:
                kind, jid, info = pending.pop(f)
                job = jobs[jid]
                if kind == "coarse":
                    starts = f.result()
                    for first, stop in info:
                        submit_chunk(jid, first, stop, starts[first])
                    continue
                for j, pr in enumerate(f.result()):
                    job.record(info + j, pr)
                    bar.update(1)
                if job.ck:
                    job.ck.save(force=True)
