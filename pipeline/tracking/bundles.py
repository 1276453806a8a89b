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


def _training_report(folder) -> dict:
    """A surrogate bundle folder's report.json ({} when there is none, e.g. for an MLflow run id)."""
    import json

    try:
        rep = json.loads((Path(str(folder)) / "report.json").read_text())
    except (OSError, ValueError):
        return {}
    return rep if isinstance(rep, dict) else {}


def surrogate_chain(folder) -> str | None:
    """The chain a surrogate bundle folder was trained in (its report.json 'chain'), None when unknown."""
    from pipeline.tracking.runs import CHAINS

    chain = _training_report(folder).get("chain")
    return chain if chain in CHAINS else None


def surrogate_rig(folder) -> str | None:
    """The name of the rig a surrogate bundle folder was trained for (report.json 'rig_name'), None if none."""
    name = _training_report(folder).get("rig_name")
    return name if isinstance(name, str) and name else None
