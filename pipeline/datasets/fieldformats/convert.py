"""A checked mapping + the rig's files -> a measured dataset (MODELS.md §7) in SI units, with a record of every
conversion.  Every problem raises FieldFormatError naming the file and the channel or property."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from pipeline.core.units import QUANTITY_OF, UnitError, column_factor
from pipeline.datasets.fieldformats.base import Channel, FieldFormatError, Source, did_you_mean, join
from pipeline.datasets.fieldformats.mapping import ChannelSpec, FromFile, Mapping, RunSpec, Value
from pipeline.datasets.measured import CONTROL_COLUMNS, OPTIONAL_RUN_COLUMNS, RUN_COLUMNS, SERIES_SIGNALS, Dataset

MIN_SAMPLES = 16
"""The fewest samples a §7 series may hold (pipeline.datasets.measured)."""


@dataclass(frozen=True)
class Conversion:
    """``signal`` of a run read from ``channel`` in ``unit``, times ``factor`` to SI."""

    signal: str
    channel: str
    unit: str
    factor: float


@dataclass(frozen=True)
class ImportedRun:
    """What was read for one run: ``samples`` at ``rate_hz`` [Hz], time taken from ``time_from``."""

    run_id: str
    file: Path | None
    group: str
    samples: int
    rate_hz: float
    time_from: str
    conversions: tuple[Conversion, ...]


@dataclass(frozen=True)
class ImportResult:
    """The dataset (SI, §7 columns) and a record per run of how it was read."""

    dataset: Dataset
    runs: tuple[ImportedRun, ...]


def _unit_of(spec: ChannelSpec, ch: Channel, where: str) -> tuple[str, float]:
    """(unit, factor to the signal's SI unit): the mapping's or the file's; they must agree when both are given."""
    if spec.unit is None and ch.unit is None:
        raise FieldFormatError(f"{where}: no unit (the file states none); add 'unit:' to the channel in the mapping, "
                               f"e.g. {{channel: {spec.channel}, unit: ...}}")
    unit = spec.unit if spec.unit is not None else ch.unit
    try:
        factor = column_factor(spec.signal, unit)
    except UnitError as e:
        src = "mapping" if spec.unit is not None else "file"
        raise FieldFormatError(f"{where}, unit from the {src}: {e}") from None
    if spec.unit is not None and ch.unit is not None:
        try:
            same = column_factor(spec.signal, ch.unit) == factor
        except UnitError:
            same = False
        if not same:
            raise FieldFormatError(f"{where}: the mapping says unit '{spec.unit}' but the file says '{ch.unit}'; "
                                   f"make them agree (a mapping's unit is for channels the file leaves without one)")
    return unit, factor


def _finite(values: np.ndarray, where: str) -> np.ndarray:
    try:
        vals = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise FieldFormatError(f"{where}: not numeric data") from None
    bad = ~np.isfinite(vals)
    if bad.any():
        i = int(np.argmax(bad))
        raise FieldFormatError(f"{where}: sample {i} is {vals[i]} (every sample must be a finite number)")
    return vals


def _channel(src: Source, run: RunSpec, path: str, what: str) -> Channel:
    full = join(run.group, path)
    try:
        return src.channel(full)
    except KeyError:
        raise FieldFormatError(f"{src.path}: no channel '{full}' ({what} of run '{run.run_id}')"
                               f"{did_you_mean(full, src.channels())}") from None


def _property(src: Source, run: RunSpec, name: str, where: str) -> object:
    """Property ``name`` of the run's group, else of the file."""
    props = {**src.properties(""), **(src.properties(run.group) if run.group else {})}
    if name not in props:
        raise FieldFormatError(f"{where}: {src.path} has no property '{name}'{did_you_mean(name, list(props))}")
    return props[name]


def _value(src: Source, run: RunSpec, column: str, value: Value, where: str) -> object:
    """A column's value, read from the file and converted when it is a FromFile."""
    if not isinstance(value, FromFile):
        return value
    raw = _property(src, run, value.name, where)
    try:
        num = float(raw)
    except (TypeError, ValueError):
        if value.unit is None and column not in QUANTITY_OF and isinstance(raw, str):
            return raw                                           # a text column: system, preset, ...
        raise FieldFormatError(f"{where}: property '{value.name}' of {src.path} is '{raw}', not a number") from None
    if value.unit is None:
        return num
    try:
        return num * column_factor(column, value.unit)
    except UnitError as e:
        raise FieldFormatError(f"{where}: {e}") from None


def _time(src: Source, run: RunSpec, n: int, chans: dict[str, Channel], where: str) -> tuple[np.ndarray, str]:
    """t_s [s] of a run with ``n`` samples, and where it came from."""
    spec = run.time
    if spec.channel is not None:
        ch = _channel(src, run, spec.channel, "time")
        cw = f"{src.path}, channel '{join(run.group, spec.channel)}' (t_s)"
        unit, factor = _unit_of(ChannelSpec("t_s", spec.channel, spec.unit), ch, cw)
        t = _finite(ch.values, cw)
        if len(t) != n:
            raise FieldFormatError(f"{cw}: {len(t)} samples, but the signals of run '{run.run_id}' hold {n}")
        dt = np.diff(t)
        if (dt <= 0).any():
            i = int(np.argmax(dt <= 0)) + 1
            raise FieldFormatError(f"{cw}: time is not increasing at sample {i} ({t[i - 1]:.9g} then {t[i]:.9g})")
        t0 = t[0] if spec.start == "first" else float(spec.start)
        return (t - t0) * factor, f"channel {spec.channel} [{unit}]"
    if spec.rate_hz is not None:
        rate = float(_value(src, run, "frequency_hz", spec.rate_hz, f"{where}.time.rate_hz"))
        if not rate > 0:
            raise FieldFormatError(f"{where}.time.rate_hz: must be > 0, got {rate:g}")
        return np.arange(n) / rate, f"rate {rate:g} Hz"
    steps = {sig: ch.step_s for sig, ch in chans.items()}
    missing = [s for s, st in steps.items() if st is None]
    if missing:
        spec0 = next(c for c in run.channels if c.signal == missing[0])
        raise FieldFormatError(f"{src.path}, channel '{join(run.group, spec0.channel)}': no sample interval in the "
                               f"file (wf_increment); give time: {{channel: NAME, unit: UNIT}} or time: {{rate_hz: "
                               f"RATE}} in the mapping")
    first = next(iter(steps.values()))
    odd = next((s for s, st in steps.items() if abs(st - first) > 1e-9 * first), None)
    if odd is not None:
        raise FieldFormatError(f"{src.path}: run '{run.run_id}' channels sample at different intervals "
                               f"({first:g} s and {steps[odd]:g} s for {odd}); import them as separate runs")
    return np.arange(n) * first, f"wf_increment {first:g} s"


def _read_run(src: Source | None, run: RunSpec) -> tuple[pd.DataFrame | None, dict, dict, ImportedRun]:
    """(series, runs.csv row, summary row, record) of one run; no series for a summary-only run."""
    where = f"run '{run.run_id}'"
    if not run.channels:
        row = {col: _value(src, run, col, v, f"{where}.{col}") for col, v in run.columns}
        summary = {col: _value(src, run, col, v, f"{where}.summary.{col}") for col, v in run.summary}
        return None, row, summary, ImportedRun(run_id=run.run_id, file=run.file, group=run.group, samples=0,
                                               rate_hz=float("nan"), time_from="", conversions=())
    chans: dict[str, Channel] = {}
    data: dict[str, np.ndarray] = {}
    conv = []
    for spec in run.channels:
        ch = _channel(src, run, spec.channel, spec.signal)
        cw = f"{src.path}, channel '{join(run.group, spec.channel)}' ({spec.signal})"
        unit, factor = _unit_of(spec, ch, cw)
        vals = _finite(ch.values, cw)
        chans[spec.signal] = ch
        data[spec.signal] = vals * factor
        conv.append(Conversion(spec.signal, join(run.group, spec.channel), unit, factor))
    lengths = {s: len(v) for s, v in data.items()}
    n = next(iter(lengths.values()))
    odd = next((s for s, m in lengths.items() if m != n), None)
    if odd is not None:
        first = next(iter(lengths))
        raise FieldFormatError(f"{src.path}: run '{run.run_id}' channels differ in length ({first}: {n} samples, "
                               f"{odd}: {lengths[odd]})")
    if n < MIN_SAMPLES:
        raise FieldFormatError(f"{src.path}: run '{run.run_id}' holds {n} samples (need at least {MIN_SAMPLES})")
    t, time_from = _time(src, run, n, chans, where)
    dt = float(np.median(np.diff(t))) if n > 1 else float("nan")
    keep = t >= -0.5 * dt                                 # samples before the record's t = 0 are not part of it
    series = pd.DataFrame({"t_s": t[keep], **{s: data[s][keep] for s in SERIES_SIGNALS if s in data}})
    row = {col: _value(src, run, col, v, f"{where}.{col}") for col, v in run.columns}
    if "duration_s" not in row:
        row["duration_s"] = float(keep.sum()) * dt
    summary = {col: _value(src, run, col, v, f"{where}.summary.{col}") for col, v in run.summary}
    rec = ImportedRun(run_id=run.run_id, file=src.path, group=run.group, samples=int(keep.sum()), rate_hz=1.0 / dt,
                      time_from=time_from, conversions=tuple(conv))
    return series, row, summary, rec


def import_runs(mapping: Mapping, open_file: Callable[[Path, str | None], Source]) -> ImportResult:
    """Read every run of ``mapping`` through ``open_file(path, format)`` (the reader registry) into a Dataset
    in SI units; each file is opened once."""
    sources: dict[Path, Source] = {}
    rows, summaries, series, recs = [], [], {}, []
    try:
        for run in mapping.runs:
            if run.file is not None and run.file not in sources:
                if not run.file.is_file():
                    raise FieldFormatError(f"{mapping.label} run '{run.run_id}': file not found ({run.file})")
                sources[run.file] = open_file(run.file, run.format)
            s, row, summ, rec = _read_run(sources.get(run.file), run)
            if s is not None:
                series[run.run_id] = s
            rows.append(row)
            if summ:
                summaries.append({"run_id": run.run_id, **summ})
            recs.append(rec)
    finally:
        for src in sources.values():
            src.close()
    first = [c for c in (*RUN_COLUMNS, *CONTROL_COLUMNS, *OPTIONAL_RUN_COLUMNS)
             if any(c in r for r in rows)]
    cols = list(dict.fromkeys(first + [c for r in rows for c in r]))
    runs = pd.DataFrame([{c: r.get(c, np.nan) for c in cols} for r in rows], columns=cols)
    summary = pd.DataFrame(summaries).set_index("run_id") if summaries else None
    return ImportResult(dataset=Dataset(runs=runs, series=series, summary=summary), runs=tuple(recs))
