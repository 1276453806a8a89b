"""``vibro import``: a mapping and a rig file in, a §7 dataset out; bad input is exit 2 with one line and nothing
written; the help carries an example mapping."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml

from pipeline.cli import build_parser, main
from pipeline.core.outdir import MARKER_NAME

FS = 5000.0
N = 200


def _rig(tmp_path, force_header="force [kN]", system="indenter-metal"):
    t = np.arange(N) / FS
    pd.DataFrame({"time [ms]": 1e3 * t, "accel [g]": np.sin(2 * np.pi * 50 * t),
                  force_header: 0.3 + 0.2 * np.sin(2 * np.pi * 50 * t)}).to_csv(tmp_path / "log.csv", index=False)
    doc = {"file": "log.csv", "time": {"channel": "time"},
           "channels": {"accel_m_s2": "accel", "force_n": "force"},
           "runs": [{"run_id": "m1", "system": system, "frequency_hz": 50, "amplitude_n": "0.2 kN",
                     "static_force_n": 300, "gap_m": "1 mm"}]}
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(doc))
    return tmp_path / "map.yaml"


def test_import_writes_a_dataset(tmp_path, capsys):
    mapping = _rig(tmp_path)
    out = tmp_path / "ds"
    assert main(["import", str(mapping), "--out", str(out)]) == 0
    assert (out / MARKER_NAME).exists()
    runs = pd.read_csv(out / "runs.csv")
    assert runs.loc[0, "gap_m"] == pytest.approx(1e-3) and runs.loc[0, "amplitude_n"] == pytest.approx(200.0)
    s = pd.read_csv(out / "series" / "m1.csv")
    assert list(s.columns) == ["t_s", "accel_m_s2", "force_n"]
    assert s["force_n"].max() == pytest.approx(500.0, rel=1e-3)
    err = capsys.readouterr().err
    assert "force_n <- force [kN] x 1000" in err and "accel_m_s2 <- accel [g] x 9.81" in err
    # a second import into its own output needs --overwrite, then replaces it
    assert main(["import", str(mapping), "--out", str(out)]) == 2
    assert main(["import", str(mapping), "--out", str(out), "--overwrite"]) == 0


@pytest.mark.parametrize(("kw", "expect"), [
    ({"force_header": "force [furlongs]"},
     "log.csv, channel 'force' (force_n), unit from the file: unknown unit 'furlongs' (force units: N, kN"),
    ({"force_header": "force"}, "log.csv, channel 'force' (force_n): no unit"),
    ({"system": "indentor-metal"}, "§7 check: runs.csv line 2, column 'system': unknown system 'indentor-metal'"),
])
def test_bad_input_is_one_line_and_nothing_written(tmp_path, capsys, kw, expect):
    mapping = _rig(tmp_path, **kw)
    out = tmp_path / "ds"
    assert main(["import", str(mapping), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expect in err, err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv", "map.yaml"]


def test_bad_yaml_and_missing_mapping(tmp_path, capsys):
    (tmp_path / "map.yaml").write_text("runs: [\n")
    assert main(["import", str(tmp_path / "map.yaml"), "--out", str(tmp_path / "o")]) == 2
    assert main(["import", str(tmp_path / "none.yaml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert "not valid YAML" in err[0] and "none.yaml not found" in err[1]


def test_help_has_an_example_mapping():
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices["import"]
    text = sub.format_help()
    for word in ("channels:", "accel_m_s2: {channel: Accel, unit: g}", "rate_hz", "{property:", "run_defaults",
                 "unit_string", "docs/import.md"):
        assert word in text, word


def _yaml_block(text: str, first: str) -> dict:
    """The YAML example starting at the line ``first`` up to the next blank line or fence, dedented."""
    import textwrap

    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.strip().startswith(first))
    block = []
    for ln in lines[i:]:
        if not ln.strip() or ln.startswith("```"):
            break
        block.append(ln)
    return yaml.safe_load(textwrap.dedent("\n".join(block)))


@pytest.mark.parametrize("where", ["help", "docs"])
def test_example_mappings_parse(tmp_path, where):
    from pathlib import Path

    from pipeline.cli.import_ import EPILOG
    from pipeline.datasets.fieldformats import parse_mapping

    text = EPILOG if where == "help" else (Path(__file__).resolve().parents[3] / "docs" / "import.md").read_text()
    doc = _yaml_block(text, "file: rig")
    m = parse_mapping(doc, "example", tmp_path)
    assert m.runs and {c.signal for c in m.runs[0].channels} >= {"accel_m_s2", "force_n"}


def test_out_holding_the_rig_file_is_refused(tmp_path, capsys):
    mapping = _rig(tmp_path)
    assert main(["import", str(mapping), "--out", str(tmp_path)]) == 2
    assert "choose an --out apart from the inputs" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv", "map.yaml"]
