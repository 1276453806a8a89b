"""Resonant impact device (RIMD) on a forced beam (MODELS.md §4, seed 002, Aguiar & Weber).

States y = [x1, v1, x2, v2, W, xh, vh]: main beam m1, RIMD hammer m2 (positions [m], velocities [m/s]), the
work done by the force F0 sin Ωt on m1 [J] and the hidden load-path mode relative to m2 (discrepancy
``load_path_mode``; at rest while off).  Phases: 0 free, 1 hammer in contact with the stop.

Equations (MODELS.md §4)::

    m1 ẍ1 = −c1 ẋ1 − k1 x1 + F0 sin Ωt + c2 φ̇ + S(φ)        φ = x2 − x1
    m2 ẍ2 = −c2 φ̇ − S(φ) − Fi                                S(φ) = k2 φ (1 + κ φ²)
    Fi = max(0, ki (1 + α max(ẋ2, 0)) δ^ni (1 + λi ẋ2)),     δ = x2 − gap   (Hunt–Crossley, seed Eqs. 1, 3)

Contact follows the two-indicator rule (MODELS.md §1a): contact iff δ ≥ 0 **and** 1 + λi ẋ2 > 0 (the
Hunt–Crossley force expression is positive); both are switching surfaces, combined into one continuous
guard ``min(δ, 1 mm · (1 + λi ẋ2))`` (metres).  Contact can resume while δ > 0.

Impacting mass: the hammer x2.  Work: W' = F0 sin(Ωt) ẋ1.  No progression (observed 0).
Effects (MODELS.md §6): ``rate_stiffening`` α [s/m], ``suspension_hardening`` κ [1/m²] on the k2 spring,
``sensor_lowpass`` fc [Hz] on the recorded acceleration (``sim.models.sensor``).
Discrepancy terms (sim.models.discrepancy; off at 0): contact_quadratic, contact_cubic join Fi (clamped at 0, the
indicators unchanged); tool_viscous, tool_quadratic_drag act on the hammer m2 (v = ẋ2); load_path_mode hangs its
hidden mass on m2; link_power_loss adds c (|v|/v_r)^p sgn v to the hammer's suspension (v = ẋ2 − ẋ1);
support_friction is the beam clamp's dry friction μ tanh(ẋ1 / v_ε) on m1; stop_mode mounts the stop on a mass
ms = ratio m2 with a spring and damper to the ground (the hidden states: its xs, ẋs; δ = x2 − gap − xs, δ̇ = ẋ2 − ẋs,
ms ẍs = Fi − ks xs − cs ẋs); drive_mode hangs the hidden mass on the beam m1 (md = ratio m1).
Off the stop (κ = 0) the equations are linear: ``sim/exact/rimd.py`` propagates the free flight exactly and leaves
the contact to the DOPRI5 steps (``method`` "auto" and "exact"; "dopri5" integrates both phases numerically).
"""
from __future__ import annotations

import math

import numpy as np
from sim.jit import njit  # numba is imported on first use (sim/jit.py)

from sim.integrator import two_indicator_guard, two_indicator_phase
from sim.models.base import SynthRig, FitBound, ModelSpec, Param
from sim.models.param import index_of
from sim.models.discrepancy import (DRIVE_MODE, DRIVE_MODE_PARAMS, LINK_PARAMS, LINK_REF, MODE_PARAMS, MODE_STATES,
                                    STOP_MODE, STOP_MODE_PARAMS, SUPPORT_FORCE, SUPPORT_VEPS, contact_extra,
                                    discrepancy_params, link_bounds, link_loss, link_params, mode_accel, mode_bounds,
                                    mode_force, site_mode_params, stop_accel, hidden_state, support_bounds,
                                    support_params, terms_at, tool_loss, vocabulary_at)
from sim.models.effects import effect_params
from sim.models.contact import hunt_crossley, hunt_crossley_damping
from sim.models.sensor import sensor_lowpass
from sim.models.terms import guide_friction, hardened_spring, rate_stiffened

M1, K1, C1, M2, K2, C2, KI, LAM, NI, F0, GAP, FREQ = range(12)   # then the effects' parameters (PARAMS)
IX1, IV1, IX2, IV2, IW, IXH, IVH = range(7)
NY_BASE = 5       # the exact propagator's linear system: the first NY_BASE states, W last
NY = 7
N_BOUNDED = 4
# the kernel checks N_GUARDS guards, as many as `guards` fills (the two-indicator contact)
N_GUARDS = 1
GUARD_STATES = (IX2, IV2, IXH, IVH)   # the states the guards read (x2, ẋ2; the mounted stop's xs, ẋs): the only
                                      # ones interpolated for them
LS = 1e-3   # length scale [m] turning the dimensionless indicator 1 + λi ẋ2 into a guard in metres


@njit(cache=True, inline="always")
def _hc_factor(y, p):
    """Hunt–Crossley damping factor 1 + λi δ̇ [-] (second contact indicator; δ̇ = ẋ2 − ẋs, the stop's ẋs 0 unless
    its mount's mode is on)."""
    return hunt_crossley_damping(p[LAM], y[IV2] - hidden_state(p[ISTOP], y[IVH]))


@njit(cache=True, inline="always")
def _delta(y, p):
    """Penetration δ = x2 − gap − xs [m] (xs the mounted stop's displacement, 0 unless its mode is on)."""
    return y[IX2] - p[GAP] - hidden_state(p[ISTOP], y[IXH])


@njit(cache=True, error_model="numpy")
def _force_at(ki, alpha, ni, lam, d, dd):
    """Hunt–Crossley force expression [N] with rate stiffening at the penetration d [m] and its rate dd [m/s], from
    scalars (``sim.models.contact.hunt_crossley``)."""
    return hunt_crossley(rate_stiffened(ki, alpha, dd), ni, lam, d, dd)


@njit(cache=True, inline="always")
def _rhs_at(t, y, ph, p, dy):
    """The equations of motion; returns the contact force expression fi [N] (0 out of contact; ``observe`` records
    it).  From scalars read before the contact branch and dy written after it: an inlined function whose branch
    splits an array's live range costs numba a reference-count increment and decrement per array on every stage (the
    expressions, and so every result bit, are unchanged)."""
    x1, v1, x2, v2 = y[IX1], y[IV1], y[IX2], y[IV2]
    m1, k1, c1, m2, k2, c2 = p[M1], p[K1], p[C1], p[M2], p[K2], p[C2]
    ki, lam, ni, f0, gap, alpha, kappa = p[KI], p[LAM], p[NI], p[F0], p[GAP], p[ALPHA], p[KAPPA]
    om = 2.0 * math.pi * p[FREQ]
    dc = terms_at(p, DISC)
    ratio = p[IMODE]
    xh, vh = y[IXH], y[IVH]
    fm = mode_force(ratio, p[IMODE + 1], p[IMODE + 2], m2, xh, vh)
    dratio = p[IDRIVE]
    fmd = mode_force(dratio, p[IDRIVE + 1], p[IDRIVE + 2], m1, xh, vh)
    sratio = p[ISTOP]
    d = x2 - gap - hidden_state(sratio, xh)
    dd = v2 - hidden_state(sratio, vh)
    # the discrepancy contact terms join the Hunt–Crossley force, clamped at 0 (the indicators stay δ, 1 + λi δ̇);
    # without them the force is the base model's, unclamped, bit for bit
    hc = _force_at(ki, alpha, ni, lam, d, dd)
    extra = contact_extra(dc, d, dd)
    fi = (hc if extra == 0.0 else max(hc + extra, 0.0)) if ph > 0 else 0.0
    phi = x2 - x1
    dphi = v2 - v1
    inner = c2 * dphi + hardened_spring(k2, phi, kappa) + link_loss(p[ILINK], p[ILINK_EXP], p[ILINK_REF], dphi)
    f = f0 * math.sin(om * t)
    dy[IX1] = v1
    a1 = (f - c1 * v1 - k1 * x1 + inner - guide_friction(p[ISUP], v1, p[ISUP_EPS]) + fmd) / m1
    dy[IV1] = a1
    dy[IX2] = v2
    a2 = (-inner - fi - tool_loss(dc, v2) + fm) / m2
    dy[IV2] = a2
    dy[IW] = f * v1
    dy[IXH] = vh
    dy[IVH] = (mode_accel(ratio, m2, fm, a2) + mode_accel(dratio, m1, fmd, a1)
               + stop_accel(sratio, p[ISTOP + 1], p[ISTOP + 2], m2, fi, xh, vh))
    return fi


@njit(cache=True)
def rhs(t, y, z, ph, p, dy):
    _rhs_at(t, y, ph, p, dy)


@njit(cache=True)
def guards(t, y, z, ph, p, g):
    two_indicator_guard(g, _delta(y, p), LS * _hc_factor(y, p), ph)


@njit(cache=True)
def on_event(t, y, z, ph, p, k):
    return two_indicator_phase(_delta(y, p), _hc_factor(y, p))


@njit(cache=True)
def observe(t, y, z, ph, p, obs, dy):
    obs[0] = max(_rhs_at(t, y, ph, p, dy), 0.0)     # the contact force, computed once with the derivatives
    obs[1] = dy[IV2]
    obs[2] = y[IX2]
    obs[3] = 0.0
    obs[4] = y[IV2]


@njit(cache=True)
def bounded(t, y, z, ph, p, b):
    b[0] = y[IX1]
    b[1] = y[IV1]
    b[2] = y[IX2]
    b[3] = y[IV2]


def _initial(p: np.ndarray):
    """Rest at x = 0; with gap 0 the hammer just touches the stop."""
    return np.zeros(NY), np.zeros(1), 0


def _atol(p: np.ndarray) -> np.ndarray:
    """Typical magnitudes: 1 mm, 1 mm·Ω, and the work of max(F0, 1 mN) over 1 mm (as the reference)."""
    xs = 1e-3
    om = 2.0 * math.pi * p[FREQ]
    return np.array([xs, xs * om, xs, xs * om, max(abs(p[F0]), 1e-3) * xs, xs, xs * om])


EFFECTS = ("rate_stiffening", "suspension_hardening", "sensor_lowpass")
"""The MODELS.md §6 effects of the RIMD (sim.models.effects): their parameters end PARAMS."""

PARAMS = (
    Param("m1", 0.368, "kg", "main beam mass", positive=True),
    Param("k1", 2850.0, "N/m", "beam stiffness to ground", positive=True),
    Param("c1", 1.269, "N s/m", "beam damping to ground", nonnegative=True),
    Param("m2", 0.360, "kg", "RIMD hammer mass", positive=True),
    Param("k2", 272.1, "N/m", "hammer suspension stiffness (to m1)", positive=True),
    Param("c2", 0.079, "N s/m", "hammer suspension damping", nonnegative=True),
    Param("ki", 92.5e3, "N/m^ni", "Hunt–Crossley contact stiffness", positive=True),
    Param("lambda_i", 8.0, "s/m", "Hunt–Crossley damping factor λi", nonnegative=True),
    Param("ni", 0.9, "-", "Hunt–Crossley exponent", positive=True),
    Param("amplitude_n", 1.0, "N", "force amplitude F0 on m1 (F0 sin Ωt); not printed in the seed, ≈ 1 N",
          nonnegative=True),
    Param("gap_m", 0.0, "m", "gap between the hammer at rest and the ground-fixed stop", nonnegative=True),
    Param("frequency_hz", 8.0, "Hz", "forcing frequency f", positive=True),
    *effect_params(EFFECTS, {"rate_stiffening": "the stop's ki, δ̇ = ẋ2",
                             "suspension_hardening": "the hammer's suspension k2, φ = x2 − x1",
                             "sensor_lowpass": "the hammer's recorded acceleration"}),
    *discrepancy_params({"contact": "joining the Hunt–Crossley force (clamped at 0), δ = x2 − gap, δ̇ = ẋ2",
                         "tool": "on the hammer m2, v = ẋ2"}),
    *link_params(0.04, "the hammer's suspension, v = ẋ2 − ẋ1"),
    *support_params("the beam's clamp, on m1, v = ẋ1"),
    *site_mode_params(STOP_MODE, "the stop on a mount: ms over the hammer's m2, δ = x2 − gap − xs"),
    *site_mode_params(DRIVE_MODE, "a hidden mass on the beam m1, which carries the forcing; md over m1"),
)
ALPHA, KAPPA = index_of(PARAMS, "alpha", "kappa")
DISC = vocabulary_at(PARAMS)   # the discrepancy terms' coefficients from here on (terms_at)
IMODE = index_of(PARAMS, *MODE_PARAMS)[0]   # then its frequency and damping ratio
ISTOP = index_of(PARAMS, *STOP_MODE_PARAMS)[0]
IDRIVE = index_of(PARAMS, *DRIVE_MODE_PARAMS)[0]
HIDDEN_SWITCHES = (IMODE, ISTOP, IDRIVE)   # the parameters that switch on a mode in the hidden states (sim.compiled)
ILINK, ILINK_EXP, ILINK_REF = index_of(PARAMS, *LINK_PARAMS, LINK_REF)
ISUP, ISUP_EPS = index_of(PARAMS, SUPPORT_FORCE, SUPPORT_VEPS)

STATES = ("x1", "v1", "x2", "v2", "work", *MODE_STATES)
BOUNDED = ("x1", "v1", "x2", "v2")

PRESETS = {
    # Seed 002 values (MODELS.md §4 table) and the gaps of its Table 3.
    "seed-002": {},
    "gap-0": {"gap_m": 0.0},
    "gap-1mm": {"gap_m": 1.0e-3},
    "gap-3mm": {"gap_m": 3.0e-3},
}

# The slow mode (4.16 Hz) decays at about 0.1 1/s without impacts (≈ 10 s, 40–80 cycles per e-fold at
# 4–8 Hz): non-impacting runs need hundreds of cycles to settle; impacting ones settle much faster.
SEED_RANGES = {"frequency_hz": (3.0, 12.0), "gap_m": (0.0, 3.0e-3), "amplitude_n": (0.25, 2.0)}
"""Seed 002's ranges (Table 3: gaps 0-3 mm, first and second impact resonances; F0 around its ~1 N): the map axes, and
the ranges the model is validated on (MODELS.md §4's independent solution)."""

DEFAULT_SETTINGS = {"min_transient": 40, "max_transient": 800, "window": 32, "max_step_frac": 0.02}

SPEC = ModelSpec(
    name="rimd",
    description="resonant impact device: beam m1 + hammer m2, Hunt–Crossley stop (MODELS.md §4, seed 002)",
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
    impacting_mass="hammer m2 (x2)",
    progression="none (the RIMD does not progress)",
    presets=PRESETS,
    default_settings=DEFAULT_SETTINGS,
    # free flight linear (κ = 0): propagated exactly, contact numerically (sim/exact/rimd.py)
    exact="sim.exact.rimd",
    # MODELS.md §6: the stop (ki, lambda_i) and the beam damping c1; one decade either side of the defaults.
    calibratable=(FitBound("ki", 9.25e3, 9.25e5, "N/m^ni"), FitBound("lambda_i", 0.8, 80.0, "s/m"),
                  FitBound("c1", 0.1269, 12.69, "N s/m")),
    # hammer impact velocity ~0.05-0.2 m/s; beam amplitude ~1-5 mm, so kappa x1^2 ~ 1 at kappa ~ 1e5 1/m^2
    effect_bounds={"alpha": FitBound("alpha", 1e-2, 100.0, "s/m"), "kappa": FitBound("kappa", 1e1, 1e7, "1/m^2"),
                   "fc": FitBound("fc", 10.0, 3000.0, "Hz")},
    # the 4-15 Hz impacts are resolved by their first ~25 harmonics
    diagnose_max_harmonic_hz=200.0,
    # candidates start from the calibrated base and from the rig's nominal values: a sensor low-pass or a
    # stiffening contact is absorbed into ki and the damping so far that the calibrated base is a false valley
    diagnose_fit={"candidate_starts": 2, "max_nfev": 10},
    # discrepancy terms: penetration ~ 8e-5 m, hammer speed ~0.1 m/s; contact_rate_product is left out: the
    # Hunt–Crossley λi ki δ^ni δ̇ (calibratable) is that term already
    discrepancy=("contact_quadratic", "contact_cubic", "tool_viscous", "tool_quadratic_drag", *MODE_PARAMS,
                 *LINK_PARAMS, SUPPORT_FORCE, *STOP_MODE_PARAMS, *DRIVE_MODE_PARAMS),
    # (bounds measured at the default point: each probe strength moves the peak force by ~3-10 %; the resonant
    # hammer is very sensitive to a loss on it)
    # the hidden mode from below the forcing (5-9 Hz) to well above the beam's and the hammer's modes
    # the link loss at the suspension's rms velocity 0.04 m/s, where its spring carries ~0.3 N: 1 mN-0.3 N
    # the clamp's friction from ~0.3 % to ~1x the forcing's 1 N; the stop's mount from a twentieth to 20x the
    # hammer's mass, from the beam's modes to well above the impacts' ring; the drive's mode as the hidden one
    discrepancy_bounds={**mode_bounds(3.0, 300.0), **link_bounds(1e-3, 0.3), **support_bounds(3e-3, 1.0),
                        **mode_bounds(10.0, 1000.0, STOP_MODE_PARAMS, (0.05, 20.0)),
                        **mode_bounds(3.0, 300.0, DRIVE_MODE_PARAMS),
                        "contact_quadratic": FitBound("contact_quadratic", 1e7, 3e9, "N/m^2"),
                        "contact_cubic": FitBound("contact_cubic", 1e11, 3e13, "N/m^3"),
                        "tool_viscous": FitBound("tool_viscous", 0.01, 10.0, "N s/m"),
                        "tool_quadratic_drag": FitBound("tool_quadratic_drag", 0.5, 300.0, "N s^2/m^2")},
    # impact-pattern maps over the seed's ranges (seed 002 Table 3: gaps 0-3 mm)
    map_kind="pattern",
    map_ranges=SEED_RANGES,
    validated={"": SEED_RANGES},
    min_work_per_m=lambda v: 0.0,     # passive beam and hammer, no progression: F0's work covers the losses
    # `vibro synth` (seed 002): across the first impact resonance at gap 0, two forcing levels, 10 kHz DAQ; impact
    # velocity ~0.1 m/s: alpha 2 s/m is +20 %; beam amplitude ~2 mm: kappa x1^2 ~ 0.4; mount resonance 60 Hz
    synth=SynthRig(frequencies_hz=(5.0, 6.0, 6.5, 7.0, 7.5, 8.0, 9.0, 10.0), level_name="amplitude_n", levels=(0.5, 1.0),
                   fixed={"gap_m": 0.0}, fs_hz=10000.0, cycles=16.3,
                   effect_strengths={"rate_stiffening": {"alpha": 2.0}, "suspension_hardening": {"kappa": 1.0e5},
                                     "sensor_lowpass": {"fc": 100.0}},
                   mount_hz=60.0),
)
