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
