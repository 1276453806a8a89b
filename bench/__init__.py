"""Benchmarks: ``python -m bench.run_all [--quick]`` or ``make bench``.

Each ``bench/bench_*.py`` module has a ``main(quick)`` (or ``main()``) and writes ``bench/results/<name>.json``.
This package also holds the small pure-Python pieces of the drill model (MODELS.md §2) that the peer
implementations (:mod:`bench.peers_heyoka`, :mod:`bench.peers_cyrk`, :mod:`bench.peers_scipy`) share: the phase
classification at the start of a segment and the switching hysteresis, both as in ``tests/reference_solutions.py``,
and the segment loop of the peers that integrate one contact segment per solver call (:func:`segment_loop`).
"""
from __future__ import annotations

import math
from pathlib import Path

from sim.layout import G_ACCEL as G_ACC   # [m/s²] per g: the project's one value, that of sim's peak_decel_g

RESULTS = Path(__file__).resolve().parent / "results"

DRILL_PARAMS = ("M1", "M2", "M3", "K1", "K2", "K3", "C1", "C2", "C3", "Pr",
                "gap_m", "static_force_n", "amplitude_n", "frequency_hz")
EFFECT_PARAMS = ("gamma", "tau", "beta", "alpha", "mu", "kappa")   # §6 effects of the drill (sim/models/drill.py)
ETA_X = 1e-15          # hysteresis on the position switching function [m] (as the reference); 1e-13 delayed every
#                        contact by ETA_X / v1 and biased the lab ROP by 1.4e-8 (the damper's force jumps at contact)


def write_between_markers(root: Path, paths, start: str, end: str, text: str) -> list[str]:
    """Replace what stands between the lines ``start`` and ``end`` of each file in ``paths`` (relative to ``root``)
    that has both with ``text`` (a line break either side), atomically (``vibrobase.files``); returns the
    paths written.  How the benchmarks keep the tables the docs quote generated."""
    from vibrobase.files import atomic_write_text

    done = []
    for rel in paths:
        path = Path(root) / rel
        doc = path.read_text()
        if start in doc and end in doc:
            head, rest = doc.split(start, 1)
            tail = rest.split(end, 1)[1]
            atomic_write_text(path, f"{head}{start}\n{text.strip(chr(10))}\n{end}{tail}")
            done.append(str(rel))
    return done


def write_block(path: Path, start: str, end: str, text: str) -> None:
    """``write_between_markers`` for one file that must have the markers: one line (SystemExit) if it has not."""
    path = Path(path)
    if not write_between_markers(path.parent, (path.name,), start, end, text):
        raise SystemExit(f"{path}: no {start} ... {end} markers")


def publish(result: dict, out: Path, text: str, doc: Path | None, markers: tuple[str, str]) -> None:
    """Write ``result`` to the JSON file ``out``, print ``text`` and, unless ``doc`` is None, write it between the
    ``markers`` of ``doc``: the end of a benchmark whose table a page quotes."""
    from vibrobase.files import atomic_write_json

    Path(out).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(Path(out), result)
    print(text)
    if doc is not None:
        write_block(doc, *markers, text)


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


def segment_loop(p: dict, transient: int, window: int, solve, name: str, max_segments: int = 1_000_000) -> dict:
    """The drill labels of a peer that integrates one contact segment at a time (the plain scipy loop and CyRK).

    ``solve(t, t_stop, y, ph, rec)`` integrates from ``t`` towards ``t_stop`` on phase ``ph`` with that phase's
    terminal switching events (and, when ``rec``, the non-terminal events of the window maxima) and returns
    ``(t, y, terminal, maxima)``: where it stopped, whether a switching surface stopped it, and the (t, y) of the
    window-maximum events.  This loop classifies the state at every segment start (MODELS.md §2), counts contact
    onsets and keeps the window maxima; it starts at rest with the surface and slider at the gap."""
    import numpy as np

    T = 1.0 / p["frequency_hz"]
    G = p["gap_m"]
    y = np.array([0, 0, 0, 0, 0, 0, G, G, 0.0])
    t = 0.0
    t_win, t_end = transient * T, (transient + window) * T
    onsets = 0
    peakf = decel = 0.0
    xb0 = W0 = None

    def note(t, y, ph):
        nonlocal peakf, decel
        pc = (p["K1"] * (y[0] - y[7]) + p["C1"] * y[1]) if ph == 1 else (p["Pr"] if ph == 2 else 0.0)
        peakf = max(peakf, pc)
        decel = max(decel, -drill_a1(p, t, y, pc))

    ph = drill_classify(p, t, y)
    if ph:
        y[6] = y[0]
    for _ in range(max_segments):
        rec = t >= t_win
        if rec and xb0 is None:
            xb0, W0 = y[7], y[8]
            note(t, y, ph)
        t_stop = t_end if rec else t_win
        if t >= t_stop * (1 - 1e-15):
            break
        t, y, terminal, maxima = solve(t, t_stop, y, ph, rec)
        for te, ye in maxima:
            note(te, ye, ph)
        if terminal:
            if rec:
                note(t, y, ph)
            new = drill_classify(p, t, y)
            if new:
                y[6] = y[0]
            if rec and ph == 0 and new != 0:
                onsets += 1
            ph = new
            if rec:
                note(t, y, ph)
    else:
        raise RuntimeError(f"{name}: too many segments")
    note(t, y, ph)
    return {"rop_m_s": (y[7] - xb0) / (window * T), "peak_force_n": peakf, "impacts_per_cycle": onsets / window,
            "peak_decel_g": decel / G_ACC, "energy_per_cycle_j": (y[8] - W0) / window}
