"""Measured-data ingest (MODELS.md §7): strict validation naming file/line/column; atomic writing."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.core.errors import UserError
from pipeline.datasets.measured import Dataset, load_dataset, write_dataset

ROOT = Path(__file__).resolve().parents[3]
PUBLISHED = ROOT / "measured" / "seed000-published"

RUNS = ("run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s\n"
        "r1,indenter-metal,60,440,199,0.001,0.1\n"
        "r2,indenter-metal,80,650,199,0.001,0.1\n")


def _series(f=60.0, spc=100, duration=0.1) -> str:
    """A sine at ``f`` sampled ``spc`` times a cycle over ``duration`` s (RUNS' duration_s)."""
    t = np.arange(round(spc * f * duration)) / (f * spc)
    return pd.DataFrame({"t_s": t, "accel_m_s2": np.sin(2 * np.pi * f * t)}).to_csv(index=False)


def _make(tmp_path: Path, runs=RUNS, series: dict | None = None, summary: str | None = None) -> Path:
    d = tmp_path / "ds"
    d.mkdir()
    (d / "runs.csv").write_text(runs)
    if series is None:
        series = {"r1": _series(60.0), "r2": _series(80.0)}
    if series:
        (d / "series").mkdir()
        for rid, text in series.items():
            (d / "series" / f"{rid}.csv").write_text(text)
    if summary is not None:
        (d / "summary.csv").write_text(summary)
    return d


def test_valid_dataset_loads(tmp_path):
    ds = load_dataset(_make(tmp_path))
    assert list(ds.runs["run_id"]) == ["r1", "r2"]
    assert set(ds.series) == {"r1", "r2"}
    assert ds.series["r1"]["accel_m_s2"].size == 600


def test_published_dataset_loads():
    """The shipped seed-000 data: 4 metal + 4 sandstone runs, summary form (MODELS.md §1 table)."""
    ds = load_dataset(PUBLISHED)
    assert len(ds.runs) == 8 and ds.systems == ["indenter-metal", "indenter-sandstone"]
    s = ds.summary
    assert s.loc["metal-90hz", "peak_decel_g"] == pytest.approx(65.8)          # seed §5
    assert s.loc["sands-40hz", "impacts_per_cycle_lower_bound"] == 1           # "more than five"
    assert s.loc["metal-40hz", "spectral_ratio"] == pytest.approx(1.81)        # 720 Hz / 80 Hz peak
    assert np.isnan(s.loc["metal-60hz", "spectral_ratio"])                      # not published: empty cell


@pytest.mark.parametrize("runs, where", [
    (RUNS.replace("r2,indenter-metal", "r2,indenter-wood"), "runs.csv line 3, column 'system'"),
    (RUNS.replace(",80,", ",abc,"), "runs.csv line 3, column 'frequency_hz'"),
    (RUNS.replace(",80,", ",nan,"), "runs.csv line 3, column 'frequency_hz'"),
    (RUNS.replace(",80,", ",,"), "runs.csv line 3, column 'frequency_hz'"),
    (RUNS.replace(",0.1\nr2", ",-0.1\nr2"), "runs.csv line 2, column 'duration_s'"),
    (RUNS.replace(",gap_m", ""), "missing required column(s) gap_m"),
    (RUNS.replace("r2,", "r1,"), "runs.csv line 3, column 'run_id'"),
])
def test_bad_runs_csv_is_named(tmp_path, runs, where):
    with pytest.raises(UserError, match=where.replace("(", r"\(").replace(")", r"\)")):
        load_dataset(_make(tmp_path, runs=runs))


def test_bad_series_is_named(tmp_path):
    text = _series(60.0).splitlines()
    text[5] = text[4]                        # repeats a time stamp: line 6 is not increasing
    with pytest.raises(UserError, match=r"series/r1.csv line 6, column 't_s'.*not increasing"):
        load_dataset(_make(tmp_path, series={"r1": "\n".join(text), "r2": _series(80.0)}))


def test_series_nan_and_unknown_run(tmp_path):
    text = _series(60.0).splitlines()
    text[10] = text[10].split(",")[0] + ",NaN"
    with pytest.raises(UserError, match=r"series/r1.csv line 11, column 'accel_m_s2'"):
        load_dataset(_make(tmp_path, series={"r1": "\n".join(text), "r2": _series(80.0)}))
    shutil.rmtree(tmp_path / "ds")
    with pytest.raises(UserError, match=r"series/r9.csv: run 'r9' is not in runs.csv"):
        load_dataset(_make(tmp_path, series={"r1": _series(), "r2": _series(80.0), "r9": _series()}))


def test_run_without_data_is_named(tmp_path):
    with pytest.raises(UserError, match=r"runs.csv line 3, column 'run_id'.*neither a series"):
        load_dataset(_make(tmp_path, series={"r1": _series()}))


def test_summary_validation(tmp_path):
    ok = load_dataset(_make(tmp_path, series={"r1": _series()}, summary="run_id,peak_decel_g\nr2,30.5\n"))
    assert ok.summary.loc["r2", "peak_decel_g"] == 30.5
    shutil.rmtree(tmp_path / "ds")
    with pytest.raises(UserError, match=r"summary.csv line 2, column 'peak_decel_g'"):
        load_dataset(_make(tmp_path, series={"r1": _series()}, summary="run_id,peak_decel_g\nr2,fast\n"))
    shutil.rmtree(tmp_path / "ds")
    with pytest.raises(UserError, match=r"summary.csv line 2, column 'run_id'.*not in runs.csv"):
        load_dataset(_make(tmp_path, series={"r1": _series(), "r2": _series(80.0)},
                           summary="run_id,peak_decel_g\nr7,3\n"))


def test_write_is_atomic_and_round_trips(tmp_path):
    ds = load_dataset(_make(tmp_path))
    out = write_dataset(ds, tmp_path / "copy")
    back = load_dataset(out)
    assert np.allclose(back.series["r2"]["accel_m_s2"], ds.series["r2"]["accel_m_s2"])
    bad = Dataset(runs=ds.runs, series={"r1": ds.series["r1"].assign(accel_m_s2=np.nan)})
    with pytest.raises(UserError, match="non-finite"):
        write_dataset(bad, tmp_path / "bad")
    assert not (tmp_path / "bad").exists()                        # nothing half-written
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".bad")]


def test_cli_reports_one_line_and_writes_nothing(tmp_path, capsys):
    from pipeline.cli import main

    d = _make(tmp_path, runs=RUNS.replace(",80,", ",eighty,"))
    rc = main(["diagnose", str(d), "--out", str(tmp_path / "out"), "--no-mlflow", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "column 'frequency_hz'" in err
    assert not (tmp_path / "out").exists()
