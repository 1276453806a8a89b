"""Units to SI (pipeline.core.units): the factors are exact, g is the project's one value, and a bad unit says why."""
from __future__ import annotations

import pytest

import sim.layout
from pipeline.core.units import G, QUANTITY_OF, SI_UNITS, UnitError, column_factor, si_factor


@pytest.mark.parametrize(("column", "unit", "factor"), [
    ("force_n", "kN", 1e3), ("force_n", "lbf", 4.4482216152605), ("accel_m_s2", "g", 9.81),
    ("accel_m_s2", "m/s^2", 1.0), ("accel_m_s2", "m / s2", 1.0), ("disp_m", "mm", 1e-3), ("disp_m", "µm", 1e-6),
    ("t_s", "ms", 1e-3), ("frequency_hz", "kHz", 1e3), ("rop_m_s", "m/h", 1 / 3600), ("peak_decel_g", "g", 1.0),
    ("peak_decel_g", "m/s2", 1 / 9.81), ("gap_m", "in", 0.0254),
])
def test_column_factor(column, unit, factor):
    assert column_factor(column, unit) == pytest.approx(factor, rel=1e-15)


def test_g_is_the_projects_one_value():
    assert G == sim.layout.G_ACCEL == SI_UNITS["g"][1]


def test_table_is_consistent():
    quantities = {q for q, _ in SI_UNITS.values()}
    assert {q for q, _ in QUANTITY_OF.values()} <= quantities
    for q in quantities:            # every quantity has its SI unit at factor 1
        assert any(f == 1.0 for u, (qq, f) in SI_UNITS.items() if qq == q), q


@pytest.mark.parametrize(("unit", "quantity", "expect"), [
    ("furlongs", "force", "unknown unit 'furlongs' (force units: N, kN, mN, MN, lbf)"),
    ("KN", "force", "(did you mean 'kN'?"),
    ("mm", "force", "unit 'mm' is a length unit, not a force unit"),
    ("G", "acceleration", "did you mean 'g'?"),
    ("m/s", "acceleration", "unit 'm/s' is a velocity unit, not an acceleration unit"),
])
def test_bad_unit_says_why(unit, quantity, expect):
    with pytest.raises(UnitError) as e:
        si_factor(unit, quantity)
    assert expect in str(e.value)
