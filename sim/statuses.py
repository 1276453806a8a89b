"""Names of the simulator's per-point status (the ``status`` label of sim.simulate and sim.simulate_batch).

Free of numpy, so the pipeline and the surrogate can name statuses without loading the simulator."""
from __future__ import annotations

STATUSES = ("ok", "no_contact", "not_settled", "runaway", "failed")
"""Every status a simulation reports (sim.api.STATUS_NAMES maps the kernel's codes onto these)."""

SETTLED_STATUSES = ("ok", "no_contact")
"""Statuses of a settled, bounded, impacting-or-not point (the constraints' 'settled')."""

BOUNDED_STATUSES = ("ok", "no_contact", "not_settled")
"""Statuses at which the labels are finite numbers (not a runaway or a failure)."""

assert set(SETTLED_STATUSES) <= set(BOUNDED_STATUSES) <= set(STATUSES)
