"""An empirical correction of ROP: what the measurements say the model gets wrong, where no physics explained it.

When a diagnosis finds a residual that no §6 effect and no proposed term explains, it may fit a Gaussian process
to the relative ROP discrepancy over the operating point (``pipeline.diagnosis.empirical``) and carry it in the
corrected rig.  It is a correction of a label, not physics: the simulator's dynamics are unchanged, and the
optimiser applies it to the simulated ROP.  Here it is only evaluated (numpy), from what the rig file stores:

    d(x)  = μ + k(x, X) (K + σn² I)⁻¹ (d_X − μ),   var(x) = σf² + σn² − k(x, X) (K + σn² I)⁻¹ k(X, x)
    k(a, b) = σf² exp(−½ Σ_j ((a_j − b_j) / ℓ_j)²) on inputs scaled to [0, 1] over the measured runs' range
    ROP_corrected = max(ROP_model + d(x) · max(ROP_model, floor), 0)   where ROP_model > 0 (else unchanged)

with d_X the measured relative discrepancies (measured − model) / max(|model|, floor) at the runs X.  σn holds the
scatter the correction cannot follow (the measurement noise and what varies faster than the runs resolve).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from sim.models.param import ParameterError, check_known_keys

LABEL = "empirical correction, physics unknown"
"""How every report names it: a fitted correction of ROP, never presented as physics."""
KEYS = ("label", "target", "inputs", "lower", "upper", "points", "values", "mean", "length_scales", "signal_sd",
        "noise_sd", "floor_m_s", "basis")
"""Keys of a rig's ``empirical_correction`` mapping (``label`` and ``basis`` optional)."""


def _floats(v: Any, what: str, n: int | None = None) -> tuple[float, ...]:
    """``v`` as a tuple of finite floats (of length ``n`` when given), else ParameterError naming ``what``."""
    try:
        out = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise ParameterError(f"rig: empirical_correction {what} must be a list of numbers, got {v!r}") from None
    if not all(math.isfinite(x) for x in out) or (n is not None and len(out) != n):
        raise ParameterError(f"rig: empirical_correction {what} must be {n or 'some'} finite numbers, got {v!r}")
    return out


@dataclass(frozen=True)
class EmpiricalCorrection:
    """A Gaussian-process correction of the model's ROP over the operating point (see the module docstring).

    ``inputs``: control names (e.g. frequency_hz, static_force_n); ``lower``/``upper``: their scaling range [SI];
    ``points``: the measured runs' controls [SI], one tuple per run; ``values``: their relative discrepancies [1];
    ``mean`` [1], ``length_scales`` [1, on the scaled inputs], ``signal_sd`` σf [1], ``noise_sd`` σn [1]: the
    fitted process; ``floor_m_s``: the smallest ROP a discrepancy is relative to [m/s]; ``basis``: where it comes
    from and how well it did on held-out runs, in words."""

    inputs: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    points: tuple[tuple[float, ...], ...]
    values: tuple[float, ...]
    mean: float
    length_scales: tuple[float, ...]
    signal_sd: float
    noise_sd: float
    floor_m_s: float
    basis: str = ""
    target: str = "rop_m_s"

    def __post_init__(self) -> None:
        n_in = len(self.inputs)
        if n_in < 1 or not all(isinstance(s, str) for s in self.inputs):
            raise ParameterError(f"rig: empirical_correction inputs must name controls, got {self.inputs!r}")
        if self.target != "rop_m_s":
            raise ParameterError(f"rig: empirical_correction target must be rop_m_s, got {self.target!r}")
        for what in ("lower", "upper", "length_scales"):
            object.__setattr__(self, what, _floats(getattr(self, what), what, n_in))
        if any(u <= lo for lo, u in zip(self.lower, self.upper)) or any(s <= 0 for s in self.length_scales):
            raise ParameterError("rig: empirical_correction needs upper > lower and length_scales > 0 per input")
        pts = tuple(_floats(p, "points", n_in) for p in self.points)
        vals = _floats(self.values, "values", len(pts))
        if len(pts) < 2:
            raise ParameterError("rig: empirical_correction needs at least 2 points")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "values", vals)
        for what in ("mean", "signal_sd", "noise_sd", "floor_m_s"):
            v = _floats([getattr(self, what)], what, 1)[0]
            if (what in ("signal_sd", "floor_m_s") and v <= 0) or (what == "noise_sd" and v < 0):
                raise ParameterError(f"rig: empirical_correction {what} must be {'>=' if what == 'noise_sd' else '>'} 0, "
                                     f"got {v!r}")
            object.__setattr__(self, what, v)

    def _scaled(self, x):
        import numpy as np     # not at import: a rig is read by commands whose --help stays light

        lo, hi, ell = (np.asarray(a, float) for a in (self.lower, self.upper, self.length_scales))
        return (x - lo) / (hi - lo) / ell

    def relative(self, controls: Mapping[str, Any]):
        """(mean, sd) arrays of the relative discrepancy [1] at operating points ``controls`` (name -> value or array;
        every name of ``inputs`` needed)."""
        import numpy as np

        missing = [n for n in self.inputs if n not in controls]
        if missing:
            raise ParameterError(f"empirical correction: needs {', '.join(missing)} (its inputs: "
                                 f"{', '.join(self.inputs)})")
        x = np.column_stack([np.atleast_1d(np.asarray(controls[n], float)) for n in self.inputs])
        xs, ps = self._scaled(x), self._scaled(np.asarray(self.points, float))
        k = self.signal_sd ** 2 * np.exp(-0.5 * ((xs[:, None, :] - ps[None, :, :]) ** 2).sum(-1))
        kk = self.signal_sd ** 2 * np.exp(-0.5 * ((ps[:, None, :] - ps[None, :, :]) ** 2).sum(-1))
        chol = np.linalg.cholesky(kk + (self.noise_sd ** 2 + 1e-12 * self.signal_sd ** 2) * np.eye(len(ps)))
        alpha = np.linalg.solve(chol.T, np.linalg.solve(chol, np.asarray(self.values) - self.mean))
        v = np.linalg.solve(chol, k.T)
        var = self.signal_sd ** 2 + self.noise_sd ** 2 - (v ** 2).sum(0)
        return self.mean + k @ alpha, np.sqrt(np.maximum(var, 0.0))

    @staticmethod
    def discrepancy(measured_m_s: Any, model_m_s: Any, floor_m_s: float):
        """The relative discrepancy d = (measured − model) / max(|model|, floor) [1] a correction is fitted to (the
        inverse of ``correct``); arrays of ROP [m/s]."""
        import numpy as np

        model = np.asarray(model_m_s, float)
        return (np.asarray(measured_m_s, float) - model) / np.maximum(np.abs(model), floor_m_s)

    def correct(self, rop_m_s: Any, controls: Mapping[str, Any]):
        """(corrected ROP, its sd) arrays [m/s] of model ROP ``rop_m_s`` [m/s] at operating points ``controls``: a
        point that progresses gets ROP + d · max(ROP, floor), never below 0; one that does not stays as it is (sd 0):
        a correction of how fast the bit goes, not of whether it goes."""
        import numpy as np

        rop = np.atleast_1d(np.asarray(rop_m_s, float))
        mu, sd = self.relative(controls)
        scale = np.maximum(np.abs(rop), self.floor_m_s)
        moving = rop > 0
        return np.where(moving, np.maximum(rop + mu * scale, 0.0), rop), np.where(moving, sd * scale, 0.0)

    def to_mapping(self) -> dict[str, Any]:
        """Plain mapping in the rig-file layout."""
        out = {"label": LABEL, "target": self.target, "inputs": list(self.inputs), "lower": list(self.lower),
               "upper": list(self.upper), "points": [list(p) for p in self.points], "values": list(self.values),
               "mean": self.mean, "length_scales": list(self.length_scales), "signal_sd": self.signal_sd,
               "noise_sd": self.noise_sd, "floor_m_s": self.floor_m_s}
        if self.basis:
            out["basis"] = self.basis
        return out

    @classmethod
    def from_mapping(cls, data: Any) -> "EmpiricalCorrection":
        """Validated correction from a rig file's ``empirical_correction`` mapping (keys :data:`KEYS`)."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"rig: 'empirical_correction' must be a mapping ({', '.join(KEYS)}), got {data!r}")
        check_known_keys(data, KEYS, "empirical_correction key")
        missing = [k for k in KEYS if k not in data and k not in ("label", "basis")]
        if missing:
            raise ParameterError(f"rig: empirical_correction needs {', '.join(missing)}")
        if not isinstance(data["inputs"], (list, tuple)) or not isinstance(data["points"], (list, tuple)):
            raise ParameterError("rig: empirical_correction inputs and points must be lists")
        return cls(inputs=tuple(str(s) for s in data["inputs"]), lower=data["lower"], upper=data["upper"],
                   points=tuple(data["points"]), values=data["values"], mean=data["mean"],
                   length_scales=data["length_scales"], signal_sd=data["signal_sd"], noise_sd=data["noise_sd"],
                   floor_m_s=data["floor_m_s"], basis=str(data.get("basis") or ""), target=str(data["target"]))
