"""The first compile of a kernel is announced on stderr (a first run must not sit silent for a minute)."""
from __future__ import annotations

import sim
from sim import compile_notice
from sim.compiled import kernel_path


def test_announced_once_when_no_cache_and_silent_with_one(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("VIBRO_KERNEL_DIR", str(tmp_path))
    monkeypatch.setattr(compile_notice, "_SEEN", set())
    spec = sim.get_model("pendulum")
    assert compile_notice.announce_compile(spec) is True
    assert "compiling the pendulum kernel" in capsys.readouterr().err
    assert compile_notice.announce_compile(spec) is False          # once per kernel and process
    monkeypatch.setattr(compile_notice, "_SEEN", set())
    path = kernel_path(spec.funcs)
    stem, folder = path.stem, path.parent
    (folder / "__pycache__").mkdir()
    (folder / "__pycache__" / f"{stem}.run_point-1.py311.nbi").write_bytes(b"")   # numba's cache index
    assert compile_notice.announce_compile(spec) is False and capsys.readouterr().err == ""
