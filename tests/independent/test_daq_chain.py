"""The independent generator's data-acquisition chain (``daq.py``): each part does what it says, measured on the
signals it writes, and a log without a chain is what the generator wrote before the chain existed."""
from __future__ import annotations

import hashlib
import math

import numpy as np
import pandas as pd
import pytest
from scipy import signal as sps
from scipy.optimize import minimize_scalar

from tests.independent import daq as D
from tests.independent.generator import LogSpec, _run, generate, true_parameters
from tests.independent.rigs import RIGS

pytestmark = pytest.mark.xdist_group("independent-test_daq_chain")   # one test worker builds the module's fixture

FS = 25600.0


def _harmonics(t: np.ndarray, x: np.ndarray, f: float, k: int = 3) -> np.ndarray:
    """Complex amplitudes c_j (x ~ mean + trend + sum Re(c_j e^{i 2 pi j f t})) of harmonics 1..k, least squares."""
    cols = [np.ones_like(t), t - t.mean()]
    for j in range(1, k + 1):
        cols += [np.cos(2 * np.pi * j * f * t), np.sin(2 * np.pi * j * f * t)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), x, rcond=None)
    return coef[2::2] - 1j * coef[3::2]


def _fit_frequency(t: np.ndarray, x: np.ndarray, f0: float, k: int = 3) -> float:
    """The fundamental [Hz] whose harmonics 1..k fit x best, near f0."""
    def sse(f):
        cols = [np.ones_like(t), t - t.mean()]
        for j in range(1, k + 1):
            cols += [np.cos(2 * np.pi * j * f * t), np.sin(2 * np.pi * j * f * t)]
        a = np.column_stack(cols)
        coef, *_ = np.linalg.lstsq(a, x, rcond=None)
        return float(np.sum((a @ coef - x) ** 2))
    return float(minimize_scalar(sse, bounds=(f0 * (1 - 1e-3), f0 * (1 + 1e-3)), method="bounded",
                                 options={"xatol": f0 * 1e-10}).x)


# ------------------------------------------------------------------------------ the filters on pure sinusoids
FILTERS = [D.DaqChain(filter="butter", order=4, cutoff=0.4), D.DaqChain(filter="butter", order=8, cutoff=0.45),
           D.DaqChain(filter="ellip", order=5, cutoff=0.4), D.DaqChain(filter="ellip", order=8, cutoff=0.45),
           D.DaqChain(filter="fir", order=0, cutoff=0.45)]


@pytest.mark.parametrize("chain", FILTERS, ids=lambda c: f"{c.filter}{c.order}-{c.cutoff}")
@pytest.mark.parametrize("f", [300.0, 3000.0])
def test_filter_delays_a_sinusoid_by_its_frequency_response(chain, f):
    """A sinusoid through the simulated filter (grid of 16 points per sample, settled start), sampled at fs:
    the fitted phase is arg H at f (H from scipy.signal.freqs / freqz) to 1e-6 rad, the amplitude |H| to 1e-6
    once the grid's own interpolation error is allowed for."""
    filt = D.design(chain, FS)
    h = 1.0 / (chain.oversample * FS)
    t = np.arange(int(0.05 * FS) * chain.oversample) * h
    x = np.sin(2 * np.pi * f * t + 0.3)
    y = D.fir_filter(filt, x) if isinstance(filt, D.FirFilter) else D.analog_filter(filt, x, h)
    keep = slice(int(0.02 * FS) * chain.oversample, None, chain.oversample)   # after the filter's start-up
    c_in, c_out = _harmonics(t[keep], x[keep], f, 1)[0], _harmonics(t[keep], y[keep], f, 1)[0]
    if isinstance(filt, D.FirFilter):
        _, H = sps.freqz(filt.taps, 1.0, worN=[f], fs=filt.rate_hz)
    else:
        _, H = sps.freqs_zpk(filt.zeros, filt.poles, filt.gain, [2 * np.pi * f])
    g = c_out / c_in
    assert abs(np.angle(g / H[0])) < 1e-6
    # linear interpolation between the grid's points lowers an analog filter's input by (w h)^2 / 12
    droop = 0.0 if isinstance(filt, D.FirFilter) else (2 * np.pi * f * h) ** 2 / 12
    assert abs(abs(g) - abs(H[0]) * (1 - droop)) < 1e-6 * abs(H[0])
    if isinstance(filt, D.FirFilter):            # linear phase: a pure delay of (taps - 1) / 2 modulator steps
        assert abs(np.angle(g * np.exp(2j * np.pi * f * filt.dc_delay()))) < 1e-6
    else:
        assert 0.0 < -np.angle(g) / (2 * np.pi * f) < 3 * filt.dc_delay()


@pytest.mark.parametrize("chain", FILTERS, ids=lambda c: f"{c.filter}{c.order}-{c.cutoff}")
def test_dc_group_delay_is_the_phase_slope_at_zero(chain):
    """tau0 = -d arg H / d omega at omega -> 0, the slope of scipy's frequency response (a difference); gain 1
    at DC."""
    filt = D.design(chain, FS)
    f = np.array([1e-3, 2e-3])
    ph = np.unwrap(np.angle(filt.response(f)))
    slope = -(ph[1] - ph[0]) / (2 * np.pi * (f[1] - f[0]))
    assert filt.dc_delay() == pytest.approx(slope, rel=1e-6)
    assert abs(filt.response(0.0)[0]) == pytest.approx(1.0, abs=1e-9)        # a calibrated channel at DC
    # the range for analog front ends: 30-200 us at 10-51.2 kHz (here 25.6 kHz)
    if not isinstance(filt, D.FirFilter):
        assert 20e-6 < filt.dc_delay() < 200e-6


def test_velocity_route_equals_filtering_the_acceleration():
    """The acceleration enters through its velocity (exact where it jumps); on a smooth signal the two routes agree
    (residual set by np.gradient's O(h^2) error: < 1e-4 of the peak)."""
    filt = D.design(D.DAQ_CHAINS["ellip6"], FS)
    h = 1.0 / (16 * FS)
    t = np.arange(40000) * h
    v = np.sin(2 * np.pi * 700 * t) * (1 - np.cos(2 * np.pi * 90 * t))
    a = np.gradient(v, h, edge_order=2)
    y1 = D.analog_filter_of_rate(filt, v, a, h)
    y2 = D.analog_filter(filt, a, h)
    assert np.max(np.abs(y1 - y2)[100:]) < 1e-4 * np.max(np.abs(y2))


def test_chain_spec_checks_itself_and_declares_or_not():
    with pytest.raises(ValueError):
        D.DaqChain(filter="bessel")
    with pytest.raises(ValueError):
        D.DaqChain(clip_fraction={"strain": 0.8})
    assert D.DaqChain(declared=False).is_off and not D.DaqChain().is_off
    filt = D.design(D.DAQ_CHAINS["butter8-comp"], FS)
    cols = D.runs_columns(D.DAQ_CHAINS["butter8-comp"], filt, FS)
    assert cols == {"daq_filter": "butter:8:11520", "daq_delay_s": filt.dc_delay(), "daq_delay_removed": 1,
                    "daq_clock_ppm": 0.0}
    assert D.runs_columns(D.DAQ_CHAINS["butter8-undeclared"], filt, FS) == {}
    assert D.declared_filter(D.DAQ_CHAINS["ellip6"], D.design(D.DAQ_CHAINS["ellip6"], FS), FS) == \
        "ellip:6:10240:0.1:80"


# ------------------------------------------------------------------------------ the chain on a generated run
RIG = RIGS["drill"]
F_RUN, LEVEL = 430.0, 1500.0          # run 0 of the drill: 25.6 kHz, from rest at 0.15 s, 28.3 cycles


def _one_run(chain: D.DaqChain | None, seed: int = 2) -> dict:
    spec = LogSpec("drill", noise="clean", seed=seed, daq=chain)
    return _run(RIG, spec, true_parameters(RIG, spec), 0, F_RUN, LEVEL, False)


@pytest.fixture(scope="module")
def runs():
    """One drill run without a chain and through several chains (the same physics: same seed)."""
    return {"none": _one_run(None), "butter8": _one_run(D.DAQ_CHAINS["butter8"]),
            "butter8-comp": _one_run(D.DAQ_CHAINS["butter8-comp"]),
            "clock": _one_run(D.DaqChain("clock", clock_ppm=80.0)),
            "clock-hum": _one_run(D.DaqChain("clock-hum", clock_ppm=80.0, hum_hz=50.0,
                                             hum={"force_n": (5.0, 2.0, 1.0)}))}


def test_run_through_the_filter_carries_its_phase(runs):
    """The fundamental of the displacement and of the force through the Butterworth, uncompensated: turned by
    arg H(j w) against the unfiltered run (-0.191 rad = -430 Hz x 2 pi x 70.8 us); compensated: the DC delay gone,
    the amplitude |H| (the droop stays).  Within 5e-4 rad for the displacement, 3e-3 for the force: the record
    starts 0.15 s after rest and is not periodic, and a harmonic fit leaks that much (measured: 1e-4, 2e-3)."""
    t = runs["none"]["t"]
    filt = D.design(D.DAQ_CHAINS["butter8"], FS)
    H = filt.response(F_RUN)[0]
    assert np.angle(H) == pytest.approx(-2 * np.pi * F_RUN * filt.dc_delay(), abs=1e-4)
    for ch, tol in (("disp_m", 5e-4), ("force_n", 3e-3)):
        base = _harmonics(t, runs["none"]["signals"][ch], F_RUN)[0]
        unc = _harmonics(t, runs["butter8"]["signals"][ch], F_RUN)[0] / base
        comp = _harmonics(t, runs["butter8-comp"]["signals"][ch], F_RUN)[0] / base
        assert abs(np.angle(unc / H)) < tol, ch
        assert abs(np.angle(comp)) < tol, ch
        assert abs(abs(comp) - abs(H)) < tol, ch


@pytest.mark.slow
def test_force_jumps_are_resolved_finer_than_the_grid(runs):
    """The drill's force jumps at each onset (its damper): those grid steps are refined, so the filtered force
    changes by < 1e-3 of its range when the grid is 4x finer (it was 2e-2 without the refinement)."""
    fine = _one_run(D.DaqChain(filter="butter", order=8, cutoff=0.45, oversample=64))
    a, b = runs["butter8"]["signals"]["force_n"], fine["signals"]["force_n"]
    assert np.max(np.abs(a - b)) < 1e-3 * np.ptp(b)


@pytest.mark.slow
def test_a_channel_delay_delays_that_channel_only(runs):
    """The force 20 us late (a conditioner's own delay) on top of the Butterworth: its fundamental turned by a
    further -430 Hz x 2 pi x 20 us = -0.054 rad (within 5e-4 rad), the other channels as without it (1e-9)."""
    d = 20e-6
    skew = _one_run(D.DaqChain("skew", filter="butter", order=8, cutoff=0.45, channel_delay_s={"force_n": d}))
    t = runs["butter8"]["t"]
    ratio = _harmonics(t, skew["signals"]["force_n"], F_RUN)[0] / \
        _harmonics(t, runs["butter8"]["signals"]["force_n"], F_RUN)[0]
    assert np.angle(ratio) == pytest.approx(-2 * np.pi * F_RUN * d, abs=5e-4)
    for ch in ("accel_m_s2", "disp_m"):
        a, b = skew["signals"][ch], runs["butter8"]["signals"][ch]
        assert np.max(np.abs(a - b)) <= 1e-9 * np.ptp(b)
    assert skew["daq"]["channel_delay_s"] == {"force_n": d}


def test_clock_error_shows_as_a_frequency_shift(runs):
    """The run's fundamental fitted in nominal time t_s: f (1 + 80 ppm) with the clock error, against the same run
    on a true clock, within 1 ppm."""
    t = runs["none"]["t"]
    f0 = _fit_frequency(t, runs["none"]["signals"]["disp_m"], F_RUN)
    f1 = _fit_frequency(t, runs["clock"]["signals"]["disp_m"], F_RUN)
    assert (f1 / f0 - 1.0) * 1e6 == pytest.approx(80.0, abs=1.0)


def test_hum_at_mains_harmonics_with_the_stated_amplitude(runs):
    """Hum minus the same run without it: 50 Hz x (1 + 80 ppm) in nominal time (the clock), harmonics 1-3 at
    the stated amplitudes 5, 2, 1 N and the truth's phases (to 1e-6)."""
    t = runs["clock"]["t"]
    d = runs["clock-hum"]["signals"]["force_n"] - runs["clock"]["signals"]["force_n"]
    assert np.max(np.abs(runs["clock-hum"]["signals"]["accel_m_s2"] - runs["clock"]["signals"]["accel_m_s2"])) == 0
    f = _fit_frequency(t, d, 50.0)
    assert (f / 50.0 - 1.0) * 1e6 == pytest.approx(80.0, abs=0.1)
    c = _harmonics(t, d, f)
    assert np.abs(c) == pytest.approx([5.0, 2.0, 1.0], abs=1e-6)
    start = 0.15
    ph = np.array(runs["clock-hum"]["daq"]["hum_phases_rad"]["force_n"])
    # sin(w t_true + ph), t_true = start + t (1+eps): the phase at t = 0 is w k start + ph - pi/2
    want = np.exp(1j * (2 * np.pi * 50.0 * np.arange(1, 4) * start + ph - np.pi / 2))
    assert np.max(np.abs(c / np.abs(c) - want)) < 1e-6


def test_saturated_channels_are_flat_at_exactly_the_range(tmp_path):
    """An accelerometer saturating at 0.8 max|x| and a load cell at 2 kN absolute, 16-bit ADC ('rig' noise): the
    written samples never pass the range, runs of identical values sit at exactly +-range as written, and the
    truth and runs.csv record the range and the declared chain."""
    chain = D.DaqChain("clip", clip_fraction={"accel_m_s2": 0.8}, clip_range={"force_n": 2000.0})
    info = generate(LogSpec("drill", noise="rig", seed=5, n_runs=1, daq=chain), tmp_path / "log", threads=1)
    rid = "drill-00-150hz"
    df = pd.read_csv(tmp_path / "log" / "series" / f"{rid}.csv")
    ranges = info["daq"]["runs"][rid]["adc_range"]
    assert ranges["force_n"] == 2000.0
    for ch, r in ranges.items():
        x = df[ch].to_numpy()
        r9 = float(f"{r:.9g}")                                   # as written (float_format %.9g)
        assert np.max(np.abs(x)) == r9
        at = np.abs(x) == r9
        assert at.sum() >= 5 and np.any(at[1:] & at[:-1])          # flat tops: neighbours at exactly the range
    assert 0.0 < info["daq"]["runs"][rid]["clipped_fraction"]["accel_m_s2"] < 0.5
    from pipeline.datasets.measured import load_dataset

    load_dataset(tmp_path / "log")                               # still a valid section-7 directory
    runs_csv = pd.read_csv(tmp_path / "log" / "runs.csv")
    assert runs_csv.loc[0, "daq_filter"] == "none" and runs_csv.loc[0, "daq_clock_ppm"] == 0.0
    assert info["name"] == "drill-control-rig-clip-s5-n1"


REFERENCE_SHA256 = {      # the files the generator wrote at commit 4b839ad (before the chain), same spec
    "runs.csv": "ca01c7170f512b517549024de30a07057cdbae37737715aae39b26cb2a2e38b0",
    "series/drill-00-150hz.csv": "0b91867f7c963ddf351823156998d8a0c00a3fb6bd57951100b35e296fc6d1da",
}


@pytest.mark.parametrize("chain", [None, D.DaqChain("off", declared=False)], ids=["none", "off"])
def test_chain_off_writes_what_the_generator_wrote_before(tmp_path, chain):
    """No chain, or a chain with every part off and nothing declared: bit-identical files (same seed)."""
    info = generate(LogSpec("drill", noise="rig", seed=5, n_runs=1, daq=chain), tmp_path / "log", threads=1)
    got = {p: hashlib.sha256((tmp_path / "log" / p).read_bytes()).hexdigest() for p in REFERENCE_SHA256}
    assert got == REFERENCE_SHA256
    assert "daq" not in info and info["name"] == "drill-control-rig-s5-n1"
    assert math.isfinite(info["truth"]["K1"])


@pytest.mark.slow
@pytest.mark.parametrize("system", sorted(RIGS))
@pytest.mark.parametrize("chain", ["field", "fir", "ellip6"])
def test_every_rig_writes_a_valid_log_through_a_chain(tmp_path, system, chain):
    """Every rig through the named chains: a valid section-7 directory, finite samples, every run declared."""
    from pipeline.datasets.measured import load_dataset

    outside = "mount_resonance" if chain == "field" else None
    info = generate(LogSpec(system, outside=outside, noise="rig", seed=1, n_runs=2, daq=D.DAQ_CHAINS[chain]),
                    tmp_path / "log", threads=1)
    ds = load_dataset(tmp_path / "log")
    runs_csv = pd.read_csv(tmp_path / "log" / "runs.csv")
    assert runs_csv["daq_filter"].str.startswith(D.DAQ_CHAINS[chain].filter).all()
    assert (runs_csv["daq_delay_s"] > 0).all() and set(runs_csv["daq_delay_removed"]) == {0}
    for df in ds.series.values():
        assert np.all(np.isfinite(df.to_numpy()))
    assert set(info["daq"]["runs"]) == set(ds.series)
