"""How sure is a recommended operating point?  Its ROP over samples of the rig's uncertain parameters.

A corrected rig (``sim.Rig`` from ``vibro diagnose``) carries the standard deviation of every fitted
parameter (``Rig.uncertainty``, SI units).  Every fitted parameter is positive and was fitted in log10, so a
sample is log-normal around the fitted value: p = p̂ · exp(σ z), z ~ N(0, 1), σ = sd / p̂ (the delta-method
inverse of the diagnosis's sd = p̂ · ln 10 · sd(log10 p)).  Samples are clipped to the parameter's fit bounds
(``ModelSpec.calibratable`` / ``effect_bounds``: an unidentifiable parameter's huge sd then spans its bounds,
not 50 decades).  Parameters are sampled independently (the rig file keeps no correlations, so the spread is
an upper estimate where fitted parameters trade off against each other).  The point is re-simulated with
every sample; a run that ends in any status but ``ok`` counts as zero ROP and as not progressing.

What the fitted model still gets wrong (``Rig.model_error``: the diagnosis's held-out rms ROP error relative to the
measured ROP) is added in quadrature, as 5-95 % half-widths around the nominal ROP (docs/optimise.md):
a = (p95 − p5) / 2, b = z · e · ROP, c = √(a² + b²), z = 1.645 (the 95 % point of a normal).  A rig with an
empirical ROP correction (``Rig.empirical``, "physics unknown") has it applied to every sample's ROP, and e is then
the correction's predictive sd at the point relative to the corrected ROP.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from vibrobase.statuses import SETTLED_STATUSES

Z_90 = 1.6448536269514722
"""Half-width of a normal's 5-95 % interval in sd (its 95 % point): a relative sd e spans ±Z_90 · e · ROP."""


def combined_half_widths(p5: float, p95: float, nominal: float, rop_rel: float | None
                         ) -> tuple[float, float | None, float | None]:
    """(parameter, model-error, combined) 5-95 % half-widths of ROP [m/s]: a = (p95 − p5) / 2, b = Z_90 · e ·
    nominal, c = √(a² + b²); b and c None when the model error e [1] is not given."""
    a = 0.5 * (float(p95) - float(p5))
    if rop_rel is None:
        return a, None, None
    b = Z_90 * float(rop_rel) * abs(float(nominal))
    return a, b, math.hypot(a, b)


@dataclass(frozen=True)
class RopSpread:
    """ROP of one operating point over samples of the rig's fitted parameters [m/s], and with its model error.

    The half-widths are of 5-95 % intervals around the nominal ROP [m/s]; the model-error ones are None when the rig
    gives no model error (``Rig.model_error``), which is unknown, not zero.
    """

    nominal_rop_m_s: float            # at the fitted values
    median_rop_m_s: float
    p5_rop_m_s: float
    p95_rop_m_s: float
    fraction_progressing: float       # samples with status ok and ROP > 0
    n_samples: int
    sampled: tuple[str, ...]          # parameters that were sampled (sd > 0)
    statuses: dict[str, int] = field(default_factory=dict)
    parameter_half_width_m_s: float = 0.0             # a = (p95 - p5) / 2
    model_error_rel: float | None = None              # e: the rig's relative ROP model error [1]
    model_error_half_width_m_s: float | None = None   # b = Z_90 e ROP
    combined_half_width_m_s: float | None = None      # c = sqrt(a² + b²)
    model_error_basis: str = ""                       # where e comes from, in words
    empirical_correction: bool = False                # ROP corrected by the rig's empirical correction; e is its sd

    def to_dict(self) -> dict:
        """Plain mapping (report.json / metrics)."""
        return {"nominal_rop_m_s": self.nominal_rop_m_s, "median_rop_m_s": self.median_rop_m_s,
                "p5_rop_m_s": self.p5_rop_m_s, "p95_rop_m_s": self.p95_rop_m_s,
                "fraction_progressing": self.fraction_progressing, "n_samples": self.n_samples,
                "sampled": list(self.sampled), "statuses": dict(self.statuses),
                "parameter_half_width_m_s": self.parameter_half_width_m_s, "model_error_rel": self.model_error_rel,
                "model_error_half_width_m_s": self.model_error_half_width_m_s,
                "combined_half_width_m_s": self.combined_half_width_m_s, "model_error_basis": self.model_error_basis,
                "empirical_correction": self.empirical_correction}


def fit_bounds(model: str) -> dict[str, tuple[float, float]]:
    """(low, high) of every fitted parameter of ``model`` (calibratable, §6 effect parameters, discrepancy terms)."""
    import sim

    spec = sim.get_model(model)
    out = {b.name: (float(b.lo), float(b.hi)) for b in spec.calibratable}
    out.update({n: (float(b.lo), float(b.hi)) for n, b in dict(spec.effect_bounds).items()})
    out.update({n: (float(b.lo), float(b.hi)) for n, b in dict(spec.discrepancy_bounds).items()})
    return out


def parameter_samples(rig, n_samples: int, seed: int) -> list[dict[str, float]]:
    """``n_samples`` log-normal samples of the rig's uncertain parameters (name -> value), clipped to the fit bounds."""
    values = rig.resolve()
    bounds = fit_bounds(rig.model)
    names = [n for n, sd in rig.uncertainty.items() if float(sd) > 0.0 and float(values[n]) > 0.0]
    rng = np.random.default_rng(seed)
    z = rng.standard_normal((n_samples, len(names)))
    out = []
    for row in z:
        sample = {}
        for name, zi in zip(names, row):
            v = float(values[name])
            s = float(rig.uncertainty[name]) / v
            x = v * math.exp(min(s * zi, 700.0))
            lo, hi = bounds.get(name, (0.0, math.inf))
            sample[name] = float(min(max(x, lo), hi))
        out.append(sample)
    return out


def rop_spread(rig, point: Mapping[str, float], n_samples: int = 32, seed: int = 0,
               settings: Mapping | None = None, n_threads: int | None = None) -> RopSpread:
    """Re-simulate the operating point ``point`` (controls, e.g. frequency_hz, amplitude_n, static_force_n) on
    ``rig`` at its fitted values and at ``n_samples`` samples of its uncertain parameters."""
    import sim

    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    samples = parameter_samples(rig, n_samples, seed)
    base = rig.resolve(**dict(point))          # every row holds every parameter (no NaN columns in the batch)
    table = [base] + [{**base, **s} for s in samples]
    df = sim.simulate_batch(rig.model, table, preset=rig.preset, settings=dict(settings or {}), n_threads=n_threads)
    ok = df["status"].isin(list(SETTLED_STATUSES)).to_numpy()
    rop = np.where(ok, df["rop_m_s"].astype(float).fillna(0.0).to_numpy(), 0.0)
    rel, basis = (None, "") if rig.model_error is None else (rig.model_error.rop_rel, rig.model_error.basis)
    if rig.empirical is not None:
        rop, rel, basis = _corrected(rig.empirical, rop, base)
    rs = rop[1:]
    counts = df["status"].iloc[1:].value_counts().to_dict()
    p5, p95 = float(np.percentile(rs, 5)), float(np.percentile(rs, 95))
    a, b, c = combined_half_widths(p5, p95, float(rop[0]), rel)
    return RopSpread(nominal_rop_m_s=float(rop[0]), median_rop_m_s=float(np.median(rs)), p5_rop_m_s=p5,
                     p95_rop_m_s=p95, fraction_progressing=float(np.mean(ok[1:] & (rs > 0))), n_samples=int(n_samples),
                     sampled=tuple(samples[0]) if samples else (), statuses={str(k): int(v) for k, v in counts.items()},
                     parameter_half_width_m_s=a, model_error_rel=rel, model_error_half_width_m_s=b,
                     combined_half_width_m_s=c, model_error_basis=basis,
                     empirical_correction=rig.empirical is not None)


def _corrected(correction, rop: np.ndarray, point: Mapping[str, float]) -> tuple[np.ndarray, float | None, str]:
    """ROP with the rig's empirical correction applied where it progresses (never below 0), the correction's sd at
    the point relative to the corrected nominal ROP (its model error: the scatter it could not follow included),
    and where that comes from."""
    out, sd = correction.correct(rop, {n: np.full(rop.size, float(point[n])) for n in correction.inputs})
    rel = float(sd[0] / out[0]) if out[0] > 0 else None
    return out, rel, f"{correction.basis}; its predictive sd at the point"
