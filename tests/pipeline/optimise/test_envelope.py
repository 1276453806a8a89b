"""The shaker's envelope from the rig file: optimise honours it like the power and deceleration limits."""
from __future__ import annotations

import json

import pytest

from pipeline.cli import main as cli_main
from pipeline.core.errors import UserError
from pipeline.optimise.envelope import Envelope

RIG = "model: drill\npreset: lab\nexciter:\n{body}"
SPACE = ["--vary", "frequency_hz=200:350", "--vary", "amplitude_n=2000:2700", "--vary", "static_force_n=1500:1800"]


def _optimise(tmp_path, body: str, n_trials: int = 48) -> tuple[int, dict | None]:
    rig = tmp_path / "rig.yaml"
    rig.write_text(RIG.format(body=body))
    out = tmp_path / "o"
    rc = cli_main(["optimise", "--simulator", "--rig", str(rig), *SPACE, "--n-trials", str(n_trials), "--n-verify",
                   "2", "--storage", f"sqlite:///{tmp_path / 'optuna.db'}", "--out", str(out), "--no-mlflow",
                   "--quiet"])
    rep = json.loads((out / "report.json").read_text()) if (out / "report.json").exists() else None
    return rc, rep


def test_force_envelope_bounds_the_amplitude_and_the_answer_says_so(tmp_path, monkeypatch):
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    rc, rep = _optimise(tmp_path, "  max_force_n: {frequency_hz: [100, 450], amplitude_n: [2600, 2100]}\n")
    assert rc == 0
    rec = rep["recommendation"]
    f, a = rec["params"]["frequency_hz"], rec["params"]["amplitude_n"]
    lim = 2600 - 500 * (f - 100) / 350
    assert a <= lim * (1 + 1e-9)
    # ROP grows with F0 here, so the optimum sits on the envelope, below the box's 2700 N, and the answer says so
    assert a >= 0.98 * lim and rec["on_envelope"] and "ON THE SHAKER'S ENVELOPE" in rep["outcome"]
    assert rep["tried"]["constraints"]["envelope"]["max_force_n"]["amplitude_n"] == [2600.0, 2100.0]


def test_stroke_limit_is_met_by_the_simulated_recommendation(tmp_path, monkeypatch):
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    # the lab optimum (265 Hz, 2.7 kN, 1.8 kN) strokes 10 µm; below 200 Hz more
    rc, rep = _optimise(tmp_path, "  max_stroke_m: 9.0e-6\n", n_trials=40)
    assert rc == 0
    rec = rep["recommendation"]
    assert rec["stroke_m_sim"] <= 9.0e-6
    assert rec["params"]["frequency_hz"] > 270.0           # the limit moved the optimum up in frequency


@pytest.mark.parametrize("body, msg", [
    ("  max_force_n: {frequency_hz: [300, 100], amplitude_n: [2000, 2500]}\n", "must increase"),
    ("  max_force_n: {frequency_hz: [100, 450], amplitude_n: [2500]}\n", "same number"),
    ("  max_force: 2500\n", "unknown key(s) ['max_force']"),
    ("  max_stroke_m: -1\n", "max_stroke_m: must be > 0"),
    ("  max_force_n: {frequency_hz: [250, 300], amplitude_n: [2500, 2400]}\n", "declare the envelope over"),
])
def test_bad_envelope_is_one_line_exit_2(tmp_path, monkeypatch, capsys, body, msg):
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    rc, _ = _optimise(tmp_path, body)
    err = capsys.readouterr().err
    assert rc == 2 and msg in err and "Traceback" not in err and len(err.splitlines()) == 1


def test_envelope_values():
    env = Envelope.from_mapping({"max_force_n": {"frequency_hz": [100, 300], "amplitude_n": [3000, 2000]},
                                 "max_velocity_m_s": 0.5})
    assert env.max_force(200.0) == pytest.approx(2500.0) and env.max_force(50.0) == 3000.0
    v = env.values({"frequency_hz": 200.0, "amplitude_n": 2750.0, "coil_velocity_m_s": 0.4})
    assert v["exciter_force"] == pytest.approx(0.1) and v["exciter_velocity"] == pytest.approx(-0.2)
    assert env.values({"frequency_hz": 200.0, "amplitude_n": 2000.0})["exciter_velocity"] == 1.0   # missing label
    assert Envelope.from_mapping(None) is None
    with pytest.raises(UserError, match="expected a mapping"):
        Envelope.from_mapping([1, 2])
