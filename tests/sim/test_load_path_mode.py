"""The structured discrepancy candidate ``load_path_mode`` (sim/models/discrepancy.py: a hidden mass on a spring and
damper at the impacting mass, two more states) against the independent generator's ``load_path_mode``
(tests/independent/dynamics.py ``with_load_path_mode``: the scipy reference with event location, sharing no code
with ``sim``), which parametrises the same physics by the hidden mass mh [kg] instead of its ratio to the
impacting mass.

At the strengths of the independent rigs (tests/independent/rigs.py ``outside["load_path_mode"]``, each chosen there
to move the labels by 5-60 %), on the fixed cycles from rest of tests/sim/test_reference_effects.py, simulator at
rtol 1e-10: every label within 1e-6 of the reference (the tolerance of the §6 effects' comparison).
"""
from __future__ import annotations

import numpy as np
import pytest

import sim
from tests.independent.dynamics import with_load_path_mode
from tests.independent.rigs import RIGS
from tests.reference_solutions import reference_run
from tests.sim.test_discrepancy_terms import PARAMS
from tests.sim.test_reference_effects import LABELS, POINTS, REL, SIM_RTOL

# the impacting mass of each model and its value at PARAMS (the ratio's denominator)
IMPACTING = {"indenter-metal": "m1", "indenter-sandstone": "m1", "drill": "M1", "pendulum": "m", "rimd": "m2"}
MODELS = sorted(POINTS)


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300) if a != b else 0.0


def _mode(model: str) -> tuple[dict, dict]:
    """(the generator's parameters, the simulator's) of the rig's hidden mode."""
    g = RIGS[model].outside["load_path_mode"]
    m_imp = PARAMS[model][IMPACTING[model]]
    return g, {"load_path_mode_ratio": g["mh"] / m_imp, "load_path_mode_hz": g["fh_hz"],
               "load_path_mode_zeta": g["zeta_h"]}


@pytest.mark.parametrize("model", MODELS)
def test_load_path_mode_against_the_independent_generator(model):
    g, s = _mode(model)
    preset, n, w = POINTS[model]
    got = sim.simulate(model, preset=preset, settings={"min_transient": n, "max_transient": n, "window": w,
                                                       "rtol": SIM_RTOL}, **s).labels
    ref = reference_run(with_load_path_mode(model), {**PARAMS[model], **g}, n, w, method="DOP853", rtol=1e-10)
    base = reference_run(model, PARAMS[model], n, w, method="DOP853", rtol=1e-10)
    assert got["status"] in ("ok", "aperiodic", "not_settled") and ref["status"] == "ok"
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    # the mode is visible: some label moves by > 1 % against the base model
    assert max(_rel(ref[k], base[k]) for k in LABELS if base[k]) > 1e-2
    for k in LABELS:
        assert _rel(got[k], ref[k]) <= REL, (k, got[k], ref[k])


@pytest.mark.parametrize("model", MODELS)
def test_load_path_mode_off_is_the_base_model_bit_for_bit(model):
    """The ratio 0 switches the mode off whatever its frequency and damping: the base model's labels and final
    state exactly (the hidden states stay at rest and out of the error norm)."""
    preset, n, w = POINTS[model]
    st = {"min_transient": n, "max_transient": n, "window": w}
    base = sim.simulate(model, preset=preset, settings=st)
    off = sim.simulate(model, preset=preset, settings={**st, "method": "dopri5"}, load_path_mode_ratio=0.0,
                       load_path_mode_hz=300.0, load_path_mode_zeta=0.05)
    ref = sim.simulate(model, preset=preset, settings={**st, "method": "dopri5"})
    assert off.labels == ref.labels
    assert all(np.array_equal(a, b) for a, b in zip(off.final_state, ref.final_state))
    assert len(base.final_state[0]) == len(sim.get_model(model).states)


def test_a_mode_without_a_frequency_is_refused():
    with pytest.raises(sim.ParameterError, match="'load_path_mode_hz' must be > 0"):
        sim.get_model("drill").resolve("lab", load_path_mode_ratio=0.25)


def test_a_rig_file_carries_the_mode():
    """The hidden mode's three parameters are a rig's ``discrepancy:`` entry like any term, and round-trip."""
    _, s = _mode("drill")
    rig = sim.Rig(model="drill", preset="lab", discrepancy=s)
    back = sim.Rig.from_mapping(rig.to_mapping())
    assert back.discrepancy == s and back.overrides() == rig.overrides()
    with pytest.raises(sim.ParameterError, match="give it under 'discrepancy'"):
        sim.Rig(model="drill", preset="lab", parameters={"load_path_mode_hz": 1000.0})
