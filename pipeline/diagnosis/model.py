"""Which parameters are fitted, and the parallel evaluation of the simulator against targets.

Calibratable base parameters and the §6 effects of a model are fitted in log10 units within the bounds
its ModelSpec gives (``calibratable``, ``effect_bounds``; an effect's "off" value 0 is approached by its
lower bound, where it no longer changes the response measurably).
"""
from __future__ import annotations

import copy
import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from pipeline.diagnosis.features import (Target, sampling_plan, simulated_features,
                                         simulated_halves)
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
    """Default candidate_starts, max_nfev (``ModelSpec.diagnose_fit``) and estimate_chain (``diagnose_chain``) of
    ``system``: the DiagnoseConfig values left None."""
    return {**_spec(system).diagnose_fit, "estimate_chain": _spec(system).diagnose_chain}


warm = sim_warm
"""Load/compile the model's kernel before threads use it (sim.registry.warm)."""


def candidates(system: str) -> dict[str, tuple[FreeParam, ...]]:
    """§6 effects that apply to ``system`` (from the model's own effect table) with their fit bounds."""
    import sim

    spec = sim.get_model(system)
    bounds = effect_bounds(system)
    return {eff: tuple(bounds[p] for p in ps) for eff, ps in spec.effects.items()}


MAX_MODEL_SAMPLES = 500_000
"""Cap on the samples of one summary run's model history (memory; the integrator steps on its own, the history is
only output)."""


def sensor_warmup_s(params: dict) -> float:
    """How long the sensor low-pass of ``params`` (fc > 0) needs to forget its start [s] (``sim.models.sensor``)."""
    from sim.models.sensor import warmup_s

    return warmup_s(float(params.get("fc", 0.0) or 0.0))


def run_settings(tg: Target, sim_settings: dict, fs_sim_hz: float, oversample: float = 4.0) -> dict:
    """Simulator settings of one summary run: sampled densely (``oversample`` x ``fs_sim_hz``, at least 4 K + 8
    samples per cycle, at most MAX_MODEL_SAMPLES in the window).  Steady state: the settings' window; from rest
    (``record_start_s``): no transient and a window from rest that covers [record_start_s, record_start_s +
    duration_s] (features.model_record cuts it).  Series runs are sampled at their record's instants instead
    (``series_settings``).  A run whose features are labels (``Target.needs_history``) is simulated without a
    history but by the same numerical integrator (method dopri5 unless ``sim_settings`` names one): its labels
    are those of the run with a history, and a pipeline that diagnoses summary data compiles no exact kernel."""
    f = tg.frequency_hz
    st = dict(sim_settings)
    if tg.record_start_s is not None:
        end = tg.record_start_s + max(tg.duration_s, 2.0 / f)
        st.update(min_transient=0, max_transient=0, window=max(int(math.ceil(end * f)) + 1, 2))
    st.setdefault("method", "dopri5")    # the integrator of the runs with a history, for the runs without one too
    window = int(st.get("window", 2))
    st["samples_per_cycle"] = max(min(int(math.ceil(oversample * fs_sim_hz / f)), MAX_MODEL_SAMPLES // max(window, 1)),
                                  4 * tg.k_max + 8)
    return st


def series_settings(tg: Target, sim_settings: dict, params: dict) -> tuple[dict, np.ndarray]:
    """(settings, history_times) of a series run: the model sampled at the record's own instants
    (``features.sampling_plan``), a steady-state record after the settings' transient, a record from rest from
    rest, with the sensor's warm-up of ``params`` before it."""
    times, window, _ = sampling_plan(tg, tg.frequency_hz, sensor_warmup_s(params))
    st = {k: v for k, v in sim_settings.items() if k != "samples_per_cycle"}
    st["window"] = window
    if tg.record_start_s is not None:
        st.update(min_transient=0, max_transient=0)
    return st, times


class Evaluator:
    """Simulates parameter sets on the runs of ``targets`` (threads; the kernel releases the GIL)
    and returns noise-normalised residuals (model - measured) / sd."""

    def __init__(self, system: str, targets: list[Target], sim_settings: dict, fs_sim_hz: float,
                 n_threads: int | None = None):
        calibratable(system)
        self.system = system
        self.targets = targets
        self.n_threads = n_threads or os.cpu_count() or 1
        self.sim_settings = dict(sim_settings)
        self.settings = [run_settings(tg, sim_settings, fs_sim_hz) for tg in targets]
        self.n_sims = 0
        self.cost = None        # a cost.CostRecorder told of every batch of fit tasks (None: none)
        self.profile_runs: frozenset = frozenset()     # runs whose undeclared DAQ chain is profiled out (nuisance)
        self.profile_signals: tuple[str, ...] = ()
        warm(system)

    def for_tasks(self, n_threads: int | None = None) -> Evaluator:
        """A copy with its own simulation count (0) for a task run elsewhere, on ``n_threads`` threads (None: this
        one's); it simulates exactly as this one does."""
        out = copy.copy(self)
        out.n_threads = n_threads or self.n_threads
        out.n_sims = 0
        out.cost = None
        return out

    def simulate(self, param_sets: list[dict], idx: list[int], history: bool = False) -> list[list]:
        """SimulationResults for every parameter set x run index, with a history where the run's features need one
        (``Target.needs_history``) or ``history`` asks for it."""
        import sim

        jobs = [(j, i) for j in range(len(param_sets)) for i in idx]

        def one(job):
            j, i = job
            tg = self.targets[i]
            params = {**tg.known, **tg.controls, **param_sets[j]}
            try:
                if tg.kind == "series":
                    st, times = series_settings(tg, self.sim_settings, params)
                    return sim.simulate(self.system, settings=st, history_times=times, **params)
                return sim.simulate(self.system, settings=self.settings[i],
                                    history=history or tg.needs_history(params), **params)
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
        return self.residual_for(self.targets[i], res)

    @staticmethod
    def residual_for(tg: Target, res) -> np.ndarray:
        """Noise-normalised residual of target ``tg`` (a run's, or it read through another chain) from ``res``."""
        m = simulated_features(tg, res)
        if m is None:        # runaway / failed: compare with zero response (large, finite residual)
            m = np.zeros_like(tg.y)
        r = (m - tg.y) / tg.sd
        if tg.lower_bound.any():
            r[tg.lower_bound] = np.minimum(r[tg.lower_bound], 0.0)
        return r

    def residuals(self, param_sets: list[dict], idx: list[int]) -> list[np.ndarray]:
        """Concatenated normalised residual over runs ``idx`` for each parameter set (a coarse fit reads the part of
        the low harmonics, ``features.low_harmonics``)."""
        sims = self.simulate(param_sets, idx)
        if self.profile_runs:
            from pipeline.diagnosis.nuisance import profiled_residuals

            return profiled_residuals(self, sims, idx)
        return [np.concatenate([self.residual_of(i, r) for i, r in zip(idx, row)]) for row in sims]

    def held_out(self, param_sets: list[dict], idx: list[int], chains: list | None = None
                 ) -> list[tuple[list[np.ndarray], list]]:
        """Per parameter set: the normalised residual of every run ``idx`` and the model's features of each half
        of its record (``features.simulated_halves``; None for summary runs).  ``chains``: per set, an undeclared
        chain (``nuisance.calibration_chains``) read on the profiled runs in place of the targets' own."""
        from pipeline.diagnosis.nuisance import with_chain

        sims = self.simulate(param_sets, idx)
        chains = chains or [None] * len(param_sets)
        out = []
        for row, nuis in zip(sims, chains):
            tgs = [with_chain(self.targets[i], nuis if i in self.profile_runs else None) for i in idx]
            out.append(([self.residual_for(tg, r) for tg, r in zip(tgs, row)],
                        [simulated_halves(tg, r) for tg, r in zip(tgs, row)]))
        return out
