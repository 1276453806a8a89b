"""Out-of-range warnings: a value outside the range the model or preset was validated on draws one stderr line that
names the likely mistake, and the run goes on; a value that cannot be is an error (exit 2, one line)."""
from __future__ import annotations

import pytest

from pipeline.cli import main

QUICK = ["--setting", "min_transient=2", "--setting", "max_transient=4", "--setting", "window=2"]
KHZ = "frequency_hz 0.3 is outside 100–450 Hz of preset lab: kHz?"


def _warnings(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ": warning: " in ln]


def test_simulate_warns_and_runs(capsys):
    assert main(["simulate", "drill", "--preset", "lab", "--set", "frequency_hz=0.3", *QUICK]) == 0
    out, err = capsys.readouterr()
    assert _warnings(err) == [f"vibro simulate: warning: {KHZ}"]
    assert "status" in out


def test_simulate_inside_the_range_says_nothing(capsys):
    assert main(["simulate", "drill", "--preset", "lab", "--set", "frequency_hz=300", *QUICK]) == 0
    assert _warnings(capsys.readouterr().err) == []


def test_an_impossible_value_is_one_error_line_not_a_warning(capsys):
    assert main(["simulate", "drill", "--preset", "lab", "--set", "frequency_hz=-0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "must be > 0" in err[0]


@pytest.mark.parametrize("argv, line", [
    (["--vary", "frequency_hz=0.1:0.45"], "frequency_hz 0.1–0.45 is outside 100–450 Hz of preset lab: kHz?"),
    (["--vary", "frequency_hz=100:450", "--set", "static_force_n=1.2"],
     "static_force_n 1.2 is outside 600–1800 N of preset lab: kN?"),
    (["--preset", "none", "--vary", "frequency_hz=10:400"], None),
])
def test_sweep_warns_before_any_work_dry_run_too(tmp_path, capsys, argv, line):
    assert main(["sweep", *argv, "--dry-run", "--out", str(tmp_path / "s")]) == 0
    warned = _warnings(capsys.readouterr().err)
    assert warned == ([] if line is None else [f"vibro sweep: warning: {line}"])
    assert not (tmp_path / "s").exists()


def test_a_rig_file_value_warns_with_the_file(tmp_path, capsys):
    rig = tmp_path / "r.yaml"
    rig.write_text("model: drill\npreset: lab\nparameters: {frequency_hz: 0.3, K1: 6.0e11}\n")
    assert main(["simulate", "--rig", str(rig), *QUICK]) in (0, 1)      # it runs (a rock 1000x too stiff may fail)
    warned = _warnings(capsys.readouterr().err)
    assert warned == [f"vibro simulate: warning: rig file {rig}: {KHZ}",
                      f"vibro simulate: warning: rig file {rig}: K1 6e11 is outside 2e6–6e9 N/m of model drill: "
                      "1000x too large?"]
