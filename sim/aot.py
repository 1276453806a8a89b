"""Ahead-of-time compiled kernels: a ``vibro simulate`` that never imports numba.

A process that loads a numba kernel from numba's on-disk cache still pays about a second of CPU for
numba and its CPU target (type registries, scipy.linalg for the BLAS check) before the first
simulation.  :func:`build` compiles a model's kernels (the numerical one and, where the model has
one, the exact propagator) once with ``numba.pycc`` into CPython extension modules beside the JIT
cache; :func:`load` imports such a module in about a millisecond, with numpy as its only
dependency (numba's runtime is linked in statically).

Each module's name carries the hash of the kernel's sources (:func:`sim.compiled.kernel_path`) and of this
CPU's model and instruction-set flags, so a change to the integrator or a model, or a cache folder shared with
another machine, leaves the old module unused rather than stale or illegal: ``simulate``
then falls back to the JIT kernel until ``vibro compile`` rebuilds.  The AOT module is compiled
from the same generated source as the JIT kernel, for this machine's CPU (``target_cpu = "host"``),
and gives bit-identical labels (``tests/sim/test_aot.py``).  It holds the GIL while it runs, so
:func:`sim.api.simulate` uses it only on the main thread; worker threads keep the GIL-free JIT kernel.
"""
from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import os
import platform
import tempfile
import warnings
from functools import lru_cache
from pathlib import Path
from typing import Callable

# run_point(p, y, z, ph_io, period, s, atol, hist_t, hist_y, hist_obs, hist_ph) -> labels
# (sim/_kernel_template.py); every array C-contiguous, as sim.api allocates them
RUN_POINT_SIGNATURE = ("f8[::1](f8[::1], f8[::1], f8[::1], i8[::1], f8, f8[::1], f8[::1], "
                       "f8[::1], f8[:, ::1], f8[:, ::1], i8[::1])")
TARGET_CPU = "host"        # compiled for this machine's CPU, like numba's JIT
_SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]
_LOADED: dict[tuple, Callable | None] = {}     # (funcs, exact) -> run_point or None


def module_path(funcs: tuple, exact: str | None = None) -> Path:
    """Path of the AOT extension module of the kernel of ``funcs`` (and exact propagator ``exact``)."""
    from sim.compiled import kernel_path

    jit_path = kernel_path(funcs, exact)
    # how it is exported, and for which CPU: a folder shared between machines never serves a module built for another
    own = hashlib.sha256(f"{RUN_POINT_SIGNATURE}|{TARGET_CPU}|{_cpu_fingerprint()}".encode()).hexdigest()[:8]
    return jit_path.with_name(f"{jit_path.stem.replace('vibro_kernel_', 'vibro_aot_', 1)}_{own}{_SUFFIX}")


@lru_cache(maxsize=1)
def _cpu_fingerprint() -> str:
    """This CPU's model and instruction-set flags (Linux: /proc/cpuinfo), else the platform's processor string."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return f"{platform.machine()}|{platform.processor()}"
    keep = [ln for ln in lines if ln.startswith(("model name", "flags", "Features", "CPU part"))]
    return "|".join(dict.fromkeys(keep))      # the first core's lines (every core repeats them)


def load(funcs: tuple, exact: str | None = None) -> Callable | None:
    """The AOT ``run_point`` of this kernel, or None when it has not been built for the current sources.

    Looked up once per kernel and process (hashing the sources costs ~0.5 ms, as much as a drill simulation):
    like numba's own cache, a process does not see sources edited or modules built after its first call."""
    key = (funcs, exact)
    if key not in _LOADED:
        path = module_path(funcs, exact)
        _LOADED[key] = _import(path) if path.exists() else None
    return _LOADED[key]


def _import(path: Path) -> Callable | None:
    """Import the extension module at ``path`` (not registered in sys.modules: ``load`` keeps it)."""
    try:
        spec = importlib.util.spec_from_file_location(path.name[: -len(_SUFFIX)], path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except ImportError:          # built for another interpreter or a damaged file: the JIT kernel serves
        return None
    return module.run_point


def build(funcs: tuple, n_bounded: int, exact: str | None = None) -> Path:
    """Compile the kernel of ``funcs`` (and ``exact``) ahead of time; returns the module's path.

    Takes seconds to a minute per kernel; does nothing when the module for the current sources exists.
    The module is compiled in a temporary folder and moved into place, so an interrupted build leaves
    nothing half-written.
    """
    from sim.compiled import kernels

    path = module_path(funcs, exact)
    if path.exists():
        return path
    run_point = kernels(funcs, n_bounded, exact)         # the generated kernel module (not compiled by this)
    name = path.name[: -len(_SUFFIX)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                   # numba.pycc's pending-deprecation notice
        from numba.pycc import CC

        with tempfile.TemporaryDirectory(dir=path.parent, prefix=".aot-build-") as tmp:
            cc = CC(name)
            cc.output_dir = tmp
            cc.target_cpu = TARGET_CPU
            cc.verbose = False
            cc.export("run_point", RUN_POINT_SIGNATURE)(run_point.py_func)
            cc.compile()
            os.replace(Path(tmp) / cc.output_file, path)     # tmp is beside path: one atomic rename
    _LOADED.pop((funcs, exact), None)
    return path
