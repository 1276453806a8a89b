"""ROP spread of an operating point over the rig's fitted-parameter uncertainty, and combined with the rig's model
error (pipeline.optimise.robustness)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.core.units import spread_words
from pipeline.optimise.robustness import Z_90, combined_half_widths, fit_bounds, parameter_samples, rop_spread
from sim import ModelError, Rig

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


def test_half_widths_combine_in_quadrature():
    a, b, c = combined_half_widths(3.0e-3, 3.2e-3, 3.1e-3, 0.05)
    assert a == pytest.approx(1e-4) and b == pytest.approx(Z_90 * 0.05 * 3.1e-3) and c == pytest.approx(math.hypot(a, b))
    assert combined_half_widths(3.0e-3, 3.2e-3, 3.1e-3, None) == (pytest.approx(1e-4), None, None)
    assert combined_half_widths(3.0e-3, 3.2e-3, 3.1e-3, 0.0)[2] == pytest.approx(1e-4)     # a measured zero is zero


def test_a_rig_with_a_model_error_widens_the_spread_by_the_stated_combination():
    """Pr known to +-10 % and a held-out ROP error of 6 %: combined = sqrt(a² + (Z_90 · 0.06 · ROP)²) >= a."""
    rig = Rig("drill", "lab", uncertainty={"Pr": 0.1 * 3000.0}, model_error=ModelError(0.06, 0.02, "test"))
    r = rop_spread(rig, POINT, n_samples=8, seed=0, settings=FAST)
    a = 0.5 * (r.p95_rop_m_s - r.p5_rop_m_s)
    b = Z_90 * 0.06 * r.nominal_rop_m_s
    assert r.parameter_half_width_m_s == pytest.approx(a, rel=1e-12) and a > 0
    assert r.model_error_rel == 0.06 and r.model_error_half_width_m_s == pytest.approx(b, rel=1e-12)
    assert r.combined_half_width_m_s == pytest.approx(math.hypot(a, b), rel=1e-12)
    assert r.combined_half_width_m_s >= r.parameter_half_width_m_s and r.model_error_basis == "test"
    d = r.to_dict()
    words = spread_words(d)
    assert f"parameter spread ±{a * 1e3:.3g}, model error ±{b * 1e3:.3g} (held-out rms 6 %), combined ±" in words
    assert f"combined ±{math.hypot(a, b) * 1e3:.3g} mm/s" in words


def test_a_rig_without_a_model_error_says_it_is_not_given():
    r = rop_spread(Rig("drill", "lab"), POINT, n_samples=2, seed=0, settings=FAST)
    assert r.model_error_rel is None and r.model_error_half_width_m_s is None and r.combined_half_width_m_s is None
    d = r.to_dict()
    assert d["model_error_rel"] is None and d["combined_half_width_m_s"] is None      # unknown, not 0
    assert "model error not given" in spread_words(d) and "combined ±" not in spread_words(d)
