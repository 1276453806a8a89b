"""pipeline.datasets.designs and the ``sobol-boundary`` sweep design: points in the unit cube, the stated share on the
boundary, every corner, determinism, and one-line messages for bad values."""
from __future__ import annotations

import numpy as np
import pytest

from pipeline.core.errors import UserError
from pipeline.datasets import designs
from pipeline.datasets.spec import design_points, make_spec, unit_design

VARY = {"frequency_hz": {"low": 100.0, "high": 450.0}, "amplitude_n": {"low": 1800.0, "high": 2700.0},
        "static_force_n": {"low": 600.0, "high": 1800.0}}


def spec(**kw):
    raw = {"model": "drill", "preset": "lab", "vary": VARY, "design": "sobol-boundary", "n_points": 64, "seed": 0}
    raw.update(kw)
    return make_spec(raw)


def on_boundary(u: np.ndarray) -> np.ndarray:
    return ((u == 0.0) | (u == 1.0)).any(axis=1)


@pytest.mark.parametrize("d,n,fraction", [(3, 64, 0.25), (3, 100, 0.5), (2, 37, 0.3), (4, 200, 0.25), (3, 20, 0.2),
                                          (3, 64, 0.0), (3, 16, 1.0), (1, 10, 0.5)])
def test_points_in_the_cube_with_the_stated_share_on_the_boundary(d, n, fraction):
    u = designs.sobol_boundary(d, n, seed=3, fraction=fraction)
    assert u.shape == (n, d)
    assert np.all((u >= 0.0) & (u <= 1.0))
    want = min(round(fraction * n), 2) if d == 1 else round(fraction * n)
    assert on_boundary(u).sum() == want             # the interior Sobol' points never sit exactly on a face
    assert len(np.unique(u, axis=0)) == n


def test_every_corner_when_the_budget_allows_and_the_rest_on_edges_and_faces():
    u = designs.sobol_boundary(3, 128, seed=0, fraction=0.25)            # 32 boundary points: 8 corners + 24
    b = u[on_boundary(u)]
    n_fixed = ((b == 0.0) | (b == 1.0)).sum(axis=1)                      # 3: corner, 2: edge, 1: face
    assert {tuple(c) for c in b[n_fixed == 3]} == {tuple(c) for c in designs.corners(3)}
    assert (n_fixed == 2).sum() == 12 and (n_fixed == 1).sum() == 12       # the 24 shared equally: 1 per edge, 2 per face
    few = designs.boundary_points(3, 5, seed=0)                           # fewer than 2^3: 5 distinct corners
    assert len(np.unique(few, axis=0)) == 5 and np.isin(few, (0.0, 1.0)).all()


def test_prefixes_keep_the_boundary_share():
    u = designs.sobol_boundary(3, 512, seed=0, fraction=0.25)
    for n in (64, 128, 256):
        assert abs(on_boundary(u[:n]).mean() - 0.25) <= 2 / n


def test_same_seed_same_points_other_seed_other_points():
    a, b = unit_design(spec(seed=5)), unit_design(spec(seed=5))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, unit_design(spec(seed=6)))
    assert spec(seed=5).fingerprint == spec(seed=5).fingerprint != spec(seed=5, boundary_fraction=0.5).fingerprint


def test_sweep_points_reach_the_ranges_ends_and_other_designs_keep_their_fingerprint():
    pts = design_points(spec(n_points=128))
    assert (pts["static_force_n"] == 1800.0).sum() > 0 and (pts["frequency_hz"] == 100.0).sum() > 0
    s = spec(design="sobol")
    assert s.boundary_fraction is None and "boundary_fraction" not in s.canonical()
    assert spec().boundary_fraction == designs.BOUNDARY_FRACTION


@pytest.mark.parametrize("change,words", [
    ({"design": "sobol-bondary"}, ["sweep.design", "did you mean sobol-boundary?"]),
    ({"design": "halton"}, ["sweep.design", "known: sobol, sobol-boundary, lhs, grid"]),
    ({"boundary_fraction": 1.5}, ["sweep.boundary_fraction", "[0, 1]"]),
    ({"boundary_fraction": -0.1}, ["sweep.boundary_fraction", "[0, 1]"]),
    ({"boundary_fraction": "many"}, ["sweep.boundary_fraction", "number"]),
    ({"design": "sobol", "boundary_fraction": 0.2}, ["boundary_fraction", "only used by the sobol-boundary design"]),
])
def test_bad_values_are_one_line_naming_the_option(change, words):
    with pytest.raises(UserError) as e:
        spec(**change)
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg


def test_cli_names_the_flag_and_lists_the_designs(tmp_path, capsys):
    from pipeline.cli import main

    out = tmp_path / "never"
    rc = main(["sweep", "--design", "sobol-boundary", "--boundary-fraction", "2", "--out", str(out), "--dry-run",
               "--no-mlflow"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "--boundary-fraction" in err
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    text = capsys.readouterr().out
    for name, meaning in designs.DESIGN_MEANINGS.items():
        assert f"  {name:<15} {meaning}" in text


def test_many_dimensions_without_listing_every_face():
    """3^40 faces and 2^40 corners are never listed: corners are drawn, and beyond MAX_FACES faces of a dimension
    its faces are drawn too."""
    u = designs.sobol_boundary(40, 400, seed=0, fraction=0.25)
    assert u.shape == (400, 40) and on_boundary(u).sum() == 100 and len(np.unique(u, axis=0)) == 400
    b = designs.boundary_points(12, 4096 + 300, seed=1)                  # every corner, then 300 on edges and faces
    assert len(b) == 4396 and on_boundary(b).all() and len(np.unique(b, axis=0)) == 4396


def test_another_design_given_on_top_drops_the_raw_specs_boundary_fraction():
    """params.yaml's sobol-boundary share does not block `--design sobol` (or make_spec(None, design="lhs"))."""
    assert make_spec(None, design="lhs").boundary_fraction is None
    assert make_spec(None).boundary_fraction == designs.BOUNDARY_FRACTION
    with pytest.raises(UserError, match="only used by the sobol-boundary design"):
        make_spec(None, design="sobol", boundary_fraction=0.3)
