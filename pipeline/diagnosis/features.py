"""Features compared between measurement and model, and their measurement noise.

Series runs, recorded at any uniform sampling rate (MODELS.md §7: the data-acquisition rate is in
general not a multiple of the forcing frequency), over any length (not whole cycles):
every signal is fitted by linear least squares on the record's own time base,
``x(t) = a0 + s·(t − t_mid) + Σ_k a_k cos kΩt + b_k sin kΩt``, k = 1..K, K = floor(max_harmonic_hz / f),
t the time since the start of excitation (``record_start_s`` + record time) or, for a steady-state
record, the record time (t = 0 is forcing phase 0).  The features are the complex coefficients
c_k = a_k − i b_k (amplitude and phase of every impact harmonic; the offset a0 is left out, so sensor
offsets do not matter); the drift s absorbs progression / creep, and for ``progression_m`` it is the
progression rate (with its regression standard error), plus, for a record from rest, the mean
position (the record's depth in the rig frame).
Noise: the sd σx of the signal's measurement noise is estimated by removing that fit, phase-folding the
rest and taking the robust (median absolute) deviation of each sample from the linear interpolation of its
two phase neighbours (samples of other cycles), scaled by that difference's noise gain.  It does not see the harmonics above K or the sharp impact transients that make
a least-squares residual non-white (neighbours in phase are ≤ T/N apart), and for an integer number of
samples per cycle it equals the old scatter about the synchronous average.  Each coefficient part
then has sd σx·sqrt(2/N) (white-noise model, N samples) — the same noise model as before.
Resolution: K f must stay below the Nyquist frequency fs/2 and the record must hold >= 2 cycles;
otherwise one line names the run and the numbers.

Summary runs: peak_decel_g, impacts_per_cycle, rop_m_s, peak_force_n and spectral_ratio (largest
acceleration harmonic k >= 2, k f <= max_harmonic_hz, other than the reference, divided by the
harmonic at spectral_ratio_ref_hz).  Their sd is a `<name>_sd` column or the assumed default.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError

HARMONIC_SIGNALS = ("accel_m_s2", "force_n", "disp_m")
CONTROL_NAMES = ("frequency_hz", "amplitude_n", "amplitude_m", "static_force_n", "gap_m")
"""Operating controls a run may set (MODELS.md §7 runs.csv; the pendulum's amplitude is amplitude_m, §3).
A run's controls are those of these that are parameters of its model."""
DEFAULT_SUMMARY_SD = {"peak_decel_g": ("rel", 0.05), "impacts_per_cycle": ("abs", 0.5), "rop_m_s": ("rel", 0.10),
                      "peak_force_n": ("rel", 0.05), "spectral_ratio": ("rel", 0.10)}
"""Assumed measurement sd of summary features when the dataset gives no `<name>_sd` column."""
MIN_CYCLES = 2.0
"""A record must hold at least this many forcing cycles (harmonics and drift are separable only then)."""
G = 9.81


def harmonic_count(frequency_hz: float, max_harmonic_hz: float) -> int:
    """Number of harmonics k >= 1 with k f <= max_harmonic_hz (at least 1)."""
    return max(1, int(math.floor(max_harmonic_hz / frequency_hz + 1e-9)))


def check_resolution(run_id: str, t: np.ndarray, f: float, k_max: int) -> None:
    """One clear line if the record cannot resolve ``k_max`` harmonics of ``f`` (Nyquist) or is shorter
    than MIN_CYCLES forcing cycles."""
    dt = float(t[1] - t[0])
    fs = 1.0 / dt
    cycles = (t[-1] - t[0] + dt) * f
    if cycles < MIN_CYCLES:
        raise UserError(f"series/{run_id}.csv: the record holds {cycles:.2f} forcing cycles of {f:g} Hz "
                        f"({t[-1] - t[0] + dt:.4g} s); need at least {MIN_CYCLES:g}")
    if k_max * f >= fs / 2:
        raise UserError(f"series/{run_id}.csv: sampling rate {fs:.6g} Hz cannot resolve harmonic {k_max} of "
                        f"{f:g} Hz ({k_max * f:g} Hz >= Nyquist {fs / 2:.6g} Hz); record at > {2 * k_max * f:g} Hz "
                        f"or lower diagnose.max_harmonic_hz")


@dataclass
class HarmonicFit:
    """Least-squares fit x = offset + slope (t - t_mid) + Σ Re(c_k e^{ikΩt}) (c_k = a_k - i b_k)."""

    c: np.ndarray          # complex, k = 1..K
    offset: float          # value at t_mid
    slope: float           # drift [unit/s]
    slope_se: float        # standard error of the drift (from the residual)
    n: int


def _design(t: np.ndarray, f: float, k_max: int) -> np.ndarray:
    tm = t - 0.5 * (t[0] + t[-1])
    w = 2.0 * math.pi * f * t
    cols = [np.ones_like(t), tm]
    for k in range(1, k_max + 1):
        cols += [np.cos(k * w), np.sin(k * w)]
    return np.column_stack(cols)


def _from_coef(a: np.ndarray, x: np.ndarray, coef: np.ndarray) -> tuple[HarmonicFit, np.ndarray]:
    """HarmonicFit of the least-squares coefficients ``coef`` of ``x`` on design ``a``, and the residual."""
    res = x - a @ coef
    dof = max(x.size - a.shape[1], 1)
    s2 = float(res @ res) / dof
    tm = a[:, 1]
    se = math.sqrt(s2 / max(float(((tm - tm.mean()) ** 2).sum()), 1e-300))
    c = coef[2::2] - 1j * coef[3::2]
    return HarmonicFit(c=c, offset=float(coef[0]), slope=float(coef[1]), slope_se=se, n=int(x.size)), res


def harmonic_fit(t: np.ndarray, x: np.ndarray, f: float, k_max: int) -> HarmonicFit:
    """Fit offset, drift and harmonics 1..k_max of ``f`` to samples (t [s], x) by linear least squares."""
    a = _design(t, f, k_max)
    return _from_coef(a, x, np.linalg.lstsq(a, x, rcond=None)[0])[0]


def _folded_noise(t: np.ndarray, y: np.ndarray, f: float) -> float:
    """Robust noise sd of a residual ``y``: phase-fold and compare each sample with the interpolation
    between its phase neighbours (1.4826 · median |e| / sqrt(1 + w1² + w2²))."""
    ph = np.mod(t * f, 1.0)
    order = np.argsort(ph, kind="stable")
    ph, y = ph[order], y[order]
    if y.size < 3:
        return 0.0
    h1, h2 = ph[1:-1] - ph[:-2], ph[2:] - ph[1:-1]
    w1 = np.where(h1 + h2 > 0, h2 / np.maximum(h1 + h2, 1e-300), 0.5)   # linear interpolation weights
    e = y[1:-1] - (w1 * y[:-2] + (1.0 - w1) * y[2:])
    return float(1.4826 * np.median(np.abs(e) / np.sqrt(1.0 + w1 ** 2 + (1.0 - w1) ** 2)))


def noise_sd(t: np.ndarray, x: np.ndarray, f: float, k_max: int = 0) -> float:
    """Measurement-noise sd [unit of x]: remove the least-squares fit (offset, drift, harmonics 1..k_max),
    phase-fold the rest and take the robust deviation from the interpolation between phase neighbours
    (see the module docstring)."""
    a = _design(t, f, k_max)
    return _folded_noise(t, x - a @ np.linalg.lstsq(a, x, rcond=None)[0], f)


@dataclass
class Target:
    """Measured features of one run: names, values, sd and group (signal / summary label), and what
    the model needs to simulate the run (controls, known parameters, time base)."""

    run_id: str
    system: str
    controls: dict
    kind: str                                      # "series" or "summary"
    known: dict = field(default_factory=dict)      # known rig parameters (preset + explicit columns)
    names: list[str] = field(default_factory=list)
    y: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    group: list[str] = field(default_factory=list)
    k_max: int = 0
    signals: tuple[str, ...] = ()
    fs_hz: float = 0.0                             # sampling rate of the measured series [Hz]
    duration_s: float = 0.0                        # length of the record [s]
    record_start_s: float | None = None            # record t = 0 after this long from rest (None: steady state)
    lower_bound: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    ratio_ref_hz: float = 0.0
    noise: dict = field(default_factory=dict)      # signal -> estimated sd (series)
    segments: dict = field(default_factory=dict)   # signal -> (n_seg, K) complex harmonics per time segment
    t_rec: np.ndarray | None = None                # record time base [s] (series)
    pinv: np.ndarray | None = None                 # least-squares operator of the record's design matrix

    @property
    def n(self) -> int:
        return self.y.size

    @property
    def frequency_hz(self) -> float:
        return float(self.controls["frequency_hz"])

    @property
    def cycles(self) -> float:
        """Forcing cycles in the record."""
        return self.duration_s * self.frequency_hz


def _complex_features(sig: str, c: np.ndarray) -> tuple[list[str], np.ndarray]:
    names = [f"{sig}:h{k}:{part}" for k in range(1, c.size + 1) for part in ("re", "im")]
    return names, np.column_stack([c.real, c.imag]).ravel()


def record_time(tg: Target, t_record: np.ndarray) -> np.ndarray:
    """Time since the start of excitation (record from rest) or record time (steady state) [s]."""
    return t_record + (tg.record_start_s or 0.0)


def series_target(tg: Target, df: pd.DataFrame, max_harmonic_hz: float, n_segments: int = 4) -> Target:
    """Fill ``tg`` (run_id, system, controls, known, record_start_s set) from a measured series."""
    f = tg.frequency_hz
    t_rec = df["t_s"].to_numpy()
    k = harmonic_count(f, max_harmonic_hz)
    check_resolution(tg.run_id, t_rec, f, k)
    dt = float(t_rec[1] - t_rec[0])
    tg.kind, tg.k_max, tg.fs_hz, tg.duration_s = "series", k, 1.0 / dt, float(t_rec[-1] - t_rec[0] + dt)
    t = record_time(tg, t_rec)
    tg.t_rec = t_rec
    a = _design(t, f, k)
    tg.pinv = np.linalg.pinv(a)
    # one operator for every signal of the record (the model's records use the same one, model_on_record)
    fits = {sig: _from_coef(a, x, tg.pinv @ x) for sig in (*HARMONIC_SIGNALS, "progression_m") if sig in df.columns
            for x in [df[sig].to_numpy()]}
    present = [sig for sig in HARMONIC_SIGNALS if sig in df.columns]
    seg_c: dict[str, list] = {sig: [] for sig in present}
    if present and tg.cycles >= 2 * n_segments * MIN_CYCLES / 2:
        x_all = np.column_stack([df[sig].to_numpy() for sig in present])
        edges = np.linspace(0, t.size, n_segments + 1).astype(int)
        for lo, hi in zip(edges[:-1], edges[1:]):    # the segment's own design (drift centring does not change c)
            coef = np.linalg.lstsq(a[lo:hi], x_all[lo:hi], rcond=None)[0]
            for j, sig in enumerate(present):
                seg_c[sig].append(coef[2::2, j] - 1j * coef[3::2, j])
    names, y, sd, group, sigs = [], [], [], [], []
    for sig in HARMONIC_SIGNALS:
        if sig not in df.columns:
            continue
        x = df[sig].to_numpy()
        hf, res = fits[sig]
        s = _folded_noise(t, res, f)
        tg.noise[sig] = s
        csd = max(s * math.sqrt(2.0 / x.size), 1e-12 * (np.abs(hf.c).max() + 1e-30))
        n_, v = _complex_features(sig, hf.c)
        names += n_
        y.append(v)
        sd.append(np.full(v.size, csd))
        group += [sig] * v.size
        sigs.append(sig)
        if seg_c[sig]:
            tg.segments[sig] = np.array(seg_c[sig])
    if "progression_m" in df.columns:
        x = df["progression_m"].to_numpy()
        hf, res = fits["progression_m"]
        s = _folded_noise(t, res, f)
        tg.noise["progression_m"] = s
        names.append("rop_m_s")
        y.append(np.array([hf.slope]))
        sd.append(np.array([max(hf.slope_se, s * math.sqrt(12.0 / x.size) / tg.duration_s, 1e-12)]))
        group.append("rop_m_s")
        if tg.record_start_s is not None:    # from rest, the rig-frame depth of the record is a feature
            names.append("progression_m:mean")
            y.append(np.array([hf.offset]))
            sd.append(np.array([max(s / math.sqrt(x.size), 1e-12)]))
            group.append("progression_m")
        sigs.append("progression_m")
    tg.names, tg.y, tg.sd, tg.group, tg.signals = names, np.concatenate(y), np.concatenate(sd), group, tuple(sigs)
    tg.lower_bound = np.zeros(tg.y.size, dtype=bool)
    return tg


def summary_target(tg: Target, srow: pd.Series, max_harmonic_hz: float, sd_defaults: dict | None = None) -> Target:
    """Fill ``tg`` from a summary.csv row."""
    sd_defaults = {**DEFAULT_SUMMARY_SD, **(sd_defaults or {})}
    tg.kind, tg.k_max = "summary", harmonic_count(tg.frequency_hz, max_harmonic_hz)
    names, y, sd, lb = [], [], [], []
    for feat in ("peak_decel_g", "impacts_per_cycle", "rop_m_s", "peak_force_n", "spectral_ratio"):
        if feat not in srow.index or pd.isna(srow[feat]):
            continue
        v = float(srow[feat])
        if feat == "spectral_ratio":
            ref = srow.get("spectral_ratio_ref_hz")
            if ref is None or pd.isna(ref):
                raise UserError(f"summary.csv, run '{tg.run_id}': spectral_ratio needs spectral_ratio_ref_hz")
            tg.ratio_ref_hz = float(ref)
        if f"{feat}_sd" in srow.index and not pd.isna(srow[f"{feat}_sd"]):
            s = float(srow[f"{feat}_sd"])
        else:
            how, val = sd_defaults[feat]
            s = val * max(abs(v), 1e-12) if how == "rel" else val
        names.append(feat)
        y.append(v)
        sd.append(s)
        lb.append(feat == "impacts_per_cycle" and bool(srow.get("impacts_per_cycle_lower_bound", 0) == 1))
    tg.names, tg.y, tg.sd, tg.group = names, np.array(y), np.array(sd), list(names)
    tg.lower_bound = np.array(lb, dtype=bool)
    return tg


def model_record(tg: Target, h: pd.DataFrame) -> tuple[np.ndarray, pd.DataFrame]:
    """The part of a simulated history that corresponds to the record, and its time base
    (see ``record_time``): a steady-state window as simulated (starts at forcing phase 0); a run
    from rest cut to [record_start_s, record_start_s + duration_s]."""
    t = h["t_s"].to_numpy()
    if tg.record_start_s is None:
        return t - t[0], h
    m = (t >= tg.record_start_s - 1e-12) & (t < tg.record_start_s + tg.duration_s - 1e-12)
    return t[m], h.loc[m]


def _history_summary(name: str, t: np.ndarray, h: pd.DataFrame, f: float) -> float:
    """Summary label over a cut history (runs from rest): MODELS.md §5 definitions."""
    if name == "rop_m_s":
        x = h["progression_m"].to_numpy()
        return float(np.polyfit(t - t.mean(), x, 1)[0])
    if name == "peak_force_n":
        return float(h["force_n"].max())
    if name == "peak_decel_g":
        return float(max(-h["accel_m_s2"].min(), 0.0) / G)
    if name == "impacts_per_cycle":
        on = h["force_n"].to_numpy() > 0
        return float(np.count_nonzero(on[1:] & ~on[:-1]) / max((t[-1] - t[0]) * f, 1e-9))
    raise KeyError(name)


def model_on_record(tg: Target, h: pd.DataFrame, sig: str) -> np.ndarray:
    """A simulated signal on the measured record's own time base (linear interpolation of the densely
    sampled model: the model's harmonics then see the same sampling as the measurement's).  Steady state:
    the window starts at forcing phase 0 and repeats if the record is longer; from rest: absolute time."""
    th = h["t_s"].to_numpy()
    x = h[sig].to_numpy()
    if tg.record_start_s is None:
        th = th - th[0]
        tq = tg.t_rec
        span = th[-1] + (th[1] - th[0])
        if tq[-1] >= span:
            tq = np.mod(tq, span)
        return np.interp(tq, th, x)
    return np.interp(record_time(tg, tg.t_rec), th, x)


def simulated_features(tg: Target, res) -> np.ndarray | None:
    """The model's values of ``tg``'s features from a SimulationResult with history (None if the
    run failed or ran away)."""
    h = res.history
    if h is None:
        return None
    f = tg.frequency_hz
    if tg.kind == "series":
        out = []
        for sig in tg.signals:
            coef = tg.pinv @ model_on_record(tg, h, sig)
            if sig == "progression_m":
                out.append(np.array([coef[1]] + ([coef[0]] if tg.record_start_s is not None else [])))
            else:
                out.append(_complex_features(sig, coef[2::2] - 1j * coef[3::2])[1])
        return np.concatenate(out)
    t, hr = model_record(tg, h)
    if t.size < 4:
        return None
    lab = res.labels
    vals = []
    for name in tg.names:
        if name == "spectral_ratio":
            vals.append(spectral_ratio(t, hr["accel_m_s2"].to_numpy(), f, tg.k_max, tg.ratio_ref_hz))
        elif tg.record_start_s is not None:
            vals.append(_history_summary(name, t, hr, f))
        else:
            v = lab.get(name)
            vals.append(0.0 if v is None else float(v))
    return np.array(vals)


def spectral_ratio(t: np.ndarray, accel: np.ndarray, f: float, k_max: int, ref_hz: float) -> float:
    """Largest acceleration harmonic (k >= 2, k f <= k_max f, other than the reference) over the
    harmonic at ref_hz (seed §5's 'ratio to the 80 Hz peak' / 'highest harmonic ... of the fundamental')."""
    amp = np.abs(harmonic_fit(t, accel, f, k_max).c)
    kr = int(round(ref_hz / f))
    others = [amp[k - 1] for k in range(2, k_max + 1) if k != kr]
    return float(max(others) / max(amp[kr - 1], 1e-12))


def peak_velocity(res) -> float | None:
    """Largest velocity of the impacting mass in the window [m/s] (a proxy of impact velocity)."""
    if res.history is None:
        return None
    return float(res.history["vel_m_s"].max())
