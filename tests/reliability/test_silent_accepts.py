"""Silent accepts: inputs that used to run as if they meant something else now end in exit 2 and one line
naming the culprit (the key, the range, the file, row and column), and write nothing."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest

from pipeline.cli import main


@pytest.fixture(autouse=True)
def _no_mlflow(monkeypatch):
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")


def _one_line_exit_2(rc: int, err: str, *words: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


# ----------------------------------------------------------------------------- settings files
def _rig_bool(d: Path) -> list[str]:
    rig = _write(d / "rig.yaml", "model: drill\npreset: lab\nparameters: {K1: true}\n")
    return ["simulate", "--rig", str(rig), "--set", "frequency_hz=200"]


def _rig_effect_bool(d: Path) -> list[str]:
    rig = _write(d / "rig.yaml", "model: drill\npreset: lab\neffects:\n  shaker_coil: {tau: 1.0e-4, beta: false}\n")
    return ["sweep", "--rig", str(rig), "--vary", "frequency_hz=100:200", "--n-points", "2", "--out", str(d / "out")]


def _rig_empty_effect(d: Path) -> list[str]:
    rig = _write(d / "rig.yaml", "model: drill\npreset: lab\neffects:\n  shaker_coil: {}\n")
    return ["sweep", "--rig", str(rig), "--vary", "frequency_hz=100:200", "--n-points", "2", "--out", str(d / "out")]


def _params_bool(d: Path) -> list[str]:
    p = _write(d / "params.yaml", "sweep:\n  model: drill\n  preset: lab\n  fixed: {K1: true}\n"
                                  "  vary: {frequency_hz: {low: 100, high: 200}}\n  n_points: 2\n")
    return ["sweep", "--params", str(p), "--out", str(d / "out")]


def _optimise_params_bool(d: Path) -> list[str]:
    p = _write(d / "params.yaml", "optimise:\n  fixed: {K1: true}\n")
    return ["optimise", "--params", str(p), "--simulator", "--model", "drill", "--preset", "lab", "--n-trials", "1",
            "--out", str(d / "out"), "--storage", f"sqlite:///{d / 'out.db'}", "--no-mlflow", "--quiet"]


def _optimise_zero_hz(d: Path) -> list[str]:
    return ["optimise", "--simulator", "--model", "drill", "--preset", "lab", "--vary", "frequency_hz=0:400",
            "--n-trials", "1", "--out", str(d / "out"), "--storage", f"sqlite:///{d / 'out.db'}", "--no-mlflow",
            "--quiet"]


# ----------------------------------------------------------------------------- measured data
def _duration_disagrees(d: Path) -> list[str]:
    """runs.csv says 0.5 s, its series holds 0.05 s (500 samples at 10 kHz)."""
    import numpy as np

    ds = d / "data"
    (ds / "series").mkdir(parents=True)
    _write(ds / "runs.csv", "run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s,preset\n"
                            "d1,drill,200,2250,1200,0,0.05,lab\nd2,drill,250,2250,1200,0,0.5,lab\n")
    t = np.arange(500) / 1e4
    for rid, f in (("d1", 200.0), ("d2", 250.0)):
        _write(ds / "series" / f"{rid}.csv", "t_s,accel_m_s2\n" + "".join(
            f"{x:.6g},{np.sin(2 * np.pi * f * x):.6g}\n" for x in t))
    return ["diagnose", str(ds), "--out", str(d / "out"), "--quiet", "--no-mlflow"]


# ----------------------------------------------------------------------------- training sets
def _training_set(d: Path, column: str | None = None, value: float = 0.0) -> Path:
    """A bare 12-row training table of the drill (no metadata: every row's own values), row 5 of ``column``
    set to ``value``."""
    import numpy as np
    import pandas as pd

    n = 12
    f = np.linspace(150.0, 450.0, n)
    df = pd.DataFrame({"point_id": np.arange(n), "frequency_hz": f, "amplitude_n": np.linspace(1800.0, 2700.0, n),
                       "rop_m_s": 1e-5 * f, "peak_force_n": 10.0 * f, "impacts_per_cycle": np.ones(n),
                       "specific_energy_j_m": 1e5 + f, "status": ["ok"] * n, "reason": [""] * n})
    if column is not None:
        df.loc[5, column] = value
    path = d / "points.parquet"
    df.to_parquet(path)
    return path


def _train(d: Path, path: Path, inputs: str = "frequency_hz,amplitude_n") -> list[str]:
    return ["train", str(path), "--model", "drill", "--inputs", inputs, "--out", str(d / "out"), "--no-mlflow",
            "--quiet"]


CASES: dict[str, tuple[Callable[[Path], list[str]], tuple[str, ...]]] = {
    "rig K1: true": (_rig_bool, ("rig.yaml", "parameter 'K1'", "must be a number")),
    "rig effect value false": (_rig_effect_bool, ("rig.yaml", "effect 'shaker_coil' parameter 'beta'")),
    "rig effect {}": (_rig_empty_effect, ("rig.yaml", "effect 'shaker_coil' gives no parameters")),
    "params sweep.fixed K1: true": (_params_bool, ("sweep.fixed.K1", "must be a number")),
    "params optimise.fixed K1: true": (_optimise_params_bool, ("optimise.fixed.K1", "must be a number")),
    "optimise --vary frequency_hz=0:400": (_optimise_zero_hz, ("range 'frequency_hz'", "low bound 0", "> 0")),
    "train on a label as input": (lambda d: _train(d, _training_set(d), "frequency_hz,rop_m_s"),
                                  ("input 'rop_m_s' is a label",)),
    "train input inf Hz": (lambda d: _train(d, _training_set(d, "frequency_hz", float("inf"))),
                                       ("column 'frequency_hz', row 5 (point_id 5)", "not a finite number")),
    "train input 0 Hz": (lambda d: _train(d, _training_set(d, "frequency_hz", 0.0)),
                         ("column 'frequency_hz', row 5", "must be > 0")),
    "train negative label": (lambda d: _train(d, _training_set(d, "peak_force_n", -3.0)),
                             ("column 'peak_force_n', row 5", "negative")),
    "train infinite label": (lambda d: _train(d, _training_set(d, "rop_m_s", float("inf"))),
                             ("column 'rop_m_s', row 5", "infinite")),
    "duration_s against its series": (_duration_disagrees, ("runs.csv line 3, column 'duration_s'", "series/d2.csv",
                                                            "500 samples")),
}


@pytest.mark.parametrize("case", list(CASES))
def test_silent_accept_is_one_line_exit_2_writing_nothing(tmp_path, capsys, case):
    make, words = CASES[case]
    argv = make(tmp_path)
    inputs = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    rc = main(argv)
    _one_line_exit_2(rc, capsys.readouterr().err, *words)
    after = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    assert after == inputs                          # nothing written, nothing changed


def test_rows_outside_the_declared_space_are_refused_before_ranges():
    """A sweep's row at 1e300 Hz (its metadata declares 100..450 Hz) never reaches the trained range."""
    import pandas as pd

    from pipeline.core.errors import UserError
    from pipeline.training.rows import check_inputs

    df = pd.DataFrame({"point_id": [0, 1, 2], "frequency_hz": [153.0, 1e300, 400.0]})
    meta = {"vary": {"frequency_hz": {"low": 100.0, "high": 450.0}}}
    check_inputs(df.iloc[[0, 2]], ["frequency_hz"], meta, "drill", "sweep")
    with pytest.raises(UserError, match=r"column 'frequency_hz', row 1 \(point_id 1\): 1e\+300 is outside the "
                                        r"sweep's declared range \[100, 450\]"):
        check_inputs(df, ["frequency_hz"], meta, "drill", "sweep")


def test_infinite_specific_energy_without_progress_is_a_label_the_simulator_writes():
    import pandas as pd

    from pipeline.core.errors import UserError
    from pipeline.training.rows import check_labels

    df = pd.DataFrame({"rop_m_s": [0.0, 2e-3], "specific_energy_j_m": [float("inf"), 5e5]})
    check_labels(df, "sweep")
    df.loc[1, "specific_energy_j_m"] = float("inf")
    with pytest.raises(UserError, match="column 'specific_energy_j_m', row 1: inf is infinite"):
        check_labels(df, "sweep")


def test_sweep_plot_skipped_says_why_in_one_line(tmp_path, capsys):
    """--plot with one varied parameter: the sweep runs, no figure is written, and one line says why."""
    out, png = tmp_path / "s", tmp_path / "s.png"
    rc = main(["sweep", "--model", "drill", "--preset", "lab", "--vary", "frequency_hz=100:200", "--n-points", "2",
               "--out", str(out), "--plot", str(png), "--no-mlflow", "--quiet"])
    assert rc == 0 and not png.exists() and list(out.glob("part-*.parquet"))
    lines = [ln for ln in capsys.readouterr().out.splitlines() if "overview figure" in ln]
    assert lines == [f"no overview figure written to {png}: it needs two varied parameters, this sweep varies "
                     "only frequency_hz"]


def test_a_far_outlier_is_refused_without_a_declared_range():
    """A bare training file (no sweep metadata): a row at 1e300 Hz among 150..450 Hz is refused by name, and a
    design's ordinary spread (log-spaced over a decade) passes."""
    import numpy as np
    import pandas as pd

    from pipeline.core.errors import UserError
    from pipeline.training.rows import check_inputs

    f = list(np.linspace(150.0, 450.0, 12))
    check_inputs(pd.DataFrame({"frequency_hz": f, "static_force_n": np.geomspace(100.0, 1e4, 12)}),
                 ["frequency_hz", "static_force_n"], {}, "drill", "data.parquet")
    bad = pd.DataFrame({"point_id": range(13), "frequency_hz": f[:6] + [1e300] + f[6:]})
    with pytest.raises(UserError, match=r"column 'frequency_hz', row 6 \(point_id 6\): 1e\+300 lies 100 "
                                        r"interquartile ranges outside"):
        check_inputs(bad, ["frequency_hz"], {}, "drill", "data.parquet")
