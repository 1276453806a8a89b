"""Designs in the unit cube [0, 1]^d: interior space-filling (scrambled Sobol', Latin hypercube) and Sobol' with a
stated fraction of its points on the cube's boundary, where constrained optima of the operating point live (an
upper bound of F0 or Fs is a face; both together an edge; a corner of the box is a corner of the cube).

Coordinates are unitless (the sweep maps them to each parameter's range, linear or log); every design is
deterministic in its seed.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from pipeline.core.design_names import BOUNDARY_FRACTION, DESIGN_MEANINGS  # noqa: F401  (designs.X, as before)


def sobol(d: int, n: int, seed: int | np.random.Generator) -> np.ndarray:
    """``n`` scrambled Sobol' points in [0, 1)^d: the first n of the 2^ceil(log2 n) sequence (a prefix keeps the low
    discrepancy, not the exact balance of a power of 2)."""
    from scipy.stats import qmc

    if n <= 0:
        return np.empty((0, d))
    return qmc.Sobol(d, scramble=True, seed=seed).random_base2(math.ceil(math.log2(n)))[:n]


def lhs(d: int, n: int, seed: int) -> np.ndarray:
    """``n`` Latin-hypercube points in [0, 1)^d."""
    from scipy.stats import qmc

    return qmc.LatinHypercube(d, seed=seed).random(n)


def corners(d: int) -> np.ndarray:
    """The 2^d corners of the unit cube, shape (2^d, d), in binary order (0...0 first, 1...1 last)."""
    return np.array(list(itertools.product((0.0, 1.0), repeat=d)), dtype=np.float64).reshape(2 ** d, d)


def faces(d: int, k: int) -> list[tuple[tuple[int, ...], tuple[float, ...]]]:
    """The k-dimensional faces of the unit cube (0 < k < d; k = 1: edges, k = d - 1: facets): each as (free axes,
    values 0/1 of the other axes in order)."""
    out = []
    for free in itertools.combinations(range(d), k):
        for ends in itertools.product((0.0, 1.0), repeat=d - k):
            out.append((free, ends))
    return out


MAX_FACES = 100_000
"""Above this many k-faces (many varied parameters) the faces of that dimension are drawn at random, one point each,
instead of listed: the cube has 3^d - 2^d - 1 of them in all."""


def _some_corners(d: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` distinct corners drawn by ``rng`` (all 2^d, in binary order, when n >= 2^d), without listing 2^d."""
    if n >= 2 ** d:
        return corners(d)
    if d <= 16:
        return corners(d)[np.sort(rng.permutation(2 ** d)[:n])]
    if d <= 62:
        idx = np.sort(rng.choice(2 ** d, size=n, replace=False)).astype(np.int64)
        return ((idx[:, None] >> np.arange(d - 1, -1, -1)) & 1).astype(np.float64)
    return rng.integers(0, 2, size=(n, d)).astype(np.float64)       # 2^-62 chance of a repeat


def _face_plan(d: int, n_rest: int, rng: np.random.Generator) -> list[tuple[tuple[int, ...], tuple[float, ...], int, int]]:
    """(free axes, ends of the other axes, points, index of the face among the k-faces) of every face that gets points: ``n_rest`` shared equally between the
    face dimensions k = 1 .. d-1, then between the k-faces (the remainders go to faces drawn by ``rng``); with more than
    ``MAX_FACES`` k-faces, that many distinct-or-not faces are drawn at random, one point each."""
    dims = list(range(1, d))
    plan = []
    for i, k in enumerate(dims):
        share = n_rest // len(dims) + (1 if i < n_rest % len(dims) else 0)
        if share == 0:
            continue
        if math.comb(d, k) * 2 ** (d - k) > MAX_FACES:
            for j in range(share):
                free = tuple(sorted(int(a) for a in rng.choice(d, size=k, replace=False)))
                plan.append((free, tuple(float(e) for e in rng.integers(0, 2, size=d - k)), 1, j))
            continue
        listed = faces(d, k)
        counts = np.full(len(listed), share // len(listed), dtype=np.int64)
        counts[rng.permutation(len(listed))[:share % len(listed)]] += 1
        plan.extend((free, ends, int(c), j) for j, ((free, ends), c) in enumerate(zip(listed, counts)) if c)
    return plan


def boundary_points(d: int, n_boundary: int, seed: int) -> np.ndarray:
    """``n_boundary`` points on the boundary of [0, 1]^d (each has a coordinate exactly 0 or 1): all 2^d corners when
    ``n_boundary`` >= 2^d (else that many corners drawn by ``seed``), the rest shared between the edges and faces
    (:func:`_face_plan`), each face's points a scrambled Sobol' sequence on its free axes seeded by (seed, face).
    In one dimension the boundary is the two ends: at most 2 points."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    n_boundary = min(n_boundary, 2) if d == 1 else n_boundary
    plan = _face_plan(d, max(n_boundary - 2 ** d, 0), rng)
    pts = [_some_corners(d, min(n_boundary, 2 ** d), rng)]
    for free, ends, c, j in plan:
        block = np.empty((c, d))
        block[:, [a for a in range(d) if a not in free]] = ends
        block[:, list(free)] = sobol(len(free), c, np.random.default_rng(np.random.SeedSequence([seed, 2, len(free), j])))
        pts.append(block)
    return np.vstack(pts)


def interleave(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rows of ``a`` and ``b`` merged so that every prefix holds about the same share of each (by rank (i + 1/2) /
    count, ``a`` first on ties): a prefix of the design (the learning curve's subsets) keeps its boundary fraction."""
    keys = np.concatenate([(np.arange(len(a)) + 0.5) / max(len(a), 1), (np.arange(len(b)) + 0.5) / max(len(b), 1)])
    order = np.argsort(keys, kind="stable")
    return np.vstack([a, b])[order]


def sobol_boundary(d: int, n: int, seed: int, fraction: float = BOUNDARY_FRACTION) -> np.ndarray:
    """``n`` points of [0, 1]^d: round(``fraction`` × n) on the boundary (:func:`boundary_points`), the rest scrambled
    Sobol' (:func:`sobol`, same seed) in the interior; merged by :func:`interleave`.  Deterministic in ``seed``."""
    n_boundary = min(int(round(fraction * n)), n)
    edge = boundary_points(d, n_boundary, seed)
    inside = sobol(d, n - len(edge), seed)
    return interleave(edge, inside)
