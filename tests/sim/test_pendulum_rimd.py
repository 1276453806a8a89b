"""Impact pendulum (MODELS.md §3, seed 001) and RIMD (MODELS.md §4, seed 002): validation.

Where the numbers come from:
* "reference" = tests/reference_solutions.py (independent scipy DOP853, rtol 1e-10, event location):
  every simulator run below that is compared with it uses the same fixed transient (min = max transient).
* MODELS.md §3 / §4 quote the independent solution's sweep results (pendulum: gap 0 -> 3.75 Hz / 94 N and
  7.25 Hz / 151 N; gap 1.0 mm -> 3.25 / 6.75 Hz; gap 2.4 mm -> 2.75 / 5.75 Hz.  RIMD: 4.16 / 14.72 Hz natural
  frequencies; first impact resonance gap 0 -> 8.0 Hz, 17.8 N; gap 1 mm -> 6.5 Hz, 20.9 N (up-sweep);
  gap 3 mm -> 5.5 Hz, 25.6 N (up-sweep); from rest no impacting branch above 5.5 / 4.5 Hz).
* Published measurements: seed 001 Table 2 (pendulum impact resonances), seed 002 Table 3 (RIMD first
  impact resonance, experiment / seed numerics), both restated in MODELS.md.  The model does not match
  them exactly; the tests assert what the model gives and the documented distance (docs/maps.md).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import sim
from pipeline.maps.compute import Z11, Z12, add_pattern, band_resonance
from tests.reference_solutions import reference_run

LABELS_CMP = ("peak_force_n", "mean_peak_force_n", "peak_decel_g", "energy_per_cycle_j")


def full_params(model: str, **over) -> dict:
    """Complete parameter dict (seed defaults + overrides) in the names shared with the reference."""
    return sim.get_model(model).resolve(None, **over)


def fixed(transient: int, window: int) -> dict:
    return {"min_transient": transient, "max_transient": transient, "window": window}


def compare_with_reference(model: str, transient: int, window: int, **over):
    p = full_params(model, **over)
    ref = reference_run(model, p, transient, window)
    res = sim.simulate(model, settings=fixed(transient, window), **over)
    lab = res.labels
    assert lab["impacts_per_cycle"] == ref["impacts_per_cycle"]
    assert lab["period"] == ref["period"]
    for k in LABELS_CMP:
        # peak values: the simulator samples each contact step at 6 points, the reference refines the
        # maximum with Brent: agreement to 1e-3 relative (measured 2e-5 .. 6e-5)
        assert lab[k] == pytest.approx(ref[k], rel=1e-3, abs=1e-9), k
    return lab, ref


# ------------------------------------------------------------------------------------ against the reference
def test_pendulum_gap0_z11_matches_reference():
    lab, ref = compare_with_reference("pendulum", 60, 4, frequency_hz=3.75, gap_m=0.0)
    assert lab["period"] == 1 and lab["impacts_per_cycle"] == 1.0
    # MODELS.md §3: the independent solution gives 94 N here
    assert lab["peak_force_n"] == pytest.approx(94.0, rel=0.01)


def test_pendulum_gap0_z12_is_period_two_as_in_reference():
    lab, ref = compare_with_reference("pendulum", 60, 8, frequency_hz=7.25, gap_m=0.0)
    # the reference shows period 2 with one impact per two cycles (z = 1/2), MODELS.md §3: 151 N
    assert ref["period"] == 2 and lab["period"] == 2
    assert lab["impacts_per_cycle"] == 0.5
    assert lab["peak_force_n"] == pytest.approx(151.0, rel=0.01)


def test_rimd_gap0_first_resonance_matches_reference():
    lab, _ = compare_with_reference("rimd", 60, 4, frequency_hz=8.0, gap_m=0.0)
    assert lab["peak_force_n"] == pytest.approx(17.8, rel=0.01)     # MODELS.md §4


@pytest.mark.slow
def test_rimd_gap3mm_from_rest_matches_reference():
    compare_with_reference("rimd", 60, 4, frequency_hz=4.5, gap_m=3e-3)


@pytest.mark.slow
def test_pendulum_chatter_two_indicator_rule_matches_reference():
    """Gap 0 at 1 Hz: six contacts per cycle, released by the force (not by δ) -> the two-indicator rule."""
    lab, _ = compare_with_reference("pendulum", 60, 4, frequency_hz=1.0, gap_m=0.0)
    assert lab["impacts_per_cycle"] == 6.0


def test_pendulum_contact_ends_on_force_not_on_penetration():
    """MODELS.md §3: contact ends when Fi falls to 0 while the hammer is still past the load cell (δ > 0)."""
    res = sim.simulate("pendulum", frequency_hz=3.75, gap_m=1e-3, history=True,
                       settings={"samples_per_cycle": 20000, "window": 2})
    h = res.history
    p = res.params
    delta = p["l"] * np.sin(h["theta"]) - p["gap_m"]
    ph = h["phase"].to_numpy()
    ends = np.flatnonzero((ph[:-1] == 1) & (ph[1:] == 0))
    assert ends.size >= 1
    # at the last contact sample the force is small and δ is still positive (released by the force)
    assert np.all(delta.to_numpy()[ends] > 0.0)
    assert np.all(h["force_n"].to_numpy() >= 0.0)            # Fi is never negative


# ------------------------------------------------------------------------------------ RIMD linear part
def rimd_matrices(p: dict):
    M = np.diag([p["m1"], p["m2"]])
    K = np.array([[p["k1"] + p["k2"], -p["k2"]], [-p["k2"], p["k2"]]])
    C = np.array([[p["c1"] + p["c2"], -p["c2"]], [-p["c2"], p["c2"]]])
    return M, K, C


def test_rimd_natural_frequencies_from_stated_matrices():
    """Seed 002 / MODELS.md §4: no-impact natural frequencies 4.16 and 14.72 Hz (measured 3.9 / 14.5 Hz)."""
    M, K, _ = rimd_matrices(full_params("rimd"))
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    f = np.sqrt(w2) / (2 * math.pi)
    assert f == pytest.approx([4.16, 14.72], abs=0.005)
    # and the measured values are within 0.3 Hz of them (documented gap)
    assert abs(f[0] - 3.9) < 0.3 and abs(f[1] - 14.5) < 0.3


def test_rimd_simulated_linear_response_is_the_matrix_frequency_response():
    """Huge gap: no impact; the simulated steady amplitude of x1, x2 equals |H(Ω) F0| from the stated
    matrices (so the simulator's equations are those matrices), and the run is period 1."""
    p = full_params("rimd", gap_m=1.0, frequency_hz=4.0)
    # slowest mode decays at ~0.105 1/s: 500 cycles = 125 s leave ~2e-6 of the start-up transient
    res = sim.simulate("rimd", settings={**fixed(500, 4), "samples_per_cycle": 400}, history=True,
                       gap_m=1.0, frequency_hz=4.0)
    assert res.labels["status"] == "no_contact" and res.labels["impacts_per_cycle"] == 0.0
    assert res.labels["period"] == 1
    M, K, C = rimd_matrices(p)
    om = 2 * math.pi * p["frequency_hz"]
    X = np.linalg.solve(K - om ** 2 * M + 1j * om * C, [p["amplitude_n"], 0.0])
    h = res.history
    for name, amp in (("x1", abs(X[0])), ("x2", abs(X[1]))):
        sim_amp = 0.5 * (h[name].max() - h[name].min())
        assert sim_amp == pytest.approx(amp, rel=2e-3)


# ------------------------------------------------------------------------------------ pendulum resonances
PEND_MODEL_REF = {0.0: (3.75, 7.25), 1.0e-3: (3.25, 6.75), 2.4e-3: (2.75, 5.75)}   # MODELS.md §3 (independent)
PEND_TABLE2 = {0.0: (3.75, 7.25), 1.0e-3: (3.00, 6.25), 2.4e-3: (2.50, 5.25)}       # seed 001 Table 2 (measured)


@pytest.fixture(scope="module")
def pendulum_sweep() -> pd.DataFrame:
    """0.25 Hz steps (as MODELS.md §3's reference sweep), each point from rest, default settings."""
    f = np.arange(1.5, 9.01, 0.25)
    rows = [dict(gap_m=g, frequency_hz=x) for g in PEND_MODEL_REF for x in f]
    return add_pattern(sim.simulate_batch("pendulum", rows))


@pytest.mark.parametrize("gap", sorted(PEND_MODEL_REF))
def test_pendulum_impact_resonances(pendulum_sweep, gap):
    d = pendulum_sweep[np.isclose(pendulum_sweep["gap_m"], gap)]
    f11, F11 = band_resonance(d, Z11)
    f12, F12 = band_resonance(d, Z12)
    # what the model gives: the independent solution's resonances (MODELS.md §3)
    assert (f11, f12) == pytest.approx(PEND_MODEL_REF[gap], abs=1e-9)
    # distance from the measurement (seed 001 Table 2): within 0.5 Hz (documented in docs/maps.md)
    m11, m12 = PEND_TABLE2[gap]
    assert abs(f11 - m11) <= 0.5 + 1e-9 and abs(f12 - m12) <= 0.5 + 1e-9
    if gap == 0.0:
        # MODELS.md §3: 94 N and 151 N from the independent solution; measured 82.4 N and 120 N (seed 001)
        assert F11 == pytest.approx(94.0, rel=0.01) and F12 == pytest.approx(151.0, rel=0.01)
        assert 1.10 < F11 / 82.4 < 1.20 and 1.20 < F12 / 120.0 < 1.30     # 14 % and 26 % above the measurement


# ------------------------------------------------------------------------------------ RIMD resonances
RIMD_FREQS = np.arange(3.0, 10.01, 0.25)


def rimd_up_sweep(gap: float) -> pd.DataFrame:
    rows, state = [], None
    for f in RIMD_FREQS:
        r = sim.simulate("rimd", gap_m=gap, frequency_hz=float(f), initial_state=state)
        state = r.final_state
        rows.append({"frequency_hz": float(f), **r.labels})
    return add_pattern(pd.DataFrame(rows))


@pytest.fixture(scope="module")
def rimd_rest() -> pd.DataFrame:
    rows = [dict(gap_m=g, frequency_hz=f) for g in (0.0, 1e-3, 3e-3) for f in RIMD_FREQS]
    return add_pattern(sim.simulate_batch("rimd", rows))


def test_rimd_gap0_first_impact_resonance(rimd_rest):
    d = rimd_rest[rimd_rest["gap_m"] == 0.0]
    f, F = band_resonance(d, Z11)
    assert f == 8.0 and F == pytest.approx(17.8, rel=0.01)            # MODELS.md §4 (independent solution)
    # seed 002 Table 3: experiment 7.75 Hz / 7.25 N, seed numerics 8.0 Hz / 8.5 N
    assert abs(f - 7.75) <= 0.25
    assert 2.3 < F / 7.25 < 2.6                                       # the model's force is ~2.5x the measured


@pytest.mark.parametrize("gap, f_ref, F_ref, f_exp, f_rest_max", [
    (1e-3, 6.5, 20.9, 6.25, 5.5),     # MODELS.md §4 up-sweep; seed 002 Table 3 experiment 6.25 Hz
    (3e-3, 5.5, 25.6, 6.00, 4.5),     # MODELS.md §4 up-sweep; seed 002 Table 3 experiment 6.00 Hz
])
def test_rimd_first_impact_resonance_up_sweep(rimd_rest, gap, f_ref, F_ref, f_exp, f_rest_max):
    up = rimd_up_sweep(gap)
    f, F = band_resonance(up, Z11)
    assert f == f_ref and F == pytest.approx(F_ref, rel=0.01)
    assert abs(f - f_exp) <= 0.5                                      # distance from the measurement
    # from rest the impacting branch is never reached above f_rest_max (coexisting attractors)
    d = rimd_rest[np.isclose(rimd_rest["gap_m"], gap)]
    impacting = d[d["impacts_per_cycle"].astype(float) > 0]
    assert impacting["frequency_hz"].max() == f_rest_max
    # and the up-sweep keeps impacting beyond it: the jump is a real coexistence, not a missing branch
    assert (up[(up["frequency_hz"] > f_rest_max) & (up["frequency_hz"] <= f_ref)]["pattern"] == Z11).all()


# ------------------------------------------------------------------------------------ bad input
def test_bad_parameters_name_the_parameter():
    with pytest.raises(sim.ParameterError, match="gap_m"):
        sim.simulate("pendulum", gap_m=-1e-3)
    with pytest.raises(sim.ParameterError, match="lambda_i"):
        sim.simulate("rimd", lambda_i=-1.0)
    with pytest.raises(sim.ParameterError, match="zeta"):
        sim.simulate("pendulum", zeta=float("nan"))
    with pytest.raises(sim.ParameterError, match="unknown parameter 'gap'"):
        sim.simulate("rimd", gap=1e-3)


def test_effects_change_the_response():
    """MODELS.md §6 effects exist, are off by default and act when switched on."""
    base = sim.simulate("rimd", frequency_hz=8.0).labels["peak_force_n"]
    stiff = sim.simulate("rimd", frequency_hz=8.0, alpha=5.0).labels["peak_force_n"]
    hard = sim.simulate("rimd", frequency_hz=8.0, kappa=1e5).labels["peak_force_n"]
    assert stiff != pytest.approx(base, rel=1e-3) and hard != pytest.approx(base, rel=1e-3)
    pb = sim.simulate("pendulum", frequency_hz=3.75).labels["peak_force_n"]
    ps = sim.simulate("pendulum", frequency_hz=3.75, alpha=5.0).labels["peak_force_n"]
    assert ps > pb     # stiffer contact at the same impact speed -> larger force
