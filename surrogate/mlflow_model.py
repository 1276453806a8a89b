"""MLflow: the bundle as a pyfunc model (with a signature) plus its directory as 'surrogate' artifacts."""
from __future__ import annotations

from pathlib import Path

import mlflow.pyfunc
import pandas as pd

from surrogate.bundle import ARTIFACT_DIR, Bundle, load_bundle


class BundleModel(mlflow.pyfunc.PythonModel):
    """pyfunc wrapper: ``mlflow.pyfunc.load_model(uri).predict(frame)`` = ``Bundle.predict(frame)``."""

    def load_context(self, context) -> None:
        self.bundle = load_bundle(context.artifacts["bundle"])

    def predict(self, context, model_input: pd.DataFrame, params=None) -> pd.DataFrame:
        return self.bundle.predict(model_input)


def log(mlflow, bundle: Bundle, bundle_dir: Path, example: pd.DataFrame, name: str = "model") -> None:
    """Log the bundle directory (artifacts 'surrogate', what ``load_bundle(run_id)`` reads) and a pyfunc
    model ``name`` whose signature is inferred from ``example`` (input columns) and its prediction."""
    from mlflow.models import infer_signature

    import logging
    import shutil
    import tempfile

    mlflow.log_artifacts(str(bundle_dir), artifact_path=ARTIFACT_DIR)
    X = example[bundle.inputs].reset_index(drop=True)
    sig = infer_signature(X, bundle.predict(X))
    with tempfile.TemporaryDirectory() as tmp:    # the model's files sit under the folder's name: make it stable
        named = Path(tmp) / ARTIFACT_DIR
        shutil.copytree(bundle_dir, named)
        # what is pickled is only the loader class (the bundle travels as artifacts), so MLflow's CloudPickle
        # caution, logged on every call, says nothing here: held back for this call only
        pyfunc_log = logging.getLogger("mlflow.pyfunc")
        level = pyfunc_log.level
        pyfunc_log.setLevel(logging.ERROR)
        try:
            mlflow.pyfunc.log_model(name=name, python_model=BundleModel(), artifacts={"bundle": str(named)},
                                    signature=sig, input_example=X.head(3), pip_requirements=_requirements())
        finally:
            pyfunc_log.setLevel(level)


def _requirements() -> list[str]:
    """Pinned runtime requirements (given explicitly: MLflow's inference would re-import and run the model)."""
    from importlib.metadata import PackageNotFoundError, version

    out = []
    for pkg in ("vibro", "scikit-learn", "numpy", "pandas", "scipy", "skops"):
        try:
            out.append(f"{pkg}=={version(pkg)}")
        except PackageNotFoundError:
            continue
    return out
