"""The side-by-side comparison of two recommendations (pipeline.comparison.workflow, `vibro compare`)."""
from __future__ import annotations

import json

import pytest

from pipeline.comparison.workflow import compare, markdown, model_rig
from pipeline.diagnosis.report_types import RigInfo
from sim import Rig

INPUTS = ["frequency_hz", "amplitude_n", "static_force_n"]


def _opt(point, fixed=None):
    return {"inputs": INPUTS, "tried": {"model": "drill", "preset": "lab", "fixed": fixed or {}},
            "recommendation": {"params": point, "rop_m_s_sim": 1e-3}}


LAB_BEST = {"frequency_hz": 280.0, "amplitude_n": 2700.0, "static_force_n": 1800.0}
OTHER = {"frequency_hz": 150.0, "amplitude_n": 2700.0, "static_force_n": 1800.0}


def test_model_rig_carries_the_fixed_parameters_and_effects():
    rig = model_rig(_opt(LAB_BEST, {"K1": 5e8, "tau": 1e-4, "beta": 3e3, "frequency_hz": 1.0}))
    assert rig.parameters == {"K1": 5e8} and rig.effects == {"shaker_coil": {"tau": 1e-4, "beta": 3e3}}


def test_both_points_on_both_models_and_the_worth(tmp_path):
    corrected_rig = Rig("drill", "lab", effects={"shaker_coil": {"tau": 1e-4, "beta": 3e3}},
                        uncertainty={"beta": 300.0})
    cmp = compare(_opt(LAB_BEST), _opt(OTHER, corrected_rig.overrides()), corrected_rig,
                  RigInfo(explained=False, selected=None, source="", discrepancy=None, verdict="unexplained",
                          absorbed={}, model_error=0.2, noise_floor=0.04, nrms=5.0, rop_model_error=None, notes=(),
                          file="rig.yaml"), n_samples=4,
                  settings={"window": 8})
    t = cmp["recommendations"]
    on_rig = {k: corrected_rig.simulate(**t[k]["point"], settings={"window": 8}).labels["rop_m_s"] for k in t}
    assert t["corrected"]["rop_m_s_on_corrected"] == pytest.approx(on_rig["corrected"], rel=1e-12)
    assert t["uncorrected"]["rop_m_s_on_corrected"] == pytest.approx(on_rig["uncorrected"], rel=1e-12)
    lab = Rig("drill", "lab").simulate(**LAB_BEST, settings={"window": 8}).labels["rop_m_s"]
    assert t["uncorrected"]["rop_m_s_on_uncorrected"] == pytest.approx(lab, rel=1e-12)
    # the coil changes the dynamics: the same point drills at a different rate on the two models
    assert t["uncorrected"]["rop_m_s_on_corrected"] != pytest.approx(lab, rel=1e-3)
    assert cmp["worth_mm_s"] == pytest.approx((on_rig["corrected"] - on_rig["uncorrected"]) * 1e3, rel=1e-12)
    assert cmp["spread"]["sampled"] == ["beta"] and cmp["spread"]["n_samples"] == 4
    assert cmp["explained"] is False and "known to be wrong" in cmp["warning"] and "5.0×" in cmp["warning"]
    md = markdown(cmp)
    assert "worth" in md and "Warning" in md
    json.dumps(cmp)                                       # JSON-able as it stands


def test_nothing_recommended_is_one_clear_error():
    from pipeline.core.errors import UserError

    empty = {"inputs": INPUTS, "tried": {"model": "drill", "preset": "lab"}, "recommendation": None,
             "outcome": "no feasible point"}
    with pytest.raises(UserError, match="uncorrected optimisation recommended nothing"):
        compare(empty, _opt(OTHER), Rig("drill", "lab"))


def test_the_spread_of_report_json_states_parameters_model_error_and_both():
    """A corrected rig with a model error: report.json's spread holds the three half-widths and report.md prints
    them; the combined one is the quadrature of the other two."""
    import math

    from sim import ModelError

    rig = Rig("drill", "lab", uncertainty={"Pr": 300.0}, model_error=ModelError(0.05, 0.02, "held-out ROP"))
    cmp = compare(_opt(LAB_BEST), _opt(OTHER), rig, n_samples=4, settings={"window": 8})
    s = json.loads(json.dumps(cmp))["spread"]
    assert s["model_error_rel"] == 0.05 and s["model_error_basis"] == "held-out ROP"
    assert s["combined_half_width_m_s"] == pytest.approx(
        math.hypot(s["parameter_half_width_m_s"], s["model_error_half_width_m_s"]), rel=1e-12)
    assert s["combined_half_width_m_s"] >= s["parameter_half_width_m_s"]
    assert f"combined ±{s['combined_half_width_m_s'] * 1e3:.3g} mm/s" in markdown(cmp)
