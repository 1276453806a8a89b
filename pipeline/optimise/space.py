"""Search space of an optimisation: named ranges of the controls (SI units, e.g. Hz, N)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.core.numbers import number
from vibrobase.errors import did_you_mean
from vibrobase.unitcube import to_unit


ON_BOUND_RTOL = 0.02
"""A recommended value within 2 % of its range's width from a bound is reported as lying on that bound."""


def describe_bounds(hits: list[dict]) -> str:
    """'amplitude_n at its upper bound 2700, static_force_n at its lower bound 600' (empty for none)."""
    return ", ".join(f"{h['name']} at its {'upper' if h['side'] == 'high' else 'lower'} bound {h['bound']:g}"
                     for h in hits)


@dataclass(frozen=True)
class Space:
    """Box of named inputs ``{name: (low, high)}``; names in ``log`` are sampled on a log scale."""

    ranges: dict[str, tuple[float, float]]
    log: frozenset[str] = field(default_factory=frozenset)

    @property
    def names(self) -> list[str]:
        return list(self.ranges)

    def validate(self, known: list[str] | tuple[str, ...] | None = None) -> "Space":
        """Raise UserError naming the range that is empty, inverted, non-finite or unknown."""
        if not self.ranges:
            raise UserError("the search space is empty: give at least one range (e.g. --range frequency_hz=10:400)")
        for name, (lo, hi) in self.ranges.items():
            if known is not None and name not in known:
                raise UserError(f"unknown parameter '{name}'{did_you_mean(name, known)}: range '{name}' is not a "
                                f"parameter of the model (known: {', '.join(known)})")
            if not (math.isfinite(lo) and math.isfinite(hi)):
                raise UserError(f"range '{name}': bounds must be finite numbers, got [{lo}, {hi}]")
            if not hi > lo:
                raise UserError(f"range '{name}': empty range [{lo:g}, {hi:g}] (low must be below high)")
            if name in self.log and lo <= 0:
                raise UserError(f"range '{name}': a log-scale range needs low > 0, got {lo:g}")
        return self

    def distributions(self) -> dict:
        import optuna

        return {n: optuna.distributions.FloatDistribution(lo, hi, log=n in self.log)
                for n, (lo, hi) in self.ranges.items()}

    def unit(self, X: pd.DataFrame) -> np.ndarray:
        """Inputs mapped to the unit cube (log names on a log scale), shape (n, d)."""
        cols = []
        for n, (lo, hi) in self.ranges.items():
            cols.append(to_unit(X[n].to_numpy(dtype=float), lo, hi, n in self.log))
        return np.column_stack(cols) if cols else np.zeros((len(X), 0))

    def contains(self, other: "Space", rtol: float = 1e-9) -> list[str]:
        """Names of ``other``'s ranges that leave this space (or are not in it)."""
        bad = []
        for n, (lo, hi) in other.ranges.items():
            if n not in self.ranges:
                bad.append(n)
                continue
            a, b = self.ranges[n]
            tol = rtol * max(abs(a), abs(b), 1.0)
            if lo < a - tol or hi > b + tol:
                bad.append(n)
        return bad

    def on_bounds(self, point, rtol: float = ON_BOUND_RTOL) -> list[dict]:
        """The bounds ``point`` ({name: value}) lies on: ``[{"name", "side": "low"|"high", "bound"}]``, a value
        within ``rtol`` of its range's width from a bound counting as on it (an optimum there would likely
        move if the box were larger)."""
        out = []
        for n, (lo, hi) in self.ranges.items():
            if n not in point:
                continue
            v, tol = float(point[n]), rtol * (hi - lo)
            if v - lo <= tol:
                out.append({"name": n, "side": "low", "bound": lo, "value": v})
            elif hi - v <= tol:
                out.append({"name": n, "side": "high", "bound": hi, "value": v})
        return out

    def to_dict(self) -> dict:
        return {n: {"low": lo, "high": hi, "scale": "log" if n in self.log else "linear"}
                for n, (lo, hi) in self.ranges.items()}


def parse_range(item: str) -> tuple[str, tuple[float, float]]:
    """``"frequency_hz=10:400"`` → ``("frequency_hz", (10.0, 400.0))``; UserError naming the item otherwise."""
    name, sep, rest = item.partition("=")
    lo_s, sep2, hi_s = rest.partition(":")
    if not sep or not sep2 or not name.strip():
        raise UserError(f"--range expects NAME=LOW:HIGH, got '{item}'")
    try:
        return name.strip(), (float(lo_s), float(hi_s))
    except ValueError:
        raise UserError(f"--range {name.strip()}: '{rest}' is not LOW:HIGH numbers") from None


def space_from_mapping(d: dict) -> Space:
    """Space from ``{name: [low, high]}`` or ``{name: {low, high, scale}}`` (params.yaml / sweep metadata)."""
    ranges, log = {}, set()
    for name, v in (d or {}).items():
        try:
            if isinstance(v, dict):
                pair = (v["low"], v["high"])
                if str(v.get("scale", "linear")) == "log":
                    log.add(name)
            else:
                pair = tuple(v)
                if len(pair) != 2 or isinstance(v, (str, bytes)):
                    raise ValueError
        except (KeyError, TypeError, ValueError):
            raise UserError(f"range '{name}': expected [low, high] or {{low, high, scale}}, got {v!r}") from None
        lo, hi = (number(x, f"range '{name}' {end}") for x, end in zip(pair, ("low", "high")))
        ranges[name] = (lo, hi)
    return Space(ranges, frozenset(log))


def default_space(model: str, preset: str | None) -> Space | None:
    """The model's published search space for ``preset`` (``ModelSpec.search_spaces``; "" = the model's
    defaults when no preset is named), if it has one."""
    from sim import get_model

    space = get_model(model).search_spaces.get(preset or "")
    return space_from_mapping(space) if space else None
