"""Names of the simulator's per-point status (the ``status`` label of sim.simulate and sim.simulate_batch).

Free of numpy, so the pipeline and the surrogate can name statuses without loading the simulator.

What each means (docs/simulate.md "Statuses"; every result is checked against these by sim.invariants):
  ok           periodic steady state: period n >= 1 (MODELS.md §5), labels are means over a window of whole periods
  aperiodic    bounded and statistically steady (the window's two halves agree on ROP, peak force, impact rate and
               work) but with no period <= 8 within the period tolerance: chaotic, quasi-periodic, or a periodic
               orbit still converging (a short transient); period 0, labels are window means
  no_contact   settled without a contact in the window (ROP 0, no impacts)
  not_settled  still transient when the window was recorded (reason says how); labels are window means
  runaway      no bounded steady state (drill: Fs >= Pr); no labels
  failed       the integration failed, or a result broke an invariant (reason says which); no labels
"""
from __future__ import annotations

STATUSES = ("ok", "aperiodic", "no_contact", "not_settled", "runaway", "failed")
"""Every status a simulation reports (sim.api.STATUS_NAMES maps the kernel's codes onto these)."""

SETTLED_STATUSES = ("ok", "aperiodic", "no_contact")
"""Statuses of a settled, bounded, impacting-or-not point (the constraints' 'settled')."""

BOUNDED_STATUSES = ("ok", "aperiodic", "no_contact", "not_settled")
"""Statuses at which the labels are finite numbers (not a runaway or a failure)."""

IMPACTING_STATUSES = ("ok", "aperiodic")
"""Settled statuses of a point in contact: its ROP says whether it progresses (the surrogate's 'progressing')."""

assert set(IMPACTING_STATUSES) <= set(SETTLED_STATUSES) <= set(BOUNDED_STATUSES) <= set(STATUSES)
