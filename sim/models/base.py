"""Model description shared by every simulated system: parameters, states, kernels."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np


class ParameterError(ValueError):
    """Bad parameter name or value (message names the parameter)."""


@dataclass(frozen=True)
class Param:
    """One named model parameter (SI units)."""

    name: str
    default: float
    unit: str
    description: str
    positive: bool = False
    nonnegative: bool = False
    integer: bool = False

    def validate(self, value) -> float:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ParameterError(f"parameter '{self.name}' must be a number, got {value!r}") from None
        if not math.isfinite(v):
            raise ParameterError(f"parameter '{self.name}' must be finite, got {value!r}")
        if self.positive and not v > 0.0:
            raise ParameterError(f"parameter '{self.name}' must be > 0 [{self.unit}], got {v:g}")
        if self.nonnegative and v < 0.0:
            raise ParameterError(f"parameter '{self.name}' must be >= 0 [{self.unit}], got {v:g}")
        return v


@dataclass(frozen=True)
class ModelSpec:
    """Everything the generic driver needs to know about one model.

    funcs = (rhs, guards, on_event, observe, bounded) numba functions (see sim.integrator).
    ``derive`` may fill parameters that default to a formula (e.g. indenter c3) and
    runs before validation of cross-parameter constraints.
    """

    name: str
    description: str
    params: tuple[Param, ...]
    states: tuple[str, ...]
    z_names: tuple[str, ...]
    bounded: tuple[str, ...]
    funcs: tuple
    n_bounded: int
    initial: Callable[[np.ndarray], tuple]
    atol: Callable[[np.ndarray], np.ndarray]   # typical magnitude of each state (atol = rtol × this)
    precheck: Callable[[np.ndarray], str | None] = lambda p: None
    effects: dict[str, tuple[str, ...]] = field(default_factory=dict)
    impacting_mass: str = ""
    progression: str = ""
    presets: dict[str, dict[str, float]] = field(default_factory=dict)
    default_settings: dict[str, float] = field(default_factory=dict)
    derive: Callable[[dict], dict] | None = None
    forcing_phase: str = "sin"
    postprocess: Callable | None = None
    needs_history: Callable[[dict], bool] = lambda values: False
    exact: str | None = None   # module of an exact propagator of the model's phases (sim/exact/), if any

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def defaults(self, preset: str | None = None) -> dict[str, float]:
        values = {p.name: p.default for p in self.params}
        if preset is not None:
            if preset not in self.presets:
                raise ParameterError(
                    f"unknown preset '{preset}' for model '{self.name}'; known: {', '.join(sorted(self.presets)) or 'none'}")
            values.update(self.presets[preset])
        return values

    def resolve(self, preset: str | None = None, **overrides) -> dict[str, float]:
        """Validated full parameter dict: defaults ← preset ← overrides ← derived."""
        values = self.defaults(preset)
        known = set(values)
        for key in overrides:
            if key not in known:
                raise ParameterError(
                    f"unknown parameter '{key}' for model '{self.name}'; known: {', '.join(self.param_names)}")
        values.update(overrides)
        by_name = {p.name: p for p in self.params}
        out = {}
        for name, v in values.items():
            if v is None:
                out[name] = None
                continue
            out[name] = by_name[name].validate(v)
        if self.derive is not None:
            out = self.derive(out)
        for name, v in out.items():
            if v is None:
                raise ParameterError(f"parameter '{name}' of model '{self.name}' has no value")
        return out

    def vector(self, values: dict[str, float]) -> np.ndarray:
        return np.array([values[p.name] for p in self.params], dtype=np.float64)
