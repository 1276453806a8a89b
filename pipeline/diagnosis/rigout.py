"""The corrected rig a diagnosis hands on: the model as the measurements corrected it (a ``sim.Rig``).

Content (README.md "Closing the loop"):
- ``preset``: the runs' common ``preset`` column (None if the runs name none);
- ``parameters``: the runs' known parameters where they differ from that preset (runs.csv parameter columns),
  then the calibrated parameters (MODELS.md §6) of the final model — fitted jointly with the selected effect
  when one is selected, else the calibrated base model;
- ``effects``: the selected §6 effect with its fitted parameters (none when nothing is selected);
- ``discrepancy``: the accepted discrepancy proposal's terms and coefficients, when no §6 effect explained the
  residual and a proposal did (``pipeline.diagnosis.discovery``);
- ``uncertainty``: the standard deviation of every fitted parameter in its SI unit.  The fit works in
  log10 p; its covariance is ``pinv(JᵀJ) · max(1, χ²/dof)`` (J = Jacobian of the noise-normalised residuals
  at the optimum, inflated when the fit is worse than the noise), and sd(p) = p · ln 10 · sd(log10 p)
  (delta method; ``pipeline.diagnosis.fit``).  Correlations between parameters are not kept.
- ``model_error``: what the final model still gets wrong about ROP: its held-out rms ROP error relative to the
  measured ROP (``error_by_group['final']['rop_m_s']``, noise-weighted; it holds the measurement noise too, so it is
  an upper estimate), with the same for pure noise beside it; absent when no held-out run measured ROP.
- ``empirical_correction``: where nothing explained the residual, a Gaussian-process correction of ROP over the
  operating point that cut the held-out ROP error (``pipeline.diagnosis.empirical``; "empirical correction, physics
  unknown"), applied by the optimiser to the simulated ROP;
- ``source``: the dataset, the verdict and, for an unexplained residual, the held-out error against the
  noise floor — the model is then known to be wrong by that much.
"""
from __future__ import annotations

import math

from pipeline.diagnosis.report_types import RigInfo
from pipeline.diagnosis.result import SystemDiagnosis

UNEXPLAINED_PREFIX = "UNEXPLAINED"
"""First word of a rig's ``source`` when the diagnosis left the residual unexplained."""


def rig_file_name(system: str, n_systems: int) -> str:
    """``rig.yaml`` for a one-system dataset, ``rig-<system>.yaml`` for each system of a several-system one."""
    return "rig.yaml" if n_systems == 1 else f"rig-{system}.yaml"


def _common(values: list, what: str) -> tuple[object, str | None]:
    """The value all runs share, or (first value, a note saying they differ)."""
    first = values[0]
    if all(v == first for v in values):
        return first, None
    return first, f"{what} differs between runs; the rig uses the first run's"


def rop_model_error(diag: SystemDiagnosis):
    """The final model's held-out ROP error as a ``sim.ModelError`` (None when no held-out run measured ROP)."""
    import sim

    errors = diag.report.errors
    err = (errors.final.by_group or {}).get("rop_m_s")
    if err is None or not math.isfinite(float(err)):
        return None
    noise = (errors.noise_by_group or {}).get("rop_m_s")
    runs = sorted({diag.targets[i].run_id for i in diag.held_out if "rop_m_s" in diag.targets[i].names})
    return sim.ModelError(rop_rel=float(err), noise_floor_rel=None if noise is None else float(noise),
                          basis=f"held-out rms ROP error of the diagnosis's final model ({diag.final}) over "
                                f"{len(runs)} held-out run(s), relative to the measured ROP; it includes their noise")


def corrected_rig(diag: SystemDiagnosis, presets: list[str | None], dataset: str):
    """(``sim.Rig``, report.json ``rig`` as a ``RigInfo`` without its file name) of one system's diagnosis ``diag``
    (its final fit, and its targets' known parameters per run), the runs' ``presets`` and the ``dataset`` named in
    the rig's source."""
    import sim

    rep, targets = diag.report, diag.targets
    system, final_err = rep.system, rep.errors.final
    spec = sim.get_model(system)
    notes = []
    preset, note = _common([p or None for p in presets], "preset")
    if note:
        notes.append(note)
    base = spec.defaults(preset)
    known_names = sorted({k for t in targets for k in t.known})
    params: dict[str, float] = {}
    for name in known_names:
        v, note = _common([t.known.get(name, base.get(name)) for t in targets], f"known parameter {name}")
        if note:
            notes.append(note)
        if v is not None and not math.isclose(float(v), float(base[name]), rel_tol=1e-12, abs_tol=0.0):
            params[name] = float(v)
    fr = diag.fits[diag.final]
    effect_of = {p: eff for eff, ps in spec.effects.items() for p in ps}
    effects: dict[str, dict[str, float]] = {}
    terms: dict[str, float] = {}
    for name in fr.free:
        if name in spec.discrepancy:
            terms[name] = float(fr.values[name])
        elif name in effect_of:
            effects.setdefault(effect_of[name], {})[name] = float(fr.values[name])
        else:
            params[name] = float(fr.values[name])
    uncertainty = {n: float(fr.sd[n]) for n in fr.free}
    absorbed = rep.absorbed or {}
    if rep.explained:
        verdict = (f"explained with {'+'.join(rep.selected)}" if rep.selected
                   else "explained by the calibrated base model (no effect needed)")
    else:
        verdict = (f"{UNEXPLAINED_PREFIX}: no §6 effect explains the residual; calibrated base model, known to be wrong "
                   f"by held-out error {final_err.error:.3g} against a noise floor of {rep.noise_floor:.3g} "
                   f"(nrms {final_err.nrms:.3g})")
        names = ", ".join(f"{n} ({100 * a.change:+.0f} % against the fit with {'+'.join(a.effects)})"
                          for n, a in absorbed.items())
        if terms:
            verdict = (f"{UNEXPLAINED_PREFIX} by the §6 effects; adopted the discrepancy proposal "
                       f"{' + '.join(terms)} (held-out error {final_err.error:.3g} against a noise floor of "
                       f"{rep.noise_floor:.3g}, nrms {final_err.nrms:.3g}; base model's error "
                       f"{rep.errors.base.error:.3g})")
        else:
            verdict += ("; parameters that may have absorbed the missing physics: " + names if names else
                        "; the calibrated parameters may have absorbed part of the missing physics")
        if diag.empirical is not None:
            verdict += f"; ROP corrected by an {diag.empirical.basis}"
    source = f"vibro diagnose {dataset} ({system}): {verdict}"
    rig = sim.Rig(model=system, preset=preset, parameters=params, effects=effects, uncertainty=uncertainty,
                  source=source, discrepancy=terms, model_error=rop_model_error(diag), empirical=diag.empirical)
    info = RigInfo(explained=bool(rep.explained), selected=rep.selected, source=source, discrepancy=terms or None,
                   verdict=rep.verdict, absorbed=absorbed, model_error=float(final_err.error),
                   noise_floor=float(rep.noise_floor), nrms=float(final_err.nrms),
                   rop_model_error=None if rig.model_error is None else rig.model_error.to_mapping(), notes=tuple(notes),
                   file=None)
    return rig, info
