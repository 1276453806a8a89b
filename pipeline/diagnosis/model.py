"""Which parameters are fitted, and the parallel evaluation of the simulator against targets.

Calibratable base parameters and the §6 effects of a model are fitted in log10 units within the bounds
its ModelSpec gives (``calibratable``, ``effect_bounds``; an effect's "off" value 0 is approached by its
lower bound, where it no longer changes the response measurably).
"""
from __future__ import annotations

import copy
import math
import os
from collections import OrderedDict
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


RESIDUAL_MEMO = 4096
"""Per-run residuals an evaluator remembers, the least recently used dropped first: the leave-one-run-out folds,
started at one fit, simulate the runs they share at the same points (a run's residual is a pure function of its
``Evaluator._memo_key``)."""

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
        self.memo: OrderedDict[tuple, np.ndarray] = OrderedDict()   # (run, parameters, ...) -> residual; shared by
        #                                                               the copies of ``for_tasks``
        warm(system)

    def for_tasks(self, n_threads: int | None = None) -> Evaluator:
        """A copy with its own simulation count (0) for a task run elsewhere, on ``n_threads`` threads (None: this
        one's); it simulates exactly as this one does, and shares its memo (a cluster's copy starts an empty one)."""
        out = copy.copy(self)
        out.memo = self.memo
        out.n_threads = n_threads or self.n_threads
        out.n_sims = 0
        out.cost = None
        return out

    def simulate(self, param_sets: list[dict], idx: list[int], history: bool = False) -> list[list]:
        """SimulationResults for every parameter set x run index, with a history where the run's features need one
        (``Target.needs_history``) or ``history`` asks for it."""
        res = self.simulate_pairs([(ps, i) for ps in param_sets for i in idx], history)
        return [res[j * len(idx):(j + 1) * len(idx)] for j in range(len(param_sets))]

    def simulate_pairs(self, pairs: list[tuple[dict, int]], history: bool = False) -> list:
        """SimulationResults of (parameter set, run index) pairs, in parallel on the evaluator's threads."""
        import sim

        def one(pair):
            ps, i = pair
            tg = self.targets[i]
            params = {**tg.known, **tg.controls, **ps}
            try:
                if tg.kind == "series":
                    st, times = series_settings(tg, self.sim_settings, params)
                    return sim.simulate(self.system, settings=st, history_times=times, **params)
                return sim.simulate(self.system, settings=self.settings[i],
                                    history=history or tg.needs_history(params), **params)
            except sim.ParameterError as e:
                raise UserError(f"run {tg.run_id}: {e}") from None

        if self.n_threads == 1 or len(pairs) == 1:
            res = [one(p) for p in pairs]
        else:
            with ThreadPoolExecutor(max_workers=self.n_threads) as pool:
                res = list(pool.map(one, pairs))
        self.n_sims += len(pairs)
        return res

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
        the low harmonics, ``features.low_harmonics``).  A run's residual at a parameter set is simulated once while
        the evaluator remembers it (``RESIDUAL_MEMO``); with a profiled chain the runs depend on each other, and
        every one is simulated."""
        if self.profile_runs:
            from pipeline.diagnosis.nuisance import profiled_residuals

            return profiled_residuals(self, self.simulate(param_sets, idx), idx)
        keys = [[self._memo_key(i, ps) for i in idx] for ps in param_sets]
        todo: dict[tuple, tuple[dict, int]] = {}
        for ps, row in zip(param_sets, keys):
            for i, k in zip(idx, row):
                if k not in self.memo and k not in todo:
                    todo[k] = (ps, i)
        for k, r in zip(todo, self.simulate_pairs(list(todo.values()))):
            self.memo[k] = self.residual_of(todo[k][1], r)
        out = [np.concatenate([self.memo[k] for k in row]) for row in keys]
        for row in keys:
            for k in row:
                self.memo.move_to_end(k)
        while len(self.memo) > RESIDUAL_MEMO:
            self.memo.popitem(last=False)
        return out

    def _memo_key(self, i: int, params: dict) -> tuple:
        """What a run's residual depends on besides the evaluator's fixed settings and targets: the run, the
        parameter set, and the target's anti-alias filter and clock, which the DAQ chain's estimate sets."""
        tg = self.targets[i]
        return i, tuple(sorted(params.items())), tg.antialias, tg.timing

    def __getstate__(self) -> dict:
        """Pickled (a cluster's task) without the memo."""
        return {**self.__dict__, "memo": OrderedDict()}

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
