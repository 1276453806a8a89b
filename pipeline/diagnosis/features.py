"""Features compared between measurement and model, and their measurement noise.

Series runs: for every measured signal (accel_m_s2, force_n, disp_m) the complex Fourier
coefficients c_k = a_k - i b_k of harmonics k = 1..K of the forcing frequency (x = Σ a_k cos kΩt +
b_k sin kΩt, t = 0 at forcing phase 0), K = floor(max_harmonic_hz / f).  They carry amplitude and
phase of every impact harmonic, are insensitive to sensor offsets (k = 0 is left out) and average
the noise over all recorded cycles.  The noise is estimated from the data: the scatter of the
signal about its synchronous (cycle) average gives the noise sd σx, so each coefficient's real and
imaginary part has sd σx·sqrt(2/N) (white noise, N samples).  progression_m gives the progression
rate (slope of the per-cycle means, with its regression standard error).

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
CONTROLS = ("frequency_hz", "amplitude_n", "static_force_n", "gap_m")
DEFAULT_SUMMARY_SD = {"peak_decel_g": ("rel", 0.05), "impacts_per_cycle": ("abs", 0.5), "rop_m_s": ("rel", 0.10),
                      "peak_force_n": ("rel", 0.05), "spectral_ratio": ("rel", 0.10)}
"""Assumed measurement sd of summary features when the dataset gives no `<name>_sd` column."""


def harmonic_count(frequency_hz: float, max_harmonic_hz: float) -> int:
    """Number of harmonics k >= 1 with k f <= max_harmonic_hz (at least 1)."""
    return max(1, int(math.floor(max_harmonic_hz / frequency_hz + 1e-9)))


def cycle_matrix(t: np.ndarray, x: np.ndarray, f: float) -> np.ndarray:
    """Reshape a uniformly sampled record into (cycles, samples per cycle), whole cycles only.
    Needs an integer number of samples per cycle (to 1e-6); otherwise UserError."""
    dt = float(t[1] - t[0])
    spc_f = 1.0 / (f * dt)
    spc = int(round(spc_f))
    if abs(spc_f - spc) > 1e-6 * spc_f or spc < 4:
        raise UserError(f"series sample rate {1 / dt:.6g} Hz is not an integer multiple of the forcing frequency "
                        f"{f:g} Hz (needed for the synchronous average); resample the series")
    m = x.size // spc
    if m < 2:
        raise UserError(f"series holds {x.size / spc:.2f} forcing cycles; need at least 2")
    return x[: m * spc].reshape(m, spc)


def harmonics(cyc: np.ndarray, k_max: int) -> np.ndarray:
    """Complex coefficients c_k = a_k - i b_k, k = 1..k_max, of the synchronous average of ``cyc``."""
    mean = cyc.mean(axis=0)
    spc = mean.size
    if k_max >= spc // 2:
        raise UserError(f"{spc} samples per cycle cannot resolve {k_max} harmonics; lower max_harmonic_hz")
    return np.fft.rfft(mean)[1: k_max + 1] * (2.0 / spc)


def noise_sd(cyc: np.ndarray) -> float:
    """Sample sd of the scatter about the synchronous average (dof: N - samples per cycle)."""
    m, spc = cyc.shape
    res = cyc - cyc.mean(axis=0)
    return float(math.sqrt((res ** 2).sum() / max(m * spc - spc, 1)))


def progression_rate(cyc: np.ndarray, f: float) -> tuple[float, float]:
    """Progression rate [m/s] = slope of per-cycle means, and its regression standard error."""
    means = cyc.mean(axis=1)
    tc = np.arange(means.size) / f
    if means.size < 3:
        return float((means[-1] - means[0]) * f), float("inf")
    a = np.vstack([tc, np.ones_like(tc)]).T
    coef, *_ = np.linalg.lstsq(a, means, rcond=None)
    res = means - a @ coef
    s2 = float((res ** 2).sum() / (means.size - 2))
    se = math.sqrt(s2 / float(((tc - tc.mean()) ** 2).sum()))
    return float(coef[0]), se


@dataclass
class Target:
    """Measured features of one run: names, values, sd and group (signal / summary label)."""

    run_id: str
    system: str
    controls: dict
    kind: str                                      # "series" or "summary"
    names: list[str] = field(default_factory=list)
    y: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    group: list[str] = field(default_factory=list)
    k_max: int = 0
    signals: tuple[str, ...] = ()
    spc: int = 0                                   # samples per cycle of the measured series
    cycles: int = 0                                # whole forcing cycles in the measured series
    lower_bound: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    ratio_ref_hz: float = 0.0
    noise: dict = field(default_factory=dict)      # signal -> estimated sd (series)
    segments: dict = field(default_factory=dict)   # signal -> (n_seg, K) complex harmonics per time segment

    @property
    def n(self) -> int:
        return self.y.size


def _complex_features(sig: str, c: np.ndarray) -> tuple[list[str], np.ndarray]:
    names = [f"{sig}:h{k}:{part}" for k in range(1, c.size + 1) for part in ("re", "im")]
    return names, np.column_stack([c.real, c.imag]).ravel()


def _detrend(sig: str, t: np.ndarray, x: np.ndarray, f: float) -> np.ndarray:
    """disp_m of a progressing sample drifts with the crater floor: remove the progression slope
    (from the per-cycle means) so the synchronous average and the noise estimate see a periodic signal."""
    if sig != "disp_m":
        return x
    rate, _ = progression_rate(cycle_matrix(t, x, f), f)
    return x - rate * t


def series_target(row: dict, df: pd.DataFrame, max_harmonic_hz: float, n_segments: int = 4) -> Target:
    """Target from a measured time series (see the module docstring)."""
    f = row["frequency_hz"]
    tg = Target(run_id=row["run_id"], system=row["system"], controls={c: float(row[c]) for c in CONTROLS},
                kind="series")
    t = df["t_s"].to_numpy()
    k = harmonic_count(f, max_harmonic_hz)
    tg.k_max = k
    names, y, sd, group = [], [], [], []
    sigs = []
    for sig in HARMONIC_SIGNALS:
        if sig not in df.columns:
            continue
        try:
            cyc = cycle_matrix(t, _detrend(sig, t, df[sig].to_numpy(), f), f)
            c = harmonics(cyc, k)
        except UserError as e:
            raise UserError(f"series/{row['run_id']}.csv, column '{sig}': {e}") from None
        tg.spc, tg.cycles = cyc.shape[1], cyc.shape[0]
        s = noise_sd(cyc)
        tg.noise[sig] = s
        csd = max(s * math.sqrt(2.0 / cyc.size), 1e-12 * (np.abs(c).max() + 1e-30))
        n_, v = _complex_features(sig, c)
        names += n_
        y.append(v)
        sd.append(np.full(v.size, csd))
        group += [sig] * v.size
        sigs.append(sig)
        m = cyc.shape[0]
        if m >= 2 * n_segments:
            edges = np.linspace(0, m, n_segments + 1).astype(int)
            tg.segments[sig] = np.array([harmonics(cyc[a:b], k) for a, b in zip(edges[:-1], edges[1:])])
    if "progression_m" in df.columns:
        cyc = cycle_matrix(t, df["progression_m"].to_numpy(), f)
        tg.spc = cyc.shape[1]
        rate, se = progression_rate(cyc, f)
        names.append("rop_m_s")
        y.append(np.array([rate]))
        sd.append(np.array([max(se, 1e-9)]))
        group.append("rop_m_s")
        sigs.append("progression_m")
    tg.names, tg.y, tg.sd, tg.group, tg.signals = names, np.concatenate(y), np.concatenate(sd), group, tuple(sigs)
    tg.lower_bound = np.zeros(tg.y.size, dtype=bool)
    return tg


def summary_target(row: dict, srow: pd.Series, max_harmonic_hz: float, sd_defaults: dict | None = None) -> Target:
    """Target from a summary.csv row."""
    sd_defaults = {**DEFAULT_SUMMARY_SD, **(sd_defaults or {})}
    f = row["frequency_hz"]
    tg = Target(run_id=row["run_id"], system=row["system"], controls={c: float(row[c]) for c in CONTROLS},
                kind="summary", k_max=harmonic_count(f, max_harmonic_hz))
    names, y, sd, lb = [], [], [], []
    for feat in ("peak_decel_g", "impacts_per_cycle", "rop_m_s", "peak_force_n", "spectral_ratio"):
        if feat not in srow.index or pd.isna(srow[feat]):
            continue
        v = float(srow[feat])
        if feat == "spectral_ratio":
            ref = srow.get("spectral_ratio_ref_hz")
            if ref is None or pd.isna(ref):
                raise UserError(f"summary.csv, run '{row['run_id']}': spectral_ratio needs spectral_ratio_ref_hz")
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


def simulated_features(tg: Target, res) -> np.ndarray | None:
    """The model's values of ``tg``'s features from a SimulationResult with history (None if the
    run failed or ran away)."""
    h = res.history
    if h is None:
        return None
    f = tg.controls["frequency_hz"]
    t = h["t_s"].to_numpy() - float(h["t_s"].iloc[0])     # window starts at forcing phase 0
    if tg.kind == "series":
        out = []
        for sig in tg.signals:
            if sig == "progression_m":
                cyc = cycle_matrix(t, h["progression_m"].to_numpy(), f)
                out.append(np.array([progression_rate(cyc, f)[0]]))
            else:
                cyc = cycle_matrix(t, _detrend(sig, t, h[sig].to_numpy(), f), f)
                out.append(_complex_features(sig, harmonics(cyc, tg.k_max))[1])
        return np.concatenate(out)
    lab = res.labels
    vals = []
    for name in tg.names:
        if name == "spectral_ratio":
            vals.append(spectral_ratio(t, h["accel_m_s2"].to_numpy(), f, tg.k_max, tg.ratio_ref_hz))
        else:
            v = lab.get(name)
            vals.append(0.0 if v is None else float(v))
    return np.array(vals)


def spectral_ratio(t: np.ndarray, accel: np.ndarray, f: float, k_max: int, ref_hz: float) -> float:
    """Largest acceleration harmonic (k >= 2, k f <= k_max f, other than the reference) over the
    harmonic at ref_hz (seed §5's 'ratio to the 80 Hz peak' / 'highest harmonic ... of the fundamental')."""
    amp = np.abs(harmonics(cycle_matrix(t, accel, f), k_max))
    kr = int(round(ref_hz / f))
    others = [amp[k - 1] for k in range(2, k_max + 1) if k != kr]
    return float(max(others) / max(amp[kr - 1], 1e-12))


def peak_velocity(res) -> float | None:
    """Largest velocity of the impacting mass in the window [m/s] (a proxy of impact velocity)."""
    if res.history is None:
        return None
    return float(res.history["vel_m_s"].max())
