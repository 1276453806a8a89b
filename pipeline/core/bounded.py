"""Bounded reads of the user's files: a size cap on every text file, and YAML without aliases or duplicate keys.

Nesting deeper than MAX_YAML_DEPTH and integers longer than numbers.MAX_INT_DIGITS are refused while reading,
and a quoted number (``"1e5"``) is kept as numbers.QuotedNumber, text that is refused where a number is meant.
A stream (``/dev/zero``, a FIFO) is read only up to the cap, so nothing the user names can make a
command read forever; YAML aliases are refused because a few hundred bytes of nested aliases expand
to gigabytes, and a duplicate key is refused because YAML would keep only the last one silently.
"""
from __future__ import annotations

import math
import os
import re
from pathlib import Path

from pipeline.core.errors import UserError
from pipeline.core.numbers import MAX_INT_DIGITS, NUMBER_TEXT, QuotedNumber

MAX_TEXT_BYTES = 16 * 2**20
"""Largest YAML / params / rig file read [bytes]: far above any real one."""

MAX_YAML_DEPTH = 64
"""Deepest nesting of lists and mappings in a YAML file (deeper is refused while composing, before Python's
recursion limit is reached)."""

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
        depth = 0

        def compose_node(self, parent, index):
            if self.check_event(yaml.AliasEvent):
                mark = self.peek_event().start_mark
                raise yaml.constructor.ConstructorError(
                    None, None, "aliases (*name) are not accepted: write the value out", mark)
            if self.depth >= MAX_YAML_DEPTH:
                raise yaml.constructor.ConstructorError(
                    None, None, f"nested more than {MAX_YAML_DEPTH} levels deep", self.peek_event().start_mark)
            self.depth += 1
            try:
                return super().compose_node(parent, index)
            finally:
                self.depth -= 1

        def construct_yaml_int(self, node):
            digits = re.sub(r"[^0-9a-fA-F]", "", str(node.value))
            if len(digits) > MAX_INT_DIGITS:
                raise yaml.constructor.ConstructorError(
                    None, None, f"an integer of {len(digits)} digits is out of range", node.start_mark)
            return super().construct_yaml_int(node)

        def construct_yaml_float(self, node):
            x = super().construct_yaml_float(node)
            if math.isinf(x) and "inf" not in str(node.value).lower():
                raise yaml.constructor.ConstructorError(
                    None, None, f"the number {str(node.value)[:40]} is out of range", node.start_mark)
            return x

        def construct_yaml_str(self, node):
            text = super().construct_yaml_str(node)
            if node.style in ("'", '"') and NUMBER_TEXT.match(text.strip().replace("_", "")):
                return QuotedNumber(text)       # refused where a number is meant, kept where text is
            return text

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

    Loader.add_constructor("tag:yaml.org,2002:int", Loader.construct_yaml_int)
    Loader.add_constructor("tag:yaml.org,2002:float", Loader.construct_yaml_float)
    Loader.add_constructor("tag:yaml.org,2002:str", Loader.construct_yaml_str)
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
