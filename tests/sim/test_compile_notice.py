"""The first compile of a kernel is announced on stderr (a first run must not sit silent for a minute), and only
then: not with numba's cache filled, not twice in a process, not under --quiet."""
from __future__ import annotations

import sys

import pytest

import sim
from sim import compile_notice
from sim.cachedir import jit_cache_dir
from sim.compiled import kernel_path

PY = f"py{sys.version_info[0]}{sys.version_info[1]}"


@pytest.fixture
def fresh(tmp_path, monkeypatch):
    """An empty kernel folder and a process that has printed nothing yet."""
    monkeypatch.setenv("VIBRO_KERNEL_DIR", str(tmp_path))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.delenv(compile_notice.QUIET_ENV, raising=False)
    monkeypatch.setattr(compile_notice, "_SEEN", set())
    monkeypatch.setattr(compile_notice, "_PRINTED", [])
    jit_cache_dir.cache_clear()
    yield tmp_path
    jit_cache_dir.cache_clear()


def _fake_index(folder, stem: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{stem}.run_point-540.{PY}.nbi").write_bytes(b"")


def test_announced_once_when_no_cache(fresh, capsys):
    spec = sim.get_model("pendulum")
    assert compile_notice.announce_compile(spec) is True
    assert "compiling the pendulum kernel" in capsys.readouterr().err
    assert compile_notice.announce_compile(spec) is False          # once per kernel and process
    assert compile_notice.announce_compile(sim.get_model("drill")) is False   # and once per process in all
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("where", ["jit", "pycache"])
def test_silent_with_numba_cache(fresh, capsys, where):
    """numba's index lives in ``jit-<digest>/<folder tag>/`` (the kernel header's cache folder); the notice used to
    look only in ``__pycache__`` and so printed on every run."""
    spec = sim.get_model("pendulum")
    path = kernel_path(spec.funcs)
    folder = jit_cache_dir() / "tmp_0123abcd" if where == "jit" else path.parent / "__pycache__"
    _fake_index(folder, path.stem)
    assert compile_notice.announce_compile(spec) is False and capsys.readouterr().err == ""


def test_index_of_another_kernel_does_not_count(fresh, capsys):
    spec = sim.get_model("pendulum")
    _fake_index(jit_cache_dir() / "tmp_0123abcd", kernel_path(sim.get_model("rimd").funcs).stem)
    assert compile_notice.announce_compile(spec) is True


def test_silent_under_quiet(fresh, capsys, monkeypatch):
    monkeypatch.setenv(compile_notice.QUIET_ENV, "1")
    assert compile_notice.announce_compile(sim.get_model("pendulum")) is False
    assert capsys.readouterr().err == ""


def test_quiet_flag_reaches_the_notice(monkeypatch):
    """``--quiet`` sets $VIBRO_QUIET for the command (worker processes inherit it) and restores it afterwards."""
    import os

    from pipeline.cli import main
    import pipeline.cli.synth as synth_cmd

    seen = {}
    monkeypatch.delenv(compile_notice.QUIET_ENV, raising=False)
    monkeypatch.setattr(synth_cmd, "run", lambda args: seen.setdefault("q", os.environ.get(compile_notice.QUIET_ENV)) and 0)
    main(["synth", "--out", "unused", "--quiet"])
    assert seen["q"] == "1" and compile_notice.QUIET_ENV not in os.environ


def test_exact_kernel_announced_in_a_fresh_process(tmp_path):
    """A fresh worker process announces the drill's exact kernel before anything imported ``sim.exact.drill``
    (make run failed at diagnose@drill-rig with KeyError 'sim.exact.drill' from the kernel's source hash)."""
    import os
    import subprocess

    code = ("import sys, sim; from sim import compile_notice; "
            "assert 'sim.exact.drill' not in sys.modules; "
            "print(compile_notice.announce_compile(sim.get_model('drill'), 'sim.exact.drill'))")
    env = {**os.environ, "VIBRO_KERNEL_DIR": str(tmp_path)}
    env.pop(compile_notice.QUIET_ENV, None)
    env.pop("NUMBA_CACHE_DIR", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True" and "compiling the drill kernel" in out.stderr


def test_silent_with_the_real_cache():
    """With the suite's filled kernel folder a second process prints nothing (needs the drill's exact kernel compiled
    by numba: the lab preset's batch runs on it)."""
    import os
    import subprocess

    code = ("import sim; from sim.compile_notice import is_cached; from sim.compiled import kernel_path; "
            "print(is_cached(kernel_path(sim.get_model('drill').funcs, 'sim.exact.drill')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ), timeout=120)
    assert out.returncode == 0, out.stderr
    if out.stdout.strip() != "True":
        pytest.skip("the drill's JIT kernel is not compiled in this kernel folder yet")
    code = "import sim; sim.simulate_batch('drill', [{}], preset='lab')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ), timeout=600)
    assert out.returncode == 0, out.stderr
    assert "compiling" not in out.stderr


def test_the_model_functions_the_kernel_calls_divide_the_ieee_way():
    """The model functions the kernel calls rather than inlines (sim/compiled.py's header) have the kernel's error
    model: x/0 is inf there as in the inlined step (caught by the finiteness check), never a ZeroDivisionError
    raised out of a GIL-free kernel."""
    from sim.compiled import kernels
    from sim.integrator import ERRORS

    spec = sim.get_model("drill")
    kernels(spec.funcs, spec.n_bounded)
    module = sys.modules[kernel_path(spec.funcs).stem]
    for name in ("rhs_once", "guards_once", "bounded", "on_event", "observe"):
        assert getattr(module, name).targetoptions.get("error_model") == ERRORS, name
