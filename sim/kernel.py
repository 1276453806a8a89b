"""Steady-state helpers of the driver in ``sim/_kernel_template.py`` (``run_point``).

The driver runs transient cycles until the stroboscopic samples of the bounded coordinates
repeat with some period n ≤ 8 (``settled_period``, checked every cycle after ``min_transient``;
capped at ``max_transient``), then a recorded window of whole cycles, split in two halves so a
non-periodic response can be judged steady (half-window statistics agree, ``_rel_close``) or not.
"""
from __future__ import annotations

import numpy as np
from sim.jit import njit  # numba is imported on first use (sim/jit.py)

from sim.integrator import MAX_PERIOD, rows_repeat, span_ranges

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

