"""Discrepancy discovery: when no §6 effect explains a rig, propose the missing term from the model's vocabulary.

The vocabulary (``sim.models.discrepancy``) is a fixed set of terms at the contact force and on the impacting mass,
each a kernel parameter off at 0.  Discovery has two steps:

1. **Screening by sparse regression.**  At the calibrated base, the sensitivity of the calibration runs' residual
   to each term (a secant to a probe strength inside its fit bounds) and to each calibratable parameter is
   simulated in one batch.  The term columns are projected off the calibratable ones (what a recalibration can
   absorb is no evidence for a term), and the residual is regressed on them with a non-negative lasso path
   (scikit-learn's ``lars_path``); each support along the path is refitted without shrinkage (relaxed lasso), the
   one with the least BIC (noise variance 1: the residuals are noise-normalised) is the support, and the order of
   entry ranks the terms.  PySINDy-style regression on
   derivatives is not used: a rig records one or two channels of the impacting mass at any rate, not the states and
   their derivatives, and the contact switches make derivative estimates meaningless around every impact.
2. **Re-fit through the simulator.**  The support and the leading single terms (at most ``max_proposals`` sets),
   and every structured candidate of the model (the hidden load-path mode: nonlinear in its frequency, so it is no
   column of the regression and is fitted from a grid of its three parameters) are each fitted with the calibratable parameters on every fold's calibration runs by the §6 machinery
   (``calibrate.fit_added``: a grid start and the regression's estimate) and judged on the held-out runs by the
   verdict rule of the effects: a proposal is *accepted* when it improves on the base materially and brings the
   held-out nrms within ``explained_nrms`` (2 = twice the noise).  The regression only chooses what to fit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Collection

import numpy as np

from pipeline.core.executors import Executor
from pipeline.diagnosis.calibrate import calibration_basis, calibration_sets, fit_added
from pipeline.diagnosis.fit import FitResult
from pipeline.diagnosis.heldout import HeldOut
from pipeline.diagnosis.judge import Fitter, FoldScheme, Judged, judge
from pipeline.diagnosis.model import Evaluator, FreeParam, calibratable
from pipeline.diagnosis.verdict import Check, ModelStats
from sim.models.discrepancy import probe_value  # noqa: F401  (the strength the models' term bounds are chosen for)

if TYPE_CHECKING:
    from pipeline.diagnosis.config import DiagnoseConfig

MAX_SUPPORT = 2
"""At most this many terms in one proposal."""
PREFIX = "discrepancy:"
"""Model names of proposals in the diagnosis' fits: ``discrepancy:`` + the terms joined by ``+``."""
NUMBERS_PER_PARAM = 2
"""A proposal is fitted only where every fold's calibration runs hold at least this many measured numbers per free
parameter (calibratable + the proposal's): with fewer, a fit interpolates the data (the published seed-000 log, 4
runs of 2-3 numbers, one a lower bound, leaves 6 per fold, under 8 for one term on 3 calibratables), and its held-out
test is no evidence."""


def calibration_numbers(ev: Evaluator, scheme: FoldScheme) -> int:
    """Measured two-sided numbers (features that are not lower bounds) of the smallest fold's calibration runs."""
    return min(sum(int((~ev.targets[i].lower_bound).sum()) for i in cal) for cal, _ in scheme.folds)


def supported(cands: dict[str, tuple], n_numbers: int, n_calibratable: int) -> tuple[dict[str, tuple], list[str]]:
    """(the candidates the data can support by NUMBERS_PER_PARAM, the names of the others)."""
    ok = {m: ps for m, ps in cands.items() if n_numbers >= NUMBERS_PER_PARAM * (n_calibratable + len(ps))}
    return ok, [m for m in cands if m not in ok]


def term_candidates(system: str) -> dict[str, FreeParam]:
    """The discrepancy terms of ``system`` (one parameter each, screened by the regression) with their fit bounds
    (``ModelSpec.discrepancy_bounds``)."""
    import sim
    from sim.models.discrepancy import TERMS

    spec = sim.get_model(system)
    return {t: spec.discrepancy_bounds[t] for t in spec.discrepancy if t in TERMS}


def structured_candidates(system: str, steady: bool = True) -> dict[str, tuple[FreeParam, ...]]:
    """The structured candidates of ``system`` (``sim.models.discrepancy.STRUCTURED`` whose parameters the model
    has) -> their parameters' fit bounds; without the parameters that act only on steady-state records
    (``STEADY_ONLY``) unless the log has some (``steady``)."""
    import sim
    from sim.models.discrepancy import STEADY_ONLY, STRUCTURED

    spec = sim.get_model(system)
    return {n: tuple(spec.discrepancy_bounds[p] for p in c.params if steady or p not in STEADY_ONLY)
            for n, c in STRUCTURED.items() if all(p in spec.discrepancy for p in c.params)}


@dataclass(frozen=True)
class Screening:
    """The sparse regression's outcome: the terms in order of entry into the lasso path (then the others by
    ``score``), the support at the path's least BIC, each term's estimated strength [its unit] (0 off the support),
    ``score`` = |correlation| of its projected sensitivity with the residual, and the BIC of each support along the
    path (refitted without shrinkage; the first is the empty support)."""

    order: list[str]
    support: list[str]
    estimate: dict[str, float]
    score: dict[str, float]
    path_bic: list[float]


def screen(ev: Evaluator, idx: list[int], base: dict, terms: dict[str, FreeParam]) -> Screening:
    """Screen the ``terms`` on runs ``idx`` at the calibrated ``base`` parameters (one batch of simulations)."""
    from scipy.optimize import nnls
    from sklearn.linear_model import lars_path

    cal = list(calibratable(ev.system))
    names = list(terms)
    probes = {t: probe_value(terms[t]) for t in names}
    sets = calibration_sets(base, cal) + [{**base, t: probes[t]} for t in names]
    rs = ev.residuals(sets, idx)
    r0 = rs[0]
    q = calibration_basis(rs[:1 + len(cal)])
    jt = np.column_stack([r - r0 for r in rs[1 + len(cal):]])       # per unit of the probe strength
    jt = jt - q @ (q.T @ jt)                  # what a recalibration can absorb is no evidence for a term
    y = -(r0 - q @ (q.T @ r0))
    norms = np.linalg.norm(jt, axis=0)
    norms[norms == 0.0] = 1.0
    x = jt / norms
    yn = float(np.linalg.norm(y)) or 1.0
    score = {t: float(abs(x[:, j] @ y) / yn) for j, t in enumerate(names)}
    _, active, coefs = lars_path(x, y, method="lasso", positive=True)
    n = y.size
    # relaxed lasso: each support along the path refitted without shrinkage (non-negative least squares), so its
    # BIC is not biased towards larger supports by the lasso's shrunk coefficients
    supports = list(dict.fromkeys(tuple(np.flatnonzero(c)) for c in coefs.T))
    fits = []
    for sup in supports:
        c = np.zeros(len(names))
        if sup:
            c[list(sup)] = nnls(x[:, list(sup)], y)[0]
        fits.append(c)
    bic = [float(np.sum((y - x @ c) ** 2) + np.count_nonzero(c) * math.log(n)) for c in fits]
    best = fits[int(np.argmin(bic))]
    entered = [names[j] for j in active]
    order = entered + sorted((t for t in names if t not in entered), key=lambda t: -score[t])
    # the largest contributions first (best is per unit-norm column: its size is the contribution's)
    support = sorted((t for j, t in enumerate(names) if best[j] > 0.0), key=lambda t: -best[names.index(t)])
    estimate = {t: float(best[j] / norms[j] * probes[t]) for j, t in enumerate(names)}
    return Screening(order=order, support=support[:MAX_SUPPORT], estimate=estimate, score=score, path_bic=bic)


def proposal_sets(scr: Screening, max_proposals: int) -> list[tuple[str, ...]]:
    """What to fit: the regression's support, then the leading single terms, at most ``max_proposals`` sets.  An
    empty support is no evidence to prune with (the linearisation at the calibrated base can miss a term the base's
    parameters absorbed: the pendulum's drag in its damping): every single term is fitted then."""
    sets: list[tuple[str, ...]] = []
    if scr.support:
        sets.append(tuple(scr.support))
    for t in scr.order:
        if (t,) not in sets:
            sets.append((t,))
    return sets if not scr.support else sets[:max_proposals]


def proposal_name(terms: tuple[str, ...]) -> str:
    return PREFIX + "+".join(terms)


def proposal_terms(name: str) -> list[str]:
    """The terms of a proposal's model name (``PREFIX`` + terms joined by ``+``)."""
    return name[len(PREFIX):].split("+")


def _start(terms: tuple[str, ...], scr: Screening, bounds: dict[str, FreeParam]) -> dict:
    """The regression's estimate of each term (its probe strength where it estimated none), inside its bounds."""
    out = {}
    for t in terms:
        lo, hi = (10 ** v for v in bounds[t].bounds)
        v = scr.estimate.get(t, 0.0) or probe_value(bounds[t])
        out[t] = float(min(max(v, lo * 1.01), hi / 1.01))
    return out


@dataclass(frozen=True)
class Discovery:
    """Discovery's outcome: the screening, every proposal's fits (reported: the single split's, or on all runs),
    held-out errors and statistics, and the verdict of the proposals against the calibrated base."""

    screening: Screening
    fits: dict[str, FitResult]
    err: dict[str, HeldOut]
    stats: dict[str, ModelStats]
    accepted: str | None
    leader: str | None
    checks: dict[str, Check]
    too_few: tuple[str, ...] = ()     # proposals not fitted: more free parameters than the data support
    n_numbers: int = 0                # measured numbers of the smallest fold's calibration runs


def discover(ev: Evaluator, cfg: DiagnoseConfig, scheme: FoldScheme, calibrated: Judged, base_stats: ModelStats,
             executor: Executor, log) -> Discovery | None:
    """Screen the model's discrepancy terms at the calibrated base (``calibrated``: the effects stage, whose base fits
    the proposals start from), re-fit the proposals on every fold and judge them on the held-out runs
    (``cfg.max_proposals`` of them; None when the model has no terms)."""
    terms = term_candidates(ev.system)
    structured = structured_candidates(ev.system, any(tg.record_start_s is None for tg in ev.targets))
    if not (terms or structured) or cfg.max_proposals < 1:
        return None
    base = calibrated.fits["base"]
    scr = screen(ev, scheme.reported_runs, base.values, terms) if terms else Screening([], [], {}, {}, [])
    log(f"{ev.system}: discrepancy screening: support {scr.support or 'none'}, order {', '.join(scr.order)}")
    sets = proposal_sets(scr, cfg.max_proposals)
    cands = {proposal_name(s): tuple(terms[t] for t in s) for s in sets}
    starts = {proposal_name(s): _start(s, scr, terms) for s in sets}
    cands.update({proposal_name((n,)): ps for n, ps in structured.items()})   # from the grid of their parameters
    n_numbers = calibration_numbers(ev, scheme)
    cands, too_few = supported(cands, n_numbers, len(calibratable(ev.system)))
    if too_few:
        log(f"{ev.system}: not fitted (the calibration runs hold {n_numbers} numbers, fewer than "
            f"{NUMBERS_PER_PARAM} per free parameter): {', '.join(too_few)}")
    if not cands:
        return Discovery(screening=scr, fits={}, err={}, stats={}, accepted=None, leader=None, checks={},
                         too_few=tuple(too_few), n_numbers=n_numbers)
    starts = {m: v for m, v in starts.items() if m in cands}
    # a structured candidate reshapes the response (a mode detuning a resonance): the base fit that absorbed it can be
    # far from the truth in every parameter, so its grid also starts at the rig's nominal values
    nominal = [proposal_name((n,)) for n in structured if proposal_name((n,)) in cands]

    def fit_on(runs: list[list[int]], start: list[FitResult]) -> list[dict[str, FitResult]]:
        return fit_added(ev, runs, cfg, cands, start, executor, extra_starts=starts, nominal=nominal, projected=True)
    fitter = Fitter.from_starts(fit_on, scheme, [f["base"] for f in calibrated.fold_fits], base)
    j = judge(ev, scheme, fitter, cfg.rule(), against=base_stats)
    for m in j.stats:
        log(f"  {m}: held-out nrms {j.err[m].nrms:.4g} (base {math.sqrt(base_stats.chi2 / max(base_stats.n, 1)):.4g})")
    return Discovery(screening=scr, fits=j.fits, err=j.err, stats=j.stats, accepted=j.verdict.selected,
                     leader=j.verdict.leader, checks=j.verdict.checks, too_few=tuple(too_few), n_numbers=n_numbers)


def spanned_effect(system: str, accepted: str, values: dict, effects: Collection[str]) -> tuple[str, dict] | None:
    """The §6 effect (one of ``effects``) an accepted proposal of one term is in another form
    (``sim.models.discrepancy.SPANS``), with its parameter's start from the proposal's fitted ``values`` (the rig's
    nominal values beneath them): (effect, {parameter: c / k}); None when the proposal spans no effect."""
    import sim
    from sim.models.discrepancy import SPANS

    terms = proposal_terms(accepted)
    span = SPANS.get(terms[0]) if len(terms) == 1 else None
    if span is None or span.effect not in effects:
        return None
    per = next((p for p in span.per if p in sim.get_model(system).param_names), None)
    if per is None or not values.get(per):
        return None
    return span.effect, {span.param: float(values[terms[0]] / values[per])}


def report(d: Discovery, base_err: HeldOut, cal_names: list[str]):
    """report.json ``discrepancy`` (a ``report_types.Discrepancy``): the screening table, the proposals ranked by
    held-out nrms (at most three), the accepted one and a sentence."""
    import sim.models.discrepancy as vocab
    from pipeline.diagnosis.report_types import Discrepancy, Proposal, ScreeningRow

    scr = d.screening
    cand = vocab.CANDIDATES
    screening = tuple(ScreeningRow(t, vocab.TERMS[t].words, vocab.TERMS[t].form, vocab.TERMS[t].kind,
                                   scr.order.index(t) + 1, scr.score[t], scr.estimate[t], t in scr.support)
                      for t in scr.order)
    rows = []
    for m in sorted(d.err, key=lambda m: (d.err[m].nrms, d.stats[m].bic)):
        fr, c, terms, e = d.fits[m], d.checks[m], proposal_terms(m), d.err[m]
        params = [q for t in terms for q in cand[t].params if q in fr.free]   # the fitted ones
        rows.append(Proposal(
            name=m, terms=tuple(terms), words=tuple(cand[t].words for t in terms),
            forms=tuple(cand[t].form for t in terms), kinds=tuple(sorted({cand[t].kind for t in terms})),
            coefficients={q: fr.values[q] for q in params}, coefficient_sd={q: fr.sd[q] for q in params},
            coefficient_ci95={q: tuple(fr.ci95[q]) for q in params}, calibrated={n: fr.values[n] for n in cal_names},
            nrms=e.nrms, error=e.error, noise_floor=e.noise_floor, systematic=e.systematic,
            by_run_nrms=e.by_run_nrms, delta_bic=c.delta_bic, delta_chi2=c.delta_chi2,
            improves=c.improves, adequate=c.adequate))
    top = rows[0] if rows else None
    if d.accepted:
        a = next(r for r in rows if r.name == d.accepted)
        text = (f"proposed and accepted: {' + '.join(a.forms)} ({'; '.join(a.words)}): held-out nrms "
                f"{base_err.nrms:.3g} → {a.nrms:.3g}, error {base_err.error:.3g} → {a.error:.3g} against a "
                f"noise floor of {a.noise_floor:.3g}")
    elif top is not None:
        text = (f"no proposal brings the held-out error to the noise (best: {' + '.join(top.forms)}, nrms "
                f"{base_err.nrms:.3g} → {top.nrms:.3g}); the missing term is not in the vocabulary "
                f"of this model ({', '.join(dict.fromkeys([*scr.order, *(t for m in d.err for t in proposal_terms(m))]))})")
    elif d.too_few:
        text = (f"no proposal fitted: the calibration runs hold {d.n_numbers} measured numbers, fewer than "
                f"{NUMBERS_PER_PARAM} per free parameter of any proposal; more runs or series records are needed "
                f"to name the missing term")
    else:
        text = "no proposal"
    if rows and d.too_few:
        text += f" (not fitted, too few numbers: {', '.join(d.too_few)})"
    return Discrepancy(screening=screening, path_bic=tuple(scr.path_bic), proposals=tuple(rows[:3]),
                       base_by_run_nrms=base_err.by_run_nrms,
                       accepted=tuple(proposal_terms(d.accepted)) if d.accepted else None, text=text)
