"""The sweep designs by name, what each puts where, and the boundary share: no numpy (``vibro --help`` stays light)."""
from __future__ import annotations

DESIGN_MEANINGS = {
    "sobol": "scrambled Sobol' in the interior (first n points of 2^ceil(log2 n) when n is not a power of 2)",
    "sobol-boundary": "sobol with boundary_fraction of the points on the box's boundary: its 2^d corners, then "
                      "Sobol' points on every edge and face (where constrained optima sit)",
    "lhs": "Latin hypercube in the interior",
    "grid": "full factorial, end points included (n_points must be a product of levels)",
}
"""Design name -> what it puts where, one line each (``vibro sweep --help``, docs/train.md)."""

BOUNDARY_FRACTION = 0.25
"""Default share of a ``sobol-boundary`` design's points on the boundary: of 1/8, 1/4 and 1/2 the best measured
(bench/bench_design.py, docs/train.md "Designs with points on the boundary")."""
