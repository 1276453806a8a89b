"""``vibro compare``: the uncorrected model's and the corrected rig's recommendations, side by side."""
from __future__ import annotations

import argparse

from pipeline.cli import args as A
from pipeline.cli.args import add_quiet, add_workers, check_workers
from pipeline.core.errors import UserError

EPILOG = """\
inputs: two `vibro optimise` output folders (their report.json): one on the uncorrected model (e.g. the lab
preset), one on the corrected rig; the corrected rig file (rig.yaml of `vibro diagnose`; its report.json
beside it, when present, says whether the diagnosis explained the data).
output under --out: report.json (both recommendations simulated on both models, the correction's worth in
mm/s, the ROP spread of the corrected recommendation over the rig's fitted-parameter uncertainty, combined with
the rig's model error (its held-out ROP error, rig file 'model_error'), the warning for an unexplained diagnosis)
and report.md.

examples:
  vibro compare --uncorrected results/optimise/rop --corrected results/optimise-rig/rop \\
      --rig results/diagnose-rig/rig.yaml --out results/closed-loop --metrics metrics/closed-loop.json
"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "compare", help="what the corrected rig's recommendation is worth: both recommendations on both models",
        description="Simulate the operating point recommended on the uncorrected model and the one recommended on "
                    "the corrected rig (vibro diagnose's rig.yaml) on both models; report what the correction is "
                    "worth in mm/s on the corrected rig, and the ROP spread of the corrected recommendation over "
                    "samples of the rig's fitted parameters (docs/closed-loop.md).",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG)
    p.add_argument("--uncorrected", required=True, metavar="DIR", help="vibro optimise output on the uncorrected model")
    p.add_argument("--corrected", required=True, metavar="DIR", help="vibro optimise output on the corrected rig")
    p.add_argument("--rig", required=True, metavar="FILE", help="the corrected rig file (vibro diagnose's rig.yaml)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (report.json, report.md)")
    p.add_argument("--metrics", metavar="FILE.json", help="also write the headline numbers to this JSON file")
    p.add_argument("--samples", type=int, default=32, help="samples of the fitted parameters (default 32)")
    p.add_argument("--seed", type=int, default=0, help="seed of the samples (default 0)")
    add_workers(p, dest="threads", help="simulation threads (default: all cores)")
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    add_quiet(p)
    A.add_overwrite(p, "comparison")
    p.set_defaults(func=run)


def _read_json(path, what: str) -> dict:
    import json
    from pathlib import Path

    from pipeline.core.bounded import MAX_TEXT_BYTES, check_input_file

    f = check_input_file(path, what, MAX_TEXT_BYTES)
    try:
        doc = json.loads(f.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise UserError(f"{what} {f}: not valid JSON ({e})") from None
    if not isinstance(doc, dict):
        raise UserError(f"{what} {f}: expected a JSON object, got {type(doc).__name__}")
    return doc


def check_optimise_report(doc: dict, path, what: str) -> None:
    """UserError naming ``path`` unless ``doc`` has what compare reads of a 'vibro optimise' report.json."""
    tried, rec = doc.get("tried"), doc.get("recommendation")
    if not isinstance(tried, dict) or not isinstance(tried.get("model"), str):
        raise UserError(f"{what} {path}: no 'tried' section naming the model; not a 'vibro optimise' report.json")
    if not isinstance(doc.get("inputs"), list):
        raise UserError(f"{what} {path}: no 'inputs' list; not a 'vibro optimise' report.json")
    if rec and not (isinstance(rec, dict) and isinstance(rec.get("params"), dict)):
        raise UserError(f"{what} {path}: 'recommendation' has no 'params'; not a 'vibro optimise' report.json")


def run(args) -> int:
    from pathlib import Path

    from pipeline import tracking
    from vibrobase.files import atomic_write_text
    from vibrobase.jsonable import dump_json
    from pipeline.core.outdir import check_out, check_out_file, prepare_out, record_out_file
    from pipeline.core.rigfile import read_rig, rig_name
    from pipeline.comparison.workflow import compare, markdown

    if args.samples < 1:
        raise UserError(f"--samples must be >= 1, got {args.samples}")
    for flag, path in (("--uncorrected", args.uncorrected), ("--corrected", args.corrected)):
        doc = _read_json(Path(path) / "report.json", f"{flag} report")
        check_optimise_report(doc, Path(path) / "report.json", f"{flag} report")
        if flag == "--uncorrected":
            unc = doc
        else:
            cor = doc
    rig = read_rig(args.rig)
    for flag, doc in (("--uncorrected", unc), ("--corrected", cor)):
        if doc["tried"]["model"] != rig.model:
            raise UserError(f"--rig {args.rig} describes model '{rig.model}', but the {flag} study optimised model "
                            f"'{doc['tried']['model']}': give the rig of the model that was optimised")
    diag_file = Path(args.rig).parent / "report.json"
    inputs = [args.uncorrected, args.corrected, args.rig, diag_file if diag_file.is_file() else None]
    check_out(args.out, inputs=[*inputs, args.metrics], overwrite=args.overwrite, marker="compare")
    if args.metrics:
        check_out_file(args.metrics, flag="--metrics", kind="json", inputs=[*inputs, args.out],
                       overwrite=args.overwrite)
    diag = _diagnosis_rig(diag_file, rig.model) if diag_file.is_file() else None
    params = {"uncorrected": args.uncorrected, "corrected": args.corrected, "rig": args.rig, "samples": args.samples,
              "seed": args.seed}
    with tracking.chain("corrected", rig_name(args.rig)), \
            tracking.run("compare", params, enabled=not args.no_mlflow) as mlflow:
        cmp = compare(unc, cor, rig, diag, n_samples=args.samples, seed=args.seed,
                      n_threads=check_workers(args.threads), rig_name=rig_name(args.rig))
        out = Path(args.out)
        with prepare_out(out, inputs=[*inputs, args.metrics], overwrite=args.overwrite, marker="compare") as tmp:
            atomic_write_text(tmp / "report.json", dump_json(cmp))
            atomic_write_text(tmp / "report.md", "# Closing the loop\n\n" + markdown(cmp))
        t = cmp["recommendations"]
        metrics = {"worth_mm_s": cmp["worth_mm_s"],
                   "corrected_breaks_uncorrected_limits": float(bool(t["corrected"]["breaks_on_uncorrected"])),
                   "corrected_surrogate_wrong": float(cmp["corrected_surrogate_wrong"] or 0),
                   "corrected_surrogate_fallback": float(bool(cmp["corrected_fallback"])),
                   "uncorrected_rop_on_corrected_mm_s": t["uncorrected"]["rop_m_s_on_corrected"] * 1e3,
                   "corrected_rop_on_corrected_mm_s": t["corrected"]["rop_m_s_on_corrected"] * 1e3,
                   "uncorrected_rop_on_uncorrected_mm_s": t["uncorrected"]["rop_m_s_on_uncorrected"] * 1e3,
                   "corrected_rop_p5_mm_s": cmp["spread"]["p5_rop_m_s"] * 1e3,
                   "corrected_rop_p95_mm_s": cmp["spread"]["p95_rop_m_s"] * 1e3,
                   "fraction_progressing": cmp["spread"]["fraction_progressing"],
                   "explained": 1.0 if cmp["explained"] else 0.0}
        for key in ("parameter_half_width_m_s", "model_error_half_width_m_s", "combined_half_width_m_s"):
            if cmp["spread"][key] is not None:       # a model error not given stays out, not 0
                metrics["corrected_rop_" + key.replace("_m_s", "_mm_s")] = cmp["spread"][key] * 1e3
        if args.metrics:
            atomic_write_text(args.metrics, dump_json(metrics))
            record_out_file(args.metrics, command="compare", kind="json")
        if mlflow is not None:
            mlflow.log_metrics({k: float(v) for k, v in metrics.items()})
            mlflow.log_artifact(str(out / "report.json"))
            mlflow.log_artifact(args.rig, artifact_path="rig")
    if not args.quiet:
        print(markdown(cmp))
    return 0


def _diagnosis_rig(path: Path, model: str):
    """The rig entry (``report_types.RigInfo``) of the diagnosis report.json ``path``: its system's, or the one
    system's (None when a several-system diagnosis has none of ``model``)."""
    from pipeline.diagnosis.report_types import DiagnoseReport

    rep = DiagnoseReport.from_json(_read_json(path, "diagnosis report"), str(path))
    if len(rep.systems) == 1:
        return rep.systems[0].rig
    return next((s.rig for s in rep.systems if s.system == model), None)
