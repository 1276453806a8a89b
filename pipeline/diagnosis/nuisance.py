"""An undeclared recording chain estimated as nuisance parameters beside every fit (never a §6 effect).

Where runs.csv declares no DAQ chain for a series run, the log's chain is unknown: a delay per channel (what the
anti-alias filter and the DAQ's alignment leave, shared by every run of the log at the same sampling rate: the
filter follows the rate) and one clock error ε.  They are profiled out of every model's residual: for each
parameter set simulated, the delays and ε that fit its features best (a cheap least squares on the harmonics'
phases, ``profile``).  A chain fixed from the base model's fit would take up whatever of a missing effect looks like
a delay (a shaker coil's lag, guide friction's phase, an accelerometer's own low-pass) before any candidate is
fitted; profiled inside each fit, the chain moves with the model, and a model's held-out runs are read through the
chain of its own calibration runs (``calibration_chains``).  The base model's fit starts it (``estimate_chain``):
for records from rest the clock is located there with the model sampled at the clock's instants, and each fit
profiles what is left as a rotation; where two effects are tried the clock is located again at the leader's and
the leading pair's fits, and at the final model's for the report (``locate_chain``).

The chain acts on the features as ``instrument.rotation``: harmonic k of signal s turns by k Ω (ε t̄ − τ_s).  A
delay is told from the clock by the clock's drift of phase over the record, which the records' two halves show
(their t̄ differ); the profile therefore compares the halves where a record has them.  Phases are unwrapped by
fitting the harmonics below PROFILE_CEILINGS_HZ in turn.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from pipeline.diagnosis.features import _coefs, _features, antialias_compensation, history_columns, model_on_record
from pipeline.diagnosis.instrument import Nuisance, channel, rotation

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
    model: str = "base"
    """The model whose fit the chain was profiled in (the final one)."""

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
        return (f"undeclared DAQ chain profiled in every model's fit, as fitted with the {self.model} model: "
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
    h = history_columns(res) if res is not None else None
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
    comp = antialias_compensation(tg)
    out = []
    for m, y, inflate, (tbar, span) in parts:
        out.append(_Item(_pairs(m, at) * (1.0 if comp is None else comp), _pairs(y, at), inflate * tg.sd[at], inflate * tg.sd[at + 1], tg.pair_kw,
                         sig, tbar, span))
    return out


@dataclass(frozen=True)
class _Kept:
    """The items' harmonics below a ceiling, concatenated: angular frequency, channel, model and measured pair, sd
    of its real and imaginary part, mid time and length of its stretch (per harmonic)."""

    kw: np.ndarray
    sig: np.ndarray
    m: np.ndarray
    y: np.ndarray
    sd_re: np.ndarray
    sd_im: np.ndarray
    tbar: np.ndarray
    span: np.ndarray


def _kept(items: list[_Item], ceiling: float) -> _Kept:
    """The harmonics of ``items`` below ``ceiling`` [Hz], in one set of arrays."""
    keep = [it.kw <= 2.0 * math.pi * ceiling for it in items]
    cat = lambda f: np.concatenate([f(it)[k] for it, k in zip(items, keep)]) if items else np.zeros(0)  # noqa: E731
    return _Kept(cat(lambda it: it.kw), cat(lambda it: it.sig).astype(int), cat(lambda it: it.m), cat(lambda it: it.y),
                 cat(lambda it: it.sd_re), cat(lambda it: it.sd_im), cat(lambda it: np.full(it.kw.size, it.tbar)),
                 cat(lambda it: np.full(it.kw.size, it.span)))


def _split(x: np.ndarray, clock: bool) -> tuple[np.ndarray, float]:
    return (1e-6 * x[:-1], 1e-6 * x[-1]) if clock else (1e-6 * x, 0.0)


def _residual(x: np.ndarray, k: _Kept, clock: bool = True) -> np.ndarray:
    tau, eps = _split(x, clock)
    z = rotation(k.kw, tau[k.sig], eps, k.tbar, k.span) * k.m - k.y
    return np.concatenate([z.real / k.sd_re, z.imag / k.sd_im])


def _jacobian(x: np.ndarray, k: _Kept, clock: bool = True) -> np.ndarray:
    """d residual / d x (delays [µs], clock [ppm]) of ``_residual``, analytic: a delay turns its channel's pairs
    by −i kΩ, the clock by i kΩ t̄ and scales them by the sinc's derivative."""
    tau, eps = _split(x, clock)
    u = k.kw * eps * k.span / (2.0 * np.pi)
    sinc = np.sinc(u)
    turn = np.exp(1j * k.kw * (eps * k.tbar - tau[k.sig]))
    zm = sinc * turn * k.m
    block = np.zeros((k.kw.size, x.size), dtype=complex)
    block[np.arange(k.kw.size), k.sig] = -1j * k.kw * zm * 1e-6
    if clock:
        safe = np.where(u != 0.0, u, 1.0)
        dsinc = np.where(u != 0.0, (np.cos(np.pi * u) - sinc) / safe, 0.0)
        block[:, -1] = (dsinc * k.kw * k.span / (2.0 * np.pi) * turn * k.m + 1j * k.kw * k.tbar * zm) * 1e-6
    return np.concatenate([block.real / k.sd_re[:, None], block.imag / k.sd_im[:, None]])


def lowest_delays_us(keys: tuple) -> np.ndarray:
    """Lower bound of each channel's delay [µs]: a causal chain only delays, but a multiplexed ADC may sample a
    channel up to one sample interval before the instant it is dated, so down to −1/fs."""
    return np.array([-1e6 / fs for _, fs in keys])


def profile(items: list[_Item], n_sig: int, clock: bool = True, lowest_us: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """The delays [µs] and clock error [ppm] (``clock``; else the delays alone) that fit ``items`` best, each delay
    within [``lowest_us``, MAX_DELAY_S] (default lower bound −MAX_DELAY_S): (x, Jacobian of the normalised residual
    at x, χ², number of residuals)."""
    x = np.zeros(n_sig + int(clock))
    lim = np.r_[np.full(n_sig, 1e6 * MAX_DELAY_S), [1e6 * MAX_CLOCK] * int(clock)]
    low = -lim.copy()
    if lowest_us is not None:
        low[:n_sig] = lowest_us
    for ceiling in PROFILE_CEILINGS_HZ:
        kept = _kept(items, ceiling)
        if kept.kw.size == 0 and math.isfinite(ceiling):
            continue
        sol = None
        if kept.kw.size * 2 >= x.size:      # Levenberg-Marquardt (MINPACK): twice as fast as the bounded trf here
            sol = least_squares(_residual, x, jac=_jacobian, args=(kept, clock), method="lm", x_scale=10.0,
                                xtol=1e-10, ftol=1e-10, max_nfev=200)
        if sol is None or np.any(sol.x > lim) or np.any(sol.x < low):
            sol = least_squares(_residual, np.clip(x, low, lim), jac=_jacobian, bounds=(low, lim),
                                args=(kept, clock), method="trf", x_scale=10.0, xtol=1e-10, ftol=1e-10, max_nfev=200)
        x = sol.x
    return x, sol.jac, float(2.0 * sol.cost), int(sol.fun.size)


def with_chain(tg, nuis: Nuisance | None):
    """``tg`` with the undeclared chain ``nuis`` in place of its own (a shallow copy; ``tg`` when ``nuis`` is None)."""
    if nuis is None:
        return tg
    out = copy.copy(tg)
    out.nuisance = nuis
    return out


def _profiled_chain(ev, row: list, idx: list[int]) -> tuple[Nuisance | None, tuple | None]:
    """The chain that fits the simulations ``row`` of runs ``idx`` best (``profile`` over the profiled runs among
    them), with the profile's (x, Jacobian, χ², n); (None, None) when none of them is profiled."""
    sig_names = ev.profile_signals
    items = [it for i, r in zip(idx, row) if i in ev.profile_runs
             for it in profile_items(ev.targets[i], r, sig_names)]
    if not items:
        return None, None
    prof = profile(items, len(sig_names), lowest_us=lowest_delays_us(sig_names))
    x = prof[0]
    seen = {int(c) for it in items for c in it.sig}
    delays = delays_at_unseen_rates(x[:-1], sig_names, seen)
    return Nuisance(tuple((key, 1e-6 * v) for key, v in zip(sig_names, delays)), 1e-6 * x[-1]), prof


def delays_at_unseen_rates(delays_us: np.ndarray, keys: tuple, seen: set[int]) -> np.ndarray:
    """``delays_us`` with each channel (signal, sampling rate) that no profiled record measured filled in from the
    measured ones: the anti-alias filter follows the rate (cut-off a fixed fraction of fs), so a delay is the same
    number of samples at every rate.  The same signal at the nearest measured rate, else the median over the
    measured signals (one front end per DAQ), in samples; 0 when nothing is measured.  A held-out run recorded at
    a rate no calibration run has would otherwise be read with no delay at all."""
    out = np.array(delays_us, dtype=float, copy=True)
    samples = {j: delays_us[j] * keys[j][1] for j in seen}          # [µs Hz] = 1e-6 samples
    if not samples:
        return out
    for j, (sig, fs) in enumerate(keys):
        if j in seen:
            continue
        same = [i for i in samples if keys[i][0] == sig]
        if same:
            near = min(same, key=lambda i: abs(math.log(keys[i][1] / fs)))
            out[j] = samples[near] / fs
        else:
            out[j] = float(np.median(list(samples.values()))) / fs
    return out


def profiled_residuals(ev, sims: list[list], idx: list[int]) -> list[np.ndarray]:
    """``Evaluator.residuals`` with the chain of ``ev.profile_runs`` profiled out of every parameter set's
    residual (the chain that fits that set's simulations best, ``profile``, in place of the targets' own)."""
    out = []
    for row in sims:
        nuis = _profiled_chain(ev, row, idx)[0]
        out.append(np.concatenate([ev.residual_for(with_chain(ev.targets[i], nuis) if i in ev.profile_runs
                                                   else ev.targets[i], r) for i, r in zip(idx, row)]))
    return out


def calibration_chains(ev, param_sets: list[dict], cal: list[int]) -> list[Nuisance | None]:
    """Per parameter set, the chain that fits its simulations of the calibration runs ``cal`` best (None: none of
    them profiled): a model's held-out runs are read through the chain of its own calibration, never one fitted to
    the held-out runs themselves."""
    cal = [i for i in cal if i in ev.profile_runs]
    if not cal or not param_sets:
        return [None] * len(param_sets)
    return [_profiled_chain(ev, row, cal)[0] for row in ev.simulate(param_sets, cal)]


def undeclared_runs(targets) -> list[int]:
    """Series runs without a declared chain (their chain is a nuisance to estimate)."""
    return [i for i, t in enumerate(targets) if t.kind == "series" and t.chain is None and t.pairs]


def estimate_chain(ev, cfg, executor, log=print, exclude: set[str] = frozenset()) -> ChainEstimate | None:
    """Fit the base model to every run with the undeclared chain profiled out, set the chain of that fit on the
    undeclared runs' targets (the clock at the instants for records from rest) and profile the chain in every fit
    from then on; None when every series run declares its chain.  The runs ``exclude`` (ids: the model's response
    there is not reproducible) are left out: their delays stay 0."""
    from pipeline.diagnosis.calibrate import _fits, nominal_values, random_starts
    from pipeline.diagnosis.fit import FitJob
    from pipeline.diagnosis.model import calibratable

    und = [i for i in undeclared_runs(ev.targets) if ev.targets[i].run_id not in exclude]
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
    est = _locate(ev, und, sig_names, fr.values, fr.chi2 / max(fr.n, 1), "base")
    if cfg.antialias is None and shows_a_filter(est) and not any(ev.targets[i].antialias for i in und):
        # the records passed an anti-alias filter: the model's content above their Nyquist frequency, which the
        # filter removed from the data, would fold onto the harmonics; the base is fitted again with it removed
        log(f"{ev.system}: the undeclared chain's delays show an anti-alias filter ({est.text()}): the model is "
            f"low-passed before it is sampled, and the chain estimated again")
        for i in und:
            ev.targets[i].antialias = True
        job = FitJob(idx, free, {}, [fr.values], cfg.max_nfev, cfg.diff_step, coarse=True)
        [fr] = _fits(executor, ev, pev.for_tasks(executor.task_threads), [job])
        est = _locate(ev, und, sig_names, fr.values, fr.chi2 / max(fr.n, 1), "base")
    ev.profile_runs, ev.profile_signals = frozenset(und), sig_names
    log(f"{ev.system}: {est.text()}")
    return est


FILTER_SAMPLES = 0.5
"""An undeclared chain whose channels' median delay is at least this many sample intervals has an anti-alias
filter (an 8th-order Butterworth at 0.45 fs delays by 1.8, a 4th-order at 0.4 fs by 1.1; a plain sampler by 0)."""
FILTER_SCALING = 0.5
"""... and, where a channel was recorded at two rates, whose delays scale with the sample interval: d ∝ fs^-s with
s at least this (a filter designed relative to the rate: s = 1; a delay the base model's misfit puts there, e.g.
a shaker coil's lag the base lacks, stays fixed in time: s ~ 0)."""


def delay_scaling(est: ChainEstimate) -> float | None:
    """The median over channels and pairs of rates of s in d ∝ fs^-s (0 where a delay is not positive); None when
    no channel has two rates."""
    by_channel: dict[str, list[tuple[float, float]]] = {}
    for (sig, fs), v in est.delay_s:
        by_channel.setdefault(sig, []).append((fs, v))
    exps = []
    for rows in by_channel.values():
        rows.sort()
        for k, (fa, da) in enumerate(rows):
            for fb, db in rows[k + 1:]:
                if fb > fa:
                    exps.append(math.log(da / db) / math.log(fb / fa) if da > 0 and db > 0 else 0.0)
    return float(np.median(exps)) if exps else None


def shows_a_filter(est: ChainEstimate) -> bool:
    """Whether the estimated delays say the records passed an anti-alias filter: at least ``FILTER_SAMPLES`` sample
    intervals in the median and, where the log has two rates, scaling with the sample interval (``FILTER_SCALING``)."""
    samples = [v * fs for (_, fs), v in est.delay_s]
    if not samples or float(np.median(samples)) < FILTER_SAMPLES:
        return False
    scaling = delay_scaling(est)
    return scaling is None or scaling >= FILTER_SCALING


def _locate(ev, und: list[int], keys: tuple, values: dict, chi2_per_n: float, model: str) -> ChainEstimate:
    """The chain that fits the model at ``values`` best on the undeclared runs ``und``, set on their targets: for
    steady-state records delays and clock as a rotation (exact there); for records from rest the clock at the
    model's instants, searched on ``CLOCK_GRID``, and the delays profiled at each clock."""
    x0, jac0, chi2_0, n0 = _at_clock(ev, und, values, keys, None)
    if all(ev.targets[i].record_start_s is None for i in und):     # steady state: the rotation is exact
        est = _estimate(ev, und, keys, (x0, jac0, chi2_0, n0), float(x0[-1]), chi2_per_n, model)
        _set(ev, und, None, Nuisance(est.delay_s, 1e-6 * float(x0[-1])))
        return est
    # the rotation is exact for a steady state only: a record from rest has its transient stretched by the clock too
    # (a drill log read 66 ppm for 80 by the rotation; χ²/n 0.91 there, 0.17 with the clock at the instants).  So
    # the clock is applied at the model's instants and searched on a grid around the rotation's estimate (coarse,
    # then fine: the χ² left when the delays are profiled out at each clock is not smooth enough for a parabola)
    pts: dict[float, tuple] = {}
    per_run: dict[float, list[list[_Item]]] = {}
    centre = float(x0[-1])
    for step, half in CLOCK_GRID:
        for e in centre + step * np.arange(-half, half + 1):
            e = round(float(np.clip(e, -1e6 * MAX_CLOCK, 1e6 * MAX_CLOCK)), 6)
            if e not in pts:
                pts[e], per_run[e] = _at_clock(ev, und, values, keys, e, per_run=True)
        centre = min(pts, key=lambda e: pts[e][2])
    eps = centre
    x, _, chi2, n = pts[eps]
    near = sorted(pts, key=lambda e: abs(e - eps))[:5]
    a = np.polyfit(near, [pts[e][2] for e in near], 2)[0]
    scale = max(1.0, chi2 / max(n - x.size - 1, 1))
    # one sd: where χ² rises by the scale, or the runs' disagreement where larger; at least half the fine grid's
    # step (its resolution)
    clock_sd = max(float(np.sqrt(scale / a)) if a > 0 else math.inf, 0.5 * CLOCK_GRID[-1][0],
                   jackknife_clock_sd(per_run, keys))
    est = _estimate(ev, und, keys, pts[eps], eps, chi2_per_n, model)
    jk = jackknife_delay_sd_us(per_run[eps], keys)
    est = replace(est, clock_sd_ppm=clock_sd,
                  delay_sd_s=tuple((k, max(v, 1e-6 * j)) for (k, v), j in zip(est.delay_sd_s, jk)))
    _set(ev, und, eps, Nuisance(est.delay_s, 0.0))
    return est


def _estimate(ev, und: list[int], keys: tuple, prof: tuple, clock_ppm: float, chi2_per_n: float,
              model: str) -> ChainEstimate:
    """The estimate of a profile ``prof`` (x: delays [µs], then the clock [ppm] where profiled, Jacobian, χ², n) with
    the clock ``clock_ppm``; sd from the Jacobian, inflated by χ²/dof when above 1 (a model error inflates it as in
    the calibration).  A profile of the delays alone (the clock at the instants) has no clock sd: 0."""
    x, jac, chi2, n = prof
    scale = max(1.0, chi2 / max(n - jac.shape[1], 1))
    sd = np.sqrt(np.clip(np.diag(np.linalg.pinv(jac.T @ jac)) * scale, 0.0, None))
    clock_sd = float(sd[-1]) if jac.shape[1] > len(keys) else 0.0
    return ChainEstimate(runs=tuple(ev.targets[i].run_id for i in und),
                         delay_s=tuple((s, 1e-6 * float(v)) for s, v in zip(keys, x[:len(keys)])),
                         delay_sd_s=tuple((s, 1e-6 * float(v)) for s, v in zip(keys, sd[:len(keys)])),
                         clock_ppm=clock_ppm, clock_sd_ppm=clock_sd, base_chi2_per_n=chi2_per_n, model=model)


def locate_chain(ev, est: ChainEstimate | None, model: str, values: dict, log=print) -> ChainEstimate | None:
    """The chain located again at ``model``'s fit ``values`` (``_locate``) and set on the targets: at the leader's
    and the leading pair's where two effects are tried, at the final model's for what reads it then (figures,
    residuals, the rig file).  ``est`` unchanged when nothing is profiled."""
    und = sorted(ev.profile_runs)
    if est is None or not und:
        return est
    out = _locate(ev, und, ev.profile_signals, values, est.base_chi2_per_n, model)
    if model != "base":
        log(f"{ev.system}: {out.text()}")
    return out


CLOCK_GRID = ((5.0, 6), (1.0, 4))
"""The clock search: (step [ppm], points either side) of a coarse grid around the rotation's estimate, then a fine
one around the coarse grid's best (each point one simulation of the undeclared runs)."""


def _set(ev, und: list[int], eps_ppm: float | None, rotation: Nuisance | None) -> None:
    """The clock ``eps_ppm`` at the model's instants (None: none) and ``rotation`` on the runs ``und``."""
    from pipeline.datasets.daq import DeclaredChain

    for i in und:
        ev.targets[i].timing = None if eps_ppm is None else DeclaredChain(None, 0.0, eps_ppm)
        ev.targets[i].nuisance = rotation


def _at_clock(ev, und: list[int], values: dict, keys: tuple, eps_ppm: float | None, per_run: bool = False):
    """``profile`` of the undeclared runs simulated at ``values``: with the clock ``eps_ppm`` applied at the instants
    and the delays alone profiled, or (None) delays and clock as a rotation; with each run's items (``per_run``)."""
    _set(ev, und, eps_ppm, None)
    row = ev.simulate([values], und)[0]
    per = [profile_items(ev.targets[i], r, keys) for i, r in zip(und, row)]
    prof = profile([it for p in per for it in p], len(keys), clock=eps_ppm is None, lowest_us=lowest_delays_us(keys))
    return (prof, per) if per_run else prof


def jackknife_clock_sd(per_run: dict[float, list[list[_Item]]], keys: tuple) -> float:
    """The jackknife sd [ppm] of the clock located at the instants, each run left out in turn (χ² with the delays
    profiled, at the clocks of ``per_run``: clock [ppm] -> each run's profile items there).  The clock is told from
    the delays by how the records' times differ between runs, so a phase error that differs between runs (a filter
    the delays describe only in part) moves it by more than the χ² curvature says; the runs' disagreement shows it.
    0 with fewer than three runs."""
    grid = np.array(sorted(per_run))
    runs = [j for j in range(len(per_run[grid[0]])) if per_run[grid[0]][j]]
    if len(runs) < 3 or grid.size < 3:
        return 0.0
    low = lowest_delays_us(keys)
    est = []
    for r in runs:
        chi2 = np.array([profile(_left_out(per_run[e], r), len(keys), clock=False, lowest_us=low)[2] for e in grid])
        est.append(_grid_minimum(grid, chi2))
    return _jackknife_sd(np.array(est))


def jackknife_delay_sd_us(per_run: list[list[_Item]], keys: tuple) -> np.ndarray:
    """The jackknife sd [µs] of each channel's delay profiled at one clock, each run that measures the channel left
    out in turn (``per_run``: each run's profile items; at a fixed clock a channel's delay depends on its own
    pairs only): as for the clock, a phase error that differs between runs shows in their disagreement.  0 for a
    channel of fewer than three runs."""
    has = [{int(c) for it in items for c in it.sig} for items in per_run]
    low = lowest_delays_us(keys)
    left = {r: profile(_left_out(per_run, r), len(keys), clock=False, lowest_us=low)[0]    # every delay, once per run
            for r, h in enumerate(has) if h}
    out = np.zeros(len(keys))
    for c in range(len(keys)):
        runs = [r for r, h in enumerate(has) if c in h]
        if len(runs) >= 3:
            out[c] = _jackknife_sd(np.array([left[r][c] for r in runs]))
    return out


def _left_out(per_run: list[list[_Item]], r: int) -> list[_Item]:
    """The profile items of every run but ``r``."""
    return [it for j, items in enumerate(per_run) if j != r for it in items]


def _jackknife_sd(estimates: np.ndarray) -> float:
    """The jackknife sd of an estimate from its leave-one-out values."""
    n = estimates.size
    return float(np.sqrt((n - 1) / n * np.sum((estimates - estimates.mean()) ** 2)))


def _grid_minimum(grid: np.ndarray, chi2: np.ndarray) -> float:
    """Where ``chi2`` on the sorted ``grid`` is least: the vertex of the parabola through the best point and its two
    neighbours, kept between them (the best point itself at an end of the grid)."""
    k = int(np.argmin(chi2))
    if k == 0 or k == grid.size - 1:
        return float(grid[k])
    a, b, _ = np.polyfit(grid[k - 1:k + 2], chi2[k - 1:k + 2], 2)
    return float(np.clip(-b / (2.0 * a), grid[k - 1], grid[k + 1])) if a > 0 else float(grid[k])
