"""Measured data as rigs record it (MODELS.md §7): any DAQ rate, partial cycles, per-system
controls, presets and parameter columns, record_start_s, and one clear line for every bad input."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.diagnosis.features import Target, check_resolution, harmonic_fit, noise_sd, series_target
from pipeline.core.errors import UserError
from pipeline.datasets.measured import load_dataset


def _signal(f: float, fs: float, cycles: float, noise: float = 0.0, drift: float = 0.0, seed: int = 0):
    """3 cos(Ωt) + 2 sin(3Ωt) + 5 + drift·t + white noise, sampled at fs for a non-whole number of cycles."""
    t = np.arange(int(cycles / f * fs)) / fs
    rng = np.random.default_rng(seed)
    x = 3 * np.cos(2 * np.pi * f * t) + 2 * np.sin(6 * np.pi * f * t) + 5.0 + drift * t
    return t, x + noise * rng.standard_normal(t.size)


@pytest.mark.parametrize("f, fs", [(30.0, 10000.0), (70.0, 10000.0), (90.0, 25600.0), (287.3, 51200.0)])
def test_harmonics_at_any_daq_rate(f, fs):
    """Forcing frequencies that do not divide the DAQ rate (the issue's 30/70/90 Hz at 10 kHz) and 17.3 cycles:
    c1 = 3, c3 = -2i (c_k = a_k - i b_k) within 5 sd of the white-noise coefficient sd 0.1·sqrt(2/N)."""
    t, x = _signal(f, fs, 17.3, noise=0.1)
    hf = harmonic_fit(t, x, f, 5)
    sd_c = 0.1 * math.sqrt(2.0 / t.size)
    assert abs(hf.c[0] - 3.0) < 5 * sd_c and abs(hf.c[2] - (-2j)) < 5 * sd_c
    assert np.all(np.abs(hf.c[[1, 3, 4]]) < 5 * sd_c)
    # the spectral estimator (features.record_noise) averages the periodogram between the harmonics: ~8 % sd with
    # 5 harmonics and 17 cycles (2500-3100 samples), so 3 sd is 25 %
    assert noise_sd(t, x, f, 5) == pytest.approx(0.1, rel=0.25)


def test_drift_is_fitted_and_noise_ignores_impacts():
    """A drift of 2 /s is the fitted slope (regression se = σ sqrt(12/N)/T ~ 5e-3 here, so 4 se = 1 %);
    the noise estimate of a signal with sharp once-per-cycle spikes (impacts, harmonics far above K) stays at
    the white-noise sd."""
    f, fs = 47.0, 10000.0
    t, x = _signal(f, fs, 12.6, noise=0.02, drift=2.0)
    hf = harmonic_fit(t, x, f, 3)
    assert hf.slope == pytest.approx(2.0, abs=4 * hf.slope_se) and hf.slope_se < 0.01
    spikes = 50.0 * np.exp(-((np.mod(t * f, 1.0) - 0.3) / 0.01) ** 2)     # 1000x the noise, 1 % of a cycle wide
    assert noise_sd(t, x + spikes, f, 3) == pytest.approx(0.02, rel=0.15)
    a = np.column_stack([np.ones_like(t), t] + [g(2 * np.pi * k * f * t) for k in (1, 2, 3) for g in (np.cos, np.sin)])
    resid = x + spikes - a @ np.linalg.lstsq(a, x + spikes, rcond=None)[0]
    assert resid.std() > 10 * 0.02          # a least-squares residual would have called the spikes noise


def test_resolution_errors_name_the_run_and_numbers():
    t = np.arange(300) / 10000.0
    with pytest.raises(UserError, match=r"series/r7.csv: the record holds 1.80 forcing cycles of 60 Hz"):
        check_resolution("r7", t, 60.0, 3)
    t = np.arange(3000) / 2000.0
    with pytest.raises(UserError, match=r"series/r8.csv: sampling rate 2000 Hz cannot resolve harmonic 20 of "
                                        r"60 Hz \(1200 Hz >= Nyquist 1000 Hz\)"):
        check_resolution("r8", t, 60.0, 20)


def test_series_target_from_rest_uses_absolute_time():
    """With record_start_s the basis is the time since the start of excitation: a record of cos(Ω t_abs)
    starting 0.1234 s into the run has c1 = 1 (not a phase-shifted coefficient)."""
    f, fs, rs = 60.0, 10000.0, 0.1234
    t = np.arange(2000) / fs
    df = pd.DataFrame({"t_s": t, "accel_m_s2": np.cos(2 * np.pi * f * (t + rs))})
    tg = series_target(Target(run_id="r", system="drill", controls={"frequency_hz": f}, kind="",
                              record_start_s=rs), df, 200.0)
    assert tg.k_max == 3 and tg.fs_hz == pytest.approx(fs)
    assert tg.y[0] == pytest.approx(1.0, abs=1e-9) and tg.y[1] == pytest.approx(0.0, abs=1e-9)


# ----------------------------------------------------------------------------- runs.csv per system
def _ds(tmp_path: Path, runs: str, fs: float = 10000.0) -> Path:
    d = tmp_path / "ds"
    (d / "series").mkdir(parents=True)
    (d / "runs.csv").write_text(runs)
    header, *lines = runs.strip().splitlines()
    for line in lines:
        row = dict(zip(header.split(","), line.split(",")))
        f = float(row["frequency_hz"])
        try:
            cycles = float(row["duration_s"]) * f          # the record runs.csv says
        except (KeyError, ValueError):
            cycles = 5.5                                    # a malformed row: runs.csv's own check names it
        t, x = _signal(f, fs, cycles)
        rid = row["run_id"]
        pd.DataFrame({"t_s": t, "accel_m_s2": x}).to_csv(d / "series" / f"{rid}.csv", index=False)
    return d


MIXED = ("run_id,system,frequency_hz,amplitude_n,amplitude_m,static_force_n,gap_m,duration_s,preset,M1,record_start_s\n"
         "d1,drill,213,2250,,1200,0,0.05,lab,61.5,0.4\n"
         "p1,pendulum,3.75,,0.00089,,0,2.0,,,\n"
         "q1,rimd,8,1,,,0,2.0,gap-0,,\n")


def test_mixed_systems_controls_presets_and_parameter_columns(tmp_path):
    ds = load_dataset(_ds(tmp_path, MIXED))
    assert ds.known["d1"]["M1"] == 61.5 and ds.known["d1"]["K1"] == 6e8       # explicit column over preset 'lab'
    assert "M1" not in ds.known["p1"] and ds.known["q1"] == {}                 # rimd gap-0 preset: controls only
    assert ds.runs.set_index("run_id").loc["d1", "record_start_s"] == 0.4
    assert np.isnan(ds.runs.set_index("run_id").loc["p1", "record_start_s"])   # empty: steady state


@pytest.mark.parametrize("old, new, where", [
    ("lab,61.5", "labx,61.5", "runs.csv line 2, column 'preset': unknown preset 'labx' for system drill"),
    (",,\nq1", ",3,\nq1", "runs.csv line 3, column 'M1': 'M1' is not a parameter of system pendulum"),
    ("lab,61.5", "lab,heavy", "runs.csv line 2, column 'M1': 'heavy' is not a number"),
    ("lab,61.5", "lab,-2", "runs.csv line 2, column 'M1'"),
    ("3.75,,0.00089", "3.75,,abc", "runs.csv line 3, column 'amplitude_m'"),
    ("3.75,,0.00089,,", "3.75,,0.00089,5,", "runs.csv line 3, column 'static_force_n': system pendulum has no "
                                              "parameter 'static_force_n'"),
    ("0.05,lab,61.5,0.4", "0.05,lab,61.5,-1", "runs.csv line 2, column 'record_start_s': must be >= 0"),
])
def test_bad_rig_parameters_are_named(tmp_path, old, new, where):
    assert old in MIXED
    with pytest.raises(UserError, match=where.replace("(", r"\(").replace(")", r"\)")):
        load_dataset(_ds(tmp_path, MIXED.replace(old, new, 1)))


def test_pendulum_needs_amplitude_m(tmp_path):
    runs = MIXED.replace(",amplitude_m", "").replace(",,0.00089", "").replace("2250,,", "2250,").replace("1,,,", "1,,")
    with pytest.raises(UserError, match="runs.csv: missing column 'amplitude_m' .needed by run 'p1', system pendulum"):
        load_dataset(_ds(tmp_path, runs))


# ----------------------------------------------------------------------------- targets of a whole dataset
def test_undersampled_run_is_named_by_diagnose(tmp_path, capsys):
    """d1 (drill, 213 Hz) at a 5 kHz DAQ: the drill's features go to 3 kHz (ModelSpec.diagnose_max_harmonic_hz),
    harmonic 14 = 2982 Hz is above Nyquist 2500 Hz; `vibro diagnose` says so in one line naming the run."""
    from pipeline.cli import main

    d = _ds(tmp_path, MIXED, fs=5000.0)
    assert main(["diagnose", str(d), "--out", str(tmp_path / "out"), "--quiet", "--no-mlflow"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "series/d1.csv: sampling rate 5000 Hz cannot resolve harmonic 14 of 213 Hz" in err[0]
    assert not (tmp_path / "out").exists()


def test_summary_only_runs_and_signal_subsets_make_targets(tmp_path):
    """A drill day: d1 logged the accelerometer only, from rest (record_start_s 0.4 s); d2 only a summary.
    Both become targets of the drill with the preset's rock; d1's features are its accel harmonics and the
    record's own time base is kept for the model (t_rec)."""
    from pipeline.diagnosis.run import DiagnoseConfig, build_targets

    runs = ("run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s,preset,record_start_s\n"
            "d1,drill,213,2250,1200,0,0.05,lab,0.4\n"
            "d2,drill,307,2250,1200,0,0.05,lab,\n")
    d = tmp_path / "ds"
    (d / "series").mkdir(parents=True)
    (d / "runs.csv").write_text(runs)
    t, x = _signal(213.0, 25600.0, 10.65)            # 0.05 s at 25.6 kHz: 1280 samples, not whole cycles
    pd.DataFrame({"t_s": t, "accel_m_s2": x}).to_csv(d / "series" / "d1.csv", index=False)
    (d / "summary.csv").write_text("run_id,rop_m_s,peak_force_n\nd2,0.0031,2700\n")
    targets = {tg.run_id: tg for tg in build_targets(load_dataset(d), DiagnoseConfig())["drill"]}
    d1, d2 = targets["d1"], targets["d2"]
    assert (d1.kind, d1.signals, d1.record_start_s) == ("series", ("accel_m_s2",), 0.4)
    assert d1.k_max == 14 and d1.t_rec.size == t.size and d1.known["K1"] == 6e8
    # 3 cos(Ω t_rec) on the absolute time base t_rec + 0.4 s: c1 = 3 exp(-iΩ 0.4 s) (c = a - i b)
    ph = 2 * np.pi * 213.0 * 0.4
    assert d1.y[:2] == pytest.approx([3 * np.cos(ph), -3 * np.sin(ph)], abs=1e-6)
    assert (d2.kind, d2.names, d2.record_start_s) == ("summary", ["rop_m_s", "peak_force_n"], None)
