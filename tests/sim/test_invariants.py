"""Invariants of every simulation result (sim/invariants.py, docs/simulate.md "Statuses and the invariants").

Every result is a valid ``ok`` (periodic over whole periods, ROP >= 0, counts and forces >= 0, the energy balance
where the model has one) or a named status with its reason: property-based tests (hypothesis) draw points over every
model's parameter box and far outside it (0.1-10 000 Hz, 1e-3-1e3 x every default) on the exact and the numerical
path.  The default suite runs a few dozen points per model and path with short windows (derandomized: the same
points every run); ``pytest -m slow`` runs a larger sweep.
"""
from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import sim
from sim.invariants import violation
from sim.models.discrepancy import PARAM_OF as DISCREPANCY_PARAMS
from vibrobase.statuses import BOUNDED_STATUSES, STATUSES

MODELS = sim.model_names()
# short runs (the properties hold for any window), and a work limit so a point far outside the box ends `failed`
# with its reason in well under a second instead of integrating for minutes
SHORT = {"min_transient": 4, "max_transient": 24, "window": 8, "max_steps": 300_000}
PATHS = [(m, method) for m in MODELS for method in ("auto", "dopri5") if method == "dopri5" or sim.get_model(m).exact]


def _scaled_parameters(spec):
    """Every parameter of ``spec`` that has a non-zero value by default, except the effects and discrepancy terms
    (off at 0, where the exact path applies) and the indenter's P and D (they only derive the static force)."""
    effect = {p for ps in spec.effects.values() for p in ps}
    return [p.name for p in spec.params
            if p.name not in effect and p.name not in DISCREPANCY_PARAMS and p.name not in ("P", "D", "frequency_hz")]


@st.composite
def points(draw, model: str):
    """(preset, overrides) of a preset of the model (or none), half of them inside the box it was validated on
    (``ModelSpec.validated``: its controls uniform in their ranges, the calibratable parameters log-uniform in their
    fit bounds), half far outside: the frequency log-uniform in 0.1-10 000 Hz and every other non-zero parameter its
    value times 10^u, u uniform in [-3, 3]."""
    spec = sim.get_model(model)
    preset = draw(st.sampled_from([None, *sorted(spec.presets)]))
    if draw(st.booleans()):
        box = spec.validated.get(preset, spec.validated.get("", {}))
        out = {n: draw(st.floats(lo, hi)) for n, (lo, hi) in box.items()}
        for b in spec.calibratable:
            out[b.name] = b.lo * (b.hi / b.lo) ** draw(st.floats(0.0, 1.0))
        return preset, out
    base = spec.resolve(preset)
    out = {"frequency_hz": 10.0 ** draw(st.floats(-1.0, 4.0))}
    for name in _scaled_parameters(spec):
        if base[name]:
            out[name] = base[name] * 10.0 ** draw(st.floats(-3.0, 3.0))
    return preset, out


def check_result(model: str, preset, overrides: dict, labels: dict) -> None:
    """A valid ``ok`` (every invariant, checked here on its own) or another named status with what it implies."""
    status = labels["status"]
    assert status in STATUSES, status
    if status in ("runaway", "failed"):
        assert labels["reason"], labels
        assert all(labels[k] is None for k in ("rop_m_s", "peak_force_n", "period")), labels
        return
    assert status in BOUNDED_STATUSES
    for k in ("rop_m_s", "peak_force_n", "mean_peak_force_n", "impacts_per_cycle", "energy_per_cycle_j"):
        assert labels[k] is not None and math.isfinite(labels[k]), (k, labels)
    assert labels["rop_m_s"] >= 0.0, labels
    assert labels["impacts_per_cycle"] >= 0.0 and labels["peak_force_n"] >= 0.0 and labels["mean_peak_force_n"] >= 0.0
    if status == "ok":
        assert labels["period"] >= 1, labels
        assert labels["impacts_per_cycle"] > 0.0 or labels["peak_force_n"] > 0.0, labels     # it is in contact
    if status == "aperiodic":
        assert labels["period"] == 0, labels
    if status == "no_contact":
        assert labels["impacts_per_cycle"] == 0.0 and labels["rop_m_s"] == 0.0, labels


def _run(model, method, point):
    preset, overrides = point
    r = sim.simulate(model, preset=preset, settings={**SHORT, "method": method}, **overrides)
    check_result(model, preset, overrides, r.labels)
    return r


_PROPERTY = settings(max_examples=16, deadline=None, derandomize=True, database=None, print_blob=True,
                     suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@pytest.mark.parametrize("model,method", PATHS, ids=[f"{m}-{meth}" for m, meth in PATHS])
def test_every_result_is_a_valid_ok_or_a_named_status(model, method):
    @_PROPERTY
    @given(points(model))
    def prop(point):
        _run(model, method, point)

    prop()


@pytest.mark.slow
@pytest.mark.parametrize("model,method", PATHS, ids=[f"{m}-{meth}" for m, meth in PATHS])
def test_every_result_is_a_valid_ok_or_a_named_status_large(model, method):
    @settings(_PROPERTY, max_examples=300)
    @given(points(model))
    def prop(point):
        _run(model, method, point)

    prop()


# ---------------------------------------------------------------------------------------- the drill's lost switch
@pytest.mark.parametrize("f", [0.3, 1.0])
def test_drill_lab_at_low_frequency_progresses_forward_on_both_paths(f):
    """`vibro simulate drill --preset lab --set frequency_hz=0.3` (kHz typed as Hz) gave ROP -47.5 m/s, status ok,
    period 0 (1 Hz: -13.1 m/s): the exact path's guard rows (x1, xb apart) and the model's phase check (x1 - xb)
    disagreed at III -> II once the slider had moved ~30 m, the switch was refused and the next missed; the slider
    then followed the bit backwards.  Now the exact path agrees with the integrator: periodic, forward."""
    exact = sim.simulate("drill", preset="lab", frequency_hz=f).labels
    dopri = sim.simulate("drill", preset="lab", frequency_hz=f, settings={"method": "dopri5"}).labels
    for lab in (exact, dopri):
        assert lab["status"] == "ok" and lab["period"] == 1 and lab["rop_m_s"] > 0, lab
    assert exact["rop_m_s"] == pytest.approx(dopri["rop_m_s"], rel=1e-6)
    assert exact["impacts_per_cycle"] == dopri["impacts_per_cycle"] == 1.0


# ---------------------------------------------------------------------------------------- the check itself
LABELS_OK = {"status": "ok", "reason": "", "rop_m_s": 1e-3, "peak_force_n": 3000.0, "mean_peak_force_n": 3000.0,
             "impacts_per_cycle": 1.0, "period": 1, "energy_per_cycle_j": 0.05}
VALUES = {"frequency_hz": 250.0, "Pr": 3000.0, "static_force_n": 1200.0}
DRILL_BALANCE = sim.get_model("drill").min_work_per_m


@pytest.mark.parametrize("change, window, words", [
    ({}, 32, None),
    ({"rop_m_s": -47.5, "period": 0}, 32, "went backwards"),
    ({"impacts_per_cycle": -1.0}, 32, "impacts_per_cycle"),
    ({"peak_force_n": -1.0}, 32, "peak_force_n"),
    ({"period": 0}, 32, "period >= 1"),
    ({"period": 3}, 32, "whole periods"),
    ({"period": 3}, 33, None),
    ({"status": "aperiodic", "period": 2}, 32, "aperiodic with period 2"),
    ({"status": "aperiodic", "period": 0}, 32, None),
    # (Pr - Fs) x ROP / f = 1800 x 1e-3 / 250 = 7.2 mJ per cycle at the least
    ({"energy_per_cycle_j": 0.005}, 32, "energy balance"),
    ({"energy_per_cycle_j": 0.0072}, 32, None),
    ({"status": "not_settled", "period": 0, "energy_per_cycle_j": 0.0}, 32, None),   # not steady: no balance
])
def test_violation_names_the_broken_invariant(change, window, words):
    got = violation({**LABELS_OK, **change}, window, DRILL_BALANCE, VALUES)
    assert got is None if words is None else words in got


def test_a_broken_result_is_failed_with_its_reason(monkeypatch):
    """The result path turns a result that breaks an invariant into `failed`, its labels null, never `ok`."""
    import numpy as np

    from sim import api, layout as I

    v = np.zeros(I.N_LABELS)
    v[I.L_STATUS], v[I.L_ROP], v[I.L_PEAK_F], v[I.L_IMPACTS], v[I.L_WINDOW] = I.STATUS_OK, -47.5, 3000.0, 0.25, 32
    spec = sim.get_model("drill")
    labels = api._labels_from_vector(v, None, spec, spec.resolve("lab", frequency_hz=0.3))
    assert labels["status"] == "failed" and "went backwards" in labels["reason"]
    assert labels["rop_m_s"] is None and labels["period"] is None
