"""Input scaling to the unit cube (by the trained ranges) and target transforms (log / identity)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from vibrobase.unitcube import to_unit


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


LOG_RULE_DECADES = 1.0
"""A positive target spanning more than this many decades is learned as log10(y) (range rule)."""


def decades(y: np.ndarray) -> float | None:
    """log10(max / min) of the finite values, or None when any is <= 0 (no log scale) or none is finite."""
    y = np.asarray(y, dtype=float)
    y = y[np.isfinite(y)]
    if not y.size or np.any(y <= 0):
        return None
    return float(np.log10(y.max() / y.min()))


def is_constant(y: np.ndarray, rtol: float = 1e-6) -> bool:
    """True when the finite values of ``y`` are one number (spread <= rtol × |mean|), e.g. peak force pinned
    at Pr: there is nothing to learn and R² is undefined."""
    y = np.asarray(y, dtype=float)
    y = y[np.isfinite(y)]
    return bool(y.size) and float(np.std(y)) <= rtol * max(abs(float(np.mean(y))), 1e-300)


@dataclass
class TargetTransform:
    """``log``: y -> log10(y) (strictly positive targets spanning decades); ``identity`` otherwise."""

    kind: str = "identity"

    @staticmethod
    def choose(y: np.ndarray, kind: str = "auto") -> "TargetTransform":
        """auto: log when every value is positive and they span more than one decade (LOG_RULE_DECADES);
        surrogate.train confirms the choice by cross-validation near that threshold."""
        if kind != "auto":
            return TargetTransform(kind)
        d = decades(y)
        return TargetTransform("log" if d is not None and d > LOG_RULE_DECADES else "identity")

    def forward(self, y: np.ndarray) -> np.ndarray:
        return np.log10(y) if self.kind == "log" else np.asarray(y, dtype=float)

    def inverse(self, z: np.ndarray) -> np.ndarray:
        return 10.0 ** np.asarray(z, dtype=float) if self.kind == "log" else np.asarray(z, dtype=float)
