"""Names shared by datasets, optimisation and reports: the objective's sense, display units.

The sweep statuses are the simulator's (``vibrobase.statuses``); the surrogate's regimes, targets and controls are
its contract (``surrogate.names``)."""
from __future__ import annotations

from pipeline.core.units import ENGINEERING

__all__ = ["MAXIMISED", "DISPLAY_UNITS", "display"]

MAXIMISED = ("rop_m_s",)
"""Labels an optimisation objective maximises by default; every other label is minimised (a cost)."""

DISPLAY_UNITS = {name: (unit or "-", f) for name, (_, unit, f) in ENGINEERING.items()}
"""Engineering unit of a label or control: name -> (unit, factor from SI), from pipeline.core.units."""


def display(name: str, value_si):
    """(value in the engineering unit, unit) of a label or control; SI unchanged for unknown names."""
    unit, factor = DISPLAY_UNITS.get(name, ("", 1.0))
    return (None if value_si is None else float(value_si) * factor), unit
