"""The DOPRI5 (Dormand-Prince 5(4)) tableau in sim/integrator.py satisfies its defining identities,
as scipy's test_coefficient_properties and diffrax's ButcherTableau checks do (Hairer, Nørsett & Wanner,
Solving ODEs I, §II.5, Table 5.2)."""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from sim import integrator as I

A, B, C, E = I.dopri5_tableau()                   # the constants as arrays; B = A's last row (FSAL)


def test_row_sums_equal_nodes():
    np.testing.assert_allclose(A.sum(axis=1), C, rtol=0, atol=1e-15)


def test_fifth_order_conditions():
    """b·c^(k-1) = 1/k for k = 1..5 and the two sixth-tree conditions of order 4 (b·A·c = 1/6, b·A·c² = 1/12)."""
    for k in range(1, 6):
        assert B @ C ** (k - 1) == pytest.approx(1.0 / k, abs=1e-14)
    assert B @ A @ C == pytest.approx(1.0 / 6.0, abs=1e-14)
    assert B @ A @ C ** 2 == pytest.approx(1.0 / 12.0, abs=1e-14)
    assert B @ (C * (A @ C)) == pytest.approx(1.0 / 8.0, abs=1e-14)
    assert B @ A @ A @ C == pytest.approx(1.0 / 24.0, abs=1e-14)


def test_embedded_fourth_order_and_error_weights():
    """E = b - b̂ sums to 0, and b̂ = b - E is itself of order 4 (b̂·c^(k-1) = 1/k, k = 1..4) but not 5."""
    assert E.sum() == pytest.approx(0.0, abs=1e-15)
    bh = B - E
    for k in range(1, 5):
        assert bh @ C ** (k - 1) == pytest.approx(1.0 / k, abs=1e-14)
    assert abs(bh @ C ** 4 - 0.2) > 1e-6


def test_coefficients_are_the_published_fractions():
    """Two entries checked exactly against the published rationals (catches a mistyped constant)."""
    assert Fraction(I.A52).limit_denominator(10 ** 5) == Fraction(-25360, 2187)
    assert Fraction(I.E5).limit_denominator(10 ** 7) == Fraction(-17253, 339200)
