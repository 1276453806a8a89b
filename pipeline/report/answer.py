"""The pipeline's answer: the recommended operating point, its verified ROP and power.

When the pipeline diagnosed a rig log, the answer is the corrected rig's recommendation (its ROP on the corrected
rig with its 5-95 % spread over the fitted parameters, the model error and both combined, and what it is worth
against the lab model's point on the same rig); the lab model's answer follows on a second line, named as such.
Read from the report's ``summary.json`` (``vibro report``), printed at the end of ``make run``.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

CONTROLS = (("frequency_hz", "f", "Hz", 1.0, "{:.0f}"), ("amplitude_n", "F0", "kN", 1e-3, "{:.2f}"),
            ("amplitude_m", "amplitude", "mm", 1e3, "{:.2f}"), ("static_force_n", "Fs", "kN", 1e-3, "{:.2f}"))
POWER_KEYS = ("power_w_sim", "power_w", "power_w_pred")


def _number(d: dict, names: tuple[str, ...]) -> float | None:
    """The first finite number of ``d`` under one of ``names``."""
    for n in names:
        v = d.get(n)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
            return float(v)
    return None


def _point(rec: dict) -> str:
    """The controls of a recommendation (optimise report.json 'recommendation': under 'params') or of a point."""
    params = rec.get("params") if isinstance(rec.get("params"), dict) else rec
    point = []
    for key, sym, unit, k, f in CONTROLS:
        v = _number(params, (key,))
        if v is not None:
            point.append(f"{sym} = {f.format(v * k)} {unit}")
    return ", ".join(point) or "recommended point"


def _power_words(power: float) -> str:
    """``power 17.7 W`` (the lab rig's exciter: tens of watts) or ``power 1.23 kW``."""
    return f"power {power * 1e-3:.2f} kW" if power >= 1e3 else f"power {power:.1f} W"


def _bounds_words(hits) -> str:
    """``F0 at its upper bound 2.70 kN`` for every control a recommendation sits on (optimise 'on_bounds')."""
    if not isinstance(hits, list):
        return ""
    sym = {key: (s, unit, k, f) for key, s, unit, k, f in CONTROLS}
    out = []
    for h in hits:
        if not isinstance(h, dict) or "name" not in h:
            continue
        s, unit, k, f = sym.get(h["name"], (h["name"], "", 1.0, "{:g}"))
        side = "upper" if h.get("side") == "high" else "lower"
        out.append(f"{s} at its {side} bound {f.format(float(h['bound']) * k)} {unit}".rstrip())
    return ", ".join(out)


def _corrected(cl: dict) -> str | None:
    """The corrected rig's recommendation in words (None without one)."""
    pt, rop = cl.get("corrected_point"), _number(cl, ("corrected_rop_mm_s",))
    if not isinstance(pt, dict) or rop is None:
        return None
    rig = f"corrected rig '{cl['rig_name']}'" if cl.get("rig_name") else "corrected rig"
    text = f"Answer ({rig}): {_point(pt)} -> ROP {rop:.2f} mm/s on the corrected rig"
    if isinstance(cl.get("spread"), dict):
        from pipeline.core.units import spread_words

        text += f" ({spread_words(cl['spread'])})"
    elif isinstance(cl.get("spread_mm_s"), list) and len(cl["spread_mm_s"]) == 2:     # a summary from before
        text += f" (5-95 %: {cl['spread_mm_s'][0]:.2f}-{cl['spread_mm_s'][1]:.2f})"
    lim = cl.get("limits") or {}
    power, decel = _number(lim, ("power_w_sim",)), _number(lim, ("peak_decel_g_sim",))
    if power is not None:
        text += ", " + _power_words(power)
    if decel is not None:
        text += f", peak deceleration {decel:.2f} g"
    if lim.get("binding"):
        text += " (binding: " + "; ".join(map(_binding_words, lim["binding"])) + ")"
    if _bounds_words(lim.get("on_bounds")):
        text += "; on the edge of the search space: " + _bounds_words(lim["on_bounds"])
    broken = cl.get("breaks_on_uncorrected")
    if isinstance(broken, dict) and broken:
        from pipeline.core.units import broken_words

        text += f"; on the lab model this point breaks its limits ({broken_words(broken)})"
    lab = _number(cl, ("uncorrected_rop_on_corrected_mm_s",))
    if lab is not None:
        text += f"; the lab model's point gives {lab:.2f} mm/s there ({cl.get('worth_mm_s', rop - lab):+.2f} mm/s)"
    if cl.get("explained") is False:
        ratio = _number(cl, ("model_error_ratio",))
        how = "" if ratio is None else f" (held-out error {ratio:.3g}x the noise floor)"
        text += f". CAUTION: the diagnosis left the rig's residual unexplained{how}: this rests on a model known to be wrong"
    if isinstance(cl.get("fallback"), str):
        text += f". Corrected-rig surrogate: {cl['fallback']}"
    elif (_number(cl, ("surrogate_wrong",)) or 0) > 0:
        text += (f". The corrected-rig surrogate was wrong at {int(cl['surrogate_wrong'])} verified point(s); the "
                 "point is the best the simulator verified, not the surrogate's optimum")
    return text


def answer_line(summary: dict, report_path: str | Path | None = None) -> str | None:
    """``Answer: f = 262 Hz, F0 = 2.70 kN, Fs = 1.79 kN -> verified ROP 8.03 mm/s, power 1.20 kW; report: ...``
    (None when the summary has no recommended point).  With a closed loop in the summary: the corrected rig's
    answer first, then ``Lab model's answer: ...`` on a second line."""
    opt = summary.get("optimise") or {}
    rec = opt.get("recommended")
    rop = opt.get("verified_rop_m_s")
    lab = None
    if isinstance(rec, dict):
        lab = _point(rec)
        if isinstance(rop, (int, float)) and math.isfinite(rop):
            lab += f" -> verified ROP {rop * 1e3:.2f} mm/s"
        power = _number(rec, POWER_KEYS)
        if power is not None:
            lab += ", " + _power_words(power)
        if _bounds_words(rec.get("on_bounds")):
            lab += "; on the edge of the search space: " + _bounds_words(rec["on_bounds"])
    corrected = _corrected(summary.get("closed_loop") or {})
    if corrected is None and lab is None:
        return None
    if corrected is None:
        text = "Answer: " + lab
    else:
        text = corrected + ("" if lab is None else "\nLab model's answer (before the diagnosis): " + lab + " on the lab model")
    if report_path:
        text += f"; report: {report_path}"
    return text


def _binding_words(text: str) -> str:
    """``power_w 17.68 of its limit 18`` -> ``power 17.7 W of its 18 W limit`` (pipeline.core.units)."""
    import re

    from pipeline.core.units import ENGINEERING

    m = re.fullmatch(r"(\S+) (\S+) of its limit (\S+)", text.strip())
    if not m or m.group(1) not in ENGINEERING:
        return text
    name, unit, k = ENGINEERING[m.group(1)]
    return f"{name} {float(m.group(2)) * k:.3g} {unit} of its {float(m.group(3)) * k:g} {unit} limit"


def _diagnosis_words(r: dict) -> str | None:
    """One diagnosis row of the summary (report section 4) in words."""
    base, final, floor = r.get("base_error"), r.get("final_error"), r.get("noise_floor")
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (base, final, floor)):
        return None
    sel = r.get("selected")
    verdict = (f"{sel} selected" if sel and sel != "none" else
               "nothing missing" if r.get("explained") else "UNEXPLAINED (no §6 effect accounts for the residual)")
    after = f" -> {final:.1%} with {sel}" if sel and sel != "none" else ""
    return (f"Diagnosis of {r.get('dataset')} ({r.get('system')}): {verdict}; held-out feature error of the "
            f"calibrated model {base:.1%}{after} (noise floor {floor:.1%})")


def summary_lines(summary: dict) -> list[str]:
    """The report's opening box: the answer (corrected rig first), the limits that bind, each diagnosis's verdict
    with its error before and after."""
    top = answer_line(summary)
    lines = top.split("\n") if top else []
    rec = (summary.get("optimise") or {}).get("recommended") or {}
    if rec.get("binding"):
        lines.append("Limits that bind at the lab model's point: " + "; ".join(map(_binding_words, rec["binding"])))
    lines += [w for w in map(_diagnosis_words, summary.get("diagnose") or []) if w]
    return lines


def headline(summary: dict) -> dict:
    """The pipeline's answer as a few flat numbers (SI, as every metric): ``vibro report --metrics``, the one file
    ``dvc metrics show`` lists.  The corrected rig's point when the loop was closed, else the lab model's."""
    cl = summary.get("closed_loop") or {}
    opt = summary.get("optimise") or {}
    rec = opt.get("recommended") or {}
    corrected = isinstance(cl.get("corrected_point"), dict)
    point = cl["corrected_point"] if corrected else (rec.get("params") or {})
    out: dict = {k: point.get(k) for k in ("frequency_hz", "amplitude_n", "amplitude_m", "static_force_n") if k in point}
    out["rop_m_s"] = (cl.get("corrected_rop_mm_s", math.nan) * 1e-3 if corrected else opt.get("verified_rop_m_s"))
    if corrected:
        spread = cl.get("spread_mm_s") or [None, None]
        full = cl.get("spread") if isinstance(cl.get("spread"), dict) else {}
        out.update(rop_m_s_p5=None if spread[0] is None else spread[0] * 1e-3,
                   rop_m_s_p95=None if spread[1] is None else spread[1] * 1e-3,
                   rop_m_s_parameter_half_width=full.get("parameter_half_width_m_s"),
                   rop_m_s_model_error_half_width=full.get("model_error_half_width_m_s"),
                   rop_m_s_combined_half_width=full.get("combined_half_width_m_s"),
                   worth_m_s=None if cl.get("worth_mm_s") is None else cl["worth_mm_s"] * 1e-3,
                   explained=int(bool(cl.get("explained"))), surrogate_fallback=int(bool(cl.get("fallback"))))
    out["lab_rop_m_s"] = opt.get("verified_rop_m_s")
    return {k: (float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v) for k, v in out.items()
            if v is not None and not (isinstance(v, float) and math.isnan(v))}


def answer_from_report(report_dir: str | Path) -> str | None:
    """:func:`answer_line` of ``report_dir/summary.json`` (None when absent or without a recommendation)."""
    d = Path(report_dir)
    try:
        summary = json.loads((d / "summary.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return answer_line(summary, d / "report.html")
