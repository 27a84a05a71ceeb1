"""A small k-d tree whose k-nearest-neighbour query is callable from numba code.

``iterate`` needs one neighbour search per step of a free-running model; a
scipy ``cKDTree.query`` call costs tens of microseconds of Python overhead
alone, more than the search itself.  This tree is built once per database
and queried inside the compiled iteration loop.  Euclidean metric; nodes keep
their bounding boxes so the search prunes with the exact box distance.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

LEAF_SIZE = 12


@njit(cache=True, nogil=True)
def select_kth(keys, items, lo, hi, k):
    """Reorder ``keys[lo:hi]`` so that ``keys[k]`` holds their ``k``-th smallest value, with
    no larger one before it and no smaller one after it; ``items`` (when not empty) is
    reordered alongside.  Returns ``keys[k]``.

    Quickselect with a Hoare partition: linear time (a sort per k-d tree node made the
    build ``O(n log^2 n)``).
    """
    carry = items.size > 0
    left, right = lo, hi - 1
    while left < right:
        pivot = keys[(left + right) // 2]
        i, j = left, right
        while i <= j:
            while keys[i] < pivot:
                i += 1
            while keys[j] > pivot:
                j -= 1
            if i <= j:
                keys[i], keys[j] = keys[j], keys[i]
                if carry:
                    items[i], items[j] = items[j], items[i]
                i += 1
                j -= 1
        if k <= j:
            right = j
        elif k >= i:
            left = i
        else:
            break
    return keys[k]


@njit(cache=True, nogil=True)
def _partition(keys, items, lo, hi, pivot):
    """Move ``keys[lo:hi]`` below ``pivot`` to the front (``items`` alongside); returns
    the first position of the rest.

    Branch-free (Lomuto, every element swapped with itself or the boundary): which side
    a point falls on is a coin toss, and a mispredicted branch per element cost more than
    the swaps.
    """
    i = lo
    for p in range(lo, hi):
        v = keys[p]
        it = items[p]
        keys[p] = keys[i]
        items[p] = items[i]
        keys[i] = v
        items[i] = it
        i += v < pivot
    return i


#: points per node whose coordinates choose its split dimension (evenly spaced in it)
SPLIT_SAMPLE = 32


@njit(cache=True, nogil=True)
def build_tree(data, leaf_size=LEAF_SIZE):
    """Return ``(perm, start, stop, left, right, box_lo, box_hi)`` for ``data`` (n, d).

    Nodes of at most ``leaf_size`` points are leaves.  A node is split in the
    dimension of widest spread over :data:`SPLIT_SAMPLE` of its points, at the mean
    of its points there (one pass, :func:`_partition`), or at the median where the
    mean would leave a child with less than a quarter of the points or less than
    half a leaf (so every leaf holds at least ``leaf_size // 2`` points).  The
    bounding boxes are tight, computed from the leaves up.  Any such tree gives
    the same exact k-NN; only the order in which a search meets points at equal
    distances depends on it.

    Against median splits at every node with top-down boxes (the selection and the
    box of every node cost a pass over its points at each level): a tree on 6000
    four-dimensional points of a noisy Ikeda or Mackey-Glass run built in 0.4
    instead of 1.3 ms, and 10^5 random points in 30 instead of 55 ms; the k-NN
    searches of :func:`skdelay._scan.tree_cells` took the same time, with
    bit-identical results (``benchmarks/tree_build.py``).
    """
    n, d = data.shape
    half = max(leaf_size // 2, 1)
    max_nodes = 2 * (n // half) + 3
    perm = np.arange(n)
    keys = np.empty(n)  # the split coordinate of perm's rows, reordered with perm
    start = np.zeros(max_nodes, dtype=np.int64)
    stop = np.zeros(max_nodes, dtype=np.int64)
    left = -np.ones(max_nodes, dtype=np.int64)
    right = -np.ones(max_nodes, dtype=np.int64)
    box_lo = np.empty((max_nodes, d))
    box_hi = np.empty((max_nodes, d))
    stack = np.zeros(max_nodes, dtype=np.int64)
    lo_s = np.empty(d)
    hi_s = np.empty(d)
    n_nodes = 1
    start[0], stop[0] = 0, n
    stack[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        lo, hi = start[node], stop[node]
        size = hi - lo
        if size <= leaf_size:
            for j in range(d):
                a, b = np.inf, -np.inf
                for p in range(lo, hi):
                    v = data[perm[p], j]
                    a = min(a, v)
                    b = max(b, v)
                box_lo[node, j], box_hi[node, j] = a, b
            continue
        for j in range(d):
            lo_s[j], hi_s[j] = np.inf, -np.inf
        for p in range(lo, hi, max(1, size // SPLIT_SAMPLE)):
            row = perm[p]
            for j in range(d):
                v = data[row, j]
                lo_s[j] = min(lo_s[j], v)
                hi_s[j] = max(hi_s[j], v)
        dim = 0
        for j in range(1, d):
            if hi_s[j] - lo_s[j] > hi_s[dim] - lo_s[dim]:
                dim = j
        total = 0.0
        for p in range(lo, hi):
            v = data[perm[p], dim]
            keys[p] = v
            total += v
        cut = _partition(keys, perm, lo, hi, total / size)
        least = max(half, size // 4)
        if cut - lo < least or hi - cut < least:  # skewed (or equal) values: the median
            cut = (lo + hi) // 2
            select_kth(keys, perm, lo, hi, cut)
        for child, a, b in ((n_nodes, lo, cut), (n_nodes + 1, cut, hi)):
            start[child], stop[child] = a, b
            stack[sp] = child
            sp += 1
        left[node], right[node] = n_nodes, n_nodes + 1
        n_nodes += 2
    for node in range(n_nodes - 1, -1, -1):  # children come after their parent
        a, b = left[node], right[node]
        if a >= 0:
            for j in range(d):
                box_lo[node, j] = min(box_lo[a, j], box_lo[b, j])
                box_hi[node, j] = max(box_hi[a, j], box_hi[b, j])
    return (perm, start[:n_nodes], stop[:n_nodes], left[:n_nodes], right[:n_nodes],
            box_lo[:n_nodes], box_hi[:n_nodes])


# inlined, and indexed by node rather than handed row views: it runs at every node a
# query visits, where a call with two fresh views cost more than the few subtractions.
# Branch-free (a max instead of an if per coordinate, the same values): which side of a box
# a query lies on is a coin toss per coordinate, and the mispredicted branches cost more
# than the arithmetic (the projected tree search of skdelay._scan on 10^5 noisy Mackey-Glass
# points, k = 30, one thread: 3.9 / 4.4 us per query at m = 2 / 5 against 4.3 / 5.1).
@njit(cache=True, inline="always")
def box_dist2(q, box_lo, box_hi, node):
    """Squared distance of ``q`` to the bounding box of ``node`` (rows of ``box_lo`` and
    ``box_hi``): the pruning bound of every search over these trees, here and in
    :mod:`skdelay._scan`."""
    s = 0.0
    for j in range(q.size):
        t = max(box_lo[node, j] - q[j], q[j] - box_hi[node, j], 0.0)
        s += t * t
    return s


@njit(cache=True, inline="always")
def insert_sorted(best_d, best_i, k, d, ident, filled):
    """Insert ``(d, ident)`` into the ascending ``best_d[:k]`` (and ``best_i``), dropping the
    last; the caller has checked ``d < best_d[k - 1]``.  ``filled``: how many slots hold a
    neighbour (the others are ``inf``); returns the count after the insertion.

    A shift rather than a heap: the callers read the neighbours nearest first.  The shift
    starts at the first empty slot: walking down from slot ``k - 1`` over the empty ones
    cost ``k^2 / 2`` moves per search while the list fills (435 of about 1000 at k = 30).
    The same neighbours in the same order; on 10^5 noisy 12-bit Mackey-Glass points (every
    point a query, one thread, the tree scan alone timed three times in turn) 3.66 -> 3.41
    us per query and tau at m = 2 and 5.19 -> 5.10 at m = 5, a gain the whole scan's
    benchmark does not resolve (benchmarks/out/delay_scan.txt, stop 78).
    """
    pos = filled if filled < k else k - 1
    while pos > 0 and best_d[pos - 1] > d:
        best_d[pos] = best_d[pos - 1]
        best_i[pos] = best_i[pos - 1]
        pos -= 1
    best_d[pos] = d
    best_i[pos] = ident
    return filled + 1 if filled < k else k


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
    filled = 0
    stack[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        if box_dist2(q, box_lo, box_hi, node) >= best_d[k - 1]:
            continue
        if left[node] < 0:
            for p in range(start[node], stop[node]):
                row = perm[p]
                s = 0.0
                for j in range(d):
                    t = data[row, j] - q[j]
                    s += t * t
                if s < best_d[k - 1]:
                    filled = insert_sorted(best_d, best_i, k, s, row, filled)
            continue
        a, b = left[node], right[node]
        da = box_dist2(q, box_lo, box_hi, a)
        db = box_dist2(q, box_lo, box_hi, b)
        if da <= db:  # push the farther child first so the nearer is searched first
            stack[sp] = b
            stack[sp + 1] = a
        else:
            stack[sp] = a
            stack[sp + 1] = b
        sp += 2


@njit(cache=True, nogil=True)
def _knn_seeded(sdata, sids, tree, q, k, t, theiler, bound, best_d, best_i, stack):
    """k nearest rows of the tree-ordered ``sdata`` to ``q``, skipping ids within ``theiler``.

    Like :func:`query_knn`, but the tree's points are stored in tree order
    (``sdata[p]`` is the point at position ``p``, ``sids[p]`` its id), ids
    ``|sids[p] - t| <= theiler`` are skipped (``theiler < 0``: none), and
    ``bound`` (squared) is an upper bound of the k-th distance known in
    advance (``np.inf`` if none): boxes and points beyond it are pruned from
    the start.  Returns the number of neighbours found (< k only when fewer
    eligible points exist).
    """
    _, start, stop, left, right, box_lo, box_hi = tree
    d = sdata.shape[1]
    for j in range(k):
        best_d[j] = np.inf
        best_i[j] = -1
    found = 0
    stack[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        bd = box_dist2(q, box_lo, box_hi, node)
        if bd >= best_d[k - 1] or bd > bound:
            continue
        if left[node] < 0:
            for p in range(start[node], stop[node]):
                s = 0.0
                for j in range(d):
                    x = sdata[p, j] - q[j]
                    s += x * x
                if s >= best_d[k - 1] or s > bound:
                    continue
                ident = sids[p]
                if theiler >= 0 and abs(ident - t) <= theiler:
                    continue
                found = insert_sorted(best_d, best_i, k, s, ident, found)
            continue
        a, b = left[node], right[node]
        da = box_dist2(q, box_lo, box_hi, a)
        db = box_dist2(q, box_lo, box_hi, b)
        if da <= db:
            stack[sp] = b
            stack[sp + 1] = a
        else:
            stack[sp] = a
            stack[sp + 1] = b
        sp += 2
    return found


@njit(cache=True, parallel=True, nogil=True)
def window_knn_lists(s, m, is_member, tree, sdata, sids, needed, k, theiler, n_chunks,
                     lists, rk2):
    """``k`` nearest member windows of every needed time, compiled and threaded.

    The window of time ``t`` is ``s[t - lag]``, ``lag = 0..m-1``; ``tree``
    (:func:`build_tree`) indexes the member windows stored in tree order
    (``sdata``, ids ``sids``).  Members within ``theiler`` samples of ``t``
    are skipped (``theiler < 0``: none), so a list holds the ``k`` nearest
    eligible members (``-1`` pads it only when fewer exist).  Fills ``lists``
    (``(needed.size, k)``, ascending distance) and ``rk2`` (squared distance of
    the ``k``-th neighbour, ``inf`` for a short list): every eligible member
    outside a list is at least that far away.

    The needed times are cut into ``n_chunks`` runs searched in parallel by
    :func:`window_knn_run`.
    """
    bounds = np.linspace(0, needed.size, n_chunks + 1).astype(np.int64)
    for ch in prange(n_chunks):
        window_knn_run(s, m, is_member, tree, sdata, sids, needed, bounds[ch], bounds[ch + 1],
                       k, theiler, lists, rk2)


@njit(cache=True, nogil=True)
def window_knn_run(s, m, is_member, tree, sdata, sids, needed, lo, hi, k, theiler, lists, rk2):
    """Rows ``lo:hi`` of :func:`window_knn_lists`, serially (no parallel region: safe to
    call from several Python threads at once, whatever numba's threading layer).

    A time ``t`` following ``t - 1`` starts from the bound given by the
    neighbours of ``t - 1`` shifted by one sample (``j + 1`` shares ``m - 1``
    coordinates with ``j``), which prunes most of the tree at once.
    """
    n_max = is_member.size
    best_d = np.empty(k)
    best_i = np.empty(k, dtype=np.int64)
    seed_d = np.empty(k)
    q = np.empty(m)
    stack = np.empty(256, dtype=np.int64)
    prev_full = False
    for r in range(lo, hi):
        t = needed[r]
        for lag in range(m):
            q[lag] = s[t - lag]
        bound = np.inf
        if prev_full and r > 0 and needed[r - 1] == t - 1:
            ok = True
            for c in range(k):
                j = np.int64(lists[r - 1, c]) + 1
                if j >= n_max or not is_member[j] or (theiler >= 0 and abs(j - t) <= theiler):
                    ok = False
                    break
                acc = 0.0
                for lag in range(m):
                    x = s[j - lag] - q[lag]
                    acc += x * x
                seed_d[c] = acc
            if ok:
                bound = seed_d.max()
        found = _knn_seeded(sdata, sids, tree, q, k, t, theiler, bound, best_d, best_i, stack)
        for c in range(k):
            lists[r, c] = best_i[c] if c < found else -1
        rk2[r] = best_d[k - 1] if found == k else np.inf
        prev_full = found == k
