"""The corrected rig of a diagnosis (pipeline.diagnosis.rigout): which values go where, and the verdict in
``source`` — on hand-made diagnosis results (the end-to-end case is in test_diagnose.py)."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from pipeline.diagnosis.features import Target
from pipeline.diagnosis.fit import FitResult
from pipeline.diagnosis.report_types import DiagnoseReport, ModelErrors, RigInfo
from pipeline.diagnosis.result import SystemDiagnosis
from pipeline.diagnosis.rigout import UNEXPLAINED_PREFIX, corrected_rig, rig_file_name


def _fit(values: dict, sd: dict) -> FitResult:
    return FitResult(values=values, sd=sd, ci95={k: (v / 2, v * 2) for k, v in values.items()}, chi2=1.0, n=10,
                     free=list(values), nfev=1)


def _diag(selected, explained, fits, final, targets, error_by_group=None, held_out=()) -> SystemDiagnosis:
    """A diagnosis of ``targets`` (an evaluator stand-in holding only them) with these ``fits``."""
    return SystemDiagnosis(report=_report(selected, explained, error_by_group), evaluator=SimpleNamespace(targets=targets), fits=fits,
                           held_out=list(held_out), final=final)


def _report(selected, explained, error_by_group=None, rig=None):
    """A drill report (the stored one-system fixture's) with this verdict, held-out errors and rig."""
    rep = DiagnoseReport.from_json(json.loads((Path(__file__).parent / "data" / "report_single.json").read_text()))
    s = rep.systems[0]
    groups = error_by_group or {"final": {}, "noise": {}}
    errors = replace(s.errors, final=ModelErrors(0.21, 35.0, None, groups["final"]), noise_floor=0.042,
                     noise_by_group=groups["noise"])
    return replace(s, selected=tuple(selected.split("+")) if selected else None, explained=explained, errors=errors,
                   absorbed={}, rig=rig)


def _targets(known_m1=(12.0, 12.0)):
    return [Target(run_id=f"r{i}", system="drill", kind="series", controls={"frequency_hz": 200.0},
                   known={"M1": m1, "K2": 6e6}) for i, m1 in enumerate(known_m1)]


BASE = {"K1": 5e8, "C1": 3e5, "Pr": 2800.0}


def test_selected_effect_goes_under_effects_with_the_jointly_fitted_base():
    import sim

    lab = sim.get_model("drill").defaults("lab")
    joint = {"K1": 5.5e8, "C1": 3.1e5, "Pr": 2900.0, "tau": 1.1e-4, "beta": 2900.0}
    fits = {"base": _fit(BASE, {k: 0.1 * v for k, v in BASE.items()}),
            "shaker_coil": _fit(joint, {k: 0.05 * v for k, v in joint.items()})}
    rig, info = corrected_rig(_diag("shaker_coil", True, fits, "shaker_coil", _targets((lab["M1"], lab["M1"]))),
                              ["lab", "lab"], "measured/drill-rig")
    assert rig.preset == "lab" and rig.effects == {"shaker_coil": {"tau": 1.1e-4, "beta": 2900.0}}
    assert rig.parameters["K1"] == 5.5e8 and rig.parameters["Pr"] == 2900.0     # the joint fit, not the base fit
    assert "M1" not in rig.parameters                       # known and equal to the preset: not repeated
    assert rig.parameters["K2"] == 6e6                      # known and different from the preset
    assert rig.uncertainty["tau"] == pytest.approx(0.05 * 1.1e-4)
    assert info.explained and "explained with shaker_coil" in rig.source and not info.notes
    assert rig.resolve(frequency_hz=200.0)["tau"] == 1.1e-4   # the effect is on when the rig is simulated


def test_unexplained_writes_the_calibrated_base_and_says_how_wrong():
    fits = {"base": _fit(BASE, {k: 0.1 * v for k, v in BASE.items()}),
            "shaker_coil": _fit({**BASE, "tau": 1e-4, "beta": 1e3}, {})}
    rig, info = corrected_rig(_diag(None, False, fits, "base", _targets()), ["lab", "lab"], "d")
    assert rig.effects == {} and rig.parameters["K1"] == 5e8
    assert rig.source.startswith(f"vibro diagnose d (drill): {UNEXPLAINED_PREFIX}")
    assert "0.21" in rig.source and "0.042" in rig.source     # held-out error against the noise floor
    assert info.explained is False and info.model_error == 0.21 and info.noise_floor == 0.042


def test_an_unexplained_rig_names_the_parameters_that_absorbed_the_missing_physics():
    from pipeline.diagnosis.report_types import Absorption

    fits = {"base": _fit(BASE, {k: 0.1 * v for k, v in BASE.items()})}
    diag = _diag(None, False, fits, "base", _targets())
    moved = {"Pr": Absorption(base=2800.0, with_=2500.0, change=0.12, effects=("shaker_coil", "guide_friction"))}
    diag = replace(diag, report=replace(diag.report, absorbed=moved))
    rig, info = corrected_rig(diag, ["lab", "lab"], "d")
    assert "may have absorbed the missing physics: Pr (+12 % against the fit with shaker_coil+guide_friction)" \
        in rig.source
    assert info.absorbed == moved and info.to_json()["absorbed"]["Pr"]["effect"] == "shaker_coil+guide_friction"


def test_the_held_out_rop_error_becomes_the_rigs_model_error():
    """The final model's held-out ROP error (relative, noise-weighted) is the rig's ``model_error``; without ROP on
    the held-out runs the rig gives none (unknown, not 0)."""
    fits = {"base": _fit(BASE, {k: 0.1 * v for k, v in BASE.items()})}
    targets = _targets((12.0, 12.0))
    targets[1].names = ["rop_m_s", "accel_m_s2:re1"]
    groups = {"final": {"rop_m_s": 0.034, "accel_m_s2": 0.2}, "noise": {"rop_m_s": 0.012, "accel_m_s2": 0.05}}
    rig, info = corrected_rig(_diag(None, True, fits, "base", targets, groups, held_out=[1, 1]), ["lab", "lab"], "d")
    assert rig.model_error.rop_rel == 0.034 and rig.model_error.noise_floor_rel == 0.012
    assert "1 held-out run" in rig.model_error.basis and "(base)" in rig.model_error.basis
    assert info.rop_model_error == rig.model_error.to_mapping()
    no_rop = {"final": {"accel_m_s2": 0.2}, "noise": {"accel_m_s2": 0.05}}
    rig, info = corrected_rig(_diag(None, True, fits, "base", targets, no_rop, held_out=[0]), ["lab", "lab"], "d")
    assert rig.model_error is None and info.rop_model_error is None


def test_runs_that_disagree_on_a_known_parameter_are_noted():
    fits = {"base": _fit(BASE, {k: 0.1 * v for k, v in BASE.items()})}
    rig, info = corrected_rig(_diag(None, True, fits, "base", _targets((12.0, 13.0))), ["lab", None], "d")
    assert rig.parameters["M1"] == 12.0
    assert any("M1" in n for n in info.notes) and any("preset" in n for n in info.notes)


def test_file_names():
    assert rig_file_name("drill", 1) == "rig.yaml"
    assert rig_file_name("indenter-metal", 2) == "rig-indenter-metal.yaml"


def test_the_terminal_summary_says_the_rigs_rop_model_error():
    from pipeline.cli.diagnose import summary_lines

    rig = RigInfo(explained=True, selected=None, source="", discrepancy=None, verdict="explained", absorbed={},
                  model_error=0.02, noise_floor=0.018, nrms=1.1,
                  rop_model_error={"rop_rel": 0.034, "noise_floor_rel": 0.012}, notes=(), file="rig.yaml")
    entry = replace(_report(None, True, rig=rig), verdict="explained")
    lines = summary_lines(DiagnoseReport("d", {}, (entry,)))
    assert "held-out ROP error 3.4 % (rms, relative; noise floor 1.2 %)" in lines[-1]
    entry = replace(entry, rig=replace(rig, rop_model_error=None))
    assert not any("model error in the rig file" in ln for ln in summary_lines(DiagnoseReport("d", {}, (entry,))))
