"""Surrogates of the simulator's response surface (regime classifier + regressors with intervals).

The training and bundle API (scikit-learn, pandas) is imported on first use of one of its names, so importing
``surrogate.errors`` or ``surrogate.names`` stays light."""
from surrogate.errors import SurrogateError

_API = {"train_bundle": "surrogate.train", "load_bundle": "surrogate.bundle", "Bundle": "surrogate.bundle",
        "ExtrapolationWarning": "surrogate.bundle", "TrainConfig": "surrogate.config"}

__all__ = ["train_bundle", "load_bundle", "Bundle", "ExtrapolationWarning", "TrainConfig", "SurrogateError"]


def __getattr__(name: str):
    if name in _API:
        import importlib

        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'surrogate' has no attribute '{name}'")
