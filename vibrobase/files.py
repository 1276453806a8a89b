"""The one atomic-write module: a file is written to a temporary sibling, flushed to disk (fsync) and
moved over its target with ``os.replace``, so a reader sees the old or the new content, never half.

Temporary siblings are named ``.NAME.PID-XXXX.tmp`` (and a folder being replaced ``.NAME.old-PID``): the writer's
process id lets the next run remove what a killed writer left (:func:`clean_stale_temps`) without touching the
temporaries of a writer still alive."""
from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Callable, Iterator


def _temp_prefix(path: Path) -> str:
    return f".{path.name}.{os.getpid()}-"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:                  # EPERM: alive, another user's
        return True
    return True


def clean_stale_temps(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary siblings of ``path`` (``.NAME.PID-XXXX.tmp``, ``.NAME.old-PID``) whose writer is
    dead (a killed run); returns what was removed.  Files and folders of any other name are never touched."""
    path = Path(path)
    pat = re.compile(rf"^\.{re.escape(path.name)}\.(?:(\d+)-[A-Za-z0-9_]+\.tmp|old-(\d+))$")
    removed = []
    try:
        siblings = list(path.parent.iterdir())
    except OSError:
        return removed
    for p in siblings:
        m = pat.match(p.name)
        if m is None or _pid_alive(int(m.group(1) or m.group(2))):
            continue
        if m.group(2) and not os.path.lexists(path):
            os.replace(p, path)      # killed between the two renames of a swap: the previous folder goes back
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                p.unlink()
        removed.append(p)
    return removed


def _atomic(path: Path, write: Callable[[str], None], mode: int = 0o644) -> Path:
    """Run ``write(tmp)`` on a temporary sibling of ``path``, fsync it and move it over ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=_temp_prefix(path), suffix=".tmp")
    os.close(fd)
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return path


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    return _atomic(Path(path), lambda tmp: Path(tmp).write_bytes(data))


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode())


def atomic_write_json(path: str | os.PathLike, obj) -> Path:
    """Write ``obj`` as indented JSON (numpy scalars, inf handled; trailing newline) atomically."""
    from vibrobase.jsonable import dump_json

    return atomic_write_text(path, dump_json(obj) + "\n")


def atomic_write_parquet(path: str | os.PathLike, data, compression: str | None = None) -> Path:
    """Write a pandas DataFrame (index dropped, NaN → null) or a pyarrow Table to Parquet atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = data if isinstance(data, pa.Table) else pa.Table.from_pandas(data.reset_index(drop=True), preserve_index=False)
    kw = {} if compression is None else {"compression": compression}
    return _atomic(Path(path), lambda tmp: pq.write_table(table, tmp, **kw))


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary sibling directory to fill; on success it replaces ``path`` (the old folder is
    moved aside first and removed after), on error it is removed and ``path`` is left untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=_temp_prefix(path), suffix=".tmp"))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    os.chmod(tmp, 0o755)
    old = None
    if path.exists():
        old = path.with_name(f".{path.name}.old-{os.getpid()}")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(path, old)
    try:
        os.replace(tmp, path)
    except BaseException:
        if old is not None:
            os.replace(old, path)         # put the previous folder back
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def atomic_write_with(path: str | os.PathLike, write: Callable[[str], None]) -> Path:
    """``write(tmp_path)`` fills a temporary sibling of ``path`` (e.g. ``df.to_csv``), which then replaces it atomically."""
    return _atomic(Path(path), write)


def atomic_write_figure(path: str | os.PathLike, fig, dpi: int = 110, close: bool = True) -> Path:
    """Save a matplotlib figure atomically (format from the suffix, default png); close it unless told not to."""
    path = Path(path)
    try:
        return _atomic(path, lambda tmp: fig.savefig(tmp, format=path.suffix[1:] or "png", dpi=dpi))
    finally:
        if close:
            import matplotlib.pyplot as plt

            plt.close(fig)


def duplicate_csv_column(path: str | os.PathLike) -> str | None:
    """The first column name a CSV file's header repeats, or None (pandas would silently rename it 'x.1')."""
    import csv

    with open(path, newline="", errors="replace") as fh:
        header = [c.strip() for c in next(csv.reader(fh), [])]
    return next((c for c in header if header.count(c) > 1), None)
