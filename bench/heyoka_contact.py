"""The machinery the heyoka.py peers of the two-indicator contact models share (the pendulum and the RIMD).

A model's peer supplies its right-hand side with the contact flag S (free 0, contact 1) as a runtime parameter, its
two contact indicators g1, g2 (MODELS.md: in contact exactly when g1 ≥ 0 and g2 > 0), the time derivatives of its
contact force and of the impacting mass's acceleration (for the window maxima), and three plain-Python functions of
(pars, t, y): the branch a state belongs to (:func:`classify`, from the indicators and their free-flow rates), the
contact force and the deceleration.  This module turns them into one ``taylor_adaptive``: each indicator is a
*terminal* event gated by S (entry: rising through +η while free; exit: falling through −η in contact; the gated
function is a nonzero constant on the other branch, so it cannot fire there), whose callback classifies the state,
sets S and returns True (integration goes on, on the new branch); the maxima of the force and of the deceleration
are *non-terminal* events on their time derivatives (active in the window only), evaluated on heyoka's dense output;
the values at every switch and at the window ends are checked explicitly.  Transient and window are two
``propagate_until`` calls.  Accumulators live in spare runtime parameters after the model's own (``Layout``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from bench import G_ACC

ETA = 1e-15            # [m] hysteresis on both indicators, as the reference (tests/reference_solutions.py ETA_X)
COOLDOWN_S = 1e-9      # [s] terminal-event cooldown (see bench.peers_heyoka.COOLDOWN_S); contacts last > 0.1 ms


class Layout(NamedTuple):
    """Runtime parameters: the model's ``n`` values, then the flag S, the window flag and the accumulators."""
    n: int
    S: int
    REC: int
    ONSETS: int
    PEAKF: int
    DECEL: int
    W0: int
    ZERO: int
    size: int


def layout(n: int) -> Layout:
    """The layout after ``n`` model parameters."""
    return Layout(n, *range(n, n + 7), n + 7)


def classify(g1: float, g2: float, r1: float, r2: float) -> int:
    """Branch (0 free, 1 contact) from the indicators and their free-flow rates: contact when min(g1, g2) > η,
    free below −η; on the surface the rates of the indicators within η decide (the reference's rule)."""
    g = min(g1, g2)
    if g > ETA:
        return 1
    if g < -ETA:
        return 0
    return 1 if min(r for gi, r in ((g1, r1), (g2, r2)) if gi <= ETA) > 0.0 else 0


@dataclass(frozen=True)
class Model:
    """What a peer supplies: ``branch``, ``force`` and ``decel`` are functions of (pars, t, y[, branch])."""
    layout: Layout
    branch: Callable
    force: Callable
    decel: Callable
    i_work: int          # index of the work state W


def _callbacks(m: Model):
    L = m.layout

    def record(ta, ph: int) -> None:
        pars, y, t = ta.pars, ta.state, ta.time
        pars[L.DECEL] = max(pars[L.DECEL], m.decel(pars, t, y, ph))
        pars[L.PEAKF] = max(pars[L.PEAKF], m.force(pars, t, y, ph))

    def switch(ta, d_sgn) -> bool:
        pars = ta.pars
        old = int(pars[L.S])
        rec = pars[L.REC] == 1.0
        if rec:
            record(ta, old)
        new = m.branch(pars, ta.time, ta.state)
        if new != old:
            pars[L.S] = float(new)
            if rec and new:
                pars[L.ONSETS] += 1.0
        if rec:
            record(ta, new)
        return True

    def peak_force(ta, t, d_sgn) -> None:
        pars = ta.pars
        pars[L.PEAKF] = max(pars[L.PEAKF], m.force(pars, t, ta.update_d_output(t), 1))

    def decel(ta, t, d_sgn) -> None:
        pars = ta.pars
        pars[L.DECEL] = max(pars[L.DECEL], m.decel(pars, t, ta.update_d_output(t), int(pars[L.S])))

    return record, switch, peak_force, decel


def build(m: Model, rhs, g1, g2, dforce, jerk, tol: float | None, compact_mode: bool, cooldown: float):
    """Compile the integrator of ``rhs`` (heyoka (variable, expression) pairs) with the events on the indicators
    ``g1``, ``g2`` and on the derivatives ``dforce``, ``jerk``; returns it and the wall time of the compilation."""
    import heyoka as hy

    L = m.layout
    par = hy.par
    S, rec = par[L.S], par[L.REC]
    _, switch, peak_force, decel = _callbacks(m)
    neg, pos = hy.event_direction.negative, hy.event_direction.positive
    # the spare accumulator parameters ride along (times par[ZERO] = 0) so heyoka sizes the parameter array
    spare = par[L.ZERO] * (par[L.ONSETS] + par[L.PEAKF] + par[L.DECEL] + par[L.W0])
    free = 1.0 - S
    t_events = [
        hy.t_event(free * (g1 - ETA) - S + spare, callback=switch, direction=pos, cooldown=cooldown),   # entry
        hy.t_event(free * (g2 - ETA) - S, callback=switch, direction=pos, cooldown=cooldown),
        hy.t_event(S * (g1 + ETA) + free, callback=switch, direction=neg, cooldown=cooldown),           # exit
        hy.t_event(S * (g2 + ETA) + free, callback=switch, direction=neg, cooldown=cooldown),
    ]
    nt_events = [
        hy.nt_event(rec * S * dforce + (1.0 - rec * S), callback=peak_force, direction=neg),   # force maximum
        hy.nt_event(rec * jerk + (1.0 - rec), callback=decel, direction=pos),   # acceleration minimum
    ]
    kw = {} if tol is None else {"tol": tol}
    t0 = time.perf_counter()
    ta = hy.taylor_adaptive(rhs, np.zeros(len(rhs)), pars=np.zeros(L.size), t_events=t_events, nt_events=nt_events,
                            compact_mode=compact_mode, **kw)
    return ta, time.perf_counter() - t0


def run(m: Model, ta, model_pars, transient: int, window: int, T: float) -> dict:
    """Labels of one point from rest (y = 0): ``transient`` cycles of period ``T``, then ``window`` recorded ones;
    ``model_pars`` = the model's runtime parameter values."""
    L = m.layout
    record = _callbacks(m)[0]
    ta.pars[:] = 0.0
    ta.pars[:L.n] = model_pars
    ta.state[:] = 0.0
    ta.time = 0.0
    ta.reset_cooldowns()
    ta.pars[L.S] = float(m.branch(ta.pars, 0.0, ta.state))
    for t_stop in (transient * T, (transient + window) * T):
        if t_stop > ta.time:
            out = ta.propagate_until(t_stop)
            if ta.time < t_stop * (1 - 1e-12):
                raise RuntimeError(f"heyoka stopped early: {out[0]}")
        if ta.pars[L.REC] == 0.0:          # the window starts: its first point sets the running maxima
            ta.pars[L.REC] = 1.0
            ta.pars[L.W0] = ta.state[m.i_work]
            ph = int(ta.pars[L.S])
            ta.pars[L.DECEL] = m.decel(ta.pars, ta.time, ta.state, ph)
            ta.pars[L.PEAKF] = m.force(ta.pars, ta.time, ta.state, ph)
    record(ta, int(ta.pars[L.S]))       # window end
    return {"rop_m_s": 0.0, "peak_force_n": float(ta.pars[L.PEAKF]),
            "impacts_per_cycle": float(ta.pars[L.ONSETS]) / window,
            "peak_decel_g": float(ta.pars[L.DECEL]) / G_ACC,
            "energy_per_cycle_j": float(ta.state[m.i_work] - ta.pars[L.W0]) / window}


def time_derivative(hy, e, states, rates, tt):
    """d e / dt along the flow: Σ ∂e/∂y_i y_i' + ∂e/∂tt (``tt`` the variable standing for time)."""
    out = hy.diff(e, tt)
    for y, r in zip(states, rates):
        out = out + hy.diff(e, y) * r
    return out
