"""Ahead-of-time kernels (sim/aot.py) and the lazy ``njit`` (sim/jit.py) that lets a simulation skip numba.

The claims checked: the AOT kernel gives the JIT kernel's labels and final state bit for bit; a fresh
``sim.simulate`` served by it never imports numba; the lazy dispatchers compile, inline, call and pickle like
numba's; ``interpreted`` evaluates a jitted function with the compiled code's arithmetic.
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys

import numpy as np
import pytest

import sim
from sim import aot
from sim import layout as I
from sim.api import _prepare, make_settings
from sim.compiled import kernels
from sim.jit import LazyDispatcher, interpreted, njit
from sim.registry import kernel_variants


def _run(run_point, model: str, preset: str | None, exact: str | None):
    """Labels vector and final (y, z, phase) of one kernel call, as sim.simulate makes it (no history)."""
    spec = sim.get_model(model)
    values = spec.resolve(preset)
    st = make_settings(spec, None)
    p, y0, z0, ph0, period, atol = _prepare(spec, values, st.rtol)
    y, z, ph = y0.copy(), z0.copy(), np.array([ph0], dtype=np.int64)
    empty = (np.empty(0), np.empty((0, y0.shape[0])), np.empty((0, I.N_OBS)), np.empty(0, dtype=np.int64))
    labels = run_point(p, y, z, ph, period, st.to_array(runaway_check=False), atol, *empty)
    return labels, y, z, ph


_SUITE_DIR = os.environ.get("VIBRO_KERNEL_DIR")     # the suite's kernel folder, before a test empties it


def _suite_kernel(spec, exact: str | None):
    """The JIT kernel from the suite's cache (compiled once for every test), not recompiled in a test's empty folder."""
    saved = os.environ.pop("VIBRO_KERNEL_DIR", None)
    if _SUITE_DIR is not None:
        os.environ["VIBRO_KERNEL_DIR"] = _SUITE_DIR
    try:
        return kernels(spec.funcs, spec.n_bounded, exact)
    finally:
        os.environ.pop("VIBRO_KERNEL_DIR", None)
        if saved is not None:
            os.environ["VIBRO_KERNEL_DIR"] = saved


def _assert_bit_identical(model: str, exact: str | None, presets) -> None:
    spec = sim.get_model(model)
    run_aot = aot.load(spec.funcs, exact)
    assert run_aot is not None, "the AOT module was built but does not load"
    run_jit = _suite_kernel(spec, exact)
    for preset in presets:
        a, b = _run(run_aot, model, preset, exact), _run(run_jit, model, preset, exact)
        assert a[0][I.L_STEPS] > 0 or exact, "the kernel did not integrate"
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y, err_msg=f"{model} {preset} exact={exact}")


@pytest.fixture
def kernel_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("VIBRO_KERNEL_DIR", str(tmp_path))
    monkeypatch.setattr(aot, "_LOADED", {})
    return tmp_path


def _fresh(code: str, env: dict) -> str:
    """stdout of ``code`` in a fresh interpreter; ``env`` adds variables (None: removes one)."""
    full = {**os.environ, **env}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env={k: v for k, v in full.items() if v is not None})
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


_PROBE = ("import sys, sim\n"
          "r = sim.simulate('drill', preset='lab')\n"
          "print(repr(r.labels['rop_m_s']), repr(r.labels['peak_decel_g']), r.labels['n_events'], "
          "'numba' in sys.modules)\n")


def test_drill_exact_aot_kernel_is_bit_identical_and_loads_without_numba(kernel_dir):
    """Built here (about 10 s) from the same generated source as the JIT kernel; the labels of the `lab` preset and
    the default point, and the final state, must agree to the last bit."""
    spec = sim.get_model("drill")
    _suite_kernel(spec, spec.exact)                                    # loaded before the folder is emptied
    assert aot.load(spec.funcs, spec.exact) is None                    # nothing built yet in this folder
    path = aot.build(spec.funcs, spec.n_bounded, spec.exact)
    assert path.exists() and path.parent == kernel_dir and not list(kernel_dir.glob(".*.tmp"))
    _assert_bit_identical("drill", spec.exact, ("lab", None))

    # a fresh process on the main thread takes the AOT kernel: no numba at all, same labels as the JIT kernel here
    jit = sim.simulate("drill", preset="lab", settings={"method": "exact"})
    rop, decel, events, numba_loaded = _fresh(_PROBE, {"VIBRO_KERNEL_DIR": str(kernel_dir)}).split()
    assert numba_loaded == "False"
    assert (float(rop), float(decel), int(events)) == (jit.labels["rop_m_s"], jit.labels["peak_decel_g"],
                                                       jit.labels["n_events"])
    # VIBRO_NO_AOT=1 ignores the module: numba's JIT kernel serves (the suite's, not one compiled afresh in the
    # empty folder), with the same labels
    out = _fresh(_PROBE, {"VIBRO_KERNEL_DIR": _SUITE_DIR, "VIBRO_NO_AOT": "1"}).split()
    assert out[3] == "True" and out[:3] == [rop, decel, events]


def test_rimd_hybrid_aot_kernel_is_bit_identical(kernel_dir):
    """The RIMD's hybrid kernel (the template with sim/exact/rimd.py's free-phase hook) built ahead of time: labels
    and final state of an impacting and a non-impacting point agree with its JIT kernel to the last bit."""
    spec = sim.get_model("rimd")
    _suite_kernel(spec, spec.exact)
    aot.build(spec.funcs, spec.n_bounded, spec.exact)
    _assert_bit_identical("rimd", spec.exact, (None, "gap-3mm"))


def test_a_stale_or_missing_module_falls_back_to_the_jit_kernel(kernel_dir):
    spec = sim.get_model("drill")
    _suite_kernel(spec, spec.exact)           # the fallback loads the suite's JIT kernel, compiled once
    path = aot.module_path(spec.funcs, spec.exact)
    assert "vibro_aot_" in path.name and path.parent == kernel_dir
    assert aot.load(spec.funcs, spec.exact) is None
    path.write_bytes(b"not an extension module")           # damaged: an ImportError, not a crash
    aot._LOADED.clear()
    assert aot.load(spec.funcs, spec.exact) is None
    r = sim.simulate("drill", preset="lab")
    assert r.labels["status"] == "ok" and r.labels["rop_m_s"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("model", sim.model_names())
def test_every_aot_kernel_is_bit_identical(model, kernel_dir):
    """Every model's kernels (the numerical integrator; the drill's exact propagator too), every preset."""
    spec = sim.get_model(model)
    for exact in kernel_variants(spec):
        _suite_kernel(spec, exact)
        aot.build(spec.funcs, spec.n_bounded, exact)
        _assert_bit_identical(model, exact, (None, *spec.presets))


def test_model_modules_do_not_import_numba_until_a_function_is_used():
    code = ("import sys, numpy as np, sim\n"
            "from sim.models import drill\n"
            "before = 'numba' in sys.modules\n"
            "y = np.zeros(drill.NY); p = drill.SPEC.vector(drill.SPEC.resolve('lab'))\n"
            "drill.classify(y, p, 0)\n"
            "print(before, 'numba' in sys.modules)\n")
    assert _fresh(code, {}) == "False True"


@njit(inline="always")
def _twice(x):
    return 2.0 * x


@njit
def _plus_one(x):
    return x + 1.0


@njit(cache=False)
def _combined(x):
    return _twice(x) + _plus_one(x)


def test_lazy_dispatchers_compile_inline_call_and_pickle():
    assert isinstance(_combined, LazyDispatcher) and _combined._dispatcher is None       # nothing compiled yet
    assert _twice.targetoptions == {"inline": "always"}        # what numba's inlining pass reads
    assert _combined(3.0) == 10.0                              # a lazy global inlined, another called
    assert len(_combined.signatures) == 1                      # the dispatcher's attributes pass through
    import numba

    @numba.njit
    def outer(x):                        # plain numba code calling a lazy dispatcher
        return _combined(x) * 2.0

    assert outer(1.0) == 8.0                                   # (2 + 2) * 2
    from sim.models import drill

    assert pickle.loads(pickle.dumps(drill.rhs)) is drill.rhs
    with pytest.raises(TypeError, match="no explicit signatures"):
        njit("f8(f8)")


def test_interpreted_gives_the_compiled_result_bit_for_bit():
    """The drill's contact classification and right-hand side at random states, interpreted vs compiled: the
    same IEEE operations in the same order (no fastmath), so equal to the last bit."""
    from sim.models import drill

    rng = np.random.default_rng(5)
    p = drill.SPEC.vector(drill.SPEC.resolve("lab"))
    rhs_py, classify_py = interpreted(drill.rhs), interpreted(drill.classify)
    for _ in range(200):
        y = rng.normal(scale=1e-3, size=drill.NY)
        z, ph, t = np.zeros(1), int(rng.integers(0, 3)), float(rng.uniform(0, 0.1))
        assert classify_py(y, p, ph) == drill.classify(y, p, ph)
        d1, d2 = np.empty(drill.NY), np.empty(drill.NY)
        rhs_py(t, y, z, ph, p, d1)
        drill.rhs(t, y, z, ph, p, d2)
        np.testing.assert_array_equal(d1, d2)
    assert drill.rhs._dispatcher is not None and interpreted(drill.rhs) is not drill.rhs.py_func


def test_vibro_compile_reports_each_kernel_once_and_a_failure_in_one_line(monkeypatch, capsys, kernel_dir):
    """The CLI's plumbing, with the compiler replaced: every distinct kernel built once (indenter-metal and -sandstone
    have their own), a failure named in one line and no traceback; the real build is tested above."""
    from pipeline.cli import main

    built = []

    def fake_build(funcs, n_bounded, exact=None):
        built.append((funcs[0].py_func.__module__, funcs[0].py_func.__name__, exact))
        return aot.module_path(funcs, exact)

    monkeypatch.setattr(aot, "build", fake_build)
    assert main(["compile", "--workers", "1"]) == 0
    err = capsys.readouterr().err
    # 5 models' numerical kernels (the indenters' are two) and the drill's, the RIMD's and both indenters' exact
    # propagators
    assert len(built) == len(set(built)) == 9 and ("sim.models.drill", "rhs", "sim.exact.drill") in built
    assert ("sim.models.rimd", "rhs", "sim.exact.rimd") in built
    assert ("sim.models.indenter", "sand_rhs", "sim.exact.indenter_sandstone") in built
    assert err.count(" built in ") == 9 and "indenter-sandstone (numerical integrator)" in err
    assert "rimd (exact propagator)" in err

    def broken(funcs, n_bounded, exact=None):
        raise RuntimeError("no C compiler")

    monkeypatch.setattr(aot, "build", broken)
    assert main(["compile", "pendulum", "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == ("vibro compile: error: ahead-of-time compilation of the pendulum (numerical integrator) kernel "
                       "failed (RuntimeError: no C compiler); simulate keeps using the JIT kernel")
    assert "pendulum (numerical integrator): failed" in err[1] and not any("Traceback" in e for e in err)
    assert main(["compile", "--workers", "0"]) == 2 and "--workers must be >= 1" in capsys.readouterr().err
