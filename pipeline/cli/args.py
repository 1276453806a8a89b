"""The command-line vocabulary shared by every subcommand (README.md "One vocabulary").

One spelling per idea, old spellings kept as aliases:

=================  ==============================  =====================================
idea               flag                            aliases (older spellings)
=================  ==============================  =====================================
fixed parameter    ``--set NAME=VALUE``            ``--fix`` (sweep), ``--fixed`` (optimise, verify)
range              ``--vary NAME=LOW:HIGH``        ``--range`` (optimise); map axes: ``--x NAME=LO:HI``
parallelism        ``--workers N``                 ``--threads``
numerical setting  ``--setting NAME=VALUE``        ``--set`` (diagnose only: its settings)
no progress bars   ``--quiet``                     ``--no-progress``
your machine       ``--rig FILE``                  (rig file, README.md "Rig files")
=================  ==============================  =====================================
"""
from __future__ import annotations

from pipeline.core.errors import UserError


def parse_assignments(items: list[str] | None, what: str = "--set") -> dict[str, float]:
    """Parse ``["k1=1e7", "gap_m=0.001"]`` into floats; a clear error names the bad item."""
    out: dict[str, float] = {}
    for item in items or []:
        if "=" not in item:
            raise UserError(f"{what} expects name=value, got '{item}'")
        name, _, raw = item.partition("=")
        name = name.strip()
        if not name:
            raise UserError(f"{what} '{item}' has no parameter name")
        try:
            value = float(raw)
        except ValueError:
            raise UserError(f"{what} {name}: '{raw}' is not a number") from None
        out[name] = value
    return out


def parse_ranges(items: list[str] | None, what: str = "--vary") -> dict[str, tuple[float, float]]:
    """``["frequency_hz=10:400"]`` -> ``{"frequency_hz": (10.0, 400.0)}``; UserError naming the bad item."""
    out: dict[str, tuple[float, float]] = {}
    for item in items or []:
        name, sep, rest = item.partition("=")
        lo_s, sep2, hi_s = rest.partition(":")
        if not sep or not sep2 or not name.strip():
            raise UserError(f"{what} expects NAME=LOW:HIGH, got '{item}'")
        try:
            out[name.strip()] = (float(lo_s), float(hi_s))
        except ValueError:
            raise UserError(f"{what} {name.strip()}: '{rest}' is not LOW:HIGH numbers") from None
    return out


def add_set(p, aliases: tuple[str, ...] = (), help: str | None = None) -> None:
    """``--set NAME=VALUE`` (dest ``sets``): hold a model parameter at a value."""
    p.add_argument("--set", *aliases, dest="sets", action="append", metavar="NAME=VALUE",
                   help=help or "hold a parameter at a value (repeatable; overrides --rig and the preset), "
                                "e.g. --set gap_m=0.001" + (f"; alias {', '.join(aliases)}" if aliases else ""))


def add_workers(p, dest: str = "workers", help: str = "parallel workers (threads; default: all cores)") -> None:
    """``--workers N`` (alias ``--threads``)."""
    p.add_argument("--workers", "--threads", dest=dest, type=int, metavar="N", help=help + "; alias --threads")


def add_quiet(p) -> None:
    """``--quiet`` (alias ``--no-progress``): no progress bars or progress lines on stderr."""
    p.add_argument("--quiet", "--no-progress", dest="quiet", action="store_true",
                   help="no progress bars (they go to stderr); alias --no-progress")


def add_rig(p, what: str = "simulate") -> None:
    """``--rig FILE``: model, preset, parameters and effects from a rig file."""
    p.add_argument("--rig", metavar="FILE.yaml",
                   help=f"{what} your own rig: model, preset, parameters and §6 effects from this rig file "
                        "(README.md 'Rig files'); --set and the controls still override it")


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
                      dict(rig.uncertainty), rig.source)
        except ParameterError as e:
            raise UserError(f"rig file {path} with --preset {preset}: {str(e).removeprefix('rig: ')}") from None
    return rig


def model_and_overrides(model: str | None, preset: str | None, rig_path: str | None,
                        sets: dict[str, float]) -> tuple[str, str | None, dict[str, float]]:
    """(model, preset, parameter overrides) of a command: the rig file's, then ``sets`` on top."""
    rig = load_rig(rig_path, model, preset)
    if rig is None:
        if not model:
            raise UserError("give a MODEL (e.g. drill; 'vibro models' lists them) or --rig FILE")
        return model, (None if preset is not None and str(preset).lower() == "none" else preset), dict(sets)
    return rig.model, rig.preset, {**rig.overrides(), **sets}
