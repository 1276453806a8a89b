"""Layouts shared by the kernels and the Python API: settings vector, label vector, status and reason
codes, observation slots.  Free of numba so that ``import sim`` stays cheap (numba loads with the first
simulation)."""
from __future__ import annotations

# ----------------------------------------------------------------------------- settings layout
# Float settings vector passed to the kernel (built by sim.api.Settings.to_array).
S_RTOL = 0
S_MIN_TRANSIENT = 1      # cycles
S_MAX_TRANSIENT = 2      # cycles
S_WINDOW = 3             # cycles
S_PERIOD_TOL = 4         # relative to each bounded coordinate's range
S_SETTLE_TOL = 5         # relative, used while waiting for settlement
S_MAX_STEPS_PER_CYCLE = 6
S_EVENT_TOL = 7          # seconds, relative to the forcing period
S_MAX_STEP_FRAC = 8      # max step as a fraction of the forcing period
S_STAT_TOL = 9           # relative agreement of half-window statistics for non-periodic steady states
S_RUNAWAY_CHECK = 10     # 1: a pre-check flagged a possible runaway; confirm it from the drift
S_MAX_STEPS = 11         # accepted steps of the whole run: a point's work limit
N_SETTINGS = 12

# ----------------------------------------------------------------------------- label layout
# L_WINDOW: the recorded window's length in forcing cycles (the setting ``window``, made whole periods of a periodic
# response); the labels' invariants check it (sim.invariants)
L_STATUS, L_ROP, L_PEAK_F, L_MEAN_PEAK_F, L_IMPACTS, L_PERIOD, L_DECEL, L_ENERGY, L_SPEC_E, \
    L_TRANSIENT, L_REASON, L_STEPS, L_EVENTS, L_DRIFT_ACC, L_WINDOW = range(15)
N_LABELS = 15

# STATUS_APERIODIC: bounded and statistically steady (the window's two halves agree), with no period <= 8
STATUS_OK, STATUS_NO_CONTACT, STATUS_RUNAWAY, STATUS_NOT_SETTLED, STATUS_FAILED, STATUS_APERIODIC = 0, 1, 2, 3, 4, 5
REASON_NONE, REASON_STEP_UNDERFLOW, REASON_TOO_MANY_STEPS, REASON_NONFINITE, REASON_DRIFT, \
    REASON_PRECHECK, REASON_NOT_PERIODIC, REASON_WORK_LIMIT, REASON_LOST_PERIOD = range(9)

OBS_FORCE, OBS_ACCEL, OBS_DISP, OBS_PROGRESS, OBS_VEL = 0, 1, 2, 3, 4
N_OBS = 5
G_ACCEL = 9.81
MAX_PERIOD = 8

# ----------------------------------------------------------------------------- kernel scratch
# Rows of integrate_cycles' per-run scratch (sim/_kernel_template.py make_workspace): wk holds the DOPRI5 stages,
# the interpolant and the dense states (each ny long), gk the guards and one observation; a hybrid propagator
# (sim/exact/rimd.py, sim/exact/indenter.py) returns the same wk and keeps its own tables in gk's rows from GK_ROWS on.
WK_ROWS = 16
GK_ROWS = 5
