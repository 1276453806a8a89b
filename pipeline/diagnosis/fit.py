"""Multi-start bounded least squares (scipy ``least_squares``, trf) on noise-normalised residuals,
with the forward-difference Jacobian columns simulated in parallel, and the parameter covariance."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from pipeline.diagnosis.model import Evaluator, FreeParam


@dataclass
class FitResult:
    """Best fit: values (parameter units), sd and 95 % interval (from the log10 covariance), chi2
    (sum of squared normalised residuals), number of residuals, starts tried."""

    values: dict[str, float]
    sd: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    chi2: float
    n: int
    free: list[str]
    nfev: int
    starts: list[dict] = field(default_factory=list)

    @property
    def k(self) -> int:
        return len(self.free)

    def bic(self) -> float:
        """Bayesian information criterion with the noise sd known: chi2 + k ln n."""
        return self.chi2 + self.k * math.log(max(self.n, 2))


POLISH_STEP = 0.002
"""Finite-difference step [log10] of the polishing iterations (0.46 % of a parameter)."""
POLISH_NFEV = 6
"""Polishing iterations after the main fit."""


@dataclass(frozen=True)
class FitJob:
    """One fit: ``free`` (log10) on runs ``idx`` with ``fixed`` held, from each of ``starts`` (dict name -> value;
    clipped to bounds); see :func:`fit`."""

    idx: list[int]
    free: list[FreeParam]
    fixed: dict
    starts: list[dict]
    max_nfev: int = 20
    diff_step: float = 0.01
    polish: bool = True
    coarse: bool = False


@dataclass(frozen=True)
class StartFit:
    """One start's solution: x [log10], chi2, the residual and Jacobian at x, simulations spent, and the record of
    the start for ``FitResult.starts``."""

    x: np.ndarray
    chi2: float
    fun: np.ndarray
    jac: np.ndarray
    nfev: int
    tried: dict


class _Problem:
    """Residual and forward-difference Jacobian of a job for ``least_squares``.  Every point simulated is kept with
    its whole residual; the coarse stage reads the low-harmonic part of it (``features.low_harmonics``), so the full
    stage, which starts where the coarse one ended, finds its first residual and Jacobian (and a replayed trial step)
    already simulated."""

    def __init__(self, ev: Evaluator, job: FitJob, step: float):
        self.ev, self.job, self.step = ev, job, step
        self.names = [p.name for p in job.free]
        self.hi = np.array([p.bounds[1] for p in job.free])
        self.cache: dict[bytes, np.ndarray] = {}      # x [log10] -> the whole residual there
        self.low = False           # compare the low harmonics only (the coarse stage)
        self.low_mask = np.concatenate([ev.targets[i].low for i in job.idx]) if job.idx else np.ones(0, bool)
        self.nfev = 0

    def params(self, x: np.ndarray) -> dict:
        return {**self.job.fixed, **{n: 10.0 ** v for n, v in zip(self.names, x)}}

    def whole(self, xs: list[np.ndarray]) -> list[np.ndarray]:
        """The whole residual at each of ``xs``, the points not yet simulated simulated in one parallel batch."""
        new: dict[bytes, np.ndarray] = {}
        for x in xs:
            if x.tobytes() not in self.cache:
                new.setdefault(x.tobytes(), x)
        if new:
            rs = self.ev.residuals([self.params(x) for x in new.values()], self.job.idx)
            self.cache.update(zip(new, rs))
            self.nfev += len(new)
        return [self.cache[x.tobytes()] for x in xs]

    def _part(self, r: np.ndarray) -> np.ndarray:
        return r[self.low_mask] if self.low else r

    def fun(self, x: np.ndarray) -> np.ndarray:
        return self._part(self.whole([x])[0])

    def jac(self, x: np.ndarray) -> np.ndarray:
        """Columns simulated in one parallel batch; a step goes inwards at an upper bound."""
        steps = [self.step if x[j] + self.step <= self.hi[j] else -self.step for j in range(x.size)]
        xs = [x + np.eye(x.size)[j] * steps[j] for j in range(x.size)]
        f0, *rs = (self._part(r) for r in self.whole([x] + xs))
        return np.column_stack([(r - f0) / h for r, h in zip(rs, steps)])

    def solve(self, x0: np.ndarray, max_nfev: int, xtol: float, ftol: float):
        lo = np.array([p.bounds[0] for p in self.job.free])
        return least_squares(self.fun, x0, jac=self.jac, bounds=(lo, self.hi), method="trf", x_scale=1.0,
                             max_nfev=max_nfev, xtol=xtol, ftol=ftol)


def fit_start(ev: Evaluator, job: FitJob, k: int) -> StartFit:
    """Fit ``job`` from its start ``k`` (a pure function of its inputs: a task of its own)."""
    pb = _Problem(ev, job, job.diff_step)
    lo = np.array([p.bounds[0] for p in job.free])
    s = job.starts[k]
    x0 = np.clip(np.array([math.log10(max(s[n], 1e-300)) for n in pb.names]), lo + 1e-9, pb.hi - 1e-9)
    if job.coarse:
        pb.low = True
        x0 = pb.solve(x0, job.max_nfev, 1e-5, 1e-6).x
        pb.low = False
    sol = pb.solve(x0, job.max_nfev, 1e-5, 1e-6)
    chi2 = float(2.0 * sol.cost)
    tried = {"start": {n: float(10 ** v) for n, v in zip(pb.names, x0)}, "chi2": chi2,
             "end": {n: float(10 ** v) for n, v in zip(pb.names, sol.x)}}
    return StartFit(x=sol.x, chi2=chi2, fun=sol.fun, jac=sol.jac, nfev=pb.nfev, tried=tried)


def finish_fit(ev: Evaluator, job: FitJob, starts: list[StartFit]) -> FitResult:
    """The best of ``starts`` (the first on a tie), polished (``job.polish``), with its covariance."""
    best = starts[0]
    for s in starts[1:]:
        if s.chi2 < best.chi2:
            best = s
    x, chi2, fun, jm = best.x, best.chi2, best.fun, best.jac
    tried = [s.tried for s in starts]
    nfev = sum(s.nfev for s in starts)
    if job.polish and POLISH_NFEV > 0:
        pb = _Problem(ev, job, POLISH_STEP)
        pb.cache[x.tobytes()] = fun          # the polish starts where the best start ended (a whole residual)
        sol = pb.solve(x, POLISH_NFEV, 1e-6, 1e-7)
        nfev += pb.nfev
        if float(2.0 * sol.cost) < chi2:
            x, chi2, fun, jm = sol.x, float(2.0 * sol.cost), sol.fun, sol.jac
            tried.append({"start": "polish", "chi2": chi2, "end": {n: float(10 ** v) for n, v in zip(pb.names, x)}})
    names = [p.name for p in job.free]
    n = fun.size
    dof = max(n - len(names), 1)
    scale = max(1.0, chi2 / dof)       # inflate when the fit is worse than the noise (model error)
    cov = np.linalg.pinv(jm.T @ jm) * scale
    sd_log = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    values = {nm: float(10 ** v) for nm, v in zip(names, x)}
    sd_log = np.minimum(sd_log, 50.0)   # unidentifiable direction: report a huge but finite interval
    sd = {nm: float(values[nm] * math.log(10) * s) for nm, s in zip(names, sd_log)}
    ci = {nm: (float(10 ** (v - 1.96 * s)), float(10 ** (v + 1.96 * s))) for nm, v, s in zip(names, x, sd_log)}
    return FitResult(values=values, sd=sd, ci95=ci, chi2=chi2, n=n, free=names, nfev=nfev, starts=tried)


def fit(ev: Evaluator, idx: list[int], free: list[FreeParam], fixed: dict, starts: list[dict],
        max_nfev: int = 20, diff_step: float = 0.01, polish: bool = True, coarse: bool = False) -> FitResult:
    """Fit ``free`` (log10) on runs ``idx`` from each start (dict name -> value; clipped to bounds), then polish the
    best fit with POLISH_NFEV iterations at the finer step POLISH_STEP.  The coarse step (``diff_step``, 2.3 %)
    averages over what an impact-driven response does at small scales (a contact that starts one sample later)
    and finds the valley; there a coarse forward difference is too crude to follow a narrow curved valley to its
    floor (rate stiffening's alpha stopped at 30 s/m of 50), and the finer step finishes the walk.
    ``coarse``: each start is first fitted on the low harmonics only (``features.low_harmonics``), whose misfit has
    one basin where the high harmonics' has one per 1/k of a cycle of impact timing.
    The starts are independent (:func:`fit_start`) and :func:`finish_fit` combines them: an executor may run the
    starts of many fits at once (``pipeline.diagnosis.calibrate``)."""
    job = FitJob(idx, free, fixed, starts, max_nfev, diff_step, polish, coarse)
    return finish_fit(ev, job, [fit_start(ev, job, k) for k in range(len(starts))])
