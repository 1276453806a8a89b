"""One command-line vocabulary (pipeline/cli/args.py): the same flag for the same idea in every subcommand,
old spellings as aliases, --version, 'vibro models MODEL', and --rig FILE on every simulating command."""
from __future__ import annotations

from pathlib import Path

import pytest

import sim
from pipeline.cli import build_parser, main

SIMULATING = ("simulate", "sweep", "map", "optimise", "verify", "train")
# subcommand -> (minimal positional arguments, flags that must parse to the same destination)
ALIASES = {
    "sweep": ([], [("--set", "--fix", "sets", ["a=1"]), ("--workers", "--threads", "workers", 2),
                   ("--quiet", "--no-progress", "quiet", True)]),
    "optimise": ([], [("--set", "--fixed", "sets", ["a=1"]), ("--vary", "--range", "ranges", ["a=1:2"]),
                      ("--workers", "--threads", "n_threads", 2), ("--quiet", "--no-progress", "quiet", True)]),
    "verify": (["p.csv"], [("--set", "--fixed", "sets", ["a=1"]), ("--workers", "--threads", "n_threads", 2),
                           ("--quiet", "--no-progress", "quiet", True)]),
    "map": (["drill", "--x", "frequency_hz"], [("--workers", "--threads", "threads", 2),
                                               ("--quiet", "--no-progress", "quiet", True)]),
    "train": (["data"], [("--workers", "--threads", "workers", 2), ("--quiet", "--no-progress", "quiet", True)]),
    "diagnose": (["data", "--out", "o"], [("--setting", "--set", "sets", ["max_nfev=3"]),
                                          ("--workers", "--threads", "threads", 2)]),
    "synth": (["--out", "o"], [("--workers", "--threads", "threads", 2)]),
}


def _value(v) -> list[str]:
    if v is True:
        return []
    return [str(x) for x in v] if isinstance(v, list) else [str(v)]


@pytest.mark.parametrize("command", sorted(ALIASES))
def test_new_flag_and_old_alias_mean_the_same(command):
    parser = build_parser()
    pos, pairs = ALIASES[command]
    for new, old, dest, value in pairs:
        a = parser.parse_args([command, *pos, new, *_value(value)])
        b = parser.parse_args([command, *pos, old, *_value(value)])
        assert getattr(a, dest) == getattr(b, dest) == value, (command, new, old)


@pytest.mark.parametrize("command", SIMULATING)
def test_every_simulating_command_takes_a_rig_file(command):
    pos = {"verify": ["p.csv"], "train": ["data"], "map": ["--x", "frequency_hz"]}.get(command, [])
    args = build_parser().parse_args([command, *pos, "--rig", "my-rig.yaml"])
    assert args.rig == "my-rig.yaml"


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith("vibro ") and out.split()[1][0].isdigit()


def test_models_model_shows_every_preset_value_and_the_spec_tables(capsys):
    spec = sim.get_model("drill")
    assert main(["models", "drill"]) == 0
    out = capsys.readouterr().out
    header = next(line for line in out.splitlines() if line.strip().startswith("parameter"))
    assert all(p in header for p in spec.presets)
    k1 = next(line for line in out.splitlines() if line.split()[:1] == ["K1"])
    for values in spec.presets.values():          # each preset's K1 appears in the K1 row
        if "K1" in values:
            assert f"{values['K1']:g}" in k1.split()
    assert "calibratable" in out and "search spaces" in out and "fit bounds" in out
    for b in spec.calibratable:
        assert f"[{b.lo:g} .. {b.hi:g}]" in out


def test_models_unknown_model_is_one_line(capsys):
    assert main(["models", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown model 'nope'" in err and len(err.strip().splitlines()) == 1


def _rig(tmp_path: Path, text: str) -> str:
    p = tmp_path / "rig.yaml"
    p.write_text(text)
    return str(p)


RIG = """model: drill
preset: lab
parameters: {K1: 5.0e8}
effects:
  guide_friction: {mu: 50.0}
source: test rig
"""


def test_simulate_rig_equals_preset_plus_sets(tmp_path, capsys):
    rig = _rig(tmp_path, RIG)
    assert main(["simulate", "--rig", rig, "--set", "frequency_hz=250", "--json"]) == 0
    a = capsys.readouterr().out
    assert main(["simulate", "drill", "--preset", "lab", "--set", "K1=5e8", "--set", "mu=50",
                 "--set", "frequency_hz=250", "--json"]) == 0
    b = capsys.readouterr().out
    assert a == b
    assert main(["simulate", "--rig", rig, "--set", "frequency_hz=250", "--set", "mu=0", "--json"]) == 0
    assert capsys.readouterr().out != a           # --set overrides the rig (friction off changes ROP)


@pytest.mark.parametrize("text,needle", [
    ("model: drill\ncolour: red\n", "unknown key 'colour'"),
    ("model: drill\nparameters: {K9: 1.0}\n", "unknown parameter 'K9'"),
    ("model: drill\neffects: {mount_resonance: {fr_hz: 300.0}}\n", "unknown effect 'mount_resonance'"),
    ("model: drill\npreset: nope\n", "nope"),
])
def test_bad_rig_file_is_one_line_naming_the_culprit(tmp_path, capsys, text, needle):
    rig = _rig(tmp_path, text)
    for argv in (["simulate", "--rig", rig], ["sweep", "--rig", rig, "--out", str(tmp_path / "s"), "--dry-run"],
                 ["map", "--rig", rig, "--x", "frequency_hz", "--no-mlflow"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert needle in err and rig in err and len(err.strip().splitlines()) == 1, (argv, err)


def test_rig_model_mismatch_is_refused(tmp_path, capsys):
    assert main(["simulate", "pendulum", "--rig", _rig(tmp_path, RIG)]) == 2
    assert "describes model 'drill'" in capsys.readouterr().err


def test_sweep_rig_sets_model_preset_and_fixed(tmp_path, capsys):
    from pipeline.cli.sweep import spec_from_args

    rig = _rig(tmp_path, RIG)
    args = build_parser().parse_args(["sweep", "--rig", rig, "--set", "K1=4e8", "--out", str(tmp_path / "s")])
    spec, _, _ = spec_from_args(args)
    assert spec.model == "drill" and spec.preset == "lab"
    assert spec.fixed["mu"] == 50.0 and spec.fixed["K1"] == 4e8      # --set over the rig


def test_sweep_params_section_rig_key(tmp_path):
    from pipeline.cli.sweep import spec_from_args

    rig = _rig(tmp_path, RIG)
    params = tmp_path / "params.yaml"
    params.write_text(f"sweep:\n  rig: {rig}\n  fixed: {{K1: 3.0e8}}\n  n_points: 8\n"
                      "  vary: {frequency_hz: {low: 100.0, high: 200.0}}\n")
    spec, _, _ = spec_from_args(build_parser().parse_args(["sweep", "--params", str(params)]))
    assert spec.model == "drill" and spec.fixed["K1"] == 3.0e8 and spec.fixed["mu"] == 50.0


def test_optimise_rig_needs_simulator_and_sets_the_config(tmp_path, capsys):
    from pipeline.cli.optimise import config_from_args

    rig = _rig(tmp_path, RIG)
    assert main(["optimise", "--rig", rig, "--out", str(tmp_path / "o"), "--no-mlflow"]) == 2
    assert "--rig" in capsys.readouterr().err
    cfg = config_from_args(build_parser().parse_args(["optimise", "--simulator", "--rig", rig, "--set", "mu=10"]))
    assert cfg.model == "drill" and cfg.preset == "lab" and cfg.fixed["K1"] == 5e8 and cfg.fixed["mu"] == 10.0


def test_optimise_feedback_never_goes_into_the_surrogate_folder(tmp_path, capsys):
    from pipeline.cli.optimise import DEFAULT_FEEDBACK, config_from_args
    from pipeline.tracking.runs import project_root

    sur = tmp_path / "models" / "surrogate"
    sur.mkdir(parents=True)
    cfg = config_from_args(build_parser().parse_args(["optimise", "--surrogate", str(sur)]))
    assert cfg.feedback == str(project_root() / DEFAULT_FEEDBACK)       # beside optuna.db, whatever the cwd
    assert not Path(DEFAULT_FEEDBACK).is_relative_to("models")
    assert main(["optimise", "--surrogate", str(sur), "--feedback", str(sur / "feedback.parquet"),
                 "--no-mlflow"]) == 2
    assert "inside the surrogate folder" in capsys.readouterr().err


def test_verify_rig_and_surrogate_together_is_refused(tmp_path, capsys):
    pts = tmp_path / "p.csv"
    pts.write_text("frequency_hz,amplitude_n,static_force_n,rop_m_s\n250,2250,1200,0.001\n")
    assert main(["verify", str(pts), "--rig", _rig(tmp_path, RIG), "--surrogate", str(tmp_path)]) == 2
    assert "carries the rig" in capsys.readouterr().err


def test_map_axis_with_range():
    from pipeline.cli.map import _axis
    from pipeline.core.errors import UserError

    assert _axis("gap_m=0:0.003", None, "--y") == ("gap_m", (0.0, 0.003))
    assert _axis("gap_m", [1.0, 2.0], "--y") == ("gap_m", (1.0, 2.0))       # older --y-range
    assert _axis("gap_m", None, "--y") == ("gap_m", (None, None))
    with pytest.raises(UserError, match="--y expects PARAM or PARAM=LO:HI"):
        _axis("gap_m=1", None, "--y")


def test_the_repos_params_yaml_serves_both_optimise_stages():
    """dvc.yaml runs `vibro optimise --params params.yaml --objective rop` and `... pareto` on one section: its
    `objectives` are the Pareto study's, and the ROP stage must not refuse them (make run once stopped there)."""
    from pipeline.cli.optimise import config_from_args
    from pipeline.core.params import read_section

    params = Path(__file__).resolve().parents[3] / "params.yaml"
    assert read_section(str(params), "optimise").get("objectives")       # the case this test is about
    base = ["optimise", "--params", str(params), "--simulator"]
    rop = config_from_args(build_parser().parse_args([*base, "--objective", "rop"]))
    assert rop.objective_list() == [("rop_m_s", "maximize")]
    pareto = config_from_args(build_parser().parse_args([*base, "--objective", "pareto"]))
    assert [name for name, _ in pareto.objective_list()] == read_section(str(params), "optimise")["objectives"]
