"""Hostile inputs on bounds: each case runs the command in a child process under a 4 GB address-space limit
(``resource.setrlimit``) and asserts its exit code, one line naming the culprit (or, for a success, the line it must
print), its peak memory, and that no file outside the test folder's ``out/`` changed (checksums before/after; the
device and working folders it might have written into are watched too).

Covers: memory bounded by design (the simulate plot's history, the sweep's validation of 1e7 points, diagnose's
rows and series samples), output targets (``map --out /dev/null`` or ``user/``, a blank ``--plot``, ``--feedback``
inside another command's output folder), streams given as input files, and exit codes (a ``failed`` simulation is a
result).  ``python -m tests.reliability.corpus_summary`` counts these cases with the rest of the corpus.
"""
from __future__ import annotations

import hashlib
import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LIMIT_AS = 4 * 2**30
"""The address-space limit every case runs under [bytes]."""


def _big_series_dataset(t: Path, mb: int) -> None:
    """One run whose series is about ``mb`` MB of text: one block of increasing times written again and again, so
    the time steps back at each block (refused once read: the whole file is parsed, as the adversarial run's 220 MB
    file was, before its refusal)."""
    ds = t / "ds"
    (ds / "series").mkdir(parents=True)
    block = "".join(f"{i * 1e-4:.7f},0.5\n" for i in range(70_000))
    with open(ds / "series" / "m40.csv", "w") as fh:
        fh.write("t_s,accel_m_s2\n")
        for _ in range(max(1, mb * 2**20 // len(block))):
            fh.write(block)
    (ds / "runs.csv").write_text("run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s\n"
                                 "m40,indenter-metal,40,500,198.9512,0.001,7\n")


def _many_runs(t: Path, n: int) -> None:
    ds = t / "ds"
    ds.mkdir()
    (ds / "runs.csv").write_text(
        "run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s\n"
        + "".join(f"r{i},indenter-metal,{40 + i % 40},500,198.9512,0.001,0.05\n" for i in range(n)))
    (ds / "summary.csv").write_text("run_id,peak_decel_g,impacts_per_cycle\n"
                                    + "".join(f"r{i},15.7,6\n" for i in range(n)))


def _fifo_dataset(t: Path) -> None:
    from tests.reliability.test_bad_inputs import _dataset

    ds = _dataset(t / "ds")
    (ds / "summary.csv").unlink()
    os.mkfifo(ds / "summary.csv")


def _train_output(t: Path) -> None:
    from pipeline.core.outdir import MARKER_NAME

    d = t / "trained"
    d.mkdir()
    (d / "manifest.json").write_text("{}")
    (d / MARKER_NAME).write_text(json.dumps({"command": "train", "files": ["manifest.json"]}))


def _report(t: Path) -> None:
    d = t / "unc"
    d.mkdir()
    (d / "report.json").write_text(json.dumps({"inputs": ["frequency_hz"], "tried": {"model": "drill"}}))


SETUPS = {
    "many_runs": lambda t: _many_runs(t, 100_000),
    "series_20mb": lambda t: _big_series_dataset(t, 20),
    "series_220mb": lambda t: _big_series_dataset(t, 220),
    "fifo_summary": _fifo_dataset,
    "train_output": _train_output,
    "dev_zero_report": _report,
    "user_folder": lambda t: (t / "user").mkdir(),
}

# (id, argv with {t}, set-up or None, exit code, fragment of the one line (stderr for exit 2, stdout for 0),
#  peak RSS bound [MB], marks)
CASES = [
    # --- memory bounded by design -------------------------------------------------------------------------------
    ("simulate-plot-history-capped", "simulate drill --preset lab --setting samples_per_cycle=20000 --setting "
     "window=5000 --plot {t}/out/x.png", None, 0, "samples per cycle instead of 20000", 2500, ()),
    ("sweep-1e7-points-dry-run", "sweep --out {t}/out/sw --n-points 10000000 --dry-run", None, 0,
     "10000000 points", 3500, ("slow",)),
    ("sweep-2e6-points-dry-run", "sweep --out {t}/out/sw --n-points 2000000 --dry-run", None, 0,
     "2000000 points", 1500, ()),
    ("diagnose-100000-runs", "diagnose {t}/ds --out {t}/out/d --no-mlflow", "many_runs", 2,
     "more than the 500", 1500, ()),
    ("diagnose-series-20mb", "diagnose {t}/ds --out {t}/out/d --no-mlflow", "series_20mb", 2,
     "time is not increasing", 900, ()),
    ("diagnose-series-220mb", "diagnose {t}/ds --out {t}/out/d --no-mlflow", "series_220mb", 2,
     "time is not increasing", 1500, ("slow",)),
    # --- output targets -----------------------------------------------------------------------------------------
    ("map-out-dev-null", "map pendulum --x frequency_hz --nx 2 --out /dev/null --no-mlflow", None, 2,
     "--out /dev/null", 1500, ()),
    ("map-out-folder-slash", "map pendulum --x frequency_hz --nx 2 --out {t}/user/ --no-mlflow", "user_folder", 2,
     "names a folder", 1500, ()),
    ("map-out-existing-folder", "map pendulum --x frequency_hz --nx 2 --out {t}/user --no-mlflow", "user_folder", 2,
     "is a folder", 1500, ()),
    ("simulate-plot-blank", ["simulate", "pendulum", "--plot", "   "], None, 2, "--plot is empty", 1500, ()),
    ("simulate-plot-blank-name", ["simulate", "pendulum", "--plot", "{t}/out/   "], None, 2, "--plot", 1500, ()),
    ("sweep-plot-blank", ["sweep", "--out", "{t}/out/sw", "--n-points", "2", "--dry-run", "--plot", "  "], None, 2,
     "--plot is empty", 1500, ()),
    ("optimise-simulator-feedback-in-train-output", "optimise --simulator --n-trials 2 --out {t}/out/o "
     "--feedback {t}/trained/fb.parquet --no-mlflow", "train_output", 2, "output folder of 'vibro train'", 1500, ()),
    ("verify-feedback-in-train-output", "verify {t}/pts.csv --model drill --out {t}/out/v "
     "--feedback {t}/trained/fb.parquet --no-mlflow", "train_output", 2, "output folder of 'vibro train'", 1500, ()),
    # --- streams as input files ---------------------------------------------------------------------------------
    ("diagnose-summary-is-a-fifo", "diagnose {t}/ds --out {t}/out/d --no-mlflow", "fifo_summary", 2,
     "not a regular file", 1500, ()),
    ("verify-points-dev-zero", "verify /dev/zero --model drill --out {t}/out/v --no-mlflow", None, 2,
     "not a regular file", 1500, ()),
    ("compare-report-dev-zero", "compare --uncorrected {t}/unc --corrected /dev/zero --rig {t}/rig.yaml "
     "--out {t}/out/c --no-mlflow", "dev_zero_report", 2, "/dev/zero", 1500, ()),
    # --- values no simulation can honestly label ------------------------------------------------------------------
    ("simulate-frequency-1e9", "simulate drill --set frequency_hz=1e9", None, 2, "--set frequency_hz=1e+09", 1500, ()),
    ("simulate-m1-1e300", "simulate drill --preset lab --set M1=1e300", None, 2, "--set M1=1e+300", 1500, ()),
    ("map-set-ki-1e-300", "map pendulum --x frequency_hz --nx 2 --set ki=1e-300 --out {t}/out/m --no-mlflow", None,
     2, "--set ki=1e-300", 1500, ()),
    # --- exit codes ---------------------------------------------------------------------------------------------
    ("simulate-failed-status-exit-0", "simulate drill --preset lab --setting max_steps=1000", None, 0, "failed",
     1500, ()),
]

WATCHED = ("/dev",)
"""Folders outside the test folder a hostile target could write into: their listing must not change."""


def _checksums(root: Path) -> dict[str, str]:
    out = {}
    for p in sorted(root.rglob("*")):
        rel = str(p.relative_to(root))
        if rel == "out" or rel.startswith("out/"):
            continue
        if p.is_fifo():
            out[rel] = "<fifo>"
        elif p.is_file():
            h = hashlib.sha256()
            with open(p, "rb") as fh:
                for block in iter(lambda: fh.read(2**20), b""):
                    h.update(block)
            out[rel] = h.hexdigest()
        else:
            out[rel] = "<dir>"
    return out


RSS_TAG = "@@peak-rss-kb "
_CHILD = ("import resource, sys\n"
          "resource.setrlimit(resource.RLIMIT_AS, ({lim}, {lim}))\n"
          "from pipeline.cli import main\n"
          "rc = 1\n"
          "try:\n"
          "    rc = main(sys.argv[1:])\n"
          "finally:\n"
          "    hwm = [ln.split()[1] for ln in open('/proc/self/status') if ln.startswith('VmHWM:')]\n"
          "    peak = max(int(hwm[0]) if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,\n"
          "               resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
          "    sys.stderr.write('\\n{tag}%d\\n' % peak)\n"
          "sys.exit(rc)\n")


def run_limited(argv: list[str], cwd: Path, timeout: float = 600) -> tuple[int, str, str, float]:
    """(exit code, stdout, stderr, peak RSS [MB]) of ``vibro argv`` in a child process under :data:`LIMIT_AS`
    (the peak of the child itself and of its own workers, as it reports it on exit).  The child's own peak is
    VmHWM, not RUSAGE_SELF: Linux carries ru_maxrss across exec, so the latter would report the pytest worker
    that spawned it."""
    env = {**os.environ, "VIBRO_NO_MLFLOW": "1", "PYTHONPATH": str(ROOT)}
    code = _CHILD.format(lim=LIMIT_AS, tag=RSS_TAG)
    try:
        p = subprocess.run([sys.executable, "-c", code, *argv], cwd=cwd, env=env, capture_output=True, text=True,
                           timeout=timeout)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"vibro {' '.join(argv)} ran past {timeout} s") from None
    lines = p.stderr.splitlines()
    peak = [int(ln[len(RSS_TAG):]) for ln in lines if ln.startswith(RSS_TAG)]
    err = "\n".join(ln for ln in lines if not ln.startswith(RSS_TAG))
    return p.returncode, p.stdout, err, (peak[0] / 1024 if peak else float("inf"))


def _params(cases):
    return [pytest.param(c, id=c[0], marks=[getattr(pytest.mark, m) for m in c[6]]) for c in cases]


@pytest.mark.parametrize("case", _params(CASES))
def test_hostile_bound(case, tmp_path):
    name, argv, setup, rc_want, fragment, rss_bound_mb, _ = case
    if setup:
        SETUPS[setup](tmp_path)
    (tmp_path / "rig.yaml").write_text("model: drill\npreset: lab\n")
    (tmp_path / "pts.csv").write_text("frequency_hz\n200\n")
    before = _checksums(tmp_path)
    watched = {d: sorted(os.listdir(d)) for d in WATCHED}
    args = [a.format(t=tmp_path) for a in (argv if isinstance(argv, list) else argv.split())]
    rc, out, err, rss_mb = run_limited(args, tmp_path)
    assert rc == rc_want, f"exit {rc}, stderr: {err[-2000:]}"
    if rc == 2:
        lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("usage:")]
        assert len(lines) == 1 and "error:" in lines[0] and "internal error" not in lines[0], err
        assert fragment in lines[0], err
    else:
        assert fragment in out, out
        assert "Traceback" not in err and "internal error" not in err, err
    assert rss_mb < rss_bound_mb, f"peak RSS {rss_mb:.0f} MB, bound {rss_bound_mb} MB"
    assert _checksums(tmp_path) == before, "a file outside out/ changed, appeared or vanished"
    assert {d: sorted(os.listdir(d)) for d in WATCHED} == watched, "a file appeared in a watched folder"


@pytest.mark.parametrize("model", ["drill", "rimd", "indenter-metal"])
def test_models_lists_only_the_discrepancy_terms_a_model_accepts(model, capsys):
    """``vibro models drill`` listed contact_rate_product, which every command then refused for the drill."""
    import sim
    from pipeline.cli import main
    from sim.models.discrepancy import PARAM_OF

    assert main(["models", model]) == 0
    out = capsys.readouterr().out
    spec = sim.get_model(model)
    listed = {ln.split()[0] for ln in out.splitlines() if ln.startswith("    ") and ln.split()}
    for p in PARAM_OF:
        assert (p in listed) == (p in spec.discrepancy), p


def test_series_over_the_sample_cap_is_refused_while_reading(tmp_path, capsys, monkeypatch):
    """The cap on a series' samples stops the read at the first chunk past it (small caps here)."""
    import pipeline.datasets.measured as measured
    from pipeline.cli import main
    from tests.reliability.test_bad_inputs import _dataset

    monkeypatch.setattr(measured, "MAX_SERIES_SAMPLES", 100)
    monkeypatch.setattr(measured, "SERIES_CHUNK_ROWS", 32)
    ds = _dataset(tmp_path / "ds")
    (ds / "series").mkdir()
    (ds / "series" / "m40.csv").write_text("t_s,accel_m_s2\n" + "".join(f"{i * 1e-4:.7f},0.5\n" for i in range(500)))
    seen = []
    real = measured._numeric
    monkeypatch.setattr(measured, "_numeric", lambda df, *a, **k: seen.append(len(df)) or real(df, *a, **k))
    rc = main(["diagnose", str(ds), "--out", str(tmp_path / "o"), "--no-mlflow"])
    err = capsys.readouterr().err
    assert rc == 2 and "series/m40.csv: more than 100 samples" in err, err
    assert seen.count(32) == 2 * 3          # three chunks of two columns parsed, not the whole file


def test_series_bad_cell_in_a_later_chunk_names_its_line(tmp_path, capsys, monkeypatch):
    import pipeline.datasets.measured as measured
    from pipeline.cli import main
    from tests.reliability.test_bad_inputs import _dataset

    monkeypatch.setattr(measured, "SERIES_CHUNK_ROWS", 32)
    ds = _dataset(tmp_path / "ds")
    (ds / "series").mkdir()
    rows = [f"{i * 1e-4:.7f},0.5" for i in range(100)]
    rows[70] = f"{70e-4:.7f},oops"
    (ds / "series" / "m40.csv").write_text("t_s,accel_m_s2\n" + "\n".join(rows) + "\n")
    rc = main(["diagnose", str(ds), "--out", str(tmp_path / "o"), "--no-mlflow"])
    err = capsys.readouterr().err
    assert rc == 2 and "series/m40.csv line 72, column 'accel_m_s2'" in err, err


def test_a_record_too_long_for_the_least_squares_design_is_refused(monkeypatch):
    """diagnose's memory per record is its design (samples x harmonic columns): capped, naming the series."""
    import numpy as np

    from pipeline.core.errors import UserError
    from pipeline.diagnosis import features

    t = np.arange(2000) * 1e-4
    features.check_resolution("r1", t, 100.0, 5)            # 2000 x 14 cells: far inside the cap
    monkeypatch.setattr(features, "MAX_DESIGN_CELLS", 10_000)
    with pytest.raises(UserError, match=r"series/r1.csv: 2000 samples x 14 harmonic columns"):
        features.check_resolution("r1", t, 100.0, 5)
