"""JSON-safe conversion and the one nested-dict flattener."""
from __future__ import annotations

import json
import math
from typing import Any, Callable


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
    """Indented JSON of ``to_jsonable(obj)``."""
    return json.dumps(to_jsonable(obj), indent=2)


def flatten(obj, prefix: str = "", leaf: Callable[[Any], Any] | None = None) -> dict:
    """Nested dict → ``{'a.b.c': leaf}``; ``leaf(value)`` may turn non-dict values (e.g. lists) into one value."""
    out: dict = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.update(flatten(v, f"{prefix}{k}.", leaf))
    else:
        out[prefix[:-1]] = obj if leaf is None else leaf(obj)
    return out
