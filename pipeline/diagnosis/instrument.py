"""What the recording does to the model's harmonic features (measured = instrument(plant(θ), φ)).

The features of a series run are the complex coefficients c_k of harmonic k of every signal (``features``).  A
linear time-invariant element of the chain multiplies c_k by its frequency response at k f: a declared filter by
H(i k Ω) (``pipeline.datasets.daq``), a delay τ by exp(−i k Ω τ).  A clock error ε dates a sample at record time t
that was taken at (1 + ε) t: harmonic k turns by k Ω ε t over the record, which the least-squares fit over a
stretch of length T around t̄ sees as exp(i k Ω ε t̄) · sinc(k Ω ε T / 2).  Both are exact for a steady state; for
a record from rest they neglect the change of the harmonics' amplitudes over τ or ε T (microseconds against a
transient of tenths of a second).  A declared delay and clock are applied exactly instead, by sampling the model at
the true instants (``features.sampling_plan``); the rotation here serves the undeclared chain (``Nuisance``),
estimated beside the calibration (``pipeline.diagnosis.nuisance``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def channel(tg, sig: str) -> tuple[str, float]:
    """The identity of a delay: the signal and the run's sampling rate [Hz] (a DAQ's anti-alias filter follows the
    rate it samples at, so runs at another rate have another delay)."""
    return sig, round(float(tg.fs_hz), 3)


@dataclass(frozen=True)
class Nuisance:
    """An undeclared chain: a delay per channel [s] (``delays``: (``channel``, τ) pairs) and a clock error ε [-]."""

    delays: tuple[tuple[tuple[str, float], float], ...] = ()
    clock: float = 0.0

    def delay(self, key: tuple[str, float]) -> float:
        return dict(self.delays).get(key, 0.0)


def rotation(kw: np.ndarray, tau: np.ndarray, eps: float, tbar: float, span: float) -> np.ndarray:
    """Complex gain of a delay ``tau`` (per pair) and a clock error ``eps`` on harmonics of angular frequency ``kw``
    fitted over a stretch of length ``span`` around record time ``tbar``."""
    return np.sinc(kw * eps * span / (2.0 * np.pi)) * np.exp(1j * kw * (eps * tbar - tau))


def instrument_gain(tg, part: int = 0) -> np.ndarray | None:
    """Complex gain of every harmonic pair of ``tg``'s features (``part`` 0: the whole record, 1 and 2: its halves):
    the declared filter's response and the undeclared chain's rotation; None when there is neither."""
    g = tg.filter_gain
    if tg.nuisance is not None and tg.pairs:
        tau = np.array([tg.nuisance.delay(channel(tg, s)) for s, _ in tg.pairs])
        r = rotation(tg.pair_kw, tau, tg.nuisance.clock, *tg.spans[part])
        g = r if g is None else g * r
    return g


def apply_gain(feats: np.ndarray, at: np.ndarray, g: np.ndarray | None) -> np.ndarray:
    """``feats`` with the complex pair (re at ``at``, im after it) multiplied by ``g``."""
    if g is None or feats is None:
        return feats
    out = np.array(feats, dtype=float, copy=True)
    z = (out[at] + 1j * out[at + 1]) * g
    out[at], out[at + 1] = z.real, z.imag
    return out
