"""Simulator core: API behaviour, validation, statuses and the published facts of MODELS.md §1–§2."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import sim
from sim import ParameterError
from sim.models.indenter import TABLE1, air_damping, pneumatic_force

FAST = {"min_transient": 20, "max_transient": 200, "window": 8}


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize("model, params, needle", [
    ("drill", {"M1": -1.0}, "'M1' must be > 0"),
    ("drill", {"frequency_hz": 0.0}, "'frequency_hz' must be > 0"),
    ("drill", {"K1": float("nan")}, "'K1' must be finite"),
    ("drill", {"bogus": 1.0}, "unknown parameter 'bogus'"),
    ("indenter-metal", {"k2": "abc"}, "'k2' must be a number"),
    ("indenter-sandstone", {"gap_m": -1e-3}, "'gap_m' must be >= 0"),
])
def test_bad_parameters_name_the_parameter(model, params, needle):
    with pytest.raises(ParameterError, match=needle):
        sim.simulate(model, **params)


def test_unknown_model_and_preset():
    with pytest.raises(ParameterError, match="unknown model 'nope'"):
        sim.simulate("nope")
    with pytest.raises(ParameterError, match="unknown preset 'x'"):
        sim.simulate("drill", preset="x")


def test_bad_setting_is_named():
    with pytest.raises(ParameterError, match="window"):
        sim.simulate("drill", settings={"window": 0})
    with pytest.raises(ParameterError, match="unknown setting"):
        sim.simulate("drill", settings={"nope": 1})


def test_batch_error_names_row_and_column():
    table = pd.DataFrame({"frequency_hz": [100.0, -5.0]})
    with pytest.raises(ParameterError, match=r"row 1: parameter 'frequency_hz'"):
        sim.simulate_batch("drill", table)


# ----------------------------------------------------------------------------- drill statuses
def test_seed003_preset_is_runaway():
    """MODELS.md §2: seed 003's table has Fs = 1260 kN >= Pr = 95 kN: no steady state (the seed reported 790 m/s)."""
    r = sim.simulate("drill", preset="seed-003")
    assert r.status == "runaway"
    assert r.labels["rop_m_s"] is None
    assert "Fs" in r.labels["reason"] and "Pr" in r.labels["reason"]
    # confirmed from the drift: (Fs - Pr) / sum(M) = 1165e3 / 138986.8 = 8.38 m/s^2
    assert "8.38 m/s^2" in r.labels["reason"].split("confirmed")[1]


def test_any_fs_above_pr_is_runaway_in_batch():
    table = pd.DataFrame({"static_force_n": [700.0, 1600.0]})
    df = sim.simulate_batch("drill", table, settings=FAST)
    assert list(df["status"]) == ["ok", "runaway"]
    assert df.loc[1, "rop_m_s"] is None or pd.isna(df.loc[1, "rop_m_s"])


def test_drill_no_forcing_does_not_progress():
    """F0 = 0 and Fs < Pr: the bit rests on the rock, contact force Fs < Pr, nothing progresses."""
    r = sim.simulate("drill", amplitude_n=0.0, static_force_n=700.0, settings=FAST)
    assert r.status in ("ok", "aperiodic")     # FAST's short transient: still converging to rest, no period yet
    assert abs(r.labels["rop_m_s"]) < 1e-9
    assert r.labels["impacts_per_cycle"] == 0.0
    assert r.labels["peak_force_n"] == pytest.approx(700.0, rel=1e-3)


def test_drill_with_gap_and_no_forcing_never_touches():
    r = sim.simulate("drill", gap_m=1e-3, amplitude_n=0.0, static_force_n=0.0, settings=FAST)
    assert r.status == "no_contact"
    assert r.labels["rop_m_s"] == 0.0


def test_specific_energy_is_work_per_metre():
    r = sim.simulate("drill", settings=FAST)
    lab = r.labels
    f = r.params["frequency_hz"]
    assert lab["rop_m_s"] > 0
    assert lab["specific_energy_j_m"] == pytest.approx(lab["energy_per_cycle_j"] * f / lab["rop_m_s"], rel=1e-9)


def test_same_input_same_result_and_batch_equals_single():
    a = sim.simulate("drill", frequency_hz=150.0, settings=FAST).labels
    b = sim.simulate("drill", frequency_hz=150.0, settings=FAST).labels
    assert a == b
    df = sim.simulate_batch("drill", [{"frequency_hz": 150.0}, {"frequency_hz": 150.0}], settings=FAST, n_threads=2)
    for k in sim.LABELS:
        assert df.loc[0, k] == a[k] and df.loc[1, k] == a[k]


def test_history_and_continuation():
    r = sim.simulate("drill", history=True, settings={**FAST, "samples_per_cycle": 50})
    h = r.history
    assert len(h) == 8 * 50
    for col in ("t_s", "x1", "xb", "force_n", "accel_m_s2", "disp_m", "progression_m", "phase"):
        assert col in h
    assert (h["force_n"] >= 0).all()
    # progression over the window equals rop * window time (within one sample)
    prog = h["progression_m"].to_numpy()
    dt_win = 8 / r.params["frequency_hz"]
    assert (prog[-1] - prog[0]) == pytest.approx(r.labels["rop_m_s"] * dt_win, rel=0.05)
    # continuing from the final steady state settles at once and reproduces the labels
    r2 = sim.simulate("drill", initial_state=r.final_state, settings={**FAST, "min_transient": 0})
    assert r2.labels["rop_m_s"] == pytest.approx(r.labels["rop_m_s"], rel=1e-4)
    assert r2.labels["transient_cycles"] <= 17


@pytest.mark.parametrize("model", sim.model_names())
def test_every_model_continues_from_its_own_final_state(model):
    """``initial_state=final_state`` is accepted by every model (the indenters keep two discrete states whether the
    sample uses them or not) and, from a settled state, reproduces the labels after a short transient."""
    r = sim.simulate(model, settings=FAST)
    r2 = sim.simulate(model, initial_state=r.final_state, settings={**FAST, "min_transient": 0})
    assert r2.status == r.status
    for k in ("peak_force_n", "impacts_per_cycle"):
        assert r2.labels[k] == pytest.approx(r.labels[k], rel=1e-3), k
    assert r2.labels["transient_cycles"] < r.labels["transient_cycles"] or r.labels["transient_cycles"] <= 2


def test_history_columns_are_the_dataframe_and_a_set_column_replaces_it():
    """``columns`` holds the history's arrays; ``history`` is the DataFrame built from them on first use, and
    ``set_column`` (the sensor low-pass's way to write the measured acceleration) is seen by the next ``history``."""
    r = sim.simulate("drill", history=True, settings={**FAST, "samples_per_cycle": 20})
    assert r._frame is None                              # nothing built until asked
    h = r.history
    assert list(h.columns) == list(r.columns)
    for col, v in r.columns.items():
        np.testing.assert_array_equal(h[col].to_numpy(), v)
    assert r.history is h                                # built once
    r.set_column("accel_m_s2", np.zeros(len(h)))
    assert (r.history["accel_m_s2"] == 0.0).all() and r.history is not h
    assert sim.simulate("drill", settings=FAST).columns is None and sim.simulate("drill", settings=FAST).history is None


def test_contact_switches_are_located_not_stepped_over():
    """In the history, the contact force is positive only in contact phases and the bit never sits
    inside the rock surface while out of contact (phase I: x1 < xt up to the event tolerance)."""
    r = sim.simulate("drill", gap_m=2e-4, history=True, settings={**FAST, "samples_per_cycle": 400})
    h = r.history
    free = h["phase"] == 0
    assert free.any() and (~free).any()
    assert (h.loc[free, "force_n"] == 0).all()
    assert (h.loc[free, "x1"] - h.loc[free, "xt"]).max() < 1e-9


# ----------------------------------------------------------------------------- indenter
def test_indenter_formulas():
    """MODELS.md §1: Fp = (101325/4) P π D² = 199 N at 1 bar and D = 50 mm; c3 = 78.6 π² Fa / f ≈ 6e3 N s/m."""
    assert pneumatic_force(1.0, 0.05) == pytest.approx(198.9, abs=0.1)
    assert air_damping(300.0, 40.0) == pytest.approx(78.6 * np.pi ** 2 * 7.5)
    params = sim.get_model("indenter-metal").resolve("table1-40hz")
    assert params["c3"] == pytest.approx(air_damping(300.0, 40.0))
    assert params["static_force_n"] == pytest.approx(pneumatic_force(1.0, 0.05))


@pytest.fixture(scope="module")
def table1_runs():
    rows = [{"frequency_hz": float(f), "amplitude_n": TABLE1[f]} for f in (40, 60, 80, 90)]
    return {m: sim.simulate_batch(m, rows) for m in ("indenter-metal", "indenter-sandstone")}


def test_indenter_first_impact_deceleration_matches_models_md(table1_runs):
    """MODELS.md §1 (independent high-accuracy solution at the defaults, Table 1 forcing, P = 1 bar):
    metal 12.3 / 26.2 / 43.0 / 50.6 g, sandstone 7.2 / 16.8 / 30.3 / 39.8 g at 40/60/80/90 Hz, one impact per cycle."""
    expected = {"indenter-metal": [12.3, 26.2, 43.0, 50.6], "indenter-sandstone": [7.2, 16.8, 30.3, 39.8]}
    for model, df in table1_runs.items():
        assert list(df["status"]) == ["ok"] * 4
        np.testing.assert_allclose(df["peak_decel_g"], expected[model], atol=0.06)
        assert list(df["impacts_per_cycle"]) == [1.0] * 4
        assert list(df["period"]) == [1] * 4


def test_indenter_published_trends(table1_runs):
    """Seed 000 §5: first-impact deceleration grows with frequency and impacts per cycle do not increase."""
    for df in table1_runs.values():
        assert np.all(np.diff(df["peak_decel_g"]) > 0)
        assert np.all(np.diff(df["impacts_per_cycle"]) <= 0)


def test_metal_does_not_progress_sandstone_does(table1_runs):
    metal, sand = table1_runs["indenter-metal"], table1_runs["indenter-sandstone"]
    assert (metal["rop_m_s"] == 0.0).all()
    assert np.isinf(metal["specific_energy_j_m"]).all()
    # MODELS.md §1: sandstone progression of roughly 5-20 mm/s at the defaults
    assert sand["rop_m_s"].between(4e-3, 2.5e-2).all()


def test_sandstone_crater_floor_only_moves_forward():
    r = sim.simulate("indenter-sandstone", preset="table1-80hz", history=True,
                     settings={"samples_per_cycle": 400, "window": 8})
    xp = r.history["progression_m"].to_numpy()
    assert np.all(np.diff(xp) >= -1e-12)
    assert xp[-1] > xp[0]
    # the crater floor never lies beyond the indenter tip: x1 - G >= xp in contact
    h = r.history
    contact = h["phase"] > 0
    assert (h.loc[contact, "x1"] - 1e-3 - h.loc[contact, "progression_m"] >= -1e-9).all()


def test_effects_change_the_response_and_default_off():
    base = sim.simulate("indenter-metal", preset="table1-60hz").labels
    coil = sim.simulate("indenter-metal", preset="table1-60hz", tau=2e-3, beta=200.0).labels
    hard = sim.simulate("indenter-metal", preset="table1-60hz", kappa=1e6).labels
    low = sim.simulate("indenter-metal", preset="table1-60hz", fc=150.0).labels
    assert coil["peak_decel_g"] != pytest.approx(base["peak_decel_g"], rel=1e-3)
    assert hard["peak_decel_g"] != pytest.approx(base["peak_decel_g"], rel=1e-3)
    # a sensor low-pass only changes what the accelerometer reports, not the contact force (an effect runs DOPRI5, so
    # the force is the DOPRI5 run's, not the default exact propagator's: sim/exact/indenter.py)
    assert low["peak_decel_g"] < base["peak_decel_g"]
    base_num = sim.simulate("indenter-metal", preset="table1-60hz", settings={"method": "dopri5"}).labels
    assert low["peak_force_n"] == pytest.approx(base_num["peak_force_n"], rel=1e-9)
