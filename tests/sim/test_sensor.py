"""The sensor low-pass (MODELS.md §6 sensor_lowpass, sim.models.sensor) and histories at chosen instants.

The low-pass against scipy's own continuous-time simulation (``scipy.signal.lsim``, another discretisation of the
same H(s)); its periodic steady state against a long run; second-order convergence across a contact's kink; and
``simulate(history_times=...)`` against the uniform history of the same run."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lsim

import sim
from sim import ParameterError
from sim.models.sensor import lowpass_rate, warmup_s


def _kinked_velocity(t: np.ndarray, f: float = 50.0) -> np.ndarray:
    """A velocity with a kink every cycle (the acceleration jumps, as at a damped contact's onset)."""
    return np.sin(2 * np.pi * f * t) + 0.4 * np.maximum(np.sin(2 * np.pi * f * t + 1.0), 0.0)


def test_lowpass_rate_is_the_continuous_butterworth_of_the_acceleration():
    fc, fs = 350.0, 20000.0
    t = np.arange(4000) / fs
    v = _kinked_velocity(t)
    wc = 2 * math.pi * fc
    # H(s) a = s H(s) v, simulated by scipy for v linear between samples: the same assumption, another method
    _, ref, _ = lsim(([wc * wc, 0.0], [1.0, math.sqrt(2) * wc, wc * wc]), v, t, interp=True)
    assert np.max(np.abs(lowpass_rate(v, 1 / fs, fc, periodic=False) - ref)) < 1e-10 * np.max(np.abs(ref))


def test_periodic_steady_state_equals_a_long_run():
    fc, fs, f = 350.0, 20000.0, 50.0                  # 400 samples per cycle
    t = np.arange(400 * 12) / fs
    v = _kinked_velocity(t, f)
    long = lowpass_rate(v, 1 / fs, fc, periodic=False)
    one = lowpass_rate(v[:400], 1 / fs, fc, periodic=True)
    assert np.max(np.abs(one - long[-400:])) < 1e-12 * np.max(np.abs(long))
    assert warmup_s(fc) * f < 12                        # 12 cycles are past the start-up


def test_second_order_across_a_kink():
    """Halving the sampling step quarters the error of the filtered acceleration where the velocity has kinks."""
    fc, f = 800.0, 50.0

    def err(fs):
        t = np.arange(int(0.2 * fs)) / fs
        fine = np.arange(int(0.2 * fs * 64)) / (fs * 64)
        exact = lowpass_rate(_kinked_velocity(fine, f), 1 / (fs * 64), fc, False)[::64]
        return np.max(np.abs(lowpass_rate(_kinked_velocity(t, f), 1 / fs, fc, False) - exact[:t.size]))

    e1, e2 = err(20000.0), err(40000.0)           # 25 and 50 samples per filter period: the asymptotic regime
    assert 3.0 < e1 / e2 < 5.0


@pytest.mark.parametrize("model, preset", [("indenter-metal", None), ("drill", "lab"), ("pendulum", None),
                                           ("rimd", None)])
def test_history_times_are_the_dense_output(model, preset):
    """Samples at chosen times equal the uniform history's samples at the same times (both the integrator's dense
    output at the same steps)."""
    st = {"min_transient": 10, "max_transient": 10, "window": 3, "samples_per_cycle": 64}
    ref = sim.simulate(model, preset=preset, settings=st, history=True)
    period = 1.0 / ref.params["frequency_hz"]
    times = np.arange(0, 3 * 64, 5) * period / 64
    got = sim.simulate(model, preset=preset, settings=st, history_times=times)
    assert got.labels == ref.labels | {"power_w": got.labels["power_w"]}
    for sig in ("force_n", "accel_m_s2", "disp_m", "vel_m_s"):
        a, b = got.history[sig].to_numpy(), ref.history[sig].to_numpy()[::5]
        assert np.max(np.abs(a - b)) <= 1e-9 * max(np.ptp(b), 1e-30), sig


def test_history_times_are_checked():
    with pytest.raises(ParameterError, match="history_times must be finite, non-decreasing and within the window"):
        sim.simulate("rimd", settings={"window": 2}, history_times=[0.0, 10.0])
    with pytest.raises(ParameterError, match="history_times"):
        sim.simulate("rimd", settings={"window": 2}, history_times=[0.1, 0.05])
