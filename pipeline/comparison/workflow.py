"""Closing the loop: what the corrected model's recommendation is worth on the rig the measurements describe.

Inputs: two optimisation results (report.json of ``vibro optimise``) — one on the uncorrected model (e.g. the
``lab`` preset) and one on the corrected rig — and the corrected rig itself (``rig.yaml`` of ``vibro diagnose``,
with its diagnosis verdict in ``source``).  Both recommended points are simulated on both models, so the table
shows each recommendation's ROP under each model; the correction is worth

    ROP(corrected recommendation on the corrected rig) − ROP(uncorrected recommendation on the corrected rig)

(the corrected rig being the best description of the machine we have).  The corrected recommendation's ROP is
also re-simulated over samples of the rig's fitted parameters (``robustness.rop_spread``), and that spread is
combined with the rig's model error (the diagnosis's held-out ROP error); an unexplained diagnosis is stated with its
held-out error against the noise floor.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Mapping

from pipeline.core.units import broken_words, point_words, spread_words
from vibrobase.statuses import SETTLED_STATUSES
from pipeline.optimise.robustness import rop_spread

if TYPE_CHECKING:
    from pipeline.diagnosis.report_types import RigInfo

UNEXPLAINED_WARNING = ("The diagnosis left the rig's residual unexplained: the recommendation rests on a model known to "
                       "be wrong — held-out error {error:.3g} against a noise floor of {noise:.3g} ({ratio:.1f}× the noise).")


def model_rig(optimise_report: Mapping):
    """The ``sim.Rig`` an optimisation ran on: its model, preset and fixed parameters (effects included)."""
    from sim import Rig

    tried = optimise_report["tried"]
    controls = set(optimise_report["inputs"])
    fixed = {k: float(v) for k, v in (tried.get("fixed") or {}).items() if k not in controls}
    return Rig(str(tried["model"]), tried.get("preset")).with_values(fixed)


def _rop(rig, point: Mapping[str, float], settings: Mapping | None) -> tuple[float, str, dict]:
    """(ROP [m/s], status, the label row: point, labels and status) of ``point`` simulated on ``rig``; a rig's
    empirical ROP correction (``sim.empirical``) applied where the point progresses, the model's own ROP kept in the
    row as ``rop_model_m_s``."""
    r = rig.simulate(**dict(point), settings=dict(settings or {}))
    rop = float(r.labels["rop_m_s"]) if r.status in SETTLED_STATUSES and r.labels.get("rop_m_s") is not None else 0.0
    row = {**dict(point), **dict(r.labels), "status": str(r.status)}
    if rig.empirical is not None and rop > 0:
        fixed, _ = rig.empirical.correct(rop, {n: [rig.resolve(**dict(point))[n]] for n in rig.empirical.inputs})
        row["rop_model_m_s"], rop = rop, float(fixed[0])
        row["rop_m_s"] = rop
    return rop, str(r.status), row


def broken_limits(optimise_report: Mapping, row: Mapping) -> dict[str, dict]:
    """The limits of an optimisation (report.json 'tried.constraints') that the label ``row`` breaks: constraint
    name -> {'label', 'value', 'limit'} (value and limit [SI]; None for a condition such as a steady state)."""
    from pipeline.optimise.constraints import UPPER_LIMITS, Constraints

    cons = Constraints(**(optimise_report.get("tried", {}).get("constraints") or {}))
    out = {}
    for name, v in cons.values(row).items():
        if v > 0:
            label, attr = UPPER_LIMITS.get(name, (None, None))
            out[name] = {"label": label, "value": None if label is None else row.get(label),
                         "limit": None if attr is None else getattr(cons, attr)}
    return out


def compare(uncorrected: Mapping, corrected: Mapping, rig, diagnosis: RigInfo | None = None, n_samples: int = 32,
            seed: int = 0, settings: Mapping | None = None, n_threads: int | None = None,
            rig_name: str | None = None) -> dict:
    """The side-by-side comparison (a JSON-able dict; ROP in m/s, ``worth_mm_s`` in mm/s).  Each recommendation on
    each model also says which of that model's optimisation limits it breaks (``breaks_on_<model>``).

    ``uncorrected`` / ``corrected``: optimise report.json mappings; ``rig``: the corrected ``sim.Rig``;
    ``diagnosis``: the diagnosis's rig entry (``report_types.RigInfo``: explained, model_error, noise_floor), if at
    hand."""
    from pipeline.core.errors import UserError

    for name, rep in (("uncorrected", uncorrected), ("corrected", corrected)):
        if not rep.get("recommendation"):
            raise UserError(f"{name} optimisation recommended nothing ({rep.get('outcome', 'no outcome')}); "
                            "nothing to compare")
    models = {"uncorrected": model_rig(uncorrected), "corrected": rig}
    reports = {"uncorrected": uncorrected, "corrected": corrected}
    points = {"uncorrected": dict(uncorrected["recommendation"]["params"]),
              "corrected": dict(corrected["recommendation"]["params"])}
    table = {}
    for rec_name, point in points.items():
        table[rec_name] = {"point": point}
        for model_name, m in models.items():
            rop, status, row = _rop(m, point, settings)
            table[rec_name][f"rop_m_s_on_{model_name}"] = rop
            table[rec_name][f"status_on_{model_name}"] = status
            table[rec_name][f"breaks_on_{model_name}"] = broken_limits(reports[model_name], row)
    worth = table["corrected"]["rop_m_s_on_corrected"] - table["uncorrected"]["rop_m_s_on_corrected"]
    spread = rop_spread(rig, points["corrected"], n_samples=n_samples, seed=seed, settings=settings, n_threads=n_threads)
    out = {"recommendations": table, "worth_mm_s": worth * 1e3,
           "uncorrected_model": models["uncorrected"].to_mapping(), "corrected_rig": rig.to_mapping(),
           "spread": spread.to_dict(), "explained": True, "warning": None, "rig_name": rig_name,
           "corrected_surrogate_wrong": (corrected.get("metrics") or {}).get("n_surrogate_wrong"),
           "corrected_fallback": (corrected.get("fallback") or {}).get("text"),
           "corrected_limits": {k: corrected["recommendation"].get(k) for k in ("power_w_sim", "peak_decel_g_sim",
                                                                              "binding", "on_bounds")}}
    if diagnosis is not None and not diagnosis.explained:
        err, noise = float(diagnosis.model_error), float(diagnosis.noise_floor)
        ratio = err / max(noise, 1e-300)
        out.update(explained=False, model_error_ratio=ratio,
                   warning=UNEXPLAINED_WARNING.format(error=err, noise=noise, ratio=ratio))
    return out


def markdown(cmp: Mapping) -> str:
    """The comparison as a Markdown section (results/closed-loop/report.md and the pipeline report)."""
    t = cmp["recommendations"]
    s = cmp["spread"]
    lines = ["| recommended by | operating point | ROP on the uncorrected model [mm/s] | ROP on the corrected rig [mm/s] |",
             "|---|---|---|---|"]
    for name, label in (("uncorrected", "uncorrected model"), ("corrected", "corrected rig")):
        r = t[name]
        lines.append(f"| {label} | {point_words(r['point'])} | {r['rop_m_s_on_uncorrected'] * 1e3:.4g} | "
                     f"{r['rop_m_s_on_corrected'] * 1e3:.4g} |")
    for name, label in (("uncorrected", "uncorrected model"), ("corrected", "corrected rig")):
        other = "corrected" if name == "uncorrected" else "uncorrected"
        broken = t[name].get(f"breaks_on_{other}")
        if broken is not None:
            words = broken_words(broken)
            lines += ["", f"The {label}'s point on the {'corrected rig' if other == 'corrected' else 'uncorrected model'}"
                      + (f" breaks that model's limits: {words}." if words else ": within that model's limits.")]
    lines += ["", f"**The correction is worth {cmp['worth_mm_s']:+.3g} mm/s** on the corrected rig: the uncorrected "
                  f"recommendation achieves {t['uncorrected']['rop_m_s_on_corrected'] * 1e3:.4g} mm/s there, the "
                  f"corrected one {t['corrected']['rop_m_s_on_corrected'] * 1e3:.4g} mm/s.", "",
              f"Uncertainty: over {s['n_samples']} samples of the fitted parameters ({', '.join(s['sampled']) or 'none'}; "
              f"log-normal, sd from the diagnosis) the corrected recommendation's ROP is {s['median_rop_m_s'] * 1e3:.4g} mm/s "
              f"median, {s['p5_rop_m_s'] * 1e3:.4g}–{s['p95_rop_m_s'] * 1e3:.4g} mm/s (5–95 %); "
              f"{s['fraction_progressing']:.0%} of the samples progress.  With what the diagnosis left unexplained: "
              f"{spread_words(s)}."]
    src = cmp["corrected_rig"].get("source")
    if src:
        lines += ["", f"Corrected rig: {src}."]
    if cmp.get("warning"):
        lines += ["", f"**Warning.** {cmp['warning']}"]
    return "\n".join(lines) + "\n"
