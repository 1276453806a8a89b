"""Errors on held-out runs: noise-normalised (nrms, χ²), relative against the noise floor (both noise-weighted, so
their ratio is the nrms), and systematic (from the
records' halves); ``fold_errors`` accumulates them over the folds of a diagnosis for any set of fitted models."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pipeline.diagnosis.model import Evaluator
from pipeline.diagnosis.nuisance import calibration_chains
from pipeline.diagnosis.verdict import ModelStats


@dataclass(frozen=True)
class HeldOut:
    """A model's errors on held-out runs (noise-normalised residuals; see ``heldout_errors``)."""

    nrms: float
    """sqrt(χ² / n) [-]: 1 is the noise level."""
    chi2: float
    """Sum of squared normalised residuals [-]."""
    n: int
    """Residuals compared."""
    by_run_nrms: dict[str, float]
    """nrms per run id [-]."""
    error: float | None
    """||r|| / ||y/sd|| [-] (None: a signal of zeros)."""
    noise_floor: float | None
    """The same for a residual of pure noise [-]."""
    error_by_group: dict[str, float | None]
    """``error`` per feature group [-]."""
    noise_by_group: dict[str, float | None]
    """``noise_floor`` per feature group [-]."""
    systematic: float | None = None
    """Relative systematic error from the records' halves [-] (None: no halves; ``systematic_error``)."""


def heldout_errors(ev: Evaluator, idx: list[int], res: list[np.ndarray]) -> HeldOut:
    """nrms, relative error and noise floor over runs ``idx`` given their noise-normalised residual vectors.

    All three are on the noise-weighted scale the verdict uses (each feature divided by its noise sd):
    ``error`` = ||r|| / ||y/sd|| (the residual relative to the measured features), ``noise_floor`` =
    sqrt(n) / ||y/sd|| (the same for a residual of pure noise), so ``error / noise_floor == nrms``.  A feature the
    noise swamps weighs little in both; a signal that is zero (a rig that does not progress) cannot divide by zero.
    Per feature group the same pair (``error_by_group``, ``noise_by_group``; None for a group of zeros)."""
    num, den, cnt = {}, {}, {}
    for i, r in zip(idx, res):
        tg = ev.targets[i]
        yw = tg.y / tg.sd
        for g in dict.fromkeys(tg.group):     # first-seen order: sums independent of hashing
            m = np.array([x == g for x in tg.group])
            num[g] = num.get(g, 0.0) + float((r[m] ** 2).sum())
            den[g] = den.get(g, 0.0) + float((yw[m] ** 2).sum())
            cnt[g] = cnt.get(g, 0) + int(m.sum())
    allr = np.concatenate(res) if res else np.zeros(1)
    by_run = {ev.targets[i].run_id: float(np.sqrt(np.mean(r ** 2))) for i, r in zip(idx, res)}
    signal = sum(den.values())

    def rel(x: float, d: float) -> float | None:
        return math.sqrt(x / d) if d > 0 else None
    return HeldOut(nrms=float(np.sqrt(np.mean(allr ** 2))), chi2=float(allr @ allr), n=int(allr.size),
                   by_run_nrms=by_run, error=rel(float(allr @ allr), signal), noise_floor=rel(float(allr.size), signal),
                   error_by_group={g: rel(num[g], den[g]) for g in num},
                   noise_by_group={g: rel(cnt[g], den[g]) for g in num})


def systematic_error(ev: Evaluator, idx: list[int], halves: list[np.ndarray | None]) -> float | None:
    """Relative systematic error of a model over the series runs ``idx`` from their records' halves.  Per feature
    group (signal) S/P = Σ r_A·r_B / Σ y² (r_A, r_B = model − measured features of each half: the noise of the two
    halves is independent and averages out of the product, a model error is in both — with either sign: an error that
    drifts over the record, as tip blunting's does, can flip sign between the halves), combined over the groups with
    inverse-variance weights (the product's noise, Σ 4 σ⁴ / P² with σ the features' noise sd, so a group the noise
    dominates — a displacement whose harmonics are small beside its drift — does not swamp the others); the square
    root of the weighted mean of the |S|/P.  None without halves.  A run the model could not simulate counts its
    features as the error."""
    num, den, var = {}, {}, {}
    for i, mh in zip(idx, halves):
        tg = ev.targets[i]
        if tg.y_halves is None:
            continue
        model = mh if mh is not None else np.zeros_like(tg.y_halves)
        ra, rb = model[0] - tg.y_halves[0], model[1] - tg.y_halves[1]
        for g in dict.fromkeys(tg.group):     # first-seen order: sums independent of hashing
            m = np.array([x == g for x in tg.group])
            num[g] = num.get(g, 0.0) + float(ra[m] @ rb[m])
            den[g] = den.get(g, 0.0) + 0.5 * float(tg.y_halves[0][m] @ tg.y_halves[0][m]
                                                   + tg.y_halves[1][m] @ tg.y_halves[1][m])
            var[g] = var.get(g, 0.0) + 4.0 * float(np.sum(tg.noise_sd[m] ** 4))
    if not num:
        return None
    ratio = {g: abs(num[g]) / max(den[g], 1e-300) for g in num}    # a drifting error flips sign between halves
    w = {g: 1.0 / max(var[g] / max(den[g], 1e-300) ** 2, 1e-30) for g in num}
    return float(math.sqrt(sum(w[g] * ratio[g] for g in num) / sum(w.values())))    # every |S|/P >= 0


def fold_errors(ev: Evaluator, folds, fold_fits: list[dict], names: list[str], fixed: dict[str, dict] | None = None
                ) -> tuple[dict[str, HeldOut], dict[str, ModelStats], list[int]]:
    """The models ``names`` of every fold's fits (``fold_fits[f][name]``, fitted on the fold's calibration runs)
    and the ``fixed`` parameter sets (name -> values, the same in every fold) judged on the folds' held-out runs: per
    model its errors (``heldout_errors`` and ``systematic``), per fitted model its ``ModelStats`` (BIC summed over
    the folds' calibration fits), and the held-out runs fold after fold."""
    fixed = fixed or {}
    every = [*fixed, *names]
    res = {m: [] for m in every}
    halves = {m: [] for m in every}
    idx: list[int] = []
    bic = {m: 0.0 for m in names}
    for (cal, test), fits in zip(folds, fold_fits):
        sets = [*fixed.values(), *(fits[m].values for m in names)]
        for m, (r, h) in zip(every, ev.held_out(sets, test, calibration_chains(ev, sets, cal))):
            res[m] += r
            halves[m] += h
        idx += test
        for m in names:
            bic[m] += fits[m].bic()
    err = {m: replace(heldout_errors(ev, idx, res[m]), systematic=systematic_error(ev, idx, halves[m])) for m in every}
    stats = {m: ModelStats(m, bic[m], err[m].chi2, err[m].n, err[m].systematic) for m in names}
    return err, stats, idx
