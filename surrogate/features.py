"""Input scaling to the unit cube (by the trained ranges) and target transforms (log / identity)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.core.unitcube import to_unit


@dataclass
class InputScaler:
    """Maps each input to [0, 1] over its trained range (log-spaced inputs in log space)."""

    inputs: list[str]
    ranges: dict[str, tuple[float, float]]
    scale: dict[str, str]

    def transform(self, X: pd.DataFrame | np.ndarray) -> np.ndarray:
        A = X[self.inputs].to_numpy(dtype=float) if isinstance(X, pd.DataFrame) else np.asarray(X, dtype=float)
        out = np.empty_like(A)
        for j, n in enumerate(self.inputs):
            lo, hi = self.ranges[n]
            out[:, j] = to_unit(A[:, j], lo, hi, self.scale.get(n) == "log" and lo > 0)
        return out


@dataclass
class TargetTransform:
    """``log``: y -> log10(y) (strictly positive targets spanning decades); ``identity`` otherwise."""

    kind: str = "identity"

    @staticmethod
    def choose(y: np.ndarray, kind: str = "auto") -> "TargetTransform":
        """auto: log when every value is positive and they span more than two decades."""
        if kind != "auto":
            return TargetTransform(kind)
        y = y[np.isfinite(y)]
        if y.size and np.all(y > 0) and np.log10(y.max() / y.min()) > 2.0:
            return TargetTransform("log")
        return TargetTransform("identity")

    def forward(self, y: np.ndarray) -> np.ndarray:
        return np.log10(y) if self.kind == "log" else np.asarray(y, dtype=float)

    def inverse(self, z: np.ndarray) -> np.ndarray:
        return 10.0 ** np.asarray(z, dtype=float) if self.kind == "log" else np.asarray(z, dtype=float)
