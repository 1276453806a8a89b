"""Worker processes die with the process that started them.

joblib's loky workers outlive a parent killed with SIGKILL (they idle until a timeout); on Linux a
worker asks the kernel for SIGKILL when its parent dies (prctl PR_SET_PDEATHSIG).
"""
from __future__ import annotations

import os
import signal
import sys

_PR_SET_PDEATHSIG = 1
_armed = False


def die_with_parent(parent_pid: int) -> None:
    """In a worker of ``parent_pid``: be killed when it dies, and exit now if it already has.

    Does nothing in ``parent_pid`` itself (an in-process run) or where prctl is unavailable."""
    global _armed
    if _armed or os.getpid() == parent_pid or not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        return
    _armed = True
    if os.getppid() != parent_pid:       # the parent died before the signal was armed
        os._exit(1)


def in_worker(parent_pid: int, fn, *args, **kwargs):
    """Call ``fn(*args, **kwargs)`` after :func:`die_with_parent` (a joblib task wrapper)."""
    die_with_parent(parent_pid)
    return fn(*args, **kwargs)
