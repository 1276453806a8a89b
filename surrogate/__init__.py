"""Surrogates of the simulator's response surface (regime classifier + regressors with intervals)."""
from surrogate.bundle import Bundle, ExtrapolationWarning, load_bundle
from surrogate.config import TrainConfig
from surrogate.train import train_bundle

__all__ = ["train_bundle", "load_bundle", "Bundle", "ExtrapolationWarning", "TrainConfig"]
