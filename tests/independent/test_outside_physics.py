"""The out-of-library physics ``contact_power`` and ``load_path_mode`` (``dynamics.py``): switched off they are the
reference model, at the rigs' strengths they move the labels by the order ``rigs.py`` states, the signals and the
switching indicators agree with the right-hand side, and their logs are §7 directories."""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pandas as pd
import pytest

from tests import reference_solutions as ref
from tests.independent import dynamics as D
from tests.independent.generator import RTOL, LogSpec, _run, generate
from tests.independent.outside import OUTSIDE, model_for
from tests.independent.rigs import OUTSIDE_KIND, RIGS

pytestmark = pytest.mark.xdist_group("independent-physics")   # one test worker computes the base runs (``_base``)
DEFAULT = {"drill": (270.0, 1500.0), "indenter-metal": (60.0, 1.0), "indenter-sandstone": (60.0, 1.0),
           "pendulum": (3.75, 0.0), "rimd": (8.0, 1.0)}
"""Each rig's default point (the model's default operating point, or the grid's nearest): (frequency, level)."""
WINDOW = 10
NUMERIC = ("rop_m_s", "peak_force_n", "mean_peak_force_n", "impacts_per_cycle", "period", "peak_decel_g",
           "energy_per_cycle_j")


def _params(system: str, extra: dict | None = None) -> dict:
    rig = RIGS[system]
    f, lev = DEFAULT[system]
    p = {**rig.known, **rig.controls(f, lev)}
    p.update(rig.derived(p))
    p.update(extra or {})
    return p


def _transient(system: str) -> int:
    """Cycles before the window: 0.3 s from rest (the rigs recording from rest), else the rig's settling run."""
    rig = RIGS[system]
    f = DEFAULT[system][0]
    return int(round(0.3 * f)) if rig.record_start_s else rig.settle_cycles


@functools.lru_cache(maxsize=None)
def _base(system: str) -> dict:
    return ref.reference_run(system, _params(system), _transient(system), WINDOW, rtol=RTOL)


def _with(system: str, outside: str, **override) -> dict:
    extra = {**RIGS[system].outside[outside], **override}
    return ref.reference_run(model_for(system, outside), _params(system, extra), _transient(system), WINDOW, rtol=RTOL)


def _mark(cases, slow):
    """``cases`` as parametrize arguments, those in ``slow`` marked slow."""
    return [pytest.param(*c, marks=pytest.mark.slow) if c in slow else c for c in cases]


def _rel(a: dict, b: dict, key: str) -> float:
    return (a[key] - b[key]) / abs(b[key])


# ----------------------------------------------------------------------------- registration
def test_outside_physics_are_registered_with_their_kind_and_parameters():
    assert set(OUTSIDE_KIND) == set(OUTSIDE)
    assert not OUTSIDE["contact_power"].measurement and not OUTSIDE["load_path_mode"].measurement
    from tests.independent.kinds import KINDS_SYSTEMS

    for name, rig in RIGS.items():
        held_out = {k for k, systems in KINDS_SYSTEMS.items() if name in systems}      # test_held_out_kinds.py
        want = (set(OUTSIDE) - set(KINDS_SYSTEMS) - ({"contact_power"} if name == "indenter-sandstone" else set())
                | held_out)
        assert set(rig.outside) == want, name
        if "contact_power" in rig.outside:
            assert set(rig.outside["contact_power"]) == {"kn", "pn"} and rig.outside["contact_power"]["pn"] == 2.5
        lpm = rig.outside["load_path_mode"]
        assert set(lpm) == {"mh", "fh_hz", "zeta_h"} and lpm["zeta_h"] == 0.05
        m = {"drill": "M1", "rimd": "m2", "pendulum": "m"}.get(name, "m1")
        assert 0.15 <= lpm["mh"] / rig.known[m] <= 0.3, name
        assert lpm["fh_hz"] > 2 * max(rig.frequencies_hz), name          # a few times the top forcing frequency
    with pytest.raises(ValueError, match="does not apply"):
        model_for("indenter-sandstone", "contact_power")


# ----------------------------------------------------------------------------- off = the reference model
@pytest.mark.parametrize("system", D.CONTACT_POWER_SYSTEMS)
def test_contact_power_off_is_the_reference_model_bit_for_bit(system):
    got = _with(system, "contact_power", kn=0.0)
    want = _base(system)
    for k in NUMERIC:
        assert got[k] == want[k], k
    assert np.array_equal(got["strobe"], want["strobe"]) and got["n_events"] == want["n_events"]


@pytest.mark.parametrize("system", sorted(RIGS))
def test_load_path_mode_uncoupled_is_the_reference_model(system):
    """fh_hz = 0 (kh = ch = 0): the hidden mass rides along without force; only the step control sees its two
    states, so the labels agree to the solver's accuracy, not bit for bit."""
    got = _with(system, "load_path_mode", fh_hz=0.0)
    want = _base(system)
    for k in NUMERIC:
        assert got[k] == pytest.approx(want[k], rel=1e-6, abs=1e-12), k
    assert got["n_events"] == want["n_events"]


# ----------------------------------------------------------------------------- on = labels move as stated
CONTACT_POWER_EXPECT = {"drill": ("rop_m_s", 0.08, 0.16), "indenter-metal": ("peak_force_n", 0.06, 0.15),
                        "pendulum": ("peak_force_n", 0.08, 0.15), "rimd": ("peak_force_n", 0.08, 0.15)}


@pytest.mark.parametrize("system", D.CONTACT_POWER_SYSTEMS)
def test_contact_power_moves_the_labels_by_the_stated_order(system):
    got, base = _with(system, "contact_power"), _base(system)
    key, lo, hi = CONTACT_POWER_EXPECT[system]
    assert lo <= _rel(got, base, key) <= hi, (key, _rel(got, base, key))
    assert got["impacts_per_cycle"] == base["impacts_per_cycle"] and got["period"] == base["period"]
    assert got["status"] == "ok"
    if system == "drill":      # phase III caps the force at Pr: the peak stays, the decel moves a little
        assert got["peak_force_n"] == base["peak_force_n"] == RIGS["drill"].known["Pr"]
        assert 0.01 <= _rel(got, base, "peak_decel_g") <= 0.05
    else:                      # a stiffer contact: a higher force peak and a higher deceleration
        assert 0.06 <= _rel(got, base, "peak_decel_g") <= 0.15


LOAD_PATH_EXPECT = {"drill": ("peak_decel_g", 0.03, 0.10), "indenter-metal": ("mean_peak_force_n", -0.45, -0.30),
                    "indenter-sandstone": ("peak_decel_g", -0.25, -0.10), "pendulum": ("peak_force_n", -0.30, -0.15),
                    "rimd": ("peak_force_n", -0.70, -0.50)}


@pytest.mark.parametrize("system", sorted(RIGS))
def test_load_path_mode_moves_the_labels_by_the_stated_order(system):
    got, base = _with(system, "load_path_mode"), _base(system)
    key, lo, hi = LOAD_PATH_EXPECT[system]
    assert lo <= _rel(got, base, key) <= hi, (key, _rel(got, base, key))
    assert got["status"] == "ok" and got["period"] == base["period"]     # steady rigs stay period 1
    if system == "indenter-metal":        # the ringing hidden mass brings a second impact per cycle
        assert base["impacts_per_cycle"] == 1.0 and got["impacts_per_cycle"] == 2.0


# ----------------------------------------------------------------------------- signals agree with the dynamics
def _state(system: str) -> tuple[np.ndarray, object]:
    """A state in contact (penetration of the rig's typical order), all velocities and the hidden states non-zero."""
    G = _params(system)["gap_m"]
    if system == "drill":
        y = [3e-6, 0.01, 1e-6, 0.004, 2e-7, 0.001, 3e-6, 0.0, 0.0, 0.0]
    elif system.startswith("indenter"):
        y = [G + 1e-4, 0.05, 1e-5, 0.01, 2e-5, 0.003, 0.0, 0.0]
    elif system == "pendulum":
        y = [np.arcsin((G + 1e-5) / 0.075), 0.5, 0.0]
    else:
        y = [1e-4, 0.01, G + 5e-5, 0.02, 0.0]
    return np.array(y), ((0.0, 0.0, 0.0) if system == "indenter-sandstone" else None)


CASES = ([("contact_power", s) for s in D.CONTACT_POWER_SYSTEMS] + [("load_path_mode", s) for s in sorted(RIGS)])


def _model(outside: str, system: str):
    m = model_for(system, outside)(_params(system, RIGS[system].outside[outside]))
    y, disc = _state(system)
    if outside == "load_path_mode":
        y = np.concatenate([y, [2e-6, 1e-3]])
    return m, y, disc


@pytest.mark.parametrize("outside,system", CASES)
def test_measured_acceleration_and_force_are_those_of_the_rhs(outside, system):
    """``accel`` (the measured signal) equals the impacting mass's acceleration of the right-hand side, on every
    branch, and the contact force of the vectorised ``force`` that of the scalar rhs."""
    m, y, disc = _model(outside, system)
    t = 0.3 * m.T
    n_br = 3 if system in ("drill", "indenter-sandstone") else 2
    for br in range(n_br):
        dy = m.flow(br, disc)(t, y.copy())
        assert len(dy) == len(y)
        a_rhs = m.acc_of(t, y, dy)
        a_obs = m.accel(np.array([t]), y[:, None], br, disc)[0]
        assert a_obs == pytest.approx(a_rhs, rel=1e-12, abs=1e-9), br
    plain = ref._make_model(system, _params(system))
    yb = y[:len(_state(system)[0])]
    a0 = plain.accel(np.array([t]), yb[:, None], 1, disc)[0]
    assert abs(m.accel(np.array([t]), y[:, None], 1, disc)[0] - a0) > 1e-6 * abs(a0)     # the term is there


@pytest.mark.parametrize("outside,system", [c for c in CASES if c[1] in ("indenter-metal", "pendulum", "rimd")])
def test_indicators_and_their_rates_follow_the_contact_law(outside, system):
    """The force indicator times the stiffness is the contact force expression (so the release surface is the
    force's zero), and ``rates`` is the time derivative of the indicators along the free flow (classify)."""
    m, y, disc = _model(outside, system)
    t = 0.3 * m.T
    g1, g2 = m.indicators(t, y)
    F = m.force(np.array([t]), y[:, None], 1, disc)[0]
    assert F > 0
    if system != "rimd":
        k = m.p["k1"] if system == "indenter-metal" else m.p["ki"]
        assert k * g2 == pytest.approx(F, rel=1e-12)
    f0 = m.flow(0, disc)
    h = 1e-7 * m.T
    fd = [(a - b) / (2 * h) for a, b in zip(m.indicators(t + h, y + h * np.array(f0(t, y))),
                                            m.indicators(t - h, y - h * np.array(f0(t, y))))]
    r = m.rates(t, y)
    assert r[0] == pytest.approx(fd[0], rel=1e-5) and r[1] == pytest.approx(fd[1], rel=1e-5)


@pytest.mark.parametrize("outside", ["contact_power", "load_path_mode"])
def test_drill_contact_rate_follows_the_contact_law(outside):
    """The drill's dP/dt (classify on a surface) is the derivative of its P along the phase-II flow."""
    m, y, disc = _model(outside, "drill")
    t = 0.3 * m.T
    f1 = m.flow(1, disc)
    h = 1e-7 * m.T
    d = np.array(f1(t, y))
    fd = (m._P(y + h * d) - m._P(y - h * d)) / (2 * h)
    assert m._Pdot(t, y, m._P(y)) == pytest.approx(fd, rel=1e-5)


# ----------------------------------------------------------------------------- logs
LOG_CASES = [("indenter-metal", "contact_power"), ("drill", "load_path_mode"), ("pendulum", "load_path_mode"),
             ("rimd", "contact_power")]
"""The writer is the same for every system: the drill's log by default, the others with the slow subset."""


@pytest.mark.parametrize("system,outside", _mark(LOG_CASES, set(LOG_CASES) - {("drill", "load_path_mode")}))
def test_outside_log_is_a_valid_section7_dataset(tmp_path, monkeypatch, system, outside):
    from pipeline.datasets.measured import load_dataset

    rig = RIGS[system]
    if rig.settle_cycles > 40:       # the format does not need the whole settling run: keep the test fast
        monkeypatch.setitem(RIGS, system, dataclasses.replace(rig, settle_cycles=40))
        rig = RIGS[system]
    spec = LogSpec(system, outside=outside, noise="white2", seed=2, n_runs=4)
    info = generate(spec, tmp_path / "log", threads=2)
    ds = load_dataset(tmp_path / "log")
    runs = pd.read_csv(tmp_path / "log" / "runs.csv")
    assert len(runs) == 4 and len(ds.series) + (0 if ds.summary is None else len(ds.summary)) == 4
    assert info["outside"] == outside and set(RIGS[system].outside[outside]) <= set(info["truth"])
    for df in ds.series.values():
        assert np.all(np.isfinite(df.drop(columns="t_s").to_numpy()))
    # the physics is in the data: the clean samples of a run at the default point differ from those without it
    f, lev = DEFAULT[system]
    on = _run(rig, spec, info["truth"], 0, f, lev, False)["signals"]["accel_m_s2"]
    plain = {k: v for k, v in info["truth"].items() if k not in rig.outside[outside]}
    off = _run(rig, LogSpec(system, seed=2, n_runs=4), plain, 0, f, lev, False)["signals"]["accel_m_s2"]
    assert np.max(np.abs(on - off)) > 0.02 * np.ptp(off)
