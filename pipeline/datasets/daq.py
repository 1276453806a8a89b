"""The data-acquisition chain a run was recorded through, as runs.csv declares it (docs/diagnose.md).

A measured signal is instrument(plant(θ), φ): the plant is the model, φ what the recording did to it.  Three
optional runs.csv columns declare φ per run (an empty cell: not declared):

- ``daq_filter``    ``kind:order:cutoff_hz`` — the anti-alias filter, an analog prototype of ``kind`` ``butter``
  (Butterworth) or ``ellip`` (elliptic, ELLIP_RIPPLE_DB pass-band ripple, ELLIP_STOP_DB stop-band attenuation,
  cut-off = pass-band edge), or ``none``;
- ``daq_delay_s``   a pure delay [s] (what DAQ alignment left uncompensated, or a digital filter's group delay);
- ``daq_clock_ppm`` the sample clock's error ε [ppm]: sample n was taken at true record time (1 + ε) n / fs while
  ``t_s`` says n / fs.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

import numpy as np

from pipeline.core.errors import UserError

FILTER_KINDS = ("butter", "ellip", "none")
ELLIP_RIPPLE_DB = 0.1
"""Pass-band ripple of a declared elliptic filter [dB]."""
ELLIP_STOP_DB = 60.0
"""Stop-band attenuation of a declared elliptic filter [dB]."""
MAX_ORDER = 16
MAX_CLOCK_PPM = 10_000.0
"""A clock error beyond 1 % is not a DAQ's clock but a wrong sampling rate in t_s."""
DAQ_COLUMNS = ("daq_filter", "daq_delay_s", "daq_clock_ppm")


@dataclass(frozen=True)
class DaqFilter:
    """An analog anti-alias filter: ``kind`` (FILTER_KINDS but 'none'), ``order``, ``cutoff_hz``."""

    kind: str
    order: int
    cutoff_hz: float

    def response(self, f_hz: np.ndarray) -> np.ndarray:
        """Complex frequency response H(i 2π f) at ``f_hz``."""
        from scipy import signal

        wc = 2.0 * math.pi * self.cutoff_hz
        if self.kind == "butter":
            z, p, k = signal.butter(self.order, wc, analog=True, output="zpk")
        else:
            z, p, k = signal.ellip(self.order, ELLIP_RIPPLE_DB, ELLIP_STOP_DB, wc, analog=True, output="zpk")
        return signal.freqs_zpk(z, p, k, worN=2.0 * math.pi * np.asarray(f_hz, dtype=float))[1]


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


def parse_filter(text: str, where: str) -> DaqFilter | None:
    """``kind:order:cutoff_hz`` or ``none`` (None); UserError prefixed ``where`` (file, line, column) otherwise."""
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
    if len(parts) != 3:
        raise UserError(f"{where}: expected {kind}:order:cutoff_hz (e.g. {kind}:4:4000), got '{text}'")
    try:
        order = int(parts[1])
    except ValueError:
        raise UserError(f"{where}: filter order '{parts[1]}' is not an integer") from None
    if not 1 <= order <= MAX_ORDER:
        raise UserError(f"{where}: filter order must be 1..{MAX_ORDER}, got {order}")
    try:
        fc = float(parts[2])
    except ValueError:
        fc = float("nan")
    if not math.isfinite(fc) or fc <= 0:
        raise UserError(f"{where}: filter cut-off '{parts[2]}' is not a positive number of Hz")
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
        if "daq_filter" in cells:
            filt = parse_filter(cells["daq_filter"], f"{label} line {line}, column 'daq_filter'")
            fs = fs_of.get(row["run_id"])
            if filt is not None and fs and filt.cutoff_hz >= fs / 2:
                raise UserError(f"{label} line {line}, column 'daq_filter': cut-off {filt.cutoff_hz:g} Hz is at or "
                                f"above the Nyquist frequency {fs / 2:g} Hz of series/{row['run_id']}.csv")
        num = {}
        for c, lim in (("daq_delay_s", 1.0), ("daq_clock_ppm", MAX_CLOCK_PPM)):
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
        out[row["run_id"]] = DeclaredChain(filt, num.get("daq_delay_s", 0.0), num.get("daq_clock_ppm", 0.0))
    return out
