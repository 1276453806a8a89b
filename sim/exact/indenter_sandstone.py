"""The indenter rig's hybrid propagator (sim/exact/indenter.py) bound to the sandstone sample."""
from __future__ import annotations

from sim.exact.indenter import (EVERY_PHASE, HANDLED_EFFECT_PARAMS, HYBRID, applies, exact_free, exact_ok, step_hint,
                                 make_workspace_sandstone)

__all__ = ["APPLIES_WHEN", "EVERY_PHASE", "HANDLED_EFFECT_PARAMS", "HYBRID", "REPLACES", "exact_applies", "exact_free",
           "exact_ok", "make_workspace", "step_hint"]
REPLACES = ("HYBRID", "exact_ok", "exact_free", "make_workspace", "step_hint")
"""The kernel template's names this module replaces (sim.compiled): the hook, its step hint and the workspace."""
APPLIES_WHEN = "no effect parameter set and nl = nu = 1"
"""When ``exact_applies`` holds, for the error of ``method`` "exact" (sim.api)."""


def exact_applies(values: dict, effects: dict) -> bool:
    """True when no effect parameter is set and nl = nu = 1 (otherwise a phase is nonlinear)."""
    return applies(values, effects, True)


make_workspace = make_workspace_sandstone
"""The template's scratch and the sandstone phase tables (sim.exact.indenter.build)."""
