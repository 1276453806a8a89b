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
rtol 1e-10: every label within 1e-6 of the reference (the tolerance of the §6 effects' comparison).  The fifth,
``contact_drift``, against the reference's own drifting contact; the sixth, ``support_friction`` (pendulum, RIMD,
indenters), against the generator's ``support_friction`` with μ = mu_s, v_ε = 1e-4 m/s; ``stop_mode`` and
``drive_mode`` against its ``mount_mode`` and ``drive_mode``; ``contact_wear`` (pendulum, metal indenter: ṡ = k_w F_c
max(v, 0), δ = x − G − s) against its ``contact_wear`` with k_w = kw; ``contact_unloading`` (pendulum, metal
indenter: below the contact's peak penetration the elastic part falls as (δ/δ_m)^n_u) against its
``unloading_hysteresis`` with n_u = nu_h.
"""
from __future__ import annotations

import numpy as np
import pytest

import sim
import math

from sim.models.discrepancy import (DRIFT_RATE, DRIVE_MODE_PARAMS, EXPONENT_REF, EXPONENT_SHIFT, LINK_PARAMS, LINK_REF,
                                    STOP_MODE_PARAMS, STRENGTH, SUPPORT_FORCE, SUPPORT_VEPS, UNLOADING_SHIFT, WEAR_RATE,
                                    WEAR_RUN)
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
    **{(m, "support_friction"): ("mu_s", moved, lambda g: {SUPPORT_FORCE: g["mu_s"], SUPPORT_VEPS: 1e-4})
       for m, moved in (("pendulum", "peak_force_n"), ("indenter-sandstone", "rop_m_s"), ("rimd", "peak_force_n"))},
    ("indenter-metal", "mount_mode"): ("ms", "peak_force_n", lambda g: _mount("indenter-metal", "m1", g)),
    ("rimd", "mount_mode"): ("ms", "peak_force_n", lambda g: _mount("rimd", "m2", g)),
    ("rimd", "drive_mode"): ("md", "peak_force_n", lambda g: _drive("rimd", "m1", g)),
    ("drill", "drive_mode"): ("md", "rop_m_s", lambda g: _drive("drill", "M2", g)),
    **{(m, "contact_wear"): ("kw", "peak_force_n", lambda g: {WEAR_RATE: g["kw"]})
       for m in ("indenter-metal", "pendulum")},
    **{(m, "unloading_hysteresis"): ("nu_h", "peak_force_n", lambda g: {UNLOADING_SHIFT: g["nu_h"] - 1.0})
       for m in ("indenter-metal", "pendulum")},
}
STRONGER = {"nc": 2.0, "eta_r": None, "cp": None, "mu_s": None, "ms": None, "md": None, "kw": None, "nu_h": 8.0}
"""The stronger case: a cone-like law n = 2; an unloading curve n_u = 8; the rock's rate strength, the link loss,
the support friction, the mounted or driving mode's mass and the wear coefficient at 3x the rig's (None)."""


def _link(model: str, g: dict) -> dict:
    """The generator's cp |v|^pd as c (|v|/v_r)^p at the model's reference velocity v_r."""
    vref = sim.get_model(model).defaults()[LINK_REF]
    return {LINK_PARAMS[0]: g["cp"] * vref ** g["pd"], LINK_PARAMS[1]: g["pd"]}


TRANSIENT = {("rimd", "drive_mode"): 80}
"""Cases whose fixed cycles from rest differ from tests/sim/test_reference_effects.py's: the RIMD with the drive's mass
at 3x still rings after 40 cycles and an impact then straddles the window's start (which side it falls on moves the
mean peak force by 1e-6 and the energy by 3e-5 between two right solutions); after 80 they agree to 1e-8."""


def _mass(model: str, name: str) -> float:
    """The mass ``name`` [kg] at the model's point of this check (the drill's lab preset)."""
    return sim.get_model(model).resolve(preset=POINTS[model][0])[name]


def _mount(model: str, imp: str, g: dict) -> dict:
    """The generator's mount (mass ms, compliance cm, damping ratio zeta_m) as the stop mode: ms over the impacting
    mass ``imp``, its frequency 1 / (2π √(cm ms))."""
    return dict(zip(STOP_MODE_PARAMS, (g["ms"] / _mass(model, imp), 1.0 / (2 * math.pi * math.sqrt(g["cm"] * g["ms"])),
                                       g["zeta_m"])))


def _drive(model: str, body: str, g: dict) -> dict:
    """The generator's drive mode (md, fd_hz, zeta_d) as the drive mode: md over the driving body ``body``."""
    return dict(zip(DRIVE_MODE_PARAMS, (g["md"] / _mass(model, body), g["fd_hz"], g["zeta_d"])))


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
    n = TRANSIENT.get(case, n)
    got = sim.simulate(model, preset=preset, settings={"min_transient": n, "max_transient": n, "window": w,
                                                       "rtol": SIM_RTOL}, **to_sim(g)).labels
    ref = reference_run(model_for(model, kind), {**PARAMS[model], **g}, n, w, method="DOP853", rtol=1e-10)
    base = reference_run(model, PARAMS[model], n, w, method="DOP853", rtol=1e-10)
    assert got["status"] in ("ok", "aperiodic", "not_settled") and ref["status"] in ("ok", "aperiodic")
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    assert _rel(ref[moved], base[moved]) > 1e-2      # the physics is visible
    for k in LABELS:
        assert _rel(got[k], ref[k]) <= REL, (k, got[k], ref[k])


DRIFTS = {"pendulum": 3.0e-6, "indenter-metal": 3.0e-4}
"""Drift rates [m/s] of the contact_drift check: ~ the probe strengths (about 0.5-1 typical penetration per record)."""


@pytest.mark.parametrize("model", list(DRIFTS))
@pytest.mark.parametrize("scale", [1.0, 10.0])
def test_contact_drift_against_the_reference(model, scale):
    """``contact_drift``, which the generator has no kind of (its wear recedes with the impact work): against the
    scipy reference's own drifting contact (tests/reference_solutions.py ``DRIFT``: the face at G + a t in the force,
    both indicators and their rates), the same tolerance; the labels move."""
    preset, n, w = POINTS[model]
    a = DRIFTS[model] * scale
    got = sim.simulate(model, preset=preset, settings={"min_transient": n, "max_transient": n, "window": w,
                                                       "rtol": SIM_RTOL}, **{DRIFT_RATE: a}).labels
    ref = reference_run(model, {**PARAMS[model], DRIFT_RATE: a}, n, w, method="DOP853", rtol=1e-10)
    base = reference_run(model, PARAMS[model], n, w, method="DOP853", rtol=1e-10)
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    assert max(_rel(ref[k], base[k]) for k in LABELS) > 1e-3      # the physics is visible
    for k in LABELS:
        assert _rel(got[k], ref[k]) <= REL, (k, got[k], ref[k])


@pytest.mark.parametrize("model, off", [("pendulum", {DRIFT_RATE: 0.0}), ("indenter-metal", {DRIFT_RATE: 0.0}),
                                        ("rimd", {SUPPORT_FORCE: 0.0, SUPPORT_VEPS: 1.0}),
                                        ("rimd", dict(zip(STOP_MODE_PARAMS, (0.0, 100.0, 0.05)))),
                                        ("rimd", dict(zip(DRIVE_MODE_PARAMS, (0.0, 20.0, 0.05)))),
                                        ("drill", dict(zip(DRIVE_MODE_PARAMS, (0.0, 300.0, 0.05)))),
                                        ("indenter-metal", dict(zip(STOP_MODE_PARAMS, (0.0, 500.0, 0.05)))),
                                        ("indenter-metal", {SUPPORT_FORCE: 0.0, SUPPORT_VEPS: 1.0}),
                                        ("indenter-metal", {EXPONENT_SHIFT: 0.0, EXPONENT_REF: 3.0e-3}),
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
                                          ("pendulum", LINK_PARAMS[0]), ("indenter-sandstone", DRIFT_RATE),
                                          ("drill", DRIFT_RATE), ("rimd", DRIFT_RATE), ("drill", SUPPORT_FORCE),
                                          ("pendulum", STOP_MODE_PARAMS[0]),
                                          ("indenter-sandstone", STOP_MODE_PARAMS[0]),
                                          ("indenter-metal", DRIVE_MODE_PARAMS[0]), ("rimd", WEAR_RATE),
                                          ("indenter-sandstone", WEAR_RATE), ("drill", WEAR_RATE),
                                          ("rimd", UNLOADING_SHIFT), ("drill", UNLOADING_SHIFT)])
def test_a_model_without_the_candidate_refuses_it(model, param):
    with pytest.raises(sim.ParameterError, match=param):
        sim.get_model(model).resolve(**{param: 0.5})


@pytest.mark.parametrize("model, entry", [("pendulum", {EXPONENT_SHIFT: 0.5}), ("drill", {STRENGTH: 20.0}),
                                          ("rimd", {LINK_PARAMS[0]: 0.05, LINK_PARAMS[1]: 2.5}),
                                          ("indenter-metal", {DRIFT_RATE: 4e-4}),
                                          ("pendulum", {SUPPORT_FORCE: 0.02}),
                                          ("indenter-metal", {WEAR_RATE: 2e-4})])
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
    with pytest.raises(sim.ParameterError, match=f"'{DRIFT_RATE}' must be <= 1"):
        sim.get_model("indenter-metal").resolve(**{DRIFT_RATE: 5.0})
    with pytest.raises(sim.ParameterError, match=f"'{SUPPORT_FORCE}' must be <= 10000"):
        sim.get_model("rimd").resolve(**{SUPPORT_FORCE: 2e4})
    with pytest.raises(sim.ParameterError, match=f"'{WEAR_RATE}' must be <= 1"):
        sim.get_model("pendulum").resolve(**{WEAR_RATE: 3.0})


def test_one_user_of_the_hidden_states_at_a_time():
    """The load-path, stop and drive modes and the wear share the two hidden states: two at once is refused in one
    line."""
    with pytest.raises(sim.ParameterError, match="load_path_mode and stop_mode: one at a time"):
        sim.get_model("rimd").resolve(load_path_mode_ratio=0.1, load_path_mode_hz=50.0,
                                      **dict(zip(STOP_MODE_PARAMS, (1.0, 100.0, 0.05))))
    with pytest.raises(sim.ParameterError, match="stop_mode and contact_wear: one at a time"):
        sim.get_model("indenter-metal").resolve(**{WEAR_RATE: 1e-4}, **dict(zip(STOP_MODE_PARAMS, (1.0, 500.0, 0.05))))


def test_a_softer_mount_under_the_stop_lowers_the_peak_force():
    """Physics: a struck surface that gives (a compliant mount of finite mass) softens the impact: the RIMD's peak
    contact force falls as the mount's frequency falls; forces stay ≥ 0 and the mount is at rest while off."""
    peaks = []
    for hz in (3000.0, 300.0, 100.0):
        r = sim.simulate("rimd", **dict(zip(STOP_MODE_PARAMS, (1.0, hz, 0.05))), history=True)
        assert np.all(r.history["force_n"] >= 0.0)
        peaks.append(r.labels["peak_force_n"])
    assert np.all(np.diff(peaks) < 0.0), peaks
    assert sim.simulate("rimd").final_state[0][-2:].tolist() == [0.0, 0.0]


def test_a_rubbing_pivot_takes_energy_and_the_swing_hits_softer():
    """Physics: dry friction at the pendulum's pivot dissipates on every swing, so the hammer reaches the load cell
    slower (the peak force falls as μ grows) and the cart does positive net work on it; forces stay ≥ 0."""
    peaks = []
    for mu in (0.0, 0.005, 0.02, 0.05):
        r = sim.simulate("pendulum", **{SUPPORT_FORCE: mu}, history=True)
        assert np.all(r.history["force_n"] >= 0.0) and r.labels["energy_per_cycle_j"] > 0.0
        peaks.append(r.labels["peak_force_n"])
    assert np.all(np.diff(peaks) < 0.0), peaks


def test_a_receding_contact_hits_softer_and_keeps_forces_non_negative():
    """Physics: a load cell that recedes from the hammer through the run (wear) meets it later in each swing, at a
    lower closing speed: the peak force falls as the drift grows; forces stay ≥ 0."""
    peaks = []
    for a in (0.0, 1e-6, 3e-6, 1e-5):
        r = sim.simulate("pendulum", **{DRIFT_RATE: a}, history=True)
        assert np.all(r.history["force_n"] >= 0.0)
        peaks.append(r.labels["peak_force_n"])
    assert np.all(np.diff(peaks) < 0.0), peaks


@pytest.mark.parametrize("model", ["pendulum", "indenter-metal"])
def test_a_wearing_face_recedes_monotonically_and_hits_softer(model):
    """Physics: the worn depth never decreases (it grows by k_w times the work pressed in); the receding face meets
    the tool later and softer, so the peak force falls as k_w grows; forces stay ≥ 0."""
    hi = sim.get_model(model).discrepancy_bounds[WEAR_RATE].hi
    peaks = []
    for kw in (0.0, hi / 300.0, hi / 30.0, hi / 3.0):
        r = sim.simulate(model, **{WEAR_RATE: kw}, history=True)
        h = r.history
        depth = h["load_path_mode_x"].to_numpy()
        ends = depth[::sim.Settings().samples_per_cycle]      # cycle ends: step ends, the states themselves
        # between them the dense output's quartic may dip by its own error where ṡ has its kink (δ̇ = 0)
        assert np.all(np.diff(ends) >= 0.0) and np.all(np.diff(depth) >= -1e-5 * depth[-1])
        assert np.all(h["force_n"] >= 0.0)
        assert (depth[-1] > 0.0) == (kw > 0.0)
        peaks.append(r.labels["peak_force_n"])
    assert np.all(np.diff(peaks) < 0.0), peaks


def test_a_wearing_rig_runs_as_long_as_it_ran_before_a_steady_state_record():
    """A wearing face never settles: a run left to settle has the transient the rig ran, N = k_w N / k_w cycles up to
    whole pairs, the depth at the record continuous in N (exactly the run's at even N); a transient the caller fixed
    (a record from rest) stands; a batch gives each row its own."""
    kw = 2e-3
    got = {n: sim.simulate("pendulum", **{WEAR_RATE: kw, WEAR_RUN: kw * n}) for n in (149.0, 150.0, 150.5)}
    assert [r.labels["transient_cycles"] for r in got.values()] == [150, 150, 152]
    fixed = sim.simulate("pendulum", settings={"min_transient": 150, "max_transient": 150}, **{WEAR_RATE: kw})
    for k in ("peak_force_n", "energy_per_cycle_j"):
        assert got[150.0].labels[k] == pytest.approx(fixed.labels[k], rel=1e-9)
    depth = {n: r.final_state[0][-2] for n, r in got.items()}
    assert depth[149.0] < depth[150.0] < depth[150.5]
    rest = sim.simulate("pendulum", settings={"min_transient": 0, "max_transient": 0}, **{WEAR_RATE: kw, WEAR_RUN: 0.3})
    assert rest.labels["transient_cycles"] == 0
    batch = sim.simulate_batch("pendulum", [{WEAR_RATE: kw, WEAR_RUN: kw * 40}, {WEAR_RATE: kw, WEAR_RUN: kw * 80}])
    assert batch["transient_cycles"].tolist() == [40, 80]


@pytest.mark.parametrize("model", ["pendulum", "indenter-metal"])
def test_a_contact_that_unloads_lower_loses_energy_each_impact_and_recovers_between(model):
    """Physics: below the peak penetration the elastic force falls faster the larger n_u, so the tool leaves each
    impact slower (the loop's area is lost): the peak force of the repeated impacts falls as n_u grows; forces stay
    ≥ 0, and the peak penetration held in the hidden state starts afresh at each contact (the surface recovers) and
    only grows through it."""
    peaks = []
    for su in (0.0, 0.5, 2.0, 6.0):
        r = sim.simulate(model, **{UNLOADING_SHIFT: su}, history=True)
        h = r.history
        assert np.all(h["force_n"] >= 0.0)
        peak, touching = h["load_path_mode_x"].to_numpy(), h["phase"].to_numpy() > 0
        edges = np.flatnonzero(np.diff(touching.astype(int)))
        contacts = [(a + 1, b + 1) for a, b in zip(edges[::2], edges[1::2])] if touching[0] == 0 else []
        assert len(contacts) > 2 or su == 0.0
        for a, b in [c for c in contacts if c[1] - c[0] > 2] if su else []:
            # (between steps the dense output's quartic may dip by its own error where δ̇ turns)
            assert peak[a] < peak[b - 1] and np.all(np.diff(peak[a:b]) >= -1e-4 * peak.max()), (su, a, b)
        peaks.append(r.labels["peak_force_n"])
    assert np.all(np.diff(peaks) < 0.0), peaks
