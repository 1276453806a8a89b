"""What every field-format reader hands back: channels by path, their units and sample steps, and the file's
properties.  A reader is a callable ``path -> Source``; the registry in ``__init__`` maps a format name to it."""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Protocol

import numpy as np


class FieldFormatError(ValueError):
    """A rig file or mapping that cannot be imported; the message names the file and the channel or key."""


@dataclass(frozen=True)
class Channel:
    """One channel as stored: ``values`` in the file's unit, ``unit`` as the file states it (None: not stated),
    ``step_s`` the sample interval [s] the file states (TDMS ``wf_increment``; None: not stated)."""

    values: np.ndarray
    unit: str | None = None
    step_s: float | None = None


class Source(Protocol):
    """An open rig file.  Channel and group paths use '/' (``Measurements/Accel``, ``run01/accel``)."""

    path: Path

    def channels(self) -> list[str]:
        """Every channel path in the file."""

    def channel(self, path: str) -> Channel:
        """The channel at ``path``; KeyError when absent."""

    def properties(self, group: str) -> dict[str, object]:
        """Scalar properties of ``group`` ('' = the file itself): TDMS properties, HDF5 attributes, MAT scalars."""

    def close(self) -> None:
        """Release the file."""


Reader = Callable[[Path], Source]


def join(group: str, name: str) -> str:
    """Channel path ``name`` inside ``group`` ('' = none)."""
    return f"{group.strip('/')}/{name.strip('/')}" if group else name.strip("/")


def did_you_mean(name: str, known: list[str]) -> str:
    """`` (did you mean 'X'?)`` for the closest of ``known`` (case-insensitive first), else a short list."""
    low = {k.lower(): k for k in known}
    close = [low[name.lower()]] if name.lower() in low else difflib.get_close_matches(name, known, n=1, cutoff=0.5)
    if close:
        return f" (did you mean '{close[0]}'?)"
    if not known:
        return " (the file has none)"
    return f" (the file has: {', '.join(known[:8])}{', ...' if len(known) > 8 else ''})"


def as_vector(values: np.ndarray, file: Path, path: str) -> np.ndarray:
    """``values`` as a 1-D array (a MATLAB 1 x n or n x 1 array included); FieldFormatError for a matrix, whose
    columns would be interleaved."""
    arr = np.asarray(values)
    if sum(d > 1 for d in arr.shape) > 1:
        raise FieldFormatError(f"{file}, channel '{path}': a {' x '.join(map(str, arr.shape))} array, not one "
                               f"signal; store each signal as its own vector")
    return arr.reshape(-1)


def scalar(value: object) -> object:
    """A property as a Python scalar: numpy scalars and 1-element arrays unwrapped, bytes decoded."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "SU" and value.size == 1:
            return scalar(value.reshape(-1)[0])
        if value.size == 1:
            return value.reshape(-1)[0].item()
        return value
    if isinstance(value, np.generic):
        return value.item()
    return value
