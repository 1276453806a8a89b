"""Which parameters are fitted, and the parallel evaluation of the simulator against targets.

Per-model knowledge lives here only (``calibratable``, ``effect_bounds``, ``default_max_harmonic_hz``):
the calibratable parameters of MODELS.md §6 and the fit bounds of every §6 effect parameter, fitted in
log10 units (an effect's "off" value 0 is approached by its lower bound, where it no longer changes the
response measurably).  The drill's effect bounds are the kN-scale ones its model defines
(``sim.models.drill.EFFECT_FIT_BOUNDS``).
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from pipeline.diagnosis.features import Target, peak_velocity, simulated_features
from pipeline.errors import UserError


@dataclass(frozen=True)
class FreeParam:
    """A fitted parameter: name, bounds [lo, hi] in its unit (fitted as log10)."""

    name: str
    lo: float
    hi: float
    unit: str

    def __post_init__(self):
        if not 0 < self.lo < self.hi:
            raise ValueError(f"FreeParam {self.name}: need 0 < lo < hi, got {self.lo}, {self.hi}")

    @property
    def bounds(self) -> tuple[float, float]:
        return math.log10(self.lo), math.log10(self.hi)


_CALIBRATABLE = {
    "indenter-metal": (FreeParam("k1", 1e6, 1e8, "N/m"), FreeParam("c1", 3.0, 3e3, "N s/m"),
                       FreeParam("pm", 0.5, 300.0, "N")),
    "indenter-sandstone": (FreeParam("kl", 5e5, 5e7, "N/m"), FreeParam("ku", 1e6, 2e8, "N/m"),
                           FreeParam("pm", 0.5, 300.0, "N")),
    # the rock under the bit; bounds span the models-start (K1 2e7, C1 5e3, Pr 1.5 kN) and lab
    # (K1 6e8, C1 4e5, Pr 3 kN) presets with a decade to spare
    "drill": (FreeParam("K1", 2e6, 6e9, "N/m"), FreeParam("C1", 5e2, 4e6, "N s/m"), FreeParam("Pr", 150.0, 3e4, "N")),
    # the load cell (ki 5.5e6 N/m, ci 1.2e3 N s/m) and the free-swing damping (zeta 0.005), MODELS.md §3
    "pendulum": (FreeParam("ki", 5e4, 5e8, "N/m"), FreeParam("ci", 10.0, 1e5, "N s/m"),
                 FreeParam("zeta", 1e-4, 0.1, "-")),
    # the stop (ki 92.5e3 N/m^ni, lambda_i 8 s/m) and the beam damping c1 = 1.269 N s/m, MODELS.md §4
    "rimd": (FreeParam("ki", 1e3, 1e7, "N/m^ni"), FreeParam("lambda_i", 0.1, 300.0, "s/m"),
             FreeParam("c1", 0.05, 50.0, "N s/m")),
}
"""MODELS.md §6 'Calibratable parameters': bounds 1-2 decades around the defaults."""

_INDENTER_EFFECTS = {
    "tau": FreeParam("tau", 1e-5, 1e-2, "s"), "beta": FreeParam("beta", 1.0, 3e3, "N s/m"),
    "alpha": FreeParam("alpha", 1e-3, 30.0, "s/m"), "mu": FreeParam("mu", 0.1, 300.0, "N"),
    "gamma": FreeParam("gamma", 1e-4, 0.5, "-"), "kappa": FreeParam("kappa", 1e2, 1e8, "1/m^2"),
    "fc": FreeParam("fc", 50.0, 5000.0, "Hz"),
}
_EFFECTS = {
    "indenter-metal": _INDENTER_EFFECTS,
    "indenter-sandstone": _INDENTER_EFFECTS,
    # contact rate of the hammer ~0.1-0.5 m/s: alpha ~ 0.1-10 s/m changes the contact stiffness by 1-100 %
    "pendulum": {"alpha": FreeParam("alpha", 1e-2, 100.0, "s/m")},
    # hammer impact velocity ~0.05-0.2 m/s; beam amplitude ~1-5 mm, so kappa x1^2 ~ 1 at kappa ~ 1e5 1/m^2
    "rimd": {"alpha": FreeParam("alpha", 1e-2, 100.0, "s/m"), "kappa": FreeParam("kappa", 1e1, 1e7, "1/m^2")},
}


def _drill_effects() -> dict[str, FreeParam]:
    from sim.models.drill import EFFECT_FIT_BOUNDS

    return {p: FreeParam(p, lo, hi, unit) for p, (lo, hi, unit) in EFFECT_FIT_BOUNDS.items()}


_MAX_HARMONIC_HZ = {"indenter-metal": 1000.0, "indenter-sandstone": 1000.0, "drill": 3000.0,
                    "pendulum": 100.0, "rimd": 200.0}
"""Default highest harmonic used as a feature [Hz]: the indenter's impacts ring up to ~1 kHz, the lab drill's
contact mode is ~500 Hz (harmonics to 3 kHz carry its impact shape), the pendulum (3-8 Hz) and RIMD (4-15 Hz)
impacts are resolved by their first ~25 harmonics."""


_FIT_SETTINGS = {"indenter-metal": {"candidate_starts": 2, "max_nfev": 15},
                 "indenter-sandstone": {"candidate_starts": 2, "max_nfev": 15}}
"""Fit effort per system.  The indenter's base fit can absorb a missing effect in pm, so its candidates also
start at the default base (issue 7).  The drill, pendulum and RIMD use one candidate start and 10 iterations:
on the drill control (16 runs, 25.6 kHz, from rest) this halves the time (README.md 'Speed') with the same
answer; the identification table in README.md is at these settings."""
_FIT_DEFAULT = {"candidate_starts": 1, "max_nfev": 10}


def default_fit_settings(system: str) -> dict:
    """Default candidate_starts and max_nfev of ``system`` (DiagnoseConfig None values)."""
    return dict(_FIT_SETTINGS.get(system, _FIT_DEFAULT))


def supported() -> tuple[str, ...]:
    """Systems the diagnosis can calibrate."""
    return tuple(_CALIBRATABLE)


def calibratable(system: str) -> tuple[FreeParam, ...]:
    """MODELS.md §6 calibratable parameters of ``system`` with their fit bounds."""
    if system not in _CALIBRATABLE:
        raise UserError(f"system '{system}': the diagnosis supports {', '.join(_CALIBRATABLE)}")
    return _CALIBRATABLE[system]


def effect_bounds(system: str) -> dict[str, FreeParam]:
    """Fit bounds of every §6 effect parameter of ``system`` (model-specific scales)."""
    calibratable(system)
    return _drill_effects() if system == "drill" else dict(_EFFECTS[system])


def default_max_harmonic_hz(system: str) -> float:
    """Default ``max_harmonic_hz`` of ``system`` (see _MAX_HARMONIC_HZ)."""
    return _MAX_HARMONIC_HZ[system]


def warm(system: str) -> None:
    """Load/compile the model's kernel in the calling thread before threads use it
    (sim.compiled.kernels is not thread-safe on its first call; see the diagnose report)."""
    import sim
    from sim.compiled import kernels

    spec = sim.get_model(system)
    kernels(spec.funcs, spec.n_bounded)


def candidates(system: str) -> dict[str, tuple[FreeParam, ...]]:
    """§6 effects that apply to ``system`` (from the model's own effect table) with their fit bounds."""
    import sim

    spec = sim.get_model(system)
    bounds = effect_bounds(system)
    return {eff: tuple(bounds[p] for p in ps) for eff, ps in spec.effects.items()}


MAX_SPC = 4096
"""Cap on the model's samples per cycle (the history is only output; the integrator steps on its own)."""


def run_settings(tg: Target, sim_settings: dict, fs_sim_hz: float, max_window: int = 0,
                 oversample: float = 4.0) -> dict:
    """Simulator settings of one run.  The model is sampled densely (``oversample`` x the record's rate,
    at least 4 K + 8 samples per cycle, at most MAX_SPC) and interpolated onto the record's own time base
    (features.model_on_record), so its harmonics see the same sampling as the measurement's.  Steady-state record: as
    many cycles as were recorded (up to ``max_window``; drifting effects depend on it).  Record from
    rest (``record_start_s``): no transient, a window from rest that covers [record_start_s,
    record_start_s + duration_s] (features.model_record cuts it)."""
    f = tg.frequency_hz
    fs = tg.fs_hz or fs_sim_hz
    spc = min(max(int(math.ceil(oversample * fs / f)), 4 * tg.k_max + 8), MAX_SPC)
    st = {**sim_settings, "samples_per_cycle": spc}
    if tg.record_start_s is not None:
        end = tg.record_start_s + max(tg.duration_s, 2.0 / f)
        st.update(min_transient=0, max_transient=0, window=max(int(math.ceil(end * f)) + 1, 2))
    elif max_window and tg.kind == "series":
        st["window"] = max(int(st.get("window", 2)), min(int(math.ceil(tg.cycles)), max_window))
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
