"""The pipeline's answer in one line: the recommended operating point, its verified ROP and power.

Read from the report's ``summary.json`` (``vibro report``), printed at the end of ``make run``.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

CONTROLS = (("frequency_hz", "f", "Hz", 1.0, "{:.0f}"), ("amplitude_n", "F0", "kN", 1e-3, "{:.2f}"),
            ("amplitude_m", "amplitude", "mm", 1e3, "{:.2f}"), ("static_force_n", "Fs", "kN", 1e-3, "{:.2f}"))
POWER_KEYS = ("power_w_sim", "power_w", "power_w_pred")


def _find(d, names: tuple[str, ...]):
    """First finite number under one of ``names`` in a nested dict (depth-first)."""
    if isinstance(d, dict):
        for n in names:
            v = d.get(n)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                return float(v)
        for v in d.values():
            found = _find(v, names)
            if found is not None:
                return found
    return None


def answer_line(summary: dict, report_path: str | Path | None = None) -> str | None:
    """``Answer: f = 262 Hz, F0 = 2.70 kN, Fs = 1.79 kN -> verified ROP 8.03 mm/s, power 1.20 kW; report: ...``
    (None when the summary has no recommended point)."""
    opt = summary.get("optimise") or {}
    rec = opt.get("recommended")
    rop = opt.get("verified_rop_m_s")
    if not isinstance(rec, dict):
        return None
    point = []
    for key, sym, unit, k, f in CONTROLS:
        v = _find(rec, (key,))
        if v is not None:
            point.append(f"{sym} = {f.format(v * k)} {unit}")
    text = "Answer: " + (", ".join(point) or "recommended point")
    if isinstance(rop, (int, float)) and math.isfinite(rop):
        text += f" -> verified ROP {rop * 1e3:.2f} mm/s"
    power = _find(rec, POWER_KEYS)
    if power is not None:
        text += f", power {power * 1e-3:.2f} kW" if power >= 1e3 else f", power {power:.1f} W"   # lab rig: ~18 W
    if report_path:
        text += f"; report: {report_path}"
    return text


def answer_from_report(report_dir: str | Path) -> str | None:
    """:func:`answer_line` of ``report_dir/summary.json`` (None when absent or without a recommendation)."""
    d = Path(report_dir)
    try:
        summary = json.loads((d / "summary.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return answer_line(summary, d / "report.html")
