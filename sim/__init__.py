"""Fast, event-locating simulators of vibro-impact drilling systems (see MODELS.md).

The simulator API (``sim.api``: numba, pandas) is imported on first use of one of its names, so importing
``sim`` for a model's specification (``get_model``, ``ParameterError``) stays light."""
from sim.models.param import ParameterError
from sim.registry import get_model, model_names
from sim.rig import ModelError, Rig

_API = ("LABELS", "Settings", "SimulationResult", "simulate", "simulate_batch")

__all__ = ["simulate", "simulate_batch", "Settings", "SimulationResult", "LABELS", "ParameterError",
           "get_model", "model_names", "ModelError", "Rig"]


def __getattr__(name: str):
    if name in _API:
        from sim import api

        return getattr(api, name)
    raise AttributeError(f"module 'sim' has no attribute '{name}'")
