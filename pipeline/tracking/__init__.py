"""MLflow tracking (runs.py), bundles by run id (bundles.py) and the dvc pipeline driver under one parent run (repro.py, ``make run``)."""
from pipeline.tracking.runs import (REPO_ROOT, experiment_name, log_params, project_root, run, setup,  # noqa: F401
                                    tracking_uri)
from pipeline.tracking.bundles import load_bundle  # noqa: F401
