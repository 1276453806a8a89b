"""Synthetic measured datasets (MODELS.md §7) from the simulator, for testing the diagnosis.

The "true" rig is the indenter model with (i) its calibratable parameters (MODELS.md §1) perturbed
log-normally, (ii) optionally any §6 effect switched on, (iii) optionally physics outside the
library (``outside``), and (iv) sensor noise and offsets.  The recorded series is the steady-state
window of the simulation, shifted so that t = 0 is the start of a forcing cycle (forcing phase 0,
Fa sin(2π f t)), sampled uniformly at about ``fs_hz``.  The truth is written to ``truth.json``
inside the dataset (the diagnosis never reads it).
"""
from __future__ import annotations

import json
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.datasets.measured import Dataset

EFFECT_DEFAULTS = {
    "shaker_coil": {"tau": 1.0e-3, "beta": 600.0},
    "rate_stiffening": {"alpha": 3.0},
    "guide_friction": {"mu": 40.0},
    "tip_blunting": {"gamma": 0.05},
    "suspension_hardening": {"kappa": 3.0e5},
    "sensor_lowpass": {"fc": 350.0},
}
"""Effect strengths used when only the effect's name is given: each visibly changes the response
(order 10 % on the acceleration harmonics) without changing the impact regime everywhere."""

OUTSIDE = {
    "mount_resonance": "the accelerometer sits on a resonant mount: measured acceleration = true acceleration "
                       "through a lightly damped 2nd-order resonance (fr_hz, zeta); no §6 effect has a resonance",
    "contact_hertz": "metal sample only: the contact is elastic Hertzian, F = kh (x1 - G)^1.5 with no damping "
                     "(simulated with the sandstone law at kl = ku = kh, nl = nu = 1.5) instead of Kelvin-Voigt",
}
"""Physics outside the library, for the 'unexplained' test."""

TABLE1_HZ = (30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0)


@dataclass
class SynthConfig:
    """What to generate.  Units: Hz, bar, seconds; noise_* are fractions of the signal's standard
    deviation; offsets are standard deviations of a constant sensor offset per run (SI units)."""

    system: str                                                     # a model of the indenter rig (rig_systems())
    effects: dict[str, float] = field(default_factory=dict)        # parameter name -> value
    outside: str | None = None
    outside_params: dict[str, float] = field(default_factory=dict)
    frequencies_hz: tuple[float, ...] = TABLE1_HZ
    pressures_bar: tuple[float, ...] = (1.0, 1.5)
    perturb: float = 0.3            # log-normal sd of the calibratable parameters
    seed: int = 0
    cycles: int = 40                # recorded forcing cycles per run
    fs_hz: float = 20000.0          # approximate sample rate (exactly f x samples-per-cycle)
    signals: tuple[str, ...] = ("accel_m_s2", "force_n", "disp_m")
    noise_accel: float = 0.03
    noise_force: float = 0.02
    noise_disp_m: float = 1.0e-6
    offset_accel_m_s2: float = 2.0
    offset_force_n: float = 5.0
    offset_disp_m: float = 1.0e-4
    n_threads: int | None = None


def resolve_effects(system: str, names_or_values: dict[str, float | None]) -> dict[str, float]:
    """Map ``{"shaker_coil": None, "alpha": 2.0}`` to parameter values, checking that each effect
    applies to ``system`` (MODELS.md §6)."""
    import sim

    spec = sim.get_model(system)
    out: dict[str, float] = {}
    param_of = {p: eff for eff, ps in spec.effects.items() for p in ps}
    for key, val in names_or_values.items():
        if key in spec.effects:
            defaults = EFFECT_DEFAULTS[key]
            out.update(defaults if val is None else {spec.effects[key][0]: float(val)})
            if val is not None and len(spec.effects[key]) > 1:
                out.update({p: defaults[p] for p in spec.effects[key][1:]})
        elif key in param_of:
            if val is None:
                raise UserError(f"--effect {key}: give a value, e.g. {key}={EFFECT_DEFAULTS[param_of[key]][key]:g}")
            out[key] = float(val)
        else:
            known = ", ".join(sorted(spec.effects) + sorted(param_of))
            raise UserError(f"--effect {key}: not an effect of {system} (known: {known})")
    return out


def rig_systems() -> tuple[str, ...]:
    """Models of the rig whose operating points the run table uses (Table 1 amplitudes, pneumatic static force)."""
    from sim.models.indenter import SPECS

    return tuple(SPECS)


def true_parameters(cfg: SynthConfig) -> dict[str, float]:
    """Calibratable parameters perturbed log-normally (seeded) plus the effect parameters."""
    import sim

    spec = sim.get_model(cfg.system)
    if cfg.system not in rig_systems() or not spec.calibratable:
        raise UserError(f"--system {cfg.system}: synthetic data are available for {', '.join(rig_systems())} "
                        "(the indenter rig's models, MODELS.md §1)")
    d = spec.defaults()
    rng = np.random.default_rng(cfg.seed)
    truth = {p: float(d[p] * math.exp(cfg.perturb * rng.standard_normal())) for p in (b.name for b in spec.calibratable)}
    truth.update(cfg.effects)
    return truth


def _mount_resonance(a: np.ndarray, fs: float, fr: float, zeta: float) -> np.ndarray:
    """True acceleration through H(s) = wr^2 / (s^2 + 2 zeta wr s + wr^2) (bilinear, prewarped at fr);
    the periodic window is prepended to itself so the result is the filter's steady state."""
    from scipy.signal import bilinear, lfilter

    wr = 2 * math.pi * fr
    b, a_ = bilinear([wr ** 2], [1.0, 2 * zeta * wr, wr ** 2], fs=fs)
    y = lfilter(b, a_, np.concatenate([a, a, a]))
    return y[2 * a.size:]


def _hertz_model() -> str:
    """The rig model with power-law contact exponents (nl, nu): simulates a Hertz contact (nl = nu = 1.5)."""
    import sim

    return next(n for n in rig_systems() if {"nl", "nu"} <= set(sim.get_model(n).param_names))


def _simulate_run(cfg: SynthConfig, truth: dict, row: dict):
    import sim

    spc = max(16, int(round(cfg.fs_hz / row["frequency_hz"])))
    st = {"samples_per_cycle": spc, "window": cfg.cycles}
    ctrl = {k: row[k] for k in ("frequency_hz", "amplitude_n", "static_force_n", "gap_m")}
    if cfg.outside == "contact_hertz":
        kh = cfg.outside_params.get("kh", 3.0e8)     # N/m^1.5: same order of contact force as k1 = 1e7 N/m
        params = {k: v for k, v in truth.items() if k not in ("k1", "c1")}
        r = sim.simulate(_hertz_model(), settings=st, history=True, kl=kh, ku=kh, nl=1.5, nu=1.5,
                         **ctrl, **params)
    else:
        r = sim.simulate(cfg.system, settings=st, history=True, **ctrl, **truth)
    if r.history is None:
        raise UserError(f"run {row['run_id']}: the true model ended with status {r.status} ({r.labels['reason']}); "
                        "choose other effect values or another seed")
    h = r.history
    fs = spc * row["frequency_hz"]
    out = {"t_s": np.arange(len(h)) / fs}
    a = h["accel_m_s2"].to_numpy()
    if cfg.outside == "mount_resonance":
        a = _mount_resonance(a, fs, cfg.outside_params.get("fr_hz", 450.0), cfg.outside_params.get("zeta", 0.1))
    sig = {"accel_m_s2": a, "force_n": h["force_n"].to_numpy(), "disp_m": h["disp_m"].to_numpy(),
           "progression_m": h["progression_m"].to_numpy() - h["progression_m"].iloc[0]}
    return out, sig, r.labels


def _add_noise(cfg: SynthConfig, sig: dict, rng: np.random.Generator) -> dict:
    out = {}
    for name in cfg.signals:
        x = sig[name]
        n = x.size
        if name == "accel_m_s2":
            y = x + cfg.noise_accel * x.std() * rng.standard_normal(n) + cfg.offset_accel_m_s2 * rng.standard_normal()
        elif name == "force_n":
            y = x + cfg.noise_force * x.std() * rng.standard_normal(n) + cfg.offset_force_n * rng.standard_normal()
        elif name == "disp_m":
            y = x + cfg.noise_disp_m * rng.standard_normal(n) + cfg.offset_disp_m * rng.standard_normal()
        else:   # progression: displacement sensor on the crater floor (same noise as disp_m, no offset needed)
            y = x + cfg.noise_disp_m * rng.standard_normal(n)
        out[name] = y
    return out


def run_table(cfg: SynthConfig) -> pd.DataFrame:
    """runs.csv rows: every frequency of ``frequencies_hz`` (Table 1 forcing amplitude, interpolated
    between Table 1 frequencies) x every pressure (static force = pneumatic force of §1)."""
    from sim.models.indenter import TABLE1, pneumatic_force

    fs_known = np.array(sorted(TABLE1))
    rows = []
    for p in cfg.pressures_bar:
        for f in cfg.frequencies_hz:
            fa = float(np.interp(f, fs_known, [TABLE1[k] for k in fs_known]))
            rows.append({"run_id": f"{cfg.system.split('-')[1][:5]}-{f:g}hz-{p:g}bar", "system": cfg.system,
                         "frequency_hz": float(f), "amplitude_n": fa,
                         "static_force_n": pneumatic_force(p, 0.05), "gap_m": 1e-3,
                         "duration_s": cfg.cycles / float(f)})
    return pd.DataFrame(rows)


def synthesize(cfg: SynthConfig, progress: bool = False) -> tuple[Dataset, dict]:
    """Build the dataset in memory: (Dataset, truth) — nothing is written here."""
    import os

    import sim

    from tqdm import tqdm

    if cfg.outside is not None and cfg.outside not in OUTSIDE:
        raise UserError(f"--outside {cfg.outside}: unknown (known: {', '.join(OUTSIDE)})")
    if cfg.outside == "contact_hertz" and "k1" not in sim.get_model(cfg.system).param_names:
        raise UserError(f"--outside contact_hertz replaces a linear contact stiffness k1, which {cfg.system} does not have")
    for s in cfg.signals:
        if s not in ("accel_m_s2", "force_n", "disp_m", "progression_m"):
            raise UserError(f"--signals: unknown signal '{s}' (accel_m_s2, force_n, disp_m, progression_m)")
    if cfg.cycles < 4:
        raise UserError(f"--cycles must be >= 4, got {cfg.cycles}")
    truth = true_parameters(cfg)
    runs = run_table(cfg)
    rows = runs.to_dict("records")
    workers = cfg.n_threads or os.cpu_count() or 1
    from sim.registry import warm

    warm(_hertz_model() if cfg.outside == "contact_hertz" else cfg.system)
    with ThreadPoolExecutor(max_workers=workers) as pool:
        it = pool.map(lambda row: _simulate_run(cfg, truth, row), rows)
        results = list(tqdm(it, total=len(rows), desc="synth", disable=not progress, unit="run"))
    rng = np.random.default_rng([cfg.seed, 1])
    series, labels = {}, {}
    for row, (t, sig, lab) in zip(rows, results):
        series[row["run_id"]] = pd.DataFrame({**t, **_add_noise(cfg, sig, rng)})
        labels[row["run_id"]] = {k: lab[k] for k in ("peak_decel_g", "impacts_per_cycle", "rop_m_s", "status")}
    info = {"system": cfg.system, "truth": truth, "effects": dict(cfg.effects), "outside": cfg.outside,
            "outside_params": cfg.outside_params, "config": {k: v for k, v in asdict(cfg).items()
                                                              if k not in ("effects", "outside_params")},
            "true_labels": labels}
    readme = (f"# Synthetic dataset ({cfg.system})\n\nGenerated by `vibro synth` (pipeline/synth.py), seed {cfg.seed}.\n"
              f"Effects switched on: {cfg.effects or 'none'}; outside physics: {cfg.outside or 'none'}.\n"
              "The truth (perturbed calibratable parameters, effect values) is in truth.json; "
              "the diagnosis does not read it.\n")
    ds = Dataset(runs=runs, series=series, summary=None,
                 extra_files={"truth.json": json.dumps(info, indent=2, default=str), "README.md": readme})
    return ds, info
