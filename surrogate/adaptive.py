"""Adaptive sampling: ask the simulator for new points where the surrogate is least sure.

Acquisition over a Sobol candidate pool (unit cube):
  boundary term  = 1 - (p1 - p2)  (p1, p2 = the two largest regime probabilities: 1 at a regime boundary)
  ROP term       = spread (std) of a bagged ensemble of ROP regressors (log units) where the
                   classifier expects progression, scaled to [0, 1]
  score = w * boundary + (1 - w) * ROP term; each batch is picked greedily, the score of a
  candidate being damped near points already chosen (distance in the unit cube) so a batch spreads out.
The comparison against the space-filling design uses the same held-out split and the same
model types for both: held-out error against the number of simulations.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import qmc
from tqdm.auto import tqdm

from vibrobase.unitcube import from_unit
from surrogate import selection
from surrogate.config import AdaptiveConfig, TrainConfig
from surrogate.data import domain_mask, regime_of
from surrogate.features import InputScaler


def _sobol(n: int, d: int, seed: int) -> np.ndarray:
    m = int(np.ceil(np.log2(max(n, 2))))
    return qmc.Sobol(d, scramble=True, seed=seed).random_base2(m)[:n]


def _to_table(U: np.ndarray, scaler: InputScaler) -> pd.DataFrame:
    cols = {}
    for j, n in enumerate(scaler.inputs):
        lo, hi = scaler.ranges[n]
        cols[n] = from_unit(U[:, j], lo, hi, scaler.scale.get(n) == "log" and lo > 0)
    return pd.DataFrame(cols)


def acquisition(Xs_train: np.ndarray, df_train: pd.DataFrame, U: np.ndarray, clf_name: str, reg_name: str,
                cfg: TrainConfig, rng: np.random.Generator) -> np.ndarray:
    """Score of every candidate row of U (higher = more informative)."""
    a = cfg.adaptive
    regimes = regime_of(df_train).to_numpy()
    clf = selection.fit_classifier(clf_name, Xs_train, regimes, cfg.seed)
    P = clf.predict_proba(U)
    Ps = np.sort(P, axis=1)
    boundary = 1.0 - (Ps[:, -1] - (Ps[:, -2] if P.shape[1] > 1 else 0.0))
    cls = list(clf.classes_)
    p_prog = P[:, cls.index("progressing")] if "progressing" in cls else np.zeros(len(U))
    m = domain_mask(df_train, "rop_m_s", "progressing")
    spread = np.zeros(len(U))
    if m.sum() >= 8:
        X, z = Xs_train[m], np.log10(df_train["rop_m_s"].to_numpy(float)[m])
        preds = []
        for k in range(a.ensemble):
            idx = rng.integers(0, len(z), len(z))
            est = selection.fit_regressor(reg_name, X[idx], z[idx], cfg.seed + k, cfg.max_gp_points)
            preds.append(est.predict(U))
        spread = np.std(preds, axis=0) * p_prog
        spread = spread / spread.max() if spread.max() > 0 else spread
    return a.boundary_weight * boundary + (1.0 - a.boundary_weight) * spread


def pick(score: np.ndarray, U: np.ndarray, taken: np.ndarray, k: int) -> np.ndarray:
    """Greedy batch: best score, damped by 1 - exp(-(d / r)^2) to the points already in the design."""
    r = 0.5 / max(len(taken) + k, 1) ** (1.0 / U.shape[1])
    d = np.min(np.linalg.norm(U[:, None, :] - taken[None, :, :], axis=2), axis=1) if len(taken) else np.full(len(U), np.inf)
    chosen = []
    avail = np.ones(len(U), bool)
    for _ in range(k):
        s = np.where(avail, score * (1.0 - np.exp(-(d / r) ** 2)), -np.inf)
        i = int(np.argmax(s))
        chosen.append(i)
        avail[i] = False
        d = np.minimum(d, np.linalg.norm(U - U[i], axis=1))
    return np.array(chosen)


def _errors(bundle_like, df_train: pd.DataFrame, test: pd.DataFrame, cfg: TrainConfig) -> dict:
    from surrogate.train import evaluate, refit_same

    ev = evaluate(refit_same(bundle_like, df_train, cfg), test)
    rop = ev["targets"].get("rop_m_s", {})
    return {"n_sims": int(len(df_train)), "error": 1.0 - ev["classification"]["accuracy"],
            "accuracy": ev["classification"]["accuracy"], "rop_m_s_rmse": rop.get("rmse"), "rop_m_s_r2": rop.get("r2")}


def run(bundle, space_filling: pd.DataFrame, test: pd.DataFrame, cfg: TrainConfig, simulate, progress: bool = False,
        ) -> dict:
    """Grow a design adaptively with ``simulate(table) -> labelled frame`` and compare it with ``space_filling``
    (the training split in point order) on the held-out ``test`` split, at equal numbers of simulations."""
    a: AdaptiveConfig = cfg.adaptive
    scaler: InputScaler = bundle.scaler
    d = len(scaler.inputs)
    rng = np.random.default_rng(cfg.seed)
    pool = _sobol(a.pool, d, cfg.seed + 1)
    design = space_filling.iloc[:a.initial].reset_index(drop=True)
    sizes = list(range(a.initial, a.budget + 1, a.batch))
    adaptive_curve, sf_curve = [], []
    bar = tqdm(sizes, desc="adaptive sampling", disable=not progress, leave=False)
    for n in bar:
        if len(design) < n:
            Xs = scaler.transform(design)
            score = acquisition(Xs, design, pool, bundle.classifier_name, "gbt", cfg, rng)
            idx = pick(score, pool, Xs, n - len(design))
            new = simulate(_to_table(pool[idx], scaler))
            pool = np.delete(pool, idx, axis=0)
            design = pd.concat([design, new[design.columns.intersection(new.columns)]], ignore_index=True)
        adaptive_curve.append(_errors(bundle, design, test, cfg))
        if n <= len(space_filling):
            sf_curve.append(_errors(bundle, space_filling.iloc[:n], test, cfg))
        bar.set_postfix_str(f"{n} sims")
    return {"adaptive": adaptive_curve, "space_filling": sf_curve, "savings": savings(adaptive_curve, sf_curve),
            "design": design}


def _sims_to_reach(curve: list[dict], key: str, level: float) -> float | None:
    """Simulations the curve needs to bring ``key`` down to ``level`` (log-linear interpolation; None if never)."""
    pts = [(c["n_sims"], c[key]) for c in curve if c.get(key) is not None]
    for (n0, e0), (n1, e1) in zip(pts, pts[1:]):
        if e1 <= level < e0 and e0 > 0 and e1 > 0:
            w = (np.log(e0) - np.log(level)) / (np.log(e0) - np.log(e1))
            return float(n0 + w * (n1 - n0))
    if pts and pts[0][1] <= level:
        return float(pts[0][0])
    return None


def savings(adaptive: list[dict], space_filling: list[dict]) -> dict:
    """For each error measure: the adaptive design's final error, the simulations it used, and the number
    the space-filling design needs for the same held-out error (None if it never gets there)."""
    out = {}
    for key in ("rop_m_s_rmse", "error"):
        if not adaptive or adaptive[-1].get(key) is None:
            continue
        level = adaptive[-1][key]
        n_ad = _sims_to_reach(adaptive, key, level)
        n_sf = _sims_to_reach(space_filling, key, level)
        out[key] = {"level": level, "adaptive_sims": n_ad, "space_filling_sims": n_sf,
                    "saved": (n_sf - n_ad) if (n_sf is not None and n_ad is not None) else None,
                    "space_filling_error_at_same_sims": next((c[key] for c in space_filling
                                                              if c["n_sims"] == adaptive[-1]["n_sims"]), None)}
    return out
