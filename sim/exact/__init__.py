"""Exact propagators of models' linear phases (sim/exact/drill.py: every phase; sim/exact/rimd.py: the free flight;
sim/exact/indenter.py: every phase while the seal friction is constant)."""
from __future__ import annotations


def effects_handled(handled: tuple, values: dict, effects: dict) -> bool:
    """True when every effect parameter of ``effects`` (effect -> its parameter names) that is not in ``handled`` is
    zero or absent in ``values``: where an exact propagator applies."""
    for names in effects.values():
        for n in names:
            if n not in handled and float(values.get(n, 0.0) or 0.0) != 0.0:
                return False
    return True
