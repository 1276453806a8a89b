"""The output rule: one way to write a command's ``--out`` folder or single output file without ever losing a
user's file.

``with prepare_out(out, inputs=[dataset], overwrite=args.overwrite, marker="diagnose") as tmp:``
the command writes everything into ``tmp`` (a hidden sibling on the same filesystem,
``vibrobase.files.atomic_directory``); on success the folder gets a marker file and is swapped in for ``out``; on any
exception (Ctrl-C included) ``tmp`` is removed, ``out`` is untouched and no folder created for the
run is left behind.

Refused before anything is written (UserError, one line):
- an ``out`` that equals, contains or lies inside one of the command's inputs;
- an ``out`` that is a file;
- a non-empty ``out`` without this command's marker (files the command did not write);
- a non-empty ``out`` with the marker unless ``overwrite`` — and even then only when every file
  in it is one the marker lists (a file the user added to an old output is never deleted).

The swap is ``atomic_directory``'s: ``out`` is moved aside, ``tmp`` moved in, then the old copy deleted.
Temporary folders a killed run left beside ``out`` are removed on the next run (``clean_stale_temps``).

Single files (``--metrics``, ``--truth``, ``--plot``, ``--feedback``, ``map --out PREFIX``): the command calls
``check_out_file`` before any work and ``record_out_file`` after writing (atomically, ``vibrobase.files``).
Refused: a path that is, or lies inside, one of the command's inputs (real paths: symlinks resolved) or a folder
another command manages (its marker: the folder is replaced whole by that command's next run); a blank name or one
ending in a folder separator; a directory, device, pipe or socket; an existing file vibro did not write (no
``.NAME.vibro`` record whose checksum matches) unless ``overwrite`` — and then only a file of the kind the command writes (:data:`KINDS`).
A ``kind="feedback"`` file is appended to, so an existing one must be a feedback file, ``overwrite`` or not.
"""
from __future__ import annotations

import hashlib
import json
import os
import stat
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Iterable, Iterator

from pipeline.core.errors import UserError
from vibrobase.files import atomic_directory, atomic_write_text, clean_stale_temps

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
    if not str(out).strip():
        raise UserError("--out is empty; give a folder")
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
    clean_stale_temps(out)
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


# ------------------------------------------------------------------------------------------ single files
RECORD_SUFFIX = ".vibro"
"""``DIR/.NAME.vibro`` records that vibro wrote ``DIR/NAME`` (command, kind, sha256 of what it wrote)."""

READ_LIMIT = 64 << 20
"""Bytes read to recognise a file's kind or checksum it; a larger file is never taken for one of ours."""


def _head(path: Path, n: int = 16) -> bytes:
    with open(path, "rb") as fh:
        return fh.read(n)


def _is_json(path: Path) -> bool:
    if path.stat().st_size > READ_LIMIT:
        return False
    try:
        json.loads(path.read_bytes())
    except ValueError:
        return False
    return True


FIGURE_MAGIC = {"png": (b"\x89PNG",), "pdf": (b"%PDF",), "svg": (b"<?xml", b"<svg"), "svgz": (b"\x1f\x8b",),
                "eps": (b"%!PS", b"\xc5\xd0\xd3\xc6"), "ps": (b"%!PS",), "jpg": (b"\xff\xd8",),
                "jpeg": (b"\xff\xd8",), "tif": (b"II*", b"MM\x00*"), "tiff": (b"II*", b"MM\x00*"),
                "webp": (b"RIFF",), "pgf": (b"%",), "raw": (), "rgba": ()}
"""The leading bytes of each figure format matplotlib writes (raw / rgba have none: never replaced)."""


def _is_figure(path: Path) -> bool:
    magic = FIGURE_MAGIC.get(path.suffix[1:].lower(), ())
    head = _head(path)
    return any(head.startswith(m) for m in magic)


def _is_parquet(path: Path) -> bool:
    return _head(path, 4) == b"PAR1"


def _is_feedback(path: Path) -> bool:
    """A feedback file: Parquet whose columns include those ``append_feedback`` adds."""
    if not _is_parquet(path):
        return False
    import pyarrow.parquet as pq

    try:
        names = set(pq.read_schema(path).names)
    except Exception:  # noqa: BLE001 - unreadable: not a feedback file
        return False
    return {"point_id", "source", "study", "created"} <= names


KINDS: dict[str, tuple[str, Callable[[Path], bool]]] = {
    "json": ("a JSON file", _is_json),
    "figure": ("a figure", _is_figure),
    "parquet": ("a Parquet file", _is_parquet),
    "feedback": ("a vibro feedback Parquet file", _is_feedback),
}
"""Output kind -> (what it is called in messages, whether an existing file is one)."""


def _record_path(path: Path) -> Path:
    return path.with_name(f".{path.name}{RECORD_SUFFIX}")


def _sha256(path: Path) -> str | None:
    if path.stat().st_size > READ_LIMIT:
        return None
    return hashlib.sha256(path.read_bytes()).hexdigest()


def written_by_vibro(path: str | os.PathLike) -> bool:
    """Whether ``path`` holds exactly what a vibro command last wrote there (its ``.NAME.vibro`` record)."""
    path = Path(path)
    try:
        rec = json.loads(_record_path(path).read_text())
        return isinstance(rec, dict) and rec.get("sha256") == _sha256(path)
    except (OSError, ValueError):
        return False


def _inside(real: Path, inputs: Iterable[str | os.PathLike | None]) -> str | None:
    """The first input that ``real`` is or lies inside (a file inside an input folder), else None."""
    for inp in inputs:
        if inp is None or not str(inp):
            continue
        ri = Path(inp).resolve()
        if real == ri or real.is_relative_to(ri):
            return str(inp)
    return None


def _managed_folder(real: Path) -> tuple[Path, str] | None:
    """The nearest folder above ``real`` holding a vibro output marker, with the command that wrote it, or None."""
    for folder in real.parents:
        if (folder / MARKER_NAME).is_file():
            return folder, str((read_marker(folder) or {}).get("command", "?"))
    return None


def check_out_file(path: str | os.PathLike, *, flag: str, kind: str, inputs: Iterable[str | os.PathLike | None] = (),
                   overwrite: bool = False) -> Path:
    """Raise UserError unless the command may write the single file ``path`` (see the module docstring);
    removes the temporaries a killed writer of ``path`` left.  Returns ``path`` as a Path."""
    what, is_kind = KINDS[kind]
    path = _file_target(path, flag)
    real = path.resolve()
    inp = _inside(real, inputs)
    if inp is not None:
        where = "is" if real == Path(inp).resolve() else "lies inside"
        raise UserError(f"{flag} {path} {where} the input {inp}; write it elsewhere")
    managed = _managed_folder(real)
    if managed is not None:
        raise UserError(f"{flag} {path} lies inside {managed[0]}, the output folder of 'vibro {managed[1]}' "
                        f"(replaced whole by its next run); write it elsewhere")
    if _file_or_nothing(path, flag, broken="remove it or give another path",
                        folder="is a directory; give a file path",
                        special="is not a regular file (a device, pipe or socket); give a file path"):
        if kind == "feedback":
            if not is_kind(path):
                raise UserError(f"{flag} {path} exists and is not {what}; rows are only appended to one")
        elif not written_by_vibro(path):
            if not overwrite:
                raise UserError(f"{flag} {path} exists and vibro did not write it; add --overwrite to replace it, "
                                f"or give another path")
            if not is_kind(path):
                raise UserError(f"--overwrite: {flag} {path} is not {what}, the kind of file {flag} writes; "
                                f"refusing to replace it")
    clean_stale_temps(path)
    return path


def record_out_file(path: str | os.PathLike, *, command: str, kind: str) -> None:
    """Record that ``command`` wrote ``path`` (so a rerun may replace it without --overwrite)."""
    path = Path(path)
    doc = {"command": command, "kind": kind, "sha256": _sha256(path),
           "written": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    atomic_write_text(_record_path(path), json.dumps(doc) + "\n")


def _file_target(path: str | os.PathLike, flag: str) -> Path:
    """``path`` as a Path when it can name a file: not empty, not a blank name, not ending in a folder separator
    (``out/`` means a folder: the file would land beside it, as ``out`` or ``out.png``)."""
    raw = os.fspath(path)
    if not raw.strip():
        raise UserError(f"{flag} is empty; give a file path")
    if raw.endswith(("/", os.sep)) or raw.rstrip("/" + os.sep) in ("", ".", ".."):
        raise UserError(f"{flag} {raw} names a folder; give a file path (e.g. {raw.rstrip('/' + os.sep) or '.'}/name)")
    p = Path(raw)
    if not p.name.strip() or p.name != p.name.strip():
        raise UserError(f"{flag} {raw!r}: the file name is blank or starts or ends with a space; give another name")
    return p


def _file_or_nothing(path: Path, flag: str, *, broken: str, folder: str, special: str) -> bool:
    """True when a regular file (a symbolic link followed) is at ``path``, False when nothing is; else UserError
    "``flag`` ``path`` ...": "is a broken symbolic link; ``broken``", or ``folder`` / ``special`` for a folder or a
    device, pipe or socket."""
    if not os.path.lexists(path):
        return False
    try:
        st = os.stat(path)
    except OSError:
        raise UserError(f"{flag} {path} is a broken symbolic link; {broken}") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserError(f"{flag} {path} {folder}")
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{flag} {path} {special}")
    return True


def check_out_prefix(prefix: str | os.PathLike, flag: str = "--out") -> Path:
    """The output PREFIX of a command writing PREFIX.png, PREFIX.parquet, ...: a file-like name in an existing or
    creatable folder; UserError naming ``flag`` when it names a folder, a device, a pipe or a blank name (``/dev/null``
    would write ``/dev/null.png`` into /dev, ``user/`` would write ``user.png`` beside the folder)."""
    p = _file_target(prefix, flag)
    _file_or_nothing(p, flag, broken="give another prefix",
                     folder=f"is a folder; give a file prefix inside it (e.g. {p}/name)",
                     special="is a device, pipe or socket, not a prefix for files; give a file prefix")
    parent = p.parent if str(p.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise UserError(f"{flag} {p}: {parent} is not a folder")
    return p


def figure_path(path: str | os.PathLike, flag: str = "--plot") -> Path:
    """``path`` with ``.png`` added when it has no suffix and does not exist (what matplotlib would write);
    UserError naming the flag when its suffix is not a figure format matplotlib writes, or when ``path`` cannot
    name a file (empty, blank, ending in a folder separator)."""
    path = _file_target(path, flag)
    fmt = path.suffix[1:].lower()
    if not fmt:
        # an existing path (/dev/null, a user's file) is checked as given, never silently turned into another
        return path if os.path.lexists(path) else path.with_name(path.name + ".png")
    if fmt not in FIGURE_MAGIC:
        raise UserError(f"{flag} {path}: '.{fmt}' is not a figure format (use one of "
                        f"{', '.join('.' + k for k in FIGURE_MAGIC)})")
    return path
