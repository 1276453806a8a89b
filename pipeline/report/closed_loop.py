"""Report section 5: closing the loop — the recommendation on the uncorrected model beside the one on the
corrected rig (``vibro compare``'s results/closed-loop/report.json; docs/closed-loop.md)."""
from __future__ import annotations

from pathlib import Path

from pipeline.core.units import broken_words, point_words, spread_words
from pipeline.report.doc import Heading, Para, Table


def section_closed_loop(doc, figs, inp, summary: dict) -> None:
    """Both recommendations with their ROP on both models, the correction's worth, the ROP spread, the warning."""
    import json

    doc.add(Heading("5. Closing the loop: the rig's corrected model and its best operating point"))
    path = inp.p(getattr(inp, "closed_loop", Path("results/closed-loop"))) / "report.json"
    if not path.is_file():
        doc.add(Para(f"No comparison at `{path}`: the compare stage has not run."))
        return
    cmp = json.loads(path.read_text())
    t, s = cmp["recommendations"], cmp["spread"]
    rows = [[label, point_words(t[k]["point"]), t[k]["rop_m_s_on_uncorrected"] * 1e3, t[k]["rop_m_s_on_corrected"] * 1e3]
            for k, label in (("uncorrected", "uncorrected model"), ("corrected", "corrected rig"))]
    doc.add(Para(f"The rig log was diagnosed into a corrected rig ({cmp['corrected_rig'].get('source', '')}); the "
                 "surrogate chain (sweep → train → optimise, verified by the simulator) ran again on it.  Each "
                 "recommended operating point, simulated on both models:"))
    doc.add(Table(["recommended by", "operating point", "ROP on the uncorrected model [mm/s]",
                   "ROP on the corrected rig [mm/s]"], rows, "Recommendations under each model"))
    doc.add(Para(f"**The correction is worth {cmp['worth_mm_s']:+.3g} mm/s** on the corrected rig (corrected "
                 f"recommendation minus uncorrected recommendation, both simulated on the corrected rig).  Over "
                 f"{s['n_samples']} samples of the fitted parameters ({', '.join(s['sampled']) or 'none'}) the "
                 f"corrected recommendation drills {s['median_rop_m_s'] * 1e3:.4g} mm/s median, "
                 f"{s['p5_rop_m_s'] * 1e3:.4g}–{s['p95_rop_m_s'] * 1e3:.4g} mm/s (5–95 %); "
                 f"{s['fraction_progressing']:.0%} of the samples progress.  With what the diagnosis left "
                 f"unexplained: {spread_words(s)}."))
    for name, label, other, where in (("corrected", "corrected rig", "uncorrected", "uncorrected model"),
                                      ("uncorrected", "uncorrected model", "corrected", "corrected rig")):
        broken = t[name].get(f"breaks_on_{other}")
        if broken is not None:
            doc.add(Para(f"The {label}'s point on the {where}: "
                         + (f"breaks that model's limits ({broken_words(broken)})." if broken
                            else "within that model's limits.")))
    if cmp.get("warning"):
        doc.add(Para(f"**Warning.** {cmp['warning']}"))
    summary["closed_loop"] = {"worth_mm_s": cmp["worth_mm_s"], "explained": cmp["explained"],
                              "corrected_point": t["corrected"]["point"],
                              "corrected_rop_mm_s": t["corrected"]["rop_m_s_on_corrected"] * 1e3,
                              "uncorrected_rop_on_corrected_mm_s": t["uncorrected"]["rop_m_s_on_corrected"] * 1e3,
                              "spread_mm_s": [s["p5_rop_m_s"] * 1e3, s["p95_rop_m_s"] * 1e3],
                              "spread": s,
                              "model_error_ratio": cmp.get("model_error_ratio"),
                              "surrogate_wrong": cmp.get("corrected_surrogate_wrong"),
                              "fallback": cmp.get("corrected_fallback"),
                              "rig_name": cmp.get("rig_name"),
                              "breaks_on_uncorrected": t["corrected"].get("breaks_on_uncorrected"),
                              "limits": cmp.get("corrected_limits") or {}}
