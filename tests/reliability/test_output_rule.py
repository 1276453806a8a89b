"""The output rule's corpus: every path a command writes (folder or single file) never costs the user a file.

Each case sets up a victim (measured data, a sweep, an optuna database, a user's figure or notes, a device node),
runs one command that would have written over it, and asserts exit 2, one error line naming the path, and every
file under the test folder byte for byte as it was (pipeline.core.outdir: check_out / check_out_file).
"""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import pytest

from pipeline.core.outdir import MARKER_NAME, check_out_file, record_out_file, written_by_vibro
from pipeline.core.errors import UserError
from tests.reliability.test_bad_inputs import _dataset, _parquet_dataset, _snapshot, run_cli

NO_ML = "--no-mlflow"


def _user_file(path: Path, text: str = "precious") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def _png(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x89PNG\r\n\x1a\n the user's own figure")


def _optimise_report(d: Path, marker: bool = True, tried: bool = True) -> None:
    d.mkdir(parents=True, exist_ok=True)
    doc = {"inputs": ["frequency_hz"], "recommendation": {"params": {"frequency_hz": 200.0}}}
    if tried:
        doc["tried"] = {"model": "drill", "preset": "lab", "fixed": {}}
    (d / "report.json").write_text(json.dumps(doc))
    if marker:
        (d / MARKER_NAME).write_text(json.dumps({"command": "optimise", "files": ["report.json"]}))


def _compare_inputs(t: Path, tried: bool = True) -> None:
    _optimise_report(t / "unc", tried=tried)
    _optimise_report(t / "cor")
    (t / "rig.yaml").write_text("model: drill\npreset: lab\n")


def _sweep_chunk(t: Path) -> None:
    (t / "pts.csv").write_text("frequency_hz\n200\n")
    _parquet_dataset((t / "sw").mkdir() or t / "sw" / "part-00000.parquet")


def _failed_rows(path: Path) -> None:
    import pandas as pd

    pd.DataFrame({"point_id": range(8), "frequency_hz": [100.0 + i for i in range(8)], "status": "failed",
                  "rop_m_s": float("nan")}).to_parquet(path)


SETUPS = {
    "dataset": lambda t: _dataset(t / "ds"),
    "parquet": lambda t: _parquet_dataset(t / "d.parquet"),
    "failed_rows": lambda t: _failed_rows(t / "d.parquet"),
    "optuna_db": lambda t: (t / "s.db").write_bytes(b"SQLite format 3\x00 a study"),
    "notes": lambda t: _user_file(t / "notes.txt"),
    "truth_dir": lambda t: (t / "tdir").mkdir(),
    "user_png": lambda t: _png(t / "fig.png"),
    "user_text_png": lambda t: _user_file(t / "fig.png"),
    "map_user_png": lambda t: _png(t / "thesis.png"),
    "compare": lambda t: _compare_inputs(t),
    "compare_out_optimise": lambda t: (_compare_inputs(t), _optimise_report(t / "other")),
    "compare_no_tried": lambda t: _compare_inputs(t, tried=False),
    "sweep_chunk": _sweep_chunk,
    "sweep_user_folder": lambda t: (_user_file(t / "u" / "thesis.tex"), _user_file(t / "u" / ".part-mine")),
    "sweep_user_metadata": lambda t: _user_file(t / "s" / "metadata.json", '{"mine": 1}'),
    "cwd_user_file": lambda t: _user_file(t / "thesis.tex"),
}

# (id, argv (str with {t}, or a list), set-up, fragment of the one error line)
CASES = [
    # --- item 1: single-file outputs -------------------------------------------------------------------
    ("diagnose-metrics-is-measured-data", "diagnose {t}/ds --out {t}/d --metrics {t}/ds/runs.csv " + NO_ML,
     "dataset", "lies inside the input"),
    ("train-metrics-is-dataset", "train {t}/d.parquet --model drill --out {t}/o --metrics {t}/d.parquet " + NO_ML,
     "parquet", "is the input"),
    ("optimise-metrics-is-study-db", "optimise --simulator --n-trials 2 --storage sqlite:///{t}/s.db "
     "--metrics {t}/s.db --out {t}/o " + NO_ML, "optuna_db", "s.db"),
    ("synth-truth-dev-null", "synth --out {t}/o --truth /dev/null", None, "not a regular file"),
    ("synth-truth-user-notes", "synth --out {t}/o --truth {t}/notes.txt", "notes", "did not write"),
    ("synth-truth-is-directory", "synth --out {t}/o --truth {t}/tdir", "truth_dir", "is a directory"),
    ("synth-truth-inside-out", "synth --out {t}/o --truth {t}/o/truth.json", None, "truth.json"),
    ("simulate-plot-user-figure", "simulate pendulum --plot {t}/fig.png", "user_png", "did not write"),
    ("simulate-plot-overwrite-not-a-figure", "simulate pendulum --plot {t}/fig.png --overwrite", "user_text_png",
     "not a figure"),
    ("simulate-plot-dev-null", "simulate pendulum --plot /dev/null", None, "not a regular file"),
    ("map-out-user-figure", "map pendulum --x frequency_hz --nx 2 --out {t}/thesis " + NO_ML, "map_user_png",
     "did not write"),
    ("verify-feedback-into-sweep-chunk", "verify {t}/pts.csv --model drill --out {t}/o "
     "--feedback {t}/sw/part-00000.parquet " + NO_ML, "sweep_chunk", "not a vibro feedback"),
    ("verify-metrics-is-points", "verify {t}/pts.csv --model drill --out {t}/o --metrics {t}/pts.csv " + NO_ML,
     "sweep_chunk", "is the input"),
    ("sweep-metrics-inside-dataset", "sweep --out {t}/sw --n-points 2 --metrics {t}/sw/metadata.json --dry-run",
     None, "lies inside"),
    ("sweep-plot-user-figure", "sweep --out {t}/sw --n-points 2 --plot {t}/fig.png --dry-run", "user_png",
     "did not write"),
    # --- item 1: folders -------------------------------------------------------------------------------
    ("compare-out-is-an-optimise-output", "compare --uncorrected {t}/unc --corrected {t}/cor --rig {t}/rig.yaml "
     "--out {t}/other " + NO_ML, "compare_out_optimise", "vibro optimise"),
    ("compare-out-is-its-input", "compare --uncorrected {t}/unc --corrected {t}/cor --rig {t}/rig.yaml "
     "--out {t}/unc " + NO_ML, "compare", "is the input"),
    ("compare-metrics-is-a-report", "compare --uncorrected {t}/unc --corrected {t}/cor --rig {t}/rig.yaml "
     "--out {t}/c --metrics {t}/cor/report.json " + NO_ML, "compare", "lies inside"),
    ("sweep-user-folder", "sweep --out {t}/u --n-points 2 " + NO_ML, "sweep_user_folder", "did not write"),
    ("sweep-overwrite-user-metadata", "sweep --out {t}/s --n-points 2 --overwrite " + NO_ML, "sweep_user_metadata",
     "metadata.json"),
    ("sweep-out-empty-string", ["sweep", "--out", "", "--n-points", "2", NO_ML], "cwd_user_file", "--out is empty"),
    # --- items 5 and 7: the user's errors, one clear line -----------------------------------------------
    ("plot-bad-extension", "simulate pendulum --plot {t}/x.xyz", None, "not a figure format"),
    ("train-adaptive-batch-over-budget", "train {t}/d.parquet --model drill --out {t}/o --adaptive --initial 16 --batch 1000 "
     "--budget 100 " + NO_ML, "parquet", "--budget"),
    ("train-every-row-failed", "train {t}/d.parquet --model drill --out {t}/o " + NO_ML, "failed_rows", "failed"),
    ("compare-report-without-tried", "compare --uncorrected {t}/unc --corrected {t}/cor --rig {t}/rig.yaml "
     "--out {t}/c " + NO_ML, "compare_no_tried", "tried"),
    ("synth-impossible-record-size", "synth --out {t}/o --frequencies 1e-5", None, "--frequencies"),
    ("min-transient-over-default-max", "simulate drill --setting min_transient=500", None, "min_transient"),
    ("rig-file-is-a-directory", "simulate --rig {t}/tdir", "truth_dir", "tdir"),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_output_rule(case, tmp_path, capsys, monkeypatch):
    name, argv, setup, fragment = case
    monkeypatch.chdir(tmp_path)
    if setup:
        SETUPS[setup](tmp_path)
    before = _snapshot(tmp_path)
    argv = argv.format(t=tmp_path).split() if isinstance(argv, str) else argv
    rc, err = run_cli(argv, capsys)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1 and "error:" in lines[0] and "internal error" not in lines[0], err
    assert fragment in lines[0], err
    after = _snapshot(tmp_path)
    assert {k: v for k, v in after.items() if not k.startswith("mlruns")} == before, "files changed or left behind"
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


# ------------------------------------------------------------------------- the rule's own promises
def test_rerun_replaces_its_own_file_and_refuses_an_edited_one(tmp_path):
    f = tmp_path / "m.json"
    check_out_file(f, flag="--metrics", kind="json")
    f.write_text('{"a": 1}')
    record_out_file(f, command="train", kind="json")
    assert written_by_vibro(f)
    check_out_file(f, flag="--metrics", kind="json")                  # our own: no --overwrite needed
    f.write_text('{"a": 2}')                                            # the user edited it since
    with pytest.raises(UserError, match="did not write"):
        check_out_file(f, flag="--metrics", kind="json")
    check_out_file(f, flag="--metrics", kind="json", overwrite=True)  # JSON: the kind --metrics writes


def test_symlink_to_an_input_is_the_input(tmp_path):
    data = tmp_path / "runs.csv"
    data.write_text("a\n1\n")
    (tmp_path / "link.json").symlink_to(data)
    with pytest.raises(UserError, match="is the input"):
        check_out_file(tmp_path / "link.json", flag="--metrics", kind="json", inputs=[data], overwrite=True)


def test_feedback_appends_only_to_a_feedback_file(tmp_path):
    import pandas as pd

    fb = tmp_path / "fb.parquet"
    pd.DataFrame({"point_id": [0], "source": ["verify"], "study": ["s"], "created": ["now"]}).to_parquet(fb)
    check_out_file(fb, flag="--feedback", kind="feedback")
    pd.DataFrame({"point_id": [0]}).to_parquet(fb)
    with pytest.raises(UserError, match="feedback"):
        check_out_file(fb, flag="--feedback", kind="feedback", overwrite=True)


def test_stale_temporaries_of_a_dead_writer_are_cleaned(tmp_path):
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    f = tmp_path / "m.json"
    stale_file = tmp_path / f".m.json.{dead}-abc123.tmp"
    stale_file.write_text("half")
    live = tmp_path / f".m.json.{os.getpid()}-def456.tmp"         # a writer still alive: never touched
    live.write_text("busy")
    user = tmp_path / ".m.json.mine.tmp"                            # not our naming: never touched
    user.write_text("mine")
    check_out_file(f, flag="--metrics", kind="json")
    assert not stale_file.exists() and live.exists() and user.exists()

    from pipeline.core.outdir import prepare_out

    out = tmp_path / "out"
    stale_dir = tmp_path / f".out.{dead}-xyz789.tmp"
    stale_dir.mkdir()
    (stale_dir / "report.md").write_text("half")
    with prepare_out(out, marker="report") as tmp:
        (tmp / "report.md").write_text("x")
    assert not stale_dir.exists() and (out / "report.md").read_text() == "x"


def test_interrupted_swap_puts_the_previous_folder_back(tmp_path):
    import subprocess
    import sys

    from vibrobase.files import clean_stale_temps

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    old = tmp_path / f".out.old-{dead}"
    old.mkdir()
    (old / "report.md").write_text("previous")
    clean_stale_temps(tmp_path / "out")
    assert (tmp_path / "out" / "report.md").read_text() == "previous" and not old.exists()


def test_plot_without_suffix_says_where_it_went(tmp_path, capsys):
    from pipeline.cli import main

    rc = main(["simulate", "pendulum", "--plot", str(tmp_path / "out")])
    assert rc == 0 and (tmp_path / "out.png").is_file()
    assert f"plot saved to {tmp_path / 'out.png'}" in capsys.readouterr().out
    assert main(["simulate", "pendulum", "--plot", str(tmp_path / "out.png")]) == 0    # a rerun: its own file
