"""The operating controls a run, a sweep or a study may set (MODELS.md §7 runs.csv; the pendulum's amplitude is
``amplitude_m``, §3): the one tuple every package reads.  A model's controls are those of these that are its
parameters."""
from __future__ import annotations

CONTROLS = ("frequency_hz", "amplitude_n", "amplitude_m", "static_force_n", "gap_m")
