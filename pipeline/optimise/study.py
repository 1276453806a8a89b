"""Optuna studies: storage, sampler choice, the batched ask/evaluate/tell loop, and candidate extraction.

Sampler (``config.DEFAULT_SAMPLER``: ``sobol-local`` for ROP, ``tpe`` for a Pareto front).  The space is 3-D,
continuous and box-bounded; the objective is cheap on the surrogate (~ms) and ~10-30 ms on the simulator, users
need constraints, and the optimum usually lies on bounds of the box and on limits.
- ``sobol-local`` (pipeline/optimise/sobol_local.py): a Sobol' pass, then a compass search with quadratic-model
  steps that clips to the box, so bounds and limits are reached exactly; restarts from the design when converged.
  The only sampler within 0.995 of a dense reference scan on every case of bench/bench_search.py within 200
  trials (docs/optimise.md "Which search").  One objective.
- ``tpe`` (multivariate, constant liar): takes optuna's constraints natively, models the
  interactions of f × F0 × Fs (multivariate), proposes batches for parallel simulation (constant
  liar), handles one or two objectives, and needs no extra package.  Default of a Pareto study; on ROP it
  stopped 1-3 % short of corner optima in 200 trials.
- ``gp``: more sample-efficient on smooth low-dimensional objectives and supports constraints,
  but needs PyTorch (not installed by default); ROP has kinks at regime changes where a GP's
  smoothness prior is a poor fit.
- ``nsga2``: genetic multi-objective with constraints; needs many more trials than TPE.
- ``random``: the baseline of the benchmark.
CMA-ES is not offered: optuna's CmaEsSampler ignores constraints (and needs the cmaes package); optuna 5 moved its
restarts to OptunaHub; the benchmark measures it on the cases without limits (samplers.cmaes_sampler).
"""
from __future__ import annotations

import json
import math
from typing import Callable

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.core.names import MAXIMISED
from pipeline.optimise.constraints import Constraints
from pipeline.optimise.space import Space
from surrogate.names import TARGETS

SAMPLERS = ("tpe", "sobol-local", "gp", "nsga2", "random")
OBJECTIVES = ("rop", "pareto")
ATTR_KEYS = ("status", *TARGETS, "p_progress", "regime")
DEFAULT_PARETO = ("rop_m_s", "power_w")
"""Objectives of ``--objective pareto`` unless the user names others: ROP against the exciter's mean power."""


def parse_objectives(items, known) -> list[tuple[str, str]]:
    """``["rop_m_s", "power_w"]`` or ``"rop_m_s,min:power_w"`` → ``[(label, "maximize"|"minimize"), ...]``.

    A bare label takes its default direction (ROP maximised, every other label minimised); ``max:``/``min:``
    choose it.  UserError naming the item for an unknown label, a repeated one, or fewer than two."""
    if isinstance(items, str):
        items = [s for s in items.split(",")]
    out: list[tuple[str, str]] = []
    for raw in items:
        item = str(raw).strip()
        way, sep, name = item.partition(":")
        if not sep:
            way, name = ("max" if item in MAXIMISED else "min"), item
        if way not in ("max", "min"):
            raise UserError(f"--objectives '{item}': the direction must be max: or min:")
        if name not in known:
            raise UserError(f"--objectives '{item}': '{name}' is not a label (known: {', '.join(known)})")
        if any(name == n for n, _ in out):
            raise UserError(f"--objectives: '{name}' is named twice")
        out.append((name, "maximize" if way == "max" else "minimize"))
    if len(out) < 2:
        raise UserError(f"--objectives: a Pareto study needs at least two labels, got {[n for n, _ in out]}")
    return out


def default_storage() -> str:
    """SQLite file ``optuna.db`` at the project root (pipeline.tracking.project_root)."""
    from pipeline.tracking import project_root

    return f"sqlite:///{project_root() / 'optuna.db'}"


def open_study(storage: str | None, name: str, objectives: list[tuple[str, str]], sampler, signature: dict,
               heartbeat_s: int | None = None):
    """Create or resume study ``name`` with ``objectives`` [(label, direction)] in ``storage`` (URL, default
    :func:`default_storage`; a shared one beats every ``heartbeat_s`` seconds, default storages.DEFAULT_HEARTBEAT_S).
    A resumed study must have the same ``signature`` (mode, model, preset, space, constraints, objectives) or
    UserError explains the clash."""
    import optuna
    import sqlalchemy.exc

    from pipeline.optimise.coordination import guard_for
    from pipeline.optimise.storages import DEFAULT_HEARTBEAT_S, check_storage_target, open_storage

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    directions = [d for _, d in objectives]
    objective = ",".join(n for n, _ in objectives)
    url = storage or default_storage()
    check_storage_target(url)       # before the worker locks: a file that is not optuna's stays untouched
    try:
        with guard_for(url).lock():   # concurrent creation of a new SQLite store
            study = optuna.create_study(storage=open_storage(url, heartbeat_s or DEFAULT_HEARTBEAT_S),
                                        study_name=name, sampler=sampler, directions=directions, load_if_exists=True)
    except (sqlalchemy.exc.ArgumentError, sqlalchemy.exc.OperationalError, ValueError, ImportError) as e:
        raise UserError(f"optuna storage '{storage}': {e}".splitlines()[0]) from None
    if len(study.directions) != len(directions):
        raise UserError(f"study '{name}' exists with {len(study.directions)} objective(s); this run asks for "
                        f"objective '{objective}': choose another --study-name")
    sig = json.loads(json.dumps(signature, default=str))
    old = study.user_attrs.get("vibro_signature")
    if old is None:
        study.set_user_attr("vibro_signature", sig)
    elif old != sig:
        diff = sorted(k for k in set(old) | set(sig) if old.get(k) != sig.get(k))
        raise UserError(f"study '{name}' in the storage was run with different {', '.join(diff)}; "
                        f"resume it with the same settings or choose another --study-name")
    return study


def n_complete(study) -> int:
    import optuna

    return sum(t.state == optuna.trial.TrialState.COMPLETE for t in study.get_trials(deepcopy=False))


def _objective_values(row: dict, objectives: list[tuple[str, str]]) -> list[float]:
    """The row's value of each objective; a missing value is the worst (no ROP = 0, a missing cost = +inf)."""
    out = []
    for name, direction in objectives:
        v = row.get(name)
        missing = v is None or (isinstance(v, float) and math.isnan(v))
        if missing:
            v = 0.0 if name == "rop_m_s" else (-math.inf if direction == "maximize" else math.inf)
        out.append(float(v))
    return out


def _clean(v):
    if isinstance(v, (np.generic,)):
        v = v.item()
    if isinstance(v, float) and math.isnan(v):
        return None
    return v


def run_study(study, evaluate: Callable[[pd.DataFrame], pd.DataFrame], space: Space, constraints: Constraints,
              objectives: list[tuple[str, str]], n_trials: int, batch_size: int, progress: bool = True,
              desc: str = "study", sampler_factory: Callable[[int], object] | None = None, guard=None) -> int:
    """Ask/evaluate/tell in batches until the study holds ``n_trials`` trials (complete, or running
    in another worker) on ``objectives`` [(label, direction)].  Returns the number of trials run now
    (0 when already complete).

    ``guard`` (coordination.guard_for) keeps several workers exact.  On a SQLite file each batch is
    counted and asked under ``guard.lock()``, after stale trials of dead workers are marked FAIL (they
    are re-run).  On a shared storage (heartbeat.HeartbeatGuard) stale trials are those whose heartbeat
    stopped, their queued retries are taken first, a worker withdraws the trials it asked beyond
    ``n_trials`` when another asked at the same moment, and it waits for the others' trials until
    ``n_trials`` are complete (each worker seeds its batches apart, so a shared study is not
    reproducible).  Batches start at multiples of ``batch_size`` and,
    with ``sampler_factory(n_done)`` (a sampler seeded by coordination.batch_seed), each is
    proposed by a sampler that depends only on the seed and the trials before it, so a resumed
    study proposes what the uninterrupted one did.  Every trial records its labels in
    ``user_attrs["labels"]`` and each constraint via ``trial.set_constraint``.  An interruption
    marks the trials in flight as failed.
    """
    import optuna
    from tqdm import tqdm

    from pipeline.optimise.coordination import StudyGuard

    guard = guard or StudyGuard(None)
    guard.register()
    TS = optuna.trial.TrialState
    dists = space.distributions()
    ran = 0
    bar = tqdm(total=n_trials, initial=n_complete(study), desc=desc, disable=not progress, unit="trial", leave=False)
    try:
        while True:
            trials = []
            try:
                with guard.lock():
                    guard.fail_stale(study)
                    every = study.get_trials(deepcopy=False)
                    states = [t.state for t in every]
                    done, waiting = states.count(TS.COMPLETE), states.count(TS.WAITING)
                    live = done + waiting + states.count(TS.RUNNING) + guard.pending_retries(every)
                    k = min(batch_size - live % batch_size, n_trials - live)
                    queued_only = k <= 0 and guard.waits
                    if queued_only:
                        if done >= n_trials:
                            break
                        k = min(waiting, batch_size)     # queued retries; else the rest runs elsewhere
                        if k == 0:
                            guard.wait()
                            continue
                    if k <= 0:
                        break
                    if sampler_factory is not None:
                        study.sampler = sampler_factory(guard.sampler_key(live))
                    for _ in range(k):
                        trial = guard.ask_queued(study, dists) if queued_only else guard.ask(study, dists)
                        if trial is None:
                            break
                        trials.append(trial)
                trials = guard.settle(study, trials, n_trials)
                if not trials:
                    continue
                X = pd.DataFrame([t.params for t in trials], columns=space.names)
                with guard.beating(study, trials):      # beating until told: a slow tell is not a dead worker
                    out = evaluate(X)
                    ran += _tell_batch(study, trials, out, constraints, objectives, bar)
            except BaseException:
                _fail_interrupted(study, trials, guard)
                raise
    finally:
        bar.close()
        guard.close()
    return ran


def _fail_interrupted(study, trials: list, guard) -> None:
    """The trials in flight marked FAIL (as interrupted: the heartbeat never retries them) and the guard told to
    stop beating, so a trial asked but not yet listed goes stale and is re-run by another worker."""
    import optuna

    from pipeline.optimise.heartbeat import INTERRUPTED_ATTR

    for t in trials:
        try:
            t.set_user_attr(INTERRUPTED_ATTR, True)
            study.tell(t, state=optuna.trial.TrialState.FAIL)
        except Exception:  # noqa: BLE001 - already told
            pass
    with guard.lock():      # an interrupt inside study.ask leaves a trial no list holds
        guard.fail_orphans(study)


def _tell_batch(study, trials: list, out: pd.DataFrame, constraints: Constraints,
                objectives: list[tuple[str, str]], bar) -> int:
    """Each trial told its row of ``out`` (labels, constraints, objective values), the bar advanced per trial; the
    number told (a trial failed as stale meanwhile by another worker is skipped: its retry runs instead)."""
    import optuna

    told = 0
    for t, row in zip(trials, out.to_dict("records")):
        try:
            t.set_user_attr("labels", {k: _clean(row[k]) for k in ATTR_KEYS if k in row})
            for key, val in constraints.values(row).items():
                t.set_constraint(key, val)
            study.tell(t, _objective_values(row, objectives))
        except optuna.exceptions.UpdateFinishedTrialError:
            continue        # failed as stale meanwhile (a stalled worker): its retry runs instead
        told += 1
        bar.update(1)
    return told


def _key(t) -> tuple:
    return tuple(sorted(t.params.items()))


def run_study_buffered(study, sampler, evaluate, space: Space, constraints: Constraints,
                       objectives: list[tuple[str, str]],
                       n_trials: int, batch_size: int, checkpoint: int = 100, progress: bool = True,
                       desc: str = "study", sampler_factory: Callable[[int], object] | None = None, guard=None):
    """Like :func:`run_study` for cheap objectives (the surrogate): trials run in an in-memory copy of
    ``study`` and are written to the persistent storage every ``checkpoint`` trials (segments end
    at multiples of ``checkpoint``) and on interruption — a database commit per trial would cost
    more than the surrogate.  Each segment starts from the storage's complete trials; a flush adds
    (under ``guard.lock()``) only trials whose inputs are not stored yet and never more than
    ``n_trials`` in all, so several workers leave exactly ``n_trials`` distinct trials.
    Returns (in-memory study holding every stored complete trial, trials run now)."""
    import optuna

    from pipeline.optimise.coordination import StudyGuard

    guard = guard or StudyGuard(None)
    if guard.waits:     # a shared storage: no lock spans the workers, so every trial is stored as it runs
        ran = run_study(study, evaluate, space, constraints, objectives, n_trials, batch_size, progress, desc,
                        sampler_factory=sampler_factory, guard=guard)
        final = optuna.create_study(directions=study.directions, sampler=sampler)
        final.add_trials(study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,)))
        return final, ran
    complete = (optuna.trial.TrialState.COMPLETE,)

    def stored():
        return study.get_trials(deepcopy=False, states=complete)

    ran = 0
    while True:
        with guard.lock():
            have = stored()
        if len(have) >= n_trials:
            break
        mem = optuna.create_study(directions=study.directions, sampler=sampler)
        mem.add_trials(have)
        target = min((len(have) // checkpoint + 1) * checkpoint, n_trials)
        try:
            ran += run_study(mem, evaluate, space, constraints, objectives, target, batch_size, progress, desc,
                             sampler_factory=sampler_factory)
        finally:
            new = [t for t in mem.get_trials(deepcopy=False)[len(have):] if t.state in complete]
            with guard.lock():
                now = stored()
                keys = {_key(t) for t in now}
                add = [t for t in new if _key(t) not in keys][:max(n_trials - len(now), 0)]
                study.add_trials(add)
    final = optuna.create_study(directions=study.directions, sampler=sampler)
    final.add_trials(stored())
    return final, ran


def trials_frame(study, space: Space) -> pd.DataFrame:
    """Complete trials: number, inputs, objective value(s), recorded labels, feasibility, violation."""
    import optuna

    rows = []
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,)):
        if any(n not in t.params for n in space.names):
            continue
        cons = t.constraints
        rec = {"trial": t.number, **{n: t.params[n] for n in space.names}}
        labels = t.user_attrs.get("labels", {})
        rec.update({k: labels.get(k) for k in ATTR_KEYS if k in labels})
        rec["value"] = t.values[0]
        for k, v in enumerate(t.values[1:], start=2):
            rec[f"value_{k}"] = v
        rec["violation"] = float(sum(max(v, 0.0) for v in cons.values()))
        rec["feasible"] = rec["violation"] <= 0
        rows.append(rec)
    return pd.DataFrame(rows)


def value_columns(n_objectives: int) -> list[str]:
    """Columns of :func:`trials_frame` holding the objective values: value, value_2, value_3, ..."""
    return ["value"] + [f"value_{k}" for k in range(2, n_objectives + 1)]


def pareto_mask(first: np.ndarray, *others: np.ndarray, directions: list[str] | None = None) -> np.ndarray:
    """Non-dominated points of objective columns ``first, *others``; ``directions`` per column
    (default: maximise the first, minimise the others — ROP against costs)."""
    cols = [np.asarray(first, dtype=float), *(np.asarray(o, dtype=float) for o in others)]
    directions = directions or ["maximize"] + ["minimize"] * (len(cols) - 1)
    C = np.column_stack([-c if d == "maximize" else c for c, d in zip(cols, directions)])   # all minimised
    keep = np.ones(len(C), dtype=bool)
    for i in range(len(C)):
        dom = np.all(C <= C[i], axis=1) & np.any(C < C[i], axis=1)
        keep[i] = not dom.any()
    return keep


def _spread(front: pd.DataFrame, cols: list[str], directions: list[str], n: int) -> pd.DataFrame:
    """``n`` points of a front spread evenly along it: greedy farthest-point choice in the objectives
    normalised to [0, 1], starting from the best of the first objective."""
    V = front[cols].to_numpy(float)
    span = np.where(np.ptp(V, axis=0) > 0, np.ptp(V, axis=0), 1.0)
    U = (V - V.min(axis=0)) / span
    start = int(np.argmax(V[:, 0]) if directions[0] == "maximize" else np.argmin(V[:, 0]))
    picked = [start]
    dist = np.linalg.norm(U - U[start], axis=1)
    while len(picked) < n:
        j = int(np.argmax(dist))
        if dist[j] <= 0:
            break
        picked.append(j)
        dist = np.minimum(dist, np.linalg.norm(U - U[j], axis=1))
    return front.iloc[picked]


def pick_candidates(trials: pd.DataFrame, space: Space, objective: str, n: int, min_dist: float = 0.02,
                    directions: list[str] | None = None) -> pd.DataFrame:
    """Up to ``n`` distinct feasible candidates to verify.

    rop: best first, skipping points within ``min_dist`` (unit-cube distance) of one already picked.
    pareto: the feasible Pareto front of the objective columns (``directions`` per objective, default
    maximise ROP and minimise the rest), thinned to ``n`` points spread evenly along the front.
    """
    feas = trials[trials["feasible"]] if len(trials) else trials
    if feas.empty:
        return feas
    if objective == "pareto":
        directions = directions or ["maximize", "minimize"]
        cols = value_columns(len(directions))
        feas = feas[np.all(np.isfinite(feas[cols].to_numpy(float)), axis=1)]
        if feas.empty:
            return feas
        front = feas[pareto_mask(*(feas[c].to_numpy(float) for c in cols), directions=directions)]
        front = front.drop_duplicates(subset=space.names).drop_duplicates(subset=cols)
        if len(front) > n:
            front = _spread(front, cols, directions, n)
        return front.sort_values("value", ascending=directions[0] != "maximize").reset_index(drop=True)
    ordered = feas.sort_values("value", ascending=False)
    U = space.unit(ordered)
    picked: list[int] = []
    for i in range(len(ordered)):
        if all(np.linalg.norm(U[i] - U[j]) >= min_dist for j in picked):
            picked.append(i)
            if len(picked) >= n:
                break
    return ordered.iloc[picked].reset_index(drop=True)
