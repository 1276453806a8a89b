"""report.json as typed, frozen records: one system's diagnosis (``SystemReport``) and the dataset's
(``DiagnoseReport``).  ``DiagnoseReport.to_json`` / ``from_json`` are the only place its keys are strings; every
reader uses attributes.  A composite identity (an effect pair, a proposal's terms) is a tuple of names here and
``"a+b"`` only in the file.

A record's JSON layout is its fields in order, each under its own name unless its metadata names another key
(``key``), converted by its ``codec`` (load, dump) and left out of the file when None if ``omit``.  report.json
carries ``report_schema`` (``SCHEMA``); a file without it is read as schema 1, a newer one is refused.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Callable, Mapping

SCHEMA = 1
"""Version of report.json's layout (report.json ``report_schema``; ``cost`` carries its own ``schema``)."""
SCHEMA_KEY = "report_schema"

Effects = tuple[str, ...]
"""A model's effects, e.g. ``("shaker_coil", "guide_friction")``; ``"shaker_coil+guide_friction"`` in the file."""

Codec = tuple[Callable[[Any], Any], Callable[[Any], Any]]


def effects_of(name: str | None) -> Effects | None:
    """The effects of a model named as the diagnosis' fits name it ("a", "a+b"); None for None."""
    return None if name is None else tuple(name.split("+"))


def _same(x):
    return x


PLAIN: Codec = (_same, _same)
EFFECTS: Codec = (effects_of, "+".join)


def _opt(c: Codec) -> Codec:
    return (lambda v: None if v is None else c[0](v), lambda v: None if v is None else c[1](v))


def _seq(c: Codec = PLAIN) -> Codec:
    return (lambda v: tuple(c[0](x) for x in v), lambda v: [c[1](x) for x in v])


def _by_name(c: Codec) -> Codec:
    return (lambda v: {k: c[0](x) for k, x in v.items()}, lambda v: {k: c[1](x) for k, x in v.items()})


def _rec(cls) -> Codec:
    return (cls.from_json, lambda x: x.to_json())


def _f(codec: Codec = PLAIN, key: str | None = None, omit: bool = False, **kw):
    """A field stored under ``key`` (default: its name) through ``codec``; ``omit``: absent from the file when None."""
    return field(metadata={"codec": codec, "key": key, "omit": omit}, **kw)


class _Record:
    """Generic JSON conversion of a frozen dataclass from its fields' metadata."""

    @classmethod
    def from_json(cls, d: Mapping):
        kw = {}
        for f in fields(cls):
            m = f.metadata
            key = m.get("key") or f.name
            if key in d:
                kw[f.name] = m.get("codec", PLAIN)[0](d[key])
            elif m.get("omit"):
                kw[f.name] = None
        return cls(**kw)

    def to_json(self) -> dict:
        out = {}
        for f in fields(self):
            m, v = f.metadata, getattr(self, f.name)
            if v is None and m.get("omit"):
                continue
            out[m.get("key") or f.name] = m.get("codec", PLAIN)[1](v)
        return out


@dataclass(frozen=True)
class ParamEstimate(_Record):
    """A fitted parameter in its SI unit."""

    value: float
    """The estimate [parameter's SI unit]."""
    sd: float
    """Its standard deviation [parameter's SI unit]."""
    ci95: tuple[float, float] = _f(_seq())
    """Its 95 % interval (low, high) [parameter's SI unit]."""


PARAMS = _by_name(_rec(ParamEstimate))


@dataclass(frozen=True)
class Absorption(_Record):
    """A calibrated parameter the base fit moved, against the fit with an effect (missing physics absorbed)."""

    base: float
    """The base fit's value [SI]."""
    with_: float = _f(key="with")
    """The value in the fit with ``effect`` [SI]."""
    change: float = _f()
    """base / with - 1 [-]."""
    effects: Effects = _f(EFFECTS, key="effect")
    """The effect(s) of the fit compared with."""


ABSORBED = _by_name(_rec(Absorption))


@dataclass(frozen=True)
class Fold(_Record):
    """One fold of the split: run ids."""

    calibration: tuple[str, ...] = _f(_seq())
    """The runs the models are fitted on."""
    held_out: tuple[str, ...] = _f(_seq())
    """The runs they are judged on."""


@dataclass(frozen=True)
class Split(_Record):
    """How the runs were split between calibration and judgement."""

    scheme: str
    """The fold scheme's name (``judge.Holdout.name``, ``judge.LeaveOneRunOut.name``)."""
    held_out: tuple[str, ...] = _f(_seq())
    """Every run held out in some fold, sorted."""
    folds: tuple[Fold, ...] = _f(_seq(_rec(Fold)))
    """The folds, in order."""


@dataclass(frozen=True)
class ModelErrors:
    """One model's held-out errors, summed over the folds (noise-normalised)."""

    error: float
    """Held-out rms error relative to the measured features [-]."""
    nrms: float
    """Held-out rms of the noise-normalised residual [-] (1: at the noise)."""
    systematic: float | None
    """The part of the error that repeats between the halves of a run [-] (None: not measured)."""
    by_group: Mapping[str, float]
    """The error per feature group (e.g. 'accel_m_s2') [-]."""


@dataclass(frozen=True)
class HeldOutErrors:
    """The held-out errors of the model defaults, the calibrated base and the final model."""

    default: ModelErrors
    """The model's default parameters (its ``systematic`` is not reported: None)."""
    base: ModelErrors
    """The calibrated base model."""
    final: ModelErrors
    """The final model (the selected effect, the adopted proposal, or the base)."""
    noise_floor: float
    """The error pure measurement noise would give [-]."""
    noise_by_group: Mapping[str, float]
    """The noise floor per feature group [-]."""
    n: int
    """Held-out features compared."""


@dataclass(frozen=True)
class Candidate(_Record):
    """One candidate effect of the single-effect stage, fitted with the calibrated parameters."""

    effects: Effects = _f(EFFECTS, key="effect")
    """The effect (one name)."""
    params: Mapping[str, float] = _f()
    """The effect's fitted parameters [SI]."""
    param_sd: Mapping[str, float] = _f()
    """Standard deviation of every free parameter [SI]."""
    calibrated: Mapping[str, float] = _f()
    """Every parameter of the fit [SI]."""
    error: float = _f()
    """Held-out error [-]."""
    nrms: float = _f()
    """Held-out nrms [-]."""
    systematic: float | None = _f()
    """Held-out systematic error [-]."""
    score: float = _f()
    """BIC on the calibration runs [-]."""
    delta_score: float = _f()
    """BIC minus the base's [-]."""
    delta_chi2_heldout: float = _f()
    """Held-out χ² below the base's [-]."""
    improves: bool = _f()
    """Better than the base on BIC and held-out χ²."""
    adequate: bool = _f()
    """Improves and brings the model to the noise."""
    calibration_chi2: float = _f()
    """χ² on the calibration runs [-]."""


@dataclass(frozen=True)
class CallEntry(_Record):
    """The numbers a threshold of the verdict saw for one model."""

    name: Effects | None = _f(_opt(EFFECTS), omit=True)
    """The model's effects (None: the base)."""
    adequate: bool = _f()
    """Brings the model to the noise."""
    nrms: float = _f()
    """Held-out nrms [-]."""
    systematic: float | None = _f()
    """Held-out systematic error [-]."""
    delta_bic: float = _f()
    """BIC gain over the base [-]."""
    delta_chi2: float = _f()
    """Held-out χ² gain over the base [-]."""
    systematic_gain: float | None = _f()
    """Systematic error removed against the base [-]."""
    improves: bool = _f()
    """Better than the base on both."""


@dataclass(frozen=True)
class Call(_Record):
    """How close the call was."""

    base: CallEntry = _f(_rec(CallEntry))
    """The calibrated base."""
    leader: CallEntry | None = _f(_opt(_rec(CallEntry)), omit=True)
    """The best candidate that improves, if any."""
    runner_up: CallEntry | None = _f(_opt(_rec(CallEntry)), omit=True)
    """The next candidate, if any."""
    bic_gap_to_runner_up: float | None = _f(omit=True)
    """Selected: BIC of the runner-up minus the leader's [-]."""
    best_candidate_share: float | None = _f(omit=True)
    """Unexplained: fraction of the excess held-out χ² the best candidate removes [-]."""
    text: str = _f()
    """The call in a sentence."""


@dataclass(frozen=True)
class PairCandidate(_Record):
    """A pair of effects tried in the second-effect stage (written with its ``name`` "a+b" and its ``effects``)."""

    effects: Effects = _f(_seq())
    """The two effects, the first stage's leader first."""
    params: Mapping[str, float] = _f()
    """The effects' fitted parameters [SI]."""
    param_sd: Mapping[str, float] = _f()
    """Their standard deviations [SI]."""
    nrms: float = _f()
    """Held-out nrms [-]."""
    systematic: float | None = _f()
    """Held-out systematic error [-]."""
    delta_bic: float = _f()
    """BIC gain over the leader alone [-]."""
    delta_chi2: float = _f()
    """Held-out χ² gain over the leader alone [-]."""
    improves: bool = _f()
    """Better than the leader alone on both."""
    adequate: bool = _f()
    """Improves and brings the model to the noise."""

    def to_json(self) -> dict:
        return {"name": "+".join(self.effects), **super().to_json()}


@dataclass(frozen=True)
class SecondEffect(_Record):
    """The second-effect stage: every pair with the first stage's leader."""

    first: Effects = _f(EFFECTS)
    """The first stage's leader."""
    candidates: tuple[PairCandidate, ...] = _f(_seq(_rec(PairCandidate)))
    """Every pair, best BIC first."""
    leader: Effects | None = _f(_opt(EFFECTS))
    """The best pair that improves, if any."""
    indistinguishable: tuple[Effects, ...] = _f(_seq(EFFECTS))
    """Pairs the data cannot tell from the leader."""
    text: str = _f()
    """The stage's call in a sentence."""


@dataclass(frozen=True)
class PairStage(_Record):
    """Whether the pair stage ran, and why."""

    tried: bool
    """The pair stage ran."""
    reason: str
    """Why (or why not)."""


@dataclass(frozen=True)
class ScreeningRow(_Record):
    """A library term of discovery's sparse regression."""

    term: str
    """The term's name."""
    words: str
    """What it means, in words."""
    form: str
    """Its formula."""
    kind: str
    """Its kind (e.g. force, instrument)."""
    entered: int
    """The regression path's step it entered at."""
    score: float
    """Its screening score [-]."""
    estimate: float
    """The regression's coefficient [SI]."""
    in_support: bool
    """In the selected support."""


@dataclass(frozen=True)
class Proposal(_Record):
    """A proposed missing term (or terms), fitted with the calibrated parameters."""

    name: str
    """The proposal's model name (``discovery.PREFIX`` + terms)."""
    terms: tuple[str, ...] = _f(_seq())
    """Its terms."""
    words: tuple[str, ...] = _f(_seq())
    """Each term in words."""
    forms: tuple[str, ...] = _f(_seq())
    """Each term's formula."""
    kinds: tuple[str, ...] = _f(_seq())
    """Each term's kind."""
    coefficients: Mapping[str, float] = _f()
    """Fitted coefficient per term [SI]."""
    coefficient_sd: Mapping[str, float] = _f()
    """Their standard deviations [SI]."""
    coefficient_ci95: Mapping[str, tuple[float, float]] = _f(_by_name(_seq()))
    """Their 95 % intervals [SI]."""
    calibrated: Mapping[str, float] = _f()
    """The calibrated parameters of the fit [SI]."""
    nrms: float = _f()
    """Held-out nrms [-]."""
    error: float = _f()
    """Held-out error [-]."""
    noise_floor: float = _f()
    """Noise floor [-]."""
    systematic: float | None = _f()
    """Held-out systematic error [-]."""
    by_run_nrms: Mapping[str, float] = _f()
    """Held-out nrms per run [-]."""
    delta_bic: float | None = _f(omit=True)
    """BIC gain over the base [-] (None: not judged)."""
    delta_chi2: float | None = _f(omit=True)
    """Held-out χ² gain over the base [-] (None: not judged)."""
    improves: bool | None = _f(omit=True)
    """Better than the base on both (None: not judged)."""
    adequate: bool | None = _f(omit=True)
    """Improves and brings the model to the noise (None: not judged)."""


@dataclass(frozen=True)
class Discrepancy(_Record):
    """Discovery: the missing term proposed when no effect explains the residual."""

    screening: tuple[ScreeningRow, ...] = _f(_seq(_rec(ScreeningRow)))
    """Every library term screened."""
    path_bic: tuple[float, ...] = _f(_seq())
    """BIC along the regression path [-]."""
    proposals: tuple[Proposal, ...] = _f(_seq(_rec(Proposal)))
    """The proposals fitted."""
    base_by_run_nrms: Mapping[str, float] = _f()
    """The base model's held-out nrms per run [-]."""
    accepted: tuple[str, ...] | None = _f(_opt(_seq()))
    """The accepted proposal's terms, if any."""
    text: str = _f()
    """Discovery's call in a sentence."""


@dataclass(frozen=True)
class ProposalAsEffect(_Record):
    """An accepted proposal that is a §6 effect in another form, refitted as that effect."""

    effect: str
    """The effect."""
    start: Mapping[str, float]
    """The start its refit took from the proposal [SI]."""
    params: Mapping[str, Any]
    """The refit's parameters."""
    selected: bool
    """The refitted effect replaced the verdict."""
    text: str
    """In a sentence."""


@dataclass(frozen=True)
class EmpiricalReport(_Record):
    """The last resort where nothing explained the residual: an empirical correction of ROP
    (``pipeline.diagnosis.empirical``), never physics."""

    label: str
    """'empirical correction, physics unknown'."""
    adopted: bool
    """It cut the held-out ROP error enough and is carried in the corrected rig."""
    inputs: tuple[str, ...] = _f(_seq())
    """The controls it varies over."""
    heldout_rop_error_before: float | None = None
    """Held-out rms relative ROP error of the final model [1] (None: no held-out ROP)."""
    heldout_rop_error_after: float | None = None
    """... with the correction fitted on the calibration runs [1]."""
    heldout_runs: int = 0
    """Held-out runs with a measured ROP."""
    halved: bool = False
    """It halved that error."""
    text: str = ""
    """In a sentence: what it did, or why it was not adopted."""


@dataclass(frozen=True)
class DeclaredChain(_Record):
    """The DAQ chain a run declares."""

    filter: str | None
    """The anti-alias filter (None: none)."""
    delay_s: float
    """Delay [s]."""
    clock_ppm: float
    """Clock error [ppm]."""


@dataclass(frozen=True)
class ChannelDelay(_Record):
    """An estimated delay of one channel."""

    channel: str
    """The signal."""
    fs_hz: float
    """Its sample rate [Hz]."""
    value_s: float
    """Delay [s]."""
    sd_s: float
    """Its standard deviation [s]."""


@dataclass(frozen=True)
class ClockEstimate(_Record):
    """The estimated clock error."""

    value: float
    """The clock's rate error [ppm]."""
    sd: float
    """Its standard deviation [ppm]."""


@dataclass(frozen=True)
class EstimatedChain(_Record):
    """An undeclared DAQ chain estimated as nuisance on the base model's calibration."""

    runs: tuple[str, ...] = _f(_seq())
    """The runs it was estimated on."""
    delays: tuple[ChannelDelay, ...] = _f(_seq(_rec(ChannelDelay)))
    """Delay per channel."""
    clock_ppm: ClockEstimate = _f(_rec(ClockEstimate))
    """Clock error."""
    base_chi2_per_n: float = _f()
    """The base model's χ² per feature with it [-]."""
    text: str = _f()
    """In a sentence."""


@dataclass(frozen=True)
class Recording(_Record):
    """What the recording did: the declared chains, the estimated one, the saturated channels, the mains hum."""

    declared: Mapping[str, DeclaredChain] = _f(_by_name(_rec(DeclaredChain)))
    """Declared chain per run id."""
    estimated: EstimatedChain | None = _f(_opt(_rec(EstimatedChain)))
    """The undeclared chain estimated (None: none)."""
    clipped: Mapping[str, Mapping[str, float]] = _f()
    """Fraction of samples saturated per run and channel [-] (the model is clipped at the same range)."""
    hum: Mapping[str, Mapping[str, float]] | None = _f(omit=True, default=None)
    """Mains hum found per channel: line frequency [Hz] -> amplitude [channel unit] (None: none; ``mains``)."""
    antialiased: tuple[str, ...] | None = _f(_opt(_seq()), omit=True, default=None)
    """Runs whose model was low-passed below the record's Nyquist frequency before it was sampled, as the DAQ's
    anti-alias filter (declared, or shown by the estimated delays) did the signal (None: none)."""


@dataclass(frozen=True)
class RunResidual:
    """One run's residual of the base and final models."""

    run_id: str
    """The run."""
    controls: Mapping[str, Any]
    """Its controls (frequency_hz, amplitude_n ... [SI]; None where not set)."""
    peak_velocity_m_s: float | None
    """Peak velocity of the base model's response [m/s]."""
    base_nrms: float
    """The calibrated base's nrms [-]."""
    final_nrms: float
    """The final model's nrms [-]."""
    held_out: bool
    """Held out in some fold."""

    @classmethod
    def from_json(cls, d: Mapping) -> RunResidual:
        tail = ("peak_velocity_m_s", "base_nrms", "final_nrms", "held_out")
        return cls(d["run_id"], {k: v for k, v in d.items() if k != "run_id" and k not in tail}, *(d[k] for k in tail))

    def to_json(self) -> dict:
        return {"run_id": self.run_id, **self.controls, "peak_velocity_m_s": self.peak_velocity_m_s,
                "base_nrms": self.base_nrms, "final_nrms": self.final_nrms, "held_out": self.held_out}


@dataclass(frozen=True)
class ResidualStructure(_Record):
    """How the calibrated base model's residual depends on the controls, harmonics and time."""

    by_run: tuple[RunResidual, ...] = _f(_seq(_rec(RunResidual)))
    """Per run."""
    spearman_base_nrms: Mapping[str, float | None] = _f()
    """Spearman correlation of the base's per-run nrms with each control [-]."""
    by_harmonic_hz: Mapping[Any, float] = _f()
    """Base residual per harmonic frequency (50 Hz bins) [-]."""
    by_time_segment: tuple[float, ...] = _f(_seq())
    """Base residual per time segment of the runs [-]."""


@dataclass(frozen=True)
class RigInfo(_Record):
    """The corrected rig handed on (report.json ``rig``)."""

    explained: bool
    """The final model explains the data."""
    selected: Effects | None = _f(_opt(EFFECTS))
    """The selected effect(s)."""
    source: str = _f()
    """The rig's source line."""
    discrepancy: Mapping[str, float] | None = _f()
    """The adopted proposal's coefficients [SI]."""
    verdict: str | None = _f()
    """The verdict."""
    absorbed: Mapping[str, Absorption] = _f(ABSORBED)
    """Parameters that may have absorbed missing physics."""
    model_error: float = _f()
    """The final model's held-out error [-]."""
    noise_floor: float = _f()
    """The noise floor [-]."""
    nrms: float = _f()
    """The final model's held-out nrms [-]."""
    rop_model_error: Mapping[str, Any] | None = _f()
    """The final model's ROP error (``sim.ModelError.to_mapping``)."""
    notes: tuple[str, ...] = _f(_seq())
    """Notes on building the rig."""
    file: str | None = _f(omit=True)
    """The rig file's name (None until the dataset's systems are known)."""


def _errors_from(d: Mapping) -> HeldOutErrors:
    g = d["error_by_group"]
    return HeldOutErrors(default=ModelErrors(d["default_error"], d["default_nrms"], None, g["default"]),
                         base=ModelErrors(d["base_error"], d["base_nrms"], d["base_systematic"], g["base"]),
                         final=ModelErrors(d["final_error"], d["final_nrms"], d["final_systematic"], g["final"]),
                         noise_floor=d["noise_floor"], noise_by_group=g["noise"], n=d["heldout_n"])


@dataclass(frozen=True)
class SystemReport:
    """One system's diagnosis (report.json ``systems[<system>]``)."""

    system: str
    """The model."""
    n_runs: int
    """Runs diagnosed."""
    unreproducible: Mapping[str, float]
    """Runs whose model response is chaotic or multi-stable: nrms of the features' move [-] by run id."""
    data: tuple[str, ...]
    """The kinds of data ('series', 'summary')."""
    split: Split
    """Calibration and held-out runs."""
    verdict: str
    """'selected', 'nothing missing' or 'unexplained' (``pipeline.diagnosis.verdict``)."""
    calibrated: Mapping[str, float]
    """The calibrated base model's parameters [SI]."""
    calibrated_uncertainty: Mapping[str, ParamEstimate]
    """Their estimates with sd and 95 % interval [SI]."""
    noise_sd: Mapping[str, Mapping[str, float]]
    """Measurement noise sd per run and signal [signal's SI unit]."""
    errors: HeldOutErrors
    """Held-out errors of the default, base and final models."""
    base_score: float
    """The base's BIC on the calibration runs [-]."""
    candidates: tuple[Candidate, ...]
    """Every single effect, best BIC first."""
    selected: Effects | None
    """The selected effect(s) (None: none)."""
    leader: Effects | None
    """The best model that improves on the base."""
    runner_up: Effects | None
    """The next one."""
    selected_params: Mapping[str, ParamEstimate] | None
    """The final model's parameters (None: the base is final) [SI]."""
    explained: bool
    """The final model brings the data to the noise."""
    best_partial_candidate: Effects | None
    """Unexplained: the leader, which explains part of the residual."""
    absorbed: Mapping[str, Absorption]
    """Calibrated parameters that may have absorbed missing physics."""
    call: Call
    """How close the call was."""
    indistinguishable: tuple[Effects, ...]
    """Effects the data cannot tell from the leader."""
    second_effect: SecondEffect | None
    """The pair stage's report (None: not tried)."""
    pair_stage: PairStage
    """Whether the pair stage ran and why."""
    discrepancy: Discrepancy | None
    """Discovery's report (None: not run)."""
    proposal_adopted: tuple[str, ...] | None
    """The adopted proposal's terms (None: none)."""
    proposal_as_effect: ProposalAsEffect | None
    """The adopted proposal read as a §6 effect."""
    recording: Recording
    """The DAQ chains and saturated samples."""
    n_simulations: int
    """Simulations run for the system."""
    empirical: EmpiricalReport | None = None
    """The empirical correction's trial (None: not tried, the residual was explained)."""
    residual_structure: ResidualStructure | None = None
    """The base residual's structure (added once the runs are simulated)."""
    notes: tuple[str, ...] = ()
    """Notes on the data and the runs left out."""
    rig: RigInfo | None = None
    """The corrected rig (added once the rig is built)."""
    figures: tuple[str, ...] = ()
    """The PNG files drawn for the system."""

    @property
    def heldout_n(self) -> int:
        return self.errors.n

    @property
    def noise_floor(self) -> float:
        return self.errors.noise_floor

    @classmethod
    def from_json(cls, d: Mapping) -> SystemReport:
        opt = {"second_effect": SecondEffect, "discrepancy": Discrepancy, "proposal_as_effect": ProposalAsEffect,
               "residual_structure": ResidualStructure, "rig": RigInfo, "empirical": EmpiricalReport}
        eff = EFFECTS[0]
        return cls(
            system=d["system"], n_runs=d["n_runs"], unreproducible=d["unreproducible"], data=tuple(d["data"]),
            split=Split.from_json(d["split"]), verdict=d["verdict"], calibrated=d["calibrated"],
            calibrated_uncertainty=PARAMS[0](d["calibrated_uncertainty"]), noise_sd=d["noise_sd"],
            errors=_errors_from(d), base_score=d["base_score"],
            candidates=tuple(Candidate.from_json(c) for c in d["candidates"]),
            selected=_opt(EFFECTS)[0](d["selected"]), leader=_opt(EFFECTS)[0](d["leader"]),
            runner_up=_opt(EFFECTS)[0](d["runner_up"]), selected_params=_opt(PARAMS)[0](d["selected_params"]),
            explained=d["explained"], best_partial_candidate=_opt(EFFECTS)[0](d["best_partial_candidate"]),
            absorbed=ABSORBED[0](d["absorbed"]), call=Call.from_json(d["call"]),
            indistinguishable=tuple(eff(x) for x in d["indistinguishable"]),
            pair_stage=PairStage.from_json(d["pair_stage"]),
            proposal_adopted=None if d["proposal_adopted"] is None else tuple(d["proposal_adopted"]),
            recording=Recording.from_json(d["recording"]), n_simulations=d["n_simulations"],
            notes=tuple(d.get("notes", ())), figures=tuple(d.get("figures", ())),
            **{k: None if d.get(k) is None else c.from_json(d[k]) for k, c in opt.items()})

    def to_json(self) -> dict:
        e, eff, sel = self.errors, _opt(EFFECTS)[1], self.selected

        def rec(x):
            return None if x is None else x.to_json()
        return {
            "system": self.system, "n_runs": self.n_runs, "unreproducible": self.unreproducible,
            "data": list(self.data), "split": self.split.to_json(), "verdict": self.verdict,
            "calibrated": self.calibrated, "calibrated_uncertainty": PARAMS[1](self.calibrated_uncertainty),
            "noise_floor": e.noise_floor, "noise_sd": self.noise_sd,
            "default_error": e.default.error, "base_error": e.base.error, "final_error": e.final.error,
            "default_nrms": e.default.nrms, "base_nrms": e.base.nrms, "final_nrms": e.final.nrms,
            "base_systematic": e.base.systematic, "final_systematic": e.final.systematic, "heldout_n": e.n,
            "error_by_group": {"default": e.default.by_group, "base": e.base.by_group, "final": e.final.by_group,
                               "noise": e.noise_by_group},
            "base_score": self.base_score, "candidates": [c.to_json() for c in self.candidates],
            "selected": eff(sel), "selected_effects": list(sel) if sel else [],
            "leader": eff(self.leader), "runner_up": eff(self.runner_up),
            "selected_params": _opt(PARAMS)[1](self.selected_params), "explained": self.explained,
            "best_partial_candidate": eff(self.best_partial_candidate), "absorbed": ABSORBED[1](self.absorbed),
            "call": self.call.to_json(), "indistinguishable": ["+".join(x) for x in self.indistinguishable],
            "second_effect": rec(self.second_effect), "pair_stage": self.pair_stage.to_json(),
            "discrepancy": rec(self.discrepancy),
            "proposal_adopted": None if self.proposal_adopted is None else list(self.proposal_adopted),
            "proposal_as_effect": rec(self.proposal_as_effect), "recording": self.recording.to_json(),
            "n_simulations": self.n_simulations,
            **({} if self.empirical is None else {"empirical": self.empirical.to_json()}),   # absent: not tried
            "residual_structure": rec(self.residual_structure),
            "notes": list(self.notes), "rig": rec(self.rig), "figures": list(self.figures)}


COMBINED = ("verdict", "calibrated", "noise_floor", "default_error", "base_error", "candidates", "selected",
            "final_error", "default_nrms", "base_nrms", "final_nrms", "base_systematic", "final_systematic", "rig",
            "proposal_adopted")
"""The keys a several-system report.json also gives at its top level, each a mapping system -> value."""

HEADLINE = ("system", "verdict", "selected", "explained", "noise_floor", "default_error", "base_error", "final_error",
            "default_nrms", "base_nrms", "final_nrms", "base_systematic", "final_systematic", "proposal_adopted",
            "wall_time_s")
"""The top-level keys of ``DiagnoseReport.headline`` (then ``rig``)."""


@dataclass(frozen=True)
class DiagnoseReport:
    """A dataset's diagnosis (report.json), always as several systems (one system is a tuple of one)."""

    dataset: str
    """The dataset's path (or 'dataset')."""
    config: Mapping[str, Any]
    """The DiagnoseConfig's settings."""
    systems: tuple[SystemReport, ...]
    """Per system, in the dataset's order."""
    wall_time_s: float | None = None
    """Wall time of the diagnosis [s] (None: not recorded)."""
    cost: Mapping[str, Any] | None = None
    """Where the time went (``pipeline.diagnosis.cost.DiagnosisCost.to_json``; None: not recorded)."""

    @property
    def explained(self) -> bool:
        """Every system explained."""
        return all(s.explained for s in self.systems)

    def system(self, name: str) -> SystemReport:
        """The report of system ``name``."""
        for s in self.systems:
            if s.system == name:
                return s
        raise KeyError(name)

    def to_json(self) -> dict:
        """report.json's content: one system's keys at the top level, or for several the list of systems and
        every ``COMBINED`` key as a mapping system -> value; then ``systems``, the time and the cost."""
        per = [s.to_json() for s in self.systems]
        out: dict = {SCHEMA_KEY: SCHEMA, "dataset": self.dataset, "config": self.config}
        if len(per) == 1:
            out.update(per[0])
        else:
            out["system"] = [p["system"] for p in per]
            out.update({k: {p["system"]: p[k] for p in per} for k in COMBINED})
            out["explained"] = self.explained
        out["systems"] = {p["system"]: p for p in per}
        if self.wall_time_s is not None:
            out["wall_time_s"] = self.wall_time_s
        if self.cost is not None:
            out["cost"] = self.cost
        return out

    def headline(self) -> dict:
        """The headline numbers (``vibro diagnose --metrics``): report.json's top-level keys below, in its layout."""
        j = self.to_json()
        return {**{k: j[k] for k in HEADLINE}, "rig": j.get("rig")}

    @classmethod
    def from_json(cls, d: Mapping, source: str = "report.json") -> DiagnoseReport:
        """The report of report.json's content ``d`` (read from ``source``); a file without ``report_schema`` is
        schema 1; a newer schema is a UserError."""
        schema = d.get(SCHEMA_KEY, 1)
        if schema != SCHEMA:
            from pipeline.core.errors import UserError

            raise UserError(f"{source}: report schema {schema!r} not readable by this version (reads {SCHEMA})")
        try:
            return cls(dataset=d["dataset"], config=d["config"],
                       systems=tuple(SystemReport.from_json(s) for s in d["systems"].values()),
                       wall_time_s=d.get("wall_time_s"), cost=d.get("cost"))
        except (KeyError, TypeError, AttributeError, ValueError) as e:
            from pipeline.core.errors import UserError

            what = f"no '{e.args[0]}'" if isinstance(e, KeyError) else str(e)
            raise UserError(f"{source}: not a diagnosis report this version reads ({what}); diagnose the data again "
                            f"with this version") from None
