"""The report speaks engineering units (mm/s, kN, W, g) and shows the diagnosis's calibrated parameters."""
from __future__ import annotations

import pytest

from pipeline.report.build import calibrated_rows, dict_table
from pipeline.core.units import convert, label


@pytest.mark.parametrize("name,text,si,shown", [
    ("rop_m_s", "ROP [mm/s]", 0.008, 8.0),
    ("rop_m_s_sim", "ROP (sim) [mm/s]", 0.008, 8.0),
    ("peak_force_n", "peak impact force [kN]", 3000.0, 3.0),
    ("power_w", "power [W]", 15.0, 15.0),            # lab-scale exciters draw watts (pipeline.core.units)
    ("peak_decel_g", "peak deceleration [g]", 40.0, 40.0),
    ("static_force_n", "static force Fs [kN]", 1200.0, 1.2),
])
def test_label_and_convert(name, text, si, shown):
    assert label(name) == text
    assert convert(name, si) == pytest.approx(shown)


def test_unknown_names_and_non_numbers_pass_through():
    assert label("status_sim") == "status_sim" and convert("rop_m_s", "ok") == "ok"


def test_dict_table_converts_columns_and_row_errors():
    t = dict_table({"rop_m_s": {"r2": 0.99, "rmse": 0.0002}, "peak_force_n": {"r2": 0.98, "rmse": 50.0}})
    assert t.columns == ["", "r2", "rmse"]
    assert t.rows[0][0] == "ROP [mm/s]" and t.rows[0][2] == pytest.approx(0.2)        # RMSE in mm/s
    assert t.rows[1][0] == "peak impact force [kN]" and t.rows[1][2] == pytest.approx(0.05)
    t = dict_table({"params": {"frequency_hz": 262.0}, "rop_m_s_sim": 0.008})
    assert ["ROP (sim) [mm/s]", pytest.approx(8.0)] in [list(r) for r in t.rows]


def _system(**changes):
    """The stored one-system report (tests/pipeline/diagnosis/data) with these fields replaced."""
    import json
    from dataclasses import replace
    from pathlib import Path

    from pipeline.diagnosis.report_types import DiagnoseReport

    path = Path(__file__).parents[1] / "diagnosis" / "data" / "report_single.json"
    return replace(DiagnoseReport.from_json(json.loads(path.read_text())).systems[0], **changes)


def _est(value, sd=None, ci95=None):
    from pipeline.diagnosis.report_types import ParamEstimate

    return ParamEstimate(value, sd if sd is not None else 0.1 * value, ci95 or (0.9 * value, 1.1 * value))


def test_calibrated_rows_list_base_and_effect_parameters_with_defaults():
    rep = _system(system="indenter-metal", calibrated={"k1": 2.0e6, "pm": 1.1},
                  calibrated_uncertainty={"k1": _est(2.0e6, 1.0e5, (1.8e6, 2.2e6)), "pm": _est(1.1, 0.05, (1.0, 1.2))},
                  selected_params={"k1": _est(2.1e6, 1e5, (1.9e6, 2.3e6)), "tau": _est(1e-4, 1e-5, (8e-5, 1.2e-4))},
                  proposal_adopted=None)
    rows = calibrated_rows(rep)
    # every value from the selected model's fit: k1 fitted with the effect, not the base-only 2.0e6
    assert [r[:2] for r in rows] == [["k1", "calibrated (with the effect)"], ["tau", "selected effect"]]
    import sim

    spec = {p.name: p for p in sim.get_model("indenter-metal").params}
    assert rows[0][2] == spec["k1"].default and rows[0][6] == spec["k1"].unit and rows[0][3] == 2.1e6
    rep = _system(system="indenter-metal", calibrated=rep.calibrated, selected_params=None, proposal_adopted=None,
                  calibrated_uncertainty={**rep.calibrated_uncertainty,
                                          "pm": _est(1.1, 0.05, (1.6e-44, 4.2e44))})   # the data cannot fix it
    rows = calibrated_rows(rep)
    assert [r[:2] for r in rows] == [["k1", "calibrated"], ["pm", "calibrated"]] and rows[0][3] == 2.0e6
    assert rows[1][5].startswith("not identifiable (") and not rows[0][5].startswith("not")


def test_calibrated_rows_name_an_adopted_discrepancy_term():
    """A diagnosis that adopted a discrepancy proposal: its term is labelled as such, not as a selected effect."""
    rep = _system(system="indenter-metal", calibrated={"k1": 2.0e6}, proposal_adopted=("tool_quadratic_drag",),
                  selected_params={"k1": _est(2.1e6), "tool_quadratic_drag": _est(3e3)})
    rows = calibrated_rows(rep)
    assert [r[:2] for r in rows] == [["k1", "calibrated (with the effect)"],
                                     ["tool_quadratic_drag", "adopted discrepancy term"]]


def test_calibrated_rows_name_the_adopted_modes_parameters():
    """An adopted hidden load-path mode: each of its three parameters is labelled as the adopted term's."""
    rep = _system(calibrated={"K1": 2.0e8}, proposal_adopted=("load_path_mode",),
                  selected_params={"K1": _est(2.1e8),
                                   **{n: _est(v) for n, v in (("load_path_mode_ratio", 0.25),
                                                              ("load_path_mode_hz", 1000.0),
                                                              ("load_path_mode_zeta", 0.05))}})
    rows = calibrated_rows(rep)
    assert [r[1] for r in rows] == ["calibrated (with the effect)"] + ["adopted discrepancy term"] * 3