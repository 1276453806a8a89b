"""Tests of `vibro optimise` / `vibro verify`: constraints, studies, verification, closing the loop.

The simulator runs on the drill `lab` preset over small budgets; `ToyBundle` below is a TEST DOUBLE of the
surrogate contract (analytic predictions), used where the test is about the optimise logic, not the surrogate.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

import sim
from pipeline.cli import main as cli_main
from pipeline.core.errors import UserError
from pipeline.optimise.constraints import Constraints, progress_force_floor
from pipeline.optimise.space import Space, parse_range
from pipeline.optimise.study import pareto_mask, pick_candidates
from pipeline.optimise.config import OptimiseConfig
from pipeline.optimise.outcome import optimise

LAB = {"frequency_hz": (100.0, 450.0), "amplitude_n": (1800.0, 2700.0), "static_force_n": (600.0, 1800.0)}
SMALL = {"frequency_hz": [250.0, 300.0], "amplitude_n": [2400.0, 2700.0], "static_force_n": [1400.0, 1800.0]}


class ToyBundle:
    """TEST DOUBLE of surrogate.Bundle (contract: inputs, ranges, model, preset, fingerprint, fixed, settings, report,
    predict).

    Predicts a smooth analytic ROP peaking at f = 280 Hz and growing with F0 and Fs (the shape MODELS.md §2 asks
    of the lab preset), a constant peak force of Pr = 3 kN, specific energy = energy / ROP with energy ∝ F0²/f,
    mean power = energy × f ∝ F0² and a peak deceleration ∝ f × F0.
    ``rop_scale`` multiplies the ROP to make the double deliberately wrong.
    """

    def __init__(self, rop_scale: float = 1.0, ranges=None):
        self.inputs = ["frequency_hz", "amplitude_n", "static_force_n"]
        self.ranges = dict(ranges or LAB)
        self.model, self.preset, self.fingerprint, self.report = "drill", "lab", "toy", {}
        self.fixed, self.settings = {}, {}      # the sweep's conditions (none: the lab preset as it is)
        self.rop_scale = rop_scale

    def predict(self, X: pd.DataFrame, strict: bool = False) -> pd.DataFrame:
        f, a, s = (X[n].to_numpy(float) for n in self.inputs)
        rop = self.rop_scale * 8e-3 * (a / 2700) * (s / 1800) * np.exp(-((f - 280.0) / 90.0) ** 2)
        energy = 1e-6 * a ** 2 / f * 50.0
        out = pd.DataFrame({"p_progress": np.full(len(X), 0.99), "regime": ["progressing"] * len(X)})
        for t, v in (("rop_m_s", rop), ("peak_force_n", np.full(len(X), 3000.0)),
                     ("impacts_per_cycle", np.ones(len(X))), ("specific_energy_j_m", energy * f / rop),
                     ("power_w", energy * f), ("peak_decel_g", 4.0 * (f / 280.0) * (a / 2700.0))):
            out[t], out[f"{t}_lo"], out[f"{t}_hi"] = v, 0.9 * v, 1.1 * v
        return out


@pytest.fixture()
def env(tmp_path, monkeypatch):
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    return tmp_path


# ---------------------------------------------------------------- constraints and spaces (no simulation)
def test_constraint_values_follow_optuna_sign_convention():
    c = Constraints(max_peak_force_n=2000.0, peak_force_static_ratio=2.0, max_specific_energy_j_m=1e6)
    ok = {"status": "ok", "rop_m_s": 1e-3, "peak_force_n": 1500.0, "static_force_n": 1000.0, "specific_energy_j_m": 5e5}
    assert c.feasible(ok) and c.violation(ok) == 0
    # 2500 N is 25 % over the 2000 N limit and 25 % over 2 × 1000 N
    v = c.values({**ok, "peak_force_n": 2500.0})
    assert v["peak_force"] == pytest.approx(0.25) and v["peak_vs_static"] == pytest.approx(0.25)
    assert not c.feasible({**ok, "status": "runaway", "rop_m_s": None, "peak_force_n": None})
    assert c.values({**ok, "specific_energy_j_m": math.inf})["specific_energy"] > 0   # nothing progresses
    assert not Constraints().feasible({**ok, "status": "not_settled"})
    assert Constraints(require_settled=False).feasible({**ok, "status": "not_settled"})


def test_contradictory_constraints_are_refused_with_the_reason():
    floor = progress_force_floor("drill", sim.get_model("drill").resolve("lab"))
    assert floor == 3000.0   # lab preset Pr (sim/models/drill.py)
    with pytest.raises(UserError, match="below the force 3000 N"):
        Constraints(max_peak_force_n=2000.0).check((600.0, 1800.0), floor)
    # k = 1 (seed 002's rule taken literally): Fs <= 1800 N can never allow the 3000 N needed to progress
    with pytest.raises(UserError, match="k must exceed 1"):
        Constraints(peak_force_static_ratio=1.0).check((600.0, 1800.0), floor)
    with pytest.raises(UserError, match="positive"):
        Constraints(max_specific_energy_j_m=0.0).check(None, None)
    Constraints(peak_force_static_ratio=2.0).check((600.0, 1800.0), floor)   # 3600 N >= 3000 N: allowed


def test_space_validation_names_the_bad_range():
    with pytest.raises(UserError, match="empty"):
        Space({}).validate()
    with pytest.raises(UserError, match="frequency_hz.*empty range"):
        Space({"frequency_hz": (400.0, 100.0)}).validate()
    with pytest.raises(UserError, match="'foo'"):
        Space({"foo": (0.0, 1.0)}).validate(["frequency_hz"])
    assert parse_range("amplitude_n=1800:2700") == ("amplitude_n", (1800.0, 2700.0))
    with pytest.raises(UserError, match="NAME=LOW:HIGH"):
        parse_range("amplitude_n=1800")


def test_pareto_mask_and_distinct_candidates():
    rop = np.array([1.0, 2.0, 3.0, 2.0, 0.5])
    se = np.array([1.0, 2.0, 5.0, 3.0, 2.0])
    # (2,3) is dominated by (2,2); (0.5,2) by (1,1); the rest trade ROP against energy
    assert pareto_mask(rop, se).tolist() == [True, True, True, False, False]
    space = Space({"x": (0.0, 1.0)})
    trials = pd.DataFrame({"x": [0.5, 0.501, 0.9, 0.1], "value": [4.0, 3.9, 3.0, 1.0], "feasible": [True] * 4})
    c = pick_candidates(trials, space, "rop", n=2)
    assert c["x"].tolist() == [0.5, 0.9]   # 0.501 is within 0.02 of 0.5 and skipped


# ---------------------------------------------------------------- studies
def test_simulator_study_recommends_a_verified_point_and_resumes(env):
    db = f"sqlite:///{env / 'optuna.db'}"
    cfg = OptimiseConfig(mode="simulator", preset="lab", ranges=SMALL, n_trials=8, n_verify=2, storage=db,
                         study_name="t-sim", seed=3, batch_size=4)
    from pipeline.cli.optimise import run_tracked       # the command's MLflow run around optimise

    rep = run_tracked(cfg, env / "out", progress=False, mlflow_enabled=True, metrics_path=str(env / "m.json")).report
    rec = rep["recommendation"]
    # the recommendation is a re-simulated point: simulating it again gives the same ROP (deterministic simulator)
    again = sim.simulate("drill", preset="lab", **rec["params"]).labels
    assert again["status"] == "ok"
    assert rec["rop_m_s_sim"] == pytest.approx(again["rop_m_s"], rel=1e-12)
    # ... and it is the best of the study's feasible trials (the study itself ran the simulator)
    trials = pd.read_csv(env / "out" / "trials.csv")
    assert rec["rop_m_s_sim"] == pytest.approx(trials.loc[trials.feasible, "value"].max(), rel=1e-12)
    assert rep["tried"]["simulator_calls"] == 8 + 2
    metrics = json.loads((env / "m.json").read_text())
    assert metrics["feasible"] and metrics["best_rop_m_s"] == pytest.approx(rec["rop_m_s_sim"])
    for f in ("report.md", "report.json", "verified.csv", "history.png", "verification.png"):
        assert (env / "out" / f).exists(), f
    import mlflow
    runs = mlflow.search_runs(experiment_names=["vibro"])
    assert runs["metrics.best_rop_m_s"].iloc[0] == pytest.approx(rec["rop_m_s_sim"])
    # resume: the stored 8 trials are kept, only 2 more run
    cfg.n_trials = 10
    rep2 = optimise(cfg, env / "out", progress=False).report
    assert rep2["tried"]["n_trials"] == 10 and rep2["tried"]["n_trials_run_now"] == 2
    assert rep2["recommendation"]["rop_m_s_sim"] >= rec["rop_m_s_sim"]
    # the same study name with other constraints is refused, not silently mixed
    cfg.max_peak_force_n = 5000.0
    with pytest.raises(UserError, match="different constraints"):
        optimise(cfg, env / "out", progress=False)


def test_surrogate_study_verifies_flags_wrong_predictions_and_closes_the_loop(env):
    bundle = ToyBundle(rop_scale=3.0)   # deliberately ~3x too optimistic
    fb = env / "feedback.parquet"
    cfg = OptimiseConfig(mode="surrogate", surrogate=str(env), ranges=SMALL, n_trials=40, n_verify=3,
                         storage=f"sqlite:///{env / 'optuna.db'}", study_name="t-sur", feedback=str(fb),
                         fallback_trials=0)     # the surrogate study's own verification (the fallback: test_workflow)
    rep = optimise(cfg, env / "out", bundle=bundle, progress=False).report
    table = pd.read_csv(env / "out" / "verified.csv")
    assert len(table) == 3
    # independent check of the verification: simulate the verified points here and compare
    truth = sim.simulate_batch("drill", table[bundle.inputs], preset="lab")
    np.testing.assert_allclose(table["rop_m_s_sim"], truth["rop_m_s"], rtol=1e-12)
    rel = (table["rop_m_s_pred"] - truth["rop_m_s"]).abs() / truth["rop_m_s"]
    assert (table["surrogate_wrong"] == (rel > 0.1)).all()
    assert table["surrogate_wrong"].any() and "wrong at" in rep["surrogate_note"]
    # the recommendation is the best *simulated* ROP among verified points, not the prediction
    rec = rep["recommendation"]
    assert rec["rop_m_s_sim"] == pytest.approx(truth["rop_m_s"].max(), rel=1e-12)
    assert rec["rop_m_s_pred"] != pytest.approx(rec["rop_m_s_sim"], rel=0.1)
    # closing the loop: verified points with simulated labels in the feedback file, no NaN-for-missing
    fbd = pd.read_parquet(fb)
    assert len(fbd) == 3 and {"point_id", "rop_m_s", "status", "surrogate_wrong", *bundle.inputs} <= set(fbd.columns)
    np.testing.assert_allclose(np.sort(fbd["rop_m_s"]), np.sort(truth["rop_m_s"]), rtol=1e-12)
    # a rerun of the completed study does not append the same points twice
    optimise(cfg, env / "out", bundle=bundle, progress=False)
    assert len(pd.read_parquet(fb)) == 3


def test_pareto_mode_trades_rop_against_power_with_ten_verified_points(env):
    # the toy's ROP grows with F0 and Fs while its power grows as F0² (ToyBundle): a real trade-off
    cfg = OptimiseConfig(mode="surrogate", surrogate=str(env), objective="pareto", ranges=SMALL, n_trials=200,
                         n_verify=12, storage=f"sqlite:///{env / 'optuna.db'}", feedback=str(env / "fb.parquet"))
    rep = optimise(cfg, env / "out", bundle=ToyBundle(), progress=False).report
    assert (env / "out" / "pareto.png").exists() and rep["objectives"] == ["rop_m_s", "power_w"]
    table = pd.read_csv(env / "out" / "verified.csv")
    assert len(table) == 12
    # every optimised objective is verified: the simulator's power next to the prediction, with its error
    truth = sim.simulate_batch("drill", table[["frequency_hz", "amplitude_n", "static_force_n"]], preset="lab")
    np.testing.assert_allclose(table["power_w_sim"], truth["energy_per_cycle_j"] * truth["frequency_hz"], rtol=1e-12)
    rel = (table["power_w_pred"] - table["power_w_sim"]).abs() / table["power_w_sim"]
    np.testing.assert_allclose(table["power_w_rel_error"], rel, rtol=1e-9)
    assert table["why"].fillna("").str.contains("power_w off by").tolist() == (rel > 0.1).tolist()
    # the front is built from the *simulated* objectives: non-dominated, distinct, sorted by ROP
    front = rep["pareto_verified"]
    r = np.array([p["rop_m_s"] for p in front])
    w = np.array([p["power_w"] for p in front])
    assert pareto_mask(r, w).all() and len(set(zip(r, w))) == len(front)
    ok = table[table["feasible_sim"]]
    assert len(front) == int(pareto_mask(ok["rop_m_s_sim"].to_numpy(), ok["power_w_sim"].to_numpy()).sum())
    assert np.all(np.diff(r) > 0) and np.all(np.diff(w) > 0)   # more ROP costs power
    md = (env / "out" / "report.md").read_text()
    assert "Verified Pareto front (rop_m_s vs power_w)" in md and "power_w [W]" in md


def test_pareto_front_of_the_study_spreads_ten_distinct_candidates():
    # a front of 50 points along rop = 1 - (1 - w)^2: 10 candidates, all distinct, spanning both ends
    w = np.linspace(0.0, 1.0, 50)
    trials = pd.DataFrame({"x": w, "value": 1 - (1 - w) ** 2, "value_2": w, "feasible": True})
    c = pick_candidates(trials, Space({"x": (0.0, 1.0)}), "pareto", n=10)
    assert len(c) == 10 and c["x"].nunique() == 10
    assert c["x"].max() == 1.0 and c["x"].min() == 0.0


def test_objectives_are_any_labels_with_a_direction():
    from pipeline.optimise.study import parse_objectives

    assert parse_objectives("rop_m_s,power_w", sim.LABELS) == [("rop_m_s", "maximize"), ("power_w", "minimize")]
    assert parse_objectives(["max:peak_decel_g", "rop_m_s"], sim.LABELS)[0] == ("peak_decel_g", "maximize")
    with pytest.raises(UserError, match="'watts' is not a label"):
        parse_objectives("rop_m_s,watts", sim.LABELS)
    with pytest.raises(UserError, match="at least two"):
        parse_objectives("rop_m_s", sim.LABELS)
    with pytest.raises(UserError, match="named twice"):
        parse_objectives("power_w,power_w", sim.LABELS)


def test_power_and_deceleration_limits_are_constraints():
    c = Constraints(max_power_w=20.0, max_decel_g=4.0)
    ok = {"status": "ok", "rop_m_s": 1e-3, "power_w": 10.0, "peak_decel_g": 3.0}
    assert c.feasible(ok) and c.names() == ["steady_state", "power", "decel"]
    # 25 W is 25 % over 20 W; 5 g is 25 % over 4 g; a missing label counts as violated
    assert c.values({**ok, "power_w": 25.0})["power"] == pytest.approx(0.25)
    assert c.values({**ok, "peak_decel_g": 5.0})["decel"] == pytest.approx(0.25)
    assert not c.feasible({**ok, "power_w": None})
    with pytest.raises(UserError, match="max_power_w must be a positive number"):
        Constraints(max_power_w=-1.0).check(None, None)


def test_on_bound_detection_names_the_control_and_side():
    space = Space(dict(LAB))
    hits = space.on_bounds({"frequency_hz": 262.0, "amplitude_n": 2700.0, "static_force_n": 1790.0})
    # 1790 N is 10 N = 0.8 % of the 1200 N range below 1800 N: within the 2 % tolerance, so on the bound
    assert [(h["name"], h["side"]) for h in hits] == [("amplitude_n", "high"), ("static_force_n", "high")]
    assert space.on_bounds({"frequency_hz": 105.0})[0]["side"] == "low"      # 5 Hz of 350: 1.4 %
    assert space.on_bounds({"frequency_hz": 110.0}) == []                    # 10 Hz of 350: 2.9 %


def test_power_limit_moves_the_optimum_off_the_corner(env):
    # without a limit the toy's best point is the corner F0 = 2700 N, Fs = 1800 N; its power is 5e-5·F0² W
    # (ToyBundle), so 320 W allows F0 <= sqrt(320 / 5e-5) = 2530 N
    base = dict(mode="surrogate", surrogate=str(env), ranges=SMALL, n_trials=60, n_verify=3,
                storage=f"sqlite:///{env / 'optuna.db'}", feedback=str(env / "fb.parquet"),
                fallback_trials=0)      # the toy's own power model sets the limit: no simulator study instead

    free = optimise(OptimiseConfig(**base, study_name="free"), env / "free", bundle=ToyBundle(),
                    progress=False).report
    assert ("amplitude_n", "high") in [(h["name"], h["side"]) for h in free["recommendation"]["on_bounds"]]
    assert "ON THE EDGE of the search space: amplitude_n at its upper bound 2700" in free["outcome"]
    assert "On the edge of the search space" in (env / "free" / "report.md").read_text()
    lim = optimise(OptimiseConfig(**base, study_name="lim", max_power_w=320.0), env / "lim", bundle=ToyBundle(),
                   progress=False).report
    trials = pd.read_csv(env / "lim" / "trials.csv")
    assert (trials["feasible"] == (5e-5 * trials["amplitude_n"] ** 2 <= 320.0)).all()
    a = lim["recommendation"]["params"]["amplitude_n"]
    assert a <= 2530.0 and "amplitude_n" not in [h["name"] for h in lim["recommendation"]["on_bounds"]]


def test_surrogate_without_the_constrained_label_is_refused(env):
    class NoPower(ToyBundle):
        def predict(self, X, strict=False):
            return super().predict(X).drop(columns=["power_w", "power_w_lo", "power_w_hi"])

    cfg = OptimiseConfig(mode="surrogate", surrogate=str(env), ranges=SMALL, n_trials=5, max_power_w=20.0,
                         storage=f"sqlite:///{env / 'optuna.db'}")
    with pytest.raises(UserError, match="predicts no power_w: retrain"):
        optimise(cfg, env / "out", bundle=NoPower(), progress=False)


def test_no_feasible_point_ends_with_a_clear_message_and_a_report(env):
    cfg = OptimiseConfig(mode="surrogate", surrogate=str(env), ranges=SMALL, n_trials=20,
                         max_specific_energy_j_m=1e-3, storage=f"sqlite:///{env / 'optuna.db'}")
    out = optimise(cfg, env / "out", bundle=ToyBundle(), progress=False)
    assert out.recommendation is None and out.outcome.startswith("no feasible point among 20 trials")
    md = (env / "out" / "report.md").read_text()
    assert "What was tried" in md and "max_specific_energy_j_m = 0.001" in md and "closest point" in md


# ---------------------------------------------------------------- CLI
def test_cli_bad_input_is_one_line_exit_2(env, capsys):
    rc = cli_main(["optimise", "--simulator", "--preset", "lab", "--peak-force-static-ratio", "1",
                   "--out", str(env / "o"), "--no-mlflow"])
    err = capsys.readouterr().err
    assert rc == 2 and "contradictory constraints" in err and "Traceback" not in err and len(err.splitlines()) == 1
    rc = cli_main(["optimise", "--simulator", "--range", "frequency_hz=400:100", "--out", str(env / "o"), "--no-mlflow"])
    assert rc == 2 and "frequency_hz" in capsys.readouterr().err
    rc = cli_main(["optimise", "--surrogate", str(env / "missing"), "--out", str(env / "o"), "--no-mlflow"])
    assert rc == 2 and "missing" in capsys.readouterr().err


def test_cli_verify_compares_file_predictions_with_the_simulator(env, capsys):
    pts = pd.DataFrame({"frequency_hz": [280.0, 300.0], "amplitude_n": [2500.0, 2600.0],
                        "static_force_n": [1500.0, 1600.0]})
    truth = sim.simulate_batch("drill", pts, preset="lab")
    pts["rop_m_s"] = [truth["rop_m_s"][0] * 1.01, truth["rop_m_s"][1] * 2.0]   # 1 % off (fine), 100 % off (wrong)
    pts.to_csv(env / "pts.csv", index=False)
    rc = cli_main(["verify", str(env / "pts.csv"), "--preset", "lab", "--out", str(env / "v"), "--no-mlflow",
                   "--metrics", str(env / "vm.json")])
    assert rc == 0
    table = pd.read_csv(env / "v" / "verified.csv")
    assert table["surrogate_wrong"].tolist() == [False, True]
    assert table["rop_rel_error"].tolist() == pytest.approx([0.01, 1.0], rel=1e-9)
    assert json.loads((env / "vm.json").read_text())["n_surrogate_wrong"] == 1
    pts["amplitude_n"] = pts["amplitude_n"].astype(object)
    pts.loc[1, "amplitude_n"] = "abc"
    pts.to_csv(env / "bad.csv", index=False)
    rc = cli_main(["verify", str(env / "bad.csv"), "--out", str(env / "v2"), "--no-mlflow"])
    err = capsys.readouterr().err
    assert rc == 2 and "row 1 column 'amplitude_n'" in err


# ---------------------------------------------------------------- the real surrogate
@pytest.mark.slow
def test_real_surrogate_bundle_end_to_end(env):
    """Train the real surrogate on 128 Sobol points of the lab space, optimise on it, verify 5 points."""
    from scipy.stats import qmc

    import surrogate

    names = list(LAB)
    u = qmc.Sobol(3, scramble=True, seed=1).random_base2(7)   # 128 points
    X = pd.DataFrame({n: LAB[n][0] + u[:, i] * (LAB[n][1] - LAB[n][0]) for i, n in enumerate(names)})
    df = sim.simulate_batch("drill", X, preset="lab").assign(point_id=np.arange(len(X)))
    bundle = surrogate.train_bundle(df, names, LAB, "drill", "lab",
                                    config={"regressors": ["gp"], "classifiers": ["trees"], "learning_curve": []})
    bundle.save(env / "sur")
    cfg = OptimiseConfig(mode="surrogate", surrogate=str(env / "sur"), n_trials=200, n_verify=5,
                         storage=f"sqlite:///{env / 'optuna.db'}")
    rep = optimise(cfg, env / "out", progress=False).report
    rec = rep["recommendation"]
    truth = sim.simulate("drill", preset="lab", **rec["params"]).labels
    assert rec["rop_m_s_sim"] == pytest.approx(truth["rop_m_s"], rel=1e-12)
    # the verified optimum beats every training point but one at most (a surrogate that learnt nothing would not)
    assert rec["rop_m_s_sim"] >= np.sort(df["rop_m_s"].dropna())[-2]
    assert len(pd.read_parquet(env / "sur" / "feedback.parquet")) == 5


def test_cli_no_feasible_point_names_the_report_it_kept(tmp_path, capsys):
    """The error of an infeasible study names the report at --out, and the report is there (not in a temporary
    folder that is removed with the failure)."""
    out = tmp_path / "o"
    rc = cli_main(["optimise", "--simulator", "--preset", "lab", "--n-trials", "4", "--n-verify", "2",
                   "--max-specific-energy-j-m", "1e-6", "--storage", f"sqlite:///{tmp_path / 'o.db'}",
                   "--feedback", str(tmp_path / "fb.parquet"), "--out", str(out), "--no-mlflow", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and f"report: {out / 'report.md'}" in err[0], err
    assert "What was tried" in (out / "report.md").read_text()
