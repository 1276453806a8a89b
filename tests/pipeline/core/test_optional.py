"""Optional packages guarded once (pipeline.core.optional): a missing one says what to install, and the CLI
reports it as one line (exit 2)."""
from __future__ import annotations

import sys

import pytest

from pipeline.core.errors import USER_ERRORS
from pipeline.core.optional import MissingPackage, try_import


def test_missing_package_names_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "nptdms", None)          # import of it now fails as if not installed
    with pytest.raises(MissingPackage, match=r"reading TDMS files needs the Python package npTDMS \(pip install npTDMS\)"):
        try_import("nptdms", package="npTDMS", feature="reading TDMS files")
    assert MissingPackage in USER_ERRORS


def test_present_package_is_returned():
    assert try_import("json", package="json", feature="x").dumps([1]) == "[1]"


def test_import_without_nptdms_is_one_line(tmp_path, monkeypatch, capsys):
    from pipeline.cli import main

    (tmp_path / "rig.tdms").write_bytes(b"TDSm")
    (tmp_path / "map.yaml").write_text("file: rig.tdms\nchannels: {accel_m_s2: g/a}\n"
                                       "runs: [{run_id: r0, system: drill}]\n")
    monkeypatch.setitem(sys.modules, "nptdms", None)
    assert main(["import", str(tmp_path / "map.yaml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("needs the Python package npTDMS (pip install npTDMS)") and "\n" not in err
    assert not (tmp_path / "o").exists()
