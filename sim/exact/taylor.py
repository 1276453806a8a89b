"""Polynomials in the step fraction θ ∈ [0, 1] that the exact propagators (sim/exact/) work on.

A linear phase ż = A z over a step of length L is the series z(θ L) = Σ_k C[k] θ^k with C[k] = (L A)^k z / k!
(rows of ``C``: the terms; columns: the components of z).  A quantity linear in z (a guard, a force, a
deceleration: a row r) is then the polynomial a[k] = r · C[k]; its roots and maxima on [0, 1] are found here to
machine precision.  Every function takes its sizes from its arrays (any number of components; ``nt`` = the terms
in use, the rest of a coefficient array is zero).
"""
from __future__ import annotations

import numpy as np

from sim.jit import njit  # numba is imported on first use (sim/jit.py)

NT = 32
"""Taylor terms: with ρ(A) L ≤ 2 the truncation is below 2^32/32! < 1e-25 (exact in double precision)."""
INV = 1.0 / np.arange(1.0, 2 * NT + 1.0)
"""1 / (n + 1): the integral of θ^n over [0, 1]."""


@njit(cache=True)
def pack_rows(A, vals, cols):
    """A's non-zeros packed by row, as ``series`` and ``flow_tables`` read them: row i has ``cols[i, 0]`` of them,
    values ``vals[i, :n]`` in columns ``cols[i, 1:n + 1]`` (``cols`` integer, or float holding integers)."""
    for i in range(A.shape[0]):
        n = 0
        for j in range(A.shape[1]):
            if A[i, j] != 0.0:
                vals[i, n] = A[i, j]
                cols[i, 1 + n] = j
                n += 1
        cols[i, 0] = n


@njit(cache=True)
def row_times(r, A, out):
    """out = r A (a row of a linear quantity times A: its time derivative along ż = A z)."""
    for j in range(A.shape[1]):
        acc = 0.0
        for i in range(A.shape[0]):
            acc += r[i] * A[i, j]
        out[j] = acc


@njit(cache=True)
def flow_tables(vals, cols, h, i_force, i_vel, i_c, i_s, f0, Phi, M):
    """Φ = exp(h A) = Σ_k (hA)^k / k! (NT terms; A from its packed rows, ``pack_rows``) into Phi, and the work of a
    harmonic force over one step, f0 ∫_0^h z[i_force] z[i_vel] dτ = zᵀ M z, into M's rows i_c and i_s.

    z[i_force] is one of the forcing oscillator's states c = cos Ωt, s = sin Ωt (i_c, i_s), whose rows of A reach
    only each other: so are the rows of (hA)^k, and M is zero outside rows i_c, i_s (left as they are).
    M[a, b] = f0 h Σ_j Σ_k U[j, a] V[k, b] / (j + k + 1) with U, V the rows i_force, i_vel of (hA)^k / k!.
    The series runs row by row as a sum of scaled rows of the previous term (contiguous scratch: this loop is most of
    a run's set-up)."""
    n = vals.shape[0]
    P = np.empty((n, n))
    Q = np.empty((n, n))
    S = np.empty((n, n))     # Φ being summed
    U = np.zeros((NT, n))
    V = np.zeros((NT, n))
    Wv = np.zeros(NT)        # Σ_j U[j, a] / (j + k + 1)
    for i in range(n):
        for j in range(n):
            P[i, j] = 0.0
            S[i, j] = 0.0
        P[i, i] = 1.0
        S[i, i] = 1.0
    for j in range(n):
        U[0, j] = P[i_force, j]
        V[0, j] = P[i_vel, j]
    for k in range(1, NT):
        f = h / k
        for i in range(n):
            for j in range(n):
                Q[i, j] = 0.0
            for q in range(int(cols[i, 0])):
                v = vals[i, q] * f
                c = int(cols[i, 1 + q])
                for j in range(n):
                    Q[i, j] += v * P[c, j]
        P, Q = Q, P
        for i in range(n):
            for j in range(n):
                S[i, j] += P[i, j]
        for j in range(n):
            U[k, j] = P[i_force, j]
            V[k, j] = P[i_vel, j]
    for i in range(n):
        for j in range(n):
            Phi[i, j] = S[i, j]
    for a in (i_c, i_s):
        for k in range(NT):
            acc = 0.0
            for j in range(NT):
                acc += U[j, a] * INV[j + k]
            Wv[k] = acc
        for b in range(n):
            acc = 0.0
            for k in range(NT):
                acc += Wv[k] * V[k, b]
            M[a, b] = f0 * h * acc


@njit(cache=True)
def series(vals, cols, z, L, C, ityp):
    """C[k] = (L A)^k z / k!, k < NT, with A's non-zeros packed by row: row i has ``cols[i, 0]`` of them, values
    ``vals[i, :n]`` in columns ``cols[i, 1:n + 1]`` (integers, or floats holding integers).  The tail is cut (set
    to 0) once two successive terms are below 1e-17 of the first in the norm scaled by the inverse typical state
    magnitudes ``ityp``.  Returns the number of terms kept."""
    nz = C.shape[1]
    C[0, :] = z
    n0 = 0.0
    for i in range(nz):
        n0 += abs(z[i]) * ityp[i]
    small = 0
    k = 1
    while k < NT:
        nk = 0.0
        f = L / k
        for i in range(nz):
            acc = 0.0
            for q in range(int(cols[i, 0])):
                acc += vals[i, q] * C[k - 1, int(cols[i, 1 + q])]
            v = acc * f
            C[k, i] = v
            nk += abs(v) * ityp[i]
        k += 1
        if nk <= 1e-17 * n0:
            small += 1
            if small == 2:
                break
        else:
            small = 0
    for j in range(k, NT):
        for i in range(nz):
            C[j, i] = 0.0
    return k


@njit(cache=True, inline="always")
def dot(r, z):
    """r · z over z's components."""
    acc = 0.0
    for i in range(z.shape[0]):
        acc += r[i] * z[i]
    return acc


@njit(cache=True, inline="always")
def row_dot(M, row, z, n):
    """M[row, :n] · z[:n], the row given by its index: no array view, so no reference counting in a step loop."""
    acc = 0.0
    for i in range(n):
        acc += M[row, i] * z[i]
    return acc


@njit(cache=True)
def row_poly(r, C, a, nt):
    """a[k] = r · C[k] for k < nt, 0 beyond (the polynomial of the quantity with row r)."""
    for k in range(nt):
        a[k] = dot(r, C[k])
    for k in range(nt, a.shape[0]):
        a[k] = 0.0


@njit(cache=True, inline="always")
def peval(a, th, nt):
    """Σ_k a[k] θ^k (Horner)."""
    v = a[nt - 1]
    for k in range(nt - 2, -1, -1):
        v = v * th + a[k]
    return v


@njit(cache=True, inline="always")
def dpeval(a, th, nt):
    """d/dθ Σ_k a[k] θ^k."""
    v = (nt - 1) * a[nt - 1]
    for k in range(nt - 2, 0, -1):
        v = v * th + k * a[k]
    return v


@njit(cache=True, inline="always")
def _f(a, x, deriv, nt):
    return dpeval(a, x, nt) if deriv else peval(a, x, nt)


@njit(cache=True, inline="always")
def _fd(a, th, deriv, nt):
    """(p, p') at θ of the polynomial a (deriv: of its derivative: (p', p'')) in one pass: two independent Horner
    chains side by side."""
    if deriv:
        v = (nt - 1) * a[nt - 1]
        d = 0.0
        for k in range(nt - 1, 1, -1):
            d = d * th + k * (k - 1) * a[k]
            if k <= nt - 2:
                v = v * th + k * a[k]
        if nt >= 3:
            v = v * th + a[1]
        return v, d
    v = a[nt - 1]
    d = (nt - 1) * a[nt - 1]
    for k in range(nt - 2, 0, -1):
        v = v * th + a[k]
        d = d * th + k * a[k]
    if nt >= 2:
        v = v * th + a[0]
    return v, d


@njit(cache=True)
def root(a, lo, hi, deriv, nt):
    """Root in [lo, hi] of the polynomial a (deriv: of its derivative), which is ≤ 0 at one end and > 0
    at the other; safeguarded Newton (bisection when a step leaves the bracket) to machine precision.
    Returns a point on the side of ``hi`` (the crossed side), within a few ulps of the root."""
    flo = _f(a, lo, deriv, nt)
    fhi = _f(a, hi, deriv, nt)
    pos_hi = fhi > 0.0
    x = lo if abs(flo) < abs(fhi) else hi
    for _ in range(100):
        fx, d = _fd(a, x, deriv, nt)
        if (fx > 0.0) == pos_hi:
            hi = x
        else:
            lo = x
        if hi - lo <= 4e-16 * max(1.0, abs(hi)) or (hi - lo <= 0.0) or fx == 0.0:
            break
        xn = x - fx / d if d != 0.0 else 0.5 * (lo + hi)
        if not (min(lo, hi) < xn < max(lo, hi)):
            xn = 0.5 * (lo + hi)
        if abs(xn - x) <= 1e-17 * max(1.0, abs(x)):
            break
        x = xn
    # Newton may approach from the uncrossed side: step across in growing ulp-sized nudges
    if hi - lo > 4e-16 * max(1.0, abs(hi)):
        eps = 4e-16 * max(1.0, abs(lo))
        for _ in range(60):
            xx = lo + eps
            if xx >= hi:
                break
            if (_f(a, xx, deriv, nt) > 0.0) == pos_hi:
                hi = xx
                break
            lo = xx
            eps *= 2.0
    return hi


@njit(cache=True)
def first_rise(a, nt):
    """The first θ in [0, 1] where the polynomial a rises through 0 (from ≤ 0 to > 0), or -1: a sign change over
    the step, or a turning point above 0 between two non-positive ends (one turning point per step at most: the
    step is a fraction of the fastest period)."""
    ga = a[0]
    gb = peval(a, 1.0, nt)
    if (ga < 0.0 and gb >= 0.0) or (ga <= 0.0 and gb > 0.0):
        return root(a, 0.0, 1.0, False, nt)
    if ga <= 0.0 and dpeval(a, 0.0, nt) > 0.0 and dpeval(a, 1.0, nt) < 0.0:
        tm = root(a, 0.0, 1.0, True, nt)
        if peval(a, tm, nt) > 0.0:
            return root(a, 0.0, tm, False, nt)
    return -1.0


@njit(cache=True)
def eval_state(C, th, z, nt):
    """z = Σ_k C[k] θ^k (the state at θ of the step)."""
    for i in range(z.shape[0]):
        v = C[nt - 1, i]
        for k in range(nt - 2, -1, -1):
            v = v * th + C[k, i]
        z[i] = v


@njit(cache=True)
def work_integral(C, th, L, f0, nt, pw, i_force, i_vel, i_rel=-1):
    """f0 ∫ z[i_force] z[i_vel] dτ over [0, θ L] from the series coefficients (with ``i_rel`` ≥ 0: of the relative
    velocity z[i_vel] - z[i_rel]): the product polynomial q_n = Σ_{j+k=n} C[j, i_force] C[k, i_vel] integrated term
    by term (Horner in θ; pw: scratch of 2 NT + 1)."""
    for n in range(2 * nt - 1):
        pw[n] = 0.0
    for j in range(nt):
        cj = C[j, i_force]
        if cj != 0.0:
            for k in range(nt):
                v = C[k, i_vel]
                if i_rel >= 0:           # loop-invariant: hoisted; without i_rel the product is bit for bit the same
                    v -= C[k, i_rel]
                pw[j + k] += cj * v
    acc = 0.0
    for n in range(2 * nt - 2, -1, -1):
        acc = acc * th + pw[n] * INV[n]
    return f0 * L * th * acc


@njit(cache=True)
def max_on(C, r, a, lo, hi, nt):
    """Max over [lo, hi] of row r on the series (a: scratch for its polynomial)."""
    row_poly(r, C, a, nt)
    return poly_max(a, lo, hi, nt)


@njit(cache=True)
def poly_max(a, lo, hi, nt):
    """Max over [lo, hi] of the polynomial a: at the root of the derivative if it turns there."""
    d_lo = dpeval(a, lo, nt)
    d_hi = dpeval(a, hi, nt)
    best = max(peval(a, lo, nt), peval(a, hi, nt))
    if d_lo > 0.0 and d_hi <= 0.0:
        th = root(a, lo, hi, True, nt)
        best = max(best, peval(a, th, nt))
    return best


@njit(cache=True)
def rise(a, nt):
    """First θ in [0, 1] where the polynomial a rises through 0, or -1 (``first_rise``; and, for a guard that starts
    above 0 — a penetration δ > 0 after a release by the force indicator — a dip below 0 and back inside the step)."""
    if a[0] > 0.0:
        if peval(a, 1.0, nt) > 0.0 and dpeval(a, 0.0, nt) < 0.0 and dpeval(a, 1.0, nt) > 0.0:
            tm = root(a, 0.0, 1.0, True, nt)
            if peval(a, tm, nt) <= 0.0:
                return root(a, tm, 1.0, False, nt)
        return -1.0
    return first_rise(a, nt)


@njit(cache=True)
def min_onset(pd, ph_, nt):
    """First θ in [0, 1] where min(pd, ph_) rises through 0 (both polynomials above 0), or -1: the onset of a contact
    with two indicators, penetration and force (the RIMD's δ and LS (1 + λi v2), the metal indenter's x1 - G and
    k1 (x1 - G) + c1 ẋ1; MODELS.md §1a)."""
    th = -1.0
    td = rise(pd, nt)
    if td >= 0.0 and peval(ph_, td, nt) > 0.0:
        th = td
    tg = rise(ph_, nt)
    if tg >= 0.0 and peval(pd, tg, nt) > 0.0 and (th < 0.0 or tg < th):
        th = tg
    return th
