"""Diagnosis of every system: synthetic data recorded as a rig records it (`vibro synth` rig
defaults: DAQ rate not a multiple of f, partial cycles, offsets; the drill from rest with record_start_s and
summary-only runs) are reproduced by the model at the true parameters to the noise level, and not at the
defaults; the slow matrix diagnoses every drill effect, a control and physics outside the library."""
from __future__ import annotations

import json

import numpy as np
import pytest

from pipeline.diagnosis.model import Evaluator, calibratable, candidates, effect_bounds
from pipeline.diagnosis.run import DiagnoseConfig, build_targets
from pipeline.datasets.measured import load_dataset, write_dataset
from pipeline.synthesis.workflow import SynthConfig, synthesize

SMALL = {  # two or three frequencies per system, short records: seconds of simulation
    "drill": dict(frequencies_hz=(190.0, 310.0, 430.0), levels=(1200.0,), cycles=12.3, summary_runs=1,
                  record_start_s=(0.05, 0.12)),
    "pendulum": dict(frequencies_hz=(3.0, 3.75), levels=(0.0,), cycles=4.4),
    "rimd": dict(frequencies_hz=(6.0, 8.0), levels=(1.0,), cycles=5.3),
}


@pytest.mark.parametrize("system", sorted(SMALL))
def test_every_system_has_calibratable_params_and_bounded_effects(system):
    import sim

    names = sim.get_model(system).param_names
    assert all(p.name in names for p in calibratable(system))
    bounds = effect_bounds(system)
    for eff, ps in candidates(system).items():          # every §6 effect of the model has fit bounds
        assert all(p.name in bounds and p.name in names for p in ps)


@pytest.mark.parametrize("system", ["drill", "pendulum", "rimd"])
def test_truth_is_at_noise_level_defaults_are_not(tmp_path, system):
    cfg = SynthConfig(system=system, seed=5, n_threads=2, **SMALL[system])
    ds, info = synthesize(cfg)
    write_dataset(ds, tmp_path / "d")
    data = load_dataset(tmp_path / "d")
    if system == "drill":
        assert data.summary is not None and len(data.series) == 2            # one run logged as a summary only
        assert data.known[data.runs["run_id"][0]]["K1"] == 6e8               # preset 'lab' from runs.csv
        assert data.runs["record_start_s"].notna().all()
        t = data.series[data.runs["run_id"][0]]["t_s"].to_numpy()
        assert abs(1 / (t[1] - t[0]) / 190.0 - round(1 / (t[1] - t[0]) / 190.0)) > 1e-3   # not whole samples/cycle
    targets = build_targets(data, DiagnoseConfig())[system]
    ev = Evaluator(system, targets, dict(DiagnoseConfig().sim_settings), 20000.0, 2)
    r_true, r_default = ev.residuals([info["truth"], {}], list(range(len(targets))))
    nrms = lambda r: float(np.sqrt(np.mean(r ** 2)))   # noqa: E731
    assert nrms(r_true) < 1.5            # 'explained' threshold of the diagnosis (run.py explained_nrms)
    assert nrms(r_default) > 5 * nrms(r_true)        # the perturbed rock / contact is visible


# ----------------------------------------------------------------------------- slow matrix (drill)
def _run(tmp_path, name, *synth_args):
    from pipeline.cli import main

    data = tmp_path / name
    assert main(["synth", "--out", str(data), "--system", "drill", *synth_args]) == 0
    out = tmp_path / (name + "-diag")
    assert main(["diagnose", str(data), "--out", str(out), "--quiet", "--no-mlflow"]) == 0
    return json.loads((out / "report.json").read_text()), json.loads((tmp_path / (name + ".truth.json")).read_text())


DRILL_EFFECTS = ["shaker_coil", "rate_stiffening", "guide_friction", "tip_blunting", "suspension_hardening"]


@pytest.mark.slow
@pytest.mark.parametrize("effect", DRILL_EFFECTS)
def test_drill_recovers_every_effect(tmp_path, effect):
    """16-run drill rig log (rig defaults: 25.6 kHz, from rest, 2 summary-only runs), default settings."""
    rep, _ = _run(tmp_path, effect, "--effect", effect, "--seed", "1")
    assert rep["selected"] == effect and rep["explained"] is True
    assert rep["final_error"] < 0.2 * rep["base_error"]


@pytest.mark.slow
def test_drill_control_selects_nothing(tmp_path):
    rep, _ = _run(tmp_path, "control", "--seed", "2")
    assert rep["selected"] is None and rep["explained"] is True


@pytest.mark.slow
def test_drill_outside_physics_is_unexplained(tmp_path):
    rep, _ = _run(tmp_path, "outside", "--outside", "mount_resonance", "--seed", "3")
    assert rep["selected"] is None and rep["explained"] is False
