"""Event-locating integrator for piecewise-smooth ODEs, compiled with numba.

Method
------
Dormand–Prince 5(4) (``DOPRI5``) with FSAL, standard error-per-step control
and Hairer's 4th-order continuous extension (``CONTD5``).  We chose it over
DOP853 and implicit methods because every model here is non-stiff inside each
branch (largest |λ|·h limit is set by the contact stiffness, not by stiffness
ratios), segments between switches are short (a contact lasts ~10–30 steps), and a
5th-order pair with a cheap 4th-order interpolant gives the best accuracy per
right-hand-side call at the 1e-7…1e-9 tolerances we need; the interpolant is what
locates the switches.

Switching surfaces
------------------
A model exposes, for its current discrete phase, a vector of *guards*
``g_i(t, y)``.  A switch happens when a guard rises through zero (a falling surface
is written as ``-h``).  After each accepted step the guards are checked at the end
and at three interior points of the dense output (so a double crossing inside one
step is not missed), the earliest crossing is bracketed and refined by the
Illinois method on the interpolant to ``event_tol`` seconds, the step is truncated
there and the model's ``on_event`` chooses (and checks) the new phase from the
state itself.  Time never steps over a switch.

Model interface (all numba-jitted functions, passed as first-class arguments)::

    rhs(t, y, z, ph, p, dy)            -> None   fill dy = f(t, y) on branch ph
    guards(t, y, z, ph, p, g)          -> None   fill g, of length N_GUARDS (inactive guards: -1.0)
    on_event(t, y, z, ph, p, k)        -> int    apply switch k (may edit y, z), return new phase
    observe(t, y, z, ph, p, obs, dy)   -> None   obs = [contact force, accel, disp, progression, velocity]
    bounded(t, y, z, ph, p, b)         -> None   coordinates that stay bounded in steady state

The model's module also defines ``N_GUARDS``, the most guards any of its phases has: the kernel checks
exactly that many after every step, and ``GUARD_STATES``, the indices of the states the guards read: the
kernel interpolates only those where it looks for a switch inside a step (``tests/sim/test_conformance.py``
checks no phase writes more guards or reads other states).
``z`` holds discrete states that change only at switches (e.g. crater floor).
Phase 0 always means "no contact"; every phase > 0 is a contact phase.
"""
from __future__ import annotations

import numpy as np
from sim.jit import njit  # numba is imported on first use (sim/jit.py)

# ----------------------------------------------------------------------------- DOPRI5 tableau
C2, C3, C4, C5 = 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0
A21 = 1.0 / 5.0
A31, A32 = 3.0 / 40.0, 9.0 / 40.0
A41, A42, A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
A51, A52, A53, A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
A61, A62, A63, A64, A65 = 9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0
A71, A73, A74, A75, A76 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
E1, E3, E4, E5, E6, E7 = (71.0 / 57600.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
                          22.0 / 525.0, -1.0 / 40.0)
D1, D3, D4, D5, D6, D7 = (-12715105075.0 / 11282082432.0, 87487479700.0 / 32700410799.0,
                          -10690763975.0 / 1880347072.0, 701980252875.0 / 199316789632.0,
                          -1453857185.0 / 822651844.0, 69997945.0 / 29380423.0)


def dopri5_tableau() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The tableau above as arrays ``(A, b, c, e)``: A (7×7), the 5th-order weights b (FSAL: A's last row), the
    nodes c and the error weights e = b − b̂.  For analysis and tests (the stability function in
    ``bench/step_budget.py``, the order conditions in ``tests/sim/test_tableau.py``); the kernel uses the constants."""
    a = np.zeros((7, 7))
    a[1, 0] = A21
    a[2, :2] = A31, A32
    a[3, :3] = A41, A42, A43
    a[4, :4] = A51, A52, A53, A54
    a[5, :5] = A61, A62, A63, A64, A65
    a[6, :6] = A71, 0.0, A73, A74, A75, A76
    c = np.array([0.0, C2, C3, C4, C5, 1.0, 1.0])
    e = np.array([E1, 0.0, E3, E4, E5, E6, E7])
    return a, a[6].copy(), c, e


from sim.layout import *  # noqa: F401,F403  (layouts re-exported for the kernel template)
from sim.layout import MAX_PERIOD

# The kernels' error model: IEEE division (x/0 -> inf or nan, caught by the step's finiteness check) instead of
# Python's ZeroDivisionError: the same quotients without a zero test and exception exit per division, which would
# split the step loop into blocks that numba's reference-count pruning cannot see across (an incref/decref pair per
# array and block per step).  The kernel template's functions and the model functions sim.compiled binds as calls.
ERRORS = "numpy"


@njit(cache=True, inline="always")
def _dense_some(r1, r2, r3, r4, r5, th, out, idx):
    """Hairer's continuous extension of DOPRI5 at θ = th ∈ [0, 1] of the step, for the components ``idx`` only
    (a tuple of indices, or a range): ``out[i] = r1 + θ(r2 + (1-θ)(r3 + θ(r4 + (1-θ) r5)))``."""
    th1 = 1.0 - th
    for i in idx:
        out[i] = r1[i] + th * (r2[i] + th1 * (r3[i] + th * (r4[i] + th1 * r5[i])))


@njit(cache=True, inline="always")
def _dense(r1, r2, r3, r4, r5, th, out):
    """The continuous extension at θ = th for every component (``_dense_some`` over all of them)."""
    _dense_some(r1, r2, r3, r4, r5, th, out, range(out.shape[0]))


@njit(cache=True, error_model="numpy")
def _crossed(ga, gb):
    """A guard crossed upward between two samples (zero counts on one side only)."""
    return (ga < 0.0 and gb >= 0.0) or (ga <= 0.0 and gb > 0.0)


@njit(cache=True, inline="always")
def widen_extremes(bvec, bmin, bmax, cyc):
    """Row ``cyc`` of the per-cycle extremes bmin/bmax widened to the bounded coordinates ``bvec`` (an exact
    propagator's step end; the kernel template writes the same loop out, see its note on array arguments)."""
    for j in range(bvec.shape[0]):
        if bvec[j] < bmin[cyc, j]:
            bmin[cyc, j] = bvec[j]
        if bvec[j] > bmax[cyc, j]:
            bmax[cyc, j] = bvec[j]


@njit(cache=True, inline="always")
def window_switch(acc, old, ph):
    """The window accumulator's bookkeeping at a switch from phase ``old`` to ``ph`` (sim/_kernel_template.py
    ``integrate_cycles``): an onset counts and opens a contact's running maximum acc[5]; a release closes it into the
    sum of per-contact maxima acc[1] and their count acc[2], or, for the contact open at the window start
    (acc[7] == -1), keeps its part in acc[7]."""
    if old == 0 and ph > 0:
        acc[3] += 1.0
        acc[5] = 0.0
    elif old > 0 and ph == 0:
        if acc[7] == -1.0:      # the contact open at the window start: keep its part
            acc[7] = acc[5]
        else:
            acc[1] += acc[5]
            acc[2] += 1.0
        acc[5] = 0.0


@njit(cache=True, inline="always")
def track_maxima(acc, obs, in_contact):
    """Update the window maxima with one observation (force counts only in contact); acc: the kernel's window
    accumulator (sim/_kernel_template.py ``integrate_cycles``)."""
    if in_contact:
        f = obs[OBS_FORCE]
        if f > acc[0]:
            acc[0] = f
        if f > acc[5]:
            acc[5] = f
    if -obs[OBS_ACCEL] > acc[4]:
        acc[4] = -obs[OBS_ACCEL]


@njit(cache=True, inline="always")
def two_indicator_guard(g, penetration, force_indicator, ph):
    """Guards of a contact that exists iff penetration ≥ 0 AND the force expression > 0 (MODELS.md
    §1a: both are switching surfaces, contact may resume while still penetrated).  One guard,
    min of the two indicators (same sign convention, any positive scaling): it rises through 0
    on entry (phase 0) and falls through 0 on release (phase 1)."""
    for i in range(g.shape[0]):
        g[i] = -1.0
    ind = min(penetration, force_indicator)
    g[0] = ind if ph == 0 else -ind


@njit(cache=True, error_model="numpy")
def two_indicator_phase(penetration, force):
    """Phase after a switch of a two-indicator contact: 1 in contact, 0 free."""
    return 1 if (penetration >= 0.0 and force > 0.0) else 0


@njit(cache=True)
def span_ranges(bmin, bmax, first, last, out):
    """out[j] = range of coordinate j over rows first..last of the per-cycle extremes."""
    for j in range(bmin.shape[1]):
        lo = bmin[first, j]
        hi = bmax[first, j]
        for k in range(first, last + 1):
            lo = min(lo, bmin[k, j])
            hi = max(hi, bmax[k, j])
        out[j] = hi - lo


@njit(cache=True)
def rows_repeat(strobe, first, last, n, ranges, tol):
    """True if strobe[k+n] ≈ strobe[k] for k in first..last-n, within tol × range (floor 1e-12)."""
    for k in range(first, last - n + 1):
        for j in range(strobe.shape[1]):
            if abs(strobe[k + n, j] - strobe[k, j]) > tol * ranges[j] + 1e-12:
                return False
    return True


@njit(cache=True)
def periodicity(strobe, ranges, tol, n_rows):
    """Smallest n ≤ 8 with strobe[k+n] ≈ strobe[k] for all k < n_rows-n (0: none).

    strobe: (rows, n_bounded) stroboscopic samples; ranges: per-coordinate range used
    to scale the tolerance (absolute floor 1e-12).
    """
    for n in range(1, MAX_PERIOD + 1):
        if n_rows < 2 * n:
            return 0
        if rows_repeat(strobe, 0, n_rows - 1, n, ranges, tol):
            return n
    return 0
