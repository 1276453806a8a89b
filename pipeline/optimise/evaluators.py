"""Things a study asks for labels: the simulator itself, or a trained surrogate bundle.

Both map a DataFrame of inputs to a DataFrame of label rows (same order) with at least
``status``, ``rop_m_s`` [m/s], ``peak_force_n`` [N], ``specific_energy_j_m`` [J/m] and the inputs.
"""
from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from surrogate.names import REGIME_TO_STATUS


class SimulatorEvaluator:
    """Labels by ``sim.simulate_batch``; counts every simulator call in ``calls``."""

    kind = "simulator"

    def __init__(self, model: str, preset: str | None, fixed: dict | None = None, settings=None,
                 n_threads: int | None = None, history_labels: bool = False):
        import sim

        self.history_labels = history_labels     # add envelope.ENVELOPE_LABELS (stroke, coil velocity) per row
        self.model, self.preset, self.fixed = model, preset, dict(fixed or {})
        self.settings, self.n_threads = settings, n_threads
        self.calls = 0
        self.resolved = sim.get_model(model).resolve(preset, **self.fixed)   # validates model/preset/fixed now

    def __call__(self, X: pd.DataFrame) -> pd.DataFrame:
        import sim

        table = X.reset_index(drop=True).copy()
        for k, v in self.fixed.items():
            if k not in table.columns:
                table[k] = v
        out = sim.simulate_batch(self.model, table, preset=self.preset, settings=self.settings,
                                 n_threads=self.n_threads)
        if self.history_labels:
            from pipeline.optimise.envelope import history_labels

            extra = history_labels(self.model, self.preset, table, self.settings)
            out = out.reset_index(drop=True)
            for c in extra.columns:
                out[c] = extra[c].to_numpy()
        self.calls += len(table)
        return out


class RopCorrected:
    """The labels of ``inner`` (a ``SimulatorEvaluator``) with a rig's empirical ROP correction applied
    (``sim.empirical``: "empirical correction, physics unknown"): ``rop_m_s`` corrected where the point progresses
    (never below 0; a point that does not progress stays at 0), the model's own in ``rop_model_m_s`` and the
    correction's sd in ``rop_correction_sd_m_s`` [m/s].  Everything else is ``inner``'s."""

    def __init__(self, inner: SimulatorEvaluator, correction):
        self.inner, self.correction = inner, correction

    def __getattr__(self, name):          # calls, resolved, model, ...: the simulator's
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def __call__(self, X: pd.DataFrame) -> pd.DataFrame:
        out = self.inner(X).reset_index(drop=True)
        table = X.reset_index(drop=True)
        ctl = {n: (table[n] if n in table.columns else pd.Series(self.inner.resolved[n], index=table.index)).to_numpy(float)
               for n in self.correction.inputs}
        rop = out["rop_m_s"].astype(float).fillna(0.0).to_numpy()
        fixed, sd = self.correction.correct(rop, ctl)
        out["rop_model_m_s"] = out["rop_m_s"]
        out["rop_m_s"] = np.where(rop > 0, fixed, out["rop_m_s"].to_numpy())    # a missing ROP stays missing
        out["rop_correction_sd_m_s"] = sd
        return out


class SurrogateEvaluator:
    """Labels predicted by a surrogate bundle (contract: ``Bundle.predict`` → p_progress, regime, T, T_lo, T_hi).

    ``status`` is derived from the predicted regime; inputs the bundle does not take (e.g. a fixed
    static force) are copied from ``fixed``.
    """

    kind = "surrogate"

    def __init__(self, bundle, fixed: dict | None = None):
        self.bundle = bundle
        self.fixed = dict(fixed or {})
        self.calls = 0

    def __call__(self, X: pd.DataFrame) -> pd.DataFrame:
        X = X.reset_index(drop=True)
        missing = [n for n in self.bundle.inputs if n not in X.columns]
        if missing:
            raise UserError(f"the surrogate needs input(s) {missing} that the search space does not provide")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # ranges are checked against bundle.ranges before the study
            pred = self.bundle.predict(X[list(self.bundle.inputs)]).reset_index(drop=True)
        self.calls += len(X)
        out = X.copy()
        for k, v in self.fixed.items():
            if k not in out.columns:
                out[k] = v
        for c in pred.columns:
            out[c] = pred[c].to_numpy()
        out["status"] = [REGIME_TO_STATUS.get(str(r), "failed") for r in pred["regime"]]
        if "rop_m_s" in out:
            rop = out["rop_m_s"].to_numpy(dtype=float)
            # a predicted regime without progression has no ROP, whatever the regressor extrapolates
            stuck = np.isin(pred["regime"].to_numpy().astype(str), ["no_progress", "runaway", "failed"])
            out["rop_m_s"] = np.where(stuck, 0.0, rop)
        return out
