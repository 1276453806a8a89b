"""The heyoka peer of the impact pendulum (bench/peers_heyoka_pendulum.py) against the independent reference.

The work-precision bench scores every peer against tests/reference_solutions.py; this checks, on one point, that
the peer integrates the same model from the same rest state and reads the same labels: at tol 1e-10 its compared
labels lie within 1e-8 (relative) of the reference's DOP853 rtol 1e-10 (whose own accuracy is ~1e-9; measured
agreement ~5e-11).  Skipped where heyoka is not installed (the bench extra: ``make bench`` installs it).
"""
from __future__ import annotations

import pytest

import sim
from bench import peers_heyoka_pendulum as peer
from bench.bench_sim import label_error
from tests.reference_solutions import reference_run

TOL = 1e-8          # relative, on each label the bench compares (peak_force_n, impacts_per_cycle, peak_decel_g)


def _params(**overrides) -> dict:
    return {k: v for k, v in sim.get_model("pendulum").resolve(None, **overrides).items() if k not in ("P", "D")}


def test_pendulum_peer_matches_the_reference():
    pytest.importorskip("heyoka")
    params = _params()                      # gap 0, 3.75 Hz: one impact per cycle (z = 1/1)
    ref = reference_run("pendulum", params, 20, 5, method="DOP853", rtol=1e-10)
    ta, _ = peer.build(1e-10)
    got = peer.run_point(ta, peer.values(params), 20, 5)
    assert got["impacts_per_cycle"] == ref["impacts_per_cycle"] == 1.0
    assert label_error(got, ref, "pendulum") <= TOL
    assert got["energy_per_cycle_j"] == pytest.approx(ref["energy_per_cycle_j"], rel=TOL)


def test_pendulum_peer_refuses_an_effect():
    with pytest.raises(ValueError, match="alpha"):
        peer.values(_params(alpha=1.0))
