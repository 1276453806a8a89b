"""Peer implementation of the drill model (MODELS.md §2) as a user would write it with scipy: a plain
``solve_ivp`` loop.

Plain Python right-hand side and event functions (no numba, no harness): one ``solve_ivp`` call per
contact segment with the terminal events of the current phase's switching surfaces; at a terminal event
take the event state, classify it (``bench.drill_classify``: the same rule and hysteresis as the
reference), set xt = x1 on contact and restart on the new branch.  The transient / window boundary is a
segment end.  No per-cycle restart and no event scans between step ends: solve_ivp's own step-end sign
check locates the events.  In the window, non-terminal events on dP/dt = 0 (phase II) and on the jerk of
M1 = 0 give the maxima of the contact force and of the deceleration; jumps at switches and the window
ends are checked explicitly.  Same structure and tolerances as :mod:`bench.peers_cyrk` (atol = rtol x
1e-3 x state scale, max step T / 50).  State: [x1, v1, x2, v2, x3, v3, xt, xb, W] (the base model: the
shaker-coil force state fh of the simulator is identically 0 without the effect and is left out).
"""
from __future__ import annotations

import math

import numpy as np

from bench import ETA_X, segment_loop


def _model(p: dict):
    """The right-hand side, the per-phase terminal events and the window extremum events of point ``p``."""
    M1, M2, M3 = p["M1"], p["M2"], p["M3"]
    K1, K2, K3, C1, C2, C3 = p["K1"], p["K2"], p["K3"], p["C1"], p["C2"], p["C3"]
    Pr, F0, Fs = p["Pr"], p["amplitude_n"], p["static_force_n"]
    Om = 2.0 * math.pi * p["frequency_hz"]

    def pc(y, ph):
        return 0.0 if ph == 0 else (K1 * (y[0] - y[7]) + C1 * y[1] if ph == 1 else Pr)

    def accels(t, y, ph):
        s12 = C2 * (y[1] - y[3]) + K2 * (y[0] - y[2])
        s23 = C3 * (y[3] - y[5]) + K3 * (y[2] - y[4])
        return (F0 * math.cos(Om * t) - s12 - pc(y, ph)) / M1, (Fs + s12 - s23) / M2, s23 / M3

    def rhs(t, y, ph):
        a1, a2, a3 = accels(t, y, ph)
        if ph == 0:
            dxt, dxb = -(K1 / C1) * (y[6] - y[7]), 0.0
        elif ph == 1:
            dxt, dxb = y[1], 0.0
        else:
            dxt, dxb = y[1], (K1 * (y[0] - y[7]) + C1 * y[1] - Pr) / C1
        return [y[1], a1, y[3], a2, y[5], a3, dxt, dxb, F0 * math.cos(Om * t) * y[1]]

    def event(f, terminal, direction):
        f.terminal, f.direction = terminal, direction
        return f

    touch = event(lambda t, y, ph: y[0] - y[6] - ETA_X, True, 1)                          # I -> II/III
    release = event(lambda t, y, ph: K1 * (y[0] - y[7]) + C1 * y[1] + 1e-10 * Pr, True, -1)  # II -> I
    progress = event(lambda t, y, ph: K1 * (y[0] - y[7]) + C1 * y[1] - Pr - 1e-10 * Pr, True, 1)  # II -> III
    stop = event(lambda t, y, ph: K1 * (y[0] - y[7]) + C1 * y[1] - Pr + 1e-10 * Pr, True, -1)   # III -> II

    def dpdt(t, y, ph):                 # dP/dt in phase II (force maximum)
        return K1 * y[1] + C1 * accels(t, y, 1)[0]

    def jerk(t, y, ph):                 # jerk of M1 (a minimum of a1 = maximum deceleration)
        a1, a2, _ = accels(t, y, ph)
        dpc = K1 * y[1] + C1 * a1 if ph == 1 else 0.0
        return (-F0 * Om * math.sin(Om * t) - C2 * (a1 - a2) - K2 * (y[1] - y[3]) - dpc) / M1

    switch = {0: [touch], 1: [release, progress], 2: [stop]}
    return rhs, switch, event(dpdt, False, -1), event(jerk, False, 1)


def run_point(p: dict, transient: int, window: int, method: str = "RK45", rtol: float = 1e-8,
              max_step_frac: float = 0.02, max_segments: int = 1_000_000) -> dict:
    """Labels of one point (``p`` from :func:`bench.drill_values`); ``method`` any solve_ivp method."""
    from scipy.integrate import solve_ivp

    rhs, switch, fmax, dmax = _model(p)
    T = 1.0 / p["frequency_hz"]
    Om = 2.0 * math.pi * p["frequency_hz"]
    fsc = max(abs(p["amplitude_n"]), abs(p["static_force_n"]), p["Pr"], 1.0)
    atol = rtol * 1e-3 * np.array([1, Om, 1, Om, 1, Om, 1, 1, fsc])

    def solve(t, t_stop, y, ph, rec):
        evs = switch[ph] + ([fmax, dmax] if rec and ph == 1 else [dmax] if rec else [])
        sol = solve_ivp(rhs, (t, t_stop), y, method=method, events=evs, args=(ph,), rtol=rtol, atol=atol,
                        max_step=max_step_frac * T)
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        maxima = [(te, ye) for k in range(len(switch[ph]), len(evs))
                  for te, ye in zip(sol.t_events[k], sol.y_events[k])] if rec else []
        if sol.status == 1:            # a terminal event: the switching surface solve_ivp stopped on
            k = min((i for i in range(len(switch[ph])) if sol.t_events[i].size),
                    key=lambda i: abs(sol.t_events[i][-1] - sol.t[-1]))
            return float(sol.t_events[k][-1]), np.array(sol.y_events[k][-1]), True, maxima
        return float(sol.t[-1]), np.array(sol.y[:, -1]), False, maxima

    return segment_loop(p, transient, window, solve, "scipy peer", max_segments)
