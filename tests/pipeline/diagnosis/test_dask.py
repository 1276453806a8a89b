"""``vibro diagnose --scheduler``: the fits on a Dask cluster give the report of a local run, bit for bit, and a
scheduler that cannot be used is one line naming it, before anything is written."""
from __future__ import annotations

import json

import pytest

# 3 short runs -> leave-one-run-out: an all-runs fit, then 3 folds fitted together (folds x models x starts tasks);
# two candidates, two base starts, and the refit and refinement stages switched on
SETTINGS = dict(min_runs_holdout=8, n_starts=2, candidate_starts=1, grid=2, profile_points=1, profile_nfev=1,
                max_nfev=3, refine_nfev=2)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A written 3-run indenter-metal dataset with a sensor low-pass (``vibro synth``)."""
    from pipeline.cli import main

    out = tmp_path_factory.mktemp("data") / "lp3"
    assert main(["synth", "--out", str(out), "--system", "indenter-metal", "--effect", "sensor_lowpass",
                 "--cycles", "6", "--frequencies", "60", "80", "100", "--levels", "1", "--seed", "4", "--quiet"]) == 0
    return out


def _diagnose(dataset, out, *extra) -> dict:
    from pipeline.cli import main

    sets = [a for k, v in SETTINGS.items() for a in ("--setting", f"{k}={v}")]
    assert main(["diagnose", str(dataset), "--out", str(out), "--quiet", "--no-mlflow",
                 "--effects", "sensor_lowpass", "guide_friction", *sets, *extra]) == 0
    return json.loads((out / "report.json").read_text())


def test_local_cluster_gives_the_local_report_bit_for_bit(dataset, tmp_path):
    local = _diagnose(dataset, tmp_path / "local", "--threads", "1")
    dask = _diagnose(dataset, tmp_path / "dask", "--scheduler", "local:2")
    rep = local["systems"]["indenter-metal"]
    assert rep["split"]["scheme"] == "leave-one-run-out" and len(rep["split"]["folds"]) == 3
    assert {c["effect"] for c in rep["candidates"]} == {"sensor_lowpass", "guide_friction"}
    for key in ("verdict", "selected", "calibrated", "calibrated_uncertainty", "base_nrms", "final_nrms",
                "final_error", "candidates", "n_simulations"):
        assert dask[key] == local[key], key               # JSON floats round-trip: equal text is equal bits
    assert local["config"].pop("n_threads") == 1 and dask["config"].pop("n_threads") is None
    local.pop("wall_time_s"), dask.pop("wall_time_s")      # and the time: nothing else may differ
    assert [(s["stage"], s["simulations"]) for s in dask.pop("cost")["stages"]] == \
        [(s["stage"], s["simulations"]) for s in local.pop("cost")["stages"]]     # the seconds differ, not the counts
    assert dask == local
    assert rep["n_simulations"] > 0 and all(c["nrms"] > 0 for c in rep["candidates"])


@pytest.mark.parametrize("address, says", [("tcp://127.0.0.1:9", "cannot reach the Dask scheduler"),
                                           ("local:0", "N must be in [1,"), ("local:two", "expected local:N")])
def test_a_bad_scheduler_is_one_line_and_writes_nothing(dataset, tmp_path, capsys, address, says):
    from pipeline.cli import main

    out = tmp_path / "diag"
    rc = main(["diagnose", str(dataset), "--out", str(out), "--quiet", "--no-mlflow", "--scheduler", address])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert f"--scheduler {address}" in err and says in err
    assert not out.exists()


def test_params_file_scheduler_of_the_wrong_type_is_named(dataset, tmp_path, capsys):
    from pipeline.cli import main

    params = tmp_path / "params.yaml"
    params.write_text("diagnose:\n  scheduler: 8786\n")
    rc = main(["diagnose", str(dataset), "--out", str(tmp_path / "diag"), "--quiet", "--no-mlflow",
               "--params", str(params)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "diagnose.scheduler" in err and "8786" in err
