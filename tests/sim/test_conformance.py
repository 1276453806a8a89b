"""Conformance suite: every registered model (``sim.model_names()``) passes the same checks.

Adding a model = one file in sim/models/ + its reference in tests/reference_solutions.py; this suite then
runs on it with no edit.  Adding an effect to a model = one entry in the model's ``EFFECTS`` list (its parameters follow from
sim/models/effects.py), its term from sim/models/terms.py in the right-hand side, and a visible strength in
``SynthRig.effect_strengths``;
``test_conformance_effect_visible_and_off_at_zero`` then checks the pair.  Select the suite with
``pytest -k conformance``.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import sim
from vibrobase.statuses import STATUSES
from sim.models.base import MAP_KINDS
from tests.reference_solutions import MODELS as REFERENCE_MODELS
from tests.reference_solutions import reference_run

MODELS = sim.model_names()
# Short, fixed transient/window: the same trajectory for simulator and reference, cheap for every model.
SHORT = {"min_transient": 10, "max_transient": 10, "window": 4}


@pytest.fixture(scope="module", params=MODELS)
def spec(request):
    return sim.get_model(request.param)


def test_conformance_registry_matches_reference():
    """Every model has an independent reference (the second half of 'a new model is one file plus its reference')."""
    assert set(MODELS) == set(REFERENCE_MODELS)


def test_conformance_spec_consistency(spec):
    names = spec.param_names
    assert len(set(names)) == len(names) and spec.name in MODELS
    assert len(spec.states) > 0 and len(spec.bounded) == spec.n_bounded
    base = spec.resolve()
    for preset in [None, *spec.presets]:
        values = spec.resolve(preset)
        assert set(values) == set(names) and all(math.isfinite(v) for v in values.values())
    for b in spec.calibratable:                    # the default lies inside its fit bounds
        assert b.lo <= base[b.name] <= b.hi, b
    for eff, params in spec.effects.items():       # every effect is off (0) by default and has fit bounds
        for p in params:
            assert base[p] == 0.0 and p in spec.effect_bounds, (eff, p)
    for preset, space in spec.search_spaces.items():   # a search space holds resolvable points
        corner = {n: hi for n, (lo, hi) in space.items()}
        spec.resolve(preset or None, **corner)
    assert spec.map_kind in ("",) + MAP_KINDS
    assert set(spec.map_relative_to) <= set(spec.map_ranges)
    floor = spec.progress_force_floor(base)
    assert floor is None or floor > 0


def test_conformance_spec_synth_rig(spec):
    """`vibro synth`'s rig (ModelSpec.synth) resolves at every default run, and its check rejects a broken rig."""
    import dataclasses

    rig = spec.synth
    if rig is None:
        pytest.skip(f"{spec.name} has no synthetic rig")
    for f in rig.frequencies_hz:
        for lev in rig.levels:
            controls = dict(rig.forcing(f, lev)) if rig.forcing else {rig.level_name: lev}
            spec.resolve(rig.preset, frequency_hz=f, **controls, **rig.fixed)
    if rig.hertz_model is not None:
        assert {"kl", "ku", "nl", "nu"} <= set(sim.get_model(rig.hertz_model).param_names)
    broken = [dataclasses.replace(rig, level_name="no_such_control", forcing=None),
              dataclasses.replace(rig, fixed={**rig.fixed, "no_such_param": 1.0}),
              dataclasses.replace(rig, effect_strengths={}) if spec.effects else None,
              dataclasses.replace(rig, signals=("strain",))]
    for bad in [b for b in broken if b is not None]:
        with pytest.raises(ValueError, match=f"model '{spec.name}' synth rig"):
            dataclasses.replace(spec, synth=bad)


def test_conformance_guards_fill_n_guards_from_guard_states(spec):
    """``guards`` writes every entry of a vector of length N_GUARDS (its module's constant) and no more, and reads
    no state outside GUARD_STATES, in every phase.  The kernel checks exactly N_GUARDS guards after each step (a
    phase writing a further guard would write past its vector: numba checks no bounds; one leaving an entry unset
    would read stale memory) and interpolates only the GUARD_STATES inside a step (a guard reading another state
    would see a stale value: here a NaN, which spreads into the guard)."""
    import sys

    from sim.api import _prepare
    from sim.jit import interpreted

    module = sys.modules[spec.funcs[1].py_func.__module__]
    n = module.N_GUARDS
    assert isinstance(n, int) and n >= 1
    p, y, z, _, period, _ = _prepare(spec, spec.resolve(), 1e-7)
    guards = interpreted(spec.funcs[1])
    rng = np.random.default_rng(0)
    read = list(module.GUARD_STATES)
    assert read and all(0 <= i < len(y) for i in read)
    others = [i for i in range(len(y)) if i not in read]
    for ph in range(4):                       # every phase of every model (drill and sandstone: 0-2), and one more
        for _ in range(3):
            yy = y + 1e-4 * rng.standard_normal(y.shape)
            g = np.full(n, np.nan)
            guards(0.3 * period, yy, z.copy(), ph, p, g)      # interpreted: a write past n raises IndexError
            assert np.all(np.isfinite(g)), (ph, g)
            stale = yy.copy()
            stale[others] = np.nan
            g_stale = np.full(n, np.nan)
            guards(0.3 * period, stale, z.copy(), ph, p, g_stale)
            assert np.array_equal(g_stale, g), (ph, g, g_stale)


def test_conformance_defaults_simulate(spec):
    r = sim.simulate(spec.name, settings=SHORT)
    assert r.status in STATUSES and r.status != "failed", r.labels.get("reason")
    assert math.isfinite(r.labels["peak_force_n"]) and r.labels["peak_force_n"] >= 0.0


def test_conformance_deterministic(spec):
    a = sim.simulate(spec.name, settings=SHORT).labels
    b = sim.simulate(spec.name, settings=SHORT).labels
    assert a == b


def test_conformance_batch_equals_single(spec):
    f0 = spec.resolve()["frequency_hz"]
    rows = [{"frequency_hz": f0}, {"frequency_hz": 1.1 * f0}]
    df = sim.simulate_batch(spec.name, rows, settings=SHORT, n_threads=2)
    for i, row in enumerate(rows):
        single = sim.simulate(spec.name, settings=SHORT, **row).labels
        assert df.loc[i, "status"] == single["status"]
        for lab in ("rop_m_s", "peak_force_n", "impacts_per_cycle"):
            a, b = df.loc[i, lab], single[lab]
            assert (a == b) or (np.isnan(a) and np.isnan(b)) or (a is None and b is None), (lab, a, b)


def test_conformance_effects_off_change_nothing(spec):
    """Every effect parameter explicitly at 0 gives exactly the base model's result."""
    if not spec.effects:
        pytest.skip(f"{spec.name} has no effects")
    off = {p: 0.0 for ps in spec.effects.values() for p in ps}
    assert sim.simulate(spec.name, settings=SHORT, **off).labels == sim.simulate(spec.name, settings=SHORT).labels


EFFECT_PAIRS = [(m, e) for m in MODELS for e in sim.get_model(m).effects]
LABELS_MOVED = ("rop_m_s", "peak_force_n", "mean_peak_force_n", "peak_decel_g", "energy_per_cycle_j")
VISIBLE = 1e-3      # an effect at its visible strength moves some label by more than this (relative, short run)


@functools.lru_cache(maxsize=None)
def _base_run(model: str):
    spec = sim.get_model(model)
    return sim.simulate(model, preset=spec.synth.preset, settings=SHORT)


@pytest.mark.parametrize(("model", "effect"), EFFECT_PAIRS)
def test_conformance_effect_visible_and_off_at_zero(model, effect):
    """Every effect a model declares (``ModelSpec.effects``): at its visible strength (``SynthRig.effect_strengths``)
    it moves the labels; with its parameters at 0 the labels and final state are the base model's, bit for bit."""
    spec = sim.get_model(model)
    assert spec.synth is not None, f"{model} declares effects but no visible strengths (SynthRig.effect_strengths)"
    strength = spec.synth.effect_strengths[effect]
    base = _base_run(model)
    off = sim.simulate(model, preset=spec.synth.preset, settings=SHORT, **{p: 0.0 for p in strength})
    assert off.labels == base.labels
    assert all(np.array_equal(a, b) for a, b in zip(off.final_state, base.final_state))
    on = sim.simulate(model, preset=spec.synth.preset, settings=SHORT, **strength).labels
    assert on["status"] != "failed", on.get("reason")
    moved = max(abs(on[k] - base.labels[k]) / max(abs(base.labels[k]), 1e-300) for k in LABELS_MOVED
                if on[k] is not None and base.labels[k] is not None)
    assert moved > VISIBLE, f"{effect} {strength}: labels move by only {moved:.2e}"


def test_conformance_agrees_with_reference(spec):
    """One case per model against the independent scipy reference (DOP853, rtol 1e-10); tolerances as in
    tests/sim/test_validation.py (ROP and peak force within 1 %, impacts per cycle equal)."""
    params = {k: v for k, v in spec.resolve().items() if k not in ("P", "D")}
    ref = reference_run(spec.name, params, SHORT["min_transient"], SHORT["window"], method="DOP853", rtol=1e-10)
    got = sim.simulate(spec.name, settings=SHORT).labels
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"]
    assert got["peak_force_n"] == pytest.approx(ref["peak_force_n"], rel=1e-2, abs=1e-9)
    assert got["rop_m_s"] == pytest.approx(ref["rop_m_s"], rel=1e-2, abs=1e-9)


@pytest.mark.parametrize("model", [m for m in MODELS if sim.get_model(m).exact is not None])
def test_conformance_exact_propagator_interface(model):
    """A model's exact propagator (``spec.exact``, sim/exact/) names the template functions it replaces (the whole
    stepper, or the free-phase hook), says whether every phase is exact, handles only the model's own effect
    parameters, applies with every effect off, and agrees with the numerical path at a tight tolerance."""
    import importlib

    spec = sim.get_model(model)

    mod = importlib.import_module(spec.exact)
    whole = {"integrate_cycles", "make_workspace"}
    hook = {"HYBRID", "exact_ok", "exact_free", "make_workspace"}
    assert set(mod.REPLACES) == whole or hook <= set(mod.REPLACES) <= hook | {"step_hint"}   # the hint: optional
    assert mod.EVERY_PHASE == (set(mod.REPLACES) == whole)
    effect_params = {n for names in spec.effects.values() for n in names}
    assert set(mod.HANDLED_EFFECT_PARAMS) <= effect_params
    assert mod.exact_applies({n: 0.0 for n in effect_params}, spec.effects)
    st = {**SHORT, "rtol": 1e-11}
    a = sim.simulate(spec.name, settings={**st, "method": "exact"}).labels
    b = sim.simulate(spec.name, settings={**st, "method": "dopri5"}).labels
    assert a["status"] == b["status"] and a["impacts_per_cycle"] == b["impacts_per_cycle"]
    for k in ("rop_m_s", "peak_force_n", "peak_decel_g", "energy_per_cycle_j"):
        assert a[k] == pytest.approx(b[k], rel=1e-7, abs=1e-15), k


@pytest.mark.parametrize("model,term", [(m, t) for m in MODELS for t in sim.get_model(m).discrepancy])
def test_conformance_discrepancy_term_visible_and_off_at_zero(model, term):
    """Every discrepancy parameter a model declares (``ModelSpec.discrepancy``, sim/models/discrepancy.py): a
    vocabulary parameter with fit bounds; at 0 the labels and final state are the base model's bit for bit; at its
    probe strength (the start of the diagnosis' screening; a structured candidate's parameters all at theirs) it
    moves the labels without failing the run."""
    from sim.models.discrepancy import probe_value
    from sim.models.discrepancy import CANDIDATES, PARAM_OF

    spec = sim.get_model(model)
    assert term in PARAM_OF and 0.0 < spec.discrepancy_bounds[term].lo < spec.discrepancy_bounds[term].hi
    preset = spec.synth.preset if spec.synth else None
    base = _base_run(model)
    off = sim.simulate(model, preset=preset, settings=SHORT, **{term: 0.0})
    assert off.labels == base.labels
    assert all(np.array_equal(a, b) for a, b in zip(off.final_state, base.final_state))
    probe = {q: probe_value(spec.discrepancy_bounds[q]) for q in CANDIDATES[PARAM_OF[term]].params}
    on = sim.simulate(model, preset=preset, settings=SHORT, **probe).labels
    assert on["status"] != "failed", on.get("reason")
    moved = max(abs(on[k] - base.labels[k]) / max(abs(base.labels[k]), 1e-300) for k in LABELS_MOVED
                if on[k] is not None and base.labels[k] is not None)
    assert moved > VISIBLE, f"{term}: labels move by only {moved:.2e}"


@pytest.mark.parametrize("model", MODELS)
def test_conformance_discrepancy_term_a_model_lacks_is_refused(model):
    """A vocabulary term the model does not declare cannot be switched on silently: one line naming it."""
    from sim.models.discrepancy import PARAM_OF

    spec = sim.get_model(model)
    lacking = [t for t in PARAM_OF if t not in spec.discrepancy and t in spec.param_names]
    for t in lacking:
        with pytest.raises(sim.ParameterError, match=f"discrepancy term '{t}' does not apply"):
            spec.resolve(**{t: 1.0})
