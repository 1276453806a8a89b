"""The chance scatter of a measured conformal coverage (bench/coverage_noise.py) against a simulation of it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bench.coverage_noise import chance_sd, in_band_probability


@pytest.mark.parametrize("n_cal, m_test", [(256, 1024), (1024, 512)])
def test_chance_sd_is_the_scatter_of_split_conformal_coverage(n_cal, m_test):
    """Split conformal on exchangeable residuals, repeated: the measured coverage's sd over repetitions is the formula's
    (Beta over calibration sets + binomial over hidden points), within the 8 % a 3000-repeat estimate allows."""
    rng = np.random.default_rng(0)
    k = math.ceil((n_cal + 1) * 0.9)
    cov = []
    for _ in range(3000):
        q = np.sort(np.abs(rng.standard_normal(n_cal)))[k - 1]
        cov.append(np.mean(np.abs(rng.standard_normal(m_test)) <= q))
    assert np.std(cov) == pytest.approx(chance_sd(n_cal, m_test), rel=0.08)
    assert abs(np.mean(cov) - 0.9) < 0.003


def test_in_band_probability_is_the_normal_mass_within_two_points():
    assert in_band_probability(0.02) == pytest.approx(0.6827, abs=1e-4)    # ±1 sd
    assert in_band_probability(0.01) == pytest.approx(0.9545, abs=1e-4)    # ±2 sd
