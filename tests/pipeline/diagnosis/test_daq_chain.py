"""The recording chain: declared DAQ columns (validated, applied to the model), an undeclared chain estimated as
nuisance (delay per channel and clock), saturated channels (the model clipped at the same range).

The fast tests check the operators on synthetic records (no simulator); the end-to-end cases diagnose a short drill
log of the independent generator whose recording is altered here exactly: a clock error by re-dating ``t_s``
(samples taken every (1 + ε)/fs, written as 1/fs), a delay by declaring the record ``τ`` later than it started."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from pipeline.core.errors import UserError
from pipeline.datasets.daq import DaqFilter, DeclaredChain, parse_filter
from pipeline.diagnosis.features import (MAX_CLIPPED_FRACTION, Target, _coefs, _features, clipped_samples,
                                         sampling_plan, series_target, simulated_features)
from pipeline.diagnosis.instrument import Nuisance
from pipeline.diagnosis.nuisance import profile, profile_items

F, FS, K = 50.0, 10_000.0, 20


def _impacts(t: np.ndarray, tau: float = 0.0, eps: float = 0.0, t0: float = 0.0) -> np.ndarray:
    """A periodic impact-like signal (a sharp pulse once a cycle, every harmonic up to K) at true instants."""
    tt = t0 + (1.0 + eps) * t - tau
    ph = (F * tt) % 1.0
    return np.exp(-((ph - 0.3) / 0.02) ** 2) + 0.3 * np.sin(2 * np.pi * F * tt)


def _target(t_rec: np.ndarray, sigs: dict, record_start: float | None = None) -> Target:
    tg = Target(run_id="r1", system="indenter-metal", kind="", controls={"frequency_hz": F},
                duration_s=t_rec.size / FS, record_start_s=record_start)
    return series_target(tg, pd.DataFrame({"t_s": t_rec, **sigs}), K * F)


def test_filter_column_is_validated_with_a_did_you_mean():
    assert parse_filter("none", "x") is None
    assert parse_filter("butter:4:4000", "x") == DaqFilter("butter", 4, 4000.0)
    with pytest.raises(UserError, match=r"runs.csv line 3, column 'daq_filter': unknown filter kind 'butterworth' "
                                        r"\(did you mean 'butter'\?\)"):
        parse_filter("butterworth:4:4000", "runs.csv line 3, column 'daq_filter'")
    for bad, msg in (("butter:4", "expected butter:order:cutoff_hz"), ("ellip:0:100", "filter order '0' is not a positive integer"), ("butter:40:100", "order must be"),
                     ("butter:4:-5", "not a positive number")):
        with pytest.raises(UserError, match=msg):
            parse_filter(bad, "w")
    h = DaqFilter("butter", 4, 1000.0).response(np.array([10.0, 1000.0]))
    assert parse_filter("ellip:6:3000:0.1:80", "x") == DaqFilter("ellip", 6, 3000.0, 0.1, 80.0)
    fir = parse_filter("fir:129:4000:16", "x", fs=10_000.0)
    assert fir.fir_delay_s == pytest.approx(64 / 160_000.0)        # (taps - 1) / 2 at 16 x fs
    assert abs(h[0]) == pytest.approx(1.0, abs=1e-6) and abs(h[1]) == pytest.approx(2 ** -0.5, rel=1e-9)
    e = DaqFilter("ellip", 6, 1000.0).response(np.array([0.0, 500.0, 3000.0]))
    ripple = 10 ** (0.1 / 20)                                       # the default 0.1 dB pass-band ripple
    assert abs(e[0]) == pytest.approx(1.0, abs=1e-12)               # a calibrated channel: gain 1 at DC
    assert 1 / ripple - 1e-9 < abs(e[1]) < ripple + 1e-9 and abs(e[2]) < 1e-2   # pass band ripple, stop band


def test_bad_daq_cell_is_one_line_naming_the_row(tmp_path):
    from pipeline.datasets.measured import load_dataset

    n = 400
    (tmp_path / "series").mkdir()
    pd.DataFrame({"t_s": np.arange(n) / FS, "accel_m_s2": _impacts(np.arange(n) / FS)}).to_csv(
        tmp_path / "series" / "a.csv", index=False)
    base = "run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s,daq_filter,daq_clock_ppm\n"
    row = f"a,indenter-metal,{F},1,200,0.001,{n / FS}"
    for cells, col in ((",ellipse:4:3000,", "daq_filter"), (",butter:4:6000,", "daq_filter"),
                       (",butter:4:3000,fast", "daq_clock_ppm")):
        (tmp_path / "runs.csv").write_text(base + row + cells + "\n")
        with pytest.raises(UserError) as e:
            load_dataset(tmp_path)
        assert str(e.value).startswith(f"runs.csv line 2, column '{col}'") and "\n" not in str(e.value)
    (tmp_path / "runs.csv").write_text(base + row + ",butter:4:3000,25\n")
    ds = load_dataset(tmp_path)
    assert ds.chains["a"] == DeclaredChain(DaqFilter("butter", 4, 3000.0), 0.0, 25.0)


def test_delay_and_clock_act_on_the_features_as_the_instrument_says():
    """Features of a record taken through a delay and a fast clock = the rotated features of the true record."""
    t = np.arange(int(20.4 / F * FS)) / FS
    tau, eps = 120e-6, 80e-6
    clean = _target(t, {"accel_m_s2": _impacts(t)})
    seen = _target(t, {"accel_m_s2": _impacts(t, tau, eps)})
    amp = np.abs(clean.y[clean.pair_at] + 1j * clean.y[clean.pair_at + 1])
    moved = np.abs(seen.y - clean.y)[clean.pair_at].max() / amp.max()
    clean.nuisance = Nuisance(((("accel_m_s2", FS), tau),), eps)
    from pipeline.diagnosis.instrument import apply_gain, instrument_gain

    err = np.abs(apply_gain(clean.y, clean.pair_at, instrument_gain(clean)) - seen.y)[clean.pair_at].max() / amp.max()
    assert moved > 0.02 and err < 5e-3 * moved         # 4 % of the largest harmonic moved, 0.3 % of that left


def _fake_result(t_abs: np.ndarray, sigs: dict):
    return SimpleNamespace(history=pd.DataFrame({"t_s": t_abs, **sigs}))


def _profile_items(seed: int = 3, tau=(95e-6, 140e-6), eps: float = 40e-6):
    rng = np.random.default_rng(seed)
    taus = dict(zip(("accel_m_s2", "force_n"), tau))
    items = []
    for start, cycles in ((0.15, 28.3), (0.45, 35.9)):
        t = np.arange(int(cycles / F * FS)) / FS
        meas = {s: _impacts(t, d, eps, start) + 0.02 * rng.standard_normal(t.size) for s, d in taus.items()}
        tg = _target(t, meas, record_start=start)
        model = {s: _impacts(t, 0.0, 0.0, start) for s in taus}
        items += profile_items(tg, _fake_result(start + t, model), tuple((s, FS) for s in taus))
    return items


def test_profile_recovers_delays_per_channel_and_the_clock():
    x = profile(_profile_items(tau=(95e-6, 140e-6), eps=40e-6), 2)[0]
    assert x[0] == pytest.approx(95.0, abs=5.0)      # µs
    assert x[1] == pytest.approx(140.0, abs=5.0)
    assert x[2] == pytest.approx(40.0, abs=5.0)      # ppm


def test_the_profiles_analytic_jacobian_is_the_residuals_derivative():
    from pipeline.diagnosis.nuisance import _jacobian, _kept, _residual

    kept = _kept(_profile_items(), math.inf)
    x = np.array([80.0, 150.0, 30.0])          # µs, µs, ppm: away from the optimum, so every term counts
    numeric = np.column_stack([(_residual(x + h, kept) - _residual(x - h, kept)) / 2e-3
                               for h in 1e-3 * np.eye(3)])
    assert np.abs(_jacobian(x, kept) - numeric).max() <= 1e-6 * np.abs(numeric).max()


def test_a_delay_is_bounded_below_by_one_sample_interval():
    """A causal chain only delays; a multiplexed ADC may date a channel up to one sample before it samples it.
    Data whose channel leads by 3 sample intervals put it there unbounded, at the bound when bounded."""
    from pipeline.diagnosis.nuisance import lowest_delays_us

    keys = (("accel_m_s2", FS), ("force_n", FS))
    items = _profile_items(tau=(95e-6, -3.0 / FS))
    assert profile(items, 2)[0][1] == pytest.approx(-3e6 / FS, abs=5.0)
    assert profile(items, 2, lowest_us=lowest_delays_us(keys))[0][1] == pytest.approx(-1e6 / FS, abs=1e-6)


def test_a_declared_null_chain_samples_the_model_as_no_chain():
    """runs.csv may say a log has no chain (``daq_filter`` none): the model is then sampled bit for bit as without
    the column (and no undeclared chain is estimated for it)."""
    t = np.arange(2000) / FS
    tg = _target(t, {"accel_m_s2": np.sin(2 * np.pi * F * t)}, record_start=0.15)
    before = sampling_plan(tg, F, 0.0)
    tg.chain = DeclaredChain(parse_filter("none", "x"), 0.0, 0.0)
    after = sampling_plan(tg, F, 0.0)
    assert np.array_equal(before[0], after[0]) and before[1:] == after[1:]


def test_the_antialias_setting_takes_true_false_or_auto_and_names_them_otherwise():
    from pipeline.cli.diagnose import typed_settings

    assert typed_settings({"antialias": "auto"})["antialias"] is None
    assert typed_settings({"antialias": "TRUE"})["antialias"] is True
    with pytest.raises(UserError, match="'antialias' must be true, false or auto, got 'maybe'"):
        typed_settings({"antialias": "maybe"})


def test_a_delay_at_a_rate_no_calibration_run_has_is_the_same_number_of_samples():
    """A held-out run recorded at 5 kHz, the calibration runs at 10 kHz: the anti-alias filter follows the rate, so
    its delay there is the 10 kHz delay in samples (twice the seconds); a signal measured at no rate takes the
    median over the others'; measured channels keep their own."""
    from pipeline.diagnosis.nuisance import delays_at_unseen_rates

    keys = (("accel_m_s2", 1e4), ("force_n", 1e4), ("accel_m_s2", 5e3), ("disp_m", 5e3), ("force_n", 2.5e4))
    out = delays_at_unseen_rates(np.array([180.0, 150.0, 0.0, 0.0, 0.0]), keys, {0, 1})
    assert out[:2].tolist() == [180.0, 150.0]
    assert out[2] == pytest.approx(360.0) and out[4] == pytest.approx(60.0)     # accel's and force's own, in samples
    assert out[3] == pytest.approx(np.median([1.8, 1.5]) * 1e6 / 5e3)           # disp: the measured channels' median
    assert delays_at_unseen_rates(np.zeros(2), keys[:2], set()).tolist() == [0.0, 0.0]


def _estimate(delays_us: dict) -> object:
    from pipeline.diagnosis.nuisance import ChainEstimate

    d = tuple(((s, fs), 1e-6 * v) for (s, fs), v in delays_us.items())
    return ChainEstimate(runs=("r",), delay_s=d, delay_sd_s=tuple((k, 1e-7) for k, _ in d), clock_ppm=0.0,
                         clock_sd_ppm=1.0, base_chi2_per_n=1.0)


def test_a_filter_is_shown_by_delays_that_scale_with_the_sample_interval():
    """The base fits' delays (report.json of the chain bench): the drill through an undeclared 8th-order Butterworth
    at 0.45 fs, 71 µs at 25.6 kHz and 35.7 µs at 51.2 kHz (1.8 samples at both, s = 1); the drill's lab-grade
    shaker-coil log, no filter, its base lacking the coil's lag, 98-100 µs and 83-86 µs (2.5 and 4.3 samples: fixed
    in time, s ~ 0.2): no filter.  With one rate only, the number of samples decides."""
    from pipeline.diagnosis.nuisance import delay_scaling, shows_a_filter

    filt = _estimate({("accel_m_s2", 25600.0): 71.0, ("force_n", 25600.0): 71.2, ("accel_m_s2", 51200.0): 35.7,
                      ("force_n", 51200.0): 35.5})
    lag = _estimate({("accel_m_s2", 25600.0): 98.0, ("force_n", 25600.0): 100.0, ("accel_m_s2", 51200.0): 83.1,
                     ("force_n", 51200.0): 85.8})
    assert delay_scaling(filt) == pytest.approx(1.0, abs=0.01) and shows_a_filter(filt)
    assert delay_scaling(lag) == pytest.approx(0.21, abs=0.03) and not shows_a_filter(lag)
    one_rate = _estimate({("accel_m_s2", 25600.0): 98.0, ("force_n", 25600.0): 100.0})
    assert delay_scaling(one_rate) is None and shows_a_filter(one_rate)
    assert not shows_a_filter(_estimate({("accel_m_s2", 25600.0): 10.0, ("accel_m_s2", 51200.0): 5.0}))  # 0.26 sample
    negative = _estimate({("accel_m_s2", 25600.0): 98.0, ("accel_m_s2", 51200.0): -20.0})
    assert delay_scaling(negative) == 0.0 and not shows_a_filter(negative)


def test_the_models_anti_alias_filter_passes_the_harmonics_and_stops_above_nyquist():
    from scipy.signal import freqz

    from pipeline.diagnosis.features import SENSOR_SUBSAMPLES, antialias_taps

    taps = antialias_taps()
    f = np.array([0.0, 0.05, 0.1, 0.18, 0.82, 0.9, 1.5, 3.9]) / SENSOR_SUBSAMPLES     # cycles per fine sample
    g = np.abs(freqz(taps, worN=2 * np.pi * f)[1])                                     # fractions of the record's fs
    assert np.allclose(g[:4], 1.0, atol=3e-4) and np.all(g[4:] < 2e-4)    # fractions of the record's fs: content
    #                                                                   within 0.18 fs of k fs would fold onto harmonics
    assert np.allclose(taps, taps[::-1])                                               # linear phase, centred: none


def test_an_anti_aliased_record_is_compared_with_the_model_low_passed_before_sampling():
    """A record whose signal holds content above its Nyquist frequency, taken through an anti-alias filter: the
    model sampled point by point folds that content onto the harmonics (an impact's spike, sampled at slightly
    other instants by a clock error, moved the pendulum's features by nrms 1.4-8.9); low-passed before it is
    sampled (``Target.antialias``) its features are the record's."""
    from pipeline.diagnosis.features import SENSOR_SUBSAMPLES, antialias_pad

    f0, fs = 37.0, 2000.0    # the tone at fs + 3 f0 folds onto harmonic 3
    t = np.arange(int(20.2 / f0 * fs)) / fs

    def sig(tt, with_alias=True):     # harmonics 1-3 and 16 (0.3 fs: the filter's droop), a tone above Nyquist
        x = sum(np.cos(2 * np.pi * k * f0 * tt + k) / k for k in (1, 2, 3, 16))
        return x + (0.5 * np.cos(2 * np.pi * (fs + 3 * f0) * tt) if with_alias else 0.0)

    tg = Target(run_id="r1", system="indenter-metal", kind="", controls={"frequency_hz": f0}, duration_s=t.size / fs)
    tg = series_target(tg, pd.DataFrame({"t_s": t, "accel_m_s2": sig(t, False)}), 16 * f0)
    point = simulated_features(tg, _fake_result(t, {"accel_m_s2": sig(t)}))
    tg.antialias = True
    times, _, t0 = sampling_plan(tg, f0, 0.0)
    pad = antialias_pad(tg)
    dt = 1.0 / (fs * SENSOR_SUBSAMPLES)
    assert pad > 0 and np.allclose(np.diff(times), dt)
    assert t0 - times[0] >= pad * dt * (1 - 1e-9) and times[-1] - (t0 + tg.t_rec[-1]) >= pad * dt * (1 - 1e-9)
    filtered = simulated_features(tg, _fake_result(times - t0, {"accel_m_s2": sig(times - t0)}))
    z_point, z_aa = (np.abs(m - tg.y).max() / np.abs(tg.y).max() for m in (point, filtered))
    assert z_point > 0.1 and z_aa < 1e-4


def test_saturated_samples_are_detected_and_the_model_is_clipped_alike():
    rng = np.random.default_rng(0)
    t = np.arange(int(20.4 / F * FS)) / FS
    x = _impacts(t) + 0.003 * rng.standard_normal(t.size)
    top = np.quantile(x, 0.985)
    clipped = np.minimum(x, top)
    m = clipped_samples(clipped)
    assert 0.005 < m.mean() < 0.03 and not clipped_samples(x).any()
    assert not clipped_samples(np.maximum(x - 0.5, 0.0)).any()      # a contact force resting at 0 is not saturation
    kept = _target(t, {"force_n": clipped})
    naive = _target(t, {"force_n": clipped + 1e-12 * np.arange(t.size)})     # the same flat tops, not detected
    assert set(kept.clipped) == {"force_n"} and kept.clipped["force_n"] == pytest.approx(m.mean(), rel=0.1)
    assert kept.saturation["force_n"].high == top and kept.saturation["force_n"].low == -np.inf
    assert not naive.clipped and not naive.saturation
    assert any("run r1, channel force_n" in n and "saturated" in n for n in kept.notes)
    # the true signal as each target's model sees it: clipped where the saturation was detected, else not
    z = [np.abs(simulated_features(tg, _fake_result(tg.t_rec, {"force_n": _impacts(tg.t_rec)})) - tg.y) / tg.sd
         for tg in (kept, naive)]
    assert z[0].max() < 4.0 < 10.0 < z[1].max()


def test_a_spike_clipped_one_sample_at_a_time_is_saturation_and_a_noise_free_peak_is_not():
    """An impact's spike, narrower than two samples at the top, is clipped for one sample per cycle: no flat top,
    but the values next to the range are each met once, where a noise-free periodic record repeats its peak and
    the values next to it once a cycle alike."""
    rng = np.random.default_rng(2)
    t = np.arange(int(20.4 / F * FS)) / FS
    clean = np.exp(-(((F * t) % 1.0 - 0.3) / 0.0006) ** 2)          # about 2 samples wide at half height
    noisy = clean + 0.003 * rng.standard_normal(t.size)
    top = 0.85 * float(clean.max())
    m = clipped_samples(np.minimum(noisy, top))
    assert 10 <= np.count_nonzero(m) <= 25 and not np.any(m[1:] & m[:-1])
    assert not clipped_samples(clean).any() and not clipped_samples(noisy).any()


def test_the_model_is_clipped_in_the_sensors_frame():
    """A saturating sensor with an offset and a slow drift (rig noise: noise proportional to the signal too): the
    range cuts the signal plus its offset, so the model is clipped after the record's drift against it (fitted on the
    unsaturated samples) is added.  Clipped at the range as it stands, the features sit tens of sd off."""
    rng = np.random.default_rng(1)
    t = np.arange(int(20.4 / F * FS)) / FS
    s = _impacts(t)
    drift = 0.08 + 0.03 * t / t[-1] - 0.02 * (t / t[-1]) ** 2
    rec = s * (1.0 + 0.01 * rng.standard_normal(t.size)) + drift + 0.003 * rng.standard_normal(t.size)
    rng_ = 0.85 * float(np.abs(s + drift).max())
    tg = _target(t, {"accel_m_s2": np.clip(rec, -rng_, rng_)})
    assert 0.01 < tg.clipped["accel_m_s2"] < 0.2 and tg.saturation["accel_m_s2"].high == pytest.approx(rng_)
    s = _impacts(tg.t_rec)
    model = simulated_features(tg, _fake_result(tg.t_rec, {"accel_m_s2": s}))
    plain = _features(tg.signals, _coefs(tg.pinv, {"accel_m_s2": np.clip(s, -rng_, rng_)}), False)
    z_model, z_plain = (float(np.max(np.abs(v - tg.y) / tg.sd)) for v in (model, plain))
    assert z_model < 4.0 and z_plain > 20.0


def test_a_channel_saturated_beyond_the_threshold_is_not_used():
    t = np.arange(int(20.4 / F * FS)) / FS
    x = _impacts(t)
    tg = _target(t, {"accel_m_s2": x, "force_n": np.minimum(x, np.quantile(x, 1.0 - 1.2 * MAX_CLIPPED_FRACTION))})
    assert tg.signals == ("accel_m_s2",) and any("not used" in n for n in tg.notes)


# --- end to end: short drill logs of the independent generator through a DAQ chain ------------------------------


def _diagnose(tmp_path, data, *args):
    from pipeline.cli import main

    out = tmp_path / (data.name + "-diag")
    params = tmp_path / "params-chain.yaml"
    params.write_text("diagnose:\n  estimate_chain: true\n")        # the default, said where the test relies on it
    assert main(["diagnose", str(data), "--out", str(out), "--quiet", "--no-mlflow", "--params", str(params), *args]) == 0
    return json.loads((out / "report.json").read_text()), (out / "report.md").read_text()


def _drill_log(tmp_path, chain: str, effect: str | None = None, noise: str = "white2"):
    from tests.independent.daq import DAQ_CHAINS
    from tests.independent.generator import LogSpec, generate

    spec = LogSpec("drill", effect=effect, noise=noise, seed=0, n_runs=8, daq=DAQ_CHAINS[chain])
    truth = generate(spec, tmp_path / spec.name, threads=2)
    return tmp_path / spec.name, truth


def _nothing_missing(rep):
    assert rep["verdict"] == "nothing missing" and rep["selected"] is None, rep["call"]["text"]


def test_an_undeclared_filter_and_clock_are_estimated_and_the_control_stays_clean(tmp_path):
    """8th-order Butterworth at 0.45 fs (its delay left in the data) and a 50 ppm clock, undeclared."""
    data, truth = _drill_log(tmp_path, "butter8-undeclared")
    rep, md = _diagnose(tmp_path, data)
    _nothing_missing(rep)
    est = rep["recording"]["estimated"]
    runs = truth["daq"]["runs"]
    for d in est["delays"]:
        true = {r["dc_delay_s"] for rid, r in runs.items() if d["fs_hz"] == pytest.approx(_fs(data, rid))}
        assert len(true) == 1 and d["value_s"] == pytest.approx(true.pop(), abs=5e-6), d
        assert 0 < d["sd_s"] < 5e-6
    # the clock within 5 ppm; its sd includes the runs' disagreement (the jackknife), which a filter the delays
    # describe only in part leaves, and covers the error
    clock = est["clock_ppm"]
    assert clock["value"] == pytest.approx(50.0, abs=5.0) and 0 < clock["sd"] < 10.0
    assert abs(clock["value"] - 50.0) <= 3.0 * clock["sd"]
    assert "Recording: undeclared DAQ chain" in md


def _fs(data, rid) -> float:
    t = pd.read_csv(data / "series" / f"{rid}.csv", usecols=["t_s"])["t_s"].to_numpy()
    return round(1.0 / float(np.median(np.diff(t))), 3)


@pytest.mark.slow
@pytest.mark.parametrize("chain", ["butter8", "butter8-comp", "ellip6"])
def test_a_declared_filter_gives_the_verdict_of_no_filter(tmp_path, chain):
    data, _ = _drill_log(tmp_path, chain)
    rep, _ = _diagnose(tmp_path, data)
    assert rep["recording"]["estimated"] is None and len(rep["recording"]["declared"]) >= 6
    _nothing_missing(rep)


@pytest.mark.slow
def test_a_saturated_accelerometer_is_noted_and_the_verdict_holds(tmp_path):
    data, truth = _drill_log(tmp_path, "clip80")
    rep, _ = _diagnose(tmp_path, data)
    _nothing_missing(rep)
    frac = {rid: r["clipped_fraction"]["accel_m_s2"] for rid, r in truth["daq"]["runs"].items()
            if r.get("clipped_fraction", {}).get("accel_m_s2")}
    assert min(frac.values()) < 0.05 < max(frac.values()) < MAX_CLIPPED_FRACTION  # 2 % at 150 Hz, 8-29 % at the others
    assert {rid: c["accel_m_s2"] for rid, c in rep["recording"]["clipped"].items()} == pytest.approx(frac)
    for rid in frac:
        assert any(f"run {rid}, channel accel_m_s2" in n and "the model is clipped" in n for n in rep["notes"]), rid


@pytest.mark.slow
def test_guide_friction_is_found_through_a_saturated_accelerometer(tmp_path):
    """The identification matrix's clip80 friction log (rig noise): the accelerometer saturated on 6 of 8 runs.
    Started only at the calibrated base, the friction fit stopped at mu = 18 N and the log was "unexplained"; the
    leading candidates' restart from the nominal base finds the truth (mu = 50 N, the generator's visible strength)."""
    data, truth = _drill_log(tmp_path, "clip80", effect="guide_friction", noise="rig")
    rep, _ = _diagnose(tmp_path, data)
    assert rep["verdict"] == "selected" and rep["selected"] == "guide_friction", rep["call"]["text"]
    assert rep["selected_params"]["mu"]["value"] == pytest.approx(truth["truth"]["mu"], rel=0.05)
    assert sum("the model is clipped" in n for n in rep["notes"]) >= 5


@pytest.mark.slow
def test_hum_on_the_forcing_harmonic_does_not_bias_the_verdict(tmp_path):
    """50 Hz hum (5, 2, 1 N at 50, 100, 150 Hz) on the force channel: its third harmonic sits on the 150 Hz run's
    forcing frequency (within the feature's noise: a few N against kN of force, sd ~1 N)."""
    data, _ = _drill_log(tmp_path, "hum50")
    assert "150" in " ".join(pd.read_csv(data / "runs.csv")["frequency_hz"].astype(str))
    rep, _ = _diagnose(tmp_path, data)
    _nothing_missing(rep)


def _clock_grid_items(extra_delay_s: dict[int, float], eps_true: float = 50.0) -> dict[float, list]:
    """Per clock on a grid [ppm], each of 6 runs' profile items when the model is sampled with that clock: one
    channel, harmonics 1-10 of the run's frequency, a 70 µs delay, the records' mid-times 30-90 ms after their first
    sample; ``extra_delay_s``: run -> a phase error of that run alone (as a delay)."""
    from pipeline.diagnosis.nuisance import _Item

    out: dict[float, list] = {}
    for e in np.arange(eps_true - 20.0, eps_true + 21.0, 2.0):
        runs = []
        for r in range(6):
            kw = 2.0 * np.pi * (150.0 + 50.0 * r) * np.arange(1, 11)
            tbar = 0.03 + 0.012 * r
            y = np.exp(1j * kw * (1e-6 * eps_true * tbar - 70e-6 - extra_delay_s.get(r, 0.0)))
            m = np.exp(1j * kw * 1e-6 * e * tbar)
            sd = np.full(kw.size, 1e-3)
            runs.append([_Item(m, y, sd, sd, kw, np.zeros(kw.size, dtype=int), tbar, 2.0 * tbar)])
        out[round(float(e), 6)] = runs
    return out


def test_the_runs_disagreeing_on_the_phase_widen_the_clocks_sd():
    """The clock is told from a delay by how the records' mid-times differ between runs: runs that agree give a
    jackknife sd far below a ppm; one run whose phase is off by a 1 µs delay alone moves the clock located without
    it by ppm, and the jackknife sd shows it (the χ² curvature does not)."""
    from pipeline.diagnosis.nuisance import jackknife_clock_sd

    keys = (("accel_m_s2", FS),)
    assert jackknife_clock_sd(_clock_grid_items({}), keys) < 0.05
    assert jackknife_clock_sd(_clock_grid_items({2: 1e-6}), keys) > 2.0
    assert jackknife_clock_sd({0.0: [[], [], []], 1.0: [[], [], []], 2.0: [[], [], []]}, keys) == 0.0


def test_a_run_whose_phase_disagrees_widens_its_channels_delay_sd():
    """At a fixed clock a channel's delay rests on its own runs: a 1 µs phase error on one of six runs moves the
    delay located without it by about 1/6 µs, which the jackknife sd shows (about d / sqrt(n (n - 1)) = 0.18 µs for
    equal weights; the higher harmonics weigh more); runs that agree give none."""
    from pipeline.diagnosis.nuisance import jackknife_delay_sd_us

    keys = (("accel_m_s2", FS),)
    assert jackknife_delay_sd_us(_clock_grid_items({})[50.0], keys)[0] < 1e-3
    assert 0.05 < jackknife_delay_sd_us(_clock_grid_items({2: 1e-6})[50.0], keys)[0] < 0.5


@pytest.mark.slow
def test_a_pendulum_control_through_the_field_chain_stays_clean(tmp_path):
    """The field chain on a pendulum control (rig noise): 50 Hz hum of 5, 2, 1 N on the force, the 20th and 40th
    harmonics of the 2.5 Hz runs; the accelerometer clipped at 85 % of its peak, one sample per impact.  Left in the
    features, the hum read hundreds of sd and the clipped spikes a gain of 0.93-0.96 on every harmonic."""
    from tests.independent.daq import DAQ_CHAINS
    from tests.independent.generator import LogSpec, generate

    spec = LogSpec("pendulum", noise="rig", seed=0, n_runs=8, daq=DAQ_CHAINS["field"])
    truth = generate(spec, tmp_path / spec.name, threads=2)
    rep, md = _diagnose(tmp_path, tmp_path / spec.name)
    _nothing_missing(rep)
    hum = rep["recording"]["hum"]["force_n"]
    assert [hum[f] for f in ("50", "100")] == pytest.approx([5.0, 2.0], rel=0.05)
    clipped = {rid for rid, r in truth["daq"]["runs"].items() if r.get("clipped_fraction", {}).get("accel_m_s2")}
    found = set(rep["recording"]["clipped"])      # a run clipped on fewer than MIN_AT_EXTREME samples is not found
    assert clipped and found <= clipped and len(found) >= len(clipped) - 1 and "Mains hum: force_n" in md
