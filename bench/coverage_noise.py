"""How far a measured 90 % interval coverage may fall from 0.90 by chance alone, beside what bench_design measured.

A split-conformal interval calibrated on ``n`` out-of-fold residuals covers a new point with a probability that is
itself random (over the calibration set): Beta(k, n + 1 − k), k = ⌈(n + 1) q⌉, sd ≈ √(q (1 − q) / (n + 2)).  Its
coverage measured on ``m`` hidden points adds binomial scatter, sd √(q (1 − q) / m).  So even an exactly calibrated
interval shows a coverage of sd s = √(q (1 − q) (1 / (n + 2) + 1 / m)), and lands inside 0.88–0.92 with
probability 2 Φ(0.02 / s) − 1.  This reads ``bench/results/design.json`` (``python -m bench.bench_design``), sets
each measured coverage against that sd (z = (coverage − 0.90) / s) and writes the table between docs/train.md's
``coverage-noise`` markers.

    python -m bench.coverage_noise [--no-doc]
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DESIGN = ROOT / "bench" / "results" / "design.json"
Q = 0.90
BAND = (0.88, 0.92)
LABELS = ("rop_m_s", "power_w", "peak_decel_g")


def chance_sd(n_cal: int, m_test: int, q: float = Q) -> float:
    """sd of the coverage an exactly calibrated split-conformal interval shows on ``m_test`` hidden points."""
    return math.sqrt(q * (1 - q) * (1.0 / (n_cal + 2) + 1.0 / m_test))


def in_band_probability(sd: float) -> float:
    """P(0.88 <= coverage <= 0.92) for a coverage ~ N(0.90, sd)."""
    return math.erf((BAND[1] - Q) / sd / math.sqrt(2.0))


def groups(rows: list[dict]) -> list[dict]:
    """Per model, design, size and hidden set: the measured coverages over seeds and labels against chance."""
    out: dict[tuple, dict] = {}
    for r in rows:
        design = r["design"] + (f" {r['fraction']:g}" if r.get("fraction") is not None else "")
        for where, sc in r["scores"].items():
            key = (r["model"], design, r["n"], where)
            g = out.setdefault(key, {"model": r["model"], "design": design, "n": r["n"], "set": where, "cells": []})
            for label in LABELS:
                m = sc["n_progressing"] if label == "rop_m_s" else sc["n"]
                c = sc["coverage"][label]
                s = chance_sd(r["n"], m)
                g["cells"].append({"seed": r.get("seed"), "label": label, "coverage": c, "sd": s,
                                   "z": (c - Q) / s, "in_band": BAND[0] <= c <= BAND[1]})
    for g in out.values():
        cells = g["cells"]
        g["sd"] = sum(c["sd"] for c in cells) / len(cells)
        g["p_in_band"] = in_band_probability(g["sd"])
        g["p_all_three"] = g["p_in_band"] ** 3
        g["in_band"] = sum(c["in_band"] for c in cells)
        g["rms_z"] = math.sqrt(sum(c["z"] ** 2 for c in cells) / len(cells))
        g["mean_z"] = sum(c["z"] for c in cells) / len(cells)
    return list(out.values())


def table(gs: list[dict]) -> str:
    lines = ["| model | design | n | hidden set | chance sd of a coverage | P(one label in 0.88–0.92) | "
             "P(all three in) | measured in band | rms z | mean z |", "|---|---|---|---|---|---|---|---|---|---|"]
    for g in gs:
        lines.append(f"| {g['model']} | {g['design']} | {g['n']} | {g['set']} | {g['sd']:.4f} | {g['p_in_band']:.2f} | "
                     f"{g['p_all_three']:.2f} | {g['in_band']}/{len(g['cells'])} | {g['rms_z']:.2f} | "
                     f"{g['mean_z']:+.2f} |")
    cells = [c for g in gs for c in g["cells"]]
    rms = math.sqrt(sum(c["z"] ** 2 for c in cells) / len(cells))
    lines.append(f"\nOver all {len(cells)} measured coverages: rms z {rms:.2f} (1 for an interval whose only error is "
                 f"chance), mean z {sum(c['z'] for c in cells) / len(cells):+.2f}; "
                 f"{sum(c['in_band'] for c in cells)} in the band, "
                 f"{sum(in_band_probability(c['sd']) for c in cells):.1f} expected by chance alone.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--no-doc", action="store_true")
    a = p.parse_args(argv)
    gs = groups(json.loads(DESIGN.read_text())["rows"])
    text = table(gs)
    print(text)
    if not a.no_doc:
        from bench import write_between_markers

        write_between_markers(ROOT, ["docs/train.md"], "<!-- coverage-noise:start -->", "<!-- coverage-noise:end -->",
                              text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
