"""Cases of the identification matrix through the DAQ chain on every system
(``bench.identification_chain``), slow.

Each case is an 8-run log of the independent generator (rig noise, seed 0) recorded through a named chain and
diagnosed at the defaults (an undeclared chain with ``estimate_chain``).  The cases the diagnosis gets wrong today
are listed as strict expected failures, with the reason measured in docs/identification.md, so that a change which
mends one says so."""
from __future__ import annotations

import pytest

from bench import identification as ident
from bench import identification_chain as chain

RIGHT = [("control", "compensated"), ("control", "uncompensated"), ("control", "saturated"),
         ("shaker_coil", "compensated"), ("shaker_coil", "uncompensated"), ("shaker_coil", "saturated"),
         ("guide_friction", "compensated"), ("guide_friction", "uncompensated"), ("guide_friction", "saturated"),
         ("rate_stiffening", "compensated"), ("rate_stiffening", "uncompensated"),
         ("sensor_lowpass", "undeclared"), ("control", "undeclared"), ("shaker_coil", "undeclared"),
         ("guide_friction", "undeclared"), ("rate_stiffening", "undeclared"),
         ("pair:shaker_coil+guide_friction", "compensated"), ("pair:shaker_coil+guide_friction", "uncompensated"),
         ("pair:shaker_coil+guide_friction", "saturated")]
WRONG = {("rate_stiffening", "saturated"): "a second effect (guide_friction) is added",
         # the verdict is right; the clock just misses its 5 ppm target
         ("pair:shaker_coil+guide_friction", "undeclared"): "both named, but the clock comes out 5.5 ppm off"}


PENDULUM_RIGHT = [(case, c) for case in ("control", "sensor_lowpass") for c in chain.CHAINS if c != "undeclared"]
"""The pendulum's control and its accelerometer's low-pass: right in every column since the model is low-passed
before sampling where the record was (the undeclared control was 'unexplained' at held-out nrms 4.96 before, the
saturated low-pass at 51)."""
_DISP = "the verdict is right, but the largest delay error is 120-140 µs (the displacement's, at 10 kHz)"
PENDULUM_WRONG = {("control", "undeclared"): _DISP, ("sensor_lowpass", "undeclared"): _DISP,
                  ("rate_stiffening", "uncompensated"): "nothing missing: the split holds out both 3.5 Hz runs, "
                                                        "where alpha shows (so in the lab-grade log too)",
                  ("pair:rate_stiffening+sensor_lowpass", "undeclared"): "the low-pass alone (held-out nrms "
                                                                         "1.68): rate stiffening does not pay on "
                                                                         "the calibration runs (the same split)"}


INDENTER_WRONG = {("guide_friction", "undeclared"): "the shaker coil is added: its lag takes up the filter's phase "
                                                    "dispersion, which a delay per channel does not hold"}
INDENTER_RIGHT = [(case, c) for case in ("control", "guide_friction", "outside:quadratic_damping") for c in chain.CHAINS
                  if (case, c) not in INDENTER_WRONG]
"""The metal indenter's control, guide friction and an outside kind in every other column (docs/identification.md)."""


_SLOW_RIG = "the verdict is right, but the delays are {} µs off (a 5-9 Hz rig pins them to tens of µs)"
RIMD_WRONG = {("control", "undeclared"): _SLOW_RIG.format(25), ("sensor_lowpass", "undeclared"): _SLOW_RIG.format(28)}
RIMD_RIGHT = [(case, c) for case in ("control", "sensor_lowpass") for c in chain.CHAINS if c != "undeclared"]
"""The RIMD's control and its accelerometer's low-pass (which a DAQ filter could pass for) in every column."""


SANDSTONE_WRONG = {("control", "undeclared"): "the verdict is right, but the displacement's delay at 25.6 kHz is "
                                              "29 µs off (± 20 µs: its harmonics are weak)"}
SANDSTONE_RIGHT = [("control", c) for c in chain.CHAINS if c != "undeclared"]
"""The sandstone indenter's control in every column."""


def _params(system: str, right: list, wrong: dict) -> list:
    return [*((system, *k) for k in right),
            *(pytest.param(system, *k, marks=pytest.mark.xfail(strict=True, reason=v)) for k, v in wrong.items())]


SYSTEMS = {"drill": (RIGHT, WRONG), "pendulum": (PENDULUM_RIGHT, PENDULUM_WRONG),
           "indenter-metal": (INDENTER_RIGHT, INDENTER_WRONG), "rimd": (RIMD_RIGHT, RIMD_WRONG),
           "indenter-sandstone": (SANDSTONE_RIGHT, SANDSTONE_WRONG)}
"""Per system: the cases right today, and the wrong ones with their reason."""


@pytest.mark.slow
@pytest.mark.parametrize("system, case, column", [p for system, (right, wrong) in SYSTEMS.items()
                                                  for p in _params(system, right, wrong)], ids=lambda x: str(x))
def test_a_case_through_the_chain(tmp_path, monkeypatch, system, case, column):
    _check(tmp_path, monkeypatch, system, case, column)


def _check(tmp_path, monkeypatch, system: str, case: str, column: str) -> None:
    monkeypatch.setattr(ident, "WORK", tmp_path)
    r = ident.run_case(system, case, "rig", 0, 2, chain.settings_of(column), 8, chain.CHAINS[column])
    assert r["correct"], (r["verdict"], r["selected"], r["leader"])
    if column == "undeclared":          # the estimated chain against the generator's truth
        assert r["delay_error_us"] <= chain.DELAY_TOL_US and r["clock_error_ppm"] <= chain.CLOCK_TOL_PPM
    if ident.expected(case) == "selected" and not ident.pair_of(case):     # a pair's target: both named
        assert all(abs(e) <= ident.PARAM_TOL for e in r["param_errors"].values()), r["param_errors"]
