"""Prediction intervals by split-conformal calibration on out-of-fold residuals.

Score = |z - ẑ| / s in the target's transformed units (z = log10 y for log targets, so the
interval is multiplicative), where s = GP posterior std when the model is a GP (locally
adaptive width) and 1 otherwise.  The half-width q is the ceil((n+1)·level)/n empirical
quantile of the scores, which covers a new exchangeable point with probability ≥ level."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ConformalInterval:
    q: float
    normalised: bool
    level: float
    n_calibration: int

    @staticmethod
    def calibrate(z: np.ndarray, z_oof: np.ndarray, std_oof: np.ndarray | None, level: float) -> "ConformalInterval":
        normalised = std_oof is not None
        s = np.maximum(std_oof, 1e-12) if normalised else 1.0
        scores = np.abs(z - z_oof) / s
        n = scores.size
        k = min(int(np.ceil((n + 1) * level)), n)
        q = float(np.sort(scores)[k - 1]) if n else float("inf")
        return ConformalInterval(q, normalised, level, n)

    def bounds(self, z_hat: np.ndarray, std: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) in transformed units."""
        s = np.maximum(std, 1e-12) if (self.normalised and std is not None) else 1.0
        return z_hat - self.q * s, z_hat + self.q * s
