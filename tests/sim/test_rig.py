"""Rig mappings (sim.rig): validation names the culprit; a rig simulates its parameters and effects."""
from __future__ import annotations

import pytest

import sim
from sim.rig import Rig


def test_round_trip_and_overrides():
    data = {"model": "drill", "preset": "lab", "parameters": {"K1": 5e8, "Pr": 2800.0},
            "effects": {"suspension_hardening": {"kappa": 3e8}}, "uncertainty": {"K1": 2e7}, "source": "test"}
    rig = Rig.from_mapping(data)
    assert rig.to_mapping() == data
    assert rig.overrides() == {"K1": 5e8, "Pr": 2800.0, "kappa": 3e8}
    values = rig.resolve(frequency_hz=250.0)
    assert values["K1"] == 5e8 and values["kappa"] == 3e8 and values["frequency_hz"] == 250.0
    assert values["M1"] == sim.get_model("drill").presets["lab"]["M1"]


def test_rig_with_effect_simulates_the_effect():
    """A rig file with an effect simulates that effect: same labels as passing the effect parameter directly."""
    rig = Rig.from_mapping({"model": "drill", "preset": "lab", "effects": {"guide_friction": {"mu": 50.0}}})
    st = {"min_transient": 20, "max_transient": 60, "window": 8}
    a = rig.simulate(settings=st).labels
    b = sim.simulate("drill", preset="lab", mu=50.0, settings=st).labels
    c = sim.simulate("drill", preset="lab", settings=st).labels
    assert a["rop_m_s"] == b["rop_m_s"]
    assert a["rop_m_s"] != c["rop_m_s"]


def test_with_values_routes_effect_parameters():
    rig = Rig.from_mapping({"model": "drill", "preset": "lab", "effects": {"tip_blunting": {"gamma": 0.01}}})
    r2 = rig.with_values({"K1": 4e8, "gamma": 0.02})
    assert r2.parameters == {"K1": 4e8} and r2.effects == {"tip_blunting": {"gamma": 0.02}}


@pytest.mark.parametrize("data, culprit", [
    ({"preset": "lab"}, "missing key 'model'"),
    ({"model": "drill", "colour": 1}, "unknown key 'colour'"),
    ({"model": "dril"}, "unknown model 'dril'"),
    ({"model": "drill", "preset": "field"}, "unknown preset 'field'"),
    ({"model": "drill", "parameters": {"K9": 1.0}}, "unknown parameter 'K9'"),
    ({"model": "drill", "parameters": {"K1": -1.0}}, "'K1'"),
    ({"model": "drill", "parameters": {"K1": "stiff"}}, "'K1'"),
    ({"model": "drill", "parameters": {"kappa": 1.0}}, "'kappa' is an effect parameter"),
    ({"model": "drill", "effects": {"shaker": {"tau": 1e-4}}}, "unknown effect 'shaker'"),
    ({"model": "drill", "effects": {"shaker_coil": {"alpha": 1.0}}}, "has no parameter 'alpha'"),
    ({"model": "drill", "effects": {"shaker_coil": 3}}, "effect 'shaker_coil' must map"),
    ({"model": "drill", "uncertainty": {"K1": -1}}, "uncertainty of 'K1'"),
    ({"model": "drill", "parameters": [1, 2]}, "'parameters' must be a mapping"),
    ({"model": "drill", "discrepancy": {"contact_quartic": 1.0}}, "discrepancy term 'contact_quartic' is not a term"),
    ({"model": "indenter-sandstone", "discrepancy": {"contact_quadratic": 1e9}}, "is not a term of model"),
    ({"model": "drill", "discrepancy": {"tool_viscous": -5.0}}, "'tool_viscous'"),
    ({"model": "drill", "discrepancy": {"tool_viscous": "x + 1"}}, "'tool_viscous' must be a number"),
    ({"model": "drill", "parameters": {"tool_viscous": 5.0}}, "give it under 'discrepancy'"),
    ({"model": "drill", "discrepancy": [1]}, "'discrepancy' must be a mapping"),
    ({"model": "drill", "model_error": 0.05}, "'model_error' must be a mapping"),
    ({"model": "drill", "model_error": {"rop": 0.05}}, "unknown model_error key 'rop'"),
    ({"model": "drill", "model_error": {"basis": "x"}}, "model_error needs rop_rel"),
    ({"model": "drill", "model_error": {"rop_rel": -0.1}}, "model_error rop_rel must be a finite number >= 0"),
    ({"model": "drill", "model_error": {"rop_rel": True}}, "model_error rop_rel"),
    ({"model": "drill", "model_error": {"rop_rel": 0.1, "basis": [1]}}, "model_error basis must be text"),
    ({"model": "drill", "model_error": {"rop_rel": 0.1, "noise_floor_rel": float("nan")}}, "noise_floor_rel"),
    ([1, 2], "expected a mapping"),
])
def test_bad_rig_names_the_culprit(data, culprit):
    with pytest.raises(sim.ParameterError, match=culprit.replace("(", r"\(")):
        Rig.from_mapping(data)


def test_rig_with_discrepancy_round_trips_and_simulates_it():
    """A rig's ``discrepancy:`` entry (an adopted proposal: term names and coefficients) survives the file layout and
    is simulated in the kernel: the same labels as the term passed directly, not the base model's."""
    data = {"model": "drill", "preset": "lab", "parameters": {"K1": 5e8}, "discrepancy": {"tool_quadratic_drag": 6e5}}
    rig = Rig.from_mapping(data)
    assert rig.to_mapping() == data and rig.overrides() == {"K1": 5e8, "tool_quadratic_drag": 6e5}
    assert rig.with_values({"tool_quadratic_drag": 7e5}).discrepancy == {"tool_quadratic_drag": 7e5}
    st = {"min_transient": 20, "max_transient": 60, "window": 8}
    a = rig.simulate(settings=st).labels
    b = sim.simulate("drill", preset="lab", K1=5e8, tool_quadratic_drag=6e5, settings=st).labels
    c = sim.simulate("drill", preset="lab", K1=5e8, settings=st).labels
    assert a["rop_m_s"] == b["rop_m_s"] and a["rop_m_s"] < 0.97 * c["rop_m_s"]     # drag slows the bit


def test_model_error_round_trips_and_survives_with_values():
    data = {"model": "drill", "preset": "lab", "parameters": {"K1": 5e8}, "uncertainty": {"K1": 2e7},
            "model_error": {"rop_rel": 0.04, "noise_floor_rel": 0.01, "basis": "held-out ROP of 3 runs"}}
    rig = Rig.from_mapping(data)
    assert rig.model_error == sim.ModelError(0.04, 0.01, "held-out ROP of 3 runs")
    assert rig.to_mapping() == data
    assert rig.with_values({"K1": 4e8}).model_error == rig.model_error
    assert Rig.from_mapping({**data, "model_error": {"rop_rel": 0.04}}).to_mapping()["model_error"] == {"rop_rel": 0.04}


def test_a_rig_without_model_error_has_none_and_writes_no_key():
    """Rig mappings from before the key: they load unchanged, the model error stays unknown (None), not 0."""
    data = {"model": "drill", "preset": "lab", "parameters": {"K1": 5e8}, "uncertainty": {"K1": 2e7}, "source": "old"}
    rig = Rig.from_mapping(data)
    assert rig.model_error is None and rig.to_mapping() == data
