"""pipeline.core.outdir.prepare_out: an --out folder never costs the user a file."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys


import pytest

from pipeline.core.errors import UserError
from pipeline.core.outdir import MARKER_NAME, check_out, prepare_out, read_marker


def _write(tmp, files: dict[str, str]) -> None:
    for rel, text in files.items():
        (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp / rel).write_text(text)


def _tree(root) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_fresh_out_is_swapped_in_with_marker(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with prepare_out(out, marker="report") as tmp:
        assert tmp.parent == out.parent and tmp.name.startswith(".out.") and tmp.name.endswith(".tmp") and not out.exists()
        _write(tmp, {"report.md": "x", "figures/f.png": "png"})
    assert _tree(out).keys() == {"report.md", "figures/f.png", MARKER_NAME}
    mk = read_marker(out)
    assert mk["command"] == "report" and mk["files"] == ["figures/f.png", "report.md"]
    assert [p.name for p in out.parent.iterdir()] == ["out"]          # no temp sibling left


def test_failure_leaves_nothing_behind_not_even_parents(tmp_path):
    out = tmp_path / "new1" / "new2" / "out"
    with pytest.raises(RuntimeError):
        with prepare_out(out, marker="diagnose") as tmp:
            _write(tmp, {"half.csv": "1,2"})
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_keyboard_interrupt_leaves_existing_output_untouched(tmp_path):
    out = tmp_path / "out"
    with prepare_out(out, marker="synth") as tmp:
        _write(tmp, {"data.csv": "old"})
    before = _tree(out)
    with pytest.raises(KeyboardInterrupt):
        with prepare_out(out, overwrite=True, marker="synth") as tmp:
            _write(tmp, {"data.csv": "new"})
            raise KeyboardInterrupt
    assert _tree(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_user_files_are_refused_and_kept(tmp_path):
    """Issue 15: `diagnose --out DIR` on a folder holding files deleted them and exited 0."""
    out = tmp_path / "mine"
    _write(out, {"thesis.tex": "years of work"})
    for overwrite in (False, True):
        with pytest.raises(UserError, match=r"holds files 'vibro diagnose' did not write \(first: thesis.tex\)"):
            with prepare_out(out, overwrite=overwrite, marker="diagnose"):
                pytest.fail("must not be entered")
    assert _tree(out) == {"thesis.tex": b"years of work"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]


def test_empty_existing_folder_is_accepted(tmp_path):
    out = tmp_path / "empty"
    out.mkdir()
    with prepare_out(out, marker="report") as tmp:
        _write(tmp, {"r.md": "r"})
    assert set(_tree(out)) == {"r.md", MARKER_NAME}


def test_own_previous_output_needs_overwrite_and_is_replaced(tmp_path):
    out = tmp_path / "out"
    with prepare_out(out, marker="report") as tmp:
        _write(tmp, {"old.md": "1", "figures/a.png": "a"})
    with pytest.raises(UserError, match="previous 'vibro report' output; add --overwrite"):
        with prepare_out(out, marker="report"):
            pass
    with prepare_out(out, overwrite=True, marker="report") as tmp:
        _write(tmp, {"new.md": "2"})
    assert set(_tree(out)) == {"new.md", MARKER_NAME}             # old.md, figures/ were its own: replaced
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # the .old copy is gone


def test_overwrite_refuses_a_file_the_user_added_to_an_old_output(tmp_path):
    out = tmp_path / "out"
    with prepare_out(out, marker="report") as tmp:
        _write(tmp, {"report.md": "r"})
    _write(out, {"figures/annotated.png": "user's"})
    with pytest.raises(UserError, match=r"did not write \(first: figures/annotated.png\)"):
        with prepare_out(out, overwrite=True, marker="report"):
            pass
    assert (out / "figures" / "annotated.png").read_text() == "user's"


def test_another_commands_output_is_refused(tmp_path):
    out = tmp_path / "out"
    with prepare_out(out, marker="synth") as tmp:
        _write(tmp, {"x": "1"})
    with pytest.raises(UserError, match="output of 'vibro synth', not of 'vibro report'"):
        check_out(out, overwrite=True, marker="report")


@pytest.mark.parametrize("rel_out, why", [
    ("data", "is the input"),                 # --out the dataset itself
    (".", "contains the input"),              # --out its parent (the case)
    ("data/sub", "lies inside the input"),
])
def test_out_overlapping_an_input_is_refused_even_with_overwrite(tmp_path, rel_out, why):
    data = tmp_path / "data"
    _write(data, {"runs.csv": "t,a\n0,1\n"})
    before = _tree(tmp_path)
    cwd = os.getcwd()
    os.chdir(tmp_path)                        # relative paths must be compared resolved
    try:
        with pytest.raises(UserError, match=why):
            with prepare_out(rel_out, inputs=["data"], overwrite=True, marker="diagnose"):
                pass
    finally:
        os.chdir(cwd)
    assert _tree(tmp_path) == before


def test_out_that_is_a_file_is_refused(tmp_path):
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(UserError, match="not a directory"):
        check_out(f, marker="report")


def test_a_file_appearing_in_out_during_the_run_is_not_deleted(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(UserError, match="did not write"):
        with prepare_out(out, marker="report") as tmp:
            _write(tmp, {"r.md": "r"})
            _write(out, {"someone_else.txt": "meanwhile"})
    assert _tree(out) == {"someone_else.txt": b"meanwhile"}


def test_sigkill_mid_write_leaves_out_intact(tmp_path):
    """kill -9 while writing: the old output is whole; only a hidden .tmp sibling may remain."""
    out = tmp_path / "out"
    with prepare_out(out, marker="report") as tmp:
        _write(tmp, {"r.md": "old"})
    code = (f"import time; from pipeline.core.outdir import prepare_out\n"
            f"with prepare_out({str(out)!r}, overwrite=True, marker='report') as t:\n"
            f"    (t / 'r.md').write_text('new'); print('ready', flush=True); time.sleep(60)\n")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                         env={**os.environ, "PYTHONPATH": os.getcwd()})
    assert p.stdout.readline().strip() == "ready"
    p.send_signal(signal.SIGKILL)
    p.wait(10)
    assert (out / "r.md").read_text() == "old" and json.loads((out / MARKER_NAME).read_text())["command"] == "report"
    leftovers = [q.name for q in tmp_path.iterdir() if q.name != "out"]
    assert all(n.startswith(".out.") and n.endswith(".tmp") for n in leftovers)
