"""``OptimiseConfig``: the ``optimise`` section of params.yaml (CLI flags override it), checked when built."""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from pipeline.core.errors import UserError
from pipeline.core.numbers import MAX_THREADS, MAX_TRIALS, number
from pipeline.optimise.constraints import Constraints, resolve_margins
from pipeline.optimise.study import DEFAULT_PARETO, OBJECTIVES, SAMPLERS, parse_objectives
from sim.registry import DEFAULT_MODEL

MODES = ("surrogate", "simulator")
DEFAULT_SAMPLER = {"rop": "sobol-local", "pareto": "tpe"}
"""Sampler of a study that names none: the space-filling pass + local search for ROP (bench/bench_search.py: the only
one within 0.995 of a dense scan on every case), TPE for a Pareto front."""
DEFAULT_TRIALS = {"surrogate": 600, "simulator": 200}
"""Complete trials of a study when ``n_trials`` is not given (on the simulator: simulator calls)."""
BOUNDS = {"n_trials": (True, 1, MAX_TRIALS), "batch_size": (True, 1, 10_000), "seed": (True, 0, 2**32 - 1),
          "n_verify": (True, 1, 10_000), "fallback_trials": (True, 0, 100_000), "n_threads": (True, 1, MAX_THREADS),
          "heartbeat_s": (True, 1, 3600), "rel_tol": (False, 0.0, 1e6), "max_peak_force_n": (False, 0.0, None),
          "peak_force_static_ratio": (False, 0.0, None), "max_specific_energy_j_m": (False, 0.0, None),
          "max_power_w": (False, 0.0, None), "max_decel_g": (False, 0.0, None), "infill_rounds": (True, 0, 100),
          "infill_points": (True, 1, 10_000)}
"""The section's numbers: key -> (integer?, low, high); an integer may equal its low, a float must lie above it."""


def check_numbers(d: dict, where: str = "optimise") -> dict:
    """``d`` (an ``optimise`` mapping) with its :data:`BOUNDS` numbers and ``fixed`` values parsed; UserError naming
    ``where.key`` for the first bad one."""
    out = dict(d)
    for key, (integer, lo, hi) in BOUNDS.items():
        if out.get(key) is not None:
            out[key] = number(out[key], f"{where}.{key}", integer=integer, lo=lo, hi=hi, lo_open=not integer)
    if out.get("fixed") is not None:        # a YAML true is no value (float(True) would read it as 1)
        if not isinstance(out["fixed"], dict):
            raise UserError(f"{where}.fixed must be a mapping name -> value, got {out['fixed']!r}")
        out["fixed"] = {k: number(v, f"{where}.fixed.{k}") for k, v in out["fixed"].items()}
    return out


@dataclass
class OptimiseConfig:
    """Keys of the ``optimise`` section of params.yaml (CLI flags override them); validated when built.

    mode: 'surrogate' (study on the bundle at ``surrogate``, then verification) or 'simulator'
    (study directly on the simulator).  objective: 'rop' (maximise ROP) or 'pareto' (the front of
    ``objectives``, default ROP against the mean power: ``["rop_m_s", "power_w"]``; any labels, each with
    an optional ``max:``/``min:`` prefix, ROP maximised and the rest minimised by default).  max_power_w [W],
    max_decel_g [g]: the exciter's power rating and the bit's deceleration limit (None = unconstrained).
    margin: a fraction kept below every limit (0.05), or {label: fraction} (``{power_w: 0.05}``); the study judges a
    surrogate's prediction by the upper end of its interval (constraints.Constraints.margins).  exciter: the rig
    file's shaker envelope (pipeline/optimise/envelope.py), honoured as constraints.  rop_correction: the rig file's
    ``empirical_correction`` (sim.empirical), applied to the simulated ROP (simulator studies).  limit_map: also simulate and
    draw maps of ROP around the recommendation with the limits' contours (pipeline/optimise/limitmap.py).
    sampler: None picks DEFAULT_SAMPLER by objective.  ranges: {name: [low, high]} — default: the surrogate's training ranges / the model's published space
    (ModelSpec.search_spaces).  n_trials: total complete trials of the study (a resumed study runs only the
    rest; default 600 on the surrogate, 200 on the simulator = simulator calls).  n_verify: points
    re-simulated (distinct best / spread along the front).  rel_tol: relative ROP error above which the
    surrogate is called wrong.  fallback_trials: when a surrogate fails its verification (the recommended point,
    or more than half of the verified points, wrong) a study of this many trials straight on the simulator, over
    the same space with the same model, rig and constraints, starting from the points already verified, makes the
    recommendation instead (0: off).  infill_rounds: before that fallback, up to this many rounds of infill
    (pipeline/optimise/infill.py): simulate ``infill_points`` points where the study looked, retrain the surrogate on
    ``train_data`` (its sweep; None: the one its report.json names) plus every point simulated so far, search and
    verify again (0: straight to the fallback).  storage: optuna storage URL (None: the SQLite file optuna.db at the
    project root); heartbeat_s: seconds between heartbeats of a running trial on a server or journal storage (None:
    storages.DEFAULT_HEARTBEAT_S; a trial silent for 3 heartbeats is failed and re-run).
    """

    mode: str = "surrogate"
    surrogate: str | None = "models/surrogate"
    model: str = DEFAULT_MODEL
    preset: str | None = "lab"
    objective: str = "rop"
    ranges: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)
    sampler: str | None = None
    n_trials: int | None = None
    batch_size: int = 8
    seed: int = 0
    max_peak_force_n: float | None = None
    peak_force_static_ratio: float | None = None
    max_specific_energy_j_m: float | None = None
    max_power_w: float | None = None
    max_decel_g: float | None = None
    objectives: list[str] | None = None
    allow_not_settled: bool = False
    margin: float | dict | None = None
    exciter: dict | None = None
    rop_correction: dict | None = None
    limit_map: bool = False
    n_verify: int = 10
    rel_tol: float = 0.10
    fallback_trials: int = 200
    storage: str | None = None
    heartbeat_s: int | None = None
    study_name: str | None = None
    feedback: str | None = None
    n_threads: int | None = None
    settings: dict | None = None
    infill_rounds: int = 3
    infill_points: int = 16
    train_data: str | None = None

    def __post_init__(self) -> None:
        self.validate()

    @classmethod
    def from_mapping(cls, d: dict | None) -> "OptimiseConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d or {}) - known)
        if unknown:
            raise UserError(f"params.yaml optimise: unknown key(s) {unknown}; known: {', '.join(sorted(known))}")
        return cls(**(d or {}))

    def validate(self) -> "OptimiseConfig":
        """UserError naming the first bad key; returns self."""
        if self.mode not in MODES:
            raise UserError(f"mode must be one of {MODES}, got '{self.mode}'")
        if self.objective not in OBJECTIVES:
            raise UserError(f"objective must be one of {OBJECTIVES}, got '{self.objective}'")
        if self.sampler is None:        # by the measurement (docs/optimise.md "Which search")
            self.sampler = DEFAULT_SAMPLER[self.objective] if self.objective in DEFAULT_SAMPLER else "tpe"
        if self.sampler not in SAMPLERS:
            raise UserError(f"sampler must be one of {SAMPLERS}, got '{self.sampler}'")
        check_numbers({k: getattr(self, k) for k in BOUNDS})      # checked, not converted: the study's name hashes them
        if self.train_data is not None and not isinstance(self.train_data, str):
            raise UserError(f"train_data must be a dataset path, got {self.train_data!r}")
        self.objective_list()
        self.constraints()      # a margin names limited labels and fractions in [0, 1)
        if self.mode == "surrogate" and not self.surrogate:
            raise UserError("mode 'surrogate' needs a surrogate bundle (--surrogate DIR or MLflow run id)")
        return self

    @property
    def total_trials(self) -> int:
        """Complete trials the study ends with: ``n_trials``, else the mode's default."""
        return int(self.n_trials or DEFAULT_TRIALS[self.mode])

    def objective_list(self) -> list[tuple[str, str]]:
        """[(label, 'maximize'|'minimize')] of the study: ROP alone, or the Pareto objectives."""
        from sim import LABELS

        if self.objective == "rop":
            if self.objectives:     # never silently ignored: named objectives ask for a Pareto study
                parse_objectives(self.objectives, LABELS)
                raise UserError("--objectives names the objectives of a Pareto study: add --objective pareto "
                                "(without it the study maximises ROP alone)")
            return [("rop_m_s", "maximize")]
        return parse_objectives(self.objectives or list(DEFAULT_PARETO), LABELS)

    def constraints(self) -> Constraints:
        cons = Constraints(max_peak_force_n=self.max_peak_force_n, peak_force_static_ratio=self.peak_force_static_ratio,
                           max_specific_energy_j_m=self.max_specific_energy_j_m, max_power_w=self.max_power_w,
                           max_decel_g=self.max_decel_g,
                           require_settled=not self.allow_not_settled, require_progress=self.objective == "pareto")
        from pipeline.optimise.envelope import Envelope

        env = Envelope.from_mapping(self.exciter, "rig file exciter")
        if env is not None:
            cons = replace(cons, envelope=env)
        return replace(cons, margins=resolve_margins(self.margin, cons)) if self.margin is not None else cons
