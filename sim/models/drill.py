"""Three-mass vibro-impact drilling model with a drifting rock slider (MODELS.md §2), with the §6 effects.

States y = [x1, v1, x2, v2, x3, v3, xt, xb, fh, W, xh, vh] (bit, exciter, top mass, rock surface,
slider base, coil force (a state only with `shaker_coil`), excitation work, the hidden load-path mode relative to
the bit: discrepancy ``load_path_mode``, at rest while off).
Phases: 0 = I no contact, 1 = II contact without progression, 2 = III contact with
progression (Pc = Pr).  In contact phases xt is integrated with ẋt = ẋ1 from xt = x1,
so it equals x1 exactly.

Effects (MODELS.md §6, drill column; all off at their default 0, and then every term below
is exactly the base model's):
  shaker_coil (tau [s], beta [N s/m]): the harmonic force on M1 is Fh with
      τ Ḟh + Fh = F0 cos Ωt − β (ẋ1 − ẋ2), Fh(0) = 0.  τ = 0 is the algebraic limit
      Fh = F0 cos Ωt − β (ẋ1 − ẋ2) (the state fh then stays 0); τ = β = 0 is the ideal force
      source.  As in the base model the force acts on M1 only; W integrates Fh ẋ1.
  rate_stiffening (alpha [s/m]): K1 → K1 (1 + α max(ẋ1, 0)) in Pc = K1 (x1 − xb) + C1 ẋ1; the
      same expression drives the guards, the phase check and the slider law of phase III
      (ẋb = (Pc − Pr)/C1, so ẋb is continuous at II↔III).  Phase I's surface relaxation keeps K1
      (the bit is off the rock; the surface moves back, so max(δ̇, 0) = 0 there anyway).
  guide_friction (mu [N]): −μ tanh((ẋ1 − ẋ2)/v_eps) on M1, reaction on M2 (sgn regularised as
      MODELS.md §1 does for the indenter; v_eps default 1e-4 m/s).
  tip_blunting (gamma [-]): Pr → Pr (1 + γ (xb − G)/1 mm).
  suspension_hardening (kappa [1/m^2]): K2 (x1 − x2) → K2 (x1 − x2)(1 + κ (x1 − x2)²).

Discrepancy terms (sim.models.discrepancy; off at 0): contact_quadratic, contact_cubic join Pc with δ = x1 − xb
(so the guards, the phase check and the slider law see them); tool_viscous, tool_quadratic_drag act on M1 (v = ẋ1);
load_path_mode hangs its hidden mass on M1; rock_rate_strength η raises the failing rock's threshold with its
failure rate in phase III: ẋb = (Pc − Pr)/(C1 + η Pr), the bit feels Pr (1 + η ẋb) (the switching surfaces are
unchanged: ẋb = 0 where Pc = Pr); link_power_loss adds c (|v|/v_r)^p sgn v to the bit-exciter link (v = ẋ1 − ẋ2);
drive_mode hangs the hidden mass in the exciter M2 instead (md = ratio M2, the hidden states relative to M2).
"""
from __future__ import annotations

import math

import numpy as np
from sim.jit import interpreted, njit  # numba is imported on first use (sim/jit.py)

from sim.models.base import SynthRig, FitBound, ModelSpec, Param
from sim.models.discrepancy import (DRIVE_MODE, DRIVE_MODE_PARAMS, LINK_PARAMS, LINK_REF, MODE_PARAMS, MODE_STATES,
                                    STRENGTH, contact_extra, discrepancy_params, link_bounds, link_loss, link_params,
                                    mode_accel, mode_bounds, mode_force, site_mode_params, strength_bounds,
                                    strength_params, terms_at, tool_loss, vocabulary_at)
from sim.models.effects import effect_params
from sim.models.param import index_of
from sim.models.contact import kelvin_voigt, rock_slider_rate, rock_surface_rate
from sim.models.sensor import sensor_lowpass
from sim.models.terms import coil_force, hardened_spring, rate_stiffened, tip_blunted

# parameter vector layout
(M1, M2, M3, K1, K2, K3, C1, C2, C3, PR, GAP, FS, F0, FREQ, VEPS) = range(15)   # then the effects' (PARAMS)
# state layout: the hidden mode's two states last (the exact propagator's linear system is the first NY_BASE, W last)
IX1, IV1, IX2, IV2, IX3, IV3, IXT, IXB, IFH, IW, IXH, IVH = range(12)
NY_BASE = 10
NY = 12
N_BOUNDED = 8
# the kernel checks N_GUARDS guards, as many as `guards` fills (phase II has two: release and threshold)
N_GUARDS = 2
GUARD_STATES = (IX1, IV1, IXT, IXB)     # the states the guards read (x1, v1, xt, xb): the only ones interpolated for them


@njit(cache=True, error_model="numpy")
def _pr_at(pr, gamma, gap, xb):
    """Rock threshold [N], raised by tip blunting (MODELS.md §6 `tip_blunting`), from scalars."""
    return tip_blunted(pr, gamma, xb - gap)


@njit(cache=True, error_model="numpy")
def _pc_at(k1, alpha, c1, x1, v1, xb, dc):
    """Phase-II contact force expression [N] from scalars; rate_stiffening: K1 → K1 (1 + α max(ẋ1, 0)); the
    discrepancy contact terms (dc: the vocabulary's coefficients, sim.models.discrepancy) with δ = x1 − xb, δ̇ = ẋ1."""
    return kelvin_voigt(rate_stiffened(k1, alpha, v1), c1, x1 - xb, v1) + contact_extra(dc, x1 - xb, v1)


@njit(cache=True, inline="always")
def _pr_eff(y, p):
    """Rock threshold [N] of the state ``y`` (``_pr_at``)."""
    return _pr_at(p[PR], p[GAMMA], p[GAP], y[IXB])


@njit(cache=True, inline="always")
def _pc_expr(y, p):
    """Phase-II contact force expression [N] of the state ``y`` (``_pc_at``)."""
    return _pc_at(p[K1], p[ALPHA], p[C1], y[IX1], y[IV1], y[IXB], terms_at(p, DISC))


@njit(cache=True, inline="always")
def _rhs_at(t, y, ph, p, dy):
    """The equations of motion; returns the contact force Pc [N] (``observe`` records it).

    Written on local scalars read first, with the branchy helpers taking scalars only, and dy written last and
    unconditionally: an inlined helper that takes an array costs numba a reference-count increment and decrement per
    array where its branches split the array's live range."""
    x1, v1, x2, v2, x3, v3 = y[IX1], y[IV1], y[IX2], y[IV2], y[IX3], y[IV3]
    xt, xb, fh_y = y[IXT], y[IXB], y[IFH]
    m1, m2, m3 = p[M1], p[M2], p[M3]
    k1, k2, k3 = p[K1], p[K2], p[K3]
    c1, c2, c3 = p[C1], p[C2], p[C3]
    pr, gap, fs, f0, freq, gamma = p[PR], p[GAP], p[FS], p[F0], p[FREQ], p[GAMMA]
    tau, beta, alpha, mu, kappa, veps = p[TAU], p[BETA], p[ALPHA], p[MU], p[KAPPA], p[VEPS]
    dc = terms_at(p, DISC)
    ratio = p[IMODE]
    fm = mode_force(ratio, p[IMODE + 1], p[IMODE + 2], m1, y[IXH], y[IVH])
    vh = y[IVH]
    # harmonic force on M1: F0 cos Ωt, or the shaker coil's
    fh, dfh = coil_force(f0 * math.cos(2.0 * math.pi * freq * t), beta, v1 - v2, tau, fh_y)
    if ph == 0:              # each phase computes only its own terms (no threshold division off progression)
        pc = 0.0
        dxt = rock_surface_rate(k1, c1, xt, xb)
        dxb = 0.0
    elif ph == 1:
        pc = _pc_at(k1, alpha, c1, x1, v1, xb, dc)
        dxt = v1
        dxb = 0.0
    else:                    # the rock fails: the bit feels Pr (1 + η ẋb), Pr itself while η = 0
        pr_x = _pr_at(pr, gamma, gap, xb)
        eta_pr = p[ISTRENGTH] * pr_x
        dxt = v1
        dxb = rock_slider_rate(_pc_at(k1, alpha, c1, x1, v1, xb, dc), pr_x, c1 + eta_pr)
        pc = pr_x + eta_pr * dxb
    d12 = x1 - x2
    # bit-exciter link: damper, (hardening) spring, guide friction; each effect term is exactly 0 when off (the
    # friction's tanh, a libm call per stage, is then not evaluated).  The friction keeps libm's tanh: the exp form of
    # terms.guide_friction differs from it by a few 1e-16 and would move the drill's labels.
    s12 = c2 * (v1 - v2) + hardened_spring(k2, d12, kappa)
    if mu != 0.0:
        s12 += mu * math.tanh((v1 - v2) / veps)
    s12 += link_loss(p[ILINK], p[ILINK_EXP], p[ILINK_REF], v1 - v2)
    s23 = c3 * (v2 - v3) + k3 * (x2 - x3)
    dy[IX1] = v1
    a1 = (fh - s12 - pc - tool_loss(dc, v1) + fm) / m1
    dy[IV1] = a1
    dy[IX2] = v2
    fmd = mode_force(p[IDRIVE], p[IDRIVE + 1], p[IDRIVE + 2], m2, y[IXH], vh)
    a2 = (fs + s12 - s23 + fmd) / m2
    dy[IV2] = a2
    dy[IX3] = v3
    dy[IV3] = s23 / m3
    dy[IXT] = dxt
    dy[IXB] = dxb
    dy[IFH] = dfh
    dy[IW] = fh * v1
    dy[IXH] = vh
    dy[IVH] = mode_accel(ratio, m1, fm, a1) + mode_accel(p[IDRIVE], m2, fmd, a2)
    return pc


@njit(cache=True)
def rhs(t, y, z, ph, p, dy):
    _rhs_at(t, y, ph, p, dy)


@njit(cache=True)
def guards(t, y, z, ph, p, g):
    """The phase's guards (MODELS.md §2), from scalars read first (``_rhs_at``); a phase with one guard sets the other
    to -1."""
    x1, v1, xt, xb = y[IX1], y[IV1], y[IXT], y[IXB]
    pc = _pc_at(p[K1], p[ALPHA], p[C1], x1, v1, xb, terms_at(p, DISC))
    pr = _pr_at(p[PR], p[GAMMA], p[GAP], xb)
    if ph == 0:
        a = x1 - xt                                 # I -> II/III: bit reaches the rock surface
        b = -1.0
    elif ph == 1:
        a = -pc                                     # II -> I: contact force falls to zero
        b = pc - pr                                 # II -> III: force reaches the threshold
    else:
        a = pr - pc                                 # III -> II: slider velocity falls to zero
        b = -1.0
    g[0] = a
    g[1] = b


@njit(cache=True)
def classify(y, p, ph):
    """Phase the state belongs to (checked at the start of every segment)."""
    if ph == 0 and y[IX1] < y[IXT]:
        return 0
    pc = _pc_expr(y, p)
    if pc >= _pr_eff(y, p):
        return 2
    if pc > 0.0:
        return 1
    return 0


@njit(cache=True)
def on_event(t, y, z, ph, p, k):
    if ph == 0:                      # onset: the bit meets the surface; II, or straight to III
        y[IXT] = y[IX1]
        return classify(y, p, 1)
    if ph == 1 and k == 0:           # release: the surface relaxes from where the bit leaves it
        y[IXT] = y[IX1]
        return 0
    return classify(y, p, ph)


@njit(cache=True)
def observe(t, y, z, ph, p, obs, dy):
    obs[0] = _rhs_at(t, y, ph, p, dy)      # the contact force: 0 (I), Pc (II) or Pr (III)
    obs[1] = dy[IV1]
    obs[2] = y[IX1]
    obs[3] = y[IXB]
    obs[4] = y[IV1]


@njit(cache=True)
def bounded(t, y, z, ph, p, b):
    xb = y[IXB]
    b[0] = y[IX1] - xb
    b[1] = y[IX2] - xb
    b[2] = y[IX3] - xb
    b[3] = y[IXT] - xb
    b[4] = y[IV1]
    b[5] = y[IV2]
    b[6] = y[IV3]
    b[7] = y[IFH]     # coil force: bounded; identically 0 when the coil is off (range 0, repeats exactly)


def _initial(p: np.ndarray):
    """Rest, springs unstretched, rock surface and slider at the gap; G = 0 starts touching."""
    y = np.zeros(NY)
    y[IXT] = p[GAP]
    y[IXB] = p[GAP]
    ph = int(interpreted(classify)(y, p, 1)) if p[GAP] <= 0.0 else 0     # interpreted: no numba import
    return y, np.zeros(1), ph


def _precheck(p: np.ndarray) -> str | None:
    if p[FS] >= p[PR]:
        return (f"static force Fs = {p[FS]:g} N >= rock threshold Pr = {p[PR]:g} N: no bounded steady state, "
                f"the string accelerates at about (Fs - Pr)/sum(M) = {(p[FS] - p[PR]) / (p[M1] + p[M2] + p[M3]):.3g} m/s^2")
    return None


def _atol(p: np.ndarray) -> np.ndarray:
    xs = max(p[F0] + p[FS], 1.0) / p[K2]          # a deflection scale of the bit spring
    om = 2.0 * math.pi * p[FREQ]
    vs = xs * om
    fsc = max(p[F0], 1.0)
    return np.array([xs, vs, xs, vs, xs, vs, xs, xs, fsc, fsc * xs, xs, vs])


EFFECTS = ("shaker_coil", "rate_stiffening", "guide_friction", "tip_blunting", "suspension_hardening",
           "sensor_lowpass")
"""The MODELS.md §6 effects of the drill (sim.models.effects): their parameters end PARAMS."""

PARAMS = (
    Param("M1", 2.0, "kg", "drill-bit mass", positive=True),
    Param("M2", 8.0, "kg", "exciter (RED module) mass", positive=True),
    Param("M3", 20.0, "kg", "top mass / frame", positive=True),
    Param("K1", 2e7, "N/m", "rock stiffness", positive=True),
    Param("K2", 2e6, "N/m", "bit-exciter spring", positive=True),
    Param("K3", 5e5, "N/m", "exciter-top spring", positive=True),
    Param("C1", 5e3, "N s/m", "rock damping", positive=True),
    Param("C2", 400.0, "N s/m", "bit-exciter damping", nonnegative=True),
    Param("C3", 1000.0, "N s/m", "exciter-top damping", nonnegative=True),
    Param("Pr", 1500.0, "N", "rock progression threshold (plastic limit of the slider)", positive=True),
    Param("gap_m", 0.0, "m", "initial gap G between bit and rock", nonnegative=True),
    Param("static_force_n", 700.0, "N", "static force Fs on M2 (gravity folded in)", nonnegative=True),
    Param("amplitude_n", 1500.0, "N", "harmonic force amplitude F0 on M1 (F0 cos Ωt)", nonnegative=True),
    Param("frequency_hz", 200.0, "Hz", "forcing frequency f", positive=True),
    Param("v_eps", 1e-4, "m/s", "tanh regularisation speed of the Coulomb term (guide_friction)", positive=True),
    *effect_params(EFFECTS, {"shaker_coil": "the force F0 cos Ωt on M1, Δv = ẋ1 − ẋ2",
                             "rate_stiffening": "the rock's K1 in phase II, δ̇ = ẋ1",
                             "guide_friction": "the bit's guides, Δv = ẋ1 − ẋ2",
                             "tip_blunting": "the threshold Pr, progression xb − G",
                             "suspension_hardening": "the bit-exciter spring K2, φ = x1 − x2",
                             "sensor_lowpass": "the bit's recorded acceleration"}),
    *discrepancy_params({"contact": "in Pc of phase II, δ = x1 − xb, δ̇ = ẋ1", "tool": "on M1, v = ẋ1"}),
    *strength_params("the slider's threshold Pr in phase III, ẋb its rate"),
    *link_params(0.01, "the bit-exciter link, v = ẋ1 − ẋ2"),
    *site_mode_params(DRIVE_MODE, "a hidden mass in the exciter M2 (the RED module that houses the drive); md "
                      "over M2"),
)
DISC = vocabulary_at(PARAMS)   # the discrepancy terms' coefficients from here on (terms_at)
IMODE = index_of(PARAMS, *MODE_PARAMS)[0]   # then its frequency and damping ratio
IDRIVE = index_of(PARAMS, *DRIVE_MODE_PARAMS)[0]
HIDDEN_SWITCHES = (IMODE, IDRIVE)   # the parameters that switch on a mode in the hidden states (sim.compiled)
(ISTRENGTH,) = index_of(PARAMS, STRENGTH)
ILINK, ILINK_EXP, ILINK_REF = index_of(PARAMS, *LINK_PARAMS, LINK_REF)
GAMMA, TAU, BETA, ALPHA, MU, KAPPA, FC = index_of(PARAMS, "gamma", "tau", "beta", "alpha", "mu", "kappa", "fc")
NP = len(PARAMS)

# Fit bounds (lo, hi, unit) of the §6 effect parameters at the `lab` preset's scale: lo = where the effect just
# becomes measurable (~0.5 % ROP at the default point), hi = large but still simulable (docs/simulate.md).
EFFECT_FIT_BOUNDS = {
    "tau": (3e-5, 5e-4, "s"),
    "beta": (200.0, 3e4, "N s/m"),
    "alpha": (3.0, 1000.0, "s/m"),
    "mu": (2.0, 500.0, "N"),
    "gamma": (3e-4, 1.0, "-"),
    "kappa": (2e7, 3e9, "1/m^2"),
    "fc": (100.0, 3e4, "Hz"),
}

# A clearly visible strength of each effect on the `lab` preset at its default point (8-14 % ROP), for
# synthetic rig data and the validation against tests/reference_solutions.py (effect sizes: docs/simulate.md).
EFFECT_VISIBLE = {
    "shaker_coil": {"tau": 1e-4, "beta": 3e3},
    "rate_stiffening": {"alpha": 50.0},
    "guide_friction": {"mu": 50.0},
    "tip_blunting": {"gamma": 0.01},
    "suspension_hardening": {"kappa": 3e8},
    "sensor_lowpass": {"fc": 1500.0},
}

STATES = ("x1", "v1", "x2", "v2", "x3", "v3", "xt", "xb", "fh", "work", *MODE_STATES)
BOUNDED = ("x1-xb", "x2-xb", "x3-xb", "xt-xb", "v1", "v2", "v3", "fh")

PRESETS = {
    # Seed 003's own parameter table (MODELS.md §2): Fs = 1260 kN >= Pr = 95 kN, a runaway.
    "seed-003": {"M1": 50142.0, "M2": 28054.5, "M3": 60790.3, "K1": 3.75e6, "K2": 701.4e3, "K3": 1095e3,
                 "C1": 16697.4, "C2": 18753.0, "C3": 25800.0, "gap_m": 0.001, "Pr": 95e3,
                 "static_force_n": 1260e3, "amplitude_n": 995e3, "frequency_hz": 0.1 / (2.0 * math.pi)},
    # MODELS.md §2 starting point, kept for comparison with its independent solution (ROP ~ m/s: too fast).
    "models-start": {},
    # Lab-scale resonance-enhanced drilling rig in hard rock (docs/simulate.md, "The drill model's lab preset").
    # Why the starting point drills at m/s: with G = 0, ROP scales exactly as (force scale)/(mass scale x time-scale^-1): scaling F0, Fs,
    # Pr by phi multiplies ROP by phi; scaling every M, K, C by lam divides it by lam -- a 2 kg bit driven by up
    # to 2 Pr = 3 kN at 200 Hz swings at ~1 m/s.  Here the bit is 30x heavier, F0 <= 0.9 Pr instead of 2 Pr, and
    # the modes are placed (bit-exciter 200 Hz, isolation 30 Hz, contact ~500 Hz) so the RED resonance gives the
    # ROP peak inside the frequency range.
    "lab": {
        # vibrating bit assembly: ~16 mm insert bit + bit sub + short drill-collar section + actuator drive
        # shaft/armature.  60 kg (vs 2 kg) brings the bit velocity amplitude down to ~0.014 m/s (default point).
        "M1": 60.0,
        # RED module / exciter body (a ~3 kN electrodynamic shaker body weighs 200-300 kg): 4 x M1.
        "M2": 240.0,
        # carriage + frame + dead weights carrying the static load: 15 x M1.
        "M3": 900.0,
        # rock contact stiffness under the bit: flat-punch 2aE/(1-nu^2), E ~ 55 GPa (granite), contact
        # radius a ~ 5 mm -> 6e8 N/m; bit-on-rock contact mode sqrt(K1/M1)/2pi ~ 500 Hz, above the forcing range.
        "K1": 6e8,
        # bit-exciter spring: puts the bit-exciter mode sqrt(K2 (1/M1 + 1/M2))/2pi at 200 Hz, the RED
        # resonance; in contact the mode stiffens and the ROP peak sits at ~200-340 Hz, inside the range.
        "K2": 7.58e7,
        # exciter-top (isolation) spring: isolation mode sqrt(K3 (1/M2 + 1/M3))/2pi = 30 Hz, well below the
        # range, so the heavy frame does not ride along and the low-frequency end stays below the peak.
        "K3": 6.73e6,
        # rock damping: bit-on-rock contact about critically damped (C1 / 2 sqrt(K1 M1) ~ 1.05; crushing rock is
        # very lossy); any impact faster than Pr/C1 = 7.5 mm/s goes straight to progression.
        "C1": 4e5,
        # bit-exciter damping, zeta2 = C2 / 2 sqrt(K2 mu12) = 0.4 (mu12 = M1 M2/(M1+M2) = 48 kg): elastomer /
        # bearing losses of the RED module.  With zeta2 = 0.25 the response near resonance was often chaotic
        # (not settled after 400 cycles); 0.4 keeps it periodic while the resonance peak stays clear.
        "C2": 4.8e4,
        # exciter-top damping, zeta3 = 0.5 (mu23 = 189.5 kg): a damped isolation mount.
        "C3": 3.57e4,
        # rock progression threshold: hard rock (UCS ~ 150-200 MPa) crushed under an insert contact of
        # ~15-20 mm^2 -> 3 kN.  Controls are scaled to it: F0 in [0.6, 0.9] Pr, Fs in [0.2, 0.6] Pr (LAB_SPACE).
        "Pr": 3000.0,
        # bit resting on the rock at start
        "gap_m": 0.0,
        # default operating point: inside LAB_SPACE near the ROP peak (measured ROP 3.6 mm/s)
        "frequency_hz": 280.0,
        "amplitude_n": 2250.0,
        "static_force_n": 1200.0,
    },
}

# Search space of the `lab` preset's controls (MODELS.md §2 requirements (i)-(iii); measured over it in
# docs/simulate.md, "The drill model's lab preset").  F0 >= 0.6 Pr closes the non-progressing
# hole F0 < min(Fs, Pr - Fs) (neither lift-off impacts nor Fs + F0 reaching Pr); Fs <= 0.6 Pr stays well
# clear of the runaway Fs >= Pr and of the near-threshold region where ROP shoots up.
LAB_SPACE = {"frequency_hz": (100.0, 450.0), "amplitude_n": (1800.0, 2700.0), "static_force_n": (600.0, 1800.0)}
# The MODELS.md §2 ranges of the default (starting-point) parameters, Pr = 1.5 kN: f 10-400 Hz, F0 0-2 Pr,
# Fs 0.05-0.95 Pr, where the independent high-accuracy solution is known.
START_SPACE = {"frequency_hz": (10.0, 400.0), "amplitude_n": (0.0, 3000.0), "static_force_n": (75.0, 1425.0)}

# `vibro synth`'s lab drilling rig (lab preset, MODELS.md §2): 8 frequencies across the RED resonance x two
# weights on bit; a 25.6 kHz DAQ logs 28.3-cycle stretches at different times (depths) after spud-in (blunting
# never settles); two runs were logged as summaries only (ROP, peak WOB force, ...) and every 5th run lost its
# force channel.  Effects at EFFECT_VISIBLE; the mount resonance at 1.2 kHz, inside diagnose_max_harmonic_hz.
SYNTH = SynthRig(frequencies_hz=(150.0, 190.0, 230.0, 270.0, 310.0, 350.0, 390.0, 430.0),
                 level_name="static_force_n", levels=(900.0, 1500.0), fixed={"amplitude_n": 2250.0, "gap_m": 0.0},
                 fs_hz=25600.0, cycles=28.3, effect_strengths=EFFECT_VISIBLE, mount_hz=1200.0, preset="lab",
                 signals=("accel_m_s2", "force_n", "progression_m"), record_start_s=(0.15, 0.3, 0.45, 0.6),
                 summary_runs=2, drop_signal_every=5)

SPEC = ModelSpec(
    name="drill",
    description="three-mass vibro-impact drilling with a drifting rock slider (MODELS.md §2)",
    params=PARAMS,
    states=STATES,
    z_names=(),
    bounded=BOUNDED,
    funcs=(rhs, guards, on_event, observe, bounded),
    n_bounded=N_BOUNDED,
    initial=_initial,
    atol=_atol,
    precheck=_precheck,
    effects=EFFECTS,
    presets=PRESETS,
    postprocess=sensor_lowpass,
    needs_history=lambda values: values.get("fc", 0.0) > 0.0,
    impacting_mass="M1 (drill bit)",
    progression="xb (rock slider base)",
    default_settings={"min_transient": 20, "max_transient": 400, "window": 32},
    # MODELS.md §6 effects at the lab preset's scale (EFFECT_FIT_BOUNDS above: measured effect sizes at each bound)
    effect_bounds={n: FitBound(n, lo, hi, u) for n, (lo, hi, u) in EFFECT_FIT_BOUNDS.items()},
    # the rock under the bit; the bounds span the models-start (K1 2e7, C1 5e3, Pr 1.5 kN) and lab (K1 6e8, C1 4e5,
    # Pr 3 kN) presets with a decade to spare (2e8 / 5e4 excluded the lab rock)
    calibratable=(FitBound("K1", 2e6, 6e9, "N/m"), FitBound("C1", 5e2, 4e6, "N s/m"),
                  FitBound("Pr", 150.0, 3e4, "N")),
    # the lab contact mode is ~500 Hz: harmonics up to 3 kHz carry the impact's shape; one candidate start and
    # 10 iterations reach the answer of 2 starts and 15 iterations on a 16-run control at half the cost
    diagnose_max_harmonic_hz=3000.0,
    diagnose_fit={"candidate_starts": 1, "max_nfev": 10},
    # discrepancy terms (sim.models.discrepancy) at the lab preset's scale: lo changes the ROP by ~0.5-1 %, the probe
    # (sim.models.discrepancy.PROBE_AT) by ~5-20 %, hi by 25-60 %.  contact_rate_product is left out: a release where
    # the δ δ̇ term takes Pc to 0 while K1 δ + C1 ẋ1 > 0 leaves the surface relaxing (phase I's base law) into the bit,
    # and the onset guard x1 − xt fires at once (event storms at some strengths); the independent reference treats
    # that overlap with two more events — the kernel's phase I would need the same before the term can be offered
    discrepancy=("contact_quadratic", "contact_cubic", "tool_viscous", "tool_quadratic_drag", *MODE_PARAMS, STRENGTH,
                 *LINK_PARAMS, *DRIVE_MODE_PARAMS),
    # the hidden mode from below the lab forcing (100-450 Hz) to above the lab contact mode (~500 Hz) x 10; the
    # rock's rate strength: the lab rock fails at ẋb ~ 0.013 m/s through C1 + η Pr, so η 1-1000 s/m is η Pr / C1
    # from 0.75 % to 7.5x
    # the link loss at the lab link's rms velocity 0.01 m/s, where its damping C2 carries ~500 N: 2-700 N
    # the drive's mode from below the forcing to the exciter's structural modes (50-3000 Hz)
    discrepancy_bounds={**mode_bounds(100.0, 5000.0), **strength_bounds(1.0, 1000.0), **link_bounds(2.0, 700.0),
                        **mode_bounds(50.0, 3000.0, DRIVE_MODE_PARAMS),
                        "contact_quadratic": FitBound("contact_quadratic", 2e12, 2e15, "N/m^2"),
                        "contact_cubic": FitBound("contact_cubic", 5e17, 5e20, "N/m^3"),
                        "tool_viscous": FitBound("tool_viscous", 300.0, 3e4, "N s/m"),
                        "tool_quadratic_drag": FitBound("tool_quadratic_drag", 2e4, 5e6, "N s^2/m^2")},
    # "lab": LAB_SPACE above; "": the MODELS.md §2 ranges at the default Pr = 1.5 kN (f 10-400 Hz,
    # F0 0-2 Pr, Fs 0.05-0.95 Pr).
    search_spaces={"lab": LAB_SPACE, "": START_SPACE},
    # validated: the lab preset over LAB_SPACE (docs/simulate.md), the defaults (and models-start) over the MODELS.md §2
    # ranges; seed-003 is the seed's own runaway table, validated at its one point only
    validated={"lab": LAB_SPACE, "": START_SPACE, "seed-003": {}},
    # energy balance: over a period the excitation and Fs put in W + Fs Δxb, the slider alone dissipates Pr Δxb
    min_work_per_m=lambda v: float(v["Pr"]) - float(v["static_force_n"]),
    # ROP maps; forces as multiples of the resolved Pr: F0 in [0, 1] Pr and Fs in [0.05, 1.1] Pr, so the
    # non-progressing (small F0) and runaway (Fs >= Pr) regions are on the map.
    map_kind="rop",
    map_ranges={"frequency_hz": (10.0, 450.0), "amplitude_n": (0.0, 1.0), "static_force_n": (0.05, 1.1)},
    map_relative_to={"amplitude_n": "Pr", "static_force_n": "Pr"},
    progress_force_floor=lambda v: float(v["Pr"]) if "Pr" in v else None,   # MODELS.md §2: Pc must reach Pr
    exact="sim.exact.drill",
    synth=SYNTH,
)
