"""The surrogate's contract: the regime classes it predicts, the targets it regresses and the controls its
inputs are usually drawn from."""
from __future__ import annotations

from sim.controls import CONTROLS  # noqa: F401  (part of the surrogate contract: the inputs it is drawn from)
from vibrobase.statuses import STATUSES

REGIMES = ("progressing", "no_progress", "runaway", "not_settled", "failed")
"""Surrogate regime classes: progressing (status ok or aperiodic, and rop_m_s > 0), no_progress (ok / aperiodic /
no_contact with rop_m_s = 0), and the simulator's own runaway, not_settled and failed."""

REGIME_TO_STATUS = {"progressing": "ok", "no_progress": "ok", "runaway": "runaway",
                    "not_settled": "not_settled", "failed": "failed"}
"""The sweep status a regime stands for (inverse of the regime rule above, up to aperiodic, no_contact → ok)."""

TARGETS = ("rop_m_s", "peak_force_n", "impacts_per_cycle", "specific_energy_j_m", "power_w", "peak_decel_g")
"""Regression targets of the surrogate contract (each with _lo/_hi 90 % intervals)."""

assert set(REGIME_TO_STATUS) == set(REGIMES) and set(REGIME_TO_STATUS.values()) <= set(STATUSES)
