"""An undeclared recording chain estimated as nuisance parameters beside the calibration (never a §6 effect).

Where runs.csv declares no DAQ chain for a series run, the log's chain is unknown: a delay per channel (what the
anti-alias filter and the DAQ's alignment leave, shared by every run of the log at the same sampling rate: the
filter follows the rate) and one clock error ε.  They are estimated once, on the base model's calibration: the base
model is fitted to every run with the chain profiled out of its residual (for each parameter set simulated, the
delays and ε that fit its features best, a cheap least squares on the harmonics' phases, ``profile``); for records
from rest the clock is then searched with the model sampled at the clock's instants (``estimate_chain``); and the
chain found is held fixed for every model the diagnosis fits and judges (base, candidates, pairs, proposals).  The physics never trades against it:
no candidate can move it, and it cannot move with a candidate.

The chain acts on the features as ``instrument.rotation``: harmonic k of signal s turns by k Ω (ε t̄ − τ_s).  A
delay is told from the clock by the clock's drift of phase over the record, which the records' two halves show
(their t̄ differ); the profile therefore compares the halves where a record has them.  Phases are unwrapped by
fitting the harmonics below PROFILE_CEILINGS_HZ in turn.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from pipeline.diagnosis.features import _coefs, _features, model_on_record, simulated_features
from pipeline.diagnosis.instrument import Nuisance, apply_gain, channel, rotation

MAX_DELAY_S = 2e-3
"""Bound of an estimated delay [s] (a delta-sigma ADC's uncompensated filter delays by ~1 ms at 25 kHz)."""
MAX_CLOCK = 1e-3
"""Bound of an estimated clock error [-] (1000 ppm; DAQ clocks are off by 10-100 ppm)."""
PROFILE_CEILINGS_HZ = (400.0, 1200.0, math.inf)
"""The profile fits the harmonics up to each of these frequencies in turn, from no delay: a delay of up to ~0.5 ms
turns the harmonics below 400 Hz by less than a quarter turn, so their phases need no unwrapping."""


@dataclass(frozen=True)
class ChainEstimate:
    """The estimated chain of a log: runs it applies to, delay per channel [s] with sd, clock error [ppm] with sd,
    and the calibration χ²/n of the base model fitted with it."""

    runs: tuple[str, ...]
    delay_s: tuple[tuple[tuple[str, float], float], ...]       # ((signal, sampling rate [Hz]), τ [s])
    delay_sd_s: tuple[tuple[tuple[str, float], float], ...]
    clock_ppm: float
    clock_sd_ppm: float
    base_chi2_per_n: float

    def to_record(self):
        """report.json ``recording.estimated`` (a ``report_types.EstimatedChain``)."""
        from pipeline.diagnosis.report_types import ChannelDelay, ClockEstimate, EstimatedChain

        sd = dict(self.delay_sd_s)
        return EstimatedChain(runs=tuple(self.runs),
                              delays=tuple(ChannelDelay(s, fs, v, sd[(s, fs)]) for (s, fs), v in self.delay_s),
                              clock_ppm=ClockEstimate(self.clock_ppm, self.clock_sd_ppm),
                              base_chi2_per_n=self.base_chi2_per_n, text=self.text())

    def text(self) -> str:
        sd = dict(self.delay_sd_s)
        d = ", ".join(f"{s} at {fs:g} Hz {1e6 * v:.2f} ± {1e6 * sd[(s, fs)]:.2f} µs" for (s, fs), v in self.delay_s)
        return (f"undeclared DAQ chain estimated on the base model's calibration and held fixed for every model: "
                f"delay {d}; clock {self.clock_ppm:.2f} ± {self.clock_sd_ppm:.2f} ppm ({len(self.runs)} runs)")


@dataclass(frozen=True)
class _Item:
    """One record (or half) in the profile: model and measured harmonic pairs, their sd, angular frequencies,
    channel index of each pair, mid time and length of the stretch."""

    m: np.ndarray
    y: np.ndarray
    sd_re: np.ndarray
    sd_im: np.ndarray
    kw: np.ndarray
    sig: np.ndarray
    tbar: float
    span: float


def _pairs(v: np.ndarray, at: np.ndarray) -> np.ndarray:
    return v[at] + 1j * v[at + 1]


def profile_items(tg, res, keys: tuple) -> list[_Item]:
    """The profile's items of one series run from its simulation ``res`` (the model's raw features, no chain): its
    two halves where it has them, else the whole record.  ``keys``: the delays' channels (``instrument.channel``)."""
    h = res.history if res is not None else None
    if h is None or not tg.pairs:
        return []
    sig = np.array([keys.index(channel(tg, s)) for s, _ in tg.pairs])
    x = {s: model_on_record(tg, h, s) for s in tg.signals}
    from_rest = tg.record_start_s is not None
    if tg.halves and tg.y_halves is not None:
        parts = [(_features(tg.signals, _coefs(ops, x, sl), from_rest), tg.y_halves[j], math.sqrt(2.0), tg.spans[j + 1])
                 for j, (sl, ops) in enumerate(tg.halves)]
    else:
        parts = [(_features(tg.signals, _coefs(tg.pinv, x), from_rest), tg.y, 1.0, tg.spans[0])]
    at = tg.pair_at
    out = []
    for m, y, inflate, (tbar, span) in parts:
        out.append(_Item(_pairs(m, at), _pairs(y, at), inflate * tg.sd[at], inflate * tg.sd[at + 1], tg.pair_kw,
                         sig, tbar, span))
    return out


def _residual(x: np.ndarray, items: list[_Item], ceiling: float, clock: bool = True) -> np.ndarray:
    tau, eps = (1e-6 * x[:-1], 1e-6 * x[-1]) if clock else (1e-6 * x, 0.0)
    out = []
    for it in items:
        keep = it.kw <= 2.0 * math.pi * ceiling
        z = rotation(it.kw[keep], tau[it.sig[keep]], eps, it.tbar, it.span) * it.m[keep] - it.y[keep]
        out += [z.real / it.sd_re[keep], z.imag / it.sd_im[keep]]
    return np.concatenate(out) if out else np.zeros(0)


def profile(items: list[_Item], n_sig: int, clock: bool = True) -> tuple[np.ndarray, np.ndarray, float, int]:
    """The delays [µs] and clock error [ppm] (``clock``; else the delays alone) that fit ``items`` best: (x, Jacobian
    of the normalised residual at x, χ², number of residuals)."""
    x = np.zeros(n_sig + int(clock))
    lim = np.r_[np.full(n_sig, 1e6 * MAX_DELAY_S), [1e6 * MAX_CLOCK] * int(clock)]
    sol = None
    for ceiling in PROFILE_CEILINGS_HZ:
        sol = least_squares(_residual, x, bounds=(-lim, lim), args=(items, ceiling, clock), method="trf",
                            x_scale=10.0, xtol=1e-10, ftol=1e-10, max_nfev=200)
        x = sol.x
    return x, sol.jac, float(2.0 * sol.cost), int(sol.fun.size)


def profiled_residuals(ev, sims: list[list], idx: list[int], low_only: bool) -> list[np.ndarray]:
    """``Evaluator.residuals`` with the chain of ``ev.profile_runs`` profiled out of every parameter set's
    residual (the chain that fits that set's simulations best, ``profile``)."""
    sig_names = ev.profile_signals
    out = []
    for row in sims:
        items = [it for i, r in zip(idx, row) if i in ev.profile_runs
                 for it in profile_items(ev.targets[i], r, sig_names)]
        nuis = None
        if items:
            x = profile(items, len(sig_names))[0]
            nuis = Nuisance(tuple((key, 1e-6 * v) for key, v in zip(sig_names, x[:-1])), 1e-6 * x[-1])
        parts = []
        for i, r in zip(idx, row):
            tg = ev.targets[i]
            ri = ev.residual_of(i, r)
            m = simulated_features(tg, r)
            if nuis is not None and i in ev.profile_runs and m is not None:   # the targets stay as they are
                tau = np.array([nuis.delay(channel(tg, s)) for s, _ in tg.pairs])
                ri = (apply_gain(m, tg.pair_at, rotation(tg.pair_kw, tau, nuis.clock, *tg.spans[0])) - tg.y) / tg.sd
            parts.append(ri[tg.low] if low_only else ri)
        out.append(np.concatenate(parts))
    return out


def undeclared_runs(targets) -> list[int]:
    """Series runs without a declared chain (their chain is a nuisance to estimate)."""
    return [i for i, t in enumerate(targets) if t.kind == "series" and t.chain is None and t.pairs]


def estimate_chain(ev, cfg, executor, log=print) -> ChainEstimate | None:
    """Fit the base model to every run with the undeclared chain profiled out, then set the chain of that fit on
    the undeclared runs' targets (held fixed from then on); None when every series run declares its chain."""
    import copy

    from pipeline.diagnosis.calibrate import _fits, nominal_values, random_starts
    from pipeline.diagnosis.fit import FitJob
    from pipeline.diagnosis.model import calibratable

    und = undeclared_runs(ev.targets)
    if not und:
        return None
    sig_names = tuple(dict.fromkeys(channel(ev.targets[i], s) for i in und for s, _ in ev.targets[i].pairs))
    idx = list(range(len(ev.targets)))
    pev = copy.copy(ev)
    pev.profile_runs, pev.profile_signals = frozenset(und), sig_names
    free = list(calibratable(ev.system))
    rng = np.random.default_rng([cfg.seed, 44])
    job = FitJob(idx, free, {}, random_starts(free, nominal_values(ev, idx), cfg.n_starts, rng), cfg.max_nfev,
                 cfg.diff_step, coarse=True)
    [fr] = _fits(executor, ev, pev.for_tasks(executor.task_threads), [job])
    x0, jac0, chi2_0, n0 = _at_clock(ev, und, fr.values, sig_names, None)
    if all(ev.targets[i].record_start_s is None for i in und):     # steady state: the rotation is exact
        return _finish(ev, und, sig_names, x0[:-1], float(x0[-1]), None, (x0, jac0, chi2_0, n0), fr, log)
    # the rotation is exact for a steady state only: a record from rest has its transient stretched by the clock too
    # (a drill log read 66 ppm for 80 by the rotation; χ²/n 0.91 there, 0.17 with the clock at the instants).  So
    # the clock is applied at the model's instants and searched on a grid around the rotation's estimate (coarse,
    # then fine: the χ² left when the delays are profiled out at each clock is not smooth enough for a parabola)
    pts: dict[float, tuple] = {}
    centre = float(x0[-1])
    for step, half in CLOCK_GRID:
        for e in centre + step * np.arange(-half, half + 1):
            e = round(float(np.clip(e, -1e6 * MAX_CLOCK, 1e6 * MAX_CLOCK)), 6)
            if e not in pts:
                pts[e] = _at_clock(ev, und, fr.values, sig_names, e)
        centre = min(pts, key=lambda e: pts[e][2])
    eps = centre
    x, _, chi2, n = pts[eps]
    near = sorted(pts, key=lambda e: abs(e - eps))[:5]
    a = np.polyfit(near, [pts[e][2] for e in near], 2)[0]
    scale = max(1.0, chi2 / max(n - x.size - 1, 1))
    # one sd: where χ² rises by the scale; at least half the fine grid's step (its resolution)
    clock_sd = max(float(np.sqrt(scale / a)) if a > 0 else math.inf, 0.5 * CLOCK_GRID[-1][0])
    return _finish(ev, und, sig_names, x, eps, clock_sd, pts[eps], fr, log)


def _finish(ev, und: list[int], keys: tuple, delays_us: np.ndarray, eps_ppm: float, clock_sd: float | None,
            prof: tuple, fr, log) -> ChainEstimate:
    """The estimate, its sd (the profile's Jacobian ``prof``, inflated by χ²/dof when above 1; the clock's
    ``clock_sd`` where it was searched at the instants, else from the Jacobian too) set on the targets: the clock at
    the instants where searched there (``clock_sd`` given), else as a rotation (steady state: exact)."""
    x, jac, chi2, n = prof
    scale = max(1.0, chi2 / max(n - x.size, 1))     # a model error inflates the sd as in the calibration
    sd = np.sqrt(np.clip(np.diag(np.linalg.pinv(jac.T @ jac)) * scale, 0.0, None))
    at_instants = clock_sd is not None
    est = ChainEstimate(runs=tuple(ev.targets[i].run_id for i in und),
                        delay_s=tuple((s, 1e-6 * float(v)) for s, v in zip(keys, delays_us)),
                        delay_sd_s=tuple((s, 1e-6 * float(v)) for s, v in zip(keys, sd)),
                        clock_ppm=eps_ppm, clock_sd_ppm=clock_sd if at_instants else float(sd[-1]),
                        base_chi2_per_n=fr.chi2 / max(fr.n, 1))
    rotation_only = Nuisance(est.delay_s, 0.0 if at_instants else 1e-6 * eps_ppm)
    _set(ev, und, eps_ppm if at_instants else None, rotation_only)
    log(f"{ev.system}: {est.text()}")
    return est


CLOCK_GRID = ((5.0, 6), (1.0, 4))
"""The clock search: (step [ppm], points either side) of a coarse grid around the rotation's estimate, then a fine
one around the coarse grid's best (each point one simulation of the undeclared runs)."""


def _set(ev, und: list[int], eps_ppm: float | None, rotation: Nuisance | None) -> None:
    """The clock ``eps_ppm`` at the model's instants (None: none) and ``rotation`` on the runs ``und``."""
    from pipeline.datasets.daq import DeclaredChain

    for i in und:
        ev.targets[i].timing = None if eps_ppm is None else DeclaredChain(None, 0.0, eps_ppm)
        ev.targets[i].nuisance = rotation


def _at_clock(ev, und: list[int], values: dict, keys: tuple, eps_ppm: float | None):
    """``profile`` of the undeclared runs simulated at ``values``: with the clock ``eps_ppm`` applied at the instants
    and the delays alone profiled, or (None) delays and clock as a rotation."""
    _set(ev, und, eps_ppm, None)
    row = ev.simulate([values], und)[0]
    items = [it for i, r in zip(und, row) for it in profile_items(ev.targets[i], r, keys)]
    return profile(items, len(keys), clock=eps_ppm is None)
