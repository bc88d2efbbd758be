"""Sizes, Newmark parameters, status codes and column layouts shared by the kernels and their
Python callers (no compiled code): the recorded time series (``REC_*``), the interval statistics
(``ST_*``) and the Poincare samples (``PC_*``)."""

from __future__ import annotations

import math

from ..params import FOX_GOODWIN_BETA, NEWMARK_BETA  # noqa: F401  (re-exported)

NDOF = 5
NSTATE = 10
GAMMA = 0.5
VC_WEIGHT = 1.0 / 12.0
"""The velocity correction's weight under Fox-Goodwin (``GearParams.velocity_correction``): Newmark's velocity
exceeds the true one by h^2/12 da/dt + O(h^4) when beta = 1/12, so the forces take v - (h/12)(a_new - a_old)."""
BETA = NEWMARK_BETA  # the default of GearParams.newmark_beta; the kernels read beta per step (K_BETA)
TWO_PI = 2.0 * math.pi


# status codes returned by the integrators
OK = 0
DIVERGED = 1  # non-finite or exploding state
NEWTON_FAILED = 2  # Newton failed even after step splitting
SPLIT_PENDING = 3  # internal (``stats_segment``): stopped before a step that needs splitting

# channels recorded per step by ``integrate_record`` (columns after the 10 states)
REC_S = 10
REC_PHI = 11
REC_OMEGA = 12
REC_DELTA = 13
REC_BD = 14
REC_PSI = 15
REC_FORCE = 16
REC_REGION = 17
N_REC = 18


# per-interval statistics written by ``integrate_stats`` (index into the stats vector)
ST_TIME = 0  # elapsed natural time
ST_SEP_TIME = 1  # time with the teeth apart (|Delta| < B_d)
ST_BACK_TIME = 2  # time in back-side contact
ST_BACK_IMPACTS = 3  # entries into back-side contact
ST_DRIVE_IMPACTS = 4  # re-entries into drive-side contact after a separation
ST_F_SUM = 5  # integral of the mesh force
ST_F_SQ = 6  # integral of the mesh force squared
ST_F_MAX = 7
ST_F_MIN = 8
ST_TR_SQ = 9  # integral of (X_p^2 + Y_p^2 + X_g^2 + Y_g^2)/2 (translational response)
ST_TR_MAX = 10  # max over time of the radial bearing deflection
ST_U_MAX = 11
ST_U_MIN = 12
ST_D_MAX = 13
ST_D_MIN = 14
ST_BD_MAX = 15
ST_BD_MIN = 16
ST_PSI_MAX = 17
ST_PSI_MIN = 18
ST_STEPS = 19  # steps taken
ST_SPLITS = 20  # steps that had to be split
N_STATS = 21


# Poincare sample columns written by ``integrate_stats`` per mesh period
PC_DELTA = 10
PC_BD = 11
PC_PSI = 12
PC_FORCE = 13
N_PC = 14


DIVERGENCE_LIMIT = 1e6  # |state| beyond this (b0 units) counts as divergence


GEO_SIZE = 14


# where ``stats_segment`` leaves its loop's locals when it stops before a step that Newton did not
# finish (SPLIT_PENDING), and where ``split_resume`` puts them back after taking that step: the
# step index, the state tuple, Newton's guess for the next step, the accumulators of
# ``stats._acc_init``, the previous step's translational response, force and region, the elapsed
# time, omega at both ends of the step and its coefficients (``newmark.step_coeffs``).
# RS_J = -1 starts a new interval.
RS_J = 0
RS_S = 1
RS_G = RS_S + 15
RS_ACC = RS_G + 5
N_LOOP_ACC = 21  # length of stats._acc_init()
RS_TR_PREV = RS_ACC + N_LOOP_ACC
RS_F_PREV = RS_TR_PREV + 1
RS_REG_PREV = RS_F_PREV + 1
RS_EL = RS_REG_PREV + 1
RS_WA = RS_EL + 1
RS_WB = RS_WA + 1
RS_HC = RS_WB + 1
RS_D_PREV = RS_HC + 7  # Delta and B_d at the start of step j (the located step's start)
RS_BD_PREV = RS_D_PREV + 1
RS_SIZE = RS_BD_PREV + 1


WORK_SIZE = 80

# The constants of one Newmark step (:func:`kernels.mesh.step_consts`), a tuple of 23 floats that
# numba keeps in registers: ``k[K_XIM2]`` is 2 xi_m. The indices are compile-time constants, so a
# named index costs nothing. Natural time, b0 units.
(
    K_IEP,  # 1/eps_p (pinion inverse mass ratio)
    K_IEG,  # 1/eps_g
    K_C_P,  # pinion bearing damping 2 xi_bp sigma_p
    K_C_G,  # gear bearing damping 2 xi_bg sigma_g
    K_K_P,  # pinion bearing stiffness sigma_p^2
    K_K_G,  # gear bearing stiffness sigma_g^2
    K_EXT_P,  # pinion weight per unit mass -g_p/eps_p (Y direction)
    K_EXT_G,  # gear weight per unit mass -g_g/eps_g
    K_XIM2,  # mesh damping 2 xi_m
    K_FS,  # static mesh force F_s
    K_E1,  # transmission error amplitude E1
    K_A0,  # nominal centre distance A0
    K_R,  # R = sum of base radii
    K_INV_R,  # 1/R
    K_BC,  # nominal half backlash B_c
    K_SIN_A0,  # sin alpha0
    K_COS_A0,  # cos alpha0
    K_MU,  # friction coefficient (0: the paper's model)
    K_COS_PHI_E,  # cos phi_e
    K_SIN_PHI_E,  # sin phi_e
    K_BETA,  # Newmark beta (GearParams.newmark_beta; 1/4 = the paper's average acceleration)
    K_VC,  # velocity correction w: the forces feel v - w h (a_new - a_old) (VC_WEIGHT or 0)
    K_LOC,  # c[C_LOC]: how the fixed-step drivers take a contact change inside a step (params.CONTACTS_*)
) = range(23)
N_K = K_LOC + 1
"""Number of step constants (length of :func:`kernels.mesh.step_consts`)."""
