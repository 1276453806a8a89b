"""``vibro report``: the pipeline's final report (Markdown + self-contained HTML) from the stage outputs."""
from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli import args as A
from pipeline.core.errors import UserError

REPORT_KEYS = {"title", "max_rows", "dpi"}


def add_parser(sub) -> None:
    p = sub.add_parser(
        "report", help="write the pipeline report (Markdown + self-contained HTML) from the stage outputs",
        description="Read the outputs of the pipeline stages and write OUT/report.md, OUT/report.html (one "
                    "self-contained page, figures embedded as base64 PNG), OUT/figures/*.png and OUT/summary.json. "
                    "Sections: dataset summary (sweep), surrogate accuracy (train), recommended operating point "
                    "with its verified ROP and the Pareto front (optimise/verify), before/after errors of the "
                    "measured-data diagnosis (diagnose). A stage that has not run gets a section saying so. "
                    "params.yaml section 'report': title (str), max_rows (rows of long tables, default 15), "
                    "dpi (figure resolution, default 100). Logs an MLflow run 'report' with the pages as artifacts.",
        epilog="Examples:\n  vibro report --out results/report\n"
               "  vibro report --out results/report --metrics results/answer.json\n"
               "  vibro report --out /tmp/rep --sweep data/sweep --surrogate models/surrogate --no-mlflow",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="results/report", help="output folder (default: results/report)")
    p.add_argument("--params", default=None, help="params file; its 'report' section is read (default: params.yaml "
                                                  "when present)")
    p.add_argument("--sweep", default="data/sweep", help="sweep dataset folder (default: data/sweep)")
    p.add_argument("--surrogate", default="models/surrogate", help="surrogate bundle folder (default: models/surrogate)")
    p.add_argument("--optimise", default="results/optimise", help="optimise output folder (default: results/optimise)")
    p.add_argument("--verify", default="results/verify", help="verify output folder (default: results/verify)")
    p.add_argument("--diagnose", default="results/diagnose", help="diagnose output folder (default: results/diagnose)")
    p.add_argument("--metrics-dir", default="metrics", help="folder of the stages' metrics JSON (default: metrics)")
    p.add_argument("--metrics", default=None,
                   help="also write the answer as a few flat numbers to this JSON file (the pipeline's dvc metric: "
                        "point, ROP and its 5-95 %% spread, worth, explained, surrogate_fallback)")
    p.add_argument("--title", default=None, help="report title (overrides params.yaml report.title)")
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    A.add_overwrite(p, "report")
    p.set_defaults(func=run)


def read_report_section(params_path: Path, missing_ok: bool = True) -> dict:
    """The 'report' section of params.yaml ({} if the file or section is absent); unknown keys are an error."""
    from pipeline.core.params import read_section

    sec = read_section(params_path, "report", missing_file_ok=missing_ok, known=REPORT_KEYS)
    for key in ("max_rows", "dpi"):
        if key in sec and (not isinstance(sec[key], int) or sec[key] <= 0):
            raise UserError(f"{params_path}: report.{key} must be a positive integer, got {sec[key]!r}")
    return sec


def run(args) -> int:
    from pipeline import tracking
    from pipeline.core.outdir import check_out_file, prepare_out, record_out_file
    from pipeline.report.build import ReportInputs, build_report

    if Path(args.surrogate).exists() and not Path(args.surrogate).is_dir():
        raise UserError(f"--surrogate {args.surrogate}: not a surrogate bundle directory")
    params = args.params or "params.yaml"                 # an explicit --params must exist
    sec = read_report_section(Path(params), missing_ok=args.params is None)
    inp = ReportInputs(root=Path("."), sweep=Path(args.sweep), surrogate=Path(args.surrogate),
                       optimise=Path(args.optimise), verify=Path(args.verify), diagnose=Path(args.diagnose),
                       metrics=Path(args.metrics_dir), params=Path(params),
                       title=args.title or sec.get("title", "vibro pipeline report"),
                       max_rows=sec.get("max_rows", 15), dpi=sec.get("dpi", 100))
    inputs = [params, args.sweep, args.surrogate, args.optimise, args.verify, args.diagnose, args.metrics_dir]
    out = Path(args.out)
    if args.metrics:
        check_out_file(args.metrics, flag="--metrics", kind="json", inputs=[*inputs, args.out],
                       overwrite=args.overwrite)
    with prepare_out(out, inputs=inputs, overwrite=args.overwrite, marker="report") as tmp, \
            tracking.run("report", {"out": args.out, **{f"report.{k}": v for k, v in sec.items()}},
                         enabled=not args.no_mlflow) as mlflow:
        res = build_report(inp, tmp)
        if mlflow is not None:
            mlflow.log_artifact(str(res.markdown), artifact_path="report")
            mlflow.log_artifact(str(res.html), artifact_path="report")
            for fig in res.figures:
                mlflow.log_artifact(str(fig), artifact_path="report/figures")
            mlflow.log_metric("report.n_figures", len(res.figures))
    if args.metrics:
        from vibrobase.files import atomic_write_text
        from vibrobase.jsonable import dump_json
        from pipeline.report.answer import headline

        atomic_write_text(args.metrics, dump_json(headline(res.summary)))
        record_out_file(args.metrics, command="report", kind="json")
    print(f"report: {out / res.html.name} ({len(res.figures)} figures) and {out / res.markdown.name}")
    return 0
