"""The MODELS.md §6 effects, each declared once: its parameters (unit, meaning, default fit bounds) and its form.

A model lists the effects it has by name (``ModelSpec.effects``); ``effect_params`` turns that list into the
model's parameters (each off at 0, ≥ 0), and ``ModelSpec`` maps each effect to its parameter names and fills
their fit bounds from here.  The terms themselves are in ``sim.models.terms`` (``sensor_lowpass`` acts on the
recorded signal: ``sim.models.sensor``).  An effect is off at 0; a log10 fit approaches "off" by its lower
bound, where it no longer changes the response measurably.  A model may override a bound in its own
``ModelSpec.effect_bounds``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Mapping

from sim.models.fitbound import FitBound
from sim.models.param import Param


@dataclass(frozen=True)
class EffectParam:
    """One parameter of an effect: default fit bounds [SI] (``bound.name`` is the parameter) and its meaning."""

    bound: FitBound
    meaning: str
    least: float = 0.0      # smallest physical value when on (0 is off); below it the effect means nothing


@dataclass(frozen=True)
class Effect:
    """A §6 effect: ``name``, its parameters and ``form``, the term in symbols (k, φ, δ̇ stand for the model's own)."""

    name: str
    params: tuple[EffectParam, ...]
    form: str

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.bound.name for p in self.params)


EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect("shaker_coil", (EffectParam(FitBound("tau", 1e-5, 1e-2, "s"), "electrical time constant L/R"),
                           EffectParam(FitBound("beta", 1.0, 3e3, "N s/m"), "back-EMF damping (Bl)^2/R")),
           "τ Ḟ + F = F_ideal − β Δv"),
    Effect("rate_stiffening", (EffectParam(FitBound("alpha", 1e-3, 30.0, "s/m"), "stiffening per unit penetration rate"),),
           "k -> k (1 + α max(δ̇, 0))"),
    Effect("guide_friction", (EffectParam(FitBound("mu", 0.1, 300.0, "N"), "Coulomb friction force"),),
           "μ tanh(Δv / v_eps)"),
    Effect("tip_blunting", (EffectParam(FitBound("gamma", 1e-4, 0.5, "-"), "growth per mm of progression"),),
           "k -> k (1 + γ progression / 1 mm)"),
    Effect("suspension_hardening", (EffectParam(FitBound("kappa", 1e2, 1e8, "1/m^2"), "cubic hardening"),),
           "k φ -> k φ (1 + κ φ²)"),
    Effect("sensor_lowpass", (EffectParam(FitBound("fc", 50.0, 5000.0, "Hz"), "accelerometer bandwidth", least=1.0),),
           "2nd-order Butterworth on the recorded acceleration"),
)}

EFFECT_FIT_BOUNDS: dict[str, FitBound] = {p.bound.name: p.bound for e in EFFECTS.values() for p in e.params}
"""Default fit bounds of every effect parameter, by parameter name."""


def effect(name: str) -> Effect:
    """The effect ``name`` (ValueError naming the known ones otherwise)."""
    if name not in EFFECTS:
        raise ValueError(f"unknown effect '{name}'; known: {', '.join(EFFECTS)}")
    return EFFECTS[name]


def effect_params(names: Iterable[str], acts_on: Mapping[str, str]) -> tuple[Param, ...]:
    """The parameters of the effects ``names``, in that order: each 0 (off) by default and ≥ 0.
    ``acts_on[effect]`` says where the effect acts in this model (e.g. "K1, δ̇ = ẋ1 in phase II")."""
    out = []
    for name in names:
        e = effect(name)
        if name not in acts_on:
            raise ValueError(f"effect '{name}': say where it acts in the model (acts_on)")
        for p in e.params:
            text = f"{name}: {p.meaning}, {e.form} on {acts_on[name]}; 0 = off"
            out.append(Param(p.bound.name, 0.0, p.bound.unit, text, nonnegative=True, least=p.least))
    return tuple(out)
