"""``vibro optimise --rig``: the recommendation's ROP spread on the corrected rig (parameters + model error)."""
from __future__ import annotations

import json
import math

from pipeline.cli import main as cli_main

# a corrected rig as vibro diagnose writes one: a fitted K1 with its sd, and the held-out ROP error left over
RIG = """model: drill
preset: lab
parameters: {K1: 5.2e8}
uncertainty: {K1: 2.0e7}
model_error: {rop_rel: 0.04, noise_floor_rel: 0.01, basis: "held-out ROP of 3 runs"}
"""
SPACE = ["--vary", "frequency_hz=200:350", "--vary", "amplitude_n=2000:2700", "--vary", "static_force_n=1500:1800"]


def _optimise_on(rig_text: str, tmp_path, monkeypatch, n_trials: int) -> dict:
    """report.json of ``vibro optimise --simulator --rig`` on a rig file of ``rig_text`` over SPACE."""
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    rig = tmp_path / "rig.yaml"
    rig.write_text(rig_text)
    out = tmp_path / "o"
    rc = cli_main(["optimise", "--simulator", "--rig", str(rig), *SPACE, "--n-trials", str(n_trials), "--n-verify",
                   "2", "--storage", f"sqlite:///{tmp_path / 'optuna.db'}", "--out", str(out), "--no-mlflow", "--quiet"])
    assert rc == 0
    return json.loads((out / "report.json").read_text())


def test_optimise_on_a_rig_states_the_spread_from_one_field(tmp_path, monkeypatch, capsys):
    rep = _optimise_on(RIG, tmp_path, monkeypatch, 24)
    out = tmp_path / "o"
    s, rec = rep["spread"], rep["recommendation"]
    assert list(rep).index("spread") == list(rep).index("outcome") + 1
    # the nominal is the recommended point re-simulated on the same rig: the verified ROP, to the simulator's rounding
    assert math.isclose(s["nominal_rop_m_s"], rec["rop_m_s_sim"], rel_tol=1e-9)
    assert s["n_samples"] == 32 and s["sampled"] == ["K1"]
    assert s["p5_rop_m_s"] <= s["median_rop_m_s"] <= s["p95_rop_m_s"]
    # b = 1.645 · e · ROP (robustness.combined_half_widths) with e the rig file's rop_rel
    assert math.isclose(s["model_error_half_width_m_s"], 1.6448536269514722 * 0.04 * s["nominal_rop_m_s"])
    assert math.isclose(s["combined_half_width_m_s"], math.hypot(s["parameter_half_width_m_s"],
                                                                 s["model_error_half_width_m_s"]))
    assert rep["metrics"]["spread_simulations"] == 33
    printed = capsys.readouterr().out
    md = (out / "report.md").read_text()
    words = f"combined ±{s['combined_half_width_m_s'] * 1e3:.3g} mm/s"
    assert "how sure:" in printed and words in printed and words in md


def test_optimise_without_a_rig_has_no_spread(tmp_path, monkeypatch):
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    out = tmp_path / "o"
    rc = cli_main(["optimise", "--simulator", "--model", "drill", "--preset", "lab", *SPACE, "--n-trials", "8",
                   "--n-verify", "1", "--storage", f"sqlite:///{tmp_path / 'optuna.db'}", "--out", str(out),
                   "--no-mlflow", "--quiet"])
    assert rc == 0
    assert "spread" not in json.loads((out / "report.json").read_text())


# the same rig with an empirical ROP correction: +20 % at 1500 N, +5 % at 1800 N, over 200-350 Hz
EMPIRICAL = RIG + """empirical_correction:
  label: empirical correction, physics unknown
  target: rop_m_s
  inputs: [frequency_hz, static_force_n]
  lower: [200.0, 1500.0]
  upper: [350.0, 1800.0]
  points: [[200.0, 1500.0], [275.0, 1500.0], [350.0, 1500.0], [200.0, 1800.0], [275.0, 1800.0], [350.0, 1800.0]]
  values: [0.2, 0.2, 0.2, 0.05, 0.05, 0.05]
  mean: 0.125
  length_scales: [1.0, 1.0]
  signal_sd: 0.1
  noise_sd: 0.01
  floor_m_s: 1.0e-4
  basis: "test correction"
"""


def test_optimise_on_a_rig_with_an_empirical_correction_recommends_by_the_corrected_rop(tmp_path, monkeypatch,
                                                                                         capsys):
    """The study and its verification see the corrected ROP; the model's own is beside it; the spread's model error
    is the correction's sd at the point, said to be an empirical correction."""
    import yaml

    import sim
    from sim.empirical import EmpiricalCorrection

    rep = _optimise_on(EMPIRICAL, tmp_path, monkeypatch, 16)
    rec, s = rep["recommendation"], rep["spread"]
    rig = sim.Rig.from_mapping(yaml.safe_load(EMPIRICAL))
    point = rec["params"]
    model_rop = float(rig.simulate(**point).labels["rop_m_s"])
    corr: EmpiricalCorrection = rig.empirical
    fixed, sd = corr.correct(model_rop, {n: [point[n]] for n in corr.inputs})
    assert model_rop > 0 and math.isclose(rec["rop_m_s_sim"], float(fixed[0]), rel_tol=1e-9)
    assert rec["rop_m_s_sim"] > model_rop * 1.04              # the correction is +5 % to +20 % over the space
    assert math.isclose(s["nominal_rop_m_s"], rec["rop_m_s_sim"], rel_tol=1e-9)
    assert s["empirical_correction"] and math.isclose(s["model_error_rel"], float(sd[0]) / float(fixed[0]))
    assert "sd of the empirical ROP correction, physics unknown" in capsys.readouterr().out


def test_the_corrected_evaluator_keeps_the_models_rop_beside_and_what_does_not_progress():
    """RopCorrected on a stand-in simulator: the progressing row's ROP is corrected (here +20 %), the other keeps its
    0 and gets no sd; a control the table does not hold (static force) is the simulator's resolved value."""
    import numpy as np
    import pandas as pd
    import yaml

    from pipeline.optimise.evaluators import RopCorrected
    from sim.empirical import EmpiricalCorrection

    class Inner:
        resolved = {"static_force_n": 1500.0}
        calls = 7

        def __call__(self, X):
            return pd.DataFrame({"rop_m_s": [2e-3, 0.0], "status": ["ok", "ok"]})

    corr = EmpiricalCorrection.from_mapping(yaml.safe_load(EMPIRICAL)["empirical_correction"])
    ev = RopCorrected(Inner(), corr)
    out = ev(pd.DataFrame({"frequency_hz": [275.0, 275.0]}))
    mu, _ = corr.relative({"frequency_hz": [275.0], "static_force_n": [1500.0]})
    assert math.isclose(out["rop_m_s"].iloc[0], 2e-3 * (1 + mu[0]), rel_tol=1e-12) and 0.15 < mu[0] < 0.25
    assert out["rop_m_s"].iloc[1] == 0.0 and out["rop_correction_sd_m_s"].iloc[1] == 0.0
    assert np.array_equal(out["rop_model_m_s"], [2e-3, 0.0]) and ev.calls == 7
