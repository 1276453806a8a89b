"""``python -m pipeline.tracking.repro``: the main job (what ``make run`` calls after installing).

1. Asks dvc which stages of ``dvc.yaml`` are out of date (``dvc status``).  If none is, it does
   no work and says so — **no MLflow run is created for a no-op**, so every parent run in the
   tracking store stands for a pipeline that actually computed something.
2. Otherwise opens an MLflow *parent run* (stage tag ``pipeline``) in the pipeline's experiment,
   logs every ``params.yaml`` value as ``<section>.<key>``, exports its id as
   ``VIBRO_PARENT_RUN_ID`` and runs ``dvc repro`` with the dvc next to this Python; each stage
   command logs itself as a child run of it.
3. Closes the parent run with a summary: tags ``vibro.status`` and ``vibro.stages_ran``, the
   metrics of every stage (``metrics/<stage>.json``, numeric leaves as ``<stage>.<key>``), the wall
   time, and the report, ``params.yaml`` and ``dvc.lock`` as artifacts; status FAILED if dvc failed.
4. Prints one progress line per stage (``[2/7] train: started, 0:41 elapsed, about 3 min left``; the
   estimate comes from the last run's stage times on this machine, ``.vibro/stage-times.json``, else
   from :data:`TYPICAL_S`), lets the stages' progress bars through on stderr, and ends with one line
   holding the answer (operating point, verified ROP, power) and where the report is, then the exact
   ``mlflow ui`` command to browse the runs.

Extra arguments are passed to ``dvc repro`` (e.g. ``-f`` to force every stage, or stage names).

With ``--exp`` it runs ``dvc exp run``: before it starts it names the stages a ``-S section.key=value`` reruns (the
stages that read that section of params.yaml and every stage downstream of them) with their estimated time; and
when the experiment fails or is interrupted, it puts the workspace back as it was (params.yaml and dvc.lock
restored, the outputs checked out of the dvc cache), so a stopped variant never leaves files half-updated.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

from pipeline import tracking
from pipeline.core import params as core_params
from pipeline.core.errors import UserError
from vibrobase.jsonable import flatten

REPORT_REL = Path("results/report/report.html")
METRICS_DIR = Path("metrics")
TIMES_REL = Path(".vibro/stage-times.json")
_RUNNING = re.compile(r"Running stage '([^']+)'")
TYPICAL_S = {"sweep": 10.0, "train": 160.0, "optimise@rop": 15.0, "optimise@pareto": 15.0, "verify": 10.0,
             "diagnose@seed000-published": 100.0, "report": 10.0,
             # the corrected chain (first-run ETA only; later runs use the measured times)
             "diagnose@drill-rig": 45.0, "sweep_rig": 10.0, "train_rig": 30.0, "optimise_rig": 45.0, "compare": 5.0}
"""Stage wall times [s] on two idle cores with the default params.yaml (docs/pipeline.md "Measured run time"):
the first run's ETA; later runs use the previous run's times (``.vibro/stage-times.json``)."""


def _mmss(seconds: float) -> str:
    s = int(round(max(seconds, 0.0)))
    return f"{s // 60}:{s % 60:02d}"


class StageClock:
    """Per-stage progress lines with elapsed time and an ETA from remembered stage times."""

    def __init__(self, planned: list[str], known: dict[str, float], out=None):
        self.planned = list(planned)
        self.known = dict(known)
        self.out = out or sys.stdout
        self.t0 = time.time()
        self.current: str | None = None
        self.started = self.t0
        self.times: dict[str, float] = {}

    def _estimate(self, stage: str) -> float:
        return self.known.get(stage, TYPICAL_S.get(stage, 60.0))

    def start(self, stage: str) -> None:
        """Stage ``stage`` began: close the previous one and print ``[k/N] stage: started ...``."""
        self.finish()
        self.current, self.started = stage, time.time()
        if stage not in self.planned:
            self.planned.append(stage)
        k = self.planned.index(stage) + 1
        left = sum(self._estimate(st) for st in self.planned[k - 1:] if st not in self.times)
        self.out.write(f"[{k}/{len(self.planned)}] {stage}: started, {_mmss(self.started - self.t0)} elapsed, "
                       f"about {_mmss(left)} left (estimate)\n")
        self.out.flush()

    def finish(self) -> None:
        """The current stage ended: print its wall time."""
        if self.current is None:
            return
        dt = time.time() - self.started
        self.times[self.current] = dt
        self.out.write(f"      {self.current}: done in {_mmss(dt)}\n")
        self.out.flush()
        self.current = None


def read_stage_times(root: Path) -> dict[str, float]:
    """Stage wall times of the last run in ``root`` ({} when none)."""
    try:
        data = json.loads((root / TIMES_REL).read_text())
        return {str(k): float(v) for k, v in data.items()}
    except (OSError, ValueError, AttributeError):
        return {}


def write_stage_times(root: Path, times: dict[str, float]) -> None:
    """Remember this run's stage wall times (merged with earlier ones) for the next ETA."""
    from vibrobase.files import atomic_write_text

    if times:
        try:
            atomic_write_text(root / TIMES_REL, json.dumps({**read_stage_times(root), **times}, indent=1))
        except OSError:
            pass


def dvc_executable() -> str:
    """The dvc installed next to this interpreter (the project's .venv), else the one on PATH."""
    here = Path(sys.executable).with_name("dvc")
    if here.exists():
        return str(here)
    found = shutil.which("dvc")
    if not found:
        raise UserError("dvc not found: run 'make install' (it installs dvc into .venv)")
    return found


def dvc_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """Environment for dvc and the stage commands: the .venv's bin first on PATH, ``VIBRO_PYTHON`` = this
    interpreter (what ``bin/vibro`` runs), dvc analytics off, plus ``extra``."""
    env = dict(os.environ)
    bindir = str(Path(sys.executable).parent)
    env["PATH"] = bindir + os.pathsep + env.get("PATH", "")
    env.setdefault("VIBRO_PYTHON", sys.executable)
    env["DVC_NO_ANALYTICS"] = "1"
    env.update(extra or {})
    return env


def stale_stages(root: Path, dvc: str, targets: list[str] | None = None) -> dict:
    """``dvc status --json``: {stage: [changes]} for every stage ``dvc repro`` would run ({} = none)."""
    proc = subprocess.run([dvc, "status", "--json", *(targets or [])], cwd=root, env=dvc_env(),
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise UserError(f"dvc status failed in {root}: {(proc.stderr or proc.stdout).strip()[-500:]}")
    text = proc.stdout.strip()
    start = text.find("{")
    try:
        return json.loads(text[start:]) if start >= 0 else {}
    except json.JSONDecodeError as e:
        raise UserError(f"could not read 'dvc status --json' output: {e}: {text[:200]!r}") from None


def read_params(root: Path) -> dict:
    """params.yaml of ``root`` as a dict ({} when absent)."""
    return core_params.read_params(root / "params.yaml", missing_ok=True)


def collect_metrics(root: Path) -> dict[str, float]:
    """Finite numeric leaves of ``metrics/*.json`` as ``<file stem>.<key path>``."""
    out: dict[str, float] = {}
    mdir = root / METRICS_DIR
    if not mdir.is_dir():
        return out
    for path in sorted(mdir.glob("*.json")):
        try:
            data = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        for key, val in flatten(data, f"{path.stem}.").items():
            if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
                continue
            out[re.sub(r"[^0-9A-Za-z_\-. /]", "_", key)[:250]] = float(val)
    return out


def mlflow_ui_command() -> str:
    """The command that browses the runs of this store."""
    mlflow_bin = Path(sys.executable).with_name("mlflow")
    exe = str(mlflow_bin) if mlflow_bin.exists() else "mlflow"
    uri = tracking.tracking_uri()
    if uri.startswith(("http://", "https://")):
        return f"open {uri} (runs are on the tracking server MLFLOW_TRACKING_URI)"
    return f"{exe} ui --backend-store-uri {uri} --port 5000   # then open http://127.0.0.1:5000"


def print_where(root: Path) -> None:
    report = root / REPORT_REL
    if report.exists():
        from pipeline.report.answer import answer_from_report

        line = answer_from_report(report.parent)
        if line:
            print(line)
        print(f"Report:  {report}  (Markdown: {report.with_suffix('.md')})")
    else:
        print(f"Report:  not built yet ({report})")
    if not os.environ.get("VIBRO_NO_MLFLOW"):
        print(f"Runs:    {mlflow_ui_command()}")


def run_repro(root: Path, dvc: str, command: list[str], repro_args: list[str],
              env: dict[str, str], clock: StageClock | None = None) -> tuple[int, list[str]]:
    """Run ``dvc <command>`` (repro or exp run), echoing its output with a progress line per stage
    (``clock``); the stages' stderr (progress bars) passes straight through.  Returns (exit code, stages that ran)."""
    ran: list[str] = []
    proc = subprocess.Popen([dvc, *command, *repro_args], cwd=root, env=env, stdout=subprocess.PIPE,
                            stderr=None, text=True, bufsize=1)
    assert proc.stdout is not None
    try:
        for line in proc.stdout:
            m = _RUNNING.search(line)
            if m and m.group(1) not in ran:
                ran.append(m.group(1))
                if clock is not None:
                    clock.start(m.group(1))
            sys.stdout.write(line)
            sys.stdout.flush()
    except KeyboardInterrupt:       # dvc got the same Ctrl-C: let it stop its stage before anything is restored
        proc.wait()
        raise
    rc = proc.wait()
    if clock is not None:
        clock.finish()
    return rc, ran


def _stage_table(root: Path) -> dict[str, tuple[set[str], set[str], set[str]]]:
    """dvc.yaml's stages (``foreach`` expanded to ``name@item``): stage -> (params sections, deps, outs)."""
    import yaml

    doc = yaml.safe_load((root / "dvc.yaml").read_text()) or {}
    out = {}

    def paths(items, item=None) -> set[str]:
        names = set()
        for e in items or []:
            name = next(iter(e)) if isinstance(e, dict) else str(e)
            names.add(name.replace("${item}", str(item)) if item is not None else name)
        return names

    for name, st in (doc.get("stages") or {}).items():
        if "foreach" in st:
            body = st.get("do") or {}
            for item in st["foreach"]:
                out[f"{name}@{item}"] = (paths(body.get("params")), paths(body.get("deps"), item),
                                         paths(body.get("outs"), item))
        else:
            out[name] = (paths(st.get("params")), paths(st.get("deps")), paths(st.get("outs")))
    return out


def exp_stages(root: Path, repro_args: list[str]) -> list[str]:
    """The stages ``dvc exp run`` reruns for the ``-S section.key=value`` in ``repro_args``: those that read a set
    section and every stage downstream of them, in dvc.yaml's order ([] without a ``-S``)."""
    sections = set()
    for i, a in enumerate(repro_args):
        value = repro_args[i + 1] if a in ("-S", "--set-param") and i + 1 < len(repro_args) else None
        if value is None and a.startswith("--set-param="):
            value = a.split("=", 1)[1]
        if value:
            sections.add(value.split("=", 1)[0].split(".", 1)[0])
    if not sections:
        return []
    table = _stage_table(root)
    hit = {s for s, (ps, _, _) in table.items() if ps & sections}
    changed = True
    while changed:          # downstream: a stage whose dependency is (inside) an output of a hit stage
        outs = {o for s in hit for o in table[s][2]}
        more = {s for s, (_, deps, _) in table.items() if s not in hit
                and any(d == o or d.startswith(o.rstrip("/") + "/") or o.startswith(d.rstrip("/") + "/")
                        for d in deps for o in outs)}
        changed = bool(more)
        hit |= more
    return [s for s in table if s in hit]


WORKSPACE_FILES = ("params.yaml", "dvc.lock")
"""What ``dvc exp run`` rewrites in the workspace besides the stage outputs."""


def snapshot_workspace(root: Path) -> dict[str, bytes | None]:
    """The bytes of :data:`WORKSPACE_FILES` (None for a missing one), to put back after a failed experiment."""
    return {rel: (root / rel).read_bytes() if (root / rel).exists() else None for rel in WORKSPACE_FILES}


def restore_workspace(root: Path, dvc: str, snap: dict[str, bytes | None], env: dict[str, str]) -> bool:
    """Put back params.yaml and dvc.lock as ``snap`` holds them and check the outputs out of the dvc cache
    (``dvc checkout --force``): the workspace as before a failed or interrupted experiment.  Whether it worked."""
    from vibrobase.files import atomic_write_bytes

    for rel, data in snap.items():
        if data is None:
            (root / rel).unlink(missing_ok=True)
        else:
            atomic_write_bytes(root / rel, data)
    p = subprocess.run([dvc, "checkout", "--force", "-q"], cwd=root, env=env, capture_output=True, text=True)
    return p.returncode == 0


def _log_pipeline_files(mlflow, root: Path) -> None:
    """params.yaml, dvc.lock and dvc.yaml as artifacts of the parent run.  dvc.yaml is logged as
    ``pipeline.dvc.yaml``: a file named dvc.yaml under a local artifact store inside the project
    would be picked up by dvc as a second pipeline."""
    import tempfile

    for rel in ("params.yaml", "dvc.lock"):
        if (root / rel).exists():
            mlflow.log_artifact(str(root / rel))
    if (root / "dvc.yaml").exists():
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / "pipeline.dvc.yaml"
            shutil.copyfile(root / "dvc.yaml", copy)
            mlflow.log_artifact(str(copy))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m pipeline.tracking.repro",
        description="Run the vibro dvc pipeline (dvc.yaml) under one MLflow parent run and say where the "
                    "report and the runs are.  Does nothing (and logs nothing) when dvc is up to date.",
        epilog="Examples:\n  python -m pipeline.tracking.repro            # what 'make run' does\n"
               "  python -m pipeline.tracking.repro -- -f      # force every stage\n"
               "  python -m pipeline.tracking.repro -- train   # reproduce up to 'train'\n"
               "  python -m pipeline.tracking.repro --exp -- -S train.seed=1   # a dvc experiment, tracked the same way",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", default=".", help="project directory holding dvc.yaml (default: .)")
    parser.add_argument("--exp", action="store_true",
                        help="run 'dvc exp run' (a dvc experiment; needs a git repository) instead of 'dvc repro'; "
                             "pass -S section.key=value after --")
    parser.add_argument("repro_args", nargs="*", help="extra arguments for 'dvc repro' / 'dvc exp run' (after --)")
    args = parser.parse_args(argv)
    try:
        return _run(Path(args.root).resolve(), list(args.repro_args), exp=args.exp)
    except UserError as e:
        print(f"run_main: error: {e}", file=sys.stderr)
        return 2


def _run(root: Path, repro_args: list[str], exp: bool = False) -> int:
    if not (root / "dvc.yaml").exists():
        raise UserError(f"no dvc.yaml in {root}: run from the project directory or pass --root")
    os.environ.setdefault("VIBRO_HOME", str(root))
    dvc = dvc_executable()
    forced = any(a in ("-f", "--force", "-F", "--force-downstream") for a in repro_args)
    targets = [a for a in repro_args if not a.startswith("-")]
    stale = dict.fromkeys(exp_stages(root, repro_args)) if exp else stale_stages(root, dvc, targets)
    if not stale and not forced and not exp:
        print("Pipeline is up to date: dvc has nothing to reproduce, so no stage ran and no MLflow run was created.")
        print_where(root)
        return 0
    print(f"Out-of-date stages: {', '.join(stale) or ('(experiment)' if exp else '(forced)')}")
    if stale:
        known = read_stage_times(root)
        total = sum(known.get(s, TYPICAL_S.get(s, 60.0)) for s in stale)
        print(f"This runs {len(stale)} stage(s), about {_mmss(total)} (estimate from "
              f"{'the last run on this machine' if all(s in known for s in stale) else 'typical stage times'})")
    snap = snapshot_workspace(root) if exp else None
    t0 = time.time()
    use_mlflow = not os.environ.get("VIBRO_NO_MLFLOW")
    env_extra: dict[str, str] = {}
    mlflow = None
    run_id = None
    if use_mlflow:
        os.environ.pop("VIBRO_PARENT_RUN_ID", None)
        mlflow = tracking.setup()
        tags = {"vibro.stage": "pipeline", "vibro.stages_planned": ",".join(stale), **tracking.run_tags(),
                "vibro.dvc_command": " ".join(["exp run" if exp else "repro", *repro_args])}
        run = mlflow.start_run(run_name="pipeline-exp" if exp else "pipeline", tags=tags)
        run_id = run.info.run_id
        tracking.log_params(mlflow, flatten(read_params(root)))
        env_extra["VIBRO_PARENT_RUN_ID"] = run_id
        env_extra["VIBRO_EXPERIMENT"] = tracking.experiment_name()
        print(f"MLflow parent run {run_id} (experiment '{tracking.experiment_name()}', {tracking.tracking_uri()})")
    rc, ran = 1, []
    clock = StageClock(list(stale), read_stage_times(root))
    try:
        command = ["exp", "run"] if exp else ["repro"]
        try:
            rc, ran = run_repro(root, dvc, command, repro_args, dvc_env(env_extra), clock)
        finally:            # also on Ctrl-C: a failed experiment leaves the workspace as it found it
            if snap is not None and rc != 0:
                ok = restore_workspace(root, dvc, snap, dvc_env())
                print("Experiment failed or interrupted: workspace restored (params.yaml, dvc.lock, outputs)"
                      if ok else "Experiment failed or interrupted: restored params.yaml and dvc.lock, but "
                                 "'dvc checkout --force' failed; run it to restore the outputs", file=sys.stderr)
        if rc == 0:
            write_stage_times(root, clock.times)
    finally:
        wall = time.time() - t0
        status = "ok" if rc == 0 else "failed"
        if mlflow is not None:
            try:
                mlflow.set_tags({"vibro.status": status, "vibro.stages_ran": ",".join(ran) or "none"})
                metrics = collect_metrics(root)
                metrics["pipeline.wall_time_s"] = wall
                metrics["pipeline.n_stages_ran"] = float(len(ran))
                mlflow.log_metrics(metrics)
                _log_pipeline_files(mlflow, root)
                for rel in ("report.html", "report.md"):
                    path = root / REPORT_REL.parent / rel
                    if path.exists():
                        mlflow.log_artifact(str(path), artifact_path="report")
            finally:
                mlflow.end_run(status="FINISHED" if rc == 0 else "FAILED")
    print()
    print(f"Pipeline {status} in {wall:.0f} s; stages run: {', '.join(ran) or 'none'}"
          + (f"; MLflow parent run {run_id}" if run_id else ""))
    print_where(root)
    return rc


if __name__ == "__main__":
    sys.exit(main())
