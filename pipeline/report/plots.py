"""Figures people look at: time histories and spectra (matplotlib, no display needed)."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pipeline.core import units  # noqa: E402


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
    ft = units.set_label(ax[1], "x", "t_s", "time in recorded window")
    ax[0].plot(t_rel * ft, h["disp_m"] * units.set_label(ax[0], "y", "disp_m", "impacting mass disp."), lw=1)
    ax[0].set_title(f"{res.model}: f = {f:g} Hz, status {res.status}, "
                    f"{res.labels.get('impacts_per_cycle')} impacts/cycle, period {res.labels.get('period')}")
    ax[1].plot(t_rel * ft, h["force_n"] * units.set_label(ax[1], "y", "force_n"), lw=1, color="C3")
    freq, amp = amplitude_spectrum(t, h["accel_m_s2"].to_numpy())
    # a model with a measured-acceleration sensor (the sensor_lowpass effect) shows its spectrum to 1 kHz
    from sim import get_model

    fmax = 1000.0 if "sensor_lowpass" in get_model(res.model).effects else 12 * f
    keep = freq <= fmax
    ax[2].plot(freq[keep] * units.set_label(ax[2], "x", "frequency_hz"),
               amp[keep] * units.set_label(ax[2], "y", "accel_m_s2", "accel. amplitude"), lw=1, color="C2")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    from vibrobase.files import atomic_write_figure

    return str(atomic_write_figure(path, fig, dpi=110))
