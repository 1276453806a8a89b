"""The §6 effect table (sim.models.effects) is the one declaration of every effect's parameters."""
from __future__ import annotations

import dataclasses

import pytest

import sim
from sim.models.effects import EFFECT_FIT_BOUNDS, EFFECTS, effect_params


def test_every_model_effect_has_the_tables_parameters_off_by_default():
    for name in sim.model_names():
        spec = sim.get_model(name)
        by_name = {p.name: p for p in spec.params}
        for eff, params in spec.effects.items():
            assert params == EFFECTS[eff].param_names, (name, eff)
            for p in params:
                assert by_name[p].default == 0.0 and by_name[p].nonnegative, (name, p)
                assert by_name[p].unit == EFFECT_FIT_BOUNDS[p].unit, (name, p)


def test_effect_params_say_where_the_effect_acts():
    (alpha,) = effect_params(["rate_stiffening"], {"rate_stiffening": "the stop"})
    assert alpha.name == "alpha" and alpha.unit == "s/m" and "on the stop" in alpha.description
    with pytest.raises(ValueError, match="acts_on"):
        effect_params(["rate_stiffening"], {})
    with pytest.raises(ValueError, match="unknown effect 'rust'"):
        effect_params(["rust"], {"rust": "the bit"})


def test_a_model_naming_an_unknown_effect_or_other_parameters_is_refused():
    spec = sim.get_model("pendulum")
    with pytest.raises(ValueError, match="model 'pendulum': unknown effect 'rust'"):
        dataclasses.replace(spec, effects=("rust",))
    with pytest.raises(ValueError, match="effect 'rate_stiffening' must have the parameters"):
        dataclasses.replace(spec, effects={"rate_stiffening": ("ki",)})
