"""Noise a real rig puts on its records, as composable parts, and named combinations of them.

Parts (each a function of the clean record x sampled at fs [Hz] and a numpy Generator; levels are fractions of the
record's RMS about its mean unless stated):
  white       additive white Gaussian noise of a fixed sd per signal (the sensor's own floor, unit of the signal)
  rms         additive white Gaussian noise, sd = level x the record's RMS (a record-wise signal-to-noise ratio)
  gain        multiplicative: x (1 + level n(t)), n white: noise proportional to the instantaneous signal
  offset      a constant offset per record (sd given in the signal's unit) plus a slow drift over the record:
              a linear ramp and a random walk, each of sd level x RMS at the record's end
  pink        1/f noise (power spectral density ∝ 1/f from 1 Hz to Nyquist), sd = level x RMS
  quantise    an ADC of ``bits`` bits over a full scale of ±(1.25 max|x|), rounding to its LSB
Summary columns (``summary_mode``): "rounded" = the rig software's noise-free numbers to 6 significant digits, no
``_sd`` columns; "stated" = numbers with noise of a stated relative sd, written in ``<label>_sd`` columns.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

SENSOR_FLOOR = {"accel_m_s2": 0.5, "force_n": 1.0, "disp_m": 2e-7, "progression_m": 2e-7}
"""Sensor noise floors [signal unit] of the 'white' part (an accelerometer's 0.05 g, a load cell's 1 N, ...)."""
OFFSET_SD = {"accel_m_s2": 2.0, "force_n": 5.0, "disp_m": 1e-4, "progression_m": 0.0}
"""Constant sensor offsets [signal unit] of the 'offset' part; positions are in the rig frame (MODELS.md §7)."""


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean((x - x.mean()) ** 2))) or 1e-30


def white(x, fs, rng, signal, level=1.0):
    return x + level * SENSOR_FLOOR[signal] * rng.standard_normal(x.size)


def rms(x, fs, rng, signal, level=0.02):
    return x + level * _rms(x) * rng.standard_normal(x.size)


def gain(x, fs, rng, signal, level=0.02):
    return x * (1.0 + level * rng.standard_normal(x.size))


def offset(x, fs, rng, signal, level=0.01):
    n = x.size
    s = level * _rms(x)
    ramp = s * rng.standard_normal() * np.linspace(0.0, 1.0, n)
    walk = np.cumsum(rng.standard_normal(n))
    walk *= s / max(abs(walk[-1]), 1e-30) * abs(rng.standard_normal())
    return x + OFFSET_SD[signal] * rng.standard_normal() + ramp + walk


def pink(x, fs, rng, signal, level=0.01):
    n = x.size
    spec = np.fft.rfft(rng.standard_normal(n))
    freq = np.fft.rfftfreq(n, 1.0 / fs)
    spec *= 1.0 / np.sqrt(np.maximum(freq, 1.0))
    y = np.fft.irfft(spec, n)
    y -= y.mean()
    return x + level * _rms(x) * y / max(float(np.std(y)), 1e-30)


def quantise(x, fs, rng, signal, bits=16):
    full = 1.25 * max(float(np.max(np.abs(x))), 1e-30)
    lsb = 2.0 * full / 2 ** bits
    return np.round(x / lsb) * lsb


PARTS = {"white": white, "rms": rms, "gain": gain, "offset": offset, "pink": pink, "quantise": quantise}


@dataclass(frozen=True)
class NoiseModel:
    """A named combination of parts, applied in order (the ADC last), and how summary columns are written."""

    name: str
    parts: tuple[tuple[str, dict], ...]
    summary_mode: str = "rounded"          # "rounded" or "stated"
    summary_sd: dict = field(default_factory=lambda: {"rop_m_s": 0.05, "peak_force_n": 0.03, "peak_decel_g": 0.03,
                                                      "impacts_per_cycle": 0.02})

    def apply(self, x: np.ndarray, fs: float, rng: np.random.Generator, signal: str) -> np.ndarray:
        for part, kw in self.parts:
            x = PARTS[part](x, fs, rng, signal, **kw)
        return x

    def apply_before_adc(self, x: np.ndarray, fs: float, rng: np.random.Generator, signal: str) -> np.ndarray:
        """The parts that act before the ADC (all but quantisation), in order."""
        for part, kw in self.parts:
            if part != "quantise":
                x = PARTS[part](x, fs, rng, signal, **kw)
        return x

    @property
    def adc_bits(self) -> int | None:
        """The ADC's bits if the model quantises, else None."""
        return next((kw.get("bits", 16) for part, kw in self.parts if part == "quantise"), None)

    def summary(self, values: dict, rng: np.random.Generator) -> dict:
        """Summary columns of a run from its noise-free values."""
        out = {}
        for k, v in values.items():
            if self.summary_mode == "rounded":
                out[k] = float(f"{v:.6g}")
            else:
                sd = self.summary_sd[k] * abs(v)
                out[k] = float(f"{v + sd * rng.standard_normal():.6g}")
                out[f"{k}_sd"] = float(f"{sd:.3g}") if sd > 0 else 1e-12
        return out


NOISE_MODELS: dict[str, NoiseModel] = {
    # no noise at all (what the simulators agree on; summaries rounded to 6 digits)
    "clean": NoiseModel("clean", ()),
    # ~2 % of the record's RMS, white, with constant offsets: the blind logs' description (every model keeps the
    # sensors' own floor: a channel without contact still records noise)
    "white2": NoiseModel("white2", (("white", {"level": 1.0}), ("rms", {"level": 0.02}), ("offset", {"level": 0.0}))),
    # a real chain: sensor floor, 1 % RMS noise, 2 % gain noise, 1/f noise, offsets with slow drift, 16-bit ADC;
    # summaries with a stated precision
    "rig": NoiseModel("rig", (("white", {"level": 1.0}), ("rms", {"level": 0.01}), ("gain", {"level": 0.02}),
                              ("pink", {"level": 0.01}), ("offset", {"level": 0.005}), ("quantise", {"bits": 16})),
                      summary_mode="stated"),
    # noise proportional to the instantaneous signal dominates (charge-amplifier gain noise), 12-bit ADC
    "gain5": NoiseModel("gain5", (("white", {"level": 1.0}), ("gain", {"level": 0.05}), ("rms", {"level": 0.002}),
                                  ("quantise", {"bits": 12}))),
    # strongly coloured noise: 1/f at 3 % with drift
    "pink3": NoiseModel("pink3", (("white", {"level": 1.0}), ("pink", {"level": 0.03}), ("offset", {"level": 0.02}))),
}
"""Noise models of the identification matrix (docs/identification.md says which ran)."""


def noise_floor_note(model: NoiseModel) -> str:
    """One line describing a noise model (for the matrix's legend)."""
    return " + ".join(f"{p}({', '.join(f'{k}={v:g}' for k, v in kw.items())})" for p, kw in model.parts) + \
        f"; summaries {model.summary_mode}"


def _check() -> None:
    for m in NOISE_MODELS.values():
        for part, _ in m.parts:
            assert part in PARTS, part
        assert m.summary_mode in ("rounded", "stated")
    assert math.isfinite(SENSOR_FLOOR["accel_m_s2"])


_check()
