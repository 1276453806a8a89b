"""Peer implementation of the impact pendulum (MODELS.md §3) with heyoka.py: Taylor integrator with events.

The base model of MODELS.md §3 (no effects, no discrepancy terms), state [θ, θ̇, W] (W the work of the cart's
inertial forcing, as in the reference).  One ``taylor_adaptive`` integrator holds both branches: the contact flag
S (free 0, contact 1) is a runtime parameter that multiplies the contact force in the right-hand side, so a single
LLVM compilation serves both branches and every parameter point.  Contact follows the two-indicator rule
(MODELS.md §3: in contact exactly when δ ≥ 0 and Fi > 0): each indicator, δ = l sin θ − gap and Fi / ki, is a
*terminal* event gated by S (entry: rising through +η while free; exit: falling through −η in contact; the gated
function is a nonzero constant on the other branch, so it cannot fire there).  heyoka locates the crossing on the
Taylor polynomial of the step; the callback classifies the state (:func:`classify`, the reference's rule and
hysteresis η = 1e-15 m), sets S and returns True: integration goes on, on the new branch.

The labels the bench compares (peak_force_n, impacts_per_cycle, peak_decel_g) come from the event machinery: the
maxima of the contact force and of the hammer's deceleration are *non-terminal* events on dFi/dt = 0 and on the
jerk of the hammer = 0 (both time derivatives taken symbolically by heyoka, active in the window only), evaluated
on heyoka's dense output; the jumps at the switches (Fi = ci δ̇ at an onset) and the window ends are checked
explicitly.  Transient and window are two ``propagate_until`` calls.  Accumulators live in spare runtime
parameters, as in :mod:`bench.peers_heyoka`.
"""
from __future__ import annotations

import math
import time

import numpy as np

from bench import G_ACC

ETA = 1e-15            # [m] hysteresis on both indicators, as the reference (tests/reference_solutions.py ETA_X)
PENDULUM_PARAMS = ("m", "l", "amplitude_m", "ki", "ci", "zeta", "gap_m", "frequency_hz", "g")
INFORMATIONAL = ("M",)   # the cart mass: the cart motion is prescribed
COOLDOWN_S = 1e-9      # [s] terminal-event cooldown (see bench.peers_heyoka.COOLDOWN_S); a contact lasts ~0.5 ms

# runtime parameter layout
(P_M, P_L, P_A0, P_KI, P_CI, P_ZETA, P_GAP, P_OM, P_G,
 P_S, P_REC, P_ONSETS, P_PEAKF, P_DECEL, P_W0, P_ZERO) = range(16)
NPARS = 16


def values(params: dict) -> dict:
    """The pendulum parameters the peer needs, as floats (``params`` = a complete resolved dict)."""
    on = [k for k, v in params.items() if k not in PENDULUM_PARAMS + INFORMATIONAL and float(v) != 0.0]
    if on:
        raise ValueError(f"the peer implements the base pendulum model only (MODELS.md §3); effect or "
                         f"discrepancy parameters set: {on}")
    return {k: float(params[k]) for k in PENDULUM_PARAMS}


def _terms(pars, t: float, y) -> tuple[float, float, float, float]:
    """(δ, δ̇, Fi expression [N], free-flight θ̈) of the state y at absolute time t."""
    l, om = pars[P_L], pars[P_OM]
    s, c = math.sin(y[0]), math.cos(y[0])
    d, dd = l * s - pars[P_GAP], l * y[1] * c
    thdd = (pars[P_A0] * om * om / l * c * math.sin(om * t) - pars[P_G] / l * s
            - 2.0 * pars[P_ZETA] * math.sqrt(pars[P_G] / l) * y[1])
    return d, dd, pars[P_KI] * d + pars[P_CI] * dd, thdd


def classify(pars, t: float, y) -> int:
    """Branch (0 free, 1 contact) of the state y: contact when min(δ, Fi / ki) > η, free below −η; on the
    surface the free-flow rates of the indicators within η decide (the reference's two-indicator rule)."""
    d, dd, f, thdd = _terms(pars, t, y)
    g1, g2 = d, f / pars[P_KI]
    g = min(g1, g2)
    if g > ETA:
        return 1
    if g < -ETA:
        return 0
    l = pars[P_L]
    ddd = l * (thdd * math.cos(y[0]) - y[1] * y[1] * math.sin(y[0]))
    rates = ((g1, dd), (g2, dd + pars[P_CI] / pars[P_KI] * ddd))
    return 1 if min(r for gi, r in rates if gi <= ETA) > 0.0 else 0


def _force(pars, t: float, y, ph: int) -> float:
    return max(_terms(pars, t, y)[2], 0.0) if ph else 0.0


def _decel(pars, t: float, y, ph: int) -> float:
    """−(absolute acceleration of the hammer) l (θ̈ cos θ − θ̇² sin θ) − A0 Ω² sin Ωt, negated."""
    _, _, _, thdd = _terms(pars, t, y)
    l, om, c = pars[P_L], pars[P_OM], math.cos(y[0])
    thdd -= _force(pars, t, y, ph) * c / (pars[P_M] * l)
    return -(l * (thdd * c - y[1] * y[1] * math.sin(y[0])) - pars[P_A0] * om * om * math.sin(om * t))


def _record_point(ta, ph: int) -> None:
    pars, y, t = ta.pars, ta.state, ta.time
    pars[P_DECEL] = max(pars[P_DECEL], _decel(pars, t, y, ph))
    pars[P_PEAKF] = max(pars[P_PEAKF], _force(pars, t, y, ph))


def _switch_cb(ta, d_sgn) -> bool:
    pars = ta.pars
    old = int(pars[P_S])
    rec = pars[P_REC] == 1.0
    if rec:
        _record_point(ta, old)
    new = classify(pars, ta.time, ta.state)
    if new != old:
        pars[P_S] = float(new)
        if rec and new:
            pars[P_ONSETS] += 1.0
    if rec:
        _record_point(ta, new)
    return True


def _peak_force_cb(ta, t, d_sgn) -> None:
    y = ta.update_d_output(t)
    pars = ta.pars
    pars[P_PEAKF] = max(pars[P_PEAKF], _force(pars, t, y, 1))


def _decel_cb(ta, t, d_sgn) -> None:
    y = ta.update_d_output(t)
    pars = ta.pars
    pars[P_DECEL] = max(pars[P_DECEL], _decel(pars, t, y, int(pars[P_S])))


def _expressions(hy):
    """(state variables, right-hand sides, δ, Fi expression, dFi/dt, jerk of the hammer) in heyoka expressions."""
    th, om, W, tt = hy.make_vars("th", "om", "W", "tt")     # tt stands for time until the derivatives are taken
    par = hy.par
    m, l, A0, ki, ci, zeta, gap, Om, g, S = (par[i] for i in (P_M, P_L, P_A0, P_KI, P_CI, P_ZETA, P_GAP, P_OM,
                                                              P_G, P_S))
    s, c, swt = hy.sin(th), hy.cos(th), hy.sin(Om * tt)
    d = l * s - gap
    fi = ki * d + ci * l * om * c
    thdd = A0 * Om * Om / l * c * swt - g / l * s - 2.0 * zeta * hy.sqrt(g / l) * om - S * fi * c / (m * l)
    acc = l * (thdd * c - om * om * s) - A0 * Om * Om * swt

    def ddt(e):     # time derivative along the flow
        return hy.diff(e, th) * om + hy.diff(e, om) * thdd + hy.diff(e, tt)

    at_t = {"tt": hy.time}
    rhs = [(th, om), (om, hy.subs(thdd, at_t)), (W, hy.subs(m * l * A0 * Om * Om * swt * c * om, at_t))]
    return rhs, d, fi, hy.subs(ddt(fi), at_t), hy.subs(ddt(acc), at_t)


def build(tol: float | None = None, compact_mode: bool = False, cooldown: float = COOLDOWN_S):
    """Compile the integrator (returns it and the wall time of the LLVM compilation)."""
    import heyoka as hy

    rhs, d, fi, dfi, jerk = _expressions(hy)
    par = hy.par
    S, ki, rec = par[P_S], par[P_KI], par[P_REC]
    neg, pos = hy.event_direction.negative, hy.event_direction.positive
    # the spare accumulator parameters ride along (times par[P_ZERO] = 0) so heyoka sizes the parameter array
    spare = par[P_ZERO] * (par[P_ONSETS] + par[P_PEAKF] + par[P_DECEL] + par[P_W0])
    free, contact = 1.0 - S, S
    t_events = [
        hy.t_event(free * (d - ETA) - contact + spare, callback=_switch_cb, direction=pos, cooldown=cooldown),
        hy.t_event(free * (fi / ki - ETA) - contact, callback=_switch_cb, direction=pos, cooldown=cooldown),
        hy.t_event(contact * (d + ETA) + free, callback=_switch_cb, direction=neg, cooldown=cooldown),
        hy.t_event(contact * (fi / ki + ETA) + free, callback=_switch_cb, direction=neg, cooldown=cooldown),
    ]
    nt_events = [
        hy.nt_event(rec * S * dfi + (1.0 - rec * S), callback=_peak_force_cb, direction=neg),   # Fi maximum
        hy.nt_event(rec * jerk + (1.0 - rec), callback=_decel_cb, direction=pos),   # acceleration minimum
    ]
    kw = {} if tol is None else {"tol": tol}
    t0 = time.perf_counter()
    ta = hy.taylor_adaptive(rhs, np.zeros(3), pars=np.zeros(NPARS), t_events=t_events, nt_events=nt_events,
                            compact_mode=compact_mode, **kw)
    return ta, time.perf_counter() - t0


def run_point(ta, p: dict, transient: int, window: int) -> dict:
    """Labels of one point (``p`` from :func:`values`) with the compiled integrator ``ta``: from rest
    (θ = θ̇ = 0), ``transient`` cycles, then ``window`` recorded cycles."""
    T = 1.0 / p["frequency_hz"]
    pars = np.zeros(NPARS)
    pars[:P_S] = [p["m"], p["l"], p["amplitude_m"], p["ki"], p["ci"], p["zeta"], p["gap_m"],
                  2.0 * math.pi * p["frequency_hz"], p["g"]]
    ta.pars[:] = pars
    ta.state[:] = 0.0
    ta.time = 0.0
    ta.reset_cooldowns()
    ta.pars[P_S] = float(classify(ta.pars, 0.0, ta.state))
    for t_stop in (transient * T, (transient + window) * T):
        if t_stop > ta.time:
            out = ta.propagate_until(t_stop)
            if ta.time < t_stop * (1 - 1e-12):
                raise RuntimeError(f"heyoka stopped early: {out[0]}")
        if ta.pars[P_REC] == 0.0:          # the window starts: its first point sets the running maxima
            ta.pars[P_REC] = 1.0
            ta.pars[P_W0] = ta.state[2]
            ph = int(ta.pars[P_S])
            ta.pars[P_DECEL] = _decel(ta.pars, ta.time, ta.state, ph)
            ta.pars[P_PEAKF] = _force(ta.pars, ta.time, ta.state, ph)
    _record_point(ta, int(ta.pars[P_S]))       # window end
    return {"rop_m_s": 0.0, "peak_force_n": float(ta.pars[P_PEAKF]),
            "impacts_per_cycle": float(ta.pars[P_ONSETS]) / window, "peak_decel_g": float(ta.pars[P_DECEL]) / G_ACC,
            "energy_per_cycle_j": float(ta.state[2] - ta.pars[P_W0]) / window}
