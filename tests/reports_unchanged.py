"""Diagnose a fixed set of stored logs and compare two such sets: a refactoring of the diagnosis leaves every
report.json number, verdict and rig file unchanged.

    python -m tests.reports_unchanged record DIR [--only NAME ...]   # diagnose every case into DIR/<case>
    python -m tests.reports_unchanged compare OLD NEW                # differences, one line each; exit 1 if any

The cases cover each path of the diagnosis: a single split with one effect selected, a pair, leave-one-run-out,
an undeclared DAQ chain estimated, discovery with nothing accepted and with a proposal accepted.  The logs are the
identification matrix's and the discovery bench's (``python -m bench.identification_chain`` and
``python -m bench.discovery`` write them under bench/results).  Timing fields
(``wall_time_s``, ``cost``) are left out of the comparison.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

RESULTS = Path(os.environ.get("VIBRO_GOLDEN_RESULTS") or Path(__file__).resolve().parents[1] / "bench" / "results")
"""Where the stored logs are (environment VIBRO_GOLDEN_RESULTS: another checkout's bench/results, e.g. from a git
worktree)."""

CASES: dict[str, tuple[str, dict]] = {
    "single": ("identification/logs/drill-guide_friction-rig-s0-n8", {}),
    "pair": ("identification/logs/drill-shaker_coil+guide_friction-rig-butter8-s0-n8", {}),
    "loro": ("identification/logs/drill-guide_friction-rig-s0-n8",
             {"min_runs_holdout": 9, "effects": ["guide_friction", "shaker_coil", "rate_stiffening"]}),
    "chain": ("identification/logs/drill-control-rig-butter8-undeclared-s0-n8", {"estimate_chain": True}),
    "discovery": ("identification/logs/drill-guide_friction-rig-butter8-undeclared-s0-n8",
                  {"effects": ["guide_friction", "shaker_coil", "tip_blunting"], "max_proposals": 2}),
    "accepted": ("discovery/logs/drill-outside-contact_power-rig-s0-n8",
                 {"effects": ["guide_friction", "tip_blunting"], "max_proposals": 2}),
    "make-run-seed000": ("measured/seed000-published", {"n_starts": 2, "max_nfev": 15, "seed": 0}),
    "make-run-drill-rig": ("measured/drill-rig", {"n_starts": 2, "max_nfev": 15, "seed": 0}),
}
"""Case name -> (log under RESULTS, or the repository's measured/ folder; DiagnoseConfig settings: the make-run
cases take params.yaml's)."""
ROOT = Path(__file__).resolve().parents[1]

VOLATILE = ("wall_time_s", "cost")


def record(out: Path, only: list[str] | None, threads: int) -> None:
    """Diagnose every case (or ``only``) into ``out``/<case>."""
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis.outputs import diagnose_into
    from pipeline.diagnosis.run import DiagnoseConfig

    for name, (log, settings) in CASES.items():
        if only and name not in only:
            continue
        rep = diagnose_into(load_dataset(ROOT / log if log.startswith("measured/") else RESULTS / log), out / name, DiagnoseConfig(n_threads=threads, **settings),
                            log=lambda s: None).report
        r = rep.systems[0]
        print(f"{name}: {r.verdict}, selected {'+'.join(r.selected) if r.selected else None}, pairs tried "
              f"{r.pair_stage.tried}, proposal {r.proposal_adopted}, {rep.wall_time_s} s", flush=True)


def _diff(a, b, path: str, out: list[str]) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            if k in VOLATILE and path == "":
                continue
            if k not in a or k not in b:
                out.append(f"{path}/{k}: only in {'new' if k in b else 'old'}")
            else:
                _diff(a[k], b[k], f"{path}/{k}", out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: {len(a)} items -> {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            _diff(x, y, f"{path}[{i}]", out)
    elif isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return
    elif a != b or type(a) is not type(b):
        out.append(f"{path}: {a!r} -> {b!r}")


def compare(old: Path, new: Path) -> list[str]:
    """Every difference between two recorded sets: report.json values (timing aside), rig files, figure files."""
    out: list[str] = []
    for case in sorted(p.name for p in old.iterdir() if p.is_dir()):
        a, b = old / case, new / case
        if not b.is_dir():
            out.append(f"{case}: not in {new}")
            continue
        diffs: list[str] = []
        _diff(json.loads((a / "report.json").read_text()), json.loads((b / "report.json").read_text()), "", diffs)
        out += [f"{case} report.json{d}" for d in diffs]
        files_a = sorted(p.name for p in a.iterdir() if p.suffix in (".yaml", ".png"))
        files_b = sorted(p.name for p in b.iterdir() if p.suffix in (".yaml", ".png"))
        if files_a != files_b:
            out.append(f"{case}: files {files_a} -> {files_b}")
        for f in files_a:
            if f.endswith(".yaml") and (b / f).exists() and (a / f).read_bytes() != (b / f).read_bytes():
                out.append(f"{case}: {f} differs")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tests.reports_unchanged", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record", help="diagnose every case into DIR/<case>")
    r.add_argument("dir", type=Path)
    r.add_argument("--only", nargs="+", choices=sorted(CASES))
    r.add_argument("--threads", type=int, default=2)
    c = sub.add_parser("compare", help="list the differences between two recorded sets")
    c.add_argument("old", type=Path)
    c.add_argument("new", type=Path)
    a = p.parse_args(argv)
    if a.cmd == "record":
        record(a.dir, a.only, a.threads)
        return 0
    diffs = compare(a.old, a.new)
    print("\n".join(diffs) if diffs else "no difference")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
