"""ROP spread of an operating point over the rig's fitted-parameter uncertainty (pipeline.optimise.robustness)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.optimise.robustness import fit_bounds, parameter_samples, rop_spread
from sim import Rig

POINT = {"frequency_hz": 280.0, "amplitude_n": 2250.0, "static_force_n": 1200.0}   # the lab preset's default point
FAST = {"window": 8}


def test_samples_are_lognormal_around_the_fitted_value_and_stay_in_the_fit_bounds():
    rig = Rig("drill", "lab", {"K1": 6e8}, uncertainty={"K1": 0.1 * 6e8, "Pr": 1e9})
    s = parameter_samples(rig, 4000, seed=1)
    k1 = np.array([x["K1"] for x in s])
    # log-normal with sigma = sd / value = 0.1: median = the fitted value, sd of ln = 0.1 (to sampling error)
    assert np.median(k1) == pytest.approx(6e8, rel=0.01)
    assert np.std(np.log(k1)) == pytest.approx(0.1, rel=0.05)
    lo, hi = fit_bounds("drill")["Pr"]                     # an unidentifiable Pr spans its bounds, no further
    pr = np.array([x["Pr"] for x in s])
    assert pr.min() == lo and pr.max() == hi
    assert parameter_samples(rig, 5, seed=3) == parameter_samples(rig, 5, seed=3)


def test_an_adopted_discrepancy_term_is_sampled_within_its_bounds():
    """A rig carrying a proposal (``discrepancy:``) with an uncertain coefficient: the samples spread it and stay
    inside the term's fit bounds."""
    rig = Rig("drill", "lab", uncertainty={"tool_quadratic_drag": 3e6}, discrepancy={"tool_quadratic_drag": 8e5})
    s = np.array([x["tool_quadratic_drag"] for x in parameter_samples(rig, 500, seed=0)])
    lo, hi = fit_bounds("drill")["tool_quadratic_drag"]
    assert s.min() == lo and s.max() == hi and np.median(s) == pytest.approx(8e5, rel=0.3)


def test_no_uncertainty_gives_no_spread():
    r = rop_spread(Rig("drill", "lab"), POINT, n_samples=3, seed=0, settings=FAST)
    assert r.sampled == () and r.fraction_progressing == 1.0
    assert r.nominal_rop_m_s > 0 and r.p5_rop_m_s == r.median_rop_m_s == r.p95_rop_m_s == r.nominal_rop_m_s


def test_uncertain_rock_threshold_spreads_the_rop():
    """Pr known to +-30 %: ROP falls steeply with the rock's threshold, so the 5-95 % band must be wide
    and contain the nominal ROP."""
    rig = Rig("drill", "lab", uncertainty={"Pr": 0.3 * 3000.0})
    r = rop_spread(rig, POINT, n_samples=24, seed=0, settings=FAST)
    assert r.sampled == ("Pr",) and r.n_samples == 24 and sum(r.statuses.values()) == 24
    assert r.p5_rop_m_s < r.nominal_rop_m_s < r.p95_rop_m_s
    assert r.p95_rop_m_s - r.p5_rop_m_s > 0.2 * r.nominal_rop_m_s
    assert 0.0 <= r.fraction_progressing <= 1.0 and math.isfinite(r.median_rop_m_s)
