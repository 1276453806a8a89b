"""The structured discrepancy candidates written after the held-out kinds, against the independent generator's kinds
of the same physics (tests/independent/kinds.py: the scipy reference with event location, sharing no code with
``sim``):

- ``contact_exponent`` (indenter-metal, pendulum): the elastic part of a linear contact law k δ becomes
  k δ_r (δ₊/δ_r)^(1+s); the generator's ``contact_exponent`` with nc = 1 + s, delta_r = δ_r;
- ``rock_rate_strength`` (drill): the failing rock's threshold Pr → Pr (1 + η ẋb); the generator's
  ``rate_strength`` with eta_r = η;
- ``link_power_loss`` (drill, indenters, RIMD): a loss c (|v|/v_r)^p sgn v in the impacting mass's suspension; the
  generator's ``power_damping`` cp |v|^pd sgn v with c = cp v_r^pd, p = pd.

At the strengths of the independent rigs (tests/independent/rigs.py ``outside[kind]``, chosen there to move a label
by 10-20 %) and at a stronger one, on the fixed cycles from rest of tests/sim/test_reference_effects.py, simulator at
rtol 1e-10: every label within 1e-6 of the reference (the tolerance of the §6 effects' comparison).
"""
from __future__ import annotations

import numpy as np
import pytest

import sim
from sim.models.discrepancy import EXPONENT_REF, EXPONENT_SHIFT, LINK_PARAMS, LINK_REF, STRENGTH
from tests.independent.outside import model_for
from tests.independent.rigs import RIGS
from tests.reference_solutions import reference_run
from tests.sim.test_discrepancy_terms import PARAMS
from tests.sim.test_reference_effects import LABELS, POINTS, REL, SIM_RTOL

CASES = {
    # (model, generator kind): (the generator's parameter scaled for the stronger case, what it moves,
    #                           the generator's parameters -> the simulator's)
    ("indenter-metal", "contact_exponent"): ("nc", "peak_force_n",
                                             lambda g: {EXPONENT_SHIFT: g["nc"] - 1.0, EXPONENT_REF: g["delta_r"]}),
    ("pendulum", "contact_exponent"): ("nc", "peak_force_n",
                                       lambda g: {EXPONENT_SHIFT: g["nc"] - 1.0, EXPONENT_REF: g["delta_r"]}),
    ("drill", "rate_strength"): ("eta_r", "rop_m_s", lambda g: {STRENGTH: g["eta_r"]}),
    **{(m, "power_damping"): ("cp", moved, lambda g, m=m: _link(m, g))
       for m, moved in (("drill", "rop_m_s"), ("indenter-sandstone", "rop_m_s"), ("rimd", "peak_force_n"))},
}
STRONGER = {"nc": 2.0, "eta_r": None, "cp": None}
"""The stronger case: a cone-like law n = 2; the rock's rate strength and the link loss at 3x the rig's (None)."""


def _link(model: str, g: dict) -> dict:
    """The generator's cp |v|^pd as c (|v|/v_r)^p at the model's reference velocity v_r."""
    vref = sim.get_model(model).defaults()[LINK_REF]
    return {LINK_PARAMS[0]: g["cp"] * vref ** g["pd"], LINK_PARAMS[1]: g["pd"]}


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300) if a != b else 0.0


@pytest.mark.parametrize("case", list(CASES), ids=lambda c: f"{c[0]}-{c[1]}")
@pytest.mark.parametrize("stronger", [False, True])
def test_candidate_against_the_independent_generator(case, stronger):
    model, kind = case
    knob, moved, to_sim = CASES[case]
    g = dict(RIGS[model].outside[kind])
    if stronger:
        g[knob] = STRONGER[knob] if STRONGER[knob] is not None else 3.0 * g[knob]
    preset, n, w = POINTS[model]
    got = sim.simulate(model, preset=preset, settings={"min_transient": n, "max_transient": n, "window": w,
                                                       "rtol": SIM_RTOL}, **to_sim(g)).labels
    ref = reference_run(model_for(model, kind), {**PARAMS[model], **g}, n, w, method="DOP853", rtol=1e-10)
    base = reference_run(model, PARAMS[model], n, w, method="DOP853", rtol=1e-10)
    assert got["status"] in ("ok", "aperiodic", "not_settled") and ref["status"] == "ok"
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    assert _rel(ref[moved], base[moved]) > 1e-2      # the physics is visible
    for k in LABELS:
        assert _rel(got[k], ref[k]) <= REL, (k, got[k], ref[k])


@pytest.mark.parametrize("model, off", [("indenter-metal", {EXPONENT_SHIFT: 0.0, EXPONENT_REF: 3.0e-3}),
                                        ("pendulum", {EXPONENT_SHIFT: 0.0, EXPONENT_REF: 3.0e-3}),
                                        ("drill", {STRENGTH: 0.0}),
                                        ("drill", {LINK_PARAMS[0]: 0.0, LINK_PARAMS[1]: 3.0}),
                                        ("rimd", {LINK_PARAMS[0]: 0.0, LINK_PARAMS[1]: 3.0})])
def test_a_candidate_off_is_the_base_model_bit_for_bit(model, off):
    """Off (whatever the exponent's reference penetration): the base model's labels and final state exactly."""
    preset, n, w = POINTS[model]
    st = {"min_transient": n, "max_transient": n, "window": w, "method": "dopri5"}
    got = sim.simulate(model, preset=preset, settings=st, **off)
    ref = sim.simulate(model, preset=preset, settings=st)
    assert got.labels == ref.labels
    assert all(np.array_equal(a, b) for a, b in zip(got.final_state, ref.final_state))


def test_a_stiffer_law_raises_the_peak_force_and_keeps_forces_non_negative():
    """Physics: at the same stiffness at δ_r, a larger exponent is softer below δ_r and stiffer above it; at the
    pendulum's default point the impact penetrates past δ_r = 4 µm, so the peak force rises with n."""
    peaks = []
    for shift in (0.0, 0.25, 0.5, 1.0):
        r = sim.simulate("pendulum", **{EXPONENT_SHIFT: shift, EXPONENT_REF: 4.0e-6}, history=True)
        assert r.status == "ok" and np.all(r.history["force_n"] >= 0.0)
        peaks.append(r.labels["peak_force_n"])
    assert np.all(np.diff(peaks) > 0.0), peaks


def test_a_stronger_rock_drills_slower_and_the_bit_feels_at_least_the_threshold():
    """Physics: a threshold that rises with the failure rate slows the failure (ROP falls monotonically with η) and
    the bit feels Pr (1 + η ẋb) ≥ Pr while the rock fails; progression never decreases."""
    rops = []
    for eta in (0.0, 10.0, 100.0, 1000.0):
        r = sim.simulate("drill", preset="lab", history=True, **{STRENGTH: eta})
        h = r.history
        assert r.status == "ok" and np.all(np.diff(h["progression_m"]) >= 0.0)
        failing = h["phase"].to_numpy() == 2
        assert np.all(h["force_n"].to_numpy()[failing] >= sim.get_model("drill").presets["lab"]["Pr"] * (1 - 1e-12))
        rops.append(r.labels["rop_m_s"])
    assert np.all(np.diff(rops) < 0.0), rops


@pytest.mark.parametrize("model, param", [("indenter-sandstone", EXPONENT_SHIFT), ("rimd", EXPONENT_SHIFT),
                                          ("drill", EXPONENT_SHIFT), ("pendulum", STRENGTH), ("rimd", STRENGTH),
                                          ("pendulum", LINK_PARAMS[0])])
def test_a_model_without_the_candidate_refuses_it(model, param):
    with pytest.raises(sim.ParameterError, match=param):
        sim.get_model(model).resolve(**{param: 0.5})


@pytest.mark.parametrize("model, entry", [("pendulum", {EXPONENT_SHIFT: 0.5}), ("drill", {STRENGTH: 20.0}),
                                          ("rimd", {LINK_PARAMS[0]: 0.05, LINK_PARAMS[1]: 2.5})])
def test_a_rig_file_carries_the_candidate(model, entry):
    """A candidate's parameter is a rig's ``discrepancy:`` entry like any term, and round-trips."""
    rig = sim.Rig(model=model, discrepancy=entry)
    back = sim.Rig.from_mapping(rig.to_mapping())
    assert back.discrepancy == entry and back.overrides() == rig.overrides()


def test_beyond_its_largest_meaningful_value_a_candidate_is_a_typo():
    with pytest.raises(sim.ParameterError, match=f"'{EXPONENT_SHIFT}' must be <= 10"):
        sim.get_model("pendulum").resolve(**{EXPONENT_SHIFT: 50.0})
    with pytest.raises(sim.ParameterError, match=f"'{STRENGTH}' must be <= 10000"):
        sim.get_model("drill").resolve(**{STRENGTH: 1e6})
