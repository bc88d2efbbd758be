"""Pseudo-arclength continuation of periodic orbits in omega, bifurcations and branch switching.

A period-N orbit is a zero of ``G(x, omega) = P^N(x; omega) - x`` where ``P`` is the Poincare map
of the simulator's Newmark discretisation with every contact change located inside its step
(:mod:`gear_env.analysis.tangent`, ``corrected=2``: the same kernels, the step split at the
crossing, so the map is smooth in x and omega), with the exact Jacobian ``M = dP^N/dx`` of that
map from its variational equations; ``dP^N/domega`` by a forward difference of the map. Its
multipliers are the eigenvalues of ``M``. (A contact that begins and ends inside one step is not
seen at any step end and so not located, nor is a crossing whose search fails; such a step keeps
the discrete map's one-sided derivative. Both are rare and occur only at grazing. ``located=False``:
the unlocated map of the fixed-step simulator, for comparison; see :class:`OrbitMap`.) The branch through ``(x, omega)``
is followed in arclength: each new point is predicted along the unit tangent ``t`` (the null
vector of ``[M - I, dP/domega]``) by a step ``ds`` and corrected by Newton's method on
``G = 0`` plus ``t . (z - z_pred) = 0``, so that folds (turning points in omega) are passed and
unstable parts are kept.

Step size. ``ds`` grows by 1.6 after a corrector that converged in <= 3 iterations, shrinks by
0.7 after one that needed >= 6, and is halved (the point rejected) when Newton fails, the
predicted direction turns by more than ``MAX_TURN`` (curvature: cos(angle) between successive
tangents < 0.96) or the corrected point is farther than 2 ds from the predicted one. Below
``ds_min`` the branch stops at its last good point with the reason.

Steps per period. The map at omega uses ``default_steps_per_period(omega)`` Newmark steps per mesh
period (the discretisation of every other result); within one corrector the count of the
predicted omega is kept, so each stored point is an exact fixed point of the map with its
recorded step count.

Bifurcations between two successive points A, B of a branch are detected by test functions and
located by bisection along the secant (each trial point corrected onto the branch):

* fold: sign of ``det(M - I)`` = prod(mu - 1) (a real multiplier through +1; also the sign of
  the omega-component of the tangent changes);
* period-doubling: sign of ``det(M + I)`` = prod(mu + 1) (a real multiplier through -1);
* Neimark-Sacker: the number of complex multipliers outside the unit circle changes;
* grazing: the number of contact-region changes along the orbit (at step ends) changes, i.e.
  an extremum of Delta - (+/-B_d) crosses zero: the orbit touches a contact boundary.

The located point carries the critical multipliers (nearest +1, -1 or the complex pair nearest
the unit circle). At a period-doubling point of a period-N branch, branch switching starts a
period-2N branch: the fixed point of ``P^2N`` on the hyperplane ``v . (x - x*) = eps`` (v: the
eigenvector of the multiplier -1), then pseudo-arclength from the secant of two such points. A
period-2N branch that comes back onto its parent (``|P^N(x) - x|`` small: the other
period-doubling point of the same bubble) ends there.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._numba_cache import announce_compile
from ..errors import SimulationDivergedError
from ..sim import kernels as K
from ..sim.params import GearParams, model_code, refuse_extensions, refuse_velocity_correction
from ..sim.simulator import (
    NEWTON_MAX_ITER,
    NEWTON_TOL,
    GearSimulator,
    check_omega,
    check_stable_steps,
    default_steps_per_period,
)
from . import tangent as TG
from .floquet import check_located

TANGENT_COMPILE_TIME = "4 min on an idle 2-core machine (one kernel holds all three tangent modes)"
"""What the first-use notice of the tangent-map kernel says (measured: 231 s at load about 1)."""

BIFURCATION_TYPES = ("fold", "period-doubling", "neimark-sacker", "grazing")
MAX_TURN = 0.96
"""Smallest cos(angle) between successive unit tangents; a sharper turn halves the step."""
CORNER_DS = 1e-3
"""A sharp turn is accepted once the step is below this: the branch has a corner (a contact
change: the map is only piecewise smooth), not a curve to resolve."""
COMPLEX_TOL = 1e-7
"""A multiplier with |Im mu| <= COMPLEX_TOL counts as real."""
MAX_PERIOD = 8
"""Default ``max_period``: a period-doubling cascade is followed up to period-8 orbits; a period
doubling of a period-8 branch is reported (a bifurcation point) but not switched onto."""
MEET_OMEGA = 1e-3
"""Two branches of one period whose continuations both stop (step size) within this distance in
omega, on the same orbit (:data:`MEET_GAP`), are one branch traced from its two ends: they met."""
MEET_GAP = 1e-3
"""Largest difference (b0, relative to 1 + max|x|) of the Poincare points of two stopped branch
ends, over the cyclic shifts of the orbit, for the ends to count as the same orbit."""


# ----------------------------------------------------------------------------- results
@dataclass
class Branch:
    """One continued branch of period-N orbits (arrays along the branch, in continuation order).

    Attributes:
        period: N (mesh periods).
        omega: (n,) Omega/omega_n.
        states: (n, 10) orbit state on the Poincare section (b0 units).
        multipliers: (n, 10) complex Floquet multipliers (exact Jacobian of the discrete map),
            sorted by decreasing modulus.
        amplitude_u / amplitude_delta: (n,) half peak-to-peak of U and Delta over the orbit (b0).
        switches: (n,) contact-region changes per orbit.
        steps_per_period: (n,) Newmark steps per mesh period of each point.
        parent: index of the branch this one was switched from (None for a primary branch).
        stop_reason: why the continuation of this branch ended.
        complete: False if it ended on a failure (Newton, step size, kernel) rather than at the
            end of the omega range or back on its parent branch.
    """

    period: int
    omega: np.ndarray
    states: np.ndarray
    multipliers: np.ndarray
    amplitude_u: np.ndarray
    amplitude_delta: np.ndarray
    switches: np.ndarray
    steps_per_period: np.ndarray
    parent: int | None = None
    stop_reason: str = ""
    complete: bool = True

    @property
    def max_multiplier(self) -> np.ndarray:
        """(n,) largest |multiplier|."""
        return np.abs(self.multipliers[:, 0]) if len(self.omega) else np.zeros(0)

    @property
    def stable(self) -> np.ndarray:
        """(n,) all |multipliers| < 1."""
        return self.max_multiplier < 1.0

    def to_json_dict(self) -> dict[str, Any]:
        """The JSON layout of ``gear-env continuation`` (lists of equal length along the branch)."""
        return {
            "period": int(self.period),
            "omega": [float(v) for v in self.omega],
            "amplitude_u": [float(v) for v in self.amplitude_u],
            "amplitude_delta": [float(v) for v in self.amplitude_delta],
            "max_multiplier": [float(v) for v in self.max_multiplier],
            "stable": [bool(v) for v in self.stable],
            "parent": self.parent,
            "stop_reason": self.stop_reason,
            "complete": bool(self.complete),
        }


@dataclass
class BifurcationPoint:
    """A located bifurcation: ``omega``, ``type`` (one of ``BIFURCATION_TYPES``), the index of its
    ``branch``, the branch ``period``, the ``state``, ``amplitude_u`` and ``amplitude_delta`` there, the critical
    ``multipliers`` (one real or a complex pair) and the omega bracket ``(lo, hi)`` it was located in.
    """

    omega: float
    type: str
    branch: int
    period: int
    state: np.ndarray
    amplitude_u: float
    multipliers: np.ndarray
    bracket: tuple[float, float]
    amplitude_delta: float = 0.0

    def to_json_dict(self) -> dict[str, Any]:
        """``{"omega", "type", "branch", ...}`` for the JSON output."""
        return {
            "omega": float(self.omega),
            "type": self.type,
            "branch": int(self.branch),
            "period": int(self.period),
            "amplitude_u": float(self.amplitude_u),
            "amplitude_delta": float(self.amplitude_delta),
            "multipliers_re": [float(m.real) for m in self.multipliers],
            "multipliers_im": [float(m.imag) for m in self.multipliers],
            "bracket": [float(self.bracket[0]), float(self.bracket[1])],
        }


@dataclass
class ContinuationResult:
    """Branches and bifurcations of :func:`continue_orbits`; ``messages`` says where and why any
    branch stopped early, ``complete`` is False if one did."""

    model: str
    omega_range: tuple[float, float]
    branches: list[Branch] = field(default_factory=list)
    bifurcations: list[BifurcationPoint] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    elapsed: float = 0.0
    notes: list[str] = field(default_factory=list)
    """Where the run stopped by design: period doublings not followed because of ``max_period``."""
    located: bool | None = True
    """The gear map had its contact changes located inside the step (:class:`OrbitMap`); None: a
    custom map (:func:`continue_map`)."""

    @property
    def complete(self) -> bool:
        """True if every branch ended normally."""
        return all(b.complete for b in self.branches)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready dict: ``model``, ``omega_range``, ``branches``, ``bifurcations``, ``messages``,
        ``complete``."""
        return {
            "model": self.model,
            "omega_range": [float(self.omega_range[0]), float(self.omega_range[1])],
            "branches": [b.to_json_dict() for b in self.branches],
            "bifurcations": [b.to_json_dict() for b in self.bifurcations],
            "messages": list(self.messages),
            "notes": list(self.notes),
            "map": "custom" if self.located is None else ("located" if self.located else "unlocated"),
            "complete": bool(self.complete),
        }


# ----------------------------------------------------------------------------- the map
@dataclass
class _Point:
    z: np.ndarray  # (11,) x and omega
    mu: np.ndarray  # (10,) sorted multipliers
    jac: np.ndarray  # (10, 10) dP^N/dx
    pw: np.ndarray  # (10,) dP^N/domega
    info: np.ndarray
    pc: np.ndarray  # (N, 10) states at the end of every mesh period
    steps: int
    iterations: int = 0
    t: np.ndarray | None = None  # unit tangent (11,)

    @property
    def omega(self) -> float:
        return float(self.z[-1])

    @property
    def amp_u(self) -> float:
        return 0.5 * float(self.info[TG.INFO_U_MAX] - self.info[TG.INFO_U_MIN])

    @property
    def amp_d(self) -> float:
        return 0.5 * float(self.info[TG.INFO_D_MAX] - self.info[TG.INFO_D_MIN])


def _multipliers(jac: np.ndarray) -> np.ndarray:
    mu = np.linalg.eigvals(jac)
    return mu[np.argsort(-np.abs(mu), kind="stable")]


class _MapFailed(RuntimeError):
    pass


class OrbitMap:
    """The period-N map of the gear model with its exact Jacobian, at any omega.

    Args:
        model: ``"constant"`` or ``"dynamic"``.
        params: GearParams (default Table 1).
        period: N.
        steps_per_period: fixed Newmark steps per mesh period, or None for
            ``default_steps_per_period(omega)``.
        located: True (default): the map with every contact change located inside its step
            (``tangent_map(..., corrected=2)``), smooth in x and omega, and its exact Jacobian, whose
            eigenvalues are the reported multipliers. False: the unlocated map of
            ``kernels.integrate_stats`` (bit-identical to the simulator's fixed steps), Newton on its
            exact, piecewise-constant Jacobian, multipliers from the crossing-corrected tangent
            (``corrected=1``); kept for comparison.
    """

    def __init__(
        self,
        model: str,
        params: GearParams | None,
        period: int,
        steps_per_period: int | None = None,
        located: bool = True,
    ):
        self.model = model
        self.located = check_located(located)
        self.smooth = self.located  # the map is smooth: its own Jacobian gives the multipliers
        self.code = model_code(model)
        self.params = params if params is not None else GearParams()
        refuse_extensions(self.params, "continuation")
        refuse_velocity_correction(self.params, "continuation")
        self.period = int(period)
        self.fixed_steps = steps_per_period
        self._c = K.readonly(np.ascontiguousarray(self.params.consts))
        self._a = np.zeros(K.NDOF)
        self._pcs = np.empty((self.period, K.N_PC))
        self._st = np.empty(K.N_STATS)
        self.evaluations = 0

    def steps(self, omega: float) -> int:
        """Newmark steps per mesh period used at omega (ValueError if a fixed count is unstable there under a
        conditionally stable ``params.newmark_beta``)."""
        if self.fixed_steps is None:
            return default_steps_per_period(omega, self.params)
        check_stable_steps(self.params, self.fixed_steps, omega)
        return self.fixed_steps

    def value(self, x: np.ndarray, omega: float, steps: int) -> np.ndarray:
        """P^N(x) (no Jacobian): the located map's kernel (``tangent_map``, so that differences of
        values and of :meth:`tangent` are consistent to round-off), or ``kernels.integrate_stats``."""
        if self.located:
            return self.tangent(x, omega, steps)[0]
        y = np.array(x, dtype=float)
        status, _, _ = K.integrate_stats(
            y, self._a, 0.0, omega, omega, self.period, steps, self._c, self.code, self._pcs, self._st,
            NEWTON_MAX_ITER, NEWTON_TOL, True,
        )  # fmt: skip
        self.evaluations += 1
        if status != K.OK:
            raise _MapFailed(f"kernel status {status} at omega={omega:.6g}")
        return y

    def tangent(
        self, x: np.ndarray, omega: float, steps: int, corrected: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(P^N(x), dP^N/dx (10, 10), info (``tangent.INFO_*``), per-period states (N, 10)).
        The located map (mode 2 of :func:`tangent.tangent_map`) if ``located``; otherwise the
        unlocated one, with the crossing-corrected Jacobian (mode 1) if ``corrected``."""
        announce_compile("tangent", "the continuation's tangent-map kernel", TANGENT_COMPILE_TIME)  # once per process
        mode = 2 if self.located else int(bool(corrected))
        status, y, jac, info, pc = TG.run_tangent_map(x, omega, self.period, steps, self._c, self.code, mode)
        self.evaluations += 1
        if status != K.OK or not np.all(np.isfinite(jac)):
            raise _MapFailed(f"kernel status {status} at omega={omega:.6g}")
        return y, jac, info, pc

    def evaluate(self, z: np.ndarray, steps: int, d_omega: float = 1e-7) -> tuple[np.ndarray, _Point]:
        """G(z) = P^N(x) - x and the point data (Jacobian; dP/domega by a forward difference of
        relative step ``d_omega``: it only enters the corrector matrix and the tangent, whose
        accuracy needs far less than the Jacobian's). Multipliers are filled in by the caller."""
        x, w = z[:-1], float(z[-1])
        y, jac, info, pc = self.tangent(x, w, steps)
        dw = d_omega * (1.0 + w)
        pw = (self.value(x, w + dw, steps) - y) / dw
        return y - x, _Point(z.copy(), np.zeros(x.size, dtype=complex), jac, pw, info, pc, steps)


def _tangent_vector(p: _Point, ref: np.ndarray) -> np.ndarray:
    """Unit null vector of [M - I, dP/domega], oriented along ``ref``."""
    n = p.z.size - 1
    a = np.zeros((n + 1, n + 1))
    a[:n, :n] = p.jac - np.eye(n)
    a[:n, n] = p.pw
    a[n] = ref
    rhs = np.zeros(n + 1)
    rhs[n] = 1.0
    try:
        t = np.linalg.solve(a, rhs)
    except np.linalg.LinAlgError:
        t = np.linalg.lstsq(a, rhs, rcond=None)[0]
    n = float(np.linalg.norm(t))
    if not math.isfinite(n) or n == 0.0:
        return ref / np.linalg.norm(ref)
    t = t / n
    return t if float(t @ ref) >= 0 else -t


def _correct(
    omap: OrbitMap, z_pred: np.ndarray, t: np.ndarray, steps: int, tol: float, max_iter: int
) -> tuple[_Point | None, str]:
    """Newton on G = 0, t . (z - z_pred) = 0 from z_pred. Returns (point or None, failure reason)."""
    z = z_pred.copy()
    last_dz = math.inf
    res = math.inf
    for it in range(max_iter + 1):
        if not (z[-1] > 0.0):
            return None, f"omega left the positive axis (omega={z[-1]:.4g})"
        try:
            g, p = omap.evaluate(z, steps)
        except _MapFailed as exc:
            return None, f"the map failed ({exc})"
        scale = 1.0 + float(np.max(np.abs(z[:-1])))
        res = float(np.max(np.abs(g)))
        if res <= tol * scale and last_dz <= 1e3 * tol * scale:
            p.iterations = it
            # the located map's Jacobian is the exact one of a map smooth in omega; the unlocated
            # map's piecewise-constant Jacobian jumps, so its multipliers come from the corrected tangent
            jac = p.jac if getattr(omap, "smooth", False) else omap.tangent(p.z[:-1], p.omega, steps, corrected=True)[1]
            p.mu = _multipliers(jac)
            return p, ""
        if it == max_iter:
            break
        n = z.size - 1
        a = np.zeros((n + 1, n + 1))
        a[:n, :n] = p.jac - np.eye(n)
        a[:n, n] = p.pw
        a[n] = t
        rhs = np.concatenate([-g, [-float(t @ (z - z_pred))]])
        try:
            dz = np.linalg.solve(a, rhs)
        except np.linalg.LinAlgError:
            return None, "singular corrector matrix"
        if not np.all(np.isfinite(dz)):
            return None, "non-finite Newton update"
        last_dz = float(np.max(np.abs(dz)))
        if last_dz > 0.5 * scale:  # damp wild updates
            dz *= 0.5 * scale / last_dz
        z = z + dz
    return None, f"Newton did not converge in {max_iter} iterations (residual {res:.2e} b0)"


# ----------------------------------------------------------------------------- test functions
def _sign_det(mu: np.ndarray, shift: float) -> float:
    v = np.prod(mu - shift)
    return float(np.sign(v.real)) if v.real != 0 else 0.0


def _n_complex_out(mu: np.ndarray) -> int:
    return int(np.sum((np.abs(mu) > 1.0) & (np.abs(mu.imag) > COMPLEX_TOL)))


def _signature(p: _Point) -> tuple[float, float, int, int]:
    """(sign det(M - I), sign det(M + I), complex multipliers outside the circle, contact switches)."""
    return (_sign_det(p.mu, 1.0), _sign_det(p.mu, -1.0), _n_complex_out(p.mu), int(p.info[TG.INFO_SWITCHES]))


def _critical(mu: np.ndarray, kind: str) -> np.ndarray:
    if kind == "fold":
        return mu[[int(np.argmin(np.abs(mu - 1.0)))]]
    if kind == "period-doubling":
        return mu[[int(np.argmin(np.abs(mu + 1.0)))]]
    if kind == "neimark-sacker":
        cpx = np.nonzero(np.abs(mu.imag) > COMPLEX_TOL)[0]
        if cpx.size == 0:
            return mu[:1]
        k = cpx[int(np.argmin(np.abs(np.abs(mu[cpx]) - 1.0)))]
        return np.array([mu[k], np.conj(mu[k])])
    return mu[:1]


REJOIN_GAP = 1e-2
"""A fold of a period-2N branch whose orbit repeats after N periods to within this (relative to
1 + max|x|) is the branch meeting its period-N parent: the branch ends there."""


def _half_vec(p: _Point, period: int) -> np.ndarray:
    """P^(N/2)(x) - x of a period-N point."""
    return p.pc[period // 2 - 1] - p.z[:-1]


def _half_gap(p: _Point, period: int) -> float:
    """max|P^(N/2)(x) - x| / (1 + max|x|) of a period-N point (0 on a period-N/2 orbit)."""
    x = p.z[:-1]
    return float(np.max(np.abs(p.pc[period // 2 - 1] - x))) / (1.0 + float(np.max(np.abs(x))))


# ----------------------------------------------------------------------------- the driver
def _check_positive(value: Any, name: str, upper: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v > 0 and (upper is None or v <= upper)):
        rng = f"in (0, {upper:g}]" if upper is not None else "> 0"
        raise ValueError(f"{name} must be a finite number {rng}, got {value!r}")
    return v


def _check_int(value: Any, name: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


class _Continuer:
    def __init__(self, model, params, omega_min, omega_max, tol, ds, ds_min, ds_max, max_points, max_iter,
                 locate_tol, max_period, max_switches, grazing, deadline, progress, map_factory=None,
                 located=True):  # fmt: skip
        self.model = model
        self.params = params
        self.lo, self.hi = omega_min, omega_max
        self.tol, self.ds0, self.ds_min, self.ds_max = tol, ds, ds_min, ds_max
        self.max_points, self.max_iter, self.locate_tol = max_points, max_iter, locate_tol
        self.max_period, self.max_switches, self.grazing = max_period, max_switches, grazing
        self.deadline = deadline
        self.progress = progress
        self.result = ContinuationResult(
            model, (omega_min, omega_max), located=None if map_factory is not None else bool(located)
        )
        self.maps: dict[int, Any] = {}
        self.map_factory = (
            map_factory if map_factory is not None else (lambda n: OrbitMap(model, params, n, located=located))
        )
        self.switch_queue: list[tuple[int, BifurcationPoint, _Point]] = []
        self.stopped_ends: dict[int, _Point] = {}  # branch -> last point, for branches stopped by the step size

    def omap(self, period: int) -> OrbitMap:
        if period not in self.maps:
            self.maps[period] = self.map_factory(period)
        return self.maps[period]

    # -- bifurcation location along the secant A -> B
    def _locate(self, omap: OrbitMap, a: _Point, b: _Point, test: Callable[[_Point], Any]) -> _Point:
        """Bisection on the arclength fraction between a and b until the bracket is below
        ``locate_tol`` of the step; each trial point is predicted along the tangent of the
        bracket's lower end (an on-branch point) and corrected onto the branch."""
        ta = test(a)
        d = b.z - a.z
        span = float(np.linalg.norm(d))
        lo_p, hi_p = a, b
        lo_t, hi_t = 0.0, 1.0
        t_lo = a.t if a.t is not None else d / span
        while hi_t - lo_t > self.locate_tol:
            th = 0.5 * (lo_t + hi_t)
            zp = lo_p.z + (th - lo_t) * span * t_lo
            p, _ = _correct(omap, zp, t_lo, omap.steps(float(zp[-1])), self.tol, self.max_iter)
            if p is None:  # fall back on the secant
                zp = a.z + th * d
                p, _ = _correct(omap, zp, d / span, omap.steps(float(zp[-1])), self.tol, self.max_iter)
                if p is None:
                    break
            if test(p) == ta:
                lo_p, lo_t = p, th
                t_lo = _tangent_vector(p, t_lo)
            else:
                hi_p, hi_t = p, th
        return hi_p if hi_p is not b else lo_p

    def _detect(
        self, bi: int, period: int, omap: OrbitMap, a: _Point, b: _Point, child: bool
    ) -> tuple[list[BifurcationPoint], float | None]:
        """Bifurcations between a and b; the second value is the omega where a period-2N branch
        (``child``) meets its period-N parent (a fold of P^2N on the parent's orbit), else None."""
        sa, sb = _signature(a), _signature(b)
        found = []
        kinds = []
        if sa[0] != sb[0]:
            kinds.append(("fold", lambda p: _signature(p)[0]))
        if sa[1] != sb[1]:
            kinds.append(("period-doubling", lambda p: _signature(p)[1]))
        if sa[2] != sb[2]:
            kinds.append(("neimark-sacker", lambda p: _signature(p)[2]))
        if self.grazing and sa[3] != sb[3]:
            kinds.append(("grazing", lambda p: _signature(p)[3]))
        for kind, test in kinds:
            p = self._locate(omap, a, b, test)
            if kind == "fold" and child and _half_gap(p, period) < REJOIN_GAP:
                return found, p.omega
            bp = BifurcationPoint(
                omega=p.omega, type=kind, branch=bi, period=period, state=p.z[:-1].copy(), amplitude_u=p.amp_u,
                multipliers=_critical(p.mu, kind), bracket=(min(a.omega, b.omega), max(a.omega, b.omega)),
                amplitude_delta=p.amp_d,
            )  # fmt: skip
            found.append(bp)
            if kind == "period-doubling":
                if 2 * period <= self.max_period:
                    self.switch_queue.append((bi, bp, p))
                else:
                    self.result.notes.append(
                        f"period doubling at omega={p.omega:.6f} of the period-{period} branch {bi}: the "
                        f"period-{2 * period} branch is not followed (max_period={self.max_period})"
                    )
        return found, None

    # -- one branch
    def run_branch(self, period: int, start: list[_Point], parent: int | None) -> None:
        omap = self.omap(period)
        bi = len(self.result.branches)
        pts: list[_Point] = list(start)
        reason, complete = "", True
        p = pts[-1]
        t = p.t
        ds = self.ds0
        gap_max = 0.0
        while True:
            if len(pts) >= self.max_points:
                reason, complete = f"stopped after max_points={self.max_points} points", False
                break
            if self.deadline is not None and time.perf_counter() > self.deadline:
                reason, complete = f"time limit reached at omega={p.omega:.6f}", False
                break
            zp = p.z + ds * t
            q, why = _correct(omap, zp, t, omap.steps(float(zp[-1])), self.tol, self.max_iter)
            ok = q is not None
            if ok:
                tq = _tangent_vector(q, t)
                dist = float(np.linalg.norm(q.z - zp))
                if float(tq @ t) < MAX_TURN and ds > CORNER_DS:
                    ok, why = False, f"the branch turns sharply (cos {float(tq @ t):.3f})"
                elif dist > 2.0 * ds:
                    ok, why = False, f"corrector moved {dist:.3g} for a step {ds:.3g}"
            if not ok:
                ds *= 0.5
                if ds < self.ds_min:
                    reason = f"step size fell below ds_min={self.ds_min:g} at omega={p.omega:.6f}: {why}"
                    complete = False
                    self.stopped_ends[bi] = p
                    break
                continue
            q.t = tq
            p_prev = p
            child = parent is not None and period > 1
            if child and len(pts) < 4:  # the switching point's own +1 multiplier is not a fold
                found, rejoin = [], None
            else:
                found, rejoin = self._detect(bi, period, omap, p, q, child)
            self.result.bifurcations.extend(found)
            pts.append(q)
            if rejoin is not None:
                reason = f"rejoined the period-{period // 2} branch at omega={rejoin:.6f}"
                break
            p, t = q, tq
            if q.iterations <= 3:
                ds = min(self.ds_max, ds * 1.6)
            elif q.iterations >= 6:
                ds = max(self.ds_min, ds * 0.7)
            if self.progress:
                self.progress(period, q.omega, len(pts))
            if not (self.lo <= q.omega <= self.hi):
                reason = f"left the omega range at omega={q.omega:.6f}"
                break
            if child:
                # P^(N/2)(x) - x changes sign where the branch passes through its parent's orbit
                # (the other half of the bubble is the same orbit shifted by N/2 periods)
                ga, gb = _half_vec(p_prev, period), _half_vec(q, period)
                na, nb = float(np.linalg.norm(ga)), float(np.linalg.norm(gb))
                gap_max = max(gap_max, na, nb)
                if _half_gap(q, period) < 1e-4:  # on the parent orbit itself
                    reason = f"rejoined the period-{period // 2} branch at omega={q.omega:.6f}"
                    break
                if float(ga @ gb) < 0.0 and min(na, nb) < 0.25 * gap_max:  # through zero, not a turn
                    w = p_prev.omega + (q.omega - p_prev.omega) * na / (na + nb)
                    reason = f"rejoined the period-{period // 2} branch at omega={w:.6f}"
                    break
        self.result.branches.append(_make_branch(period, pts, parent, reason, complete))
        if not complete and not self._met(bi):
            self.result.messages.append(f"branch {bi} (period {period}): {reason}")

    def _met(self, bi: int) -> bool:
        """If branch ``bi`` stopped (step size) where another stopped branch of the same period
        stopped, on the same orbit (:data:`MEET_OMEGA`, :data:`MEET_GAP`), the two are one branch
        traced from both ends: mark both complete, drop the other's failure message, return True.
        (Where the two ends meet the map is not smooth enough for Newton: a grazing corner.)"""
        q = self.stopped_ends.get(bi)
        if q is None:
            return False
        for bj, p in self.stopped_ends.items():
            if bj == bi or p.pc.shape != q.pc.shape or abs(p.omega - q.omega) > MEET_OMEGA:
                continue
            n = q.pc.shape[0]
            scale = 1.0 + float(np.max(np.abs(q.pc)))
            gap = min(float(np.max(np.abs(np.roll(p.pc, k, axis=0) - q.pc))) for k in range(n))
            if gap > MEET_GAP * scale:
                continue
            for a, b in ((bi, bj), (bj, bi)):
                br = self.result.branches[a]
                br.complete = True
                br.stop_reason = (
                    f"met branch {b} (the same period-{br.period} orbit followed from its other end) at "
                    f"omega={self.stopped_ends[a].omega:.6f}; {br.stop_reason}"
                )
            prefix = f"branch {bj} (period "
            self.result.messages = [m for m in self.result.messages if not m.startswith(prefix)]
            del self.stopped_ends[bj], self.stopped_ends[bi]
            return True
        return False

    def start_primary(self, omega0: float, direction: float, transient: int, x0: Any = None) -> list[_Point]:
        omap = self.omap(1)
        if x0 is None:
            sim = GearSimulator(self.params, self.model, None, omega0)
            try:
                sim.advance(transient)
            except SimulationDivergedError as exc:
                raise RuntimeError(f"the start simulation at omega={omega0:.6g} failed: {exc}") from None
            x0 = sim.state
        z = np.concatenate([np.asarray(x0, float), [omega0]])
        t = np.zeros(z.size)
        t[-1] = 1.0  # natural-parameter corrector at omega0
        p, why = _correct(omap, z, t, omap.steps(omega0), self.tol, 40)
        if p is None:
            raise RuntimeError(f"no period-1 orbit found at omega={omega0:.6g}: {why}")
        ref = np.zeros(z.size)
        ref[-1] = direction
        p.t = _tangent_vector(p, ref)
        return [p]

    def start_switched(self, bp: BifurcationPoint, p: _Point, eps: float = 0.02) -> list[_Point] | None:
        period = 2 * bp.period
        omap = self.omap(period)
        mu, vec = np.linalg.eig(p.jac)
        k = int(np.argmin(np.abs(mu + 1.0)))
        v = np.real(vec[:, k])
        v = v / np.linalg.norm(v)
        t = np.concatenate([v, [0.0]])
        for e0 in (eps, 0.25 * eps, -eps):  # a smaller offset, then the other side, if needed
            pts = []
            for e in (e0, 2 * e0):
                zp = p.z + e * t
                q, _ = _correct(omap, zp, t, omap.steps(p.omega), self.tol, self.max_iter)
                if q is None or float(np.max(np.abs(q.pc[bp.period - 1] - q.z[:-1]))) < 1e-6:
                    break  # no convergence, or the period-N orbit itself
                pts.append(q)
            if len(pts) == 2:
                break
        if len(pts) < 2:
            return None
        sec = pts[1].z - pts[0].z
        pts[0].t = sec / np.linalg.norm(sec)
        pts[1].t = _tangent_vector(pts[1], pts[0].t)
        return pts


def _make_branch(period: int, pts: list[_Point], parent: int | None, reason: str, complete: bool) -> Branch:
    return Branch(
        period=period,
        omega=np.array([p.omega for p in pts]),
        states=np.array([p.z[:-1] for p in pts]),
        multipliers=np.array([p.mu for p in pts]),
        amplitude_u=np.array([p.amp_u for p in pts]),
        amplitude_delta=np.array([p.amp_d for p in pts]),
        switches=np.array([int(p.info[TG.INFO_SWITCHES]) for p in pts], dtype=int),
        steps_per_period=np.array([p.steps for p in pts], dtype=int),
        parent=parent,
        stop_reason=reason,
        complete=complete,
    )


def continue_orbits(
    model: str = "dynamic",
    omega_min: float = 0.05,
    omega_max: float = 3.0,
    params: GearParams | None = None,
    *,
    tol: float = 1e-9,
    ds: float = 0.01,
    ds_min: float = 1e-5,
    ds_max: float = 0.04,
    max_points: int = 2000,
    max_iter: int = 12,
    locate_tol: float = 1e-3,
    max_period: int = MAX_PERIOD,
    max_switches: int = 8,
    grazing: bool = True,
    transient: int = 300,
    time_limit: float | None = None,
    progress: Callable[[int, float, int], None] | None = None,
    located: bool = True,
) -> ContinuationResult:
    """Continue the period-1 orbit of the gear model over [omega_min, omega_max], locate its
    bifurcations and switch onto period-doubled branches.

    Args:
        model: ``"constant"`` or ``"dynamic"``.
        omega_min, omega_max: the omega range (Omega/omega_n, 1e-3 <= omega_min < omega_max <= 100);
            the primary branch starts at omega_min from a simulated transient.
        params: GearParams (default Table 1).
        tol: Newton tolerance on max|P^N(x) - x| relative to 1 + max|x| (in (0, 1e-4]).
        ds, ds_min, ds_max: initial, smallest and largest arclength step in (x, omega) (b0 units
            and omega together; 0 < ds_min <= ds <= ds_max <= 1).
        max_points: points per branch (>= 2).
        max_iter: Newton iterations per corrector (>= 2).
        locate_tol: bifurcations are bisected to this fraction of the step they lie in
            (in (0, 0.5]).
        max_period: branch switching at period-doubling points stops at this period (1..256; default
            :data:`MAX_PERIOD` = 8: a period doubling of a period-8 branch is a note, not a branch).
        max_switches: at most this many period-doubling switches in all (>= 0).
        grazing: detect grazing (contact boundary touched) as well.
        transient: mesh periods simulated to start the primary branch.
        time_limit: seconds; a branch still running then stops at its last point (None: no limit).
        progress: called as progress(period, omega, points) after every accepted point.
        located: continue on the map with contact changes located inside the step (default; smooth
            in omega, exact multipliers); False: the unlocated discrete map (see :class:`OrbitMap`).

    Returns:
        :class:`ContinuationResult`. A branch that fails (Newton, step size, kernel) ends at its
        last good point and says why (``stop_reason``, ``messages``); what was found is returned.
    """
    model_code(model)
    located = check_located(located)
    lo = check_omega(omega_min, "omega_min")
    hi = check_omega(omega_max, "omega_max")
    if not lo < hi:
        raise ValueError(f"omega_min must be < omega_max, got {lo!r} >= {hi!r}")
    if params is not None and not isinstance(params, GearParams):
        raise ValueError(f"params must be a GearParams, got {type(params).__name__}")
    tol = _check_positive(tol, "tol", 1e-4)
    ds_max = _check_positive(ds_max, "ds_max", 1.0)
    ds = _check_positive(ds, "ds", ds_max)
    ds_min = _check_positive(ds_min, "ds_min", ds)
    max_points = _check_int(max_points, "max_points", 2, 1_000_000)
    max_iter = _check_int(max_iter, "max_iter", 2, 1000)
    locate_tol = _check_positive(locate_tol, "locate_tol", 0.5)
    max_period = _check_int(max_period, "max_period", 1, 256)
    max_switches = _check_int(max_switches, "max_switches", 0, 1000)
    transient = _check_int(transient, "transient", 0, 10_000_000)
    if time_limit is not None:
        time_limit = _check_positive(time_limit, "time_limit")
    return _run(
        model, params if params is not None else GearParams(), lo, hi, None, None, 1.0, transient,
        tol=tol, ds=ds, ds_min=ds_min, ds_max=ds_max, max_points=max_points, max_iter=max_iter,
        locate_tol=locate_tol, max_period=max_period, max_switches=max_switches, grazing=grazing,
        time_limit=time_limit, progress=progress, located=bool(located),
    )  # fmt: skip


def _run(model, params, lo, hi, map_factory, x0, direction, transient, *, tol, ds, ds_min, ds_max, max_points,
         max_iter, locate_tol, max_period, max_switches, grazing, time_limit, progress, located=True):  # fmt: skip
    t0 = time.perf_counter()
    deadline = None if time_limit is None else t0 + time_limit
    c = _Continuer(
        model, params, lo, hi, tol, ds, ds_min, ds_max, max_points, max_iter, locate_tol, max_period,
        max_switches, bool(grazing), deadline, progress, map_factory, located,
    )  # fmt: skip
    omega0 = lo if direction > 0 else hi
    try:
        start = c.start_primary(omega0, direction, transient, x0)
    except RuntimeError as exc:
        c.result.messages.append(str(exc))
        c.result.elapsed = time.perf_counter() - t0
        return c.result
    c.run_branch(1, start, None)
    switches = 0
    while c.switch_queue and switches < max_switches:
        bi, bp, p = c.switch_queue.pop(0)
        done = [
            k for k, b in enumerate(c.result.branches)
            if b.parent == bi and b.period == 2 * bp.period and b.stop_reason.startswith("rejoined")
            and abs(b.omega[-1] - bp.omega) < 1e-3
        ]  # fmt: skip
        if done:  # the other end of a period-doubling bubble already traced
            continue
        switches += 1
        start = c.start_switched(bp, p)
        if start is None:
            c.result.messages.append(
                f"no period-{2 * bp.period} branch found at the period-doubling point omega={bp.omega:.6f}"
            )
            continue
        c.run_branch(2 * bp.period, start, bi)
    c.result.elapsed = time.perf_counter() - t0
    return c.result


def continue_map(
    map_factory: Callable[[int], Any],
    x0: Any,
    omega_min: float,
    omega_max: float,
    *,
    direction: int = 1,
    tol: float = 1e-9,
    ds: float = 0.01,
    ds_min: float = 1e-5,
    ds_max: float = 0.04,
    max_points: int = 2000,
    max_iter: int = 12,
    locate_tol: float = 1e-3,
    max_period: int = MAX_PERIOD,
    max_switches: int = 8,
    time_limit: float | None = None,
) -> ContinuationResult:
    """The continuation of :func:`continue_orbits` for any periodically forced system.

    ``map_factory(N)`` returns an object with the interface of :class:`OrbitMap` (a
    :class:`FiniteDifferenceMap` for a smooth system); the branch starts from the fixed point near
    ``x0`` at omega_min (``direction`` = 1) or omega_max (-1). Options as :func:`continue_orbits`.
    """
    lo, hi = float(omega_min), float(omega_max)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ValueError(
            f"omega_min, omega_max must satisfy 0 < omega_min < omega_max, got {omega_min!r}, {omega_max!r}"
        )
    if direction not in (1, -1):
        raise ValueError(f"direction must be 1 or -1, got {direction!r}")
    return _run(
        "custom", None, lo, hi, map_factory, np.asarray(x0, float), float(direction), 0,
        tol=tol, ds=ds, ds_min=ds_min, ds_max=ds_max, max_points=max_points, max_iter=max_iter,
        locate_tol=locate_tol, max_period=max_period, max_switches=max_switches, grazing=False,
        time_limit=time_limit, progress=None,
    )  # fmt: skip


class FiniteDifferenceMap:
    """Period-N map of a smooth forced system from a one-period function, for :func:`continue_map`.

    Args:
        advance: ``advance(x, omega) -> x`` after one forcing period (x: (n,) array, not modified).
        period: N.
        amplitude: ``amplitude(points (N, n)) -> float`` reported as ``amplitude_u`` (default:
            half peak-to-peak of the first coordinate over the N section points).
        fd_step: relative central-difference step of the Jacobian.
    """

    smooth = True
    """The system is smooth: the multipliers are the eigenvalues of the corrector's Jacobian."""

    def __init__(self, advance: Callable[[np.ndarray, float], np.ndarray], period: int = 1,
                 amplitude: Callable[[np.ndarray], float] | None = None, fd_step: float = 1e-6):  # fmt: skip
        self.advance = advance
        self.period = int(period)
        self.amplitude = amplitude
        self.fd_step = fd_step
        self.evaluations = 0

    def steps(self, omega: float) -> int:
        """Unused discretisation count (kept for the :class:`OrbitMap` interface)."""
        return 0

    def value(self, x: np.ndarray, omega: float, steps: int = 0) -> np.ndarray:
        """P^N(x)."""
        y = np.array(x, float)
        for _ in range(self.period):
            y = np.asarray(self.advance(y, omega), float)
        self.evaluations += 1
        return y

    def _orbit(self, x: np.ndarray, omega: float) -> np.ndarray:
        pts = []
        y = np.array(x, float)
        for _ in range(self.period):
            y = np.asarray(self.advance(y, omega), float)
            pts.append(y)
        return np.array(pts)

    def tangent(self, x: np.ndarray, omega: float, steps: int = 0, corrected: bool = False):
        """(P^N(x), central-difference Jacobian, info, section points (N, n))."""
        pc = self._orbit(x, omega)
        n = x.size
        jac = np.empty((n, n))
        for j in range(n):
            h = self.fd_step * (1.0 + abs(x[j]))
            e = np.zeros(n)
            e[j] = h
            jac[:, j] = (self.value(x + e, omega) - self.value(x - e, omega)) / (2 * h)
        info = np.zeros(TG.N_INFO)
        amp = self.amplitude(pc) if self.amplitude is not None else 0.5 * float(np.ptp(pc[:, 0]))
        info[TG.INFO_U_MAX] = amp
        info[TG.INFO_U_MIN] = -amp
        return pc[-1].copy(), jac, info, pc

    def evaluate(self, z: np.ndarray, steps: int = 0, d_omega: float = 1e-7):
        """As :meth:`OrbitMap.evaluate`."""
        x, w = z[:-1], float(z[-1])
        y, jac, info, pc = self.tangent(x, w)
        dw = d_omega * (1.0 + w)
        pw = (self.value(x, w + dw) - self.value(x, w - dw)) / (2 * dw)
        return y - x, _Point(z.copy(), np.zeros(x.size, dtype=complex), jac, pw, info, pc, 0)


def orbit_at(
    omega: float,
    model: str = "dynamic",
    params: GearParams | None = None,
    period: int = 1,
    x0: Any = None,
    *,
    tol: float = 1e-10,
    max_iter: int = 30,
    transient: int = 300,
    located: bool = True,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Period-N orbit at fixed omega by Newton with the exact Jacobian of the discrete map.

    Returns (state (10,), multipliers (10,) sorted by decreasing modulus, converged). ``x0``:
    start state (None: after ``transient`` periods from MODEL.md A10). ``located``: the map with
    contact changes located inside the step (default) or the unlocated one (:class:`OrbitMap`).
    """
    w = check_omega(omega)
    period = _check_int(period, "period", 1, 256)
    omap = OrbitMap(model, params, period, located=check_located(located))
    if x0 is None:
        sim = GearSimulator(omap.params, model, None, w)
        sim.advance(transient)
        x0 = sim.state
    z = np.concatenate([np.asarray(x0, float), [w]])
    t = np.zeros(11)
    t[10] = 1.0
    p, _ = _correct(omap, z, t, omap.steps(w), _check_positive(tol, "tol", 1e-4), max_iter)
    if p is None:
        return z[:10], np.full(10, np.nan + 0j), False
    return p.z[:10].copy(), p.mu, True


__all__ = [
    "BIFURCATION_TYPES",
    "FiniteDifferenceMap",
    "continue_map",
    "BifurcationPoint",
    "Branch",
    "ContinuationResult",
    "OrbitMap",
    "continue_orbits",
    "orbit_at",
]
