"""The indenter rig's hybrid propagator (sim/exact/indenter.py: every phase exact while the seal friction is ± pm,
DOPRI5 across the shaker body's velocity reversals) against the numerical path and the independent reference.

Away from the reversals every phase of both samples is linear (MODELS.md §1 with tanh = ±1), so at a tight rtol the
hybrid and the DOPRI5 kernel should agree to about that tolerance, and with the reference (tests/reference_solutions.py,
DOP853 rtol 1e-10) to about the reference's own accuracy.  The matrices here are written afresh from MODELS.md §1.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.linalg import expm

import sim
from sim.exact import indenter as hy
from sim.exact import indenter_metal, indenter_sandstone
from sim.exact.taylor import NT
from sim.models import contact
from sim.models import indenter as ind
from tests.reference_solutions import reference_run

COMPARED = ("peak_force_n", "mean_peak_force_n", "peak_decel_g", "energy_per_cycle_j")
FIXED = {"min_transient": 40, "max_transient": 40, "window": 10}


def _pair(model, preset, overrides, rtol=1e-11):
    st = {**FIXED, "rtol": rtol}
    hyb = sim.simulate(model, preset=preset, settings={**st, "method": "exact"}, **overrides).labels
    num = sim.simulate(model, preset=preset, settings={**st, "method": "dopri5"}, **overrides).labels
    return hyb, num


@pytest.mark.parametrize("model, preset, overrides", [
    ("indenter-metal", "table1-40hz", {}),                  # MODELS.md §1: one impact per cycle at 40-90 Hz
    ("indenter-metal", "table1-60hz", {}),
    ("indenter-metal", "table1-90hz", {}),
    ("indenter-metal", "table1-60hz", {"gap_m": 0.0, "k1": 1e8, "c1": 3.0}),   # stiff, barely damped contact
    ("indenter-metal", "table1-60hz", {"pm": 200.0}),       # strong seal friction: long DOPRI5 stretches
    ("indenter-sandstone", "table1-40hz", {}),
    ("indenter-sandstone", "table1-60hz", {}),
    ("indenter-sandstone", "table1-90hz", {}),
    ("indenter-sandstone", "table1-60hz", {"kl": 5e5, "ku": 2e6}),   # soft rock: long loading and unloading
], ids=["metal-40", "metal-60", "metal-90", "metal-stiff-gap0", "metal-pm200", "sand-40", "sand-60", "sand-90",
        "sand-soft"])
def test_hybrid_matches_tight_dopri5(model, preset, overrides):
    hyb, num = _pair(model, preset, overrides)
    assert hyb["status"] == num["status"] and hyb["status"] in ("ok", "aperiodic")    # pm 200: aperiodic
    assert hyb["impacts_per_cycle"] == num["impacts_per_cycle"] > 0
    assert hyb["period"] == num["period"]
    for k in COMPARED + (("rop_m_s",) if model == "indenter-sandstone" else ()):
        # DOPRI5 at rtol 1e-11 is good to ~1e-9 on these labels (bench/README.md); 1e-7 leaves room
        assert hyb[k] == pytest.approx(num[k], rel=1e-7, abs=1e-12), k


@pytest.mark.parametrize("model", ["indenter-metal", "indenter-sandstone"])
def test_hybrid_matches_reference(model):
    # Table 1 at 60 Hz against the independent reference, the hybrid's DOPRI5 stretches at rtol 1e-10: agreement to
    # about the reference's own accuracy (~1e-8 on these labels; test_validation asks 1 % at the default rtol)
    spec = sim.get_model(model)
    values = {k: v for k, v in spec.resolve("table1-60hz").items() if k not in ("P", "D")}
    ref = reference_run(model, values, 40, 10, method="DOP853", rtol=1e-10)
    got = sim.simulate(model, preset="table1-60hz", settings={**FIXED, "rtol": 1e-10, "method": "exact"}).labels
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    assert got["period"] == ref["period"]
    for k in COMPARED:
        assert got[k] == pytest.approx(ref[k], rel=1e-6), k


def test_default_rtol_labels_closer_to_tight_than_dopri5():
    # the point of the exact phases: at the default rtol the metal's labels at Table 1, 60 Hz are within 1e-6 of
    # DOPRI5 at 1e-11 (measured 8e-8), where DOPRI5 at the default rtol is 3e-6 off on the energy per cycle
    ref = sim.simulate("indenter-metal", preset="table1-60hz", settings={"rtol": 1e-11, "method": "dopri5"}).labels
    got = sim.simulate("indenter-metal", preset="table1-60hz").labels
    for k in COMPARED:
        assert got[k] == pytest.approx(ref[k], rel=1e-6), k


def _matrix_from_models_md(p, kc, cc):
    """A of ż = A z (z = x1, v1, x2, v2, x3, v3, cos Ωt, sin Ωt, 1, σ, offset) written from MODELS.md §1 with
    sgn(ẋ2) = σ and the contact force kc (x1 - offset) + cc ẋ1."""
    m1, m2, m3 = p[ind.M1], p[ind.M2], p[ind.M3]
    k2, c2, k3, c3 = p[ind.K2], p[ind.C2], p[ind.K3], p[ind.C3]
    om = 2 * math.pi * p[ind.FREQ]
    A = np.zeros((11, 11))
    # m1 x1'' = Fa sin Ωt - c2 (v1 - v2) - k2 (x1 - x2) - Fr
    A[0, 1] = 1
    A[1, [0, 1, 2, 3, 7, 10]] = [-(k2 + kc) / m1, -(c2 + cc) / m1, k2 / m1, c2 / m1, p[ind.FA] / m1, kc / m1]
    # m2 x2'' = -Fa sin Ωt + c2 φ1' + k2 φ1 - c3 φ2' - k3 φ2
    A[2, 3] = 1
    A[3, [0, 1, 2, 3, 4, 5, 7]] = [k2 / m2, c2 / m2, -(k2 + k3) / m2, -(c2 + c3) / m2, k3 / m2, c3 / m2,
                                   -p[ind.FA] / m2]
    # m3 x3'' = Fp + c3 φ2' + k3 φ2 - pm σ
    A[4, 5] = 1
    A[5, [2, 3, 4, 5, 8, 9]] = [k3 / m3, c3 / m3, -k3 / m3, -c3 / m3, p[ind.FP] / m3, -p[ind.PM] / m3]
    A[6, 7] = -om
    A[7, 6] = om
    return A


@pytest.mark.parametrize("model, sand", [("indenter-metal", False), ("indenter-sandstone", True)])
def test_phase_tables_are_the_flow_of_models_md(model, sand):
    spec = sim.get_model(model)
    p = spec.vector(spec.resolve("table1-60hz"))
    _, gk = hy.build(p, 1 / 60, 8, sand, 1e-7)
    assert gk[hy.G_INFO, 3] == hy.v_band(1e-7) * p[ind.VEPS] < gk[hy.G_INFO, 4]       # the band's edges at rtol 1e-7
    h = gk[hy.G_INFO, 0]
    assert gk[hy.G_INFO, 1] * h == pytest.approx(1 / 60, rel=1e-12)
    assert hy._rho(p, sand) * h <= hy.RHO_H * (1 + 1e-12)
    assert hy._rho(p, sand) <= hy._rho_bound(p)
    laws = [(0.0, 0.0), (p[ind.KL], 0.0), (p[ind.KU], 0.0)] if sand else [(0.0, 0.0), (p[ind.K1], p[ind.C1])]
    rng = np.random.default_rng(3)
    for q, (kc, cc) in enumerate(laws):
        A = _matrix_from_models_md(p, kc, cc)
        assert max(abs(np.linalg.eigvals(A))) <= hy._rho(p, sand)     # the step bound is a bound
        b = hy.GK_ROWS + q * hy.PH_ROWS
        phi = gk[b + hy.P_PHI:b + hy.P_PHI + 11, :11]
        np.testing.assert_allclose(phi, expm(A * h), rtol=1e-12, atol=1e-12 * np.abs(expm(A * h)).max())
        # the work Fa ∫ sin Ωt (v1 - v2) dt over a step from z, against quadrature of the exact flow
        z = np.array([2e-4, 0.03, -1e-4, 0.01, 3e-4, -0.02, math.cos(0.7), math.sin(0.7), 1.0, 1.0, 1e-3])
        M = gk[b + hy.P_M:b + hy.P_M + 11, :11]
        wq = quad(lambda s: p[ind.FA] * (expm(A * s) @ z)[7] * ((expm(A * s) @ z)[1] - (expm(A * s) @ z)[3]),
                  0, h, epsabs=0, epsrel=1e-12)[0]
        assert z @ M @ z == pytest.approx(wq, rel=1e-9)
        # the curvature bound holds: |g(θ) - g(0) - θ h g'(0)| <= B max|z''| / t for each tabled row
        t_typ = gk[hy.G_TYP, :11]
        for _ in range(20):
            zr = z * rng.uniform(-1, 1, 11)
            zr[8] = 1.0
            zdd = A @ A @ zr
            nz2 = max(abs(zdd) / t_typ)
            for ti in range(5):
                tab = gk[b + hy.P_T + ti * NT:b + hy.P_T + (ti + 1) * NT, :11]
                r = tab[0]
                for th in (0.3, 0.7, 1.0):
                    g = r @ expm(A * th * h) @ zr
                    lin = r @ zr + th * h * (r @ A @ zr)
                    assert abs(g - lin) <= gk[b + hy.P_B, ti] * nz2 * (1 + 1e-9) + 1e-13 * abs(g)


def test_friction_band_edge_follows_the_tolerance():
    # beyond v_band(rtol) v_eps the exact phases take the model's friction pm tanh(v2 / v_eps) as ± pm; the two differ
    # by pm (1 - tanh V) = 2 pm / (e^(2V) + 1), which must stay within BAND_TOL rtol pm, and V is the narrowest such edge
    for rtol in (1e-3, 1e-6, 1e-7, 1e-9, 1e-11, 1e-13):
        v = hy.v_band(rtol)
        assert 2.0 / (math.exp(2.0 * v) + 1.0) <= hy.BAND_TOL * rtol
        assert 2.0 / (math.exp(2.0 * (v - 0.01)) + 1.0) > hy.BAND_TOL * rtol
    assert hy.v_band(1e-7) == pytest.approx(10.71, abs=0.01)        # the edge docs/speed.md quotes
    # never wider than where the model's tanh rounds to ±1 (the friction bit-exact), in Python and in numba alike
    assert hy.v_band(1e-17) == hy.V_EXACT
    assert math.tanh(hy.V_EXACT) == 1.0 and math.tanh(-hy.V_EXACT) == -1.0
    assert hy.V_HYST > 0.0
    veps = 1e-4
    sgn = contact.coulomb_sign
    assert sgn(hy.V_EXACT * veps, veps) == 1.0 and sgn(-hy.V_EXACT * veps, veps) == -1.0
    assert contact.coulomb_sign.py_func(hy.V_EXACT * veps, veps) == 1.0


def test_friction_sign_is_tanh():
    # the model's regularised sign (1 - e) / (1 + e), e = exp(-2|x|), against libm's tanh (accurate to < 1 ulp):
    # within 2.3e-16 absolute everywhere, odd, 0 at 0, monotone, ±1 exactly from |x| = 18.72 (e < 2^-54) on
    x = np.concatenate([np.linspace(-25.0, 25.0, 200_001), np.logspace(-12.0, 1.5, 20_001)])
    veps = 1.0                      # x / veps = x exactly
    f = np.array([contact.coulomb_sign(v * veps, veps) for v in x])
    assert np.max(np.abs(f - np.tanh(x))) <= 2.3e-16
    assert np.all(np.array([contact.coulomb_sign(-v * veps, veps) for v in x]) == -f)
    assert contact.coulomb_sign(0.0, veps) == 0.0
    grid = f[:200_001]
    assert np.all(np.diff(grid) >= 0.0)
    assert contact.coulomb_sign(18.72 * veps, veps) == 1.0 and contact.coulomb_sign(18.70 * veps, veps) < 1.0
    # beyond V_ONE it returns ± 1 without the exp: the values the exp form has there (and far out, where exp underflows)
    e = math.exp(-2.0 * contact.V_ONE)
    assert (1.0 - e) / (1.0 + e) == 1.0 and contact.V_ONE < hy.V_EXACT
    assert contact.coulomb_sign(1e3, veps) == 1.0 and contact.coulomb_sign(-1e300, veps) == -1.0


def test_step_hint_plans_the_approach_to_a_reversal():
    p = sim.get_model("indenter-metal").vector(sim.get_model("indenter-metal").resolve("table1-60hz"))
    veps = p[ind.VEPS]
    y = np.zeros(ind.NY)
    dy = np.zeros(ind.NY)
    rate = 1e5                                # |x2''| / v_eps [1/s]
    y[ind.IV2], dy[ind.IV2] = 8.0 * veps, -rate * veps          # approaching the reversal from u = 8
    h_done, en_done, h = 2e-5, 1e-3, 1e-3
    got = hy.step_hint(0.0, y, None, 0, p, dy, h, h_done, en_done)
    d, d_done = got * rate, h_done * rate
    # the planned step aims the modelled error norm en_done (Δ / Δ_done)^5 e^(2Δ) at EN_AIM (Newton stops once its
    # last correction of ln Δ is below 1e-4, so Δ is good to ~1e-8 relative and the norm to a few 1e-8)
    assert en_done * (d / d_done) ** 5 * math.exp(2.0 * d) == pytest.approx(hy.EN_AIM, rel=1e-6)
    assert 0.0 < got < h
    # the plan is the smaller, the larger the error so far; with a tiny one even a step to the reversal aims below
    # EN_AIM, and the controller's proposal stands
    assert hy.step_hint(0.0, y, None, 0, p, dy, h, h_done, 1e-1) < got
    y[ind.IV2] = 4.0 * veps
    assert hy.step_hint(0.0, y, None, 0, p, dy, h, h_done, 1e-12) == h
    y[ind.IV2] = 8.0 * veps
    # the controller's proposal when it is smaller, when moving away from the reversal and inside the core
    assert hy.step_hint(0.0, y, None, 0, p, dy, 1e-7, h_done, en_done) == 1e-7
    dy[ind.IV2] = rate * veps
    assert hy.step_hint(0.0, y, None, 0, p, dy, h, h_done, en_done) == h
    dy[ind.IV2] = -rate * veps
    y[ind.IV2] = hy.U_CORE * veps
    assert hy.step_hint(0.0, y, None, 0, p, dy, h, h_done, en_done) == h


def test_auto_uses_the_hybrid_only_where_every_phase_is_linear():
    effects = sim.get_model("indenter-sandstone").effects
    assert indenter_sandstone.exact_applies({"nl": 1.0, "nu": 1.0}, effects)
    assert not indenter_sandstone.exact_applies({"nl": 1.3, "nu": 1.0}, effects)
    assert not indenter_sandstone.exact_applies({"gamma": 0.1}, effects)
    assert not indenter_metal.exact_applies({"alpha": 1.0}, sim.get_model("indenter-metal").effects)
    assert indenter_metal.exact_applies({"nl": 2.0}, sim.get_model("indenter-metal").effects)   # not the metal's
    st = {**FIXED, "window": 4}
    auto = sim.simulate("indenter-metal", preset="table1-60hz", settings=st).labels
    exact = sim.simulate("indenter-metal", preset="table1-60hz", settings={**st, "method": "exact"}).labels
    num = sim.simulate("indenter-metal", preset="table1-60hz", settings={**st, "method": "dopri5"}).labels
    assert auto == exact and auto["n_steps"] != num["n_steps"]
    mu = sim.simulate("indenter-metal", preset="table1-60hz", settings=st, mu=5.0).labels
    mu_num = sim.simulate("indenter-metal", preset="table1-60hz", settings={**st, "method": "dopri5"}, mu=5.0).labels
    assert mu == mu_num
    with pytest.raises(sim.ParameterError, match="method"):
        sim.simulate("indenter-metal", settings={**st, "method": "exact"}, mu=5.0)
    # the error names the condition, not an empty list of handled effects
    with pytest.raises(sim.ParameterError, match=r"'method'.*applies only with .*nl = nu = 1"):
        sim.simulate("indenter-sandstone", settings={**st, "method": "exact"}, nl=1.3)
