"""The one number parser: every number a user gives (flag, params.yaml or rig-file value, CSV cell) becomes a
finite float or an int here, or a UserError naming it.

Text must be written as a plain decimal number (``1e5``, ``-0.25``, ``300``): no ``1_000``, no ``0x10``, no
``infinity``.  A file value that YAML read as text (``"1e5"`` in quotes) is refused rather than coerced, and an
integer longer than MAX_INT_DIGITS is refused before Python builds it (``int()`` of 5001 digits is an error).
"""
from __future__ import annotations

import math
import re

from pipeline.core.errors import UserError

NUMBER_TEXT = re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$")
"""A number as text: decimal digits, an optional point and exponent (what every flag and CSV cell may hold)."""
MAX_INT_DIGITS = 18
"""Longest integer accepted (|n| < 1e18): far above any count or seed, far below Python's 4300-digit limit."""
MAX_NUMBER_CHARS = 64
"""Longest number text accepted (``float()`` of a megabyte of digits is slow and meaningless)."""


MAX_TRIALS = 1_000_000
"""Most optimisation trials one study may ask for (a typo like 1e12 is an error, not a hang)."""
MAX_THREADS = 1024
"""Most simulator threads one command may ask for."""


PLAUSIBLE_FACTOR = 1e6
"""A model parameter given by a user lies within this factor of its default (1e300 or 1e-300 is a typo)."""


def plausible(value: float, default: float) -> bool:
    """True when ``value`` is 0, ``default`` is 0 (no scale to compare with), or within PLAUSIBLE_FACTOR of it."""
    d, v = abs(float(default)), abs(float(value))
    return d == 0 or v == 0 or d / PLAUSIBLE_FACTOR <= v <= d * PLAUSIBLE_FACTOR


class QuotedNumber(str):
    """A file value that looks like a number but was written as text (YAML ``"1e5"``): refused by :func:`number`."""


def number(value, what: str, *, integer: bool = False, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False) -> float | int:
    """``value`` (number text, int or float) as a finite number in [lo, hi] (``(lo, hi]`` with ``lo_open``);
    an int when ``integer`` (refusing 2.7); UserError naming ``what`` otherwise."""
    x = _as_float(value, what)
    if not math.isfinite(x):
        raise UserError(f"{what}: must be finite, got {value!r}")
    if integer:
        if x != int(x):
            raise UserError(f"{what}: must be an integer, got {value!r}")
        x = int(x)
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise UserError(f"{what}: must be {'>' if lo_open else '>='} {fmt(lo)}, got {value!r}")
    if hi is not None and x > hi:
        raise UserError(f"{what}: must be <= {fmt(hi)} (an upper bound on the work), got {value!r}")
    return x


def _as_float(value, what: str) -> float:
    if isinstance(value, bool):
        raise UserError(f"{what}: must be a number, got {str(value).lower()} (a yes/no, not a value)")
    if isinstance(value, QuotedNumber):
        raise UserError(f"{what}: '{value}' is quoted text, not a number; write it without quotes")
    if isinstance(value, int):
        if abs(value) >= 10**MAX_INT_DIGITS:
            raise UserError(f"{what}: an integer of {len(str(abs(value)))} digits is out of range")
        return float(value)
    if isinstance(value, float):
        return value
    if isinstance(value, str):
        text = value.strip()
        if text.lower().lstrip("+-") in ("nan", "inf", "infinity"):
            return float(text)                              # named as not finite by the caller
        if len(text) > MAX_NUMBER_CHARS or not NUMBER_TEXT.match(text):
            shown = text if len(text) <= 40 else text[:37] + "..."
            raise UserError(f"{what}: '{shown}' is not a number")
        return float(text)
    try:                                                    # numpy scalars
        import numbers

        if isinstance(value, numbers.Real):
            return _as_float(value.item() if hasattr(value, "item") else float(value), what)
    except (TypeError, ValueError, OverflowError):
        pass
    raise UserError(f"{what}: expected a number, got {type(value).__name__} {str(value)[:40]!r}")


def fmt(x: float) -> str:
    """A bound for a message: an integer without decimals, else %g."""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"
