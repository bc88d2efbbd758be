"""numba kernels of the gear-bearing model, split by concern.

=====================  ======================================================================
module                 holds
=====================  ======================================================================
``kernels.layout``     sizes, Newmark parameters, status codes, column layouts (REC_, ST_, PC_)
``kernels.jit``        the ``kernel`` decorators, ``readonly``, ``runtime_int``/``runtime_true``
``kernels.mesh``       the model, written once: backlash, geometry, excitation, friction, mesh
                       force, the equations of motion in residual form and their derivatives,
                       accelerations, step constants, static equilibrium
``kernels.newmark``    one Newmark-beta step: predictor, Newton iteration, step splitting
``kernels.drivers``    many steps per call: ``integrate_record``, ``integrate_stats(_batch)``,
                       ``integrate_stats_lazy`` (Python, the split fallback compiled on need)
``kernels.stats``      the interval statistics accumulated by the drivers
=====================  ======================================================================

Every name is re-exported here, so ``from gear_env import kernels as K; K.integrate_stats`` and
``K.ST_F_MAX`` work as before the split. Python code calls the drivers through
:func:`gear_env.integration.integrate`. ``gear_env/reference.py`` is the readable (and
independent) statement of the equations of ``kernels.mesh``.
"""

from __future__ import annotations

from numba import njit  # re-exported: gear_env.kernels exposed it before the split

from ..params import (
    C_A0,
    C_ALPHA0,
    C_BC,
    C_COS_A0,
    C_E1,
    C_EPS_G,
    C_EPS_P,
    C_FS,
    C_GG,
    C_GP,
    C_KAPPA,
    C_MU,
    C_PHI_E,
    C_PHI_K,
    C_R,
    C_SIG_G,
    C_SIG_P,
    C_SIN_A0,
    C_XI_BG,
    C_XI_BP,
    C_XI_M,
)
from .drivers import (
    _excitation_table,
    _integrate_stats_batch,
    _poincare_store_t,
    _record_row_t,
    integrate_record,
    integrate_stats,
    integrate_stats_batch,
    integrate_stats_lazy,
    integrate_stats_tab,
    split_resume,
    start_step,
    stats_segment,
)
from .jit import kernel, kernel_inline, readonly, runtime_int, runtime_true
from .layout import (
    BETA,
    DIVERGED,
    DIVERGENCE_LIMIT,
    GAMMA,
    GEO_SIZE,
    K_A0,
    K_BC,
    K_C_G,
    K_C_P,
    K_COS_A0,
    K_COS_PHI_E,
    K_E1,
    K_EXT_G,
    K_EXT_P,
    K_FS,
    K_IEG,
    K_IEP,
    K_INV_R,
    K_K_G,
    K_K_P,
    K_MU,
    K_R,
    K_SIN_A0,
    K_SIN_PHI_E,
    K_XIM2,
    N_K,
    N_PC,
    N_REC,
    N_STATS,
    NDOF,
    NEWTON_FAILED,
    NSTATE,
    OK,
    PC_BD,
    PC_DELTA,
    PC_FORCE,
    PC_PSI,
    REC_BD,
    REC_DELTA,
    REC_FORCE,
    REC_OMEGA,
    REC_PHI,
    REC_PSI,
    REC_REGION,
    REC_S,
    RS_J,
    RS_SIZE,
    SPLIT_PENDING,
    ST_BACK_IMPACTS,
    ST_BACK_TIME,
    ST_BD_MAX,
    ST_BD_MIN,
    ST_D_MAX,
    ST_D_MIN,
    ST_DRIVE_IMPACTS,
    ST_F_MAX,
    ST_F_MIN,
    ST_F_SQ,
    ST_F_SUM,
    ST_PSI_MAX,
    ST_PSI_MIN,
    ST_SEP_TIME,
    ST_SPLITS,
    ST_STEPS,
    ST_TIME,
    ST_TR_MAX,
    ST_TR_SQ,
    ST_U_MAX,
    ST_U_MIN,
    TWO_PI,
    WORK_SIZE,
)
from .mesh import (
    FRICTION_SHARPNESS,
    accel,
    backlash,
    backlash_branch,
    backlash_inverse,
    backlash_slopes,
    bearing_t,
    deflection_gradient_t,
    deflection_t,
    eom_residual_t,
    excitation,
    force_direction_dpsi_t,
    force_direction_t,
    force_gradient_t,
    force_t,
    friction_t,
    geometry,
    geometry_t,
    geometry_taylor_t,
    mesh_state,
    mesh_t,
    psi_t,
    static_equilibrium,
    step_consts,
)
from .newmark import (
    DQ_LINEAR,
    MAX_SPLIT_LEVEL,
    NEWTON_BAD,
    NEWTON_DONE,
    NEWTON_MORE,
    _diverged_t,
    corrector_t,
    guess_t,
    load_t,
    newmark_step,
    newmark_step_t,
    newmark_try_t,
    newton_iter_t,
    newton_start_t,
    omega_step_t,
    split_step_t,
    step_coeffs,
    store_t,
)
from .stats import _acc_init, _acc_step, _acc_store, _stats_init
