"""Model description shared by every simulated system: parameters, states, kernels."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from sim.models.param import ParameterError  # noqa: F401  (re-exported: the models and sim.api raise it from here)
from vibrobase.errors import did_you_mean
from sim.models.discrepancy import CANDIDATES, HIDDEN_MODES, HIDDEN_USERS, MODE_STATES, PARAM_OF as DISCREPANCY_PARAMS
from sim.models.effects import EFFECT_FIT_BOUNDS, EFFECTS, effect
from sim.models.fitbound import FitBound  # noqa: F401  (re-exported: the models build their bounds from here)
from sim.models.param import Param  # noqa: F401  (re-exported: the models declare their parameters from here)
from sim.models.ranges import out_of_range


DIAGNOSE_FIT_KEYS = ("candidate_starts", "max_nfev")
"""Keys of ``ModelSpec.diagnose_fit`` (the diagnosis' default fit effort)."""

MAP_KINDS = ("pattern", "rop")
"""Kinds of parameter maps: Peterka-style impact-pattern maps, or ROP maps."""


SYNTH_SIGNALS = ("accel_m_s2", "force_n", "disp_m", "progression_m")
"""Signals a synthetic rig (``SynthRig.signals``) can record (MODELS.md §7)."""


@dataclass(frozen=True)
class SynthRig:
    """How ``vibro synth`` records this model's rig by default (MODELS.md §7): every frequency [Hz] x every
    level of a second control, at a DAQ rate ``fs_hz`` [Hz] over ``cycles`` forcing cycles (need not be whole).

    ``level_name`` is the second control: a parameter set to each level, or, with ``forcing``, a rig quantity
    (e.g. pressure in bar) that ``forcing(frequency_hz, level) -> {parameter: value}`` turns into the run's
    forcing (e.g. the indenter's Table 1 amplitude and pneumatic static force); ``level_tag`` then ends the
    run ids with the level and this unit instead of the level's index.  ``fixed`` are controls held in every
    run, ``preset`` the parameter set of the rig, ``record_start_s`` [s] the record starts after a start from
    rest cycled over the runs (None: steady state), ``summary_runs`` runs logged as summaries only,
    ``drop_signal_every`` every n-th run loses its second channel (0: none).  ``effect_strengths``: effect ->
    {parameter: value} of a clearly visible strength of every §6 effect of the model (``--effect NAME``).
    ``mount_hz`` [Hz]: resonance of the outside-physics accelerometer mount, inside the diagnosed harmonics.
    ``hertz_model``: the model that simulates the outside-physics elastic Hertz contact in place of this
    model's linear contact (its power law at kl = ku = kh, nl = nu = 1.5), None if the rig has none."""

    frequencies_hz: tuple[float, ...]
    level_name: str
    levels: tuple[float, ...]
    fixed: dict[str, float]
    fs_hz: float
    cycles: float
    effect_strengths: dict[str, dict[str, float]]
    mount_hz: float
    preset: str | None = None
    signals: tuple[str, ...] = ("accel_m_s2", "force_n", "disp_m")
    record_start_s: tuple[float, ...] | None = None
    summary_runs: int = 0
    drop_signal_every: int = 0
    forcing: Callable[[float, float], dict[str, float]] | None = None
    level_tag: str = ""
    hertz_model: str | None = None

    def check(self, spec: "ModelSpec") -> None:
        """ValueError naming the field unless every name is a parameter / effect / preset of ``spec``."""
        where = f"model '{spec.name}' synth rig"
        names = set(spec.param_names)
        if not self.frequencies_hz or not all(f > 0 for f in self.frequencies_hz):
            raise ValueError(f"{where}: frequencies_hz must be > 0, got {self.frequencies_hz!r}")
        if not self.levels:
            raise ValueError(f"{where}: levels must not be empty")
        if not spec.calibratable:
            raise ValueError(f"{where}: the model has no calibratable parameters to perturb")
        if self.forcing is None and self.level_name not in names:
            raise ValueError(f"{where}: level_name '{self.level_name}' is not a parameter (or give forcing)")
        forced = self.forcing(self.frequencies_hz[0], self.levels[0]) if self.forcing is not None else {}
        for n in list(self.fixed) + list(forced):
            if n not in names:
                raise ValueError(f"{where}: fixed/forcing control '{n}' is not a parameter")
        if self.preset is not None and self.preset not in spec.presets:
            raise ValueError(f"{where}: unknown preset '{self.preset}'")
        if not self.signals or not set(self.signals) <= set(SYNTH_SIGNALS):
            raise ValueError(f"{where}: signals {self.signals!r} must be among {SYNTH_SIGNALS}")
        for n, v in (("fs_hz", self.fs_hz), ("mount_hz", self.mount_hz)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{where}: {n} must be > 0, got {v!r}")
        if not self.cycles >= 2.5:
            raise ValueError(f"{where}: cycles must be >= 2.5, got {self.cycles!r}")
        if any(x < 0 for x in self.record_start_s or ()) or self.summary_runs < 0 or self.drop_signal_every < 0:
            raise ValueError(f"{where}: record_start_s, summary_runs and drop_signal_every must be >= 0")
        if set(self.effect_strengths) != set(spec.effects):
            raise ValueError(f"{where}: effect_strengths must give exactly the effects {sorted(spec.effects)}, "
                             f"got {sorted(self.effect_strengths)}")
        for eff, vals in self.effect_strengths.items():
            if tuple(vals) != spec.effects[eff] or not all(v > 0 for v in vals.values()):
                raise ValueError(f"{where}: effect_strengths['{eff}'] must give {spec.effects[eff]} > 0, got {vals!r}")


@dataclass(frozen=True)
class ModelSpec:
    """Everything the generic driver needs to know about one model.

    funcs = (rhs, guards, on_event, observe, bounded) numba functions (see sim.integrator).
    ``derive`` may fill parameters that default to a formula (e.g. indenter c3) and
    runs before validation of cross-parameter constraints.
    """

    name: str
    description: str
    params: tuple[Param, ...]
    states: tuple[str, ...]
    z_names: tuple[str, ...]
    bounded: tuple[str, ...]
    funcs: tuple
    n_bounded: int
    initial: Callable[[np.ndarray], tuple]
    atol: Callable[[np.ndarray], np.ndarray]   # typical magnitude of each state (atol = rtol × this)
    precheck: Callable[[np.ndarray], str | None] = lambda p: None
    effects: dict[str, tuple[str, ...]] = field(default_factory=dict)   # §6 effect -> its parameters; give the names
    impacting_mass: str = ""
    progression: str = ""
    presets: dict[str, dict[str, float]] = field(default_factory=dict)
    default_settings: dict[str, float] = field(default_factory=dict)
    derive: Callable[[dict], dict] | None = None
    forcing_phase: str = "sin"
    postprocess: Callable | None = None
    needs_history: Callable[[dict], bool] = lambda values: False
    # --- what the workflows need to know about the model (checked by __post_init__) ---
    calibratable: tuple[FitBound, ...] = ()                   # MODELS.md §6 "Calibratable parameters", with fit bounds
    effect_bounds: dict[str, FitBound] = field(default_factory=dict)   # effect parameter -> fit bounds; off = 0
    search_spaces: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)  # preset ("" = defaults) -> control ranges
    # the ranges [SI] the model or a preset was validated on: preset ("" = the defaults and every preset without an
    # entry of its own) -> parameter -> (lo, hi); with the calibratable fit bounds, a value outside them draws a
    # warning naming the likely unit slip (sim.models.ranges; `vibro simulate`, `vibro sweep`, rig files)
    validated: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)
    map_kind: str = ""                                        # "pattern" or "rop" (MAP_KINDS)
    map_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)   # default map axis ranges [SI]
    map_relative_to: dict[str, str] = field(default_factory=dict)  # axis -> parameter its map range is a multiple of
    progress_force_floor: Callable[[Mapping[str, float]], float | None] = lambda v: None  # force needed to progress [N]
    # energy balance of a periodic steady state (sim.invariants): the least work the excitation does per metre of
    # progression [J/m] (drill: Pr - Fs; a passive model that does not progress: 0, the work covers its losses); None:
    # the labels hold no balance to check (a source of work they do not record, e.g. the indenter's pneumatic piston)
    min_work_per_m: Callable[[Mapping[str, float]], float] | None = None
    diagnose_max_harmonic_hz: float = 1000.0                  # highest harmonic the diagnosis uses as a feature [Hz]
    diagnose_fit: dict[str, int] = field(default_factory=lambda: {"candidate_starts": 1, "max_nfev": 10})
    # diagnosis fit effort: random starts per candidate, least-squares iterations (DIAGNOSE_FIT_KEYS)
    diagnose_chain: bool = True
    # whether the diagnosis estimates an undeclared DAQ chain (a delay per channel, a clock) beside every fit by default
    exact: str | None = None   # module of an exact propagator of the model's phases (sim/exact/), if any
    # discrepancy terms the model has (sim.models.discrepancy; each a parameter, off at 0) and their fit bounds
    # [SI]: lo = where the term just becomes measurable, hi = large but still simulable
    discrepancy: tuple[str, ...] = ()
    discrepancy_bounds: dict[str, FitBound] = field(default_factory=dict)
    synth: SynthRig | None = None   # how `vibro synth` records the model's rig (None: no synthetic rig)

    def __post_init__(self):
        """A table checks itself: fills effect bounds from the shared §6 table (sim.models.effects) where the
        model gives none, then checks every bound, space, range and preset against the parameters."""
        names = set(self.param_names)
        where = f"model '{self.name}'"
        if not isinstance(self.effects, Mapping):     # the effect names (sim.models.effects): their parameters
            try:
                object.__setattr__(self, "effects", {e: effect(e).param_names for e in self.effects})
            except ValueError as err:
                raise ValueError(f"{where}: {err}") from None
        for e, ps in self.effects.items():
            if e not in EFFECTS or tuple(ps) != EFFECTS[e].param_names:
                raise ValueError(f"{where}: effect '{e}' must have the parameters of sim.models.effects, "
                                 f"got {ps!r}")
        effect_params = [p for ps in self.effects.values() for p in ps]
        if effect_params:
            filled = {p: EFFECT_FIT_BOUNDS[p] for p in effect_params if p not in self.effect_bounds and p in EFFECT_FIT_BOUNDS}
            if filled:
                object.__setattr__(self, "effect_bounds", {**filled, **self.effect_bounds})
        for p in effect_params:
            if p not in names:
                raise ValueError(f"{where}: effect parameter '{p}' is not a parameter")
            if p not in self.effect_bounds:
                raise ValueError(f"{where}: effect parameter '{p}' has no fit bounds (add it to effect_bounds "
                                 "or to sim.models.effects.EFFECT_FIT_BOUNDS)")
        for key, b in [(b.name, b) for b in self.calibratable] + list(self.effect_bounds.items()):
            if key != b.name or b.name not in names:
                raise ValueError(f"{where}: fit bound '{key}' is not a parameter")
        for what, table in (("search space", self.search_spaces), ("validated ranges", self.validated)):
            for preset, space in table.items():
                if preset != "" and preset not in self.presets:
                    raise ValueError(f"{where}: {what} for unknown preset '{preset}'")
                for n, (lo, hi) in space.items():
                    if n not in names or not lo < hi:
                        raise ValueError(f"{where}: {what} '{preset}': bad range {n} = ({lo}, {hi})")
        if self.map_kind not in ("",) + MAP_KINDS:
            raise ValueError(f"{where}: map_kind '{self.map_kind}' is not one of {MAP_KINDS}")
        for n, (lo, hi) in self.map_ranges.items():
            if n not in names or not lo < hi:
                raise ValueError(f"{where}: bad map range {n} = ({lo}, {hi})")
        for n, ref in self.map_relative_to.items():
            if n not in self.map_ranges or ref not in names:
                raise ValueError(f"{where}: map_relative_to {n} -> {ref}: needs a map range and a parameter")
        if not (math.isfinite(self.diagnose_max_harmonic_hz) and self.diagnose_max_harmonic_hz > 0):
            raise ValueError(f"{where}: diagnose_max_harmonic_hz must be > 0, got {self.diagnose_max_harmonic_hz!r}")
        if set(self.diagnose_fit) != set(DIAGNOSE_FIT_KEYS) or not all(
                isinstance(v, int) and v >= 1 for v in self.diagnose_fit.values()):
            raise ValueError(f"{where}: diagnose_fit must give integers >= 1 for exactly {DIAGNOSE_FIT_KEYS}, "
                             f"got {self.diagnose_fit!r}")
        for t in self.discrepancy:
            if t not in DISCREPANCY_PARAMS or t not in names:
                raise ValueError(f"{where}: discrepancy term '{t}' is not a parameter of sim.models.discrepancy and of the model")
            b = self.discrepancy_bounds.get(t)
            if b is None or b.name != t or not 0.0 < b.lo < b.hi:
                raise ValueError(f"{where}: discrepancy term '{t}' needs fit bounds 0 < lo < hi")
        if self.synth is not None:
            self.synth.check(self)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def defaults(self, preset: str | None = None) -> dict[str, float]:
        values = {p.name: p.default for p in self.params}
        if preset is not None:
            if preset not in self.presets:
                raise ParameterError(f"unknown preset '{preset}' for model '{self.name}'"
                                     f"{did_you_mean(preset, self.presets)}; "
                                     f"known: {', '.join(sorted(self.presets)) or 'none'}")
            values.update(self.presets[preset])
        return values

    def resolve(self, preset: str | None = None, **overrides) -> dict[str, float]:
        """Validated full parameter dict: defaults ← preset ← overrides ← derived."""
        values = self.defaults(preset)
        self.check_names(overrides)
        values.update(overrides)
        by_name = {p.name: p for p in self.params}
        out = {}
        for name, v in values.items():
            if v is None:
                out[name] = None
                continue
            out[name] = by_name[name].validate(v)
        for name in DISCREPANCY_PARAMS:     # a term the model does not have must stay off
            if out.get(name) and name not in self.discrepancy:
                raise ParameterError(f"discrepancy term '{name}' does not apply to model '{self.name}' "
                                     f"(its terms: {', '.join(self.discrepancy) or 'none'})")
        for mode in HIDDEN_MODES:
            ratio_name, hz_name, _ = CANDIDATES[mode].params
            ratio, hz = out.get(ratio_name), out.get(hz_name)
            if ratio and not hz:       # a hidden mass on no spring: not a mode
                raise ParameterError(f"discrepancy {mode}: parameter '{hz_name}' must be > 0 [Hz] when "
                                     f"'{ratio_name}' is > 0, got {hz!r}")
        on = [c for c in HIDDEN_USERS if out.get(CANDIDATES[c].params[0])]
        if len(on) > 1:            # they share the model's two hidden states
            raise ParameterError(f"discrepancy {' and '.join(on)}: one at a time (they share the hidden states "
                                 f"{', '.join(MODE_STATES)})")
        if self.derive is not None:
            out = self.derive(out)
        for name, v in out.items():
            if v is None:
                raise ParameterError(f"parameter '{name}' of model '{self.name}' has no value")
        return out

    def check_names(self, names, where: str = "") -> None:
        """ParameterError naming the first of ``names`` that is no parameter of the model, with the likely one
        (``where``: a prefix naming the source, e.g. ``sweep.fixed``)."""
        known = self.param_names
        for key in names:
            if key not in known:
                raise ParameterError(f"{where + ': ' if where else ''}unknown parameter '{key}' for model '{self.name}'"
                                     f"{did_you_mean(key, known)}; known: {', '.join(known)}")

    def out_of_range(self, preset: str | None, values: Mapping[str, float | tuple[float, float]]) -> list[str]:
        """One warning line per value (or sweep range) outside what the model or ``preset`` was validated on
        (``validated``, the calibratable fit bounds), naming the likely unit slip (sim.models.ranges)."""
        return out_of_range(self, preset, values)

    def vector(self, values: dict[str, float]) -> np.ndarray:
        return np.array([values[p.name] for p in self.params], dtype=np.float64)
