"""One stderr line before numba compiles a model's kernel ("first run only"), so a first run does not
sit silent for 30-70 s.  Kept outside ``sim/compiled.py``: that file is part of every kernel's source hash."""
from __future__ import annotations

import sys

_SEEN: set[str] = set()


def kernel_stem(spec) -> tuple[str, "object"]:
    """(file stem, folder) of ``spec``'s generated kernel module, as ``sim.compiled._kernels`` names it."""
    from sim import compiled

    mod_name = spec.funcs[0].py_func.__module__
    tag = f"{mod_name.replace('.', '_')}_{spec.funcs[0].py_func.__name__}_{compiled._digest(mod_name)}"
    return f"vibro_kernel_{tag}", compiled._kernel_dir()


def announce_compile(spec) -> bool:
    """Print the notice when ``spec``'s kernel has no numba cache yet (once per kernel and process);
    returns whether it was printed."""
    stem, folder = kernel_stem(spec)
    if stem in _SEEN:
        return False
    _SEEN.add(stem)
    if any((folder / "__pycache__").glob(f"{stem}.*.nbi")):
        return False
    print(f"vibro: compiling the {spec.funcs[0].py_func.__module__.rsplit('.', 1)[-1]} kernel with numba "
          f"(first run only, about 30-70 s; cached in {folder})", file=sys.stderr, flush=True)
    return True
