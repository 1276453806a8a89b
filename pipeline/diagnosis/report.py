"""Residual structure, figures (PNG) and report.md of a diagnosis."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from vibrobase.files import atomic_write_figure  # noqa: E402
from pipeline.core.units import ENGINEERING, factor, label, set_label  # noqa: E402
from pipeline.diagnosis.features import harmonic_fit, history_columns, model_record, record_time  # noqa: E402
from pipeline.diagnosis.report_types import (Candidate, Discrepancy, DiagnoseReport, ParamEstimate,  # noqa: E402
                                             Recording, ResidualStructure, RunResidual, SecondEffect,
                                             SystemReport)
from pipeline.diagnosis.result import SimulatedRun, SimulatedRuns, SystemDiagnosis  # noqa: E402
from sim.controls import CONTROLS as CONTROL_KEYS  # noqa: E402


def _tag(system: str) -> str:
    """Short file tag of a system: indenter-metal -> metal, drill -> drill."""
    return system.split("-")[-1]


def _nrms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r ** 2))) if r.size else float("nan")


def residual_structure(diag: SystemDiagnosis, base_runs: list[SimulatedRun],
                       final_runs: list[SimulatedRun]) -> ResidualStructure:
    """How the calibrated base model's residual depends on frequency, amplitude, static force, peak
    indenter velocity, harmonic frequency and time within the run (all runs; Spearman correlations)."""
    ev = diag.evaluator
    rows = []
    for b, f in zip(base_runs, final_runs):
        tg = ev.targets[b.run]
        rows.append(RunResidual(tg.run_id, {**{k: tg.controls.get(k) for k in CONTROL_KEYS}, **tg.controls},
                                b.peak_velocity_m_s, _nrms(b.residual), _nrms(f.residual), b.run in diag.held_out))
    corr = {}
    y = [r.base_nrms for r in rows]
    covariates = [{**{k: r.controls[k] for k in CONTROL_KEYS}, "peak_velocity_m_s": r.peak_velocity_m_s} for r in rows]
    for key in (*CONTROL_KEYS, "peak_velocity_m_s"):
        x = [np.nan if c[key] is None else c[key] for c in covariates]
        if all(v is None or not np.isfinite(v) for v in x):
            continue
        if len(set(x)) > 2:
            rho = spearmanr(x, y, nan_policy="omit").statistic
            corr[key] = None if rho is None or not np.isfinite(rho) else float(rho)
    by_h: dict[float, list[float]] = {}
    for b in base_runs:
        tg = ev.targets[b.run]
        if tg.kind != "series":
            continue
        for j, name in enumerate(tg.names):
            if name.startswith("accel_m_s2:h") and name.endswith(":re"):
                k = int(name.split(":h")[1].split(":")[0])
                hz = round(k * tg.controls["frequency_hz"] / 50.0) * 50.0
                by_h.setdefault(hz, []).append(math.hypot(b.residual[j], b.residual[j + 1]))
    seg = []
    for b in base_runs:
        tg = ev.targets[b.run]
        if tg.kind != "series" or not tg.segments or b.model is None:
            continue
        for sig, segs in tg.segments.items():
            names = [n for n in tg.names if n.startswith(sig + ":")]
            j0 = tg.names.index(names[0])
            m = b.model[j0:j0 + len(names)]
            mc = m[0::2] + 1j * m[1::2]
            sd = tg.sd[j0] * math.sqrt(segs.shape[0])
            seg.append([_nrms(np.abs(s - mc) / sd) for s in segs])
    return ResidualStructure(
        by_run=tuple(rows), spearman_base_nrms=corr,
        by_harmonic_hz={f"{k:g}": float(np.sqrt(np.mean(np.square(v)))) for k, v in sorted(by_h.items())},
        by_time_segment=tuple(float(x) for x in np.sqrt(np.mean(np.square(seg), axis=0))) if seg else ())


def _save(fig, path: Path) -> str:
    fig.tight_layout()
    atomic_write_figure(path, fig, dpi=100)
    return path.name


def _timehist_runs(diag: SystemDiagnosis) -> list[int]:
    """Target indices of the runs drawn measured against simulated: the first two held out, if series."""
    return [i for i in diag.held_out[:2] if diag.evaluator.targets[i].kind == "series"]


def _has_summary(diag: SystemDiagnosis) -> bool:
    return any(tg.kind == "summary" for tg in diag.evaluator.targets)


def figure_names(diag: SystemDiagnosis) -> list[str]:
    """The PNG files :func:`figures` draws for ``diag``, in its order (report.json 'figures')."""
    tag = _tag(diag.system)
    return ([f"residual_{tag}.png"] + [f"timehist_{diag.evaluator.targets[i].run_id}.png" for i in _timehist_runs(diag)]
            + ([f"summary_{tag}.png"] if _has_summary(diag) else [])
            + ([f"proposals_{tag}.png"] if diag.report.discrepancy and diag.report.discrepancy.proposals else []))


def figures(diag: SystemDiagnosis, runs: SimulatedRuns, series: dict, out: Path) -> list[str]:
    """Residual before/after, residual structure, measured vs simulated time histories and spectra, drawn into
    directory ``out`` from the measured ``series`` (run id -> DataFrame); the file names."""
    ev, sysname, final = diag.evaluator, diag.system, diag.final
    base_runs, final_runs, default_runs = runs.base, runs.final, runs.default
    tag = _tag(sysname)
    files = [_residual_figure(diag, out / f"residual_{tag}.png")]
    # measured vs simulated for up to two held-out runs
    for i in _timehist_runs(diag):
        name = _timehist_figure(diag, runs, series, i, out)
        if name is not None:
            files.append(name)
    if _has_summary(diag):
        models = [("model defaults", default_runs, "x"), ("calibrated base", base_runs, "o")]
        if final != "base":
            models.append((f"with {final}", final_runs, "s"))
        fig = summary_figure(ev.targets, models, f"{sysname}: summary features, measured vs model")
        files.append(_save(fig, out / f"summary_{tag}.png"))
    disc = diag.report.discrepancy
    if disc and disc.proposals:
        files.append(_proposals_figure(diag, disc, out / f"proposals_{tag}.png"))
    return files


def _x(r: RunResidual, key: str):
    """A run's control ``key`` or its peak velocity [SI]."""
    return r.peak_velocity_m_s if key == "peak_velocity_m_s" else r.controls.get(key)


def _residual_figure(diag: SystemDiagnosis, path: Path) -> str:
    """The calibrated base's (and the final model's) per-run nrms against each varied control, the residual by
    harmonic and by time segment."""
    sysname, final = diag.system, diag.final
    st = diag.report.residual_structure
    rows = st.by_run
    keys = [k for k in (*CONTROL_KEYS, "peak_velocity_m_s")
            if len({_x(r, k) for r in rows if _x(r, k) is not None}) > 1][:4]
    hz = st.by_harmonic_hz
    panels = [("control", k) for k in keys] + ([("harmonics", None)] if hz else []) + \
        ([("segments", None)] if st.by_time_segment else [])
    ncol = min(3, max(len(panels), 1))
    nrow = max(1, math.ceil(len(panels) / ncol))
    fig, ax = plt.subplots(nrow, ncol, figsize=(4.4 * ncol, 3.6 * nrow), squeeze=False)
    series_ = [("base_nrms", "calibrated base (before)", "o")]
    if final != "base":          # nothing selected: the base is the final model, drawn once
        series_.append(("final_nrms", f"with {final} (after)", "s"))
    for (kind, key), a in zip(panels, ax.ravel()):
        if kind == "control":
            k = set_label(a, "x", key)
            for col, lab, mk in series_:
                a.scatter([_x(r, key) * k for r in rows], [getattr(r, col) for r in rows], marker=mk, label=lab,
                          alpha=0.7)
            ho = [r for r in rows if r.held_out]
            a.scatter([_x(r, key) * k for r in ho], [r.base_nrms for r in ho], facecolors="none", edgecolors="k", s=90,
                      label="held-out run")
            a.axhline(1.0, color="grey", ls="--", lw=1)
            a.set_yscale("log")
            a.set_ylabel("residual / noise (nrms)")
        elif kind == "harmonics":
            a.bar([float(k) for k in hz], list(hz.values()), width=40)
            a.set_xlabel("harmonic frequency [Hz] (acceleration, 50 Hz bins)")
            a.set_ylabel("calibrated base |residual| / noise")
            a.set_yscale("log")
        else:
            a.plot(range(1, len(st.by_time_segment) + 1), st.by_time_segment, "o-")
            a.set_xlabel("time segment of the record")
            a.set_ylabel("calibrated base residual / noise")
            a.ticklabel_format(axis="y", useOffset=False)
    for a in ax.ravel()[len(panels):]:
        a.axis("off")
    if keys:
        ax[0, 0].legend(fontsize=7)
    fig.suptitle(f"{sysname}: residual structure before/after")
    return _save(fig, path)


def _timehist_figure(diag: SystemDiagnosis, runs: SimulatedRuns, series: dict, i: int, out: Path) -> str | None:
    """Held-out run ``i``: measured vs simulated (model defaults, calibrated base, final model) waveform over one
    forcing cycle and harmonic spectrum per signal; None for a summary run (no figure)."""
    ev, final = diag.evaluator, diag.final
    base_runs, final_runs, default_runs = runs.base, runs.final, runs.default
    tg = ev.targets[i]
    k = [d.run for d in base_runs].index(i)
    results = {"model defaults": default_runs[k].result, "calibrated base": base_runs[k].result}
    if final != "base":
        results[f"with {final}"] = final_runs[k].result
    f = tg.controls["frequency_hz"]
    if tg.kind != "series":
        return None
    df = series[tg.run_id]
    sigs = [s for s in ("accel_m_s2", "force_n") if s in df.columns]
    fig, ax = plt.subplots(len(sigs), 2, figsize=(12, 3.4 * len(sigs)), squeeze=False)
    for r_, sig in enumerate(sigs):
        _signal_panels(ax[r_], tg, df, sig, f, results)
    ax[0, 0].legend(fontsize=7)
    fig.suptitle(f"{tg.run_id} (held out): measured vs simulated")
    return _save(fig, out / f"timehist_{tg.run_id}.png")


def _signal_panels(ax_row, tg, df, sig: str, f: float, results: dict) -> None:
    """One signal's row: the measured and each model's waveform over a forcing cycle (harmonics 1..k_max) and their
    harmonic amplitudes, in the signal's engineering unit."""
    ph = np.linspace(0.0, 1.0, 200, endpoint=False)
    basis = np.exp(2j * np.pi * np.outer(ph, np.arange(1, tg.k_max + 1)))
    ks = factor(sig)      # SI -> the signal's unit in pipeline.core.units
    hm = harmonic_fit(record_time(tg, df["t_s"].to_numpy()), df[sig].to_numpy(), f, tg.k_max).c * ks
    ax_row[0].plot(ph, (basis @ hm).real, "k", lw=2, label=f"measured (harmonics 1-{tg.k_max})")
    spec_m = np.abs(hm)
    kk = np.arange(1, tg.k_max + 1) * f
    ax_row[1].plot(kk, spec_m, "ko-", lw=2, label="measured")
    for name, res in results.items():
        h = None if res is None else history_columns(res)
        if h is None:
            continue
        t, hr = model_record(tg, h)
        c = harmonic_fit(t, hr[sig], f, tg.k_max).c * ks
        ax_row[0].plot(ph, (basis @ c).real, lw=1, label=name)
        ax_row[1].plot(kk, np.abs(c), ".-", lw=1, label=name)
    ax_row[0].set_xlabel("forcing phase [cycles]")
    words = ENGINEERING[sig][0]
    set_label(ax_row[0], "y", sig, f"{words}, mean removed")
    set_label(ax_row[1], "x", "frequency_hz", "harmonic frequency")
    set_label(ax_row[1], "y", sig, f"harmonic amplitude of {words}")
    ax_row[1].set_yscale("log")


def summary_figure(targets: list, models: list[tuple[str, list[dict], str]], title: str):
    """One panel per summary feature of ``targets`` against the frequency: the measured value with its noise sd and
    each of ``models`` (label, per-target runs with a 'model' feature vector or None, marker); values [SI] drawn in
    the feature's engineering unit (pipeline.core.units)."""
    feats = sorted({n for tg in targets if tg.kind == "summary" for n in tg.names})
    fig, ax = plt.subplots(1, len(feats), figsize=(4 * len(feats), 3.6), squeeze=False)
    for a, feat in zip(ax[0], feats):
        k = set_label(a, "y", feat)
        set_label(a, "x", "frequency_hz")
        rows = [(i, tg, tg.names.index(feat)) for i, tg in enumerate(targets) if feat in tg.names]
        xs = [tg.controls["frequency_hz"] for _, tg, _ in rows]
        a.errorbar(xs, [tg.y[j] * k for _, tg, j in rows], yerr=[tg.sd[j] * k for _, tg, j in rows], fmt="ko",
                   label="measured")
        for lab, runs_, mk in models:
            ys = [np.nan if runs_[i].model is None else runs_[i].model[j] * k for i, _, j in rows]
            a.plot(xs, ys, mk, label=lab, alpha=0.8)
        a.set_title(ENGINEERING[feat][0] if feat in ENGINEERING else feat)
    ax[0, 0].legend(fontsize=7)
    fig.suptitle(title)
    return fig


def _proposals_figure(diag: SystemDiagnosis, disc: Discrepancy, path: Path) -> str:
    """The held-out residual of every held-out run before (calibrated base) and after each discrepancy proposal,
    against the frequency, and the noise level."""
    f_of = {t.run_id: t.controls["frequency_hz"] for t in diag.evaluator.targets}
    fig, a = plt.subplots(figsize=(6.4, 4.2))
    base = disc.base_by_run_nrms
    a.scatter([f_of[r] for r in base], list(base.values()), marker="o", s=50, label="calibrated base (before)")
    for k, p_ in enumerate(disc.proposals, 1):
        by = p_.by_run_nrms
        a.scatter([f_of[r] for r in by], list(by.values()), marker="sdv"[k - 1], alpha=0.8,
                  label=f"#{k} {' + '.join(p_.forms)} (nrms {p_.nrms:.3g})")
    a.axhline(1.0, color="grey", ls="--", lw=1, label="noise level")
    a.set_yscale("log")
    set_label(a, "x", "frequency_hz")
    a.set_ylabel("held-out residual / noise (nrms)")
    a.legend(fontsize=7)
    a.set_title(f"{diag.system}: proposals for the missing term, held-out runs")
    return _save(fig, path)


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _name(effects: tuple[str, ...] | None) -> str | None:
    """A model's effects as report.md names them (``a+b``)."""
    return None if effects is None else "+".join(effects)


def _param_line(n: str, v: ParamEstimate) -> str:
    lo, hi = v.ci95
    if not (lo > 0 and hi / lo < 1e4):
        return f"- {n} = {v.value:.4g}: not identifiable from these data (95 % interval spans > 4 decades)"
    return f"- {n} = {v.value:.4g} ± {v.sd:.2g} ({lo:.4g} … {hi:.4g})"


def markdown(report: DiagnoseReport) -> str:
    """report.md text."""
    lines = [f"# Model diagnosis of `{report.dataset}`", "",
             f"Wall time {report.wall_time_s:.0f} s. Errors are on held-out runs only (see 'split'), all weighted by "
             "the measurement noise of each feature: `error` = ||(model − measured)/sd|| / ||measured/sd||, the "
             "residual relative to the measured features; `noise_floor` = the same for a residual of pure noise; "
             "`nrms` = residual / noise = error / noise floor (1 = at the noise level; docs/diagnose.md).", ""]
    for rep in report.systems:
        lines += _system_lines(rep)
    if report.cost:
        lines += cost_lines(report.cost)
    return "\n".join(lines)


COST_COLUMNS = ("simulations", "cpu_s", "wall_s")


def cost_lines(cost: dict) -> list[str]:
    """report.md's table of where the time went: report.json ``cost``, a row per stage (its parts indented under it,
    not added again to the total), the total and the machine's load average."""
    from pipeline.core import units

    systems = sorted({s["system"] for s in cost["stages"] if s["system"]})
    head = ["stage", *(["system"] if len(systems) > 1 else []), *(units.label(c) for c in COST_COLUMNS)]
    lines = ["## Cost", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def row(name: str, system: str, vals: dict) -> str:
        cells = [name, *([system] if len(systems) > 1 else []),
                 *(f"{units.convert(c, vals[c]):.4g}" if c != "simulations" else str(vals[c]) for c in COST_COLUMNS)]
        return "| " + " | ".join(cells) + " |"
    for s in cost["stages"]:
        lines.append(row(s["stage"] if s["part_of"] is None else f"  ↳ {s['stage']}", s["system"], s))
    lines.append(row("**total**", "", cost["total"]))
    load = ", ".join(f"{x:g}" for x in cost["load_avg"])
    return lines + ["", f"Indented rows are the fit tasks of the stage above by model, already in its numbers; the "
                        f"total adds the other rows. Machine load average (1, 5, 15 min) at the end: {load}.", ""]


def _system_lines(rep: SystemReport) -> list[str]:
    """report.md section of one system's report entry."""
    lines = [f"## {rep.system} ({rep.n_runs} runs, {', '.join(rep.data)} data, {rep.split.scheme})", ""]
    lines += _verdict_lines(rep)
    second = rep.second_effect
    if second:
        lines += _second_effect_lines(second)
    if rep.discrepancy:
        lines += _discrepancy_lines(rep.discrepancy)
    if rep.empirical:
        lines += [f"**Last resort**: {rep.empirical.text}. It corrects ROP only, over "
                  f"{', '.join(rep.empirical.inputs) or 'the operating point'}; it is not physics, and the rig's "
                  f"dynamics are unchanged.", ""]
    if rep.indistinguishable:
        lines += [f"Indistinguishable on these data from {_name(rep.leader if not second else second.first)} "
                  f"(BIC within the margin): {', '.join(_name(m) for m in rep.indistinguishable)}.", ""]
    if rep.absorbed:
        lines += ["Parameters the base fit moved to absorb the missing physics (base fit against the fit with "
                  f"{_name(rep.leader)}): " + ", ".join(f"{n} {a.base:.4g} vs {a.with_:.4g} ({100 * a.change:+.0f} %)"
                                                        for n, a in rep.absorbed.items()) + ".", ""]
    if rep.rig:
        lines += [f"Corrected rig: [`{rep.rig.file}`]({rep.rig.file}) (use it with `--rig`): {rep.rig.source}.", ""]
    lines += _error_lines(rep)
    lines += _candidate_lines(rep)
    lines += [""] + [f"![{f}]({f})" for f in rep.figures] + [""]
    lines += _recording_lines(rep.recording)
    if rep.notes:
        lines += [f"Note: {n}" for n in rep.notes] + [""]
    return lines


def _verdict_lines(rep: SystemReport) -> list[str]:
    """The verdict, how close the call was, the pair stage and the single-effect step's leader and runner-up
    against the calibrated base."""
    lines = []
    err = rep.errors
    verdict = {"nothing missing": "**nothing missing** (the calibrated base model is adequate)",
               "selected": f"**{_name(rep.selected)}** selected",
               "unexplained": "**unexplained** (no §6 effect brings the model to the data)"}[rep.verdict]
    lines += [f"Verdict: {verdict}.", "", f"How close the call was: {rep.call.text}.", ""]
    stage = rep.pair_stage
    if stage:
        lines += [f"Two effects: {'tried' if stage.tried else 'not tried'} ({stage.reason}).", ""]
    second = rep.second_effect
    lead1 = second.first if second else rep.leader      # the single-effect step's leader
    shown = [m for m in (lead1, rep.runner_up) if m]
    by = {c.effects: c for c in rep.candidates}
    lines += ["| model | held-out error (noise floor) | held-out nrms | systematic error | ΔBIC vs base | "
              "held-out Δχ² vs base | adequate | improves |", "|---|---|---|---|---|---|---|---|",
              f"| calibrated base | {_fmt(err.base.error)} ({_fmt(err.noise_floor)}) | {_fmt(err.base.nrms)} | "
              f"{_fmt(err.base.systematic)} | 0 | 0 | {'yes' if rep.call.base.adequate else 'no'} | — |"]
    for m in shown:
        c = by[m]
        role = "selected" if m == rep.selected else ("leader" if m == lead1 else "runner-up")
        lines.append(f"| {_name(m)} ({role}) | {_fmt(c.error)} ({_fmt(err.noise_floor)}) | {_fmt(c.nrms)} | "
                     f"{_fmt(c.systematic)} | {_judged(-c.delta_score, c.delta_chi2_heldout, c)}")
    lines.append("")
    return lines


def _judged(delta_bic, delta_chi2, stats) -> str:
    """The judged cells of a model's row (a candidate, a pair or a proposal): ``ΔBIC | held-out Δχ² | adequate |
    improves |``."""
    return (f"{_fmt(delta_bic)} | {_fmt(delta_chi2)} | {'yes' if stats.adequate else 'no'} | "
            f"{'yes' if stats.improves else 'no'} |")


def _second_effect_lines(second: SecondEffect) -> list[str]:
    """The second effect's step: its call and its three best pairs."""
    lines = []
    first = _name(second.first)
    lines += [f"Second effect, each added to {first} and judged against {first} alone: {second.text}.", "",
              "| model | held-out nrms | systematic error | ΔBIC | held-out Δχ² | adequate | improves |",
              "|---|---|---|---|---|---|---|"]
    lines += [f"| {_name(c.effects)} | {_fmt(c.nrms)} | {_fmt(c.systematic)} | "
              f"{_judged(c.delta_bic, c.delta_chi2, c)}" for c in second.candidates[:3]]
    lines.append("")
    return lines


def _discrepancy_lines(disc: Discrepancy) -> list[str]:
    """The proposals for the missing term: the call, the screening and every proposal."""
    lines = []
    lines += [f"Proposing the missing term (no §6 effect explains the residual): {disc.text}.", "",
              "Screening (non-negative sparse regression of the calibrated base's residual on each term's "
              "sensitivity, calibratable directions projected out): "
              + ", ".join(f"{s.term} (#{s.entered}, score {s.score:.2f}"
                          + (", in the support)" if s.in_support else ")") for s in disc.screening) + ".", ""]
    if not disc.proposals:
        return lines
    lines += ["| rank | proposal | terms | coefficients (sd) | held-out error (noise floor) | held-out nrms | "
              "ΔBIC | held-out Δχ² | adequate | improves |", "|---|---|---|---|---|---|---|---|---|---|"]
    for k, p_ in enumerate(disc.proposals, 1):
        co = ", ".join(f"{t} = {p_.coefficients[t]:.3g} ± {p_.coefficient_sd[t]:.2g}" for t in p_.coefficients)
        lines.append(f"| {k} | {'; '.join(p_.words)} | {' + '.join(p_.forms)} | {co} | "
                     f"{_fmt(p_.error)} ({_fmt(p_.noise_floor)}) | {_fmt(p_.nrms)} | "
                     f"{_judged(p_.delta_bic, p_.delta_chi2, p_)}")
    lines.append("")
    return lines


def _error_lines(rep: SystemReport) -> list[str]:
    """Held-out errors of the default, calibrated and final models, and the calibrated and final parameters."""
    e = rep.errors
    lines = [
        "| model | held-out error | held-out nrms | systematic error |", "|---|---|---|---|",
        f"| default parameters | {_fmt(e.default.error)} | {_fmt(e.default.nrms)} | — |",
        f"| calibrated base (before) | {_fmt(e.base.error)} | {_fmt(e.base.nrms)} | {_fmt(e.base.systematic)} |",
        f"| final (after) | {_fmt(e.final.error)} | {_fmt(e.final.nrms)} | {_fmt(e.final.systematic)} |",
        f"| noise floor | {_fmt(e.noise_floor)} | 1 | 0 |", "",
        "Calibrated base parameters (value, sd, 95 % interval):", ""]
    lines += [_param_line(n, v) for n, v in rep.calibrated_uncertainty.items()]
    if rep.selected_params:
        final = _name(rep.selected) or "the proposal " + " + ".join(rep.proposal_adopted)
        lines += ["", f"Parameters with `{final}` (value, sd, 95 % interval):", ""]
        lines += [_param_line(n, v) for n, v in rep.selected_params.items()]
    return lines


def _candidate_lines(rep: SystemReport) -> list[str]:
    """Every candidate effect with its fitted parameters and scores, and the calibrated base's residual structure."""
    lines = []
    lines += ["", "Candidates (score = BIC on calibration runs; lower is better):", "",
              "| effect | fitted effect parameters | held-out error | held-out nrms | systematic error | "
              "score − base score | held-out Δχ² |", "|---|---|---|---|---|---|---|"]
    for c in rep.candidates:
        lines.append(_candidate_row(c))
    st = rep.residual_structure
    lines += ["", "Residual structure of the calibrated base model (Spearman correlation of per-run nrms with): "
              + ", ".join(f"{k} {v:+.2f}" for k, v in st.spearman_base_nrms.items() if v is not None) + "."]
    if st.by_time_segment:
        lines.append("Residual / noise by quarter of the record: "
                     + ", ".join(f"{x:.3g}" for x in st.by_time_segment) + ".")
    return lines


def _candidate_row(c: Candidate) -> str:
    ps = ", ".join(f"{k}={v:.3g}" for k, v in c.params.items())
    return (f"| {_name(c.effects)} | {ps} | {_fmt(c.error)} | {_fmt(c.nrms)} | {_fmt(c.systematic)} | "
            f"{_fmt(c.delta_score)} | {_fmt(c.delta_chi2_heldout)} |")


def _recording_lines(rec: Recording | None) -> list[str]:
    """report.md lines on the DAQ chain: the declared chains, and the undeclared chain estimated as nuisance."""
    if not rec:
        return []
    out = []
    if rec.declared:
        out.append(f"Recording chain declared in runs.csv for {len(rec.declared)} run(s): the model's signals went "
                   "through it before the comparison.")
    if rec.estimated:
        out.append("Recording: " + rec.estimated.text + ".")
    if rec.hum:
        out.append("Mains hum: " + "; ".join(f"{sig} " + ", ".join(f"{a:.3g} at {f} Hz" for f, a in lines.items())
                                             for sig, lines in rec.hum.items())
                   + " (fitted beside the forcing harmonics, in the sd of those a line sits on).")
    if rec.antialiased:
        out.append(f"Anti-alias filter: the model was low-passed below each record's Nyquist frequency before it was "
                   f"sampled, as the DAQ's filter did the signal, on {len(rec.antialiased)} run(s): "
                   f"{', '.join(rec.antialiased)}.")
    return out + ([""] if out else [])
