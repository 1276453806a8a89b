"""The ranges each model and preset was validated on (ModelSpec.validated) and the warning naming a likely slip."""
from __future__ import annotations

import math

import pytest

import sim
from sim.models.ranges import unit_slip

MODELS = sim.model_names()


@pytest.mark.parametrize("model", MODELS)
def test_every_model_declares_its_validated_ranges_and_its_presets_lie_inside(model):
    """Each model validates its controls somewhere, and every preset's controls lie inside the ranges that apply to
    it (its own entry, else the defaults'): a preset's ranges describe it."""
    spec = sim.get_model(model)
    assert spec.validated.get("") or any(spec.validated.values()), model
    for preset in [None, *spec.presets]:
        values = spec.resolve(preset)
        ranges = spec.validated.get(preset, spec.validated.get("", {}))
        assert spec.out_of_range(preset, {k: values[k] for k in ranges}) == [], (model, preset)


@pytest.mark.parametrize("value, rng, unit, slip", [
    ((0.3, 0.3), (100.0, 450.0), "Hz", "kHz?"),
    ((300e3, 300e3), (100.0, 450.0), "Hz", "mHz?"),
    ((1500.0, 1500.0), (100.0, 450.0), "Hz", "rad/s?"),
    ((2.25, 2.25), (1800.0, 2700.0), "N", "kN?"),
    ((1.0, 1.0), (0.0, 3e-3), "m", "mm?"),
    ((60000.0, 60000.0), (10.0, 100.0), "kg", "g?"),
    ((6e11, 6e11), (2e6, 6e9), "N/m", "1000x too large?"),
    ((0.1, 0.45), (100.0, 450.0), "Hz", "kHz?"),
    ((5000.0, 5000.0), (100.0, 450.0), "Hz", ""),
])
def test_unit_slip_names_the_likely_unit(value, rng, unit, slip):
    assert unit_slip(*value, *rng, unit) == slip


def test_warning_text():
    spec = sim.get_model("drill")
    assert spec.out_of_range("lab", {"frequency_hz": 0.3}) == ["frequency_hz 0.3 is outside 100–450 Hz of preset lab: "
                                                             "kHz?"]
    assert spec.out_of_range(None, {"frequency_hz": 5000.0, "amplitude_n": 10.0}) == [
        "frequency_hz 5000 is outside 10–400 Hz of model drill (the model was not validated there)"]
    assert spec.out_of_range("seed-003", {"frequency_hz": 0.5}) == []     # the seed's own table: one point
    assert spec.out_of_range("lab", {"M1": 1e6}) == []                    # no validated range declared
    assert spec.out_of_range("lab", {"frequency_hz": (50.0, 300.0)})[0].startswith("frequency_hz 50–300 is outside")
    assert math.isfinite(spec.validated["lab"]["frequency_hz"][1])


def test_a_bad_declaration_is_refused():
    import dataclasses

    spec = sim.get_model("drill")
    with pytest.raises(ValueError, match="validated ranges for unknown preset 'nope'"):
        dataclasses.replace(spec, validated={"nope": {"frequency_hz": (1.0, 2.0)}})
    with pytest.raises(ValueError, match="bad range frequency_hz"):
        dataclasses.replace(spec, validated={"": {"frequency_hz": (2.0, 1.0)}})
