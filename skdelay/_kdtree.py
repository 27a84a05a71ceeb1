"""A small k-d tree whose k-nearest-neighbour query is callable from numba code.

``iterate`` needs one neighbour search per step of a free-running model; a
scipy ``cKDTree.query`` call costs tens of microseconds of Python overhead
alone, more than the search itself.  This tree is built once per database
and queried inside the compiled iteration loop.  Euclidean metric; nodes keep
their bounding boxes so the search prunes with the exact box distance.
"""

from __future__ import annotations

import numpy as np
from numba import njit

LEAF_SIZE = 12


@njit(cache=True)
def build_tree(data):
    """Return ``(perm, start, stop, left, right, box_lo, box_hi)`` for ``data`` (n, d)."""
    n, d = data.shape
    max_nodes = 2 * (n // max(LEAF_SIZE // 2, 1)) + 3
    perm = np.arange(n)
    start = np.zeros(max_nodes, dtype=np.int64)
    stop = np.zeros(max_nodes, dtype=np.int64)
    left = -np.ones(max_nodes, dtype=np.int64)
    right = -np.ones(max_nodes, dtype=np.int64)
    box_lo = np.zeros((max_nodes, d))
    box_hi = np.zeros((max_nodes, d))
    stack = np.zeros(max_nodes, dtype=np.int64)
    n_nodes = 1
    start[0], stop[0] = 0, n
    stack[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        lo, hi = start[node], stop[node]
        for j in range(d):
            box_lo[node, j] = np.inf
            box_hi[node, j] = -np.inf
        for p in range(lo, hi):
            row = perm[p]
            for j in range(d):
                v = data[row, j]
                box_lo[node, j] = min(box_lo[node, j], v)
                box_hi[node, j] = max(box_hi[node, j], v)
        if hi - lo <= LEAF_SIZE:
            continue
        dim = 0
        widest = -1.0
        for j in range(d):
            w = box_hi[node, j] - box_lo[node, j]
            if w > widest:
                widest = w
                dim = j
        if widest <= 0.0:
            continue  # all points identical: keep as a (large) leaf
        idx = perm[lo:hi].copy()
        order = np.argsort(data[idx, dim])
        perm[lo:hi] = idx[order]
        mid = (lo + hi) // 2
        for child, a, b in ((n_nodes, lo, mid), (n_nodes + 1, mid, hi)):
            start[child], stop[child] = a, b
            stack[sp] = child
            sp += 1
        left[node], right[node] = n_nodes, n_nodes + 1
        n_nodes += 2
    return (perm, start[:n_nodes], stop[:n_nodes], left[:n_nodes], right[:n_nodes],
            box_lo[:n_nodes], box_hi[:n_nodes])


@njit(cache=True)
def _box_dist2(q, lo, hi):
    s = 0.0
    for j in range(q.size):
        if q[j] < lo[j]:
            t = lo[j] - q[j]
            s += t * t
        elif q[j] > hi[j]:
            t = q[j] - hi[j]
            s += t * t
    return s


@njit(cache=True)
def query_knn(data, tree, q, k, best_d, best_i, stack):
    """Fill ``best_d`` (squared distances, ascending) and ``best_i`` with the ``k`` nearest rows.

    ``stack`` is int64 scratch space of length >= 2 * depth + 2 (64 is plenty).
    """
    perm, start, stop, left, right, box_lo, box_hi = tree
    d = data.shape[1]
    for j in range(k):
        best_d[j] = np.inf
        best_i[j] = -1
    stack[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        if _box_dist2(q, box_lo[node], box_hi[node]) >= best_d[k - 1]:
            continue
        if left[node] < 0:
            for p in range(start[node], stop[node]):
                row = perm[p]
                s = 0.0
                for j in range(d):
                    t = data[row, j] - q[j]
                    s += t * t
                if s < best_d[k - 1]:
                    pos = k - 1
                    while pos > 0 and best_d[pos - 1] > s:
                        best_d[pos] = best_d[pos - 1]
                        best_i[pos] = best_i[pos - 1]
                        pos -= 1
                    best_d[pos] = s
                    best_i[pos] = row
            continue
        a, b = left[node], right[node]
        da = _box_dist2(q, box_lo[a], box_hi[a])
        db = _box_dist2(q, box_lo[b], box_hi[b])
        if da <= db:  # push the farther child first so the nearer is searched first
            stack[sp] = b
            stack[sp + 1] = a
        else:
            stack[sp] = a
            stack[sp + 1] = b
        sp += 2
