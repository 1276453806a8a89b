"""Names shared by datasets, surrogates, optimisation and reports: sweep statuses, regimes, targets, controls.

One place, so a regime or target added here reaches every workflow."""
from __future__ import annotations

from pipeline.core.units import ENGINEERING

STATUSES = ("ok", "no_contact", "not_settled", "runaway", "failed")
"""Per-point status of a sweep row (sim.simulate_batch's ``status`` column)."""

SETTLED_STATUSES = ("ok", "no_contact")
"""Statuses of a settled, bounded, impacting-or-not point (the constraints' 'settled')."""

BOUNDED_STATUSES = ("ok", "no_contact", "not_settled")
"""Statuses at which the labels are finite numbers (not a runaway or a failure)."""

REGIMES = ("progressing", "no_progress", "runaway", "not_settled", "failed")
"""Surrogate regime classes: progressing (status ok and rop_m_s > 0), no_progress (ok / no_contact with
rop_m_s = 0), and the simulator's own runaway, not_settled and failed."""

REGIME_TO_STATUS = {"progressing": "ok", "no_progress": "ok", "runaway": "runaway",
                    "not_settled": "not_settled", "failed": "failed"}
"""The sweep status a regime stands for (inverse of the regime rule above, up to no_contact → ok)."""

TARGETS = ("rop_m_s", "peak_force_n", "impacts_per_cycle", "specific_energy_j_m", "power_w", "peak_decel_g")
"""Regression targets of the surrogate contract (each with _lo/_hi 90 % intervals)."""

MAXIMISED = ("rop_m_s",)
"""Labels an optimisation objective maximises by default; every other label is minimised (a cost)."""

DISPLAY_UNITS = {name: (unit or "-", f) for name, (_, unit, f) in ENGINEERING.items()}
"""Engineering unit of a label or control: name -> (unit, factor from SI), from pipeline.core.units."""


def display(name: str, value_si):
    """(value in the engineering unit, unit) of a label or control; SI unchanged for unknown names."""
    unit, factor = DISPLAY_UNITS.get(name, ("", 1.0))
    return (None if value_si is None else float(value_si) * factor), unit

CONTROLS = ("frequency_hz", "amplitude_n", "amplitude_m", "static_force_n", "gap_m")
"""Operating-point controls a surrogate's inputs are usually drawn from."""

assert set(REGIME_TO_STATUS) == set(REGIMES) and set(REGIME_TO_STATUS.values()) <= set(STATUSES)
