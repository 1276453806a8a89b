"""MLflow tracking with embedded defaults.

Tracking URI: ``$MLFLOW_TRACKING_URI`` if set (e.g. a shared server), else a SQLite file
``mlflow.db`` at the repository root (``$VIBRO_HOME`` overrides the root).  Experiment:
``$VIBRO_EXPERIMENT`` or ``vibro``.  A ``dvc repro`` opens one parent run and exports
its id as ``VIBRO_PARENT_RUN_ID``; every stage's run becomes its child.

Every run carries the tags ``git_commit`` (the repository's HEAD, ``+dirty`` when tracked files
differ) and ``dvc_exp`` (``$DVC_EXP_NAME``, set by ``dvc exp run``; ``workspace`` otherwise), and a
run name that tells variants apart (``optimise-rop``, ``diagnose-seed000-published``).  The tag
``vibro.chain`` says which chain a run belongs to: ``lab`` (the preset's model) or ``corrected`` (a rig
file, e.g. the diagnosis's corrected rig); runs of the corrected chain end in ``-corrected``
(``train-corrected``, ``optimise-rop-corrected``), or in the rig's name when the command knows its rig file
(``sweep-my-rig``, tag ``vibro.rig``: ``pipeline.core.rigfile.rig_name``).  The experiment is created as classic model development
(tag ``mlflow.experimentKind``), so the MLflow UI opens it as a machine-learning experiment, not in the
GenAI view.
"""
from __future__ import annotations

import contextlib
import contextvars
import functools
import os
import subprocess
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


EXPERIMENT_KIND_TAG = "mlflow.experimentKind"
EXPERIMENT_KIND = "custom_model_development"
"""MLflow 3's experiment kind for classic ML (the UI's 'Machine learning' view; 'genai_development' is the GenAI
one): the values of the kind selector in mlflow/server/js."""


def git_commit(root: str | None = None) -> str:
    """HEAD of the git repository at ``root`` (default: the project root), ``+dirty`` if tracked files changed;
    ``unknown`` outside a repository or without git."""
    return _git_commit_at(str(Path(root or project_root()).resolve()))


@functools.lru_cache(maxsize=None)
def _git_commit_at(cwd: str) -> str:
    """git_commit for one resolved folder, cached per folder (``$VIBRO_HOME`` may point elsewhere later)."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return "unknown"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head.stdout.strip() + ("+dirty" if dirty.returncode == 0 and dirty.stdout.strip() else "")


def dvc_experiment() -> str:
    """The dvc experiment this process runs in (``$DVC_EXP_NAME``, set by ``dvc exp run``), else ``workspace``."""
    return os.environ.get("DVC_EXP_NAME") or "workspace"


def run_tags() -> dict[str, str]:
    """Tags every run carries: ``git_commit`` and ``dvc_exp``."""
    return {"git_commit": git_commit(), "dvc_exp": dvc_experiment()}


_VARIANT: contextvars.ContextVar[str | None] = contextvars.ContextVar("vibro_run_variant", default=None)
CHAINS = ("lab", "corrected")
"""Values of the ``vibro.chain`` tag: the preset's model, or a rig file (the corrected rig)."""
_CHAIN: contextvars.ContextVar[str] = contextvars.ContextVar("vibro_run_chain", default="lab")
_RIG: contextvars.ContextVar[str | None] = contextvars.ContextVar("vibro_run_rig", default=None)


@contextlib.contextmanager
def chain(name: str, rig: str | None = None):
    """Runs opened inside belong to chain ``name`` (one of :data:`CHAINS`): tag ``vibro.chain``, name suffix; with
    ``rig`` (a rig's name) they carry it as tag ``vibro.rig`` and as the name's suffix instead of the chain's."""
    if name not in CHAINS:
        raise ValueError(f"chain '{name}': one of {', '.join(CHAINS)}")
    token, rig_token = _CHAIN.set(name), _RIG.set(rig or None)
    try:
        yield
    finally:
        _CHAIN.reset(token)
        _RIG.reset(rig_token)


def current_chain() -> str:
    """The chain of the runs opened here (:func:`chain`; ``lab`` outside one)."""
    return _CHAIN.get()


@contextlib.contextmanager
def variant(name: str | None):
    """Runs opened inside are named ``<stage>-<name>`` (lets a command name the run a workflow opens)."""
    token = _VARIANT.set(name)
    try:
        yield
    finally:
        _VARIANT.reset(token)


def run_name(stage: str, variant: str | None = None, chain: str = "lab", rig: str | None = None) -> str:
    """``stage`` or ``stage-variant`` (e.g. ``optimise-rop``), ending in ``-<rig>`` on a named rig
    (``optimise-rop-drill-rig``), else in ``-<chain>`` outside the lab chain (``optimise-rop-corrected``): distinct
    names for the variants of a stage, the two chains and the rigs."""
    name = f"{stage}-{variant}" if variant and variant != stage else stage
    if rig:
        return f"{name}-{rig}"
    return name if chain == "lab" else f"{name}-{chain}"


HTTP_DEFAULTS = {"MLFLOW_HTTP_REQUEST_TIMEOUT": "10", "MLFLOW_HTTP_REQUEST_MAX_RETRIES": "1",
                 "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR": "1"}
"""A tracking server's request limits unless the user set them (MLflow's own wait minutes on a dead server)."""


def _quiet_mlflow() -> None:
    import logging

    for name in ("mlflow", "alembic", "sqlalchemy"):
        logging.getLogger(name).setLevel(logging.WARNING)
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")
    for key, value in HTTP_DEFAULTS.items():
        os.environ.setdefault(key, value)


def _first_contact(mlflow):
    """The experiment (or None), asked once; an unreachable tracking server is a UserError naming it."""
    from pipeline.core.errors import UserError

    uri = tracking_uri()
    try:
        return mlflow.get_experiment_by_name(experiment_name())
    except Exception as e:  # noqa: BLE001 - connection refused, timeout, DNS: the server, not the project
        if not uri.startswith(("http:", "https:")):
            raise
        raise UserError(f"MLflow tracking server {uri} did not answer within "
                        f"{os.environ['MLFLOW_HTTP_REQUEST_TIMEOUT']} s ({type(e).__name__}); start it, unset "
                        f"MLFLOW_TRACKING_URI, or pass --no-mlflow") from None


@contextlib.contextmanager
def _creating_store():
    """Held while a SQLite store's tables and experiment may be created: two commands started together on a fresh
    repository would otherwise both create the tables (SQLite: 'table experiments already exists')."""
    uri = tracking_uri()
    if not uri.startswith("sqlite:///"):
        yield
        return
    import fcntl

    lock = Path(uri[len("sqlite:///"):] + ".lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    with open(lock, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def setup():
    """Point mlflow at the configured store and experiment; returns the mlflow module."""
    _quiet_mlflow()
    import mlflow

    mlflow.set_tracking_uri(tracking_uri())
    with _creating_store():
        if _first_contact(mlflow) is None:
            art = project_root() / "mlartifacts"
            uri = tracking_uri()
            kwargs = {"artifact_location": art.as_uri()} if uri.startswith("sqlite:") else {}
            try:          # the kind at creation: the UI never sees the experiment without it
                mlflow.create_experiment(experiment_name(), tags={EXPERIMENT_KIND_TAG: EXPERIMENT_KIND}, **kwargs)
            except Exception:  # noqa: BLE001 - created concurrently by another process
                pass
    exp = mlflow.set_experiment(experiment_name())
    if (exp.tags or {}).get(EXPERIMENT_KIND_TAG) != EXPERIMENT_KIND:      # created before the tag existed
        try:
            mlflow.set_experiment_tag(EXPERIMENT_KIND_TAG, EXPERIMENT_KIND)
        except Exception:  # noqa: BLE001 - a read-only tracking server: the UI label is cosmetic
            pass
    return mlflow


@contextlib.contextmanager
def run(stage: str, params: dict | None = None, tags: dict | None = None, enabled: bool = True,
        variant: str | None = None):
    """Context manager: an MLflow run for ``stage`` (child of $VIBRO_PARENT_RUN_ID if set), named
    ``run_name(stage, variant)`` (``variant`` defaults to the enclosing :func:`variant`), tagged with :func:`run_tags`.

    Tagged ``vibro.chain`` with the enclosing :func:`chain`.  Yields the mlflow module (or None when ``enabled``
    is false, e.g. ``--no-mlflow``)."""
    if not enabled or os.environ.get("VIBRO_NO_MLFLOW"):
        yield None
        return
    mlflow = setup()
    all_tags = {"vibro.stage": stage, "vibro.chain": current_chain(), **run_tags(),
                **({"vibro.rig": _RIG.get()} if _RIG.get() else {}), **(tags or {})}
    parent = os.environ.get("VIBRO_PARENT_RUN_ID")
    if parent:
        all_tags["mlflow.parentRunId"] = parent
    name = run_name(stage, variant or _VARIANT.get(), current_chain(), _RIG.get())
    with mlflow.start_run(run_name=name, tags=all_tags):
        if params:
            log_params(mlflow, params)
        yield mlflow


def log_params(mlflow, params: dict) -> None:
    """Log params (values stringified and truncated to MLflow's limit)."""
    flat = {str(k): (str(v)[:500]) for k, v in params.items()}
    items = list(flat.items())
    for i in range(0, len(items), 90):
        mlflow.log_params(dict(items[i:i + 90]))
