"""Figures people look at: time histories and spectra (matplotlib, no display needed)."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def amplitude_spectrum(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum of a uniformly sampled signal over whole cycles (Hann window)."""
    n = x.size
    dt = float(t[1] - t[0])
    w = np.hanning(n)
    spec = np.abs(np.fft.rfft((x - x.mean()) * w)) * 2.0 / w.sum()
    return np.fft.rfftfreq(n, dt), spec


def plot_time_history(res, path: str | os.PathLike) -> str:
    """Displacement and contact force of the impacting mass over the recorded window, and the
    acceleration spectrum (0–1000 Hz for the indenter, 0–12 f otherwise)."""
    h = res.history
    t = h["t_s"].to_numpy()
    t_rel = t - t[0]
    f = res.params["frequency_hz"]
    fig, ax = plt.subplots(3, 1, figsize=(9, 9))
    ax[0].plot(t_rel * 1e3, h["disp_m"] * 1e3, lw=1)
    ax[0].set_ylabel("impacting mass disp. [mm]")
    ax[0].set_title(f"{res.model}: f = {f:g} Hz, status {res.status}, "
                    f"{res.labels.get('impacts_per_cycle')} impacts/cycle, period {res.labels.get('period')}")
    ax[1].plot(t_rel * 1e3, h["force_n"], lw=1, color="C3")
    ax[1].set_ylabel("contact force [N]")
    ax[1].set_xlabel("time in recorded window [ms]")
    freq, amp = amplitude_spectrum(t, h["accel_m_s2"].to_numpy())
    # a model with a measured-acceleration sensor (the sensor_lowpass effect) shows its spectrum to 1 kHz
    from sim import get_model

    fmax = 1000.0 if "sensor_lowpass" in get_model(res.model).effects else 12 * f
    keep = freq <= fmax
    ax[2].plot(freq[keep], amp[keep] / 9.81, lw=1, color="C2")
    ax[2].set_xlabel("frequency [Hz]")
    ax[2].set_ylabel("accel. amplitude [g]")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    from pipeline.core.files import atomic_write_figure

    return str(atomic_write_figure(path, fig, dpi=110))
