"""Peer implementation of the drill model (MODELS.md §2) with heyoka.py: Taylor integrator with events.

One ``taylor_adaptive`` integrator holds all three phases; the phase is a one-hot triple of runtime
parameters (s1, s2, s3) in the right-hand side, so a single LLVM compilation serves every phase and
every parameter point.  Every switching surface of the table in MODELS.md §2 is a *terminal* event
(``t_event``) gated by its phase flag (the gated function is a nonzero constant in the other phases,
so it cannot fire there); heyoka locates the crossing on the Taylor polynomial of the step, the
callback classifies the state (``bench.drill_classify``, the same rule and hysteresis as the
reference), flips the flags, sets xt = x1 on contact and returns True: integration restarts on the
new branch.  The transient/window boundary is a time event.  Labels over the window come from the
event machinery too: maxima of the contact force (phase II) and of the deceleration of M1 are
*non-terminal* events on dP/dt = 0 and on the jerk = 0 (active in the window only), evaluated on
heyoka's dense output; jumps at the switches and the window ends are checked explicitly.

Because all of this lives in one integrator that runs a point from start to end in one
``propagate_until`` call, the ensemble mode (``ensemble_propagate_until``, threads over copies of
the integrator) applies directly.  The callbacks are Python: they take the GIL, which limits the
ensemble's thread scaling (a few switches and extrema per cycle).
Accumulators (onsets, peak force, peak deceleration, xb and W at the window start) are stored in
spare runtime parameters, so they travel with each ensemble copy.
"""
from __future__ import annotations

import math
import time

import numpy as np

from bench import ETA_X, G_ACC, drill_classify, drill_values as values  # noqa: F401 -- values: the peers' interface

# runtime parameter layout
(P_M1, P_M2, P_M3, P_K1, P_K2, P_K3, P_C1, P_C2, P_C3, P_PR, P_F0, P_FS, P_OM,
 P_S1, P_S2, P_S3, P_REC, P_TWIN, P_ONSETS, P_PEAKF, P_DECEL, P_XB0, P_W0, P_ZERO) = range(24)
NPARS = 24
COOLDOWN_S = 1e-9      # [s] terminal-event cooldown: heyoka's automatic one (cooldown=-1) grows with tol and at
#                        tol >= 1e-8 swallowed the release event after II -> III (the bit never left the rock:
#                        label error 0.94); 1 ns is far below any phase duration, and the hysteresis ETA_X / eP
#                        keeps a surface from re-firing at the restart


def _pdict(pars) -> dict:
    return {"M1": pars[P_M1], "M2": pars[P_M2], "M3": pars[P_M3], "K1": pars[P_K1], "K2": pars[P_K2],
            "K3": pars[P_K3], "C1": pars[P_C1], "C2": pars[P_C2], "C3": pars[P_C3], "Pr": pars[P_PR],
            "amplitude_n": pars[P_F0], "static_force_n": pars[P_FS], "frequency_hz": pars[P_OM] / (2 * math.pi)}


def _phase(pars) -> int:
    return 0 if pars[P_S1] == 1.0 else (1 if pars[P_S2] == 1.0 else 2)


def _force(pars, y, ph) -> float:
    if ph == 0:
        return 0.0
    if ph == 1:
        return pars[P_K1] * (y[0] - y[7]) + pars[P_C1] * y[1]
    return pars[P_PR]


def _decel(pars, t, y, ph) -> float:
    """-(acceleration of M1) at absolute time t."""
    pc = _force(pars, y, ph)
    a1 = (pars[P_F0] * math.cos(pars[P_OM] * t) - pars[P_C2] * (y[1] - y[3]) - pars[P_K2] * (y[0] - y[2]) - pc) / pars[P_M1]
    return -a1


def _set_phase(pars, ph: int) -> None:
    pars[P_S1] = 1.0 if ph == 0 else 0.0
    pars[P_S2] = 1.0 if ph == 1 else 0.0
    pars[P_S3] = 1.0 if ph == 2 else 0.0


def _record_point(ta, ph: int) -> None:
    pars, y, t = ta.pars, ta.state, ta.time
    pars[P_DECEL] = max(pars[P_DECEL], _decel(pars, t, y, ph))
    if ph:
        pars[P_PEAKF] = max(pars[P_PEAKF], _force(pars, y, ph))


def _switch_cb(ta, d_sgn) -> bool:
    pars, y = ta.pars, ta.state
    old = _phase(pars)
    rec = pars[P_REC] == 1.0
    if rec:
        _record_point(ta, old)
    new = drill_classify(_pdict(pars), ta.time, y)
    if new:
        y[6] = y[0]          # the plate rides on the bit
    if new != old:
        _set_phase(pars, new)
        if rec and old == 0:
            pars[P_ONSETS] += 1.0
    if rec:
        _record_point(ta, new)
    return True


def _window_cb(ta, d_sgn) -> bool:
    pars, y = ta.pars, ta.state
    pars[P_REC] = 1.0
    pars[P_XB0] = y[7]
    pars[P_W0] = y[8]
    _record_point(ta, _phase(pars))
    return True


def _peak_force_cb(ta, t, d_sgn) -> None:
    y = ta.update_d_output(t)
    pars = ta.pars
    pars[P_PEAKF] = max(pars[P_PEAKF], _force(pars, y, 1))


def _decel_cb(ta, t, d_sgn) -> None:
    y = ta.update_d_output(t)
    pars = ta.pars
    pars[P_DECEL] = max(pars[P_DECEL], _decel(pars, t, y, _phase(pars)))


def build(tol: float | None = None, compact_mode: bool = False, cooldown: float = COOLDOWN_S):
    """Compile the integrator (returns it and the wall time of the LLVM compilation).  ``cooldown`` [s]: the
    terminal events' cooldown (heyoka's automatic one grows with ``tol``; see :data:`COOLDOWN_S`)."""
    import heyoka as hy

    x1, v1, x2, v2, x3, v3, xt, xb, W = hy.make_vars("x1", "v1", "x2", "v2", "x3", "v3", "xt", "xb", "W")
    par = hy.par
    M1, M2, M3, K1, K2, K3, C1, C2, C3, Pr, F0, Fs, Om = (par[i] for i in range(13))
    s1, s2, s3, rec, twin = par[P_S1], par[P_S2], par[P_S3], par[P_REC], par[P_TWIN]
    P = K1 * (x1 - xb) + C1 * v1
    Pc = s2 * P + s3 * Pr
    F = F0 * hy.cos(Om * hy.time)
    s12 = C2 * (v1 - v2) + K2 * (x1 - x2)
    s23 = C3 * (v2 - v3) + K3 * (x2 - x3)
    a1 = (F - s12 - Pc) / M1
    a2 = (Fs + s12 - s23) / M2
    sys = [(x1, v1), (v1, a1), (x2, v2), (v2, a2), (x3, v3), (v3, s23 / M3),
           (xt, s1 * (-(K1 / C1) * (xt - xb)) + (s2 + s3) * v1),
           (xb, s3 * (P - Pr) / C1),
           (W, F * v1)]
    eP = 1e-10 * Pr
    neg, pos = hy.event_direction.negative, hy.event_direction.positive
    t_events = [
        hy.t_event(s1 * (x1 - xt - ETA_X) + (1.0 - s1) * (-1.0), callback=_switch_cb, direction=pos, cooldown=cooldown),   # I -> II/III
        hy.t_event(s2 * (P + eP) + (1.0 - s2), callback=_switch_cb, direction=neg, cooldown=cooldown),                  # II -> I
        hy.t_event(s2 * (P - Pr - eP) + (1.0 - s2) * (-1.0), callback=_switch_cb, direction=pos, cooldown=cooldown),    # II -> III
        hy.t_event(s3 * (P - Pr + eP) + (1.0 - s3), callback=_switch_cb, direction=neg, cooldown=cooldown),             # III -> II
        # window start; the spare accumulator parameters ride along (times par[P_ZERO] = 0) so heyoka
        # sizes the parameter array to hold them
        hy.t_event(hy.time - twin + par[P_ZERO] * (par[P_ONSETS] + par[P_PEAKF] + par[P_DECEL]
                                                    + par[P_XB0] + par[P_W0]),
                   callback=_window_cb, direction=pos),
    ]
    # dP/dt in phase II and the jerk of M1 (for maxima of the contact force and of the deceleration)
    a1_ii = (F - s12 - P) / M1
    dP = K1 * v1 + C1 * a1_ii
    jerk = (-F0 * Om * hy.sin(Om * hy.time) - C2 * (a1 - a2) - K2 * (v1 - v2) - s2 * dP) / M1
    nt_events = [
        hy.nt_event(rec * s2 * dP + (1.0 - rec * s2), callback=_peak_force_cb, direction=neg),
        hy.nt_event(rec * jerk + (1.0 - rec), callback=_decel_cb, direction=pos),   # a1 minimum = decel max
    ]
    kw = {} if tol is None else {"tol": tol}
    t0 = time.perf_counter()
    ta = hy.taylor_adaptive(sys, np.zeros(9), pars=np.zeros(NPARS), t_events=t_events, nt_events=nt_events,
                            compact_mode=compact_mode, **kw)
    return ta, time.perf_counter() - t0


def _setup(ta, p: dict, transient: int, window: int) -> float:
    """Reset ``ta`` to the rest state of point ``p``; returns the end time."""
    T = 1.0 / p["frequency_hz"]
    pars = np.zeros(NPARS)
    pars[:13] = [p["M1"], p["M2"], p["M3"], p["K1"], p["K2"], p["K3"], p["C1"], p["C2"], p["C3"], p["Pr"],
                 p["amplitude_n"], p["static_force_n"], 2.0 * math.pi * p["frequency_hz"]]
    pars[P_TWIN] = transient * T if transient > 0 else 0.5 * T * 1e-9   # window start (tiny > 0 for 0 cycles)
    G = p["gap_m"]
    y = np.array([0, 0, 0, 0, 0, 0, G, G, 0.0])
    ph = drill_classify(p, 0.0, y)
    _set_phase(pars, ph)
    if ph:
        y[6] = y[0]
    ta.pars[:] = pars
    ta.state[:] = y
    ta.time = 0.0
    ta.reset_cooldowns()
    return (transient + window) * T


def _labels(ta, window: int, T: float) -> dict:
    pars, y = ta.pars, ta.state
    ph = _phase(pars)
    _record_point(ta, ph)        # window end
    dur = window * T
    return {"rop_m_s": (y[7] - pars[P_XB0]) / dur, "peak_force_n": float(pars[P_PEAKF]),
            "impacts_per_cycle": float(pars[P_ONSETS]) / window, "peak_decel_g": float(pars[P_DECEL]) / G_ACC,
            "energy_per_cycle_j": (y[8] - pars[P_W0]) / window}


def run_point(ta, p: dict, transient: int, window: int) -> dict:
    """Labels of one point (``p`` from :func:`bench.drill_values`) with the compiled integrator ``ta``."""
    t_end = _setup(ta, p, transient, window)
    out = ta.propagate_until(t_end)
    if ta.time < t_end * (1 - 1e-12):
        raise RuntimeError(f"heyoka stopped early: {out[0]}")
    return _labels(ta, window, 1.0 / p["frequency_hz"])


def run_ensemble(ta, points: list[dict], transient: int, window: int) -> list[dict]:
    """All points in heyoka's ensemble mode (threads over copies of ``ta``).  Every point must share the
    frequency (ensemble_propagate_until takes one end time); callers group points by frequency."""
    import heyoka as hy

    f = points[0]["frequency_hz"]
    if any(q["frequency_hz"] != f for q in points):
        raise ValueError("ensemble: one frequency per call")
    t_end = (transient + window) / f

    def gen(tcopy, i):
        _setup(tcopy, points[i], transient, window)
        return tcopy

    res = hy.ensemble_propagate_until(ta, t_end, len(points), gen)
    return [_labels(r[0], window, 1.0 / f) for r in res]
