"""Verdicts on rig logs this project did not make: the independent generator (tests/independent: scipy reference,
samples at the DAQ's instants, a rig's noise) writes the log, ``vibro diagnose`` judges it at its defaults.

Every kind of verdict runs by default on short drill logs: one effect here, a log from outside the library with the
pair stage and discovery switched off, and a control through an undeclared DAQ chain (test_daq_chain.py).  The slow subset runs the outside log at the defaults (pairs and
proposals), two effects at once, the pendulum's and the other systems' short logs, and every kind of verdict on every
system at both noise models of the identification matrix (``python -m bench.identification`` runs the whole
matrix)."""
from __future__ import annotations

import json

import pytest

from tests.independent.generator import LogSpec, generate
from tests.independent.rigs import RIGS

PARAM_TOL = 0.05      # issue target: parameters of a selected effect within 5 % of the truth


def _diagnose(tmp_path, spec: LogSpec, *args) -> tuple[dict, dict]:
    from pipeline.cli import main

    data = tmp_path / spec.name
    truth = generate(spec, data, threads=2)
    out = tmp_path / (spec.name + "-diag")
    assert main(["diagnose", str(data), "--out", str(out), "--quiet", "--no-mlflow", *args]) == 0
    return json.loads((out / "report.json").read_text()), truth


def _check(rep: dict, truth: dict, spec: LogSpec) -> None:
    if spec.effect:
        assert rep["verdict"] == "selected" and rep["selected"] == spec.effect, rep["call"]["text"]
        fitted = next(c for c in rep["candidates"] if c["effect"] == spec.effect)["params"]
        for k, v in fitted.items():
            assert v == pytest.approx(truth["truth"][k], rel=PARAM_TOL), (k, v)
    elif spec.outside:
        assert rep["verdict"] == "unexplained" and rep["selected"] is None, rep["call"]["text"]
        assert "UNEXPLAINED" in rep["rig"]["source"]
        adopted = rep["proposal_adopted"]       # a discrepancy proposal the held-out runs accepted, or none
        assert (rep["rig"]["discrepancy"] is not None) == bool(adopted)
        assert ("adopted the discrepancy proposal" if adopted else "absorbed") in rep["rig"]["source"]
        assert rep["discrepancy"]["proposals"] and len(rep["discrepancy"]["proposals"]) <= 3
    else:
        assert rep["verdict"] == "nothing missing" and rep["selected"] is None, rep["call"]["text"]
        assert rep["discrepancy"] is None and rep["proposal_adopted"] is None    # no proposal on a control
    if not spec.outside and not spec.effect:    # a control: the calibrated rig is the true rig
        for k in truth["calibratable"]:
            assert rep["calibrated"][k] == pytest.approx(truth["truth"][k], rel=PARAM_TOL), (k, rep["calibrated"][k])
    # with an effect, the target is the effect's parameters (above); the base parameters trade off against
    # them (pendulum behind a 100 Hz low-pass: fc +0.6 % with ki +6 %) and are reported in the matrix, not asserted
    assert rep["call"]["text"] and rep["heldout_n"] > 0
    _check_empirical(rep)


def _check_empirical(rep: dict) -> None:
    """The last resort is tried exactly where nothing explained the residual; adopted only where it cut the held-out
    ROP error by the default 20 %, and then carried in the rig file, named as what it is."""
    emp = rep.get("empirical")
    if rep["explained"] or rep["proposal_adopted"]:
        assert emp is None and "ROP corrected by an empirical" not in rep["rig"]["source"]
        return
    assert emp is not None and emp["label"] == "empirical correction, physics unknown"
    before, after = emp["heldout_rop_error_before"], emp["heldout_rop_error_after"]
    assert emp["adopted"] == (before is not None and after <= 0.8 * before), emp
    assert emp["adopted"] == ("ROP corrected by an empirical correction, physics unknown" in rep["rig"]["source"])


# by default the drill with one effect (about 50 s of CPU, docs/diagnose.md's cost table); a drill control is judged
# by default through an undeclared DAQ chain (test_daq_chain.py); the lab-grade control, the pendulum's log (its
# chaotic run) and the indenters' and the RIMD's short logs cost 1-6 times that and run with the slow subset
FAST = [LogSpec("drill", effect="shaker_coil", noise="rig", seed=0, n_runs=8)]
OUTSIDE = LogSpec("drill", outside="quadratic_damping", noise="rig", seed=1, n_runs=8)
SLOW_SHORT = [LogSpec("drill", noise="rig", seed=1, n_runs=8), OUTSIDE,
              LogSpec("pendulum", effect="sensor_lowpass", noise="white2", seed=0, n_runs=8),
              LogSpec("indenter-metal", noise="white2", seed=1, n_runs=8),
              LogSpec("indenter-sandstone", effect="tip_blunting", noise="rig", seed=0, n_runs=8),
              LogSpec("rimd", outside="quadratic_damping", noise="rig", seed=1, n_runs=8)]


@pytest.mark.parametrize("spec", [*FAST, *(pytest.param(s, marks=pytest.mark.slow) for s in SLOW_SHORT)],
                         ids=lambda s: s.name)
def test_verdict_on_an_independent_log(tmp_path, spec):
    rep, truth = _diagnose(tmp_path, spec)
    _check(rep, truth, spec)
    if spec.effect:     # one effect explains the log: the pair stage (on by default) costs it nothing, and says so
        assert not rep["pair_stage"]["tried"] and rep["second_effect"] is None, rep["pair_stage"]
        assert f"{spec.effect} alone leaves held-out nrms" in rep["pair_stage"]["reason"]
    # the pendulum's 7.25 Hz run at gap 1 mm is chaotic in the model (two tolerances give different orbits, see
    # tests/independent/rigs.py): the report names it, and no other run of any log
    chaotic = {"pendu-07-7.25hz"} if spec.system == "pendulum" else set()
    assert set(rep["unreproducible"]) == chaotic
    assert all(any(r in n and "left out of the fits" in n for n in rep["notes"]) for r in chaotic)
    used = {r for fold in rep["split"]["folds"] for r in (*fold["calibration"], *fold["held_out"])}
    assert not used & chaotic and len(used) == rep["n_runs"] - len(chaotic)     # the split of the others is kept


def test_a_log_from_outside_the_library_is_unexplained_by_every_single_effect(tmp_path):
    """Quadratic damping (outside MODELS.md §6) on the drill: every §6 effect is fitted and none is forced onto the
    log.  The pair stage and discovery are off here (three quarters of the diagnosis's cost on this log); the
    same log at the defaults, pairs and proposals included, is in the slow subset."""
    rep, _ = _diagnose(tmp_path, OUTSIDE, "--setting", "max_effects=1", "--setting", "max_proposals=0")
    assert rep["verdict"] == "unexplained" and rep["selected"] is None, rep["call"]["text"]
    assert "UNEXPLAINED" in rep["rig"]["source"] and rep["rig"]["discrepancy"] is None
    assert {c["effect"] for c in rep["candidates"]} == set(RIGS["drill"].effects)
    assert not any(c["adequate"] for c in rep["candidates"]) and not rep["pair_stage"]["tried"]
    assert rep["discrepancy"] is None and rep["proposal_adopted"] is None
    _check_empirical(rep)      # quadratic damping on the drill: tried on the held-out runs' ROP, never called physics
    assert rep["empirical"]["heldout_rop_error_before"] > 0 and rep["empirical"]["heldout_runs"] == 2


def _slow_cases() -> list[LogSpec]:
    from tests.independent.kinds import KINDS_SYSTEMS

    out = []
    for system, rig in RIGS.items():
        eff = sorted(rig.effects)
        outside = sorted(set(rig.outside) - set(KINDS_SYSTEMS))   # the held-out kinds are the benches'
        for k, noise in enumerate(("white2", "rig")):
            out += [LogSpec(system, noise=noise, seed=k),
                    LogSpec(system, effect=eff[k % len(eff)], noise=noise, seed=k),
                    LogSpec(system, outside=outside[k % len(outside)], noise=noise, seed=k)]
    return out


@pytest.mark.slow
@pytest.mark.parametrize("spec", _slow_cases(), ids=lambda s: s.name)
def test_verdict_subset_of_the_matrix(tmp_path, spec):
    rep, truth = _diagnose(tmp_path, spec)
    _check(rep, truth, spec)


@pytest.mark.slow
def test_two_effects_at_once_are_both_found(tmp_path):
    """Shaker coil and guide friction together on the independent drill rig: the coil alone improves on the base but
    leaves the held-out residual far above the noise (nrms ~14); with ``max_effects: 2`` the greedy second step
    adds guide friction, the pair is selected, both effects' parameters come out near the truth and the rig file
    carries both."""
    import yaml

    spec = LogSpec("drill", effect="shaker_coil", overrides={"mu": 50.0}, noise="rig", seed=0, n_runs=8)
    rep, truth = _diagnose(tmp_path, spec, "--effects", "shaker_coil", "guide_friction")
    assert rep["call"]["text"].startswith("one effect: unexplained"), rep["call"]["text"]
    assert rep["pair_stage"]["tried"] and "shaker_coil improves on the base" in rep["pair_stage"]["reason"]
    assert rep["verdict"] == "selected" and rep["selected_effects"] == ["shaker_coil", "guide_friction"]
    pair = rep["second_effect"]["candidates"][0]
    assert pair["name"] == rep["selected"] and pair["adequate"] and pair["improves"]
    for k in ("tau", "beta", "mu"):
        assert pair["params"][k] == pytest.approx(truth["truth"][k], rel=0.1), (k, pair["params"][k])
    rig = yaml.safe_load((tmp_path / (spec.name + "-diag") / "rig.yaml").read_text())
    assert set(rig["effects"]) == {"shaker_coil", "guide_friction"} and set(rig["effects"]["guide_friction"]) == {"mu"}


@pytest.mark.slow
def test_a_coil_and_guide_friction_are_both_named_at_the_defaults(tmp_path):
    """The blind 16-run drill log with a shaker coil and guide friction, every effect a candidate, nothing set: the
    coil alone leaves the held-out residual far above the noise (under the old rule 'explained' by a systematic
    error under 0.5 %), so the pair stage runs by default and names both effects near the truth."""
    spec = LogSpec("drill", effect="shaker_coil", overrides={"mu": 50.0}, noise="rig", seed=0)
    rep, truth = _diagnose(tmp_path, spec)
    assert rep["pair_stage"]["tried"] and rep["second_effect"]["first"] == "shaker_coil", rep["pair_stage"]
    assert rep["verdict"] == "selected" and rep["selected_effects"] == ["shaker_coil", "guide_friction"], rep["call"]
    pair = rep["second_effect"]["candidates"][0]
    for k in ("tau", "beta", "mu"):
        assert pair["params"][k] == pytest.approx(truth["truth"][k], rel=0.1), (k, pair["params"][k])


@pytest.mark.slow
def test_a_contact_rate_product_proposal_is_refitted_and_named_as_rate_stiffening(tmp_path):
    """The independent pendulum log with rate stiffening α = 5 s/m: an accepted contact_rate_product proposal (c δ₊ δ̇
    with c = ki α, at the log's calibration) is rate stiffening in another form.  Refitted from α = c / ki and judged
    on the held-out runs, it is named rate_stiffening with α near the truth and the residual at the noise."""
    from pipeline.core.executors import InlineExecutor
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis import discovery as D
    from pipeline.diagnosis.fit import FitResult
    from pipeline.diagnosis.model import Evaluator, candidates
    from pipeline.diagnosis.run import DiagnoseConfig, _as_effect, build_targets, make_folds
    from pipeline.diagnosis.verdict import ModelStats

    spec = LogSpec("pendulum", effect="rate_stiffening", overrides={"alpha": 5.0}, noise="white2", seed=0, n_runs=8)
    truth = generate(spec, tmp_path / spec.name, threads=2)["truth"]
    cfg = DiagnoseConfig(max_nfev=6, refine_nfev=4, grid=2, profile_nfev=0, n_threads=2)
    targets = build_targets(load_dataset(tmp_path / spec.name), cfg)["pendulum"]
    ev = Evaluator("pendulum", targets, dict(cfg.sim_settings), cfg.fs_sim_hz, cfg.n_threads)
    scheme = make_folds(targets, cfg)
    name = D.proposal_name(("contact_rate_product",))
    vals = {**{k: truth[k] for k in ("ki", "ci", "zeta")}, "contact_rate_product": truth["ki"] * truth["alpha"]}
    fr = FitResult(values=vals, sd={k: 0.0 for k in vals}, ci95={k: (v, v) for k, v in vals.items()}, chi2=0.0, n=1,
                   free=list(vals), nfev=0)
    found = D.Discovery(screening=D.Screening([], [], {}, {}, []), fits={name: fr}, err={}, stats={}, accepted=name,
                        leader=name, checks={})
    own = {"rate_stiffening": ModelStats("rate_stiffening", float("inf"), 0.0, 1, None)}
    named = _as_effect(ev, cfg, scheme, found, candidates("pendulum"), own, InlineExecutor(), lambda s: None)
    assert named is not None and named.effect == "rate_stiffening"
    assert named.start["alpha"] == pytest.approx(5.0, rel=1e-9)
    assert named.params["alpha"] == pytest.approx(5.0, rel=0.1), named.text
    assert named.err.nrms <= cfg.explained_nrms, named.text


@pytest.mark.slow
def test_a_leader_right_only_under_its_own_chain_is_selected(tmp_path):
    """Guide friction on the independent indenter-metal rig (records from rest, undeclared chain): at the chain
    located at the base's fit the leader leaves held-out nrms 6.35, so the pair stage fits it again under the chain
    located at its own fit, where it reaches nrms 0.92 and no pair beats it: selected, mu within PARAM_TOL (it was
    reported unexplained with the adequate fit in its table)."""
    spec = LogSpec("indenter-metal", effect="guide_friction", noise="rig", seed=0, n_runs=8)
    rep, truth = _diagnose(tmp_path, spec)
    assert rep["pair_stage"]["tried"], rep["pair_stage"]
    _check(rep, truth, spec)
