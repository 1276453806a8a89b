"""The last resort of a diagnosis (pipeline.diagnosis.empirical): an empirical ROP correction is adopted where it
predicts held-out runs and only there, and it comes back from the model's residuals unchanged."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pipeline.diagnosis.empirical import RopRuns, rop_runs, try_correction

FREQ = np.linspace(150.0, 430.0, 15)
GRID = [(f, fs) for fs in (900.0, 1500.0) for f in FREQ]       # 30 runs, as a 16-run log's two force levels


def runs(discrepancy) -> RopRuns:
    """Runs whose measured ROP is the model's times 1 + ``discrepancy(f, Fs)``."""
    ctl = [{"frequency_hz": f, "static_force_n": fs, "amplitude_n": 2250.0} for f, fs in GRID]
    model = np.array([1e-3 * (1 + f / 430.0) * fs / 1500.0 for f, fs in GRID])
    meas = model * (1 + np.array([discrepancy(f, fs) for f, fs in GRID]))
    return RopRuns(list(range(len(GRID))), ctl, meas, model)


def holdout(n: int, every: int = 4):
    test = [i for i in range(n) if i % every == 1]
    return [([i for i in range(n) if i not in test], test)]


def test_a_smooth_discrepancy_is_learnt_and_adopted():
    """A 10 % discrepancy that varies smoothly with frequency and force: the held-out ROP error falls by far more
    than half, the correction is refitted on every run and goes over the two varied controls."""
    st = try_correction(runs(lambda f, fs: 0.1 * np.sin(f / 60.0) + 0.05 * (fs - 1200.0) / 300.0), holdout(30),
                        seed=0, min_gain=0.2)
    assert st.adopted and st.halved, st.reason
    assert st.after < 0.2 * st.before
    assert st.correction.inputs == ("frequency_hz", "static_force_n") and len(st.correction.points) == 30


def test_noise_is_not_learnt():
    """A discrepancy of independent ±5 % draws predicts nothing about a held-out run: not adopted, with the reason."""
    rng = np.random.default_rng(3)
    draws = {g: 0.05 * rng.standard_normal() for g in GRID}
    st = try_correction(runs(lambda f, fs: draws[(f, fs)]), holdout(30), seed=0, min_gain=0.2)
    assert not st.adopted and st.correction is None
    assert "less than the 20 % cut" in st.reason and st.after > 0.8 * st.before


@pytest.mark.parametrize("what, reason", [
    ("no rop", "no run measured a ROP"),
    ("one point", "the runs measured ROP at one operating point"),
    ("few runs", "fewer than 4 calibration runs"),
])
def test_where_it_cannot_be_tried_it_says_why(what, reason):
    r = runs(lambda f, fs: 0.1)
    if what == "no rop":
        r = RopRuns(r.idx, r.controls, np.zeros(len(GRID)), r.model)
    elif what == "one point":
        r = RopRuns(r.idx, [r.controls[0]] * len(GRID), r.measured, r.model)
    else:
        r = RopRuns(r.idx[:4], r.controls[:4], r.measured[:4], r.model[:4])
    st = try_correction(r, holdout(len(r.idx)), seed=0, min_gain=0.2)
    assert not st.adopted and reason in st.reason and st.before is None


def test_the_model_rop_is_read_back_from_the_residual():
    """The model's ROP is the measured one plus the noise-normalised residual times its sd; runs without a ROP
    feature (an indenter) are left out."""
    tgs = [SimpleNamespace(names=["accel_m_s2:h1:re", "rop_m_s"], y=np.array([1.0, 2e-3]), sd=np.array([0.1, 1e-5]),
                           controls={"frequency_hz": 200.0}),
           SimpleNamespace(names=["accel_m_s2:h1:re"], y=np.array([1.0]), sd=np.array([0.1]),
                           controls={"frequency_hz": 300.0})]
    r = rop_runs(tgs, [np.array([0.5, -3.0]), np.array([0.2])])
    assert r.idx == [0] and r.measured.tolist() == [2e-3]
    assert r.model[0] == pytest.approx(2e-3 - 3.0 * 1e-5)


def test_mlflow_gets_the_trial_from_the_report():
    """The numbers MLflow logs are the report's fields (a diagnosis of rate-dependent strength on the drill, whose
    correction was adopted: tests/pipeline/diagnosis/data/report_empirical.json)."""
    import json
    from pathlib import Path

    from pipeline.cli.diagnose import _flat_metrics
    from pipeline.diagnosis.report_types import DiagnoseReport

    path = Path(__file__).parent / "data" / "report_empirical.json"
    rep = DiagnoseReport.from_json(json.loads(path.read_text()), str(path))
    emp = rep.systems[0].empirical
    m = _flat_metrics(rep)
    assert emp.adopted and emp.halved and m["drill.empirical_adopted"] == 1.0
    assert m["drill.empirical_heldout_rop_error_before"] == emp.heldout_rop_error_before
    assert m["drill.empirical_heldout_rop_error_after"] == emp.heldout_rop_error_after < emp.heldout_rop_error_before
