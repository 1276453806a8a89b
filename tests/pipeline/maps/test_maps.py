"""Response maps (`vibro map`, pipeline/maps.py): impact-pattern classification on cases with a known
answer, continuation sweeps, ROP regions, and the CLI (files, errors, MLflow).

Known answers come from: the classification rule itself (MODELS.md §5 labels -> Peterka classes, seed 001),
a linear no-impact response (period 1, no impact, by construction), the independent reference
(tests/reference_solutions.py: pendulum gap 0 at 7.25 Hz is period 2 with one impact per two cycles), and
MODELS.md §4 (RIMD gap 3 mm: the up-sweep impacts at 5.5 Hz, from rest / down-sweep it does not).
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import sim
from pipeline.maps import compute as M
from pipeline.cli import main
from tests.reference_solutions import reference_run


@pytest.fixture(autouse=True)
def _no_mlflow(monkeypatch):
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")


# ------------------------------------------------------------------------------ classification rule
@pytest.mark.parametrize("status, ipc, period, code, label", [
    ("no_contact", 0.0, 1, M.NO_IMPACT, "no impact"),
    ("no_contact", 0.0, 3, M.NO_IMPACT, "no impact"),      # residual free swing: still no impact
    ("ok", 1.0, 1, M.Z11, "z=1/1"),
    ("ok", 0.5, 2, M.Z12, "z=1/2"),
    ("ok", 1.0, 2, M.OTHER_PERIODIC, "2/2"),                # two impacts per two cycles, not z = 1/1
    ("ok", 2.0, 1, M.OTHER_PERIODIC, "2/1"),
    ("ok", 0.34375, 3, M.OTHER_PERIODIC, "1/3"),            # 11 onsets in a 32-cycle window, period 3
    ("ok", 1.0625, 0, M.NON_PERIODIC, "non-periodic"),
    ("not_settled", 0.5, 0, M.NON_PERIODIC, "non-periodic"),
    ("runaway", None, None, M.RUNAWAY, "runaway"),
    ("failed", None, None, M.FAILED, "failed"),
])
def test_classify_pattern_rule(status, ipc, period, code, label):
    assert M.classify_pattern(status, ipc, period) == (code, label)


@pytest.mark.parametrize("status, rop, region", [
    ("ok", 1e-3, M.ROP_OK), ("ok", 0.0, M.ROP_NONE), ("no_contact", 0.0, M.ROP_NONE),
    ("runaway", None, M.ROP_RUNAWAY), ("failed", None, M.ROP_FAILED), ("not_settled", 2e-3, M.ROP_UNSETTLED)])
def test_rop_region_rule(status, rop, region):
    assert M.rop_region(status, rop) == region


# ------------------------------------------------------------------------------ known-answer simulations
def test_linear_no_impact_response_is_period_one_without_impacts():
    """Pendulum with a gap it can never reach (l sin θ ≤ l < gap): a forced, lightly damped oscillator.
    After 600 cycles at 3 Hz (200 s ≈ 11 free-decay time constants 1/(ζ ω0) = 17.5 s) it is period 1."""
    df = M.grid_map("pendulum", "frequency_hz", [3.0], "gap_m", [0.1],
                    settings={"min_transient": 600, "max_transient": 600, "window": 16})
    r = df.iloc[0]
    assert r["status"] == "no_contact" and r["impacts_per_cycle"] == 0.0 and r["period"] == 1
    assert r["pattern"] == M.NO_IMPACT


def test_period_two_case_of_the_reference_is_classified_z12():
    """Pendulum gap 0: the reference gives period 1 / one impact at 3.75 Hz and period 2 / one impact
    per two cycles at 7.25 Hz (MODELS.md §3's z = 1/1 and z = 1/2 resonances)."""
    p = sim.get_model("pendulum").resolve(None, gap_m=0.0, frequency_hz=7.25)
    ref = reference_run("pendulum", p, 60, 8)
    assert ref["period"] == 2 and ref["impacts_per_cycle"] == 0.5
    df = M.grid_map("pendulum", "frequency_hz", [3.75, 7.25], "gap_m", [0.0])
    assert list(df["pattern_name"]) == ["z=1/1", "z=1/2"]
    assert list(df["period"]) == [1, 2]


def test_bifurcation_continuation_shows_coexisting_attractors():
    """RIMD gap 3 mm (MODELS.md §4): continued upwards the impacting branch survives to 5.5 Hz; from
    rest (the first down point) and continued downwards there is no impact at 5.5 Hz."""
    pts, strobe = M.bifurcation("rimd", "frequency_hz", [4.5, 5.0, 5.5], "both", fixed={"gap_m": 3e-3})
    up = pts[pts["direction"] == "up"].set_index("frequency_hz")
    down = pts[pts["direction"] == "down"].set_index("frequency_hz")
    assert up.loc[5.5, "pattern_name"] == "z=1/1"
    assert up.loc[5.5, "peak_force_n"] == pytest.approx(25.6, rel=0.01)     # MODELS.md §4
    assert down.loc[5.5, "pattern_name"] == "no impact"
    # stroboscopic samples: one per recorded cycle (default window 32); period 1 -> all equal within the
    # periodicity tolerance (Settings.period_tol = 1e-3, relative to the motion's range > |x2| here)
    s = strobe[(strobe["direction"] == "up") & (strobe["frequency_hz"] == 5.5)]
    assert len(s) == sim.get_model("rimd").default_settings["window"]
    assert up.loc[5.5, "period"] == 1
    assert np.ptp(s["disp_m"]) < 1e-3 * np.abs(s["disp_m"]).max()
    # on the non-impacting down branch at 5.5 Hz the hammer stays short of the stop
    s_down = strobe[(strobe["direction"] == "down") & (strobe["frequency_hz"] == 5.5)]
    assert (s_down["disp_m"] < 3e-3).all()


def test_rop_map_draws_runaway_and_progressing_regions():
    """Drill `lab` preset: Fs ≥ Pr = 3 kN has no bounded steady state (MODELS.md §2) -> runaway row;
    the default operating point (Fs = 1.2 kN, F0 = 2.25 kN) progresses."""
    df = M.grid_map("drill", "frequency_hz", [280.0], "static_force_n", [1200.0, 3300.0], preset="lab")
    assert list(df["rop_region_name"]) == ["progressing", "runaway"]
    assert df.loc[0, "rop_m_s"] > 0.0 and pd.isna(df.loc[1, "rop_m_s"])     # no ROP number for a runaway


# ------------------------------------------------------------------------------ CLI
def test_cli_peterka_writes_png_and_parquet(tmp_path, capsys):
    out = tmp_path / "pm"
    rc = main(["map", "pendulum", "--x", "frequency_hz", "--x-range", "3.75", "7.25", "--nx", "2",
               "--y", "gap_m", "--y-range", "0", "0.001", "--ny", "2", "--out", str(out), "--no-progress"])
    assert rc == 0
    png, pq = tmp_path / "pm.png", tmp_path / "pm.parquet"
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
    df = pd.read_parquet(pq)
    assert len(df) == 4
    assert {"frequency_hz", "gap_m", "peak_force_n", "period", "status", "pattern_name", "pattern_label"} <= set(df)
    cell = df[(df["gap_m"] == 0.0) & (df["frequency_hz"] == 3.75)].iloc[0]
    assert cell["pattern_name"] == "z=1/1"
    assert "4 points" in capsys.readouterr().out
    assert not [p for p in tmp_path.glob(".*") if p.suffix != ".vibro"]   # no temporary files left behind
    assert {p.name for p in tmp_path.glob(".*.vibro")} == {".pm.png.vibro", ".pm.parquet.vibro"}  # ours, on record


def test_cli_bifurcation_and_rop(tmp_path):
    out = tmp_path / "bif"
    assert main(["map", "rimd", "--x", "frequency_hz", "--x-range", "7.5", "8.5", "--nx", "3",
                 "--direction", "up", "--out", str(out), "--no-progress"]) == 0
    pts = pd.read_parquet(tmp_path / "bif.parquet")
    strobe = pd.read_parquet(tmp_path / "bif.strobe.parquet")
    assert list(pts["frequency_hz"]) == [7.5, 8.0, 8.5] and set(pts["direction"]) == {"up"}
    assert len(strobe) == 3 * sim.get_model("rimd").default_settings["window"]
    assert (tmp_path / "bif.png").exists()
    out = tmp_path / "rop"
    assert main(["map", "drill", "--preset", "lab", "--x", "frequency_hz", "--x-range", "250", "300", "--nx", "2",
                 "--y", "static_force_n", "--y-range", "1200", "3300", "--ny", "2", "--out", str(out),
                 "--no-progress"]) == 0
    df = pd.read_parquet(tmp_path / "rop.parquet")
    assert set(df[df["static_force_n"] == 3300.0]["rop_region_name"]) == {"runaway"}
    assert (tmp_path / "rop.png").exists()


@pytest.mark.parametrize("argv, needle", [
    (["map", "pendulum", "--x", "freq", "--y", "gap_m"], "'freq' is not a parameter"),
    (["map", "pendulum", "--x", "frequency_hz", "--x-range", "5", "1", "--y", "gap_m"], "LO <= HI"),
    (["map", "pendulum", "--x", "frequency_hz", "--y", "gap_m", "--color", "force"], "--color 'force'"),
    (["map", "pendulum", "--x", "frequency_hz", "--y", "gap_m", "--set", "zeta=-1"], "zeta"),
    (["map", "pendulum", "--x", "frequency_hz", "--y", "gap_m", "--y-range", "-1", "0"], "gap_m"),
    (["map", "pendulum", "--x", "frequency_hz", "--y", "frequency_hz"], "different parameters"),
    (["map", "pendulum", "--x", "M", "--y", "gap_m"], "no default range for 'M'"),
    (["map", "pendulum", "--x", "frequency_hz", "--setting", "window=1"], "window"),
])
def test_cli_user_errors_are_one_line_exit_2(argv, needle, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1 and "Traceback" not in err


def test_cli_logs_to_mlflow(tmp_path, monkeypatch):
    monkeypatch.delenv("VIBRO_NO_MLFLOW", raising=False)
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'ml.db'}")
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    out = tmp_path / "m"
    assert main(["map", "rimd", "--x", "frequency_hz", "--x-range", "8", "8.25", "--nx", "2", "--y", "gap_m",
                 "--y-range", "0", "0", "--ny", "1", "--out", str(out), "--no-progress"]) == 0
    import mlflow

    runs = mlflow.search_runs(experiment_names=["vibro"])
    assert len(runs) == 1 and runs.iloc[0]["params.model"] == "rimd"
    assert runs.iloc[0]["metrics.n_points"] == 2
