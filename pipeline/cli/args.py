"""The command-line vocabulary and the validated argument types shared by every subcommand.

One spelling per idea (docs/commands.md "One vocabulary"), old spellings kept as aliases:

=================  ==============================  =================================================
idea               flag                            aliases (older spellings)
=================  ==============================  =================================================
fixed parameter    ``--set NAME=VALUE``            ``--fix`` (sweep), ``--fixed`` (optimise, verify)
range              ``--vary NAME=LOW:HIGH``        ``--range`` (optimise); map axes: ``--x NAME=LO:HI``
parallelism        ``--workers N``                 ``--threads``
numerical setting  ``--setting NAME=VALUE``        ``--set`` (diagnose only: its settings)
no progress bars   ``--quiet``                     ``--no-progress``
your machine       ``--rig FILE``                  (rig file, docs/commands.md "Rig files")
=================  ==============================  =================================================

Every number a user gives (flag, ``--set``/``--setting``/``--fix`` value, params.yaml value) goes
through one of the types below: finite, an integer when an integer is meant (2.7 is refused, not
truncated), inside its range, and below an upper bound on the work it asks for.  A violation is a
:class:`UserError` naming the argument; argparse ``type=`` callables raise ``ArgumentTypeError``
(argparse then exits 2 with one line naming the flag).
"""
from __future__ import annotations

import argparse
import math
import sys
from typing import Callable, Collection, Mapping

from pipeline.core.errors import UserError
from pipeline.core.numbers import MAX_THREADS, MAX_TRIALS, number  # noqa: F401 - the one number parser, re-exported
from vibrobase.errors import did_you_mean

# upper bounds on the work one command may ask for (a typo like 1e12 is an error, not a MemoryError or a hang)
MAX_POINTS = 10_000_000        # sweep / verify points, map grid cells
MAX_CYCLES = 1_000_000         # recorded/transient forcing cycles

# simulator settings (sim.Settings): (integer?, low, high, low inclusive) — bounds on work included
SETTINGS_BOUNDS: dict[str, tuple[bool, float, float, bool]] = {
    "rtol": (False, 1e-14, 0.1, True),
    "min_transient": (True, 0, 100_000, True),
    "max_transient": (True, 1, 100_000, True),
    "window": (True, 2, 10_000, True),
    "period_tol": (False, 0.0, 1.0, False),
    "settle_tol": (False, 0.0, 1.0, False),
    "max_steps_per_cycle": (True, 11, 10_000_000, True),
    "max_steps": (True, 1000, 1_000_000_000, True),
    "event_tol": (False, 0.0, 1e-3, False),
    "max_step_frac": (False, 0.0, 1.0, False),
    "stat_tol": (False, 0.0, 1.0, False),
    "samples_per_cycle": (True, 2, 100_000, True),
}

TEXT_SETTINGS = ("method",)
"""sim.Settings fields whose value is a word: ``method`` = auto | exact | dopri5 (sim.api.METHODS)."""


def arg_type(*, integer: bool = False, lo: float | None = None, hi: float | None = None,
             lo_open: bool = False) -> Callable[[str], float | int]:
    """An argparse ``type=``: a validated number (see :func:`number`)."""
    def parse(text: str):
        try:
            return number(text, "value", integer=integer, lo=lo, hi=hi, lo_open=lo_open)
        except UserError as e:
            raise argparse.ArgumentTypeError(str(e).removeprefix("value: ")) from None
    parse.__name__ = "integer" if integer else "number"      # argparse names it in "invalid integer value"
    return parse


# the shared types of the subcommands' flags
finite = arg_type()
positive = arg_type(lo=0.0, lo_open=True)
nonnegative = arg_type(lo=0.0)
fraction = arg_type(lo=0.0, hi=1.0, lo_open=True)
seed = arg_type(integer=True, lo=0, hi=2**32 - 1)
threads = arg_type(integer=True, lo=1, hi=MAX_THREADS)
n_points = arg_type(integer=True, lo=1, hi=MAX_POINTS)
n_trials = arg_type(integer=True, lo=1, hi=MAX_TRIALS)


def count(lo: int = 1, hi: int = MAX_POINTS) -> Callable[[str], int]:
    """An argparse ``type=`` for an integer count in [lo, hi]."""
    return arg_type(integer=True, lo=lo, hi=hi)


def parse_assignments(items: list[str] | None, what: str = "--set", words: Collection[str] = ()) -> dict[str, float]:
    """Parse ``["k1=1e7", "gap_m=0.001"]`` into finite floats (the names in ``words`` keep their text); a clear
    error names the bad item."""
    out: dict[str, float] = {}
    for item in items or []:
        if "=" not in item:
            raise UserError(f"{what} expects name=value, got '{item}'")
        name, _, raw = item.partition("=")
        name = name.strip()
        if not name:
            raise UserError(f"{what} '{item}' has no parameter name")
        out[name] = raw.strip() if name in words else number(raw.strip(), f"{what} {name}")
    return out


def parse_settings(items: list[str] | None) -> dict | None:
    """The simulator's ``--setting NAME=VALUE`` items, parsed and checked (:func:`check_settings`)."""
    return check_settings(parse_assignments(items, "--setting", words=TEXT_SETTINGS))


def parse_ranges(items: list[str] | None, what: str = "--vary") -> dict[str, tuple[float, float]]:
    """``["frequency_hz=10:400"]`` -> ``{"frequency_hz": (10.0, 400.0)}``; UserError naming the bad item."""
    out: dict[str, tuple[float, float]] = {}
    for item in items or []:
        name, sep, rest = item.partition("=")
        lo_s, sep2, hi_s = rest.partition(":")
        if not sep or not sep2 or not name.strip():
            raise UserError(f"{what} expects NAME=LOW:HIGH, got '{item}'")
        out[name.strip()] = (number(lo_s, f"{what} {name.strip()}: low"), number(hi_s, f"{what} {name.strip()}: high"))
    return out


PROG = ["vibro"]
"""The running command's name for warning lines (``vibro simulate``; set by pipeline.cli.main)."""


def warn_out_of_range(model: str, preset: str | None, values: Mapping, source: str = "") -> None:
    """One stderr line per value (or sweep range) in ``values`` outside the ranges the model or its preset was
    validated on, naming the likely mistake (``ModelSpec.out_of_range``); the run goes on.  ``source`` prefixes
    the lines (e.g. ``rig file r.yaml: ``)."""
    from sim import get_model

    for line in get_model(model).out_of_range(preset, values):
        print(f"{PROG[0]}: warning: {source}{line}", file=sys.stderr, flush=True)


def add_set(p, aliases: tuple[str, ...] = (), help: str | None = None) -> None:
    """``--set NAME=VALUE`` (dest ``sets``): hold a model parameter at a value."""
    p.add_argument("--set", *aliases, dest="sets", action="append", metavar="NAME=VALUE",
                   help=help or "hold a parameter at a value (repeatable; overrides --rig and the preset), "
                                "e.g. --set gap_m=0.001" + (f"; alias {', '.join(aliases)}" if aliases else ""))


def add_workers(p, dest: str = "workers", help: str = "parallel workers (threads; default: all cores)") -> None:
    """``--workers N`` (alias ``--threads``)."""
    p.add_argument("--workers", "--threads", dest=dest, type=threads, metavar="N", help=help + "; alias --threads")


def add_quiet(p) -> None:
    """``--quiet`` (alias ``--no-progress``): no progress bars or progress lines on stderr."""
    p.add_argument("--quiet", "--no-progress", dest="quiet", action="store_true",
                   help="no progress bars (they go to stderr); alias --no-progress")


def add_chain(p, default_note: str = "corrected with --rig, else lab") -> None:
    """``--chain lab|corrected``: which chain the command's MLflow run belongs to."""
    p.add_argument("--chain", choices=["lab", "corrected"],
                   help="MLflow: the chain this run belongs to, tag vibro.chain; runs of the corrected chain are "
                        f"named <stage>-corrected (default: {default_note})")


def chain_of(args, default: str | None = None) -> str:
    """``--chain`` if given, else ``default``, else ``corrected`` with a ``--rig`` and ``lab`` without."""
    return getattr(args, "chain", None) or default or ("corrected" if getattr(args, "rig", None) else "lab")


def add_rig(p, what: str = "simulate") -> None:
    """``--rig FILE``: model, preset, parameters and effects from a rig file."""
    p.add_argument("--rig", metavar="FILE.yaml",
                   help=f"{what} your own rig: model, preset, parameters and §6 effects from this rig file "
                        "(docs/commands.md 'Rig files'); --set and the controls still override it")


def check_workers(n: int | None, flag: str = "--workers") -> int | None:
    """``n`` if it is None or >= 1, else a UserError."""
    if n is not None and n < 1:
        raise UserError(f"{flag} must be an integer >= 1, got {n}")
    return n


def load_rig(path: str | None, model: str | None = None, preset: str | None = None):
    """The ``sim.Rig`` of rig file ``path`` (None without one), its preset replaced by ``preset`` when given;
    a ``model`` that differs from the rig's is a UserError naming both."""
    if not path:
        return None
    from pipeline.core.rigfile import read_rig

    rig = read_rig(path)
    if model and model != rig.model:
        raise UserError(f"model '{model}' but rig file {path} describes model '{rig.model}'")
    if preset is not None:
        from sim import ParameterError, Rig

        p = None if str(preset).lower() == "none" else preset
        try:
            rig = Rig(rig.model, p, dict(rig.parameters), {e: dict(v) for e, v in rig.effects.items()},
                      dict(rig.uncertainty), rig.source, dict(rig.discrepancy), rig.model_error)
        except ParameterError as e:
            raise UserError(f"rig file {path} with --preset {preset}: {str(e).removeprefix('rig: ')}") from None
    warn_out_of_range(rig.model, rig.preset, rig.overrides(), f"rig file {path}: ")
    return rig


def check_plausible(model: str, preset: str | None, sets: dict[str, float], flag: str = "--set") -> None:
    """UserError naming ``flag`` and the parameter when a value is not within :data:`PLAUSIBLE_FACTOR` of the
    default (of ``preset``): 0 and a parameter whose default is 0 are always allowed.  Unknown names, models and
    presets are left to the simulator's own checks."""
    import math

    import sim
    from pipeline.core.numbers import PLAUSIBLE_FACTOR, plausible

    if model not in sim.model_names():
        return
    spec = sim.get_model(model)
    try:
        defaults = spec.defaults(preset)
    except sim.ParameterError:
        return
    for name, v in sets.items():
        d = defaults.get(name)
        if d is None or not isinstance(v, (int, float)) or not math.isfinite(v):
            continue
        if not plausible(v, d):
            where = f"preset {preset}'s" if preset else "the model's default"
            raise UserError(f"{flag} {name}={v:g}: not within a factor {PLAUSIBLE_FACTOR:g} of {where} {d:g}; "
                            f"not a physical value for {model}")


def model_and_overrides(model: str | None, preset: str | None, rig_path: str | None,
                        sets: dict[str, float]) -> tuple[str, str | None, dict[str, float]]:
    """(model, preset, parameter overrides) of a command: the rig file's, then ``sets`` on top (each within
    :data:`PLAUSIBLE_FACTOR` of its default)."""
    from pipeline.core.rigfile import check_mode_complete

    rig = load_rig(rig_path, model, preset)
    if rig is None:
        if not model:
            raise UserError("give a MODEL (e.g. drill; 'vibro models' lists them) or --rig FILE")
        preset = None if preset is not None and str(preset).lower() == "none" else preset
        check_mode_complete(sets, "--set")
        check_plausible(model, preset, sets)
        return model, preset, dict(sets)
    values = {**rig.overrides(), **sets}
    check_mode_complete(values, "--set")
    check_plausible(rig.model, rig.preset, sets)
    return rig.model, rig.preset, values


def check_settings(values: dict | None, what: str = "--setting") -> dict | None:
    """Validate simulator settings (from ``--setting`` or params.yaml): known names, finite, integers
    where sim.Settings holds ints, inside :data:`SETTINGS_BOUNDS`; returns them with ints as int."""
    if values is None:
        return None
    if not isinstance(values, dict):
        raise UserError(f"{what}: expected a mapping of setting name to value, got {type(values).__name__}")
    out = {}
    for name, v in values.items():
        if name in TEXT_SETTINGS:
            from sim.api import METHODS     # the choices live with the simulator (numpy: imported only here)

            if v not in METHODS:
                raise UserError(f"{what} {name}: must be one of {', '.join(METHODS)}, got {v!r}")
            out[name] = v
            continue
        if name not in SETTINGS_BOUNDS:
            known = (*SETTINGS_BOUNDS, *TEXT_SETTINGS)
            raise UserError(f"{what} '{name}' is unknown{did_you_mean(name, known)} (known: {', '.join(known)})")
        integer, lo, hi, lo_incl = SETTINGS_BOUNDS[name]
        out[name] = number(v, f"{what} {name}", integer=integer, lo=lo, hi=hi, lo_open=not lo_incl)
    if out.get("max_transient", math.inf) < out.get("min_transient", 0):
        raise UserError(f"{what} max_transient ({out['max_transient']}) must be >= min_transient ({out['min_transient']})")
    if "min_transient" in out and "max_transient" not in out:
        from sim.api import Settings

        cap = Settings().max_transient
        if out["min_transient"] > cap:
            raise UserError(f"{what} min_transient ({out['min_transient']}) exceeds the default max_transient ({cap}); "
                            f"also set max_transient >= {out['min_transient']}")
    return out


def add_overwrite(p: argparse.ArgumentParser, what: str = "output") -> None:
    """The shared ``--overwrite``: replace this command's own previous output in --out (never other files)."""
    p.add_argument("--overwrite", action="store_true",
                   help=f"replace a previous {what} of this command in --out (files it did not write are never deleted)")
