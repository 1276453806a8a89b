"""HDF5 through h5py: a channel is a dataset path (``run01/accel``), its unit the attribute ``unit`` / ``units``
/ ``unit_string``, its step the attribute ``wf_increment`` [s]; properties are a group's attributes ('' = the
file's root).  MATLAB v7.3 files are HDF5 and read here too (``matlab=True``: scalars and char arrays become
properties, MATLAB's reference store ``#refs#`` is skipped)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.core.optional import try_import
from pipeline.datasets.fieldformats.base import Channel, FieldFormatError, as_vector, scalar

UNIT_ATTRS = ("unit", "units", "unit_string")
STEP_ATTRS = ("wf_increment",)


def _text(value: object) -> str | None:
    value = scalar(value)
    return str(value).strip() or None if value is not None else None


class Hdf5Source:
    """An open HDF5 file; datasets are read when asked for."""

    def __init__(self, path: Path, matlab: bool = False):
        h5py = try_import("h5py", package="h5py", feature="reading HDF5 and MATLAB v7.3 files (vibro import)")
        self.path = Path(path)
        self._matlab = matlab
        try:
            self._file = h5py.File(str(path), "r")
        except Exception as e:  # noqa: BLE001 - a parser failing on a corrupt file: the file's fault
            raise FieldFormatError(f"{path}: not a readable HDF5 file ({e})") from None
        self._datasets: dict[str, object] = {}

        def visit(name: str, obj) -> None:          # returning anything but None would stop the walk
            if isinstance(obj, h5py.Dataset) and not name.startswith("#refs#"):
                self._datasets[name] = obj

        self._file.visititems(visit)

    def _is_char(self, ds) -> bool:
        return self._matlab and _text(ds.attrs.get("MATLAB_class")) == "char"

    def channels(self) -> list[str]:
        return [n for n, ds in self._datasets.items()
                if ds.dtype.kind in "fiub" and ds.size > 1 and not self._is_char(ds)]

    def channel(self, path: str) -> Channel:
        ds = self._datasets[path.strip("/")]
        if ds.dtype.kind not in "fiub" or self._is_char(ds):
            raise KeyError(path)
        unit = next((_text(ds.attrs[a]) for a in UNIT_ATTRS if a in ds.attrs), None)
        step = next((float(scalar(ds.attrs[a])) for a in STEP_ATTRS if a in ds.attrs), None)
        return Channel(values=as_vector(ds[()], self.path, path), unit=unit, step_s=step if step and step > 0 else None)

    def properties(self, group: str) -> dict[str, object]:
        g = self._file.get(group.strip("/") or "/")
        if g is None or not hasattr(g, "attrs"):
            return {}
        out = {k: scalar(v) for k, v in g.attrs.items() if not k.startswith("MATLAB_")}
        if self._matlab and hasattr(g, "keys"):      # a struct's scalar fields and strings
            for k in g.keys():
                ds = g[k]
                if not hasattr(ds, "dtype"):
                    continue
                if self._is_char(ds):
                    out[k] = "".join(map(chr, np.asarray(ds[()]).reshape(-1)))
                elif ds.size == 1 and ds.dtype.kind in "fiub":
                    out[k] = scalar(ds[()])
        return out

    def close(self) -> None:
        self._file.close()
