"""Constraints of the operating point, in optuna's convention (a value <= 0 is feasible).

Each constraint is normalised by its limit so violations are comparable (0.1 = 10 % over).
Inputs are label rows: ``status`` (MODELS.md §5 status; surrogate regimes are mapped onto it),
``rop_m_s`` [m/s], ``peak_force_n`` [N], ``specific_energy_j_m`` [J/m], ``static_force_n`` [N],
``power_w`` [W] (the excitation's mean power) and ``peak_decel_g`` [g] (the bit's peak deceleration).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Mapping

from pipeline.core.errors import UserError
from vibrobase.statuses import BOUNDED_STATUSES, SETTLED_STATUSES

SETTLED = SETTLED_STATUSES
BOUNDED = BOUNDED_STATUSES


def _num(x) -> float | None:
    if x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(v) else v


UPPER_LIMITS = {"power": ("power_w", "max_power_w"), "decel": ("peak_decel_g", "max_decel_g")}
"""Plain upper limits on a label: constraint key -> (label, Constraints field)."""

LIMITED_LABELS = {"peak_force_n": ("max_peak_force_n", "peak_force_static_ratio"),
                  "specific_energy_j_m": ("max_specific_energy_j_m",), "power_w": ("max_power_w",),
                  "peak_decel_g": ("max_decel_g",)}
"""Label -> the Constraints fields that limit it: the labels a margin may name."""


def resolve_margins(margin, cons: "Constraints") -> dict[str, float]:
    """``margin`` (a fraction for every limited label, or {label: fraction}) -> {label: fraction} over the labels
    ``cons`` limits; UserError naming a bad fraction, an unknown label or a label without a limit."""
    if margin is None:
        return {}
    limited = [lab for lab, attrs in LIMITED_LABELS.items() if any(getattr(cons, a) is not None for a in attrs)]
    if not isinstance(margin, dict):
        margin = {lab: margin for lab in limited}
        if not limited:
            raise UserError("--margin: no limit to keep a margin from (give --max-power-w, --max-decel-g, ...)")
    out = {}
    for lab, m in margin.items():
        if lab not in LIMITED_LABELS:
            raise UserError(f"--margin {lab}: not a limited label (known: {', '.join(LIMITED_LABELS)})")
        if lab not in limited:
            raise UserError(f"--margin {lab}: {lab} has no limit (give --{LIMITED_LABELS[lab][0].replace('_', '-')})")
        try:
            if isinstance(m, bool):         # YAML's yes/no would pass float() as 1/0
                raise TypeError
            v = float(m)
        except (TypeError, ValueError):
            raise UserError(f"--margin {lab}: '{m}' is not a number") from None
        if not (0.0 <= v < 1.0):
            raise UserError(f"--margin {lab}: a fraction of the limit in [0, 1) is needed (0.05 = 5 %), got {m}")
        out[lab] = v
    return out


@dataclass(frozen=True)
class Constraints:
    """What a recommended operating point must satisfy.

    max_peak_force_n: peak_force_n <= this [N] (tool life).  peak_force_static_ratio: k with
    peak_force_n <= k × static_force_n (seed 002: the impulsive force should stay below the
    static preload to avoid bit bounce).  max_specific_energy_j_m: specific_energy_j_m <= this [J/m].
    max_power_w: power_w <= this [W] (the exciter's power rating).  max_decel_g: peak_decel_g <= this [g]
    (the bit's deceleration limit: tool life).  envelope: the exciter's force-against-frequency, stroke and coil
    velocity limits (pipeline/optimise/envelope.py), declared in the rig file.
    require_settled: status must be ok/no_contact (else not_settled is allowed; runaway/failed never are).
    require_progress: rop_m_s > 0 (set by the Pareto mode, where specific energy is otherwise infinite).
    margins: {label: fraction}: a point must stay that fraction below every limit on the label (0.05: power <=
    0.95 × max_power_w), and a predicted row is judged by the upper end of its interval (``label_hi``), so the
    recommendation stays feasible within the surrogate's uncertainty and a simulated one within ± the margin.
    """

    max_peak_force_n: float | None = None
    peak_force_static_ratio: float | None = None
    max_specific_energy_j_m: float | None = None
    max_power_w: float | None = None
    max_decel_g: float | None = None
    require_settled: bool = True
    require_progress: bool = False
    margins: Mapping[str, float] = field(default_factory=dict)
    envelope: object = None         # envelope.Envelope: the exciter's limits from the rig file, or None

    def limit_of(self, label: str, limit: float) -> float:
        """The limit a point must keep below on ``label``: ``limit`` less the label's margin (a fraction of it)."""
        return limit * (1.0 - float(self.margins.get(label, 0.0)))

    def _with_uncertainty(self, row: Mapping, label: str) -> float | None:
        """The label's value; under a margin, the upper end of its predicted interval (``label_hi``) when the row
        has one (a surrogate's prediction), so the point stays below the limit within that uncertainty."""
        v = _num(row.get(label))
        hi = _num(row.get(f"{label}_hi")) if label in self.margins else None
        return v if hi is None or v is None else max(v, hi)

    def names(self) -> list[str]:
        out = ["steady_state"]
        if self.require_progress:
            out.append("progress")
        if self.max_peak_force_n is not None:
            out.append("peak_force")
        if self.peak_force_static_ratio is not None:
            out.append("peak_vs_static")
        if self.max_specific_energy_j_m is not None:
            out.append("specific_energy")
        out += [key for key, (_, attr) in UPPER_LIMITS.items() if getattr(self, attr) is not None]
        if self.envelope is not None:
            out += list(self.envelope.values({}))
        return out

    def values(self, row: Mapping) -> dict[str, float]:
        """Constraint values of one label row (<= 0 feasible; a missing label counts as violated by 1)."""
        status = str(row.get("status"))
        ok = status in (SETTLED if self.require_settled else BOUNDED)
        out = {"steady_state": -1.0 if ok else 1.0}
        rop = _num(row.get("rop_m_s"))
        if self.require_progress:
            out["progress"] = -1.0 if (rop is not None and rop > 0) else 1.0
        pk = self._with_uncertainty(row, "peak_force_n")
        if self.max_peak_force_n is not None:
            lim = self.limit_of("peak_force_n", self.max_peak_force_n)
            out["peak_force"] = 1.0 if pk is None else (pk - lim) / lim
        if self.peak_force_static_ratio is not None:
            fs = _num(row.get("static_force_n"))
            lim = None if fs is None else self.limit_of("peak_force_n", self.peak_force_static_ratio * fs)
            if pk is None or lim is None:
                out["peak_vs_static"] = 1.0
            elif lim <= 0:
                out["peak_vs_static"] = 1.0 if pk > 0 else -1.0
            else:
                out["peak_vs_static"] = (pk - lim) / lim
        if self.max_specific_energy_j_m is not None:
            se = self._with_uncertainty(row, "specific_energy_j_m")
            lim = self.limit_of("specific_energy_j_m", self.max_specific_energy_j_m)
            # inf (nothing progresses) -> a large finite violation: optuna stores finite constraints only
            out["specific_energy"] = 1.0 if se is None else (1e3 if math.isinf(se) else min((se - lim) / lim, 1e3))
        for key, (label, attr) in UPPER_LIMITS.items():
            lim = getattr(self, attr)
            if lim is not None:
                lim = self.limit_of(label, lim)
                v = self._with_uncertainty(row, label)
                out[key] = 1.0 if v is None or math.isinf(v) else min((v - lim) / lim, 1e3)
        if self.envelope is not None:
            out.update(self.envelope.values(row))
        return out

    def feasible(self, row: Mapping) -> bool:
        return all(v <= 0 for v in self.values(row).values())

    def violation(self, row: Mapping) -> float:
        """Total violation (0 when feasible): how far a point is from meeting every constraint."""
        return sum(max(v, 0.0) for v in self.values(row).values())

    def check(self, static_range: tuple[float, float] | None, progress_force_floor: float | None) -> None:
        """Raise UserError for limits that are invalid or contradict each other / the physics.

        static_range: (low, high) of static_force_n over the search (or its fixed value twice).
        progress_force_floor: contact force the tool must reach to progress at all [N]
        (drill: the rock threshold Pr), or None when the model has no such floor.
        """
        for name in ("max_peak_force_n", "peak_force_static_ratio", "max_specific_energy_j_m", "max_power_w",
                     "max_decel_g"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise UserError(f"constraint {name} must be a positive number, got {v!r}")
        if progress_force_floor is None:
            return
        floor = progress_force_floor
        if self.max_peak_force_n is not None and self.max_peak_force_n < floor:
            raise UserError(
                f"contradictory constraints: max_peak_force_n = {self.max_peak_force_n:g} N is below the force "
                f"{floor:g} N the tool must reach to progress (rock threshold Pr), so no point with ROP > 0 "
                f"can satisfy it")
        if self.peak_force_static_ratio is not None and static_range is not None:
            best = self.peak_force_static_ratio * static_range[1]
            if best < floor:
                extra = (" — and static_force_n >= Pr is a runaway, so on this model k must exceed 1"
                         if self.peak_force_static_ratio <= 1 else "")
                raise UserError(
                    f"contradictory constraints: peak_force_n <= {self.peak_force_static_ratio:g} × static_force_n "
                    f"allows at most {best:g} N at static_force_n = {static_range[1]:g} N, below the force "
                    f"{floor:g} N the tool must reach to progress{extra}")

    def to_dict(self) -> dict:
        out = asdict(self)
        out["margins"] = dict(self.margins)
        out["envelope"] = None if self.envelope is None else self.envelope.to_dict()
        for key in ("margins", "envelope"):     # a study without them keeps the signature it always had
            if not out[key]:
                del out[key]
        return out


def progress_force_floor(model: str, values: Mapping[str, float]) -> float | None:
    """Contact force a model's tool must reach to progress [N] (``ModelSpec.progress_force_floor``), or None."""
    from sim import get_model

    return get_model(model).progress_force_floor(values)
