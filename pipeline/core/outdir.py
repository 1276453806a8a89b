"""One way to write a command's ``--out`` folder without ever losing a user's file.

``with prepare_out(out, inputs=[dataset], overwrite=args.overwrite, marker="diagnose") as tmp:``
the command writes everything into ``tmp`` (a hidden sibling on the same filesystem,
``pipeline.core.files.atomic_directory``); on success the folder gets a marker file and is swapped in for ``out``; on any
exception (Ctrl-C included) ``tmp`` is removed, ``out`` is untouched and no folder created for the
run is left behind.

Refused before anything is written (UserError, one line):
- an ``out`` that equals, contains or lies inside one of the command's inputs;
- an ``out`` that is a file;
- a non-empty ``out`` without this command's marker (files the command did not write);
- a non-empty ``out`` with the marker unless ``overwrite`` — and even then only when every file
  in it is one the marker lists (a file the user added to an old output is never deleted).

The swap is ``atomic_directory``'s: ``out`` is moved aside, ``tmp`` moved in, then the old copy deleted.
"""
from __future__ import annotations

import json
import os
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Iterable, Iterator

from pipeline.core.errors import UserError
from pipeline.core.files import atomic_directory, atomic_write_text

MARKER_NAME = ".vibro-output.json"


def _files(root: Path) -> list[str]:
    """Relative paths of every file (and symlink) under ``root``, sorted."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        base = Path(dirpath)
        out += [str((base / f).relative_to(root)) for f in filenames]
        out += [str((base / d).relative_to(root)) for d in dirnames if (base / d).is_symlink()]
    return sorted(out)


def read_marker(out: str | os.PathLike) -> dict | None:
    """The marker of a previous output in ``out`` (None when absent or unreadable)."""
    try:
        doc = json.loads((Path(out) / MARKER_NAME).read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def _overlaps(a: Path, b: Path) -> bool:
    return a == b or a.is_relative_to(b) or b.is_relative_to(a)


def check_out(out: str | os.PathLike, *, inputs: Iterable[str | os.PathLike] = (), overwrite: bool = False,
              marker: str) -> None:
    """Raise UserError unless command ``marker`` may write ``out`` (see the module docstring)."""
    out = Path(out)
    real = out.resolve()
    for inp in inputs:
        if inp is None:
            continue
        ri = Path(inp).resolve()
        if _overlaps(real, ri):
            where = "is" if real == ri else ("contains" if ri.is_relative_to(real) else "lies inside")
            raise UserError(f"--out {out} {where} the input {inp}; choose an --out apart from the inputs")
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    if not out.exists():
        return
    present = [f for f in _files(out) if f != MARKER_NAME]
    if not present and not (out / MARKER_NAME).exists():
        return                                               # an empty folder: nothing to lose
    mk = read_marker(out)
    if mk is None:
        raise UserError(f"--out {out} holds files 'vibro {marker}' did not write "
                        f"(first: {present[0] if present else MARKER_NAME}); choose a new or empty --out")
    if mk.get("command") != marker:
        raise UserError(f"--out {out} holds the output of 'vibro {mk.get('command')}', not of 'vibro {marker}'; "
                        f"choose a new or empty --out")
    if not overwrite:
        raise UserError(f"--out {out} holds a previous 'vibro {marker}' output; add --overwrite to replace it, "
                        f"or choose a new --out")
    own = set(mk.get("files") or [])
    foreign = [f for f in present if f not in own]
    if foreign:
        raise UserError(f"--overwrite: {out} holds {len(foreign)} file(s) 'vibro {marker}' did not write "
                        f"(first: {foreign[0]}); move them away or choose a new --out")


def _remove_created(dirs: list[Path]) -> None:
    for d in reversed(dirs):
        try:
            d.rmdir()                    # only if empty: never removes anything else
        except OSError:
            break


@contextmanager
def prepare_out(out: str | os.PathLike, *, inputs: Iterable[str | os.PathLike] = (), overwrite: bool = False,
                marker: str) -> Iterator[Path]:
    """Check ``out``, yield a temporary sibling to write into, swap it in on success (see module doc)."""
    out = Path(out)
    inputs = list(inputs)
    check_out(out, inputs=inputs, overwrite=overwrite, marker=marker)
    created: list[Path] = []
    for parent in reversed(out.absolute().parents):
        if not parent.exists():
            parent.mkdir()
            created.append(parent)
    try:
        with atomic_directory(out) as tmp:
            yield tmp
            doc = {"command": marker, "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                   "files": _files(tmp)}
            atomic_write_text(tmp / MARKER_NAME, json.dumps(doc, indent=1) + "\n")
            check_out(out, inputs=inputs, overwrite=overwrite, marker=marker)   # nobody wrote there meanwhile
    except BaseException:
        _remove_created(created)
        raise
