"""``vibro``: the project's single command-line program.

Each subcommand lives in its own module ``pipeline.cli.<name>`` exposing
``add_parser(subparsers)`` (which sets ``func``); modules are imported when the parser
is built so ``vibro --help`` lists them all.  A command parses its arguments, calls its
workflow (imported lazily inside its run function, so ``--help`` stays fast) and logs.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from pipeline.core.errors import USER_ERRORS

SUBCOMMANDS = ("simulate", "sweep", "train", "optimise", "verify", "diagnose", "synth", "map", "report", "models")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vibro",
        description="Simulate vibro-impact drilling systems, build labelled datasets, learn surrogates, "
                    "optimise the operating point for rate of penetration, and diagnose the model against "
                    "measured rig data.  Models: drill, indenter-metal, indenter-sandstone, pendulum, rimd "
                    "(specification: MODELS.md).",
        epilog="Run 'vibro SUBCOMMAND --help' for the options of each subcommand.")
    parser.add_argument("--debug", action="store_true", help="show Python tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="SUBCOMMAND")
    for name in SUBCOMMANDS:
        try:
            mod = importlib.import_module(f"pipeline.cli.{name}")
        except ModuleNotFoundError as e:
            if e.name == f"pipeline.cli.{name}":
                continue
            raise
        mod.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        rc = args.func(args)
        return int(rc or 0)
    except USER_ERRORS as e:
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
        print(f"vibro {args.command}: internal error: {type(e).__name__}: {e} (rerun with --debug for details)",
              file=sys.stderr)
        return 1


