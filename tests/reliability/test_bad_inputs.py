"""The bad-input corpus: every user mistake exits 2 with one line naming the culprit,
writes nothing and deletes nothing.

Two parts: hand-written cases (the adversarial run's findings, one per file format, the output-folder rules),
and generated cases, one per argument of every subcommand (read from the parser itself, so a renamed or new flag
is covered without editing this file).  ``python -m tests.reliability.corpus_summary`` prints the counts
docs/reliability.md quotes.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from pipeline.cli import build_parser, main

# ----------------------------------------------------------------------------------- file set-ups
PARAMS_LIST = "- a\n- b\n"


def _dataset(root: Path, zeros: bool = False) -> Path:
    """A small measured dataset (MODELS.md §7, summary only); ``zeros``: every feature 0."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "runs.csv").write_text(
        "run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s,pressure_bar\n"
        + "".join(f"m{f},indenter-metal,{f},{300 + 5 * f},198.9512,0.001,0.05,1.0\n" for f in (40, 60, 80)))
    v = (0, 0) if zeros else (15.7, 6)
    (root / "summary.csv").write_text("run_id,peak_decel_g,impacts_per_cycle\n"
                                      + "".join(f"m{f},{v[0]},{v[1]}\n" for f in (40, 60, 80)))
    return root


def _user_files(d: Path) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "thesis.tex").write_text("precious")
    return d


def _bundle_dir(d: Path, corrupt: str) -> Path:
    d.mkdir(parents=True)
    if corrupt == "garbage":
        (d / "bundle.skops").write_bytes(b"not a zip")
    elif corrupt == "manifest":
        (d / "bundle.skops").write_bytes(b"x")
        (d / "manifest.json").write_text("{not json")
    return d


def _sweep_with_foreign_part(d: Path) -> Path:
    import pandas as pd

    d.mkdir(parents=True)
    pd.DataFrame({"a": [1.0]}).to_parquet(d / "part-00000.parquet")     # no vibro fingerprint: the user's file
    return d


def _parquet_dataset(path: Path) -> Path:
    import pandas as pd

    pd.DataFrame({"point_id": range(8), "frequency_hz": [100.0 + i for i in range(8)], "status": "ok",
                  "rop_m_s": 1e-3}).to_parquet(path)
    return path


SETUPS = {
    "params_list": lambda t: (t / "p.yaml").write_text(PARAMS_LIST),
    "params_bad_yaml": lambda t: (t / "p.yaml").write_text("sweep: [unclosed\n"),
    "params_nan_window": lambda t: (t / "p.yaml").write_text("sweep:\n  settings: {window: .nan}\n"),
    "params_big_npoints": lambda t: (t / "p.yaml").write_text("sweep:\n  n_points: 1.0e12\n"),
    "params_opt_str": lambda t: (t / "p.yaml").write_text("optimise:\n  n_trials: many\n"),
    "params_diag_str": lambda t: (t / "p.yaml").write_text("diagnose:\n  max_nfev: lots\n"),
    "params_diag_settings": lambda t: (t / "p.yaml").write_text("diagnose:\n  sim_settings: {window: 2.5}\n"),
    "params_report_list": lambda t: (t / "p.yaml").write_text("report: [1, 2]\n"),
    "corrupt_parquet": lambda t: (t / "d.parquet").write_bytes(b"PAR1 this is not parquet"),
    "corrupt_csv": lambda t: (t / "pts.csv").write_bytes(b"\x00\xff\xfe garbage\n\x00\x00"),
    "empty_csv": lambda t: (t / "pts.csv").write_text(""),
    "dup_csv": lambda t: (t / "pts.csv").write_text("frequency_hz,frequency_hz\n100,120\n"),
    "corrupt_json_metrics": lambda t: (t / "metrics").mkdir(),
    "dataset": lambda t: _dataset(t / "ds"),
    "dataset_zeros": lambda t: _dataset(t / "ds", zeros=True),
    "dataset_dup_col": lambda t: (_dataset(t / "ds"), (t / "ds" / "summary.csv").write_text(
        "run_id,peak_decel_g,peak_decel_g\nm40,1,2\nm60,1,2\nm80,1,2\n")),
    "dataset_in_out": lambda t: _dataset(t / "parent" / "ds"),
    "user_out": lambda t: (_dataset(t / "ds"), _user_files(t / "out")),
    "synth_over_dataset": lambda t: (_dataset(t / "ds"), _user_files(t / "ds")),
    "report_figures": lambda t: (t / "rep" / "figures").mkdir(parents=True) or (t / "rep" / "figures" / "mine.png").write_bytes(b"x"),
    "bundle_garbage": lambda t: _bundle_dir(t / "b", "garbage"),
    "bundle_manifest": lambda t: _bundle_dir(t / "b", "manifest"),
    "surrogate_file": lambda t: (t / "b.txt").write_text("not a bundle"),
    "sweep_foreign": lambda t: _sweep_with_foreign_part(t / "sw"),
    "file_as_out": lambda t: (t / "afile").write_text("x"),
    "points_and_bad_manifest": lambda t: ((t / "pts.csv").write_text("frequency_hz\n100\n"), _bundle_dir(t / "b", "manifest")),
    "points_and_user_out": lambda t: ((t / "pts.csv").write_text("frequency_hz\n100\n"), _user_files(t / "out")),
    "parquet_and_user_out": lambda t: (_parquet_dataset(t / "d.parquet"), _user_files(t / "out")),
}

# (id, argv with {t} = the test's folder, set-up or None, fragment the one-line error must contain)
NO_ML = "--no-mlflow"
CASES = [
    # --- the adversarial run's findings --------------------------------------------------------------------
    ("diagnose-out-holds-user-files", "diagnose {t}/ds --out {t}/out " + NO_ML, "user_out", "did not write"),
    ("diagnose-out-is-dataset-parent", "diagnose {t}/parent/ds --out {t}/parent " + NO_ML, "dataset_in_out", "contains the input"),
    ("diagnose-out-is-dataset", "diagnose {t}/ds --out {t}/ds " + NO_ML, "dataset", "is the input"),
    ("synth-out-on-dataset-with-user-files", "synth --out {t}/ds", "synth_over_dataset", "did not write"),
    ("report-out-holds-figures", "report --out {t}/rep " + NO_ML, "report_figures", "did not write"),
    ("sweep-overwrite-foreign-part", "sweep --out {t}/sw --overwrite --n-points 2 " + NO_ML, "sweep_foreign", "did not write"),
    ("setting-window-nan", "simulate drill --setting window=nan", None, "--setting window"),
    ("setting-window-2.7", "simulate drill --setting window=2.7", None, "must be an integer"),
    ("setting-min-transient-1e8", "simulate drill --setting min_transient=1e8", None, "--setting min_transient"),
    ("setting-unknown", "simulate drill --setting windw=3", None, "windw"),
    ("sweep-setting-window-nan", "sweep --out {t}/o --setting window=nan --dry-run", None, "--setting window"),
    ("map-setting-window-2.7", "map pendulum --x frequency_hz --nx 3 --setting window=2.7", None, "--setting window"),
    ("params-top-level-list", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_list", "p.yaml"),
    ("params-bad-yaml", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_bad_yaml", "p.yaml"),
    ("params-window-nan", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_nan_window", "settings window"),
    ("params-n-points-1e12", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_big_npoints", "n_points"),
    ("params-optimise-str", "optimise --simulator --params {t}/p.yaml --out {t}/o " + NO_ML, "params_opt_str", "n_trials"),
    ("params-diagnose-str", "diagnose {t}/ds --params {t}/p.yaml --out {t}/o " + NO_ML, "params_diag_str", "max_nfev"),
    ("params-diagnose-settings", "diagnose {t}/ds --params {t}/p.yaml --out {t}/o " + NO_ML, "params_diag_settings", "window"),
    ("params-report-list", "report --params {t}/p.yaml --out {t}/o " + NO_ML, "params_report_list", "report"),
    ("corrupt-parquet-train", "train {t}/d.parquet --out {t}/o " + NO_ML, "corrupt_parquet", "d.parquet"),
    ("diagnose-set-max-nfev-inf", "diagnose {t}/ds --out {t}/o --set max_nfev=inf " + NO_ML, "dataset", "max_nfev"),
    ("diagnose-set-max-nfev-2.5", "diagnose {t}/ds --out {t}/o --set max_nfev=2.5 " + NO_ML, "dataset", "max_nfev"),
    ("sweep-n-points-1e12", "sweep --out {t}/o --n-points 1000000000000 --dry-run", None, "--n-points"),
    ("sweep-n-points-float", "sweep --out {t}/o --n-points 1e12 --dry-run", None, "--n-points"),
    ("train-threads-0", "train {t}/d.parquet --out {t}/o --threads 0 " + NO_ML, None, "--threads"),
    ("synth-noise-accel-negative", "synth --out {t}/o --noise-accel -0.1", None, "--noise-accel"),
    ("report-params-missing", "report --params {t}/nothere.yaml --out {t}/o " + NO_ML, None, "nothere.yaml"),
    ("report-surrogate-garbage", "report --surrogate {t}/b --out {t}/o " + NO_ML, "bundle_garbage", "b"),
    ("report-surrogate-bad-manifest", "report --surrogate {t}/b --out {t}/o " + NO_ML, "bundle_manifest", "manifest.json"),
    ("report-surrogate-file", "report --surrogate {t}/b.txt --out {t}/o " + NO_ML, "surrogate_file", "b.txt"),
    ("diagnose-all-zero-features", "diagnose {t}/ds --out {t}/o " + NO_ML, "dataset_zeros", "summary.csv"),
    ("diagnose-duplicated-csv-column", "diagnose {t}/ds --out {t}/o " + NO_ML, "dataset_dup_col", "peak_decel_g"),
    ("verify-duplicated-csv-column", "verify {t}/pts.csv --out {t}/o " + NO_ML, "dup_csv", "frequency_hz"),
    # --- one corrupt file per format the project reads ------------------------------------------------------
    ("corrupt-yaml", "diagnose {t}/ds --params {t}/p.yaml --out {t}/o " + NO_ML, "params_bad_yaml", "p.yaml"),
    ("corrupt-csv-points", "verify {t}/pts.csv --out {t}/o " + NO_ML, "corrupt_csv", "pts.csv"),
    ("empty-csv-points", "verify {t}/pts.csv --out {t}/o " + NO_ML, "empty_csv", "pts.csv"),
    ("corrupt-parquet-points", "verify {t}/d.parquet --out {t}/o " + NO_ML, "corrupt_parquet", "d.parquet"),
    ("corrupt-json-manifest", "verify {t}/pts.csv --surrogate {t}/b --out {t}/o " + NO_ML, "points_and_bad_manifest", "manifest.json"),
    ("corrupt-bundle-payload", "optimise --surrogate {t}/b --out {t}/o " + NO_ML, "bundle_garbage", "b"),
    # --- output folders -----------------------------------------------------------------------------------
    ("out-is-a-file", "synth --out {t}/afile", "file_as_out", "afile"),
    ("train-out-holds-user-files", "train {t}/d.parquet --model drill --out {t}/out " + NO_ML, "parquet_and_user_out", "did not write"),
    ("verify-out-holds-user-files", "verify {t}/pts.csv --out {t}/out " + NO_ML, "points_and_user_out", "did not write"),
    ("optimise-out-holds-user-files", "optimise --simulator --n-trials 2 --out {t}/out " + NO_ML, "user_out", "did not write"),
]


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else b"<dir>") for p in sorted(root.rglob("*"))}


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    try:
        rc = main(argv)
    except SystemExit as e:            # argparse: usage line + "error: argument --x: ..."
        rc = e.code
    err = capsys.readouterr().err
    return rc, err


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_input(case, tmp_path, capsys, monkeypatch):
    name, argv, setup, fragment = case
    monkeypatch.chdir(tmp_path)                 # nothing lands in the repository (default --out folders)
    if setup:
        SETUPS[setup](tmp_path)
    before = _snapshot(tmp_path)
    rc, err = run_cli(argv.format(t=tmp_path).split(), capsys)
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("usage:") and not ln.startswith(" ")]
    assert rc == 2, err
    assert len(lines) == 1 and "error" in lines[0] and "internal error" not in lines[0], err
    assert fragment in lines[0], err
    after = _snapshot(tmp_path)
    assert {k: v for k, v in after.items() if not k.startswith("mlruns")} == before, "files changed or left behind"


# --------------------------------------------------------------------- one generated case per argument
def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _bad_value(action: argparse.Action) -> list[str] | None:
    """argv fragment giving this argument a value it must refuse (None: no generic bad value)."""
    flag = action.option_strings[-1] if action.option_strings else None
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        return [f"{flag}=yes"]
    if action.choices is not None:
        return ([flag] if flag else []) + ["no-such-choice"] * (action.nargs if isinstance(action.nargs, int) else 1)
    if action.type is not None and flag:
        return [flag] + ["nan"] * (action.nargs if isinstance(action.nargs, int) else 1)
    if flag and action.nargs is None:
        return [flag]                              # a flag that needs a value, given none
    return None


def generated_cases() -> list[tuple[str, list[str], str]]:
    out = []
    for cmd, p in _subparsers().items():
        for a in p._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            bad = _bad_value(a)
            if bad is None:
                continue
            culprit = a.option_strings[-1] if a.option_strings else a.dest
            out.append((f"{cmd}{culprit if culprit.startswith('-') else ':' + culprit}", [cmd, *bad], culprit))
    return out


GENERATED = generated_cases()


@pytest.mark.parametrize("case", GENERATED, ids=[c[0] for c in GENERATED])
def test_every_argument_refuses_a_bad_value(case, capsys, tmp_path, monkeypatch):
    name, argv, culprit = case
    monkeypatch.chdir(tmp_path)
    rc, err = run_cli(argv, capsys)
    assert rc == 2, err
    last = [ln for ln in err.splitlines() if ln.strip()][-1]
    assert "error:" in last and culprit.lstrip("-") in last, err
    assert not list(tmp_path.iterdir()), "a refused command wrote something"


def test_every_subcommand_has_generated_cases():
    """A subcommand whose arguments yield no generated case would be untested by the loop above."""
    per = {c[0].split("-")[0].split(":")[0] for c in GENERATED}
    assert set(_subparsers()) - {"models"} <= per


def test_internal_error_is_one_line_and_traceback_only_with_debug(capsys, monkeypatch):
    """A bug (not a user mistake) is exit 1 with one line; --debug shows the traceback."""
    import pipeline.cli.models as models_cmd

    def boom(args):
        raise RuntimeError("a bug")

    monkeypatch.setattr(models_cmd, "run", boom)
    parser_rc, err = run_cli(["models"], capsys)
    assert parser_rc == 1 and "internal error: RuntimeError: a bug" in err and "Traceback" not in err
    with pytest.raises(RuntimeError):
        main(["--debug", "models"])


def test_corpus_size():
    """docs/reliability.md quotes these numbers (tests/reliability/corpus_summary.py)."""
    assert len(CASES) >= 40 and len(GENERATED) >= 60
