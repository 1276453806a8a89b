"""One stderr line before numba compiles a model's kernel ("first run only"), so a first run does not
sit silent for 30-70 s.  Kept outside ``sim/compiled.py``: that file is part of every kernel's source hash."""
from __future__ import annotations

import sys

_SEEN: set[tuple] = set()


def announce_compile(spec, exact: str | None = None) -> bool:
    """Print the notice when ``spec``'s kernel (with exact propagator ``exact``) has no numba cache yet
    (once per kernel and process); returns whether it was printed."""
    key = (spec.name, exact)
    if key in _SEEN:
        return False
    _SEEN.add(key)
    from sim.compiled import kernel_path

    path = kernel_path(spec.funcs, exact)
    stem, folder = path.stem, path.parent
    if any((folder / "__pycache__").glob(f"{stem}.*.nbi")):
        return False
    print(f"vibro: compiling the {spec.funcs[0].py_func.__module__.rsplit('.', 1)[-1]} kernel with numba "
          f"(first run only, about 30-70 s; cached in {folder})", file=sys.stderr, flush=True)
    return True
