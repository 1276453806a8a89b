"""Independent high-accuracy reference solutions of the vibro-impact models of MODELS.md (sections 1-6).

Pure numpy/scipy.  Deliberately shares NO code with the fast simulator in ``sim/``: it is the yardstick
the simulator is validated and benchmarked against.

Method
------
* Every smooth branch (free flight, contact, progression, loading, unloading, ...) is integrated with a
  scipy.integrate solver class (``method``, ``rtol`` as given: the steppers solve_ivp uses) driven step by
  step, with terminal event functions for every switching surface of that branch (with crossing
  direction).  Events are searched on the dense output of every step at 16 sub-intervals, and local
  extrema of an event function near 0 are refined, so a surface crossed twice inside one step (which
  solve_ivp, comparing signs at step ends only, misses) is still found; roots by brentq on the
  interpolant.  Each event ends the segment; the next
  segment restarts on the branch decided from the state (``classify``) -- never from "which event fired"
  alone -- so an immediate exit or a very short visit is not missed.
* Switching surfaces carry a tiny hysteresis ``eta`` (1e-15 m for positions, 1e-10*Pr for the drill force,
  1e-12 m/s for velocities): the entry surface of a branch is ``h = g - eta`` and the exit surface
  ``h = g + eta``.  A segment that starts *on* a surface (|g| <= eta) is put on the side the flow moves to
  (sign of dg/dt, computed analytically); if even that is ambiguous (grazing, or an equilibrium lying
  exactly on the surface) the non-contact side is taken and an entry is then caught as soon as g exceeds
  eta.  So a segment never starts on its own triggering side: no zero-length event loops, and an
  equilibrium on a surface (e.g. RIMD with F0 = 0 and gap 0) does not fire events forever.  The location
  error this introduces is eta / |dg/dt| (~1e-14 s), far below any contact duration.  It is not harmless at
  the 1e-8 level: where a contact force jumps at the onset (the drill's damper C1 v1) a contact delayed by
  eta / v1 transfers a little less momentum, and with eta = 1e-13 m the drill `lab` ROP came out 1.41e-8
  high (1.44e-9 at 1e-14 m, 1.7e-10 at 1e-15 m: linear in eta; ``python -m bench.reference_hysteresis``),
  the only disagreement with the simulator's exact propagator.  Hence 1e-15 m (atol of positions at rtol 1e-12; round-off of a mm-scale position ~1e-19).
* Integration runs cycle by cycle in *local* cycle time tau in [0, T) (all forcings are T-periodic), which
  keeps the time resolution of event location at ~1e-16*T however long the run; every cycle boundary is
  a segment end, giving exact stroboscopic samples.
* Contact-force maxima and the largest deceleration are found on the dense output: 200 samples per
  contact segment (about 200 per cycle, min 16, in free segments), then the best sample is refined with a
  bounded Brent search on the interpolant.
* The excitation work W is an extra ODE state.
* ``sample_times`` (absolute times from the start at rest, t = 0): every segment evaluates the times that
  fall in it on its own dense output, vectorised (a time on a segment boundary goes to the later segment,
  as in the ``samples_per_cycle`` history); runs without it do no extra work.

Effects (MODELS.md section 6; every parameter off at 0 = absent; a non-zero parameter of an effect the
model does not have is an error)
-----------------------------------------------------------------------------------------------------
* indenter-metal / -sandstone: ``shaker_coil`` (tau, beta): tau dFem/dt + Fem = Fa sin(Om t) - beta phi1',
  Fem a state from Fem(0) = 0, or for tau = 0 the algebraic Fem = Fa sin(Om t) - beta phi1'; it acts on m1,
  its reaction on m2, and W integrates Fem phi1'.  ``rate_stiffening`` (alpha): k -> k (1 + alpha max(x1', 0))
  in the contact force, so for the metal also in its force indicator k1 (1 + ...) (x1 - G) + c1 x1' (the
  release surface); for the sandstone in both branches (so in loading only: x1' < 0 while unloading).
  ``guide_friction`` (mu): -mu tanh(phi1' / v_eps) on m1, reaction on m2 (v_eps as the seal's, 1e-4 m/s).
  ``suspension_hardening`` (kappa): k2 phi1 -> k2 phi1 (1 + kappa phi1^2).  Sandstone ``tip_blunting``
  (gamma): kl, ku -> (1 + gamma xh / 1 mm) with xh the crater floor held in the discrete state: xp while
  free or loading, the floor at the start of an unloading while unloading (the floor itself moves then).
  Both factors multiply kl and ku alike, so they cancel from the xp <-> xf relations of section 1b.
* drill: shaker_coil, rate_stiffening, guide_friction, tip_blunting, suspension_hardening as in ``_Drill``.
* pendulum: ``rate_stiffening``: Fi = ki (1 + alpha max(d', 0)) d + ci d' (and so its force indicator).
* rimd: ``rate_stiffening``: Fi = ki (1 + alpha max(x2', 0)) d^ni (1 + lambda_i x2') (the indicator
  1 + lambda_i x2' is unchanged); ``suspension_hardening``: k2 phi (1 + kappa phi^2), phi = x2 - x1.
* every model: ``sensor_lowpass`` (fc > 0): the measured acceleration z of the impacting mass (drill M1,
  indenter m1, RIMD m2, pendulum hammer absolute) is the true one a through the continuous 2nd-order
  Butterworth low-pass, z'' + sqrt(2) wc z' + wc^2 z = wc^2 a(t), wc = 2 pi fc: two ODE states after W,
  integrated with the model from rest (z = z' = 0 at t = 0), with a from the same right-hand side.  It
  changes no dynamics; peak_decel_g and the sampled ``accel_m_s2`` are of z (the window search then uses
  >= 10 samples per 1/fc in every segment and refines a maximum on a segment end too, since z is smooth
  across switches); the true a is ``accel_true_m_s2``.  The filter's poles (|s| = wc) bound an explicit
  method's step to a few / wc, so with fc >> f DOP853 runs cost more (pendulum at 3.75 Hz: x8 at fc =
  300 Hz, x35 at 3 kHz); method="LSODA" (stiff switching) then runs the 3 kHz case 8x faster than DOP853
  with labels within 2e-9 of it.

Discrepancy terms (the simulator's vocabulary for physics the library lacks: ``DISCREPANCY_PARAMS``, applicable
per model in ``DISCREPANCY``; each a parameter named as the term, >= 0, off at 0 = exactly the base model; a
non-zero term that does not apply is an error)
-----------------------------------------------------------------------------------------------------------
* contact terms, added INSIDE the model's contact force expression, so also in its release / threshold
  indicators: ``contact_quadratic`` cq [N/m^2] += cq max(d, 0)^2, ``contact_cubic`` cc [N/m^3] += cc max(d, 0)^3,
  ``contact_rate_product`` cp [N s/m^2] += cp max(d, 0) d'.
  - drill: P = K1 (1 + alpha max(x1', 0)) (x1 - xb) + C1 x1' + extras, d = x1 - xb, d' = x1': the phase-II force,
    the II -> I (P = 0) and II <-> III (P = Pr) surfaces, classify (and its dP/dt), the phase-III slider law
    xb' = (P - Pr) / C1.  The phase-I plate relaxation xt' = -(K1/C1)(xt - xb) and the onset x1 = xt are the
    base model's.
  - indenter-metal: k1 (1 + alpha ..) (x1 - G) + c1 x1' + extras, d = x1 - G (its force indicator too).
  - pendulum: ki (1 + alpha ..) d + ci d' + extras, d = l sin(th) - gap, d' = l th' cos(th) (force indicator too).
  - rimd: Fi = max(0, HC + extras) in contact, HC the Hunt-Crossley expression, d = x2 - gap, d' = x2'; the
    contact indicators stay d >= 0 and 1 + lambda_i x2' > 0 (so Fi may be 0 inside contact when cp x2' < 0).
  - indenter-sandstone: none (a non-zero contact term is an error).
* ``contact_drift_m_s`` a [m/s] (indenter-metal, pendulum; ``DRIFT``): the struck surface at gap + a t, so
  d = x - gap - a t and d' = x' - a wherever d and d' appear (the force, both indicators and their rates).
* tool terms, a force on the impacting mass: ``tool_viscous`` cv [N s/m] -cv v, ``tool_quadratic_drag`` cd
  [N s^2/m^2] -cd v |v|: drill M1 (v = x1'), indenter m1 (v = x1', both samples), rimd hammer m2 (v = x2');
  pendulum: tangential on the hammer, v = l th' (relative to the cart): th'' += -(cv th' + cd l th' |th'|) / m.
  They enter the impacting mass's acceleration everywhere (rhs, classify's free-flow rates, the recorded and
  filtered acceleration); the excitation work W is unchanged (it is the drive's work).

Tolerances
----------
``atol_i = rtol * atol_scale * s_i`` with ``s_i`` = 1 for a position in metres (so positions are "atol_scale
metres" typical, 1 mm by default), Omega for a velocity (1 mm * Omega: ~0.4-2.5 m/s for these models),
1/l for the pendulum angle, Omega/l for its rate, a force scale (F0, Fa, Fs, Pr ... whichever is
largest, N) for the work state W and the coil forces, Omega^2 for the filtered acceleration and
Omega^2 wc for its rate.  ``max_step = max_step_fraction * T`` (default T/20) so that a low-order
baseline (e.g. method="RK45", rtol=1e-6) cannot stride over the forcing.

Labels (MODELS.md section 5, over the recorded window)
------------------------------------------------------
* contact interval = from a contact onset (non-contact -> contact branch; drill phases II and III are
  both contact) to the next separation.  ``impacts_per_cycle`` = onsets in the window / window_cycles.
  ``mean_peak_force_n`` = mean of the maxima of the intervals whose onset lies in the window; an interval
  still open at the window end is followed past it (at most one more cycle) to its separation.  With
  persistent contact and no onset in the window (e.g. drill with F0 = 0 resting on the rock) it equals
  ``peak_force_n``; with no contact at all it is 0.  ``peak_force_n`` is the window maximum.
* ``period``: smallest n <= 8 with |s[k+n] - s[k]| <= 1e-3 * range_j for every k and bounded coordinate
  j (range_j from the dense samples of the window, floored at 1e-9 * its typical scale so that a constant
  coordinate does not demand exact equality); 0 if none (also when window_cycles <= n for every n).
* ``peak_decel_g`` = max over the window of -(measured acceleration of the impacting mass) / 9.81.
* ``energy_per_cycle_j`` = increase of the work state W over the window / window_cycles;
  ``specific_energy_j_m`` = window work / window progression (inf if progression <= 0 or the model
  cannot progress).  ``rop_m_s`` = progression / window duration (drill xb, sandstone xp; else 0).
* extras: ``status`` ('runaway' for a drill with Fs >= Pr, 'no_contact' if no contact in the window,
  else 'ok' -- the reference does not judge settling), ``strobe`` (window_cycles x n_bounded samples at
  the cycle starts), ``strobe_names``, ``n_events`` (switching events over the whole run, transient
  included), ``wall_s``; with samples_per_cycle > 0, ``history`` = dict of t_s, disp_m, force_n,
  accel_m_s2, progression_m (and accel_true_m_s2 if fc > 0) sampled at t = t_window_start + j T /
  samples_per_cycle; with sample_times, ``samples`` = dict of t_s (the times given), disp_m, vel_m_s,
  force_n, accel_m_s2 (measured), accel_true_m_s2, progression_m of the impacting mass (pendulum:
  absolute hammer position and velocity; progression: drill xb, sandstone the current crater floor).

Public entry point: :func:`reference_run`.
"""
from __future__ import annotations

import math
import time

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, OdeSolution, Radau
from scipy.optimize import brentq, minimize_scalar

G_ACC = 9.81              # g used to express decelerations in g
ETA_X = 1e-15             # hysteresis on position-like switching functions [m]
ETA_V = 1e-12             # hysteresis on velocity switching functions [m/s]
N_CONTACT_SAMPLES = 200   # dense-output samples per contact segment
N_FREE_PER_CYCLE = 200    # dense-output samples per cycle in non-contact segments (min 16 per segment)
N_PER_FC = 10             # with sensor_lowpass: at least this many samples per 1/fc in every segment

MODELS = ("drill", "indenter-metal", "indenter-sandstone", "pendulum", "rimd")

# section-6 effect parameters (off at 0) and the models that have each (MODELS.md section 6)
EFFECT_PARAMS = ("tau", "beta", "alpha", "mu", "gamma", "kappa", "fc")
EFFECTS = {
    "drill": ("tau", "beta", "alpha", "mu", "gamma", "kappa", "fc"),
    "indenter-metal": ("tau", "beta", "alpha", "mu", "kappa", "fc"),
    "indenter-sandstone": ("tau", "beta", "alpha", "mu", "gamma", "kappa", "fc"),
    "pendulum": ("alpha", "fc"),
    "rimd": ("alpha", "kappa", "fc"),
}


# discrepancy terms (the simulator's fixed vocabulary for physics the library lacks): each a parameter named as the
# term, >= 0, off at 0 (then the model is exactly the base model); the models each applies to
DISCREPANCY_PARAMS = ("contact_quadratic", "contact_cubic", "contact_rate_product", "tool_viscous",
                      "tool_quadratic_drag")
DISCREPANCY = {
    "drill": DISCREPANCY_PARAMS,
    "indenter-metal": DISCREPANCY_PARAMS,
    "indenter-sandstone": ("tool_viscous", "tool_quadratic_drag"),
    "pendulum": DISCREPANCY_PARAMS,
    "rimd": DISCREPANCY_PARAMS,
}


DRIFT = "contact_drift_m_s"
DRIFT_MODELS = ("indenter-metal", "pendulum")
"""A contact whose position moves at a steady rate a [m/s] from t = 0 (>= 0, off at 0): the struck surface at
gap + a t (t the absolute time: the cycle's start ``t_cycle0`` + the cycle's time), so d = x - (gap + a t) and
d' = x' - a everywhere d and d' appear (force, both indicators, their rates)."""


def _req(params: dict, names, model: str) -> dict:
    missing = [n for n in names if n not in params]
    if missing:
        raise KeyError(f"reference_run({model!r}): missing parameter(s) {missing}")
    return {n: float(params[n]) for n in names}


def _switched_params(params: dict, model: str, every: tuple, own: tuple, what: str) -> dict:
    """The ``own`` parameters of a switchable kind (``what``: "effect parameter", "discrepancy term"; absent = 0,
    each finite and >= 0); a non-zero one of ``every`` the model does not have is an error."""
    for n in every:
        if n not in own and float(params.get(n, 0.0)) != 0.0:
            raise ValueError(f"reference_run({model!r}): {what} {n!r} = {params[n]!r} does not apply "
                             f"to this model (its {what}s: {own})")
    out = {n: float(params.get(n, 0.0)) for n in own}
    bad = [n for n, v in out.items() if not (v >= 0.0 and math.isfinite(v))]
    if bad:
        raise ValueError(f"reference_run({model!r}): {what}(s) {bad} must be finite and >= 0")
    return out


def _effect_params(params: dict, model: str) -> dict:
    """The model's effect parameters (absent = 0); a non-zero effect the model does not have is an error."""
    return _switched_params(params, model, EFFECT_PARAMS, EFFECTS[model], "effect parameter")


def _discrepancy_params(params: dict, model: str) -> dict:
    """Every discrepancy term (absent = 0; those the model lacks stay 0): a non-zero one that does not apply to the
    model is an error."""
    out = _switched_params(params, model, DISCREPANCY_PARAMS, DISCREPANCY[model], "discrepancy term")
    return {n: out.get(n, 0.0) for n in DISCREPANCY_PARAMS}


def _extra(d, dd, cq, cc, cp):
    """Discrepancy contact terms cq max(d, 0)^2 + cc max(d, 0)^3 + cp max(d, 0) dd, scalar."""
    if d <= 0.0:
        return 0.0
    return d * (cq * d + cc * d * d + cp * dd)


def _extra_vec(d, dd, cq, cc, cp):
    """``_extra`` vectorised."""
    dp = np.maximum(d, 0.0)
    return dp * (cq * dp + cc * dp * dp + cp * dd)


def _extra_rate(d, dd, ddd, cq, cc, cp):
    """Forward time derivative of ``_extra`` given dd = d', ddd = d'' (d/dt+ max(d, 0) = max(d', 0) at d = 0)."""
    if d > 0.0:
        dpd = dd
    elif d == 0.0:
        dpd = max(dd, 0.0)
    else:
        return 0.0
    dp = max(d, 0.0)
    return dpd * (2.0 * cq * dp + 3.0 * cc * dp * dp + cp * dd) + cp * dp * ddd


def _tool(v, cv, cd):
    """Discrepancy tool terms: force -cv v - cd v |v| on the impacting mass (scalar or vectorised)."""
    return -cv * v - cd * v * abs(v)


# =====================================================================================================
# Model definitions.  Conventions:
#   * t is the local time in the current forcing cycle; forcing is periodic in T.
#   * rhs(t, y, br, disc) -> list of the core derivatives (scalar, hot path); ``flow`` appends the
#     sensor_lowpass states, fed by acc_of(t, y, dy) = the true acceleration of the impacting mass
#   * vectorised post-processing: force / accel / vel / disp / progression / bounded with t (N,), Y (n, N)
#   * classify(t, y, disc) -> (branch, y, disc) decides the branch at the start of every segment
#   * events(br, disc) -> list of (g, direction), g vectorised g(t (N,), Y (n, N)); all terminal
#   * on_segment_end / on_event update the discrete state disc
#   * state layout: the model's states, the work W (index iW), then the two filter states (fc > 0 only)
# =====================================================================================================
class _Model:
    name = ""
    bounded_names: tuple = ()
    contact_branches: tuple = (1,)

    def __init__(self, p: dict):
        self.p = p
        self.f = p["frequency_hz"]
        if not self.f > 0:
            raise ValueError("frequency_hz must be > 0")
        self.T = 1.0 / self.f
        self.Om = 2.0 * math.pi * self.f

    def _init_discrepancy(self, params: dict):
        """Discrepancy terms (``_discrepancy_params``) into p and attributes; dcon / dtool: any contact / tool
        term on (every use is guarded by them, so with all terms at 0 nothing is computed differently)."""
        self.p.update(_discrepancy_params(params, self.name))
        p = self.p
        self.dq, self.dc, self.dp = p["contact_quadratic"], p["contact_cubic"], p["contact_rate_product"]
        self.tv, self.td = p["tool_viscous"], p["tool_quadratic_drag"]
        self.dcon = bool(self.dq or self.dc or self.dp)
        self.dtool = bool(self.tv or self.td)
        self.t_cycle0 = 0.0
        self.t_now = 0.0        # the cycle's time of the last rhs call (the force helpers' signatures carry no t)
        own = (DRIFT,) if self.name in DRIFT_MODELS else ()
        self.drift = _switched_params(params, self.name, (DRIFT,), own, "discrepancy candidate").get(DRIFT, 0.0)

    def _init_sensor(self):
        """sensor_lowpass: z'' + sqrt(2) wc z' + wc^2 z = wc^2 a(t), two states after W (call once scales is set)."""
        self.iW = len(self.scales) - 1
        self.fc = self.p.get("fc", 0.0)
        self.iz = None
        if self.fc > 0.0:
            self.wc = 2.0 * math.pi * self.fc
            self.iz = len(self.scales)
            # atol: 1 mm * Om^2 for the measured acceleration, times wc for its rate
            self.scales = list(self.scales) + [self.Om ** 2, self.Om ** 2 * self.wc]

    def initial_state(self):
        y, disc = self.initial()
        if self.iz is not None:
            y = np.concatenate([y, [0.0, 0.0]])
        return y, disc

    def flow(self, br, disc):
        """y' = fun(t, y) on branch br: the model's rhs, plus the sensor filter if fc > 0."""
        rhs = self.rhs
        if self.iz is None:
            return lambda t, y: rhs(t, y, br, disc)
        iz, wc2, c, acc = self.iz, self.wc ** 2, math.sqrt(2.0) * self.wc, self.acc_of

        def fun(t, y):
            dy = rhs(t, y, br, disc)
            a = acc(t, y, dy)
            zd = y[iz + 1]
            dy.append(zd)
            dy.append(wc2 * (a - y[iz]) - c * zd)
            return dy
        return fun

    def accel_meas(self, t, Y, br, disc):
        """Measured acceleration of the impacting mass: the filter output if fc > 0, else the true one."""
        if self.iz is None:
            return self.accel(t, Y, br, disc)
        return Y[self.iz]

    def observe(self, t, Y, br, disc) -> dict:
        a = self.accel(t, Y, br, disc)
        return {"disp_m": self.disp(t, Y, br, disc), "vel_m_s": self.vel(t, Y, br, disc),
                "force_n": self.force(t, Y, br, disc),
                "accel_m_s2": a if self.iz is None else Y[self.iz], "accel_true_m_s2": a,
                "progression_m": self.progression(t, Y, br, disc)}

    # defaults ------------------------------------------------------------------------------------
    def is_contact(self, br) -> bool:
        return br in self.contact_branches

    def on_segment_end(self, br, t, y, disc):
        return disc

    def on_event(self, br, idx, t, y, disc):
        return y, disc

    def progression_scalar(self, y, disc) -> float:
        return 0.0

    def progression(self, t, Y, br, disc):
        return np.zeros_like(t)

    def atol(self, rtol, atol_scale):
        return rtol * atol_scale * np.asarray(self.scales, dtype=float)


class _TwoIndicatorModel(_Model):
    """Two-branch model (0 = free, 1 = contact) whose contact set is {g1 >= 0 and g2 > 0}.

    g = min(g1, g2) is continuous; entry = g rising through +eta, exit = g falling through -eta.
    Subclasses give indicators(t, y) -> (g1, g2) and free-flow rates(t, y) -> (dg1/dt, dg2/dt)
    (on the boundary the contact force is zero, or about to jump up, so the free flow decides).
    g2 is the contact force expression divided by a positive stiffness-like factor (metres).
    """

    eta = ETA_X

    def classify(self, t, y, disc):
        g1, g2 = self.indicators(t, y)
        g = min(g1, g2)
        if g > self.eta:
            return 1, y, disc
        if g < -self.eta:
            return 0, y, disc
        r1, r2 = self.rates(t, y)
        active = [r for gi, r in ((g1, r1), (g2, r2)) if gi <= self.eta]
        return (1 if min(active) > 0.0 else 0), y, disc

    def events(self, br, disc):
        eta = self.eta
        ind = self.indicators
        if br == 0:
            def enter(t, y):
                a, b = ind(t, y)
                return np.minimum(a, b) - eta
            return [(enter, 1.0)]

        def leave(t, y):
            a, b = ind(t, y)
            return np.minimum(a, b) + eta
        return [(leave, -1.0)]


def _stiffened_indicators(d, dd, alpha, tau):
    """(d, d (1 + alpha max(dd, 0)) + tau dd): penetration and force expression / k of a Kelvin-Voigt contact
    k (1 + alpha max(dd, 0)) d + c dd, tau = c / k (scalar or vectorised)."""
    return d, d * (1.0 + alpha * np.maximum(dd, 0.0)) + tau * dd


def _stiffened_rates(d, dd, ddd, alpha, tau):
    """Time derivatives of ``_stiffened_indicators`` given dd = d', ddd = d'' (scalar)."""
    r2 = dd * (1.0 + alpha * max(dd, 0.0)) + tau * ddd
    if dd > 0.0:
        r2 += alpha * ddd * d
    return dd, r2


# ---------------------------------------------------------------------------------------------------
# 2. drill
# ---------------------------------------------------------------------------------------------------
class _Drill(_Model):
    """MODELS.md section 2 with the section-6 drill effects (all off at 0, the default):
    shaker_coil (tau, beta): the harmonic force on M1 is Fh, tau dFh/dt + Fh = F0 cos(Om t) - beta (v1 - v2),
    Fh(0) = 0; tau = 0 means the algebraic limit Fh = F0 cos(Om t) - beta (v1 - v2) (state Fh unused, stays 0).
    rate_stiffening (alpha): contact expression P = K1 (1 + alpha max(v1, 0)) (x1 - xb) + C1 v1 (phase II force,
    switching surfaces, and the slider law of phase III).  guide_friction (mu, v_eps): -mu tanh((v1 - v2)/v_eps)
    on M1, reaction on M2.  tip_blunting (gamma): threshold Pr (1 + gamma (xb - G) / 1 mm).
    suspension_hardening (kappa): K2 d (1 + kappa d^2), d = x1 - x2.  sensor_lowpass (fc): on a1.
    """
    name = "drill"
    # phases: 0 = I (no contact), 1 = II (contact, no progression), 2 = III (contact with progression)
    contact_branches = (1, 2)
    bounded_names = ("x1-xb", "x2-xb", "x3-xb", "xt-xb", "v1", "v2", "v3", "Fh")
    PARAMS = ("M1", "M2", "M3", "K1", "K2", "K3", "C1", "C2", "C3", "Pr",
              "gap_m", "static_force_n", "amplitude_n", "frequency_hz")

    def __init__(self, params):
        params = dict(params)
        params.setdefault("v_eps", 1e-4)
        p = _req(params, self.PARAMS + ("v_eps",), self.name)
        p.update(_effect_params(params, self.name))
        super().__init__(p)
        self._init_discrepancy(params)
        self.G, self.Fs, self.F0 = p["gap_m"], p["static_force_n"], p["amplitude_n"]
        self.coil_state = p["tau"] > 0.0
        fsc = max(abs(self.F0), abs(self.Fs), p["Pr"], 1.0)
        # state [x1, v1, x2, v2, x3, v3, xt, xb, Fh, W]; Fh in N: same "atol_scale * force scale" as W
        self.scales = [1, self.Om, 1, self.Om, 1, self.Om, 1, 1, fsc, fsc]
        self.etaP = 1e-10 * max(p["Pr"], 1.0)
        self.bscales = np.array([1, 1, 1, 1, self.Om, self.Om, self.Om, fsc])
        self._init_sensor()

    def initial(self):
        G = self.G
        return np.array([0, 0, 0, 0, 0, 0, G, G, 0, 0.0]), None

    # effect-aware pieces (scalar) -----------------------------------------------------------------
    def _F(self, t, y):
        """Force the exciter applies to M1."""
        if self.coil_state:
            return y[8]
        return self.F0 * math.cos(self.Om * t) - self.p["beta"] * (y[1] - y[3])

    def _P(self, y):
        """Phase-II contact expression (rate_stiffening acts on K1; discrepancy contact terms, d = x1 - xb)."""
        p = self.p
        P = p["K1"] * (1.0 + p["alpha"] * max(y[1], 0.0)) * (y[0] - y[7]) + p["C1"] * y[1]
        if self.dcon:
            P += _extra(y[0] - y[7], y[1], self.dq, self.dc, self.dp)
        return P

    def _Pr(self, y):
        return self.p["Pr"] * (1.0 + self.p["gamma"] * (y[7] - self.G) / 1e-3)

    def _link(self, y):
        """Force of the bit-exciter link on M1 (pulls M1 back, pushes M2): damper + spring + guides."""
        p = self.p
        d, dv = y[0] - y[2], y[1] - y[3]
        return (p["C2"] * dv + p["K2"] * d * (1.0 + p["kappa"] * d * d)
                + p["mu"] * math.tanh(dv / p["v_eps"]))

    def rhs(self, t, y, br, disc):
        p = self.p
        v1, x2, v2, x3, v3, xt, xb, Fh = y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8]
        K1, C1 = p["K1"], p["C1"]
        if br == 0:
            Pc = 0.0
            dxt = -(K1 / C1) * (xt - xb)
            dxb = 0.0
        elif br == 1:
            Pc = self._P(y)
            dxt = v1
            dxb = 0.0
        else:
            Pc = self._Pr(y)
            dxt = v1
            dxb = (self._P(y) - Pc) / C1
        F = self._F(t, y)
        link = self._link(y)
        a1 = (F - link - Pc) / p["M1"]
        if self.dtool:
            a1 += _tool(v1, self.tv, self.td) / p["M1"]
        a2 = (self.Fs + link - p["C3"] * (v2 - v3) - p["K3"] * (x2 - x3)) / p["M2"]
        a3 = (-p["C3"] * (v3 - v2) - p["K3"] * (x3 - x2)) / p["M3"]
        if self.coil_state:
            dFh = (self.F0 * math.cos(self.Om * t) - p["beta"] * (v1 - v2) - Fh) / p["tau"]
        else:
            dFh = 0.0
        return [v1, a1, v2, a2, v3, a3, dxt, dxb, dFh, F * v1]

    def acc_of(self, t, y, dy):
        return dy[1]

    def _a1(self, t, y, Pc):
        a1 = (self._F(t, y) - self._link(y) - Pc) / self.p["M1"]
        if self.dtool:
            a1 += _tool(y[1], self.tv, self.td) / self.p["M1"]
        return a1

    def _Pdot(self, t, y, Pc):
        """dP/dt along the phase-II flow (xb fixed) with contact force Pc acting on the bit."""
        p = self.p
        a1 = self._a1(t, y, Pc)
        v1 = y[1]
        k1 = p["K1"] * (1.0 + p["alpha"] * max(v1, 0.0))
        dk1 = p["K1"] * p["alpha"] * a1 if v1 > 0.0 else 0.0
        r = k1 * v1 + dk1 * (y[0] - y[7]) + p["C1"] * a1
        if self.dcon:
            r += _extra_rate(y[0] - y[7], v1, a1, self.dq, self.dc, self.dp)
        return r

    def classify(self, t, y, disc):
        x1, xt = y[0], y[6]
        d = x1 - xt
        if d < -ETA_X:
            return 0, y, None
        # at (or beyond) the plate: d(x1 - xt)/dt in phase I equals the base P/C1; at x1 = xt >= xb the
        # rate_stiffening term K1 alpha max(v1, 0) (x1 - xb) >= 0 vanishes unless v1 > 0, so P has the same sign.
        # The discrepancy contact terms break that agreement (the plate relaxes by the base law in phase I):
        # contact is then {x1 >= xt and P > 0} (the two-indicator rule of MODELS.md 1a), the branch follows P, the
        # full expression, and a state at or beyond the plate with P <= 0 is phase I "overlapping" (disc True):
        # e.g. right after every release with contact_rate_product, which leaves P_base = -cp (x1 - xb) x1' > 0
        # there, so the plate relaxes into the bit force-free.  Its events: P rising through 0 (contact again,
        # the plate on the bit) or x1 falling behind the plate (by 2 eta, so classify then sees d < -eta).
        P = self._P(y)
        Pr = self._Pr(y)
        eP = self.etaP
        if P > Pr + eP:
            br = 2
        elif P >= Pr - eP:                     # on the II/III surface: where does P go?
            br = 2 if self._Pdot(t, y, Pr) > 0.0 else 1
        elif P > eP:
            br = 1
        elif P >= -eP:                         # on the I/II surface
            br = 1 if self._Pdot(t, y, 0.0) > 0.0 else 0
        else:
            br = 0
        if br != 0:
            y = y.copy()
            y[6] = x1          # plate rides on the bit
        return br, y, (True if (br == 0 and self.dcon) else None)

    def _P_vec(self, Y):
        p = self.p
        P = p["K1"] * (1.0 + p["alpha"] * np.maximum(Y[1], 0.0)) * (Y[0] - Y[7]) + p["C1"] * Y[1]
        if self.dcon:
            P = P + _extra_vec(Y[0] - Y[7], Y[1], self.dq, self.dc, self.dp)
        return P

    def _Pr_vec(self, Y):
        return self.p["Pr"] * (1.0 + self.p["gamma"] * (Y[7] - self.G) / 1e-3)

    def events(self, br, disc):
        eP = self.etaP
        P, Pr = self._P_vec, self._Pr_vec
        if br == 0:
            if disc:           # overlapping the plate (discrepancy contact terms only; classify)
                return [(lambda t, y: P(y) - eP, 1.0),
                        (lambda t, y: y[0] - y[6] + 2.0 * ETA_X, -1.0)]
            return [(lambda t, y: y[0] - y[6] - ETA_X, 1.0)]
        if br == 1:
            return [(lambda t, y: P(y) + eP, -1.0),               # -> I
                    (lambda t, y: P(y) - Pr(y) - eP, 1.0)]        # -> III
        return [(lambda t, y: P(y) - Pr(y) + eP, -1.0)]           # -> II

    def on_event(self, br, idx, t, y, disc):
        if br != 0:
            y = y.copy()
            y[6] = y[0]
        return y, disc

    # vectorised ------------------------------------------------------------------------------------
    def force(self, t, Y, br, disc):
        if br == 0:
            return np.zeros_like(t)
        if br == 1:
            return np.maximum(self._P_vec(Y), 0.0)
        return self._Pr_vec(Y) * np.ones_like(t)

    def accel(self, t, Y, br, disc):
        p = self.p
        if br == 0:
            Pc = 0.0
        elif br == 1:
            Pc = self._P_vec(Y)
        else:
            Pc = self._Pr_vec(Y)
        if self.coil_state:
            F = Y[8]
        else:
            F = self.F0 * np.cos(self.Om * t) - p["beta"] * (Y[1] - Y[3])
        d, dv = Y[0] - Y[2], Y[1] - Y[3]
        link = p["C2"] * dv + p["K2"] * d * (1.0 + p["kappa"] * d * d) + p["mu"] * np.tanh(dv / p["v_eps"])
        a1 = (F - link - Pc) / p["M1"]
        if self.dtool:
            a1 = a1 + _tool(Y[1], self.tv, self.td) / p["M1"]
        return a1

    def disp(self, t, Y, br, disc):
        return Y[0]

    def vel(self, t, Y, br, disc):
        return Y[1]

    def progression(self, t, Y, br, disc):
        return Y[7]

    def progression_scalar(self, y, disc):
        return float(y[7])

    def bounded(self, t, Y, br, disc):
        xb = Y[7]
        return np.array([Y[0] - xb, Y[2] - xb, Y[4] - xb, Y[6] - xb, Y[1], Y[3], Y[5], Y[8]])


# ---------------------------------------------------------------------------------------------------
# 1. indenter (shared part)
# ---------------------------------------------------------------------------------------------------
class _IndenterBase(_Model):
    """MODELS.md section 1 with the section-6 indenter effects (all off at 0):
    shaker_coil (tau, beta): tau dFem/dt + Fem = Fa sin(Om t) - beta phi1', Fem(0) = 0; tau = 0 is the algebraic
    limit Fem = Fa sin(Om t) - beta phi1' (state Fem unused, stays 0); the force acts on m1, its reaction on m2, and
    W integrates Fem phi1'.  suspension_hardening (kappa): k2 phi1 -> k2 phi1 (1 + kappa phi1^2).
    guide_friction (mu): -mu tanh(phi1' / v_eps) on m1, reaction on m2.  rate_stiffening / tip_blunting: in the
    contact laws of the subclasses.  sensor_lowpass (fc): on a1.
    """
    COMMON = ("m1", "m2", "m3", "k2", "c2", "k3", "c3", "pm",
              "gap_m", "static_force_n", "amplitude_n", "frequency_hz")

    def _setup(self, params, extra):
        params = dict(params)
        params.setdefault("v_eps", 1e-4)
        p = _req(params, self.COMMON + ("v_eps",) + extra, self.name)
        p.update(_effect_params(params, self.name))
        _Model.__init__(self, p)
        self._init_discrepancy(params)
        self.G, self.Fp, self.Fa = p["gap_m"], p["static_force_n"], p["amplitude_n"]
        self.coil_state = p["tau"] > 0.0
        self.alpha, self.mu, self.kappa, self.beta = p["alpha"], p["mu"], p["kappa"], p["beta"]
        fsc = max(abs(self.Fa), abs(self.Fp), 1.0)
        # state [x1, v1, x2, v2, x3, v3, Fem, W]
        self.scales = [1, self.Om, 1, self.Om, 1, self.Om, fsc, fsc]
        self._init_sensor()

    def initial(self):
        return np.zeros(8), self._disc0()

    def _disc0(self):
        return None

    def _body(self, t, y, Fr):
        """Derivatives for a given contact force Fr (scalar path)."""
        p = self.p
        x1, v1, x2, v2, x3, v3 = y[0], y[1], y[2], y[3], y[4], y[5]
        phi, dphi = x1 - x2, v1 - v2
        drive = self.Fa * math.sin(self.Om * t)
        if self.coil_state:
            Fem = y[6]
            dFem = (drive - self.beta * dphi - Fem) / p["tau"]
        else:
            Fem = drive - self.beta * dphi
            dFem = 0.0
        f1 = p["c2"] * dphi + p["k2"] * phi * (1.0 + self.kappa * phi * phi)
        if self.mu:
            f1 += self.mu * math.tanh(dphi / p["v_eps"])
        f2 = p["c3"] * (v2 - v3) + p["k3"] * (x2 - x3)
        a1 = (Fem - f1 - Fr) / p["m1"]
        if self.dtool:
            a1 += _tool(v1, self.tv, self.td) / p["m1"]
        a2 = (-Fem + f1 - f2) / p["m2"]
        a3 = (self.Fp + f2 - p["pm"] * math.tanh(v2 / p["v_eps"])) / p["m3"]
        return [v1, a1, v2, a2, v3, a3, dFem, Fem * dphi]

    def acc_of(self, t, y, dy):
        return dy[1]

    def _a1_vec(self, t, Y, Fr):
        p = self.p
        phi, dphi = Y[0] - Y[2], Y[1] - Y[3]
        Fem = Y[6] if self.coil_state else self.Fa * np.sin(self.Om * t) - self.beta * dphi
        f1 = p["c2"] * dphi + p["k2"] * phi * (1.0 + self.kappa * phi * phi)
        if self.mu:
            f1 = f1 + self.mu * np.tanh(dphi / p["v_eps"])
        a1 = (Fem - f1 - Fr) / p["m1"]
        if self.dtool:
            a1 = a1 + _tool(Y[1], self.tv, self.td) / p["m1"]
        return a1

    def disp(self, t, Y, br, disc):
        return Y[0]

    def vel(self, t, Y, br, disc):
        return Y[1]


class _IndenterMetal(_TwoIndicatorModel, _IndenterBase):
    """Fr = max(0, k1 (1 + alpha max(v1, 0)) (x1 - G) + c1 v1): rate_stiffening enters the force expression, and
    so the second (force) indicator of the two-indicator contact."""
    name = "indenter-metal"
    bounded_names = ("x1", "v1", "x2", "v2")

    def __init__(self, params):
        self._setup(params, ("k1", "c1"))
        self.t_kv = self.p["c1"] / self.p["k1"]
        self.bscales = np.array([1, self.Om, 1, self.Om])

    def _pen(self, t, x1, v1):
        """Penetration and its rate of the (drifting) face G + a t."""
        return x1 - self.G - self.drift * (self.t_cycle0 + t), v1 - self.drift

    def _Fr(self, y):
        p = self.p
        d, dd = self._pen(self.t_now, y[0], y[1])
        F = p["k1"] * (1.0 + self.alpha * max(dd, 0.0)) * d + p["c1"] * dd
        if self.dcon:
            F += _extra(d, dd, self.dq, self.dc, self.dp)
        return max(0.0, F)

    def rhs(self, t, y, br, disc):
        self.t_now = t
        return self._body(t, y, self._Fr(y) if br == 1 else 0.0)

    def indicators(self, t, y):
        d, dd = self._pen(t, y[0], y[1])
        g1, g2 = _stiffened_indicators(d, dd, self.alpha, self.t_kv)
        if self.dcon:
            g2 = g2 + _extra_vec(d, dd, self.dq, self.dc, self.dp) / self.p["k1"]
        return g1, g2

    def rates(self, t, y):
        a1 = self._body(t, y, 0.0)[1]
        d, dd = self._pen(t, y[0], y[1])
        r1, r2 = _stiffened_rates(d, dd, a1, self.alpha, self.t_kv)
        if self.dcon:
            r2 += _extra_rate(d, dd, a1, self.dq, self.dc, self.dp) / self.p["k1"]
        return r1, r2

    def force(self, t, Y, br, disc):
        if br == 0:
            return np.zeros_like(t)
        p = self.p
        d, dd = self._pen(t, Y[0], Y[1])
        F = p["k1"] * (1.0 + self.alpha * np.maximum(dd, 0.0)) * d + p["c1"] * dd
        if self.dcon:
            F = F + _extra_vec(d, dd, self.dq, self.dc, self.dp)
        return np.maximum(F, 0.0)

    def accel(self, t, Y, br, disc):
        return self._a1_vec(t, Y, self.force(t, Y, br, disc))

    def bounded(self, t, Y, br, disc):
        return np.array([Y[0], Y[1], Y[2], Y[3]])


class _IndenterSandstone(_IndenterBase):
    """Branches: 0 free, 1 loading, 2 unloading.  disc = (xp, xf, xh), kept current at every segment end.

    Both branch stiffnesses carry the factor (1 + gamma xh / 1 mm)(1 + alpha max(v1, 0)) (tip_blunting,
    rate_stiffening), which cancels from the algebraic xp <-> xf relations.  xh is the crater floor held for the
    blunting: xp while free or loading, the floor at the start of the unloading while unloading (the floor
    itself moves continuously then); on reloading it takes the floor of that moment.  rate_stiffening acts in
    loading only (v1 < 0 while unloading).
    """
    name = "indenter-sandstone"
    contact_branches = (1, 2)
    bounded_names = ("x1-xp", "v1", "x2-xp", "v2")

    def __init__(self, params):
        self._setup(params, ("kl", "ku", "nl", "nu"))
        p = self.p
        self.kl, self.ku, self.nl, self.nu = p["kl"], p["ku"], p["nl"], p["nu"]
        self.gamma = p["gamma"]
        self.eta4 = ETA_X * min(1.0, self.kl / self.ku)
        self.bscales = np.array([1, self.Om, 1, self.Om])

    def _disc0(self):
        return (0.0, 0.0, 0.0)

    # algebraic relations of seed Eqs. 9-10 (exact form, MODELS.md 1b)
    def _xf_from_xp(self, x1, xp):
        phi3 = max(x1 - self.G - xp, 0.0)
        return x1 - self.G - (self.kl * phi3 ** self.nl / self.ku) ** (1.0 / self.nu)

    def _xp_from_xf(self, x1, xf):
        phi4 = max(x1 - self.G - xf, 0.0)
        return x1 - self.G - (self.ku * phi4 ** self.nu / self.kl) ** (1.0 / self.nl)

    def _fac(self, v1, xh):
        """(1 + gamma xh / 1 mm)(1 + alpha max(v1, 0)), scalar."""
        return (1.0 + self.gamma * xh / 1e-3) * (1.0 + self.alpha * max(v1, 0.0))

    def _fac_vec(self, V1, xh):
        return (1.0 + self.gamma * xh / 1e-3) * (1.0 + self.alpha * np.maximum(V1, 0.0))

    def _Fr(self, x1, v1, br, disc):
        xp, xf, xh = disc
        if br == 1:
            return self.kl * self._fac(v1, xh) * max(x1 - self.G - xp, 0.0) ** self.nl
        if br == 2:
            return self.ku * self._fac(v1, xh) * max(x1 - self.G - xf, 0.0) ** self.nu
        return 0.0

    def rhs(self, t, y, br, disc):
        return self._body(t, y, self._Fr(y[0], y[1], br, disc))

    def classify(self, t, y, disc):
        xp, xf, xh = disc
        x1, v1 = y[0], y[1]
        phi3 = x1 - self.G - xp
        if phi3 < -ETA_X:
            return 0, y, (xp, xp, xp)
        if phi3 > ETA_X:
            contact = True
        else:
            contact = v1 > ETA_V or (abs(v1) <= ETA_V and self._body(t, y, 0.0)[1] > 0.0)
        if not contact:
            return 0, y, (xp, xp, xp)
        F = self.kl * self._fac(v1, xp) * max(phi3, 0.0) ** self.nl
        loading = v1 > ETA_V or (abs(v1) <= ETA_V and self._body(t, y, F)[1] > 0.0)
        xf = self._xf_from_xp(x1, xp)
        if loading:
            return 1, y, (xp, xf, xp)
        return 2, y, (xp, xf, xh)

    def events(self, br, disc):
        xp, xf, _ = disc
        G = self.G
        if br == 0:
            return [(lambda t, y: y[0] - G - xp - ETA_X, 1.0)]
        if br == 1:
            return [(lambda t, y: y[1] + ETA_V, -1.0),                 # velocity reversal -> unloading
                    (lambda t, y: y[0] - G - xp + ETA_X, -1.0)]        # (safety) back off the floor
        return [(lambda t, y: y[0] - G - xf + self.eta4, -1.0),        # fully unloaded -> free
                (lambda t, y: y[1] - ETA_V, 1.0)]                      # reversal -> reloading

    def on_segment_end(self, br, t, y, disc):
        xp, xf, xh = disc
        if br == 1:
            return (xp, self._xf_from_xp(y[0], xp), xh)
        if br == 2:
            return (self._xp_from_xf(y[0], xf), xf, xh)
        return disc

    def on_event(self, br, idx, t, y, disc):
        xp, xf, xh = disc
        if br == 2 and idx == 0:       # left contact while unloading: crater floor = end of unloading branch
            return y, (xf, xf, xf)
        if br == 1 and idx == 1:
            return y, (xp, xp, xp)
        return y, disc

    def _xp_vec(self, Y, br, disc):
        xp, xf, _ = disc
        if br == 2:
            phi4 = np.maximum(Y[0] - self.G - xf, 0.0)
            return Y[0] - self.G - (self.ku * phi4 ** self.nu / self.kl) ** (1.0 / self.nl)
        return np.full(Y.shape[1], xp)

    def force(self, t, Y, br, disc):
        xp, xf, xh = disc
        if br == 1:
            return self.kl * self._fac_vec(Y[1], xh) * np.maximum(Y[0] - self.G - xp, 0.0) ** self.nl
        if br == 2:
            return self.ku * self._fac_vec(Y[1], xh) * np.maximum(Y[0] - self.G - xf, 0.0) ** self.nu
        return np.zeros_like(t)

    def accel(self, t, Y, br, disc):
        return self._a1_vec(t, Y, self.force(t, Y, br, disc))

    def progression(self, t, Y, br, disc):
        return self._xp_vec(Y, br, disc)

    def progression_scalar(self, y, disc):
        return float(disc[0])

    def bounded(self, t, Y, br, disc):
        xp = self._xp_vec(Y, br, disc)
        return np.array([Y[0] - xp, Y[1], Y[2] - xp, Y[3]])


# ---------------------------------------------------------------------------------------------------
# 3. pendulum
# ---------------------------------------------------------------------------------------------------
class _Pendulum(_TwoIndicatorModel):
    """Fi = max(0, ki (1 + alpha max(d', 0)) d + ci d') (rate_stiffening), d = l sin(th) - gap; sensor_lowpass on
    the absolute hammer acceleration l (th'' cos th - th'^2 sin th) - A0 Om^2 sin(Om t)."""
    name = "pendulum"
    bounded_names = ("theta", "theta_dot")
    PARAMS = ("m", "l", "amplitude_m", "ki", "ci", "zeta", "gap_m", "frequency_hz")

    def __init__(self, params):
        params = dict(params)
        params.setdefault("g", 9.81)
        p = _req(params, self.PARAMS + ("g",), self.name)
        p.update(_effect_params(params, self.name))
        super().__init__(p)
        self._init_discrepancy(params)
        self.l, self.A0, self.gap, self.m = p["l"], p["amplitude_m"], p["gap_m"], p["m"]
        self.alpha = p["alpha"]
        self.w0 = math.sqrt(p["g"] / self.l)
        self.Aacc = self.A0 * self.Om ** 2 / self.l
        self.t_kv = p["ci"] / p["ki"]
        fsc = max(self.m * self.A0 * self.Om ** 2, 1e-3)
        # state [theta, theta_dot, W]; W in J = N * m  -> scale force * 1 m
        self.scales = [1.0 / self.l, self.Om / self.l, fsc]
        self.bscales = np.array([1.0 / self.l, self.Om / self.l])
        self._init_sensor()

    def initial(self):
        return np.zeros(3), None

    def _thdd(self, t, th, om, Fi):
        p = self.p
        c = math.cos(th)
        thdd = (self.Aacc * c * math.sin(self.Om * t) - (p["g"] / self.l) * math.sin(th)
                - 2.0 * p["zeta"] * self.w0 * om - Fi * c / (self.m * self.l))
        if self.dtool:     # tangential -cv (l th') - cd (l th') |l th'| on the hammer, over m l
            thdd -= (self.tv * om + self.td * self.l * om * abs(om)) / self.m
        return thdd

    def _Fi(self, th, om):
        p = self.p
        d = self.l * math.sin(th) - self.gap - self.drift * (self.t_cycle0 + self.t_now)
        dd = self.l * om * math.cos(th) - self.drift
        F = p["ki"] * (1.0 + self.alpha * max(dd, 0.0)) * d + p["ci"] * dd
        if self.dcon:
            F += _extra(d, dd, self.dq, self.dc, self.dp)
        return max(0.0, F)

    def rhs(self, t, y, br, disc):
        th, om = y[0], y[1]
        self.t_now = t
        Fi = self._Fi(th, om) if br == 1 else 0.0
        W = self.m * self.l * self.A0 * self.Om ** 2 * math.sin(self.Om * t) * math.cos(th) * om
        return [om, self._thdd(t, th, om, Fi), W]

    def acc_of(self, t, y, dy):
        th, om = y[0], y[1]
        return (self.l * (dy[1] * math.cos(th) - om * om * math.sin(th))
                - self.A0 * self.Om ** 2 * math.sin(self.Om * t))

    def indicators(self, t, y):
        th, om = y[0], y[1]
        d = self.l * np.sin(th) - self.gap - self.drift * (self.t_cycle0 + t)
        dd = self.l * om * np.cos(th) - self.drift
        g1, g2 = _stiffened_indicators(d, dd, self.alpha, self.t_kv)
        if self.dcon:
            g2 = g2 + _extra_vec(d, dd, self.dq, self.dc, self.dp) / self.p["ki"]
        return g1, g2

    def rates(self, t, y):
        th, om = y[0], y[1]
        dd = self.l * om * math.cos(th) - self.drift
        thdd = self._thdd(t, th, om, 0.0)
        ddd = self.l * (thdd * math.cos(th) - om * om * math.sin(th))
        d = self.l * math.sin(th) - self.gap - self.drift * (self.t_cycle0 + t)
        r1, r2 = _stiffened_rates(d, dd, ddd, self.alpha, self.t_kv)
        if self.dcon:
            r2 += _extra_rate(d, dd, ddd, self.dq, self.dc, self.dp) / self.p["ki"]
        return r1, r2

    def force(self, t, Y, br, disc):
        if br == 0:
            return np.zeros_like(t)
        p = self.p
        dd = self.l * Y[1] * np.cos(Y[0]) - self.drift
        d = self.l * np.sin(Y[0]) - self.gap - self.drift * (self.t_cycle0 + t)
        F = p["ki"] * (1.0 + self.alpha * np.maximum(dd, 0.0)) * d + p["ci"] * dd
        if self.dcon:
            F = F + _extra_vec(d, dd, self.dq, self.dc, self.dp)
        return np.maximum(F, 0.0)

    def accel(self, t, Y, br, disc):
        p = self.p
        th, om = Y[0], Y[1]
        Fi = self.force(t, Y, br, disc)
        c = np.cos(th)
        thdd = (self.Aacc * c * np.sin(self.Om * t) - (p["g"] / self.l) * np.sin(th)
                - 2.0 * p["zeta"] * self.w0 * om - Fi * c / (self.m * self.l))
        if self.dtool:
            thdd = thdd - (self.tv * om + self.td * self.l * om * np.abs(om)) / self.m
        return self.l * (thdd * c - om * om * np.sin(th)) - self.A0 * self.Om ** 2 * np.sin(self.Om * t)

    def disp(self, t, Y, br, disc):
        return self.l * np.sin(Y[0]) + self.A0 * np.sin(self.Om * t)

    def vel(self, t, Y, br, disc):
        return self.l * Y[1] * np.cos(Y[0]) + self.A0 * self.Om * np.cos(self.Om * t)

    def bounded(self, t, Y, br, disc):
        return np.array([Y[0], Y[1]])


# ---------------------------------------------------------------------------------------------------
# 4. RIMD
# ---------------------------------------------------------------------------------------------------
class _Rimd(_TwoIndicatorModel):
    """Fi = max(0, ki (1 + alpha max(v2, 0)) d^ni (1 + lambda_i v2)) (rate_stiffening; the force indicator
    1 + lambda_i v2 is unchanged); suspension_hardening: k2 phi -> k2 phi (1 + kappa phi^2), phi = x2 - x1;
    sensor_lowpass on a2."""
    name = "rimd"
    bounded_names = ("x1", "v1", "x2", "v2")
    PARAMS = ("m1", "k1", "c1", "m2", "k2", "c2", "ki", "lambda_i", "ni",
              "amplitude_n", "gap_m", "frequency_hz")
    LS = 1e-3   # length scale multiplying the dimensionless indicator (1 + lambda*v2) [m]

    def __init__(self, params):
        p = _req(params, self.PARAMS, self.name)
        p.update(_effect_params(params, self.name))
        super().__init__(p)
        self._init_discrepancy(params)
        self.F0, self.gap = p["amplitude_n"], p["gap_m"]
        self.alpha, self.kappa = p["alpha"], p["kappa"]
        fsc = max(abs(self.F0), 1e-3)
        self.scales = [1, self.Om, 1, self.Om, fsc]
        self.bscales = np.array([1, self.Om, 1, self.Om])
        self._init_sensor()

    def initial(self):
        return np.zeros(5), None

    def _Fi(self, y):
        p = self.p
        d = y[2] - self.gap
        if d <= 0.0:
            return 0.0
        F = (p["ki"] * (1.0 + self.alpha * max(y[3], 0.0)) * d ** p["ni"]
             * max(0.0, 1.0 + p["lambda_i"] * y[3]))
        if self.dcon:
            F = max(0.0, F + _extra(d, y[3], self.dq, self.dc, self.dp))
        return F

    def _acc(self, t, y, Fi):
        p = self.p
        x1, v1, x2, v2 = y[0], y[1], y[2], y[3]
        F = self.F0 * math.sin(self.Om * t)
        phi = x2 - x1
        hard = p["k2"] * self.kappa * phi * phi * phi          # hardening part of the k2 spring force
        a1 = (-(p["c1"] + p["c2"]) * v1 - (p["k1"] + p["k2"]) * x1 + F + p["c2"] * v2 + p["k2"] * x2
              + hard) / p["m1"]
        a2 = (-p["c2"] * v2 - p["k2"] * x2 + p["c2"] * v1 + p["k2"] * x1 - hard - Fi) / p["m2"]
        if self.dtool:
            a2 += _tool(v2, self.tv, self.td) / p["m2"]
        return a1, a2, F * v1

    def rhs(self, t, y, br, disc):
        a1, a2, w = self._acc(t, y, self._Fi(y) if br == 1 else 0.0)
        return [y[1], a1, y[3], a2, w]

    def acc_of(self, t, y, dy):
        return dy[3]

    def indicators(self, t, y):
        return y[2] - self.gap, self.LS * (1.0 + self.p["lambda_i"] * y[3])

    def rates(self, t, y):
        a2 = self._acc(t, y, 0.0)[1]
        return y[3], self.LS * self.p["lambda_i"] * a2

    def force(self, t, Y, br, disc):
        if br == 0:
            return np.zeros_like(t)
        p = self.p
        d = np.maximum(Y[2] - self.gap, 0.0)
        F = (p["ki"] * (1.0 + self.alpha * np.maximum(Y[3], 0.0)) * d ** p["ni"]
             * np.maximum(0.0, 1.0 + p["lambda_i"] * Y[3]))
        if self.dcon:
            F = np.maximum(0.0, F + _extra_vec(d, Y[3], self.dq, self.dc, self.dp))
        return F

    def accel(self, t, Y, br, disc):
        p = self.p
        Fi = self.force(t, Y, br, disc)
        phi = Y[2] - Y[0]
        hard = p["k2"] * self.kappa * phi * phi * phi
        a2 = (-p["c2"] * Y[3] - p["k2"] * Y[2] + p["c2"] * Y[1] + p["k2"] * Y[0] - hard - Fi) / p["m2"]
        if self.dtool:
            a2 = a2 + _tool(Y[3], self.tv, self.td) / p["m2"]
        return a2

    def disp(self, t, Y, br, disc):
        return Y[2]

    def vel(self, t, Y, br, disc):
        return Y[3]

    def bounded(self, t, Y, br, disc):
        return np.array([Y[0], Y[1], Y[2], Y[3]])


def _make_model(model: str, params: dict) -> _Model:
    if model == "drill":
        return _Drill(params)
    if model == "indenter-metal":
        return _IndenterMetal(params)
    if model == "indenter-sandstone":
        return _IndenterSandstone(params)
    if model == "pendulum":
        return _Pendulum(params)
    if model == "rimd":
        return _Rimd(params)
    raise ValueError(f"unknown model {model!r}; expected one of {MODELS}")


# =====================================================================================================
# Recording of window statistics
# =====================================================================================================
def _refined_max(fun, dense, ts, vals, ends=False):
    """Max of fun over [ts[0], ts[-1]] given samples vals = fun(ts); refine an interior max with Brent
    (with ``ends``, also a max on the first or last sample: for a signal smooth across segment ends)."""
    i = int(np.argmax(vals))
    best = float(vals[i])
    n = len(ts)
    if 0 < i < n - 1 or (ends and n > 1):
        a, b = float(ts[max(i - 1, 0)]), float(ts[min(i + 1, n - 1)])

        def neg(tt):
            return -float(fun(np.array([tt]), dense(tt)[:, None])[0])
        res = minimize_scalar(neg, bounds=(a, b), method="bounded",
                              options={"xatol": max((b - a) * 1e-9, 1e-300)})
        if -res.fun > best:
            best = -float(res.fun)
    return best


HIST_KEYS = ("t_s", "disp_m", "force_n", "accel_m_s2", "progression_m")
SAMPLE_KEYS = ("t_s", "disp_m", "vel_m_s", "force_n", "accel_m_s2", "accel_true_m_s2", "progression_m")


class _Recorder:
    def __init__(self, model: _Model, window_cycles: int, samples_per_cycle: int, sample_times=None):
        self.m = model
        self.prev_contact = False
        self.cur = None            # open contact interval: [max_force, counted]
        self.interval_max = []     # maxima of intervals whose onset lies in the window
        self.n_onsets = 0
        self.peak_force = 0.0
        self.any_contact = False
        self.peak_decel = -math.inf
        nb = len(model.bounded_names)
        self.bmin = np.full(nb, np.inf)
        self.bmax = np.full(nb, -np.inf)
        self.spc = samples_per_cycle
        if samples_per_cycle > 0:
            n = window_cycles * samples_per_cycle
            keys = HIST_KEYS + (("accel_true_m_s2",) if model.iz is not None else ())
            self.hist = {k: np.full(n, np.nan) for k in keys}
        self.tail_closed = False
        # sampling at absolute times: sorted times, index of the first one not yet taken, last segment seen
        self.st = sample_times
        if sample_times is not None:
            self.si = 0
            self.samples = {k: np.full(sample_times.size, np.nan) for k in SAMPLE_KEYS}
            self.samples["t_s"] = sample_times.copy()
            self.last = None

    def sample(self, tau1, dense, br, disc, t_cycle0, final=False):
        """Evaluate the samples with t < t_cycle0 + tau1 (all remaining ones if final) on this segment's dense
        output; a time on a segment boundary goes to the later segment, as in the history."""
        ts = self.st
        i0 = self.si
        i1 = ts.size if final else int(np.searchsorted(ts, t_cycle0 + tau1, side="left"))
        if i1 > i0:
            tt = ts[i0:i1] - t_cycle0
            obs = self.m.observe(tt, dense(tt), br, disc)
            for k, v in obs.items():
                self.samples[k][i0:i1] = v
            self.si = i1

    def segment(self, kwin, phase, tau0, tau1, dense, br, disc, t_cycle0):
        m = self.m
        contact = m.is_contact(br)
        # ---- contact interval bookkeeping (all phases) ----
        if contact and not self.prev_contact:
            if phase == "tail":          # new onset after the window: not ours
                self.tail_closed = True
                return
            self.cur = [0.0, phase == "window"]
            if phase == "window":
                self.n_onsets += 1
        elif not contact and self.prev_contact:
            if self.cur is not None and self.cur[1]:
                self.interval_max.append(self.cur[0])
            self.cur = None
            if phase == "tail":
                self.tail_closed = True
        elif contact and self.cur is None:
            self.cur = [0.0, False]
        self.prev_contact = contact
        if phase == "transient" or tau1 <= tau0:
            return
        if phase == "tail":
            if contact and self.cur is not None:
                n = N_CONTACT_SAMPLES
                ts = np.linspace(tau0, tau1, n)
                Y = dense(ts)
                self.cur[0] = max(self.cur[0], _refined_max(
                    lambda t, Yv: m.force(t, Yv, br, disc), dense, ts, m.force(ts, Y, br, disc)))
            return
        # ---- window ----
        if contact:
            n = N_CONTACT_SAMPLES
        else:
            n = max(16, int(math.ceil(N_FREE_PER_CYCLE * (tau1 - tau0) / m.T)))
        filtered = m.iz is not None
        if filtered:     # the measured signal rings at ~fc long after the contact: resolve it everywhere
            n = max(n, int(math.ceil(N_PER_FC * m.fc * (tau1 - tau0))))
        ts = np.linspace(tau0, tau1, n)
        Y = dense(ts)
        acc = m.accel_meas(ts, Y, br, disc)
        self.peak_decel = max(self.peak_decel, _refined_max(
            lambda t, Yv: -m.accel_meas(t, Yv, br, disc), dense, ts, -acc, ends=filtered))
        if contact:
            self.any_contact = True
            F = m.force(ts, Y, br, disc)
            fmax = _refined_max(lambda t, Yv: m.force(t, Yv, br, disc), dense, ts, F)
            self.peak_force = max(self.peak_force, fmax)
            self.cur[0] = max(self.cur[0], fmax)
        B = m.bounded(ts, Y, br, disc)
        self.bmin = np.minimum(self.bmin, B.min(axis=1))
        self.bmax = np.maximum(self.bmax, B.max(axis=1))
        if self.spc > 0:
            dt = m.T / self.spc
            js = np.arange(self.spc)
            idx = js[(js * dt >= tau0) & (js * dt < tau1)]
            if idx.size:
                tt = idx * dt
                Yh = dense(tt)
                k = kwin * self.spc + idx
                h = self.hist
                h["t_s"][k] = t_cycle0 + tt
                obs = m.observe(tt, Yh, br, disc)
                for key in h:
                    if key != "t_s":
                        h[key][k] = obs[key]


# =====================================================================================================
# Event-located integration of one smooth branch
# =====================================================================================================
_SOLVERS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA}
N_EVENT_SUB = 16   # event functions are checked at this many sub-intervals of every accepted step


def _crossing(g, direction, sol, ss, vals, T):
    """Earliest time in [ss[0], ss[-1]] where g crosses 0 in ``direction`` on the interpolant ``sol``.

    g is scanned at the sub-sample times ss (values vals); a sign change in the triggering direction is
    bracketed and solved with brentq.  Because an even number of crossings between two samples (a
    narrow dip through the surface) would leave no sign change, every interior sample that is a local
    extremum towards the triggering side, and close to 0 relative to the local variation, is refined
    with a bounded Brent search; if the extremum crosses 0 the earlier half is bracketed too.
    (scipy's solve_ivp only compares the signs at step ends, and misses such dips: seen on the drill.)
    """
    sgn = 1.0 if direction > 0 else -1.0
    v = sgn * vals                       # trigger when v goes from < 0 to >= 0

    def gs(tt):
        return sgn * float(g(np.array([tt]), sol(tt)[:, None])[0])

    eps4 = 4 * np.finfo(float).eps
    neg = v < 0.0
    cr = np.flatnonzero(neg[:-1] & ~neg[1:])
    i_cr = int(cr[0]) if cr.size else len(ss)
    vi, vl, vr = v[1:-1], v[:-2], v[2:]
    ext = np.flatnonzero((vi < 0.0) & (vi >= vl) & (vi >= vr)
                         & (-vi <= 4.0 * np.maximum(vi - vl, vi - vr))) + 1
    for i in ext:
        if i >= i_cr:
            break
        lo, hi = ss[i - 1], ss[i + 1]
        res = minimize_scalar(lambda tt: -gs(tt), bounds=(lo, hi), method="bounded",
                              options={"xatol": (hi - lo) * 1e-10})
        if -res.fun >= 0.0:
            return brentq(gs, lo, float(res.x), xtol=1e-17 * T, rtol=eps4)
    if i_cr < len(ss):
        return brentq(gs, ss[i_cr], ss[i_cr + 1], xtol=1e-17 * T, rtol=eps4)
    return None


def _integrate(fun, t0, y0, t1, events, method, rtol, atol, max_step, T, n_sub=N_EVENT_SUB):
    """Integrate y' = fun(t, y) from t0 towards t1 and stop at the first event.

    events: list of (g, direction), g vectorised: g(t (N,), Y (n, N)) -> (N,).
    Returns (dense OdeSolution or None, t_end, y_end, index of the event that fired or None).
    """
    try:
        cls = _SOLVERS[method]
    except KeyError:
        raise ValueError(f"unknown method {method!r}; expected one of {sorted(_SOLVERS)}") from None
    solver = cls(fun, t0, y0, t1, rtol=rtol, atol=atol, max_step=max_step)
    ts = [t0]
    interps = []
    while solver.status == "running":
        msg = solver.step()
        if solver.status == "failed":
            raise RuntimeError(f"{method} step failed at t={solver.t}: {msg}")
        t_old, t_new = solver.t_old, solver.t
        if t_new == t_old:
            continue
        sol = solver.dense_output()
        hit = None
        if events:
            ss = np.linspace(t_old, t_new, n_sub + 1)
            Y = sol(ss)
            for j, (g, d) in enumerate(events):
                tr = _crossing(g, d, sol, ss, g(ss, Y), T)
                if tr is not None and (hit is None or tr < hit[0]):
                    hit = (tr, j)
        if hit is not None:
            tr, j = hit
            if tr > t_old:
                interps.append(sol)
                ts.append(tr)
            dense = OdeSolution(ts, interps) if interps else None
            return dense, tr, np.array(sol(tr), dtype=float), j
        interps.append(sol)
        ts.append(t_new)
    dense = OdeSolution(ts, interps) if interps else None
    return dense, float(solver.t), np.array(solver.y, dtype=float), None


# =====================================================================================================
# Driver
# =====================================================================================================
def _run_cycle(m, y, disc, kwin, phase, rec, t_cycle0, solver_kw, max_events_per_cycle):
    T = m.T
    m.t_cycle0 = t_cycle0      # the models see the cycle's time; a drifting contact reads the absolute one
    tiny = 1e-13 * T
    tau = 0.0
    n_ev = 0
    n_zero = 0
    while T - tau > tiny:
        br, y, disc = m.classify(tau, y, disc)
        try:
            dense, t1, y1, idx = _integrate(m.flow(br, disc), tau, y, T, m.events(br, disc), T=T, **solver_kw)
        except RuntimeError as exc:
            raise RuntimeError(f"{m.name}: integration failed at cycle {kwin} ({phase}), "
                               f"tau={tau}: {exc}") from exc
        if t1 > tau and dense is not None:
            if rec.st is not None and phase != "tail":
                rec.sample(t1, dense, br, disc, t_cycle0)
                rec.last = (t1, dense, br, disc, t_cycle0)
            rec.segment(kwin, phase, tau, t1, dense, br, disc, t_cycle0)
        disc = m.on_segment_end(br, t1, y1, disc)
        if idx is not None:
            y1, disc = m.on_event(br, idx, t1, y1, disc)
            n_ev += 1
            if n_ev > max_events_per_cycle:
                raise RuntimeError(
                    f"{m.name}: more than {max_events_per_cycle} switching events in forcing cycle "
                    f"{kwin} ({phase}) -- chattering / Zeno contact; the reference cannot resolve it")
            if t1 - tau <= tiny:
                n_zero += 1
                if n_zero > 100:
                    raise RuntimeError(f"{m.name}: zero-length segment loop at cycle {kwin}, tau={tau}")
            else:
                n_zero = 0
        tau = t1
        y = y1
        if phase == "tail" and rec.tail_closed:
            break
    return y, disc, n_ev


def _period(strobe, rng, floor):
    tol = 1e-3 * np.maximum(rng, floor)
    n_s = strobe.shape[0]
    for n in range(1, 9):
        if n_s <= n:
            break
        d = np.abs(strobe[n:] - strobe[:-n])
        if np.all(d <= tol[None, :]):
            return n
    return 0


def reference_run(model: str, params: dict, transient_cycles: int, window_cycles: int,
                  method: str = "DOP853", rtol: float = 1e-10, atol_scale: float = 1e-3,
                  samples_per_cycle: int = 0, *, sample_times=None, max_step_fraction: float = 0.05,
                  max_events_per_cycle: int = 2000, event_subdivisions: int = N_EVENT_SUB) -> dict:
    """High-accuracy event-located reference solution of one run of ``model`` (see module docstring).

    Runs ``transient_cycles`` forcing cycles from the rest state of MODELS.md, then records
    ``window_cycles`` cycles and returns the MODELS.md section-5 labels plus ``strobe``, ``n_events``,
    ``wall_s`` (and ``history`` if ``samples_per_cycle > 0``).  ``model`` is a name in MODELS, or a factory
    ``params -> model object`` (e.g. a subclass of one of the model classes below adding a term); the object's
    ``name`` then says which model's labels apply.

    ``sample_times``: 1-D non-decreasing absolute times [s] since the start from rest (t = 0), anywhere in
    [0, (transient_cycles + window_cycles) T]; the result then holds ``samples`` (module docstring).

    Keyword-only extras: ``max_step_fraction`` (max step = this * T), ``max_events_per_cycle`` (more
    switching events than this in one forcing cycle raises RuntimeError: chattering / Zeno), and
    ``event_subdivisions`` (sub-intervals of each step scanned for events; 1 reproduces solve_ivp's
    step-end-only sign check, i.e. "what a user would write").
    """
    t_wall = time.perf_counter()
    if window_cycles < 1 or transient_cycles < 0:
        raise ValueError("need window_cycles >= 1 and transient_cycles >= 0")
    if isinstance(model, str):
        m = _make_model(model, params)
    else:
        m = model(params)
        if not isinstance(m, _Model) or m.name not in MODELS:
            raise TypeError(f"model factory {model!r} must return a reference model of one of {MODELS}")
        model = m.name
    T = m.T
    n_cycles = transient_cycles + window_cycles
    if sample_times is not None:
        sample_times = np.array(sample_times, dtype=float)
        if sample_times.ndim != 1 or not np.all(np.isfinite(sample_times)):
            raise ValueError("sample_times must be a 1-D array of finite times [s]")
        if np.any(np.diff(sample_times) < 0.0):
            raise ValueError("sample_times must be non-decreasing")
        t_end = n_cycles * T
        if sample_times.size and (sample_times[0] < 0.0 or sample_times[-1] > t_end * (1.0 + 1e-12)):
            raise ValueError(f"sample_times must lie in [0, {t_end!r}] s (transient + window cycles of "
                             f"{model}); got [{sample_times[0]!r}, {sample_times[-1]!r}]")
    atol = m.atol(rtol, atol_scale)
    solver_kw = dict(method=method, rtol=rtol, atol=atol, max_step=max_step_fraction * T,
                     n_sub=max(1, int(event_subdivisions)))
    rec = _Recorder(m, window_cycles, samples_per_cycle, sample_times)
    y, disc = m.initial_state()
    nb = len(m.bounded_names)
    strobe = np.empty((window_cycles, nb))
    n_events = 0
    W0 = P0 = None
    iW = m.iW
    for k in range(n_cycles):
        phase = "window" if k >= transient_cycles else "transient"
        kwin = k - transient_cycles
        if kwin == 0:
            W0 = float(y[iW])
            P0 = m.progression_scalar(y, disc)
        if phase == "window":
            # disc is kept current at every segment end, so br=None is enough here
            strobe[kwin] = m.bounded(np.array([0.0]), y[:, None], None, disc)[:, 0]
        y, disc, ne = _run_cycle(m, y, disc, kwin, phase, rec, k * T, solver_kw, max_events_per_cycle)
        n_events += ne
    W1 = float(y[iW])
    P1 = m.progression_scalar(y, disc)
    if sample_times is not None and rec.si < sample_times.size:      # times at the very end of the run
        rec.sample(*rec.last, final=True)
    # follow a contact interval still open at the end of the window to its separation (<= 1 cycle)
    if rec.cur is not None and rec.cur[1]:
        _run_cycle(m, y, disc, window_cycles, "tail", rec, (transient_cycles + window_cycles) * T,
                   solver_kw, max_events_per_cycle)
        if not rec.tail_closed and rec.cur is not None:
            rec.interval_max.append(rec.cur[0])
    duration = window_cycles * T
    prog = P1 - P0
    work = W1 - W0
    rng = rec.bmax - rec.bmin
    floor = 1e-9 * atol_scale * m.bscales
    if rec.interval_max:
        mean_peak = float(np.mean(rec.interval_max))
    elif rec.any_contact:          # persistent contact, no onset in the window
        mean_peak = rec.peak_force
    else:
        mean_peak = 0.0
    status = "ok"
    if model == "drill" and m.Fs >= m.p["Pr"]:
        status = "runaway"
    elif not rec.any_contact:
        status = "no_contact"
    out = {
        "rop_m_s": prog / duration if model in ("drill", "indenter-sandstone") else 0.0,
        "peak_force_n": float(rec.peak_force),
        "mean_peak_force_n": mean_peak,
        "impacts_per_cycle": rec.n_onsets / window_cycles,
        "period": _period(strobe, rng, floor),
        "peak_decel_g": float(rec.peak_decel) / G_ACC + 0.0,
        "energy_per_cycle_j": work / window_cycles,
        "specific_energy_j_m": (work / prog) if (model in ("drill", "indenter-sandstone") and prog > 0)
        else float("inf"),
        "status": status,
        "strobe": strobe,
        "strobe_names": m.bounded_names,
        "n_events": int(n_events),
    }
    if samples_per_cycle > 0:
        out["history"] = rec.hist
    if sample_times is not None:
        out["samples"] = rec.samples
    out["wall_s"] = time.perf_counter() - t_wall
    return out
