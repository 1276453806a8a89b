"""MATLAB ``.mat`` through scipy.io (v4-v7.2); a v7.3 file is HDF5 and goes to the HDF5 reader.  A channel is
a variable or a struct field, written ``var`` or ``struct/field`` (``struct.field`` too); scalars and strings
are properties of their struct ('' = the file's top level)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.datasets.fieldformats.base import Channel, FieldFormatError, as_vector, scalar
from pipeline.datasets.fieldformats.hdf5 import Hdf5Source


def _walk(node: dict, prefix: str, channels: dict, props: dict) -> None:
    """Sort a loadmat tree into channels (numeric arrays of 2+ elements) and properties per struct."""
    here = props.setdefault(prefix, {})
    for key, value in node.items():
        if key.startswith("__"):
            continue
        path = f"{prefix}/{key}" if prefix else key
        if isinstance(value, dict):
            _walk(value, path, channels, props)
        elif isinstance(value, np.ndarray) and value.dtype.kind in "fiub" and value.size > 1:
            channels[path] = value
        else:
            v = scalar(value)
            if isinstance(v, (int, float, str, bool)):
                here[key] = v


class MatSource:
    """A MATLAB v4-v7.2 file, loaded whole."""

    def __init__(self, path: Path):
        from scipy import io

        self.path = Path(path)
        try:
            tree = io.loadmat(str(path), simplify_cells=True)
        except Exception as e:  # noqa: BLE001 - a parser failing on a corrupt file: the file's fault
            raise FieldFormatError(f"{path}: not a readable MATLAB file ({e})") from None
        self._channels: dict[str, np.ndarray] = {}
        self._props: dict[str, dict] = {}
        _walk(tree, "", self._channels, self._props)

    def channels(self) -> list[str]:
        return list(self._channels)

    def channel(self, path: str) -> Channel:
        return Channel(values=as_vector(self._channels[path.strip("/").replace(".", "/")], self.path, path))

    def properties(self, group: str) -> dict[str, object]:
        return dict(self._props.get(group.strip("/").replace(".", "/"), {}))

    def close(self) -> None:
        self._channels = {}


class Mat73Source(Hdf5Source):
    """A MATLAB v7.3 file (HDF5 inside); ``struct.field`` paths accepted as ``struct/field``."""

    def __init__(self, path: Path):
        super().__init__(path, matlab=True)

    def channel(self, path: str) -> Channel:
        return super().channel(path.replace(".", "/"))

    def properties(self, group: str) -> dict[str, object]:
        return super().properties(group.replace(".", "/"))


def open_mat(path: Path):
    """The reader for ``path``: scipy.io for v4-v7.2, HDF5 for v7.3 (recognised by its header)."""
    with open(path, "rb") as fh:
        head = fh.read(128)
    if b"MATLAB 7.3" in head[:116] or head[:8] == b"\x89HDF\r\n\x1a\n":
        return Mat73Source(path)
    return MatSource(path)
