"""Which parameters are fitted, and the parallel evaluation of the simulator against targets.

Calibratable base parameters and the §6 effects of a model are fitted in log10 units within the bounds
its ModelSpec gives (``calibratable``, ``effect_bounds``; an effect's "off" value 0 is approached by its
lower bound, where it no longer changes the response measurably).
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from pipeline.diagnosis.features import Target, peak_velocity, simulated_features
from pipeline.core.errors import UserError
from sim.models.base import FitBound
from sim.registry import warm as sim_warm


FreeParam = FitBound
"""A fitted parameter: name, bounds [lo, hi] in its unit, fitted as log10 (``sim.models.base.FitBound``)."""


def supported_systems() -> tuple[str, ...]:
    """Models the diagnosis can calibrate: those whose ModelSpec lists calibratable parameters."""
    import sim

    return tuple(n for n in sim.model_names() if sim.get_model(n).calibratable)


def _spec(system: str):
    """The ModelSpec of a system the diagnosis supports (UserError naming the supported ones otherwise)."""
    import sim

    if system not in sim.model_names() or not sim.get_model(system).calibratable:
        raise UserError(f"system '{system}': the diagnosis supports {', '.join(supported_systems())} "
                        "(models with calibratable parameters, MODELS.md §6)")
    return sim.get_model(system)


def calibratable(system: str) -> tuple[FitBound, ...]:
    """The calibratable parameters of ``system`` with their fit bounds (``ModelSpec.calibratable``)."""
    return _spec(system).calibratable


def effect_bounds(system: str) -> dict[str, FitBound]:
    """Fit bounds of every §6 effect parameter of ``system`` (``ModelSpec.effect_bounds``)."""
    return dict(_spec(system).effect_bounds)


def default_max_harmonic_hz(system: str) -> float:
    """Default highest harmonic used as a feature [Hz] (``ModelSpec.diagnose_max_harmonic_hz``)."""
    return _spec(system).diagnose_max_harmonic_hz


def default_fit_settings(system: str) -> dict:
    """Default candidate_starts and max_nfev of ``system`` (``ModelSpec.diagnose_fit``; DiagnoseConfig None values)."""
    return dict(_spec(system).diagnose_fit)


warm = sim_warm
"""Load/compile the model's kernel before threads use it (sim.registry.warm)."""


def candidates(system: str) -> dict[str, tuple[FreeParam, ...]]:
    """§6 effects that apply to ``system`` (from the model's own effect table) with their fit bounds."""
    import sim

    spec = sim.get_model(system)
    bounds = effect_bounds(system)
    return {eff: tuple(bounds[p] for p in ps) for eff, ps in spec.effects.items()}


MAX_MODEL_SAMPLES = 500_000
"""Cap on the samples of one model history (memory; the integrator steps on its own, the history is only output).
A cap per cycle instead (4096) starved low-frequency runs: the pendulum at 3 Hz recorded at 10 kHz got 1.2x
instead of 4x oversampling and its truth mismatch was ~8 instead of ~1 (issue 12)."""


def run_settings(tg: Target, sim_settings: dict, fs_sim_hz: float, max_window: int = 0,
                 oversample: float = 4.0) -> dict:
    """Simulator settings of one run.  The model is sampled densely (``oversample`` x the record's rate,
    at least 4 K + 8 samples per cycle, at most MAX_MODEL_SAMPLES in the whole window) and interpolated onto the
    record's own time base (features.model_on_record), so its harmonics see the same sampling as the measurement's.
    Steady-state record: as many cycles as were recorded (up to ``max_window``; drifting effects depend on it).
    Record from rest (``record_start_s``): no transient, a window from rest that covers [record_start_s,
    record_start_s + duration_s] (features.model_record cuts it)."""
    f = tg.frequency_hz
    fs = tg.fs_hz or fs_sim_hz
    st = dict(sim_settings)
    if tg.record_start_s is not None:
        end = tg.record_start_s + max(tg.duration_s, 2.0 / f)
        st.update(min_transient=0, max_transient=0, window=max(int(math.ceil(end * f)) + 1, 2))
    elif max_window and tg.kind == "series":
        st["window"] = max(int(st.get("window", 2)), min(int(math.ceil(tg.cycles)), max_window))
    window = int(st.get("window", 2))
    st["samples_per_cycle"] = max(min(int(math.ceil(oversample * fs / f)), MAX_MODEL_SAMPLES // max(window, 1)),
                                  4 * tg.k_max + 8)
    return st


class Evaluator:
    """Simulates parameter sets on the runs of ``targets`` (threads; the kernel releases the GIL)
    and returns noise-normalised residuals (model - measured) / sd."""

    def __init__(self, system: str, targets: list[Target], sim_settings: dict, fs_sim_hz: float,
                 n_threads: int | None = None, max_window: int = 0):
        calibratable(system)
        self.system = system
        self.targets = targets
        self.n_threads = n_threads or os.cpu_count() or 1
        self.settings = [run_settings(tg, sim_settings, fs_sim_hz, max_window) for tg in targets]
        self.n_sims = 0
        warm(system)

    def simulate(self, param_sets: list[dict], idx: list[int]) -> list[list]:
        """SimulationResults (with history) for every parameter set x run index."""
        import sim

        jobs = [(j, i) for j in range(len(param_sets)) for i in idx]

        def one(job):
            j, i = job
            tg = self.targets[i]
            try:
                return sim.simulate(self.system, settings=self.settings[i], history=True,
                                    **{**tg.known, **tg.controls, **param_sets[j]})
            except sim.ParameterError as e:
                raise UserError(f"run {tg.run_id}: {e}") from None

        if self.n_threads == 1 or len(jobs) == 1:
            res = [one(j) for j in jobs]
        else:
            with ThreadPoolExecutor(max_workers=self.n_threads) as pool:
                res = list(pool.map(one, jobs))
        self.n_sims += len(jobs)
        out = [[None] * len(idx) for _ in param_sets]
        for (j, i), r in zip(jobs, res):
            out[j][idx.index(i)] = r
        return out

    def residual_of(self, i: int, res) -> np.ndarray:
        tg = self.targets[i]
        m = simulated_features(tg, res)
        if m is None:        # runaway / failed: compare with zero response (large, finite residual)
            m = np.zeros_like(tg.y)
        r = (m - tg.y) / tg.sd
        if tg.lower_bound.any():
            r[tg.lower_bound] = np.minimum(r[tg.lower_bound], 0.0)
        return r

    def residuals(self, param_sets: list[dict], idx: list[int]) -> list[np.ndarray]:
        """Concatenated normalised residual over runs ``idx`` for each parameter set."""
        sims = self.simulate(param_sets, idx)
        return [np.concatenate([self.residual_of(i, r) for i, r in zip(idx, row)]) for row in sims]

    def run_details(self, params: dict, idx: list[int]) -> list[dict]:
        """Per run: normalised residual, simulated features and peak velocity (for reports)."""
        sims = self.simulate([params], idx)[0]
        out = []
        for i, r in zip(idx, sims):
            tg = self.targets[i]
            m = simulated_features(tg, r)
            out.append({"run": i, "residual": self.residual_of(i, r), "model": m, "result": r,
                        "peak_velocity_m_s": peak_velocity(r)})
        return out
