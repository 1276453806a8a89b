"""MLflow tracking (runs.py), bundles by run id (bundles.py) and the dvc pipeline driver under one parent run (repro.py, ``make run``)."""
from pipeline.tracking.runs import (CHAINS, REPO_ROOT, chain, current_chain, dvc_experiment,  # noqa: F401
                                    experiment_name, git_commit, log_params, project_root, run, run_name, run_tags,
                                    setup, tracking_uri, variant)
from pipeline.tracking.bundles import load_bundle  # noqa: F401
