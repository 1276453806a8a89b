"""The data-acquisition chain a run was recorded through, as runs.csv declares it (docs/diagnose.md).

A measured signal is instrument(plant(θ), φ): the plant is the model, φ what the recording did to it.  Optional
runs.csv columns declare φ per run (an empty cell: not declared):

- ``daq_filter``    the anti-alias filter: ``butter:order:cutoff_hz`` (analog Butterworth, -3 dB at the cut-off),
  ``ellip:order:cutoff_hz[:ripple_db:stop_db]`` (analog elliptic, cut-off = pass-band edge, default
  ELLIP_RIPPLE_DB and ELLIP_STOP_DB), ``fir:taps:cutoff_hz:oversample`` (a delta-sigma ADC's linear-phase decimation
  filter, taps at oversample x fs: a pure delay of (taps - 1) / (2 oversample fs), its pass band taken as flat),
  or ``none``;
- ``daq_delay_s``   a pure delay [s] on top of the filter (what the DAQ's alignment left uncompensated); with a
  ``daq_delay_removed`` column it is instead the filter's own group delay, already in its response, and
  ``daq_delay_removed`` = 1 says the DAQ moved the time stamps back by it (the model is then advanced by it), 0 that
  it stayed in the data;
- ``daq_clock_ppm`` the sample clock's error ε [ppm]: sample n was taken at true record time (1 + ε) n / fs while
  ``t_s`` says n / fs.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

import numpy as np

from pipeline.core.errors import UserError

FILTER_KINDS = ("butter", "ellip", "fir", "none")
ELLIP_RIPPLE_DB = 0.1
"""Pass-band ripple of a declared elliptic filter [dB]."""
ELLIP_STOP_DB = 60.0
"""Stop-band attenuation of a declared elliptic filter [dB]."""
MAX_ORDER = 16
MAX_CLOCK_PPM = 10_000.0
"""A clock error beyond 1 % is not a DAQ's clock but a wrong sampling rate in t_s."""
DAQ_COLUMNS = ("daq_filter", "daq_delay_s", "daq_delay_removed", "daq_clock_ppm")


@dataclass(frozen=True)
class DaqFilter:
    """An anti-alias filter: ``kind`` (FILTER_KINDS but 'none'), ``order`` (fir: taps), ``cutoff_hz``, the elliptic's
    ``ripple_db`` and ``stop_db``, the FIR's delay ``fir_delay_s`` (its taps, oversampling and the run's rate)."""

    kind: str
    order: int
    cutoff_hz: float
    ripple_db: float = ELLIP_RIPPLE_DB
    stop_db: float = ELLIP_STOP_DB
    fir_delay_s: float = 0.0

    def response(self, f_hz: np.ndarray) -> np.ndarray:
        """Complex frequency response H(i 2π f) at ``f_hz``."""
        from scipy import signal

        w = 2.0 * math.pi * np.asarray(f_hz, dtype=float)
        if self.kind == "fir":
            return np.exp(-1j * w * self.fir_delay_s)
        wc = 2.0 * math.pi * self.cutoff_hz
        if self.kind == "butter":
            z, p, k = signal.butter(self.order, wc, analog=True, output="zpk")
        else:
            z, p, k = signal.ellip(self.order, self.ripple_db, self.stop_db, wc, analog=True, output="zpk")
            # an even-order elliptic starts one ripple low at DC; a calibrated channel reads a static signal at gain 1
            k = k / abs(signal.freqs_zpk(z, p, k, worN=[0.0])[1][0])
        return signal.freqs_zpk(z, p, k, worN=w)[1]

    def text(self) -> str:
        return f"{self.kind}:{self.order}:{self.cutoff_hz:g}"


@dataclass(frozen=True)
class DeclaredChain:
    """The recording chain runs.csv declares for a run: a filter (None: none), a pure delay [s], a clock error [ppm]."""

    filter: DaqFilter | None = None
    delay_s: float = 0.0
    clock_ppm: float = 0.0

    def true_times(self, times: np.ndarray, t0: float) -> np.ndarray:
        """The true instants of samples the record dates ``times`` (record time 0 at ``t0``), delayed: the signal a
        sample holds is the plant's at t0 + (1 + ε)(t − t0) − τ."""
        return t0 + (1.0 + 1e-6 * self.clock_ppm) * (times - t0) - self.delay_s

    def gain(self, f_hz: np.ndarray) -> np.ndarray:
        """The filter's complex gain at ``f_hz`` (1 without a filter)."""
        f_hz = np.asarray(f_hz, dtype=float)
        return np.ones(f_hz.shape, dtype=complex) if self.filter is None else self.filter.response(f_hz)


def _number(text: str, what: str, where: str, integer: bool = False) -> float:
    try:
        v = int(text) if integer else float(text)
    except ValueError:
        v = None
    if v is None or not math.isfinite(v) or v <= 0:
        raise UserError(f"{where}: {what} '{text}' is not a positive {'integer' if integer else 'number'}")
    return v


def parse_filter(text: str, where: str, fs: float | None = None) -> DaqFilter | None:
    """A ``daq_filter`` cell (module docstring) or None for ``none``; UserError prefixed ``where`` (file, line,
    column) otherwise.  ``fs``: the run's sampling rate (a FIR's delay)."""
    parts = [p.strip() for p in str(text).split(":")]
    kind = parts[0].lower()
    if kind not in FILTER_KINDS:
        near = difflib.get_close_matches(kind, FILTER_KINDS, n=1)
        hint = f" (did you mean '{near[0]}'?)" if near else ""
        raise UserError(f"{where}: unknown filter kind '{parts[0]}'{hint}; expected kind:order:cutoff_hz with kind "
                        f"one of {', '.join(FILTER_KINDS)}")
    if kind == "none":
        if len(parts) > 1:
            raise UserError(f"{where}: 'none' takes no order or cut-off, got '{text}'")
        return None
    shapes = {"butter": ("order", "cutoff_hz"), "ellip": ("order", "cutoff_hz", "ripple_db", "stop_db"),
              "fir": ("taps", "cutoff_hz", "oversample")}
    ok = len(parts) - 1 == len(shapes[kind]) or (kind == "ellip" and len(parts) == 3)
    if not ok:
        raise UserError(f"{where}: expected {kind}:{':'.join(shapes[kind])}"
                        + (" (ripple and stop band optional)" if kind == "ellip" else "") + f", got '{text}'")
    order = int(_number(parts[1], "filter order" if kind != "fir" else "tap count", where, integer=True))
    if kind != "fir" and order > MAX_ORDER:
        raise UserError(f"{where}: filter order must be 1..{MAX_ORDER}, got {order}")
    fc = _number(parts[2], "filter cut-off [Hz]", where)
    if kind == "ellip" and len(parts) == 5:
        return DaqFilter(kind, order, fc, _number(parts[3], "ripple [dB]", where), _number(parts[4], "stop band [dB]", where))
    if kind == "fir":
        over = _number(parts[3], "oversampling", where, integer=True)
        return DaqFilter(kind, order, fc, fir_delay_s=(order - 1) / (2.0 * over * fs) if fs else 0.0)
    return DaqFilter(kind, order, fc)


def declared_chains(runs, fs_of: dict[str, float], label: str = "runs.csv") -> dict[str, DeclaredChain]:
    """Run id -> its declared chain, for the runs with at least one DAQ column filled; UserError naming ``label``,
    the line and the column for a bad value (a filter at or above the Nyquist frequency of the run's series,
    ``fs_of``, is one too)."""
    cols = [c for c in DAQ_COLUMNS if c in runs.columns]
    out: dict[str, DeclaredChain] = {}
    for i, row in enumerate(runs.to_dict("records")):
        line = i + 2
        cells = {c: str(row[c]).strip() for c in cols if str(row[c]).strip() not in ("", "nan")}
        if not cells:
            continue
        filt = None
        fs = fs_of.get(row["run_id"])
        if "daq_filter" in cells:
            filt = parse_filter(cells["daq_filter"], f"{label} line {line}, column 'daq_filter'", fs)
            if filt is not None and fs and filt.cutoff_hz >= fs / 2:
                raise UserError(f"{label} line {line}, column 'daq_filter': cut-off {filt.cutoff_hz:g} Hz is at or "
                                f"above the Nyquist frequency {fs / 2:g} Hz of series/{row['run_id']}.csv")
        num = {}
        for c, lim in (("daq_delay_s", 1.0), ("daq_clock_ppm", MAX_CLOCK_PPM), ("daq_delay_removed", 1.0)):
            if c not in cells:
                continue
            try:
                v = float(cells[c])
            except ValueError:
                v = float("nan")
            if not math.isfinite(v):
                raise UserError(f"{label} line {line}, column '{c}': '{cells[c]}' is not a finite number")
            if abs(v) > lim:
                raise UserError(f"{label} line {line}, column '{c}': |{v:g}| exceeds {lim:g}")
            num[c] = v
        delay = num.get("daq_delay_s", 0.0)
        if "daq_delay_removed" in num:      # the delay is the filter's own: in its response, or removed by the DAQ
            if num["daq_delay_removed"] not in (0.0, 1.0):
                raise UserError(f"{label} line {line}, column 'daq_delay_removed': must be 0 or 1, "
                                f"got '{cells['daq_delay_removed']}'")
            delay = -delay if num["daq_delay_removed"] == 1.0 else 0.0
        out[row["run_id"]] = DeclaredChain(filt, delay, num.get("daq_clock_ppm", 0.0))
    return out
