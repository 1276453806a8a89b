"""A surrogate bundle by directory or MLflow run id (the run's 'surrogate' artifacts are downloaded first)."""
from __future__ import annotations

import os
import re
from pathlib import Path

from pipeline.core.errors import UserError

RUN_ID = re.compile(r"^[0-9a-f]{32}$")


def load_bundle(ref: str | os.PathLike, model: str | None = None):
    """``surrogate.load_bundle`` of a bundle directory, or of the artifacts of MLflow run ``ref``.

    ``model``: UserError unless the bundle was trained on that model's data."""
    from surrogate import load_bundle as load_dir
    from surrogate.bundle import ARTIFACT_DIR

    path = Path(ref)
    if not path.exists() and RUN_ID.match(str(ref)):
        path = _download_run(str(ref), ARTIFACT_DIR)
    elif not path.exists():
        raise UserError(f"surrogate '{ref}': no such directory (and not an MLflow run id); run 'vibro train' first")
    return load_dir(path, model=model)


def _download_run(run_id: str, artifact_dir: str) -> Path:
    from pipeline.tracking import runs

    mlflow = runs.setup()
    try:
        local = mlflow.artifacts.download_artifacts(run_id=run_id, artifact_path=artifact_dir)
    except Exception as e:  # noqa: BLE001 - unknown run, or a run without a surrogate
        raise UserError(f"MLflow run '{run_id}' has no '{artifact_dir}' artifacts at {runs.tracking_uri()} "
                        f"({type(e).__name__})") from None
    return Path(local)
