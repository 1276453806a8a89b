"""Bounded reads of the user's files: a size cap on every text file, and YAML without aliases or duplicate keys.

A stream (``/dev/zero``, a FIFO) is read only up to the cap, so nothing the user names can make a
command read forever; YAML aliases are refused because a few hundred bytes of nested aliases expand
to gigabytes, and a duplicate key is refused because YAML would keep only the last one silently.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from pipeline.core.errors import UserError

MAX_TEXT_BYTES = 16 * 2**20
"""Largest YAML / params / rig file read [bytes]: far above any real one."""

MAX_CSV_BYTES = 2 * 2**30
"""Largest CSV table read [bytes]: a long DAQ record at 100 kHz is a few hundred MB."""


def check_size(path: str | os.PathLike, limit: int, what: str) -> None:
    """UserError naming ``what`` and ``path`` when it is not a regular file or is larger than ``limit`` bytes."""
    p = Path(path)
    try:
        st = p.stat()
    except OSError:
        return                       # the reader says what is missing
    import stat

    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{what} {p}: not a regular file (a device, pipe or folder cannot be read as a {what})")
    if st.st_size > limit:
        raise UserError(f"{what} {p}: {st.st_size} bytes, more than the {limit // 2**20} MiB a {what} may hold")


def check_input_file(path: str | os.PathLike, what: str, limit: int = MAX_CSV_BYTES) -> Path:
    """``path`` as a Path when it is a regular file of at most ``limit`` bytes; UserError naming ``what``: "not
    found" only when nothing is there (a FIFO, a device or a folder is named as such, not as missing)."""
    p = Path(path)
    if not p.exists() and not p.is_symlink():
        raise UserError(f"{what} {p}: file not found")
    if p.is_symlink() and not p.exists():
        raise UserError(f"{what} {p}: a broken symbolic link")
    check_size(p, limit, what)
    return p


def read_text_capped(path: str | os.PathLike, label: str, limit: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of ``path``, read up to ``limit`` bytes; UserError starting with ``label`` when it
    is longer, not text, or a folder."""
    p = Path(path)
    if p.is_dir():
        raise UserError(f"{label}: a folder, not a file")
    with open(p, "rb") as fh:           # a stream is read only up to the cap: never forever
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise UserError(f"{label}: more than {limit // 2**20} MiB (the most a settings file may hold)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise UserError(f"{label}: not a text (UTF-8) file") from None


def _loader(floats_12: bool):
    """SafeLoader that refuses aliases and duplicate keys; ``floats_12`` also reads ``5e8`` as a float (YAML 1.2)."""
    import yaml

    class Loader(yaml.SafeLoader):
        def compose_node(self, parent, index):
            if self.check_event(yaml.AliasEvent):
                mark = self.peek_event().start_mark
                raise yaml.constructor.ConstructorError(
                    None, None, "aliases (*name) are not accepted: write the value out", mark)
            return super().compose_node(parent, index)

        def construct_mapping(self, node, deep=False):
            seen: set = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                if not isinstance(key, (str, int, float, bool)):
                    continue
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key '{key}' (YAML keeps only the last one)", key_node.start_mark)
                seen.add(key)
            return super().construct_mapping(node, deep=deep)

    if floats_12:
        Loader.add_implicit_resolver(
            "tag:yaml.org,2002:float",
            re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
            list("-+0123456789."))
    return Loader


def load_yaml(path: str | os.PathLike, label: str, floats_12: bool = False):
    """The YAML document of ``path`` (size-capped, no aliases, no duplicate keys); UserError starting with
    ``label`` and naming the line and column otherwise.  ``floats_12``: see :func:`_loader`."""
    import yaml

    text = read_text_capped(path, label)
    try:
        return yaml.load(text, Loader=_loader(floats_12))  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        why = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise UserError(f"{label}{where}: not valid YAML ({why})") from None
