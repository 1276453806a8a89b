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


def test_exact_kernel_announced_in_a_fresh_process(tmp_path):
    """A fresh worker process announces the drill's exact kernel before anything imported ``sim.exact.drill``
    (make run failed at diagnose@drill-rig with KeyError 'sim.exact.drill' from the kernel's source hash)."""
    import os
    import subprocess
    import sys

    code = ("import sys, sim; from sim import compile_notice; "
            "assert 'sim.exact.drill' not in sys.modules; "
            "print(compile_notice.announce_compile(sim.get_model('drill'), 'sim.exact.drill'))")
    env = {**os.environ, "VIBRO_KERNEL_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True" and "compiling the drill kernel" in out.stderr
