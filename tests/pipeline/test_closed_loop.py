"""Closing the loop end to end against a known truth.

A drill rig log is made with `vibro synth` (python API: perturbed rock + a §6 effect the lab model lacks),
diagnosed (`vibro diagnose`'s driver: calibration, candidate effects, corrected rig), and the operating point
recommended on the corrected rig is simulated on the truth.  It must reach >= 98 % of the truth's own best ROP
over the same search space (the lab preset's LAB_SPACE).  Optimiser here: the best point of one grid over
LAB_SPACE (the same grid for the corrected rig, the truth and the uncorrected lab model, so the three are compared
on equal terms); the shortfall of the uncorrected lab recommendation on the truth is printed and checked to be
computed.  Slow: two drill diagnoses (~5 min each on 2 shared cores)."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from vibrobase.statuses import IMPACTING_STATUSES

GRID = {"frequency_hz": np.linspace(100.0, 450.0, 22), "amplitude_n": np.linspace(1800.0, 2700.0, 4),
        "static_force_n": np.linspace(600.0, 1800.0, 4)}
"""sim.models.drill.LAB_SPACE on a 22 x 4 x 4 grid (16.7 Hz, 300 N, 400 N steps)."""


def _best(rig):
    """(point, ROP) of the grid's best progressing point on ``rig`` (status ok or aperiodic only)."""
    import sim

    table = [{k: float(x) for k, x in zip(GRID, v)} for v in itertools.product(*GRID.values())]
    df = sim.simulate_batch(rig.model, [{**rig.overrides(), **p} for p in table], preset=rig.preset)
    rop = np.where(df["status"].isin(IMPACTING_STATUSES), df["rop_m_s"].astype(float).fillna(0.0), 0.0)
    i = int(np.argmax(rop))
    return table[i], float(rop[i])


def _rop(rig, point) -> float:
    r = rig.simulate(**point)
    return float(r.labels["rop_m_s"]) if r.status in IMPACTING_STATUSES else 0.0


@pytest.mark.slow
# The diagnosis runs with the pipeline's settings (params.yaml 'diagnose': n_starts 2, max_nfev 15).  At the drill's
# lighter default effort (max_nfev 10) shaker_coil was left unexplained at seeds 0 and 1 (nrms 186 / 358, cf. the
# drill identification table in README.md) — an open issue of the diagnosis, not of this loop.  shaker_coil: seed 0
# (the seed of measured/drill-rig); suspension_hardening: seed 1 (passed at the default effort too).
@pytest.mark.parametrize("effect, seed", [("shaker_coil", 0), ("suspension_hardening", 1)])
def test_corrected_recommendation_reaches_the_truths_best(tmp_path, effect, seed):
    from pipeline.core.rigfile import read_rig
    from pipeline.datasets.measured import load_dataset, write_dataset
    from pipeline.synthesis.workflow import SynthConfig, resolve_effects, synthesize
    from pipeline.diagnosis.outputs import diagnose_into
    from sim import Rig

    ds, info = synthesize(SynthConfig(system="drill", effects=resolve_effects("drill", {effect: None}), seed=seed))
    write_dataset(ds, tmp_path / "log")
    truth = Rig("drill", "lab").with_values(info["truth"])     # the rig the log was made on
    from pathlib import Path

    from pipeline.cli.diagnose import load_config

    cfg = load_config(str(Path(__file__).resolve().parents[2] / "params.yaml"), {}, None, None)
    rep = diagnose_into(load_dataset(tmp_path / "log"), tmp_path / "diag", cfg, log=lambda s: None).report.systems[0]
    corrected = read_rig(tmp_path / "diag" / "rig.yaml")
    assert rep.selected == (effect,), rep.rig.source
    point_c, _ = _best(corrected)
    point_lab, _ = _best(Rig("drill", "lab"))
    _, truth_best = _best(truth)
    on_truth_c, on_truth_lab = _rop(truth, point_c), _rop(truth, point_lab)
    print(f"\n{effect}: truth best {truth_best * 1e3:.4g} mm/s; corrected recommendation {point_c} -> "
          f"{on_truth_c * 1e3:.4g} mm/s on the truth ({on_truth_c / truth_best:.1%}); uncorrected lab recommendation "
          f"{point_lab} -> {on_truth_lab * 1e3:.4g} mm/s ({on_truth_lab / truth_best:.1%}); shortfall "
          f"{(truth_best - on_truth_lab) * 1e3:.3g} mm/s")
    assert on_truth_c >= 0.98 * truth_best
    assert np.isfinite(on_truth_lab) and 0.0 <= on_truth_lab <= truth_best * (1 + 1e-9)


@pytest.mark.slow
def test_out_of_library_loop_reaches_the_truths_best(tmp_path):
    """Physics the library lacks, end to end: the independent generator's drill rig with a velocity-squared loss on
    the bit (tests/independent, quadratic_damping: no §6 effect has it) → `vibro diagnose` → no effect explains it,
    the discrepancy proposal tool_quadratic_drag is accepted and written into the rig file → the recommendation on
    that corrected rig reaches >= 95 % of the true rig's best ROP (issue target), where the calibrated base model's
    (the rig without the proposal) is printed against it.  The truth is simulated with the kernel's own
    tool_quadratic_drag term: the same force −cq v|v| on M1 as the generator's (tests/sim/test_discrepancy_terms.py
    checks the kernel's term against the independent reference)."""
    import json

    from pipeline.core.rigfile import read_rig
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis.outputs import diagnose_into
    from pipeline.diagnosis.run import DiagnoseConfig
    from sim import Rig
    from tests.independent.generator import LogSpec, generate

    spec = LogSpec("drill", outside="quadratic_damping", noise="rig", seed=0, n_runs=8)
    info = generate(spec, tmp_path / "log", threads=2)
    rep = diagnose_into(load_dataset(tmp_path / "log"), tmp_path / "diag", DiagnoseConfig(n_threads=2),
                        log=lambda s: None).report.system("drill")
    assert rep.verdict == "unexplained" and rep.proposal_adopted == ("tool_quadratic_drag",), \
        json.dumps(rep.discrepancy.to_json(), default=str)[:2000]
    corrected = read_rig(tmp_path / "diag" / "rig.yaml")
    assert set(corrected.discrepancy) == {"tool_quadratic_drag"}
    truth_values = info["truth"]
    cq = truth_values.pop("cq")
    truth = Rig("drill", "lab").with_values({**truth_values, "tool_quadratic_drag": cq})
    uncorrected = Rig("drill", "lab").with_values(rep.calibrated)          # the calibrated base, no proposal
    point_c, _ = _best(corrected)
    point_u, _ = _best(uncorrected)
    _, truth_best = _best(truth)
    on_truth_c, on_truth_u = _rop(truth, point_c), _rop(truth, point_u)
    print(f"\nquadratic drag: truth best {truth_best * 1e3:.4g} mm/s; with the proposal {point_c} -> "
          f"{on_truth_c * 1e3:.4g} mm/s on the truth ({on_truth_c / truth_best:.1%}); calibrated base {point_u} -> "
          f"{on_truth_u * 1e3:.4g} mm/s ({on_truth_u / truth_best:.1%})")
    assert on_truth_c >= 0.95 * truth_best
    assert 0.0 <= on_truth_u <= truth_best * (1 + 1e-9)
