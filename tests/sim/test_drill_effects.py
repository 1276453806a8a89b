"""The drill's MODELS.md §6 effects (shaker_coil, rate_stiffening, guide_friction, tip_blunting,
suspension_hardening) against the independent reference (tests/reference_solutions.py, scipy DOP853,
rtol 1e-10, event location), on the `lab` preset.

Adding an effect to the drill = one entry in sim.models.drill.EFFECTS and in EFFECT_VISIBLE (its bounds in EFFECT_FIT_BOUNDS): the
parametrised checks below then run on it.  Tolerances are those of tests/sim/test_validation.py (the
acceptance: ROP, forces, deceleration, energy within 1 %; impacts per cycle and period equal).  Both runs use
the same fixed transient and window so they integrate the same trajectory; 240 transient cycles put the base
lab point past its settling (232 cycles with the default settings), so the period is compared too.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import sim
from sim.models import drill
from tests.reference_solutions import reference_run

pytestmark = pytest.mark.xdist_group("test_drill_effects")   # one test worker builds the module's fixture

TRANSIENT, WINDOW = 240, 16
REL = 1e-2                      # tests/sim/test_validation.py
VISIBLE = 3 * REL               # an effect "clearly visible": ROP or peak deceleration moves > 3x the tolerance
ALL_OFF = {name: 0.0 for names in drill.SPEC.effects.values() for name in names}   # every effect parameter off


def _compare(overrides: dict, transient: int = TRANSIENT, window: int = WINDOW, preset: str | None = "lab"):
    params = drill.SPEC.resolve(preset, **overrides)
    ref = reference_run("drill", params, transient, window, method="DOP853", rtol=1e-10)
    got = sim.simulate("drill", preset=preset, settings={"min_transient": transient, "max_transient": transient,
                                                         "window": window}, **overrides).labels
    assert got["status"] in ("ok", "aperiodic", "not_settled")
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    if ref["period"] > 0:
        assert got["period"] == ref["period"]
    assert got["rop_m_s"] == pytest.approx(ref["rop_m_s"], rel=REL, abs=1e-9)
    assert got["peak_force_n"] == pytest.approx(ref["peak_force_n"], rel=REL)
    assert got["mean_peak_force_n"] == pytest.approx(ref["mean_peak_force_n"], rel=REL)
    assert got["peak_decel_g"] == pytest.approx(ref["peak_decel_g"], rel=REL)
    assert got["energy_per_cycle_j"] == pytest.approx(ref["energy_per_cycle_j"], rel=REL)
    return got, ref


@pytest.fixture(scope="module")
def base_ref():
    """Reference labels of the base model (no effect parameters passed at all)."""
    return reference_run("drill", drill.SPEC.resolve("lab"), TRANSIENT, WINDOW)


def test_all_effects_off_reproduce_the_base_model(base_ref):
    """Every effect parameter explicitly 0: the simulator matches the reference run *without* any effect
    parameter (the reference's base model), period 1 and one impact per cycle as the lab preset has."""
    got, ref = _compare(ALL_OFF)
    assert ref["rop_m_s"] == base_ref["rop_m_s"] and ref["peak_decel_g"] == base_ref["peak_decel_g"]
    assert got["period"] == 1 and got["impacts_per_cycle"] == 1.0


@pytest.mark.parametrize("effect", sorted(drill.EFFECT_VISIBLE))
def test_effect_against_reference(effect, base_ref):
    values = drill.EFFECT_VISIBLE[effect]
    got, ref = _compare({**ALL_OFF, **values})
    # the effect must be clearly visible, or agreeing with the reference proves nothing about its term
    moved = max(abs(ref["rop_m_s"] / base_ref["rop_m_s"] - 1), abs(ref["peak_decel_g"] / base_ref["peak_decel_g"] - 1))
    assert moved > VISIBLE, f"{effect} {values}: labels move by only {moved:.2%}"


SLOW = [
    # tau = 0 with beta > 0: the algebraic limit Fh = F0 cos(Om t) - beta (v1 - v2)
    ("coil-algebraic", {"beta": 1e4}, "lab"),
    # every effect at the upper end of its fit range (large but simulable)
    *[(f"hi-{k}", {k: hi}, "lab") for k, (lo, hi, _) in drill.EFFECT_FIT_BOUNDS.items() if k not in ("tau", "beta")],
    ("hi-shaker_coil", {"tau": drill.EFFECT_FIT_BOUNDS["tau"][1], "beta": drill.EFFECT_FIT_BOUNDS["beta"][1]}, "lab"),
    # all effects on at once, off the default operating point
    ("all-150hz", {**{k: v for d in drill.EFFECT_VISIBLE.values() for k, v in d.items()}, "frequency_hz": 150.0},
     "lab"),
    # MODELS.md §2 starting point with a gap (I -> III jumps), coil and friction on
    ("models-start-gap", {"gap_m": 5e-4, "frequency_hz": 164.5399032646247, "amplitude_n": 1213.6447136247984,
                          "static_force_n": 1001.9234472396665, "tau": 2e-4, "beta": 50.0, "mu": 20.0,
                          "kappa": 1e8, "alpha": 5.0}, None),
]


@pytest.mark.slow
@pytest.mark.parametrize("case", SLOW, ids=[c[0] for c in SLOW])
def test_effect_against_reference_slow(case):
    _, overrides, preset = case
    _compare({**ALL_OFF, **overrides}, transient=120, window=16, preset=preset)


# ------------------------------------------------------------------------------------------ exactness
def _base_rhs(t, y, ph, p):
    """MODELS.md §2 base equations, written out here (the link force C2 φ̇ + K2 φ grouped as one term)."""
    x1, v1, x2, v2, x3, v3, xt, xb = y[:8]
    K1, C1 = p["K1"], p["C1"]
    pc = [0.0, K1 * (x1 - xb) + C1 * v1, p["Pr"]][ph]
    f = p["amplitude_n"] * math.cos(2.0 * math.pi * p["frequency_hz"] * t)
    link = p["C2"] * (v1 - v2) + p["K2"] * (x1 - x2)
    top = p["C3"] * (v2 - v3) + p["K3"] * (x2 - x3)
    dxt = [-(K1 / C1) * (xt - xb), v1, v1][ph]
    dxb = [0.0, 0.0, (K1 * (x1 - xb) + C1 * v1 - p["Pr"]) / C1][ph]
    return np.array([v1, (f - link - pc) / p["M1"], v2, (p["static_force_n"] + link - top) / p["M2"], v3,
                     top / p["M3"], dxt, dxb, 0.0, f * v1, 0.0, 0.0])     # the hidden mode off: at rest


@pytest.mark.parametrize("ph", [0, 1, 2])
def test_effect_terms_vanish_exactly_when_off(ph):
    """All effects 0: the model's right-hand side is the base model's, bit for bit, and fh stays 0."""
    values = drill.SPEC.resolve("lab", **ALL_OFF)
    p = drill.SPEC.vector(values)
    rng = np.random.default_rng(ph)
    for _ in range(20):
        y = np.zeros(drill.NY)
        y[:8] = rng.normal(scale=[1e-4, 0.02, 1e-4, 0.02, 1e-4, 0.02, 1e-4, 1e-5])
        y[drill.IW] = rng.normal()
        t = rng.uniform(0.0, 1.0 / values["frequency_hz"])
        dy = np.empty(drill.NY)
        drill.rhs(t, y, np.zeros(0), ph, p, dy)
        assert np.array_equal(dy, _base_rhs(t, y, ph, values)), (ph, dy - _base_rhs(t, y, ph, values))


def test_state_layout():
    """W last of the base states (the exact propagator's linear system is the first NY_BASE), the hidden mode's two
    after it; fh just before W; names line up with the constants."""
    assert drill.IW == drill.NY_BASE - 1 and drill.STATES[drill.IW] == "work"
    assert (drill.IXH, drill.IVH) == (drill.NY - 2, drill.NY - 1) == (len(drill.STATES) - 2, len(drill.STATES) - 1)
    assert drill.IFH == drill.IW - 1 and drill.STATES[drill.IFH] == "fh"
    assert len(drill.PARAMS) == drill.NP and len(drill.BOUNDED) == drill.N_BOUNDED
    names = [q.name for q in drill.PARAMS]
    for const, name in [(drill.TAU, "tau"), (drill.BETA, "beta"), (drill.ALPHA, "alpha"), (drill.MU, "mu"),
                        (drill.GAMMA, "gamma"), (drill.KAPPA, "kappa"), (drill.VEPS, "v_eps"), (drill.FC, "fc")]:
        assert names[const] == name


def test_coil_with_tau_zero_is_algebraic():
    """tau = 0, beta > 0: Fh = F0 cos(Om t) - beta (v1 - v2) acts on M1 and fh's derivative is 0."""
    values = drill.SPEC.resolve("lab", **{**ALL_OFF, "beta": 1e3})
    p = drill.SPEC.vector(values)
    y = np.zeros(drill.NY)
    y[drill.IV1], y[drill.IV2] = 0.01, -0.002
    dy = np.empty(drill.NY)
    drill.rhs(0.0, y, np.zeros(0), 0, p, dy)
    fh = values["amplitude_n"] - 1e3 * 0.012
    link = values["C2"] * 0.012
    assert dy[drill.IFH] == 0.0
    assert dy[drill.IV1] == pytest.approx((fh - link) / values["M1"], rel=1e-12)
    assert dy[drill.IW] == pytest.approx(fh * 0.01, rel=1e-12)     # work of the force actually applied to M1


def test_effect_tables_check_themselves():
    """EFFECT_FIT_BOUNDS / EFFECT_VISIBLE cover exactly the SPEC.effects parameters, in the Param units,
    with 0 (off) below every lower bound and every visible strength inside its bounds."""
    params = {q.name: q for q in drill.PARAMS}
    effect_params = {n for names in drill.SPEC.effects.values() for n in names}
    assert set(drill.SPEC.effects) == {"shaker_coil", "rate_stiffening", "guide_friction", "tip_blunting",
                                       "suspension_hardening", "sensor_lowpass"}
    assert set(drill.EFFECT_FIT_BOUNDS) == effect_params
    assert set(drill.EFFECT_VISIBLE) == set(drill.SPEC.effects)
    for name, (lo, hi, unit) in drill.EFFECT_FIT_BOUNDS.items():
        assert 0.0 < lo < hi and unit == params[name].unit and params[name].default == 0.0
    for effect, vals in drill.EFFECT_VISIBLE.items():
        assert set(vals) == set(drill.SPEC.effects[effect])
        for name, v in vals.items():
            lo, hi, _ = drill.EFFECT_FIT_BOUNDS[name]
            assert lo <= v <= hi
