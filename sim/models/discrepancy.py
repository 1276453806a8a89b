"""The discrepancy vocabulary: a fixed set of terms a model can gain where no MODELS.md §6 effect explains a rig.

Each term is a model parameter named as the term, ≥ 0 and off at 0 (then the model is the base model bit for bit),
with a fixed form at a fixed site: the contact force expression (``contact_*``, also in the contact's release and
threshold indicators, so the switching stays consistent) or the impacting mass's equation of motion (``tool_*``).
A model lists the terms it has in ``ModelSpec.discrepancy``; the diagnosis proposes a sparse combination of them
(``pipeline.diagnosis.discovery``) and a rig file carries an adopted one as a ``discrepancy:`` entry of term names
and coefficients (``sim.rig``) — never an expression.  The kernels compose ``contact_extra`` and ``tool_loss``.

One *structured* candidate sits beside the terms: ``load_path_mode``, a hidden mass on a spring and damper at the
impacting mass (an extra mode in the load path), three parameters (``MODE_PARAMS``: mass ratio, frequency, damping
ratio) and two more states (``MODE_STATES``, after the model's own; off while the ratio is 0).  Not in the
vocabulary: a first-order lag on the forcing (where a model has ``shaker_coil``, its τ is that lag); a cubic spring
is §6 ``suspension_hardening``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

from sim.jit import njit  # numba is imported on first use (sim/jit.py)
from sim.models.fitbound import FitBound
from sim.models.param import Param

CONTACT = "contact"
TOOL = "tool"


@dataclass(frozen=True)
class Term:
    """One discrepancy term: ``name`` (= its parameter), unit, site (CONTACT or TOOL), form in symbols, kind of
    physics (what a researcher would call it) and its meaning in words."""

    name: str
    unit: str
    site: str
    form: str
    kind: str
    words: str

    @property
    def params(self) -> tuple[str, ...]:
        """The parameters of the term: its own name."""
        return (self.name,)


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
    Term("contact_quadratic", "N/m^2", CONTACT, "F_c += c δ₊²", "contact",
         "contact stiffening quadratic in penetration"),
    Term("contact_cubic", "N/m^3", CONTACT, "F_c += c δ₊³", "contact",
         "contact stiffening cubic in penetration"),
    Term("contact_rate_product", "N s/m^2", CONTACT, "F_c += c δ₊ δ̇", "contact",
         "contact damping growing with penetration (Hunt–Crossley-like)"),
    Term("tool_viscous", "N s/m", TOOL, "F_tool −= c v", "velocity_loss",
         "viscous loss on the impacting mass"),
    Term("tool_quadratic_drag", "N s^2/m^2", TOOL, "F_tool −= c v |v|", "velocity_loss",
         "velocity-squared loss (drag) on the impacting mass"),
)}
"""The vocabulary, in the kernels' parameter order (``index_of(PARAMS, *TERMS)``; δ₊ = max(δ, 0) the penetration, δ̇ its rate, v the impacting
mass's velocity)."""

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

CANDIDATES: dict[str, Term | Structured] = {**TERMS, **STRUCTURED}
"""Every candidate of the vocabulary by name."""

PARAM_OF: dict[str, str] = {p: c.name for c in CANDIDATES.values() for p in c.params}
"""Every discrepancy parameter -> the candidate it belongs to."""


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


def mode_bounds(hz_lo: float, hz_hi: float) -> dict[str, FitBound]:
    """Fit bounds of the hidden mode: its frequency in [hz_lo, hz_hi] [Hz] (a model's own: from below its forcing to
    well above its contact's harmonics), a mass of 2 % to 2x the impacting mass's and a damping ratio 0.5-50 %.
    The residual is multimodal in the frequency (each harmonic the mode meets): its start grid takes ~7 points per
    decade, the mass 3 and the damping 2."""
    n_hz = max(4, round(7 * math.log10(hz_hi / hz_lo)))
    return {"load_path_mode_ratio": FitBound("load_path_mode_ratio", 0.02, 2.0, "-", grid=3),
            "load_path_mode_hz": FitBound("load_path_mode_hz", hz_lo, hz_hi, "Hz", grid=n_hz),
            "load_path_mode_zeta": FitBound("load_path_mode_zeta", 0.005, 0.5, "-", grid=2)}


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
    what = ("mass over the impacting mass's (0 = off)", "frequency with the impacting mass held",
            "damping ratio")
    most = (MODE_MAX_RATIO, math.inf, MODE_MAX_ZETA)
    for name, unit, w, hi in zip(mode.params, mode.units, what, most):
        out.append(Param(name, 0.0, unit, f"discrepancy {MODE} ({mode.words}, {acts_on.get(TOOL, '')}): its {w}",
                         nonnegative=True, most=hi))
    return tuple(out)


@njit(cache=True, inline="always")
def contact_extra(cq, cc, cp, d, dd):
    """The contact terms [N]: cq δ₊² + cc δ₊³ + cp δ₊ δ̇ (cq [N/m²], cc [N/m³], cp [N s/m²], δ [m], δ̇ [m/s]);
    exactly 0.0 when the three coefficients are 0."""
    dp = max(d, 0.0)
    return dp * (dp * (cq + cc * dp) + cp * dd)


@njit(cache=True, inline="always")
def tool_loss(cv, cq, v):
    """The tool terms' force [N] opposing the impacting mass's velocity v [m/s]: cv v + cq v |v| (cv [N s/m],
    cq [N s²/m²]); exactly 0.0 when both are 0."""
    return v * (cv + cq * abs(v))


@njit(cache=True, inline="always")
def mode_force(ratio, fh, zeta, m_imp, xh, vh):
    """The hidden mode's pull on the impacting mass [N]: kh xh + ch vh with mh = ratio m_imp [kg], kh = mh (2π fh)²,
    ch = 2 ζ mh 2π fh (xh [m], vh [m/s] the hidden mass relative to the impacting one); exactly 0.0 while off."""
    wh = 2.0 * math.pi * fh
    return ratio * m_imp * wh * (wh * xh + 2.0 * zeta * vh)


@njit(cache=True, inline="always")
def mode_accel(ratio, m_imp, f, a_imp):
    """ẍh [m/s²] of the hidden mass relative to the impacting mass: −f / mh − a_imp (f the pull ``mode_force``,
    a_imp the impacting mass's acceleration [m/s²]); 0.0 while off, so the states stay at rest."""
    if ratio == 0.0:
        return 0.0
    return -f / (ratio * m_imp) - a_imp
