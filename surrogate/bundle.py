"""The trained surrogate: input schema + regime classifier + one regressor (with intervals) per target.

``Bundle.predict(X)`` returns p_progress, regime and, per target T, T / T_lo / T_hi (90 %
prediction interval by default).  By default the numbers are gated by the predicted
regime: where it is ``no_progress`` ROP is 0 and specific energy +inf (exactly, lo = hi);
targets learned on the progressing regime are NaN where it is ``not_settled``, and every
target is NaN where it is ``runaway`` or ``failed`` (the simulator gives no numbers there).
``conditional=True`` returns every regressor's raw prediction instead (the value the
target would have if the point were in the target's training domain).
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from pipeline.core.errors import UserError
from pipeline.core.files import atomic_write_text, atomic_write_with
from surrogate.candidates import SubsampledGP
from surrogate.features import InputScaler, TargetTransform
from surrogate.intervals import ConformalInterval

FORMAT = 1
ARTIFACT_DIR = "surrogate"


class ExtrapolationWarning(UserWarning):
    """A prediction was asked for outside the ranges the surrogate was trained on."""


@dataclass
class TargetModel:
    """One regression target: estimator on scaled inputs -> transformed target, plus its interval."""

    target: str
    name: str                  # candidate that won the CV (gp | gbt | mlp | krr)
    estimator: object
    transform: TargetTransform
    interval: ConformalInterval
    domain: str                # progressing | settled | all

    def predict(self, Xs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(value, lo, hi) in original units."""
        if isinstance(self.estimator, SubsampledGP):
            z, s = self.estimator.predict(Xs, return_std=True)
        else:
            z, s = self.estimator.predict(Xs), None
        lo, hi = self.interval.bounds(z, s)
        inv = self.transform.inverse
        return inv(z), inv(lo), inv(hi)


@dataclass
class Bundle:
    inputs: list[str]
    ranges: dict[str, tuple[float, float]]
    model: str
    preset: str | None
    fingerprint: str
    scaler: InputScaler
    classifier: object
    classifier_name: str
    classes: list[str]
    regressors: dict[str, TargetModel]
    report: dict = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)      # the sweep's fixed parameters [SI]: the conditions it was trained under
    settings: dict = field(default_factory=dict)   # the sweep's simulator settings (verification re-simulates with them)

    def __setstate__(self, state: dict) -> None:
        """Bundles pickled before ``fixed``/``settings`` existed load with both empty."""
        self.__dict__.update({"fixed": {}, "settings": {}, **state})

    # ---- checks ---------------------------------------------------------------------------
    def check_model(self, model: str | None) -> None:
        """UserError unless this bundle was trained on ``model``'s data (None = no check)."""
        if model is not None and model != self.model:
            raise UserError(f"surrogate was trained on model '{self.model}' data (preset {self.preset!r}); "
                            f"it cannot be used for model '{model}'")

    def _inputs_array(self, X) -> np.ndarray:
        if not isinstance(X, pd.DataFrame):
            X = pd.DataFrame(X)
        missing = [n for n in self.inputs if n not in X.columns]
        if missing:
            raise UserError(f"predict: missing input column(s) {missing}; the surrogate needs {self.inputs}")
        A = np.empty((len(X), len(self.inputs)))
        for j, n in enumerate(self.inputs):
            col = pd.to_numeric(X[n], errors="coerce").to_numpy(dtype=float)
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                raise UserError(f"predict: column '{n}' row {int(bad[0])} is not a finite number")
            A[:, j] = col
        return A

    def out_of_range(self, A: np.ndarray) -> list[str]:
        """Messages naming each input (and first row) outside the trained range."""
        msgs = []
        for j, n in enumerate(self.inputs):
            lo, hi = self.ranges[n]
            tol = 1e-9 * (hi - lo)
            bad = np.flatnonzero((A[:, j] < lo - tol) | (A[:, j] > hi + tol))
            if bad.size:
                msgs.append(f"{n} = {A[bad[0], j]:g} (row {int(bad[0])}, {bad.size} row(s)) is outside the trained "
                            f"range [{lo:g}, {hi:g}]")
        return msgs

    # ---- prediction ----------------------------------------------------------------------
    def predict(self, X, strict: bool = False, conditional: bool = False) -> pd.DataFrame:
        """Predict at the rows of X (a DataFrame holding the input columns; other columns ignored).

        Outside the trained ranges: ExtrapolationWarning, or UserError when ``strict``."""
        A = self._inputs_array(X)
        msgs = self.out_of_range(A)
        if msgs:
            text = "surrogate extrapolation: " + "; ".join(msgs)
            if strict:
                raise UserError(text)
            warnings.warn(text, ExtrapolationWarning, stacklevel=2)
        with threadpool_limits(1):   # OpenMP threads spin on a shared machine; 1 is faster for these sizes
            return self._predict(X, self.scaler.transform(A), conditional)

    def _predict(self, X, Xs: np.ndarray, conditional: bool) -> pd.DataFrame:
        proba = self.classifier.predict_proba(Xs)
        cls = [str(c) for c in self.classifier.classes_]
        out = pd.DataFrame(index=X.index if isinstance(X, pd.DataFrame) else None)
        out["p_progress"] = proba[:, cls.index("progressing")] if "progressing" in cls else 0.0
        regime = np.array(cls, dtype=object)[proba.argmax(1)]
        out["regime"] = regime
        for t, tm in self.regressors.items():
            v, lo, hi = tm.predict(Xs)
            if not conditional:
                no_num = np.isin(regime, ["runaway", "failed"])
                if tm.domain == "progressing":
                    no_num |= regime == "not_settled"
                    stop = regime == "no_progress"
                    fill = np.inf if t == "specific_energy_j_m" else 0.0
                    v, lo, hi = (np.where(stop, fill, a) for a in (v, lo, hi))
                v, lo, hi = (np.where(no_num, np.nan, a) for a in (v, lo, hi))
            out[t], out[f"{t}_lo"], out[f"{t}_hi"] = v, lo, hi
        return out

    # ---- persistence ---------------------------------------------------------------------
    def schema(self) -> dict:
        return {"format": FORMAT, "inputs": self.inputs, "ranges": {k: list(v) for k, v in self.ranges.items()},
                "scale": self.scaler.scale, "model": self.model, "preset": self.preset,
                "fixed": self.fixed, "settings": self.settings,
                "fingerprint": self.fingerprint, "classifier": self.classifier_name, "classes": self.classes,
                "targets": {t: {"model": m.name, "transform": m.transform.kind, "domain": m.domain,
                                "interval_q": m.interval.q, "interval_level": m.interval.level,
                                "interval_normalised": m.interval.normalised}
                            for t, m in self.regressors.items()},
                "outputs": ["p_progress", "regime"] + [f"{t}{s}" for t in self.regressors for s in ("", "_lo", "_hi")],
                "versions": _versions()}

    def save(self, path: str | os.PathLike) -> Path:
        """Write bundle.json (schema, human-readable), report.json and bundle.joblib (estimators), atomically."""
        import joblib

        from pipeline.core.jsonable import dump_json

        d = Path(path)
        d.mkdir(parents=True, exist_ok=True)
        atomic_write_text(d / "bundle.json", dump_json(self.schema()) + "\n")
        atomic_write_text(d / "report.json", dump_json(self.report) + "\n")
        atomic_write_with(d / "bundle.joblib", lambda tmp: joblib.dump({"format": FORMAT, "bundle": self}, tmp, compress=3))
        return d


def _versions() -> dict:
    import sklearn

    return {"scikit-learn": sklearn.__version__, "numpy": np.__version__}


def load_bundle(ref: str | os.PathLike, model: str | None = None) -> Bundle:
    """Load a bundle from its directory (pipeline.tracking.load_bundle also resolves MLflow run ids).

    ``model``: raise UserError unless the bundle was trained on that model's data."""
    import joblib

    path = Path(ref)
    if not (path / "bundle.joblib").is_file():
        raise UserError(f"'{ref}' is not a surrogate bundle directory (no bundle.joblib)")
    try:
        obj = joblib.load(path / "bundle.joblib")
    except Exception as e:  # noqa: BLE001 - corrupt / foreign pickle
        raise UserError(f"{path / 'bundle.joblib'}: cannot be read ({type(e).__name__}: {e})") from None
    if not isinstance(obj, dict) or obj.get("format") != FORMAT or not isinstance(obj.get("bundle"), Bundle):
        raise UserError(f"{path / 'bundle.joblib'}: not a vibro surrogate bundle of format {FORMAT}")
    b = obj["bundle"]
    b.check_model(model)
    return b
