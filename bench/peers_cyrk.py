"""Peer implementation of the drill model (MODELS.md §2) with CyRK (compiled Runge-Kutta, C++ core).

What is used, and why: CyRK's numba interface (``nbsolve_ivp`` / ``nbsolve2_ivp``) does **not** support
events in 0.20 ("Events not currently supported by nbsolve_ivp" in its source), and a phase-switching
model needs its switching surfaces located.  ``pysolve_ivp`` does support SciPy-style events with
``terminal`` and ``direction`` (root-found by CyRK's C++ solver), so the peer is ``pysolve_ivp`` with a
numba-jitted right-hand side (``pass_dy_as_arg=True``) and numba-jitted event functions, driven
segment by segment: integrate the current phase with the terminal events of its switching surfaces;
at a terminal event take the event state, classify it (``bench.drill_classify``: the same rule and
hysteresis as the reference), set xt = x1 on contact, restart on the new branch.  The transient /
window boundary is a segment end.  In the window, non-terminal events on dP/dt = 0 (phase II) and on
the jerk of M1 = 0 give the maxima of the contact force and of the deceleration from CyRK's event
states; jumps at switches and the window ends are checked explicitly.

Solver settings mirror the jitted simulator's: RK45 (Dormand-Prince 5(4), the same pair), rtol 1e-8,
atol = rtol x 1e-3 x state scale (positions 1 mm, velocities 1 mm x Omega), max step T / 50.
The right-hand side and events are called from C++ through Python (CyRK's PySolver hooks): that
per-call overhead, not the arithmetic, dominates.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench import ETA_X, segment_loop

# parameter vector: M1 M2 M3 K1 K2 K3 C1 C2 C3 Pr F0 Fs Om


def _pvec(p: dict) -> np.ndarray:
    return np.array([p["M1"], p["M2"], p["M3"], p["K1"], p["K2"], p["K3"], p["C1"], p["C2"], p["C3"], p["Pr"],
                     p["amplitude_n"], p["static_force_n"], 2.0 * math.pi * p["frequency_hz"]])


@njit(cache=True)
def _pc(y, q, ph):
    if ph == 0:
        return 0.0
    if ph == 1:
        return q[3] * (y[0] - y[7]) + q[6] * y[1]
    return q[9]


@njit(cache=True)
def diffeq(dy, t, y, q, ph):
    F = q[10] * math.cos(q[12] * t)
    pc = _pc(y, q, ph)
    s12 = q[7] * (y[1] - y[3]) + q[4] * (y[0] - y[2])
    s23 = q[8] * (y[3] - y[5]) + q[5] * (y[2] - y[4])
    dy[0] = y[1]
    dy[1] = (F - s12 - pc) / q[0]
    dy[2] = y[3]
    dy[3] = (q[11] + s12 - s23) / q[1]
    dy[4] = y[5]
    dy[5] = s23 / q[2]
    if ph == 0:
        dy[6] = -(q[3] / q[6]) * (y[6] - y[7])
        dy[7] = 0.0
    elif ph == 1:
        dy[6] = y[1]
        dy[7] = 0.0
    else:
        dy[6] = y[1]
        dy[7] = (q[3] * (y[0] - y[7]) + q[6] * y[1] - q[9]) / q[6]
    dy[8] = F * y[1]


@njit(cache=True)
def ev_touch(t, y, q, ph):            # I -> II/III
    return y[0] - y[6] - ETA_X


@njit(cache=True)
def ev_release(t, y, q, ph):          # II -> I
    return q[3] * (y[0] - y[7]) + q[6] * y[1] + 1e-10 * q[9]


@njit(cache=True)
def ev_progress(t, y, q, ph):         # II -> III
    return q[3] * (y[0] - y[7]) + q[6] * y[1] - q[9] - 1e-10 * q[9]


@njit(cache=True)
def ev_stop(t, y, q, ph):             # III -> II
    return q[3] * (y[0] - y[7]) + q[6] * y[1] - q[9] + 1e-10 * q[9]


@njit(cache=True)
def _accels(t, y, q, ph):
    F = q[10] * math.cos(q[12] * t)
    s12 = q[7] * (y[1] - y[3]) + q[4] * (y[0] - y[2])
    s23 = q[8] * (y[3] - y[5]) + q[5] * (y[2] - y[4])
    a1 = (F - s12 - _pc(y, q, ph)) / q[0]
    a2 = (q[11] + s12 - s23) / q[1]
    return a1, a2


@njit(cache=True)
def ev_force_max(t, y, q, ph):        # dP/dt in phase II
    a1, a2 = _accels(t, y, q, 1)
    return q[3] * y[1] + q[6] * a1


@njit(cache=True)
def ev_decel_max(t, y, q, ph):        # jerk of M1 (a minimum of a1 = maximum deceleration)
    a1, a2 = _accels(t, y, q, ph)
    dpc = q[3] * y[1] + q[6] * a1 if ph == 1 else 0.0
    return (-q[10] * q[12] * math.sin(q[12] * t) - q[7] * (a1 - a2) - q[4] * (y[1] - y[3]) - dpc) / q[0]


def _ev(f, terminal, direction):
    """Mark a jitted event function as CyRK/SciPy expect (attributes on the dispatcher: no Python wrapper)."""
    f.terminal = terminal
    f.direction = direction
    return f


# per phase: terminal switching events; window-only non-terminal extrema events
_SWITCH = {0: [_ev(ev_touch, True, 1)],
           1: [_ev(ev_release, True, -1), _ev(ev_progress, True, 1)],
           2: [_ev(ev_stop, True, -1)]}
_FMAX = _ev(ev_force_max, False, -1)
_DMAX = _ev(ev_decel_max, False, 1)


def warm_up() -> None:
    """Compile the numba functions (cached on disk)."""
    q = np.ones(13)
    y = np.zeros(9)
    dy = np.zeros(9)
    for ph in (0, 1, 2):
        diffeq(dy, 0.0, y, q, ph)
        for f in (ev_touch, ev_release, ev_progress, ev_stop, ev_force_max, ev_decel_max):
            f(0.0, y, q, ph)


def run_point(p: dict, transient: int, window: int, method: str = "RK45", rtol: float = 1e-8,
              max_step_frac: float = 0.02, max_segments: int = 1_000_000) -> dict:
    """Labels of one point (``p`` from :func:`bench.drill_values`)."""
    from CyRK import pysolve_ivp

    q = _pvec(p)
    T = 1.0 / p["frequency_hz"]
    Om = q[12]
    fsc = max(abs(p["amplitude_n"]), abs(p["static_force_n"]), p["Pr"], 1.0)
    atol = rtol * 1e-3 * np.array([1, Om, 1, Om, 1, Om, 1, 1, fsc])

    def solve(t, t_stop, y, ph, rec):
        evs = _SWITCH[ph] + ([_FMAX, _DMAX] if rec and ph == 1 else [_DMAX] if rec else [])
        sol = pysolve_ivp(diffeq, (t, t_stop), y, method=method, events=evs, args=(q, ph), rtol=rtol, atol=atol,
                          max_step=max_step_frac * T, pass_dy_as_arg=True)
        if not sol.success:
            raise RuntimeError(f"CyRK failed: {sol.message}")
        maxima = [(sol.t_events[k][j], sol.y_events[k][:9, j]) for k in range(len(_SWITCH[ph]), len(evs))
                  for j in range(sol.t_events[k].size)] if rec else []
        if sol.event_terminated:
            k = sol.event_terminate_index
            return float(sol.t_events[k][-1]), np.array(sol.y_events[k][:9, -1]), True, maxima
        return float(sol.t[-1]), np.array(sol.y[:9, -1]), False, maxima

    return segment_loop(p, transient, window, solve, "CyRK peer", max_segments)
