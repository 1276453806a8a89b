"""Infill until the surrogate is right where it is used: a surrogate the simulator contradicts is retrained on its
sweep plus points simulated where the study looked (the feedback file), instead of being replaced at once by a study
on the simulator; each round is reported."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

import sim
from pipeline.optimise.outcome import optimise
from pipeline.optimise.config import OptimiseConfig
from pipeline.optimise.infill import InfillReport, NearIncumbent

LAB = {"frequency_hz": (100.0, 450.0), "amplitude_n": (1800.0, 2700.0), "static_force_n": (600.0, 1800.0)}
LIMITS = {"max_power_w": 18.0, "max_decel_g": 4.0}      # params.yaml 'optimise': both bind on the lab preset


@pytest.fixture()
def poor_surrogate(tmp_path, monkeypatch):
    """A deliberately poor surrogate of the lab preset: kernel ridge on 48 random points, its sweep saved beside it."""
    import surrogate

    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    u = np.random.default_rng(0).random((48, 3))
    X = pd.DataFrame({n: lo + u[:, i] * (hi - lo) for i, (n, (lo, hi)) in enumerate(LAB.items())})
    df = sim.simulate_batch("drill", X, preset="lab").assign(point_id=np.arange(len(X)))
    df.to_parquet(tmp_path / "sweep.parquet")
    bundle = surrogate.train_bundle(df, list(LAB), LAB, "drill", "lab",
                                    config={"regressors": ["krr"], "classifiers": ["trees"], "learning_curve": [],
                                            "cv_folds": 2, "workers": 1})
    bundle.save(tmp_path / "sur")
    return tmp_path


def _config(d, **kw) -> OptimiseConfig:
    base = dict(mode="surrogate", surrogate=str(d / "sur"), n_trials=120, n_verify=6, batch_size=8,
                storage=f"sqlite:///{d / 'o.db'}", feedback=str(d / "fb.parquet"), train_data=str(d / "sweep.parquet"),
                infill_rounds=3, infill_points=16, fallback_trials=8, **LIMITS)
    return OptimiseConfig(**{**base, **kw})


def test_infill_makes_a_wrong_surrogate_agree_at_its_recommendation_without_the_fallback(poor_surrogate):
    d = poor_surrogate
    rep = optimise(_config(d), d / "out", progress=False).report
    inf = InfillReport.from_json(rep["infill"])
    first, last = inf.rounds[0], inf.rounds[-1]
    assert first.failed is not None and first.n_wrong > first.n_verified / 2      # round 0: the surrogate is wrong
    assert first.points_added == 16 and 1 <= inf.n_rounds <= 3
    assert last.failed is None and not last.recommendation_wrong and inf.agreed   # the last round agrees
    # a round that agrees but still moved the recommendation up (> 1 %) is followed by another, within the bound
    for before, r in zip(inf.rounds[:-2], inf.rounds[1:-1]):
        assert r.failed is not None or r.rop_m_s_sim > 1.01 * before.rop_m_s_sim
    assert "fallback" not in rep and rep["metrics"]["surrogate_fallback"] is False
    # the recommendation is the last round's, verified: its simulated ROP is the simulator's at its controls
    rec = rep["recommendation"]
    assert rec["params"] == last.params and rec["rop_m_s_sim"] == last.rop_m_s_sim
    truth = sim.simulate("drill", preset="lab", **rec["params"]).labels
    assert rec["rop_m_s_sim"] == pytest.approx(truth["rop_m_s"], rel=1e-12)
    assert truth["power_w"] <= LIMITS["max_power_w"] and truth["peak_decel_g"] <= LIMITS["max_decel_g"]
    assert abs(rec["rop_m_s_pred"] / rec["rop_m_s_sim"] - 1) <= 0.1
    # every extra simulation is counted: the infill points and the later rounds' verifications
    assert inf.simulations == sum(r.points_added for r in inf.rounds) + sum(r.n_verified for r in inf.rounds[1:])
    assert rep["metrics"]["infill_simulations"] == inf.simulations and rep["metrics"]["infill_rounds"] == inf.n_rounds
    # the data path is the feedback file: verified and infill points of every round's study are in it
    fb = pd.read_parquet(d / "fb.parquet")
    assert set(fb["study"]) == {r.study_name for r in inf.rounds}
    assert (fb["source"] == "optimise-infill").sum() == sum(r.points_added for r in inf.rounds)
    assert len(fb) == rep["feedback_rows"] == inf.simulations + first.n_verified
    # the retrained surrogate was fitted on the sweep's training split plus those rows
    assert last.n_train > first.n_train
    md = (d / "out" / "report.md").read_text()
    assert "## Infill" in md and f"| {last.round} | {last.study_name} |" in md
    assert InfillReport.from_json(json.loads((d / "out" / "report.json").read_text())["infill"]) == inf


def test_no_infill_rounds_is_the_fallback_at_once(poor_surrogate):
    d = poor_surrogate
    rep = optimise(_config(d, infill_rounds=0), d / "out", progress=False).report
    assert "infill" not in rep and rep["metrics"]["surrogate_fallback"] is True and rep["tried"]["mode"] == "simulator"


def test_without_a_sweep_the_report_says_why_and_falls_back(poor_surrogate):
    d = poor_surrogate
    rep = optimise(_config(d, train_data=None), d / "out", progress=False).report
    assert rep["infill"]["n_rounds"] == 0 and "give --train-data" in rep["infill"]["note"]
    assert rep["metrics"]["surrogate_fallback"] is True


def test_the_design_looks_on_the_limits_and_the_faces_around_the_incumbent(poor_surrogate):
    """Half the points lie on a limit the study ran into (within 5 %), the rest near the incumbent, every other one
    on the face of the box the incumbent lies on; none repeats a verified point."""
    from pipeline.optimise.strategies import build_strategies
    from pipeline.optimise.workflow import plan_optimise, run_optimise
    import surrogate

    d = poor_surrogate
    cfg = _config(d, infill_rounds=0)
    res = run_optimise(plan_optimise(cfg, build_strategies(cfg, surrogate.load_bundle(d / "sur"))), progress=False)
    X = NearIncumbent()(res, 16, seed=1)
    assert len(X) == 16 and list(X.columns) == list(LAB)
    space = res.problem.space
    U, V = space.unit(X), space.unit(res.verified)
    assert min(np.linalg.norm(U[i] - V[j]) for i in range(len(U)) for j in range(len(V))) >= 0.01
    limits = [k for k in res.constraints.names() if k not in ("steady_state", "progress")]
    edge = X.head(8).merge(res.trials, on=list(LAB), how="left")      # the study's own trials
    assert len(edge) == 8 and edge["trial"].notna().all()
    assert all(any(abs(v) <= 0.05 for k, v in res.constraints.values(row).items() if k in limits)
               for row in edge.to_dict("records"))
    from pipeline.optimise.infill import incumbent

    assert incumbent(res) == {n: float(res.verified.iloc[0][n]) for n in LAB}     # nothing recommended: the top
    # an incumbent in a corner of the box (F0 and Fs at their upper bounds, as the limited lab optimum is)
    inc = {**incumbent(res), "amplitude_n": 2700.0, "static_force_n": 1800.0}
    res = dataclasses.replace(res, recommendation={"params": inc})
    X = NearIncumbent()(res, 16, seed=1)
    faces = space.on_bounds(inc)
    assert [h["name"] for h in faces] == ["amplitude_n", "static_force_n"]
    local = X.tail(8).reset_index(drop=True)
    for h in faces:
        assert (local[h["name"]] == h["bound"]).sum() >= 3
    assert (np.abs(space.unit(local) - space.unit(pd.DataFrame([inc]))) <= 0.1 + 1e-12).all()


def test_the_flags_and_params_yaml_set_the_loop(tmp_path):
    from pipeline.cli import build_parser
    from pipeline.cli.optimise import config_from_args
    from pipeline.core.errors import UserError

    def cfg(*argv):
        return config_from_args(build_parser().parse_args(["optimise", "--simulator", *argv]))

    assert (cfg().infill_rounds, cfg().infill_points, cfg().train_data) == (3, 16, None)
    c = cfg("--infill-rounds", "0", "--infill-points", "4", "--train-data", "data/sweep-rig")
    assert (c.infill_rounds, c.infill_points, c.train_data) == (0, 4, "data/sweep-rig")
    (tmp_path / "p.yaml").write_text("optimise:\n  infill_rounds: 5\n")
    assert cfg("--params", str(tmp_path / "p.yaml")).infill_rounds == 5
    (tmp_path / "p.yaml").write_text("optimise:\n  infill_rounds: -1\n")
    with pytest.raises(UserError, match="infill_rounds"):
        cfg("--params", str(tmp_path / "p.yaml"))


def test_another_sweep_is_never_mixed_into_the_surrogate(poor_surrogate):
    """A --train-data that is not the surrogate's own sweep (another rig's, another design) is refused by its
    fingerprint: the report says so and the fallback runs."""
    d = poor_surrogate
    pd.read_parquet(d / "sweep.parquet").iloc[:-1].to_parquet(d / "other.parquet")
    rep = optimise(_config(d, train_data=str(d / "other.parquet")), d / "out", progress=False).report
    assert rep["infill"]["n_rounds"] == 0 and "not the sweep the surrogate was trained on" in rep["infill"]["note"]
    assert rep["metrics"]["surrogate_fallback"] is True


@pytest.mark.slow
def test_infill_on_a_corrected_rig_through_the_commands(tmp_path, monkeypatch, capsys):
    """The whole chain on a rig with a §6 effect (the shaker coil), as `make run` does on the corrected rig: sweep,
    train (which records its sweep), optimise under the pipeline's limits with 12 verified points.  The surrogate
    (kernel ridge on 48 points) is wrong at its recommended point; infill makes it agree there without the fallback,
    and the recommendation is compared with a 200-trial study straight on the simulator (~2 min on 2 shared cores)."""
    from pipeline.cli import main
    from pipeline.core.rigfile import write_rig
    from sim import Rig

    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    monkeypatch.chdir(tmp_path)
    write_rig("rig.yaml", Rig("drill", "lab", effects={"shaker_coil": {"tau": 1e-4, "beta": 3000.0}}))
    quiet = ["--no-mlflow", "--quiet"]
    limits = ["--max-power-w", "18", "--max-decel-g", "4"]
    vary = [a for n, (lo, hi) in LAB.items() for a in ("--vary", f"{n}={lo:g}:{hi:g}")]
    assert main(["sweep", "--rig", "rig.yaml", *vary,
                 "--n-points", "48", "--seed", "0", "--out", "data/sweep", *quiet]) == 0
    assert main(["train", "data/sweep", "--rig", "rig.yaml", "--chain", "corrected", "--out", "models/sur",
                 "--regressors", "krr", "--classifiers", "trees", "--cv-folds", "2", *quiet]) == 0
    capsys.readouterr()
    assert main(["optimise", "--surrogate", "models/sur", *limits, "--n-trials", "400", "--n-verify", "12",
                 "--out", "results/sur", *quiet]) == 0
    printed = capsys.readouterr().out
    rep = json.loads((tmp_path / "results" / "sur" / "report.json").read_text())
    inf = InfillReport.from_json(rep["infill"])
    assert inf.train_data == "data/sweep"              # the sweep vibro train recorded, no --train-data needed
    assert inf.rounds[0].failed is not None and inf.agreed and inf.n_rounds >= 1
    assert "fallback" not in rep and not rep["recommendation"]["surrogate_wrong"]
    assert inf.rounds[-1].n_wrong <= 1                  # agrees at >= 11 of the 12 verified points
    assert all(line in printed for line in rep["infill"]["lines"]) and rep["infill"]["text"] in printed
    assert main(["optimise", "--simulator", "--rig", "rig.yaml", *limits, "--n-trials", "200",
                 "--out", "results/sim", *quiet]) == 0
    sim_best = json.loads((tmp_path / "results" / "sim" / "report.json").read_text())["recommendation"]["rop_m_s_sim"]
    ratio = rep["recommendation"]["rop_m_s_sim"] / sim_best
    print(f"\ninfill: {inf.n_rounds} round(s), {inf.simulations} extra simulations; recommended "
          f"{rep['recommendation']['rop_m_s_sim'] * 1e3:.4g} mm/s = {ratio:.3f} of the simulator study's")
    assert ratio >= 0.98
