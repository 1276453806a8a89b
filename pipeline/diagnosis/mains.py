"""Mains hum on a record's channels: fitted where it stands apart from the forcing harmonics, allowed for where it
sits on one.

A force or acceleration channel picks up the mains (50 or 60 Hz and its harmonics) through its cable, with a phase
of its own in every run.  A hum line between two forcing harmonics is fitted beside them (two columns more in the
least-squares design: it leaks neither into the harmonics nor into the model's comparison).  A hum line on a
forcing harmonic (within ``TOUCH`` / T of k f, T the record's length) cannot be told from the signal there, so
that harmonic's two features carry the hum's amplitude, measured on the log's other runs, in their sd (a random
phase: A / √2 per part).  A channel has hum at a mains frequency when one of its lines stands ``HUM_Z`` sd above
the noise on at least two runs and half of those where it can be measured (``detect``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MAINS_HZ = (50.0, 60.0)
"""The mains frequencies looked for [Hz]."""
HUM_Z = 8.0
"""A line's amplitude over its sd that makes it hum."""
TOUCH = 2.0
"""A mains harmonic within this many 1/T of a forcing harmonic sits on it (T: the record's length)."""
LINE_MAX_FRACTION = 0.45
"""Mains harmonics are looked for up to this fraction of the sampling rate (an anti-alias filter's pass band)."""
LOCAL_BINS = 25
"""Periodogram bins either side of a line whose level is the noise it is measured against."""


@dataclass(frozen=True)
class Line:
    """A mains harmonic measured on one run's channel."""

    mains_hz: float
    """Its family: 50 or 60 Hz."""
    harmonic: int
    """m: the line is at m × mains_hz."""
    amplitude: float
    """Its amplitude [the channel's unit]."""
    z: float
    """The amplitude over its sd [-]."""


def mains_lines(f: float, k_max: int, duration_s: float, fs_hz: float,
                families: tuple[float, ...] = MAINS_HZ) -> tuple[list[tuple[float, int]], dict[tuple[float, int], int]]:
    """The mains harmonics (family, m) up to the features' highest harmonic (k_max + ½) f and LINE_MAX_FRACTION fs:
    (those apart from every forcing harmonic, {those on one: its k})."""
    top = min((k_max + 0.5) * f, LINE_MAX_FRACTION * fs_hz)
    apart, on = [], {}
    for fm in families:
        for m in range(1, int(math.floor(top / fm)) + 1):
            k = int(round(m * fm / f))
            if 1 <= k <= k_max and abs(m * fm - k * f) < TOUCH / duration_s:
                on[(fm, m)] = k
            else:
                apart.append((fm, m))
    return apart, on


def line_columns(t: np.ndarray, lines: list[tuple[float, int]]) -> np.ndarray:
    """cos, sin columns of the lines (family, m) at times ``t`` [s], (N, 2 len(lines)), distinct frequencies only."""
    freqs = sorted({fm * m for fm, m in lines})
    w = 2.0 * math.pi * np.outer(t, freqs)
    return np.column_stack([np.cos(w), np.sin(w)]) if freqs else np.zeros((t.size, 0))


def measure(t: np.ndarray, res: np.ndarray, lines: list[tuple[float, int]], power: np.ndarray,
            df: float) -> list[Line]:
    """Each line's amplitude on the residual ``res`` of a harmonic fit (the lines apart from the harmonics are
    nearly orthogonal to them) and its z against the level of the residual's periodogram ``power`` (bins ``df``
    [Hz] apart, white noise of sd σ reading σ²) within LOCAL_BINS bins of it."""
    if not lines or res.size < 8:
        return []
    n = res.size
    per_family = {}
    for fm, m in lines:
        per_family.setdefault(fm, []).append(m)
    out = []
    for fm, ms in per_family.items():
        freqs = np.array([fm * m for m in ms])          # increasing, as line_columns orders them
        c = np.linalg.lstsq(line_columns(t, [(fm, m) for m in ms]), res, rcond=None)[0]
        amp = np.hypot(c[:freqs.size], c[freqs.size:])
        for m, fl, am in zip(ms, freqs, amp):
            j = int(round(fl / df))
            near = np.r_[max(j - LOCAL_BINS, 1):max(j - 3, 1), j + 4:min(j + LOCAL_BINS + 1, power.size)]
            level = float(np.median(power[near])) / math.log(2.0) if near.size else float(np.mean(power[1:]))
            sd = math.sqrt(2.0 * max(level, 1e-300) / n)
            out.append(Line(fm, int(m), float(am), float(am / sd)))
    return out


Hum = dict
"""channel -> mains frequency [Hz] -> {m: amplitude [channel unit]}: the hum found on a log (``detect``)."""


def detect(per_run: list[dict[str, list[Line]]]) -> Hum:
    """The hum of a log from each series run's measured lines (channel -> lines): a channel has hum at a mains
    frequency where one of its lines stands HUM_Z sd out on at least two runs and on at least half of the runs that
    measured it (a subharmonic or a transient of one run is not hum); its amplitude per harmonic m is the median
    over the runs that measured it."""
    seen: dict[tuple[str, float, int], list[Line]] = {}
    for lines in per_run:
        for sig, ls in lines.items():
            for ln in ls:
                seen.setdefault((sig, ln.mains_hz, ln.harmonic), []).append(ln)
    found = {(sig, fm) for (sig, fm, _), lns in seen.items()
             if (hits := sum(ln.z > HUM_Z for ln in lns)) >= 2 and 2 * hits >= len(lns)}
    out: Hum = {}
    for (sig, fm, m), lns in sorted(seen.items()):
        if (sig, fm) in found:
            out.setdefault(sig, {}).setdefault(fm, {})[m] = float(np.median([ln.amplitude for ln in lns]))
    return out


def amplitude(hum: Hum, sig: str, fm: float, m: int) -> float:
    """The hum's amplitude at m × fm on a channel: as measured, else (never apart from a forcing harmonic) the
    largest of its family's measured lines."""
    amps = hum[sig][fm]
    return amps.get(m, max(amps.values()))


def as_record(hum: Hum) -> dict[str, dict[str, float]]:
    """channel -> {line frequency [Hz] as text: amplitude [channel unit]} (report.json)."""
    return {sig: {f"{fm * m:g}": a for fm, amps in fams.items() for m, a in amps.items()} for sig, fams in hum.items()}


def describe(hum: Hum) -> str:
    """One line per channel: the hum's family and amplitudes."""
    parts = []
    for sig, fams in hum.items():
        for fm, amps in fams.items():
            parts.append(f"{sig} at {fm:g} Hz (" + ", ".join(f"{a:.3g} at {m * fm:g} Hz" for m, a in amps.items())
                         + ")")
    return "; ".join(parts)


def allow_for(tg, hum: Hum) -> None:
    """Put the hum on ``tg``'s harmonic features that a mains line sits on into their sd (and noise sd): A / √2 per
    part, A the channel's amplitude at that line (``amplitude``); a note names the run, channel and harmonics."""
    tg.hum = hum
    families = tuple({fm for v in hum.values() for fm in v})
    _, on = mains_lines(tg.frequency_hz, tg.k_max, tg.duration_s, tg.fs_hz, families)
    where = {}
    for j, (sig, k) in enumerate(tg.pairs):
        for (fm, m), kk in on.items():
            if kk == k and fm in hum.get(sig, {}):
                a = amplitude(hum, sig, fm, m) / math.sqrt(2.0)
                at = int(tg.pair_at[j])
                tg.sd[at:at + 2] = np.hypot(tg.sd[at:at + 2], a)
                tg.noise_sd[at:at + 2] = np.hypot(tg.noise_sd[at:at + 2], a)
                where.setdefault(sig, []).append(k)
    for sig, ks in where.items():
        tg.notes.append(f"run {tg.run_id}, channel {sig}: mains hum on harmonic(s) {', '.join(map(str, ks))} "
                        f"(a mains line sits on them): their sd include its amplitude")
