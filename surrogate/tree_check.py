"""Bounds checks for the tree storage a bundle may hold.

skops does not trust scikit-learn's tree storage (``Tree``, ``TreePredictor``) because their node
arrays hold raw child and feature indices that prediction follows without bounds checks: a
crafted file crashes the process.  A bundle may hold them only because :func:`check_trees` walks
the loaded object graph and checks every node array before anything predicts.
"""
from __future__ import annotations

from typing import Callable, Iterator

import numpy as np


class TreeStorageError(ValueError):
    """A tree's node arrays would make prediction read outside them."""


def _check_children(left: np.ndarray, right: np.ndarray, feature: np.ndarray, inner: np.ndarray,
                    n_features: int) -> None:
    """Children of inner node i lie in (i, n) (so a walk always ends) and features in [0, n_features)."""
    n = len(left)
    idx = np.flatnonzero(inner)
    for name, child in (("left child", left), ("right child", right)):
        c = child[idx].astype(np.int64)
        bad = idx[(c <= idx) | (c >= n)]
        if bad.size:
            raise TreeStorageError(f"node {int(bad[0])}: {name} {int(child[bad[0]])} is outside ({int(bad[0])}, {n})")
    f = feature[idx].astype(np.int64)
    bad = idx[(f < 0) | (f >= n_features)]
    if bad.size:
        raise TreeStorageError(f"node {int(bad[0])}: feature {int(feature[bad[0]])} is outside [0, {n_features})")


def check_tree(tree, n_features: int) -> None:
    """``sklearn.tree._tree.Tree``: node_count within the allocated capacity, then every inner node's indices."""
    count, capacity = int(tree.node_count), int(tree.capacity)
    if not 1 <= count <= capacity:   # the arrays below are views of node_count nodes: check before reading
        raise TreeStorageError(f"node_count {count} is outside [1, {capacity}] (the stored nodes)")
    left, right = tree.children_left, tree.children_right
    _check_children(left, right, tree.feature, left != -1, n_features)


def check_predictor(predictor, n_features: int) -> None:
    """``TreePredictor`` (histogram gradient boosting): record layout, then every inner node's indices.

    Categorical splits index further bitset arrays; vibro never trains on categorical inputs, so
    a node marked categorical is refused."""
    from sklearn.ensemble._hist_gradient_boosting.common import PREDICTOR_RECORD_DTYPE

    nodes = predictor.nodes
    if not isinstance(nodes, np.ndarray) or nodes.dtype != PREDICTOR_RECORD_DTYPE or nodes.ndim != 1 or not len(nodes):
        raise TreeStorageError("predictor nodes are not a non-empty array of predictor records")
    inner = nodes["is_leaf"] == 0
    if np.any(nodes["is_categorical"][inner] != 0):
        raise TreeStorageError("a node splits on a categorical input (vibro trains on numeric inputs only)")
    _check_children(nodes["left"], nodes["right"], nodes["feature_idx"], inner, n_features)


def _checkers() -> dict[type, Callable[[object, int], None]]:
    from sklearn.ensemble._hist_gradient_boosting.predictor import TreePredictor
    from sklearn.tree._tree import Tree

    return {Tree: check_tree, TreePredictor: check_predictor}


# skops type names a bundle may hold only because check_trees validates them after loading
CHECKED_TYPES = ("sklearn.tree._tree.Tree", "sklearn.ensemble._hist_gradient_boosting.predictor.TreePredictor")


def _walk(obj, seen: set[int]) -> Iterator[object]:
    """Every object reachable through attributes, containers and object arrays, once."""
    stack = [obj]
    while stack:
        o = stack.pop()
        if id(o) in seen or isinstance(o, (str, bytes, int, float, bool, type(None))):
            continue
        seen.add(id(o))
        yield o
        if isinstance(o, dict):
            stack.extend(o.values())
        elif isinstance(o, (list, tuple, set, frozenset)):
            stack.extend(o)
        elif isinstance(o, np.ndarray):
            if o.dtype == object:
                stack.extend(o.ravel().tolist())
        elif hasattr(o, "__dict__"):
            stack.extend(vars(o).values())


def check_trees(obj, n_features: int) -> int:
    """Check every tree storage reachable from ``obj`` for inputs of ``n_features`` columns;
    returns how many were checked (TreeStorageError naming the first bad node)."""
    checkers = _checkers()
    n = 0
    for o in _walk(obj, set()):
        check = checkers.get(type(o))
        if check is not None:
            check(o, n_features)
            n += 1
    return n
