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

import hashlib
import json
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from vibrobase.files import atomic_write_bytes, atomic_write_text
from surrogate.bundle_check import BundleContentError, check_contents, check_payload_size
from surrogate.candidates import SubsampledGP
from surrogate.errors import BundleError, DataError
from surrogate.features import InputScaler, TargetTransform
from surrogate.intervals import ConformalInterval
from surrogate.tree_check import CHECKED_TYPES, TreeStorageError, check_trees

FORMAT = 2                       # 1: bundle.joblib (pickle), no manifest; 2: skops + manifest
PAYLOAD = "bundle.skops"
MANIFEST = "manifest.json"
MANIFEST_KIND = "vibro-surrogate-bundle"
ARTIFACT_DIR = "surrogate"
MAX_MANIFEST_BYTES = 2**20
"""Largest manifest.json read [bytes]; a real one is under 1 kB."""
MAX_FILE_BYTES = 256 * 2**20
"""Largest file of a bundle [bytes] (the payload is compressed: a real one is a few MB)."""


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
        """BundleError unless this bundle was trained on ``model``'s data (None = no check)."""
        if model is not None and model != self.model:
            raise BundleError(f"surrogate was trained on model '{self.model}' data (preset {self.preset!r}); "
                            f"it cannot be used for model '{model}'")

    def _inputs_array(self, X) -> np.ndarray:
        if not isinstance(X, pd.DataFrame):
            X = pd.DataFrame(X)
        missing = [n for n in self.inputs if n not in X.columns]
        if missing:
            raise DataError(f"predict: missing input column(s) {missing}; the surrogate needs {self.inputs}")
        A = np.empty((len(X), len(self.inputs)))
        for j, n in enumerate(self.inputs):
            col = pd.to_numeric(X[n], errors="coerce").to_numpy(dtype=float)
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                raise DataError(f"predict: column '{n}' row {int(bad[0])} is not a finite number")
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

        Outside the trained ranges: ExtrapolationWarning, or DataError when ``strict``."""
        A = self._inputs_array(X)
        msgs = self.out_of_range(A)
        if msgs:
            text = "surrogate extrapolation: " + "; ".join(msgs)
            if strict:
                raise DataError(text)
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
        """Write bundle.skops (estimators), bundle.json (schema), report.json, then manifest.json
        (sha256 and size of each), each atomically; the manifest last, so a half-written bundle
        never verifies."""
        import skops.io as sio

        from vibrobase.jsonable import dump_json

        d = Path(path)
        d.mkdir(parents=True, exist_ok=True)
        data = sio.dumps(self)
        unknown = sorted(set(sio.get_untrusted_types(data=data)) - set(TRUSTED_TYPES) - set(CHECKED_TYPES))
        if unknown:   # a bug, not a user error: a new estimator class must be reviewed and listed
            raise RuntimeError(f"bundle holds types not in surrogate.bundle.TRUSTED_TYPES: {unknown}")
        atomic_write_bytes(d / PAYLOAD, data)
        atomic_write_text(d / "bundle.json", dump_json(self.schema()) + "\n")
        atomic_write_text(d / "report.json", dump_json(self.report) + "\n")
        files = {n: {"sha256": hashlib.sha256((d / n).read_bytes()).hexdigest(), "size": (d / n).stat().st_size}
                 for n in (PAYLOAD, "bundle.json", "report.json")}
        atomic_write_text(d / MANIFEST, dump_json({"kind": MANIFEST_KIND, "format": FORMAT, "payload": PAYLOAD,
                                                "files": files, "versions": _versions()}) + "\n")
        return d


# Types a bundle may hold beyond skops' defaults (numpy, scipy, scikit-learn estimators): reviewed
# classes of this package and scikit-learn internals skops does not trust by default.  Loading
# refuses anything else *before* constructing it.  scikit-learn's tree storage, which skops leaves
# out on purpose, is not here: it is surrogate.tree_check.CHECKED_TYPES, bounds-checked after loading.
TRUSTED_TYPES = (
    "surrogate.bundle.Bundle", "surrogate.bundle.TargetModel", "surrogate.candidates.SubsampledGP",
    "surrogate.features.InputScaler", "surrogate.features.TargetTransform", "surrogate.intervals.ConformalInterval",
    "sklearn.gaussian_process.kernels.ConstantKernel", "sklearn.gaussian_process.kernels.Matern",
    "sklearn.gaussian_process.kernels.RBF", "sklearn.gaussian_process.kernels.Product",
    "sklearn.gaussian_process.kernels.Sum", "sklearn.gaussian_process.kernels.WhiteKernel",
    "sklearn.gaussian_process.kernels.Hyperparameter",
    "sklearn.neural_network._stochastic_optimizers.AdamOptimizer",
    "sklearn.neural_network._stochastic_optimizers.SGDOptimizer",
)


def _versions() -> dict:
    import sklearn
    import skops

    return {"scikit-learn": sklearn.__version__, "numpy": np.__version__, "skops": skops.__version__}


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(2**20), b""):
            h.update(block)
    return h.hexdigest()


def verify_bundle(path: str | os.PathLike) -> dict:
    """Check a bundle directory's manifest and every file's size and sha256 WITHOUT deserialising
    anything; returns the manifest.  BundleError (one line naming the file) when corrupt, foreign,
    tampered or of an old format.  This catches damage and mix-ups, not a deliberate attacker
    (who can rewrite the manifest too): that is what the skops trusted-type check in
    :func:`load_bundle` is for."""
    d = Path(path)
    mpath = d / MANIFEST
    if not d.is_dir() or not (mpath.is_file() or (d / "bundle.joblib").is_file()):
        raise BundleError(f"'{path}' is not a surrogate bundle directory (no {MANIFEST})")
    if not mpath.is_file():
        raise BundleError(f"{d}: an old-format surrogate bundle (bundle.joblib, a pickle without a manifest); it is not "
                        f"loaded because unpickling runs code: retrain it with 'vibro train'")
    if mpath.is_file() and mpath.stat().st_size > MAX_MANIFEST_BYTES:
        raise BundleError(f"{mpath}: {mpath.stat().st_size} bytes, not a bundle manifest "
                          f"(at most {MAX_MANIFEST_BYTES})")
    try:
        man = json.loads(mpath.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise BundleError(f"{mpath}: unreadable bundle manifest ({type(e).__name__})") from None
    if not isinstance(man, dict) or man.get("kind") != MANIFEST_KIND:
        raise BundleError(f"{mpath}: not a vibro surrogate bundle manifest")
    if man.get("format") != FORMAT:
        raise BundleError(f"{mpath}: bundle format {man.get('format')!r}, this vibro reads format {FORMAT}; "
                        f"retrain with 'vibro train'")
    files = man.get("files")
    if not isinstance(files, dict) or man.get("payload") != PAYLOAD or PAYLOAD not in files:
        raise BundleError(f"{mpath}: malformed bundle manifest (no '{PAYLOAD}' entry)")
    for name, rec in files.items():
        f = d / str(name)
        if "/" in str(name) or not isinstance(rec, dict):
            raise BundleError(f"{mpath}: malformed entry {name!r}")
        if not f.is_file():
            raise BundleError(f"{f}: missing (listed in the bundle manifest)")
        if f.stat().st_size != rec.get("size"):
            raise BundleError(f"{f}: {f.stat().st_size} bytes, the manifest says {rec.get('size')} (truncated or replaced)")
        if f.stat().st_size > MAX_FILE_BYTES:
            raise BundleError(f"{f}: {f.stat().st_size // 2**20} MiB, more than the {MAX_FILE_BYTES // 2**20} MiB a "
                              "bundle file may hold")
        if _sha256(f) != rec.get("sha256"):
            raise BundleError(f"{f}: sha256 differs from the bundle manifest (damaged or tampered with)")
    return man


def load_bundle(ref: str | os.PathLike, model: str | None = None) -> Bundle:
    """Load a bundle from its directory (a caller resolves other references, e.g. MLflow run ids, to one).

    Order: manifest and hashes (:func:`verify_bundle`), then the skops payload's types against
    :data:`TRUSTED_TYPES` and the tree storage types, and only then are objects constructed; every
    tree's node arrays are bounds-checked and every stored value checked (surrogate.bundle_check, with a bound on
    the inflated size before loading) before the bundle is returned.  ``model``: raise BundleError unless
    the bundle was trained on that model's data."""
    import skops.io as sio

    path = Path(ref)
    if not path.is_dir():
        raise BundleError(f"'{ref}' is not a surrogate bundle directory")
    verify_bundle(path)
    f = path / PAYLOAD
    data = f.read_bytes()
    try:
        untrusted = sio.get_untrusted_types(data=data)
    except Exception as e:  # noqa: BLE001 - not a skops file
        raise BundleError(f"{f}: cannot be read ({type(e).__name__})") from None
    foreign = sorted(set(untrusted) - set(TRUSTED_TYPES) - set(CHECKED_TYPES))
    if foreign:
        raise BundleError(f"{f}: holds type(s) a vibro bundle never contains ({', '.join(foreign[:3])}); refusing to load")
    try:
        check_payload_size(data)       # before any array is inflated
    except BundleContentError as e:
        raise BundleError(f"{f}: {e}; refusing to load") from None
    try:
        b = sio.loads(data, trusted=list(untrusted))
    except Exception as e:  # noqa: BLE001 - damaged content of a verified file: a foreign writer
        raise BundleError(f"{f}: cannot be read ({type(e).__name__}: {str(e)[:120]})") from None
    if not isinstance(b, Bundle) or not isinstance(b.inputs, list):
        raise BundleError(f"{f}: not a vibro surrogate bundle")
    try:
        check_trees(b, len(b.inputs))
    except TreeStorageError as e:
        raise BundleError(f"{f}: a tree model is malformed ({e}); refusing to use it") from None
    try:
        check_contents(b, lambda X: b.predict(X, conditional=True))
    except (BundleContentError, AttributeError) as e:       # AttributeError: a stored field is missing
        raise BundleError(f"{f}: malformed bundle: {e}; refusing to use it") from None
    b.check_model(model)
    return b
