"""Sanity checks of the independent reference solver (tests/reference_solutions.py) itself.

Quick set (default, ~20 s): physics sanity per model, exact linear solutions, the MODELS.md section-1
first-impact decelerations with a short transient.  `pytest -m slow` adds the full MODELS.md table with
the ~3 s transient the piston creep needs.
"""
import math

import numpy as np
import pytest
from scipy.linalg import expm

from tests.reference_solutions import reference_run

DRILL = dict(M1=2.0, M2=8.0, M3=20.0, K2=2e6, C2=400.0, K3=5e5, C3=1000.0, K1=2e7, C1=5e3, Pr=1500.0,
             gap_m=0.0, frequency_hz=200.0, amplitude_n=1500.0, static_force_n=700.0)

RIMD = dict(m1=0.368, k1=2850.0, c1=1.269, m2=0.360, k2=272.1, c2=0.079, ki=92.5e3, lambda_i=8.0, ni=0.9,
            amplitude_n=1.0, gap_m=0.0, frequency_hz=8.0)

PEND = dict(m=0.298, l=0.075, amplitude_m=0.89e-3, ki=5.5e6, ci=1.2e3, zeta=0.005, gap_m=0.0, g=9.81)

# MODELS.md section 1: Table-1 forcing and the published reference first-impact decelerations (g)
TABLE1 = {40: 300.0, 60: 440.0, 80: 650.0, 90: 840.0}
METAL_G = {40: 12.3, 60: 26.2, 80: 43.0, 90: 50.6}
SAND_G = {40: 7.2, 60: 16.8, 80: 30.3, 90: 39.8}


def indenter(f, Fa, **kw):
    p = dict(m1=3.46, k2=2.3e5, c2=2.3e3, m2=60.0, m3=0.5, k3=2e4, pm=20.0, v_eps=1e-4,
             static_force_n=(101325 / 4) * 1.0 * math.pi * 0.05 ** 2, gap_m=1e-3,
             k1=1e7, c1=300.0, kl=5e6, ku=2e7, nl=1.0, nu=1.0,
             c3=78.6 * math.pi ** 2 * Fa / f, amplitude_n=Fa, frequency_hz=float(f))
    p.update(kw)
    return p


def rimd_matrices(p):
    M = np.diag([p["m1"], p["m2"]])
    K = np.array([[p["k1"] + p["k2"], -p["k2"]], [-p["k2"], p["k2"]]])
    C = np.array([[p["c1"] + p["c2"], -p["c2"]], [-p["c2"], p["c2"]]])
    return M, K, C


# ------------------------------------------------------------------------------------------ drill
def test_drill_progresses_periodic():
    r = reference_run("drill", DRILL, 50, 20)
    assert r["status"] == "ok"
    assert r["rop_m_s"] > 0.0
    assert r["period"] >= 1
    assert r["impacts_per_cycle"] >= 1.0
    assert 0.0 < r["peak_force_n"] <= DRILL["Pr"] * (1 + 1e-9)
    assert r["energy_per_cycle_j"] > 0.0
    assert math.isfinite(r["specific_energy_j_m"])
    assert r["strobe"].shape == (20, 8)          # 7 mechanical coordinates + coil force Fh


def test_drill_no_forcing_no_progress():
    r = reference_run("drill", dict(DRILL, amplitude_n=0.0), 40, 10)
    assert abs(r["rop_m_s"]) < 1e-12
    assert r["impacts_per_cycle"] == 0.0
    assert r["energy_per_cycle_j"] == 0.0
    assert r["specific_energy_j_m"] == float("inf")
    assert 0.0 < r["peak_force_n"] < DRILL["Pr"]       # sits on the rock (G = 0), below the threshold


def test_drill_runaway_flagged_and_baseline_method_runs():
    r = reference_run("drill", dict(DRILL, static_force_n=1600.0), 10, 5)
    assert r["status"] == "runaway"
    b = reference_run("drill", DRILL, 20, 5, method="RK45", rtol=1e-6, samples_per_cycle=16)
    h = b["history"]
    assert set(h) == {"t_s", "disp_m", "force_n", "accel_m_s2", "progression_m"}
    assert all(len(v) == 5 * 16 and np.all(np.isfinite(v)) for v in h.values())
    assert np.all(np.diff(h["t_s"]) > 0)
    assert np.all(np.diff(h["progression_m"]) >= -1e-15)     # the slider never moves back


# ---------------------------------------------------------------------------------------- indenter
@pytest.mark.parametrize("f", [40, 90])
def test_metal_first_impact_deceleration_short_transient(f):
    # the deceleration settles long before the piston creep does (0.5 s vs 3 s agree to 1e-5)
    r = reference_run("indenter-metal", indenter(f, TABLE1[f]), int(0.5 * f), 2)
    assert r["rop_m_s"] == 0.0
    assert r["impacts_per_cycle"] == 1.0
    assert r["peak_decel_g"] == pytest.approx(METAL_G[f], rel=0.03)


def test_sandstone_progresses_90hz():
    r = reference_run("indenter-sandstone", indenter(90, TABLE1[90]), 45, 4)
    assert r["impacts_per_cycle"] == 1.0
    assert r["peak_decel_g"] == pytest.approx(SAND_G[90], rel=0.03)
    assert 5e-3 <= r["rop_m_s"] <= 25e-3                    # MODELS.md: roughly 5-20 mm/s


@pytest.mark.slow
@pytest.mark.parametrize("sample,table", [("indenter-metal", METAL_G), ("indenter-sandstone", SAND_G)])
@pytest.mark.parametrize("f", [40, 60, 80, 90])
def test_models_md_deceleration_table(sample, table, f):
    r = reference_run(sample, indenter(f, TABLE1[f]), int(3.0 * f), 5)
    assert r["impacts_per_cycle"] == 1.0
    assert r["period"] == 1
    assert r["peak_decel_g"] == pytest.approx(table[f], rel=0.03)


def test_chattering_cap_raises():
    with pytest.raises(RuntimeError, match="switching events"):
        reference_run("indenter-metal", indenter(70, 540.0), 35, 2, max_events_per_cycle=0)


# ---------------------------------------------------------------------------------------- pendulum
def test_pendulum_gap0_first_resonance():
    # MODELS.md section 3: gap 0 -> 3.75 Hz, 94 N, z = 1/1 (hammer starts touching the load cell)
    r = reference_run("pendulum", dict(PEND, frequency_hz=3.75), 100, 4)
    assert r["impacts_per_cycle"] == 1.0
    assert r["period"] == 1
    assert r["peak_force_n"] == pytest.approx(94.0, rel=0.01)


# -------------------------------------------------------------------------------------------- rimd
def test_rimd_no_forcing_no_impact():
    for gap in (0.0, 1e-3):
        r = reference_run("rimd", dict(RIMD, amplitude_n=0.0, gap_m=gap), 5, 5)
        assert r["impacts_per_cycle"] == 0.0
        assert r["peak_force_n"] == 0.0
        assert r["n_events"] == 0
        assert r["status"] == "no_contact"


def test_rimd_gap0_first_resonance():
    # MODELS.md section 4: gap 0, F0 = 1 N: first impact resonance 8.0 Hz, about 17.8 N
    r = reference_run("rimd", dict(RIMD, frequency_hz=8.0), 60, 2)
    assert r["impacts_per_cycle"] == 1.0
    assert r["peak_force_n"] == pytest.approx(17.8, rel=0.01)


def test_rimd_linear_transient_matches_matrix_exponential():
    """Huge gap: the run is linear; compare the strobe from rest with the exact solution (expm)."""
    p = dict(RIMD, gap_m=1e3, frequency_hz=4.0)
    r = reference_run("rimd", p, 0, 12)
    M, K, C = rimd_matrices(p)
    Om = 2 * math.pi * p["frequency_hz"]
    Mi = np.linalg.inv(M)
    A = np.zeros((6, 6))               # [x1, x2, v1, v2, s = sin, c = cos]
    A[0:2, 2:4] = np.eye(2)
    A[2:4, 0:2] = -Mi @ K
    A[2:4, 2:4] = -Mi @ C
    A[2:4, 4] = Mi @ np.array([p["amplitude_n"], 0.0])
    A[4, 5], A[5, 4] = Om, -Om
    z0 = np.array([0, 0, 0, 0, 0, 1.0])
    T = 1 / p["frequency_hz"]
    exact = np.array([expm(A * k * T) @ z0 for k in range(12)])
    exact = exact[:, [0, 2, 1, 3]]     # -> strobe order x1, v1, x2, v2
    scale = np.abs(exact).max(axis=0)
    assert np.all(np.abs(r["strobe"] - exact).max(axis=0) / scale < 3e-8)


def test_rimd_huge_gap_steady_amplitude_is_linear_frequency_response():
    p = dict(RIMD, gap_m=1e3, frequency_hz=4.0)
    # slowest mode decays at 0.105 1/s: 400 cycles = 100 s leaves ~3e-5 of the start-up transient
    r = reference_run("rimd", p, 400, 2, samples_per_cycle=64)
    assert r["impacts_per_cycle"] == 0.0 and r["period"] == 1
    M, K, C = rimd_matrices(p)
    Om = 2 * math.pi * p["frequency_hz"]
    X = np.linalg.solve(K - Om ** 2 * M + 1j * Om * C, [p["amplitude_n"], 0.0])   # F0 e^{i Om t}
    t = r["history"]["t_s"]
    x2_lin = np.imag(X[1] * np.exp(1j * Om * t))
    x2 = r["history"]["disp_m"]
    # steady amplitude: least-squares sinusoid through the sampled history
    basis = np.column_stack([np.sin(Om * t), np.cos(Om * t), np.ones_like(t)])
    a, b, _ = np.linalg.lstsq(basis, x2, rcond=None)[0]
    assert math.hypot(a, b) == pytest.approx(abs(X[1]), rel=1e-4)
    assert np.abs(x2 - x2_lin).max() / abs(X[1]) < 1e-4
