"""The `vibro` program: labels as table/JSON, plots, and one-line errors (never a traceback)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from pipeline.cli import main
from sim.api import LABELS


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *args], capture_output=True, text=True, timeout=600)


def test_simulate_json_has_every_label(capsys):
    rc = main(["simulate", "drill", "--set", "frequency_hz=150", "--setting", "window=8", "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    for name in (*LABELS, "status", "reason"):
        assert name in out
    assert out["status"] == "ok" and out["rop_m_s"] > 0
    # inf is not JSON: specific energy of a non-progressing run is the string "inf"
    assert main(["simulate", "indenter-metal", "--preset", "table1-90hz", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["specific_energy_j_m"] == "inf"


def test_setting_method_picks_the_integrator(capsys):
    """--setting method=dopri5 runs the numerical integrator on the drill (its step count follows rtol), auto the
    exact propagator; both agree on the labels to the integrator's accuracy."""
    base = ["simulate", "drill", "--preset", "lab", "--json"]
    runs = {}
    for key, extra in (("tight", ["method=dopri5", "rtol=1e-10"]), ("loose", ["method=dopri5", "rtol=1e-6"]),
                       ("auto", [])):
        assert main(base + [a for x in extra for a in ("--setting", x)]) == 0
        runs[key] = json.loads(capsys.readouterr().out)
    assert runs["tight"]["n_steps"] > 2 * runs["loose"]["n_steps"]
    assert runs["auto"]["n_steps"] not in (runs["tight"]["n_steps"], runs["loose"]["n_steps"])
    assert runs["tight"]["rop_m_s"] == pytest.approx(runs["auto"]["rop_m_s"], rel=1e-7)


def test_simulate_plot(tmp_path, capsys):
    png = tmp_path / "plot.png"
    assert main(["simulate", "indenter-sandstone", "--preset", "table1-80hz", "--plot", str(png)]) == 0
    assert png.stat().st_size > 10_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, needle", [
    (["simulate", "nope"], "unknown model 'nope'"),
    (["simulate", "drill", "--set", "M1"], "expects name=value"),
    (["simulate", "drill", "--set", "M1=abc"], "'abc' is not a number"),
    (["simulate", "drill", "--set", "M1=-2"], "'M1' must be > 0"),
    (["simulate", "drill", "--set", "frequency_hz=0"], "'frequency_hz' must be > 0"),
    (["simulate", "drill", "--set", "K1=nan"], "--set K1: must be finite"),
    (["simulate", "drill", "--set", "zz=1"], "unknown parameter 'zz'"),
    (["simulate", "drill", "--preset", "bad"], "unknown preset 'bad'"),
    (["simulate", "drill", "--setting", "method=rk4"], "--setting method: must be one of auto, exact, dopri5"),
    (["simulate", "pendulum", "--setting", "method=exact"], "model 'pendulum' has no exact propagator"),
    (["compile", "nope"], "unknown model 'nope'"),
    (["diagnose", "no-such-dir", "--out", "/tmp/never-written", "--setting", "method=dopri5"],
     "diagnose setting 'method' is unknown"),
])
def test_bad_input_is_one_line_error(args, needle):
    p = run_cli(*args)
    assert p.returncode == 2
    assert needle in p.stderr
    assert "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def test_help_lists_subcommands_and_examples():
    p = run_cli("--help")
    assert p.returncode == 0 and "simulate" in p.stdout
    p = run_cli("simulate", "--help")
    assert p.returncode == 0 and "--plot" in p.stdout and "examples:" in p.stdout


def test_models_lists_parameters(capsys):
    assert main(["models", "drill"]) == 0
    out = capsys.readouterr().out
    assert "seed-003" in out and "Pr" in out and "tip_blunting" in out


def test_models_lists_a_candidates_parameters_only_where_the_model_offers_it(capsys):
    """The contact exponent and its reference penetration on the pendulum; neither on the sandstone, whose contact
    has its own exponents."""
    assert main(["models", "pendulum"]) == 0
    out = capsys.readouterr().out
    assert "contact_exponent_shift" in out and "contact_exponent_ref_m" in out
    assert main(["models", "indenter-sandstone"]) == 0
    out = capsys.readouterr().out
    assert "contact_exponent" not in out and "load_path_mode_hz" in out
    assert "contact_drift_m_s" not in out and "support_friction_v_eps_m_s" in out
    assert main(["models", "drill"]) == 0
    assert "support_friction" not in capsys.readouterr().out
