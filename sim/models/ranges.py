"""The ranges a model or preset was validated on, and the warning for a value outside them that names the likely
mistake (a unit slip: "frequency_hz 0.3 is outside 100–450 Hz of preset lab: kHz?").

The ranges are knowledge about the model, declared with it (``ModelSpec.validated``: preset -> parameter -> (lo, hi),
"" for the defaults and every preset without its own entry; the calibratable parameters' fit bounds count too).  A
value outside is allowed, only warned about: the simulator runs it, but nobody checked the model there.  A value that
is physically impossible (a negative mass, a zero frequency) is refused by its ``Param`` instead.
"""
from __future__ import annotations

import math
from typing import Mapping

# (factor, how the unit was typed) of the usual slips: the value typed in a unit `factor` times the SI one
_PREFIXES = ((1e3, "k"), (1e-3, "m"), (1e6, "M"), (1e-6, "µ"))
_SPECIAL = {("kg", 1e-3): "g", ("kg", 1e3): "t", ("kg", 1e-6): "mg", ("m", 1e-2): "cm",
            ("Hz", 1.0 / (2.0 * math.pi)): "rad/s"}
_PREFIXED = ("Hz", "N", "m", "s")
"""Units a prefix slip is named in (kHz, kN, mm, ms); other units get "1000x too large"."""


def num(x: float) -> str:
    """A bound or value for a message: 100, 0.3, 2e6, 5e-4."""
    return f"{x:g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def unit_slip(lo_v: float, hi_v: float, lo: float, hi: float, unit: str) -> str:
    """The unit the values [lo_v, hi_v] were likely typed in, when a usual factor brings them into [lo, hi]
    (``"kHz?"``), else ``""``."""
    factors = [(f, _SPECIAL[(unit, f)]) for u, f in _SPECIAL if u == unit]
    if unit in _PREFIXED:
        factors += [(f, f"{p}{unit}") for f, p in _PREFIXES]
    elif unit != "kg":
        factors += [(f, f"{num(1 / f)}x too large" if f < 1 else f"{num(f)}x too small") for f, _ in _PREFIXES]
    for f, typed in factors:
        if lo * (1 - 1e-9) <= lo_v * f and hi_v * f <= hi * (1 + 1e-9):
            return f"{typed}?"
    return ""


def out_of_range(spec, preset: str | None, values: Mapping[str, float | tuple[float, float]]) -> list[str]:
    """One line per value of ``values`` (a number, or a (low, high) range of a sweep) outside the range the model
    ``spec`` or its ``preset`` was validated on, naming the likely mistake; names without a validated range pass."""
    own = spec.validated.get(preset) if preset is not None else None
    ranges = {b.name: (b.lo, b.hi, f"model {spec.name}") for b in spec.calibratable}
    where = f"preset {preset}" if own is not None else f"model {spec.name}"
    controls = own if own is not None else spec.validated.get("", {})
    ranges.update({n: (lo, hi, where) for n, (lo, hi) in controls.items()})
    units = {p.name: p.unit for p in spec.params}
    out = []
    for name, v in values.items():
        if name not in ranges or v is None:
            continue
        lo_v, hi_v = (float(v[0]), float(v[1])) if isinstance(v, (tuple, list)) else (float(v), float(v))
        lo, hi, src = ranges[name]
        if lo <= lo_v and hi_v <= hi:
            continue
        unit = units.get(name, "")
        shown = num(lo_v) if lo_v == hi_v else f"{num(lo_v)}–{num(hi_v)}"
        slip = unit_slip(lo_v, hi_v, lo, hi, unit)
        out.append(f"{name} {shown} is outside {num(lo)}–{num(hi)} {unit} of {src}"
                   + (f": {slip}" if slip else " (the model was not validated there)"))
    return out
