"""Periodic orbits by shooting on the one-period map, and their Floquet multipliers.

The one-period map ``P`` takes the 10-dim state ``x`` on the Poincare section (mesh phase
2 pi k) to the state one mesh period later, computed by the simulator's Newmark-beta kernel with
every contact change located inside its step (``tangent.tangent_map(..., corrected=2)``: a step
whose end lies in another contact region than its start is split at the crossing). A period-N orbit
is a fixed point of ``P^N``; it is found with Newton's method on ``G(x) = P^N(x) - x`` with the
exact Jacobian of that map (its variational equations, propagated with the steps).

The Floquet multipliers are the eigenvalues of the monodromy matrix ``M = dP^N/dx`` at the fixed
point. With the contact changes located, the map is smooth in x and omega (except where a contact
begins and ends inside one step, which no step end sees: at grazing), and ``M`` converges to the
monodromy of the ODE at O(h^2) with no sawtooth: at the grazing orbits the multipliers are
within 0.003 of an event-located reference at the default step count (docs/ANALYSIS.md).

``located=False`` gives the map of releases up to 0.4.0: the fixed-step kernel
(``kernels.integrate_stats``, bit-identical to ``GearSimulator``), with a central finite-difference
Jacobian (step ``fd_step * (1 + |x_j|)``). That map is only piecewise smooth: the backlash force is
continuous with a kinked derivative at Delta = +/- B_d, so the Jacobian jumps when a perturbation
changes the contact region at the end of some Newmark step, and near grazing the multipliers can be
off by 0.02-0.04 and jump with omega.

Bifurcation type of an unstable orbit, from the multiplier of largest modulus: real and negative
-> ``"period-doubling"``; complex pair -> ``"neimark-sacker"`` (torus); real and positive ->
``"fold"`` (saddle-node / cyclic fold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SimulationDivergedError
from ..sim import kernels as K
from ..sim.integration import integrate
from ..sim.params import GearParams, model_code, refuse_extensions, refuse_velocity_correction
from ..sim.simulator import (
    GearSimulator,
    check_count,
    check_omega,
    check_stable_steps,
    resolve_steps,
)
from . import tangent as TG


def check_located(located: Any) -> bool:
    """``located`` as a bool; ValueError naming it unless it is True or False."""
    if not isinstance(located, (bool, np.bool_)):
        raise ValueError(f"located must be True or False, got {located!r}")
    return bool(located)


BIFURCATIONS = ("stable", "period-doubling", "neimark-sacker", "fold")
"""Labels of :attr:`PeriodicOrbit.bifurcation`."""

COMPLEX_TOL = 1e-6
"""A multiplier with |Im mu| <= COMPLEX_TOL * |mu| counts as real."""


@dataclass(frozen=True)
class PeriodicOrbit:
    """A period-N orbit of the gear model at a fixed meshing frequency.

    Attributes:
        omega: meshing frequency Omega/omega_n.
        model: ``"constant"`` or ``"dynamic"``.
        period: N, in mesh periods.
        state: (10,) state on the Poincare section (b0 units, natural-time velocities).
        multipliers: (10,) complex Floquet multipliers, sorted by decreasing modulus.
        monodromy: (10, 10) Jacobian of P^N at ``state`` (exact for the located map,
            central differences for the unlocated one).
        converged: True if the Newton residual reached the tolerance.
        residual: max-norm of P^N(state) - state [b0 units].
        iterations: Newton iterations used.
        stable: converged and all |multipliers| < 1.
        bifurcation: ``"stable"`` or how the orbit is unstable (see module docstring).
    """

    omega: float
    model: str
    period: int
    state: np.ndarray
    multipliers: np.ndarray
    monodromy: np.ndarray
    converged: bool
    residual: float
    iterations: int
    stable: bool
    bifurcation: str

    @property
    def max_multiplier(self) -> float:
        """Largest |multiplier| (the orbit is stable if < 1)."""
        return float(np.abs(self.multipliers[0]))


class PeriodMap:
    """The N-period Poincare map P^N of the gear model at fixed omega (kernel calls, no Python loop
    per step).

    Args:
        omega: meshing frequency Omega/omega_n.
        model: backlash model.
        params: physical parameters (default Table 1).
        period: N (mesh periods per map application).
        steps_per_period: Newmark steps per mesh period; None: ``default_steps_per_period(omega)``.
        located: True (default): contact changes located inside the step, exact Jacobian
            (``tangent.tangent_map``, mode 2); False: the fixed-step kernel of the simulator
            (``kernels.integrate_stats``) with a finite-difference Jacobian.
    """

    def __init__(
        self,
        omega: float,
        model: str = "dynamic",
        params: GearParams | None = None,
        period: int = 1,
        steps_per_period: int | None = None,
        located: bool = True,
    ):
        self.omega = check_omega(omega)
        self.model = model
        self.code = model_code(model)
        self.params = params if params is not None else GearParams()
        if not isinstance(self.params, GearParams):
            raise ValueError(f"params must be a GearParams, got {type(self.params).__name__}")
        refuse_extensions(self.params, "Floquet analysis")
        refuse_velocity_correction(self.params, "Floquet analysis")
        self.period = check_count(period, "period")
        self.steps = resolve_steps(steps_per_period, self.omega, self.params)
        check_stable_steps(self.params, self.steps, self.omega)  # GearParams.newmark_beta < 1/4: refused before work
        self._c = np.ascontiguousarray(self.params.consts)
        self._a = np.zeros(K.NDOF)
        self._pc = np.empty((self.period, K.N_PC))
        self._st = np.empty(K.N_STATS)
        self.located = check_located(located)
        self.evaluations = 0
        self._last: tuple[tuple, np.ndarray, np.ndarray, np.ndarray] | None = None  # (key, x, P(x), jacobian)

    def _located(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P^N(x), dP^N/dx) of the located map (the last call's result is reused for the same x)."""
        x = np.asarray(x, dtype=float)
        key = (self.omega, self.steps, self.period, self.code)  # public attributes: a change invalidates
        if self._last is not None and self._last[0] == key and np.array_equal(self._last[1], x):
            return self._last[2].copy(), self._last[3].copy()
        status, y, jac, _, _ = TG.run_tangent_map(x, self.omega, self.period, self.steps, self._c, self.code, 2)
        self.evaluations += 1
        if status != K.OK or not (np.all(np.isfinite(y)) and np.all(np.isfinite(jac))):
            raise SimulationDivergedError(0, f"kernel status {status} in the period map", self.omega)
        self._last = (key, x.copy(), y.copy(), jac.copy())
        return y, jac

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """P^N(x). Raises SimulationDivergedError if the integration fails."""
        if self.located:
            return self._located(x)[0]
        y = np.array(x, dtype=float, copy=True)
        r = integrate(
            y, self._a, self._c, self.code, self.omega, self.omega, self.period, self.steps,
            poincare=self._pc, stats=self._st,
        )  # fmt: skip
        self.evaluations += 1
        if r.status != K.OK:
            raise SimulationDivergedError(r.done, f"kernel status {r.status} in the period map", self.omega)
        return y

    def jacobian(self, x: np.ndarray, fd_step: float = 1e-6) -> np.ndarray:
        """dP^N/dx (10 x 10) at x: exact for the located map; for the unlocated one central
        differences with step fd_step * (1 + |x_j|)."""
        if self.located:
            return self._located(x)[1]
        n = K.NSTATE
        jac = np.empty((n, n))
        for j in range(n):
            h = fd_step * (1.0 + abs(x[j]))
            e = np.zeros(n)
            e[j] = h
            jac[:, j] = (self(x + e) - self(x - e)) / (2.0 * h)
        return jac


def classify_multipliers(mu: np.ndarray) -> str:
    """Bifurcation label of a set of multipliers: the type of the one with the largest modulus.

    Returns ``"stable"`` if all |mu| < 1, else ``"period-doubling"`` (real < 0),
    ``"neimark-sacker"`` (complex) or ``"fold"`` (real > 0).
    """
    mu = np.asarray(mu, dtype=complex)
    k = int(np.argmax(np.abs(mu)))
    m = mu[k]
    if abs(m) < 1.0:
        return "stable"
    if abs(m.imag) > COMPLEX_TOL * abs(m):
        return "neimark-sacker"
    return "period-doubling" if m.real < 0 else "fold"


def _sorted_multipliers(jac: np.ndarray) -> np.ndarray:
    mu = np.linalg.eigvals(jac)
    return mu[np.argsort(-np.abs(mu), kind="stable")]


def find_periodic_orbit(
    omega: float,
    model: str = "dynamic",
    params: GearParams | None = None,
    period: int = 1,
    x0: Any = None,
    steps_per_period: int | None = None,
    *,
    transient: int = 200,
    tol: float = 1e-11,
    max_iter: int = 30,
    fd_step: float = 1e-6,
    located: bool = True,
) -> PeriodicOrbit:
    """Find a period-N orbit by shooting (Newton on P^N(x) - x) and compute its Floquet multipliers.

    Args:
        omega: meshing frequency Omega/omega_n (> 0).
        model: ``"constant"`` or ``"dynamic"``.
        params: physical parameters (default Table 1).
        period: N, the period in mesh periods (>= 1).
        x0: initial guess (10 values on the section); None: the state after ``transient`` mesh
            periods from the static equilibrium (MODEL.md A10).
        steps_per_period: Newmark steps per mesh period (the discretisation of the map); None:
            ``default_steps_per_period(omega)``.
        transient: mesh periods simulated to build the default initial guess.
        tol: convergence tolerance on max|P^N(x) - x| (b0 units).
        max_iter: maximum Newton iterations.
        fd_step: relative finite-difference step of the Jacobian (unlocated map only).
        located: True (default): the map with contact changes located inside the step and its exact
            Jacobian; False: the simulator's fixed-step map and a finite-difference Jacobian
            (:class:`PeriodMap`).

    Returns:
        :class:`PeriodicOrbit`. If Newton did not converge, ``converged`` is False and the state is
        the best iterate found (multipliers are those of the Jacobian there). Never NaN.

    Raises:
        ValueError: on invalid arguments.
        SimulationDivergedError: if even the initial guess cannot be integrated.
    """
    pmap = PeriodMap(omega, model, params, period, steps_per_period, located=located)
    check_count(transient, "transient", 0)
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a finite number > 0, got {tol!r}")
    check_count(max_iter, "max_iter", 1)
    if not (isinstance(fd_step, (int, float)) and 0 < fd_step < 1e-2):
        raise ValueError(f"fd_step must be in (0, 1e-2), got {fd_step!r}")
    if x0 is None:
        sim = GearSimulator(pmap.params, model, pmap.steps, pmap.omega)
        if transient > 0:
            sim.advance(transient)
        x = sim.state
    else:
        x = np.asarray(x0, dtype=float).copy()
        if x.shape != (K.NSTATE,) or not np.all(np.isfinite(x)):
            raise ValueError(f"x0 must be 10 finite values, got shape {x.shape}")

    g = pmap(x) - x
    res = float(np.max(np.abs(g)))
    best = (res, x.copy())
    jac = None
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007
        if res <= tol * (1.0 + float(np.max(np.abs(x)))):
            break
        jac = pmap.jacobian(x, fd_step)
        try:
            dx = np.linalg.solve(jac - np.eye(K.NSTATE), -g)
        except np.linalg.LinAlgError:
            dx = np.linalg.lstsq(jac - np.eye(K.NSTATE), -g, rcond=None)[0]
        # damped step: limit the size, then backtrack until the residual decreases
        scale = 1.0 + float(np.max(np.abs(x)))
        step = float(np.max(np.abs(dx)))
        lam = min(1.0, 0.5 * scale / step) if step > 0 else 1.0
        accepted = False
        while lam > 1e-4:
            xn = x + lam * dx
            try:
                gn = pmap(xn) - xn
            except SimulationDivergedError:
                lam *= 0.5
                continue
            rn = float(np.max(np.abs(gn)))
            if rn < res or lam == 1.0 and rn < 2.0 * res:
                x, g, res = xn, gn, rn
                accepted = True
                break
            lam *= 0.5
        if res < best[0]:
            best = (res, x.copy())
        if not accepted:
            break
        jac = None
    x = best[1] if best[0] < res else x
    res = min(res, best[0])
    converged = res <= tol * (1.0 + float(np.max(np.abs(x))))
    if jac is None or not np.array_equal(x, best[1]):
        jac = pmap.jacobian(x, fd_step)
    mu = _sorted_multipliers(jac)
    label = classify_multipliers(mu)
    return PeriodicOrbit(
        omega=pmap.omega,
        model=model,
        period=pmap.period,
        state=x,
        multipliers=mu,
        monodromy=jac,
        converged=bool(converged),
        residual=res,
        iterations=it,
        stable=bool(converged and label == "stable"),
        bifurcation=label,
    )


def linear_multipliers(omega: float, model: str = "constant", params: GearParams | None = None) -> np.ndarray:
    """Analytic Floquet multipliers exp(lambda_i T) of the LINEAR system (full contact, kappa ignored,
    psi = alpha0), T = 2 pi / omega in natural time, sorted by decreasing modulus.

    In full contact with k_m = k_m0 the equations of MODEL.md sec. 3b are linear with constant
    coefficients: q'' = -(D_c + 2 xi_m w g^T) q' - (D_k + w g^T) q + const, with g = dDelta/dq and
    w = M^-1 g (plus w dB_d/dq^T in the stiffness for the dynamic model). Used to check the shooting.
    """
    w = check_omega(omega)
    p = params if params is not None else GearParams()
    c = p.consts
    from ..sim.params import C_ALPHA0, C_EPS_G, C_EPS_P, C_SIG_G, C_SIG_P, C_XI_BG, C_XI_BP, C_XI_M

    a0 = c[C_ALPHA0]
    s, co = math.sin(a0), math.cos(a0)
    g = np.array([s, -co, -s, co, 1.0])
    minv = np.array([1 / c[C_EPS_P], 1 / c[C_EPS_P], 1 / c[C_EPS_G], 1 / c[C_EPS_G], 1.0])
    wv = minv * g
    dk = np.diag([c[C_SIG_P] ** 2] * 2 + [c[C_SIG_G] ** 2] * 2 + [0.0])
    dc = np.diag([2 * c[C_XI_BP] * c[C_SIG_P]] * 2 + [2 * c[C_XI_BG] * c[C_SIG_G]] * 2 + [0.0])
    kk = dk + np.outer(wv, g)
    if model_code(model) == 1:
        geo = np.zeros(K.GEO_SIZE)
        x = np.zeros(K.NSTATE)
        K.static_equilibrium(c, 1, 0.0, x)
        K.geometry(x[:5], c, 1, geo)
        kk = kk - np.outer(wv, geo[2:7])  # f = Delta - B_d(q)
    cc = dc + 2 * c[C_XI_M] * np.outer(wv, g)
    a = np.zeros((10, 10))
    a[:5, 5:] = np.eye(5)
    a[5:, :5] = -kk
    a[5:, 5:] = -cc
    lam = np.linalg.eigvals(a)
    mu = np.exp(lam * 2 * math.pi / w)
    return mu[np.argsort(-np.abs(mu), kind="stable")]


__all__ = [
    "BIFURCATIONS",
    "PeriodMap",
    "PeriodicOrbit",
    "classify_multipliers",
    "find_periodic_orbit",
    "linear_multipliers",
]
