"""The RIMD's hybrid propagator (sim/exact/rimd.py: free flight exact, contact DOPRI5) against the numerical path
and the independent reference.

Off the stop the RIMD is linear (MODELS.md §4 with κ = 0), so the hybrid path differs from the DOPRI5 kernel only in
the free flight: at a tight rtol both should agree to about that tolerance, and with the reference
(tests/reference_solutions.py, DOP853 rtol 1e-10) to about the reference's own accuracy.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.linalg import expm

import sim
from sim.exact import rimd as hy
from vibrobase.statuses import IMPACTING_STATUSES
from tests.reference_solutions import reference_run

COMPARED = ("peak_force_n", "mean_peak_force_n", "peak_decel_g", "energy_per_cycle_j")
FIXED = {"min_transient": 40, "max_transient": 40, "window": 10}


def _pair(overrides, rtol=1e-11):
    st = {**FIXED, "rtol": rtol}
    hyb = sim.simulate("rimd", settings={**st, "method": "exact"}, **overrides).labels
    num = sim.simulate("rimd", settings={**st, "method": "dopri5"}, **overrides).labels
    return hyb, num


@pytest.mark.parametrize("overrides", [
    {},                                                     # gap 0, 8 Hz: the first impact resonance (MODELS.md §4)
    {"gap_m": 3e-3, "frequency_hz": 4.5},                   # gap 3 mm, impacting from rest below 4.5 Hz
    {"gap_m": 1e-3, "frequency_hz": 5.0},                   # gap 1 mm below its first resonance, period 1
    {"frequency_hz": 6.0},                                  # gap 0 below the resonance: steady, not periodic (aperiodic)
    {"alpha": 2.0},                                         # rate_stiffening: acts in contact (numerical there)
    {"lambda_i": 80.0},                                     # release by the damping indicator 1 + λi ẋ2 while δ > 0
], ids=["gap0-8hz", "gap3mm-4.5hz", "gap1mm-5hz", "gap0-6hz", "alpha", "lambda80"])
def test_hybrid_matches_tight_dopri5(overrides):
    hyb, num = _pair(overrides)
    assert hyb["status"] == num["status"] and hyb["status"] in IMPACTING_STATUSES    # 6 Hz: aperiodic
    assert hyb["impacts_per_cycle"] == num["impacts_per_cycle"] > 0
    assert hyb["period"] == num["period"]
    for k in COMPARED:
        # DOPRI5 at rtol 1e-11 is good to ~1e-9 on these labels (bench/README.md: 3.4e-9 at 1e-10); 1e-7 leaves room
        assert hyb[k] == pytest.approx(num[k], rel=1e-7, abs=1e-12), k
    # the free flight takes grid steps (>= 16 per cycle) instead of error-controlled ones
    assert hyb["n_steps"] < num["n_steps"]


def test_hybrid_without_impacts_is_the_linear_response():
    # gap 3 mm at 8 Hz from rest never reaches the stop (MODELS.md §4: from rest, gap 3 mm stays off the impacting
    # branch above 4.5 Hz): the whole run is exact, and its work per cycle is DOPRI5's at a tight tolerance
    ov = {"gap_m": 3e-3, "frequency_hz": 8.0}
    hyb, num = _pair(ov)
    assert hyb["status"] == num["status"] == "no_contact"
    assert hyb["n_events"] == 0
    assert hyb["energy_per_cycle_j"] == pytest.approx(num["energy_per_cycle_j"], rel=1e-8)
    assert hyb["peak_decel_g"] == pytest.approx(num["peak_decel_g"], rel=1e-8)


def test_hybrid_matches_reference():
    # the default point against the independent reference, the hybrid's contact steps at rtol 1e-10: agreement to
    # about the reference's own accuracy (~1e-8 on these labels; test_validation asks 1 % at the default rtol)
    spec = sim.get_model("rimd")
    ref = reference_run("rimd", spec.resolve(None), 40, 10, method="DOP853", rtol=1e-10)
    got = sim.simulate("rimd", settings={**FIXED, "rtol": 1e-10, "method": "exact"}).labels
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    assert got["period"] == ref["period"]
    for k in COMPARED:
        assert got[k] == pytest.approx(ref[k], rel=1e-6), k


def test_auto_uses_the_hybrid_only_where_the_free_flight_is_linear():
    effects = sim.get_model("rimd").effects
    assert hy.exact_applies({"alpha": 2.0, "kappa": 0.0}, effects)
    assert not hy.exact_applies({"alpha": 0.0, "kappa": 1e5}, effects)
    st = {**FIXED, "window": 4}
    auto = sim.simulate("rimd", settings=st).labels
    assert auto == sim.simulate("rimd", settings={**st, "method": "exact"}).labels
    # κ > 0 (suspension_hardening): the free flight is nonlinear, auto runs DOPRI5 and "exact" is refused
    hard = sim.simulate("rimd", settings=st, kappa=1e5).labels
    assert hard == sim.simulate("rimd", settings={**st, "method": "dopri5"}, kappa=1e5).labels
    with pytest.raises(sim.ParameterError, match="'method'.*handles alpha"):
        sim.simulate("rimd", settings={**st, "method": "exact"}, kappa=1e5)
    # a time history comes from the numerical path
    r = sim.simulate("rimd", history=True, settings={**st, "samples_per_cycle": 20})
    assert r.history is not None and len(r.history) == 80
    assert r.labels == sim.simulate("rimd", settings={**st, "method": "dopri5"}).labels


def test_continuation_from_a_hybrid_final_state():
    # an up-sweep continues from the previous point's final state (MODELS.md §4): the hybrid's final state is a
    # state of the model that DOPRI5 continues from as well as the hybrid does
    first = sim.simulate("rimd", frequency_hz=7.5, settings=FIXED)
    a = sim.simulate("rimd", frequency_hz=8.0, initial_state=first.final_state,
                     settings={**FIXED, "method": "exact", "rtol": 1e-11}).labels
    b = sim.simulate("rimd", frequency_hz=8.0, initial_state=first.final_state,
                     settings={**FIXED, "method": "dopri5", "rtol": 1e-11}).labels
    for k in COMPARED:
        assert a[k] == pytest.approx(b[k], rel=1e-7), k


def test_workspace_is_the_exact_flow_of_the_stated_equations():
    # Φ against scipy's expm of the matrix written from MODELS.md §4 here (not from sim/), and the work over one full
    # step, zᵀ M z, against quadrature of F0 sin(Ωτ) ẋ1(τ) along the exact flow
    spec = sim.get_model("rimd")
    v = spec.resolve(None, frequency_hz=7.0, gap_m=1e-3)
    p = spec.vector(v)
    period = 1.0 / v["frequency_hz"]
    wk, gk = hy.make_workspace(p, period, np.zeros(32), hy.NY)
    assert wk.shape == (16, hy.NY)
    h = gk[hy.G_INFO, 0]
    n_grid = gk[hy.G_INFO, 1]
    assert n_grid >= 16 and h == pytest.approx(period / n_grid, rel=1e-15)
    m1, k1, c1, m2, k2, c2, f0 = (v[n] for n in ("m1", "k1", "c1", "m2", "k2", "c2", "amplitude_n"))
    om = 2 * math.pi * v["frequency_hz"]
    # z = x1, v1, x2, v2, cos Ωt, sin Ωt, 1
    A = np.zeros((7, 7))
    A[0, 1] = 1.0
    A[1, :4] = [-(k1 + k2) / m1, -(c1 + c2) / m1, k2 / m1, c2 / m1]
    A[1, 5] = f0 / m1
    A[2, 3] = 1.0
    A[3, :4] = [k2 / m2, c2 / m2, -k2 / m2, -c2 / m2]
    A[4, 5] = -om
    A[5, 4] = om
    phi = gk[hy.G_PHI:hy.G_PHI + 7, :7]
    assert np.allclose(phi, expm(A * h), rtol=1e-13, atol=1e-15)
    z0 = np.array([1e-3, -2e-2, 3e-3, 5e-2, math.cos(0.3), math.sin(0.3), 1.0])
    M = gk[hy.G_M:hy.G_M + 7, :7]
    w, _ = quad(lambda tau: f0 * (expm(A * tau) @ z0)[5] * (expm(A * tau) @ z0)[1], 0.0, h, epsabs=0, epsrel=1e-13)
    assert z0 @ M @ z0 == pytest.approx(w, rel=1e-11)
    # M has only rows c and s (the forcing oscillator reaches only itself), which exact_free sums alone
    assert set(np.flatnonzero(np.abs(M).sum(axis=1))) <= {hy.IC, hy.IS}
