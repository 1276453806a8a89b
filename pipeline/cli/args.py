"""Validated argument types and ``KEY=VALUE`` parsing shared by the subcommands.

Every number a user gives (flag, ``--set``/``--setting``/``--fix`` value, params.yaml value) goes
through one of these: finite, an integer when an integer is meant (2.7 is refused, not truncated),
inside its range, and below an upper bound on the work it asks for.  A violation is a
:class:`UserError` naming the argument; argparse ``type=`` callables raise ``ArgumentTypeError``
(argparse then exits 2 with one line naming the flag).
"""
from __future__ import annotations

import argparse
import math
from typing import Callable

from pipeline.core.errors import UserError

# upper bounds on the work one command may ask for (a typo like 1e12 is an error, not a MemoryError or a hang)
MAX_POINTS = 10_000_000        # sweep / verify points, map grid cells
MAX_TRIALS = 1_000_000         # optimisation trials
MAX_THREADS = 1024
MAX_CYCLES = 1_000_000         # recorded/transient forcing cycles

# simulator settings (sim.Settings): (integer?, low, high, low inclusive) — bounds on work included
SETTINGS_BOUNDS: dict[str, tuple[bool, float, float, bool]] = {
    "rtol": (False, 1e-14, 0.1, True),
    "min_transient": (True, 0, 100_000, True),
    "max_transient": (True, 1, 100_000, True),
    "window": (True, 2, 10_000, True),
    "period_tol": (False, 0.0, 1.0, False),
    "settle_tol": (False, 0.0, 1.0, False),
    "max_steps_per_cycle": (True, 11, 10_000_000, True),
    "event_tol": (False, 0.0, 1e-3, False),
    "max_step_frac": (False, 0.0, 1.0, False),
    "stat_tol": (False, 0.0, 1.0, False),
    "samples_per_cycle": (True, 2, 100_000, True),
}


def number(value, what: str, *, integer: bool = False, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False) -> float | int:
    """``value`` (str, int or float) as a finite number in [lo, hi] (``(lo, hi]`` with ``lo_open``);
    an int when ``integer`` (refusing 2.7); UserError naming ``what`` otherwise."""
    if isinstance(value, bool):
        raise UserError(f"{what}: expected a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise UserError(f"{what}: '{value}' is not a number") from None
    if not math.isfinite(x):
        raise UserError(f"{what}: must be finite, got {value!r}")
    if integer:
        if x != int(x):
            raise UserError(f"{what}: must be an integer, got {value!r}")
        x = int(x)
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise UserError(f"{what}: must be {'>' if lo_open else '>='} {_fmt(lo)}, got {value!r}")
    if hi is not None and x > hi:
        raise UserError(f"{what}: must be <= {_fmt(hi)} (an upper bound on the work), got {value!r}")
    return x


def _fmt(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


def arg_type(*, integer: bool = False, lo: float | None = None, hi: float | None = None,
             lo_open: bool = False) -> Callable[[str], float | int]:
    """An argparse ``type=``: a validated number (see :func:`number`)."""
    def parse(text: str):
        try:
            return number(text, "value", integer=integer, lo=lo, hi=hi, lo_open=lo_open)
        except UserError as e:
            raise argparse.ArgumentTypeError(str(e).removeprefix("value: ")) from None
    parse.__name__ = "integer" if integer else "number"      # argparse names it in "invalid integer value"
    return parse


# the shared types of the subcommands' flags
finite = arg_type()
positive = arg_type(lo=0.0, lo_open=True)
nonnegative = arg_type(lo=0.0)
fraction = arg_type(lo=0.0, hi=1.0, lo_open=True)
seed = arg_type(integer=True, lo=0, hi=2**32 - 1)
threads = arg_type(integer=True, lo=1, hi=MAX_THREADS)
n_points = arg_type(integer=True, lo=1, hi=MAX_POINTS)
n_trials = arg_type(integer=True, lo=1, hi=MAX_TRIALS)


def count(lo: int = 1, hi: int = MAX_POINTS) -> Callable[[str], int]:
    """An argparse ``type=`` for an integer count in [lo, hi]."""
    return arg_type(integer=True, lo=lo, hi=hi)


def parse_assignments(items: list[str] | None, what: str = "--set") -> dict[str, float]:
    """Parse ``["k1=1e7", "gap_m=0.001"]`` into finite floats; a clear error names the bad item."""
    out: dict[str, float] = {}
    for item in items or []:
        if "=" not in item:
            raise UserError(f"{what} expects name=value, got '{item}'")
        name, _, raw = item.partition("=")
        name = name.strip()
        if not name:
            raise UserError(f"{what} '{item}' has no parameter name")
        out[name] = number(raw.strip(), f"{what} {name}")
    return out


def check_settings(values: dict | None, what: str = "--setting") -> dict | None:
    """Validate simulator settings (from ``--setting`` or params.yaml): known names, finite, integers
    where sim.Settings holds ints, inside :data:`SETTINGS_BOUNDS`; returns them with ints as int."""
    if values is None:
        return None
    if not isinstance(values, dict):
        raise UserError(f"{what}: expected a mapping of setting name to value, got {type(values).__name__}")
    out = {}
    for name, v in values.items():
        if name not in SETTINGS_BOUNDS:
            raise UserError(f"{what} '{name}' is unknown (known: {', '.join(SETTINGS_BOUNDS)})")
        integer, lo, hi, lo_incl = SETTINGS_BOUNDS[name]
        out[name] = number(v, f"{what} {name}", integer=integer, lo=lo, hi=hi, lo_open=not lo_incl)
    if out.get("max_transient", math.inf) < out.get("min_transient", 0):
        raise UserError(f"{what} max_transient ({out['max_transient']}) must be >= min_transient ({out['min_transient']})")
    return out


def add_overwrite(p: argparse.ArgumentParser, what: str = "output") -> None:
    """The shared ``--overwrite``: replace this command's own previous output in --out (never other files)."""
    p.add_argument("--overwrite", action="store_true",
                   help=f"replace a previous {what} of this command in --out (files it did not write are never deleted)")
