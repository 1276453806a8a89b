"""The mapping of a rig's files to the measured format (MODELS.md §7), checked into frozen dataclasses.

The command reads the YAML; ``parse_mapping(doc, label, base)`` takes the parsed document.  Keys (docs/import.md):
``file``, ``format``, ``channels`` (§7 signal -> channel [+ unit]), ``time`` (a channel, a sample rate, or the
channels' own step), ``run_defaults`` and ``runs`` (runs.csv columns; a value is a number in the column's unit, a
``"VALUE UNIT"`` string, or ``{property: NAME, unit: U}`` read from the file; ``summary`` for summary.csv).
"""
from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from pathlib import Path

from pipeline.core.units import QUANTITY_OF, UnitError, column_factor
from pipeline.datasets.fieldformats.base import FieldFormatError
from pipeline.datasets.measured import (CONTROL_COLUMNS, OPTIONAL_RUN_COLUMNS, RUN_COLUMNS, SERIES_SIGNALS,
                                        SUMMARY_FEATURES)

TOP_KEYS = ("file", "format", "channels", "time", "run_defaults", "runs")
RUN_KEYS = ("file", "format", "group", "channels", "time", "summary")
"""Keys of a run entry that are not runs.csv columns."""
TIME_KEYS = ("channel", "unit", "start", "rate_hz")
CHANNEL_KEYS = ("channel", "unit")
PROPERTY_KEYS = ("property", "attribute", "variable")
"""Spellings of "read this value from the file" (a TDMS property, an HDF5 attribute, a MAT variable)."""
KNOWN_COLUMNS = (*RUN_COLUMNS, *CONTROL_COLUMNS, *OPTIONAL_RUN_COLUMNS, "preset")
_WITH_UNIT = re.compile(r"^\s*(?P<num>[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?)\s*(?P<unit>\S.*?)?\s*$")


@dataclass(frozen=True)
class FromFile:
    """A value read from the rig file: property ``name`` of the run's group (else of the file), in ``unit``
    (None: the column's own unit)."""

    name: str
    unit: str | None = None


Value = float | str | FromFile


@dataclass(frozen=True)
class ChannelSpec:
    """§7 ``signal`` read from ``channel`` (inside the run's group), in ``unit`` (None: the file's)."""

    signal: str
    channel: str
    unit: str | None = None


@dataclass(frozen=True)
class TimeSpec:
    """Where t_s comes from: a ``channel`` [``unit``] shifted by ``start`` (0, 'first', or a value in that unit),
    else a sample rate ``rate_hz`` [Hz] (t_s = i / rate), else (both None) the channels' own step."""

    channel: str | None = None
    unit: str | None = None
    start: float | str = 0.0
    rate_hz: float | FromFile | None = None


@dataclass(frozen=True)
class RunSpec:
    """One run: its ``file`` (None: a summary-only run given wholly in the mapping) and ``format``, the ``group``
    its channels are in, its runs.csv ``columns`` and summary.csv ``summary`` values, in order."""

    file: Path | None
    format: str | None
    group: str
    channels: tuple[ChannelSpec, ...]
    time: TimeSpec
    columns: tuple[tuple[str, Value], ...]
    summary: tuple[tuple[str, Value], ...] = ()

    @property
    def run_id(self) -> str:
        return str(dict(self.columns).get("run_id", ""))


@dataclass(frozen=True)
class Mapping:
    """A checked mapping file: ``label`` (its path, for messages) and its ``runs``."""

    label: str
    runs: tuple[RunSpec, ...]


def _close(name: str, pool) -> str:
    close = difflib.get_close_matches(name, list(pool), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _check_keys(doc: dict, allowed, where: str) -> None:
    for k in doc:
        if k not in allowed:
            raise FieldFormatError(f"{where}: unknown key '{k}'{_close(str(k), allowed)} "
                                   f"(known: {', '.join(allowed)})")


def _from_file(doc: dict, where: str) -> FromFile:
    keys = [k for k in PROPERTY_KEYS if k in doc]
    _check_keys(doc, (*PROPERTY_KEYS, "unit"), where)
    if len(keys) != 1 or not isinstance(doc[keys[0]], str):
        raise FieldFormatError(f"{where}: give one of {', '.join(PROPERTY_KEYS)} with the name to read from the file")
    unit = doc.get("unit")
    return FromFile(name=doc[keys[0]], unit=None if unit is None else str(unit))


def parse_value(column: str, value: object, where: str) -> Value:
    """A runs.csv / summary.csv value in the column's unit (a ``"VALUE UNIT"`` string converted), text kept as
    text, or a FromFile; FieldFormatError naming ``where`` for anything else."""
    if isinstance(value, dict):
        ff = _from_file(value, where)
        if ff.unit is not None:
            _factor(column, ff.unit, where)
        return ff
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise FieldFormatError(f"{where}: '{value}' is not a number, a text or {{property: NAME}}")
    if isinstance(value, (int, float)):
        return float(value) if column in QUANTITY_OF else value
    m = _WITH_UNIT.match(value)
    if column in QUANTITY_OF:
        if not m:
            raise FieldFormatError(f"{where}: '{value}' is not a number (with an optional unit, e.g. '0.5 mm')")
        num = float(m["num"])
        return num * _factor(column, m["unit"], where) if m["unit"] else num
    if m and m["unit"]:
        raise FieldFormatError(f"{where}: '{value}' has a unit, but vibro knows no unit for column '{column}'; "
                               f"give it as a plain number in the model's SI unit (vibro models SYSTEM)")
    return value


def _factor(column: str, unit: str, where: str) -> float:
    try:
        return column_factor(column, unit)
    except UnitError as e:
        raise FieldFormatError(f"{where}: {e}") from None


def _channels(doc: object, where: str) -> dict[str, ChannelSpec]:
    if not isinstance(doc, dict):
        raise FieldFormatError(f"{where}: expected signal: channel pairs ({', '.join(SERIES_SIGNALS)})")
    out = {}
    for signal, spec in doc.items():
        w = f"{where}.{signal}"
        if signal == "t_s":
            raise FieldFormatError(f"{w}: time goes under 'time:' (channel, unit / rate_hz)")
        if signal not in SERIES_SIGNALS:
            raise FieldFormatError(f"{w}: '{signal}' is not a §7 signal{_close(str(signal), SERIES_SIGNALS)} "
                                   f"(known: {', '.join(SERIES_SIGNALS)})")
        if isinstance(spec, str):
            spec = {"channel": spec}
        if not isinstance(spec, dict) or not isinstance(spec.get("channel"), str):
            raise FieldFormatError(f"{w}: give the channel's name, or {{channel: NAME, unit: UNIT}}")
        _check_keys(spec, CHANNEL_KEYS, w)
        unit = None if spec.get("unit") is None else str(spec["unit"])
        if unit is not None:
            _factor(signal, unit, w)
        out[signal] = ChannelSpec(signal=signal, channel=spec["channel"], unit=unit)
    return out


def _time(doc: object, where: str) -> TimeSpec:
    if doc is None:
        return TimeSpec()
    if isinstance(doc, str):
        doc = {"channel": doc}
    if not isinstance(doc, dict):
        raise FieldFormatError(f"{where}: give {{channel: NAME, unit: UNIT}} or {{rate_hz: RATE}}")
    _check_keys(doc, TIME_KEYS, where)
    if "channel" in doc and "rate_hz" in doc:
        raise FieldFormatError(f"{where}: give a time channel or rate_hz, not both")
    unit = None if doc.get("unit") is None else str(doc["unit"])
    if unit is not None:
        _factor("t_s", unit, f"{where}.unit")
    start = doc.get("start", 0.0)
    if not (start == "first" or (isinstance(start, (int, float)) and not isinstance(start, bool))):
        raise FieldFormatError(f"{where}.start: '{start}' is neither 'first' nor a number (in the channel's unit)")
    rate = doc.get("rate_hz")
    if rate is not None:
        rate = parse_value("frequency_hz", rate, f"{where}.rate_hz")
        if isinstance(rate, float) and rate <= 0:
            raise FieldFormatError(f"{where}.rate_hz: must be > 0, got {rate:g}")
        if start != 0.0:
            raise FieldFormatError(f"{where}.start: only with a time channel (with rate_hz the record starts at t = 0)")
    channel = doc.get("channel")
    if channel is not None and not isinstance(channel, str):
        raise FieldFormatError(f"{where}.channel: give the channel's name")
    return TimeSpec(channel=channel, unit=unit, start=start if start == "first" else float(start), rate_hz=rate)


def _columns(doc: dict, where: str) -> dict[str, Value]:
    out = {}
    for col, value in doc.items():
        col = str(col)
        near = difflib.get_close_matches(col, KNOWN_COLUMNS, n=1, cutoff=0.8)
        if col not in KNOWN_COLUMNS and near and near[0] not in doc:
            raise FieldFormatError(f"{where}.{col}: not a runs.csv column vibro knows (did you mean '{near[0]}'?); "
                                   f"an extra column needs a name apart from the known ones")
        out[col] = parse_value(col, value, f"{where}.{col}")
    return out


def _summary(doc: object, where: str) -> dict[str, Value]:
    if not isinstance(doc, dict):
        raise FieldFormatError(f"{where}: give feature: value pairs ({', '.join(SUMMARY_FEATURES)})")
    for k in doc:
        if k not in SUMMARY_FEATURES:
            raise FieldFormatError(f"{where}.{k}: not a summary feature{_close(str(k), SUMMARY_FEATURES)} "
                                   f"(known: {', '.join(SUMMARY_FEATURES)})")
    return {k: parse_value(k, v, f"{where}.{k}") for k, v in doc.items()}


def parse_mapping(doc: object, label: str, base: Path) -> Mapping:
    """Check a parsed mapping document; files are relative to ``base`` (the mapping's folder).  Every problem
    raises FieldFormatError naming ``label`` and the key."""
    if not isinstance(doc, dict):
        raise FieldFormatError(f"{label}: expected a mapping of keys ({', '.join(TOP_KEYS)})")
    _check_keys(doc, TOP_KEYS, label)
    runs = doc.get("runs")
    if not isinstance(runs, list) or not runs:
        raise FieldFormatError(f"{label}: 'runs' must list at least one run (- run_id: ..., system: ..., ...)")
    defaults = doc.get("run_defaults") or {}
    if not isinstance(defaults, dict):
        raise FieldFormatError(f"{label}: run_defaults must be column: value pairs")
    for k in ("channels", "time", "summary"):
        if k in defaults:
            raise FieldFormatError(f"{label} run_defaults.{k}: '{k}' goes at the top of the mapping or in a run")
    channels = _channels(doc.get("channels") or {}, f"{label} channels")
    time = doc.get("time")
    out = []
    for i, entry in enumerate(runs):
        where = f"{label} runs[{i}]"
        if not isinstance(entry, dict):
            raise FieldFormatError(f"{where}: expected column: value pairs (run_id: ..., system: ...)")
        merged = {**defaults, **entry}
        rid = merged.get("run_id")
        where = f"{label} run '{rid}'" if isinstance(rid, (str, int)) and not isinstance(rid, bool) else where
        for col in ("run_id", "system"):
            if col not in merged:
                raise FieldFormatError(f"{where}: missing '{col}'")
        if not isinstance(rid, (str, int)) or isinstance(rid, bool):
            raise FieldFormatError(f"{where}: run_id must be a name given in the mapping (letters, digits, '_-.')")
        file = merged.get("file", doc.get("file"))
        if file is not None and (not isinstance(file, str) or not file):
            raise FieldFormatError(f"{where}.file: give the rig file's path as text")
        fmt = merged.get("format", doc.get("format"))
        group = merged.get("group", "")
        if not isinstance(group, str):
            raise FieldFormatError(f"{where}.group: give the group's name as text")
        summary = _summary(entry["summary"], f"{where}.summary") if "summary" in entry else {}
        own = entry.get("channels", {})
        none = own is None or (own == {} and "channels" in entry)        # 'channels: {}': a summary-only run
        chans = {} if none else {**channels, **_channels(own, f"{where} channels")}
        if not chans and not summary:
            raise FieldFormatError(f"{where}: no channels (map at least one of {', '.join(SERIES_SIGNALS)}; or, for "
                                   f"a summary-only run, 'channels: {{}}' and a 'summary:' row)")
        if not chans and "duration_s" not in merged:
            raise FieldFormatError(f"{where}: a summary-only run needs its duration_s")
        cols = _columns({k: v for k, v in merged.items() if k not in RUN_KEYS}, where)
        cols["run_id"] = str(cols["run_id"])
        reads = chans or any(isinstance(v, FromFile) for v in (*cols.values(), *summary.values()))
        if file is None and reads:
            raise FieldFormatError(f"{where}: no file (give 'file:' at the top of the mapping or in the run)")
        out.append(RunSpec(file=None if file is None else base / file, format=None if fmt is None else str(fmt),
                           group=group, channels=tuple(chans.values()),
                           time=_time(entry["time"] if "time" in entry else time, f"{where}.time"),
                           columns=tuple(cols.items()), summary=tuple(summary.items())))
    ids = [r.run_id for r in out]
    dup = next((r for r in ids if ids.count(r) > 1), None)
    if dup is not None:
        raise FieldFormatError(f"{label}: run '{dup}' appears twice")
    return Mapping(label=label, runs=tuple(out))
