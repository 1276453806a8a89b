"""The discrepancy vocabulary: a fixed set of terms a model can gain where no MODELS.md §6 effect explains a rig.

Each term is a model parameter named as the term, ≥ 0 and off at 0 (then the model is the base model bit for bit),
with a fixed form at a fixed site: the contact force expression (``contact_*``, also in the contact's release and
threshold indicators, so the switching stays consistent) or the impacting mass's equation of motion (``tool_*``).
A model lists the terms it has in ``ModelSpec.discrepancy``; the diagnosis proposes a sparse combination of them
(``pipeline.diagnosis.discovery``) and a rig file carries an adopted one as a ``discrepancy:`` entry of term names
and coefficients (``sim.rig``) — never an expression.

A term is declared once, in ``TERMS``: its site and its form as the exponents of the site's two variables
(``SITES``).  The site sums the kernels call, ``contact_extra`` and ``tool_loss``, are generated from those
declarations at import (``site_source``: a Horner form in the site's first variable), and a model reads the
coefficients of the whole block once (``terms_at(p, first)``, ``first`` from ``vocabulary_at``): a new term is one
line here, its reference in tests/reference_solutions.py and its visible strengths.

Ten *structured* candidates sit beside the terms.  ``load_path_mode`` is a hidden mass on a spring and damper at the
impacting mass (an extra mode in the load path), three parameters (``MODE_PARAMS``: mass ratio, frequency, damping
ratio) and two more states (``MODE_STATES``, after the model's own; off while the ratio is 0).  The second,
``contact_exponent``, makes the elastic part of a linear contact law a free power of the penetration (one parameter,
the exponent's shift, ``EXPONENT_SHIFT``; its reference penetration ``EXPONENT_REF`` is the model's, not fitted), on
the models whose contact's elastic part is linear (``exponent_params``, ``shaped``).  The third,
``rock_rate_strength``, raises a failing rock's threshold with its failure rate (the drill's slider;
``strength_params``); the fourth, ``link_power_loss``, a loss in the impacting mass's suspension with a free power
of the relative velocity (``link_params``, ``link_loss``); the fifth, ``contact_drift``, a contact position that
moves at a steady rate through a run (``drift_params``, ``drifted``); the sixth, ``support_friction``, a dry
friction at a support other than the tool's guides (``support_params``; the kernels call
``sim.models.terms.guide_friction``'s regularised Coulomb law there).  ``stop_mode`` and ``drive_mode`` put the
hidden mode's mass elsewhere in the load path: under the stop (a compliant mount: ``hidden_state``, ``stop_accel``) or
on the body that carries the drive (``mode_force``, ``mode_accel`` there).  ``contact_wear`` lets the struck surface
recede with the work pressed into it (``wear_params``, ``wear_speed``), its depth in the first hidden state: the
modes and the wear use the same two hidden states, as does ``contact_unloading``, a contact that unloads along a
lower curve than it loads (``unloading_params``, ``unloaded``, ``peak_rate``: the peak penetration in the first), one
candidate at a time (``HIDDEN_USERS``).  Not in the vocabulary: a first-order lag on the forcing (where a model has
``shaker_coil``, its τ is that lag); a cubic spring is §6 ``suspension_hardening``.
"""
from __future__ import annotations

import linecache
import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

from sim.jit import njit  # numba is imported on first use (sim/jit.py)
from sim.models.fitbound import FitBound
from sim.models.param import Param

CONTACT = "contact"
TOOL = "tool"


@dataclass(frozen=True)
class Site:
    """Where terms act and what they are polynomials in: ``x`` and ``y`` as (code in the site function, symbol), the
    site function's ``name`` and ``args`` (after the coefficient tuple), ``lhs`` (the force a term joins, in symbols)
    whether the form says y before x (``y_first``) and which variable a term's form must contain (``vanish``: 0 = x,
    1 = y), so that the term vanishes where the site's force must not move (no penetration; a mass at rest).  A
    term's force is c x^a y^b; the site sums them in Horner form in x, after factoring out the least power of each
    (``site_source``)."""

    name: str
    args: tuple[str, ...]
    x: tuple[str, str]
    y: tuple[str, str]
    lhs: str
    vanish: int
    y_first: bool = False


SITES: dict[str, Site] = {
    CONTACT: Site("contact_extra", ("d", "dd"), ("max(d, 0.0)", "δ₊"), ("dd", "δ̇"), "F_c +=", vanish=0),
    TOOL: Site("tool_loss", ("v",), ("abs(v)", "|v|"), ("v", "v"), "F_tool −=", vanish=1, y_first=True),
}
"""The sites: the contact force expression (δ₊ = max(δ, 0) the penetration, δ̇ its rate; also in the contact's release
and threshold indicators) and the force opposing the impacting mass's velocity v."""

_SUPER = str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")


@dataclass(frozen=True)
class Term:
    """One discrepancy term: ``name`` (= its parameter), unit, site (CONTACT or TOOL), its form c x^a y^b as the
    exponents ``powers`` = (a, b) of its site's variables (``SITES``), kind of physics (what a researcher would call
    it) and its meaning in words."""

    name: str
    unit: str
    site: str
    powers: tuple[int, int]
    kind: str
    words: str

    def __post_init__(self):
        if self.site not in SITES or min(self.powers) < 0 or self.powers[SITES[self.site].vanish] < 1:
            raise ValueError(f"discrepancy term '{self.name}': its site {self.site!r} must be one of {tuple(SITES)} "
                             f"and its powers {self.powers} non-negative, with the site's vanishing variable "
                             f"(δ₊ at the contact, v at the tool)")

    @property
    def params(self) -> tuple[str, ...]:
        """The parameters of the term: its own name."""
        return (self.name,)

    @property
    def form(self) -> str:
        """The form in symbols, e.g. ``F_c += c δ₊²`` (from ``powers``)."""
        site = SITES[self.site]
        f = [sym + (str(n).translate(_SUPER) if n > 1 else "")
             for (_, sym), n in zip((site.x, site.y), self.powers) if n]
        return f"{site.lhs} c {' '.join(f[::-1] if site.y_first else f)}"


@dataclass(frozen=True)
class Structured:
    """A structured candidate: several parameters (``params``, ``units``) that enter together, off while the first
    is 0; ``name``, ``site``, ``form``, ``kind`` and ``words`` as for a ``Term``."""

    name: str
    params: tuple[str, ...]
    units: tuple[str, ...]
    site: str
    form: str
    kind: str
    words: str


TERMS: dict[str, Term] = {t.name: t for t in (
    Term("contact_quadratic", "N/m^2", CONTACT, (2, 0), "contact", "contact stiffening quadratic in penetration"),
    Term("contact_cubic", "N/m^3", CONTACT, (3, 0), "contact", "contact stiffening cubic in penetration"),
    Term("contact_rate_product", "N s/m^2", CONTACT, (1, 1), "contact",
         "contact damping growing with penetration (Hunt–Crossley-like)"),
    Term("tool_viscous", "N s/m", TOOL, (0, 1), "velocity_loss", "viscous loss on the impacting mass"),
    Term("tool_quadratic_drag", "N s^2/m^2", TOOL, (1, 1), "velocity_loss",
         "velocity-squared loss (drag) on the impacting mass"),
)}
"""The vocabulary, in the kernels' parameter order (contiguous from ``vocabulary_at(PARAMS)``; δ₊ = max(δ, 0) the
penetration, δ̇ its rate, v the impacting mass's velocity).  The only declaration of a term: the site sums below are
generated from it."""

MODE = "load_path_mode"
MODE_PARAMS = ("load_path_mode_ratio", "load_path_mode_hz", "load_path_mode_zeta")
"""The hidden mode's mass mh over the impacting mass's [-] (0 = off), its frequency fh with the impacting mass held
[Hz] and its damping ratio ζh [-]: kh = mh (2π fh)², ch = 2 ζh mh 2π fh."""
MODE_MAX_RATIO = 100.0
MODE_MAX_ZETA = 100.0
"""Largest hidden mass (x the impacting mass) and damping ratio accepted: far beyond the fit bounds, below typos."""
MODE_STATES = ("load_path_mode_x", "load_path_mode_v")
"""The hidden mass's position relative to the impacting mass [m] (pendulum: along the hammer's tangent) and its
rate [m/s]: the last two states of every model."""

STRUCTURED: dict[str, Structured] = {MODE: Structured(
    MODE, MODE_PARAMS, ("-", "Hz", "-"), TOOL,
    "m_h (ẍ_h + a) = −k_h x_h − c_h ẋ_h, F_tool += k_h x_h + c_h ẋ_h", "mode",
    "an extra mode in the load path: a hidden mass on a spring and damper at the impacting mass")}
"""The structured candidates (discovery fits each as one proposal, beside the screened terms)."""

EXPONENT = "contact_exponent"
EXPONENT_SHIFT = "contact_exponent_shift"
"""The contact law's exponent above the linear law's, s = n − 1 [-] (0 = off): Hertz's sphere 0.5, a cone 1."""
EXPONENT_REF = "contact_exponent_ref_m"
"""The penetration δ_r [m] at which the shaped law has the linear law's force: a model parameter, never fitted (the
calibrated stiffness absorbs it: k δ_r^−s δ₊^(1+s) is the family whatever δ_r), set near the model's typical
penetration so that the calibrated stiffness stays inside its fit bounds."""
EXPONENT_MAX_SHIFT = 10.0
"""Largest exponent shift accepted: far beyond the fit bounds, below typos."""
STRUCTURED[EXPONENT] = Structured(
    EXPONENT, (EXPONENT_SHIFT,), ("-",), CONTACT, "F_c: k δ → k δ_r (δ₊/δ_r)^(1+s)", "contact",
    "a contact law that is a free power of the penetration (Hertz-like: a rounded tip or a curved cap)")

STRENGTH = "rock_rate_strength"
"""The rock's dynamic strength increase η [s/m] (0 = off): its failure threshold Pr → Pr (1 + η ẋb) while it fails
at the rate ẋb."""
STRENGTH_MAX = 1e4
"""Largest η accepted [s/m]: far beyond the fit bounds, below typos."""
STRUCTURED[STRENGTH] = Structured(
    STRENGTH, (STRENGTH,), ("s/m",), CONTACT, "P_r → P_r (1 + η ẋ_b): ẋ_b = (P_c − P_r) / (C_1 + η P_r)",
    "contact",
    "a rock whose failure threshold rises with the rate of failure (dynamic strength increase)")

LINK = "link_power_loss"
LINK_PARAMS = ("link_power_loss_n", "link_power_loss_exponent")
"""The loss force at the reference relative velocity c [N] (0 = off) and its exponent p [-] (1 = viscous)."""
LINK_REF = "link_power_loss_ref_m_s"
"""The reference relative velocity v_r [m/s] of the link loss: a model parameter near the link's rms velocity, never
fitted (c and p then trade off little)."""
LINK_MAX_EXPONENT = 10.0
"""Largest exponent accepted: far beyond the fit bounds, below typos."""
STRUCTURED[LINK] = Structured(
    LINK, LINK_PARAMS, ("N", "-"), TOOL, "F_link += c (|v|/v_r)^p sgn v", "velocity_loss",
    "a loss in the impacting mass's suspension that grows as a power of the relative velocity (an elastomer or "
    "squeeze-film loss)")

DRIFT = "contact_drift"
DRIFT_RATE = "contact_drift_m_s"
"""The contact position's drift rate a [m/s] (0 = off; > 0 the contact recedes, as a worn tip or sample face does)."""
DRIFT_MAX = 1.0
"""Largest drift rate accepted [m/s]: far beyond the fit bounds, below typos."""
STRUCTURED[DRIFT] = Structured(
    DRIFT, (DRIFT_RATE,), ("m/s",), CONTACT, "x_c(t) = G + a t: δ = x − x_c(t), δ̇ = ẋ − a", "drift",
    "a contact position that moves steadily through a run (wear of the tip or the sample face, creep of the mount, "
    "thermal growth), from the run's start at rest")

SUPPORT = "support_friction"
SUPPORT_FORCE = "support_friction_n"
"""The support's dry friction force μ [N] (0 = off)."""
SUPPORT_VEPS = "support_friction_v_eps_m_s"
"""Its regularisation speed [m/s] (MODELS.md §1's Coulomb law, tanh(v / v_eps)); not fitted."""
SUPPORT_MAX = 1e4
"""Largest support friction accepted [N]: far beyond the fit bounds, below typos."""
STRUCTURED[SUPPORT] = Structured(
    SUPPORT, (SUPPORT_FORCE,), ("N",), TOOL, "F_s −= μ tanh(v / v_ε) at a support (not the tool's guides)",
    "friction",
    "dry friction at a support other than the tool's guides (a pivot, a clamp, a body's carriages on the ground)")

STOP_MODE = "stop_mode"
STOP_MODE_PARAMS = ("stop_mode_ratio", "stop_mode_hz", "stop_mode_zeta")
"""A compliant mount under the stop: its mass ms over the impacting mass's [-] (0 = off), its frequency on its mount
fs [Hz] and damping ratio ζs [-]: ks = ms (2π fs)², cs = 2 ζs ms 2π fs.  Its states are ``MODE_STATES`` (the mount's
displacement from rest [m] and rate): the hidden states hold one candidate at a time (``HIDDEN_USERS``)."""
STRUCTURED[STOP_MODE] = Structured(
    STOP_MODE, STOP_MODE_PARAMS, ("-", "Hz", "-"), CONTACT,
    "m_s ẍ_s = F_c − k_s x_s − c_s ẋ_s, δ = x − G − x_s, δ̇ = ẋ − ẋ_s", "mode",
    "a compliant mount with inertia under the stop or the sample: the struck surface is a mass on a spring and "
    "damper to the ground")

DRIVE_MODE = "drive_mode"
DRIVE_MODE_PARAMS = ("drive_mode_ratio", "drive_mode_hz", "drive_mode_zeta")
"""A mode inside the drive: a hidden mass md over the driving body's [-] (0 = off) on a spring and damper at the body
that carries the forcing, its frequency with the body held fd [Hz] and damping ratio ζd [-].  Its states are
``MODE_STATES`` (relative to the driving body)."""
STRUCTURED[DRIVE_MODE] = Structured(
    DRIVE_MODE, DRIVE_MODE_PARAMS, ("-", "Hz", "-"), TOOL,
    "m_d (ẍ_d + a_drive) = −k_d x_d − c_d ẋ_d, F_drive += k_d x_d + c_d ẋ_d", "mode",
    "a mode inside the drive: a hidden mass on a spring and damper at the body that carries the forcing")

WEAR = "contact_wear"
WEAR_RATE = "contact_wear_m_j"
"""The wear coefficient k_w [m/J] (0 = off): the struck surface recedes by k_w per joule pressed into it."""
WEAR_MAX = 1.0
"""Largest wear coefficient accepted [m/J]: far beyond the fit bounds, below typos."""
WEAR_RUN = "contact_wear_before_m_j"
"""How long a wearing rig ran before a steady-state record, as k_w N [m/J] (N its forcing cycles; 0 = the settings'
transient): the face never settles, so what such a record shows depends on it (the depth there is about k_w N times
the work pressed in per cycle; ``run_cycles``, ``wear_coef``).  Fitted as k_w N rather than N: the depth at the
record then stays put while k_w moves, so the two are nearly independent in a fit."""
STRUCTURED[WEAR] = Structured(
    WEAR, (WEAR_RATE, WEAR_RUN), ("m/J", "m/J"), CONTACT, "ṡ = k_w F_c max(v, 0), δ = x − G − s, v = ẋ − ẋ_c", "drift",
    "a struck surface that wears or dents away with the work pressed into it (impact wear, Archard-like): the "
    "contact position recedes through a run, faster where the impacts are harder")
# The contact law's rate stays the approach rate v: its dashpot spans the whole indentation, the elastic part δ and the
# worn depth s (the permanent part of the same deformation), so the wear moves only the law's δ.

UNLOADING = "contact_unloading"
UNLOADING_SHIFT = "contact_unloading_shift"
"""The unloading curve's exponent above the loading law's, s_u = n_u − 1 [-] (0 = off): below the impact's peak
penetration δ_m the elastic part falls as (δ/δ_m)^(1+s_u) from its value there."""
UNLOADING_MAX_SHIFT = 50.0
"""Largest unloading shift accepted: far beyond the fit bounds, below typos."""
STRUCTURED[UNLOADING] = Structured(
    UNLOADING, (UNLOADING_SHIFT,), ("-",), CONTACT,
    "F_e(δ) = F_e(δ_m) (δ/δ_m)^(1+s_u) while δ < δ_m, δ_m the contact's peak penetration", "contact",
    "a contact that unloads along a lower curve than it loads (hysteretic or plastic work lost at every impact), the "
    "surface recovering between impacts")

STEADY_ONLY = frozenset({WEAR_RUN})
"""Parameters that act only on a run left to settle (a steady-state record), not on a record from rest: discovery
fits them only where a log has steady-state records."""

HIDDEN_MODES = (MODE, STOP_MODE, DRIVE_MODE)
"""The modes that use the hidden states ``MODE_STATES``."""
HIDDEN_USERS = (*HIDDEN_MODES, WEAR, UNLOADING)
"""Every candidate that uses the hidden states (the modes; the wear holds its depth s in the first, the unloading
curve its contact's peak penetration δ_m): at most one on at a time."""

COMPANION: dict[str, str] = {EXPONENT_REF: EXPONENT_SHIFT, LINK_REF: LINK_PARAMS[0], SUPPORT_VEPS: SUPPORT_FORCE}
"""Parameters that shape a candidate without being fitted -> the candidate's parameter they belong to."""

CANDIDATES: dict[str, Term | Structured] = {**TERMS, **STRUCTURED}
"""Every candidate of the vocabulary by name."""

PARAM_OF: dict[str, str] = {p: c.name for c in CANDIDATES.values() for p in c.params}
"""Every discrepancy parameter -> the candidate it belongs to."""

SWITCH: dict[str, str] = {p: c.params[0] for c in CANDIDATES.values() for p in c.params}
"""Every discrepancy parameter -> the one that switches its candidate on (a term's own; a structured candidate's
first: the others, e.g. the link loss's exponent, shape it and may sit at any value while it is off)."""


def any_on(values: Mapping[str, float], names: Sequence[str]) -> bool:
    """Whether any candidate of the discrepancy parameters ``names`` is switched on in ``values``."""
    return any(float(values.get(SWITCH[n], 0.0) or 0.0) for n in names)


@dataclass(frozen=True)
class Span:
    """A term that is a §6 effect in another form: its coefficient c is the effect's parameter ``param`` times the
    model parameter ``per`` names (the first of them the model has), so ``param`` = c / that value."""

    effect: str
    param: str
    per: tuple[str, ...]


SPANS: dict[str, Span] = {
    # rate stiffening k (1 + α δ̇₊) δ = k δ + k α δ δ̇₊: the term's c δ₊ δ̇ with c = k α (equal while loading)
    "contact_rate_product": Span("rate_stiffening", "alpha", ("ki", "k1", "K1")),
}
"""Terms that span a §6 effect's form -> how their coefficient converts to the effect's parameter (the contact
stiffness the effect multiplies: the pendulum's and RIMD's ki, the indenter's k1, the drill's K1)."""


PROBE_AT = 0.45
"""The probe strength of a term: this fraction of its log10 fit range above the lower bound (about the strength that
changes the labels by ~10 %).  A model's ``discrepancy_bounds`` are chosen so that it does (the conformance test
checks the labels move there); the diagnosis' screening starts from it."""


def probe_value(b: FitBound) -> float:
    """A term's probe strength [its unit]: ``PROBE_AT`` of its log10 fit range ``b.bounds`` above the lower bound."""
    lo, hi = b.bounds
    return float(10 ** (lo + PROBE_AT * (hi - lo)))


def mode_bounds(hz_lo: float, hz_hi: float, names: Sequence[str] = MODE_PARAMS,
                ratio: tuple[float, float] = (0.02, 2.0)) -> dict[str, FitBound]:
    """Fit bounds of the hidden mode: its frequency in [hz_lo, hz_hi] [Hz] (a model's own: from below its forcing to
    well above its contact's harmonics), a mass of 2 % to 2x the impacting mass's and a damping ratio 0.5-50 %.
    The residual is multimodal in the frequency (each harmonic the mode meets): its start grid takes ~7 points per
    decade, the mass 3 and the damping 2.  ``names``: the mode's three parameters (a stop or drive mode's), ``ratio``
    the mass ratio's bounds (a mount may outweigh the impacting mass)."""
    n_hz = max(4, round(7 * math.log10(hz_hi / hz_lo)))
    r, hz, zeta = names
    return {r: FitBound(r, ratio[0], ratio[1], "-", grid=3), hz: FitBound(hz, hz_lo, hz_hi, "Hz", grid=n_hz),
            zeta: FitBound(zeta, 0.005, 0.5, "-", grid=2)}


def exponent_bounds() -> dict[str, FitBound]:
    """Fit bounds of the contact exponent's shift: n from 1.03 to 3 (Hertz's sphere 1.5, a cone 2), fitted in log10
    from a start grid of 3."""
    return {EXPONENT_SHIFT: FitBound(EXPONENT_SHIFT, 0.03, 2.0, "-", grid=3)}


def discrepancy_params(acts_on: Mapping[str, str]) -> tuple[Param, ...]:
    """Every term's parameter in vocabulary order, then the hidden mode's, 0 (off) by default and ≥ 0;
    ``acts_on[site]`` says what δ, δ̇ and v are in this model.  A model lists the parameters it has in
    ``ModelSpec.discrepancy``; the others must stay 0."""
    out = []
    for t in TERMS.values():
        where = acts_on.get(t.site, "not in this model")
        out.append(Param(t.name, 0.0, t.unit, f"discrepancy term: {t.words}, {t.form} ({where}); 0 = off",
                         nonnegative=True))
    mode = STRUCTURED[MODE]
    what = ("mass over the impacting mass's (0 = off)", "frequency with the impacting mass held", "damping ratio")
    return (*out, *_mode_params(MODE, f"{mode.words}, {acts_on.get(TOOL, '')}", what))


def site_mode_params(name: str, acts_on: str) -> tuple[Param, ...]:
    """The parameters of a hidden mode at another site than the impacting mass (``STOP_MODE``, ``DRIVE_MODE``;
    ``acts_on``: which body and what the mass ratio is of), 0 (off) by default and ≥ 0."""
    return _mode_params(name, f"{STRUCTURED[name].words}; {acts_on}", ("mass ratio (0 = off)", "frequency",
                                                                        "damping ratio"))


def _mode_params(name: str, context: str, what: Sequence[str]) -> tuple[Param, ...]:
    """A hidden mode's three parameters (mass ratio, frequency, damping ratio: ``what`` each is, in words), 0 (off)
    by default, ≥ 0 and below the typo ceilings; ``context`` the words in their descriptions' brackets."""
    mode = STRUCTURED[name]
    return tuple(Param(q, 0.0, unit, f"discrepancy {name} ({context}): its {w}", nonnegative=True, most=hi)
                 for q, unit, w, hi in zip(mode.params, mode.units, what, (MODE_MAX_RATIO, math.inf, MODE_MAX_ZETA)))


def exponent_params(ref_m: float, acts_on: str) -> tuple[Param, ...]:
    """The contact-exponent candidate's parameters of a model whose contact's elastic part is linear in the
    penetration (``acts_on``: what k and δ are there): the shift, 0 (off) by default, and its reference penetration
    ``ref_m`` [m]."""
    return (Param(EXPONENT_SHIFT, 0.0, "-", f"discrepancy {EXPONENT} ({acts_on}): the exponent n − 1 of "
                  f"{STRUCTURED[EXPONENT].form}; 0 = off", nonnegative=True, most=EXPONENT_MAX_SHIFT),
            Param(EXPONENT_REF, ref_m, "m", f"discrepancy {EXPONENT}: the penetration δ_r at which the shaped "
                  "law has the linear law's force (not fitted: the calibrated stiffness absorbs it)", positive=True))


def unloading_params(acts_on: str) -> tuple[Param, ...]:
    """The unloading candidate's parameter of a model whose contact's elastic part has a loading law (``acts_on``:
    what δ is there), 0 (off) by default; the contact's peak penetration is the first hidden state."""
    return (Param(UNLOADING_SHIFT, 0.0, "-", f"discrepancy {UNLOADING} ({acts_on}): the exponent n_u − 1 of "
                  f"{STRUCTURED[UNLOADING].form}; 0 = off", nonnegative=True, most=UNLOADING_MAX_SHIFT),)


def unloading_bounds() -> dict[str, FitBound]:
    """Fit bounds of the unloading shift: n_u from 1.05 (a faint loop) to 11 (nearly all the elastic energy lost),
    in log10 from a start grid of 3."""
    return {UNLOADING_SHIFT: FitBound(UNLOADING_SHIFT, 0.05, 10.0, "-", grid=3)}


def strength_params(acts_on: str) -> tuple[Param, ...]:
    """The rock rate-strength candidate's parameter of a model with a failing rock (``acts_on``: its threshold and
    failure rate), 0 (off) by default."""
    return (Param(STRENGTH, 0.0, "s/m", f"discrepancy {STRENGTH} ({acts_on}): "
                  f"{STRUCTURED[STRENGTH].form}; 0 = off", nonnegative=True, most=STRENGTH_MAX),)


def strength_bounds(lo: float, hi: float) -> dict[str, FitBound]:
    """Fit bounds [s/m] of the rock's rate strength η (a model's own, for its rock's damping and threshold), fitted
    in log10 from a start grid of 3."""
    return {STRENGTH: FitBound(STRENGTH, lo, hi, "s/m", grid=3)}


def link_params(ref_m_s: float, acts_on: str) -> tuple[Param, ...]:
    """The link-loss candidate's parameters of a model whose impacting mass hangs on a suspension (``acts_on``: which
    link, v its relative velocity): the force, 0 (off) by default, the exponent and its reference velocity
    ``ref_m_s`` [m/s]."""
    form = STRUCTURED[LINK].form
    return (Param(LINK_PARAMS[0], 0.0, "N", f"discrepancy {LINK} ({acts_on}): the force c of {form} at v = v_r; "
                  "0 = off", nonnegative=True),
            Param(LINK_PARAMS[1], 1.0, "-", f"discrepancy {LINK}: the exponent p of {form} (1 = viscous, 0 = "
                  "dry friction with a hard sign, slow to integrate)", nonnegative=True, most=LINK_MAX_EXPONENT),
            Param(LINK_REF, ref_m_s, "m/s", f"discrepancy {LINK}: the reference relative velocity v_r (not fitted)",
                  positive=True))


def link_bounds(force_lo: float, force_hi: float) -> dict[str, FitBound]:
    """Fit bounds of the link loss: its force at v_r [N] (a model's own, for its link's forces) and an exponent
    from 1 (viscous) to 4, each fitted in log10 from a start grid of 3."""
    return {LINK_PARAMS[0]: FitBound(LINK_PARAMS[0], force_lo, force_hi, "N", grid=3),
            LINK_PARAMS[1]: FitBound(LINK_PARAMS[1], 1.0, 4.0, "-", grid=3)}


def drift_params(acts_on: str) -> tuple[Param, ...]:
    """The contact-drift candidate's parameter of a model with a contact at a fixed position (``acts_on``: which
    position and penetration), 0 (off) by default."""
    return (Param(DRIFT_RATE, 0.0, "m/s", f"discrepancy {DRIFT} ({acts_on}): the rate a of {STRUCTURED[DRIFT].form}, "
                  "t from the run's start; 0 = off", nonnegative=True, most=DRIFT_MAX),)


def drift_bounds(lo: float, hi: float) -> dict[str, FitBound]:
    """Fit bounds [m/s] of the contact's drift rate (a model's own: from ~5 % to ~30x its typical penetration over
    a run), fitted in log10 from a start grid of 3."""
    return {DRIFT_RATE: FitBound(DRIFT_RATE, lo, hi, "m/s", grid=3)}


def wear_params(acts_on: str) -> tuple[Param, ...]:
    """The contact-wear candidate's parameters of a model with a contact at a fixed position (``acts_on``: which
    surface and penetration): its coefficient, 0 (off) by default (its depth s is the first hidden state), and k_w N,
    N the cycles run before a steady-state record (``run_cycles``)."""
    return (Param(WEAR_RATE, 0.0, "m/J", f"discrepancy {WEAR} ({acts_on}): the coefficient k_w of "
                  f"{STRUCTURED[WEAR].form}, s from 0 at rest; 0 = off", nonnegative=True, most=WEAR_MAX),
            Param(WEAR_RUN, 0.0, "m/J", f"discrepancy {WEAR}: k_w N, N the forcing cycles the rig ran from rest "
                  "before a steady-state record (the transient of a run left to settle); 0 = the settings' transient",
                  nonnegative=True, most=1e7))


def wear_bounds(lo: float, hi: float, cycles: tuple[float, float] = (20.0, 2000.0)) -> dict[str, FitBound]:
    """Fit bounds of the wear: its coefficient [m/J] (a model's own: from a recession of ~5 % of its typical
    penetration to ~30x it over a run) and k_w N [m/J] for N in ``cycles`` (from a short settling to minutes of
    running) at a mid coefficient, both in log10 from a start grid of 3."""
    mid = math.sqrt(lo * hi)
    return {WEAR_RATE: FitBound(WEAR_RATE, lo, hi, "m/J", grid=3),
            WEAR_RUN: FitBound(WEAR_RUN, mid * cycles[0], mid * cycles[1], "m/J", grid=3)}


def run_cycles(values: Mapping[str, float]) -> int:
    """The transient [cycles] a run left to settle has instead of its settings' (a candidate whose rig never settles
    and that says how long it ran: the wear's ``WEAR_RUN``, up to whole pairs, ``run_pairs``), or 0 (the settings'
    transient).  Plain Python (``py_func``): a run served by an ahead-of-time kernel imports no numba."""
    return int(run_pairs.py_func(float(values.get(WEAR_RATE, 0.0) or 0.0), float(values.get(WEAR_RUN, 0.0) or 0.0)))


def support_params(acts_on: str) -> tuple[Param, ...]:
    """The support-friction candidate's parameters of a model with a support that can rub (``acts_on``: which body,
    v its velocity): the force, 0 (off) by default, and its regularisation speed (MODELS.md §1's 1e-4 m/s)."""
    form = STRUCTURED[SUPPORT].form
    return (Param(SUPPORT_FORCE, 0.0, "N", f"discrepancy {SUPPORT} ({acts_on}): the force μ of {form}; 0 = off",
                  nonnegative=True, most=SUPPORT_MAX),
            Param(SUPPORT_VEPS, 1e-4, "m/s", f"discrepancy {SUPPORT}: the regularisation speed v_ε of {form} (not "
                  "fitted)", positive=True))


def support_bounds(lo: float, hi: float) -> dict[str, FitBound]:
    """Fit bounds [N] of the support's friction force (a model's own, for the forces on that body), fitted in
    log10 from a start grid of 3."""
    return {SUPPORT_FORCE: FitBound(SUPPORT_FORCE, lo, hi, "N", grid=3)}


def vocabulary_at(params: Sequence[Param]) -> int:
    """Index of the first term's parameter in a model's parameter vector ``params``: the terms follow it contiguously
    in vocabulary order (as ``discrepancy_params`` lays them out), which ``terms_at`` reads."""
    names = [q.name for q in params]
    first = names.index(next(iter(TERMS)))
    if tuple(names[first:first + len(TERMS)]) != tuple(TERMS):
        raise ValueError(f"the discrepancy terms must follow each other in vocabulary order {tuple(TERMS)}")
    return first


def _power(code: str, n: int) -> str:
    return " * ".join([code] * n)


def _site_sum(site: Site, at: Mapping[str, tuple[int, Term]]) -> str:
    """The expression of a site's sum of terms ``at`` (name -> (position in the coefficient tuple, term)): with
    x^a0 y^b0 the least powers factored out, Horner in x, each level's coefficients c y^(b - b0) in vocabulary order.
    The contact's δ₊ (c₂ δ̇ + δ₊ (c₀ + δ₊ c₁)) and the tool's v (c₃ + |v| c₄) are the evaluation orders of the
    hand-written sums they replace, bit for bit (IEEE + and × commute exactly)."""
    if not at:
        return "0.0"
    a0 = min(t.powers[0] for _, t in at.values())
    b0 = min(t.powers[1] for _, t in at.values())
    levels: dict[int, list[str]] = {}
    for i, t in at.values():
        levels.setdefault(t.powers[0] - a0, []).append(" * ".join([f"c[{i}]"] + ["y"] * (t.powers[1] - b0)))
    expr = ""
    for k in range(max(levels), -1, -1):
        expr = f"x * ({expr})" if expr else ""
        if k in levels:
            expr = " + ".join(levels[k] + ([expr] if expr else []))
    for var, n in (("y", b0), ("x", a0)):
        if n:
            expr = f"{_power(var, n)} * ({expr})"
    return expr


def site_source(terms: Mapping[str, Term]) -> str:
    """Python source of ``terms_at(p, i)`` (the coefficients of the vocabulary ``terms``, a tuple read from the
    parameter vector p at i on) and of every site's sum (``SITES``: ``contact_extra(c, d, dd)``, ``tool_loss(c, v)``)
    of those coefficients c; exactly 0.0 while the site's coefficients are 0."""
    reads = "".join(f"p[i + {j}], " for j in range(len(terms)))
    out = [f"def terms_at(p, i):\n    return ({reads})\n"]
    for name, site in SITES.items():
        at = {n: (j, t) for j, (n, t) in enumerate(terms.items()) if t.site == name}
        forms = "; ".join(f"c[{j}] {t.name}: {t.form}" for j, t in at.values())
        out.append(f"def {site.name}(c, {', '.join(site.args)}):\n"
                   f"    \"\"\"The {name} site's terms [N] (generated): {forms or 'none'}.\"\"\"\n"
                   f"    x = {site.x[0]}\n    y = {site.y[0]}\n"
                   f"    return {_site_sum(site, at)}\n")
    return "\n\n".join(out)


def site_functions(terms: Mapping[str, Term]) -> dict[str, Callable]:
    """``site_source(terms)`` as Python functions by name (registered with linecache, so tracebacks show them)."""
    src = site_source(terms)
    fname = f"<sim.models.discrepancy sites {abs(hash(src)):x}>"
    linecache.cache[fname] = (len(src), None, src.splitlines(True), fname)
    ns: dict = {"__name__": __name__}
    exec(compile(src, fname, "exec"), ns)
    return {n: ns[n] for n in ("terms_at", *(s.name for s in SITES.values()))}


# The kernels' site functions, generated from TERMS (inlined into every kernel; scalars and a tuple of floats only, no
# branch: numba adds no reference counting where a model calls them inside its phase branches).  Not cached on disk
# by numba (no source file): being inlined, they are compiled only as part of their callers.
_SITES = site_functions(TERMS)
terms_at = njit(inline="always")(_SITES["terms_at"])
contact_extra = njit(inline="always")(_SITES["contact_extra"])
tool_loss = njit(inline="always")(_SITES["tool_loss"])


@njit(cache=True, error_model="numpy")
def shaped(d, s, dref):
    """The contact-exponent candidate's penetration [m] in a contact's elastic part: δ (δ/δ_r)^s for δ > 0, else δ
    (the release indicator keeps its sign), exactly δ while s = 0 (d, dref [m], s [-])."""
    if s == 0.0 or d <= 0.0:
        return d
    return d * (d / dref) ** s


@njit(cache=True, error_model="numpy")
def unloaded(e, em, d, dm, su):
    """The elastic part's penetration measure [m] on the unloading curve: em (δ/δ_m)^(1+s_u) while 0 < δ < δ_m (em
    the loading law's measure at the peak δ_m, e at δ), else e (loading, out of contact); exactly e while s_u = 0."""
    if su == 0.0 or d >= dm or d <= 0.0:
        return e
    return em * (d / dm) ** (1.0 + su)


@njit(cache=True, error_model="numpy")
def peak_rate(su, ph, d, dm, dd):
    """The rate [m/s] of the contact's peak penetration δ_m (the unloading candidate's hidden state): δ̇ in contact
    (phase ph > 0) while loading at the peak (δ̇ > 0, δ ≥ δ_m to round-off: a reload below it follows the unloading
    curve back), else 0; 0 while off."""
    if su == 0.0 or ph <= 0 or dd <= 0.0 or d < dm - 1e-9 * abs(dm):
        return 0.0
    return dd


@njit(cache=True, error_model="numpy")
def drifted(gap, a, t):
    """The contact position [m] at time t [s] of a contact at gap [m] drifting at a [m/s]: exactly gap while a = 0."""
    return gap + a * t


@njit(cache=True, error_model="numpy")
def link_loss(c, pw, vref, dv):
    """The link loss [N] opposing the relative velocity dv [m/s]: c (|dv|/v_r)^p sgn dv (c [N], p [-], v_r [m/s]);
    exactly 0.0 while c = 0."""
    if c == 0.0 or dv == 0.0:
        return 0.0
    f = c * (abs(dv) / vref) ** pw
    return f if dv > 0.0 else -f


@njit(cache=True, error_model="numpy")
def mode_force(ratio, fh, zeta, m_imp, xh, vh):
    """The hidden mode's pull on the impacting mass [N]: kh xh + ch vh with mh = ratio m_imp [kg], kh = mh (2π fh)²,
    ch = 2 ζ mh 2π fh (xh [m], vh [m/s] the hidden mass relative to the impacting one); exactly 0.0 while off."""
    wh = 2.0 * math.pi * fh
    return ratio * m_imp * wh * (wh * xh + 2.0 * zeta * vh)


@njit(cache=True, error_model="numpy")
def hidden_state(switch, s):
    """The hidden state s (the mounted stop's displacement [m] or rate [m/s], the wear's depth [m], the contact's peak
    penetration [m]) while the candidate that holds it is on (its first parameter ``switch`` ≠ 0), else exactly 0.0
    (the hidden states may then hold another candidate)."""
    return s if switch != 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def run_pairs(kw, before):
    """The transient n = 2 ⌈N / 2⌉ [cycles] of a wearing run that ran N = ``before`` / k_w cycles before its record:
    whole pairs, so that the record starts in the same half of a period-2 orbit whatever N; 0 while either is 0."""
    if before <= 0.0 or kw == 0.0:
        return 0.0
    return 2.0 * math.ceil(before / kw / 2.0)


@njit(cache=True, error_model="numpy")
def wear_coef(kw, before, freq, t):
    """k_w [m/J] at time t [s] of a run that ran N = ``before`` / k_w cycles before its record (its transient n at
    ``freq`` [Hz], ``run_pairs``): through the last pair k_w (N − n + 2) / 2, so that the depth at the record moves
    continuously with N, exactly the run's at even N (a fit's derivative sees it); else k_w."""
    n = run_pairs(kw, before)
    if n == 0.0:
        return kw
    run = before / kw
    c = t * freq
    return kw * (run - n + 2.0) / 2.0 if n - 2.0 <= c < n else kw


@njit(cache=True, error_model="numpy")
def wear_speed(kw, f, dd):
    """ṡ = k_w F_c max(v, 0) [m/s], the worn depth's rate: the work pressed into the surface (f the contact force [N],
    0 out of contact; v the approach rate ẋ − ẋ_c [m/s], the rate the contact law reads)."""
    return kw * f * max(dd, 0.0)


@njit(cache=True, error_model="numpy")
def stop_accel(ratio, fh, zeta, m_imp, f, xs, vs):
    """ẍs [m/s²] of the mounted stop (ms = ratio m_imp [kg] on ks = ms (2π fh)², cs = 2 ζ ms 2π fh) pushed by the
    contact force f [N]: f / ms − ωs² xs − 2 ζ ωs vs; 0.0 while off."""
    if ratio == 0.0:
        return 0.0
    ws = 2.0 * math.pi * fh
    return f / (ratio * m_imp) - ws * (ws * xs + 2.0 * zeta * vs)


@njit(cache=True, error_model="numpy")
def mode_accel(ratio, m_imp, f, a_imp):
    """ẍh [m/s²] of the hidden mass relative to the impacting mass: −f / mh − a_imp (f the pull ``mode_force``,
    a_imp the impacting mass's acceleration [m/s²]); 0.0 while off, so the states stay at rest."""
    if ratio == 0.0:
        return 0.0
    return -f / (ratio * m_imp) - a_imp
