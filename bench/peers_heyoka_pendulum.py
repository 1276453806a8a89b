"""Peer implementation of the impact pendulum (MODELS.md §3) with heyoka.py: Taylor integrator with events.

The base model of MODELS.md §3 (no effects, no discrepancy terms), state [θ, θ̇, W] (W the work of the cart's
inertial forcing, as in the reference).  One ``taylor_adaptive`` integrator holds both branches; the contact flag S
multiplies the contact force in the right-hand side, so a single LLVM compilation serves both branches and every
parameter point.  The two indicators of the contact rule (MODELS.md §3: in contact exactly when δ ≥ 0 and Fi > 0)
are δ = l sin θ − gap and Fi / ki; the window maxima come from non-terminal events on dFi/dt = 0 and on the
hammer's jerk = 0, both time derivatives taken symbolically by heyoka.  Events, callbacks and the run:
:mod:`bench.heyoka_contact`.
"""
from __future__ import annotations

import math

from bench import heyoka_contact as hc
from sim.models.discrepancy import COMPANION

PENDULUM_PARAMS = ("m", "l", "amplitude_m", "ki", "ci", "zeta", "gap_m", "frequency_hz", "g")
INFORMATIONAL = ("M",)   # the cart mass: the cart motion is prescribed
P_M, P_L, P_A0, P_KI, P_CI, P_ZETA, P_GAP, P_OM, P_G = range(9)
L = hc.layout(9)


def values(params: dict) -> dict:
    """The pendulum parameters the peer needs, as floats (``params`` = a complete resolved dict)."""
    # a candidate's companion (e.g. its regularisation speed) shapes it while it is on and sits at its default off
    on = [k for k, v in params.items()
          if k not in PENDULUM_PARAMS + INFORMATIONAL and k not in COMPANION and float(v) != 0.0]
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


def branch(pars, t: float, y) -> int:
    """Free (0) or contact (1): the two-indicator rule on δ and Fi / ki (:func:`bench.heyoka_contact.classify`)."""
    d, dd, f, thdd = _terms(pars, t, y)
    ddd = pars[P_L] * (thdd * math.cos(y[0]) - y[1] * y[1] * math.sin(y[0]))
    return hc.classify(d, f / pars[P_KI], dd, dd + pars[P_CI] / pars[P_KI] * ddd)


def force(pars, t: float, y, ph: int) -> float:
    return max(_terms(pars, t, y)[2], 0.0) if ph else 0.0


def decel(pars, t: float, y, ph: int) -> float:
    """−(absolute acceleration of the hammer), the acceleration l (θ̈ cos θ − θ̇² sin θ) − A0 Ω² sin Ωt."""
    thdd = _terms(pars, t, y)[3]
    l, om, c = pars[P_L], pars[P_OM], math.cos(y[0])
    thdd -= force(pars, t, y, ph) * c / (pars[P_M] * l)
    return -(l * (thdd * c - y[1] * y[1] * math.sin(y[0])) - pars[P_A0] * om * om * math.sin(om * t))


MODEL = hc.Model(L, branch, force, decel, i_work=2)


def _expressions(hy):
    """(right-hand sides, the two indicators, dFi/dt, jerk of the hammer) in heyoka expressions."""
    th, om, W, tt = hy.make_vars("th", "om", "W", "tt")     # tt stands for time until the derivatives are taken
    par = hy.par
    m, l, A0, ki, ci, zeta, gap, Om, g = (par[i] for i in range(9))
    S = par[L.S]
    s, c, swt = hy.sin(th), hy.cos(th), hy.sin(Om * tt)
    d = l * s - gap
    fi = ki * d + ci * l * om * c
    thdd = A0 * Om * Om / l * c * swt - g / l * s - 2.0 * zeta * hy.sqrt(g / l) * om - S * fi * c / (m * l)
    acc = l * (thdd * c - om * om * s) - A0 * Om * Om * swt
    at_t = {"tt": hy.time}

    def ddt(e):
        return hy.subs(hc.time_derivative(hy, e, (th, om), (om, thdd), tt), at_t)

    rhs = [(th, om), (om, hy.subs(thdd, at_t)), (W, hy.subs(m * l * A0 * Om * Om * swt * c * om, at_t))]
    return rhs, d, fi / ki, ddt(fi), ddt(acc)


def build(tol: float | None = None, compact_mode: bool = False, cooldown: float = hc.COOLDOWN_S):
    """Compile the integrator (returns it and the wall time of the LLVM compilation)."""
    import heyoka as hy

    return hc.build(MODEL, *_expressions(hy), tol=tol, compact_mode=compact_mode, cooldown=cooldown)


def run_point(ta, p: dict, transient: int, window: int) -> dict:
    """Labels of one point (``p`` from :func:`values`) with the compiled integrator ``ta``: from rest
    (θ = θ̇ = 0), ``transient`` cycles, then ``window`` recorded cycles."""
    pars = [p["m"], p["l"], p["amplitude_m"], p["ki"], p["ci"], p["zeta"], p["gap_m"],
            2.0 * math.pi * p["frequency_hz"], p["g"]]
    return hc.run(MODEL, ta, pars, transient, window, 1.0 / p["frequency_hz"])
