"""Mains hum on a force channel (pipeline/diagnosis/mains.py): found on the log, fitted beside the harmonics where it
stands apart from them, carried in the sd of the harmonics it sits on; a log without hum finds none.

The records are synthetic (no simulator): an impact-like periodic force, white noise, and 50 Hz hum of 5, 2 and
1 N at its first three harmonics with a random phase per run (the independent generator's ``hum50`` chain)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipeline.diagnosis import mains
from pipeline.diagnosis.features import Target, series_target, simulated_features
from tests.pipeline.diagnosis.test_daq_chain import _fake_result

FS, K, HUM = 2000.0, 30, (5.0, 2.0, 1.0)


def _force(t: np.ndarray, f: float) -> np.ndarray:
    ph = (f * t) % 1.0
    return 40.0 * np.exp(-((ph - 0.3) / 0.03) ** 2) + 10.0 * np.sin(2 * np.pi * f * t)


def _record(f: float, rng, hum: bool, cycles: float = 40.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(int(cycles / f * FS)) / FS
    x = _force(t, f) + 0.3 * rng.standard_normal(t.size)
    if hum:
        x += sum(a * np.cos(2 * np.pi * 50.0 * (m + 1) * t + rng.uniform(0, 2 * np.pi)) for m, a in enumerate(HUM))
    return t, x


def _target(t: np.ndarray, x: np.ndarray, f: float, hum_hz: tuple = ()) -> Target:
    tg = Target(run_id=f"r{f:g}", system="rimd", kind="", controls={"frequency_hz": f}, duration_s=t.size / FS)
    return series_target(tg, pd.DataFrame({"t_s": t, "force_n": x}), K * f, hum_hz=hum_hz)


FREQS = (5.0, 6.5, 7.5, 9.0)      # 50 Hz is the 10th harmonic of 5 Hz; apart from the others' harmonics


def _log(hum: bool, seed: int = 0) -> dict[float, tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return {f: _record(f, rng, hum) for f in FREQS}


def test_hum_is_found_with_its_amplitudes_and_a_log_without_it_finds_none():
    hum = mains.detect([_target(t, x, f).lines for f, (t, x) in _log(True).items()])
    assert set(hum) == {"force_n"} and set(hum["force_n"]) == {50.0}
    assert [hum["force_n"][50.0][m] for m in (1, 2, 3)] == pytest.approx(HUM, rel=0.05)
    assert mains.detect([_target(t, x, f).lines for f, (t, x) in _log(False).items()]) == {}


def test_a_line_in_one_run_only_is_not_hum():
    """A component at 50 Hz in one run (a subharmonic, a transient) is that run's, not the mains'."""
    lines = []
    for f, (t, x) in _log(False).items():
        if f == 7.5:
            x = x + 5.0 * np.cos(2 * np.pi * 50.0 * t)
        lines.append(_target(t, x, f).lines)
    assert max(ln.z for ln in lines[2]["force_n"]) > 50 * mains.HUM_Z
    assert mains.detect(lines) == {}


def test_hum_apart_from_the_harmonics_is_fitted_out_and_on_one_is_carried_in_its_sd():
    """The true force through each target's operator, against its features: 50 Hz hum leaks into the neighbouring
    harmonics of the 6.5 Hz run (a finite record) unless fitted beside them, and sits on the 10th harmonic of the
    5 Hz run, where only its amplitude in the sd makes the residual noise-sized."""
    log = _log(True, seed=1)
    hum = mains.detect([_target(t, x, f).lines for f, (t, x) in log.items()])
    z = {}
    for f in (5.0, 6.5):
        t, x = log[f]
        naive, handled = _target(t, x, f), _target(t, x, f, hum_hz=(50.0,))
        mains.allow_for(handled, hum)
        z[f] = [float(np.max(np.abs(simulated_features(tg, _fake_result(tg.t_rec, {"force_n": _force(tg.t_rec, f)}))
                                    - tg.y) / tg.sd)) for tg in (naive, handled)]
    assert z[6.5][0] > 6.0 and z[6.5][1] < 4.5
    assert z[5.0][0] > 100.0 and z[5.0][1] < 4.5
    t, x = log[5.0]
    handled = _target(t, x, 5.0, hum_hz=(50.0,))
    mains.allow_for(handled, hum)
    assert any("harmonic(s) 10, 20, 30" in n for n in handled.notes)
