"""Diagnosis: features and noise, splits, and end-to-end recovery of undeclared effects
from synthetic data (`vibro synth`).  The every-effect matrix, the control and the 'outside' case
are slow (several minutes each on 2 shared cores); one small end-to-end case runs by default."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pipeline.diagnosis.features import Target, harmonic_fit, spectral_ratio
from pipeline.diagnosis.run import DiagnoseConfig, make_folds


def test_progression_rate_and_spectral_ratio():
    f, spc = 40.0, 100
    t = np.arange(spc * 10) / (f * spc)
    hf = harmonic_fit(t, 0.01 * t + 1e-4 * np.sin(2 * np.pi * f * t), f, 3)
    assert hf.slope == pytest.approx(0.01, rel=1e-9) and hf.slope_se < 1e-9
    # harmonic 18 (720 Hz) of amplitude 1.81, harmonic 2 (80 Hz) of amplitude 1: seed §5's metal 40 Hz ratio
    a = np.cos(2 * np.pi * 2 * f * t) + 1.81 * np.cos(2 * np.pi * 18 * f * t) + 0.5 * np.cos(2 * np.pi * f * t)
    assert spectral_ratio(t, a, f, 25, 80.0) == pytest.approx(1.81, rel=1e-9)


def test_the_cached_pseudo_inverse_fits_as_lstsq_does():
    """harmonic_fit solves with the time base's cached pseudo-inverse: the same coefficients as numpy's lstsq to
    round-off, on an impact-like signal with drift (every harmonic up to 25 carries energy)."""
    f, spc = 40.0, 2000
    t = np.arange(spc * 2) / (f * spc)
    x = np.maximum(np.sin(2 * np.pi * f * t) - 0.9, 0.0) ** 1.5 * 1e3 + 3.0 * t + 0.2
    from pipeline.diagnosis.features import _design

    a = _design(t, f, 25)
    ref = np.linalg.lstsq(a, x, rcond=None)[0]
    got = harmonic_fit(t, x, f, 25)
    c_ref = ref[2::2] - 1j * ref[3::2]
    assert np.max(np.abs(got.c - c_ref)) <= 1e-12 * np.max(np.abs(c_ref))
    assert got.offset == pytest.approx(ref[0], rel=1e-12) and got.slope == pytest.approx(ref[1], rel=1e-10)


def test_a_steady_summary_run_is_simulated_without_history_unless_its_features_need_one():
    """A steady-state summary run's peak deceleration and impacts per cycle are the simulator's labels: it runs
    without a history, by the same integrator (the same labels); a spectral ratio or a sensor low-pass needs one."""
    from pipeline.diagnosis.features import simulated_features
    from pipeline.diagnosis.model import Evaluator

    ctrl = {"frequency_hz": 60.0, "amplitude_n": 440.0, "static_force_n": 198.9512, "gap_m": 1e-3}
    labels = Target(run_id="a", system="indenter-metal", kind="summary", controls=ctrl,
                    names=["peak_decel_g", "impacts_per_cycle"], y=np.array([30.0, 1.0]), sd=np.array([3.0, 0.5]),
                    lower_bound=np.zeros(2, dtype=bool), duration_s=1 / 60.0, k_max=16)
    spectral = Target(run_id="b", system="indenter-metal", kind="summary", controls=ctrl,
                      names=["peak_decel_g", "spectral_ratio"], y=np.array([30.0, 0.5]), sd=np.array([3.0, 0.05]),
                      lower_bound=np.zeros(2, dtype=bool), duration_s=1 / 60.0, k_max=16, ratio_ref_hz=60.0)
    assert not labels.needs_history({}) and labels.needs_history({"fc": 500.0}) and spectral.needs_history({})
    ev = Evaluator("indenter-metal", [labels, spectral], dict(DiagnoseConfig().sim_settings), 20000.0, 1)
    (r_lab, r_spec), = ev.simulate([{}], [0, 1])
    assert r_lab.columns is None and r_spec.columns is not None
    m = simulated_features(labels, r_lab)
    assert m.tolist() == [r_lab.labels["peak_decel_g"], r_lab.labels["impacts_per_cycle"]]
    assert simulated_features(spectral, r_spec)[0] == m[0]       # the history changes no step of the integrator
    (r_fc,), = ev.simulate([{"fc": 2000.0}], [0])
    assert r_fc.columns is not None


def _targets(n):
    return [Target(run_id=f"r{i}", system="indenter-metal", kind="series",
                   controls={"frequency_hz": 30.0 + 10 * (i % 8), "amplitude_n": 1.0,
                             "static_force_n": 200.0 + 100 * (i // 8), "gap_m": 1e-3}) for i in range(n)]


def test_folds_are_deterministic_and_disjoint():
    scheme = make_folds(_targets(16), DiagnoseConfig())
    assert scheme.name == "holdout" and len(scheme.folds) == 1
    cal, test = scheme.folds[0]
    assert len(test) == 4 and not set(cal) & set(test) and sorted(cal + test) == list(range(16))
    assert 0 not in test and 15 not in test                 # the frequency range ends stay in calibration
    assert scheme.reported_runs == cal                      # a single split reports its calibration fits
    assert make_folds(_targets(16), DiagnoseConfig()) == scheme
    scheme = make_folds(_targets(4), DiagnoseConfig())
    assert scheme.name == "leave-one-run-out" and [t for _, t in scheme.folds] == [[0], [1], [2], [3]]
    assert scheme.reported_runs == [0, 1, 2, 3]             # leave-one-run-out reports a fit on all runs


def test_two_levels_at_the_same_frequencies_are_not_held_out_at_one_frequency():
    """Two static forces run at the same four frequencies (the independent pendulum's two gaps, the indenters' two
    forces): every 4th run of the sorted list would hold out both runs at the second frequency, and no calibration
    run would show that frequency; the second pick moves to the next frequency of its level.  Where every run has
    the same frequency nothing can move, and the split is every 4th run."""
    def runs(freqs, forces):
        return [Target(run_id=f"r{i}", system="indenter-metal", kind="series",
                       controls={"frequency_hz": f, "amplitude_n": 1.0, "static_force_n": fs, "gap_m": 1e-3})
                for i, (fs, f) in enumerate((fs, f) for fs in forces for f in freqs)]

    tg = runs((40.0, 60.0, 70.0, 90.0), (200.0, 300.0))
    (cal, test), = make_folds(tg, DiagnoseConfig()).folds
    assert [(tg[i].controls["static_force_n"], tg[i].controls["frequency_hz"]) for i in test] == [(200.0, 60.0),
                                                                                               (300.0, 70.0)]
    assert {tg[i].controls["frequency_hz"] for i in cal} == {40.0, 60.0, 70.0, 90.0}
    tg = runs((50.0,), (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0))
    assert make_folds(tg, DiagnoseConfig()).folds[0][1] == [1, 5]
    tg = runs((40.0, 55.0, 70.0, 85.0), (200.0,)) + runs((45.0, 60.0, 75.0, 90.0), (300.0,))   # interleaved: as before
    assert [tg[i].controls["frequency_hz"] for i in make_folds(tg, DiagnoseConfig()).folds[0][1]] == [55.0, 60.0]


def _synth(tmp_path, name, *args):
    from pipeline.cli import main

    out = tmp_path / name
    assert main(["synth", "--out", str(out), *args]) == 0
    return out


def _diagnose(tmp_path, data, *args):
    from pipeline.cli import main

    out = tmp_path / (data.name + "-diag")
    assert main(["diagnose", str(data), "--out", str(out), "--quiet", *args]) == 0
    return json.loads((out / "report.json").read_text()), out


def test_small_end_to_end_recovers_sensor_lowpass(tmp_path, monkeypatch):
    """6 short runs, two candidates: the sensor low-pass (fc = 350 Hz) must be selected and cut the
    held-out error to the noise level; report files, figures and the MLflow run must exist."""
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    data = _synth(tmp_path, "lp", "--system", "indenter-metal", "--effect", "sensor_lowpass", "--cycles", "8",
                  "--frequencies", "60", "80", "100", "--seed", "4")
    rep, out = _diagnose(tmp_path, data, "--effects", "sensor_lowpass", "guide_friction",
                         "--set", "min_runs_holdout=6", "--set", "holdout_every=3", "--set", "n_starts=1", "--set", "candidate_starts=1")
    for key in ("system", "calibrated", "noise_floor", "default_error", "base_error", "candidates", "selected",
                "final_error", "explained"):
        assert key in rep
    assert rep["selected"] == "sensor_lowpass" and rep["explained"] is True
    assert rep["final_error"] < 0.2 * rep["base_error"]
    assert rep["final_nrms"] <= 1.5
    fc = next(c for c in rep["candidates"] if c["effect"] == "sensor_lowpass")["params"]["fc"]
    assert fc == pytest.approx(350.0, rel=0.05)            # the synthetic truth (pipeline/synthesis/workflow.py)
    assert (out / "report.md").exists() and list(out.glob("*.png"))
    import mlflow

    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'mlflow.db'}")
    runs = mlflow.search_runs(experiment_names=["vibro"])
    assert len(runs) == 1 and runs.iloc[0]["tags.vibro.stage"] == "diagnose"
    # the corrected rig: written beside the report, logged with the run, and a rig every command reads
    from pipeline.core.rigfile import read_rig

    rig = read_rig(out / "rig.yaml")
    sel = next(c for c in rep["candidates"] if c["effect"] == "sensor_lowpass")
    assert rig.model == "indenter-metal" and rig.effects == {"sensor_lowpass": {"fc": pytest.approx(fc)}}
    for name, value in sel["calibrated"].items():          # calibrated jointly with the selected effect
        if name != "fc":
            assert rig.parameters[name] == pytest.approx(value)
    assert set(rig.uncertainty) == set(sel["param_sd"]) and all(v > 0 for v in rig.uncertainty.values())
    assert rig.uncertainty["fc"] == pytest.approx(sel["param_sd"]["fc"])
    assert "explained with sensor_lowpass" in rig.source and rep["rig"]["file"] == "rig.yaml"
    assert rep["rig"]["explained"] is True
    client = mlflow.tracking.MlflowClient()
    assert [a.path for a in client.list_artifacts(runs.iloc[0]["run_id"], "rig")] == ["rig/rig.yaml"]
    assert "rig.yaml" in (out / "report.md").read_text()


def test_small_end_to_end_finds_two_effects_at_once(tmp_path):
    """6 short runs with a shaker coil and a sensor low-pass, three candidates: the coil leads but leaves held-out nrms
    far above pair_nrms, so the pair stage (on by default) fits it with each other candidate and selects the coil and
    the low-pass, both near the synthetic truth.  The independent generator's 8-run drill log with a coil and guide
    friction is the slow-marked ``test_two_effects_at_once_are_both_found``."""
    import yaml

    data = _synth(tmp_path, "pair", "--system", "indenter-metal", "--effect", "shaker_coil", "--effect",
                  "sensor_lowpass", "--cycles", "8", "--frequencies", "60", "80", "100", "--seed", "4", "--quiet")
    truth = json.loads((tmp_path / "pair.truth.json").read_text())["effects"]
    rep, out = _diagnose(tmp_path, data, "--no-mlflow", "--effects", "shaker_coil", "sensor_lowpass", "guide_friction",
                         "--set", "min_runs_holdout=6", "--set", "holdout_every=3", "--set", "n_starts=1",
                         "--set", "candidate_starts=1", "--set", "grid=2", "--set", "profile_points=1",
                         "--set", "profile_nfev=1", "--set", "estimate_chain=false")   # vibro synth records no chain
    assert rep["call"]["text"].startswith("one effect: unexplained"), rep["call"]["text"]
    assert rep["pair_stage"]["tried"] and "shaker_coil improves on the base" in rep["pair_stage"]["reason"]
    assert rep["verdict"] == "selected" and rep["selected_effects"] == ["shaker_coil", "sensor_lowpass"]
    pair = rep["second_effect"]["candidates"][0]
    assert pair["name"] == rep["selected"] and pair["adequate"] and pair["improves"]
    assert set(truth) == {"tau", "beta", "fc"}                # pipeline/synthesis/workflow.py effect_defaults
    for k, v in truth.items():
        assert pair["params"][k] == pytest.approx(v, rel=0.02), (k, pair["params"][k])
    rig = yaml.safe_load((out / "rig.yaml").read_text())
    assert set(rig["effects"]) == {"shaker_coil", "sensor_lowpass"}


# ----------------------------------------------------------------------------- slow matrix
METAL = ["shaker_coil", "rate_stiffening", "guide_friction", "suspension_hardening", "sensor_lowpass"]
SAND = METAL + ["tip_blunting"]
MATRIX = [("indenter-metal", e) for e in METAL] + [("indenter-sandstone", e) for e in SAND]


@pytest.mark.slow
@pytest.mark.parametrize("system, effect", MATRIX)
def test_recovers_every_effect(tmp_path, monkeypatch, system, effect):
    """16 runs (Table 1 frequencies x 1.0 / 1.5 bar), default settings: the effect used to make the
    data is selected, explains the held-out residual, and cuts the held-out error at least 5-fold."""
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")
    data = _synth(tmp_path, f"{effect}", "--system", system, "--effect", effect, "--cycles", "20", "--seed", "1")
    rep, _ = _diagnose(tmp_path, data)
    assert rep["selected"] == effect
    assert rep["explained"] is True
    assert rep["final_error"] < 0.2 * rep["base_error"]


@pytest.mark.slow
@pytest.mark.parametrize("system", ["indenter-metal", "indenter-sandstone"])
def test_control_selects_nothing(tmp_path, monkeypatch, system):
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")
    data = _synth(tmp_path, "control", "--system", system, "--cycles", "20", "--seed", "2")
    rep, _ = _diagnose(tmp_path, data)
    assert rep["selected"] is None and rep["explained"] is True
    assert rep["base_nrms"] <= 1.5


@pytest.mark.slow
def test_outside_physics_is_unexplained(tmp_path, monkeypatch):
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")
    data = _synth(tmp_path, "outside", "--system", "indenter-metal", "--outside", "mount_resonance",
                  "--cycles", "20", "--seed", "3")
    rep, out = _diagnose(tmp_path, data)
    assert rep["selected"] is None and rep["explained"] is False
    assert "unexplained" in (out / "report.md").read_text()
