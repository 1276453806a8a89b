"""Fast, event-locating simulators of vibro-impact drilling systems (see MODELS.md)."""
from sim.api import LABELS, Settings, SimulationResult, simulate, simulate_batch
from sim.models.base import ParameterError
from sim.registry import get_model, model_names
from sim.rig import Rig

__all__ = ["simulate", "simulate_batch", "Settings", "SimulationResult", "LABELS", "ParameterError",
           "get_model", "model_names", "Rig"]
