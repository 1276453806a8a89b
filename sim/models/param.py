"""A named model parameter with its unit, default and the check of a value (``ParameterError`` when it fails): its
own module so that the model specification (sim.models.base) and the shared effect table (sim.models.effects)
both build on it.  Without numpy: ``import sim`` (hence every ``vibro --help``) imports it for ParameterError."""
from __future__ import annotations

import math
from dataclasses import dataclass

from vibrobase.errors import InputError, did_you_mean


class ParameterError(InputError):
    """Bad parameter name or value (message names the parameter); public as ``sim.ParameterError``."""


def check_known_keys(data, known: tuple[str, ...], what: str) -> None:
    """ParameterError naming the first key of the mapping ``data`` not in ``known`` (with a did-you-mean); ``what``
    says what a key is, e.g. "key" or "model_error key" of a rig."""
    for key in data:
        if key not in known:
            raise ParameterError(f"rig: unknown {what} '{key}'{did_you_mean(key, known)}; known: {', '.join(known)}")


@dataclass(frozen=True)
class Param:
    """One named model parameter (SI units)."""

    name: str
    default: float
    unit: str
    description: str
    positive: bool = False
    nonnegative: bool = False
    integer: bool = False
    least: float = 0.0          # smallest value other than 0 (off): below it the parameter means nothing physical
    most: float = math.inf      # largest value with a physical meaning (a damping ratio of 1e300 is a typo)

    def validate(self, value) -> float:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ParameterError(f"parameter '{self.name}' must be a number, got {value!r}") from None
        if not math.isfinite(v):
            raise ParameterError(f"parameter '{self.name}' must be finite, got {value!r}")
        if self.positive and not v > 0.0:
            raise ParameterError(f"parameter '{self.name}' must be > 0 [{self.unit}], got {v:g}")
        if self.nonnegative and v < 0.0:
            raise ParameterError(f"parameter '{self.name}' must be >= 0 [{self.unit}], got {v:g}")
        if self.least and v != 0.0 and abs(v) < self.least:
            raise ParameterError(f"parameter '{self.name}' must be 0 (off) or >= {self.least:g} [{self.unit}], "
                                 f"got {v:g}")
        if abs(v) > self.most:
            raise ParameterError(f"parameter '{self.name}' must be <= {self.most:g} [{self.unit}], got {v:g}")
        return v


def index_of(params: tuple[Param, ...], *names: str) -> tuple[int, ...]:
    """Positions of the parameters ``names`` in the vector ``params`` (the kernel's layout)."""
    where = {p.name: i for i, p in enumerate(params)}
    missing = [n for n in names if n not in where]
    if missing:
        raise ValueError(f"no parameter {missing} in {[p.name for p in params]}")
    return tuple(where[n] for n in names)
