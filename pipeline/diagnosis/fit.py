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


def fit(ev: Evaluator, idx: list[int], free: list[FreeParam], fixed: dict, starts: list[dict],
        max_nfev: int = 20, diff_step: float = 0.01, polish: bool = True, coarse: bool = False) -> FitResult:
    """Fit ``free`` (log10) on runs ``idx`` from each start (dict name -> value; clipped to bounds), then polish the
    best fit with POLISH_NFEV iterations at the finer step POLISH_STEP.  The coarse step (``diff_step``, 2.3 %)
    averages over what an impact-driven response does at small scales (a contact that starts one sample later)
    and finds the valley; there a coarse forward difference is too crude to follow a narrow curved valley to its
    floor (rate stiffening's alpha stopped at 30 s/m of 50), and the finer step finishes the walk.
    ``coarse``: each start is first fitted on the low harmonics only (``features.low_harmonics``), whose misfit has
    one basin where the high harmonics' has one per 1/k of a cycle of impact timing."""
    lo = np.array([p.bounds[0] for p in free])
    hi = np.array([p.bounds[1] for p in free])
    names = [p.name for p in free]
    cache: dict[bytes, np.ndarray] = {}
    nfev = 0

    def params(x: np.ndarray) -> dict:
        return {**fixed, **{n: 10.0 ** v for n, v in zip(names, x)}}

    low = [False]

    def fun(x: np.ndarray) -> np.ndarray:
        nonlocal nfev
        key = x.tobytes() + (b"low" if low[0] else b"")
        if key not in cache:
            cache[key] = ev.residuals([params(x)], idx, low_only=low[0])[0]
            nfev += 1
        return cache[key]

    step = [diff_step]

    def jac(x: np.ndarray) -> np.ndarray:
        nonlocal nfev
        f0 = fun(x)
        steps = []
        for j in range(x.size):      # step inwards at an upper bound
            h = step[0] if x[j] + step[0] <= hi[j] else -step[0]
            steps.append(h)
        xs = [x + np.eye(x.size)[j] * steps[j] for j in range(x.size)]
        rs = ev.residuals([params(xj) for xj in xs], idx, low_only=low[0])
        nfev += x.size
        return np.column_stack([(r - f0) / h for r, h in zip(rs, steps)])

    best, tried = None, []
    for s in starts:
        x0 = np.clip(np.array([math.log10(max(s[n], 1e-300)) for n in names]), lo + 1e-9, hi - 1e-9)
        if coarse:
            low[0] = True
            x0 = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=max_nfev,
                               xtol=1e-5, ftol=1e-6).x
            low[0] = False
        sol = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=max_nfev,
                            xtol=1e-5, ftol=1e-6)
        chi2 = float(2.0 * sol.cost)
        tried.append({"start": {n: float(10 ** v) for n, v in zip(names, x0)}, "chi2": chi2,
                      "end": {n: float(10 ** v) for n, v in zip(names, sol.x)}})
        if best is None or chi2 < best[1]:
            best = (sol, chi2)
    if polish and POLISH_NFEV > 0:
        step[0] = POLISH_STEP
        sol = least_squares(fun, best[0].x, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=POLISH_NFEV,
                            xtol=1e-6, ftol=1e-7)
        if float(2.0 * sol.cost) < best[1]:
            best = (sol, float(2.0 * sol.cost))
            tried.append({"start": "polish", "chi2": best[1], "end": {n: float(10 ** v) for n, v in zip(names, sol.x)}})
    sol, chi2 = best
    n = sol.fun.size
    jm = sol.jac
    dof = max(n - len(names), 1)
    scale = max(1.0, chi2 / dof)       # inflate when the fit is worse than the noise (model error)
    cov = np.linalg.pinv(jm.T @ jm) * scale
    sd_log = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    values = {nm: float(10 ** v) for nm, v in zip(names, sol.x)}
    sd_log = np.minimum(sd_log, 50.0)   # unidentifiable direction: report a huge but finite interval
    sd = {nm: float(values[nm] * math.log(10) * s) for nm, s in zip(names, sd_log)}
    ci = {nm: (float(10 ** (v - 1.96 * s)), float(10 ** (v + 1.96 * s))) for nm, v, s in zip(names, sol.x, sd_log)}
    return FitResult(values=values, sd=sd, ci95=ci, chi2=chi2, n=n, free=names, nfev=nfev, starts=tried)
