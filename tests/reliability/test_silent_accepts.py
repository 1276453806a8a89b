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


CASES: dict[str, tuple[Callable[[Path], list[str]], tuple[str, ...]]] = {
    "rig K1: true": (_rig_bool, ("rig.yaml", "parameter 'K1'", "must be a number")),
    "rig effect value false": (_rig_effect_bool, ("rig.yaml", "effect 'shaker_coil' parameter 'beta'")),
    "rig effect {}": (_rig_empty_effect, ("rig.yaml", "effect 'shaker_coil' gives no parameters")),
    "params sweep.fixed K1: true": (_params_bool, ("sweep.fixed.K1", "must be a number")),
    "params optimise.fixed K1: true": (_optimise_params_bool, ("optimise.fixed.K1", "expected a number")),
    "optimise --vary frequency_hz=0:400": (_optimise_zero_hz, ("range 'frequency_hz'", "low bound 0", "> 0")),
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
