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


def calibratable(system: str) -> tuple[FitBound, ...]:
    """The calibratable parameters of ``system`` with their fit bounds (``ModelSpec.calibratable``)."""
    import sim

    return sim.get_model(system).calibratable


warm = sim_warm
"""Load/compile the model's kernel before threads use it (sim.registry.warm)."""


def candidates(system: str) -> dict[str, tuple[FreeParam, ...]]:
    """§6 effects that apply to ``system`` (from the model's own effect table) with their fit bounds."""
    import sim

    spec = sim.get_model(system)
    return {eff: tuple(spec.effect_bounds[p] for p in ps) for eff, ps in spec.effects.items()}


class Evaluator:
    """Simulates parameter sets on the runs of ``targets`` (threads; the kernel releases the GIL)
    and returns noise-normalised residuals (model - measured) / sd."""

    def __init__(self, system: str, targets: list[Target], sim_settings: dict, fs_sim_hz: float,
                 n_threads: int | None = None, max_window: int = 0):
        if system not in supported_systems():
            raise UserError(f"system '{system}': the diagnosis supports {', '.join(supported_systems())} "
                            "(models with calibratable parameters, MODELS.md §6)")
        self.system = system
        self.targets = targets
        self.n_threads = n_threads or os.cpu_count() or 1
        self.settings = []
        for tg in targets:
            f = tg.controls["frequency_hz"]
            spc = tg.spc or max(int(math.ceil(fs_sim_hz / f)), 4 * tg.k_max + 8)
            st = {**sim_settings, "samples_per_cycle": spc}
            if max_window and tg.cycles:   # simulate as many cycles as were recorded (drifting effects)
                st["window"] = max(int(st.get("window", 2)), min(tg.cycles, max_window))
            self.settings.append(st)
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
                                    **tg.controls, **param_sets[j])
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
