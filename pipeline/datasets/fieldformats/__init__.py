"""Rig files in the formats labs write -> the measured format (MODELS.md §7), through a mapping file.

base.py       the reader interface (``Source``, ``Channel``) and ``FieldFormatError``
tdms.py       NI LabVIEW TDMS (npTDMS)          hdf5.py     HDF5 (h5py)
matlab.py     MATLAB .mat (scipy.io; v7.3 via the HDF5 reader)
csvheader.py  CSV with units in the header (``accel [g]``)
mapping.py    the mapping (channel -> signal, unit, the run table), checked into frozen dataclasses
convert.py    ``import_runs(mapping, open_file) -> ImportResult``: the dataset in SI and what was converted

A new format is one reader module and one entry in ``READERS`` (and its extensions in ``EXTENSIONS``).
"""
from __future__ import annotations

from pathlib import Path

from pipeline.datasets.fieldformats.base import Channel, FieldFormatError, Reader, Source
from pipeline.datasets.fieldformats.convert import Conversion, ImportedRun, ImportResult, import_runs
from pipeline.datasets.fieldformats.csvheader import CsvSource
from pipeline.datasets.fieldformats.hdf5 import Hdf5Source
from pipeline.datasets.fieldformats.mapping import Mapping, parse_mapping
from pipeline.datasets.fieldformats.matlab import open_mat
from pipeline.datasets.fieldformats.tdms import TdmsSource

READERS: dict[str, Reader] = {"tdms": TdmsSource, "hdf5": Hdf5Source, "mat": open_mat, "csv": CsvSource}
"""Format name -> reader (``path -> Source``)."""
EXTENSIONS = {".tdms": "tdms", ".h5": "hdf5", ".hdf5": "hdf5", ".hdf": "hdf5", ".mat": "mat", ".csv": "csv"}


def open_file(path: Path, fmt: str | None = None) -> Source:
    """``path`` opened by the reader of ``fmt`` (None: from the file's extension)."""
    if fmt is None:
        fmt = EXTENSIONS.get(Path(path).suffix.lower())
        if fmt is None:
            raise FieldFormatError(f"{path}: unknown format of '{Path(path).suffix or 'no extension'}' files; give "
                                   f"'format:' in the mapping ({', '.join(READERS)})")
    if fmt not in READERS:
        import difflib

        close = difflib.get_close_matches(fmt, list(READERS), n=1, cutoff=0.5)
        raise FieldFormatError(f"format '{fmt}' is unknown{f' (did you mean {close[0]!r}?)' if close else ''} "
                               f"(known: {', '.join(READERS)})")
    return READERS[fmt](Path(path))


__all__ = ["Channel", "Conversion", "EXTENSIONS", "FieldFormatError", "ImportResult", "ImportedRun", "Mapping",
           "READERS", "Reader", "Source", "import_runs", "open_file", "parse_mapping"]
