"""The sensed mesh-force level relative to the family's steady force at the same speed (``force_level``).

Below contact loss the mesh force is linear in the transmission error, so the RMS of the dynamic mesh force over
the static one, ``rho = expm1(observation["force_rms"])``, factorises into the pair and the speed:

    log rho = log q + log h(omega),     q = (e_m1 factor) / (load factor x duty level),

with one shape ``h`` for the whole family of the Demand tasks (``LOG_H`` at ``H_OMEGAS``: to +-0.03 across the
family, measured by ``agents.demand_scripts.force_shape``). ``log rho - log h`` at the step's mean speed is
therefore the pair's ``log q`` read off one clean step: a vibration level normalised by its speed-dependent
baseline, as condition monitoring does. It adds no information to the observation (it is a function of the
observation's ``omega``, ``domega`` and ``force_rms`` entries), only a scaling in which the pair shows directly;
the ``steady_`` entry keeps it from the last clean, steady step (a memory feature). Settings ``force_level=True``
(docs/ENVIRONMENT.md). No numba here.
"""

from __future__ import annotations

import numpy as np

H_OMEGAS = np.round(np.arange(0.9, 2.0001, 0.05), 3)
"""Speeds of the force shape table ``LOG_H``."""
LOG_H = np.array(
    [-0.109, 0.227, -0.002, -0.404, -0.789, -0.976, -0.824, -0.540, -0.270, -0.035, 0.168, 0.347, 0.509,
     0.657, 0.794, 0.921, 1.041, 1.155, 1.263, 1.366, 1.466, 1.563, 1.660]
)  # fmt: skip
"""log of the steady force RMS ratio per unit ``q`` at ``H_OMEGAS`` (the Demand tasks' pair, e_m1 x0.25, load x1.5;
``agents.demand_scripts.force_shape`` measures it)."""
LEVEL_CLIP = 5.0
"""Bound of the ``force_level`` entries (log units)."""
TROUBLE_DEFECT = float(np.log1p(0.5))
"""``defect`` observation above which a step counts as troubled (c > 0.5, as the memory features)."""
STEADY_DOMEGA = 0.3
"""A step is steady when its ``domega`` observation (change of omega / max_domega) is at most this in size (to
1e-6: the float32 observation of a step that follows the limit at 0.03 per step reads 0.3000000119)."""


def troubled(contact: np.ndarray, impacts: np.ndarray, defect: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Troubled steps from their observation entries: ``contact_loss`` above ``TROUBLE_CONTACT``, any impact
    (``drive_impacts`` + ``back_impacts`` > 0) or ``defect`` above :data:`TROUBLE_DEFECT`; ``margin`` raises the
    two continuous thresholds (for noisy sensors; impacts are counted events, exact)."""
    from .env_terms import TROUBLE_CONTACT

    c = np.asarray(contact, float) > TROUBLE_CONTACT + margin
    return c | (np.asarray(impacts, float) > 0) | (np.asarray(defect, float) > TROUBLE_DEFECT + margin)


def step_mean_omega(omega_end: np.ndarray, domega_obs: np.ndarray, max_domega: float) -> np.ndarray:
    """The mean speed of a step from its end speed (omega units) and its ``domega`` observation."""
    return np.asarray(omega_end, float) - 0.5 * np.asarray(domega_obs, float) * max_domega


def force_level(omega_mid: np.ndarray, force_rms_obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(log q, known) of steps with mean speed ``omega_mid`` and ``force_rms`` observation ``force_rms_obs``:
    log(expm1(force_rms)) - log h(omega_mid), NaN where omega_mid lies outside ``H_OMEGAS`` (known False). A
    silent sensor reads as a very precise pair (the ratio is floored at 1e-6)."""
    w = np.asarray(omega_mid, float)
    known = (w >= H_OMEGAS[0]) & (w <= H_OMEGAS[-1])
    level = np.log(np.maximum(np.expm1(np.asarray(force_rms_obs, float)), 1e-6)) - np.interp(w, H_OMEGAS, LOG_H)
    return np.where(known, level, np.nan), known


def mean_level_update(
    q: np.ndarray, count: np.ndarray, omega_mid: np.ndarray, force_rms_obs: np.ndarray, use: np.ndarray, window: int
) -> tuple[np.ndarray, np.ndarray]:
    """One step of the ``level_window`` average of the pair's q = rho / h(omega) (the ``mean_force_level`` entry,
    and the estimate of ``agents.demand_scripts.FilteredFollow``): the steps with ``use`` add their sensed q,
    a running mean over the first ``window`` of them, then an exponential average of weight 1/``window``.
    Averaging q rather than log q keeps it unbiased under additive sensor noise on ``force_rms``, which for a
    precise pair is larger than the reading itself. Returns the new (q, count)."""
    w = np.asarray(omega_mid, float)
    use = np.asarray(use, bool)
    sensed = np.expm1(np.asarray(force_rms_obs, float)) / np.exp(np.interp(w, H_OMEGAS, LOG_H))
    count = np.where(use, np.asarray(count, float) + 1.0, count)
    k = 1.0 / np.minimum(np.maximum(count, 1.0), window)
    q = np.where(use, q + k * (sensed - q), q)
    return q, count


__all__ = [
    "H_OMEGAS",
    "LEVEL_CLIP",
    "LOG_H",
    "STEADY_DOMEGA",
    "TROUBLE_DEFECT",
    "force_level",
    "step_mean_omega",
    "troubled",
]
