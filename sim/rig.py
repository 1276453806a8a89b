"""A rig: one model with its known parameters, calibrated parameters and switched-on effects.

A rig is what a user means by "my machine": the model (MODELS.md §1-4), an optional preset, parameter
values that override the preset, the §6 effects that are on with their parameters, and where it came
from.  It is the in-memory form of a rig file (``--rig FILE``, docs/commands.md "Rig files"); the diagnosis
writes the corrected rig in the same form.  Controls (``frequency_hz``, ``amplitude_n``, ...) are
given per simulation, on top of the rig.

Only mappings here: reading and writing YAML is the command layer's job.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterator, Mapping

from sim.empirical import EmpiricalCorrection
from sim.models.param import ParameterError, check_known_keys
from vibrobase.errors import did_you_mean
from sim.models.discrepancy import PARAM_OF as DISCREPANCY_PARAMS
from sim.registry import get_model, model_names

RIG_KEYS = ("model", "preset", "parameters", "effects", "discrepancy", "uncertainty", "model_error",
            "empirical_correction", "source")
"""Keys of a rig mapping; ``model`` is required, the others optional."""
MODEL_ERROR_KEYS = ("rop_rel", "noise_floor_rel", "basis")
"""Keys of a rig's ``model_error`` mapping; ``rop_rel`` is required."""


def _nonnegative(v: Any, what: str) -> float:
    """``v`` as a finite float >= 0, else ParameterError naming ``what``."""
    try:
        ok = not isinstance(v, bool) and math.isfinite(float(v)) and float(v) >= 0.0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ParameterError(f"rig: {what} must be a finite number >= 0, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class ModelError:
    """What the model still gets wrong about ROP once its parameters are fitted (dimensionless, relative to ROP).

    ``rop_rel``: relative sd of the model's ROP against the rig [1] (the diagnosis's held-out rms ROP error);
    ``noise_floor_rel``: the same for a residual of pure measurement noise [1], None if not known;
    ``basis``: where the number comes from, in words.
    """

    rop_rel: float
    noise_floor_rel: float | None = None
    basis: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "rop_rel", _nonnegative(self.rop_rel, "model_error rop_rel"))
        if self.noise_floor_rel is not None:
            object.__setattr__(self, "noise_floor_rel",
                               _nonnegative(self.noise_floor_rel, "model_error noise_floor_rel"))
        if not isinstance(self.basis, str):
            raise ParameterError(f"rig: model_error basis must be text, got {self.basis!r}")

    def to_mapping(self) -> dict[str, Any]:
        """Plain mapping in the rig-file layout."""
        out: dict[str, Any] = {"rop_rel": self.rop_rel}
        if self.noise_floor_rel is not None:
            out["noise_floor_rel"] = self.noise_floor_rel
        if self.basis:
            out["basis"] = self.basis
        return out

    @classmethod
    def from_mapping(cls, data: Any) -> "ModelError":
        """Validated model error from a rig file's ``model_error`` mapping (keys :data:`MODEL_ERROR_KEYS`)."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"rig: 'model_error' must be a mapping ({', '.join(MODEL_ERROR_KEYS)}), got {data!r}")
        check_known_keys(data, MODEL_ERROR_KEYS, "model_error key")
        if "rop_rel" not in data:
            raise ParameterError("rig: model_error needs rop_rel (relative sd of the model's ROP)")
        basis = data.get("basis")
        return cls(rop_rel=data["rop_rel"], noise_floor_rel=data.get("noise_floor_rel"),
                   basis="" if basis is None else basis)


@dataclass(frozen=True)
class Rig:
    """A model plus its known and calibrated parameters and active effects (all values SI).

    ``parameters``: parameter name -> value, overriding the preset.  ``effects``: §6 effect name ->
    {effect parameter -> value}.  ``discrepancy``: parameter of the fixed vocabulary (sim.models.discrepancy: a
    term, or one of the hidden mode's three) -> value, an adopted proposal of the diagnosis (names and numbers only, never an expression).
    ``uncertainty``: parameter (or effect parameter) name -> standard deviation of its fitted value [same unit].
    ``model_error``: what the fitted model still gets wrong about ROP (:class:`ModelError`), None when not given.
    ``empirical``: a correction of the model's ROP fitted to the measurements where no physics explained them
    (:class:`sim.empirical.EmpiricalCorrection`, rig-file key ``empirical_correction``), None when not given.
    The constructor validates every name and value against the model's ``ModelSpec`` and raises ``ParameterError``
    naming the culprit.
    """

    model: str
    preset: str | None = None
    parameters: Mapping[str, float] = field(default_factory=dict)
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    uncertainty: Mapping[str, float] = field(default_factory=dict)
    source: str = ""
    discrepancy: Mapping[str, float] = field(default_factory=dict)
    model_error: ModelError | None = None
    empirical: EmpiricalCorrection | None = None

    def __post_init__(self) -> None:
        if self.empirical is not None and not isinstance(self.empirical, EmpiricalCorrection):
            raise ParameterError(f"rig: empirical must be an EmpiricalCorrection, got {type(self.empirical).__name__}")
        if self.model_error is not None and not isinstance(self.model_error, ModelError):
            raise ParameterError(f"rig: model_error must be a ModelError, got {type(self.model_error).__name__}")
        if self.model not in model_names():
            raise ParameterError(f"rig: unknown model '{self.model}'{did_you_mean(self.model, model_names())}; "
                                 f"known models: {', '.join(model_names())}")
        spec = get_model(self.model)
        spec.defaults(self.preset)                      # unknown preset -> ParameterError naming the known ones
        known = set(spec.param_names)
        spec.check_names(self.parameters, "rig")
        effect_params = {p for ps in spec.effects.values() for p in ps}
        for name in self.parameters:
            if name in DISCREPANCY_PARAMS:
                raise ParameterError(f"rig: '{name}' is a discrepancy term; give it under 'discrepancy' "
                                     f"({{{name}: value}})")
            if name in effect_params:
                raise ParameterError(f"rig: '{name}' is an effect parameter; give it under 'effects' "
                                     f"({self._effect_of(spec, name)}: {{{name}: value}})")
        for eff, vals in self.effects.items():
            if eff not in spec.effects:
                raise ParameterError(f"rig: unknown effect '{eff}' for model '{self.model}'"
                                     f"{did_you_mean(eff, spec.effects)}; known: {', '.join(spec.effects) or 'none'}")
            if not isinstance(vals, Mapping):
                raise ParameterError(f"rig: effect '{eff}' must map its parameters to values, e.g. "
                                     f"{{{spec.effects[eff][0]}: value}}; got {vals!r}")
            if not vals:        # its parameters would keep their defaults (off): the effect would be ignored
                raise ParameterError(f"rig: effect '{eff}' gives no parameters, so it would stay off; give "
                                     f"{{{', '.join(f'{n}: value' for n in spec.effects[eff])}}} or remove it")
            for name in vals:
                if name not in spec.effects[eff]:
                    raise ParameterError(f"rig: effect '{eff}' has no parameter '{name}'"
                                         f"{did_you_mean(name, spec.effects[eff])}; "
                                         f"its parameters: {', '.join(spec.effects[eff])}")
        for name in self.discrepancy:
            if name not in spec.discrepancy:
                raise ParameterError(f"rig: discrepancy term '{name}' is not a term of model '{self.model}'"
                                     f"{did_you_mean(name, spec.discrepancy)}; "
                                     f"its terms: {', '.join(spec.discrepancy) or 'none'}")
        for what, v in self._values():
            if isinstance(v, bool):     # YAML's true/false would pass float() as 1/0
                raise ParameterError(f"rig: {what} must be a number, got {str(v).lower()} (a yes/no, not a value)")
        for name, sd in self.uncertainty.items():
            if name not in known:
                raise ParameterError(f"rig: uncertainty of unknown parameter '{name}' for model '{self.model}'"
                                     f"{did_you_mean(name, spec.param_names)}")
            try:
                ok = math.isfinite(float(sd)) and float(sd) >= 0.0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ParameterError(f"rig: uncertainty of '{name}' must be a finite number >= 0, got {sd!r}")
        spec.resolve(self.preset, **self.overrides())   # every value validated by its Param

    def _values(self) -> Iterator[tuple[str, Any]]:
        """(what, value) of every value the rig gives, ``what`` naming it for a message."""
        yield from ((f"parameter '{n}'", v) for n, v in self.parameters.items())
        for eff, vals in self.effects.items():
            yield from ((f"effect '{eff}' parameter '{n}'", v) for n, v in vals.items())
        yield from ((f"discrepancy term '{n}'", v) for n, v in self.discrepancy.items())
        yield from ((f"uncertainty of '{n}'", v) for n, v in self.uncertainty.items())

    @staticmethod
    def _effect_of(spec, name: str) -> str:
        return next(eff for eff, ps in spec.effects.items() if name in ps)

    def overrides(self) -> dict[str, float]:
        """Parameter overrides of this rig (parameters, effect parameters, discrepancy terms), for ``sim.simulate``."""
        out = dict(self.parameters)
        for vals in self.effects.values():
            out.update(vals)
        out.update(self.discrepancy)
        return out

    def resolve(self, **controls: float) -> dict[str, float]:
        """Full validated parameter dict of this rig with ``controls`` (and any other overrides) on top."""
        return get_model(self.model).resolve(self.preset, **{**self.overrides(), **controls})

    def simulate(self, **kwargs: Any):
        """``sim.simulate`` of this rig; keyword arguments are controls, parameters, ``settings``, ``history``."""
        from sim.api import simulate

        return simulate(self.model, preset=self.preset, **{**self.overrides(), **kwargs})

    def with_values(self, values: Mapping[str, float]) -> "Rig":
        """A copy with some parameters or effect parameters replaced (e.g. a sample of fitted values)."""
        spec = get_model(self.model)
        params = dict(self.parameters)
        effects = {e: dict(v) for e, v in self.effects.items()}
        terms = dict(self.discrepancy)
        for name, v in values.items():
            eff = next((e for e, ps in spec.effects.items() if name in ps), None)
            if name in spec.discrepancy:
                terms[name] = float(v)
            elif eff is None:
                params[name] = float(v)
            else:
                effects.setdefault(eff, {})[name] = float(v)
        return Rig(self.model, self.preset, params, effects, dict(self.uncertainty), self.source, terms,
                   self.model_error, self.empirical)

    def to_mapping(self) -> dict[str, Any]:
        """Plain mapping in the rig-file layout (inverse of :meth:`from_mapping`)."""
        out: dict[str, Any] = {"model": self.model}
        if self.preset is not None:
            out["preset"] = self.preset
        out["parameters"] = {k: float(v) for k, v in self.parameters.items()}
        if self.effects:
            out["effects"] = {e: {k: float(v) for k, v in vals.items()} for e, vals in self.effects.items()}
        if self.discrepancy:
            out["discrepancy"] = {k: float(v) for k, v in self.discrepancy.items()}
        if self.uncertainty:
            out["uncertainty"] = {k: float(v) for k, v in self.uncertainty.items()}
        if self.model_error is not None:
            out["model_error"] = self.model_error.to_mapping()
        if self.empirical is not None:
            out["empirical_correction"] = self.empirical.to_mapping()
        if self.source:
            out["source"] = self.source
        return out

    @classmethod
    def from_mapping(cls, data: Any) -> "Rig":
        """Validated rig from a rig-file mapping (keys :data:`RIG_KEYS`)."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"rig: expected a mapping with keys {', '.join(RIG_KEYS)}, got {type(data).__name__}")
        check_known_keys(data, RIG_KEYS, "key")
        if "model" not in data:
            raise ParameterError("rig: missing key 'model'")
        for key in ("parameters", "effects", "discrepancy", "uncertainty"):
            if data.get(key) is not None and not isinstance(data[key], Mapping):
                raise ParameterError(f"rig: '{key}' must be a mapping (name: value), got {data[key]!r}")
        preset = data.get("preset")
        source = data.get("source") or ""
        error = None if data.get("model_error") is None else ModelError.from_mapping(data["model_error"])
        emp = data.get("empirical_correction")
        emp = None if emp is None else EmpiricalCorrection.from_mapping(emp)
        return cls(model=str(data["model"]), preset=None if preset is None else str(preset),
                   parameters=dict(data.get("parameters") or {}), effects=dict(data.get("effects") or {}),
                   uncertainty=dict(data.get("uncertainty") or {}), source=str(source),
                   discrepancy=dict(data.get("discrepancy") or {}), model_error=error, empirical=emp)
