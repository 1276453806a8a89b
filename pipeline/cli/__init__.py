"""``vibro``: the project's single command-line program.

Each subcommand lives in its own module ``pipeline.cli.<name>`` (``import_`` for ``import``) exposing
``add_parser(subparsers)`` (which sets ``func``); modules are imported when the parser
is built so ``vibro --help`` lists them all.  A command parses its arguments, calls its
workflow (imported lazily inside its run function, so ``--help`` stays fast) and logs.
"""
from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
import time
import warnings

# One BLAS/OpenMP thread per worker: vibro parallelises over simulations and fits itself, and OpenBLAS's own
# threads beside them spin for the cores (a 4000 x 52 least-squares took 1.1 s instead of 29 ms under load, and
# the diagnosis spent 70 % of its time there).  Set before numpy loads; an explicit setting is kept.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from pipeline.core.errors import USER_ERRORS, machine_error, show_warnings  # noqa: E402
from vibrobase.errors import did_you_mean  # noqa: E402

QUIET_ENV = "VIBRO_QUIET"      # read by sim/compile_notice.py (not imported here: --help stays fast)
SUBCOMMANDS = ("simulate", "sweep", "train", "optimise", "verify", "import", "diagnose", "synth", "map", "report",
               "models", "compare", "compile")
MODULE_OF = {"import": "import_"}
"""Subcommands whose module name differs (``import`` is a Python keyword)."""


def version() -> str:
    """The installed package's version (pyproject.toml), or the source tree's when not installed."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as _v

    try:
        return _v("vibro")
    except PackageNotFoundError:
        import re
        from pathlib import Path

        text = (Path(__file__).resolve().parents[2] / "pyproject.toml").read_text()
        m = re.search(r'^version\s*=\s*"([^"]+)"', text, re.M)
        return m.group(1) if m else "unknown"


class _VersionAction(argparse.Action):
    """``--version``: prints ``vibro VERSION`` and exits, reading the version only when asked
    (importlib.metadata costs ~20 ms of every start-up otherwise)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="show program's version number and exit"):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"vibro {version()}", flush=True)
        parser.exit()


_INVALID_CHOICE = re.compile(r"^(argument .*?): invalid choice: '(.*)' \(choose from (.*)\)$")


class VibroParser(argparse.ArgumentParser):
    """argparse with a did-you-mean (``vibrobase.errors.did_you_mean``) on a mistyped flag or choice, in one line naming
    the subcommand: ``vibro sweep: error: unknown option --npoints (did you mean --n-points?)``.  Its subcommands'
    parsers are of this class too (argparse makes them of their parent's class)."""

    def parse_args(self, args=None, namespace=None):
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            self._unknown(ns, extra)
        return ns

    def _unknown(self, ns, extra: list[str]) -> None:
        """Exit 2 with one line naming the first unknown option (and its likely spelling) or the stray arguments."""
        commands = getattr(self, "commands", {})
        parser = commands.get(getattr(ns, "command", None), self)
        flag = next((a for a in extra if a.startswith("-") and len(a) > 1), None)
        if flag is not None:
            flag = flag.partition("=")[0]
            options = [o for a in parser._actions for o in a.option_strings if o.startswith("--")]
            message = f"unknown option {flag}{did_you_mean(flag, options)}"
        else:
            message = f"unexpected argument(s) {' '.join(extra)} (see '{parser.prog} --help')"
        parser.exit(2, f"{parser.prog}: error: {message}\n")

    def error(self, message: str):
        m = _INVALID_CHOICE.match(message)
        if m is None:
            super().error(message)
        what, word, choices = m.groups()
        options = re.findall(r"'([^']*)'", choices)
        self.exit(2, f"{self.prog}: error: {what}: invalid choice '{word}'{did_you_mean(word, options)}; "
                     f"choose from {', '.join(options)}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = VibroParser(
        prog="vibro",
        description="Simulate vibro-impact drilling systems, build labelled datasets, learn surrogates, "
                    "optimise the operating point for rate of penetration, and diagnose the model against "
                    "measured rig data.  Models: drill, indenter-metal, indenter-sandstone, pendulum, rimd "
                    "(specification: MODELS.md).",
        epilog="Run 'vibro SUBCOMMAND --help' for the options of each subcommand.")
    parser.add_argument("--debug", action="store_true", help="show Python tracebacks on errors")
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", metavar="SUBCOMMAND")
    for name in SUBCOMMANDS:
        try:
            mod = importlib.import_module(f"pipeline.cli.{MODULE_OF.get(name, name)}")
        except ModuleNotFoundError as e:
            if e.name == f"pipeline.cli.{MODULE_OF.get(name, name)}":
                continue
            raise
        mod.add_parser(sub)
    parser.commands = sub.choices      # name -> its parser (VibroParser names the one a mistyped flag went to)
    return parser


def _done(args, wall: float) -> None:
    """One stderr line with the command's wall and CPU time (the per-stage line of a pipeline run)."""
    if getattr(args, "quiet", False) or wall < 2.0:
        return
    import resource

    cpu = sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))  # + finished workers
    print(f"vibro {args.command}: done in {wall:.0f} s wall, {cpu:.0f} s CPU",
          file=sys.stderr, flush=True)


def user_errors() -> tuple[type[BaseException], ...]:
    """The errors reported as one line (exit 2): USER_ERRORS, plus the surrogate library's SurrogateError once
    a command has loaded the surrogate (a command that never did cannot raise it, and importing it up front would
    load the surrogate into every command)."""
    loaded = sys.modules.get("surrogate.errors")
    return USER_ERRORS + ((loaded.SurrogateError,) if loaded is not None else ())


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from pipeline.cli.args import PROG

    PROG[0] = f"vibro {args.command}"
    t0 = time.perf_counter()
    quiet_before = os.environ.get(QUIET_ENV)
    if getattr(args, "quiet", False):      # no compile notice either, in this process and its workers
        os.environ[QUIET_ENV] = "1"
    try:
        with warnings.catch_warnings(record=True) as caught:     # shown after success, never before an error
            warnings.simplefilter("default")
            rc = args.func(args)
        show_warnings(caught)
        _done(args, time.perf_counter() - t0)
        return int(rc or 0)
    except user_errors() as e:          # evaluated when an exception arrives, after the command ran
        if args.debug:
            raise
        msg = str(e) if not isinstance(e, OSError) or not e.filename else f"{e.strerror}: {e.filename}"
        msg = " ".join(ln.strip() for ln in msg.splitlines() if ln.strip())       # one line, always
        print(f"vibro {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"vibro {args.command}: interrupted (completed work is kept; rerun the same command to resume)",
              file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - last resort: one line, not a traceback
        if args.debug or os.environ.get("VIBRO_DEBUG"):
            raise
        msg = machine_error(e)
        if msg is not None:                     # the machine's or the user's files: disk full, read-only, ...
            print(f"vibro {args.command}: error: {msg}", file=sys.stderr)
            return 2
        print(f"vibro {args.command}: internal error: {type(e).__name__}: {e} (rerun with --debug for details)",
              file=sys.stderr)
        return 1
    finally:
        if quiet_before is None:
            os.environ.pop(QUIET_ENV, None)
        else:
            os.environ[QUIET_ENV] = quiet_before


