"""Where compiled code is kept on disk, and the digest of the simulator's sources that keys numba's cache.

numba caches each ``cache=True`` function by its own file's time stamp only; a function that reads a constant from
another module (``sim/exact/drill.py`` takes the drill's parameter indices from ``sim/models/drill.py``) would load
stale machine code after that other module changed.  Every jitted function of ``sim`` is therefore cached under
``jit-<digest of every sim source>``: any edit of the simulator starts from an empty cache.
"""
from __future__ import annotations

import hashlib
import os
import tempfile
from functools import lru_cache
from pathlib import Path

SIM_DIR = Path(__file__).resolve().parent


def kernel_dir() -> Path:
    """``$VIBRO_KERNEL_DIR``, else ``.numba_cache/`` in the repository, else ``~/.cache/vibro`` (the first writable)."""
    env = os.environ.get("VIBRO_KERNEL_DIR")
    candidates = [Path(env)] if env else []
    candidates += [SIM_DIR.parent / ".numba_cache", Path.home() / ".cache" / "vibro"]
    for c in candidates:
        try:
            c.mkdir(parents=True, exist_ok=True)
            if os.access(c, os.W_OK):
                return c
        except OSError:
            continue
    return Path(tempfile.mkdtemp(prefix="vibro-kernels-"))


def source_digest(root: Path = SIM_DIR) -> str:
    """sha256 (16 hex digits) of every ``*.py`` under ``root``, in path order."""
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


@lru_cache(maxsize=1)
def jit_cache_dir() -> Path:
    """numba's cache folder for the simulator's functions (``$NUMBA_CACHE_DIR`` when the user set one)."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    return Path(env) if env else kernel_dir() / f"jit-{source_digest()}"
