"""Features compared between measurement and model, and their measurement noise.

Series runs, recorded at any uniform sampling rate (MODELS.md §7: the data-acquisition rate is in general not a
multiple of the forcing frequency), over any length (not whole cycles): every acceleration, force and displacement
is fitted by linear least squares on the record's own time base, x(t) = cubic drift + Σ a_k cos kΩt + b_k sin kΩt,
k = 1..K, K = floor(max_harmonic_hz / f), t the time since the start of excitation (``record_start_s`` + record
time) or, for a steady-state record, the record time (t = 0 is forcing phase 0).  The features are the complex
coefficients c_k = a_k − i b_k (amplitude and phase of every impact harmonic; offsets and slow drifts stay in the
polynomial); the progression is fitted with a linear drift, its rate (and, for a record from rest, its mean: the
record's depth in the rig frame) being the features.  The model is sampled at the same instants
(``sampling_plan``) and reduced by the same operators, and so is each half of a record (``halves``: the
systematic error of the verdict).

Noise (``record_noise``): per signal, record and harmonic, from the periodogram of what a fit with slowly varying
amplitudes leaves (``band_noise``); each coefficient part has sd sqrt(2 S_k / N), and a model floor is added in
quadrature (``series_target``).  Resolution: K f must stay below the Nyquist frequency fs/2 and the record must
hold >= 2 cycles; otherwise one line names the run and the numbers.

Summary runs: peak_decel_g, impacts_per_cycle, rop_m_s, peak_force_n and spectral_ratio (largest acceleration
harmonic k >= 2, k f <= max_harmonic_hz, other than the reference, divided by the harmonic at
spectral_ratio_ref_hz).  Their sd is a `<name>_sd` column or the assumed default, with a floor.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.datasets.daq import DeclaredChain
from pipeline.diagnosis import mains
from pipeline.diagnosis.instrument import Nuisance, apply_gain, instrument_gain
from sim.controls import CONTROLS as CONTROL_NAMES
from sim.layout import G_ACCEL as G   # [m/s²] per g: the project's one value
from vibrobase.statuses import BOUNDED_STATUSES

HARMONIC_SIGNALS = ("accel_m_s2", "force_n", "disp_m")
DEFAULT_SUMMARY_SD = {"peak_decel_g": ("rel", 0.05), "impacts_per_cycle": ("abs", 0.5), "rop_m_s": ("rel", 0.10),
                      "peak_force_n": ("rel", 0.05), "spectral_ratio": ("rel", 0.10)}
"""Assumed measurement sd of summary features when the dataset gives no `<name>_sd` column."""
MIN_CYCLES = 2.0
"""A record must hold at least this many forcing cycles (harmonics and drift are separable only then)."""


class UnusableRecord(UserError):
    """A series record none of whose channels can be used (saturated): the run is skipped and named."""


def harmonic_count(frequency_hz: float, max_harmonic_hz: float) -> int:
    """Number of harmonics k >= 1 with k f <= max_harmonic_hz (at least 1)."""
    return max(1, int(math.floor(max_harmonic_hz / frequency_hz + 1e-9)))


MAX_DESIGN_CELLS = 2**25
"""Most cells (samples x columns) of one record's least-squares design: 268 MB, a few times that while its
pseudo-inverse is formed, so a diagnosis of long records stays within a few GB."""


def check_resolution(run_id: str, t: np.ndarray, f: float, k_max: int) -> None:
    """One clear line if the record cannot resolve ``k_max`` harmonics of ``f`` (Nyquist) or is shorter
    than MIN_CYCLES forcing cycles."""
    dt = float(t[1] - t[0])
    fs = 1.0 / dt
    cycles = (t[-1] - t[0] + dt) * f
    if cycles < MIN_CYCLES:
        raise UserError(f"series/{run_id}.csv: the record holds {cycles:.2f} forcing cycles of {f:g} Hz "
                        f"({t[-1] - t[0] + dt:.4g} s); need at least {MIN_CYCLES:g}")
    cells = t.size * (2 * k_max + DRIFT_DEGREE + 1)
    if cells > MAX_DESIGN_CELLS:
        raise UserError(f"series/{run_id}.csv: {t.size} samples x {2 * k_max + DRIFT_DEGREE + 1} harmonic columns "
                        f"make a least-squares design of {cells:.3g} cells, more than the {MAX_DESIGN_CELLS} a "
                        f"diagnosis holds (MAX_DESIGN_CELLS, 8 bytes each); resample the record, shorten it, or lower "
                        f"diagnose.max_harmonic_hz")
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


DRIFT_DEGREE = 3
"""Degree of the polynomial drift fitted beside the harmonics of accelerations, forces and displacements: a sensor's
slow drift (and a record's slow transient) then stays out of the harmonic features, and the noise estimate removes
the same drift (``_slow_design``).  The progression keeps a linear drift: its rate is a feature."""


def _design(t: np.ndarray, f: float, k_max: int, drift: int = 1) -> np.ndarray:
    """Columns 1, t − t_mid [s], then τ^j for j = 2..drift (τ = (t − t_mid) / half the record), then cos kΩt,
    sin kΩt for k = 1..k_max."""
    tm = t - 0.5 * (t[0] + t[-1])
    tau = tm / max(0.5 * (t[-1] - t[0]), 1e-300)
    w = 2.0 * math.pi * f * t
    cols = [np.ones_like(t), tm] + [tau ** j for j in range(2, drift + 1)]
    for k in range(1, k_max + 1):
        cols += [np.cos(k * w), np.sin(k * w)]
    return np.column_stack(cols)


def _harmonics(coef: np.ndarray, drift: int) -> np.ndarray:
    """Complex harmonics c_k = a_k − i b_k of coefficients on ``_design(..., drift)``."""
    return coef[drift + 1::2] - 1j * coef[drift + 2::2]


def _from_coef(a: np.ndarray, x: np.ndarray, coef: np.ndarray, drift: int = 1) -> tuple[HarmonicFit, np.ndarray]:
    """HarmonicFit of the least-squares coefficients ``coef`` of ``x`` on design ``a``, and the residual."""
    res = x - a @ coef
    dof = max(x.size - a.shape[1], 1)
    s2 = float(res @ res) / dof
    tm = a[:, 1]
    se = math.sqrt(s2 / max(float(((tm - tm.mean()) ** 2).sum()), 1e-300))
    return HarmonicFit(c=_harmonics(coef, drift), offset=float(coef[0]), slope=float(coef[1]), slope_se=se,
                       n=int(x.size)), res


@functools.lru_cache(maxsize=16)
def _cached_design(t_bytes: bytes, f: float, k_max: int) -> tuple[np.ndarray, np.ndarray]:
    """``_design(t, f, k_max)`` of the time base ``t_bytes`` (float64) and its pseudo-inverse, read-only: a fit
    builds the same model time base thousands of times, and a product with the pseudo-inverse costs a tenth of a
    ``lstsq`` (the coefficients agree to round-off, 1e-15 relative)."""
    a = _design(np.frombuffer(t_bytes, dtype=np.float64), f, k_max)
    pinv = np.linalg.pinv(a)
    a.flags.writeable = pinv.flags.writeable = False
    return a, pinv


def harmonic_fit(t: np.ndarray, x: np.ndarray, f: float, k_max: int) -> HarmonicFit:
    """Fit offset, drift and harmonics 1..k_max of ``f`` to samples (t [s], x) by linear least squares."""
    a, pinv = _cached_design(np.ascontiguousarray(t, dtype=np.float64).tobytes(), float(f), int(k_max))
    x = np.asarray(x, dtype=np.float64)
    return _from_coef(a, x, pinv @ x)[0]


NOISE_MIN_BINS = 32
"""Fewest periodogram bins a harmonic's noise estimate averages (neighbouring harmonics' bands are pooled until
there are as many)."""
NOISE_TRIM = 0.8
"""The noise level is the mean of the lowest NOISE_TRIM of the bins (robust to the lines a residual keeps), divided
by that mean's fraction of the full mean for exponentially distributed bins (white Gaussian noise)."""
_TRIM_BIAS = (1.0 - (1.0 - math.log(1.0 - NOISE_TRIM)) * (1.0 - NOISE_TRIM)) / NOISE_TRIM


def _trimmed_level(vals: np.ndarray) -> float:
    """White-equivalent level of periodogram bins: the trimmed mean (NOISE_TRIM) over its exponential-law bias."""
    if vals.size == 0:
        return 0.0
    v = np.sort(vals)[:max(int(math.ceil(NOISE_TRIM * vals.size)), 1)]
    return float(v.mean()) / _TRIM_BIAS


SLOW_DEGREE = 2
"""Degree of the polynomials the harmonic amplitudes of a record from rest may vary by over the record in the noise
estimate's fit (a transient is not noise); a steady-state record's amplitudes are constant (degree 0)."""
NOISE_EXTRA_HARMONICS = 4
"""Harmonics above the features' k_max the noise estimate's fit removes as well (an impact's lines go on far above
the features; the nearest would leak into the top bands)."""


def _exclude_bins(degree: int) -> float:
    """Bins either side of every harmonic left out of the noise bands: a fit whose amplitudes vary as polynomials of
    ``degree`` takes the noise out of about degree + 1 bins around each line, a Hann window spreads a bin over 2."""
    return degree + 1.5


def _slow_design(t: np.ndarray, f: float, k_max: int, degree: int = SLOW_DEGREE) -> np.ndarray:
    """Design of the noise estimate: a cubic drift and every harmonic with amplitudes that vary over the record
    as polynomials of ``degree`` (a transient or a slow change of the response is not noise)."""
    tau = (t - 0.5 * (t[0] + t[-1])) / max(0.5 * (t[-1] - t[0]), 1e-300)
    w = 2.0 * math.pi * f * t
    cols = [tau ** j for j in range(4)]
    for k in range(1, k_max + 1):
        c, s = np.cos(k * w), np.sin(k * w)
        for j in range(degree + 1):
            cols += [c * tau ** j, s * tau ** j]
    return np.column_stack(cols)


def _periodogram(res: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(bin frequencies [Hz], Hann-windowed periodogram normalised so that white noise of sd σ gives σ², bin width)."""
    n = res.size
    w = np.hanning(n)
    p = np.abs(np.fft.rfft(res * w)) ** 2 / max(float(np.sum(w * w)), 1e-300)
    df = fs / n
    return np.arange(p.size) * df, p, df


def _band_bins(fj: np.ndarray, f: float, df: float, k_max: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """(harmonic number of every bin, which bins may hold noise): within 0.5 f of k f, k <= k_max, and not within
    ``_exclude_bins(degree)`` of a harmonic (or of DC)."""
    k_of = np.round(fj / f)
    ok = (np.abs(fj - k_of * f) >= _exclude_bins(degree) * df) & (k_of <= max(k_max, 1))
    return k_of, ok


def _pooled(vals: np.ndarray, k_of: np.ndarray, ok: np.ndarray, k: int, k_max: int) -> float:
    """``_trimmed_level`` of the band of harmonic k, pooled with its neighbours up to NOISE_MIN_BINS bins."""
    for spread in range(0, k_max + 2):
        m = ok & (np.abs(k_of - k) <= spread)
        if np.count_nonzero(m) >= NOISE_MIN_BINS or spread > k_max:
            break
    return _trimmed_level(vals[m] if np.any(m) else vals[1:])


def band_noise(res: np.ndarray, fs: float, f: float, k_max: int, degree: int = 0) -> np.ndarray:
    """Noise variance density [unit²] around each harmonic k = 0..k_max of ``f`` (k = 0: the slow band below
    0.5 f, DC left out), white-equivalent (a white noise of sd σ gives σ² at every k): a trimmed mean
    (``_trimmed_level``) of the Hann-windowed periodogram of the residual ``res`` over the bins within 0.5 f of k f,
    leaving out ``_exclude_bins(degree)`` around every harmonic, and pooling neighbouring bands of harmonics
    1..k_max up to NOISE_MIN_BINS bins.  The periodogram is first whitened by the power law f^b that the bands
    follow (b ≈ 0 white or gain noise, −1 for 1/f noise), so that pooling and trimming do not bias a sloping
    spectrum.  Trimming over frequency is robust to the lines a least-squares residual keeps (harmonics above k_max
    folded by the sampling, subharmonics), a band per harmonic follows coloured noise, and noise proportional to
    the signal, which spreads over every band, is seen in full (a median over time would see only the quiet part
    of each cycle)."""
    fj, p, df = _periodogram(res, fs)
    k_of, ok = _band_bins(fj, f, df, k_max, degree)
    out = np.empty(k_max + 1)
    out[0] = _pooled(p, k_of, ok, 0, 0)
    if k_max == 0:
        return out
    ks = np.arange(1, k_max + 1)
    raw = np.array([_pooled(p, k_of, ok, k, k_max) for k in ks])
    b = 0.0
    if k_max >= 3 and np.all(raw > 0):
        b = float(np.polyfit(np.log(ks), np.log(raw), 1)[0])
    white = p / np.maximum(fj / f, 0.5) ** b
    out[1:] = [_pooled(white, k_of, ok, k, k_max) * k ** b for k in ks]
    return out


def _broadband(res: np.ndarray, fs: float, f: float, k_max: int, degree: int = 0) -> float:
    """sd of a white noise with the residual's periodogram level over the bands of harmonics 1..k_max."""
    fj, p, df = _periodogram(res, fs)
    k_of, ok = _band_bins(fj, f, df, k_max, degree)
    m = ok & (k_of >= 1)
    return math.sqrt(_trimmed_level(p[m] if np.any(m) else p[1:]))


def record_noise(t: np.ndarray, x: np.ndarray, f: float, k_max: int, degree: int = 0,
                 keep: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """(noise variance density around k f, k = 0..k_max (``band_noise``), broadband sd [unit of x]) of a record:
    the residual of a harmonic fit whose amplitudes may vary as polynomials of ``degree`` over the record
    (``_slow_design``; SLOW_DEGREE for a record from rest, 0 in steady state), on the record's own time base.
    ``keep``: the usable samples (saturated ones left out of the fit, their residual 0 and the periodogram scaled
    up by the fraction left out)."""
    fs = 1.0 / float(t[1] - t[0])
    # a few harmonics above k_max too: their lines would leak into the top bands
    k_fit = max(min(k_max + NOISE_EXTRA_HARMONICS, int(math.floor(fs / (2.0 * f) - 0.5))), k_max)
    a = _slow_design(t, f, k_fit, degree)
    if keep is None:
        res = x - a @ np.linalg.lstsq(a, x, rcond=None)[0]
    else:
        res = np.where(keep, x - a @ np.linalg.lstsq(a[keep], x[keep], rcond=None)[0], 0.0)
        res = res * math.sqrt(keep.size / max(np.count_nonzero(keep), 1))
    return band_noise(res, fs, f, k_max, degree), _broadband(res, fs, f, k_max, degree)


def noise_sd(t: np.ndarray, x: np.ndarray, f: float, k_max: int = 0) -> float:
    """Broadband measurement-noise sd [unit of x] of a record (``record_noise``)."""
    return record_noise(t, x, f, max(k_max, 1))[1]


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
    pinv: dict | None = None                       # least-squares operators of the record's time base (_operators)
    halves: list = field(default_factory=list)     # [(slice, operators)] of the record's two halves
    y_halves: np.ndarray | None = None             # (2, n) features of each half (series; the summary has none)
    noise_sd: np.ndarray | None = None             # the noise part of sd, without the model floor (series)
    max_harmonic_hz: float = 0.0                    # the features' highest harmonic frequency
    chain: DeclaredChain | None = None             # the DAQ chain runs.csv declares (None: undeclared)
    nuisance: Nuisance | None = None               # an undeclared chain's delays (nuisance.estimate_chain)
    timing: DeclaredChain | None = None            # ... and its clock, applied at the model's instants
    antialias: bool = False                        # the record passed an anti-alias filter: so does the model
    pairs: tuple = ()                              # (signal, k) of every harmonic feature pair, in feature order
    pair_at: np.ndarray | None = None              # index of each pair's real part in the features
    pair_kw: np.ndarray | None = None              # each pair's angular frequency k Ω [rad/s]
    filter_gain: np.ndarray | None = None          # the declared filter's response at each pair (None: no filter)
    spans: tuple = ()                              # (mid record time, length) [s] of the record and of its halves
    clipped: dict = field(default_factory=dict)    # signal -> fraction of samples saturated
    saturation: dict = field(default_factory=dict)  # signal -> Saturation (its range; the model is clipped there)
    lines: dict = field(default_factory=dict)      # signal -> [mains.Line] measured apart from the harmonics
    hum: dict = field(default_factory=dict)        # the log's mains hum (mains.Hum) allowed for on this run
    notes: list = field(default_factory=list)      # what the features left out, for the report

    @property
    def low(self) -> np.ndarray:
        """Which features a first, coarse fit uses (``low_harmonics``)."""
        return low_harmonics(self.names, self.frequency_hz, self.max_harmonic_hz)

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

    def needs_history(self, params: dict) -> bool:
        """Whether simulating this run needs a time history: every run whose features are not labels
        (``labels_only``), and a run with a sensor low-pass (``params``' fc > 0), which filters the history."""
        return not labels_only(self) or float(params.get("fc", 0.0) or 0.0) > 0.0


def labels_only(tg) -> bool:
    """Whether a run's model features are the simulator's steady-state labels (a steady-state summary run without
    a spectral ratio): no time history is needed to compute them."""
    return tg.kind == "summary" and tg.record_start_s is None and "spectral_ratio" not in tg.names


LOW_FRACTION = 0.2
"""A coarse fit compares the harmonics up to this fraction of max_harmonic_hz (at least the second) and every
non-harmonic feature."""


def low_harmonics(names: list[str], f: float, max_harmonic_hz: float) -> np.ndarray:
    """Mask of the features a coarse fit uses: every feature but the harmonics above LOW_FRACTION × max_harmonic_hz
    (and above the second).  An impact's high harmonics turn by k × its timing: their misfit is periodic in any
    parameter that shifts the impact, with a local minimum every 1/k of a cycle, where the low harmonics' misfit has
    one; fitting those first finds the right basin."""
    k_low = max(2, int(math.floor(LOW_FRACTION * max_harmonic_hz / f + 1e-9))) if max_harmonic_hz else 10 ** 9
    out = np.ones(len(names), dtype=bool)
    for j, n in enumerate(names):
        if ":h" in n:
            out[j] = int(n.split(":h")[1].split(":")[0]) <= k_low
    return out


def _complex_features(sig: str, c: np.ndarray) -> tuple[list[str], np.ndarray]:
    names = [f"{sig}:h{k}:{part}" for k in range(1, c.size + 1) for part in ("re", "im")]
    return names, np.column_stack([c.real, c.imag]).ravel()


def record_time(tg: Target, t_record: np.ndarray) -> np.ndarray:
    """Time since the start of excitation (record from rest) or record time (steady state) [s]."""
    return t_record + (tg.record_start_s or 0.0)


def _operators(t: np.ndarray, f: float, k: int, lines: tuple = ()) -> dict:
    """Least-squares operators of a time base: "harmonic" (cubic drift, DRIFT_DEGREE) for accelerations, forces and
    displacements, "linear" (offset and rate) for the progression.  ``lines``: mains hum lines (family, m) fitted
    beside the harmonics (``mains``), their rows dropped from the operator."""
    a = _design(t, f, k, DRIFT_DEGREE)
    harmonic = np.linalg.pinv(np.column_stack([a, mains.line_columns(t, list(lines))]))[:a.shape[1]] if lines \
        else np.linalg.pinv(a)
    return {"harmonic": harmonic, "linear": np.linalg.pinv(_design(t, f, k, 1))}


def _coefs(ops: dict, x: dict, sl: slice = slice(None)) -> dict:
    """Each signal's least-squares coefficients on its operator (samples ``sl`` of ``x``)."""
    return {sig: ops["linear" if sig == "progression_m" else "harmonic"] @ v[sl] for sig, v in x.items()}


def _features(signals: tuple[str, ...], coef: dict, from_rest: bool) -> np.ndarray:
    """Feature values from each signal's least-squares coefficients (``_coefs``): the complex harmonics
    c_k = a_k − i b_k of accel / force / displacement, the progression's rate and, for a record from rest, its mean
    (the record's depth in the rig frame)."""
    out = []
    for sig in signals:
        c = coef[sig]
        if sig == "progression_m":
            out.append(np.array([c[1]] + ([c[0]] if from_rest else [])))
        else:
            h = _harmonics(c, DRIFT_DEGREE)
            out.append(np.column_stack([h.real, h.imag]).ravel())
    return np.concatenate(out)


def steady_cycles(cycles: float, max_cycles: float = 0.0) -> int:
    """Whole cycles of a steady-state record that its features use: a multiple of 4 (of 2 below 8 cycles), at most
    ``max_cycles`` (> 0)."""
    c = math.floor(cycles + 1e-9)
    if max_cycles:
        c = min(c, int(max_cycles))
    return max((c // 4) * 4 if c >= 8 else (c // 2) * 2, 2)


def _halves(t: np.ndarray, f: float, k: int, steady: bool, lines: tuple = ()) -> list:
    """The record's two halves (slices) and the least-squares operators of their own time bases; a steady-state
    record (whole pairs of cycles, ``steady_cycles``) is split between its pairs."""
    mid = t.size // 2
    if steady:
        mid = int(np.searchsorted(t, t[0] + 0.5 * (t[-1] - t[0] + (t[1] - t[0])) - 1e-9 * (t[1] - t[0])))
    return [(sl, _operators(t[sl], f, k, lines)) for sl in (slice(0, mid), slice(mid, t.size))]


MAX_CLIPPED_FRACTION = 0.5
"""A channel saturated in more than this fraction of its samples is not used (named in the notes): the model is
clipped at the same range (``Target.saturation``), so what is left is the instants the signal enters and leaves its
range; past half the record those say little and the noise estimate rests on few samples."""


MIN_AT_EXTREME = 3
"""Samples at exactly a channel's maximum (or minimum) that make it a saturation: a noisy signal reaches its extreme
once; a clipped one sits there in flat tops (at 25.6 kHz an impact's flat top may be a single sample)."""


def clipped_samples(x: np.ndarray) -> np.ndarray:
    """Mask of the saturated samples of a channel: the samples at exactly its maximum or minimum, when at least
    MIN_AT_EXTREME sit there and either two of them are adjacent (a flat top) or the samples next to them differ
    from one to the next (an impact's spike clipped for one sample at a time, with noise: a noise-free periodic
    record may repeat its peak once a cycle, but then its neighbours too); an extreme of exactly 0 is a contact
    force at rest, not a sensor's range."""
    out = np.zeros(x.size, dtype=bool)
    for v in (float(x.max()), float(x.min())):
        at = x == v
        idx = np.flatnonzero(at)
        if v == 0.0 or idx.size < MIN_AT_EXTREME or idx.size == x.size:
            continue
        flat = bool(np.any(at[1:] & at[:-1]))
        side = [x[np.clip(idx + d, 0, x.size - 1)] for d in (-1, 1)]
        if flat or max(float(np.ptp(s_)) for s_ in side) > 1e-9 * abs(v):
            out |= at
    return out


def _whole_cycles(df: pd.DataFrame, f: float, max_cycles: float) -> pd.DataFrame:
    """A steady-state record cut to whole cycles (``steady_cycles``: a multiple of 4, at most ``max_cycles``)."""
    t_all = df["t_s"].to_numpy()
    if t_all.size > 1:
        dt0 = float(t_all[1] - t_all[0])
        n_cyc = steady_cycles((t_all[-1] - t_all[0] + dt0) * f, max_cycles)
        df = df.iloc[:int(np.searchsorted(t_all, n_cyc / f - 1e-9 * dt0))]
    return df


@dataclass(frozen=True)
class Saturation:
    """Where a record's channel saturated, for clipping the model alike: the ADC's range (low, high) [unit; -inf /
    +inf on a side it never reached] and, to place the model in the sensor's frame (its offset and slow drift move
    the signal against the range), the drift basis of the record and the measured values at its unsaturated
    samples."""

    low: float
    high: float
    keep: np.ndarray           # indices of the unsaturated samples
    basis: np.ndarray          # (N, DRIFT_DEGREE + 1) polynomial drift over the record
    basis_pinv: np.ndarray     # its least-squares operator on the unsaturated samples
    measured: np.ndarray       # the record at the unsaturated samples [unit]

    @classmethod
    def of(cls, t: np.ndarray, x: np.ndarray, m: np.ndarray) -> "Saturation":
        """From a record's times, values and saturated-sample mask (``clipped_samples``)."""
        lo, hi = float(x.min()), float(x.max())
        tau = (t - 0.5 * (t[0] + t[-1])) / max(0.5 * (t[-1] - t[0]), 1e-300)
        basis = np.column_stack([tau ** j for j in range(DRIFT_DEGREE + 1)])
        keep = np.flatnonzero(~m)
        return cls(lo if np.any(m & (x == lo)) else -math.inf, hi if np.any(m & (x == hi)) else math.inf,
                   keep, basis, np.linalg.pinv(basis[keep]), x[keep])

    def clip(self, x: np.ndarray) -> np.ndarray:
        """A model's signal at the record's instants as the saturating channel writes it: moved by the record's
        drift against the model (fitted on the unsaturated samples), clipped at the range, moved back."""
        d = self.basis @ (self.basis_pinv @ (self.measured - x[self.keep]))
        return np.clip(x + d, self.low, self.high) - d


def _unsaturated(tg: Target, df: pd.DataFrame) -> tuple[tuple[str, ...], dict[str, np.ndarray]]:
    """The record's signals without the channels saturated in more than ``MAX_CLIPPED_FRACTION`` of their samples,
    and the unsaturated samples of those saturated less (the noise is estimated on them); their range on
    ``tg.saturation`` (the model is clipped there), notes and clipped fractions on ``tg``."""
    sigs = tuple(sig for sig in (*HARMONIC_SIGNALS, "progression_m") if sig in df.columns)
    keep = {}
    for sig in HARMONIC_SIGNALS:
        if sig not in sigs:
            continue
        vals = df[sig].to_numpy()
        m = clipped_samples(vals)
        frac = float(m.mean())
        if frac > MAX_CLIPPED_FRACTION:
            sigs = tuple(s_ for s_ in sigs if s_ != sig)
            tg.notes.append(f"run {tg.run_id}, channel {sig}: {frac:.1%} of the samples saturated (identical values "
                            f"at the channel's extreme), more than {MAX_CLIPPED_FRACTION:.0%}: the channel is not used")
        elif frac > 0:
            keep[sig] = ~m
            tg.clipped[sig] = frac
            tg.saturation[sig] = Saturation.of(df["t_s"].to_numpy(), vals, m)
            tg.notes.append(f"run {tg.run_id}, channel {sig}: {frac:.2%} of the samples saturated (identical values "
                            f"at the channel's extreme): the model is clipped at the same range")
    return sigs, keep


def _segment_harmonics(t: np.ndarray, f: float, k: int, present: list[str], x_all: dict[str, np.ndarray],
                       n_segments: int) -> dict[str, np.ndarray]:
    """The harmonics of each signal fitted on each of ``n_segments`` equal segments of the record (the segment's
    own fit, harmonics as the features')."""
    a_h = _design(t, f, k, DRIFT_DEGREE)
    x_stack = np.column_stack([x_all[sig] for sig in present])
    edges = np.linspace(0, t.size, n_segments + 1).astype(int)
    seg_c: dict[str, list] = {sig: [] for sig in present}
    for lo, hi in zip(edges[:-1], edges[1:]):
        cs = np.linalg.lstsq(a_h[lo:hi], x_stack[lo:hi], rcond=None)[0]
        for j, sig in enumerate(present):
            seg_c[sig].append(_harmonics(cs[:, j], DRIFT_DEGREE))
    return {sig: np.array(v) for sig, v in seg_c.items()}


def _feature_sd(tg: Target, t: np.ndarray, a: np.ndarray, k: int, sigs: tuple[str, ...],
                x_all: dict[str, np.ndarray], coef: dict, keep: dict, from_rest: bool, model_floor: float) -> tuple:
    """Per feature: name, sd (noise and model floor), noise sd and group, with the (signal, harmonic) pairs and
    where each pair's first feature sits; the broadband noise of each signal on ``tg.noise``."""
    f = tg.frequency_hz
    names, sd, noise, group = [], [], [], []
    pairs, pair_at = [], []
    for sig in sigs:
        dens, broad = record_noise(t, x_all[sig], f, k, SLOW_DEGREE if from_rest else 0, keep.get(sig))
        n = t.size
        tg.noise[sig] = broad
        c = coef[sig]
        if sig == "progression_m":
            _, res = _from_coef(a, x_all[sig], c)
            se = math.sqrt(float(res @ res) / max(n - a.shape[1], 1) / max(float(((t - t.mean()) ** 2).sum()), 1e-300))
            s_rate = max(se, math.sqrt(12.0 * dens[0] / n) / tg.duration_s)
            names.append("rop_m_s")
            sd.append(math.hypot(s_rate, model_floor * abs(c[1])))
            noise.append(s_rate)
            group.append("rop_m_s")
            if from_rest:
                names.append("progression_m:mean")
                sd.append(math.hypot(math.sqrt(dens[0] / n), model_floor * abs(c[0])))
                noise.append(math.sqrt(dens[0] / n))
                group.append("progression_m")
            continue
        h = _harmonics(c, DRIFT_DEGREE)
        floor = model_floor * math.sqrt(float(np.mean(np.abs(h) ** 2)))
        csd = np.sqrt(2.0 * dens[1:] / n + floor ** 2)
        csd = np.maximum(csd, 1e-12 * (float(np.abs(h).max()) + 1e-30))
        pair_at += list(len(names) + 2 * np.arange(k))
        pairs += [(sig, j) for j in range(1, k + 1)]
        names += _complex_features(sig, h)[0]
        sd += list(np.repeat(csd, 2))
        noise += list(np.repeat(np.sqrt(2.0 * dens[1:] / n), 2))
        group += [sig] * (2 * k)
    return names, sd, noise, group, pairs, pair_at


def _mains_lines(t: np.ndarray, f: float, k: int, x_all: dict, coef: dict, apart: list) -> dict:
    """The mains lines ``apart`` from the harmonics measured on each harmonic signal's residual (``mains.measure``,
    against the residual's ``_periodogram``)."""
    sigs = [sig for sig in x_all if sig in HARMONIC_SIGNALS]
    if not apart:
        return {sig: [] for sig in sigs}
    a = _design(t, f, k, DRIFT_DEGREE)
    out = {}
    for sig in sigs:
        res = x_all[sig] - a @ coef[sig]
        _, power, df = _periodogram(res, 1.0 / float(t[1] - t[0]))
        out[sig] = mains.measure(t, res, apart, power, df)
    return out


def series_target(tg: Target, df: pd.DataFrame, max_harmonic_hz: float, n_segments: int = 4,
                  model_floor: float = 0.0, max_cycles: float = 0.0, hum_hz: tuple[float, ...] = ()) -> Target:
    """Fill ``tg`` (run_id, system, controls, known, record_start_s set) from a measured series.

    Feature sd: the noise of each harmonic coefficient part, sqrt(2 S_k / N) with S_k the record's noise density
    around k f (``record_noise``: coloured and signal-proportional noise included), and in quadrature the model
    floor ``model_floor`` × the RMS harmonic amplitude of the signal (what two correct simulations of the same
    equations and a rig's sampling may differ by, not noise).  Progression: its rate's sd from the slow band
    (sqrt(12 S_0 / N) / T, at least the regression's) and the same relative floor.
    A steady-state record is cut to whole cycles (``steady_cycles``: a multiple of 4, at most ``max_cycles``), so
    that each half holds whole pairs of cycles: a period-2 response (an impact every second cycle) then leaves the
    harmonics of f alone whichever of its two phases the record started in, and the model's orbit may be in the
    other one (a steady state does not say).  A record from rest keeps every sample (its phase is the run's).
    Mains lines apart from the harmonics are measured on every harmonic signal (``Target.lines``); those of the
    mains frequencies ``hum_hz`` (the log's hum, ``mains.detect``) are fitted beside the harmonics."""
    f = tg.frequency_hz
    if tg.record_start_s is None:
        df = _whole_cycles(df, f, max_cycles)
    t_rec = df["t_s"].to_numpy()
    k = harmonic_count(f, max_harmonic_hz)
    check_resolution(tg.run_id, t_rec, f, k)
    dt = float(t_rec[1] - t_rec[0])
    tg.kind, tg.k_max, tg.fs_hz, tg.duration_s = "series", k, 1.0 / dt, float(t_rec[-1] - t_rec[0] + dt)
    tg.max_harmonic_hz = max_harmonic_hz
    t = record_time(tg, t_rec)
    tg.t_rec = t_rec
    a = _design(t, f, k)
    sigs, keep = _unsaturated(tg, df)
    if not sigs:
        raise UnusableRecord(f"run {tg.run_id}: every channel is saturated in more than {MAX_CLIPPED_FRACTION:.0%} "
                             f"of its samples; the run is skipped")
    apart, _ = mains.mains_lines(f, k, tg.duration_s, tg.fs_hz)
    hum_lines = tuple(ln for ln in apart if ln[0] in hum_hz)
    tg.pinv = _operators(t, f, k, hum_lines)
    x_all = {sig: df[sig].to_numpy() for sig in sigs}
    coef = _coefs(tg.pinv, x_all)
    from_rest = tg.record_start_s is not None
    tg.halves = _halves(t, f, k, not from_rest, hum_lines) if tg.cycles >= 2 * MIN_CYCLES else []
    tg.lines = _mains_lines(t, f, k, x_all, coef, apart)
    spans = [(float(np.mean(t_rec)), tg.duration_s)]
    spans += [(float(np.mean(t_rec[sl])), float(t_rec[sl][-1] - t_rec[sl][0] + dt)) for sl, _ in tg.halves]
    tg.spans = tuple(spans)
    if tg.halves:
        tg.y_halves = np.array([_features(sigs, _coefs(ops, x_all, sl), from_rest) for sl, ops in tg.halves])
    present = [sig for sig in HARMONIC_SIGNALS if sig in sigs]
    if present and tg.cycles >= 2 * n_segments * MIN_CYCLES / 2:
        tg.segments = _segment_harmonics(t, f, k, present, x_all, n_segments)
    names, sd, noise, group, pairs, pair_at = _feature_sd(tg, t, a, k, sigs, x_all, coef, keep, from_rest,
                                                          model_floor)
    tg.names, tg.sd, tg.group, tg.signals = names, np.array(sd), group, sigs
    tg.noise_sd = np.array(noise)
    tg.y = _features(sigs, coef, from_rest)
    tg.lower_bound = np.zeros(tg.y.size, dtype=bool)
    tg.pairs, tg.pair_at = tuple(pairs), np.array(pair_at, dtype=int)
    tg.pair_kw = 2.0 * math.pi * f * np.array([j for _, j in pairs], dtype=float)
    if tg.chain is not None and tg.chain.filter is not None:
        tg.filter_gain = tg.chain.gain(tg.pair_kw / (2.0 * math.pi))
    return tg


def summary_target(tg: Target, srow: pd.Series, max_harmonic_hz: float, sd_defaults: dict | None = None,
                   floor: float = 0.0) -> Target:
    """Fill ``tg`` from a summary.csv row.  A feature's sd is its ``<name>_sd`` column or the assumed default, and in
    quadrature ``floor`` × its value (a label the rig's software and the model define slightly differently)."""
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
        sd.append(math.hypot(s, floor * abs(v)))
        lb.append(feat == "impacts_per_cycle" and bool(srow.get("impacts_per_cycle_lower_bound", 0) == 1))
    tg.names, tg.y, tg.sd, tg.group = names, np.array(y), np.array(sd), list(names)
    tg.lower_bound = np.array(lb, dtype=bool)
    return tg


Columns = Mapping[str, np.ndarray]
"""A simulated history as its columns (``SimulationResult.columns``: t_s, states, signals), one array each."""


def history_columns(res) -> Columns | None:
    """The history of a simulation result as arrays: its ``columns`` where it has them (no DataFrame is built),
    else its ``history`` DataFrame's; None without a history."""
    cols = getattr(res, "columns", None)
    if cols is not None:
        return cols
    h = getattr(res, "history", None)
    return None if h is None else {c: h[c].to_numpy() for c in h.columns}


def model_record(tg: Target, h: Columns) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The part of a simulated history (its columns) that corresponds to the record, and its time base
    (``record_time``).  Series: the history was sampled at the record's own instants (``sampling_plan``), after a
    warm-up of the sensor where one was needed: its last N rows.  Summary: a steady-state window as simulated
    (starts at forcing phase 0); a run from rest cut to [record_start_s, record_start_s + duration_s]."""
    t = np.asarray(h["t_s"])
    if tg.t_rec is not None:
        rows = _record_rows(tg, h)
        return record_time(tg, tg.t_rec), {c: np.asarray(v)[rows] for c, v in h.items()}
    if tg.record_start_s is None:
        return t - t[0], dict(h)
    m = (t >= tg.record_start_s - 1e-12) & (t < tg.record_start_s + tg.duration_s - 1e-12)
    return t[m], {c: np.asarray(v)[m] for c, v in h.items()}


SENSOR_SUBSAMPLES = 8
"""Model samples per record interval while a sensor low-pass is on: it filters the sampled velocity, exact for a
velocity linear between samples (sim.models.sensor), so a contact's kink wants a finer grid than the record's."""


ANTIALIAS_TAPS = 8
"""Length of the model's anti-alias filter in record samples (``antialias_taps``)."""
ANTIALIAS_CUTOFF = 0.5
"""Its cut-off as a fraction of the record's sampling rate."""


@functools.lru_cache(maxsize=4)
def antialias_taps(sub: int = SENSOR_SUBSAMPLES) -> np.ndarray:
    """A linear-phase low-pass (Kaiser-windowed sinc, β = 8) on a grid ``sub`` times finer than the record's, unit
    gain at DC: flat to 3e-4 (below the features' model floor) up to 0.18 fs, 74 dB down above 0.82 fs of the
    record's rate.  Content folds onto a harmonic kf only from within kf of a multiple of fs, so the model keeps what
    a DAQ's anti-alias filter lets through; harmonics above 0.18 fs (``check_resolution``'s bound is fs/2) have the
    droop divided out (``antialias_compensation``).  Applied centred it turns no phase: the filter's delay and
    pass-band response are the chain's (declared, or estimated as delays)."""
    from scipy.signal import firwin

    taps = firwin(ANTIALIAS_TAPS * sub + 1, 2.0 * ANTIALIAS_CUTOFF / sub, window=("kaiser", 8.0))
    return taps / taps.sum()


def antialias_compensation(tg: Target) -> np.ndarray | None:
    """1 / the model's anti-alias filter's gain at each of ``tg``'s harmonic pairs (None without the filter): its
    pass band droops above 0.18 fs, and a record's harmonics may reach fs/2; the filter stays transparent there."""
    if not tg.antialias or tg.pair_kw is None:
        return None
    return _inverse_gain(tuple((tg.pair_kw / (tg.fs_hz * SENSOR_SUBSAMPLES)).tolist()))


@functools.lru_cache(maxsize=256)
def _inverse_gain(w: tuple[float, ...]) -> np.ndarray:
    """1 / |gain| of ``antialias_taps`` at the angular frequencies ``w`` [rad per fine sample]: a record's harmonics
    are fixed, so each record's is computed once, not once per simulation."""
    from scipy.signal import freqz

    out = 1.0 / np.maximum(np.abs(freqz(antialias_taps(), worN=np.array(w))[1]), 1e-3)
    out.flags.writeable = False
    return out


def antialias_pad(tg: Target) -> int:
    """Model samples the anti-alias filter needs either side of the record (fine grid; 0 without it)."""
    return ANTIALIAS_TAPS * SENSOR_SUBSAMPLES // 2 if tg.antialias else 0


ORBIT_CYCLES = 4
"""A steady-state record's model starts a multiple of this many forcing periods into the settled window when it
needs samples before the record: a period-2 (or period-4) orbit one forcing period on is the other half of its
orbit (the pendulum at 5.5 Hz: the displacement differs by more than its amplitude), not the record's."""


def sampling_plan(tg: Target, frequency_hz: float, warmup_s: float = 0.0) -> tuple[np.ndarray, int, float]:
    """Where to sample the model of a series run: (times from the start of the simulated window [s], window cycles,
    first record time [s] in that window).  The times are the record's own instants — a steady-state record
    starts at forcing phase 0 of the window (after a multiple of ORBIT_CYCLES cycles where samples before it are
    needed), a record from rest at record_start_s of a window that starts at rest — and, for ``warmup_s`` > 0 (a
    sensor's dynamics to settle), the same uniform grid SENSOR_SUBSAMPLES times finer, extended backwards over that
    long (from rest: back to t = 0).  A record that passed an anti-alias filter (``Target.antialias``) is sampled
    on the finer grid too, extended by the filter's half length either side (``model_on_record`` filters it)."""
    period = 1.0 / frequency_hz
    pad = antialias_pad(tg)
    sub = SENSOR_SUBSAMPLES if warmup_s > 0 or pad else 1
    dt = 1.0 / (tg.fs_hz * sub)
    lead_s = max(warmup_s, pad * dt * 1.01)
    if tg.record_start_s is None:
        whole = ORBIT_CYCLES * period
        t0 = math.ceil(lead_s / whole - 1e-9) * whole if lead_s > 0 else 0.0
    else:
        t0 = tg.record_start_s
    n_pre = int(math.floor(min(lead_s, t0) / dt + 1e-9)) if lead_s > 0 else 0
    times = t0 + np.arange(-n_pre, tg.t_rec.size * sub + pad) * dt
    end = max(t0 + tg.duration_s, float(times[-1]) + dt)
    chain = tg.chain or tg.timing
    # a declared (or estimated) delay and clock: the plant at the true instants (a null chain changes nothing)
    if chain is not None and (chain.delay_s or chain.clock_ppm):
        times = chain.true_times(times, t0)
        end = float(times[-1]) + dt
        if times[0] < 0:            # delayed past the start from rest: the first samples hold the rest state
            times = np.maximum(times, np.arange(times.size) * 1e-9 * dt)
    window = int(math.ceil(end / period)) + 1
    return times, max(window, 2), t0


def history_summary(name: str, t: np.ndarray, h: Columns | pd.DataFrame, f: float) -> float:
    """Summary label over a cut history (runs from rest; its columns or a DataFrame): MODELS.md §5 definitions."""
    if name == "rop_m_s":
        x = np.asarray(h["progression_m"])
        return float(np.polyfit(t - t.mean(), x, 1)[0])
    if name == "peak_force_n":
        return float(np.max(h["force_n"]))
    if name == "peak_decel_g":
        return float(max(-np.min(h["accel_m_s2"]), 0.0) / G)
    if name == "impacts_per_cycle":
        on = np.asarray(h["force_n"]) > 0
        return float(np.count_nonzero(on[1:] & ~on[:-1]) / max((t[-1] - t[0]) * f, 1e-9))
    raise KeyError(name)


def _record_rows(tg: Target, h: Columns) -> np.ndarray:
    """Rows of a history sampled by ``sampling_plan`` at the record's instants: the last N on its grid (every
    SENSOR_SUBSAMPLES-th where it was sampled finer), before the anti-alias filter's padding."""
    n = tg.t_rec.size
    t = np.asarray(h["t_s"])
    sub = max(int(round(1.0 / (tg.fs_hz * (t[1] - t[0])))), 1) if t.size > 1 else 1
    end = t.size - antialias_pad(tg)
    return np.arange(end - n * sub, end, sub)        # the grid runs sub - 1 points past the record's end


def model_on_record(tg: Target, h: Columns, sig: str) -> np.ndarray:
    """A simulated signal (a history's columns) at the measured record's own instants (``sampling_plan``); through
    the anti-alias filter (``antialias_taps``, centred on each instant) where the record passed one, and clipped at
    the range where the record's channel saturated (``Target.saturation``; a DAQ's ADC comes after its filter).
    Before a record from rest the model holds its rest value."""
    x = _on_record(tg, h, sig)
    return tg.saturation[sig].clip(x) if sig in tg.saturation else x


def _on_record(tg: Target, h: Columns, sig: str) -> np.ndarray:
    """``model_on_record`` before the ADC's range."""
    x = np.asarray(h[sig], dtype=float)
    rows = _record_rows(tg, h)
    if not tg.antialias:
        return x[rows]
    from scipy.signal import upfirdn

    taps = antialias_taps()
    half, sub = taps.size // 2, (int(rows[1] - rows[0]) if rows.size > 1 else 1)
    first = int(rows[0]) - half
    if first < 0:                       # before a record from rest: the rest state
        x, rows, first = np.concatenate([np.full(-first, x[0]), x]), rows - first, 0
    seg = x[first:int(rows[-1]) + half + 1]
    # polyphase, out[n] = sum_j taps[j] seg[n sub - j]: instant k (seg index half + k sub) is n = k + 2 half / sub
    return upfirdn(taps, seg, 1, sub)[2 * half // sub:][:rows.size]


DIVERGED = 1e100
"""A simulated signal beyond this magnitude (any unit) has diverged: its least-squares features would overflow, so
the run counts as one the model could not simulate (features None), like a failed one."""


def _diverged(x: dict[str, np.ndarray]) -> bool:
    """Whether any signal of ``x`` is non-finite or beyond :data:`DIVERGED`."""
    return any(v.size and not (np.all(np.isfinite(v)) and float(np.max(np.abs(v))) < DIVERGED) for v in x.values())


def _model_gain(tg: Target, part: int = 0) -> np.ndarray | None:
    """What the model's harmonic pairs are multiplied by: the recording chain's gain (``instrument_gain``; ``part``
    0 the record, 1 and 2 its halves) and the inverse of the model's anti-alias filter's pass band."""
    comp, g = antialias_compensation(tg), instrument_gain(tg, part)
    return g if comp is None else comp if g is None else comp * g


def simulated_halves(tg: Target, res) -> np.ndarray | None:
    """The model's features of each half of a series record, (2, n) (None: no halves, no history, or diverged)."""
    h = history_columns(res)
    if not tg.halves or h is None:
        return None
    x = {sig: model_on_record(tg, h, sig) for sig in tg.signals}
    if _diverged(x):
        return None
    return np.array([apply_gain(_features(tg.signals, _coefs(ops, x, sl), tg.record_start_s is not None), tg.pair_at,
                                _model_gain(tg, j + 1)) for j, (sl, ops) in enumerate(tg.halves)])


def simulated_features(tg: Target, res) -> np.ndarray | None:
    """The model's values of ``tg``'s features from a SimulationResult with history (None if the run has no
    history — it failed or ran away — or its signals diverged, :data:`DIVERGED`)."""
    if labels_only(tg):
        lab = res.labels
        m = np.array([0.0 if lab.get(name) is None else float(lab[name]) for name in tg.names])
        return None if lab["status"] not in BOUNDED_STATUSES or _diverged({"labels": m}) else m
    h = history_columns(res)
    if h is None:
        return None
    f = tg.frequency_hz
    if tg.kind == "series":
        x = {sig: model_on_record(tg, h, sig) for sig in tg.signals}
        if _diverged(x):
            return None
        m = _features(tg.signals, _coefs(tg.pinv, x), tg.record_start_s is not None)
        return apply_gain(m, tg.pair_at, _model_gain(tg))
    lab = res.labels
    t, hr = model_record(tg, h)
    if t.size < 4 or _diverged({c: np.asarray(v, dtype=float) for c, v in hr.items() if c != "t_s"}):
        return None
    vals = []
    for name in tg.names:
        if name == "spectral_ratio":
            vals.append(spectral_ratio(t, hr["accel_m_s2"], f, tg.k_max, tg.ratio_ref_hz))
        elif tg.record_start_s is not None:
            vals.append(history_summary(name, t, hr, f))
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
    h = history_columns(res)
    return None if h is None else float(np.max(h["vel_m_s"]))
