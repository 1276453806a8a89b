"""``vibro compile`` talks as it goes: a line per kernel with the elapsed time and an estimate, also under --quiet,
the pipeline's models first, and its own measured total at the end (the compiler replaced by a stub)."""
from __future__ import annotations

import io
import re
from pathlib import Path

import pytest
import yaml

from pipeline.cli import compile as compile_cmd
from pipeline.cli import main
from pipeline.core.errors import UserError
from sim import aot, model_names

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture
def stub_build(tmp_path, monkeypatch):
    """An empty kernel folder and a build that records its calls instead of compiling."""
    monkeypatch.setenv("VIBRO_KERNEL_DIR", str(tmp_path))
    monkeypatch.setattr(aot, "_LOADED", {})
    built = []

    def fake_build(funcs, n_bounded, exact=None):
        built.append((funcs[0].py_func.__module__, exact))
        return aot.module_path(funcs, exact)

    monkeypatch.setattr(aot, "build", fake_build)
    return built


def test_quiet_compile_prints_one_line_per_kernel_pipeline_first_and_its_total(stub_build, capsys):
    assert main(["compile", "--quiet", "--workers", "1"]) == 0
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[0].startswith("vibro compile: building 9 kernels in 1 process")
    progress = [ln for ln in lines if re.match(r"vibro compile: \[\d+/9\] ", ln)]
    assert len(progress) == 9
    assert [int(re.search(r"\[(\d+)/9\]", ln).group(1)) for ln in progress] == list(range(1, 10))
    assert all(re.search(r"built in \d+ s; \d+:\d\d elapsed", ln) for ln in progress)
    assert all("about " in ln and "left (estimate)" in ln for ln in progress[:-1])   # the last has nothing left
    assert not any("vibro_aot_" in ln for ln in progress)                 # --quiet: no module paths
    order = [re.search(r"\] (\S+) \(", ln).group(1) for ln in progress]
    assert order == ["drill", "drill", "indenter-metal", "indenter-metal", "indenter-sandstone",
                     "indenter-sandstone", "pendulum", "rimd", "rimd"]          # the pipeline's models first
    assert stub_build[0] == ("sim.models.drill", None)
    assert re.fullmatch(r"vibro compile: 9 kernels in \d+:\d\d \(9 built, 0 up to date; 1 process\)", lines[-1])


def test_verbose_compile_names_each_module(stub_build, capsys):
    assert main(["compile", "drill", "--workers", "1"]) == 0
    progress = [ln for ln in capsys.readouterr().err.splitlines() if "/2] drill" in ln]
    assert len(progress) == 2 and all("vibro_aot_" in ln for ln in progress)


def test_estimate_is_the_mean_build_time_over_the_free_processes():
    t = iter([0.0, 60.0, 100.0, 200.0])
    out = io.StringIO()
    clock = compile_cmd.CompileClock(n_total=5, workers=2, out=out, now=lambda: next(t))
    first = clock.line(("drill (numerical integrator)", "/k/a.so", None, 50.0), n_left_to_build=4, quiet=True)
    assert first == ("vibro compile: [1/5] drill (numerical integrator): built in 50 s; 1:00 elapsed, "
                     "about 1:40 left (estimate)")                     # 50 s x 4 kernels / 2 processes
    second = clock.line(("drill (exact propagator)", "", "RuntimeError: x", None), n_left_to_build=1, quiet=False)
    assert second == "vibro compile: [2/5] drill (exact propagator): failed; 1:40 elapsed, about 0:50 left (estimate)"
    assert clock.total(3, 1, 1) == "vibro compile: 5 kernels in 3:20 (3 built, 1 up to date, 1 failed; 2 processes)"


def test_the_pipelines_models_come_first_and_are_models():
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    first = compile_cmd.pipeline_models()
    assert params["sweep"]["model"] == first[0]
    assert set(first) <= set(model_names()) and {"indenter-metal", "indenter-sandstone"} <= set(first)
    assert compile_cmd.pipeline_first(["rimd", "indenter-sandstone", "drill", "pendulum"]) == [
        "drill", "indenter-sandstone", "rimd", "pendulum"]


def test_help_and_makefile_state_no_compile_time_of_their_own(capsys):
    """The one compile time is the one `vibro compile` measures and prints; the install compiles nothing itself
    and says once that kernels compile on first use, naming `vibro compile` for all of them ahead of time."""
    with pytest.raises(SystemExit):
        main(["compile", "--help"])
    help_text = capsys.readouterr().out
    makefile = (ROOT / "Makefile").read_text().splitlines()
    make_lines = [ln for ln in makefile if "compil" in ln]
    for text in [help_text, *make_lines]:
        assert not re.search(r"\d+(\.\d+)? ?(min|minutes)\b", text), text
    assert "prints the time it took" in help_text
    start = makefile.index(next(ln for ln in makefile if ln.startswith("$(STAMP):"))) + 1
    install = []
    for ln in makefile[start:]:
        if not ln.startswith("\t"):
            break
        install.append(ln.strip())
    assert install and not any(re.search(r"vibro compile\b", ln) and not ln.startswith("@echo") for ln in install)
    said = [ln for ln in install if ln.startswith("@echo") and "first use" in ln]
    assert len(said) == 1 and "vibro compile" in said[0]


def test_jit_only_fills_the_jit_cache_and_builds_no_module(stub_build, monkeypatch, capsys):
    """--jit-only compiles each JIT kernel once with the signature simulate calls, builds no AOT module, and says
    "up to date" for a kernel numba loaded from its cache."""
    import types

    import sim.compiled

    compiled, misses = [], {"n": 1}

    def fake_kernels(funcs, n_bounded, exact=None):
        def compile_(sig):
            compiled.append((funcs[0].py_func.__module__, exact, sig))
        return types.SimpleNamespace(compile=compile_,
                                     stats=types.SimpleNamespace(cache_misses={"sig": misses["n"]}))

    monkeypatch.setattr(sim.compiled, "kernels", fake_kernels)
    assert main(["compile", "drill", "--jit-only", "--quiet", "--workers", "1"]) == 0
    assert stub_build == []                                        # no ahead-of-time module
    assert [(m, e) for m, e, _ in compiled] == [("sim.models.drill", None), ("sim.models.drill", "sim.exact.drill")]
    assert all(sig == compile_cmd.jit_argument_types() for _, _, sig in compiled)      # what a call looks up
    assert capsys.readouterr().err.count(" built in ") == 2
    misses["n"] = 0                                                # numba found both in its cache
    assert main(["compile", "drill", "--jit-only", "--quiet", "--workers", "1"]) == 0
    err = capsys.readouterr().err
    assert err.count(": up to date;") == 2 and " built in " not in err


def test_jit_argument_types_are_what_a_call_is_typed_as():
    """numba's cache keys an entry by what ``compile`` received: the tuple must equal the types of the arrays
    sim.api passes, or a precompiled kernel would be compiled again by the first simulation."""
    import numpy as np
    from numba import typeof

    c1, i1, c2 = np.zeros(3), np.zeros(1, dtype=np.int64), np.zeros((0, 4))
    call = (c1, c1, c1, i1, 0.01, c1, c1, np.empty(0), c2, np.zeros((0, 5)), np.empty(0, dtype=np.int64))
    assert compile_cmd.jit_argument_types() == tuple(typeof(a) for a in call)


def test_a_first_run_compiles_the_sweep_models_kernels_and_the_diagnosed_systems_numerical_ones():
    """bench.first_run's compile phase is what `make run` compiles on first use: the sweep model's two kernels, and
    only the numerical integrator of an indenter (a diagnosis records histories; the exact propagator gives none)."""
    kernels = compile_cmd.pipeline_kernels()
    assert kernels[0] == compile_cmd.pipeline_models()[0] == "drill"
    assert {"indenter-metal:numerical", "indenter-sandstone:numerical"} <= set(kernels)
    assert compile_cmd.parse_kernel("rimd:exact", model_names()) == ("rimd", "exact")
    assert compile_cmd.parse_kernel("rimd", model_names()) == ("rimd", None)


@pytest.mark.parametrize("arg, says", [("drll", "did you mean drill"), ("drill:fast", "'numerical' or 'exact'")])
def test_a_wrong_kernel_argument_is_one_clear_line(arg, says):
    with pytest.raises(UserError, match=says):
        compile_cmd.parse_kernel(arg, model_names())


def test_the_first_run_bench_measures_make_test_in_the_parts_it_runs():
    """``python -m bench.first_run --phases install,test-kernels,test``: the kernels phase is the Makefile's target
    that ``make test`` runs first, so the test phase after it runs the suite alone."""
    from bench.first_run import phase_command

    root = Path(__file__).resolve().parents[3]
    assert phase_command("test-kernels", root) == ["make", "kernels-jit"]
    assert phase_command("test", root) == ["make", "test"]
    makefile = (root / "Makefile").read_text()
    assert "\nkernels-jit: install\n" in makefile and "\ntest: kernels-jit\n" in makefile
    with pytest.raises(ValueError, match="test-kernels, test"):
        phase_command("tests", root)
