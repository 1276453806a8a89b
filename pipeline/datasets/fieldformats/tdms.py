"""TDMS (NI LabVIEW) through npTDMS: channel ``group/channel``, unit from ``unit_string``, step from
``wf_increment`` [s]; properties of a group, or of the file ('')."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.core.optional import try_import
from pipeline.datasets.fieldformats.base import Channel, FieldFormatError, scalar


class TdmsSource:
    """An open TDMS file (read whole: npTDMS's ``TdmsFile.read``)."""

    def __init__(self, path: Path):
        nptdms = try_import("nptdms", package="npTDMS", feature="reading TDMS files (vibro import)")
        self.path = Path(path)
        try:
            self._file = nptdms.TdmsFile.read(str(path))
        except Exception as e:  # noqa: BLE001 - a parser failing on a corrupt file: the file's fault
            raise FieldFormatError(f"{path}: not a readable TDMS file ({e})") from None
        self._channels = {f"{g.name}/{c.name}": c for g in self._file.groups() for c in g.channels()}

    def channels(self) -> list[str]:
        return list(self._channels)

    def channel(self, path: str) -> Channel:
        ch = self._channels[path.strip("/")]
        props = ch.properties
        unit = props.get("unit_string")
        step = props.get("wf_increment")
        return Channel(values=np.asarray(ch[:]), unit=str(unit).strip() or None if unit is not None else None,
                       step_s=float(step) if step is not None and float(step) > 0 else None)

    def properties(self, group: str) -> dict[str, object]:
        if not group.strip("/"):
            return {k: scalar(v) for k, v in self._file.properties.items()}
        names = {g.name: g for g in self._file.groups()}
        g = names.get(group.strip("/"))
        return {} if g is None else {k: scalar(v) for k, v in g.properties.items()}

    def close(self) -> None:
        self._file = None
