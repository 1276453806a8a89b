"""Contact laws of the models (MODELS.md §1-4): scalar functions, composed by the models' right-hand sides.

Each takes and returns floats only, so a call costs no reference counting: each is compiled once (IEEE division, as
the kernel) and LLVM inlines it into the kernels, rather than numba inlining its IR at every call site, which made
each kernel's compile about a third longer for the same machine code (docs/architecture.md, "Where a contact law
goes").  A stiffness passed in is the effective one, with the §6 terms already applied (``sim.models.terms``).  A
contact that ends when its force expression falls to zero (two-indicator release, MODELS.md §1a) locates its
switches with ``sim.integrator.two_indicator_guard`` / ``two_indicator_phase``.
"""
from __future__ import annotations

import math

from sim.jit import njit  # numba is imported on first use (sim/jit.py)

V_ONE = 19.0
"""|v| / v_eps from which ``coulomb_sign`` returns ± 1 directly (its exp form is ± 1 from 18.72 on: the same values)."""


@njit(cache=True, error_model="numpy")
def kelvin_voigt(k, c, d, dd):
    """Spring-dashpot force expression k δ + c δ̇ [N] (unclamped: its sign is the release indicator); k [N/m],
    c [N s/m], penetration δ [m] and its rate δ̇ [m/s]."""
    return k * d + c * dd


@njit(cache=True, error_model="numpy")
def released_force(expr, ph):
    """Force [N] of a two-indicator contact in phase ph: the expression clamped at 0 in contact (ph > 0), else 0."""
    return max(expr, 0.0) if ph > 0 else 0.0


@njit(cache=True, error_model="numpy")
def hunt_crossley_damping(lam, dd):
    """Hunt-Crossley damping factor 1 + λ δ̇ [-] (λ [s/m]); its sign is the contact's second indicator."""
    return 1.0 + lam * dd


@njit(cache=True, error_model="numpy")
def hunt_crossley(k, n, lam, d, dd):
    """Hunt-Crossley force expression k max(δ, 0)^n (1 + λ δ̇) [N] (k [N/m^n]; not clamped in the damping factor)."""
    return k * max(d, 0.0) ** n * hunt_crossley_damping(lam, dd)


@njit(cache=True, error_model="numpy")
def power(x, n):
    """x ** n without a pow call for the linear law n = 1 (the same value, bit for bit)."""
    return x if n == 1.0 else x ** n


@njit(cache=True, error_model="numpy")
def branch_force(k, depth, n):
    """Force k max(depth, 0)^n [N] of a power-law loading or unloading branch (sandstone, MODELS.md §1b)."""
    return k * power(max(depth, 0.0), n)


@njit(cache=True, error_model="numpy")
def branch_depth(f, k, n):
    """Depth (f / k)^(1/n) [m] at which the branch k depth^n carries the force f [N] (its inverse)."""
    return power(f / k, 1.0 / n)


@njit(cache=True, error_model="numpy")
def rock_surface_rate(k1, c1, xt, xb):
    """Drill rock off contact (MODELS.md §2 phase I): the massless surface relaxes towards the slider base,
    ẋt = −(K1/C1)(xt − xb) [m/s] (K1 [N/m], C1 [N s/m], xt, xb [m])."""
    return -(k1 / c1) * (xt - xb)


@njit(cache=True, error_model="numpy")
def rock_slider_rate(pc_expr, pr, c1):
    """Drill rock progressing (MODELS.md §2 phase III, Pc = Pr): slider base rate ẋb = (Pc − Pr)/C1 [m/s] from the
    phase-II force expression pc_expr [N] and the threshold Pr [N]."""
    return (pc_expr - pr) / c1


@njit(cache=True, error_model="numpy")
def coulomb_sign(v, veps):
    """tanh(v / veps), the regularised sign of a Coulomb friction (MODELS.md §1), as (1 − e) / (1 + e) with
    e = exp(−2 |v| / veps): one exp instead of libm's tanh (which goes through the slower expm1).  Within a few 1e-16
    of tanh (absolute), odd, exactly 0 at v = 0 and exactly ± 1 from |v| / veps ≥ 18.72; from V_ONE on ± 1 without the
    exp, whose underflow far out is libm's slow path."""
    a = abs(v / veps)
    if a >= V_ONE:
        return math.copysign(1.0, v)
    e = math.exp(-2.0 * a)
    return math.copysign((1.0 - e) / (1.0 + e), v)
