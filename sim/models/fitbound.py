"""The fit bound of a parameter: its own module so that the model specification (sim.models.base) and the
shared effect table (sim.models.effects) both build on it without importing each other."""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class FitBound:
    """Fit bounds of a calibratable or effect parameter [SI]; fitted in log10 when log=True.  ``grid``: interior
    points of the diagnosis' start grid along this parameter (0: the configured ``grid``), more for a parameter the
    residual is multimodal in (a hidden mode's frequency)."""

    name: str
    lo: float
    hi: float
    unit: str
    log: bool = True
    grid: int = 0

    def __post_init__(self):
        if not self.lo < self.hi:
            raise ValueError(f"fit bound '{self.name}': lo {self.lo!r} must be < hi {self.hi!r}")
        if self.log and not self.lo > 0.0:
            raise ValueError(f"fit bound '{self.name}': a log10 fit needs lo > 0, got {self.lo!r}")

    @property
    def bounds(self) -> tuple[float, float]:
        """(lo, hi) in the fitted coordinate (log10 when ``log``)."""
        return (math.log10(self.lo), math.log10(self.hi)) if self.log else (self.lo, self.hi)
