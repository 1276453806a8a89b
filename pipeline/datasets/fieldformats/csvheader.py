"""CSV with the unit in each header: ``time [ms], accel [g], force [kN]``.  A channel is the column's name
without its unit (``accel``; the whole header ``accel [g]`` is accepted too); a CSV has no properties."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.core.bounded import MAX_CSV_BYTES, check_size
from pipeline.datasets.fieldformats.base import Channel, FieldFormatError

HEADER = re.compile(r"^(?P<name>.*?)\s*\[(?P<unit>[^\]]*)\]\s*$")
"""``name [unit]``; a header without brackets is a channel with no unit."""


class CsvSource:
    """A CSV file with one header row, loaded whole."""

    def __init__(self, path: Path):
        self.path = Path(path)
        check_size(self.path, MAX_CSV_BYTES, str(path))
        try:
            df = pd.read_csv(self.path, dtype=str, keep_default_na=False, skipinitialspace=True)
        except pd.errors.EmptyDataError:
            raise FieldFormatError(f"{path}: file is empty") from None
        except (pd.errors.ParserError, UnicodeDecodeError) as e:
            raise FieldFormatError(f"{path}: not a readable CSV file ({str(e).splitlines()[0]})") from None
        self._df = df
        self._cols: dict[str, tuple[str, str | None]] = {}    # name -> (header, unit)
        for col in df.columns:
            head = str(col).strip()
            m = HEADER.match(head)
            name, unit = (m["name"].strip(), m["unit"].strip() or None) if m else (head, None)
            if name in self._cols:
                raise FieldFormatError(f"{path}: column '{name}' appears more than once")
            self._cols[name] = (col, unit)

    def channels(self) -> list[str]:
        return list(self._cols)

    def channel(self, path: str) -> Channel:
        key = path.strip()
        m = HEADER.match(key)
        if key not in self._cols and m and m["name"].strip() in self._cols:
            key = m["name"].strip()
        col, unit = self._cols[key]
        raw = self._df[col].astype(str).str.strip()
        vals = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(vals)
        if bad.any():
            i = int(np.argmax(bad))
            what = "empty" if raw.iloc[i] == "" else f"'{raw.iloc[i]}' is not a finite number"
            raise FieldFormatError(f"{self.path} line {i + 2}, column '{str(col).strip()}': {what}")
        return Channel(values=vals, unit=unit)

    def properties(self, group: str) -> dict[str, object]:
        return {}

    def close(self) -> None:
        self._df = None
