"""Benchmarks (issue 2 and friends): ``python -m bench.run_all [--quick]`` or ``make bench``.

Each ``bench/bench_*.py`` module has a ``main(quick)`` (or ``main()``) and writes ``bench/results/<name>.json``.
This package also holds the small pure-Python pieces of the drill model (MODELS.md §2) that the peer
implementations (:mod:`bench.peers_heyoka`, :mod:`bench.peers_cyrk`) share: the phase classification
at the start of a segment and the switching hysteresis, both as in ``tests/reference_solutions.py``.
"""
from __future__ import annotations

import math
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
G_ACC = 9.81

DRILL_PARAMS = ("M1", "M2", "M3", "K1", "K2", "K3", "C1", "C2", "C3", "Pr",
                "gap_m", "static_force_n", "amplitude_n", "frequency_hz")
EFFECT_PARAMS = ("gamma", "tau", "beta", "alpha", "mu", "kappa")   # §6 effects of the drill (sim/models/drill.py)
ETA_X = 1e-15          # hysteresis on the position switching function [m] (as the reference); 1e-13 delayed every
#                        contact by ETA_X / v1 and biased the lab ROP by 1.4e-8 (the damper's force jumps at contact)


def drill_values(params: dict) -> dict:
    """The drill parameters a peer needs, as floats (``params`` = a complete resolved dict)."""
    on = [k for k in EFFECT_PARAMS if float(params.get(k, 0.0)) != 0.0]
    if on:
        raise ValueError(f"the peers implement the base drill model only (MODELS.md §2); effect parameters set: {on}")
    return {k: float(params[k]) for k in DRILL_PARAMS}


def drill_a1(p: dict, t: float, y, pc: float) -> float:
    """Acceleration of the bit M1 with contact force ``pc``."""
    om = 2.0 * math.pi * p["frequency_hz"]
    return (p["amplitude_n"] * math.cos(om * t) - p["C2"] * (y[1] - y[3]) - p["K2"] * (y[0] - y[2]) - pc) / p["M1"]


def drill_classify(p: dict, t: float, y) -> int:
    """Phase (0 = I, 1 = II, 2 = III) the state ``y`` belongs to at the start of a segment (MODELS.md §2:
    "check at the start of each segment which phase the state actually belongs to").  On a surface
    (within the hysteresis) the sign of the force rate decides, as in the reference."""
    K1, C1, Pr = p["K1"], p["C1"], p["Pr"]
    eP = 1e-10 * max(Pr, 1.0)
    if y[0] - y[6] < -ETA_X:
        return 0
    P = K1 * (y[0] - y[7]) + C1 * y[1]
    if P > Pr + eP:
        return 2
    if P >= Pr - eP:
        return 2 if K1 * y[1] + C1 * drill_a1(p, t, y, Pr) > 0.0 else 1
    if P > eP:
        return 1
    if P >= -eP:
        return 1 if K1 * y[1] + C1 * drill_a1(p, t, y, 0.0) > 0.0 else 0
    return 0
