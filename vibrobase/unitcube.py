"""The one mapping between a parameter range and the unit interval (linear, or logarithmic in the value)."""
from __future__ import annotations

import math

import numpy as np


def to_unit(x, lo: float, hi: float, log: bool = False) -> np.ndarray:
    """Values in [lo, hi] → [0, 1]; ``log``: uniform in log(x) (lo > 0; non-positive x clipped to 1e-300)."""
    x = np.asarray(x, dtype=float)
    if log:
        a, b = math.log(lo), math.log(hi)
        return (np.log(np.maximum(x, 1e-300)) - a) / (b - a)
    return (x - lo) / (hi - lo)


def from_unit(u, lo: float, hi: float, log: bool = False) -> np.ndarray:
    """Unit-interval coordinates ``u`` → values in [lo, hi] (the inverse of :func:`to_unit`)."""
    u = np.asarray(u, dtype=float)
    if log:
        a, b = math.log(lo), math.log(hi)
        return np.exp(a + u * (b - a))
    return lo + u * (hi - lo)
