"""Write an independent rig log (MODELS.md §7 directory) and its truth.

``generate(LogSpec(system, effect=..., outside=..., noise=..., seed=...), out_dir)`` simulates every run of the
rig (``rigs.RIGS``) with the scipy reference (``tests/reference_solutions.py``), samples each signal at the DAQ's
own instants on the dense output, adds the noise model's noise, and writes ``runs.csv``, ``series/<run_id>.csv``
and ``summary.csv``.  The truth (perturbed calibratable parameters, the effect, the outside physics) is returned
and, with ``truth_path``, written apart from the data.

Runs: every frequency at every level of the rig; records from rest (``record_start_s``, cycled over the runs) or
in steady state; DAQ rates and record lengths cycled over the runs (not whole cycles, not multiples of f); two runs
are logged as summaries only (their labels over a whole-cycle record: the rig software's numbers), and the 2nd series run and every
``drop_signal_every``-th after it lost its second channel.
"""
from __future__ import annotations

import json
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from tests.independent import daq as D
from tests.independent.noise import NOISE_MODELS
from tests.independent.outside import OUTSIDE, measured_accel, model_for
from tests.independent.rigs import RIGS, Rig
from tests.reference_solutions import reference_run

RTOL = 1e-9
"""The reference's tolerance for generated logs: labels within ~1e-8 of its rtol-1e-10 solution, a third of the cost."""


@dataclass(frozen=True)
class LogSpec:
    """What to generate: a rig, at most one §6 effect and/or one outside-physics term, a noise model, a seed."""

    system: str
    effect: str | None = None
    outside: str | None = None
    noise: str = "white2"
    seed: int = 0
    n_runs: int | None = None          # use the first n runs of the grid (spread over it), None: all
    effect_scale: float = 1.0          # multiplies the effect's visible strength
    overrides: dict = field(default_factory=dict)   # rig parameters to set in the truth (e.g. two effects)
    daq: D.DaqChain | None = None      # the data-acquisition chain (``daq.py``); None: samples of the physics

    @property
    def chain(self) -> D.DaqChain | None:
        """The DAQ chain if it changes anything, else None."""
        return None if self.daq is None or self.daq.is_off else self.daq

    @property
    def name(self) -> str:
        what = self.effect or (f"outside-{self.outside}" if self.outside else "control")
        runs = "" if self.n_runs is None else f"-n{self.n_runs}"
        daq = "" if self.chain is None else f"-{self.chain.name}"
        return f"{self.system}-{what}-{self.noise}{daq}-s{self.seed}{runs}"


def true_parameters(rig: Rig, spec: LogSpec) -> dict:
    """The rig's calibratable parameters perturbed log-normally (seeded), the effect and outside parameters."""
    rng = np.random.default_rng([spec.seed, 7])
    truth = {n: float(rig.known[n] * math.exp(rig.perturb * rng.standard_normal())) for n in rig.calibratable}
    if spec.effect:
        truth.update({k: v * spec.effect_scale for k, v in rig.effects[spec.effect].items()})
    if spec.outside:
        truth.update(rig.outside[spec.outside])
    truth.update(spec.overrides)
    return truth


def _pick(n: int, k: int) -> set[int]:
    """k runs spread over n, never the first or the last."""
    if k <= 0 or n < 4:
        return set()
    return {int(round(x)) for x in np.linspace(1, n - 2, k + 2)[1:-1]}


def _series_times(rig: Rig, i: int, f: float) -> tuple[float | None, float, float, int]:
    """(record_start_s or None, fs, duration, transient cycles) of series run i."""
    fs = rig.fs_hz[i % len(rig.fs_hz)]
    cycles = rig.record_cycles[i % len(rig.record_cycles)]
    n = int(math.floor(cycles / f * fs))
    duration = n / fs
    if rig.record_start_s:
        return rig.record_start_s[i % len(rig.record_start_s)], fs, duration, 0
    return None, fs, duration, rig.settle_cycles


def _run(rig: Rig, spec: LogSpec, truth: dict, i: int, f: float, level: float, summary: bool) -> dict:
    """One run: its runs.csv row, and its clean samples (series) or labels (summary)."""
    ctrl = rig.controls(f, level)
    params = {**rig.known, **ctrl, **truth}
    params.update(rig.derived(params))
    run_id = f"{spec.system.split('-')[-1][:5]}-{i:02d}-{f:g}hz"
    row = {"run_id": run_id, "system": rig.system, **ctrl}
    if rig.preset:
        row["preset"] = rig.preset
    model = model_for(spec.system, spec.outside)
    T = 1.0 / f
    rs, fs, duration, settle = _series_times(rig, i, f)
    if summary:      # whole cycles, so the reference's window labels cover exactly the record
        k0 = settle if rs is None else max(int(round(rs * f)), 1)
        nw = max(int(round(duration * f)), 4)
        out = reference_run(model, params, k0, nw, rtol=RTOL)
        row.update(duration_s=nw * T, record_start_s=None if rs is None else k0 * T)
        if spec.chain is not None:            # the DAQ declares its chain for every run
            row.update(D.runs_columns(spec.chain, D.design(spec.chain, fs), fs))
        labels = {k: float(out[k]) for k in rig.summary_labels}
        if spec.outside in OUTSIDE and OUTSIDE[spec.outside].measurement:
            labels.pop("peak_decel_g", None)      # the rig software's deceleration comes from the mounted sensor
        return {"row": row, "summary": labels}
    n = int(round(duration * fs))
    t_rec = np.arange(n) / fs
    start = (rs if rs is not None else settle * T)
    chain = spec.chain
    row.update(duration_s=duration, record_start_s=rs)
    filt = None
    if chain is not None:
        filt = D.design(chain, fs)
        row.update(D.runs_columns(chain, filt, fs))
    if chain is not None and chain.times_change:
        sig, times, daq = _chain_signals(spec, chain, filt, model, params, truth, start, fs, n, T, rs is not None)
    else:
        times = start + t_rec
        sig = _plain_signals(spec, model, params, truth, start, times, fs, n, T, rs is not None, duration)
        daq = {}
    if chain is not None:
        daq.update(filter=D.declared_filter(chain, filt, fs), dc_delay_s=0.0 if filt is None else filt.dc_delay(),
                   compensated=bool(chain.compensated and filt is not None), clock_ppm=chain.clock_ppm)
        if chain.hum:
            phases = D.hum_phases(chain, np.random.default_rng([spec.seed, 13, i]))
            for ch in sig:
                if ch in chain.hum:
                    sig[ch] = np.asarray(sig[ch], dtype=float) + D.hum_at(chain, ch, phases[ch], times, filt)
            daq.update(hum_hz=chain.hum_hz, hum_amplitudes={k: list(v) for k, v in chain.hum.items()},
                       hum_phases_rad=phases)
    return {"row": row, "t": t_rec, "signals": sig, "fs": fs, "daq": daq}


def _plain_signals(spec, model, params, truth, start, times, fs, n, T, from_rest, duration) -> dict:
    """The signals sampled at the instants ``times`` [s] on the dense output (no filter, a nominal clock)."""
    warm = OUTSIDE[spec.outside].warmup_s(truth) if spec.outside in OUTSIDE and OUTSIDE[spec.outside].measurement else 0.0
    n_cycles = int(math.ceil((start + duration) / T)) + 1
    fine = None
    if warm:     # measurement-side physics: the true acceleration on a fine grid aligned with the DAQ's instants
        sub = 8
        t0 = max(start - warm, 0.0)
        k0 = int(math.floor((start - t0) * fs * sub))
        fine = start + (np.arange(-k0, n * sub) / (fs * sub))
        fine = fine[fine >= 0.0]
        out = reference_run(model, params, 0, n_cycles, rtol=RTOL, sample_times=fine)
    else:
        out = reference_run(model, params, 0, n_cycles, rtol=RTOL, sample_times=times)
    smp = out["samples"]
    if fine is not None:
        a = measured_accel(spec.outside, truth, smp["t_s"], smp["vel_m_s"], from_rest=from_rest)
        j = np.searchsorted(smp["t_s"], times - 0.25 / (fs * 8))
        smp = {k: np.asarray(v)[j] for k, v in smp.items()}
        smp["accel_m_s2"] = a[j]
    return {"accel_m_s2": smp["accel_m_s2"], "force_n": smp["force_n"], "disp_m": smp["disp_m"],
            "progression_m": smp["progression_m"]}


def _chain_signals(spec, chain, filt, model, params, truth, start, fs, n, T, from_rest):
    """The signals through the chain's filter (continuous, on a grid of ``chain.oversample`` points per sample
    interval of the DAQ's clock) sampled at the DAQ's instants: true time start + clock (k / fs + tau_c), tau_c
    the DC group delay when compensated (``daq.py``).  Returns (signals, true sample times, truth notes)."""
    eps = chain.clock
    tau_c = filt.dc_delay() if (filt is not None and chain.compensated) else 0.0
    times = start + eps * (np.arange(n) / fs + tau_c)
    mount = spec.outside in OUTSIDE and OUTSIDE[spec.outside].measurement
    if filt is None and not mount:
        out = reference_run(model, params, 0, int(math.ceil(times[-1] / T)) + 1, rtol=RTOL, sample_times=times)
        smp = out["samples"]
        return ({k: np.asarray(smp[k]) for k in ("accel_m_s2", "force_n", "disp_m", "progression_m")}, times,
                {"true_times": "start + (1 + ppm 1e-6) k / fs"})
    os_ = chain.oversample
    h = eps / (os_ * fs)                                     # grid step, true time [s]
    warm = max(filt.settle_s() if filt is not None else 0.0,
               OUTSIDE[spec.outside].warmup_s(truth) if mount else 0.0)
    t_first = times[0] - (0.0 if from_rest else warm)
    j0 = int(math.floor((times[0] - max(t_first, 0.0)) / h * (1 + 1e-12)))
    if from_rest:                                            # from the start of excitation (the rig at rest)
        j0 = int(math.floor(times[0] / h * (1 + 1e-12)))
    grid = times[0] + h * np.arange(-j0, (n - 1) * os_ + 1)
    grid = np.maximum(grid, 0.0)
    out = reference_run(model, params, 0, int(math.ceil(grid[-1] / T)) + 1, rtol=RTOL, sample_times=grid)
    smp = {k: np.asarray(v, dtype=float) for k, v in out["samples"].items()}
    take = j0 + os_ * np.arange(n)

    direct = ["force_n", "disp_m", "progression_m"] + (["accel_m_s2"] if truth.get("fc", 0.0) > 0.0 else [])
    cells = {}
    if isinstance(filt, D.AnalogFilter):         # steps holding a jump (a force's onset): refined on sub-points
        cells = {k: D.jump_cells(smp[k]) for k in direct}
        every = np.unique(np.concatenate([c for c in cells.values()] + [np.zeros(0, dtype=int)]))
        if every.size:
            frac = np.arange(D.JUMP_SUB + 1) / D.JUMP_SUB
            sub_t = grid[every, None] + (grid[every + 1] - grid[every])[:, None] * frac[None, :]
            ref = reference_run(model, params, 0, int(math.ceil(sub_t[-1, -1] / T)) + 1, rtol=RTOL,
                                sample_times=np.maximum.accumulate(sub_t.ravel()))["samples"]
            sub = {k: np.asarray(ref[k], dtype=float).reshape(sub_t.shape) for k in direct}
            cells = {k: (c, sub[k][np.searchsorted(every, c)]) for k, c in cells.items() if c.size}

    def through(u, key=None):
        if filt is None:
            return u
        if isinstance(filt, D.FirFilter):
            return D.fir_filter(filt, u)
        if key in cells:
            return D.analog_filter(filt, u, h, *cells[key])
        return D.analog_filter(filt, u, h)

    if truth.get("fc", 0.0) > 0.0:                           # sensor_lowpass: the sensor's output is smooth
        acc = through(smp["accel_m_s2"], "accel_m_s2")
    elif mount:
        m = D.mount_filter(truth["fr_hz"], truth["zeta_r"])
        if isinstance(filt, D.FirFilter):
            acc = D.fir_filter(filt, D.analog_filter_of_rate(m, smp["vel_m_s"], smp["accel_true_m_s2"], h))
        else:
            g = m if filt is None else filt.cascade(m)
            acc = D.analog_filter_of_rate(g, smp["vel_m_s"], smp["accel_true_m_s2"], h)
    elif isinstance(filt, D.FirFilter):
        acc = through(smp["accel_m_s2"])
    else:                                                    # through the velocity: the acceleration jumps
        acc = D.analog_filter_of_rate(filt, smp["vel_m_s"], smp["accel_m_s2"], h)
    sig = {"accel_m_s2": acc[take]}
    for k in ("force_n", "disp_m", "progression_m"):
        sig[k] = through(smp[k], k)[take]
    return sig, times, {"grid_step_s": h, "grid_start_s": float(grid[0])}


def _adc_range(chain: D.DaqChain | None, signal: str, x: np.ndarray) -> float | None:
    """The ADC range of a saturating channel [signal unit], None if it does not saturate."""
    if chain is None:
        return None
    if signal in chain.clip_range:
        return float(chain.clip_range[signal])
    if signal in chain.clip_fraction:
        return float(chain.clip_fraction[signal] * np.max(np.abs(x)))
    return None


def generate(spec: LogSpec, out_dir: str | Path, truth_path: str | Path | None = None, threads: int = 2) -> dict:
    """Write the §7 directory ``out_dir`` (must not exist) and return the truth."""
    rig = RIGS[spec.system]
    noise = NOISE_MODELS[spec.noise]
    out_dir = Path(out_dir)
    if out_dir.exists():
        raise FileExistsError(out_dir)
    truth = true_parameters(rig, spec)
    grid = rig.run_grid()
    if spec.n_runs is not None and spec.n_runs < len(grid):
        grid = [grid[int(round(j))] for j in np.linspace(0, len(grid) - 1, spec.n_runs)]
    summ = _pick(len(grid), rig.summary_runs)
    with ThreadPoolExecutor(max_workers=threads) as pool:
        runs = list(pool.map(lambda a: _run(rig, spec, truth, a[0], a[1][0], a[1][1], a[0] in summ), enumerate(grid)))
    rng = np.random.default_rng([spec.seed, 11])
    (out_dir / "series").mkdir(parents=True)
    rows, summary = [], []
    chain = spec.chain
    daq_runs: dict = {}
    n_series = 0
    for r in runs:
        rows.append(r["row"])
        if "summary" in r:
            summary.append({"run_id": r["row"]["run_id"], **noise.summary(r["summary"], rng)})
            continue
        sigs = list(rig.signals)
        if rig.drop_signal_every and n_series % rig.drop_signal_every == 1:
            sigs = sigs[:1] + sigs[2:]            # this run lost its second channel
        n_series += 1
        cols = {"t_s": r["t"]}
        for s in sigs:
            x = np.asarray(r["signals"][s], dtype=float)
            rng_ = _adc_range(chain, s, x)
            if rng_ is None:
                cols[s] = noise.apply(x, r["fs"], rng, s)
            else:                       # the sensor's noise, then the ADC saturating at its range
                cols[s] = D.adc(noise.apply_before_adc(x, r["fs"], rng, s), rng_, noise.adc_bits)
                r["daq"].setdefault("adc_range", {})[s] = rng_
                r["daq"].setdefault("clipped_fraction", {})[s] = float(np.mean(np.abs(cols[s]) >= rng_))
        if r["daq"]:
            daq_runs[r["row"]["run_id"]] = r["daq"]
        df = pd.DataFrame(cols)
        df.to_csv(out_dir / "series" / f"{r['row']['run_id']}.csv", index=False, float_format="%.9g")
    runs_df = pd.DataFrame(rows)
    if runs_df["record_start_s"].isna().all():
        runs_df = runs_df.drop(columns=["record_start_s"])
    runs_df.to_csv(out_dir / "runs.csv", index=False, float_format="%.12g")
    if summary:
        pd.DataFrame(summary).to_csv(out_dir / "summary.csv", index=False, float_format="%.12g")
    spec_d = asdict(spec)
    if spec.daq is None:
        spec_d.pop("daq")               # the truth of a log without a chain, as it was
    info = {"spec": spec_d, "name": spec.name, "system": spec.system, "truth": truth,
            "effect": spec.effect, "outside": spec.outside, "noise": spec.noise,
            "calibratable": list(rig.calibratable)}
    if chain is not None:
        info["daq"] = {"chain": asdict(chain), "runs": daq_runs}
    if truth_path is not None:
        Path(truth_path).write_text(json.dumps(info, indent=2))
    return info
