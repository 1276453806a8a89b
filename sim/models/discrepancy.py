"""The discrepancy vocabulary: a fixed set of terms a model can gain where no MODELS.md §6 effect explains a rig.

Each term is a model parameter named as the term, ≥ 0 and off at 0 (then the model is the base model bit for bit),
with a fixed form at a fixed site: the contact force expression (``contact_*``, also in the contact's release and
threshold indicators, so the switching stays consistent) or the impacting mass's equation of motion (``tool_*``).
A model lists the terms it has in ``ModelSpec.discrepancy``; the diagnosis proposes a sparse combination of them
(``pipeline.diagnosis.discovery``) and a rig file carries an adopted one as a ``discrepancy:`` entry of term names
and coefficients (``sim.rig``) — never an expression.  The kernels compose ``contact_extra`` and ``tool_loss``.

Not in the vocabulary (no kernel term yet): a hidden degree of freedom in the load path and a first-order lag on
the forcing (where a model has ``shaker_coil``, its τ is that lag); a cubic spring is §6 ``suspension_hardening``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from sim.jit import njit  # numba is imported on first use (sim/jit.py)
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

def discrepancy_params(acts_on: Mapping[str, str]) -> tuple[Param, ...]:
    """Every term's parameter in vocabulary order, 0 (off) by default and ≥ 0; ``acts_on[site]`` says what δ, δ̇
    and v are in this model.  A model lists the terms it has in ``ModelSpec.discrepancy``; the others must stay 0."""
    out = []
    for t in TERMS.values():
        where = acts_on.get(t.site, "not in this model")
        out.append(Param(t.name, 0.0, t.unit, f"discrepancy term: {t.words}, {t.form} ({where}); 0 = off",
                         nonnegative=True))
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
