"""The one bundle validator: what a loaded bundle holds is checked before anything predicts with it.

Two steps.  :func:`check_payload_size` reads the skops archive's table of contents (no array is inflated) and
refuses a payload whose members would inflate past MAX_INFLATED_BYTES, so a small crafted file cannot ask for
gigabytes.  :func:`check_contents` then checks every stored value a prediction reads: the input names and
trained ranges (finite, low < high, the scaler's the same), the targets' transforms, domains and intervals, the
simulator settings and fixed values, the weight shapes of every estimator against the number of inputs, and
finally one probe prediction at the centre of the ranges, which must give finite numbers.
"""
from __future__ import annotations

import io
import math
import zipfile
from typing import Any, Callable

import numpy as np

MAX_INFLATED_BYTES = 512 * 2**20
"""Largest total size of a bundle payload's members once inflated [bytes]; real bundles are a few MB."""
MAX_INPUTS = 64
"""Most inputs a bundle may have (a sweep varies a handful of parameters)."""
TRANSFORMS = ("identity", "log")
DOMAINS = ("progressing", "settled", "all")
SCALES = ("linear", "log")


class BundleContentError(ValueError):
    """A stored value of a bundle is missing, of the wrong type or shape, or out of range."""


def check_payload_size(data: bytes, limit: int = MAX_INFLATED_BYTES) -> None:
    """BundleContentError when the skops archive ``data`` is not a zip or would inflate past ``limit`` bytes."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            total = sum(max(int(i.file_size), 0) for i in z.infolist())
    except (zipfile.BadZipFile, ValueError, OSError) as e:
        raise BundleContentError(f"not a skops archive ({e})") from None
    if total > limit:
        raise BundleContentError(f"its arrays would take {total / 2**20:.0f} MiB once inflated, more than the "
                                 f"{limit // 2**20} MiB a surrogate bundle may hold")


def _finite_pair(value: Any) -> tuple[float, float] | None:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        return None
    if isinstance(value, (str, bytes)) or not (math.isfinite(lo) and math.isfinite(hi)):
        return None
    return lo, hi


def _check_schema(b) -> None:
    inputs = b.inputs
    if not isinstance(inputs, list) or not 1 <= len(inputs) <= MAX_INPUTS or \
            not all(isinstance(n, str) and n for n in inputs) or len(set(inputs)) != len(inputs):
        raise BundleContentError(f"'inputs' must be 1..{MAX_INPUTS} distinct names, got {str(inputs)[:80]}")
    if not isinstance(b.ranges, dict) or set(b.ranges) != set(inputs):
        have = sorted(b.ranges) if isinstance(b.ranges, dict) else type(b.ranges).__name__
        raise BundleContentError(f"'ranges' must give one range per input {inputs}, has {have}")
    for n in inputs:
        pair = _finite_pair(b.ranges[n])
        if pair is None:
            raise BundleContentError(f"trained range of '{n}' is not two finite numbers: {b.ranges[n]!r}")
        if not pair[0] < pair[1]:
            raise BundleContentError(f"trained range of '{n}' is inverted or empty: [{pair[0]:g}, {pair[1]:g}]")
    sc = b.scaler
    if getattr(sc, "inputs", None) != inputs or not isinstance(getattr(sc, "ranges", None), dict) or \
            any(_finite_pair(sc.ranges.get(n)) != _finite_pair(b.ranges[n]) for n in inputs):
        raise BundleContentError("the input scaler's inputs or ranges differ from the bundle's")
    scale = getattr(sc, "scale", None)
    if not isinstance(scale, dict) or any(scale.get(n, "linear") not in SCALES for n in inputs):
        raise BundleContentError(f"input scales must be one of {', '.join(SCALES)}, got {str(scale)[:80]}")
    if not isinstance(b.classes, list) or not b.classes or not all(isinstance(c, str) for c in b.classes):
        raise BundleContentError(f"'classes' must be a list of regime names, got {str(b.classes)[:80]}")
    if not isinstance(b.regressors, dict):
        raise BundleContentError("'regressors' must map targets to models")
    for t, tm in b.regressors.items():
        kind = getattr(getattr(tm, "transform", None), "kind", None)
        if kind not in TRANSFORMS:
            raise BundleContentError(f"target '{t}': transform {kind!r} is not one of {', '.join(TRANSFORMS)}")
        if getattr(tm, "domain", None) not in DOMAINS:
            raise BundleContentError(f"target '{t}': domain {getattr(tm, 'domain', None)!r} is not one of "
                                     f"{', '.join(DOMAINS)}")
        iv = getattr(tm, "interval", None)
        q = getattr(iv, "q", None)
        if isinstance(q, bool) or not isinstance(q, (int, float)) or not math.isfinite(q) or q < 0 or \
                not isinstance(getattr(iv, "normalised", None), bool):
            raise BundleContentError(f"target '{t}': interval half-width q must be a finite number >= 0, got {q!r}")


def _check_values(b) -> None:
    """``fixed`` parameters finite numbers; ``settings`` valid simulator settings (sim.Settings)."""
    from sim.api import Settings
    from sim import ParameterError

    for what, d in (("fixed", b.fixed), ("settings", b.settings)):
        if not isinstance(d, dict):
            raise BundleContentError(f"'{what}' must be a mapping, got {type(d).__name__}")
    for k, v in b.fixed.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise BundleContentError(f"fixed value '{k}' must be a finite number, got {v!r}")
    known = set(Settings.__dataclass_fields__)
    for k, v in b.settings.items():
        if k not in known:
            raise BundleContentError(f"setting '{k}' is not a simulator setting")
        if k == "method":
            if not isinstance(v, str):
                raise BundleContentError(f"setting 'method' must be a word, got {v!r}")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise BundleContentError(f"setting '{k}' must be a finite number, got {v!r}")
    try:
        Settings(**b.settings).validate()
    except (ParameterError, TypeError, ValueError) as e:
        raise BundleContentError(f"settings: {e}") from None


def _mlp_shapes(est, n_in: int, what: str) -> None:
    coefs, inters = getattr(est, "coefs_", None), getattr(est, "intercepts_", None)
    if not isinstance(coefs, list) or not isinstance(inters, list) or not coefs or len(coefs) != len(inters):
        raise BundleContentError(f"{what}: MLP weights missing or unpaired")
    rows = n_in
    for i, (w, c) in enumerate(zip(coefs, inters)):
        if not (isinstance(w, np.ndarray) and w.ndim == 2 and w.shape[0] == rows and isinstance(c, np.ndarray)
                and c.shape == (w.shape[1],)):
            shape = getattr(w, "shape", None)
            raise BundleContentError(f"{what}: MLP layer {i} weight has shape {shape}, expected ({rows}, k) "
                                     f"with a bias of k values")
        if not (np.isfinite(w).all() and np.isfinite(c).all()):
            raise BundleContentError(f"{what}: MLP layer {i} holds non-finite weights")
        rows = w.shape[1]


def _gp_shapes(gp, n_in: int, what: str) -> None:
    X, alpha = getattr(gp, "X_train_", None), getattr(gp, "alpha_", None)
    if not (isinstance(X, np.ndarray) and X.ndim == 2 and X.shape[1] == n_in and isinstance(alpha, np.ndarray)
            and alpha.shape[0] == X.shape[0]):
        raise BundleContentError(f"{what}: Gaussian-process training points have shape {getattr(X, 'shape', None)}, "
                                 f"coefficients {getattr(alpha, 'shape', None)}; expected (n, {n_in}) and (n,)")
    L = getattr(gp, "L_", None)
    if not (isinstance(L, np.ndarray) and L.shape == (X.shape[0], X.shape[0])):
        raise BundleContentError(f"{what}: Gaussian-process factor has shape {getattr(L, 'shape', None)}")
    if not (np.isfinite(X).all() and np.isfinite(alpha).all() and np.isfinite(L).all()):
        raise BundleContentError(f"{what}: Gaussian process holds non-finite values")


def _estimators(est, depth: int = 0):
    """``est`` and the estimators it wraps (TransformedTargetRegressor, SubsampledGP)."""
    yield est
    if depth < 3:
        for attr in ("regressor_", "gp_"):
            inner = getattr(est, attr, None)
            if inner is not None:
                yield from _estimators(inner, depth + 1)


def _check_estimator(est, n_in: int, what: str) -> None:
    from sklearn.dummy import DummyRegressor

    for e in _estimators(est):
        if isinstance(e, DummyRegressor):     # a constant target: predicts its constant whatever the inputs
            if not np.isfinite(np.asarray(getattr(e, "constant_", np.nan), dtype=float)).all():
                raise BundleContentError(f"{what}: constant model holds a non-finite value")
            continue
        n = getattr(e, "n_features_in_", None)
        if n is not None and (isinstance(n, bool) or not isinstance(n, (int, np.integer)) or int(n) != n_in):
            raise BundleContentError(f"{what}: fitted on {n!r} inputs, the bundle lists {n_in}")
        if hasattr(e, "coefs_"):
            _mlp_shapes(e, n_in, what)
        if hasattr(e, "X_train_"):
            _gp_shapes(e, n_in, what)


def check_contents(b, predict: Callable[[Any], Any] | None = None) -> None:
    """BundleContentError naming the first stored value that is missing, malformed or out of range; then, with
    ``predict`` (the bundle's conditional prediction on a DataFrame), one probe at the centre of the ranges."""
    import pandas as pd

    _check_schema(b)
    _check_values(b)
    n_in = len(b.inputs)
    _check_estimator(b.classifier, n_in, "classifier")
    classes = [str(c) for c in getattr(b.classifier, "classes_", [])]
    if not classes or len(set(classes)) != len(classes):
        raise BundleContentError(f"classifier: regimes {classes[:5]} (none, or repeated)")
    for t, tm in b.regressors.items():
        _check_estimator(tm.estimator, n_in, f"regressor '{t}'")
    if predict is None:
        return
    centre = pd.DataFrame({n: [0.5 * (float(b.ranges[n][0]) + float(b.ranges[n][1]))] for n in b.inputs})
    try:
        out = predict(centre)
        probe = out.drop(columns=["regime"]).to_numpy(dtype=float)
    except Exception as e:  # noqa: BLE001 - whatever a malformed estimator raises
        raise BundleContentError(f"a probe prediction fails ({type(e).__name__}: {str(e)[:100]})") from None
    if probe.shape[0] != 1 or not np.isfinite(probe).all():
        bad = [c for c in out.columns if c != "regime" and not np.isfinite(out[c].to_numpy(dtype=float)).all()]
        raise BundleContentError(f"a probe prediction at the centre of the ranges is not finite ({', '.join(bad[:3])})")
