"""Did-you-mean: a mistyped flag, subcommand, choice, model, preset, parameter, setting or file key is named with its
likely spelling in one line (one helper, ``vibrobase.errors.did_you_mean``), exit 2."""
from __future__ import annotations

import pytest

from pipeline.cli import main
from vibrobase.errors import did_you_mean


@pytest.mark.parametrize("word, choices, hint", [
    ("frequency", ("frequency_hz", "amplitude_n"), "frequency_hz"),
    ("freq", ("frequency_hz", "gap_m"), "frequency_hz"),
    ("k1", ("K1", "K2", "C1"), "K1"),
    ("--npoints", ("--n-points", "--seed", "--out"), "--n-points"),
    ("simulat", ("simulate", "sweep"), "simulate"),
    ("parameter", ("model", "preset", "parameters"), "parameters"),
    ("zz", ("K1", "frequency_hz"), None),
])
def test_did_you_mean(word, choices, hint):
    assert did_you_mean(word, choices) == ("" if hint is None else f" (did you mean {hint}?)")


def _error_line(capsys, argv) -> str:
    """The one stderr line of a command that exits 2 (argparse's SystemExit or the command's return code)."""
    try:
        rc = main(argv)
    except SystemExit as e:
        rc = e.code
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("argv, needle", [
    (["sweep", "--npoints", "64"], "vibro sweep: error: unknown option --npoints (did you mean --n-points?)"),
    (["simulate", "drill", "--prest", "lab"], "unknown option --prest (did you mean --preset?)"),
    (["simulat", "drill"], "invalid choice 'simulat' (did you mean simulate?)"),
    (["sweep", "--design", "sobl"], "invalid choice 'sobl' (did you mean sobol?)"),
    (["simulate", "dril"], "unknown model 'dril' (did you mean drill?)"),
    (["simulate", "drill", "--preset", "lb"], "unknown preset 'lb' for model 'drill' (did you mean lab?)"),
    (["simulate", "drill", "--set", "frequency=300"], "unknown parameter 'frequency' for model 'drill' "
                                                        "(did you mean frequency_hz?)"),
    (["simulate", "drill", "--setting", "windw=8"], "(did you mean window?)"),
    (["sweep", "--vary", "frequency=100:300", "--dry-run"], "unknown parameter 'frequency' for model 'drill' "
                                                              "(did you mean frequency_hz?)"),
    (["sweep", "--set", "k1=1e8", "--dry-run"], "unknown parameter 'k1' for model 'drill' (did you mean K1?)"),
    (["optimise", "--simulator", "--vary", "frequency=100:300", "--no-mlflow", "--out", "/tmp/never-written"],
     "unknown parameter 'frequency' (did you mean frequency_hz?)"),
    (["map", "drill", "--x", "freq", "--y", "amplitude_n"], "(did you mean frequency_hz?)"),
])
def test_a_typo_is_named_with_its_likely_spelling(capsys, argv, needle):
    assert needle in _error_line(capsys, argv)


@pytest.mark.parametrize("text, needle", [
    ("model: drill\nparameter: {K1: 1.0e8}\n", "unknown key 'parameter' (did you mean parameters?)"),
    ("model: dril\n", "unknown model 'dril' (did you mean drill?)"),
    ("model: drill\nparameters: {k1: 1.0e8}\n", "unknown parameter 'k1' for model 'drill' (did you mean K1?)"),
    ("model: drill\neffects: {shaker_coli: {tau: 1.0e-4}}\n", "(did you mean shaker_coil?)"),
    ("model: drill\neffects: {shaker_coil: {tau: 1.0e-4, betta: 3.0e3}}\n", "(did you mean beta?)"),
])
def test_a_rig_file_typo_is_named(tmp_path, capsys, text, needle):
    rig = tmp_path / "rig.yaml"
    rig.write_text(text)
    assert needle in _error_line(capsys, ["simulate", "--rig", str(rig)])


def test_the_surrogate_study_names_a_mistyped_range_before_its_training_ranges():
    """`optimise --vary frequency=...` on a surrogate: the unknown name first, not "leave the training ranges {}"."""
    from types import SimpleNamespace

    from pipeline.core.errors import UserError
    from pipeline.optimise.config import OptimiseConfig
    from pipeline.optimise.samplers import tpe_sampler
    from pipeline.optimise.strategies import surrogate_strategies

    bundle = SimpleNamespace(model="drill", preset="lab", fixed={}, inputs=["frequency_hz"],
                             ranges={"frequency_hz": (100.0, 450.0)}, settings=None)
    cfg = OptimiseConfig.from_mapping({"ranges": {"frequency": [100.0, 300.0]}})
    with pytest.raises(UserError, match=r"unknown parameter 'frequency' \(did you mean frequency_hz\?\)"):
        surrogate_strategies(cfg, bundle, tpe_sampler)
