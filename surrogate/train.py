"""``train_bundle``: held-out split, CV model selection, conformal intervals, held-out report, learning curve."""
from __future__ import annotations

import numpy as np
import pandas as pd
from sklearn.model_selection import train_test_split
from joblib import delayed
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

from surrogate.errors import DataError
from surrogate import metrics, selection
from surrogate.bundle import Bundle, TargetModel
from surrogate.config import TrainConfig
from surrogate.data import domain_mask, fingerprint_frame, regime_of
from sklearn.dummy import DummyRegressor

from surrogate.features import InputScaler, TargetTransform, decades, is_constant
from surrogate.intervals import ConformalInterval

MIN_POINTS = 12   # fewer points in a target's domain: the target is not learned


def with_power(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with a ``power_w`` column [W] = energy_per_cycle_j × frequency_hz when it lacks one but has both
    (sweeps made before sim returned power_w)."""
    if "power_w" in df.columns or not {"energy_per_cycle_j", "frequency_hz"} <= set(df.columns):
        return df
    e = pd.to_numeric(df["energy_per_cycle_j"], errors="coerce")
    return df.assign(power_w=e * pd.to_numeric(df["frequency_hz"], errors="coerce"))


def split(df: pd.DataFrame, regimes: np.ndarray, fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices (train, held-out), stratified by regime where every regime has >= 2 points."""
    idx = np.arange(len(df))
    counts = pd.Series(regimes).value_counts()
    strat = regimes if counts.min() >= 2 else None
    tr, te = train_test_split(idx, test_size=fraction, random_state=seed, stratify=strat)
    return np.sort(tr), np.sort(te)


def split_frame(df: pd.DataFrame, cfg: TrainConfig) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(train, held-out) frames of a sweep frame, in point order — the split ``train_bundle`` uses."""
    df = df.reset_index(drop=True)
    if "point_id" in df.columns:
        df = df.sort_values("point_id", kind="stable").reset_index(drop=True)
    tr, te = split(df, regime_of(df).to_numpy(), cfg.test_fraction, cfg.seed)
    return df.iloc[tr].reset_index(drop=True), df.iloc[te].reset_index(drop=True)


CV_CHECK_DECADES = (0.5, 3.0)
"""Positive targets spanning this many decades (around the 1-decade range rule) get the CV check of the
transform: the cheapest candidate is cross-validated on log10(y) and on y, and the lower CV RMSE in the
target's own units decides.  Below 0.5 decade a log scale changes little; above 3 the rule is never wrong."""


def _check_candidate(cfg: TrainConfig) -> str:
    return "gbt" if "gbt" in cfg.regressors else cfg.regressors[0]


def choose_transform(t: str, Xs: np.ndarray, y: np.ndarray, cfg: TrainConfig) -> tuple[TargetTransform, dict]:
    """The target's scale: ``train.transforms`` if set, else the range rule (log above LOG_RULE_DECADES) checked
    by cross-validation in the CV_CHECK_DECADES band.  Returns (transform, how it was chosen)."""
    asked = cfg.transforms.get(t, "auto")
    d = decades(y)
    rule = TargetTransform.choose(y, asked)
    how = {"asked": asked, "decades": d, "rule": rule.kind}
    if asked != "auto" or d is None or not CV_CHECK_DECADES[0] <= d <= CV_CHECK_DECADES[1]:
        how["chosen"] = rule.kind
        return rule, how
    name = _check_candidate(cfg)
    rmse = {}
    for kind in ("log", "identity"):
        tf = TargetTransform(kind)
        sel = selection.select_regressor([name], Xs, tf.forward(y), tf, cfg.cv_folds, cfg.seed, cfg.max_gp_points,
                                         cfg.workers, final=False)
        rmse[kind] = sel.scores_original[name]
    chosen = min(rmse, key=rmse.get)
    how.update({"cv_candidate": name, "cv_rmse": rmse, "chosen": chosen})
    return TargetTransform(chosen), how


def _constant_target(t: str, y: np.ndarray, cfg: TrainConfig) -> tuple[TargetModel, dict]:
    """A target with one value in the data: predicted as that value (interval of zero width), reported as
    constant rather than scored against an R² goal it cannot have."""
    value = float(np.mean(y))
    est = DummyRegressor(strategy="constant", constant=value).fit(np.zeros((y.size, 1)), y)
    iv = ConformalInterval(0.0, False, cfg.interval, int(y.size))
    info = {"model": "constant", "transform": "identity", "constant": value, "n_train": int(y.size),
            "interval_q": 0.0, "interval_normalised": False}
    return TargetModel(t, "constant", est, TargetTransform("identity"), iv, cfg.domains[t]), info


def _fit_target(t: str, Xs: np.ndarray, y: np.ndarray, cfg: TrainConfig, progress) -> tuple[TargetModel, dict]:
    if is_constant(y):
        return _constant_target(t, y, cfg)
    tf, how = choose_transform(t, Xs, y, cfg)
    z = tf.forward(y)
    sel = selection.select_regressor(cfg.regressors, Xs, z, tf, cfg.cv_folds, cfg.seed, cfg.max_gp_points, cfg.workers)
    est = sel.fitted if sel.fitted is not None else selection.fit_regressor(sel.name, Xs, z, cfg.seed,
                                                                            cfg.max_gp_points)
    iv = ConformalInterval.calibrate(z, sel.oof, sel.oof_std, cfg.interval)
    info = {"model": sel.name, "transform": tf.kind, "transform_choice": how, "cv_rmse_transformed": sel.scores,
            "cv_rmse": sel.scores_original, "cv_skipped": sel.errors,
            "n_train": int(y.size), "interval_q": iv.q, "interval_normalised": iv.normalised}
    if progress:
        progress.set_postfix_str(f"{t}: {sel.name}")
    return TargetModel(t, sel.name, est, tf, iv, cfg.domains[t]), info


def evaluate(bundle: Bundle, df: pd.DataFrame) -> dict:
    """Held-out metrics of ``bundle`` on the rows of ``df`` (true regimes / domains)."""
    pred = bundle.predict(df, conditional=True)
    reg = regime_of(df).to_numpy()
    out = {"classification": metrics.classification(reg, pred["regime"].to_numpy(), list(bundle.classes)),
           "targets": {}}
    for t, tm in bundle.regressors.items():
        m = domain_mask(df, t, tm.domain)
        y = df[t].to_numpy(dtype=float)[m]
        out["targets"][t] = metrics.regression(y, pred[t].to_numpy()[m], pred[f"{t}_lo"].to_numpy()[m],
                                               pred[f"{t}_hi"].to_numpy()[m])
        if tm.transform.kind == "log":   # R² of log10 values: meaningful where a few huge values rule the variance
            out["targets"][t]["r2_log10"] = metrics.regression(np.log10(y), np.log10(pred[t].to_numpy()[m])).get("r2")
        out["targets"][t]["domain"] = tm.domain
    return out


def fit(df: pd.DataFrame, inputs: list[str], ranges: dict, scale: dict, model: str, preset: str | None,
        cfg: TrainConfig, fingerprint: str, progress: bool = False) -> tuple[Bundle, dict]:
    """Select and fit every model on all rows of ``df`` (no held-out evaluation)."""
    scaler = InputScaler(list(inputs), {k: tuple(map(float, v)) for k, v in ranges.items()}, dict(scale))
    Xs = scaler.transform(df)
    regimes = regime_of(df).to_numpy()
    steps = [None] + [t for t in cfg.targets]
    bar = tqdm(steps, desc="train", disable=not progress, leave=False)
    info: dict = {"targets": {}, "skipped_targets": {}}
    regs: dict[str, TargetModel] = {}
    for step in bar:
        if step is None:
            cs = selection.select_classifier(cfg.classifiers, Xs, regimes, cfg.cv_folds, cfg.seed, cfg.workers)
            clf = selection.fit_classifier(cs.name, Xs, regimes, cfg.seed)
            info["classifier"] = {"model": cs.name, "cv_accuracy": cs.scores, "cv_skipped": cs.errors,
                                  "classes": cs.classes}
            continue
        if step not in df.columns:   # e.g. a sweep made before the label existed: say so, learn the rest
            info["skipped_targets"][step] = f"the dataset has no column '{step}'"
            continue
        m = domain_mask(df, step, cfg.domains[step])
        if m.sum() < MIN_POINTS:
            info["skipped_targets"][step] = f"only {int(m.sum())} training points in domain '{cfg.domains[step]}'"
            continue
        y = df[step].to_numpy(dtype=float)[m]
        regs[step], info["targets"][step] = _fit_target(step, Xs[m], y, cfg, bar)
    b = Bundle(inputs=list(inputs), ranges=scaler.ranges, model=model, preset=preset, fingerprint=fingerprint,
               scaler=scaler, classifier=clf, classifier_name=info["classifier"]["model"],
               classes=[str(c) for c in clf.classes_], regressors=regs, config=cfg.to_dict())
    return b, info


def refit_same(bundle: Bundle, df: pd.DataFrame, cfg: TrainConfig) -> Bundle:
    """The bundle's selected model types refitted on ``df`` (no CV; intervals kept) — for learning curves."""
    Xs = bundle.scaler.transform(df)
    regimes = regime_of(df).to_numpy()
    clf = selection.fit_classifier(bundle.classifier_name, Xs, regimes, cfg.seed)
    regs = {}
    for t, tm in bundle.regressors.items():
        m = domain_mask(df, t, tm.domain)
        if m.sum() < 3:
            continue
        z = tm.transform.forward(df[t].to_numpy(dtype=float)[m])
        if tm.name == "constant":
            est = DummyRegressor(strategy="constant", constant=float(np.mean(z))).fit(Xs[m], z)
        else:
            est = selection.fit_regressor(tm.name, Xs[m], z, cfg.seed, cfg.max_gp_points)
        regs[t] = TargetModel(t, tm.name, est, tm.transform, tm.interval, tm.domain)
    return Bundle(bundle.inputs, bundle.ranges, bundle.model, bundle.preset, bundle.fingerprint, bundle.scaler, clf,
                  bundle.classifier_name, [str(c) for c in clf.classes_], regs, {}, bundle.config, bundle.fixed,
                  bundle.settings)


def _curve_point(bundle: Bundle, train: pd.DataFrame, test: pd.DataFrame, cfg: TrainConfig, n: int) -> dict:
    """Held-out scores of the bundle's model types refitted on the first ``n`` training rows (on all of them:
    the bundle itself, which is that refit)."""
    b = bundle if n == len(train) else refit_same(bundle, train.iloc[:n], cfg)
    ev = evaluate(b, test)
    row = {"n_train": n, "accuracy": ev["classification"]["accuracy"]}
    for t, m in ev["targets"].items():
        row[f"{t}_r2"] = m.get("r2")
        row[f"{t}_rmse"] = m.get("rmse")
    return row


def learning_curve(bundle: Bundle, train: pd.DataFrame, test: pd.DataFrame, cfg: TrainConfig,
                   progress: bool = False) -> list[dict]:
    """Held-out error of the selected model types against the number of training simulations.

    Subsets are prefixes of the training split in point order (a Sobol design's prefix stays space-filling);
    the sizes are fitted in ``cfg.workers`` processes, largest first (the costliest start first)."""
    sizes = sorted({min(len(train), max(MIN_POINTS * 2, int(round(f * len(train))))) for f in cfg.learning_curve},
                   reverse=True)
    jobs = (delayed(_curve_point)(bundle, train, test, cfg, n) for n in sizes)
    rows = list(tqdm(selection.parallel(cfg.workers, return_as="generator")(jobs), total=len(sizes),
                     desc="learning curve", disable=not progress, leave=False))
    return rows[::-1]


def needed(curve: list[dict], key: str, goal: float) -> int | None:
    """Smallest training size on the curve from which ``key`` stays >= goal (None if never)."""
    ok = [r["n_train"] for r in curve if r.get(key) is not None and r[key] >= goal]
    if not ok:
        return None
    last_bad = max([r["n_train"] for r in curve if r.get(key) is None or r[key] < goal], default=0)
    later = [n for n in ok if n > last_bad]
    return min(later) if later else None


def train_bundle(df: pd.DataFrame, inputs: list[str], ranges: dict, model: str, preset: str | None,
                 config: TrainConfig | dict | None = None, scale: dict | None = None, fingerprint: str | None = None,
                 progress: bool = False, fixed: dict | None = None, settings: dict | None = None,
                 extra: pd.DataFrame | None = None) -> Bundle:
    """Train the surrogate on a sweep frame: hold out ``test_fraction`` (never trained on), select
    every model by CV on the rest, calibrate 90 % intervals, and put the held-out report in ``bundle.report``.
    ``fixed`` / ``settings``: the sweep's fixed parameters and simulator settings, carried by the bundle so
    optimisation and verification simulate under the conditions the surrogate learned.
    ``extra``: rows always trained on, never held out (points simulated where an optimiser looked); the
    held-out report stays on the sweep's own design."""
    cfg = config if isinstance(config, TrainConfig) else TrainConfig.from_dict(config)
    with threadpool_limits(cfg.threads):
        bundle = _train_bundle(df, inputs, ranges, model, preset, cfg, scale, fingerprint, progress, extra)
    bundle.fixed, bundle.settings = dict(fixed or {}), dict(settings or {})
    bundle.report.update({"fixed": bundle.fixed, "settings": bundle.settings})
    return bundle


def _train_bundle(df, inputs, ranges, model, preset, cfg: TrainConfig, scale, fingerprint, progress,
                  extra: pd.DataFrame | None = None) -> Bundle:
    df = with_power(df.reset_index(drop=True))
    if "point_id" in df.columns:
        df = df.sort_values("point_id", kind="stable").reset_index(drop=True)
    scale = scale or {n: "linear" for n in inputs}
    fingerprint = fingerprint or fingerprint_frame(df if extra is None else pd.concat([df, extra], ignore_index=True))
    regimes = regime_of(df).to_numpy()
    if len(df) < 4 * MIN_POINTS:
        raise DataError(f"dataset has {len(df)} points; the surrogate needs at least {4 * MIN_POINTS}")
    train, test = split_frame(df, cfg)
    if extra is not None and len(extra):
        train = pd.concat([train, with_power(extra.reset_index(drop=True))], ignore_index=True)
    bundle, info = fit(train, inputs, ranges, scale, model, preset, cfg, fingerprint, progress)
    held = evaluate(bundle, test)
    curve = learning_curve(bundle, train, test, cfg, progress) if cfg.learning_curve else []
    g = cfg.goals
    goals = {"rop_m_s_r2": g.get("rop_m_s_r2"), "peak_force_n_r2": g.get("peak_force_n_r2"),
             "accuracy": g.get("accuracy")}
    tg = held["targets"]
    constant = {t: i["constant"] for t, i in info["targets"].items() if i.get("model") == "constant"}
    need = {k: needed(curve, k, v) for k, v in goals.items()
            if v is not None and not (k.endswith("_r2") and k[:-3] in constant)}
    cov = [m.get("coverage") for t, m in tg.items() if m.get("coverage") is not None and t not in constant]
    notes: dict[str, str] = {}

    def r2_goal(target: str):
        """True/False against the goal; None (with a note) where R² is undefined: a constant target."""
        m = tg.get(target, {})
        if target in constant or (m.get("n") and m.get("r2") is None):
            value = constant.get(target)
            notes[f"{target}_r2"] = (f"constant in the data ({value:.6g}): nothing to learn, predicted exactly"
                                     if value is not None else "constant in the held-out data: R² undefined")
            return None
        return (m.get("r2") if m.get("r2") is not None else -np.inf) >= goals[f"{target}_r2"]

    classes = held["classification"].get("classes") or []
    if len(classes) <= 1:
        notes["accuracy"] = f"one regime in the data ({', '.join(classes) or 'none'}): no classification to assess"
    if not cov:
        notes["coverage"] = "no target with a varying value to cover"
    met = {
        "rop_m_s_r2": r2_goal("rop_m_s"),
        "peak_force_n_r2": r2_goal("peak_force_n"),
        "accuracy": None if "accuracy" in notes else (held["classification"]["accuracy"] or 0) >= goals["accuracy"],
        "coverage": None if not cov else all(g["coverage_low"] <= c <= g["coverage_high"] for c in cov),
    }
    bundle.report = {"model": model, "preset": preset, "fingerprint": fingerprint, "inputs": list(inputs),
                     "ranges": {k: list(v) for k, v in bundle.ranges.items()},
                     "n_points": int(len(df)), "n_train": int(len(train)), "n_test": int(len(test)),
                     "regime_counts": {k: int(v) for k, v in pd.Series(regimes).value_counts().items()},
                     "selection": info, "held_out": held, "learning_curve": curve,
                     "simulations_needed": need, "goals": g, "goals_met": {k: (None if v is None else bool(v)) for k, v in met.items()},
                     "goals_notes": notes, "constant_targets": constant,
                     "interval_level": cfg.interval}
    if extra is not None and len(extra):
        bundle.report["n_extra"] = int(len(extra))
    return bundle
