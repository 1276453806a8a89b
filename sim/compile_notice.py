"""One stderr line before numba compiles a model's kernel ("first run only"), so a first run does not
sit silent for 30-70 s.  Kept outside ``sim/compiled.py``: that file is part of every kernel's source hash."""
from __future__ import annotations

import os
import sys
from pathlib import Path

_SEEN: set[tuple] = set()          # kernels already looked at in this process
_PRINTED: list[bool] = []          # non-empty once the notice was printed
QUIET_ENV = "VIBRO_QUIET"      # set by the command line under --quiet (inherited by worker processes)


def is_cached(path: Path) -> bool:
    """Whether numba holds a cache index of the kernel module ``path``'s ``run_point`` for this Python: under the
    simulator's numba cache folder (``jit-<digest>/<folder tag>/``, where the kernel's header puts it) or, when
    numba runs without that folder, in ``__pycache__`` beside the module."""
    from sim.cachedir import jit_cache_dir

    index = f"{path.stem}.run_point-*.py{sys.version_info[0]}{sys.version_info[1]}*.nbi"
    return any(jit_cache_dir().glob(f"*/{index}")) or any((path.parent / "__pycache__").glob(index))


def announce_compile(spec, exact: str | None = None) -> bool:
    """Print the notice when ``spec``'s kernel (with exact propagator ``exact``) has no numba cache yet, at most
    once per process and never with ``$VIBRO_QUIET`` set; returns whether it was printed."""
    key = (spec.name, exact)
    if _PRINTED or key in _SEEN:
        return False
    _SEEN.add(key)
    if os.environ.get(QUIET_ENV):
        return False
    from sim.compiled import kernel_path

    path = kernel_path(spec.funcs, exact)
    if is_cached(path):
        return False
    _PRINTED.append(True)
    print(f"vibro: compiling the {spec.funcs[0].py_func.__module__.rsplit('.', 1)[-1]} kernel with numba "
          f"(first run only, about 30-70 s; cached in {path.parent})", file=sys.stderr, flush=True)
    return True
