"""The delay scan: sigma_m(tau) over an ``(m, tau)`` grid, driven by one frozen options object.

A row ``t`` of the scan's database is the two-window vector ``v_t(m, tau)``
(read off the 1-D series on the fly) with target ``s[t+1]``; nothing of size
``(n_rows, n_lags)`` is ever built.  Every local fit is
:func:`skdelay._neighbours.fit_neighbourhood`, called from the compiled kernel
:func:`scan_cells` and :func:`tree_cells`.

Neighbour search (``ScanOptions.search``):

* ``"candidates"`` -- the second window of row ``t`` is the first
  window of row ``t - c`` (``c = second_window_start(m, tau)``), so one k-d
  tree per ``m`` on the m-dimensional windows serves every ``tau``: each
  needed time gets its ``K`` nearest windows once (:func:`candidate_lists`,
  built once per ``m`` and shared by all tasks of that ``m``), and for a
  chunk of taus the compiled kernel re-ranks, for every query ``q``, the union
  of the neighbours of its first window and those of its second window
  (shifted by ``c``) by the exact 2m-dimensional distance and fits the local
  model on the ``k`` nearest.  Every point outside both lists is at least
  ``r_K(q)^2 + r_K(q - c)^2`` away, so when the ``k``-th re-ranked distance is
  below that bound the neighbours are provably the exact k-NN
  (``exact_fraction``).  Candidates close in *either* window matter: with
  first-window candidates only, rare states get neighbours far away in the
  second window and the extrapolated forecasts can turn the dip into a peak.
  The lists can miss true neighbours: measured on 2*10^4 noisy 12-bit
  Mackey-Glass points (delay 100, k = 30, m = 2 and 5, five taus, every point a
  query), sigma differed from the exact search by up to 4.3 %, and by the same
  amount when a 10^-7 jitter broke every tie (the exact search moved by
  < 10^-4 under that jitter): misses, not ties.  The true 2m-dimensional
  neighbours at large tau lie at first-window rank ~10^3 (median over
  queries), far beyond any affordable list.
* ``"tree"`` -- the exact k-NN (k-NN only): for every tau a k-d tree on the
  leading principal components of both windows (:func:`window_components`,
  :data:`TREE_COMPONENTS` per window), searched depth-first, nearer child
  first (the queries run in the tree's order, a held-out query at the leaf it
  descends to, so that consecutive queries read the same leaves); the
  projected distance bounds the 2m-dimensional one from below, so a box or
  point is pruned only when it cannot be nearer than the current ``k``-th
  neighbour, and the full distance is computed for the few points left
  (:func:`tree_cells`).  Smooth windows
  are nearly flat in the first few components (two hold 99.98 % of the
  variance of noisy Mackey-Glass windows), so the 4-dimensional tree prunes
  almost as well as a 2m-dimensional one at a fraction of its cost; rough
  windows only make it slower, never inexact.  Its cost is one tree build per
  tau (~ n log n) plus a few microseconds per query.  It stays exact because the
  cheap approximations measured were not accurate enough: on 10^5 noisy 12-bit
  Mackey-Glass points (delay 100, k = 30, every point a query, one thread) a
  query and tau cost 4.4-5.6 us of search and 0.6-1.4 us of fit (m = 2-5);
  stopping the search after the query's own leaf (the heap seeded from the
  previous query, or also with the query's neighbours at the previous tau, or
  keeping 60-90 propagated neighbours) halved the time but moved sigma by up
  to 2.6-7 %, and after two leaves (about half the time) by up to 0.8-1.7 % per m: neighbours
  enter a moving neighbourhood faster than propagation finds them.  Pruning a
  box already when its distance reaches a quarter (a tenth) of the ``k``-th
  (an approximate search with ``eps = 1`` (2.2)) saved only 24 % (37 %) of the
  time and moved sigma by up to 0.4 % (0.9 %); a search per leaf of queries
  (the boxes near the leaf found once, each query scanning them nearest first)
  saved at most 17 %: the cost lies in the ~200 points a query must examine,
  the temporal neighbours of the Theiler window among them, not in the descent.
* ``"auto"`` (default) -- whichever of ``"tree"`` and ``"candidates"`` a
  measured cost model (:func:`_use_tree`) expects to be faster for the cell,
  the approximate lists only where they halve the cost: the tree for every
  query of a full-precision scan, for refined cells and for most coarse
  passes; the candidate lists for a coarse pass with few queries on a long
  record (10^4 on 10^6 rows, fewer than about 300 on 10^5 rows and 200 taus),
  where one tree per tau would cost far more than the queries; and the lists
  for radius neighbourhoods.
* ``"exact"`` -- a plain k-d tree on the 2m-dimensional vectors, rebuilt for
  every ``(m, tau)`` (the reference).

Standard errors: the queries of a cell (sorted in time) are cut into
:data:`N_BATCHES` contiguous batches; the spread of the batch means of the
squared error gives the standard error of the mean square (batch means absorb
the short-range correlation of successive errors), propagated to the rms by
the delta method, ``se(sigma) = se(mean e^2) / (2 sigma)``.

Refinement: a coarse pass forecasts ``n_queries`` random rows for every cell;
then the taus around each dip are recomputed with :data:`REFINE_GROWTH` times
more queries (nested sets, up to all rows) until the dip centre's standard
error (:func:`skdelay._dips.locate_dips`) is below ``target_centre_se``.  That
error comes from resampling the cells' query batches (``centre_error=
"batches"``, the default) or, more conservatively, from redrawing each cell
within its standard error (``"redraws"``), which overstates it on curves with
several valleys: clean Mackey-Glass tau = 17 (10^5 samples, m = 2..5, tau =
1..384, 2000 coarse queries) refined 432 cells with 12.4*10^6 forecasts in
97 s under "redraws", none (3.1*10^6 forecasts, 32 s) under "batches", with
the same centres within 0.17 samples and centre errors of 0.02-0.14.
Under ``search="auto"`` the taus around each significant dip that the
candidate lists approximated are then recomputed with the tree search and the
same queries (:func:`_polish`): the lists' errors are small but not uniform in
tau, and a dip's centre and width are read off differences between
neighbouring taus.

Tasks are ``(m, chunk of taus)`` scans and slices of the candidate lists
(:func:`list_slice`), all dispatched through joblib, so any ``n_jobs`` is kept
busy and ``joblib.parallel_config(backend="dask")`` runs the scan unchanged,
list build included.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from itertools import pairwise
from numbers import Real

import numba
import numpy as np
from joblib import Parallel, delayed, effective_n_jobs
from numba import njit
from scipy.spatial import cKDTree

from skdelay._checks import check_positive_int, check_random_state
from skdelay._dips import batch_table, locate_dips
from skdelay._embedding import second_window_start, two_window_columns
from skdelay._kdtree import (
    box_dist2,
    build_tree,
    insert_sorted,
    select_kth,
    window_knn_lists,
    window_knn_run,
)
from skdelay._neighbours import (
    RADIUS_CAP,
    chunk_slices,
    fit_from_series,
    fit_neighbourhood,
    neighbourhood_buffers,
    tree_neighbours,
)

__all__ = [
    "N_BATCHES",
    "REFINE_GROWTH",
    "TARGET_CENTRE_SE",
    "ScanOptions",
    "ScanResult",
    "candidate_lists",
    "cell_stats",
    "default_n_candidates",
    "list_index",
    "list_slice",
    "neighbourhood_mode",
    "scan_cells",
    "scan_series",
    "tree_cells",
    "window_components",
]

#: Contiguous query batches per cell for the standard error.  32 batch means give the
#: standard error itself to ~13 % (chi-square with 31 degrees of freedom), and a batch
#: of a 10^4-query cell (~300 queries, spread over ~3 % of the record) is much longer
#: than the correlation time of successive forecast errors.
N_BATCHES = 32
#: Target standard error (samples) of a dip centre; refinement stops below it.
TARGET_CENTRE_SE = 0.2
#: Factor by which each refinement round multiplies the queries of the dip cells
#: (halves their standard errors, since se ~ 1 / sqrt(n_queries)).
REFINE_GROWTH = 4
#: At most this many refinement rounds (16x the coarse queries).  A broad dip (an
#: oversampled record: half-widths of tens of samples) keeps a centre error above the
#: target whatever the queries, and refining it to every point cost 100x the coarse scan
#: (135 s instead of 1.5 s on Mackey-Glass sampled 20x finer than usual).
MAX_REFINE_ROUNDS = 2
#: Rounds of exact neighbours on the dip cells (:func:`_polish`): a second round only
#: when the polished dip moved onto cells the first did not reach.
POLISH_ROUNDS = 2
#: Tasks per worker and m: several chunks of taus per worker balance the unequal
#: cost of the m values and of a loaded machine without re-sending lists too often.
TASKS_PER_WORKER = 4
#: Memory (bytes) of the default candidate lists of one m (int32, ``n_needed * K``): the
#: list build costs ~ n_needed * K neighbour-query work too, so this also bounds its
#: time.  10^5 rows keep the accurate 8k candidates; 10^6 rows get 67 (the paper-scale
#: scan, where 240 took over 10 minutes of single-threaded k-d tree queries per m).
LIST_BYTES = 1 << 28
#: Leaf size of the k-d tree of the candidate lists: lists of tens of neighbours read
#: many leaves, and larger leaves cut the node overhead (measured on 10^6 noisy 12-bit
#: Mackey-Glass points, 67 neighbours, one thread: m = 5 lists 29 / 17 / 17 / 19 us per
#: time at leaf sizes 12 / 64 / 128 / 256; m = 2: 11 / 8 / 8 / 10 us).
LIST_LEAF_SIZE = 64
#: Slices of the needed times of one list build, each followed by a progress report
#: (a list build takes tens of seconds at 10^6 points).
LIST_SLICES = 8
#: Arrays larger than this (bytes) are handed to process workers as one memory map
#: written once, instead of joblib hashing and dumping them again for every task.
SHARE_BYTES = 1 << 24
#: Principal components per window in the projected k-d tree of the tree search (a tree
#: on 2 x 2 dimensions).  Measured on 2*10^4 noisy 12-bit Mackey-Glass points (delay 100,
#: m = 5, k = 30, tau = 80..120): two components hold 99.98 % of the window variance, and a
#: query computes the full 2m-dimensional distance of 16 points (k-NN from its
#: predecessor's neighbours included), after 60 tree nodes and 171 projected distances.
#: More components tighten the bound but slow the tree; the result is exact either way.
TREE_COMPONENTS = 2
#: :func:`tree_cells` copies the tree's points in full (``2m`` values, tree order) when
#: there is at least one query per this many database rows; below that the copy costs
#: more than the queries save by reading it instead of the scattered series.
LOCAL_COPY = 64
#: Leaf size of the per-tau trees (16 and 32 points per leaf: the same work within 10 %
#: on the case above, 8: 20 % more).
TREE_LEAF_SIZE = 16
#: ``search="auto"`` costs for one ``(m, chunk of taus)`` cell (:func:`_use_tree`),
#: in microseconds of one core.  Fitted on a 2-core machine (one other job running) to
#: coarse passes of noisy 12-bit Mackey-Glass (delay 100, m = 2..5, tau = 1..200, k = 30,
#: one worker, ``refine=False``) at 3*10^4 rows (500 and 2000 queries) and 10^5 rows
#: (1000, 4000 and 10^4 queries), ``python benchmarks/delay_scan.py --part c``:
#:
#: * the tree search builds one tree per tau, ``TREE_BUILD * n log2 n`` (0.014-0.016 us),
#:   and searches and fits each query, ``TREE_QUERY`` (4.9 us at 3*10^4 rows, 7.1 at 10^5);
#: * the candidate lists cost ``LIST_ROW`` per needed time and candidate (36-38 us per
#:   time with 240 candidates) and their re-ranking ``LIST_QUERY`` per query and candidate,
#:   plus one fit (8.8-9.4 us per query with 240 candidates).
#:
#: The old rule (the lists above 10 database rows per query) took the lists for all but
#: the last of these five passes, although the tree was faster in four of them (by 12 %,
#: 30 %, 7 % and 15 %; the lists by 13 % at 10^5 rows and 1000 queries) and is exact.
TREE_BUILD, TREE_QUERY = 0.015, 6.0
LIST_ROW, LIST_QUERY, FIT_QUERY = 0.15, 0.033, 1.2
#: The lists are approximate (sigma up to 3.5 % off at 10^5 rows; 2.7 % median, 5.9 % at
#: most, near the dip of 10^6 rows with their 67 candidates), so ``"auto"`` takes them only
#: where the model expects them to cost less than half the trees: the paper-scale coarse
#: pass (10^6 rows, 10^4 queries, 500 taus: 6.7x by the model; the lists' 146 s of CPU
#: there were measured), not a full-precision scan of the dip region of the same record
#: (1.6x: without this factor the benchmark's exact reference itself ran on the lists, 2.9 %
#: median from the exact neighbourhoods of the default scan's dip), nor 10^5 rows with 1000
#: queries (the lists 10-13 % faster).
LIST_ADVANTAGE = 2.0

_MODES = {"none": "none", "segment": "segment", "radius": "radius"}


def default_n_candidates(k, n_rows=0):
    """Candidates per window and query of the candidate search.

    ``max(8 k, 64)``, reduced for long records so that the lists of ``n_rows``
    needed times fit :data:`LIST_BYTES` (256 MB), but never below ``2 k``.

    Measured on 3*10^4 noisy 12-bit Mackey-Glass points (delay 100, ``k = 30``,
    m = 2 and 4, six delays around and away from the dip, 3000 queries): the
    relative difference of sigma to the exact search was, median / max,
    1.0 % / 4.8 % for ``2k`` candidates, 1.7 % / 2.9 % for ``4k`` and
    0.3 % / 2.0 % for ``8k`` (exact neighbourhoods: < 0.1 %, 1-4 %, 15-26 %).
    Below ``64`` the lists of small ``k`` miss too much of the other window.
    The price is memory and time: the lists hold ``n_rows * n_candidates``
    int32 per ``m`` (1 GB for 10^6 rows at 240) and cost as many neighbour
    queries, hence the cap; pass ``n_candidates`` to override it.

    Examples
    --------
    >>> from skdelay._scan import default_n_candidates
    >>> default_n_candidates(30), default_n_candidates(4), default_n_candidates(30, 10**6)
    (240, 64, 67)
    """
    accurate = max(8 * int(k), 64)
    if n_rows > 0:
        accurate = min(accurate, LIST_BYTES // (4 * int(n_rows)))
    return max(accurate, 2 * int(k))


def neighbourhood_mode(value):
    """Named mode of the public ``equal_neighbourhood`` values.

    ``False``/``None`` -> ``"none"``, ``True``/``"segment"`` -> ``"segment"``,
    ``"radius"`` -> ``"radius"``.
    """
    if value is None or value is False or (isinstance(value, np.bool_) and not value):
        return "none"
    if value is True or (isinstance(value, np.bool_) and value):
        return "segment"
    if isinstance(value, str) and value in _MODES:
        return _MODES[value]
    raise ValueError(
        "equal_neighbourhood must be False, True/'segment' (shorter series for smaller m) "
        f"or 'radius' (one neighbourhood radius for every m), got {value!r}."
    )


@dataclass(frozen=True)
class ScanOptions:
    """Validated settings of one delay scan (built once, passed to every task).

    Parameters
    ----------
    k : int, default=30
        Neighbourhood size.
    order : {1, 0}, default=1
        Local linear or local constant fits.
    ridge : float, default=1e-3
        Relative ridge of the local fits (>= 0).
    radius : float or None, default=None
        Radius neighbourhoods (in the units of the scanned series) with k-NN fallback.
    theiler : int, default=0
        Temporal exclusion of the in-sample error (out-of-sample splits ignore it).
    search : {"auto", "tree", "candidates", "exact"}, default="auto"
        Neighbour search (see the module notes; radius neighbourhoods use
        ``"candidates"`` under ``"auto"``).
    n_candidates : int, default=None
        Candidates per window for ``"candidates"``; None: :func:`default_n_candidates`
        of the number of needed times (see :meth:`candidates_for`).
    neighbourhood : {"none", "segment", "radius"} or bool, default="none"
        Equal neighbourhood size for every ``m`` (normalised by :func:`neighbourhood_mode`).
    n_queries : int or None, default=None
        Queries of the coarse pass per cell; None: every row.
    refine : bool, default=True
        Recompute the taus around each dip with more queries (see the module notes).
    target_centre_se : float, default=TARGET_CENTRE_SE
        Refinement stops when every dip centre's standard error is below this.
    centre_error : {"batches", "redraws"}, default="batches"
        The centre error that refinement targets and that sets how far around
        the dip it and the polish reach (see the module notes).

    Examples
    --------
    >>> from skdelay._scan import ScanOptions
    >>> ScanOptions(k=10).candidates_for(1000), ScanOptions(k=10, n_candidates=12).n_candidates
    (80, 12)
    >>> ScanOptions(k=10, n_candidates=5)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: n_candidates=5 is smaller than n_neighbors=10: ... use n_candidates >= 10 ...
    """

    k: int = 30
    order: int = 1
    ridge: float = 1e-3
    radius: float | None = None
    theiler: int = 0
    search: str = "auto"
    n_candidates: int | None = None
    neighbourhood: str = "none"
    n_queries: int | None = None
    refine: bool = True
    target_centre_se: float = TARGET_CENTRE_SE
    centre_error: str = "batches"

    def __post_init__(self):
        k = check_positive_int(self.k, name="n_neighbors")
        if isinstance(self.order, (bool, np.bool_)) or self.order not in (0, 1):
            raise ValueError(f"order must be 0 (local constant) or 1 (local linear), got "
                             f"{self.order!r}.")
        if not isinstance(self.ridge, Real) or not self.ridge >= 0 or not np.isfinite(self.ridge):
            raise ValueError(f"ridge must be a finite number >= 0 (relative to the "
                             f"neighbourhood's variance, e.g. 1e-3), got {self.ridge!r}.")
        if self.radius is not None and (not isinstance(self.radius, Real)
                                        or not self.radius > 0 or not np.isfinite(self.radius)):
            raise ValueError(f"radius must be None (k-NN) or a finite number > 0 in the units "
                             f"of the series, got {self.radius!r}.")
        theiler = check_positive_int(self.theiler, name="theiler_window", minimum=0)
        if self.search not in ("auto", "tree", "candidates", "exact"):
            raise ValueError(f"search must be 'auto', 'tree', 'candidates' or 'exact', got "
                             f"{self.search!r}.")
        if self.n_candidates is None:
            n_cand = None
        else:
            n_cand = check_positive_int(self.n_candidates, name="n_candidates")
            if n_cand < k:
                raise ValueError(
                    f"n_candidates={n_cand} is smaller than n_neighbors={k}: the re-ranked "
                    f"candidates could not fill a neighbourhood; use n_candidates >= {k} "
                    "(default max(8 k, 64), fewer for long records)."
                )
        n_queries = (None if self.n_queries is None
                     else check_positive_int(self.n_queries, name="n_queries"))
        if not isinstance(self.target_centre_se, Real) or not self.target_centre_se > 0:
            raise ValueError(f"target_centre_se must be > 0 samples, got "
                             f"{self.target_centre_se!r}.")
        if self.centre_error not in ("batches", "redraws"):
            raise ValueError(f"centre_error must be 'batches' or 'redraws', got "
                             f"{self.centre_error!r}.")
        for name, value in (("k", k), ("theiler", theiler), ("n_candidates", n_cand),
                            ("n_queries", n_queries), ("order", int(self.order)),
                            ("ridge", float(self.ridge)), ("refine", bool(self.refine)),
                            ("neighbourhood", neighbourhood_mode(self.neighbourhood)),
                            ("radius", None if self.radius is None else float(self.radius))):
            object.__setattr__(self, name, value)

    def candidates_for(self, n_needed):
        """Candidates per window for lists of ``n_needed`` times."""
        if self.n_candidates is not None:
            return self.n_candidates
        return default_n_candidates(self.k, n_needed)

    def check_rows(self, n_rows, *, in_sample=True):
        """Raise ValueError unless ``n_rows`` rows leave a neighbourhood for every query."""
        if in_sample and self.theiler >= n_rows:
            raise ValueError(
                f"theiler_window={self.theiler} is not shorter than the {n_rows} rows of the "
                "scan; use a smaller theiler_window or a longer series."
            )
        free = n_rows - (2 * self.theiler + 1 if in_sample else 0)
        if free < self.k:
            raise ValueError(
                f"theiler_window={self.theiler} leaves {max(free, 0)} of the {n_rows} rows as "
                f"neighbours of a query, fewer than n_neighbors={self.k}; use a smaller "
                "theiler_window, fewer neighbours, a smaller tau/m range or a longer series."
            )


@dataclass
class ScanResult:
    """Raw output of :func:`scan_series` (errors in the units of the scanned series).

    Arrays are ``(n_splits, n_m, n_tau)``: ``error`` (rms one-step error),
    ``se`` (its standard error), ``n_queries`` and ``exact`` (fraction of
    provably exact neighbourhoods); ``coarse`` ``(n_m, n_tau)`` marks cells not
    refined beyond the coarse pass; ``batch_msq`` ``(n_splits, n_m, n_tau,
    N_BATCHES)`` holds each cell's mean squared error per query batch (NaN: no
    such batch), for the bootstrap of the dip centre (:mod:`skdelay._dips`).
    """

    error: np.ndarray
    se: np.ndarray
    batch_msq: np.ndarray
    n_queries: np.ndarray
    exact: np.ndarray
    coarse: np.ndarray
    segment_length: dict
    radius: float | None


# ----------------------------------------------------------------------------- kernels
@njit(cache=True, inline="always")
def _slot(table, j):
    """Slot of ``j`` in an open-addressing hash set (its own, or the empty one to fill).

    ``table`` has a power-of-two size, ``-1`` marks empty slots; linear probing.
    """
    mask = table.size - 1
    h = (j * 2654435761) & mask
    while table[h] != -1 and table[h] != j:
        h = (h + 1) & mask
    return h


@njit(cache=True, nogil=True)
def scan_cells(s, q_t, lists, rk2, row_of, u_min, starts, m, k, radius2, width, is_db,
               ridge, order, fallback, sq, n_exact):
    """Squared one-step errors of a chunk of taus: re-rank the candidates and fit, compiled.

    For every query ``q`` of ``q_t`` and start ``c`` of ``starts`` (one per
    tau): the candidates are ``lists[row_of[q - u_min]]`` (first window) and
    ``lists[row_of[q - c - u_min]] + c`` (second window), kept if they are
    database times (``is_db``); duplicates are skipped with a small hash set.
    The ``k`` nearest by the exact 2m-dimensional distance (or, with
    ``radius2 > 0``, up to ``width`` within ``max(radius2, k-th distance)``)
    are fitted by :func:`~skdelay._neighbours.fit_neighbourhood`.  Adds the
    squared error to ``sq[tau_index, batch]`` (batch ``i * n_batches //
    n_queries`` of query ``i``) and counts in ``n_exact[tau_index]`` the
    queries whose neighbourhood is provably exact (k-th distance within
    ``rk2[q] + rk2[q - c]``).

    Queries are the outer loop: a query's first-window candidates and their
    first-window distances are read once and reused for every tau of the chunk
    (the reads of scattered series values dominate the cost).
    """
    n_q = q_t.size
    n_tau = starts.size
    n_batches = sq.shape[1]
    kk = lists.shape[1]
    p = 2 * m
    first = np.empty(kk, dtype=np.int64)
    first_d = np.empty(kk)
    cand = np.empty(2 * kk, dtype=np.int64)
    dist = np.empty(2 * kk)
    scratch = np.empty(2 * kk)
    no_items = np.empty(0, dtype=np.int64)  # select_kth reorders the distances only
    size = 1
    while size < 4 * kk:  # load factor <= 1/2 keeps linear probing short
        size *= 2
    table = np.full(size, -1, dtype=np.int64)
    touched = np.empty(2 * kk, dtype=np.int64)
    Vn, yn, w, vq, fit_buf, a = neighbourhood_buffers(width, p)
    n_max = is_db.size
    for i in range(n_q):
        q = q_t[i]
        r1 = row_of[q - u_min]
        batch = (i * n_batches) // n_q
        n1 = 0
        for c in range(kk):  # first-window candidates: the same for every tau
            j = np.int64(lists[r1, c])
            if j < 0 or j >= n_max or not is_db[j]:
                continue
            h = _slot(table, j)
            if table[h] == j:
                continue
            table[h] = j
            touched[n1] = h
            acc = 0.0
            for lag in range(m):
                d = s[q - lag] - s[j - lag]
                acc += d * d
            first[n1] = j
            first_d[n1] = acc
            n1 += 1
        for lag in range(m):
            vq[lag] = s[q - lag]
        for it in range(n_tau):
            c0 = starts[it]
            r2 = row_of[q - c0 - u_min]
            for lag in range(m):
                vq[m + lag] = s[q - c0 - lag]
            nc = 0
            for c in range(n1):
                j = first[c]
                acc = first_d[c]
                for lag in range(m):
                    d = vq[m + lag] - s[j - c0 - lag]
                    acc += d * d
                cand[nc] = j
                dist[nc] = acc
                nc += 1
            n2 = n1
            for c in range(kk):  # second-window candidates of this tau
                j = np.int64(lists[r2, c])
                if j < 0:
                    continue
                j += c0
                if j >= n_max or not is_db[j]:
                    continue
                h = _slot(table, j)
                if table[h] == j:
                    continue
                table[h] = j
                touched[n2] = h
                n2 += 1
                acc = 0.0
                for lag in range(m):
                    d = vq[lag] - s[j - lag]
                    acc += d * d
                    d = vq[m + lag] - s[j - c0 - lag]
                    acc += d * d
                cand[nc] = j
                dist[nc] = acc
                nc += 1
            # drop this tau's entries; they were inserted after the first-window ones,
            # so the probe chains of those stay intact
            for c in range(n1, n2):
                table[touched[c]] = -1
            if nc == 0:
                pred = fallback
            else:
                scratch[:nc] = dist[:nc]
                reach = max(select_kth(scratch, no_items, 0, nc, min(k, nc) - 1), radius2)
                if reach <= rk2[r1] + rk2[r2]:
                    n_exact[it] += 1
                used = 0
                for c in range(nc):
                    if dist[c] <= reach and used < width:
                        j = cand[c]
                        for lag in range(m):
                            Vn[used, lag] = s[j - lag]
                            Vn[used, m + lag] = s[j - c0 - lag]
                        yn[used] = s[j + 1]
                        w[used] = 1.0
                        used += 1
                for c in range(used, width):
                    w[c] = 0.0
                _, pred = fit_neighbourhood(Vn, yn, w, vq, ridge, order, fallback, fit_buf, a)
            e = pred - s[q + 1]
            sq[it, batch] += e * e
        for c in range(n1):
            table[touched[c]] = -1


# The two helpers below stand in for np.searchsorted and np.argsort, whose numba
# implementations took 1.8 and 2.6 s of the 9 s that tree_cells took to compile (numba
# 0.68.1, cold cache): every test process and loky worker of a fresh checkout pays it.
@njit(cache=True, nogil=True)
def _rows_of(db_t, q_t):
    """``np.searchsorted(db_t, q_t)`` (left side) for sorted ``db_t``: binary search."""
    out = np.empty(q_t.size, dtype=np.int64)
    for i in range(q_t.size):
        lo, hi = 0, db_t.size
        while lo < hi:
            mid = (lo + hi) // 2
            if db_t[mid] < q_t[i]:
                lo = mid + 1
            else:
                hi = mid
        out[i] = lo
    return out


@njit(cache=True, nogil=True)
def _order_by(keys, first, q_order):
    """``q_order[:] = argsort(keys)``, stable: a counting sort over the keys, which lie in
    ``0 .. first.size - 2`` (``first``: scratch)."""
    first[:] = 0
    for i in range(keys.size):
        first[keys[i] + 1] += 1
    for r in range(first.size - 1):
        first[r + 1] += first[r]
    for i in range(keys.size):
        pos = keys[i]
        q_order[first[pos]] = i
        first[pos] += 1


@njit(cache=True, nogil=True)
def _leaf_of(qp, left, right, box_lo, box_hi):
    """The leaf a point descends to: at every node the child whose box is nearer."""
    node = 0
    while left[node] >= 0:
        a, b = left[node], right[node]
        if box_dist2(qp, box_lo, box_hi, b) < box_dist2(qp, box_lo, box_hi, a):
            node = b
        else:
            node = a
    return node


@njit(cache=True, nogil=True)
def tree_cells(s, U, q_t, db_t, m, starts, k, theiler, ridge, order, fallback, leaf, sq,
               chunk):
    """Exact k-NN and local fits of every tau of ``starts`` for the queries ``q_t``, compiled.

    For each tau (second-window start ``c``) a k-d tree is built on the
    projected vectors ``(U[j], U[j - c])`` of the database times ``db_t``,
    where ``U[t]`` holds the leading principal components of the window
    ``s[t - lag]`` (``lag = 0..m-1``; orthonormal directions, so the projected
    squared distance never exceeds the 2m-dimensional one).  A depth-first
    search, nearer child first, prunes a box when its projected distance
    reaches the current ``k``-th 2m-dimensional distance, and a point when its
    projected distance does; the others get their exact distance.  When the
    search ends no unvisited point can be nearer than the ``k``-th neighbour, so
    the neighbourhood is the exact k-NN (up to the order of equal distances).
    The tree's points, projected and full (``2m`` values), are copied in the
    tree's order, so a leaf's points and their exact distances are read from
    contiguous memory, and the neighbours are kept sorted by distance (an
    insertion, not a heap: the fit reads them nearest first).

    The search starts empty.  Starting it from the previous query's neighbours
    (or, for held-out queries, from the neighbours of ``q - 1`` one sample on)
    did not pay: the first leaves bound it as tightly (on 10^5 noisy 12-bit
    Mackey-Glass points, k = 30, m = 2, a query visited 61 nodes and 210 points
    seeded, 63 and 221 unseeded), and the seeds' exact distances and the
    bookkeeping that kept them out of the heap cost more than they pruned.
    Unseeded, with the sorted neighbours and the copy, the scan took 11-13 %
    less CPU than seeded with a heap (``python benchmarks/delay_scan.py --part
    a --quick``, against 63631c8 in the same session; per tau,
    ``benchmarks/tree_build.py``).  The queries run in the
    tree's order, so that consecutive queries read the same boxes and leaves
    from cache: a query that is a database time (as in every scan without a
    time-series split) at its own place in the tree, a held-out query (the test
    fold of a time-series split, scored against a training database) at the
    leaf it descends to (:func:`_leaf_of`).  On the case above, every point a
    query, 4.65 / 5.39 / 6.77 us per query and tau at m = 2 / 3 / 5 against
    5.57 / 6.15 / 6.98 in time order; the held-out queries of a 2-fold
    time-series split of 10^5 samples took 14-19 % less time than in time order
    on Mackey-Glass (m = 2 and 4) and on noisy Ikeda at m = 2, the same at m = 4
    (``python benchmarks/tree_build.py --n 100000 --held-out-only``, with the
    seeds' removal).  Each query's error still counts in its own batch
    (its place in ``q_t``).  Database times within ``theiler`` samples of the
    query are skipped (``theiler < 0``: none).

    Adds the squared errors to ``sq[tau_index, batch]`` (batch ``i * n_batches
    // n_queries`` of query ``i``).

    The result is that of the plain k-d tree (:func:`_exact_task`) to the last bit, not
    only the same neighbourhoods: each neighbourhood is fitted in order of distance, as the
    plain tree returns it, with the distances computed in the same order of operations, and
    the squared errors are summed in query order per batch, over the same slices of
    ``chunk`` queries.  Only the order of points at equal distances (a series that repeats
    values), or at distances within rounding of each other, can differ, and with it the
    fit.
    """
    n_db = db_t.size
    p = U.shape[1]
    pp2 = 2 * p
    width = 2 * m
    n_tau = starts.size
    n_batches = sq.shape[1]
    n_q = q_t.size
    # queries that are database times run in the tree's order (both sorted and unique)
    q_row = _rows_of(db_t, q_t)
    in_tree_order = True
    for i in range(n_q):
        if q_row[i] >= n_db or db_t[q_row[i]] != q_t[i]:
            in_tree_order = False
            break
    tree_pos = np.empty(n_db, dtype=np.int64)
    q_order = np.empty(n_q, dtype=np.int64)
    q_key = np.empty(n_q, dtype=np.int64)
    first = np.empty(n_db + 1, dtype=np.int64)
    data = np.empty((n_db, pp2))
    sdata = np.empty((n_db, pp2))  # projected points in tree order
    # and their 2m-dimensional vectors, where enough queries read them to repay the copy
    # (about 8 ns per row against 0.3-0.7 us saved per query on 6000 noisy Ikeda and
    # Mackey-Glass points: benchmarks/tree_build.py)
    local = LOCAL_COPY * n_q >= n_db
    sfull = np.empty((n_db if local else 0, width))
    sids = np.empty(n_db, dtype=np.int64)
    qp = np.empty(pp2)
    hd = np.empty(k)  # the k nearest so far: squared distances ascending ...
    hj = np.empty(k, dtype=np.int64)  # ... and their tree positions
    stack = np.empty(256, dtype=np.int64)
    stack_d = np.empty(256)
    Vn, yn, w, vq, fit_buf, a = neighbourhood_buffers(k, width)
    e2 = np.empty(n_q)
    part = np.empty(n_batches)
    for it in range(n_tau):
        c = starts[it]
        for r in range(n_db):
            j = db_t[r]
            for f in range(p):
                data[r, f] = U[j, f]
                data[r, p + f] = U[j - c, f]
        perm, start, stop, left, right, box_lo, box_hi = build_tree(data, leaf)
        if in_tree_order:
            for r in range(n_db):
                tree_pos[perm[r]] = r
            for i in range(n_q):
                q_key[i] = tree_pos[q_row[i]]
        else:  # the first position of the leaf each query descends to
            for i in range(n_q):
                q = q_t[i]
                for f in range(p):
                    qp[f] = U[q, f]
                    qp[p + f] = U[q - c, f]
                q_key[i] = start[_leaf_of(qp, left, right, box_lo, box_hi)]
        _order_by(q_key, first, q_order)
        for r in range(n_db):
            j = db_t[perm[r]]
            sids[r] = j
            for f in range(pp2):
                sdata[r, f] = data[perm[r], f]
            if local:
                for lag in range(m):
                    sfull[r, lag] = s[j - lag]
                    sfull[r, m + lag] = s[j - c - lag]
        for r0 in range(n_q):
            i = q_order[r0]  # the query's place in q_t
            q = q_t[i]
            for f in range(p):
                qp[f] = U[q, f]
                qp[p + f] = U[q - c, f]
            for lag in range(m):
                vq[lag] = s[q - lag]
                vq[m + lag] = s[q - c - lag]
            for x in range(k):
                hd[x] = np.inf
                hj[x] = -1
            held = 0
            stack[0] = 0
            stack_d[0] = 0.0
            sp = 1
            while sp > 0:  # depth first, nearer child first; boxes keep their distance
                sp -= 1
                if stack_d[sp] >= hd[k - 1]:
                    continue
                node = stack[sp]
                if left[node] >= 0:
                    lc, rc = left[node], right[node]
                    dl = box_dist2(qp, box_lo, box_hi, lc)
                    dr = box_dist2(qp, box_lo, box_hi, rc)
                    if dl > dr:
                        lc, rc, dl, dr = rc, lc, dr, dl
                    if dr < hd[k - 1]:
                        stack[sp] = rc
                        stack_d[sp] = dr
                        sp += 1
                    if dl < hd[k - 1]:
                        stack[sp] = lc
                        stack_d[sp] = dl
                        sp += 1
                    continue
                for r in range(start[node], stop[node]):
                    pd = 0.0
                    for f in range(pp2):
                        d1 = sdata[r, f] - qp[f]
                        pd += d1 * d1
                    if pd >= hd[k - 1]:
                        continue
                    if theiler >= 0 and abs(sids[r] - q) <= theiler:
                        continue
                    acc = 0.0
                    if local:
                        for lag in range(m):
                            d1 = vq[lag] - sfull[r, lag]
                            d2 = vq[m + lag] - sfull[r, m + lag]
                            acc += d1 * d1 + d2 * d2
                    else:
                        j = sids[r]
                        for lag in range(m):
                            d1 = vq[lag] - s[j - lag]
                            d2 = vq[m + lag] - s[j - c - lag]
                            acc += d1 * d1 + d2 * d2
                    if acc < hd[k - 1]:
                        held = insert_sorted(hd, hj, k, acc, r, held)
            for x in range(k):  # the plain tree's order: nearest first, empty slots last
                r = hj[x]
                if r < 0:
                    w[x] = 0.0
                    yn[x] = 0.0
                    for f in range(width):
                        Vn[x, f] = 0.0
                    continue
                w[x] = 1.0
                j = sids[r]
                yn[x] = s[j + 1]
                for lag in range(m):
                    Vn[x, lag] = s[j - lag]
                    Vn[x, m + lag] = s[j - c - lag]
            _, pred = fit_neighbourhood(Vn, yn, w, vq, ridge, order, fallback, fit_buf, a)
            e = pred - s[q + 1]
            e2[i] = e * e
        for lo in range(0, n_q, chunk):  # as np.bincount over each slice, then added
            part[:] = 0.0
            for i in range(lo, min(n_q, lo + chunk)):
                part[(i * n_batches) // n_q] += e2[i]
            for b in range(n_batches):
                sq[it, b] += part[b]


def window_components(s, m, times, n_components):
    """Leading principal components of the windows ``s[t - lag]`` (``lag = 0..m-1``).

    The directions come from the windows of ``times``; returns ``U`` (``(s.size,
    n_components)``, rows before ``m - 1`` are zero) with ``U[t]`` the window of
    ``t`` projected on them.  Orthonormal directions: a projected distance is a
    lower bound of the window distance.
    """
    W = s[np.asarray(times)[:, None] - np.arange(m)]
    _, vecs = np.linalg.eigh(np.cov(W, rowvar=False).reshape(m, m))
    P = np.ascontiguousarray(vecs[:, ::-1][:, :n_components])
    U = np.zeros((s.size, n_components))
    for lag in range(m):
        U[m - 1:] += s[m - 1 - lag: s.size - lag, None] * P[lag]
    return U


def list_index(s, m, members):
    """The k-d tree of the member windows for :func:`candidate_lists`.

    Returns ``(tree, sdata, sids, is_member)``: the tree of
    :func:`skdelay._kdtree.build_tree`, the member windows and times in tree
    order, and a boolean mask of the members (one past the last member).
    """
    members = np.asarray(members, dtype=np.int64)
    data = np.ascontiguousarray(s[members[:, None] - np.arange(m)])
    tree = build_tree(data, LIST_LEAF_SIZE)
    sdata = np.ascontiguousarray(data[tree[0]])
    sids = np.ascontiguousarray(members[tree[0]])
    is_member = np.zeros(int(members.max()) + 2, dtype=np.bool_)
    is_member[members] = True
    return tree, sdata, sids, is_member


def list_slice(s, m, index, needed, k, theiler, n_threads=1, out=None):
    """``(lists, rk2)`` of the times ``needed`` (a slice of them) on the tree ``index``.

    ``k`` neighbours per time (at most the number of members); see
    :func:`candidate_lists`.  Runs on ``n_threads`` numba threads: one inside a
    joblib task, where the tasks themselves are the parallelism.  ``out``: the
    rows of this slice in arrays of the whole list (``(needed.size, k)`` int32
    and ``needed.size`` float64, C-contiguous), filled in place and returned;
    thread workers then build one list without a concatenation afterwards.
    """
    tree, sdata, sids, is_member = (tuple(np.asarray(a) for a in index[0]),
                                    *(np.asarray(a) for a in index[1:]))
    needed = np.ascontiguousarray(needed, dtype=np.int64)
    if needed.size and int(needed.max()) + 2 > is_member.size:  # times past the last member
        grown = np.zeros(int(needed.max()) + 2, dtype=np.bool_)
        grown[: is_member.size] = is_member
        is_member = grown
    if out is None:
        lists = np.full((needed.size, k), -1, dtype=np.int32)
        rk2 = np.full(needed.size, np.inf)
    else:  # every row is written by the search below
        lists, rk2 = out
    if needed.size == 0:
        return lists, rk2
    s64 = np.ascontiguousarray(s, dtype=np.float64)
    theiler = -1 if theiler is None else int(theiler)
    n_threads = max(1, min(int(n_threads), numba.config.NUMBA_NUM_THREADS))
    if n_threads == 1:  # a task: no parallel region (tasks may be threads themselves)
        window_knn_run(s64, int(m), is_member, tree, sdata, sids, needed, 0, needed.size, k,
                       theiler, lists, rk2)
        return lists, rk2
    before = numba.get_num_threads()
    numba.set_num_threads(n_threads)
    try:
        n_chunks = max(1, min(needed.size // 64, 16 * n_threads))
        window_knn_lists(s64, int(m), is_member, tree, sdata, sids, needed, k, theiler,
                         n_chunks, lists, rk2)
    finally:
        numba.set_num_threads(before)
    return lists, rk2


def _list_cuts(n_needed, n_slices):
    """Boundaries of the slices of the needed times (at least 10^4 times per slice)."""
    n_slices = max(1, min(n_slices, n_needed // 10_000))
    return np.linspace(0, n_needed, n_slices + 1).astype(np.int64)


def _padded(parts, n_list):
    """Lists of ``n_list`` columns from the slices (short lists: ``rk2`` becomes inf)."""
    lists = np.concatenate([p[0] for p in parts]) if len(parts) > 1 else parts[0][0]
    rk2 = np.concatenate([p[1] for p in parts]) if len(parts) > 1 else parts[0][1]
    if lists.shape[1] < n_list:
        full = np.full((lists.shape[0], n_list), -1, dtype=np.int32)
        full[:, : lists.shape[1]] = lists
        lists, rk2 = full, np.full_like(rk2, np.inf)
    return lists, rk2


def candidate_lists(s, m, members, needed, n_list, theiler, workers=1, progress=None):
    """``n_list`` nearest first-window neighbours (times, -1 = none) of every needed time.

    Neighbours come from ``members`` (times); with ``theiler`` (None: no
    exclusion), members within ``theiler`` samples of the needed time are
    skipped during the search, so every list holds the ``n_list`` nearest
    eligible members (-1 pads a list only when fewer exist).  Returns
    ``lists`` (int32, ``(needed.size, n_list)``) and ``rk2``, the squared
    distance of the last neighbour (``inf`` for a short list): every eligible
    member outside a list is at least that far away.

    One compiled k-d tree search per needed time
    (:func:`skdelay._kdtree.window_knn_lists`), threaded over ``workers``
    threads; consecutive needed times start from the shifted neighbours of
    their predecessor, which bounds the search at once.  ``progress``: called
    as ``progress(done, total)`` after each of up to :data:`LIST_SLICES` slices
    of the needed times.  The scan runs the same slices
    (:func:`list_slice`) as joblib tasks instead.
    """
    members = np.asarray(members, dtype=np.int64)
    needed = np.ascontiguousarray(needed, dtype=np.int64)
    index = list_index(s, m, members)
    k = int(min(n_list, members.size))
    cuts = _list_cuts(needed.size, LIST_SLICES)
    parts = []
    for n, (lo, hi) in enumerate(pairwise(cuts)):
        parts.append(list_slice(s, m, index, needed[lo:hi], k, theiler, workers))
        if progress is not None:
            progress(n + 1, cuts.size - 1)
    return _padded(parts, n_list)


def _batch_ids(n_q, n_batches):
    return (np.arange(n_q) * n_batches) // n_q


def _exact_task(s, m, taus, db_t, q_t, opt, n_batches):
    """Reference search: a k-d tree on the 2m-dimensional vectors for every tau."""
    sq = np.zeros((len(taus), n_batches))
    fallback = float(s[db_t + 1].mean())
    batch = _batch_ids(q_t.size, n_batches)
    theiler = opt["theiler"]
    for i, tau in enumerate(taus):
        cols = two_window_columns(m, int(tau))
        tree = cKDTree(s[db_t[:, None] - cols])
        kk = opt["k"] * (RADIUS_CAP if opt["radius"] else 1)
        for sl in chunk_slices(q_t.size, kk * 2 * m):
            pos, weight = tree_neighbours(
                tree, s[q_t[sl, None] - cols], opt["k"], radius=opt["radius"],
                query_ids=None if theiler is None else q_t[sl], fit_ids=db_t,
                theiler_window=0 if theiler is None else theiler, workers=1)
            pred = fit_from_series(s, q_t[sl], db_t[pos], weight, cols, opt["ridge"],
                                   opt["order"], fallback)
            sq[i] += np.bincount(batch[sl], (pred - s[q_t[sl] + 1]) ** 2, minlength=n_batches)
    return sq, np.full(len(taus), q_t.size)


def _tree_task(s, U, m, starts, db_t, q_t, opt, n_batches):
    """One chunk of taus of one ``m``: exact k-NN by the projected k-d tree of each tau."""
    k = min(opt["k"], db_t.size)
    sq = np.zeros((starts.size, n_batches))
    theiler = -1 if opt["theiler"] is None else int(opt["theiler"])
    # the query slices of _exact_task, so that the sums are its sums
    chunk = chunk_slices(q_t.size, opt["k"] * 2 * m)[0].stop if q_t.size else 1
    tree_cells(s, np.asarray(U), q_t, db_t, m, starts, k, theiler, opt["ridge"],
               opt["order"], float(s[db_t + 1].mean()), TREE_LEAF_SIZE, sq, chunk)
    return sq, np.full(starts.size, q_t.size)


def _candidates_task(s, m, starts, db_t, q_t, shared, opt, n_batches):
    lists, rk2, row_of, u_min, is_db = (np.asarray(a) if isinstance(a, np.ndarray) else a
                                        for a in shared)
    k = min(opt["k"], db_t.size)
    width = k if opt["radius"] is None else min(2 * lists.shape[1], RADIUS_CAP * k)
    radius2 = 0.0 if opt["radius"] is None else opt["radius"] ** 2
    sq = np.zeros((starts.size, n_batches))
    n_exact = np.zeros(starts.size, dtype=np.int64)
    scan_cells(s, q_t, lists, rk2, row_of, u_min, starts, m, k, radius2, width, is_db,
               opt["ridge"], opt["order"], float(s[db_t + 1].mean()), sq, n_exact)
    return sq, n_exact


# ----------------------------------------------------------------------------- equal neighbourhoods
def _mean_kth_distance(s, m, tau, db_t, k, theiler, rng, n_probe=1000):
    cols = two_window_columns(m, tau)
    V = s[db_t[:, None] - cols]
    probes = rng.choice(db_t.size, size=min(n_probe, db_t.size), replace=False)
    pos, weight = tree_neighbours(cKDTree(V), V[probes], k, query_ids=db_t[probes],
                                  fit_ids=db_t, theiler_window=theiler)
    dist = np.linalg.norm(V[pos] - V[probes][:, None, :], axis=2)
    return float(np.where(weight, dist, 0.0).max(axis=1).mean())


def _segment_length(s, m, tau, db_t, k, theiler, d_ref, rng, n_min):
    """Length of the (last) database segment whose mean k-th distance is d_ref."""
    n_hi, d_hi = db_t.size, _mean_kth_distance(s, m, tau, db_t, k, theiler, rng)
    if d_hi >= d_ref:
        return n_hi
    while True:
        n_lo = max(n_min, n_hi // 2)
        d_lo = _mean_kth_distance(s, m, tau, db_t[-n_lo:], k, theiler, rng)
        if d_lo >= d_ref or n_lo == n_min:
            break
        n_hi, d_hi = n_lo, d_lo
    if d_lo < d_ref or d_lo == d_hi:
        return n_lo
    frac = (np.log(d_ref) - np.log(d_hi)) / (np.log(d_lo) - np.log(d_hi))
    return round(float(np.exp(np.log(n_hi) + frac * (np.log(n_lo) - np.log(n_hi)))))


# ----------------------------------------------------------------------------- driver
class _MappedArray(np.memmap):
    """A whole read-only memory map that pickles as its file's path.

    joblib's loky workers receive memory maps by path on their own, but Dask
    (and plain pickle) would copy the data into every task that holds it in a
    tuple: the paper-scale scan on a 2-worker LocalCluster spent 295 s CPU
    against 175 s in threads (benchmarks/out/scan_scaling.txt).  Views of it
    (slices) are not whole and pickle their data as usual.
    """

    _whole = False

    def __reduce_ex__(self, protocol):
        if self._whole and self.filename is not None:
            return np.load, (self.filename, "r")
        return np.asarray(self).__reduce_ex__(protocol)


class _Shared:
    """Arrays handed to process workers as memory maps written once (see SHARE_BYTES)."""

    def __init__(self, enabled):
        self.enabled = enabled
        self.folder = None
        self.count = 0

    def __call__(self, arr):
        if not self.enabled or arr.nbytes < SHARE_BYTES:
            return arr
        if self.folder is None:
            self.folder = tempfile.mkdtemp(prefix="skdelay-scan-")
        self.count += 1
        path = os.path.join(self.folder, f"a{self.count}.npy")
        np.save(path, arr)
        mapped = np.load(path, mmap_mode="r").view(_MappedArray)
        mapped._whole = True
        return mapped

    def release(self, arrays):
        """Delete the files of memory-mapped arrays whose tasks are done."""
        for arr in arrays:
            path = getattr(arr, "filename", None)
            if isinstance(arr, np.memmap) and path and self.folder \
                    and os.path.dirname(os.path.abspath(path)) == os.path.abspath(self.folder):
                os.remove(path)

    def close(self):
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)
            self.folder = None


def batch_means(sq, n_q):
    """Mean squared error per batch ``(n_cells, n_batches)`` from the per-batch sums
    ``sq`` of ``n_q`` queries (NaN for a batch without queries)."""
    n_b = sq.shape[1]
    counts = np.bincount(_batch_ids(n_q, n_b), minlength=n_b)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(counts > 0, sq / np.maximum(counts, 1), np.nan)


def cell_stats(sq, n_q):
    """rms error and its standard error from per-batch sums of squared errors.

    ``sq`` (n_cells, n_batches) holds the sums of the squared errors of the
    ``n_q`` queries cut into contiguous batches (query ``i`` in batch
    ``i * n_batches // n_q``).  The standard error of the mean square is the
    spread of the batch means over ``sqrt(n_batches)``; the delta method gives
    that of the rms, ``se / (2 rms)``.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._scan import cell_stats
    >>> e2 = np.random.default_rng(0).normal(size=6400) ** 2   # errors of unit variance
    >>> sq = np.bincount(np.arange(6400) * 32 // 6400, e2)[None, :]
    >>> rms, se = cell_stats(sq, 6400)
    >>> bool(abs(rms[0] - 1) < 3 * se[0]), bool(0.005 < se[0] < 0.015)  # ~ 1 / sqrt(2 n)
    (True, True)
    """
    rms = np.sqrt(sq.sum(axis=1) / n_q)
    means = batch_means(sq, n_q)
    used = np.bincount(_batch_ids(n_q, sq.shape[1]), minlength=sq.shape[1]) > 0
    if used.sum() < 2:
        return rms, np.full(rms.shape, np.nan)
    se_msq = means[:, used].std(axis=1, ddof=1) / math.sqrt(used.sum())
    with np.errstate(divide="ignore", invalid="ignore"):
        se = np.where(rms > 0, se_msq / (2 * rms), 0.0)
    return rms, se


def scan_series(s, ms, taus, splits, options, *, random_state=None, n_jobs=None, verbose=0,
                progress=False):
    """Forecast errors of every ``(split, m, tau)`` cell (not normalised) and their metadata.

    Parameters
    ----------
    s : ndarray of shape (n_samples,)
        The series (already rescaled to unit order, see ``Standardiser``).
    ms, taus : ndarray of int
        Sorted grids.
    splits : list of (ndarray, ndarray or None)
        ``(db_t, test_t)`` times; ``test_t=None`` is the in-sample,
        Theiler-excluded error over the database itself.
    options : ScanOptions
    random_state, n_jobs, verbose, progress
        Query subsets; joblib workers and verbosity; a tqdm bar over the tasks.

    Returns
    -------
    ScanResult

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._scan import ScanOptions, scan_series
    >>> rng = np.random.default_rng(0)
    >>> s = np.zeros(3000)
    >>> s[:9] = rng.uniform(size=9)
    >>> for t in range(8, 2999):   # delay 7
    ...     s[t + 1] = 0.5 * s[t] + 0.5 * (np.sin(3 * s[t - 6]) + np.sin(3 * s[t - 7]))
    >>> db = np.arange(15, 2999)
    >>> res = scan_series(s, [2], np.arange(1, 15), [(db, None)],
    ...                   ScanOptions(k=20, theiler=5, n_queries=500), random_state=0)
    >>> int(np.argmin(res.error[0, 0])) + 1, res.error.shape, bool(np.all(res.se > 0))
    (7, (1, 1, 14), True)
    """
    rng = check_random_state(random_state)
    opt = options
    n_workers = max(1, effective_n_jobs(n_jobs))
    n_m, n_tau, n_split = len(ms), len(taus), len(splits)
    ms = np.asarray(ms, dtype=np.int64)
    taus = np.asarray(taus, dtype=np.int64)
    err = np.full((n_split, n_m, n_tau), np.nan)
    se = np.full_like(err, np.nan)
    bmsq = np.full(err.shape + (N_BATCHES,), np.nan)
    nq = np.zeros(err.shape, dtype=np.int64)
    exact = np.zeros_like(err)
    seg_len, radius = {}, opt.radius
    plans = []  # per split: per m (db_m, query order)
    for db_t, test_t in splits:
        w = opt.theiler if test_t is None else None
        seg = {int(m): db_t.size for m in ms}
        rad = opt.radius
        if opt.neighbourhood != "none" and n_m > 1:
            tau_ref = int(np.median(taus))
            n_min = min(db_t.size, max(4 * opt.k + 2 * (w or 0) + 2, 50))
            d_ref = _mean_kth_distance(s, int(ms[-1]), tau_ref, db_t, opt.k, w or 0, rng)
            if opt.neighbourhood == "radius":
                rad = radius = d_ref
            else:
                for m in ms[:-1]:
                    seg[int(m)] = _segment_length(s, int(m), tau_ref, db_t, opt.k, w or 0,
                                                  d_ref, rng, n_min)
        pool = db_t if test_t is None else test_t
        perm = rng.permutation(pool)  # nested query sets: the first n of one order
        per_m = {}
        for m in ms:
            db_m = db_t[-seg[int(m)]:]
            order = perm if test_t is not None or db_m.size == db_t.size \
                else perm[np.isin(perm, db_m)]
            per_m[int(m)] = (db_m, order)
            seg_len[int(m)] = int(db_m.size)
        plans.append((w, rad, per_m))

    job_opt = {"k": opt.k, "order": opt.order, "ridge": opt.ridge, "theiler": None}
    shared = _Shared(n_workers > 1)
    components = {}  # (split, m) -> window components of the tree search
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=0, desc="delay scan", unit="task")

    def n_chunks_of(idx):
        """Scan tasks (chunks of taus) of a cell with tau indices ``idx``."""
        return max(1, min(idx.size, TASKS_PER_WORKER * n_workers))

    def prepare(cell):
        """One (split, m) cell: its query set, tau chunks, candidate-list tasks and a
        ``make(list_results) -> (scan tasks, shared arrays)``."""
        split, m, idx, n_q = cell[:4]
        search = cell[4] if len(cell) > 4 else opt.search  # the polish forces "tree"
        w, rad, per_m = plans[split]
        db_m, order = per_m[m]
        q_t = np.sort(order[:n_q])
        o = dict(job_opt, theiler=w, radius=rad)
        n_b = min(N_BATCHES, q_t.size)
        chunks = [c for c in np.array_split(idx, n_chunks_of(idx)) if c.size]
        if search == "exact":
            tasks = [delayed(_exact_task)(s, m, taus[c], db_m, q_t, o, n_b) for c in chunks]
            return _Cell(cell, q_t, chunks, [], lambda _: (tasks, ()))
        if search == "tree" or (search == "auto" and rad is None and _use_tree(
                m, db_m, q_t, taus[idx], opt)):
            key = (split, m)
            if key not in components:
                components[key] = shared(window_components(
                    s, m, db_m, min(m, TREE_COMPONENTS)))
            tasks = [delayed(_tree_task)(
                s, components[key], m,
                np.array([second_window_start(m, int(t)) for t in taus[c]], dtype=np.int64),
                db_m, q_t, o, n_b) for c in chunks]
            return _Cell(cell, q_t, chunks, [], lambda _: (tasks, ()))
        starts = np.array([second_window_start(m, int(t)) for t in taus[idx]])
        plan = _candidate_plan(s, m, db_m, q_t, np.unique(starts), opt)
        index = (tuple(plan.index[0]), *(shared(a) for a in plan.index[1:]))
        cuts = _list_cuts(plan.needed.size, max(LIST_SLICES, TASKS_PER_WORKER * n_workers))
        # workers in this process fill one list in place: no serial concatenation of the
        # slices (~0.6 s per m at 10^6 rows) between the list build and the scan
        whole = (np.empty((plan.needed.size, plan.k), dtype=np.int32),
                 np.empty(plan.needed.size)) if in_process else None
        list_tasks = [delayed(list_slice)(s, m, index, plan.needed[lo:hi], plan.k, w, 1,
                                          None if whole is None else
                                          (whole[0][lo:hi], whole[1][lo:hi]))
                      for lo, hi in pairwise(cuts)]

        def make(parts):
            lists, rk2 = _padded([whole] if whole is not None else parts, plan.n_list)
            arrays = (shared(lists), shared(rk2), plan.row_of, plan.u_min, shared(plan.is_db))
            shared.release(index[1:])
            tasks = [delayed(_candidates_task)(
                s, m, np.array([second_window_start(m, int(t)) for t in taus[c]]),
                db_m, q_t, arrays, o, n_b) for c in chunks]
            return tasks, arrays

        return _Cell(cell, q_t, chunks, list_tasks, make)

    def collect(prepared, tasks, arrays, results):
        """Sum the scan tasks' results (consumed from ``results``) into the tables."""
        (split, m), q_t, chunks = prepared.cell[:2], prepared.q_t, prepared.chunks
        j = ms.tolist().index(m)
        sums = {}  # tau chunk -> (sq, n_exact) summed over its query chunks
        for n in range(len(tasks)):
            sq, n_ex = next(results)
            key = id(chunks[n])
            if key in sums:
                sums[key] = (sums[key][0] + sq, sums[key][1] + n_ex, chunks[n])
            else:
                sums[key] = (sq, n_ex, chunks[n])
            if bar is not None:
                bar.update(1)
        for sq, n_ex, c in sums.values():
            rms, sem = cell_stats(sq, q_t.size)
            err[split, j, c] = rms
            se[split, j, c] = sem
            bmsq[split, j, c] = np.nan
            bmsq[split, j, c, :sq.shape[1]] = batch_means(sq, q_t.size)
            nq[split, j, c] = q_t.size
            exact[split, j, c] = n_ex / q_t.size
        shared.release(arrays)

    def run(cells, parallel):
        """cells: list of (split, m, tau indices, n_queries).

        One joblib call per cell carries the candidate-list tasks of that cell
        and then the scan tasks of the previous one.  The main process
        prepares the next cell (its k-d tree) as soon as the call is
        dispatched and assembles the lists as soon as they are in (thread
        workers fill them in place), so the list build is as parallel as the
        scan under any backend and only the first cell's tree is serial.
        (Scan tasks first, lists last, measured 176 s against 168 s on the
        paper-scale scan with 2 workers: the assembly then waits for the whole
        call.)
        """
        if bar is not None:  # every scan task is known now (list tasks: once planned)
            bar.total += sum(n_chunks_of(c[2]) for c in cells)
            bar.refresh()
        pending = None  # (cell, scan tasks, shared arrays) whose scan goes out next
        nxt = prepare(cells[0]) if cells else None
        n = 0
        while pending is not None or nxt is not None:
            lists = nxt.list_tasks if nxt is not None else []
            scan = pending[1] if pending is not None else []
            if bar is not None:
                bar.total += len(lists)
                what = ([f"candidate lists m={nxt.cell[1]}"] if lists else []) + \
                    ([f"scan m={pending[0].cell[1]}"] if scan else [])
                bar.set_postfix_str(", ".join(what))
            results = iter(parallel(lists + scan)) if lists or scan else iter(())
            # the call is dispatched: prepare the next cell (its k-d tree) while the workers
            # build these lists, so no call waits on the main thread but the very first
            following = prepare(cells[n + 1]) if n + 1 < len(cells) else None
            ready = None
            if nxt is not None:
                parts = []
                for _ in lists:
                    parts.append(next(results))
                    if bar is not None:
                        bar.update(1)
                ready = (nxt, *nxt.make(parts))
            if pending is not None:
                collect(pending[0], pending[1], pending[2], results)
            for _ in results:  # run the generator to its end: the call is then complete
                raise RuntimeError("the scan received more results than it sent tasks")
            pending, nxt, n = ready, following, n + 1

    try:
        # threads by default: every task is a nogil compiled kernel, so threads run them in
        # parallel without copying or memory-mapping the series and the lists (with loky
        # processes the same scan spent 8 % more CPU at 10^6 points); a backend the user
        # configures (loky, Dask) still wins, and then large arrays go out as memory maps
        with Parallel(n_jobs=n_jobs, verbose=verbose, return_as="generator",
                      prefer="threads") as parallel:
            in_process = n_workers == 1 or _uses_threads(parallel)
            shared.enabled = not in_process
            coarse_cells = []
            for split, (_, _, per_m) in enumerate(plans):
                for m in ms[::-1]:  # costliest (largest m) first: better load balance
                    n_all = per_m[int(m)][1].size
                    n_q = n_all if opt.n_queries is None else min(opt.n_queries, n_all)
                    coarse_cells.append((split, int(m), np.arange(n_tau), n_q))
            run(coarse_cells, parallel)
            n_coarse = nq.copy()
            if opt.refine and n_tau >= 3:
                bm = bmsq if opt.centre_error == "batches" else None
                _refine(err, se, bm, nq, plans, ms, taus, opt, run, parallel)
                if opt.search == "auto" and radius is None:
                    _polish(err, se, bm, exact, nq, ms, taus, opt, run, parallel)
    finally:
        shared.close()
        if bar is not None:
            bar.close()
    n_all = np.array([[per_m[int(m)][1].size for m in ms] for (_, _, per_m) in plans])
    # coarse: some split still forecasts only the coarse subset of its rows there
    coarse = np.any((nq == n_coarse) & (n_coarse < n_all[:, :, None]), axis=0)
    return ScanResult(error=err, se=se, batch_msq=bmsq, n_queries=nq, exact=exact,
                      coarse=coarse, segment_length=seg_len, radius=radius)


def _curve_and_se(err, se):
    """Mean over splits and its standard error (independent folds)."""
    n_split = err.shape[0]
    return err.mean(axis=0), np.sqrt(np.sum(se ** 2, axis=0)) / n_split


def _dip_cells(err, se, bmsq, ms, taus):
    """Per ``m``: the dip's centre standard error, the tau indices around its centre
    that a redrawn curve could put its dip run on (None: no dip, or a dip at the grid's
    edge) and whether the dip is significant."""
    import pandas as pd

    curve, curve_se = _curve_and_se(err, se)
    fe = pd.DataFrame(curve.T, index=pd.Index(taus, name="tau"), columns=pd.Index(ms, name="m"))
    sef = pd.DataFrame(np.nan_to_num(curve_se.T, nan=0.0), index=fe.index, columns=fe.columns)
    batches = None if bmsq is None else batch_table(bmsq, ms, taus)
    dips = locate_dips(fe, se=sef, batch_msq=batches)
    out = {}
    for m in ms:
        row = dips.loc[m]
        if "edge" in row["reason"] or not np.isfinite(row["delay"]):
            out[int(m)] = (np.nan, None, False)
            continue
        reach = 2 * float(row["half_width"]) + 2 * float(row["centre_se"]) + 1
        out[int(m)] = (float(row["centre_se"]),
                       np.flatnonzero(np.abs(taus - float(row["delay"])) <= reach),
                       bool(row["significant"]))
    return out


def _refine(err, se, bmsq, nq, plans, ms, taus, opt, run, parallel):
    """More queries on the taus around each dip until its centre is known to target."""
    for _ in range(MAX_REFINE_ROUNDS):
        dips = _dip_cells(err, se, bmsq, ms, taus)
        cells = []
        for j, m in enumerate(ms):
            centre_se, idx, _ = dips[int(m)]
            if idx is None or centre_se < opt.target_centre_se:
                continue
            for split, (_, _, per_m) in enumerate(plans):
                n_all = per_m[int(m)][1].size
                n_now = int(nq[split, j, idx].min()) if idx.size else n_all
                if idx.size == 0 or n_now >= n_all:
                    continue
                cells.append((split, int(m), idx, min(n_all, REFINE_GROWTH * n_now)))
        if not cells:
            return
        run(cells, parallel)


def _polish(err, se, bmsq, exact, nq, ms, taus, opt, run, parallel):
    """Exact neighbours (the tree search) on the taus around each dip, with the queries
    each cell already has.

    The candidate lists of a long record move sigma by a few per cent, and not
    uniformly in tau: on 10^6 noisy 12-bit Mackey-Glass points (delay 150, 10^4
    queries, 67 candidates) they moved the m = 5 dip centre by 0.21 samples and its
    half-width by 0.23 against a full-precision scan, ten times the centre's standard
    error from the query subsampling (0.037).  Those cells are few (about 20 taus per
    m), so they get the exact search; a polished dip that moves onto approximate
    cells is polished once more.
    """
    for _ in range(POLISH_ROUNDS):
        dips = _dip_cells(err, se, bmsq, ms, taus)
        cells = []
        for j, m in enumerate(ms):
            _, idx, significant = dips[int(m)]
            if idx is None or not significant:  # no delay is read off an insignificant dip
                continue
            for split in range(err.shape[0]):
                todo = idx[exact[split, j, idx] < 1]
                for n_q in np.unique(nq[split, j, todo]):  # cells keep their query sets
                    cells.append((split, int(m), todo[nq[split, j, todo] == n_q], int(n_q),
                                  "tree"))
        if not cells:
            return
        run(cells, parallel)


def _uses_threads(parallel):
    """Does this joblib call run its tasks in threads of this process?"""
    return bool(getattr(getattr(parallel, "_backend", None), "uses_threads", False))


@dataclass
class _Cell:
    """A prepared (split, m) cell of :func:`scan_series` (see its ``prepare``)."""

    cell: tuple
    q_t: np.ndarray
    chunks: list
    list_tasks: list
    make: object


@dataclass
class _CandidatePlan:
    """What the candidate lists of one ``m`` need: the tree, the times, the row map."""

    index: tuple
    needed: np.ndarray
    k: int
    n_list: int
    row_of: np.ndarray
    u_min: int
    is_db: np.ndarray


def _use_tree(m, db_t, q_t, taus, opt):
    """Whether ``search="auto"`` takes the exact tree search for one cell.

    Always where every database row is a query (a full-precision cell); elsewhere unless
    the candidate lists are expected to cost less than ``1 / LIST_ADVANTAGE`` of it.  Cost
    model of :data:`TREE_BUILD` and its neighbours (microseconds): the tree search builds a
    tree of the ``db_t.size`` rows per tau and searches each query; the lists are built once
    for the needed times (the queries and their second windows' starts, at most the rows
    they span) and re-rank ``K`` candidates per query and tau.
    """
    n_db, n_q, n_tau = int(db_t.size), int(q_t.size), len(taus)
    if n_q >= n_db:
        return True
    starts = {second_window_start(m, int(t)) for t in taus}
    span = int(q_t.max()) - int(q_t.min()) + max(starts) + 1
    n_needed = min(span, n_q * (len(starts) + 1))
    k = opt.candidates_for(n_needed)
    tree = n_tau * (TREE_BUILD * n_db * np.log2(max(n_db, 2)) + TREE_QUERY * n_q)
    lists = LIST_ROW * k * n_needed + n_tau * n_q * (LIST_QUERY * k + FIT_QUERY)
    return bool(tree <= LIST_ADVANTAGE * lists)


def _candidate_plan(s, m, db_t, q_t, starts, opt):
    """The needed times of one ``m`` (queries and their second windows' starts) and the
    k-d tree of the member windows; the lists themselves are built by :func:`list_slice`."""
    reach_back = int(starts.max())
    members = np.arange(max(m - 1, int(db_t.min()) - reach_back), int(db_t.max()) + 1)
    # the times as a mask over their range (np.unique of the 5 * 10^6 query-start
    # differences of the paper-scale scan took 0.5 s per m, all of it serial)
    lo = int(q_t.min()) - int(starts.max())
    wanted = np.zeros(int(q_t.max()) - lo + 1, dtype=np.bool_)
    wanted[q_t - lo] = True
    for start in starts:
        wanted[q_t - int(start) - lo] = True
    needed = np.flatnonzero(wanted) + lo
    u_min = int(needed[0])
    row_of = np.full(int(needed[-1]) - u_min + 1, -1, dtype=np.int64)
    row_of[needed - u_min] = np.arange(needed.size)
    n_list = opt.candidates_for(needed.size)
    is_db = np.zeros(s.size, dtype=np.bool_)
    is_db[db_t] = True
    return _CandidatePlan(list_index(s, m, members), needed, int(min(n_list, members.size)),
                          n_list, row_of, u_min, is_db)
