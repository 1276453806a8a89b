"""``--margin``: the recommendation keeps a stated fraction below every limit, within the surrogate's uncertainty."""
from __future__ import annotations

import pytest

from pipeline.cli import main as cli_main
from pipeline.core.errors import UserError
from pipeline.optimise.config import OptimiseConfig
from pipeline.optimise.constraints import Constraints
from pipeline.optimise.strategies import build_strategies
from pipeline.optimise.workflow import plan_optimise, run_optimise

from .test_optimise import ToyBundle

LIMITS = {"max_power_w": 18.0, "max_decel_g": 4.0}
SPACE = {"frequency_hz": [150.0, 300.0], "amplitude_n": [2200.0, 2700.0], "static_force_n": [1400.0, 1800.0]}


def _run(tmp_path, name: str, mode: str = "simulator", limits=None, **kw):
    cfg = OptimiseConfig(mode=mode, surrogate=str(tmp_path), preset="lab", ranges=SPACE, n_trials=64, n_verify=6,
                         storage=f"sqlite:///{tmp_path / 'optuna.db'}", study_name=name, **(limits or LIMITS), **kw)
    bundle = ToyBundle() if mode == "surrogate" else None
    return run_optimise(plan_optimise(cfg, build_strategies(cfg, bundle)), progress=False)


def test_margin_keeps_every_verified_point_feasible_under_the_stated_uncertainty(tmp_path):
    res = _run(tmp_path, "margin", margin=0.05)
    rec = res.recommendation
    assert rec is not None and {m["label"] for m in rec["margins"]} == {"power_w", "peak_decel_g"}
    for m in rec["margins"]:        # the answer states the margin it kept, and kept it
        assert m["margin"] == 0.05 and m["kept_below"] == pytest.approx(0.95 * m["limit"])
        assert m["value_sim"] <= m["kept_below"] and m["headroom"] >= 0.05
    assert "margin kept: power_w" in res.outcome
    ok = res.verified[res.verified["feasible_sim"]]
    assert len(ok)
    for label, lim in (("power_w", 18.0), ("peak_decel_g", 4.0)):
        # every point called feasible stays under the limit when its value is off by ± the margin (5 % of the limit)
        assert (ok[f"{label}_sim"] + 0.05 * lim <= lim).all()
    from pipeline.optimise.limitmap import write_limit_maps

    pngs, n = write_limit_maps(res, tmp_path / "maps", shape=(7, 5))     # ROP around it, the limits drawn
    assert n == 70 and sorted(p.split("/")[-1] for p in pngs) == ["limit_map_frequency_hz_amplitude_n.png",
                                                                   "limit_map_frequency_hz_static_force_n.png"]
    plain = _run(tmp_path, "no-margin")
    assert "margins" not in plain.recommendation
    # without the margin the optimum sits closer to a limit than the margin allows
    assert max(plain.recommendation["power_w_sim"] / 18.0, plain.recommendation["peak_decel_g_sim"] / 4.0) > 0.95


def test_margin_judges_a_surrogate_prediction_by_its_interval(tmp_path):
    # ToyBundle's power is 5e-5 F0² W (242-365 W over SPACE), its interval ± 10 %
    res = _run(tmp_path, "sur-margin", mode="surrogate", limits={"max_power_w": 330.0}, margin={"power_w": 0.05},
               fallback_trials=0)
    pred_ok = res.verified[res.verified["feasible_pred"]]
    assert len(pred_ok)
    # every point the study called feasible has its interval's top below 0.95 × 330 W
    assert (pred_ok["power_w_hi"] <= 0.95 * 330.0 + 1e-9).all()
    assert (pred_ok["power_w_pred"] > 0.95 * 330.0 / 1.1 - 1.0).any()       # and the interval is what binds
    assert [m["label"] for m in res.recommendation["margins"]] == ["power_w"]


def test_margin_constraint_values():
    c = Constraints(max_power_w=20.0, margins={"power_w": 0.1})
    assert c.values({"status": "ok", "power_w": 18.0})["power"] == pytest.approx(0.0)
    assert c.values({"status": "ok", "power_w": 17.0, "power_w_hi": 19.0})["power"] > 0      # the interval counts
    assert Constraints(max_power_w=20.0).values({"status": "ok", "power_w": 19.0, "power_w_hi": 21.0})["power"] < 0


@pytest.mark.parametrize("argv, msg", [
    (["--margin", "0.05"], "no limit to keep a margin from"),
    (["--max-power-w", "18", "--margin", "1.5"], "in [0, 1)"),
    (["--max-power-w", "18", "--margin", "peak_decel_g=0.1"], "peak_decel_g has no limit"),
    (["--max-power-w", "18", "--margin", "rop=0.1"], "not a limited label"),
    (["--max-power-w", "18", "--margin", "power_w=x"], "--margin power_w"),
])
def test_bad_margin_is_one_line_exit_2(tmp_path, capsys, argv, msg):
    rc = cli_main(["optimise", "--simulator", "--preset", "lab", *argv, "--out", str(tmp_path / "o"), "--no-mlflow"])
    err = capsys.readouterr().err
    assert rc == 2 and msg in err and "Traceback" not in err and len(err.splitlines()) == 1


def test_margin_config_refuses_a_bad_fraction():
    with pytest.raises(UserError, match="margin"):
        OptimiseConfig(mode="simulator", max_power_w=18.0, margin=-0.1)
    with pytest.raises(UserError, match="not a number"):
        OptimiseConfig(mode="simulator", max_power_w=18.0, margin=False)        # params.yaml 'margin: no'
    with pytest.raises(UserError, match="no limit"):
        OptimiseConfig(mode="simulator", max_power_w=18.0, margin={"peak_decel_g": 0.1})
