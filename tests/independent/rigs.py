"""The five rigs of MODELS.md as an independent lab would set them up: known parameters, the calibratable ones
(perturbed in the truth), the operating grid, the data-acquisition system and visible effect strengths.

Values are MODELS.md's (§1-4 tables, the drill's `lab` rig of §2 as the project documents it); nothing here is
read from ``sim/``.  Records either start from rest (``record_start_s``: the record holds what the rig did after
that long, transients and drifts included) or follow a long settling run (steady state, starting at forcing phase 0).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

TABLE1 = {30: 220.0, 40: 300.0, 50: 370.0, 60: 440.0, 70: 540.0, 80: 650.0, 90: 840.0, 100: 900.0}
"""Seed 000 Table 1: the indenter's forcing amplitude Fa [N] at each frequency [Hz]."""


def _indenter_controls(f: float, pressure_bar: float) -> dict:
    """runs.csv controls of the indenter at f [Hz] and piston pressure [bar] (MODELS.md §1: Fp = 101325/4 P π D²,
    D = 0.05 m; Fa from Table 1; gap 1 mm)."""
    return {"frequency_hz": f, "amplitude_n": TABLE1[int(round(f))],
            "static_force_n": 101325.0 / 4.0 * pressure_bar * math.pi * 0.05 ** 2, "gap_m": 1e-3}


def _indenter_derived(p: dict) -> dict:
    """c3 = 78.6 π² Fa / f (MODELS.md §1, equivalent air damping)."""
    return {"c3": 78.6 * math.pi ** 2 * p["amplitude_n"] / p["frequency_hz"]}


INDENTER = {"m1": 3.46, "m2": 60.0, "m3": 0.5, "k2": 2.30e5, "c2": 2.30e3, "k3": 2.0e4, "pm": 20.0, "v_eps": 1e-4}
METAL = {"k1": 1.0e7, "c1": 300.0}
SANDSTONE = {"kl": 5.0e6, "ku": 2.0e7, "nl": 1.0, "nu": 1.0}
DRILL_LAB = {"M1": 60.0, "M2": 240.0, "M3": 900.0, "K1": 6e8, "K2": 7.58e7, "K3": 6.73e6, "C1": 4e5, "C2": 4.8e4,
             "C3": 3.57e4, "Pr": 3000.0, "v_eps": 1e-4}
PENDULUM = {"m": 0.298, "l": 0.075, "ki": 5.5e6, "ci": 1.2e3, "zeta": 0.005, "g": 9.81}
RIMD = {"m1": 0.368, "k1": 2850.0, "c1": 1.269, "m2": 0.360, "k2": 272.1, "c2": 0.079, "ki": 92.5e3,
        "lambda_i": 8.0, "ni": 0.9}


@dataclass(frozen=True)
class Rig:
    """One rig.  ``controls(f, level)`` gives the runs.csv controls of a run; ``derived(params)`` parameters that
    follow from them.  ``record_start_s`` (cycled over the runs; empty: steady state after ``settle_cycles``),
    ``record_cycles`` (cycled; need not be whole), ``fs_hz`` (cycled: records at different DAQ rates),
    ``effects``: §6 effect -> {parameter: a clearly visible value}; ``outside``: out-of-library physics ->
    {parameter: value} (``outside.py``)."""

    system: str
    known: dict[str, float]
    calibratable: tuple[str, ...]
    controls: Callable[[float, float], dict]
    frequencies_hz: tuple[float, ...]
    levels: tuple[float, ...]
    fs_hz: tuple[float, ...]
    record_cycles: tuple[float, ...]
    signals: tuple[str, ...]
    effects: dict[str, dict[str, float]]
    outside: dict[str, dict[str, float]]
    record_start_s: tuple[float, ...] = ()
    settle_cycles: int = 0
    preset: str | None = None
    derived: Callable[[dict], dict] = lambda p: {}
    summary_runs: int = 2
    drop_signal_every: int = 5
    summary_labels: tuple[str, ...] = ("peak_force_n", "peak_decel_g", "impacts_per_cycle")
    perturb: float = 0.3
    extra: dict = field(default_factory=dict)

    def run_grid(self) -> list[tuple[float, float]]:
        """(frequency, level) of every run: every frequency at every level."""
        return [(f, lev) for lev in self.levels for f in self.frequencies_hz]


_COMMON_INDENTER_EFFECTS = {"shaker_coil": {"tau": 1.0e-3, "beta": 600.0}, "rate_stiffening": {"alpha": 3.0},
                            "guide_friction": {"mu": 40.0}, "suspension_hardening": {"kappa": 3.0e5},
                            "sensor_lowpass": {"fc": 350.0}}

RIGS: dict[str, Rig] = {
    "indenter-metal": Rig(
        system="indenter-metal", known={**INDENTER, **METAL}, calibratable=("k1", "c1", "pm"),
        controls=_indenter_controls, derived=_indenter_derived,
        frequencies_hz=(40.0, 50.0, 60.0, 70.0, 80.0, 90.0), levels=(1.0, 1.5),
        fs_hz=(10000.0, 25600.0), record_cycles=(14.3, 18.7), record_start_s=(0.25, 0.4),
        signals=("accel_m_s2", "force_n", "disp_m"), effects=dict(_COMMON_INDENTER_EFFECTS),
        outside={"mount_resonance": {"fr_hz": 450.0, "zeta_r": 0.08}, "quadratic_damping": {"cq": 3.0e3},
                 # δ_typ 0.14 mm; at 60 Hz / 1 bar: peak force +9.3 %, peak decel +13.0 % (period 1 kept)
                 "contact_power": {"kn": 1.0e12, "pn": 2.5},
                 # mh = 0.2 m1; at 60 Hz / 1 bar: a second impact per cycle (1 -> 2), mean peak force -37 %,
                 # peak decel -11 %, energy/cycle +7 % (period 1 kept)
                 "load_path_mode": {"mh": 0.7, "fh_hz": 300.0, "zeta_h": 0.05},
                 # held-out kinds (kinds.py); effects at 60 Hz / 1 bar over 0.3 s + 10 cycles (period 0 kept):
                 # Hertz-like tip, same stiffness at δ_typ 0.14 mm: peak force +13 % (+4..+21 % over f), decel +19 %
                 "contact_exponent": {"nc": 1.5, "delta_r": 1.4e-4},
                 # unloading δm (δ/δm)^4: peak decel -9 %, peak force -4 % (-5..+17 % over f), energy/cycle -3 %
                 "unloading_hysteresis": {"nu_h": 4.0},
                 # 2 kg plate on a 2e7 N/m mount (503 Hz): peak force -14 % (-7..-34 % over f), peak decel -35 %
                 "mount_mode": {"ms": 2.0, "cm": 5.0e-8, "zeta_m": 0.05},
                 # the plate recedes 0.2 mm per J of loading work: peak force -9 % (-5..-12 % over f), decel -12 %
                 "contact_wear": {"kw": 2.0e-4}}),
    "indenter-sandstone": Rig(
        system="indenter-sandstone", known={**INDENTER, **SANDSTONE}, calibratable=("kl", "ku", "pm"),
        controls=_indenter_controls, derived=_indenter_derived,
        frequencies_hz=(40.0, 50.0, 60.0, 70.0, 80.0, 90.0), levels=(1.0, 1.5),
        fs_hz=(10000.0, 25600.0), record_cycles=(14.3, 18.7), record_start_s=(0.25, 0.4),
        signals=("accel_m_s2", "force_n", "disp_m"),
        effects={**_COMMON_INDENTER_EFFECTS, "tip_blunting": {"gamma": 0.05}},
        outside={"mount_resonance": {"fr_hz": 450.0, "zeta_r": 0.08}, "quadratic_damping": {"cq": 3.0e3},
                 # (no contact_power: the sandstone's own branches are power laws with calibratable stiffnesses)
                 # mh = 0.2 m1; at 60 Hz / 1 bar: peak force +5 %, peak decel -16 %, ROP +4 %, energy/cycle +10 %
                 "load_path_mode": {"mh": 0.7, "fh_hz": 300.0, "zeta_h": 0.05},
                 # held-out kinds (kinds.py); at 60 Hz / 1 bar over 0.3 s + 10 cycles:
                 # cubic flexure loss, ~100 N at φ̇1 0.2 m/s: ROP -7 % (-1..-9 % over f), peak decel -11 %
                 "power_damping": {"cp": 1.0e4, "pd": 3.0},
                 # shaker-body carriages, 40 N (2 x the seal's): peak decel +13 %, energy +38 %, ROP +2 % (-19..+3 %)
                 "support_friction": {"mu_s": 40.0}},
        summary_labels=("rop_m_s", "peak_force_n", "peak_decel_g", "impacts_per_cycle")),
    "drill": Rig(
        system="drill", known=dict(DRILL_LAB), calibratable=("K1", "C1", "Pr"), preset="lab",
        controls=lambda f, fs: {"frequency_hz": f, "amplitude_n": 2250.0, "static_force_n": fs, "gap_m": 0.0},
        frequencies_hz=(150.0, 190.0, 230.0, 270.0, 310.0, 350.0, 390.0, 430.0), levels=(900.0, 1500.0),
        fs_hz=(25600.0, 51200.0), record_cycles=(28.3, 35.9), record_start_s=(0.15, 0.3, 0.45),
        signals=("accel_m_s2", "force_n", "progression_m"),
        effects={"shaker_coil": {"tau": 1e-4, "beta": 3e3}, "rate_stiffening": {"alpha": 50.0},
                 "guide_friction": {"mu": 50.0}, "tip_blunting": {"gamma": 0.01},
                 "suspension_hardening": {"kappa": 3e8}, "sensor_lowpass": {"fc": 1500.0}},
        outside={"mount_resonance": {"fr_hz": 1200.0, "zeta_r": 0.08}, "quadratic_damping": {"cq": 8.0e5},
                 # δ_typ 4.6 µm (kn δ^pn ≈ 0.4 K1 δ there); at 270 Hz / Fs 1500 N the peak force stays capped at
                 # Pr (phase III at every grid point) and the peak decel moves +2.8 %: the effect shows in the ROP,
                 # +11.7 % (+4..18 % over the grid), and in the shape of the phase-II force rise
                 "contact_power": {"kn": 2.5e16, "pn": 2.5},
                 # mh = 0.25 M1, 1 kHz (2.3 x 430 Hz, 1/3 of 3 kHz); at 270 Hz / 1500 N: peak decel +6 %,
                 # ROP +8 %, energy/cycle +7 % (period 1 kept)
                 "load_path_mode": {"mh": 15.0, "fh_hz": 1000.0, "zeta_h": 0.05},
                 # held-out kinds (kinds.py); at 270 Hz / Fs 1500 N over 0.3 s + 10 cycles:
                 # failing rock 5 s/m stronger per m/s of failure rate: ROP -16 % (-11..-17 % over f at 1500 N), peak
                 # force +4 %, decel -10 %
                 "rate_strength": {"eta_r": 5.0},
                 # md = 0.2 M2 at 400 Hz inside the exciter: ROP +8 % (+8..+13 % over f), peak decel +4 %, energy +5 %
                 "drive_mode": {"md": 48.0, "fd_hz": 400.0, "zeta_d": 0.05},
                 # cubic link loss, ~300 N at |ẋ1 - ẋ2| 0.02 m/s: ROP -8 % (-9..+1 % over f), peak decel -3 %
                 "power_damping": {"cp": 4.0e7, "pd": 3.0}},
        summary_labels=("rop_m_s", "peak_force_n", "peak_decel_g", "impacts_per_cycle")),
    "pendulum": Rig(
        system="pendulum", known=dict(PENDULUM), calibratable=("ki", "ci", "zeta"),
        controls=lambda f, gap: {"frequency_hz": f, "amplitude_m": 0.89e-3, "gap_m": gap},
        # 7.25 Hz at gap 1 mm is chaotic (its orbit changes with the solver's tolerance): kept, as rigs record such runs
        frequencies_hz=(2.5, 3.0, 3.5, 3.75, 5.5, 6.5, 7.25), levels=(0.0, 1.0e-3),
        fs_hz=(10000.0, 5000.0), record_cycles=(12.4, 15.1), settle_cycles=150,
        signals=("accel_m_s2", "force_n", "disp_m"),
        effects={"rate_stiffening": {"alpha": 8.0}, "sensor_lowpass": {"fc": 100.0}},
        outside={"mount_resonance": {"fr_hz": 40.0, "zeta_r": 0.08}, "quadratic_damping": {"cq": 6.0},
                 # δ_typ 10 µm; at 3.75 Hz / gap 0: peak force and peak decel +11.3 % (period 1 kept)
                 "contact_power": {"kn": 9.0e13, "pn": 2.5},
                 # mh = 0.2 m; at 3.75 Hz / gap 0: peak force and decel -22 %, energy/cycle -34 % (the impact
                 # meets the hammer alone, the swing carries both masses; period 1 kept)
                 "load_path_mode": {"mh": 0.06, "fh_hz": 25.0, "zeta_h": 0.05},
                 # held-out kinds (kinds.py); at 3.75 Hz / gap 0 after 150 cycles (period 1 kept):
                 # Hertz-like cap, the load cell's stiffness at 4 µm: peak force and decel +16 %
                 "contact_exponent": {"nc": 1.5, "delta_r": 4.0e-6},
                 # unloading δm (δ/δm)^2: peak force -6 %, energy/cycle -9 %
                 "unloading_hysteresis": {"nu_h": 2.0},
                 # the cap wears 2 mm/J of loading work (~0.1 mm over the settling run): peak force -10 %
                 "contact_wear": {"kw": 2.0e-3},
                 # pivot torque 0.01 N x l (0.3 % of the hammer's weight): peak force -8 %, energy/cycle -5 %
                 "support_friction": {"mu_s": 0.01}}),
    "rimd": Rig(
        system="rimd", known=dict(RIMD), calibratable=("ki", "lambda_i", "c1"),
        controls=lambda f, f0: {"frequency_hz": f, "amplitude_n": f0, "gap_m": 0.0},
        frequencies_hz=(5.0, 6.0, 6.5, 7.0, 7.5, 8.0, 9.0), levels=(0.5, 1.0),
        fs_hz=(10000.0, 5000.0), record_cycles=(16.3, 12.8), settle_cycles=250,
        signals=("accel_m_s2", "force_n", "disp_m"),
        effects={"rate_stiffening": {"alpha": 20.0}, "suspension_hardening": {"kappa": 1.0e5},
                 "sensor_lowpass": {"fc": 100.0}},
        outside={"mount_resonance": {"fr_hz": 60.0, "zeta_r": 0.08}, "quadratic_damping": {"cq": 30.0},
                 # δ_typ 67 µm; at 8 Hz / F0 1 N: peak force and decel +11.3 % (1-3 % off resonance; period 1)
                 "contact_power": {"kn": 7.0e10, "pn": 2.5},
                 # mh = 0.15 m2 (the low end): the added mass detunes the sharp 8 Hz impact resonance: peak force
                 # -61 % at 8 Hz, +17 % at 6 Hz, -44 % at 9 Hz (period 1 kept); no smaller mass keeps it subtle
                 "load_path_mode": {"mh": 0.054, "fh_hz": 30.0, "zeta_h": 0.05},
                 # held-out kinds (kinds.py); at 8 Hz / F0 1 N after 250 cycles (period 1 kept):
                 # 50 g stop on a 2e5 N/m support (318 Hz): peak force +14 %, energy/cycle +72 %
                 "mount_mode": {"ms": 0.05, "cm": 5.0e-6, "zeta_m": 0.05},
                 # md = 0.2 m1 at 20 Hz in the beam: peak force +7 %, energy/cycle +19 %
                 "drive_mode": {"md": 0.07, "fd_hz": 20.0, "zeta_d": 0.05},
                 # cubic hammer-spring loss: peak force -16 %
                 "power_damping": {"cp": 200.0, "pd": 3.0},
                 # the beam's clamp, 0.2 N: peak force -5 %, energy/cycle +75 %
                 "support_friction": {"mu_s": 0.2}}),
}

OUTSIDE_KIND = {"contact_power": "contact", "load_path_mode": "mode", "quadratic_damping": "velocity_loss",
                "mount_resonance": "sensor",
                # held-out kinds (kinds.py), labelled by the physics, not by any vocabulary
                "contact_exponent": "contact", "unloading_hysteresis": "contact", "rate_strength": "contact",
                "mount_mode": "mode", "drive_mode": "mode", "contact_wear": "drift",
                "power_damping": "velocity_loss", "support_friction": "friction"}
"""The kind of term each out-of-library physics (``outside.py``) is, for scoring a diagnosis's proposals."""
