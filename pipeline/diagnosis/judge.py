"""One judging stage, used by every stage of a diagnosis that weighs models (the effects, the pairs, the proposals,
a proposal read as an effect): fit the models on every fold's calibration runs, score them on the fold's held-out
runs, call the verdict against a reference model, and fit the parameters the split reports.

The fold scheme is an object, not a name: ``Holdout`` (one split; its calibration fits are the reported ones) or
``LeaveOneRunOut`` (a fold per run; the reported parameters come from a fit on all runs, which is also where the
effects stage starts every fold).  ``make_folds`` picks one from the number of runs.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, ClassVar, Protocol

from pipeline.core.errors import UserError
from pipeline.diagnosis.heldout import HeldOut, fold_errors
from pipeline.diagnosis.verdict import ModelStats, Verdict, VerdictRule, decide

if TYPE_CHECKING:
    from pipeline.diagnosis.config import DiagnoseConfig
    from pipeline.diagnosis.features import Target
    from pipeline.diagnosis.fit import FitResult
    from pipeline.diagnosis.model import Evaluator

Fits = dict[str, "FitResult"]
"""Fitted models by name on one set of runs."""
Fold = tuple[list[int], list[int]]
"""(calibration runs, held-out runs) as indices into the system's targets."""


class FoldScheme(Protocol):
    """How a system's runs are split, and which fits its diagnosis reports."""

    name: ClassVar[str]
    folds: tuple[Fold, ...]

    @property
    def reported_runs(self) -> list[int]:
        """The runs the reported parameters are fitted on."""

    def warm(self, fit_all: Callable[[], Fits]) -> Fits | None:
        """The fits every fold starts from (None: each fold draws its own starts)."""

    def reported(self, fold_fits: list[Fits], fit_all: Callable[[], Fits]) -> Fits:
        """The reported fits, given the folds' fits and a fit on ``reported_runs`` (called only where needed)."""


@dataclass(frozen=True)
class Holdout:
    """One split: every ``holdout_every``-th run held out; the calibration fits are the reported ones."""

    name: ClassVar[str] = "holdout"
    folds: tuple[Fold, ...]

    @property
    def reported_runs(self) -> list[int]:
        return self.folds[0][0]

    def warm(self, fit_all: Callable[[], Fits]) -> Fits | None:
        return None

    def reported(self, fold_fits: list[Fits], fit_all: Callable[[], Fits]) -> Fits:
        return fold_fits[0]


@dataclass(frozen=True)
class LeaveOneRunOut:
    """A fold per run; the reported parameters are a fit on all runs, where every fold of the effects stage starts."""

    name: ClassVar[str] = "leave-one-run-out"
    folds: tuple[Fold, ...]

    @property
    def reported_runs(self) -> list[int]:
        return sorted({i for cal, test in self.folds for i in (*cal, *test)})

    def warm(self, fit_all: Callable[[], Fits]) -> Fits | None:
        return fit_all()

    def reported(self, fold_fits: list[Fits], fit_all: Callable[[], Fits]) -> Fits:
        return fit_all()


def make_folds(targets: list[Target], cfg: DiagnoseConfig) -> FoldScheme:
    """Deterministic split.  >= min_runs_holdout runs: ``Holdout``, every holdout_every-th run of the
    (static force, gap, amplitude, frequency)-sorted list held out (offset 1, so both ends stay in calibration), each
    moved on to the next run of its static force and gap whose forcing frequency is not held out yet where one is
    (``_held_out``);
    fewer: ``LeaveOneRunOut``."""
    n = len(targets)
    c = [targets[i].controls for i in range(n)]
    order = sorted(range(n), key=lambda i: (c[i].get("static_force_n", 0.0), c[i].get("gap_m", 0.0),
                                            c[i].get("amplitude_n", c[i].get("amplitude_m", 0.0)),
                                            c[i]["frequency_hz"], targets[i].run_id))
    if n >= max(cfg.min_runs_holdout, 3):
        test = _held_out(order, [c[i] for i in order], cfg.holdout_every)
        cal = sorted(set(range(n)) - set(test))
        return Holdout(((cal, test),))
    if n < 2:
        raise UserError(f"system '{targets[0].system}': only {n} run; need at least 2 to hold one out")
    return LeaveOneRunOut(tuple(([j for j in range(n) if j != i], [i]) for i in range(n)))


def _held_out(order: list[int], controls: list[dict], every: int) -> list[int]:
    """The held-out runs of the sorted ``order`` (their ``controls``): every ``every``-th from offset 1; a pick whose
    forcing frequency is already held out moves to the next run of the same static force and gap whose frequency
    is not, where there is one.  Two levels run at the same frequencies (a pendulum's two gaps) would otherwise both
    be held out at one frequency, and the calibration would not see what happens there."""
    def level(k: int) -> tuple:
        return controls[k].get("static_force_n", 0.0), controls[k].get("gap_m", 0.0)

    picked: list[int] = []
    for j in range(1, len(order), every):
        free = [k for k in range(j, len(order)) if level(k) == level(j) and k not in picked
                and all(controls[k]["frequency_hz"] != controls[p]["frequency_hz"] for p in picked)]
        picked.append(free[0] if free else j)
    return sorted(order[k] for k in picked)


def without_runs(scheme: FoldScheme, runs: set[int]) -> FoldScheme:
    """``scheme`` with ``runs`` left out of every fold's calibration and held-out runs (a fold that held out only
    them is dropped), the split itself unchanged; ``scheme`` as it is when that would leave a fold with fewer than
    two calibration runs or no fold at all."""
    folds = tuple(([i for i in cal if i not in runs], [i for i in test if i not in runs])
                  for cal, test in scheme.folds)
    folds = tuple((cal, test) for cal, test in folds if test)
    if not runs or not folds or any(len(cal) < 2 for cal, _ in folds):
        return scheme
    return replace(scheme, folds=folds)


@dataclass(frozen=True)
class Fitter:
    """How a stage fits its models: ``on_folds(calibration sets)`` -> fits per set, ``on_all()`` -> the fits on the
    scheme's ``reported_runs`` (asked only by a scheme that reports them)."""

    on_folds: Callable[[list[list[int]]], list[Fits]]
    on_all: Callable[[], Fits]

    @classmethod
    def from_starts(cls, fit: Callable[[list[list[int]], list[FitResult]], list[Fits]], scheme: FoldScheme,
                    fold_starts: list[FitResult], reported_start: FitResult) -> Fitter:
        """A stage that builds on an earlier one: ``fit(run sets, start fits)`` on every fold from that fold's entry
        of ``fold_starts``, and on the scheme's reported runs from ``reported_start`` (the earlier reported fit)."""
        return cls(lambda sets: fit(sets, fold_starts), lambda: fit([scheme.reported_runs], [reported_start])[0])


@dataclass(frozen=True)
class Judged:
    """A stage's outcome.  ``fold_fits``: per fold, each model fitted on its calibration runs; ``fits``: the reported
    fits (None where ``keep`` declined them); ``err``: held-out errors per model (``heldout.fold_errors``, fixed
    models too); ``stats``: ``ModelStats`` of the fitted models; ``cal_chi2``: calibration χ² summed over the folds;
    ``verdict``: against the reference (None without one); ``held_out``: the held-out runs, fold after fold."""

    fold_fits: list[Fits]
    fits: Fits | None
    err: dict[str, HeldOut]
    stats: dict[str, ModelStats]
    cal_chi2: dict[str, float]
    verdict: Verdict | None
    held_out: list[int]


def judge(ev: Evaluator, scheme: FoldScheme, fitter: Fitter, rule: VerdictRule,
          against: ModelStats | str | None = None, candidates: list[str] | None = None,
          fixed: dict[str, dict] | None = None, keep: Callable[[Judged], bool] | None = None) -> Judged:
    """Fit (``fitter``) on every fold of ``scheme``, score every fitted model and the ``fixed`` parameter sets (name ->
    values: e.g. the rig's nominal model) on the held-out runs, and decide ``candidates`` (default: every fitted
    model but a reference named by ``against``) against ``against`` (its stats, or the name of a model judged here).
    The reported fits are fitted last, and only when ``keep`` (given the judged stage) says they are wanted."""
    fold_fits = fitter.on_folds([cal for cal, _ in scheme.folds])
    names = list(fold_fits[0])
    err, stats, held_out = fold_errors(ev, scheme.folds, fold_fits, names, fixed or {})
    cal_chi2 = {m: sum(f[m].chi2 for f in fold_fits) for m in names}
    verdict = None
    if against is not None:
        ref = stats[against] if isinstance(against, str) else against
        cands = candidates if candidates is not None else [m for m in names if m != against]
        verdict = decide(ref, [stats[m] for m in cands], rule)
    out = Judged(fold_fits, None, err, stats, cal_chi2, verdict, held_out)
    if keep is not None and not keep(out):
        return out
    return replace(out, fits=scheme.reported(fold_fits, fitter.on_all))
