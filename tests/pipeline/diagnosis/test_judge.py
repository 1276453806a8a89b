"""The judging stage every model-weighing stage of a diagnosis uses (pipeline/diagnosis/judge.py), on a stand-in
evaluator whose residual is known in closed form: the scheme decides which fits are reported and when the fit on all
runs is paid for, the held-out errors and BIC are the folds' sums, and the verdict is the rule's."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from pipeline.diagnosis.config import DiagnoseConfig
from pipeline.diagnosis.features import Target
from pipeline.diagnosis.fit import FitResult
from pipeline.diagnosis.judge import Fitter, Holdout, LeaveOneRunOut, judge, make_folds, without_runs
from pipeline.diagnosis.verdict import SELECTED


@dataclass
class _Ev:
    """Residual of run i under values {'x': x}: (x - 1) * (i + 1) on 3 features of sd 1 (the truth is x = 1)."""

    targets: list
    profile_runs = frozenset()      # no undeclared DAQ chain profiled

    def held_out(self, sets, idx, chains=None):
        return [([np.full(3, (v.get("x", 0.0) - 1.0) * (i + 1)) for i in idx], [None] * len(idx)) for v in sets]


def _targets(n: int) -> list[Target]:
    return [Target(run_id=f"r{i}", system="drill", kind="summary", controls={"frequency_hz": 100.0 + i},
                   y=np.ones(3), sd=np.ones(3), group=["a"] * 3) for i in range(n)]


def _fit(x: float, chi2: float, k: int) -> FitResult:
    return FitResult(values={"x": x}, sd={"x": 0.0}, ci95={"x": (x, x)}, chi2=chi2, n=6, free=["x"] * k, nfev=1)


def _fitter(calls: list[str]) -> Fitter:
    def on_folds(sets):
        calls.append(f"folds {len(sets)}")
        return [{"base": _fit(2.0, 100.0, 1), "good": _fit(1.0, 2.0, 2)} for _ in sets]

    def on_all():
        calls.append("all")
        return {"base": _fit(1.4, 90.0, 1), "good": _fit(1.0, 1.0, 2)}
    return Fitter(on_folds, on_all)


def test_the_scheme_decides_which_fits_are_reported_and_when_all_runs_are_fitted():
    ev, rule = _Ev(_targets(4)), DiagnoseConfig().rule()
    hold = Holdout((([0, 1, 2], [3]),))
    calls: list[str] = []
    j = judge(ev, hold, _fitter(calls), rule, against="base")
    assert calls == ["folds 1"] and j.fits is j.fold_fits[0] and j.held_out == [3]
    loro = make_folds(_targets(4), DiagnoseConfig())
    assert isinstance(loro, LeaveOneRunOut)
    calls = []
    j = judge(ev, loro, _fitter(calls), rule, against="base")
    assert calls == ["folds 4", "all"] and j.fits["base"].values == {"x": 1.4} and j.held_out == [0, 1, 2, 3]
    calls = []
    j = judge(ev, loro, _fitter(calls), rule, against="base", keep=lambda j: False)
    assert calls == ["folds 4"] and j.fits is None        # declined: the fit on all runs is never paid for


def test_held_out_errors_bic_and_verdict_are_the_folds_sums():
    ev, rule = _Ev(_targets(4)), DiagnoseConfig().rule()
    loro = make_folds(_targets(4), DiagnoseConfig())
    j = judge(ev, loro, _fitter([]), rule, against="base", fixed={"nominal": {"x": 3.0}})
    # base at x = 2 on every held-out run i: residual i + 1 on 3 features
    chi2 = sum(3 * (i + 1) ** 2 for i in range(4))
    assert j.err["base"].chi2 == pytest.approx(chi2) and j.err["base"].n == 12
    assert j.err["nominal"].nrms == pytest.approx(math.sqrt(sum(3 * (2.0 * (i + 1)) ** 2 for i in range(4)) / 12))
    assert "nominal" not in j.stats                        # a fixed model is scored, not judged
    assert j.stats["base"].bic == pytest.approx(4 * (100.0 + math.log(6)))
    assert j.stats["good"].bic == pytest.approx(4 * (2.0 + 2 * math.log(6)))
    assert j.cal_chi2 == {"base": 400.0, "good": 8.0}
    assert j.stats["good"].chi2 == 0.0 and j.verdict.kind == SELECTED and j.verdict.selected == "good"
    against = judge(ev, loro, _fitter([]), rule, against=j.stats["good"], candidates=["base"])
    assert against.verdict.selected is None               # the base does not improve on 'good'


def test_a_chaotic_run_leaves_every_fold_and_the_split_stays():
    """``without_runs``: the run leaves calibration and held-out sets; a fold that held out only it goes; the split of
    the other runs is the one ``make_folds`` chose (a chaotic run dropped from runs.csv would change it)."""
    hold = make_folds(_targets(8), DiagnoseConfig())
    (cal, test), = hold.folds
    out = without_runs(hold, {cal[-1]})
    assert isinstance(out, Holdout) and out.folds == ((cal[:-1], test),) and out.reported_runs == cal[:-1]
    assert without_runs(hold, {test[0]}).folds == ((cal, test[1:]),)
    loro = make_folds(_targets(4), DiagnoseConfig())
    out = without_runs(loro, {2})
    assert isinstance(out, LeaveOneRunOut) and out.folds == (([1, 3], [0]), ([0, 3], [1]), ([0, 1], [3]))
    assert out.reported_runs == [0, 1, 3]
    # nothing to leave out, or leaving it out would leave a fold with one calibration run: the scheme as it was
    assert without_runs(loro, set()) is loro and without_runs(make_folds(_targets(3), DiagnoseConfig()), {0}).folds \
        == make_folds(_targets(3), DiagnoseConfig()).folds
