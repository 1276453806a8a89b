"""Indenter rig: three masses, metal or sandstone sample (MODELS.md §1), with the §6 effects.

States y = [x1, v1, x2, v2, x3, v3, Fem, W, xh, vh]: armature+indenter, shaker body, piston head,
electromagnetic force (a state only with `shaker_coil`), excitation work, the hidden load-path mode relative to
m1 (discrepancy ``load_path_mode``; at rest while off).
Discrete states z = [xp, xf] (sandstone crater floor and unloading end point).
Phases: metal 0 free / 1 contact; sandstone 0 free / 1 loading / 2 unloading.

Every phase is linear where the seal friction is ± pm (exactly from |v2| = 20 v_eps, to rtol pm / 100 from a V v_eps
set by the tolerance, ``sim.exact.indenter.v_band``): ``sim/exact/indenter.py`` propagates it exactly there and the
DOPRI5 steps run across the shaker body's velocity reversals (``method`` "auto", "exact").

Effects (MODELS.md §6; all off at their default 0):
  shaker_coil (tau [s], beta [N s/m]), rate_stiffening (alpha [s/m]), guide_friction (mu [N]),
  tip_blunting (gamma [-], sandstone), suspension_hardening (kappa [1/m^2]),
  sensor_lowpass (fc [Hz]: applied to the recorded acceleration, ``sim.models.sensor``).

Discrepancy terms (sim.models.discrepancy; off at 0): the metal's Kelvin–Voigt expression gains the contact terms
(δ = x1 − G, δ̇ = ẋ1, also in its force indicator), contact_exponent's shift on its elastic part's δ and
contact_drift's moving face x_c = G + a t (δ = x1 − x_c, δ̇ = ẋ1 − a); both
samples take the tool terms on m1 (v = ẋ1), the load_path_mode's hidden mass on m1 and link_power_loss
c (|v|/v_r)^p sgn v in the armature's flexure (v = ẋ1 − ẋ2), and support_friction μ tanh(ẋ2 / v_ε) on the shaker
body m2 (its carriages on the ground); stop_mode puts the metal sample on a mount, ms = ratio m1 on a spring and
damper to the ground (the hidden states: its xs, ẋs; δ = x1 − G − xs, ms ẍs = Fr − ks xs − cs ẋs).
"""
from __future__ import annotations

import math

import numpy as np
from sim.jit import njit  # numba is imported on first use (sim/jit.py)

from sim.integrator import two_indicator_guard, two_indicator_phase
from sim.models.base import FitBound, ModelSpec, Param, SynthRig
from sim.models.discrepancy import (DRIFT_RATE, EXPONENT_REF, EXPONENT_SHIFT, LINK_PARAMS, LINK_REF, MODE_PARAMS,
                                    MODE_STATES, SUPPORT_FORCE, SUPPORT_VEPS, contact_extra, discrepancy_params,
                                    drift_bounds, drift_params, drifted, exponent_bounds, exponent_params, link_bounds,
                                    link_loss, link_params, mode_accel, mode_bounds, mode_force, shaped,
                                    site_mode_params, stop_accel, hidden_state, support_bounds, support_params,
                                    terms_at, tool_loss, vocabulary_at, wear_bounds, wear_coef, wear_params,
                                    wear_speed, peak_rate, unloaded, unloading_bounds, unloading_params,
                                    STOP_MODE, STOP_MODE_PARAMS, UNLOADING_SHIFT, WEAR_RATE, WEAR_RUN)
from sim.models.effects import effect_params
from sim.models.param import index_of
from sim.models.contact import branch_depth, branch_force, coulomb_sign, kelvin_voigt, released_force
from sim.models.sensor import sensor_lowpass
from sim.models.terms import coil_force, guide_friction, hardened_spring, rate_stiffened, tip_blunted

(M1, M2, M3, K2, C2, K3, C3, PM, GAP, FP, FA, FREQ, VEPS, K1, C1, KL, KU, NL, NU) = range(19)   # then the effects'

IX1, IV1, IX2, IV2, IX3, IV3, IFEM, IW, IXH, IVH = range(10)
NY = 10
IXP, IXF = 0, 1
N_BOUNDED = 4
# the kernel checks N_GUARDS guards, as many as `guards` fills (sandstone loading and unloading have two; metal one)
N_GUARDS = 2
GUARD_STATES = (IX1, IV1, IXH, IVH)   # the states the guards read (x1, v1; the metal's mount xs, ẋs or worn depth):
                                      # the only ones interpolated for them


def air_damping(fa_n: float, f_hz: float) -> float:
    """Equivalent air damping c3 [N s/m] of the pneumatic cylinder (seed Eq. 6 as restated
    in MODELS.md §1: c3 = 78.6 π² Fa / f)."""
    return 78.6 * math.pi ** 2 * fa_n / f_hz


def pneumatic_force(p_bar: float, d_m: float) -> float:
    """Pneumatic force Fp [N] = (101325/4) P π D² (seed Eq. 5)."""
    return (101325.0 / 4.0) * p_bar * math.pi * d_m ** 2


# ----------------------------------------------------------------------------- shared body
@njit(cache=True, inline="always")
def _body(t, y, p, fr, dy):
    """Equations of motion given the sample's reaction fr on m1.

    Every element of y and p is read first, into scalars, and dy is written last, unconditionally: the branches on
    the effects (on or off) then split no array's live range, and numba's reference-count pruning removes the
    increments and decrements of the arrays of an inlined call (a pair per array on every stage of a step
    otherwise).  The expressions are those of the equations, term for term."""
    x1 = y[IX1]
    v1 = y[IV1]
    x2 = y[IX2]
    v2 = y[IV2]
    x3 = y[IX3]
    v3 = y[IV3]
    fem_y = y[IFEM]
    m1 = p[M1]
    m2 = p[M2]
    m3 = p[M3]
    k2 = p[K2]
    c2 = p[C2]
    k3 = p[K3]
    c3 = p[C3]
    pm = p[PM]
    fp = p[FP]
    fa = p[FA]
    veps = p[VEPS]
    tau = p[TAU]
    beta = p[BETA]
    mu = p[MU]
    kappa = p[KAPPA]
    dc = terms_at(p, DISC)
    ratio = p[IMODE]
    fm = mode_force(ratio, p[IMODE + 1], p[IMODE + 2], m1, y[IXH], y[IVH])
    vh = y[IVH]
    om = 2.0 * math.pi * p[FREQ]
    phi1 = x1 - x2
    dphi1 = v1 - v2
    phi2 = x2 - x3
    dphi2 = v2 - v3
    fem, dfem = coil_force(fa * math.sin(om * t), beta, dphi1, tau, fem_y)
    inner = (c2 * dphi1 + hardened_spring(k2, phi1, kappa) + guide_friction(mu, dphi1, veps)
             + link_loss(p[ILINK], p[ILINK_EXP], p[ILINK_REF], dphi1))
    dy[IX1] = v1
    a1 = (fem - inner - fr - tool_loss(dc, v1) + fm) / m1
    dy[IV1] = a1
    dy[IX2] = v2
    dy[IV2] = (-fem + inner - c3 * dphi2 - k3 * phi2 - guide_friction(p[ISUP], v2, p[ISUP_EPS])) / m2
    dy[IX3] = v3
    dy[IV3] = (fp + c3 * dphi2 + k3 * phi2 - pm * coulomb_sign(v2, veps)) / m3
    dy[IFEM] = dfem
    dy[IW] = fem * dphi1
    dy[IXH] = vh
    dy[IVH] = mode_accel(ratio, m1, fm, a1) + stop_accel(p[ISTOP], p[ISTOP + 1], p[ISTOP + 2], m1, fr, y[IXH], vh)


# ----------------------------------------------------------------------------- metal sample
@njit(cache=True, inline="always")
def _metal_delta(t, y, p):
    """The metal's penetration δ = x1 − x_c − xs − s_w [m] (x_c = G + a t, a the contact drift's rate; xs the sample's
    mount; s_w the face's worn depth; each 0 unless its discrepancy is on)."""
    return y[IX1] - drifted(p[GAP], p[IDRIFT], t) - hidden_state(p[ISTOP], y[IXH]) - hidden_state(p[IWEAR], y[IXH])


@njit(cache=True, inline="always")
def _metal_contact(t, y, p):
    """Kelvin–Voigt force expression of the metal sample [N] (unclamped), with rate stiffening and the discrepancy
    contact terms (δ = x1 − x_c − xs − s_w, δ̇ = ẋ1 − a − ẋs: the wear leaves the law's rate the approach rate), and
    the penetration δ [m] and the contact's peak penetration δ_m [m] (0 unless the unloading curve is on)."""
    d = _metal_delta(t, y, p)
    v1 = y[IV1] - p[IDRIFT] - hidden_state(p[ISTOP], y[IVH])
    su = p[IUNL]
    dm = hidden_state(su, y[IXH])
    e = unloaded(shaped(d, p[IEXP], p[IEXP_REF]), shaped(dm, p[IEXP], p[IEXP_REF]), d, dm, su)
    fe = kelvin_voigt(rate_stiffened(p[K1], p[ALPHA], v1), p[C1], e, v1) + contact_extra(terms_at(p, DISC), d, v1)
    return fe, d, dm


@njit(cache=True, inline="always")
def _metal_rhs_at(t, y, ph, p, dy):
    """The equations of motion with the metal's contact; returns its force expression [N] (``metal_observe``)."""
    fe, d, dm = _metal_contact(t, y, p)          # read before the branch (``_body``)
    fr = fe if ph > 0 else 0.0
    _body(t, y, p, fr, dy)
    v = y[IV1] - p[IDRIFT]
    dy[IXH] += wear_speed(wear_coef(p[IWEAR], p[IWEAR_RUN], p[FREQ], t), fr, v) + peak_rate(p[IUNL], ph, d, dm, v)
    return fe


@njit(cache=True)
def metal_rhs(t, y, z, ph, p, dy):
    _metal_rhs_at(t, y, ph, p, dy)


@njit(cache=True)
def metal_guards(t, y, z, ph, p, g):
    fe, d, _ = _metal_contact(t, y, p)
    two_indicator_guard(g, d, fe * 1e-7, ph)


@njit(cache=True)
def metal_on_event(t, y, z, ph, p, k):
    fe, d, _ = _metal_contact(t, y, p)
    new = two_indicator_phase(d, fe)
    if p[IUNL] != 0.0 and new > ph:     # each contact's peak penetration starts afresh (the surface recovered);
        y[IXH] = max(d, 0.0)            # kept through the flight, so the indicator stays continuous at release
    return new


@njit(cache=True)
def metal_observe(t, y, z, ph, p, obs, dy):
    fe = _metal_rhs_at(t, y, ph, p, dy)     # the force expression, computed once with the derivatives
    obs[0] = released_force(fe, ph)
    obs[1] = dy[IV1]
    obs[2] = y[IX1]
    obs[3] = 0.0
    obs[4] = y[IV1]


@njit(cache=True)
def metal_bounded(t, y, z, ph, p, b):
    b[0] = y[IX1]
    b[1] = y[IV1]
    b[2] = y[IX2]
    b[3] = y[IV2]


# ----------------------------------------------------------------------------- sandstone sample
@njit(cache=True, error_model="numpy")
def _branch_k(k, gamma, xp, alpha, v1):
    """Branch stiffness k (1 + γ xp / 1 mm)(1 + α max(ẋ1, 0)): tip blunting (xp: the crater floor at the current
    impact's start) and rate stiffening, from scalars."""
    return rate_stiffened(tip_blunted(k, gamma, xp), alpha, v1)


@njit(cache=True, inline="always")
def _load_force(y, z, p):
    """Loading branch [N] of the state ``y`` (penetration below the crater floor xp)."""
    return branch_force(_branch_k(p[KL], p[GAMMA], z[IXP], p[ALPHA], y[IV1]), y[IX1] - p[GAP] - z[IXP], p[NL])


@njit(cache=True, inline="always")
def _sand_force(y, z, ph, p):
    """Sample reaction [N] on phase ph: loading (1), unloading (2) or none.

    Written on local scalars read before the branches (``_body``): an inlined helper that takes arrays costs numba
    a reference-count increment and decrement per array where its branches split the code (the expressions are those
    of ``_load_force`` and of its unloading twin)."""
    d = y[IX1] - p[GAP]
    xp = z[IXP]
    v1 = y[IV1]
    gamma = p[GAMMA]
    alpha = p[ALPHA]
    dl = d - xp
    du = d - z[IXF]
    kl = p[KL]
    ku = p[KU]
    nl = p[NL]
    nu = p[NU]
    if ph == 0:
        return 0.0
    k, depth, n = (kl, dl, nl) if ph == 1 else (ku, du, nu)
    return branch_force(_branch_k(k, gamma, xp, alpha, v1), depth, n)


@njit(cache=True, error_model="numpy")
def _xp_unloading_at(e, v1, xp, xf, kl, ku, nl, nu, gamma, alpha):
    """Crater floor [m] that keeps the loading branch through the current (depth, force) point, from scalars: e = x1 − G,
    v1 = ẋ1, the crater floor xp and unloading end point xf and the branches' parameters."""
    f = branch_force(_branch_k(ku, gamma, xp, alpha, v1), e - xf, nu)
    return e - branch_depth(f, _branch_k(kl, gamma, xp, alpha, v1), nl)


@njit(cache=True, inline="always")
def _xp_unloading(y, z, p):
    """``_xp_unloading_at`` of the state."""
    return _xp_unloading_at(y[IX1] - p[GAP], y[IV1], z[IXP], z[IXF], p[KL], p[KU], p[NL], p[NU], p[GAMMA], p[ALPHA])


@njit(cache=True, inline="always")
def _floor(y, z, ph, p):
    """The crater floor [m] of phase ph: z's xp, or in unloading the floor through the current point (every element
    read before the branch, ``_body``)."""
    e = y[IX1] - p[GAP]
    v1 = y[IV1]
    xp = z[IXP]
    xf = z[IXF]
    kl = p[KL]
    ku = p[KU]
    nl = p[NL]
    nu = p[NU]
    gamma = p[GAMMA]
    alpha = p[ALPHA]
    if ph == 2:
        return _xp_unloading_at(e, v1, xp, xf, kl, ku, nl, nu, gamma, alpha)
    return xp


@njit(cache=True, inline="always")
def _sand_rhs_at(t, y, z, ph, p, dy):
    """The equations of motion with the sandstone's reaction; returns the reaction [N] (``sand_observe``)."""
    fr = _sand_force(y, z, ph, p)
    _body(t, y, p, fr, dy)
    return fr


@njit(cache=True)
def sand_rhs(t, y, z, ph, p, dy):
    _sand_rhs_at(t, y, z, ph, p, dy)


@njit(cache=True)
def sand_guards(t, y, z, ph, p, g):
    """The phase's guards (MODELS.md §1b), from scalars read first (see ``_body``); a phase with one guard sets the
    other to -1."""
    e = y[IX1] - p[GAP]
    v1 = y[IV1]
    xp = z[IXP]
    xf = z[IXF]
    if ph == 0:
        a = e - xp                  # reaches the crater floor
        b = -1.0
    elif ph == 1:
        a = -v1                     # loading -> unloading (velocity reverses)
        b = -(e - xp)               # safety: leaves the floor
    else:
        a = -(e - xf)               # unloading ends: no contact, xp = xf
        b = v1                      # unloading -> loading (reloads)
    g[0] = a
    g[1] = b


@njit(cache=True)
def sand_on_event(t, y, z, ph, p, k):
    if ph == 0:
        return 1 if y[IV1] >= 0.0 else 0
    if ph == 1:
        if k == 0:   # reversal: fix the end point of the unloading branch
            f = _load_force(y, z, p)
            ku = _branch_k(p[KU], p[GAMMA], z[IXP], p[ALPHA], y[IV1])
            z[IXF] = y[IX1] - p[GAP] - branch_depth(f, ku, p[NU])
            return 2
        return 0
    if k == 0:       # fully unloaded: the crater floor has moved to xf
        z[IXP] = z[IXF]
        return 0
    z[IXP] = _xp_unloading(y, z, p)
    return 1


@njit(cache=True)
def sand_observe(t, y, z, ph, p, obs, dy):
    obs[0] = _sand_rhs_at(t, y, z, ph, p, dy)      # the reaction, computed once with the derivatives
    obs[1] = dy[IV1]
    obs[2] = y[IX1]
    obs[3] = _floor(y, z, ph, p)
    obs[4] = y[IV1]


@njit(cache=True)
def sand_bounded(t, y, z, ph, p, b):
    xp = _floor(y, z, ph, p)
    b[0] = y[IX1] - xp
    b[1] = y[IV1]
    b[2] = y[IX2] - xp
    b[3] = y[IV2]


# ----------------------------------------------------------------------------- parameters
def _initial(p: np.ndarray):
    """Rest, springs unstretched, x = 0 (the assembly drifts forward under Fp to the sample)."""
    return np.zeros(NY), np.zeros(2), 0   # with G = 0 the first step's guard catches the touch


def _atol(p: np.ndarray) -> np.ndarray:
    xs = max(p[GAP], 1e-4)
    om = 2.0 * math.pi * p[FREQ]
    return np.array([xs, xs * om, xs, xs * om, xs, xs * om, max(p[FA], 1.0), max(p[FA], 1.0) * xs, xs, xs * om])


EFFECTS = ("shaker_coil", "rate_stiffening", "guide_friction", "tip_blunting", "suspension_hardening",
           "sensor_lowpass")
"""The MODELS.md §6 effects of the indenter rig (sim.models.effects): their parameters end the kernel's vector;
tip blunting needs a progressing sample (sandstone)."""

COMMON = (
    Param("m1", 3.46, "kg", "armature + load cell + indenter", positive=True),
    Param("m2", 60.0, "kg", "shaker body on carriages", positive=True),
    Param("m3", 0.5, "kg", "pneumatic piston head", positive=True),
    Param("k2", 2.30e5, "N/m", "armature suspension stiffness", positive=True),
    Param("c2", 2.30e3, "N s/m", "armature suspension damping", nonnegative=True),
    Param("k3", 2.0e4, "N/m", "air spring of the piston", positive=True),
    Param("c3", None, "N s/m", "air damping; default 78.6 π² Fa / f (sim.models.indenter.air_damping)", nonnegative=True),
    Param("pm", 20.0, "N", "seal friction, Coulomb on the shaker body's velocity", nonnegative=True),
    Param("gap_m", 1e-3, "m", "initial gap G between indenter and sample", nonnegative=True),
    Param("static_force_n", None, "N", "pneumatic force Fp; default (101325/4) P π D²", nonnegative=True),
    Param("amplitude_n", 440.0, "N", "electromagnetic force amplitude Fa (Fa sin Ωt)", nonnegative=True),
    Param("frequency_hz", 60.0, "Hz", "forcing frequency f", positive=True),
    Param("v_eps", 1e-4, "m/s", "tanh regularisation speed of the Coulomb terms", positive=True),
    Param("k1", 1.0e7, "N/m", "metal contact stiffness", positive=True),
    Param("c1", 300.0, "N s/m", "metal contact damping", nonnegative=True),
    Param("kl", 5.0e6, "N/m^nl", "sandstone loading stiffness", positive=True),
    Param("ku", 2.0e7, "N/m^nu", "sandstone unloading stiffness", positive=True),
    Param("nl", 1.0, "-", "sandstone loading exponent", positive=True),
    Param("nu", 1.0, "-", "sandstone unloading exponent", positive=True),
    *effect_params(EFFECTS, {"shaker_coil": "the force Fa sin Ωt between armature and body, Δv = ẋ1 − ẋ2",
                             "rate_stiffening": "the contact's k1 or kl, ku, δ̇ the penetration rate",
                             "guide_friction": "the armature guides, Δv = ẋ1 − ẋ2",
                             "tip_blunting": "the sandstone's kl, ku, progression xp",
                             "suspension_hardening": "the armature suspension k2, φ1 = x1 − x2",
                             "sensor_lowpass": "the armature's recorded acceleration"}),
    Param("P", 1.0, "bar", "pneumatic pressure", positive=True),
    Param("D", 0.05, "m", "piston diameter", positive=True),
    *discrepancy_params({"contact": "in the metal's Kelvin–Voigt expression, δ = x1 − G, δ̇ = ẋ1 (not the sandstone)",
                         "tool": "on m1, v = ẋ1"}),
    *exponent_params(1.4e-4, "the metal's k1 δ, δ = x1 − G (not the sandstone)"),
    *link_params(0.08, "the armature's flexure, v = ẋ1 − ẋ2"),
    *drift_params("the metal's face G, δ = x1 − x_c (not the sandstone)"),
    *support_params("the shaker body's carriages on the ground, on m2, v = ẋ2"),
    *site_mode_params(STOP_MODE, "the metal sample on a mount: ms over m1, δ = x1 − G − xs (not the sandstone)"),
    *wear_params("the metal's face, δ = x1 − G − s (not the sandstone)"),
    *unloading_params("the metal's k1 δ, δ = x1 − G (not the sandstone)"),
)
DISC = vocabulary_at(COMMON)   # the discrepancy terms' coefficients from here on (terms_at)
IMODE = index_of(COMMON, *MODE_PARAMS)[0]   # then its frequency and damping ratio
ISTOP = index_of(COMMON, *STOP_MODE_PARAMS)[0]
IWEAR, IWEAR_RUN = index_of(COMMON, WEAR_RATE, WEAR_RUN)   # the wear and its k_w N before a record
(IUNL,) = index_of(COMMON, UNLOADING_SHIFT)
HIDDEN_SWITCHES = (IMODE, ISTOP, IWEAR, IUNL)   # the parameters that switch on a hidden-state user (sim.compiled)
IEXP, IEXP_REF = index_of(COMMON, EXPONENT_SHIFT, EXPONENT_REF)   # the contact exponent's shift and δ_r
ILINK, ILINK_EXP, ILINK_REF = index_of(COMMON, *LINK_PARAMS, LINK_REF)
(IDRIFT,) = index_of(COMMON, DRIFT_RATE)
ISUP, ISUP_EPS = index_of(COMMON, SUPPORT_FORCE, SUPPORT_VEPS)
TAU, BETA, ALPHA, MU, GAMMA, KAPPA, FC = index_of(COMMON, "tau", "beta", "alpha", "mu", "gamma", "kappa", "fc")
# The kernel's parameter vector ends with the effects' parameters; P and D only feed static_force_n.


def _derive(values: dict) -> dict:
    v = dict(values)
    if v.get("c3") is None:
        v["c3"] = air_damping(v["amplitude_n"], v["frequency_hz"])
    if v.get("static_force_n") is None:
        v["static_force_n"] = pneumatic_force(v["P"], v["D"])
    return v


# discrepancy terms (sim.models.discrepancy): penetration δ ~ 1.4e-4 m under the metal's k1, armature speed ~0.3 m/s,
# m1 Ω ~ 1.3e3 N s/m at 60 Hz; lo ~ 1/20 and hi ~ 30x of a ~10 % change of the labels.  The sandstone's contact is
# its power-law branches (kl, ku, nl, nu): only the tool terms apply there.
# The hidden mode from below the forcing (30-100 Hz) to above the impacts' ~1 kHz ring.
# The link loss at the flexure's rms velocity 0.08 m/s (sandstone, 60 Hz), where its damping carries ~175 N: 1-300 N.
# The metal face's drift from ~6 µm to ~3 mm over a 0.3 s run; its wear from a recession of ~5 % of the penetration to
# ~30x it over such a run (~1.8 J pressed in).  The shaker body's carriages rub with 1-500 N (the
# guides' friction range, the body's forces are the coil's and the flexure's hundreds of N).  The metal's mount from
# a twentieth to 20x the armature's mass, from the forcing's harmonics to above the impacts' ring.
_TOOL_BOUNDS = {**mode_bounds(20.0, 3000.0), **link_bounds(1.0, 300.0), **support_bounds(1.0, 500.0),
                "tool_viscous": FitBound("tool_viscous", 5.0, 4e3, "N s/m"),
                "tool_quadratic_drag": FitBound("tool_quadratic_drag", 50.0, 1e5, "N s^2/m^2")}
_METAL_BOUNDS = {"contact_quadratic": FitBound("contact_quadratic", 3e8, 3e11, "N/m^2"),
                 "contact_cubic": FitBound("contact_cubic", 2e12, 2e15, "N/m^3"),
                 "contact_rate_product": FitBound("contact_rate_product", 1e5, 1e8, "N s/m^2"), **exponent_bounds(),
                 **drift_bounds(2e-5, 1e-2), **wear_bounds(4e-6, 2.5e-3), **unloading_bounds(),
                 **mode_bounds(50.0, 5000.0, STOP_MODE_PARAMS, (0.05, 20.0)),
                 **_TOOL_BOUNDS}


def _spec(name: str, funcs: tuple, z: tuple, bounded: tuple, presets: dict, effects: tuple[str, ...], progression: str,
          calibratable: tuple[FitBound, ...], map_kind: str, synth: SynthRig, exact: str,
          discrepancy: dict[str, FitBound]) -> ModelSpec:
    return ModelSpec(
        name=name,
        description=f"indenter rig, {name.split('-')[1]} sample (MODELS.md §1)",
        params=COMMON,
        states=("x1", "v1", "x2", "v2", "x3", "v3", "fem", "work", *MODE_STATES),
        z_names=z,
        bounded=bounded,
        funcs=funcs,
        n_bounded=N_BOUNDED,
        initial=_initial,
        atol=_atol,
        effects=effects,
        impacting_mass="m1 (armature + indenter)",
        progression=progression,
        presets=presets,
        derive=_derive,
        default_settings={"min_transient": 40, "max_transient": 600, "window": 16},
        postprocess=sensor_lowpass,
        needs_history=lambda values: values.get("fc", 0.0) > 0.0,
        calibratable=calibratable,
        map_kind=map_kind,
        map_ranges=MAP_RANGES,
        validated={"": MAP_RANGES},     # Table 1's frequencies and amplitudes, the cylinder's static forces
        # impacts ring up to ~1 kHz; the base fit can absorb a missing effect in pm, so each candidate also
        # starts at the default base: 2 starts, 15 iterations
        diagnose_max_harmonic_hz=1000.0,
        diagnose_fit={"candidate_starts": 2, "max_nfev": 15},
        synth=synth,
        # every phase linear while the seal friction is ± pm (|ẋ2| ≥ v_band(rtol) v_eps): exact there, DOPRI5 across the
        # shaker body's velocity reversals (sim/exact/indenter.py)
        exact=exact,
        discrepancy=tuple(discrepancy),
        discrepancy_bounds=discrepancy,
    )


TABLE1 = {30: 220.0, 40: 300.0, 50: 370.0, 60: 440.0, 70: 540.0, 80: 650.0, 90: 840.0, 100: 900.0}
"""Seed 000 Table 1: forcing amplitude Fa [N] used at each frequency [Hz]."""

_PRESETS = {f"table1-{f}hz": {"frequency_hz": float(f), "amplitude_n": fa} for f, fa in TABLE1.items()}
_COMMON_EFFECTS = tuple(e for e in EFFECTS if e != "tip_blunting")

# MODELS.md §1 "Calibratable": metal k1, c1, pm; sandstone kl, ku, pm (bounds: 1-2 decades around the defaults).
_METAL_FIT = (FitBound("k1", 1e6, 1e8, "N/m"), FitBound("c1", 3.0, 3e3, "N s/m"), FitBound("pm", 0.5, 300.0, "N"))
_SAND_FIT = (FitBound("kl", 5e5, 5e7, "N/m"), FitBound("ku", 1e6, 2e8, "N/m"), FitBound("pm", 0.5, 300.0, "N"))
MAP_RANGES = {"frequency_hz": (30.0, 100.0), "amplitude_n": (100.0, 900.0), "static_force_n": (50.0, 400.0)}
"""Default map axes: seed 000 Table 1 frequencies and amplitudes, static forces of the pneumatic cylinder."""

def synth_forcing(frequency_hz: float, pressure_bar: float) -> dict[str, float]:
    """The rig's forcing at a run of `vibro synth`: Table 1 amplitude [N] (interpolated in frequency [Hz]) and
    the pneumatic static force [N] of the pressure [bar] on the 50 mm piston (MODELS.md §1)."""
    fs_known = np.array(sorted(TABLE1))
    return {"amplitude_n": float(np.interp(frequency_hz, fs_known, [TABLE1[k] for k in fs_known])),
            "static_force_n": pneumatic_force(pressure_bar, 0.05)}


# `vibro synth`'s indenter rig: the Table 1 frequencies x pressures 1 and 1.5 bar, gap 1 mm, 20 kHz DAQ.  Effect
# strengths visibly change the response (order 10 % on the acceleration harmonics) without changing the impact
# regime everywhere; the mount resonance 450 Hz is inside diagnose_max_harmonic_hz.
_SYNTH_EFFECTS = {
    "shaker_coil": {"tau": 1.0e-3, "beta": 600.0},
    "rate_stiffening": {"alpha": 3.0},
    "guide_friction": {"mu": 40.0},
    "tip_blunting": {"gamma": 0.05},
    "suspension_hardening": {"kappa": 3.0e5},
    "sensor_lowpass": {"fc": 350.0},
}


def _synth(effects: dict, hertz_model: str | None) -> SynthRig:
    return SynthRig(frequencies_hz=tuple(float(f) for f in TABLE1), level_name="pressure_bar", levels=(1.0, 1.5),
                    fixed={"gap_m": 1e-3}, fs_hz=20000.0, cycles=40.0,
                    effect_strengths={e: v for e, v in _SYNTH_EFFECTS.items() if e in effects}, mount_hz=450.0,
                    forcing=synth_forcing, level_tag="bar", hertz_model=hertz_model)


SPECS = {
    "indenter-metal": _spec("indenter-metal", (metal_rhs, metal_guards, metal_on_event, metal_observe, metal_bounded),
                            (), ("x1", "v1", "x2", "v2"), _PRESETS, _COMMON_EFFECTS, "none (metal does not progress)",
                            _METAL_FIT, "pattern", _synth(_COMMON_EFFECTS, "indenter-sandstone"),
                            "sim.exact.indenter_metal", _METAL_BOUNDS),
    "indenter-sandstone": _spec("indenter-sandstone",
                                (sand_rhs, sand_guards, sand_on_event, sand_observe, sand_bounded),
                                ("xp", "xf"), ("x1-xp", "v1", "x2-xp", "v2"), _PRESETS,
                                (*_COMMON_EFFECTS, "tip_blunting"), "xp (crater floor)",
                                _SAND_FIT, "rop", _synth((*_COMMON_EFFECTS, "tip_blunting"), None),
                                "sim.exact.indenter_sandstone", _TOOL_BOUNDS),
}
