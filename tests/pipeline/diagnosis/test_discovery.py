"""Discrepancy discovery (pipeline.diagnosis.discovery): the screening's sparse regression on a problem whose answer
is known, the proposals it leads to, and the report's shape.  The end-to-end checks on logs of the independent
generator are in test_independent_verdicts.py; the matrix is ``python -m bench.discovery``."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.diagnosis import discovery as D
from pipeline.diagnosis.model import calibratable

SYSTEM = "drill"


class LinearRig:
    """A stand-in Evaluator whose residual is linear in log10 of the calibratable parameters and in the terms'
    strengths: r = Jc (log p − log p_true) + Σ_t Jt[t] (c_t − c_true_t) / probe_t + noise — the screening's model
    exactly, so its answer is known."""

    def __init__(self, truth_terms: dict, n: int = 400, seed: int = 0, noise: float = 1.0):
        rng = np.random.default_rng(seed)
        self.system = SYSTEM
        self.cal = [p.name for p in calibratable(SYSTEM)]
        self.terms = D.term_candidates(SYSTEM)
        self.jc = rng.standard_normal((n, len(self.cal))) * 30.0
        self.jt = {t: rng.standard_normal(n) * 20.0 for t in self.terms}
        # the last term's signature is mostly a calibratable direction: screening must not credit it
        last = list(self.terms)[-1]
        self.jt[last] = self.jc[:, 0] * 0.7 + 0.1 * self.jt[last]
        self.truth_terms = truth_terms
        self.true_cal = {n: 10.0 ** (k + 1) for k, n in enumerate(self.cal)}
        self.noise = rng.standard_normal(n) * noise

    def residuals(self, sets, idx):
        out = []
        for s in sets:
            r = self.noise.copy()
            r += self.jc @ np.array([math.log10(s[n] / self.true_cal[n]) for n in self.cal])
            for t, b in self.terms.items():
                r += self.jt[t] * (s.get(t, 0.0) - self.truth_terms.get(t, 0.0)) / D.probe_value(b)
            out.append(r)
        return out


def test_screening_finds_the_term_behind_the_residual():
    terms = D.term_candidates(SYSTEM)
    true = "tool_quadratic_drag"
    value = D.probe_value(terms[true]) * 0.8
    ev = LinearRig({true: value})
    scr = D.screen(ev, [0], dict(ev.true_cal), terms)
    assert scr.support == [true] and scr.order[0] == true
    assert scr.estimate[true] == pytest.approx(value, rel=0.05)
    assert all(scr.estimate[t] == 0.0 for t in terms if t != true)
    assert min(scr.path_bic) < scr.path_bic[0] - 100        # the support is worth its cost in BIC


def test_screening_finds_nothing_in_noise_alone():
    ev = LinearRig({})
    scr = D.screen(ev, [0], dict(ev.true_cal), D.term_candidates(SYSTEM))
    assert scr.support == []
    assert sorted(D.proposal_sets(scr, 3)) == sorted((t,) for t in D.term_candidates(SYSTEM))   # no evidence: all


def test_a_term_a_recalibration_can_mimic_is_not_credited():
    """The residual of a mis-calibrated base along the last term's (calibration-like) signature: the projection
    takes it out, and nothing is selected."""
    ev = LinearRig({})
    base = dict(ev.true_cal)
    base[ev.cal[0]] *= 10 ** 0.02
    scr = D.screen(ev, [0], base, D.term_candidates(SYSTEM))
    assert list(D.term_candidates(SYSTEM))[-1] not in scr.support


def test_two_terms_at_once_and_the_proposals_they_lead_to():
    terms = D.term_candidates(SYSTEM)
    a, b = "contact_quadratic", "tool_viscous"
    ev = LinearRig({a: D.probe_value(terms[a]), b: 0.5 * D.probe_value(terms[b])})
    scr = D.screen(ev, [0], dict(ev.true_cal), terms)
    assert set(scr.support) == {a, b}
    sets = D.proposal_sets(scr, 3)
    assert sets[0] == tuple(scr.support) and len(sets) == 3 and len(set(sets)) == 3
    assert {s[0] for s in sets[1:]} <= {a, b} | set(scr.order[:3])
    assert D.proposal_sets(scr, 1) == [tuple(scr.support)]


def test_proposal_names_round_trip():
    name = D.proposal_name(("contact_quadratic", "tool_viscous"))
    assert name.startswith(D.PREFIX) and D.proposal_terms(name) == ["contact_quadratic", "tool_viscous"]


@pytest.mark.parametrize("system", ["drill", "indenter-metal", "indenter-sandstone", "pendulum", "rimd"])
def test_the_hidden_mode_is_a_structured_candidate_of_every_model(system):
    """The hidden load-path mode is fitted as a proposal of its own (three parameters, with bounds), never screened
    as a regression column; so are the contact exponent where the contact's elastic part is linear, the rock's
    rate strength where a rock fails, the link loss where the impacting mass hangs on a suspension, the contact's
    drift and wear where it sits at a fixed position and the support friction where a support can rub."""
    from sim.models.discrepancy import (DRIFT, DRIFT_RATE, DRIVE_MODE, DRIVE_MODE_PARAMS, EXPONENT, EXPONENT_SHIFT,
                                        LINK, LINK_PARAMS, MODE, MODE_PARAMS, STOP_MODE, STOP_MODE_PARAMS, STRENGTH,
                                        SUPPORT, SUPPORT_FORCE, UNLOADING, UNLOADING_SHIFT, WEAR, WEAR_RATE)

    structured = D.structured_candidates(system)
    own = {"indenter-metal": [EXPONENT, LINK, DRIFT, SUPPORT, STOP_MODE, WEAR, UNLOADING],
           "indenter-sandstone": [LINK, SUPPORT],
           "pendulum": [EXPONENT, DRIFT, SUPPORT, WEAR, UNLOADING], "drill": [STRENGTH, LINK, DRIVE_MODE],
           "rimd": [LINK, SUPPORT, STOP_MODE, DRIVE_MODE]}[system]
    assert list(structured) == [MODE, *own]
    assert tuple(b.name for b in structured[MODE]) == MODE_PARAMS
    for name in structured:
        assert all(0.0 < 10 ** b.bounds[0] < 10 ** b.bounds[1] for b in structured[name])
    assert not ((set(MODE_PARAMS) | {EXPONENT_SHIFT, STRENGTH, *LINK_PARAMS, DRIFT_RATE, SUPPORT_FORCE,
                                     *STOP_MODE_PARAMS, *DRIVE_MODE_PARAMS, WEAR_RATE, UNLOADING_SHIFT})
                & set(D.term_candidates(system)))


def test_a_structured_proposal_reports_its_parameters():
    """report(): a proposal of the hidden mode lists its kind "mode", its three parameters with sd and interval."""
    from pipeline.diagnosis.fit import FitResult
    from pipeline.diagnosis.verdict import Check, ModelStats
    from sim.models.discrepancy import MODE, MODE_PARAMS

    name = D.proposal_name((MODE,))
    vals = {"K1": 1e8, "C1": 1e4, "Pr": 2e3, **dict(zip(MODE_PARAMS, (0.25, 1000.0, 0.05)))}
    fr = FitResult(values=vals, free=list(vals), chi2=10.0, n=100, nfev=20, sd={k: 0.1 * v for k, v in vals.items()},
                   ci95={k: (0.8 * v, 1.2 * v) for k, v in vals.items()})
    from pipeline.diagnosis.heldout import HeldOut

    err = HeldOut(nrms=1.1, chi2=121.0, n=100, by_run_nrms={"a": 1.0, "b": 1.2}, error=0.01, noise_floor=0.009,
                  error_by_group={}, noise_by_group={}, systematic=0.001)
    base_err = HeldOut(nrms=20.0, chi2=4e4, n=100, by_run_nrms={"a": 19.0, "b": 21.0}, error=0.2, noise_floor=0.009,
                       error_by_group={}, noise_by_group={})
    d = D.Discovery(screening=D.Screening([], [], {}, {}, []), fits={name: fr}, err={name: err},
                    stats={name: ModelStats(name=name, bic=50.0, chi2=121.0, n=100, systematic=0.001)},
                    accepted=name, leader=name,
                    checks={name: Check(adequate=True, nrms=1.1, systematic=0.001, delta_bic=-50.0, delta_chi2=400.0,
                                        systematic_gain=None, improves=True)})
    rep = D.report(d, base_err, ["K1", "C1", "Pr"])
    [p] = rep.proposals
    assert p.kinds == ("mode",) and p.terms == (MODE,)
    assert list(p.coefficients) == list(MODE_PARAMS) and p.coefficients["load_path_mode_hz"] == 1000.0
    assert rep.accepted == (MODE,) and "hidden mass" in rep.text
    assert rep.to_json()["proposals"][0]["terms"] == [MODE]       # a list in report.json
    import dataclasses     # not accepted: the text names every candidate tried, the structured one too
    text = D.report(dataclasses.replace(d, accepted=None), base_err, ["K1", "C1", "Pr"]).text
    assert text.endswith(f"not in the vocabulary of this model ({MODE})")


@pytest.mark.parametrize("system", ["drill", "indenter-metal", "indenter-sandstone", "pendulum", "rimd"])
def test_every_span_converts_to_an_effect_the_model_has(system):
    """A term declared as a §6 effect in another form (``SPANS``) names that effect's parameter, and every model that
    has both the term and the effect has the stiffness its coefficient is divided by."""
    import sim
    from sim.models.discrepancy import SPANS, TERMS
    from sim.models.effects import EFFECTS

    spec = sim.get_model(system)
    for term, span in SPANS.items():
        assert term in TERMS and span.param in EFFECTS[span.effect].param_names
        if term in spec.discrepancy and span.effect in spec.effects:
            assert any(p in spec.param_names for p in span.per), (system, term)


def test_contact_rate_product_is_rate_stiffening_in_another_form():
    """c δ₊ δ̇ = k α δ δ̇₊ while loading: an accepted contact_rate_product proposal on the pendulum starts rate
    stiffening at α = c / ki (the load cell's fitted stiffness); a proposal of another term, or of two, spans
    nothing, nor does an effect the diagnosis does not try."""
    name = D.proposal_name(("contact_rate_product",))
    values = {"ki": 5.0e6, "ci": 1.2e3, "zeta": 0.005, "contact_rate_product": 2.5e7}
    assert D.spanned_effect("pendulum", name, values, ["rate_stiffening", "sensor_lowpass"]) == (
        "rate_stiffening", {"alpha": pytest.approx(5.0)})
    assert D.spanned_effect("indenter-metal", name, {"k1": 1e7, "contact_rate_product": 3e7},
                            ["rate_stiffening"]) == ("rate_stiffening", {"alpha": pytest.approx(3.0)})
    assert D.spanned_effect("pendulum", name, values, ["sensor_lowpass"]) is None
    assert D.spanned_effect("pendulum", D.proposal_name(("contact_cubic",)), values, ["rate_stiffening"]) is None
    both = D.proposal_name(("contact_rate_product", "contact_cubic"))
    assert D.spanned_effect("pendulum", both, values, ["rate_stiffening"]) is None


def test_a_proposal_needs_two_numbers_per_free_parameter():
    """A summary log like the published seed-000 data (4 runs of 2-3 numbers, one a lower bound; leave-one-run-out)
    leaves 6 two-sided numbers in the smallest fold: no proposal on 3 calibratables (4 parameters need 8) is fitted,
    and the report says why instead of ranking fits that interpolate the data."""
    from types import SimpleNamespace

    from pipeline.diagnosis.heldout import HeldOut

    lb = [np.array([True, False, False]), np.zeros(2, bool), np.zeros(2, bool), np.zeros(3, bool)]
    ev = SimpleNamespace(targets=[SimpleNamespace(lower_bound=m) for m in lb])
    loro = SimpleNamespace(folds=tuple(([j for j in range(4) if j != i], [i]) for i in range(4)))
    assert D.calibration_numbers(ev, loro) == 6            # the fold without the 3-number two-sided run
    cands = {"discrepancy:tool_viscous": ("c",), "discrepancy:load_path_mode": ("r", "f", "z")}
    assert D.supported(cands, 6, 3) == ({}, list(cands))
    assert D.supported(cands, 8, 3) == ({"discrepancy:tool_viscous": ("c",)}, ["discrepancy:load_path_mode"])
    assert D.supported(cands, 12, 3) == (cands, [])
    d = D.Discovery(screening=D.Screening([], [], {}, {}, []), fits={}, err={}, stats={}, accepted=None, leader=None,
                    checks={}, too_few=tuple(cands), n_numbers=6)
    base_err = HeldOut(nrms=4.2, chi2=50.0, n=3, by_run_nrms={"a": 4.2}, error=0.3, noise_floor=0.07,
                       error_by_group={}, noise_by_group={})
    rep = D.report(d, base_err, ["k1", "c1", "pm"])
    assert rep.proposals == () and rep.accepted is None
    assert "hold 6 measured numbers" in rep.text and "more runs or series records" in rep.text


def test_a_parameter_that_acts_on_steady_state_records_only_is_fitted_only_where_a_log_has_them():
    """The wear's run before a steady-state record (k_w N) moves nothing on a record from rest: discovery fits it
    only when the log has steady-state records."""
    from sim.models.discrepancy import WEAR, WEAR_RATE, WEAR_RUN

    steady = D.structured_candidates("pendulum", steady=True)[WEAR]
    from_rest = D.structured_candidates("pendulum", steady=False)[WEAR]
    assert [b.name for b in steady] == [WEAR_RATE, WEAR_RUN] and [b.name for b in from_rest] == [WEAR_RATE]


class AbsorbedRig:
    """A stand-in Evaluator for a structured candidate with a narrow basin (a hidden mode near a forcing harmonic):
    r = Jc (log p − log p_true) + a w(θ) + Jc[:, 0] b h(θ), θ the candidate's log10 parameter.  Its narrow part w
    vanishes at θ_true and is ~1 elsewhere; its broad part h (0 at θ_true, 1 far from it) is a calibratable
    direction, which a base fit without the candidate absorbs: at that base every grid point near θ_true reads
    worse than the far ones, until a recalibration is allowed."""

    def __init__(self, n: int = 300, seed: int = 1):
        rng = np.random.default_rng(seed)
        self.system = SYSTEM
        self.free = list(calibratable(SYSTEM))
        self.cal = [p.name for p in self.free]
        self.jc = rng.standard_normal((n, len(self.cal)))
        self.narrow = rng.standard_normal(n) * 0.6
        self.true_cal = {p.name: 10 ** (0.5 * (p.bounds[0] + p.bounds[1])) for p in self.free}
        self.theta = math.log10(400.0)
        self.targets = [type("T", (), {"low": np.ones(n, bool)})()]

    def shape(self, x: float) -> tuple[float, float]:
        d = (x - self.theta) / 0.04
        return 1.0 - math.exp(-d * d), 1.0 - math.exp(-d * d / 400.0)

    def residuals(self, sets, idx):
        out = []
        for s in sets:
            w, h = self.shape(math.log10(s["mode_hz"])) if s.get("mode_hz") else (1.0, 1.0)    # off: far
            dp = np.array([math.log10(s[c] / self.true_cal[c]) for c in self.cal])
            out.append(self.jc @ dp + self.narrow * w + self.jc[:, 0] * 3.0 * h)
        return out

    def absorbed_base(self) -> dict:
        """The base fit without the candidate (θ far away): the calibratable offset that cancels the broad part."""
        return {**self.true_cal, self.cal[0]: self.true_cal[self.cal[0]] * 10 ** -3.0}


def test_a_narrow_basin_the_base_absorbed_is_found_by_projecting_out_the_recalibration():
    """``candidate_start``'s ``projected`` ranking: at the absorbed base the grid point next to the truth (453 Hz
    against 400) reads worse than every far one, so the profiles of the raw ranking miss it; with the recalibration
    projected out it ranks first and its profile is the start."""
    from types import SimpleNamespace

    from pipeline.diagnosis.calibrate import candidate_start
    from sim.models.fitbound import FitBound

    rig = AbsorbedRig()
    eff = (FitBound("mode_hz", 50.0, 3000.0, "Hz", grid=12),)
    cfg = SimpleNamespace(grid=4, profile_points=2, profile_nfev=3, diff_step=0.01)
    base = rig.absorbed_base()
    axis = 10 ** np.linspace(*eff[0].bounds, 14)[1:-1]
    near = float(axis[np.argmin(abs(np.log10(axis) - rig.theta))])
    raw = [float(r @ r) for r in rig.residuals([{**base, "mode_hz": f} for f in axis], [0])]
    assert np.argmin(raw) != np.argmin(abs(axis - near))             # the unprofiled grid misses it
    plain = candidate_start(rig, [0], base, eff, rig.free, cfg)
    found = candidate_start(rig, [0], base, eff, rig.free, cfg, projected=True)
    assert plain["mode_hz"] != near
    assert found["mode_hz"] == near
    chi2 = [float(r @ r) for r in rig.residuals([plain, found], [0])]
    assert chi2[1] < chi2[0]
