"""The Markdown report of an optimisation (``report.md``), written from its report.json dict by the command."""
from __future__ import annotations

from pathlib import Path

import math

import numpy as np
import pandas as pd

from pipeline.core.names import display
from pipeline.core.units import spread_sentence
from pipeline.optimise.space import describe_bounds


def _fmt(v, unit: str = "") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.4g}{unit}"
    return f"{v}{unit}"


def _eng(name: str, v) -> str:
    """A value of a label or control in its engineering unit (mm/s, kW, g, kN: pipeline.core.names.DISPLAY_UNITS)."""
    if v is None or isinstance(v, (bool, str)) or (isinstance(v, float) and math.isnan(v)):
        return _fmt(v)
    return _fmt(display(name, v)[0])


def _head(name: str, suffix: str = "") -> str:
    """Column heading 'name suffix [unit]'."""
    unit = display(name, 0.0)[1]
    return f"{name}{suffix}" + (f" [{unit}]" if unit else "")


def _infill_lines(rep: dict) -> list[str]:
    """The infill section: one row per round of simulations where a contradicted surrogate's study looked."""
    inf = rep.get("infill")
    if not inf:
        return []
    lines: list[str] = []
    lines += ["## Infill: simulations where the study looked, surrogate retrained", "", inf["text"] + ".", ""]
    if inf["rounds"]:
        lines += ["| round | study | trained on | verified | wrong | median ROP error | recommended wrong "
                  "| ROP simulated [mm/s] | ROP predicted [mm/s] | points added |", "|" + "---|" * 10]
        for r in inf["rounds"]:
            med = r["rop_rel_error_median"]
            lines.append(f"| {r['round']} | {r['study_name']} | {_fmt(r['n_train'])} | {r['n_verified']} | "
                         f"{r['n_wrong']} | {'—' if med is None else format(med, '.1%')} | "
                         f"{'yes' if r['recommendation_wrong'] else 'no'} | {_eng('rop_m_s', r['rop_m_s_sim'])} | "
                         f"{_eng('rop_m_s', r['rop_m_s_pred'])} | {r['points_added']} |")
        lines.append("")
    return lines


def _recommendation_lines(rep: dict, rec: dict) -> list[str]:
    """The recommendation section: the point and its simulated labels, the limits it sits at, the margins kept,
    the envelope, the limit maps and whether it lies on the edge of the search space."""
    lines = []
    labels = [k for k in ("rop_m_s", "power_w", "peak_decel_g", "peak_force_n", "specific_energy_j_m")
              if rec.get(f"{k}_sim") is not None]
    lines += ["## Recommendation (verified by the simulator)", "",
              "| " + " | ".join(_head(n) for n in rec["params"]) + " | "
              + " | ".join(_head(k, " simulated") for k in labels) + " | ROP predicted [mm/s] | status |",
              "|" + "---|" * (len(rec["params"]) + len(labels) + 2),
              "| " + " | ".join(_eng(n, v) for n, v in rec["params"].items()) + " | "
              + " | ".join(_eng(k, rec[f"{k}_sim"]) for k in labels)
              + f" | {_eng('rop_m_s', rec.get('rop_m_s_pred'))} | {rec['status_sim']} |", ""]
    if rec.get("binding"):
        lines += ["At the limit(s): " + ", ".join(rec["binding"]) + ".", ""]
    if rec.get("margins"):
        lines += ["Margin kept: " + ", ".join(
            f"{m['label']} {m['value_sim']:.4g} ≤ {m['kept_below']:.4g} ({m['margin']:.0%} below the limit "
            f"{m['limit']:g}; headroom {m['headroom']:.1%})" for m in rec["margins"] if m["value_sim"] is not None)
                  + ".", ""]
    if rec.get("on_envelope"):
        lines += ["**On the shaker's envelope:** " + ", ".join(rec["on_envelope"]) + ".", ""]
    maps = [Path(f).name for f in rep.get("figures") or [] if Path(f).name.startswith("limit_map_")]
    if maps:
        lines += ["ROP around the recommendation, with the limits (solid), the limits less their margin (dashed) "
                  "and the exciter's envelope:", "", *(f"![{m}]({m})" for m in maps), ""]
    if rec.get("on_bounds"):
        lines += ["**On the edge of the search space:** " + describe_bounds(rec["on_bounds"])
                  + ". The optimum may lie beyond this bound; widen that range (sweep and train on it) to know.", ""]
    else:
        lines += ["The recommendation lies inside the search space (no control within 2 % of a bound).", ""]
    return lines


def _table_lines(rep: dict, table: pd.DataFrame) -> list[str]:
    """The verified table: each optimised objective's prediction next to the simulator's value, per point."""
    t = rep["tried"]
    lines = []
    shown = ["rop_m_s", *[o for o in t.get("objectives", []) if o != "rop_m_s"]]
    shown += [k for k in ("power_w", "peak_decel_g") if k not in shown and f"{k}_sim" in table]
    cols = [c for c in table.columns if c in rep["inputs"]]
    for k in shown:
        cols += [c for c in (f"{k}_pred", f"{k}_sim") if c in table.columns]
    cols += [c for c in ("status_pred", "status_sim", "feasible_sim", "surrogate_wrong", "why") if c in table.columns]
    heads = [_head(c[:-5], " pred") if c.endswith("_pred") and c[:-5] in shown else
             _head(c[:-4], " sim") if c.endswith("_sim") and c[:-4] in shown else _head(c) if c in rep["inputs"]
             else c for c in cols]
    name_of = {c: (c[:-5] if c.endswith("_pred") else c[:-4] if c.endswith("_sim") else c) for c in cols}
    lines += ["## Prediction next to the simulator (every optimised objective)", "",
              "| " + " | ".join(heads) + " |", "|" + "---|" * len(cols)]
    for _, r in table.iterrows():
        lines.append("| " + " | ".join(_eng(name_of[c], r[c]) if name_of[c] in shown or c in rep["inputs"]
                                       else _fmt(r[c]) for c in cols) + " |")
    lines.append("")
    return lines


def markdown(rep: dict, table: pd.DataFrame | None) -> str:
    """report.md of the report dict ``rep`` (outputs.report_dict) and the verified table (None when nothing was)."""
    t = rep["tried"]
    lines = [f"# Optimisation report — {rep['study_name']}", "", f"**Outcome:** {rep['outcome']}", ""]
    fb = rep.get("fallback")
    if fb:
        said = ""
        if fb.get("surrogate_best_rop_m_s_pred") is not None and fb.get("surrogate_best_rop_m_s_sim") is not None:
            said = (f"  The surrogate study ({fb['surrogate_study']}) predicted "
                    f"{_eng('rop_m_s', fb['surrogate_best_rop_m_s_pred'])} mm/s at its best verified point, where the "
                    f"simulator gave {_eng('rop_m_s', fb['surrogate_best_rop_m_s_sim'])} mm/s.")
        lines += [f"**Surrogate failed its verification:** {fb['text']}.{said}", ""]
    rec = rep.get("recommendation")
    if rec:
        lines += _recommendation_lines(rep, rec)
    if rep.get("spread"):
        lines += [f"**How sure:** {spread_sentence(rep['spread'])}.", ""]
    lines += _infill_lines(rep)
    lines += ["## What was tried", "",
              f"- mode: {t['mode']} (study on the {'surrogate, then re-simulated' if t['mode'] == 'surrogate' else 'simulator'}),"
              f" objective: {t['objective']} ({', '.join(t.get('objectives', []))}), sampler: {t['sampler']}, seed {t['seed']}",
              f"- model: {t['model']}, preset: {t['preset']}, fixed: {t['fixed'] or 'none'}",
              f"- space: " + ", ".join(f"{n} ∈ [{r['low']:g}, {r['high']:g}]" for n, r in t["space"].items()),
              f"- constraints: " + (", ".join(f"{k} = {v}" for k, v in t["constraints"].items() if v not in (None, False))
                                    or "none"),
              f"- trials: {t['n_trials']} complete ({t['n_trials_run_now']} run now), feasible: {t['n_feasible']}, "
              f"statuses: {t['status_counts']}",
              f"- simulator calls: {t['simulator_calls']} (study {t['simulator_calls_study']}, verification "
              f"{t['n_verified']})", f"- storage: {t['storage']}", ""]
    if t.get("closest"):
        lines += [f"- closest point to feasibility: {t['closest']}", ""]
    if table is not None and len(table):
        lines += _table_lines(rep, table)
    if rep.get("surrogate_note"):
        lines += ["## Surrogate check", "", rep["surrogate_note"], ""]
    front = rep.get("pareto_verified")
    if rep.get("objectives"):
        names = rep["objectives"]
        lines += [f"## Verified Pareto front ({' vs '.join(names)})", ""]
        if front:
            lines += [f"{len(front)} distinct non-dominated points, each re-simulated:", "",
                      "| " + " | ".join(_head(n) for n in names) + " | " + " | ".join(_head(n) for n in rep["inputs"])
                      + " |", "|" + "---|" * (len(names) + len(rep["inputs"]))]
            for p in front:
                lines.append("| " + " | ".join(_eng(n, p[n]) for n in names) + " | "
                             + " | ".join(_eng(n, p["params"][n]) for n in rep["inputs"]) + " |")
            if len(front) < 2:
                lines += ["", f"Only {len(front)} verified point is non-dominated: within these constraints "
                              f"{' and '.join(names)} do not trade off (one point is best in every objective)."]
        else:
            lines += ["No feasible verified point."]
        lines.append("")
    return "\n".join(lines)
