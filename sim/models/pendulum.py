"""Impact pendulum in a moving cart (MODELS.md §3, seed 001, Aguiar & Weber 2012).

States y = [theta, theta_dot, W, xh, vh]: hammer angle relative to the cart [rad], its rate [rad/s], the
work done by the prescribed cart motion [J] and the hidden states: the load-path mode along the hammer's tangent
(discrepancy ``load_path_mode``), the load cell's worn depth (``contact_wear``) or the contact's peak penetration
(``contact_unloading``) in xh; at rest while off.
Phases: 0 free swing, 1 contact with the load cell.

Equation of motion (MODELS.md §3)::

    θ̈ = (A0 Ω² / l) cos θ sin Ωt − (g / l) sin θ − 2 ζ ω0 θ̇ − Fi cos θ / (m l),   ω0 = √(g/l)
    δ = l sin θ − gap,  δ̇ = l θ̇ cos θ,  Fi = ki (1 + α max(δ̇, 0)) δ + ci δ̇   (in contact only)

Contact follows the two-indicator rule (MODELS.md §1a/§3): the hammer is in contact exactly when
δ ≥ 0 **and** the force expression is > 0; both are switching surfaces, combined into one continuous
guard ``min(δ, Fi/ki)`` (metres), so contact ends when Fi falls to zero (Fi is never negative) and
may resume while the hammer is still past the load cell.

Impacting mass: the hammer, absolute displacement x = l sin θ + A0 sin Ωt (observed acceleration is
its second derivative).  Work: W' = m l A0 Ω² sin(Ωt) cos θ θ̇ (power of the cart's inertial forcing).
The pendulum does not progress (observed progression 0).

Effects (MODELS.md §6): ``rate_stiffening`` α [s/m] (0 = off); ``sensor_lowpass`` fc [Hz] on the recorded
acceleration (``sim.models.sensor``).
Discrepancy terms (sim.models.discrepancy; off at 0): the contact terms join Fi (and its indicator), as does
contact_exponent's shift of the elastic part's δ; contact_drift moves the load cell to x_c = gap + a t
(δ = l sin θ − x_c, δ̇ = l θ̇ cos θ − a); contact_wear wears the load cell's face by s,
ṡ = k_w Fi max(δ̇, 0) (δ = l sin θ − x_c − s, the law's rate still l θ̇ cos θ − a); contact_unloading lowers the
elastic part below the contact's peak penetration δ_m to ki δ_m (δ/δ_m)^(1+s_u); support_friction is the pivot's
dry friction, a tangential force μ tanh(l θ̇ / v_ε) on the hammer (a torque μ l), θ̈ −= μ tanh(l θ̇ / v_ε) / (m l);
tool_quadratic_drag is a tangential force −c (l θ̇)|l θ̇| on the hammer, θ̈ −= c l θ̇|θ̇| / m; load_path_mode's
hidden mass pulls tangentially at the hammer, θ̈ += f / (m l), and shares the hammer's tangential acceleration
l θ̈ − A0 Ω² sin Ωt cos θ + g sin θ (the cart's and gravity's tangential parts, which act on it as on the hammer).
"""
from __future__ import annotations

import math

import numpy as np
from sim.jit import njit  # numba is imported on first use (sim/jit.py)

from sim.integrator import two_indicator_guard, two_indicator_phase
from sim.models.base import SynthRig, FitBound, ModelSpec, Param
from sim.models.discrepancy import (DRIFT_RATE, EXPONENT_REF, EXPONENT_SHIFT, MODE_PARAMS, MODE_STATES, SUPPORT_FORCE,
                                    SUPPORT_VEPS, UNLOADING_SHIFT, WEAR_RATE, WEAR_RUN, contact_extra,
                                    discrepancy_params, drift_bounds, drift_params, drifted, exponent_bounds,
                                    exponent_params, mode_accel, mode_bounds, mode_force, peak_rate, shaped,
                                    hidden_state, support_bounds, support_params, terms_at, tool_loss, unloaded,
                                    unloading_bounds, unloading_params, vocabulary_at, wear_bounds, wear_coef,
                                    wear_params, wear_speed)
from sim.models.effects import effect_params
from sim.models.param import index_of
from sim.models.contact import kelvin_voigt, released_force
from sim.models.sensor import sensor_lowpass
from sim.models.terms import guide_friction, rate_stiffened

# parameter vector layout
MASS, LEN, A0, KI, CI, ZETA, GAP, FREQ, GRAV, MCART = range(10)   # then the effects' parameters (PARAMS)
ITH, IOM, IW, IXH, IVH = range(5)
NY = 5
N_BOUNDED = 2
# the kernel checks N_GUARDS guards, as many as `guards` fills (the two-indicator contact)
N_GUARDS = 1
GUARD_STATES = (ITH, IOM, IXH)   # the states the guards read (θ, θ̇; the worn depth or peak penetration)


# sin θ, cos θ and sin Ωt are libm calls, the largest cost of this model's evaluations: each is computed once per
# evaluation and passed on


@njit(cache=True, error_model="numpy")
def _force_at(ki, alpha, ci, d, dd, dc, s, dref, dm, su):
    """Spring–dashpot force expression ki (1 + α max(δ̇,0)) δ + ci δ̇ [N] (unclamped), from scalars, with the
    discrepancy contact terms (dc: the vocabulary's coefficients), the contact exponent's shift s on the elastic
    part's δ (reference penetration dref [m]) and the unloading curve's shift su below the contact's peak
    penetration dm [m] (sim.models.discrepancy)."""
    e = unloaded(shaped(d, s, dref), shaped(dm, s, dref), d, dm, su)
    return kelvin_voigt(rate_stiffened(ki, alpha, dd), ci, e, dd) + contact_extra(dc, d, dd)


@njit(cache=True, inline="always")
def _delta(t, y, p, s, c):
    """Penetration δ = l sin θ − x_c − s_w [m] and its rate δ̇ = l θ̇ cos θ − a [m/s] (s, c = sin θ, cos θ; the load
    cell's face at x_c = gap + a t, a the contact drift's rate, worn by s_w, the contact wear's depth: the law's rate
    stays the approach rate, sim.models.discrepancy; each 0 unless its discrepancy is on)."""
    a = p[IDRIFT]
    return p[LEN] * s - drifted(p[GAP], a, t) - hidden_state(p[IWEAR], y[IXH]), p[LEN] * y[IOM] * c - a


@njit(cache=True, inline="always")
def _force_expr(t, y, p, s, c):
    """``_force_at`` of the state (s, c = sin θ, cos θ) [N], the penetration δ [m], its rate δ̇ [m/s] and the contact's
    peak penetration δ_m [m] (0 unless the unloading curve is on)."""
    d, dd = _delta(t, y, p, s, c)
    su = p[IUNL]
    dm = hidden_state(su, y[IXH])
    return _force_at(p[KI], p[ALPHA], p[CI], d, dd, terms_at(p, DISC), p[IEXP], p[IEXP_REF], dm, su), d, dd, dm


@njit(cache=True, inline="always")
def _thdd(y, p, fi, s, c, sin_wt, fm):
    om = 2.0 * math.pi * p[FREQ]
    w0 = math.sqrt(p[GRAV] / p[LEN])
    return (p[A0] * om * om / p[LEN] * c * sin_wt - p[GRAV] / p[LEN] * s
            - 2.0 * p[ZETA] * w0 * y[IOM] - fi * c / (p[MASS] * p[LEN])
            - (tool_loss(terms_at(p, DISC), p[LEN] * y[IOM]) + guide_friction(p[ISUP], p[LEN] * y[IOM], p[ISUP_EPS]))
            / (p[MASS] * p[LEN]) + fm / (p[MASS] * p[LEN]))


@njit(cache=True, inline="always")
def _rhs_at(t, y, ph, p, dy, s, c, sin_wt):
    """Fill dy given s, c = sin θ, cos θ and sin Ωt; returns the contact force expression fi [N] (0 out of contact)."""
    # before the branch: a branch that splits an array's live range costs numba a reference-count increment and
    # decrement per array (a few flops cost less)
    fe, d, dd, dm = _force_expr(t, y, p, s, c)
    fi = fe if ph > 0 else 0.0
    om = 2.0 * math.pi * p[FREQ]
    ratio = p[IMODE]
    fm = mode_force(ratio, p[IMODE + 1], p[IMODE + 2], p[MASS], y[IXH], y[IVH])
    thdd = _thdd(y, p, fi, s, c, sin_wt, fm)
    dy[ITH] = y[IOM]
    dy[IOM] = thdd
    dy[IW] = p[MASS] * p[LEN] * p[A0] * om * om * sin_wt * c * y[IOM]
    dy[IXH] = (y[IVH] + wear_speed(wear_coef(p[IWEAR], p[IWEAR_RUN], p[FREQ], t), fi, dd)
               + peak_rate(p[IUNL], ph, d, dm, dd))
    dy[IVH] = mode_accel(ratio, p[MASS], fm, p[LEN] * thdd - p[A0] * om * om * sin_wt * c + p[GRAV] * s)
    return fi


@njit(cache=True)
def rhs(t, y, z, ph, p, dy):
    om = 2.0 * math.pi * p[FREQ]
    _rhs_at(t, y, ph, p, dy, math.sin(y[ITH]), math.cos(y[ITH]), math.sin(om * t))


@njit(cache=True)
def guards(t, y, z, ph, p, g):
    th = y[ITH]
    om_ = y[IOM]
    lenp, gap, ki, ci, alpha = p[LEN], p[GAP], p[KI], p[CI], p[ALPHA]     # read before the branches (``_rhs_at``)
    dc = terms_at(p, DISC)
    sh, dref = p[IEXP], p[IEXP_REF]
    if ph == 0 and th > -math.pi and lenp * th < gap:
        # free flight, certainly short of the stop: for θ ∈ (−π, 0) sin θ < 0, and for θ ≥ 0 sin θ ≤ θ, so
        # δ = l sin θ − gap < 0 and the guard min(δ, ·) is negative.  l θ − gap [m] is then returned instead of the
        # exact guard (same sign, no sin/cos: most free-flight guard checks, 4 per step, cost no libm call; the
        # exact guard is evaluated from l θ ≥ gap on, where a crossing can be, so every switch is still found and
        # located within event_tol).
        # The bound stands for both indicators of the shared two-indicator guard (and for a drifting or worn contact,
        # which only recedes: a ≥ 0, ṡ_w ≥ 0)
        d = lenp * th - gap
        ind = d
    else:
        d, dd = _delta(t, y, p, math.sin(th), math.cos(th))
        su = p[IUNL]
        ind = _force_at(ki, alpha, ci, d, dd, dc, sh, dref, hidden_state(su, y[IXH]), su) / ki
    two_indicator_guard(g, d, ind, ph)


@njit(cache=True)
def on_event(t, y, z, ph, p, k):
    s, c = math.sin(y[ITH]), math.cos(y[ITH])
    fe, d, _, _ = _force_expr(t, y, p, s, c)
    new = two_indicator_phase(d, fe)
    if p[IUNL] != 0.0 and new > ph:     # each contact's peak penetration starts afresh (the surface recovered);
        y[IXH] = max(d, 0.0)            # kept through the flight, so the indicator stays continuous at release
    return new


@njit(cache=True)
def observe(t, y, z, ph, p, obs, dy):
    om = 2.0 * math.pi * p[FREQ]
    s, c = math.sin(y[ITH]), math.cos(y[ITH])
    sin_wt = math.sin(om * t)
    fi = _rhs_at(t, y, ph, p, dy, s, c, sin_wt)      # rhs, with the sines and cosines computed here once
    obs[0] = released_force(fi, ph)
    obs[1] = p[LEN] * (dy[IOM] * c - y[IOM] * y[IOM] * s) - p[A0] * om * om * sin_wt
    obs[2] = p[LEN] * s + p[A0] * sin_wt
    obs[3] = 0.0
    obs[4] = p[LEN] * y[IOM] * c + p[A0] * om * math.cos(om * t)


@njit(cache=True)
def bounded(t, y, z, ph, p, b):
    b[0] = y[ITH]
    b[1] = y[IOM]


def _initial(p: np.ndarray):
    """Rest, hanging vertically (θ = 0); with gap 0 the hammer just touches the load cell."""
    return np.zeros(NY), np.zeros(1), 0


def _atol(p: np.ndarray) -> np.ndarray:
    """Typical magnitudes: 1 mm of hammer travel (θ ≈ 1e-3/l), its rate at Ω, and the work of the
    inertial force m A0 Ω² over 1 mm (the same scales as tests/reference_solutions.py)."""
    xs = 1e-3
    om = 2.0 * math.pi * p[FREQ]
    fsc = max(p[MASS] * p[A0] * om * om, 1e-3)
    return np.array([xs / p[LEN], xs * om / p[LEN], fsc * xs, xs, xs * om])


EFFECTS = ("rate_stiffening", "sensor_lowpass")
"""The MODELS.md §6 effects of the pendulum (sim.models.effects): their parameters end PARAMS."""

PARAMS = (
    Param("m", 0.298, "kg", "hammer mass", positive=True),
    Param("l", 0.075, "m", "wire length (pendulum length)", positive=True),
    Param("amplitude_m", 0.89e-3, "m", "cart displacement amplitude A0 (x_cart = A0 sin Ωt)", nonnegative=True),
    Param("ki", 5.5e6, "N/m", "load-cell contact stiffness", positive=True),
    Param("ci", 1.2e3, "N s/m", "load-cell contact damping", nonnegative=True),
    Param("zeta", 0.005, "-", "light free-swing damping ratio (0 in the seed; 0.5 % so free swings settle)",
          nonnegative=True),
    Param("gap_m", 0.0, "m", "gap between the hanging hammer and the load cell", nonnegative=True),
    Param("frequency_hz", 3.75, "Hz", "cart forcing frequency f", positive=True),
    Param("g", 9.81, "m/s^2", "gravitational acceleration", positive=True),
    Param("M", 5.38, "kg", "cart mass (informational: the cart motion is prescribed)", positive=True),
    *effect_params(EFFECTS, {"rate_stiffening": "the load cell's ki, δ̇ the hammer's penetration rate",
                             "sensor_lowpass": "the hammer's recorded acceleration"}),
    *discrepancy_params({"contact": "in the load cell's expression, δ = l sin θ − gap, δ̇ = l θ̇ cos θ",
                         "tool": "tangential on the hammer, v = l θ̇"}),
    *exponent_params(1.7e-5, "the load cell's ki δ, δ = l sin θ − gap"),
    *drift_params("the load cell's position gap, δ = l sin θ − x_c"),
    *support_params("the pivot, a torque μ l: tangential on the hammer, v = l θ̇"),
    *wear_params("the load cell's face, δ = l sin θ − gap − s"),
    *unloading_params("the load cell's ki δ, δ = l sin θ − gap"),
)
(ALPHA,) = index_of(PARAMS, "alpha")
DISC = vocabulary_at(PARAMS)   # the discrepancy terms' coefficients from here on (terms_at)
IMODE = index_of(PARAMS, *MODE_PARAMS)[0]   # then its frequency and damping ratio
IWEAR, IWEAR_RUN = index_of(PARAMS, WEAR_RATE, WEAR_RUN)   # the wear and its k_w N before a record
(IUNL,) = index_of(PARAMS, UNLOADING_SHIFT)
HIDDEN_SWITCHES = (IMODE, IWEAR, IUNL)   # the parameters that switch on a hidden-state user (sim.compiled)
IEXP, IEXP_REF = index_of(PARAMS, EXPONENT_SHIFT, EXPONENT_REF)   # the contact exponent's shift and δ_r
(IDRIFT,) = index_of(PARAMS, DRIFT_RATE)
ISUP, ISUP_EPS = index_of(PARAMS, SUPPORT_FORCE, SUPPORT_VEPS)

STATES = ("theta", "theta_dot", "work", *MODE_STATES)
BOUNDED = ("theta", "theta_dot")

PRESETS = {
    # Seed 001 (Aguiar & Weber 2012) Table 2 gaps; every other value is the seed's (MODELS.md §3).
    "seed-001": {},
    "gap-0": {"gap_m": 0.0},
    "gap-1.0mm": {"gap_m": 1.0e-3},
    "gap-2.4mm": {"gap_m": 2.4e-3},
}

# A free swing decays with time constant 1/(ζ ω0) ≈ 17.5 s (~65 cycles at 3.75 Hz): non-impacting runs
# need several hundred cycles to settle to settle_tol.  min_transient 60 lets impacting runs (which lose
# energy at every impact and settle in tens of cycles) stop early; max_transient 600 caps the slow
# free-swing ones (a non-impacting run at the cap is still labelled no_contact from its window).
# Step cap 0.03 T: the free swing is smooth, so the cap alone limits its steps (``python -m bench.step_budget``);
# 0.03 is the largest cap that keeps the labels as accurate as a finer one (``python -m bench.step_cap``).
SEED_RANGES = {"frequency_hz": (1.0, 10.0), "gap_m": (0.0, 3.0e-3), "amplitude_m": (0.2e-3, 1.5e-3)}
"""Seed 001's ranges (Figs. 13-14: 1-10 Hz, gaps up to 3 mm, cart amplitudes around its 0.89 mm): the map axes, and
the ranges the model is validated on (its Table 2 resonances and an independent solution, MODELS.md §3)."""

DEFAULT_SETTINGS = {"min_transient": 60, "max_transient": 600, "window": 32, "max_step_frac": 0.03}

SPEC = ModelSpec(
    name="pendulum",
    description="impact pendulum in a moving cart, spring-dashpot load cell (MODELS.md §3, seed 001)",
    params=PARAMS,
    states=STATES,
    z_names=(),
    bounded=BOUNDED,
    funcs=(rhs, guards, on_event, observe, bounded),
    n_bounded=N_BOUNDED,
    initial=_initial,
    atol=_atol,
    effects=EFFECTS,
    postprocess=sensor_lowpass,
    needs_history=lambda values: values.get("fc", 0.0) > 0.0,
    impacting_mass="hammer m (absolute x = l sin θ + A0 sin Ωt)",
    progression="none (the pendulum does not progress)",
    presets=PRESETS,
    default_settings=DEFAULT_SETTINGS,
    # MODELS.md §6: the load cell (ki, ci) and the free-swing damping zeta; one decade either side of the defaults.
    calibratable=(FitBound("ki", 5.5e5, 5.5e7, "N/m"), FitBound("ci", 1.2e2, 1.2e4, "N s/m"),
                  FitBound("zeta", 5e-4, 5e-2, "-")),
    # contact rate of the hammer ~0.1-0.5 m/s: alpha ~ 0.1-10 s/m changes the contact stiffness by 1-100 %
    effect_bounds={"alpha": FitBound("alpha", 1e-2, 100.0, "s/m"), "fc": FitBound("fc", 5.0, 2000.0, "Hz")},
    # the 3-8 Hz impacts are resolved by their first ~25 harmonics
    diagnose_max_harmonic_hz=100.0,
    # candidates start from the calibrated base and from the rig's nominal values: a sensor low-pass or a
    # stiffening contact is absorbed into ki and the damping so far that the calibrated base is a false valley
    diagnose_fit={"candidate_starts": 2, "max_nfev": 10},
    # no undeclared DAQ chain by default: its delays per channel take up rate stiffening and the accelerometer's
    # own low-pass on this rig's slow, harmonic-rich records (docs/diagnose.md)
    diagnose_chain=False,
    # discrepancy terms: penetration ~ 1.7e-5 m, hammer speed ~0.3 m/s; tool_viscous is left out: on l θ̇ it is
    # the calibratable free-swing damping zeta exactly
    discrepancy=("contact_quadratic", "contact_cubic", "contact_rate_product", "tool_quadratic_drag", *MODE_PARAMS,
                 EXPONENT_SHIFT, DRIFT_RATE, SUPPORT_FORCE, WEAR_RATE, WEAR_RUN, UNLOADING_SHIFT),
    # (bounds measured at the default point: each probe strength moves the peak force by ~3-8 %)
    # the hidden mode from below the cart forcing (2.5-7.5 Hz) to well above the swing's harmonics; the contact's
    # drift from ~1 µm to ~0.5 mm over a 5 s run, its wear from ~5 % of the penetration to ~30x it over such a run
    # (~0.014 J pressed in); the pivot's friction (as a force at the hammer) from ~1 % to ~2x
    # the cart's inertial forcing m A0 Ω² ≈ 0.15 N
    discrepancy_bounds={**mode_bounds(2.0, 200.0), **exponent_bounds(), **drift_bounds(2e-7, 1e-4),
                        **support_bounds(1e-3, 0.3), **wear_bounds(5e-5, 3e-2),
                        **unloading_bounds(),
                        "contact_quadratic": FitBound("contact_quadratic", 1e10, 5e12, "N/m^2"),
                        "contact_cubic": FitBound("contact_cubic", 1e15, 3e17, "N/m^3"),
                        "contact_rate_product": FitBound("contact_rate_product", 3e6, 3e9, "N s/m^2"),
                        "tool_quadratic_drag": FitBound("tool_quadratic_drag", 0.2, 100.0, "N s^2/m^2")},
    # impact-pattern maps over the seed's ranges (seed 001 Figs. 13-14: 1-10 Hz, gaps up to 3 mm)
    map_kind="pattern",
    map_ranges=SEED_RANGES,
    validated={"": SEED_RANGES},
    min_work_per_m=lambda v: 0.0,     # passive hammer, no progression: the cart's work covers the losses
    # `vibro synth` (seed 001): around the z = 1/1 and 1/2 resonances, gaps 0 and 1 mm, 10 kHz DAQ; contact rate
    # ~0.3 m/s, so alpha 1 s/m is +30 % contact stiffness; mount resonance 40 Hz, inside the diagnosed harmonics
    synth=SynthRig(frequencies_hz=(2.5, 3.0, 3.5, 3.75, 4.5, 5.5, 6.5, 7.25), level_name="gap_m", levels=(0.0, 1.0e-3),
                   fixed={"amplitude_m": 0.89e-3}, fs_hz=10000.0, cycles=12.4,
                   effect_strengths={"rate_stiffening": {"alpha": 1.0}, "sensor_lowpass": {"fc": 100.0}}, mount_hz=40.0),
)
