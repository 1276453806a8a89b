"""The jitted simulator against the independent high-accuracy reference (tests/reference_solutions.py:
scipy DOP853, rtol 1e-10, event location on the dense output, restart on every branch).

Issue 2's acceptance: ROP and peak force within 1 %, impacts per cycle and period equal in periodic
regimes.  Both runs use the same fixed transient (min_transient = max_transient) and window, so they
integrate the same trajectory.  Points cover single-impact progression, period-2/4 orbits with a gap
(I -> III jumps), persistent contact, multi-impact (period-5, 2.6 impacts per cycle) and sandstone
loading/unloading.  Measured agreement at the time of writing: ROP ~1e-7 relative, peak force
~1e-5, deceleration ~1e-5.
"""
from __future__ import annotations

import pytest

import sim
from tests.reference_solutions import reference_run

CASES = [
    # id, model, overrides, transient cycles, window cycles
    ("drill-default-p1", "drill", {}, 60, 16),
    ("drill-gap-p4", "drill", {"frequency_hz": 25.441221899039114, "amplitude_n": 2263.2503025113356,
                               "static_force_n": 343.6088765159217, "gap_m": 1e-4}, 60, 16),
    ("drill-gap-p2", "drill", {"frequency_hz": 164.5399032646247, "amplitude_n": 1213.6447136247984,
                               "static_force_n": 1001.9234472396665, "gap_m": 5e-4}, 80, 16),
    ("drill-persistent-contact", "drill", {"frequency_hz": 66.22224896065715, "amplitude_n": 1716.4857522636391,
                                           "static_force_n": 1089.7820367312563}, 60, 16),
    # c2 lowered from 2300 to 500 N s/m lets the armature bounce: period 5, 2.625 impacts per cycle
    ("metal-multi-impact", "indenter-metal", {"frequency_hz": 40.0, "amplitude_n": 300.0, "c2": 500.0}, 60, 20),
    ("sandstone-60hz", "indenter-sandstone", {"frequency_hz": 60.0, "amplitude_n": 440.0}, 40, 10),
]
SLOW_CASES = [
    ("metal-90hz-table1", "indenter-metal", {"frequency_hz": 90.0, "amplitude_n": 840.0}, 150, 10),
    ("sandstone-multi", "indenter-sandstone", {"frequency_hz": 40.0, "amplitude_n": 300.0, "c2": 500.0}, 80, 20),
    ("drill-high-f", "drill", {"frequency_hz": 380.0, "amplitude_n": 2900.0, "static_force_n": 1400.0,
                               "gap_m": 1e-4}, 120, 16),
]


def _compare(model, overrides, transient, window):
    spec = sim.get_model(model)
    params = spec.resolve(None, **overrides)
    ref_params = {k: v for k, v in params.items() if k not in ("P", "D")}
    ref = reference_run(model, ref_params, transient, window, method="DOP853", rtol=1e-10)
    got = sim.simulate(model, settings={"min_transient": transient, "max_transient": transient, "window": window},
                       **overrides).labels
    assert got["status"] in ("ok", "no_contact", "not_settled")
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    if ref["period"] > 0:
        assert got["period"] == ref["period"]
    assert got["rop_m_s"] == pytest.approx(ref["rop_m_s"], rel=1e-2, abs=1e-9)
    assert got["peak_force_n"] == pytest.approx(ref["peak_force_n"], rel=1e-2)
    assert got["mean_peak_force_n"] == pytest.approx(ref["mean_peak_force_n"], rel=1e-2)
    assert got["peak_decel_g"] == pytest.approx(ref["peak_decel_g"], rel=1e-2)
    assert got["energy_per_cycle_j"] == pytest.approx(ref["energy_per_cycle_j"], rel=1e-2)
    return got, ref


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_against_reference(case):
    _, model, overrides, transient, window = case
    _compare(model, overrides, transient, window)


@pytest.mark.slow
@pytest.mark.parametrize("case", SLOW_CASES, ids=[c[0] for c in SLOW_CASES])
def test_against_reference_slow(case):
    _, model, overrides, transient, window = case
    _compare(model, overrides, transient, window)


# Window maxima to the integration tolerance.  At rtol 1e-10 the simulator's peak force and
# peak deceleration must agree with the reference at rtol 1e-12 (whose own error is below 1e-10) to 1e-7.
# Before the per-step peak refinement, indenter-metal at 60 Hz (MODELS.md Table 1 point) stayed 1.5e-6 low in
# peak_decel_g at every rtol: the maximum lay inside a step whose three samples were below the running maximum,
# or just before a step start, where it was looked for by extrapolating the next step's interpolant.
# Measured at the time of writing: metal 60 Hz 4e-10, metal 30 Hz 1e-9, sandstone 5e-9, pendulum 7e-9, RIMD 6e-9.
PEAK_CASES = [
    ("indenter-metal", "table1-60hz"),
    ("indenter-metal", "table1-30hz"),
    ("indenter-sandstone", "table1-60hz"),
    ("pendulum", "seed-001"),
    ("rimd", "seed-002"),
]


@pytest.mark.parametrize("model,preset", PEAK_CASES, ids=[f"{m}-{p}" for m, p in PEAK_CASES])
def test_window_maxima_to_the_integration_tolerance(model, preset):
    n, w = 40, 10
    params = {k: v for k, v in sim.get_model(model).resolve(preset).items() if k not in ("P", "D")}
    ref = reference_run(model, params, n, w, method="DOP853", rtol=1e-12)
    got = sim.simulate(model, preset=preset,
                       settings={"min_transient": n, "max_transient": n, "window": w, "rtol": 1e-10}).labels
    for label in ("peak_force_n", "mean_peak_force_n", "peak_decel_g"):
        assert got[label] == pytest.approx(ref[label], rel=1e-7), label
