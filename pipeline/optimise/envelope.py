"""The shaker's envelope: what the exciter can deliver, declared in a rig file and honoured by ``optimise``.

A rig file may hold (README.md "Rig files")::

    exciter:
      max_force_n: {frequency_hz: [100, 250, 450], amplitude_n: [2700, 2600, 2000]}   # linear between the points
      max_stroke_m: 1.5e-3          # the coil's stroke: half the peak-to-peak of x1 - x2 over the steady cycles
      max_velocity_m_s: 0.4         # the coil's peak velocity |v1 - v2| (its back-EMF, so the amplifier's voltage)

Every item is optional.  The force limit depends on the controls alone and is exact; stroke and velocity are labels
of the steady state, computed from the simulator's time history (``stroke_m``, ``coil_velocity_m_s``), so a study
limited by them runs on the simulator.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from vibrobase.statuses import SETTLED_STATUSES

ENVELOPE_LABELS = ("stroke_m", "coil_velocity_m_s")
"""Labels the envelope's stroke and velocity limits read (from the simulator's history)."""


@dataclass(frozen=True)
class Envelope:
    """The exciter's limits: amplitude_n <= the piecewise-linear ``force_table`` [(frequency_hz, amplitude_n)] at the
    point's frequency, ``stroke_m`` <= max_stroke_m [m], ``coil_velocity_m_s`` <= max_velocity_m_s [m/s]."""
    force_table: tuple[tuple[float, float], ...] = ()
    max_stroke_m: float | None = None
    max_velocity_m_s: float | None = None

    @classmethod
    def from_mapping(cls, d: Mapping | None, where: str = "exciter") -> "Envelope | None":
        """The envelope of a rig file's ``exciter`` mapping (None for none); UserError naming the bad item."""
        if d is None:
            return None
        if not isinstance(d, Mapping):
            raise UserError(f"{where}: expected a mapping of max_force_n, max_stroke_m, max_velocity_m_s; got {d!r}")
        unknown = sorted(set(d) - {"max_force_n", "max_stroke_m", "max_velocity_m_s"})
        if unknown:
            raise UserError(f"{where}: unknown key(s) {unknown}; known: max_force_n, max_stroke_m, max_velocity_m_s")
        table: tuple = ()
        if d.get("max_force_n") is not None:
            t = d["max_force_n"]
            if not isinstance(t, Mapping) or set(t) != {"frequency_hz", "amplitude_n"}:
                raise UserError(f"{where}.max_force_n: expected {{frequency_hz: [..], amplitude_n: [..]}}, got {t!r}")
            f, a = (_numbers(t[k], f"{where}.max_force_n.{k}") for k in ("frequency_hz", "amplitude_n"))
            if len(f) != len(a) or len(f) < 1:
                raise UserError(f"{where}.max_force_n: frequency_hz and amplitude_n need the same number (>= 1) of "
                                f"values, got {len(f)} and {len(a)}")
            if any(b <= x for x, b in zip(f, f[1:])):
                raise UserError(f"{where}.max_force_n.frequency_hz: must increase, got {list(f)}")
            if any(v <= 0 for v in (*f, *a)):
                raise UserError(f"{where}.max_force_n: frequencies and forces must be > 0")
            table = tuple(zip(f, a))
        out = {}
        for key in ("max_stroke_m", "max_velocity_m_s"):
            v = d.get(key)
            if v is not None:
                (x,) = _numbers([v], f"{where}.{key}")
                if x <= 0:
                    raise UserError(f"{where}.{key}: must be > 0, got {v!r}")
                out[key] = x
        return cls(table, out.get("max_stroke_m"), out.get("max_velocity_m_s"))

    def to_dict(self) -> dict:
        return {"max_force_n": {"frequency_hz": [f for f, _ in self.force_table],
                                "amplitude_n": [a for _, a in self.force_table]} if self.force_table else None,
                "max_stroke_m": self.max_stroke_m, "max_velocity_m_s": self.max_velocity_m_s}

    @property
    def needs_history(self) -> bool:
        """True when a limit reads a label of the simulator's history (stroke, velocity)."""
        return self.max_stroke_m is not None or self.max_velocity_m_s is not None

    def max_force(self, frequency_hz: float) -> float:
        """The largest amplitude the exciter delivers at ``frequency_hz`` [N] (the table's ends hold beyond it)."""
        f, a = zip(*self.force_table)
        return float(np.interp(frequency_hz, f, a))

    def check_space(self, ranges: Mapping[str, tuple[float, float]]) -> None:
        """UserError when a force envelope is declared but the study neither searches nor fixes what it reads."""
        if self.force_table and "frequency_hz" in ranges:
            f0, f1 = ranges["frequency_hz"]
            lo, hi = self.force_table[0][0], self.force_table[-1][0]
            if len(self.force_table) > 1 and (f0 < lo - 1e-9 or f1 > hi + 1e-9):
                raise UserError(f"exciter.max_force_n covers {lo:g}-{hi:g} Hz, the search {f0:g}-{f1:g} Hz: "
                                f"declare the envelope over the whole frequency range")

    def values(self, row: Mapping) -> dict[str, float]:
        """Constraint values (<= 0 within the envelope), normalised by the limit; a missing label violates by 1."""
        out = {}
        if self.force_table:
            f, a = _num(row.get("frequency_hz")), _num(row.get("amplitude_n"))
            if f is None or a is None:
                out["exciter_force"] = 1.0
            else:
                lim = self.max_force(f)
                out["exciter_force"] = (a - lim) / lim
        for key, label, lim in (("exciter_stroke", "stroke_m", self.max_stroke_m),
                                ("exciter_velocity", "coil_velocity_m_s", self.max_velocity_m_s)):
            if lim is not None:
                v = _num(row.get(label))
                out[key] = 1.0 if v is None else min((v - lim) / lim, 1e3)
        return out

    def on_envelope(self, row: Mapping, rtol: float = 0.02) -> list[str]:
        """The envelope limits a point sits on (within ``rtol`` below the limit), as sentences."""
        out = []
        if self.force_table and _num(row.get("frequency_hz")) is not None and _num(row.get("amplitude_n")):
            lim = self.max_force(float(row["frequency_hz"]))
            if float(row["amplitude_n"]) >= (1 - rtol) * lim:
                out.append(f"force {float(row['amplitude_n']):.4g} N of the exciter's {lim:.4g} N at "
                           f"{float(row['frequency_hz']):.4g} Hz")
        for label, lim, what, unit in (("stroke_m", self.max_stroke_m, "stroke", "m"),
                                       ("coil_velocity_m_s", self.max_velocity_m_s, "coil velocity", "m/s")):
            v = _num(row.get(label, row.get(f"{label}_sim")))
            if lim is not None and v is not None and v >= (1 - rtol) * lim:
                out.append(f"{what} {v:.4g} {unit} of its {lim:.4g} {unit}")
        return out


def history_labels(model: str, preset: str | None, rows: pd.DataFrame, settings=None) -> pd.DataFrame:
    """``stroke_m`` (half the peak-to-peak of x1 - x2) and ``coil_velocity_m_s`` (peak |v1 - v2|) over the recorded
    steady cycles of each row's simulation (NaN where it did not settle)."""
    import sim

    out = []
    for row in rows.to_dict("records"):
        vals = {k: v for k, v in row.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        try:
            r = sim.simulate(model, preset=preset, history=True, settings=settings, **vals)
        except sim.ParameterError:
            out.append((math.nan, math.nan))
            continue
        h = r.history
        if r.status not in SETTLED_STATUSES or h is None or not len(h):
            out.append((math.nan, math.nan))
            continue
        rel = (h["x1"] - h["x2"]).to_numpy(float)
        out.append((0.5 * float(rel.max() - rel.min()), float(np.abs((h["v1"] - h["v2"]).to_numpy(float)).max())))
    return pd.DataFrame(out, columns=list(ENVELOPE_LABELS))


def _num(x) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(v) else v


def _numbers(v, what: str) -> tuple[float, ...]:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        v = [v]
    if not isinstance(v, (list, tuple)):
        raise UserError(f"{what}: expected a list of numbers, got {v!r}")
    out = []
    for x in v:
        if isinstance(x, bool):
            raise UserError(f"{what}: expected numbers, got {x!r}")
        try:
            y = float(x)
        except (TypeError, ValueError):
            raise UserError(f"{what}: '{x}' is not a number") from None
        if not math.isfinite(y):
            raise UserError(f"{what}: values must be finite, got {x!r}")
        out.append(y)
    return tuple(out)
