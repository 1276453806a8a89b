"""Name → model lookup.  Models register by module; import is lazy to keep start-up fast."""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from sim.models.param import ParameterError
from vibrobase.errors import did_you_mean

if TYPE_CHECKING:                  # the models (numpy, numba) are imported on the first get_model
    from sim.models.base import ModelSpec

_MODULES = {
    "drill": "sim.models.drill",
    "indenter-metal": "sim.models.indenter",
    "indenter-sandstone": "sim.models.indenter",
    "pendulum": "sim.models.pendulum",
    "rimd": "sim.models.rimd",
}


DEFAULT_MODEL = "drill"
"""The model a workflow uses when none is named (with its DEFAULT_PRESET)."""
DEFAULT_PRESET = "lab"


def model_names() -> tuple[str, ...]:
    return tuple(_MODULES)


def get_model(name: str) -> ModelSpec:
    """The ModelSpec of ``name`` (ParameterError naming the known models otherwise)."""
    if name not in _MODULES:
        raise ParameterError(f"unknown model '{name}'{did_you_mean(name, _MODULES)}; known models: {', '.join(_MODULES)}")
    mod = importlib.import_module(_MODULES[name])
    specs = getattr(mod, "SPECS", None)
    if specs is not None:
        return specs[name]
    return mod.SPEC


def kernel_variants(spec: ModelSpec) -> tuple[str | None, ...]:
    """The kernels of a model: None for the numerical integrator, then its exact propagator's module, if any."""
    return (None, spec.exact) if spec.exact else (None,)


def warm(name: str) -> None:
    """Load ``name``'s kernels in the calling thread before worker threads use them (sim.compiled.kernels is not
    thread-safe on its first call).  numba compiles a kernel at its first run, and ``sim.api`` says so then: a notice
    here would also name a variant the caller may never run."""
    from sim.compiled import kernels

    spec = get_model(name)
    for exact in kernel_variants(spec):
        kernels(spec.funcs, spec.n_bounded, exact)
