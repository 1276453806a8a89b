"""The fits of one system's diagnosis: the base model and every candidate effect on each fold's calibration runs.

Each stage (base fits, candidate starting points, candidate fits, base refit, leader refinement) is one batch of
independent tasks (folds x models x starts) on an executor (``pipeline.core.executors``): every task is a pure
function of its inputs (the seeded starts are drawn here, beforehand), and the results are combined in the order
the tasks were listed, so a cluster gives the numbers a local run gives.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Collection

import numpy as np

from pipeline.core.executors import Executor
from pipeline.diagnosis.fit import FitJob, FitResult, StartFit, finish_fit, fit, fit_start
from pipeline.diagnosis.model import Evaluator, FreeParam, calibratable
from sim.registry import warm as sim_warm

if TYPE_CHECKING:
    from pipeline.diagnosis.config import DiagnoseConfig


@dataclass(frozen=True)
class _Counted:
    """A task: ``fn(evaluator, item)`` on the task's own copy of the evaluator, BLAS on one thread (as in the
    driver: the same numbers on every executor); returns (result, simulations run)."""

    fn: Callable

    def __call__(self, ev: Evaluator, item):
        from threadpoolctl import threadpool_limits

        own = ev.for_tasks()
        sim_warm(own.system)                  # the kernel loaded before the evaluator's threads use it
        with threadpool_limits(1):
            out = self.fn(own, item)
        return out, own.n_sims


def _batch(executor: Executor, ev: Evaluator, shared: Evaluator, fn: Callable, items: list,
           labels: list[str] | None = None) -> list:
    """``fn`` over ``items`` on the executor; the simulations counted on ``ev``, and each task's simulations, CPU and
    wall seconds told to ``ev.cost`` under its label (the model it fits), where both are given."""
    if not items:
        return []
    done = executor.map(_Counted(fn), shared, items)
    ev.n_sims += sum(n for _, n in done)
    if ev.cost is not None and labels is not None:
        st, k = executor.stats, len(items)
        ev.cost.tasks(labels, [n for _, n in done], st.cpu_s[-k:], st.wall_s[-k:])
    return [r for r, _ in done]


def _start_task(ev: Evaluator, item: tuple[FitJob, int]) -> StartFit:
    return fit_start(ev, *item)


def _finish_task(ev: Evaluator, item: tuple[FitJob, list[StartFit]]) -> FitResult:
    return finish_fit(ev, *item)


def _fits(executor: Executor, ev: Evaluator, shared: Evaluator, jobs: list[FitJob],
          labels: list[str] | None = None) -> list[FitResult]:
    """Every start of every job as one batch, then every job's best start polished as another (``labels``: the
    model of each job, for the cost)."""
    pairs = [(j, k) for j, job in enumerate(jobs) for k in range(len(job.starts))]
    ends = _batch(executor, ev, shared, _start_task, [(jobs[j], k) for j, k in pairs],
                  None if labels is None else [labels[j] for j, _ in pairs])
    per_job: list[list[StartFit]] = [[] for _ in jobs]
    for (j, _), end in zip(pairs, ends):
        per_job[j].append(end)
    return _batch(executor, ev, shared, _finish_task, list(zip(jobs, per_job)), labels)


def random_starts(free: list[FreeParam], defaults: dict, n: int, rng) -> list[dict]:
    """The defaults and ``n - 1`` points drawn uniformly in log10 within the bounds."""
    starts = [{p.name: defaults[p.name] for p in free}]
    for _ in range(n - 1):
        starts.append({p.name: 10 ** rng.uniform(*p.bounds) for p in free})
    return starts


def nominal_values(ev: Evaluator, idx: list[int]) -> dict[str, float]:
    """The rig's nominal parameter values for the runs ``idx``: the model's defaults under the rig's known values."""
    import sim

    return {**sim.get_model(ev.system).defaults(), **ev.targets[idx[0]].known}


CAL_STEP = 0.01
"""Step [log10] of the calibratable parameters' sensitivity columns."""


def calibration_sets(base: dict, free: list[FreeParam]) -> list[dict]:
    """``base`` and each of ``free`` stepped by CAL_STEP [log10]: the sets whose residuals :func:`calibration_basis`
    turns into the directions a recalibration moves the residual in."""
    return [dict(base)] + [{**base, p.name: base[p.name] * 10 ** CAL_STEP} for p in free]


def calibration_basis(rs: list[np.ndarray]) -> np.ndarray:
    """Orthonormal basis of the calibratable parameters' sensitivity columns, from the residuals of
    :func:`calibration_sets` (first the base's)."""
    jc = np.column_stack([(r - rs[0]) / CAL_STEP for r in rs[1:]])
    return np.linalg.qr(jc)[0]


def candidate_start(ev: Evaluator, idx: list[int], base: dict, eff: tuple[FreeParam, ...], free: list[FreeParam],
                    cfg: DiagnoseConfig, projected: bool = False) -> dict:
    """Starting point of a candidate's fit: a log grid of the effect's parameters (``cfg.grid`` interior points per
    parameter, or the parameter's own ``FitBound.grid``) at the base parameters ``base`` (one parallel batch of simulations), then, at the best
    ``cfg.profile_points`` grid points, the base parameters refitted for ``cfg.profile_nfev`` iterations with the
    effect held there (its profile): a base fit that absorbed the missing effect (the drill's Pr standing in for
    guide friction) makes the effect look wrong at every grid point until the base parameters move back.
    ``projected``: also profile the best grid points once what a recalibration can absorb is projected out of their
    residuals (the calibratable parameters' sensitivities at ``base``: one Gauss-Newton step of the profile for 1 +
    len(free) more simulations per run), which finds a narrow basin the unprofiled grid ranks below the
    compensating base (a drive's mode at 400 Hz on the drill, 0.2 of M2: raw nrms 18 at its nearest grid point
    against 14 elsewhere, 6 projected, 0.5 at the truth)."""
    axes = [np.linspace(*p.bounds, (p.grid or cfg.grid) + 2)[1:-1] for p in eff]     # a bound may ask for more
    mesh = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(eff), -1).T
    sets = [{**base, **{p.name: 10 ** v for p, v in zip(eff, row)}} for row in mesh]
    cal = calibration_sets(base, free) if projected else []
    rs = ev.residuals(sets + cal, idx)
    chi2 = [float(r @ r) for r in rs[:len(sets)]]
    order = list(np.argsort(chi2))
    best = sets[order[0]], chi2[order[0]]
    held_at = order[:cfg.profile_points]
    if projected:
        q = calibration_basis(rs[len(sets):])
        rest = [float(np.sum((r - q @ (q.T @ r)) ** 2)) for r in rs[:len(sets)]]
        held_at += [j for j in np.argsort(rest)[:cfg.profile_points] if j not in held_at]
    if cfg.profile_nfev > 0:
        start = [{p.name: base[p.name] for p in free}]
        for j in held_at:
            held = {p.name: sets[j][p.name] for p in eff}
            fr = fit(ev, idx, free, held, start, cfg.profile_nfev, cfg.diff_step, polish=False)
            if fr.chi2 < best[1]:
                best = {**fr.values, **held}, fr.chi2
    return best[0]


def _candidate_start_task(ev: Evaluator, item: tuple) -> dict:
    return candidate_start(ev, *item)


def fit_models(ev: Evaluator, folds: list[list[int]], cfg: DiagnoseConfig, cands: dict, rng, executor: Executor,
               warm: dict[str, FitResult] | None = None) -> list[tuple[dict[str, FitResult], list[str]]]:
    """Per fold (its calibration runs' indices): the base model and every candidate fitted, and the lines that
    report them.  ``warm``: start each model from these fits (leave-one-run-out folds start from the all-runs
    fit; each fold is still refitted on its own runs); without it the base starts are drawn from ``rng``."""
    free = list(calibratable(ev.system))
    shared = ev.for_tasks(executor.task_threads)
    nominal = [nominal_values(ev, idx) for idx in folds]
    nominal_base = [{p.name: d[p.name] for p in free} for d in nominal]     # the calibratable ones, per fold
    base_jobs = [FitJob(idx, free, {}, [warm["base"].values] if warm else random_starts(free, d, cfg.n_starts, rng),
                        cfg.max_nfev, cfg.diff_step, coarse=not warm) for idx, d in zip(folds, nominal)]
    outs = [{"base": b} for b in _fits(executor, ev, shared, base_jobs, ["base"] * len(base_jobs))]
    lines = [[f"  base: chi2/n = {o['base'].chi2 / o['base'].n:.4g}"] for o in outs]
    keys = [(f, eff) for f in range(len(folds)) for eff in cands]
    if warm:
        starts = {key: [warm[key[1]].values] for key in keys}
    else:   # grid of the effect at the calibrated base, and at the default base parameters (the base
        #     fit may have compensated the missing effect with a base parameter, e.g. pm for mu)
        items = [(f, eff, (folds[f], b, cands[eff], free, cfg)) for f, eff in keys
                 for b in [outs[f]["base"].values, nominal_base[f]][:cfg.candidate_starts]]
        found = _batch(executor, ev, shared, _candidate_start_task, [it for _, _, it in items],
                       [eff for _, eff, _ in items])
        starts = {key: [] for key in keys}
        for (f, eff, _), s in zip(items, found):
            starts[(f, eff)].append(s)
    jobs = [FitJob(folds[f], free + list(cands[eff]), {}, starts[(f, eff)], cfg.max_nfev, cfg.diff_step,
                   coarse=not warm) for f, eff in keys]
    for (f, eff), fr in zip(keys, _fits(executor, ev, shared, jobs, [eff for _, eff in keys])):
        outs[f][eff] = fr
        lines[f].append(f"  {eff}: chi2/n = {fr.chi2 / fr.n:.4g}")
    _refit_base(executor, ev, shared, folds, cfg, free, outs, lines)
    _refine_leader(executor, ev, shared, folds, cfg, cands, free, outs, lines)
    if not warm and _restart_leaders(executor, ev, shared, folds, cfg, cands, free, nominal_base, outs, lines):
        _refit_base(executor, ev, shared, folds, cfg, free, outs, lines)
    return list(zip(outs, lines))


RESTARTED_LEADERS = 2
"""How many leading candidates ``_restart_leaders`` starts again from the rig's nominal base."""


def _restart_leaders(executor: Executor, ev: Evaluator, shared: Evaluator, folds: list[list[int]],
                     cfg: DiagnoseConfig, cands: dict, free: list[FreeParam], nominal_base: list[dict],
                     outs: list[dict[str, FitResult]], lines: list[list[str]]) -> bool:
    """With one candidate start (``cfg.candidate_starts`` 1) and the leader, refined, still above the noise level: the
    ``RESTARTED_LEADERS`` leading candidates that beat the base are also fitted from the effect's grid at the rig's
    nominal base (the second start of ``candidate_starts`` 2), keeping the better fit; returns whether that changed
    which candidate fits best (the base is then refitted from it, ``_refit_base``).  The start at the calibrated
    base can lead the coarse first fit into another basin: on a drill log whose accelerometer saturated on 5 of 8
    runs, guide friction ended at mu = 18 N (calibration chi2 23310) and from the nominal base at 50 N (77; the
    truth, 50 N: 86).  Only the candidates that decide the verdict pay for it, and only when none of them fits."""
    if not cands or cfg.candidate_starts >= 2:
        return False
    leaders = [_leader(out, cands) for out in outs]
    items = []
    for f, out in enumerate(outs):
        if _at_noise(out[leaders[f]], cfg):
            continue
        items += [(f, m, (folds[f], nominal_base[f], cands[m], free, cfg))
                  for m in sorted(cands, key=lambda c: out[c].chi2)[:RESTARTED_LEADERS]
                  if out[m].chi2 < out["base"].chi2]
    if not items:
        return False
    found = _batch(executor, ev, shared, _candidate_start_task, [it for _, _, it in items], [m for _, m, _ in items])
    jobs = [FitJob(folds[f], free + list(cands[m]), {}, [start], cfg.max_nfev, cfg.diff_step, coarse=True)
            for (f, m, _), start in zip(items, found)]
    for (f, m, _), fr in zip(items, _fits(executor, ev, shared, jobs, [m for _, m, _ in items])):
        if fr.chi2 < outs[f][m].chi2:
            outs[f][m] = _extended(outs[f][m], fr)
        lines[f].append(f"  {m} (from the nominal base): chi2/n = {fr.chi2 / fr.n:.4g}")
    return any(_leader(out, cands) != lead for out, lead in zip(outs, leaders))


def _leader(out: dict[str, FitResult], cands: dict) -> str:
    """The candidate of ``out`` (one fold's fits) with the lowest calibration chi2."""
    return min(cands, key=lambda m: out[m].chi2)


def _at_noise(fr: FitResult, cfg: DiagnoseConfig) -> bool:
    """Whether a fit's calibration chi2/n is at the noise level (at most explained_nrms^2)."""
    return fr.chi2 / fr.n <= cfg.explained_nrms ** 2


def refit(ev: Evaluator, folds: list[list[int]], cfg: DiagnoseConfig, added: dict[str, list[FreeParam]],
          start_fits: list[dict[str, FitResult]], executor: Executor) -> list[dict[str, FitResult]]:
    """Per fold: ``start_fits[f]`` with the models of ``added`` (name -> its parameters beside the calibratable
    ones) fitted again on the fold's runs from their values there (one start each, ``refine_nfev`` iterations):
    after something the fits depend on changed (the undeclared chain's clock)."""
    free = list(calibratable(ev.system))
    keys = [(f, m) for f in range(len(folds)) for m in added]
    jobs = [FitJob(folds[f], free + list(added[m]), {}, [start_fits[f][m].values], cfg.refine_nfev, cfg.diff_step)
            for f, m in keys]
    outs = [dict(s) for s in start_fits]
    for (f, m), fr in zip(keys, _fits(executor, ev, ev.for_tasks(executor.task_threads), jobs, [m for _, m in keys])):
        outs[f][m] = _extended(start_fits[f][m], fr)
    return outs


def _refit_base(executor: Executor, ev: Evaluator, shared: Evaluator, folds: list[list[int]], cfg: DiagnoseConfig,
                free: list[FreeParam], outs: list[dict[str, FitResult]], lines: list[list[str]]) -> None:
    """Fit the base model once more from the calibratable values of the best candidate fit, when that fit is
    better than the base's: a candidate starts from more points and may find the base parameters the base's own
    iterations did not reach; an effect must not be preferred only because the base fit stopped short."""
    todo = []
    for f, out in enumerate(outs):
        best = min((m for m in out if m != "base"), key=lambda m: out[m].chi2, default=None)
        if best is None or out[best].chi2 >= out["base"].chi2 or cfg.refine_nfev <= 0:
            continue
        start = {p.name: out[best].values[p.name] for p in free}
        todo.append((f, best, FitJob(folds[f], free, {}, [start], cfg.max_nfev + cfg.refine_nfev, cfg.diff_step)))
    for (f, best, _), more in zip(todo, _fits(executor, ev, shared, [job for _, _, job in todo], ["base"] * len(todo))):
        out = outs[f]
        if more.chi2 < out["base"].chi2:
            out["base"] = _extended(out["base"], more)
            lines[f].append(f"  base (again, from {best}'s values): chi2/n = {more.chi2 / more.n:.4g}")


def _refine_leader(executor: Executor, ev: Evaluator, shared: Evaluator, folds: list[list[int]], cfg: DiagnoseConfig,
                   cands: dict, free: list[FreeParam], outs: list[dict[str, FitResult]], lines: list[list[str]]) -> None:
    """Spend ``cfg.refine_nfev`` more iterations on the leading candidate only, when it beats the base but has
    not reached the noise level (calibration chi2/n above explained_nrms^2).  A strong effect seen from a base
    fit that compensated for it (drill shaker_coil: K1 fitted 35 % low) needs ~20 iterations; giving every
    candidate that many would double the time, and the others are not near the data anyway."""
    if not cands or cfg.refine_nfev <= 0:
        return
    todo = []
    for f, out in enumerate(outs):
        lead = _leader(out, cands)
        fr = out[lead]
        if fr.chi2 >= out["base"].chi2 or _at_noise(fr, cfg):
            continue
        todo.append((f, lead, FitJob(folds[f], free + list(cands[lead]), {}, [fr.values], cfg.refine_nfev,
                                     cfg.diff_step)))
    for (f, lead, _), more in zip(todo, _fits(executor, ev, shared, [job for _, _, job in todo],
                                              [lead for _, lead, _ in todo])):
        out = outs[f]
        if more.chi2 < out[lead].chi2:
            out[lead] = _extended(out[lead], more)
        lines[f].append(f"  {lead} (refined): chi2/n = {out[lead].chi2 / out[lead].n:.4g}")


def _extended(before: FitResult, more: FitResult) -> FitResult:
    """``more``, counting the iterations and starts of the fit it continued."""
    out = copy.copy(more)
    out.nfev = more.nfev + before.nfev
    out.starts = before.starts + more.starts
    return out


def fit_added(ev: Evaluator, folds: list[list[int]], cfg: DiagnoseConfig, cands: dict, start_fits: list[FitResult],
              executor: Executor, carried: tuple[FreeParam, ...] = (),
              extra_starts: dict[str, dict] | None = None,
              nominal: bool | Collection[str] = False, projected: bool = False) -> list[dict[str, FitResult]]:
    """Per fold: each candidate of ``cands`` (name -> its fitted parameters) added to the model of ``start_fits[f]``
    (the calibratable parameters and ``carried``), all fitted together on the fold's runs.  Each starts from a grid
    of the added parameters at that fit (``candidate_start``: the calibratable and carried parameters refitted at
    the best grid points), with ``nominal`` (True, or the names of the candidates it applies to) also from the grid
    at that fit with the calibratable parameters at the rig's nominal values (a fit that absorbed the added physics in a base parameter, e.g. the RIMD's λi standing in
    for rate stiffening, hides it at every grid point), with ``projected`` the grid also ranked with the
    recalibration projected out (``candidate_start``), and, where given, from ``start_fits[f]``'s values with
    ``extra_starts[name]`` on top (e.g. a sparse regression's estimate); ``max_nfev + refine_nfev`` iterations."""
    free = list(calibratable(ev.system)) + list(carried)
    shared = ev.for_tasks(executor.task_threads)
    keys = [(f, c) for f in range(len(folds)) for c in cands]
    at_nominal = set(cands) if nominal is True else set(nominal or ())
    items = []          # (fold, candidate, the parameters its grid starts at)
    for f, c in keys:
        items.append((f, c, start_fits[f].values))
        if c in at_nominal:
            nom = nominal_values(ev, folds[f])
            items.append((f, c, {**start_fits[f].values, **{p.name: nom[p.name] for p in calibratable(ev.system)}}))
    found_all = _batch(executor, ev, shared, _candidate_start_task,
                       [(folds[f], b, cands[c], free, cfg, projected) for f, c, b in items], [c for _, c, _ in items])
    by_key: dict = {}
    for (f, c, _), s in zip(items, found_all):
        by_key.setdefault((f, c), []).append(s)
    jobs = []
    for f, c in keys:
        starts = list(by_key[(f, c)])
        if extra_starts and c in extra_starts:
            starts.append({**start_fits[f].values, **extra_starts[c]})
        jobs.append(FitJob(folds[f], free + list(cands[c]), {}, starts, cfg.max_nfev + cfg.refine_nfev, cfg.diff_step))
    outs: list[dict[str, FitResult]] = [{} for _ in folds]
    for (f, c), fr in zip(keys, _fits(executor, ev, shared, jobs, [c for _, c in keys])):
        outs[f][c] = fr
    return outs


def fit_additions(ev: Evaluator, folds: list[list[int]], cfg: DiagnoseConfig, first: str, cands: dict,
                  first_fits: list[FitResult], executor: Executor) -> list[dict[str, FitResult]]:
    """Per fold: the effect ``first`` plus each other candidate, fitted together (greedy forward selection), from
    the fold's fit with ``first`` and from the rig's nominal calibratable values (``fit_added``).  Keys ``"first+other"``."""
    adds = {f"{first}+{e}": cands[e] for e in cands if e != first}
    return fit_added(ev, folds, cfg, adds, first_fits, executor, carried=tuple(cands[first]), nominal=True)
