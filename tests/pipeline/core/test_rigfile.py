"""Rig files round-trip and refuse bad content with one line naming the file."""
from __future__ import annotations

import pytest

from pipeline.core.errors import UserError
from pipeline.core.rigfile import read_rig, write_rig
from sim import Rig


def test_round_trip(tmp_path):
    rig = Rig.from_mapping({"model": "drill", "preset": "lab", "parameters": {"K1": 5.2e8},
                            "effects": {"shaker_coil": {"tau": 1e-4, "beta": 3000.0}},
                            "uncertainty": {"K1": 2e7}, "source": "unit test"})
    path = write_rig(tmp_path / "rig.yaml", rig, comment="made by a test")
    text = path.read_text()
    assert text.startswith("# vibro rig file") and "# made by a test" in text
    assert read_rig(path) == rig


@pytest.mark.parametrize("text, culprit", [
    ("model: drill\npreset: nope\n", "unknown preset 'nope'"),
    ("model: drill\nparameters: {K7: 1}\n", "unknown parameter 'K7'"),
    ("model: drill\neffects: {coil: {tau: 1}}\n", "unknown effect 'coil'"),
    ("model: drill\nspeed: 3\n", "unknown key 'speed'"),
    ("model: drill\nmodel_error: {rop_rel: much}\n", "model_error rop_rel"),
    ("model: drill\nmodel_error: {rop_rel: -0.1}\n", "model_error rop_rel must be a finite number >= 0"),
    ("model: drill\nmodel_error: {rop_rel: 0.1, sd: 2}\n", "unknown model_error key 'sd'"),
    ("model: [drill\n", "not valid YAML"),
    ("- 1\n- 2\n", "expected a mapping"),
])
def test_bad_rig_file(tmp_path, text, culprit):
    p = tmp_path / "rig.yaml"
    p.write_text(text)
    with pytest.raises(UserError) as e:
        read_rig(p)
    assert str(p) in str(e.value) and culprit in str(e.value) and "\n" not in str(e.value)


def test_missing_rig_file(tmp_path):
    with pytest.raises(UserError, match="not found"):
        read_rig(tmp_path / "none.yaml")


def test_exponent_without_sign_or_dot_is_a_number(tmp_path):
    """PyYAML's YAML 1.1 rules read '5.0e8' and '5e8' as strings; a rig file means numbers."""
    from pipeline.core.rigfile import read_rig

    p = tmp_path / "rig.yaml"
    p.write_text("model: drill\npreset: lab\nparameters: {K1: 5.0e8, C1: 4e5, K2: 7.58e+07}\n")
    rig = read_rig(p)
    assert rig.parameters == {"K1": 5.0e8, "C1": 4.0e5, "K2": 7.58e7}
    assert all(isinstance(v, float) for v in rig.parameters.values())


OLD_RIG_FILE = """\
# vibro rig file (README.md "Rig files"): the model, its preset, parameter values overriding the preset [SI],
# the MODELS.md §6 effects that are on with their parameters, standard deviations of fitted values, and the source.
# the corrected rig of this diagnosis (report.json 'rig')
model: drill
preset: lab
parameters:
  K1: 622910000.0
  Pr: 3635.38
effects:
  shaker_coil:
    tau: 9.9967e-05
    beta: 2999.9
uncertainty:
  K1: 82000.0
  Pr: 0.09
source: 'vibro diagnose measured/drill-rig (drill): explained with shaker_coil'
"""


def test_a_rig_file_from_before_model_error_loads_unchanged(tmp_path):
    p = tmp_path / "rig.yaml"
    p.write_text(OLD_RIG_FILE)
    rig = read_rig(p)
    assert rig.model_error is None and rig.parameters == {"K1": 6.2291e8, "Pr": 3635.38}
    assert rig.effects == {"shaker_coil": {"tau": 9.9967e-5, "beta": 2999.9}} and rig.uncertainty["Pr"] == 0.09
    body = [ln for ln in write_rig(tmp_path / "again.yaml", rig).read_text().splitlines() if not ln.startswith("#")]
    assert body == [ln for ln in OLD_RIG_FILE.splitlines() if not ln.startswith("#")]     # written back as it was


def test_model_error_round_trips_through_the_file_and_keeps_with_preset(tmp_path):
    from pipeline.cli.args import load_rig
    from sim import ModelError

    rig = Rig("drill", "lab", {"K1": 5.2e8}, uncertainty={"K1": 2e7},
              model_error=ModelError(0.042, 0.011, "held-out rms ROP error over 3 runs"))
    path = write_rig(tmp_path / "rig.yaml", rig)
    assert read_rig(path) == rig
    assert "rop_rel: 0.042" in path.read_text()
    p = tmp_path / "exp.yaml"
    p.write_text("model: drill\nmodel_error: {rop_rel: 4e-2}\n")            # read as a number, as everywhere
    assert read_rig(p).model_error.rop_rel == 0.04
    p.write_text("model: drill\nmodel_error: {rop_rel: '4e-2'}\n")          # quoted text is refused
    with pytest.raises(UserError, match="model_error rop_rel"):
        read_rig(p)
    assert load_rig(str(path), preset="none").model_error == rig.model_error   # --preset keeps it
