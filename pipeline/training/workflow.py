"""``load_training_data`` and ``run_training``: what ``vibro train`` does after parsing.

The command loads and checks the dataset (:func:`load_training_data`, UserErrors before anything is written),
then calls :func:`run_training` into its temporary output folder inside its MLflow run, logs and prints the
:class:`TrainResult`.  Imports ``surrogate`` (the library) and ``pipeline.datasets`` (the sweep store).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from pipeline.core.errors import UserError


@dataclass(frozen=True)
class TrainingData:
    """A checked sweep dataset and what the surrogate learns from it."""
    source: str                       # the dataset folder (messages)
    df: pd.DataFrame
    meta: dict                        # the sweep's metadata.json ({} without one)
    model: str
    preset: str | None
    inputs: list[str]
    ranges: dict
    fingerprint: str


def load_training_data(dataset: str, model: str | None = None, inputs: list[str] | None = None) -> TrainingData:
    """Load sweep ``dataset``, check its labels, its model against ``model`` and infer the inputs and ranges."""
    from pipeline.datasets.store import load_with_metadata
    from pipeline.training import rows
    from surrogate import data

    df, meta = load_with_metadata(dataset)
    df = data.check_frame(df, f"dataset '{dataset}'")
    name = meta.get("model") or model
    if not name:
        raise UserError(f"dataset '{dataset}' has no metadata.json naming its model: pass --model")
    if model and meta.get("model") and model != meta["model"]:
        raise UserError(f"--model {model} but dataset '{dataset}' was simulated with model '{meta['model']}'")
    where = f"dataset '{dataset}'"
    rows.check_not_labels(list(inputs or meta.get("vary") or []), where)
    names, ranges = data.infer_inputs(df, meta, inputs)
    rows.check_inputs(df, names, meta, name, where)      # refused before the ranges are trusted
    rows.check_labels(df, where)
    fp = meta.get("fingerprint") or data.fingerprint_frame(df)
    return TrainingData(str(dataset), df, meta, name, meta.get("preset"), names, ranges, fp)


def simulator(model: str, preset, meta: dict, rig=None):
    """table of inputs -> labelled frame, with the sweep's fixed parameters and settings (with ``rig``: the
    rig's preset, parameters and effects instead of the sweep's preset and fixed parameters)."""
    import sim

    fixed = meta.get("fixed") or {}
    settings = meta.get("settings") or None
    if rig is not None:
        preset, fixed = rig.preset, rig.overrides()

    def run(table):
        for k, v in fixed.items():
            if k not in table.columns:
                table[k] = v
        return sim.simulate_batch(model, table, preset=preset, settings=settings)

    return run


def retrain(data: TrainingData, cfg, extra: pd.DataFrame, progress: bool = False):
    """The surrogate of ``data`` (its sweep, inputs, ranges and conditions) retrained with ``cfg`` (a
    ``surrogate.config.TrainConfig``) on the sweep plus ``extra``: simulated rows (e.g. a feedback file's), always
    trained on, never held out.  Rows of ``extra`` outside the sweep's ranges are left out (the surrogate's box
    stays the sweep's); UserError naming a label no simulator writes."""
    import numpy as np

    from pipeline.training import rows
    from surrogate import data as sdata
    from surrogate.train import train_bundle

    keep = np.ones(len(extra), dtype=bool)
    for n, (lo, hi) in data.ranges.items():
        x = pd.to_numeric(extra[n], errors="coerce").to_numpy(dtype=float)
        tol = rows.RANGE_RTOL * (hi - lo)
        keep &= (x >= lo - tol) & (x <= hi + tol)
    extra = extra.loc[keep, [c for c in data.df.columns if c in extra.columns and c != "point_id"]]
    rows.check_labels(extra, "extra training rows")
    fp = f"{data.fingerprint}+{sdata.fingerprint_frame(extra.reset_index(drop=True))[:16]}"
    return train_bundle(data.df, data.inputs, data.ranges, data.model, data.preset, cfg,
                        scale=sdata.scales(data.meta, data.inputs), fingerprint=fp, progress=progress,
                        fixed=data.meta.get("fixed"), settings=data.meta.get("settings"), extra=extra)


@dataclass(frozen=True)
class TrainResult:
    """The trained bundle (saved), the adaptive study (None without --adaptive), the figures written,
    the flat metrics (MLflow) and the headline metrics (the --metrics file)."""
    bundle: object
    adaptive: dict | None
    figures: dict[str, str]
    flat_metrics: dict[str, float]
    headline: dict


def run_training(data: TrainingData, cfg, out_dir: str | Path, rig=None, progress: bool = True,
                 provenance: dict | None = None) -> TrainResult:
    """Train the surrogate of ``data`` with ``cfg`` (a ``surrogate.config.TrainConfig``), run the adaptive study
    when enabled (simulating on ``rig`` if given), save the bundle, report and figures under ``out_dir``.
    ``provenance`` (e.g. the rig file and the chain) is recorded in the bundle's report."""
    from vibrobase.files import atomic_write_parquet
    from surrogate import adaptive as adaptive_mod
    from surrogate import data as sdata
    from surrogate import report
    from surrogate.selection import release_workers
    from surrogate.train import split_frame, train_bundle

    out = Path(out_dir)
    meta = data.meta
    bundle = train_bundle(data.df, data.inputs, data.ranges, data.model, data.preset, cfg,
                          scale=sdata.scales(meta, data.inputs), fingerprint=data.fingerprint, progress=progress,
                          fixed=meta.get("fixed"), settings=meta.get("settings"))
    release_workers()       # the fitting processes' CPU counts in the command's "done in" line
    train, test = split_frame(data.df, cfg)
    ad = None
    if cfg.adaptive.enabled:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(cfg.threads):
            ad = adaptive_mod.run(bundle, train, test, cfg, simulator(data.model, data.preset, meta, rig),
                                  progress=progress)
        design = ad.pop("design")
        atomic_write_parquet(out / "adaptive_design.parquet", design)
        bundle.report["adaptive"] = ad
    bundle.report.update(provenance or {})
    bundle.save(out)
    from pipeline.core.units import ENGINEERING

    figs = report.figures(bundle, test, out, ad, units=ENGINEERING)
    r = bundle.report
    headline = {"held_out": r["held_out"], "goals_met": r["goals_met"],
                "goals_notes": r.get("goals_notes", {}),
                "constant_targets": r.get("constant_targets", {}),
                "transforms": {t: i.get("transform_choice") for t, i in
                               r["selection"]["targets"].items() if i.get("transform_choice")},
                "simulations_needed": r["simulations_needed"], "n_train": r["n_train"],
                "n_test": r["n_test"], "adaptive_savings": (ad or {}).get("savings")}
    return TrainResult(bundle, ad, figs, report.flat_metrics(r), headline)
