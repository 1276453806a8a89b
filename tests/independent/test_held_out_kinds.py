"""The held-out out-of-library kinds (``kinds.py``), frozen: each is registered where the benches
pick outside physics by name; at zero strength it is the reference model (to the integrator's tolerance); at the
rig's default strength it moves a stated label by a stated range and stays physical (contact forces >= 0,
progression and wear never decreasing); its signals agree with its right-hand side and its switching surfaces
with its force law; and the log it writes is a §7 directory."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from tests import reference_solutions as ref
from tests.independent import kinds as K
from tests.independent.generator import RTOL, LogSpec, _run, generate
from tests.independent.outside import OUTSIDE, model_for
from tests.independent.rigs import OUTSIDE_KIND, RIGS
from tests.independent.test_outside_physics import DEFAULT, NUMERIC, WINDOW, _base, _mark, _params, _transient

PAIRS = [(k, s) for k, systems in K.KINDS_SYSTEMS.items() for s in systems]
pytestmark = pytest.mark.xdist_group("independent-physics")   # one test worker computes the base runs (``_base``)
SLOW = {("mount_mode", "rimd")}        # a 318 Hz mount under an 8 Hz forcing for 260 cycles: ~40 s

ZERO = {"contact_exponent": {"nc": 1.0}, "unloading_hysteresis": {"nu_h": 1.0}, "rate_strength": {"eta_r": 0.0},
        "mount_mode": {"cm": 0.0}, "drive_mode": {"fd_hz": 0.0}, "contact_wear": {"kw": 0.0},
        "power_damping": {"cp": 0.0}, "support_friction": {"mu_s": 0.0}}
"""Each kind switched off."""

EXPECT = {
    ("contact_exponent", "indenter-metal"): ("peak_force_n", 0.08, 0.18),
    ("contact_exponent", "pendulum"): ("peak_force_n", 0.10, 0.20),
    ("unloading_hysteresis", "indenter-metal"): ("peak_decel_g", -0.13, -0.05),
    ("unloading_hysteresis", "pendulum"): ("energy_per_cycle_j", -0.14, -0.05),
    ("rate_strength", "drill"): ("rop_m_s", -0.22, -0.10),
    ("mount_mode", "indenter-metal"): ("peak_decel_g", -0.45, -0.25),
    ("mount_mode", "rimd"): ("peak_force_n", 0.08, 0.20),
    ("drive_mode", "drill"): ("rop_m_s", 0.04, 0.13),
    ("drive_mode", "rimd"): ("peak_force_n", 0.04, 0.11),
    ("contact_wear", "indenter-metal"): ("peak_force_n", -0.13, -0.05),
    ("contact_wear", "pendulum"): ("peak_force_n", -0.15, -0.06),
    ("power_damping", "drill"): ("rop_m_s", -0.12, -0.05),
    ("power_damping", "indenter-sandstone"): ("rop_m_s", -0.10, -0.04),
    ("power_damping", "rimd"): ("peak_force_n", -0.22, -0.10),
    ("support_friction", "indenter-sandstone"): ("peak_decel_g", 0.08, 0.18),
    ("support_friction", "pendulum"): ("peak_force_n", -0.12, -0.05),
    ("support_friction", "rimd"): ("energy_per_cycle_j", 0.50, 1.00),
}
"""(label, lowest, highest relative change) at the rig's default strength and point (``DEFAULT``): the values
``rigs.py`` states next to each strength, with a margin for the solver and the platform."""

LOG_CASE = {"contact_exponent": "pendulum", "unloading_hysteresis": "indenter-metal", "rate_strength": "drill",
            "mount_mode": "indenter-metal", "drive_mode": "drill", "contact_wear": "pendulum",
            "power_damping": "indenter-sandstone", "support_friction": "rimd"}
"""One system per kind in the default suite (its log, off and on); the kinds are frozen, so the other pairs run
with the ``slow`` subset."""
OTHER_PAIRS = {p for p in PAIRS if LOG_CASE[p[0]] != p[1]}


def _with(kind: str, system: str, spc: int = 0, **override) -> dict:
    extra = {**RIGS[system].outside[kind], **override}
    return ref.reference_run(model_for(system, kind), _params(system, extra), _transient(system), WINDOW,
                             rtol=RTOL, samples_per_cycle=spc)


def _rel(a: dict, b: dict, key: str) -> float:
    return (a[key] - b[key]) / abs(b[key])


# ----------------------------------------------------------------------------- registration
def test_held_out_kinds_are_registered_with_their_kind_systems_and_parameters():
    assert len(K.KINDS_SYSTEMS) >= 8 and set(K.KINDS_SYSTEMS) == set(K.KINDS_PARAMS) == set(ZERO)
    families = {s for systems in K.KINDS_SYSTEMS.values() for s in systems}
    assert families == set(RIGS)                         # every rig family has held-out kinds
    for kind, systems in K.KINDS_SYSTEMS.items():
        assert kind in OUTSIDE and not OUTSIDE[kind].measurement and kind in OUTSIDE_KIND
        assert set(ZERO[kind]) <= set(K.KINDS_PARAMS[kind])
        for name, rig in RIGS.items():
            if name in systems:
                assert set(rig.outside[kind]) == set(K.KINDS_PARAMS[kind]), (kind, name)
                assert (kind, name) in EXPECT
            else:
                assert kind not in rig.outside, (kind, name)
                with pytest.raises(ValueError, match="does not apply"):
                    model_for(name, kind)
    assert set(EXPECT) == set(PAIRS)


# ----------------------------------------------------------------------------- off = the reference model
@pytest.mark.parametrize("kind,system", _mark(PAIRS, OTHER_PAIRS))
def test_kind_switched_off_is_the_reference_model(kind, system):
    """Zero strength: the labels of the base model to the solver's accuracy (the added states, if any, only
    change the step control), the same number of switching events."""
    got, want = _with(kind, system, **ZERO[kind]), _base(system)
    for k in NUMERIC:
        assert got[k] == pytest.approx(want[k], rel=1e-6, abs=1e-12), k
    assert got["status"] == want["status"]
    if kind == "unloading_hysteresis":      # one more event per impact: the velocity reversal (entry + exit + it)
        assert 2 * got["n_events"] == 3 * want["n_events"]
    else:
        assert got["n_events"] == want["n_events"]


# ----------------------------------------------------------------------------- on = labels move as stated
@pytest.mark.parametrize("kind,system", _mark(PAIRS, SLOW | OTHER_PAIRS))
def test_kind_moves_its_label_by_the_stated_range_and_stays_physical(kind, system):
    got, base = _with(kind, system, spc=64), _base(system)
    key, lo, hi = EXPECT[(kind, system)]
    assert lo <= _rel(got, base, key) <= hi, (key, _rel(got, base, key))
    assert got["status"] == "ok" and got["period"] == base["period"]
    assert got["impacts_per_cycle"] == base["impacts_per_cycle"]
    h = got["history"]
    assert np.all(np.isfinite(h["force_n"])) and np.min(h["force_n"]) >= 0.0          # contact forces push
    prog = np.asarray(h["progression_m"])
    assert np.all(np.diff(prog) >= -(1e-6 * np.ptp(prog) + 1e-12))                     # never goes back
    if system in ("drill", "indenter-sandstone"):
        assert got["rop_m_s"] > 0.0
    if kind == "contact_wear":                                                         # the surface wore
        assert prog[-1] > prog[0] > 0.0


# ----------------------------------------------------------------------------- signals agree with the dynamics
def _state(kind: str, system: str, m) -> tuple[np.ndarray, object]:
    """A state in contact with every velocity and every added state non-zero."""
    G = _params(system)["gap_m"]
    disc = None
    if system == "drill":
        y = [3e-6, 0.01, 1e-6, 0.004, 2e-7, 0.001, 3e-6, 0.0, 0.0, 0.0]
    elif system.startswith("indenter"):
        y = [G + 1e-4, 0.05, 1e-5, 0.01, 2e-5, 0.003, 0.0, 0.0]
        if system == "indenter-sandstone":
            disc = (0.0, 0.0, 0.0)
    elif system == "pendulum":
        y = [np.arcsin((G + 1e-5) / 0.075), 0.5, 0.0]
    else:
        y = [1e-4, 0.01, G + 5e-5, 0.02, 0.0]
    extra = {"mount_mode": [2e-6, -1e-3], "drive_mode": [2e-6, 1e-3], "contact_wear": [1e-6]}.get(kind, [])
    y = np.array(y + extra, dtype=float)
    assert len(y) == len(m.initial_state()[0])
    return y, disc


@pytest.mark.parametrize("kind,system", PAIRS)
def test_measured_acceleration_and_force_are_those_of_the_rhs(kind, system):
    """``accel`` (the measured signal) is the impacting mass's acceleration of the right-hand side on every branch
    (the unloading branch of the hysteresis too), the vectorised ``force`` the scalar rhs's force."""
    m = model_for(system, kind)(_params(system, RIGS[system].outside[kind]))
    y, disc = _state(kind, system, m)
    t = 0.3 * m.T
    n_br = 3 if system in ("drill", "indenter-sandstone") else 2
    discs = [disc] + ([1.2 * float(m._geo(y)[0])] if kind == "unloading_hysteresis" else [])
    for dsc in discs:
        for br in range(n_br):
            dy = m.flow(br, dsc)(t, y.copy())
            assert len(dy) == len(y)
            a_rhs = m.acc_of(t, y, dy)
            a_obs = m.accel(np.array([t]), y[:, None], br, dsc)[0]
            assert a_obs == pytest.approx(a_rhs, rel=1e-12, abs=1e-9), (br, dsc)
    plain = ref._make_model(system, _params(system))
    yb = y[:len(plain.initial_state()[0])]
    a0 = plain.accel(np.array([t]), yb[:, None], 1, disc)[0]
    a1 = m.accel(np.array([t]), y[:, None], 1, discs[-1])[0]
    if kind not in ("drive_mode", "support_friction", "rate_strength"):   # these act on another body / phase
        assert abs(a1 - a0) > 1e-6 * abs(a0)


KV_CASES = [(k, s) for k, s in PAIRS if s in ("indenter-metal", "pendulum") and k != "support_friction"]


@pytest.mark.parametrize("kind,system", KV_CASES + [("mount_mode", "rimd")])
def test_indicators_and_their_rates_follow_the_contact_law(kind, system):
    """The force indicator times the stiffness is the contact force (so release is the force's zero), and the
    rates are the time derivatives of the indicators along the free flow (classify on a surface)."""
    m = model_for(system, kind)(_params(system, RIGS[system].outside[kind]))
    y, disc = _state(kind, system, m)
    discs = [None] + ([1.2 * float(m._geo(y)[0])] if kind == "unloading_hysteresis" else [])
    t = 0.3 * m.T
    f0 = m.flow(0, None)
    h = 1e-7 * m.T
    for dsc in discs:
        ind = (lambda tt, yy: m._ind(tt, yy, dsc)) if hasattr(m, "_ind") else m.indicators
        rates = (lambda tt, yy: m._rates(tt, yy, dsc)) if hasattr(m, "_rates") else m.rates
        g1, g2 = ind(t, y)
        F = m.force(np.array([t]), y[:, None], 1, dsc)[0]
        assert F > 0
        if system != "rimd":
            assert m.kc * g2 == pytest.approx(F, rel=1e-12)
        d = np.array(f0(t, y))
        fd = [(a - b) / (2 * h) for a, b in zip(ind(t + h, y + h * d), ind(t - h, y - h * d))]
        r = rates(t, y)
        assert r[0] == pytest.approx(fd[0], rel=1e-5) and r[1] == pytest.approx(fd[1], rel=1e-5), dsc


def test_unloading_hysteresis_loses_the_loop_area_each_impact():
    """On the pendulum the impact's loading/unloading loop: the unloading curve k δm (δ/δm)^nu lies below the
    loading line inside the impact (nu > 1), meets it at δm, and the lost work per cycle grows with nu."""
    m = model_for("pendulum", "unloading_hysteresis")(_params("pendulum", {"nu_h": 2.0}))
    dm = 1e-5
    d = np.linspace(1e-7, dm, 50)
    assert np.all(m._shape(d, dm)[:-1] < d[:-1]) and m._shape(np.array(dm), dm) == pytest.approx(dm)
    e = [_with("unloading_hysteresis", "pendulum", nu_h=nu)["energy_per_cycle_j"] for nu in (1.5, 3.0)]
    assert e[1] < e[0] < _base("pendulum")["energy_per_cycle_j"]


# ----------------------------------------------------------------------------- logs
LOG_DEFAULT = {("rate_strength", "drill"), ("contact_wear", "pendulum")}
"""Logs written by default: a rig recording from rest and one recording after a settling run (the writer is the same
for every kind; each kind's physics is checked above, and the other kinds' logs run with the slow subset)."""


@pytest.mark.parametrize("kind,system", _mark(PAIRS, set(PAIRS) - LOG_DEFAULT))
def test_held_out_log_is_a_valid_section7_dataset(tmp_path, monkeypatch, kind, system):
    from pipeline.datasets.measured import load_dataset

    rig = RIGS[system]
    if rig.settle_cycles > 40:       # the format does not need the whole settling run: keep the test fast
        monkeypatch.setitem(RIGS, system, dataclasses.replace(rig, settle_cycles=40))
        rig = RIGS[system]
    spec = LogSpec(system, outside=kind, noise="white2", seed=2, n_runs=4)
    info = generate(spec, tmp_path / "log", threads=2)
    ds = load_dataset(tmp_path / "log")
    runs = pd.read_csv(tmp_path / "log" / "runs.csv")
    assert len(runs) == 4 and len(ds.series) + (0 if ds.summary is None else len(ds.summary)) == 4
    assert info["outside"] == kind and set(rig.outside[kind]) <= set(info["truth"])
    for df in ds.series.values():
        assert np.all(np.isfinite(df.drop(columns="t_s").to_numpy()))
    # the physics is in the data: the clean samples of a run at the default point differ from those without it
    f, lev = DEFAULT[system]
    on = _run(rig, spec, info["truth"], 0, f, lev, False)["signals"]
    plain = {k: v for k, v in info["truth"].items() if k not in rig.outside[kind]}
    off = _run(rig, LogSpec(system, seed=2, n_runs=4), plain, 0, f, lev, False)["signals"]
    assert max(np.max(np.abs(on[s] - off[s])) / np.ptp(off[s]) for s in ("accel_m_s2", "force_n")) > 0.02
