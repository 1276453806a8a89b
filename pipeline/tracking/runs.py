"""MLflow tracking with embedded defaults.

Tracking URI: ``$MLFLOW_TRACKING_URI`` if set (e.g. a shared server), else a SQLite file
``mlflow.db`` at the repository root (``$VIBRO_HOME`` overrides the root).  Experiment:
``$VIBRO_EXPERIMENT`` or ``vibro``.  A ``dvc repro`` opens one parent run and exports
its id as ``VIBRO_PARENT_RUN_ID``; every stage's run becomes its child.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def project_root() -> Path:
    return Path(os.environ.get("VIBRO_HOME", REPO_ROOT))


def tracking_uri() -> str:
    env = os.environ.get("MLFLOW_TRACKING_URI")
    if env:
        return env
    return f"sqlite:///{project_root() / 'mlflow.db'}"


def experiment_name() -> str:
    return os.environ.get("VIBRO_EXPERIMENT", "vibro")


def _quiet_mlflow() -> None:
    import logging

    for name in ("mlflow", "alembic", "sqlalchemy"):
        logging.getLogger(name).setLevel(logging.WARNING)
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")


def setup():
    """Point mlflow at the configured store and experiment; returns the mlflow module."""
    _quiet_mlflow()
    import mlflow

    mlflow.set_tracking_uri(tracking_uri())
    if mlflow.get_experiment_by_name(experiment_name()) is None:
        art = project_root() / "mlartifacts"
        uri = tracking_uri()
        kwargs = {"artifact_location": art.as_uri()} if uri.startswith("sqlite:") else {}
        try:
            mlflow.create_experiment(experiment_name(), **kwargs)
        except Exception:  # noqa: BLE001 - created concurrently by another process
            pass
    mlflow.set_experiment(experiment_name())
    return mlflow


@contextlib.contextmanager
def run(stage: str, params: dict | None = None, tags: dict | None = None, enabled: bool = True):
    """Context manager: an MLflow run for ``stage`` (child of $VIBRO_PARENT_RUN_ID if set).

    Yields the mlflow module (or None when ``enabled`` is false, e.g. ``--no-mlflow``)."""
    if not enabled or os.environ.get("VIBRO_NO_MLFLOW"):
        yield None
        return
    mlflow = setup()
    all_tags = {"vibro.stage": stage, **(tags or {})}
    parent = os.environ.get("VIBRO_PARENT_RUN_ID")
    if parent:
        all_tags["mlflow.parentRunId"] = parent
    with mlflow.start_run(run_name=stage, tags=all_tags):
        if params:
            log_params(mlflow, params)
        yield mlflow


def log_params(mlflow, params: dict) -> None:
    """Log params (values stringified and truncated to MLflow's limit)."""
    flat = {str(k): (str(v)[:500]) for k, v in params.items()}
    items = list(flat.items())
    for i in range(0, len(items), 90):
        mlflow.log_params(dict(items[i:i + 90]))
