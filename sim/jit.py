"""``njit`` that defers importing numba until a function is compiled or called.

Importing numba and its CPU target costs about a second of CPU (bench/startup.py); a ``vibro simulate`` served by an
ahead-of-time kernel (:mod:`sim.aot`) needs none of it, yet it imports the model modules for
their parameters and presets.  The model, integrator and exact-propagator modules therefore
decorate with this ``njit``: it returns a :class:`LazyDispatcher` that holds the Python function
and the options, and builds the numba dispatcher on first use.

Inside jitted code a ``LazyDispatcher`` global behaves as the dispatcher it stands for: numba
types it through ``_numba_type_`` and inlines ``inline="always"`` functions through
``targetoptions`` and ``py_func`` (the attributes numba's ``typeof`` and ``InlineInlinables``
pass read).  Called from Python it calls the compiled function.
"""
from __future__ import annotations

import importlib
import threading
import types
from typing import Any, Callable

from sim.cachedir import jit_cache_dir

_LOCK = threading.Lock()
_DISPATCHER_API = frozenset({"compile", "signatures", "nopython_signatures", "overloads", "get_overload", "stats",
                             "inspect_types", "inspect_llvm", "inspect_asm", "inspect_cfg", "recompile",
                             "get_call_template", "typeof_pyval", "get_compile_result", "get_metadata"})


class LazyDispatcher:
    """A numba ``njit`` function compiled on first use (see the module docstring)."""

    def __init__(self, py_func: Callable, options: dict[str, Any]):
        self.py_func = py_func
        self.options = dict(options)
        # what numba's InlineInlinables pass reads of a dispatcher (``cache`` is not a target option)
        self.targetoptions = {k: v for k, v in self.options.items() if k != "cache"}
        self._dispatcher = None
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__

    @property
    def dispatcher(self):
        """The numba dispatcher (imports numba on the first access)."""
        if self._dispatcher is None:
            with _LOCK:
                if self._dispatcher is None:
                    import numba
                    from numba import njit as _njit

                    if self.options.get("cache"):    # keyed by every sim source (sim/cachedir.py)
                        numba.config.CACHE_DIR = str(jit_cache_dir())
                    self._dispatcher = _njit(**self.options)(self.py_func)
        return self._dispatcher

    @property
    def _numba_type_(self):
        """The numba type of the dispatcher: how numba types this object as a global in jitted code."""
        from numba.core import types

        return types.Dispatcher(self.dispatcher)

    def __call__(self, *args):
        return self.dispatcher(*args)

    def __getattr__(self, name: str):
        # only the dispatcher's public API: a probe for anything else (pytest's collection, inspect, hasattr)
        # must not import numba and compile
        if name not in _DISPATCHER_API:
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __reduce__(self):                     # pickled by reference, like a module-level function
        return _lookup, (self.__module__, self.__qualname__)

    def __repr__(self) -> str:
        return f"<LazyDispatcher {self.__module__}.{self.__qualname__} (numba {'compiled' if self._dispatcher else 'not yet loaded'})>"


def _lookup(module: str, qualname: str) -> LazyDispatcher:
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def interpreted(func: LazyDispatcher | Callable) -> Callable:
    """``func`` run by the Python interpreter, the jitted functions it calls too: for a model's set-up code that
    calls a jitted function once (e.g. the drill's initial contact phase) without importing numba.

    Same IEEE double arithmetic in the same order as the compiled code (no fastmath anywhere in sim/), hence the
    same result; far slower, so never for the integration itself."""
    fn = getattr(func, "py_func", func)
    if fn not in _INTERPRETED:
        _INTERPRETED[fn] = _interpreted(fn, {})
    return _INTERPRETED[fn]


_INTERPRETED: dict[Callable, Callable] = {}


def _interpreted(fn: Callable, memo: dict) -> Callable:
    if fn in memo:
        return memo[fn]
    env = dict(fn.__globals__)
    clone = types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__, fn.__closure__)
    memo[fn] = clone
    for name in fn.__code__.co_names:      # every global the code reads: jitted ones become interpreted too
        val = env.get(name)
        if isinstance(val, LazyDispatcher):
            env[name] = _interpreted(val.py_func, memo)
    return clone


def njit(*args, **options):
    """``numba.njit`` with numba imported on first use: ``@njit``, ``@njit(cache=True, inline="always")``."""
    if args and callable(args[0]) and len(args) == 1 and not options:
        return LazyDispatcher(args[0], {})
    if args:
        raise TypeError("sim.jit.njit takes no explicit signatures; use keyword options")

    def wrap(func: Callable) -> LazyDispatcher:
        return LazyDispatcher(func, options)

    return wrap
