"""The verdict of a diagnosis from held-out statistics: nothing missing, a §6 effect selected, or unexplained.

Every statistic is on the held-out runs (never those a model was fitted to), except the information criterion:

- ``nrms``: sqrt(χ²/n) of the noise-normalised residual; the feature sd is the noise estimated per signal, record
  and harmonic (features.record_noise) with a model floor in quadrature, so 1 means "at the noise level";
- ``systematic``: the relative systematic error from the record halves, sqrt(Σ r_A·r_B / Σ y²) with r_A, r_B the
  residuals of the two halves of every series record: noise is independent between the halves and averages out of
  the product, a model error is in both, so this needs no estimate of σ at all;
- ``delta_bic``: the base model's BIC minus the candidate's on the calibration runs (χ² + k ln n with the same σ);
- ``delta_chi2``: the base model's held-out χ² minus the candidate's.

The rule (thresholds in ``VerdictRule``; docs/diagnose.md derives them from the identification matrix):

1. A model is **adequate** when its held-out nrms ≤ ``explained_nrms`` *or* its systematic error ≤
   ``systematic_tol`` with its nrms ≤ ``systematic_nrms_cap``: either the residual is at the noise level, or it is
   too small to matter where the noise estimate is off (σ misestimated up to the cap's factor, 2: the bound the
   noise estimate is checked to).  A residual further above the noise is a model error whatever its relative size
   (a drill's coil fitted alone beside guide friction: systematic 0.4 %, nrms 13, ROP off by 3-26 %).
2. A candidate **improves** on the base when it wins on the calibration runs (delta_bic ≥ ``bic_margin``), on the
   held-out runs (delta_chi2 ≥ ``test_margin``), and materially: it removes at least half of ``systematic_tol``
   of systematic error (held-out), so a tiny mismatch between two simulations of the same equations, significant
   only because the records are long and clean, is never assigned to an effect; or it brings a base whose held-out
   nrms is above ``explained_nrms`` to the noise level; or it cuts the base's held-out nrms to ``nrms_ratio`` of
   it or less (a ratio: the same whatever σ's scale).  A drift such as tip blunting that the calibrated base
   matches on average leaves little split-half error but an nrms of 2-3 that the effect takes to 0.4-0.6.
3. Of the improving candidates the one with the lowest BIC is the **leader**: *selected* if adequate, else the
   residual is *unexplained* (the leader is the best partial explanation).  With no improving candidate: *nothing
   missing* if the base is adequate, else *unexplained*.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

NOTHING_MISSING = "nothing missing"
SELECTED = "selected"
UNEXPLAINED = "unexplained"


@dataclass(frozen=True)
class VerdictRule:
    """Thresholds of the verdict (DiagnoseConfig carries them; see the module docstring)."""

    explained_nrms: float = 2.0
    systematic_tol: float = 0.005
    bic_margin: float = 10.0
    test_margin: float = 25.0
    nrms_ratio: float = 0.5
    systematic_nrms_cap: float = 4.0


@dataclass(frozen=True)
class ModelStats:
    """What the verdict reads of one model (base or candidate)."""

    name: str
    bic: float                       # calibration runs
    chi2: float                      # held-out
    n: int                           # held-out residuals
    systematic: float | None         # held-out split-half systematic error (None: no series halves)

    @property
    def nrms(self) -> float:
        return math.sqrt(self.chi2 / max(self.n, 1))


@dataclass(frozen=True)
class Check:
    """What the rule saw of one model against the reference (``Verdict.checks``; report.json ``call`` entries)."""

    adequate: bool
    """Held-out residual at the noise level (rule 1)."""
    nrms: float
    """Held-out nrms [-]."""
    systematic: float | None
    """Held-out systematic error [-] (None: no series halves)."""
    delta_bic: float
    """The reference's BIC minus the model's (calibration runs) [-]."""
    delta_chi2: float
    """The reference's held-out χ² minus the model's [-]."""
    systematic_gain: float | None
    """Systematic error removed against the reference [-]."""
    improves: bool
    """Improves on the reference (rule 2; False for the reference itself)."""


@dataclass(frozen=True)
class Verdict:
    """The call and the numbers behind it: ``kind`` (NOTHING_MISSING, SELECTED, UNEXPLAINED), the selected effect,
    the leader (best improving candidate, selected or not) and the runner-up (next by BIC), and per model why."""

    kind: str
    selected: str | None
    leader: str | None
    runner_up: str | None
    checks: dict[str, Check] = field(default_factory=dict)    # model -> what the rule saw of it

    @property
    def explained(self) -> bool:
        return self.kind != UNEXPLAINED


def adequate(m: ModelStats, rule: VerdictRule) -> bool:
    """Held-out residual at the noise level, or a systematic error below the tolerance with a residual not far
    above the noise (rule 1)."""
    return m.nrms <= rule.explained_nrms or (m.systematic is not None and m.systematic <= rule.systematic_tol
                                             and m.nrms <= rule.systematic_nrms_cap)


def _gain(base: ModelStats, m: ModelStats) -> float | None:
    if base.systematic is None or m.systematic is None:
        return None
    return base.systematic - m.systematic


def improves(base: ModelStats, m: ModelStats, rule: VerdictRule) -> bool:
    """Better on calibration (BIC) and held-out (χ²) runs, and materially: by a systematic error, by bringing a
    base above the noise level down to it, or by cutting its held-out nrms to ``nrms_ratio`` of it (rule 2)."""
    gain = _gain(base, m)
    material = (gain is None or gain >= 0.5 * rule.systematic_tol
                or (base.nrms > rule.explained_nrms and m.nrms <= rule.explained_nrms)
                or m.nrms <= rule.nrms_ratio * base.nrms)
    return base.bic - m.bic >= rule.bic_margin and base.chi2 - m.chi2 >= rule.test_margin and material


def decide(base: ModelStats, candidates: list[ModelStats], rule: VerdictRule) -> Verdict:
    """The verdict (module docstring, rule 3)."""
    ranked = sorted(candidates, key=lambda m: m.bic)
    checks = {}
    for m in [base, *ranked]:
        checks[m.name] = Check(adequate=adequate(m, rule), nrms=m.nrms, systematic=m.systematic,
                               delta_bic=base.bic - m.bic, delta_chi2=base.chi2 - m.chi2,
                               systematic_gain=_gain(base, m), improves=m is not base and improves(base, m, rule))
    winners = [m for m in ranked if checks[m.name].improves]
    leader = winners[0] if winners else None
    others = [m for m in ranked if m is not leader]
    runner = others[0].name if others else None
    if leader is not None:
        kind = SELECTED if checks[leader.name].adequate else UNEXPLAINED
        return Verdict(kind, leader.name if kind == SELECTED else None, leader.name, runner, checks)
    kind = NOTHING_MISSING if checks[base.name].adequate else UNEXPLAINED
    return Verdict(kind, None, None, runner, checks)


def indistinguishable(v: Verdict, stats: dict[str, ModelStats], rule: VerdictRule) -> list[str]:
    """Improving candidates whose BIC is within ``bic_margin`` of the leader's: the data at hand cannot tell them
    from the leader (empty when nothing leads)."""
    if v.leader is None:
        return []
    lead = stats[v.leader].bic
    return [m for m, c in v.checks.items()
            if m != v.leader and c.improves and stats[m].bic - lead < rule.bic_margin]


def _ratio(x: float | None, limit: float) -> str:
    return "n/a" if x is None else f"{x:.3g} ({x / limit:.2g}× the limit {limit:g})"


def _entry(check: Check, name: str | None = None):
    from dataclasses import asdict

    from pipeline.diagnosis.report_types import CallEntry, effects_of

    return CallEntry(name=effects_of(name), **asdict(check))


def closeness(v: Verdict, stats: dict[str, ModelStats], rule: VerdictRule):
    """How close the call was (a ``report_types.Call``): the numbers each threshold saw, and a sentence a user can
    weigh."""
    from pipeline.diagnosis.report_types import Call

    base = stats["base"]
    c = v.checks
    gap = share = None
    if v.kind == SELECTED:
        lead = c[v.leader]
        gap = (stats[v.runner_up].bic - stats[v.leader].bic) if v.runner_up else math.inf
        text = (f"{v.leader} selected: held-out nrms {_ratio(lead.nrms, rule.explained_nrms)}, systematic error "
                f"{_ratio(lead.systematic, rule.systematic_tol)}; BIC better than the base by {lead.delta_bic:.3g} "
                f"(margin {rule.bic_margin:g}) and than the runner-up {v.runner_up} by {gap:.3g}; held-out χ² "
                f"{lead.delta_chi2:.3g} below the base's (margin {rule.test_margin:g})")
    elif v.kind == NOTHING_MISSING:
        best = c[v.runner_up] if v.runner_up else None
        text = (f"nothing missing: the calibrated base has held-out nrms {_ratio(c['base'].nrms, rule.explained_nrms)} "
                f"and systematic error {_ratio(c['base'].systematic, rule.systematic_tol)}")
        if best:
            text += (f"; the best candidate {v.runner_up} gains ΔBIC {best.delta_bic:.3g} (margin {rule.bic_margin:g}) "
                     f"and held-out Δχ² {best.delta_chi2:.3g} (margin {rule.test_margin:g})")
    else:
        who = v.leader or v.runner_up
        text = (f"unexplained: the calibrated base has held-out nrms {c['base'].nrms:.3g} and systematic error "
                f"{_ratio(c['base'].systematic, rule.systematic_tol)}")
        if who:
            w = c[who]
            excess = max(base.chi2 - base.n, 1e-300)
            share = max(0.0, min(1.0, w.delta_chi2 / excess))
            text += (f"; the best candidate {who} removes {100 * share:.0f} % of the excess held-out χ² and leaves nrms "
                     f"{w.nrms:.3g}, systematic error {_ratio(w.systematic, rule.systematic_tol)}")
    return Call(base=_entry(c[base.name]), leader=_entry(c[v.leader], v.leader) if v.leader else None,
                runner_up=_entry(c[v.runner_up], v.runner_up) if v.runner_up else None, bic_gap_to_runner_up=gap,
                best_candidate_share=share, text=text)
