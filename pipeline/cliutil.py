"""Small helpers shared by the subcommands: ``--set name=value`` parsing and JSON output."""
from __future__ import annotations

import json
import math

from pipeline.errors import UserError


def parse_assignments(items: list[str] | None, what: str = "--set") -> dict[str, float]:
    """Parse ``["k1=1e7", "gap_m=0.001"]`` into floats; a clear error names the bad item."""
    out: dict[str, float] = {}
    for item in items or []:
        if "=" not in item:
            raise UserError(f"{what} expects name=value, got '{item}'")
        name, _, raw = item.partition("=")
        name = name.strip()
        if not name:
            raise UserError(f"{what} '{item}' has no parameter name")
        try:
            value = float(raw)
        except ValueError:
            raise UserError(f"{what} {name}: '{raw}' is not a number") from None
        out[name] = value
    return out


def to_jsonable(obj):
    """JSON-safe copy: numpy scalars → Python, inf → the string 'inf' (JSON has no infinity)."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return "inf" if obj > 0 else ("-inf" if obj < 0 else None)
    return obj


def dump_json(obj) -> str:
    return json.dumps(to_jsonable(obj), indent=2)
