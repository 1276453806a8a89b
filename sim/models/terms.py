"""The MODELS.md §6 effect terms, each written once: scalar functions the models compose (compiled once and inlined
by LLVM, like the contact laws of ``sim.models.contact``).

Every term is exactly the base model's expression when its parameter is 0 (the effect is off), so a model
with every effect off computes the base model bit for bit.  ``sensor_lowpass`` acts on the recorded signal,
not on the equations: ``sim.models.sensor``.  A model declares which effects it has in ``ModelSpec.effects``;
``tests/sim/test_conformance.py`` then checks each of them on it.
"""
from __future__ import annotations

from sim.jit import njit  # numba is imported on first use (sim/jit.py)
from sim.models.contact import coulomb_sign

MM = 1e-3
"""The length [m] tip blunting's γ refers to (1 mm)."""


@njit(cache=True, error_model="numpy")
def coil_force(drive, beta, dv, tau, f_state):
    """shaker_coil: the exciter's force [N] and its rate [N/s].  With τ > 0 [s] the force is the state f_state
    obeying τ Ḟ + F = drive − β dv; with τ = 0 the algebraic limit drive − β dv (rate 0).  drive: the ideal
    force [N], β [N s/m], dv: the relative velocity of the two bodies the coil sits between [m/s]."""
    if tau > 0.0:
        return f_state, (drive - beta * dv - f_state) / tau
    return drive - beta * dv, 0.0


@njit(cache=True, error_model="numpy")
def rate_stiffened(k, alpha, rate):
    """rate_stiffening: contact stiffness k → k (1 + α max(δ̇, 0)) (α [s/m], penetration rate δ̇ [m/s])."""
    return k * (1.0 + alpha * max(rate, 0.0))


@njit(cache=True, error_model="numpy")
def guide_friction(mu, dv, veps):
    """guide_friction: Coulomb force μ sgn(dv) [N] on the tool's guides, regularised as ``coulomb_sign``
    (μ [N], dv and veps [m/s]); exactly 0, without the exp, when μ = 0."""
    return mu * coulomb_sign(dv, veps) if mu != 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def tip_blunted(k, gamma, progression):
    """tip_blunting: a stiffness or threshold k → k (1 + γ progression / 1 mm) (γ [-], progression [m])."""
    return k * (1.0 + gamma * progression / MM)


@njit(cache=True, error_model="numpy")
def hardened_spring(k, phi, kappa):
    """suspension_hardening: spring force k φ (1 + κ φ²) [N] (k [N/m], extension φ [m], κ [1/m²])."""
    return k * phi * (1.0 + kappa * phi * phi)
