"""Invariants every simulation result satisfies, checked on every result in the result path (``sim.api``).

A result that breaks one is not a number to trust: it gets status ``failed`` with the broken invariant as its reason
and no labels, never ``ok`` (docs/simulate.md "Statuses").  The invariants (MODELS.md §5):

- progression never decreases: ``rop_m_s >= 0`` (the drill's slider and the sandstone's crater floor only move
  forward; a non-progressing model reports 0);
- impacts per cycle, peak and mean peak forces are >= 0;
- ``ok`` is a periodic steady state: ``period`` >= 1 and the window holds whole periods; ``aperiodic`` has period 0;
- the energy balance, where the model declares one (``ModelSpec.min_work_per_m``): over whole periods of a steady
  state the excitation's work per cycle covers what the progression costs at the least, ``energy_per_cycle_j >=
  min_work_per_m × progression per cycle`` (drill: (Pr − Fs) per metre; a passive model that does not progress: 0),
  within ``ENERGY_TOL`` of the work's scale.
"""
from __future__ import annotations

from typing import Mapping

from vibrobase.statuses import BOUNDED_STATUSES

ENERGY_TOL = 0.02
"""Relative tolerance of the energy balance: the window's end repeats its start only to the periodicity tolerance,
so the stored energy differs by up to ~1e-3 of its swing; 2 % of the work per cycle (plus the floor) covers it."""

PROGRESS_TOL_M = 1e-12
"""Backward progression over the window [m] still counted as none (rounding of the progression's difference)."""


def violation(labels: Mapping, window_cycles: int, min_work_per_m, values: Mapping[str, float]) -> str | None:
    """The first invariant (module docstring) ``labels`` break, as a reason, or None.  ``window_cycles``: the
    recorded window [forcing cycles]; ``min_work_per_m``: the model's energy balance (None: none declared);
    ``values``: the run's resolved parameters."""
    status = labels["status"]
    if status not in BOUNDED_STATUSES:
        return None
    rop = labels["rop_m_s"]
    f = float(values["frequency_hz"])
    if rop is not None and rop * window_cycles / f < -PROGRESS_TOL_M:
        return (f"the progression went backwards (rop_m_s {rop:.4g} m/s < 0) although it only moves forward: "
                "the simulator lost a contact switch here")
    for name in ("impacts_per_cycle", "peak_force_n", "mean_peak_force_n"):
        if labels[name] is not None and labels[name] < 0:
            return f"{name} {labels[name]:.4g} < 0"
    period = labels["period"]
    if status == "ok" and not (period is not None and period >= 1 and window_cycles % period == 0):
        return f"status ok needs a period >= 1 and a window of whole periods, got period {period} in {window_cycles} cycles"
    if status == "aperiodic" and period != 0:
        return f"status aperiodic with period {period}"
    work = labels["energy_per_cycle_j"]
    if status == "ok" and min_work_per_m is not None and work is not None and rop is not None:
        floor = min_work_per_m(values) * rop / f
        if work < floor - ENERGY_TOL * (abs(work) + abs(floor)) - 1e-300:
            return (f"energy balance: the excitation's work {work:.4g} J per cycle is below the {floor:.4g} J the "
                    "steady state dissipates at the least")
    return None
