"""The data-acquisition chain between a rig's sensors and its log: anti-alias filter, sample clock, ADC range, hum.

A ``DaqChain`` is an option of the log spec (``LogSpec(daq=...)``); ``None`` (or a chain with every part off) leaves
the generator's output exactly as it was.  Order of the chain, as in a real front end (every part optional):

  1. physics: the reference's dense output, as a continuous function of the true time t (s from the start of
     excitation).
  2. mains hum (``hum_hz``, ``hum``: amplitudes of the harmonics k = 1, 2, ... per channel, in the channel's unit,
     random phases per run and channel) enters with the sensor's cable, *before* the filter: it is added to the
     continuous signal and passes the filter (its steady-state response, since mains is on before any record).
  3. anti-alias filter (``filter``), acting on the continuous signal:
       butter  analog Butterworth of ``order``, -3 dB at ``cutoff`` x fs
       ellip   analog elliptic of ``order``, pass-band ripple ``ripple_db`` up to ``cutoff`` x fs, stop band
               ``stop_db`` down, scaled to gain 1 at DC (a calibrated channel; scipy's even orders start at
               -ripple_db)
       fir     a delta-sigma ADC's decimation filter: a linear-phase FIR (Kaiser window, ``stop_db``, cut-off
               ``cutoff`` x fs, transition up to fs/2) on the modulator's stream at ``oversample`` x fs, decimated
     The analog kinds are simulated exactly for a piecewise-linear input on a uniform grid of ``oversample``
     points per sample interval (first-order hold, the filter in modal form, one exact complex recursion per
     pole): the grid is the dense output at those instants.  The acceleration of the impacting mass, which jumps
     at a contact's onset, enters as its velocity (``H a = C w + (CB) v + D a`` with ``w = x - B v``, exact for v
     piecewise linear, as ``outside.measured_accel`` does); a force that jumps (the drill's damper at onset) is
     resolved to the grid step (its jump moves by at most half a step, 1/(2 oversample fs)).  The filter starts
     settled on the signal's value at the grid's first point: at t = 0 for a record from rest (the rig was at rest
     before the excitation started), early enough for its slowest pole to decay below 1e-12 for a steady-state
     record.
     ``compensated``: as DAQ software that aligns channels writes it, every time stamp is moved back by the
     filter's group delay at DC, tau0 (sample k holds the filter's output at the instant of t_s + tau0): what
     remains is the filter's phase non-linearity and amplitude droop.  Uncompensated: tau0 stays in the data.
  4. sampling at the DAQ's clock: the true interval between samples is (1 + clock_ppm 1e-6) / fs while ``t_s``
     is written from the nominal rate, k / fs (``record_start_s`` is the true instant of the first sample).
     ``channel_delay_s`` (channel -> d [s]): that channel's samples hold the signal d earlier (a signal
     conditioner's own delay; a multiplexed ADC's later channels, d < 0); never declared, in the truth only.
  5. the noise model's parts before the ADC (sensor floor, RMS noise, gain noise, 1/f, offsets and drift;
     ``noise.py``): their levels are those of the record as written (the sensors' noise as the chain band-limits
     it), so they are added at the samples, as without a chain.
  6. the ADC: saturation at a range per channel (``clip_fraction``: range = fraction x max|x| of the run's
     noise-free record after steps 1-4; ``clip_range``: an absolute range in the channel's unit): samples beyond
     it are written as exactly +-range; then the noise model's quantisation, with the ADC's full scale = the
     range on a saturating channel (so +-range is a code), as before on the others.

``declared``: runs.csv holds what the DAQ declares (``runs_columns``) - ``daq_filter`` = ``kind:order:cutoff_hz``
(``butter:8:11520``; elliptic ``ellip:6:11520:ripple_db:stop_db``; FIR ``fir:taps:cutoff_hz:oversample``, the taps
at oversample x fs), ``daq_delay_s`` = the filter's group delay at DC [s] (0 without a filter),
``daq_delay_removed`` = 1 when the time stamps were moved back by it (compensated), else 0, and
``daq_clock_ppm`` = the clock's error [ppm]; undeclared: none of these columns.  The truth holds the chain and,
per run, the filter, tau0, the clock, the ranges and the hum's phases.

``DAQ_CHAINS`` names the chains the matrix uses; ``python -m tests.independent.generator --help`` builds others.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal as sps

KINDS = ("butter", "ellip", "fir")
CHANNELS = ("accel_m_s2", "force_n", "disp_m", "progression_m")


@dataclass(frozen=True)
class DaqChain:
    """A data-acquisition chain (module docstring); every part off by default."""

    name: str = "daq"
    filter: str | None = None           # "butter", "ellip", "fir" or None
    order: int = 8                      # analog order; fir: taps at oversample x fs (0: from stop_db by Kaiser)
    cutoff: float = 0.45                # cut-off / fs [-]
    ripple_db: float = 0.1              # ellip pass-band ripple [dB]
    stop_db: float = 80.0               # ellip stop band / fir stop-band attenuation [dB]
    compensated: bool = False           # time stamps moved back by the DC group delay
    oversample: int = 16                # grid points per sample interval (fir: the modulator's rate / fs)
    clock_ppm: float = 0.0              # true interval = (1 + clock_ppm 1e-6) / fs
    clip_fraction: dict = field(default_factory=dict)   # channel -> range / max|x| of the noise-free record
    clip_range: dict = field(default_factory=dict)      # channel -> absolute range [channel unit]
    hum_hz: float = 50.0                # mains frequency [Hz]
    hum: dict = field(default_factory=dict)             # channel -> (amplitude of harmonic 1, 2, ...) [unit]
    channel_delay_s: dict = field(default_factory=dict)  # channel -> its own extra delay [s] (undeclared)
    declared: bool = True               # runs.csv declares filter, delay and clock

    def __post_init__(self):
        if self.filter is not None and self.filter not in KINDS:
            raise ValueError(f"filter {self.filter!r}: one of {KINDS} or None")
        if self.filter in ("butter", "ellip") and not 1 <= self.order <= 12:
            raise ValueError(f"analog filter order {self.order}: 1..12")
        if not 0.0 < self.cutoff < 0.5:
            raise ValueError(f"cutoff {self.cutoff}: a fraction of fs in (0, 0.5)")
        if self.oversample < 2:
            raise ValueError("oversample >= 2")
        for d in (self.clip_fraction, self.clip_range, self.hum, self.channel_delay_s):
            for ch in d:
                if ch not in CHANNELS:
                    raise ValueError(f"channel {ch!r}: one of {CHANNELS}")
        if any(not 0.0 < v for v in (*self.clip_fraction.values(), *self.clip_range.values())):
            raise ValueError("saturation ranges must be > 0")

    @property
    def is_off(self) -> bool:
        """True when the chain changes nothing (the generator then writes what it wrote without one)."""
        return (not self.times_change and not self.clip_fraction and not self.clip_range
                and not any(any(a != 0.0 for a in amps) for amps in self.hum.values()) and not self.declared)

    @property
    def times_change(self) -> bool:
        """True when the samples are taken at other instants or through a filter."""
        return self.filter is not None or self.clock_ppm != 0.0 or any(v != 0.0 for v in self.channel_delay_s.values())

    @property
    def clock(self) -> float:
        """True sample interval / nominal one [-]."""
        return 1.0 + 1e-6 * self.clock_ppm


# ------------------------------------------------------------------------------------------------- filters
@dataclass(frozen=True)
class AnalogFilter:
    """A proper analog filter G(s) = k prod(s - z) / prod(s - p) with distinct poles: poles, residues of its
    strictly proper part, direct term D."""

    zeros: np.ndarray
    poles: np.ndarray
    gain: float

    @property
    def direct(self) -> float:
        return float(np.real(self.gain)) if self.zeros.size == self.poles.size else 0.0

    def residues(self) -> np.ndarray:
        p, z = self.poles, self.zeros
        out = np.empty(p.size, dtype=complex)
        for i, pi in enumerate(p):
            out[i] = self.gain * np.prod(pi - z) / np.prod(pi - np.delete(p, i))
        return out

    def response(self, f_hz) -> np.ndarray:
        """G(j 2 pi f)."""
        _, h = sps.freqs_zpk(self.zeros, self.poles, self.gain, 2.0 * np.pi * np.atleast_1d(f_hz))
        return h

    def dc_delay(self) -> float:
        """Group delay at DC [s]: sum Re(1/z) - sum Re(1/p)."""
        return float(np.sum(np.real(1.0 / self.zeros)) - np.sum(np.real(1.0 / self.poles)))

    def settle_s(self) -> float:
        """Time for the slowest pole to decay by 1e-12 [s]."""
        return 28.0 / float(np.min(-np.real(self.poles)))

    def cascade(self, other: "AnalogFilter") -> "AnalogFilter":
        return AnalogFilter(np.concatenate([self.zeros, other.zeros]), np.concatenate([self.poles, other.poles]),
                            self.gain * other.gain)


@dataclass(frozen=True)
class FirFilter:
    """A linear-phase FIR on the modulator's stream at rate ``oversample`` x fs."""

    taps: np.ndarray
    rate_hz: float

    def dc_delay(self) -> float:
        return (self.taps.size - 1) / 2.0 / self.rate_hz

    def response(self, f_hz) -> np.ndarray:
        _, h = sps.freqz(self.taps, 1.0, worN=np.atleast_1d(f_hz), fs=self.rate_hz)
        return h

    def settle_s(self) -> float:
        return self.taps.size / self.rate_hz


def design(chain: DaqChain, fs: float) -> AnalogFilter | FirFilter | None:
    """The chain's filter at sample rate fs [Hz] (cut-off chain.cutoff x fs)."""
    fc = chain.cutoff * fs
    wc = 2.0 * math.pi * fc
    if chain.filter == "butter":
        z, p, k = sps.butter(chain.order, wc, analog=True, output="zpk")
    elif chain.filter == "ellip":
        z, p, k = sps.ellip(chain.order, chain.ripple_db, chain.stop_db, wc, analog=True, output="zpk")
        k = k / abs(np.prod(-z) / np.prod(-p) * k)       # a calibrated channel: gain 1 at DC (even orders: not)
    elif chain.filter == "fir":
        rate = chain.oversample * fs
        n = chain.order
        if n <= 0:
            n, _ = sps.kaiserord(chain.stop_db, (0.5 - chain.cutoff) * fs / (rate / 2.0))
        n += (n + 1) % 2                                # odd: the delay is a whole number of grid steps
        beta = sps.kaiser_beta(chain.stop_db)
        # cut-off halfway through the transition band (fc .. fs/2), so the pass band holds up to fc
        taps = sps.firwin(n, 0.5 * (fc + 0.5 * fs), window=("kaiser", beta), fs=rate)
        return FirFilter(np.asarray(taps), rate)
    else:
        return None
    return AnalogFilter(np.asarray(z, dtype=complex), np.asarray(p, dtype=complex), float(np.real(k)))


def declared_filter(chain: DaqChain, filt, fs: float) -> str:
    """The ``daq_filter`` string of a run (module docstring)."""
    fc = chain.cutoff * fs
    if filt is None:
        return "none"
    if isinstance(filt, FirFilter):
        return f"fir:{filt.taps.size}:{fc:g}:{chain.oversample}"
    if chain.filter == "ellip":
        return f"ellip:{chain.order}:{fc:g}:{chain.ripple_db:g}:{chain.stop_db:g}"
    return f"{chain.filter}:{chain.order}:{fc:g}"


def mount_filter(fr_hz: float, zeta_r: float) -> AnalogFilter:
    """The resonant mount of ``outside.mount_resonance`` as a filter on the true acceleration."""
    wr = 2.0 * math.pi * fr_hz
    return AnalogFilter(np.zeros(0, dtype=complex), np.roots([1.0, 2.0 * zeta_r * wr, wr * wr]).astype(complex),
                        wr * wr)


def _first_order(u: np.ndarray, h: float, p: complex, drive: complex) -> np.ndarray:
    """x' = p x + drive u on a uniform grid of step h [s], u linear between the points, x settled on u[0]."""
    lam = np.exp(p * h)
    alpha = (lam - 1.0) / p
    beta = (lam - 1.0 - p * h) / (p * p)
    b0, b1 = drive * beta / h, drive * (alpha - beta / h)
    x0 = -drive * u[0] / p
    zi = np.array([lam * x0 + b1 * u[0]])             # lfilter's state after the settled point before u[0]
    y, _ = sps.lfilter([b0, b1], [1.0, -lam], u.astype(complex), zi=zi)
    return y


JUMP_SUB = 64
"""Points per grid step on which a step holding a jump is refined (``jump_cells``)."""


def jump_cells(u: np.ndarray, factor: float = 10.0) -> np.ndarray:
    """Grid steps j (u[j] -> u[j+1]) holding a jump: a change ``factor`` times both neighbours' and above 1e-6 of
    the signal's range (a contact force's onset through a damper)."""
    d = np.abs(np.diff(u))
    nb = np.maximum(np.concatenate([[0.0], d[:-1]]), np.concatenate([d[1:], [0.0]]))
    return np.flatnonzero((d > factor * nb) & (d > 1e-6 * max(float(np.ptp(u)), 1e-300)))


def _kicks(u: np.ndarray, h: float, p: complex, cells: np.ndarray, u_sub: np.ndarray) -> np.ndarray:
    """The state x' = p x + u gains at the end of each refined step: the response to (input on the step's
    ``JUMP_SUB`` sub-points, linear between them) minus (the straight line the grid assumes)."""
    s = u_sub.shape[1] - 1
    frac = np.arange(s + 1) / s
    d = u_sub - (u[cells, None] + (u[cells + 1] - u[cells])[:, None] * frac[None, :])
    d[:, 0] = d[:, -1] = 0.0
    hs = h / s
    lam = np.exp(p * hs)
    alpha = (lam - 1.0) / p
    beta = (lam - 1.0 - p * hs) / (p * p)
    b0, b1 = beta / hs, alpha - beta / hs
    x = np.zeros(cells.size, dtype=complex)
    for m in range(s):
        x = lam * x + b0 * d[:, m + 1] + b1 * d[:, m]
    return x


def analog_filter(filt: AnalogFilter, u: np.ndarray, h: float, cells: np.ndarray | None = None,
                  u_sub: np.ndarray | None = None) -> np.ndarray:
    """The filter's output on the grid for the input u (linear between points), settled on u[0]; grid steps
    ``cells`` (``jump_cells``) are taken as linear between the ``u_sub`` values (rows: u at t_j + k h / JUMP_SUB,
    k = 0..JUMP_SUB) instead."""
    y = filt.direct * u
    for p, r in zip(filt.poles, filt.residues()):
        x = _first_order(u, h, p, 1.0)
        if cells is not None and cells.size:
            seq = np.zeros(u.size, dtype=complex)
            np.add.at(seq, cells + 1, _kicks(u, h, p, cells, u_sub))
            x = x + sps.lfilter([1.0], [1.0, -np.exp(p * h)], seq)
        y = y + r * x
    return np.real(y)


def analog_filter_of_rate(filt: AnalogFilter, v: np.ndarray, a: np.ndarray, h: float) -> np.ndarray:
    """G acting on a = v' from the samples of v (linear between points) and a (for the direct term only):
    per mode x' = p x + a, w = x - v, w' = p w + p v; y = D a + sum r (w + v)."""
    r = filt.residues()
    y = filt.direct * a + np.real(np.sum(r)) * v
    for p, ri in zip(filt.poles, r):
        # w settled on v[0] with the rig at rest: x = 0 (a = 0) -> w = -v[0]; _first_order settles w on
        # -p v[0] / p = -v[0]: the same
        y = y + ri * _first_order(v, h, p, p)
    return np.real(y)


def fir_filter(filt: FirFilter, u: np.ndarray) -> np.ndarray:
    """The FIR's output on the stream u (its history before u[0] held at u[0])."""
    n = filt.taps.size
    ext = np.concatenate([np.full(n - 1, u[0]), u])
    return sps.oaconvolve(ext, filt.taps, mode="valid")


# ------------------------------------------------------------------------------------------------ hum, ADC
def hum_phases(chain: DaqChain, rng: np.random.Generator) -> dict:
    """Random phases [rad] of every hum harmonic, per channel."""
    return {ch: [float(x) for x in rng.uniform(0.0, 2.0 * math.pi, len(amps))] for ch, amps in chain.hum.items()}


def hum_at(chain: DaqChain, channel: str, phases: list, t: np.ndarray, filt=None) -> np.ndarray:
    """Hum on ``channel`` at true times t [s], through the filter in steady state."""
    out = np.zeros_like(t)
    for k, (a, ph) in enumerate(zip(chain.hum.get(channel, ()), phases), start=1):
        f = k * chain.hum_hz
        g = complex(filt.response(f)[0]) if filt is not None else 1.0 + 0.0j
        out += a * abs(g) * np.sin(2.0 * math.pi * f * t + ph + np.angle(g))
    return out


def adc(x: np.ndarray, rng_: float, bits: int | None) -> np.ndarray:
    """Saturate at +-rng_ (those samples exactly +-rng_), then quantise over the full scale +-rng_."""
    y = np.clip(x, -rng_, rng_)
    if bits:
        lsb = 2.0 * rng_ / 2 ** bits
        y = np.clip(np.round(y / lsb) * lsb, -rng_, rng_)
    return y


def runs_columns(chain: DaqChain, filt, fs: float) -> dict:
    """The runs.csv columns a DAQ declares for a run ({} when undeclared)."""
    if not chain.declared:
        return {}
    return {"daq_filter": declared_filter(chain, filt, fs),
            "daq_delay_s": 0.0 if filt is None else filt.dc_delay(),
            "daq_delay_removed": int(bool(chain.compensated and filt is not None)),
            "daq_clock_ppm": chain.clock_ppm}


DAQ_CHAINS: dict[str, DaqChain] = {
    # an 8th-order Butterworth at 0.45 fs (a DSA card's analog front end), delay left in the data
    "butter8": DaqChain("butter8", filter="butter", order=8, cutoff=0.45),
    # the same, aligned by the DAQ software (DC group delay removed from the time stamps)
    "butter8-comp": DaqChain("butter8-comp", filter="butter", order=8, cutoff=0.45, compensated=True),
    # a 6th-order elliptic at 0.4 fs, 0.1 dB ripple, 80 dB stop band
    "ellip6": DaqChain("ellip6", filter="ellip", order=6, cutoff=0.4),
    # a delta-sigma ADC's linear-phase decimation filter at 16 x fs
    "fir": DaqChain("fir", filter="fir", order=0, cutoff=0.45),
    # the Butterworth, undeclared, with a 50 ppm clock
    "butter8-undeclared": DaqChain("butter8-undeclared", filter="butter", order=8, cutoff=0.45, clock_ppm=50.0,
                                   declared=False),
    # a sample clock 80 ppm slow, nothing else
    "clock80": DaqChain("clock80", clock_ppm=80.0),
    # the accelerometer saturates at 80 % of its record's peak
    "clip80": DaqChain("clip80", clip_fraction={"accel_m_s2": 0.8}),
    # 50 Hz hum with its 2nd and 3rd harmonics on the force channel
    "hum50": DaqChain("hum50", hum_hz=50.0, hum={"force_n": (5.0, 2.0, 1.0)}),
    # all of it: a field chain
    "field": DaqChain("field", filter="butter", order=8, cutoff=0.45, clock_ppm=50.0,
                      clip_fraction={"accel_m_s2": 0.85}, hum_hz=50.0, hum={"force_n": (5.0, 2.0, 1.0)}),
    # the field chain without its clipping, and without its hum: what each part costs
    "field-noclip": DaqChain("field-noclip", filter="butter", order=8, cutoff=0.45, clock_ppm=50.0, hum_hz=50.0,
                             hum={"force_n": (5.0, 2.0, 1.0)}),
    "field-nohum": DaqChain("field-nohum", filter="butter", order=8, cutoff=0.45, clock_ppm=50.0,
                            clip_fraction={"accel_m_s2": 0.85}),
}
"""Named chains (the identification matrix's, and ``--daq NAME`` of the generator's command)."""
