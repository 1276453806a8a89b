"""Run one parameter point to a labelled steady state (numba; model functions passed in).

Sequence: transient cycles until the stroboscopic samples of the bounded coordinates
repeat with some period n ≤ 8 (checked every cycle after ``min_transient``; capped at
``max_transient``), then a recorded window of whole cycles, split in two halves so a
non-periodic response can be judged steady (half-window statistics agree) or not.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from sim.integrator import (
    G_ACCEL, L_DECEL, L_DRIFT_ACC, L_ENERGY, L_EVENTS, L_IMPACTS, L_MEAN_PEAK_F, L_PEAK_F, L_PERIOD,
    L_REASON, L_ROP, L_SPEC_E, L_STATUS, L_STEPS, L_TRANSIENT, MAX_PERIOD, N_LABELS, N_OBS, OBS_PROGRESS,
    REASON_DRIFT, REASON_NOT_PERIODIC, REASON_PRECHECK, S_MAX_TRANSIENT, S_MIN_TRANSIENT, S_PERIOD_TOL,
    S_RUNAWAY_CHECK, S_SETTLE_TOL, S_STAT_TOL, S_WINDOW, STATUS_FAILED, STATUS_NO_CONTACT, STATUS_NOT_SETTLED,
    STATUS_OK, STATUS_RUNAWAY, periodicity, rows_repeat, span_ranges,
)

N_ACC = 8


@njit(cache=True)
def settled_period(strobe, bmin, bmax, last, tol):
    """Smallest n ≤ 8 for which rows last-2n..last repeat with period n and the samples one
    16-cycle span apart (a multiple of n) agree too (0: not settled yet).

    Tolerance is relative to each coordinate's range over the rows compared."""
    ranges = np.empty(strobe.shape[1])
    for n in range(1, MAX_PERIOD + 1):
        first = last - 2 * n
        if first < 0:
            return 0
        span_ranges(bmin, bmax, first, last, ranges)
        if not rows_repeat(strobe, first, last, n, ranges, tol):
            continue
        # slow creep passes a one-period test: also require no drift over a 16-cycle span
        span = (16 // n) * n
        if last - span < 0:
            return 0
        span_ranges(bmin, bmax, last - span, last, ranges)
        if rows_repeat(strobe, last - span, last, span, ranges, tol):
            return n
    return 0


@njit(cache=True)
def _rel_close(a, b, tol, floor):
    return abs(a - b) <= tol * max(abs(a), abs(b)) + floor

