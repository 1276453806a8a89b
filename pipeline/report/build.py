"""The pipeline's final report: reads the stage outputs and writes ``report.md`` + a self-contained
``report.html`` (figures embedded as base64 PNG) + ``figures/*.png`` + ``summary.json``.

Sections: dataset summary (sweep), surrogate accuracy (train), recommended operating point with its
verified ROP and the Pareto front (optimise / verify), and the before/after errors of the
measured-data diagnosis (diagnose).  A stage whose outputs are missing gets a section that says so
(the report of a partial pipeline is still written); figures a stage wrote itself are included.
"""
from __future__ import annotations

import json
import math
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pipeline.core.errors import UserError  # noqa: E402
from vibrobase.statuses import IMPACTING_STATUSES  # noqa: E402
from pipeline.report.doc import Document, Figure, Heading, Para, Table, fmt, to_html, to_markdown  # noqa: E402
from pipeline.core.units import ENGINEERING, convert, factor, label, set_label, split  # noqa: E402
from vibrobase.files import atomic_write_bytes, atomic_write_text  # noqa: E402
from vibrobase.jsonable import dump_json, flatten  # noqa: E402
from sim.controls import CONTROLS  # noqa: E402
from sim.models.discrepancy import PARAM_OF  # noqa: E402
from pipeline.diagnosis.report_types import DiagnoseReport, SystemReport  # noqa: E402


@dataclass
class ReportInputs:
    """Where the stage outputs are (defaults = the paths dvc.yaml uses)."""
    root: Path = Path(".")
    sweep: Path = Path("data/sweep")
    surrogate: Path = Path("models/surrogate")
    optimise: Path = Path("results/optimise")
    verify: Path = Path("results/verify")
    diagnose: Path = Path("results/diagnose")
    closed_loop: Path = Path("results/closed-loop")     # vibro compare (docs/closed-loop.md)
    metrics: Path = Path("metrics")
    params: Path = Path("params.yaml")
    title: str = "vibro pipeline report"
    max_rows: int = 15
    dpi: int = 100

    def p(self, rel: Path) -> Path:
        return rel if rel.is_absolute() else self.root / rel


@dataclass
class ReportResult:
    markdown: Path
    html: Path
    summary: dict = field(default_factory=dict)
    figures: list[Path] = field(default_factory=list)


# ----------------------------------------------------------------------------------------- helpers
def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, json.JSONDecodeError) as e:
        raise UserError(f"{path}: not readable JSON ({e})") from None


def _leaf(obj):
    """One table cell for a non-dict value: short lists joined, long ones counted."""
    if isinstance(obj, list) and len(obj) <= 8 and all(not isinstance(v, (dict, list)) for v in obj):
        return ", ".join(fmt(v) for v in obj)
    if isinstance(obj, list):
        return f"[{len(obj)} items]"
    return obj


def _num(v) -> float | None:
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str) and v in ("inf", "-inf"):
        return float(v)
    return None


ROW_UNIT_COLUMNS = ("mae", "rmse", "value", "sd", "default", "calibrated")
"""Columns whose values are in the unit of their row's quantity (e.g. a target's MAE)."""


def _cell(row: str, col: str, v):
    """A value in engineering units: by its column's quantity, else (error columns) by its row's."""
    if split(col)[0] in ENGINEERING:
        return convert(col, v)
    if col in ROW_UNIT_COLUMNS:
        return convert(row, v)
    return v


def dict_table(d: dict, caption: str = "", max_rows: int = 60) -> Table:
    """A dict as a table: {row: {col: scalar}} → rows × columns; anything else → flattened key / value.
    Known quantities (``rop_m_s``, ``peak_force_n``, ...) are shown in engineering units (mm/s, kN, kW, g)."""
    if d and all(isinstance(v, dict) for v in d.values()):
        inner = [v for v in d.values()]
        if all(all(not isinstance(x, (dict, list)) for x in v.values()) for v in inner):
            cols: list[str] = []
            for v in inner:
                cols += [c for c in v if c not in cols]
            if len(cols) <= 10:
                rows = [[label(k)] + [_cell(k, c, v.get(c)) for c in cols] for k, v in d.items()][:max_rows]
                return Table(["", *[label(c) for c in cols]], rows, caption)
    flat = flatten(d, leaf=_leaf)
    rows = [[label(k), convert(k, v)] for k, v in flat.items()][:max_rows]
    return Table(["quantity", "value"], rows, caption)


def frame_table(df: pd.DataFrame, caption: str) -> Table:
    """A data frame as a table, columns labelled and converted to engineering units."""
    cols = list(df.columns)
    rows = [[convert(c, v) for c, v in zip(cols, r)] for r in df.values.tolist()]
    return Table([label(c) for c in cols], rows, caption)


def _pngs(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*.png")) if folder.is_dir() else []


class _Figs:
    """Saves report figures into ``out/figures`` and remembers them."""

    def __init__(self, out: Path, dpi: int):
        self.dir = out / "figures"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.dpi = dpi
        self.paths: list[Path] = []

    def save(self, fig, name: str) -> Path:
        path = self.dir / f"{name}.png"
        tmp = self.dir / f".{name}.tmp.png"
        fig.tight_layout()
        fig.savefig(tmp, dpi=self.dpi)
        plt.close(fig)
        tmp.replace(path)
        self.paths.append(path)
        return path

    def copy(self, src: Path, name: str) -> Path:
        path = self.dir / f"{name}.png"
        atomic_write_bytes(path, src.read_bytes())
        self.paths.append(path)
        return path


def _stage_figures(doc: Document, figs: _Figs, folder: Path, stage: str, limit: int = 6) -> None:
    """Copy (and show) the PNG figures a stage wrote itself."""
    for i, png in enumerate(_pngs(folder)[:limit]):
        rel = png.relative_to(folder).with_suffix("")
        name = f"{stage}-" + "-".join(rel.parts)
        doc.add(Figure(figs.copy(png, name), f"{stage}: {rel.as_posix()}"))


def _metrics_files(inp: ReportInputs, stage: str) -> list[Path]:
    mdir = inp.p(inp.metrics)
    if not mdir.is_dir():
        return []
    return sorted(p for p in mdir.glob("*.json") if p.stem == stage or p.stem.startswith(stage + "-")
                  or p.stem.startswith(stage + "@") or p.stem.startswith(stage + "_"))


# ----------------------------------------------------------------------------------------- sections
def load_sweep(path: Path) -> tuple[pd.DataFrame, dict]:
    """The sweep dataset (partial ones too) and its metadata."""
    from pipeline.datasets.store import load_dataset

    df = load_dataset(path, allow_partial=True)
    meta = _read_json(path / "metadata.json") or {}
    return df, meta


def _stage_folder(doc: Document, inp: ReportInputs, heading: str, where: Path, what: str, stage: str) -> Path | None:
    """A section's heading, then its stage's output folder ``where``; None, said in the section, when it is not there."""
    doc.add(Heading(heading))
    path = inp.p(where)
    if path.is_dir():
        return path
    doc.add(Para(f"No {what} at `{where}`: the {stage} stage has not run."))
    return None


def section_sweep(doc: Document, figs: _Figs, inp: ReportInputs, summary: dict) -> None:
    path = _stage_folder(doc, inp, "1. Dataset (sweep)", inp.sweep, "sweep dataset", "sweep")
    if path is None:
        return
    df, meta = load_sweep(path)
    n = len(df)
    status = df["status"].value_counts().to_dict() if "status" in df else {}
    ok = df[df["status"].isin(list(IMPACTING_STATUSES))] if "status" in df else df     # steady and impacting
    model, preset = meta.get("model"), meta.get("preset")     # sweep metadata.json (pipeline/datasets/store.py)
    expected = meta.get("n_points")
    partial = "" if meta.get("complete", True) and (expected in (None, n)) else \
        f" **Incomplete sweep: {n} of {expected} points.**"
    doc.add(Para(f"`{inp.sweep}`: **{n}** simulated points of model `{model}` (preset `{preset}`); "
                 + ", ".join(f"{k}: {v}" for k, v in sorted(status.items())) + "." + partial))
    summary["sweep"] = {"n_points": n, "status_counts": {str(k): int(v) for k, v in status.items()},
                        "model": model, "preset": preset}
    inputs = [c for c in CONTROLS if c in df]
    inputs += [c for c in (meta.get("vary") or {}) if c in df and c not in inputs] if isinstance(meta.get("vary"), dict) else []
    labels = [c for c in ("rop_m_s", "peak_force_n", "impacts_per_cycle", "period", "peak_decel_g",
                          "energy_per_cycle_j", "specific_energy_j_m") if c in df]
    rows = []
    for c in inputs + labels:
        col = pd.to_numeric(ok[c], errors="coerce").replace([np.inf, -np.inf], np.nan).dropna()
        k = factor(c)
        rows.append([label(c), "input" if c in inputs else "label (ok, aperiodic points)", col.min() * k if len(col) else None,
                     col.median() * k if len(col) else None, col.max() * k if len(col) else None])
    if rows:
        doc.add(Table(["column", "kind", "min", "median", "max"], rows, "Ranges over the dataset"))
    if "rop_m_s" in ok and len(ok):
        rop = pd.to_numeric(ok["rop_m_s"], errors="coerce")
        summary["sweep"]["rop_max_m_s"] = float(rop.max())
    if {"frequency_hz", "rop_m_s"} <= set(df.columns) and len(ok):
        fig, ax = plt.subplots(1, 2, figsize=(11, 4))
        xcol = "amplitude_n" if "amplitude_n" in df else (inputs[1] if len(inputs) > 1 else "frequency_hz")
        fx, fy = (set_label(ax[0], "x", "frequency_hz"), set_label(ax[0], "y", xcol))
        set_label(ax[1], "x", "frequency_hz"), set_label(ax[1], "y", xcol)
        sc = ax[0].scatter(ok["frequency_hz"] * fx, ok[xcol] * fy, c=pd.to_numeric(ok["rop_m_s"]) * factor("rop_m_s"),
                           s=12, cmap="viridis")
        fig.colorbar(sc, ax=ax[0], label=label("rop_m_s"))
        ax[0].set_title("ROP over the sweep (status ok or aperiodic)")
        for st, grp in df.groupby("status"):
            ax[1].scatter(grp["frequency_hz"] * fx, grp[xcol] * fy, s=8, label=f"{st} ({len(grp)})")
        ax[1].set_title("status of every point")
        ax[1].legend(fontsize=8)
        doc.add(Figure(figs.save(fig, "sweep-rop-map"), "Sweep: ROP of the progressing points (left) and the "
                                                        "status of every point (right)."))


def section_train(doc: Document, figs: _Figs, inp: ReportInputs, summary: dict) -> None:
    path = _stage_folder(doc, inp, "2. Surrogate accuracy (train)", inp.surrogate, "surrogate bundle", "train")
    if path is None:
        return
    from surrogate.bundle import MANIFEST, PAYLOAD, verify_bundle
    from surrogate.errors import SurrogateError

    if any((path / f).exists() for f in (MANIFEST, PAYLOAD, "bundle.joblib")):
        verify_bundle(path)    # a corrupt / foreign / tampered bundle is the user's error (exit 2), never skipped
    report = _read_json(path / "report.json")          # bundle.report as `vibro train` writes it
    if report is None:
        try:
            from surrogate import load_bundle  # the shared contract's reader (unpickles the models)

            report = getattr(load_bundle(path), "report", None)
        except (ImportError, SurrogateError):
            report = None
    if not report:
        for m in _metrics_files(inp, "train"):
            report = _read_json(m)
    held = report.get("held_out") if isinstance(report, dict) else None
    if isinstance(held, dict) and isinstance(held.get("targets"), dict):
        cls = held.get("classification") or {}
        doc.add(Para(f"Trained on {report.get('n_train', '?')} points, scored on {report.get('n_test', '?')} held-out "
                     f"points never trained on. Regime classifier held-out accuracy: {fmt(cls.get('accuracy'))}."))
        cols = ("n", "r2", "mae", "rmse", "coverage", "domain")
        targets = {t: {c: v.get(c) for c in cols if c in v} for t, v in held["targets"].items() if isinstance(v, dict)}
        chosen = ((report.get("selection") or {}).get("targets") or {})
        constant = report.get("constant_targets") or {}
        for t in targets:
            targets[t]["model"] = (chosen.get(t) or {}).get("model")
            targets[t]["scale"] = (chosen.get(t) or {}).get("transform")
            if t in constant:   # nothing to learn: no R², no coverage to judge
                targets[t] = {"n": targets[t].get("n"), "domain": targets[t].get("domain"), "model": "constant",
                              "scale": f"constant = {constant[t]:.6g}"}
        doc.add(dict_table(targets, "Held-out accuracy per target (R², MAE, RMSE; coverage of the prediction "
                                    "interval; scale: log = learned as log10, chosen by range and CV)"))
        notes = report.get("goals_notes") or {}
        if constant or notes:
            doc.add(Para("Not failures: " + "; ".join(
                [f"`{t}` is constant in the data ({v:.6g} at every point), so it is predicted exactly and has no R² goal"
                 for t, v in constant.items()]
                + [f"{k}: {n}" for k, n in notes.items() if not (k.endswith("_r2") and k[:-3] in constant)]) + "."))
        met = report.get("goals_met") or {}
        if met:
            doc.add(Para("Goals: " + ", ".join(f"{k} {'met' if v else 'NOT met'}" for k, v in met.items()
                                               if v is not None) + "."))
        summary["train"] = {"held_out": held, "n_train": report.get("n_train"), "n_test": report.get("n_test")}
    elif report:
        doc.add(dict_table(report, "Held-out accuracy of the surrogate (bundle.report)"))
        summary["train"] = report
    else:
        doc.add(Para("The surrogate bundle carries no accuracy report."))
    _stage_figures(doc, figs, path, "train")


OPTIMISE_REPORT = "report.json"
"""What ``vibro optimise`` writes in each study folder (pipeline/optimise/outputs.py, keys ``REPORT_KEYS``)."""


def _optimise_reports(folder: Path) -> list[Path]:
    """The optimise report.json files under ``folder``: the ROP study's (``rop/``) first, then the rest."""
    first = [folder / "rop" / OPTIMISE_REPORT, folder / OPTIMISE_REPORT]
    return [p for p in dict.fromkeys(first + sorted(folder.rglob(OPTIMISE_REPORT))) if p.exists()]


def _pareto_frame(folder: Path) -> pd.DataFrame | None:
    """The verified Pareto front: ``pareto_verified`` of the first optimise report.json that has one."""
    for p in sorted(folder.rglob(OPTIMISE_REPORT)):
        front = (_read_json(p) or {}).get("pareto_verified")
        if isinstance(front, list) and front and isinstance(front[0], dict):
            df = pd.json_normalize(front)
            return df.rename(columns=lambda c: c.replace("params.", ""))
    return None


def _recommendation(folder: Path) -> tuple[Path, dict] | None:
    """(file, ``recommendation``) of the ROP study's report.json (``rop/`` first), else of any optimise report."""
    for p in _optimise_reports(folder):
        rec = (_read_json(p) or {}).get("recommendation")
        if isinstance(rec, dict):
            return p, rec
    return None


def _base_name(key: str) -> str:
    """'params.amplitude_n' / 'power_w_sim' / 'rop_m_s_pred' -> the label or control name."""
    key = key.split(".")[-1]
    for suffix in ("_sim", "_pred", "_lo", "_hi"):
        if key.endswith(suffix):
            return key[: -len(suffix)]
    return key


def _eng_name(key: str) -> str:
    """Column name with its engineering unit (pipeline.core.units), e.g. 'power (sim) [W]'."""
    return label(key.split(".")[-1])


def _eng_value(key: str, v):
    """A value in the engineering unit of its column; non-numbers unchanged."""
    return convert(key, v)


def section_optimise(doc: Document, figs: _Figs, inp: ReportInputs, summary: dict) -> None:
    path = _stage_folder(doc, inp, "3. Recommended operating point (optimise, verified by the simulator)",
                         inp.optimise, "optimisation results", "optimise")
    if path is None:
        return
    found = _recommendation(path)
    if found:
        p, rec = found
        verified = rec.get("rop_m_s_sim")
        summary["optimise"] = {"recommended": rec, "verified_rop_m_s": verified}
        v = _num(verified)
        where = p.relative_to(inp.root) if p.is_relative_to(inp.root) else p
        doc.add(Para("Recommended point" + (f": verified ROP **{v * 1e3:.4g} mm/s**" if v is not None else "")
                     + f" (from `{where}`)."))
        if rec.get("binding"):
            doc.add(Para("It sits at the limit(s): " + ", ".join(rec["binding"]) + "."))
        if rec.get("on_bounds"):
            doc.add(Para("**On the edge of the search space:** " + ", ".join(
                f"{h['name']} at its {'upper' if h['side'] == 'high' else 'lower'} bound {h['bound']:g}"
                for h in rec["on_bounds"]) + ". The optimum may lie beyond this bound; widen that range to know."))
        elif "on_bounds" in rec:
            doc.add(Para("The recommended point lies inside the search space (no control within 2 % of a bound)."))
        shown = {_eng_name(k): _eng_value(k, val) for k, val in flatten(rec).items()
                 if k not in ("binding",) and not k.startswith("on_bounds")}
        doc.add(dict_table(shown, "Recommended operating point in engineering units (`_sim` = simulated, "
                                  "`_pred` = surrogate)"))
    else:
        doc.add(Para("No recommended point among the optimisation outputs (no feasible point was verified)."))
    mfiles = _metrics_files(inp, "optimise")
    if mfiles:
        data = {m.stem: (_read_json(m) or {}) for m in mfiles}
        keys = [k for d in data.values() for k in d if not isinstance(d[k], (dict, list))]
        keys = list(dict.fromkeys(keys))
        doc.add(Table(["quantity", *data], [[label(k), *[convert(k, d.get(k)) for d in data.values()]] for k in keys],
                      "Optimisation metrics per study (engineering units)"))
    doc.add(Heading("Pareto front", 3))
    front = _pareto_frame(path)
    if front is None or front.empty:
        doc.add(Para("No Pareto front among the optimisation outputs."))
    else:
        summary.setdefault("optimise", {})["pareto_size"] = int(len(front))
        doc.add(frame_table(front.head(inp.max_rows),
                            f"Verified Pareto front ({len(front)} points; first {min(len(front), inp.max_rows)} shown)"))
        num = [c for c in front.columns if pd.api.types.is_numeric_dtype(front[c])]
        ycol = next((c for c in num if "rop" in c), None)
        xcol = next((c for c in num if c != ycol and any(s in c for s in ("power", "energy", "force", "decel"))), None)
        if ycol and xcol:
            fig, ax = plt.subplots(figsize=(6, 4))
            f2 = front.sort_values(xcol)
            ax.plot(f2[xcol] * set_label(ax, "x", xcol), f2[ycol] * set_label(ax, "y", ycol), "o-")
            ax.set_title("Pareto front (verified by the simulator)")
            ax.grid(alpha=0.3)
            doc.add(Figure(figs.save(fig, "pareto-front"), f"Pareto front: {label(ycol)} against {label(xcol)}."))
    _stage_figures(doc, figs, path, "optimise", limit=8)


def section_verify(doc: Document, figs: _Figs, inp: ReportInputs, summary: dict) -> None:
    path = inp.p(inp.verify)
    mfiles = _metrics_files(inp, "verify")
    if not path.is_dir() and not mfiles:
        return
    doc.add(Heading("Verification by the simulator", 3))
    for m in mfiles:
        data = _read_json(m) or {}
        summary["verify"] = data
        doc.add(dict_table(data, f"Surrogate prediction against the simulator ({m.name})"))
    _stage_figures(doc, figs, path, "verify")


DIAG_COLUMNS = (("default_error", "default params"), ("base_error", "before (calibrated base)"),
                ("final_error", "after (with selected effect)"), ("noise_floor", "noise floor"),
                ("selected", "selected effect"), ("explained", "explained"))


def _diag_rows(name: str, rep: DiagnoseReport) -> list[dict]:
    """One row per system of a diagnosis."""
    return [{"dataset": name, "system": r.system, "default_error": r.errors.default.error,
             "base_error": r.errors.base.error, "final_error": r.errors.final.error, "noise_floor": r.noise_floor,
             "selected": "+".join(r.selected) if r.selected else "none", "explained": r.explained}
            for r in rep.systems]


def _headline_rows(name: str, headline: dict) -> list[dict]:
    """The row of a ``vibro diagnose --metrics`` file (``DiagnoseReport.headline``), where no report.json is at hand."""
    row = {"dataset": name, "system": str(headline.get("system", name))}
    for key, _ in DIAG_COLUMNS:
        v = headline.get(key)
        row[key] = "none" if key == "selected" and not v else v
    return [row]


def section_diagnose(doc: Document, figs: _Figs, inp: ReportInputs, summary: dict) -> None:
    doc.add(Heading("4. Measured-data diagnosis (before / after)"))
    path = inp.p(inp.diagnose)
    reports: dict[str, DiagnoseReport] = {}
    if path.is_dir():
        for p in sorted(path.glob("*/report.json")) + ([path / "report.json"] if (path / "report.json").exists() else []):
            d = _read_json(p)
            if d:
                reports[p.parent.name] = DiagnoseReport.from_json(d, str(p))
    rows = [r for name, rep in reports.items() for r in _diag_rows(name, rep)]
    if not reports:
        for m in _metrics_files(inp, "diagnose"):
            name = m.stem.split("-", 1)[1] if "-" in m.stem else m.stem
            rows += _headline_rows(name, _read_json(m) or {})
    if not rows:
        doc.add(Para(f"No diagnosis results at `{inp.diagnose}`: the diagnose stage has not run."))
        return
    summary["diagnose"] = rows
    doc.add(Para("Relative feature error of the model against each measured dataset, every feature weighted by its "
                 "measurement noise (||(model − measured)/sd|| / ||measured/sd||): with the default parameters, after "
                 "calibrating the uncertain parameters (**before** adding an effect), and **after** the selected §6 "
                 "effect; the noise floor is the same quantity for a residual of pure noise, so error / noise floor "
                 "is the held-out nrms (docs/diagnose.md)."))
    doc.add(Table(["dataset", "system", *[label for _, label in DIAG_COLUMNS]],
                  [[r["dataset"], r["system"], *[r.get(k) for k, _ in DIAG_COLUMNS]] for r in rows],
                  "Diagnosis: errors before / after"))
    numeric = [r for r in rows if all(_num(r.get(k)) is not None for k in ("base_error", "final_error"))]
    if numeric:
        fig, ax = plt.subplots(figsize=(max(5, 1.6 * len(numeric) + 2), 4))
        x = np.arange(len(numeric))
        for i, (key, label) in enumerate(DIAG_COLUMNS[:3]):
            ax.bar(x + (i - 1) * 0.27, [_num(r.get(key)) or 0.0 for r in numeric], 0.27, label=label)
        ax.plot(x, [_num(r.get("noise_floor")) or np.nan for r in numeric], "k_", ms=30, mew=2, label="noise floor")
        ax.set_xticks(x, [f"{r['dataset']}\n{r['system']}" for r in numeric], fontsize=8)
        ax.set_ylabel("relative feature error")
        ax.set_title("Measured-data diagnosis: errors before / after")
        ax.legend(fontsize=8)
        ax.grid(axis="y", alpha=0.3)
        doc.add(Figure(figs.save(fig, "diagnosis-errors"), "Diagnosis: error with default parameters, after "
                                                          "calibration (before) and with the selected effect (after)."))
    _calibrated_tables(doc, reports, summary)
    _stage_figures(doc, figs, path, "diagnose", limit=8)


def _param_info(system: str) -> dict[str, tuple[float | None, str]]:
    """parameter -> (default, unit) of model ``system`` ({} when it is not a model name)."""
    try:
        import sim

        return {p.name: (p.default, p.unit) for p in sim.get_model(system).params}
    except Exception:  # noqa: BLE001 - a report of an unknown system still lists its values
        return {}


UNIDENTIFIABLE_SPAN = 100.0
"""A parameter whose 95 % interval spans more than this factor (two decades) is flagged "not identifiable"."""


def calibrated_rows(rep: SystemReport) -> list[list]:
    """Rows (parameter, role, default, calibrated, ± sd, 95 % interval, unit) of one system's diagnosis, every value
    from the selected model's fit (the calibrated base parameters fitted together with the selected effect, then the
    effect's own), else from the base fit; an interval wider than UNIDENTIFIABLE_SPAN says "not identifiable"."""
    info = _param_info(rep.system)
    cal = rep.calibrated
    block = rep.selected_params
    with_effect = block is not None
    if block is None:
        block = rep.calibrated_uncertainty
    rows = []
    for name, d in block.items():
        adopted = PARAM_OF.get(name, name) in (rep.proposal_adopted or ())    # a term, or the mode's
        added = "adopted discrepancy term" if adopted else "selected effect"
        role = ("calibrated (with the effect)" if name in cal else added) if with_effect else "calibrated"
        default, unit = info.get(name, (None, ""))
        ci = d.ci95 if d.ci95 is not None and len(d.ci95) == 2 else None
        span = None
        if ci:
            span = f"{fmt(ci[0])} .. {fmt(ci[1])}"
            lo, hi = (float(x) for x in ci)
            if lo <= 0 or hi / lo > UNIDENTIFIABLE_SPAN:
                span = f"not identifiable ({span})"
        rows.append([name, role, default, d.value, d.sd, span, unit])
    return rows


def _calibrated_tables(doc: Document, reports: dict[str, DiagnoseReport], summary: dict) -> None:
    """The diagnosis's calibrated parameters (and the selected effect's) per dataset and system, with the
    model defaults next to them: what a rig file of the measured machine would hold."""
    out = {}
    for name, rep in reports.items():
        for r in rep.systems:
            system = r.system
            rows = calibrated_rows(r)
            if not rows:
                continue
            out[f"{name}/{system}"] = {row[0]: row[3] for row in rows}
            doc.add(Table(["parameter", "role", "default", "calibrated", "± sd", "95 % interval", "unit"], rows,
                          f"Calibrated parameters: {name}, {system} (SI units; sd from the fit's Jacobian)"))
    if out:
        summary["diagnose_calibrated"] = out


from pipeline.report.closed_loop import section_closed_loop  # noqa: E402  (closing the loop)

SECTIONS = (section_sweep, section_train, section_optimise, section_verify, section_diagnose, section_closed_loop)


def build_report(inp: ReportInputs, out: Path) -> ReportResult:
    """Write ``report.md``, ``report.html``, ``figures/`` and ``summary.json`` into ``out``."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: exists and is not a directory")
    figdir = out / "figures"
    if figdir.is_dir():
        shutil.rmtree(figdir)
    figs = _Figs(out, inp.dpi)
    doc = Document(inp.title)
    from pipeline.core.params import read_params

    params = read_params(inp.p(inp.params), missing_ok=True)
    sw = params.get("sweep") or {}
    doc.add(Para(f"Model `{sw.get('model', '?')}`, preset `{sw.get('preset')}`; parameters from "
                 f"`{inp.params}` (every value is also logged to MLflow).  Produced by `vibro report`."))
    summary: dict = {}
    for section in SECTIONS:
        section(doc, figs, inp, summary)
    from pipeline.report.answer import answer_line, summary_lines

    top = summary_lines(summary)
    if top:     # the answer above the evidence: the corrected rig's first when the loop was closed
        doc.blocks[1:1] = [Heading("Answer")] + [Para(f"**{ln}**" if ln.startswith("Answer") else ln) for ln in top]
    md = to_markdown(doc, out)
    page = to_html(doc)
    atomic_write_text(out / "report.md", md)
    atomic_write_text(out / "report.html", page)
    line = answer_line(summary, "report.html")     # beside summary.json: ``out`` may be a temporary folder
    if line:
        summary["answer"] = line
    atomic_write_text(out / "summary.json", dump_json(summary))
    return ReportResult(out / "report.md", out / "report.html", summary, figs.paths)


def finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
