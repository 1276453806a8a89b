"""Synthetic measured datasets (MODELS.md §7) from the simulator, for testing the diagnosis.

The "true" rig is any supported model (indenter-metal, indenter-sandstone, drill, pendulum, rimd) with
(i) its calibratable parameters (MODELS.md §6) perturbed log-normally, (ii) optionally any §6 effect
switched on, (iii) optionally physics outside the library (``outside``), and (iv) sensor noise and
offsets.  It is recorded the way a data-acquisition system records it: uniformly at ``fs_hz`` (not a
multiple of the forcing frequency; the model is simulated at >= 4x that rate and interpolated onto the
DAQ's time base), over a record that is not a whole number of cycles, either in steady state or, with
``record_start_s``, a stretch of a run from rest (the drill: blunting never settles).  ``summary_runs``
runs are written as summary.csv rows only, and ``drop_signal_every`` removes one signal from some runs.
The truth goes to a separate file (never read by the diagnosis).
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
"""Indenter effect strengths used when only the effect's name is given: each visibly changes the response
(order 10 % on the acceleration harmonics) without changing the impact regime everywhere."""
_OTHER_DEFAULTS = {
    # contact rate ~0.3 m/s: +30 % contact stiffness
    "pendulum": {"rate_stiffening": {"alpha": 1.0}},
    # impact velocity ~0.1 m/s: +20 %; beam amplitude ~2 mm: kappa x1^2 ~ 0.4
    "rimd": {"rate_stiffening": {"alpha": 2.0}, "suspension_hardening": {"kappa": 1.0e5}},
}


def effect_defaults(system: str) -> dict[str, dict[str, float]]:
    """Default effect strengths of ``system``: the drill's are its model's EFFECT_VISIBLE (measured visible on
    the lab preset, sim/models/drill.py); pendulum and rimd as _OTHER_DEFAULTS; the indenter's EFFECT_DEFAULTS."""
    if system == "drill":
        from sim.models.drill import EFFECT_VISIBLE

        return {k: dict(v) for k, v in EFFECT_VISIBLE.items()}
    return {k: dict(v) for k, v in _OTHER_DEFAULTS.get(system, EFFECT_DEFAULTS).items()}


OUTSIDE = {
    "mount_resonance": "the accelerometer sits on a resonant mount: measured acceleration = true acceleration "
                       "through a lightly damped 2nd-order resonance (fr_hz, zeta); no §6 effect has a resonance",
    "contact_hertz": "metal sample only: the contact is elastic Hertzian, F = kh (x1 - G)^1.5 with no damping "
                     "(simulated with the sandstone law at kl = ku = kh, nl = nu = 1.5) instead of Kelvin-Voigt",
}
"""Physics outside the library, for the 'unexplained' test."""
MOUNT_HZ = {"indenter-metal": 450.0, "indenter-sandstone": 450.0, "drill": 1200.0, "pendulum": 40.0, "rimd": 60.0}
"""Default mount resonance per system: inside the harmonics the diagnosis uses (model.default_max_harmonic_hz)."""

TABLE1_HZ = (30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0)


@dataclass(frozen=True)
class RigDefaults:
    """What a rig of one system records by default: frequencies, the second control axis (name, values),
    fixed controls, preset, signals, DAQ rate, record length, record_start_s (None: steady state)."""

    frequencies_hz: tuple[float, ...]
    level_name: str
    levels: tuple[float, ...]
    fixed: dict
    preset: str | None
    signals: tuple[str, ...]
    fs_hz: float
    cycles: float
    record_start_s: tuple[float, ...] | None = None
    summary_runs: int = 0
    drop_signal_every: int = 0


RIGS = {
    "indenter-metal": RigDefaults(TABLE1_HZ, "pressure_bar", (1.0, 1.5), {"gap_m": 1e-3}, None,
                                  ("accel_m_s2", "force_n", "disp_m"), 20000.0, 40),
    "indenter-sandstone": RigDefaults(TABLE1_HZ, "pressure_bar", (1.0, 1.5), {"gap_m": 1e-3}, None,
                                      ("accel_m_s2", "force_n", "disp_m"), 20000.0, 40),
    # lab drilling rig (drill preset 'lab', MODELS.md §2): 8 frequencies across the RED resonance x two
    # weights on bit; a 25.6 kHz DAQ logs 0.1 s stretches at different times (depths) after spud-in;
    # two runs were logged as summaries only (ROP, peak WOB force, ...) and every 5th run lost its force channel
    "drill": RigDefaults((150.0, 190.0, 230.0, 270.0, 310.0, 350.0, 390.0, 430.0), "static_force_n", (900.0, 1500.0),
                         {"amplitude_n": 2250.0, "gap_m": 0.0}, "lab", ("accel_m_s2", "force_n", "progression_m"),
                         25600.0, 28.3, (0.15, 0.3, 0.45, 0.6), 2, 5),
    # pendulum (seed 001): around the z = 1/1 and 1/2 resonances, gaps 0 and 1 mm, 10 kHz DAQ
    "pendulum": RigDefaults((2.5, 3.0, 3.5, 3.75, 4.5, 5.5, 6.5, 7.25), "gap_m", (0.0, 1.0e-3),
                            {"amplitude_m": 0.89e-3}, None, ("accel_m_s2", "force_n", "disp_m"), 10000.0, 12.4),
    # RIMD (seed 002): across the first impact resonance at gap 0, two forcing levels, 10 kHz DAQ
    "rimd": RigDefaults((5.0, 6.0, 6.5, 7.0, 7.5, 8.0, 9.0, 10.0), "amplitude_n", (0.5, 1.0),
                        {"gap_m": 0.0}, None, ("accel_m_s2", "force_n", "disp_m"), 10000.0, 16.3),
}


@dataclass
class SynthConfig:
    """What to generate.  Units: Hz, seconds, SI; ``levels`` are values of the rig's second control
    (indenter: pressure in bar; drill: static force N; pendulum: gap m; rimd: amplitude N); noise_* are
    fractions of the signal's standard deviation; offsets are sds of a constant sensor offset per run.
    None = the system's RigDefaults."""

    system: str                                                     # any model with calibratable parameters (RIGS)
    effects: dict[str, float] = field(default_factory=dict)        # parameter name -> value
    outside: str | None = None
    outside_params: dict[str, float] = field(default_factory=dict)
    frequencies_hz: tuple[float, ...] | None = None
    levels: tuple[float, ...] | None = None
    pressures_bar: tuple[float, ...] | None = None    # indenter alias of levels
    perturb: float = 0.3            # log-normal sd of the calibratable parameters
    seed: int = 0
    cycles: float | None = None     # recorded forcing cycles per run (need not be whole)
    fs_hz: float | None = None      # DAQ sample rate
    record_start_s: tuple[float, ...] | None = None   # cycled over the runs; () = steady state
    summary_runs: int | None = None
    drop_signal_every: int | None = None
    signals: tuple[str, ...] | None = None
    noise_accel: float = 0.03
    noise_force: float = 0.02
    noise_disp_m: float = 1.0e-6
    offset_accel_m_s2: float = 2.0
    offset_force_n: float = 5.0
    offset_disp_m: float = 1.0e-4
    n_threads: int | None = None

    def resolved(self) -> "SynthConfig":
        """A copy with every None filled from the system's RigDefaults."""
        if self.system not in RIGS:
            raise UserError(f"--system {self.system}: synthetic data are available for {', '.join(RIGS)}")
        rig = RIGS[self.system]
        c = SynthConfig(**asdict(self))
        c.frequencies_hz = tuple(self.frequencies_hz or rig.frequencies_hz)
        c.levels = tuple(self.levels or self.pressures_bar or rig.levels)
        c.cycles = float(self.cycles if self.cycles is not None else rig.cycles)
        c.fs_hz = float(self.fs_hz or rig.fs_hz)
        c.record_start_s = tuple(rig.record_start_s or ()) if self.record_start_s is None else tuple(self.record_start_s)
        c.summary_runs = rig.summary_runs if self.summary_runs is None else self.summary_runs
        c.drop_signal_every = rig.drop_signal_every if self.drop_signal_every is None else self.drop_signal_every
        c.signals = tuple(self.signals or rig.signals)
        return c


def resolve_effects(system: str, names_or_values: dict[str, float | None]) -> dict[str, float]:
    """Map ``{"shaker_coil": None, "alpha": 2.0}`` to parameter values, checking that each effect
    applies to ``system`` (MODELS.md §6)."""
    import sim

    if system not in sim.model_names():
        raise UserError(f"--system {system}: unknown (known: {', '.join(sim.model_names())})")
    spec = sim.get_model(system)
    dflt = effect_defaults(system)
    out: dict[str, float] = {}
    param_of = {p: eff for eff, ps in spec.effects.items() for p in ps}
    for key, val in names_or_values.items():
        if key in spec.effects:
            defaults = dflt[key]
            out.update(defaults if val is None else {spec.effects[key][0]: float(val)})
            if val is not None and len(spec.effects[key]) > 1:
                out.update({p: defaults[p] for p in spec.effects[key][1:]})
        elif key in param_of:
            if val is None:
                raise UserError(f"--effect {key}: give a value, e.g. {key}={dflt[param_of[key]][key]:g}")
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
    """Calibratable parameters perturbed log-normally (seeded) around the rig's values, plus the effects."""
    import sim

    cfg = cfg.resolved()
    rig = RIGS[cfg.system]
    d = sim.get_model(cfg.system).defaults(rig.preset)
    rng = np.random.default_rng(cfg.seed)
    truth = {p.name: float(d[p.name] * math.exp(cfg.perturb * rng.standard_normal())) for p in sim.get_model(cfg.system).calibratable}
    truth.update(cfg.effects)
    return truth


def _mount_resonance(a: np.ndarray, fs: float, fr: float, zeta: float, periodic: bool) -> np.ndarray:
    """Acceleration through H(s) = wr^2 / (s^2 + 2 zeta wr s + wr^2) (bilinear, prewarped at fr).  A periodic
    (steady-state) window is prepended to itself so the result is the filter's steady state; a record from
    rest is filtered from rest."""
    from scipy.signal import bilinear, lfilter

    wr = 2 * math.pi * fr
    b, a_ = bilinear([wr ** 2], [1.0, 2 * zeta * wr, wr ** 2], fs=fs)
    if not periodic:
        return lfilter(b, a_, a)
    y = lfilter(b, a_, np.concatenate([a, a, a]))
    return y[2 * a.size:]


def _hertz_model() -> str:
    """The rig model with power-law contact exponents (nl, nu): simulates a Hertz contact (nl = nu = 1.5)."""
    import sim

    return next(n for n in rig_systems() if {"nl", "nu"} <= set(sim.get_model(n).param_names))


def _simulate_run(cfg: SynthConfig, truth: dict, row: dict, known: dict):
    """The true run sampled on the DAQ's time base: (t, true signals, true summary features)."""
    import sim

    from pipeline.diagnosis.features import _history_summary

    f = row["frequency_hz"]
    spc = max(32, int(math.ceil(4.0 * cfg.fs_hz / f)))      # >= 4x the DAQ rate, then interpolated
    rs = row.get("record_start_s")
    from_rest = rs is not None and np.isfinite(rs)
    n_rec = int(math.floor(row["duration_s"] * cfg.fs_hz))
    if from_rest:
        st = {"samples_per_cycle": spc, "min_transient": 0, "max_transient": 0,
              "window": int(math.ceil((rs + row["duration_s"]) * f)) + 1}
    else:
        st = {"samples_per_cycle": spc, "window": int(math.ceil(cfg.cycles)) + 1}
    ctrl = {k: row[k] for k in ("frequency_hz", "amplitude_n", "amplitude_m", "static_force_n", "gap_m")
            if k in row and np.isfinite(row[k])}
    if cfg.outside == "contact_hertz":
        kh = cfg.outside_params.get("kh", 3.0e8)     # N/m^1.5: same order of contact force as k1 = 1e7 N/m
        params = {k: v for k, v in truth.items() if k not in ("k1", "c1")}
        r = sim.simulate(_hertz_model(), settings=st, history=True, kl=kh, ku=kh, nl=1.5, nu=1.5,
                         **{**known, **ctrl, **params})
    else:
        r = sim.simulate(cfg.system, settings=st, history=True, **{**known, **ctrl, **truth})
    if r.history is None:
        raise UserError(f"run {row['run_id']}: the true model ended with status {r.status} ({r.labels['reason']}); "
                        "choose other effect values or another seed")
    h = r.history
    th = h["t_s"].to_numpy() - (0.0 if from_rest else float(h["t_s"].iloc[0]))
    a = h["accel_m_s2"].to_numpy()
    if cfg.outside == "mount_resonance":
        a = _mount_resonance(a, spc * f, cfg.outside_params.get("fr_hz", MOUNT_HZ[cfg.system]),
                             cfg.outside_params.get("zeta", 0.1), periodic=not from_rest)
    t = np.arange(n_rec) / cfg.fs_hz
    tq = t + (rs if from_rest else 0.0)
    sig = {"accel_m_s2": a, "force_n": h["force_n"].to_numpy(), "disp_m": h["disp_m"].to_numpy(),
           "progression_m": h["progression_m"].to_numpy() - (0.0 if from_rest else h["progression_m"].iloc[0])}
    sig = {k: np.interp(tq, th, v) for k, v in sig.items()}
    if from_rest:
        m = (th >= rs) & (th < rs + row["duration_s"])
        hc = h.loc[m].assign(accel_m_s2=a[m])
        summ = {k: _history_summary(k, th[m], hc, f) for k in ("rop_m_s", "peak_force_n", "impacts_per_cycle",
                                                             "peak_decel_g")}
    else:
        summ = {k: r.labels[k] for k in ("rop_m_s", "peak_force_n", "impacts_per_cycle", "peak_decel_g")}
    return {"t_s": t}, sig, {**summ, "status": r.labels["status"]}


def _add_noise(cfg: SynthConfig, sig: dict, rng: np.random.Generator, signals) -> dict:
    out = {}
    for name in signals:
        x = sig[name]
        n = x.size
        if name == "accel_m_s2":
            y = x + cfg.noise_accel * x.std() * rng.standard_normal(n) + cfg.offset_accel_m_s2 * rng.standard_normal()
        elif name == "force_n":
            y = x + cfg.noise_force * x.std() * rng.standard_normal(n) + cfg.offset_force_n * rng.standard_normal()
        elif name == "disp_m":
            y = x + cfg.noise_disp_m * rng.standard_normal(n) + cfg.offset_disp_m * rng.standard_normal()
        else:   # progression: depth sensor in the rig frame (no offset: MODELS.md §7)
            y = x + cfg.noise_disp_m * rng.standard_normal(n)
        out[name] = y
    return out


def run_table(cfg: SynthConfig) -> pd.DataFrame:
    """runs.csv rows: every frequency x every level of the rig's second control (indenter: Table 1 forcing
    amplitude, interpolated; static force = pneumatic force of the pressure, §1)."""
    cfg = cfg.resolved()
    rig = RIGS[cfg.system]
    rows = []
    tag = cfg.system.split("-")[-1][:5]
    for j, lev in enumerate(cfg.levels):
        for i, f in enumerate(cfg.frequencies_hz):
            row = {"run_id": f"{tag}-{f:g}hz-{j + 1}", "system": cfg.system, "frequency_hz": float(f)}
            if cfg.system.startswith("indenter"):
                from sim.models.indenter import TABLE1, pneumatic_force

                fs_known = np.array(sorted(TABLE1))
                row.update(amplitude_n=float(np.interp(f, fs_known, [TABLE1[k] for k in fs_known])),
                           static_force_n=pneumatic_force(lev, 0.05), gap_m=1e-3)
                row["run_id"] = f"{tag}-{f:g}hz-{lev:g}bar"
            else:
                row.update(rig.fixed)
                row[rig.level_name] = float(lev)
            row["duration_s"] = cfg.cycles / float(f)
            if rig.preset:
                row["preset"] = rig.preset
            if cfg.record_start_s:
                row["record_start_s"] = cfg.record_start_s[(i + j * len(cfg.frequencies_hz)) % len(cfg.record_start_s)]
            rows.append(row)
    return pd.DataFrame(rows)


def _summary_picks(n: int, k: int) -> list[int]:
    """Which runs are logged as summaries only: k runs spread over the table, never the first or last."""
    if k <= 0:
        return []
    return sorted({int(round(x)) for x in np.linspace(1, n - 2, k + 2)[1:-1]})[:k]


def synthesize(cfg: SynthConfig, progress: bool = False) -> tuple[Dataset, dict]:
    """Build the dataset in memory: (Dataset, truth) — nothing is written here."""
    import os

    import sim

    from tqdm import tqdm

    from pipeline.datasets.measured import known_parameters

    cfg = cfg.resolved()
    if cfg.outside is not None and cfg.outside not in OUTSIDE:
        raise UserError(f"--outside {cfg.outside}: unknown (known: {', '.join(OUTSIDE)})")
    if cfg.outside == "contact_hertz" and "k1" not in sim.get_model(cfg.system).param_names:
        raise UserError(f"--outside contact_hertz replaces a linear contact stiffness k1, which {cfg.system} does not have")
    for s in cfg.signals:
        if s not in ("accel_m_s2", "force_n", "disp_m", "progression_m"):
            raise UserError(f"--signals: unknown signal '{s}' (accel_m_s2, force_n, disp_m, progression_m)")
    if cfg.cycles < 2.5:
        raise UserError(f"--cycles must be >= 2.5, got {cfg.cycles:g}")
    truth = true_parameters(cfg)
    runs = run_table(cfg)
    known = known_parameters(runs)
    rows = runs.to_dict("records")
    workers = cfg.n_threads or os.cpu_count() or 1
    from sim.registry import warm

    warm(_hertz_model() if cfg.outside == "contact_hertz" else cfg.system)
    with ThreadPoolExecutor(max_workers=workers) as pool:
        it = pool.map(lambda row: _simulate_run(cfg, truth, row, known[row["run_id"]]), rows)
        results = list(tqdm(it, total=len(rows), desc="synth", disable=not progress, unit="run"))
    rng = np.random.default_rng([cfg.seed, 1])
    summ_idx = set(_summary_picks(len(rows), cfg.summary_runs))
    series, labels, summary = {}, {}, []
    for i, (row, (t, sig, lab)) in enumerate(zip(rows, results)):
        labels[row["run_id"]] = lab
        if i in summ_idx:    # a summary-only log: features with 5 % (ROP 10 %) measurement scatter
            srow = {"run_id": row["run_id"]}
            for k, rel in (("rop_m_s", 0.10), ("peak_force_n", 0.05), ("peak_decel_g", 0.05)):
                if lab[k] is not None:
                    srow[k] = lab[k] * (1 + rel * rng.standard_normal())
                    srow[f"{k}_sd"] = rel * abs(lab[k])
            summary.append(srow)
            continue
        sigs = list(cfg.signals)
        if cfg.drop_signal_every and i % cfg.drop_signal_every == cfg.drop_signal_every - 1 and len(sigs) > 1:
            sigs = sigs[:1] + sigs[2:]          # this run lost its second channel
        series[row["run_id"]] = pd.DataFrame({**t, **_add_noise(cfg, sig, rng, sigs)})
    info = {"system": cfg.system, "truth": truth, "effects": dict(cfg.effects), "outside": cfg.outside,
            "outside_params": cfg.outside_params,
            "config": {k: v for k, v in asdict(cfg).items() if k not in ("effects", "outside_params")},
            "true_labels": labels}
    readme = (f"# Synthetic dataset ({cfg.system})\n\nGenerated by `vibro synth` (pipeline/datasets/synth.py), seed {cfg.seed}.\n"
              f"DAQ rate {cfg.fs_hz:g} Hz, {cfg.cycles:g} cycles per record"
              + (f", records from rest starting at {', '.join(f'{x:g}' for x in cfg.record_start_s)} s" if cfg.record_start_s
                 else ", steady state") + f", {len(summary)} summary-only runs.\n"
              f"Effects switched on: {cfg.effects or 'none'}; outside physics: {cfg.outside or 'none'}.\n"
              "The truth (perturbed calibratable parameters, effect values) is kept apart from the data "
              "(the diagnosis does not read it).\n")
    ds = Dataset(runs=runs, series=series, summary=pd.DataFrame(summary).set_index("run_id") if summary else None,
                 extra_files={"README.md": readme}, known=known)
    return ds, info
