"""Synthetic measured datasets (MODELS.md §7) from the simulator, for testing the diagnosis.

The "true" rig is any model whose ModelSpec has a ``synth`` rig (sim.models.base.SynthRig) with
(i) its calibratable parameters (MODELS.md §6) perturbed log-normally, (ii) optionally any §6 effect
switched on, (iii) optionally physics outside the library (``outside``), and (iv) sensor noise and
offsets.  It is recorded the way a data-acquisition system records it: uniformly at ``fs_hz`` (not a
multiple of the forcing frequency; the model is simulated at >= 4x that rate and interpolated onto the
DAQ's time base), over a record that is not a whole number of cycles, either in steady state or, with
``record_start_s``, a stretch of a run from rest (e.g. a drill whose bit blunting never settles).  ``summary_runs``
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
from sim.controls import CONTROLS
from vibrobase.errors import did_you_mean


def effect_defaults(system: str) -> dict[str, dict[str, float]]:
    """Default (clearly visible) effect strengths of ``system``: its ModelSpec's ``synth.effect_strengths``."""
    return {k: dict(v) for k, v in rig_of(system).effect_strengths.items()}


def rig_of(system: str):
    """The model's synthetic rig (``sim.models.base.SynthRig``); UserError for an unknown model or one without."""
    import sim

    if system not in sim.model_names():
        raise UserError(f"--system {system}: unknown{did_you_mean(system, sim.model_names())} "
                        f"(known: {', '.join(sim.model_names())})")
    rig = sim.get_model(system).synth
    if rig is None:
        known = ", ".join(n for n in sim.model_names() if sim.get_model(n).synth is not None)
        raise UserError(f"--system {system}: vibro synth does not know model {system}'s rig (known: {known})")
    return rig


OUTSIDE = {
    "mount_resonance": "the accelerometer sits on a resonant mount: measured acceleration = true acceleration "
                       "through a lightly damped 2nd-order resonance (fr_hz, zeta); no §6 effect has a resonance",
    "contact_hertz": "the contact is elastic Hertzian, F = kh (x1 - G)^1.5 with no damping, simulated by the "
                     "rig's hertz_model (power law at kl = ku = kh, nl = nu = 1.5) instead of a linear k1, c1 contact",
}
"""Physics outside the library, for the 'unexplained' test.  The default mount resonance of a rig is its
``synth.mount_hz`` (inside the harmonics the diagnosis uses)."""

OUTSIDE_PARAMS: dict[str, dict[str, tuple[float, float, str]]] = {
    "mount_resonance": {"fr_hz": (1.0, math.inf, "Hz, below half the sample rate --fs"),
                        "zeta": (1e-4, 100.0, "damping ratio")},
    "contact_hertz": {"kh": (1.0, 1e15, "N/m^1.5")},
}
"""The --outside-param names of each outside physics with their (low, high) bounds [inclusive] and unit."""


def check_outside_params(outside: str | None, values: dict[str, float], fs_hz: float) -> None:
    """UserError naming an --outside-param that its --outside does not have, or a value out of its bounds
    (``fr_hz`` also below the Nyquist frequency ``fs_hz / 2``, where the bilinear filter is defined)."""
    if values and outside is None:
        raise UserError(f"--outside-param {next(iter(values))}: give --outside (one of {', '.join(OUTSIDE)}) too")
    table = OUTSIDE_PARAMS.get(outside or "", {})
    for name, v in values.items():
        if name not in table:
            raise UserError(f"--outside-param {name}: --outside {outside} has no parameter '{name}' "
                            f"(its parameters: {', '.join(table)})")
        lo, hi, unit = table[name]
        hi = min(hi, 0.5 * fs_hz * (1 - 1e-9)) if name == "fr_hz" else hi
        if not lo <= v <= hi:
            raise UserError(f"--outside-param {name}={v:g}: must be in [{lo:g}, {hi:g}] ({unit})")


@dataclass
class SynthConfig:
    """What to generate.  Units: Hz, seconds, SI; ``levels`` are values of the rig's second control
    (``ModelSpec.synth.level_name``); noise_* are fractions of the signal's standard deviation; offsets are sds
    of a constant sensor offset per run.  None = the model's rig default (``ModelSpec.synth``)."""

    system: str                                                     # any model with a synthetic rig (ModelSpec.synth)
    effects: dict[str, float] = field(default_factory=dict)        # parameter name -> value
    outside: str | None = None
    outside_params: dict[str, float] = field(default_factory=dict)
    frequencies_hz: tuple[float, ...] | None = None
    levels: tuple[float, ...] | None = None
    pressures_bar: tuple[float, ...] | None = None    # alias of levels (rigs whose level is a pressure)
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
        """A copy with every None filled from the model's rig (ModelSpec.synth)."""
        rig = rig_of(self.system)
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

    dflt = effect_defaults(system)
    spec = sim.get_model(system)
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


def true_parameters(cfg: SynthConfig) -> dict[str, float]:
    """Calibratable parameters perturbed log-normally (seeded) around the rig's values, plus the effects."""
    import sim

    cfg = cfg.resolved()
    d = sim.get_model(cfg.system).defaults(rig_of(cfg.system).preset)
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


def _hertz_model(system: str) -> str:
    """The model simulating ``system``'s contact as an elastic Hertz contact (its rig's hertz_model, with a
    power-law contact kl, ku, nl, nu); UserError if the rig has none."""
    import sim

    name = rig_of(system).hertz_model
    if name is None or not {"kl", "ku", "nl", "nu"} <= set(sim.get_model(name).param_names):
        raise UserError(f"--outside contact_hertz: the {system} rig has no Hertz-contact model")
    return name


def _simulate_run(cfg: SynthConfig, truth: dict, row: dict, known: dict):
    """The true run sampled at the DAQ's own instants: (t, true signals, true summary features).  The simulator's
    dense output is sampled at every instant of the record (``sim.simulate(history_times=...)``); the outside
    mount resonance filters a 4x finer grid aligned with them, started early enough to have settled."""
    import sim

    from pipeline.diagnosis.features import history_summary

    f = row["frequency_hz"]
    period = 1.0 / f
    rs = row.get("record_start_s")
    from_rest = rs is not None and np.isfinite(rs)
    n_rec = int(math.floor(row["duration_s"] * cfg.fs_hz))
    from pipeline.diagnosis.features import SENSOR_SUBSAMPLES
    from sim.models.sensor import warmup_s

    warm = warmup_s(truth.get("fc", 0.0))            # the sensor_lowpass effect's start-up
    # a sensor's dynamics (the low-pass effect, the outside mount) want a grid finer than the DAQ's
    sub = SENSOR_SUBSAMPLES if (warm > 0 or cfg.outside == "mount_resonance") else 1
    dt = 1.0 / (cfg.fs_hz * sub)
    if cfg.outside == "mount_resonance":
        zeta = cfg.outside_params.get("zeta", 0.1)
        fr = cfg.outside_params.get("fr_hz", rig_of(cfg.system).mount_hz)
        warm = max(warm, 30.0 / (zeta * 2 * math.pi * fr))
    t0 = rs if from_rest else math.ceil(warm / period - 1e-9) * period
    n_pre = int(math.floor(min(warm, t0) / dt + 1e-9))
    times = t0 + np.arange(-n_pre, n_rec * sub) * dt
    window = int(math.ceil((t0 + row["duration_s"]) * f)) + 1
    st = {"window": window}
    if from_rest:
        st.update(min_transient=0, max_transient=0)
    ctrl = {k: row[k] for k in CONTROLS
            if k in row and np.isfinite(row[k])}
    if cfg.outside == "contact_hertz":
        kh = cfg.outside_params.get("kh", 3.0e8)     # N/m^1.5: same order of contact force as k1 = 1e7 N/m
        params = {k: v for k, v in truth.items() if k not in ("k1", "c1")}
        r = sim.simulate(_hertz_model(cfg.system), settings=st, history_times=times, kl=kh, ku=kh, nl=1.5, nu=1.5,
                         **{**known, **ctrl, **params})
    else:
        r = sim.simulate(cfg.system, settings=st, history_times=times, **{**known, **ctrl, **truth})
    if r.history is None:
        raise UserError(f"run {row['run_id']}: the true model ended with status {r.status} ({r.labels['reason']}); "
                        "choose other effect values or another seed")
    h = r.history
    a = h["accel_m_s2"].to_numpy()
    if cfg.outside == "mount_resonance":
        a = _mount_resonance(a, 1.0 / dt, cfg.outside_params.get("fr_hz", rig_of(cfg.system).mount_hz),
                             cfg.outside_params.get("zeta", 0.1), periodic=False)
    keep = slice(n_pre, None, sub)
    sig = {"accel_m_s2": a[keep], "force_n": h["force_n"].to_numpy()[keep], "disp_m": h["disp_m"].to_numpy()[keep],
           "progression_m": h["progression_m"].to_numpy()[keep]}
    if not from_rest:      # a steady-state record: positions relative to the window's progression at its start
        sig["progression_m"] = sig["progression_m"] - sig["progression_m"][0]
    t = np.arange(n_rec) / cfg.fs_hz
    if from_rest:
        ts = times[keep]
        hc = h.iloc[keep].assign(accel_m_s2=a[keep])
        summ = {k: history_summary(k, ts, hc, f) for k in ("rop_m_s", "peak_force_n", "impacts_per_cycle",
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
    """runs.csv rows: every frequency x every level of the rig's second control (the level itself, or the
    rig's ``forcing(frequency, level)``, e.g. a table of forcing amplitudes and a pneumatic static force)."""
    cfg = cfg.resolved()
    rig = rig_of(cfg.system)
    rows = []
    tag = cfg.system.split("-")[-1][:5]
    for j, lev in enumerate(cfg.levels):
        for i, f in enumerate(cfg.frequencies_hz):
            row = {"run_id": f"{tag}-{f:g}hz-{j + 1}", "system": cfg.system, "frequency_hz": float(f)}
            if rig.forcing is not None:
                row.update(rig.forcing(float(f), float(lev)))
            row.update(rig.fixed)
            if rig.forcing is None:
                row[rig.level_name] = float(lev)
            if rig.level_tag:
                row["run_id"] = f"{tag}-{f:g}hz-{lev:g}{rig.level_tag}"
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


MIN_SAMPLES_PER_CYCLE = 10
"""Fewest DAQ samples per forcing cycle a synthetic record may have (diagnose needs the cycle's shape)."""


def check_sampling(cfg: SynthConfig) -> None:
    """UserError unless the resolved ``cfg`` samples every forcing cycle at least MIN_SAMPLES_PER_CYCLE times."""
    f_hi = max(cfg.frequencies_hz)
    if cfg.fs_hz / f_hi < MIN_SAMPLES_PER_CYCLE:
        raise UserError(f"--fs {cfg.fs_hz:g} Hz gives {cfg.fs_hz / f_hi:.3g} samples per cycle at {f_hi:g} Hz "
                        f"(--frequencies); need >= {MIN_SAMPLES_PER_CYCLE}: raise --fs or lower the frequencies")


def check_from_rest(cfg: SynthConfig) -> None:
    """UserError when a record from rest (``record_start_s``) would end more than MAX_FROM_REST_CYCLES forcing
    cycles after the start at the highest frequency: the simulation from rest would hold them all."""
    from pipeline.datasets.measured import MAX_FROM_REST_CYCLES

    f_hi = max(cfg.frequencies_hz)
    for start in cfg.record_start_s or ():
        cycles = start * f_hi + cfg.cycles
        if cycles > MAX_FROM_REST_CYCLES:
            raise UserError(f"--record-start {start:g}: {cycles:.3g} forcing cycles from rest at {f_hi:g} Hz, more "
                            f"than the {MAX_FROM_REST_CYCLES} a record from rest may span; a record that late is in "
                            "steady state (omit --record-start)")


def synthesize(cfg: SynthConfig, progress: bool = False) -> tuple[Dataset, dict]:
    """Build the dataset in memory: (Dataset, truth) — nothing is written here."""
    import os

    import sim

    from tqdm import tqdm

    from pipeline.datasets.measured import known_parameters

    cfg = cfg.resolved()
    if cfg.outside is not None and cfg.outside not in OUTSIDE:
        raise UserError(f"--outside {cfg.outside}: unknown{did_you_mean(cfg.outside, OUTSIDE)} "
                        f"(known: {', '.join(OUTSIDE)})")
    if cfg.outside == "contact_hertz" and "k1" not in sim.get_model(cfg.system).param_names:
        raise UserError(f"--outside contact_hertz replaces a linear contact stiffness k1, which {cfg.system} does not have")
    for s in cfg.signals:
        if s not in ("accel_m_s2", "force_n", "disp_m", "progression_m"):
            raise UserError(f"--signals: unknown signal '{s}' (accel_m_s2, force_n, disp_m, progression_m)")
    if cfg.cycles < 2.5:
        raise UserError(f"--cycles must be >= 2.5, got {cfg.cycles:g}")
    check_sampling(cfg)
    check_outside_params(cfg.outside, dict(cfg.outside_params), float(cfg.fs_hz))
    check_from_rest(cfg)
    truth = true_parameters(cfg)
    runs = run_table(cfg)
    known = known_parameters(runs)
    rows = runs.to_dict("records")
    workers = cfg.n_threads or os.cpu_count() or 1
    from sim.registry import warm

    warm(_hertz_model(cfg.system) if cfg.outside == "contact_hertz" else cfg.system)
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
    readme = (f"# Synthetic dataset ({cfg.system})\n\nGenerated by `vibro synth` (pipeline/synthesis/workflow.py), seed {cfg.seed}.\n"
              f"DAQ rate {cfg.fs_hz:g} Hz, {cfg.cycles:g} cycles per record"
              + (f", records from rest starting at {', '.join(f'{x:g}' for x in cfg.record_start_s)} s" if cfg.record_start_s
                 else ", steady state") + f", {len(summary)} summary-only runs.\n"
              f"Effects switched on: {cfg.effects or 'none'}; outside physics: {cfg.outside or 'none'}.\n"
              "The truth (perturbed calibratable parameters, effect values) is kept apart from the data "
              "(the diagnosis does not read it).\n")
    ds = Dataset(runs=runs, series=series, summary=pd.DataFrame(summary).set_index("run_id") if summary else None,
                 extra_files={"README.md": readme}, known=known)
    return ds, info
