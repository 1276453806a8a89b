"""The drill model's `lab` preset and its search space LAB_SPACE (MODELS.md §2 requirements (i)-(iii)).

A coarse grid (8 log-spaced frequencies x 3 F0 x 3 Fs over LAB_SPACE, window 16 cycles) keeps this fast;
docs/simulate.md, "The drill model's lab preset" has the 12 x 6 x 6 measurements behind the preset.
"""
import numpy as np
import pytest

import sim
from sim.models.drill import LAB_SPACE, PRESETS
from vibrobase.statuses import IMPACTING_STATUSES

WINDOW = {"window": 16}


@pytest.fixture(scope="module")
def grid():
    f = np.geomspace(*LAB_SPACE["frequency_hz"], 8)
    a = np.linspace(*LAB_SPACE["amplitude_n"], 3)
    s = np.linspace(*LAB_SPACE["static_force_n"], 3)
    rows = [dict(frequency_hz=fi, amplitude_n=ai, static_force_n=si) for ai in a for si in s for fi in f]
    return sim.simulate_batch("drill", rows, preset="lab", settings=WINDOW)


def test_space_keeps_static_force_below_threshold():
    # Fs >= Pr is a runaway (MODELS.md §2): the whole space must stay below the rock threshold
    assert set(LAB_SPACE) == {"frequency_hz", "amplitude_n", "static_force_n"}
    for lo, hi in LAB_SPACE.values():
        assert 0 < lo < hi
    assert LAB_SPACE["static_force_n"][1] < PRESETS["lab"]["Pr"]


def test_lab_mostly_progressing(grid):
    # requirement (i): a bounded, progressing steady state over most of the volume (MODELS.md §2; "most" = 80 %)
    progressing = grid["status"].isin(IMPACTING_STATUSES) & (grid["rop_m_s"].fillna(0.0) > 0.0)
    assert progressing.mean() >= 0.8, grid["status"].value_counts().to_dict()


def test_lab_interior_frequency_optimum(grid):
    # requirement (ii): for most (F0, Fs) pairs the best frequency lies strictly inside the range
    interior = 0
    pairs = grid.groupby(["amplitude_n", "static_force_n"])
    for _, g in pairs:
        rop = g.sort_values("frequency_hz")["rop_m_s"].fillna(-1.0).to_numpy()
        i = int(np.argmax(rop))
        interior += bool(0 < i < len(rop) - 1 and rop[i] > 0.0)
    assert interior >= 0.75 * pairs.ngroups, f"interior optimum for {interior} of {pairs.ngroups} pairs"


def test_lab_rop_realistic(grid):
    # requirement (iii): lab-scale hard-rock ROP at the optimum of about 0.1-10 mm/s (MODELS.md §2)
    rop_max = grid["rop_m_s"].max()
    assert 0.1e-3 <= rop_max <= 10e-3, rop_max
    # and every (F0, Fs) pair's best ROP is of that order too (not just the single best point)
    best = grid.groupby(["amplitude_n", "static_force_n"])["rop_m_s"].max()
    assert (best >= 0.1e-3).mean() >= 0.8, best.to_dict()


def test_lab_static_force_at_threshold_is_runaway():
    pr = PRESETS["lab"]["Pr"]
    for fs in (pr, 1.2 * pr):
        r = sim.simulate("drill", preset="lab", static_force_n=fs, settings=WINDOW)
        assert r.status == "runaway", (fs, r.labels["status"], r.labels["reason"])
        assert r.labels["rop_m_s"] is None


def test_seed_003_is_runaway():
    # seed 003's own table has Fs = 1260 kN >= Pr = 95 kN (MODELS.md §2)
    r = sim.simulate("drill", preset="seed-003", settings=WINDOW)
    assert r.status == "runaway"
    assert "Fs" in r.labels["reason"] and "Pr" in r.labels["reason"]
