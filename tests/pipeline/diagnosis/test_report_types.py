"""report.json as typed records: ``DiagnoseReport.from_json`` then ``to_json`` gives the file back, key for key and
in order, with its schema version added; a newer schema is refused."""
from __future__ import annotations

import json
from dataclasses import FrozenInstanceError
from pathlib import Path

import pytest

from pipeline.core.errors import UserError
from pipeline.diagnosis.report_types import SCHEMA, SCHEMA_KEY, DiagnoseReport

DATA = Path(__file__).parent / "data"
FIXTURES = sorted(DATA.glob("report_*.json"))
STORED = sorted((Path(__file__).resolve().parents[3] / "bench" / "results" / "identification" / "diagnoses")
                .glob("*/report.json"))
"""The identification matrix's diagnoses, where this machine has them (gitignored)."""


@pytest.mark.parametrize("path", FIXTURES + STORED, ids=lambda p: p.parent.name if p in STORED else p.stem)
def test_round_trip_gives_the_file_back(path):
    d = json.loads(path.read_text())
    out = DiagnoseReport.from_json(d, str(path)).to_json()
    assert json.dumps(out) == json.dumps({SCHEMA_KEY: SCHEMA, **d})      # same keys, same order, same values
    again = DiagnoseReport.from_json(out)
    assert again.to_json() == out


def test_fixtures_cover_each_shape():
    reps = {p.stem: DiagnoseReport.from_json(json.loads(p.read_text())) for p in FIXTURES}
    assert len(reps["report_systems"].systems) == 2
    pair = reps["report_pair"].systems[0]
    assert pair.selected == ("shaker_coil", "guide_friction")
    assert pair.second_effect.candidates[0].effects == ("shaker_coil", "guide_friction")
    disc = reps["report_discrepancy"].systems[0]
    assert not disc.explained and disc.discrepancy.proposals[0].terms
    single = reps["report_single"].systems[0]
    assert single.candidates[0].effects == (single.candidates[0].to_json()["effect"],)
    assert single.errors.final.nrms == json.loads((DATA / "report_single.json").read_text())["final_nrms"]
    with pytest.raises(FrozenInstanceError):
        single.verdict = "x"


def test_a_newer_schema_is_refused():
    d = {**json.loads((DATA / "report_single.json").read_text()), SCHEMA_KEY: SCHEMA + 1}
    with pytest.raises(UserError, match=r"somewhere/report\.json.*schema 2"):
        DiagnoseReport.from_json(d, "somewhere/report.json")


def test_an_older_layout_is_refused_in_one_line():
    """A report.json from before a field existed (here ``pair_stage``) names the file and the missing key."""
    d = json.loads((DATA / "report_single.json").read_text())
    for s in d["systems"].values():
        del s["pair_stage"]
    with pytest.raises(UserError, match=r"old/report\.json: not a diagnosis report this version reads \(no 'pair_stage'\)"):
        DiagnoseReport.from_json(d, "old/report.json")
