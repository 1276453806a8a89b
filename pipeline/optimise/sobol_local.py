"""A space-filling pass then a local pattern search: an optuna sampler for a box whose optimum may lie on its faces.

Trials ``0 .. n_startup-1`` are the points of the (unscrambled) Sobol' sequence from its second point on, the box's
centre first.  Every later trial is a move of a compass (pattern) search around the incumbent — the best feasible
complete trial, else the one closest to feasibility: one coordinate stepped up or down by a radius in the unit cube,
clipped to the box, so a bound is reached exactly and an optimum in a corner or on a face is found as well as an
interior one.  Each round opens with the maximiser of quadratic fits (of the objective, and of every constraint)
to the trials nearest the incumbent within twice the radius; then the compass moves that change the point.  A round
without improvement halves the radius; an improvement restarts the rounds at twice the radius that found it.  When
the radius falls below ``radius_min`` the search is converged, and the next one starts from the best trial that no
better trial lies within ``basin`` of (another peak's basin: restarts); when every such search has converged,
further trials continue the Sobol' sequence.

Every proposal is a function of the trials before it (their parameters, values, constraints and the radius each
local move records in ``system_attrs``), never of a random state, so a batch asked at once gets distinct moves
(running trials count as tried) and a resumed study proposes what the uninterrupted one did.  One objective only.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import optuna

RADIUS_ATTR = "vibro_local_radius"
"""System attribute of a local move: the radius (unit cube) it was proposed with."""
KIND_ATTR = "vibro_local_kind"
"""System attribute of a local move: 'model' (a quadratic fit's maximiser) or 'compass' (one coordinate stepped)."""
ANCHOR_ATTR = "vibro_local_anchor"
"""System attribute of a local move: the number of the trial whose local search it belongs to."""


def _sobol(index: int, d: int) -> np.ndarray:
    """Point ``index`` of the unscrambled d-dimensional Sobol' sequence (0 = the origin, 1 = the centre)."""
    from scipy.stats import qmc

    eng = qmc.Sobol(d, scramble=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # balance warning: single points are drawn on purpose
        eng.fast_forward(index)
        return eng.random(1)[0]


class SobolLocalSampler(optuna.samplers.BaseSampler):
    """Space-filling Sobol' pass of ``n_startup`` trials, then a compass search with restarts (see the module)."""

    def __init__(self, n_startup: int = 32, radius0: float = 0.25, radius_min: float = 0.004, seed: int = 0,
                 basin: float = 0.2):
        self.n_startup, self.radius0, self.radius_min = int(n_startup), float(radius0), float(radius_min)
        self.basin = float(basin)
        self.seed = int(seed)       # kept for the samplers' common signature: the search is a function of the trials

    # ------------------------------------------------------------------ optuna's sampler interface
    def infer_relative_search_space(self, study, trial) -> dict:
        for t in study.get_trials(deepcopy=False):
            if t.number != trial.number and t.distributions:
                return dict(t.distributions)
        return {}       # no trial holds parameters yet: sample_independent gives this one its Sobol' point

    def sample_independent(self, study, trial, name, dist):
        """A trial asked before any other trial holds parameters (the study's first, or one asked at the same
        moment by another worker): coordinate ``j`` (its j-th parameter) of its Sobol' point."""
        j = sum(1 for n in trial.params if n != name)
        return _from_unit(_sobol(trial.number + 1, j + 1)[j], dist)

    def sample_relative(self, study, trial, space: dict) -> dict:
        if not space:
            return {}
        names = list(space)
        u, radius, kind, *anchor = self._propose(study, trial.number, names, space)
        if radius is not None:
            study._storage.set_trial_system_attr(trial._trial_id, RADIUS_ATTR, radius)
            study._storage.set_trial_system_attr(trial._trial_id, KIND_ATTR, kind)
            study._storage.set_trial_system_attr(trial._trial_id, ANCHOR_ATTR, anchor[0])
        return {n: _from_unit(u[j], space[n]) for j, n in enumerate(names)}

    def before_trial(self, study, trial) -> None:
        pass

    def after_trial(self, study, trial, state, values) -> None:
        pass

    def reseed_rng(self) -> None:
        pass

    # ------------------------------------------------------------------ the search
    def _propose(self, study, number: int, names: list[str], space: dict):
        """(unit-cube point, radius, 'model' | 'compass', anchor's trial number) of trial ``number``; (point, None,
        None) for a point of the Sobol' sequence.

        Trials asked just before this one (by another worker on the shared study) that hold no parameters yet are
        proposed for first, in their order, exactly as they propose for themselves: this trial then takes the
        next move, not the same one."""
        trials = study.get_trials(deepcopy=False)
        running = optuna.trial.TrialState.RUNNING
        pending = [t.number for t in trials
                   if t.number < number and t.state == running and not all(n in t.params for n in names)]
        ahead: list[tuple] = []
        for m in pending:
            ahead.append(self._propose_one(trials, study.direction, m, names, space, ahead))
        return self._propose_one(trials, study.direction, number, names, space, ahead)

    def _propose_one(self, trials, direction, number: int, names: list[str], space: dict, ahead: list[tuple]):
        """:meth:`_propose` for trial ``number``, given the proposals ``ahead`` of trials asked before it."""
        d = len(names)
        if number < self.n_startup:
            return _sobol(number + 1, d), None, None
        trials = [t for t in trials if all(n in t.params for n in names)]
        done = [t for t in trials if t.state == optuna.trial.TrialState.COMPLETE]
        if not done:
            return _sobol(number + 1, d), None, None
        sign = 1.0 if direction == optuna.study.StudyDirection.MAXIMIZE else -1.0
        others = [t for t in trials if t.number != number]
        seen = np.array([[_to_unit(t.params[n], space[n]) for n in names] for t in others]
                        + [list(a[0]) for a in ahead]).reshape(-1, d)
        U = np.array([[_to_unit(t.params[n], space[n]) for n in names] for t in done])
        ranks = [_rank(t, sign) for t in done]
        # the compass order is a function of the trial's number, not of a worker's seed, so that a worker can
        # propose for another's trial exactly (``ahead``), and trials asked at once start from different moves
        order = np.random.default_rng(number).permutation(2 * d)
        # anchors: the best trial, then each trial no better trial lies within ``basin`` of (a local maximum of the
        # trials at that scale), best first; the first whose local search is not converged moves (restarts)
        by_rank = sorted(range(len(done)), key=lambda i: ranks[i], reverse=True)
        pos = np.empty(len(done), dtype=int)
        pos[by_rank] = np.arange(len(done))
        shadowed = np.zeros(len(done), dtype=bool)     # a better trial lies within the basin (rows in chunks: memory)
        for a in range(0, len(done), 256):
            near = np.linalg.norm(U[a:a + 256, None, :] - U[None, :, :], axis=2) < self.basin
            shadowed[a:a + 256] = np.any(near & (pos[None, :] < pos[a:a + 256, None]), axis=1)
        models: dict[int, set] = {}     # anchor -> radii its quadratic-model step was asked at
        for t in others:
            if t.system_attrs.get(KIND_ATTR) == "model":
                models.setdefault(t.system_attrs.get(ANCHOR_ATTR), set()).add(t.system_attrs.get(RADIUS_ATTR))
        for _, radius, kind, *anchor in ahead:
            if kind == "model":
                models.setdefault(anchor[0], set()).add(radius)
        for i in by_rank:
            if shadowed[i]:
                continue
            move = self._local_move(done[i], U[i], done, names, space, seen, models.get(done[i].number, set()),
                                    order, sign, number)
            if move is not None:
                return move
        return _sobol(number + 1, d), None, None    # every local search converged: explore on

    def _local_move(self, inc, x0, done, names, space, seen, modelled: set, order, sign, number):
        """The next move of the local search around ``inc`` (unit point ``x0``), None when it has converged;
        ``modelled``: the radii its quadratic-model step was already asked at."""
        r = min(self.radius0, 2.0 * inc.system_attrs[RADIUS_ATTR]) if RADIUS_ATTR in inc.system_attrs \
            else self.radius0
        while r >= self.radius_min:
            # a round: the maximiser of a quadratic fitted around the incumbent (once), then the compass moves;
            # a move already asked (running ones included) is skipped, so a batch gets distinct moves
            if r not in modelled:
                x = _model_step(done, names, space, x0, r, sign, number)
                if x is not None and not _present(x, seen):
                    return x, r, "model", inc.number
            for k in order:
                j, step = int(k) // 2, (r, -r)[int(k) % 2]
                x = x0.copy()
                x[j] = min(max(x0[j] + step, 0.0), 1.0)
                if abs(x[j] - x0[j]) > 1e-12 and not _present(x, seen):
                    return x, r, "compass", inc.number
            r *= 0.5
        return None


def _present(x: np.ndarray, seen: np.ndarray) -> bool:
    return bool(len(seen)) and bool(np.any(np.max(np.abs(seen - x), axis=1) < 1e-9))


def _features(Z: np.ndarray, full: bool) -> np.ndarray:
    """Quadratic features of unit-cube offsets ``Z`` (n, d): 1, z, z², and the cross terms when ``full``."""
    d = Z.shape[1]
    cols = [np.ones(len(Z)), *Z.T, *(Z ** 2).T]
    if full:
        cols += [Z[:, i] * Z[:, j] for i in range(d) for j in range(i + 1, d)]
    return np.column_stack(cols)


def _model_step(done, names, space, x0: np.ndarray, r: float, sign: float, number: int) -> np.ndarray | None:
    """The maximiser, within ±2 r of ``x0`` and the box, of a quadratic least-squares fit of the objective to the
    feasible complete trials nearest ``x0``, among the candidates that quadratic fits of every constraint (to all the
    nearest trials) predict feasible; None when too few trials or no predicted gain."""
    d = len(x0)
    n_full = 1 + 2 * d + d * (d - 1) // 2
    X = np.array([[_to_unit(t.params[n], space[n]) for n in names] for t in done])
    near = np.argsort(np.linalg.norm(X - x0, axis=1))[:3 * n_full]
    ranks = [_rank(done[i], sign) for i in near]
    ok = [i for i, k in zip(near, ranks) if k[0] == 1 and math.isfinite(k[1])]
    if len(ok) < 2 * d + 3:
        return None
    rng = np.random.default_rng(number)
    lo, hi = np.maximum(-2.0, -x0 / r), np.minimum(2.0, (1.0 - x0) / r)
    cand = np.vstack([np.zeros((1, d)), rng.uniform(lo, hi, size=(2000, d)),
                      np.array(list(np.ndindex(*(3,) * d))) / 2.0 * (hi - lo) + lo])    # the trust box's grid
    pred = _fit_predict((X[ok] - x0) / r, np.array([_rank(done[i], sign)[1] for i in ok]), cand, n_full)
    keys = sorted({k for i in near for k in (done[i].constraints or {})})
    for key in keys:        # a constraint's fit over the nearest trials, feasible or not
        rows = [i for i in near if key in (done[i].constraints or {})]
        if len(rows) >= 2 * d + 3:
            c = _fit_predict((X[rows] - x0) / r, np.array([float(done[i].constraints[key]) for i in rows]), cand,
                             n_full)
            pred = np.where(c <= 0, pred, -np.inf)
    best = int(np.argmax(pred))
    if not np.isfinite(pred[best]) or pred[best] <= pred[0] or np.linalg.norm(cand[best]) * r < 1e-9:
        return None
    return np.clip(x0 + r * cand[best], 0.0, 1.0)


def _fit_predict(Z: np.ndarray, y: np.ndarray, cand: np.ndarray, n_full: int) -> np.ndarray:
    """A quadratic least-squares fit of ``y`` at offsets ``Z`` (cross terms when there are enough points), at ``cand``."""
    full = len(Z) >= n_full + 3
    scale = max(float(np.ptp(y)), 1e-300)
    coef, *_ = np.linalg.lstsq(_features(Z, full), (y - y.mean()) / scale, rcond=None)
    return (_features(cand, full) @ coef) * scale + y.mean()


def _rank(t, sign: float) -> tuple:
    """Sort key of a complete trial, larger is better: feasible first, then the objective; else least violation."""
    violation = sum(max(float(v), 0.0) for v in t.constraints.values()) if t.constraints else 0.0
    if violation > 0:
        return (0, -violation)
    v = t.values[0] if t.values else float("nan")
    return (1, sign * v if math.isfinite(v) else -math.inf)


def _to_unit(x: float, dist) -> float:
    lo, hi = dist.low, dist.high
    if getattr(dist, "log", False):
        return (math.log(x) - math.log(lo)) / (math.log(hi) - math.log(lo))
    return (x - lo) / (hi - lo)


def _from_unit(u: float, dist) -> float:
    lo, hi = dist.low, dist.high
    u = min(max(float(u), 0.0), 1.0)
    x = math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))) if getattr(dist, "log", False) else lo + u * (hi - lo)
    return min(max(x, lo), hi)
