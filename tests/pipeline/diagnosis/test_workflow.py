"""The diagnose driver is thin: a self-checking config in, a frozen ``DiagnoseResult`` out, no file written; the command
(``pipeline/cli/diagnose.py``, through ``pipeline.diagnosis.outputs``) writes report.json with the keys it always had."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from pipeline.core.errors import UserError
from pipeline.diagnosis.run import DiagnoseConfig

SYSTEM_KEYS = ["system", "n_runs", "unreproducible", "data", "split", "verdict", "calibrated", "calibrated_uncertainty",
               "noise_floor", "noise_sd", "default_error", "base_error", "final_error", "default_nrms", "base_nrms", "final_nrms",
               "base_systematic", "final_systematic", "heldout_n", "error_by_group", "base_score", "candidates",
               "selected", "selected_effects", "leader", "runner_up", "selected_params", "explained", "best_partial_candidate", "absorbed",
               "call", "indistinguishable", "second_effect", "pair_stage", "discrepancy", "proposal_adopted", "proposal_as_effect", "recording", "n_simulations", "residual_structure", "notes", "rig", "figures"]
REPORT_KEYS = ["report_schema", "dataset", "config", *SYSTEM_KEYS, "systems", "wall_time_s", "cost"]
RIG_KEYS = ["explained", "selected", "source", "discrepancy", "verdict", "absorbed", "model_error", "noise_floor", "nrms",
            "rop_model_error", "notes",
            "file"]
# a small, quick diagnosis: 6 short runs, one candidate, one start (seconds on one core)
SETTINGS = dict(effects=["sensor_lowpass"], min_runs_holdout=6, holdout_every=3, n_starts=1, candidate_starts=1,
                max_nfev=4, refine_nfev=0, n_threads=2)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A written 6-run indenter-metal dataset with a sensor low-pass (``vibro synth``)."""
    from pipeline.cli import main

    out = tmp_path_factory.mktemp("data") / "lp"
    assert main(["synth", "--out", str(out), "--system", "indenter-metal", "--effect", "sensor_lowpass",
                 "--cycles", "8", "--frequencies", "60", "80", "100", "--seed", "4"]) == 0
    return out


def _private_keys(d, path=""):
    """Paths of the keys starting with '_' anywhere in the nested dict ``d``."""
    out = []
    if isinstance(d, dict):
        for k, v in d.items():
            out += ([f"{path}/{k}"] if str(k).startswith("_") else []) + _private_keys(v, f"{path}/{k}")
    elif isinstance(d, list):
        for i, v in enumerate(d):
            out += _private_keys(v, f"{path}[{i}]")
    return out


def test_diagnose_returns_a_frozen_result_and_writes_nothing(dataset, tmp_path, monkeypatch):
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis.workflow import diagnose
    from pipeline.diagnosis.result import DiagnoseResult, SimulatedRuns, SystemDiagnosis

    monkeypatch.chdir(tmp_path)
    before = sorted(p.relative_to(dataset) for p in dataset.rglob("*"))
    res = diagnose(load_dataset(dataset), DiagnoseConfig(**SETTINGS), log=lambda s: None)
    assert list(tmp_path.iterdir()) == []                                     # nothing in the current folder
    assert sorted(p.relative_to(dataset) for p in dataset.rglob("*")) == before   # nor beside the data
    assert isinstance(res, DiagnoseResult) and len(res.systems) == len(res.runs) == len(res.rigs) == 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.report = {}
    diag = res.systems[0]
    assert isinstance(diag, SystemDiagnosis) and isinstance(res.runs[0], SimulatedRuns)
    assert list(res.report.to_json()) == REPORT_KEYS and list(diag.report.to_json()) == SYSTEM_KEYS
    assert res.report.systems == (diag.report,) and res.report.system("indenter-metal") is diag.report
    assert _private_keys(res.report.to_json()) == []
    assert set(diag.fits) == {"base", "sensor_lowpass"} and diag.final in diag.fits
    assert diag.held_out and all(0 <= i < len(diag.targets) for i in diag.held_out)
    assert res.rigs[0][0] == "rig.yaml" == diag.report.rig.file and res.rigs[0][1].model == "indenter-metal"


def test_the_command_writes_report_json_with_its_keys(dataset, tmp_path):
    from pipeline.cli import main

    out = tmp_path / "diag"
    sets = [a for k, v in SETTINGS.items() if k not in ("effects", "n_threads") for a in ("--setting", f"{k}={v}")]
    assert main(["diagnose", str(dataset), "--out", str(out), "--quiet", "--no-mlflow", "--threads", "2",
                 "--effects", *SETTINGS["effects"], *sets]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert list(rep) == REPORT_KEYS and list(rep["systems"]["indenter-metal"]) == SYSTEM_KEYS
    assert list(rep["rig"]) == RIG_KEYS
    assert (rep["rig"]["rop_model_error"] or {}).get("rop_rel") == rep["error_by_group"]["final"].get("rop_m_s")
    assert _private_keys(rep) == []
    assert rep["figures"][0] == "residual_metal.png" and all((out / f).is_file() for f in rep["figures"])
    written = {p.name for p in out.iterdir() if not p.name.startswith(".")}     # beside the command's marker
    assert written == {"report.json", "report.md", "rig.yaml", *rep["figures"]}
    _check_cost(rep, (out / "report.md").read_text())


def _check_cost(rep: dict, md: str) -> None:
    """report.json ``cost``: every stage of the diagnosis, the candidate's share of the calibration, the total the
    sum of the top-level stages, the simulations those before the figures ran the report's count; report.md's table
    prints it."""
    cost = rep["cost"]
    stages = [(s["stage"], s["part_of"]) for s in cost["stages"]]
    assert stages == [("features", None), ("unreproducible-run check", None), ("DAQ chain", None), ("calibration", None),
                      ("base", "calibration"), ("sensor_lowpass", "calibration"), ("held-out", None), ("pairs", None),
                      ("discovery", None), ("DAQ chain at the final model", None), ("figures: runs", None),
                      ("figures: drawing", None)]
    top = [s for s in cost["stages"] if s["part_of"] is None]
    for k in ("simulations", "cpu_s", "wall_s"):
        assert abs(cost["total"][k] - sum(s[k] for s in top)) <= 0.002 * len(top), k     # rounded to 1 ms
    fitting = [s["simulations"] for s in top if not s["stage"].startswith("figures")]
    assert sum(fitting) == rep["n_simulations"] > 0
    parts = [s for s in cost["stages"] if s["part_of"] == "calibration"]
    cal = next(s for s in top if s["stage"] == "calibration")
    assert sum(s["simulations"] for s in parts) == cal["simulations"]     # every simulation of it is a fit task's
    assert "## Cost" in md and f"| **total** | {cost['total']['simulations']} |" in md


@pytest.mark.parametrize("bad", [dict(n_starts=0), dict(grid=2.5), dict(candidate_starts=3), dict(explained_nrms=0.0),
                                 dict(seed=True), dict(systematic_tol=float("nan")), dict(effects="shaker_coil"),
                                 dict(sim_settings=None), dict(fit_unreproducible="yes")])
def test_config_checks_itself(bad):
    with pytest.raises(UserError, match="diagnose setting"):
        DiagnoseConfig(**bad)


def test_config_accepts_its_bounds():
    cfg = DiagnoseConfig(model_floor=0.0, summary_floor=0.0, profile_nfev=0, record_window=0, explained_nrms=3,
                         n_threads=1, effects=["shaker_coil"])
    assert cfg.model_floor == 0.0 and cfg.explained_nrms == 3


@pytest.mark.parametrize("item, msg", [
    ("fit_unreproducable=true", "diagnose setting 'fit_unreproducable' is unknown (did you mean fit_unreproducible?)"),
    ("fit_unreproducible=maybe", "diagnose setting 'fit_unreproducible' must be true or false, got 'maybe'")])
def test_a_bad_setting_is_one_line_naming_it(tmp_path, capsys, item, msg):
    from pipeline.cli import main

    published = Path(__file__).resolve().parents[3] / "measured" / "seed000-published"
    assert main(["diagnose", str(published), "--out", str(tmp_path / "d"), "--setting", item,
                 "--no-mlflow"]) == 2
    err = capsys.readouterr().err
    assert msg in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "d").exists()


def test_true_and_false_as_text_are_the_settings_booleans():
    from pipeline.cli.diagnose import typed_settings

    assert typed_settings({"fit_unreproducible": "True", "estimate_chain": "false"}) == {
        "fit_unreproducible": True, "estimate_chain": False}
