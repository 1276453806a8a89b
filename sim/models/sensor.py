"""MODELS.md §6 ``sensor_lowpass``: the accelerometer's bandwidth, applied to a run's recorded acceleration.

The measured acceleration is the true one through the continuous-time 2nd-order Butterworth low-pass
H(s) = ωc² / (s² + √2 ωc s + ωc²), ωc = 2π fc.  It changes no dynamics, only what is observed, so it is applied
to the time history after the run.  The filter is run on the impacting mass's *velocity* (continuous: a contact's
force jump is only a kink in it) and its output is the filtered derivative — H(s)·a = (s H(s))·v, the rate state of
the same filter — discretised exactly for a velocity linear between samples (first-order hold): second-order in
the sampling step across an impact, where filtering the acceleration itself (which jumps at a contact's onset)
would be first-order.

Start of the filter: a run from rest (no transient cycles and no initial state) and a history at chosen times
(``simulate(history_times=...)``) start it from rest at the first sample; a steady-state window sampled uniformly
(whole cycles) is taken to repeat, and the filter is started in its periodic steady state.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from sim.jit import njit
from sim.layout import G_ACCEL as G   # [m/s²] per g: the project's one value


def warmup_s(fc: float) -> float:
    """How long the low-pass at ``fc`` [Hz] takes to forget its start [s]: 30 time constants of its envelope,
    1/(ζ ωc) with ζ = 1/√2 (e^-30 ~ 1e-13); 0 for fc = 0 (no filter)."""
    return 30.0 / (math.sqrt(0.5) * 2.0 * math.pi * fc) if fc and fc > 0 else 0.0


def _discrete(fc: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Φ, B, D) of the filter sampled every ``dt`` [s] for an input linear between samples (first-order hold),
    output the rate of the Butterworth state x = (z, ż): w[n+1] = Φ w[n] + B u[n], y[n] = w1[n] + D u[n], with
    w = x − Γ1 u[n] and x[n+1] = Φ x[n] + Γ0 u[n] + Γ1 u[n+1] from the matrix exponential of the system
    augmented by the input's ramp.  Returns (Φ, B, Γ1); D = Γ1[1]."""
    from scipy.linalg import expm

    wc = 2.0 * math.pi * fc
    m = np.zeros((4, 4))
    m[:2, :2] = np.array([[0.0, 1.0], [-wc * wc, -math.sqrt(2.0) * wc]]) * dt
    m[1, 2] = wc * wc * dt
    m[2, 3] = 1.0                    # u(t) = u[n] + (u[n+1] - u[n]) (t - t_n)/dt: the increment is a state
    e = expm(m)
    phi, gu, gs = e[:2, :2], e[:2, 2], e[:2, 3]
    g0, g1 = gu - gs, gs             # x[n+1] = Φ x[n] + gu u[n] + gs (u[n+1] - u[n])
    return phi, phi @ g1 + g0, g1


@njit(cache=True, nogil=True)
def _state_space(phi: np.ndarray, b: np.ndarray, d: float, u: np.ndarray, w0: np.ndarray, y: np.ndarray) -> np.ndarray:
    """y[n] = w1[n] + d u[n] with w[n+1] = Φ w[n] + B u[n] from w[0] = ``w0``, written into ``y``; returns w[N]."""
    p00, p01, p10, p11 = phi[0, 0], phi[0, 1], phi[1, 0], phi[1, 1]
    b0, b1 = b[0], b[1]
    s0, s1 = w0[0], w0[1]
    for n in range(u.size):
        un = u[n]
        y[n] = s1 + d * un
        s0, s1 = p00 * s0 + p01 * s1 + b0 * un, p10 * s0 + p11 * s1 + b1 * un
    out = np.empty(2)
    out[0] = s0
    out[1] = s1
    return out


def _response(phi: np.ndarray, b: np.ndarray, d: float, u: np.ndarray,
              w0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Output y[0..N-1] (the rate state) for inputs u from state w0, and the state w[N] (the recursion itself,
    compiled: a few ns a sample)."""
    y = np.empty(u.size)
    w_n = _state_space(np.ascontiguousarray(phi), np.ascontiguousarray(b), float(d),
                       np.ascontiguousarray(u, dtype=np.float64), np.asarray(w0, dtype=np.float64), y)
    return y, w_n


def lowpass_rate(v: np.ndarray, dt: float, fc: float, periodic: bool) -> np.ndarray:
    """The acceleration v̇ through the Butterworth low-pass at ``fc`` [Hz], from the velocity ``v`` sampled every
    ``dt`` [s]: from rest at the first sample, or (``periodic``) in the periodic steady state of ``v`` repeated end
    to end (the state after one repetition equals the state at its start: w0 = (I − Φ^N)^-1 w_forced[N]).  A
    periodic velocity may carry an offset (drift is not periodic: give a steady-state window of a bounded motion)."""
    phi, b, g1 = _discrete(fc, dt)
    d = float(g1[1])
    if not periodic:            # at rest: x[0] = 0, so w[0] = −Γ1 v[0]
        return _response(phi, b, d, v, -g1 * v[0])[0]
    _, w_n = _response(phi, b, d, v, np.zeros(2))
    w0 = np.linalg.solve(np.eye(2) - np.linalg.matrix_power(phi, v.size), w_n)
    return _response(phi, b, d, v, w0)[0]


def sensor_lowpass(res):
    """``ModelSpec.postprocess`` of every model with ``fc``: the measured acceleration (history ``accel_m_s2``,
    the true one kept as ``accel_true_m_s2``) and ``peak_decel_g`` of the low-passed signal; a run without a
    history is simulated again with one (400 samples per cycle at least)."""
    fc = res.params.get("fc", 0.0)
    if not fc or res.labels["status"] in ("runaway", "failed"):
        return res
    from sim.api import simulate

    hist = res.columns
    from_rest = res.labels.get("transient_cycles", 0) == 0 and res.initial_state is None
    if hist is None:
        settings = replace(res.settings, samples_per_cycle=max(res.settings.samples_per_cycle, 400))
        full = simulate(res.model, settings=settings, history=True, initial_state=res.initial_state,
                        **{**res.params, "fc": 0.0})
        hist = full.columns
    t = np.asarray(hist["t_s"])
    if t.size < 3:
        return res
    dt = float(t[1] - t[0])
    if not np.allclose(np.diff(t), dt, rtol=1e-6, atol=0.0):
        raise ValueError("sensor_lowpass needs a uniformly sampled history")
    a = np.asarray(hist["accel_true_m_s2"] if "accel_true_m_s2" in hist else hist["accel_m_s2"])
    periodic = not from_rest and res.history_times is None
    filt = lowpass_rate(np.asarray(hist["vel_m_s"]), dt, float(fc), periodic)
    res.labels["peak_decel_g"] = float(max(-filt.min(), 0.0) / G)
    if res.columns is not None:
        res.set_column("accel_true_m_s2", a)
        res.set_column("accel_m_s2", filt)
    return res
