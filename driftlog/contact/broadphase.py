"""Broad phase: which axis-aligned boxes overlap, on a hashed uniform grid.

Logs are boxed by their capsule inflated by how far they can move in the step; two logs are a
candidate pair when their boxes overlap.  The grid's cell is as large as the largest box, so
each box centre is binned once and a query looks at the 3 x 3 cells around its own; the grid
is hashed (cells to a table of about 2 n buckets), so an unbounded domain costs no memory.
Static obstacles (walls, piers, cut meshes) are binned once into every cell their box covers;
a pair is reported only from the first cell both boxes share, so never twice.

Where the box centres fill a compact area (at most about 4 cells per box), the grid is dense,
not hashed: cells numbered column by column, so that the three cells of a neighbouring column
are one contiguous run of the sorted boxes; one pass, serial, in the same order as the hashed
grid (log i, then the 3 x 3 neighbourhood column by column, then j).

``PairCache`` keeps the broad phase between sub-steps (a Verlet list of boxes): the pairs of
boxes inflated by a skin are found once; while every log's current box stays inside its
inflated box, the current pairs are those of the kept list whose current boxes overlap, put in
the order a fresh grid gives (so that sequential impulses and Gauss-Seidel sweeps see the same
contacts in the same order: results identical to a fresh broad phase at every step).

``sweep_pairs`` finds the same set of pairs by sorting the boxes along the axis they spread
over more and sweeping (Baraff 1992's sort and sweep), in another order: for callers that use
the pairs as a set (the per-log clocks' contact windows: which logs meet, and their islands),
where boxes spread along a long valley make the grid's cells crowded or its table sparse.

``brute_pairs`` (all n (n - 1) / 2 box tests) is the reference the tests compare against.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import PARALLEL_MIN, kernel
from driftlog.columns import CAP_AX, CAP_AY, CAP_BX, CAP_BY, CAP_R, THETA

__all__ = ["grid_pairs", "sweep_pairs", "brute_pairs", "StaticGrid", "log_boxes", "PairCache"]

_P1, _P2 = 73856093, 19349663


@nb.njit(cache=True, inline="always")
def _key(ix, iy, mask):
    return ((ix * _P1) ^ (iy * _P2)) & mask


@nb.njit(cache=True)
def _bin_centres(x, y, cell, mask):
    n = x.size
    ix = np.floor(x / cell).astype(np.int64)
    iy = np.floor(y / cell).astype(np.int64)
    start = np.zeros(mask + 2, np.int64)
    for i in range(n):
        start[_key(ix[i], iy[i], mask) + 1] += 1
    for k in range(mask + 1):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        k = _key(ix[i], iy[i], mask)
        order[fill[k]] = i
        fill[k] += 1
    return ix, iy, start, order


@kernel
def _count_or_fill(x, y, ex, ey, ix, iy, start, order, mask, offsets, pairs, fill):
    """Pass 1 (fill = False): pairs per log; pass 2: write them at ``offsets``."""
    n = x.size
    for i in nb.prange(n):
        c = 0
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                cx, cy = ix[i] + dx, iy[i] + dy
                k = _key(cx, cy, mask)
                for q in range(start[k], start[k + 1]):
                    j = order[q]
                    # j > i: each pair once; same cell: hash collisions do not duplicate
                    if j <= i or ix[j] != cx or iy[j] != cy:
                        continue
                    if abs(x[i] - x[j]) > ex[i] + ex[j] or abs(y[i] - y[j]) > ey[i] + ey[j]:
                        continue
                    if fill:
                        pairs[offsets[i] + c, 0] = i
                        pairs[offsets[i] + c, 1] = j
                    c += 1
        if not fill:
            offsets[i] = c


@nb.njit(cache=True)
def _dense_pairs(x, y, ex, ey, cell, ix0, iy0, nx, ny):
    """One serial pass on a dense grid of nx x ny cells (padded by one cell on every side)."""
    n = x.size
    key = np.empty(n, np.int64)
    start = np.zeros(nx * ny + 1, np.int64)
    for i in range(n):
        k = (np.int64(np.floor(x[i] / cell)) - ix0 + 1) * ny + \
            (np.int64(np.floor(y[i] / cell)) - iy0 + 1)
        key[i] = k
        start[k + 1] += 1
    for k in range(nx * ny):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    sx, sy, sex, sey = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    sid = np.empty(n, np.int64)
    for i in range(n):
        q = fill[key[i]]
        fill[key[i]] += 1
        sx[q], sy[q], sex[q], sey[q], sid[q] = x[i], y[i], ex[i], ey[i], i
    cap = 4 * n + 16
    out = np.empty((cap, 2), np.int64)
    m = 0
    for i in range(n):
        xi, yi, exi, eyi = x[i], y[i], ex[i], ey[i]
        for dx in range(-1, 2):
            # cells (ix + dx, iy - 1 .. iy + 1): consecutive numbers, one run of boxes
            k = key[i] + dx * ny
            for q in range(start[k - 1], start[k + 2]):
                j = sid[q]
                if j <= i:
                    continue
                if abs(xi - sx[q]) > exi + sex[q] or abs(yi - sy[q]) > eyi + sey[q]:
                    continue
                if m == cap:
                    cap *= 2
                    grown = np.empty((cap, 2), np.int64)
                    grown[:m] = out[:m]
                    out = grown
                out[m, 0] = i
                out[m, 1] = j
                m += 1
    return out[:m].copy()


def grid_pairs(x, y, ex, ey, dense=True):
    """Pairs (i, j), i < j, of boxes (centre x, y; half extents ex, ey) that overlap.

    Sorted by i, then by grid order (the 3 x 3 cells around i's, column by column, then j);
    the same input gives the same order whether the grid is dense or hashed.  ``dense``:
    False always hashes (the benchmarks' reference).
    """
    n = x.size
    empty = np.empty((0, 2), np.int64)
    if n < 2:
        return empty
    cell = 2.0 * max(float(ex.max()), float(ey.max()))
    if dense and cell > 0.0 and (n < PARALLEL_MIN or nb.get_num_threads() == 1):
        ix0, ix1 = np.floor(float(x.min()) / cell), np.floor(float(x.max()) / cell)
        iy0, iy1 = np.floor(float(y.min()) / cell), np.floor(float(y.max()) / cell)
        nx, ny = ix1 - ix0 + 3.0, iy1 - iy0 + 3.0
        if nx * ny <= 4.0 * n + 64.0:
            return _dense_pairs(x, y, ex, ey, cell, int(ix0), int(iy0), int(nx), int(ny))
    mask = (1 << int(np.ceil(np.log2(2 * n)))) - 1
    ix, iy, start, order = _bin_centres(x, y, cell, mask)
    counts = np.zeros(n, np.int64)
    _count_or_fill(x, y, ex, ey, ix, iy, start, order, mask, counts, empty, False)
    offsets = np.zeros(n, np.int64)
    np.cumsum(counts[:-1], out=offsets[1:])
    pairs = np.empty((int(counts.sum()), 2), np.int64)
    _count_or_fill(x, y, ex, ey, ix, iy, start, order, mask, offsets, pairs, True)
    return pairs


# the sweep's order: the boxes' lower ends quantised to QBITS bits over their range and
# sorted by an LSD radix sort of RADIX-bit digits (linear in n; numba's argsort took 60 % of
# the sweep at 1e4 boxes)
QBITS = 33
RADIX = 11


@nb.njit(cache=True, inline="always")
def _quant(v, lo_min, scale):
    """Quantised position: non-decreasing in v (monotone rounding), >= 0 from lo_min on.

    Capped at 2**62: a box's upper end may lie far beyond the lower ends' range (lower ends
    a round-off apart, a box a metre long), where the product would overflow int64.
    """
    return np.int64(min((v - lo_min) * scale, 4.611686018427388e18))


@nb.njit(cache=True)
def _radix_order(q):
    """Stable argsort of non-negative int64 keys below 2**QBITS (LSD radix sort)."""
    n = q.size
    nb_ = 1 << RADIX
    o = np.arange(n)
    tmp = np.empty(n, np.int64)
    count = np.empty(nb_ + 1, np.int64)
    for shift in range(0, QBITS, RADIX):
        count[:] = 0
        for a in range(n):
            count[((q[o[a]] >> shift) & (nb_ - 1)) + 1] += 1
        for d in range(nb_):
            count[d + 1] += count[d]
        for a in range(n):
            i = o[a]
            d = (q[i] >> shift) & (nb_ - 1)
            tmp[count[d]] = i
            count[d] += 1
        o, tmp = tmp, o
    return o


@nb.njit(cache=True)
def _sweep(x, y, ex, ey):
    n = x.size
    alongx = x.max() - x.min() >= y.max() - y.min()
    c = x if alongx else y
    e = ex if alongx else ey
    lo = c - e
    lo_min = lo.min()
    span = lo.max() - lo_min
    scale = (2.0 ** QBITS - 2.0) / span if span > 0.0 else 0.0
    q = np.empty(n, np.int64)
    for i in range(n):
        q[i] = _quant(lo[i], lo_min, scale)
    o = _radix_order(q)
    # the sweep stops at a box whose quantised lower end is beyond i's end's (grown by more
    # than round-off): the boxes are in the order of q, non-decreasing in lo, so every box
    # before the stop starts at or before i's end's quantum, and every box whose interval
    # meets i's is before it (a conservative cut: every pair it keeps gets grid_pairs' own test)
    tol = 1e-9 * (max(abs(c.max()), abs(c.min())) + e.max())
    # the boxes in sweep order, side by side (the scan then reads memory in order)
    qs = np.empty(n, np.int64)
    bs = np.empty((n, 4))
    for a in range(n):
        i = o[a]
        qs[a] = q[i]
        bs[a, 0] = x[i]
        bs[a, 1] = y[i]
        bs[a, 2] = ex[i]
        bs[a, 3] = ey[i]
    out = np.empty((max(16, 2 * n), 2), np.int64)
    m = 0
    for a in range(n):
        i = o[a]
        xi, yi, exi, eyi = bs[a, 0], bs[a, 1], bs[a, 2], bs[a, 3]
        qhi = _quant(c[i] + e[i] + tol, lo_min, scale)
        for b in range(a + 1, n):
            if qs[b] > qhi:
                break
            if abs(xi - bs[b, 0]) > exi + bs[b, 2] or abs(yi - bs[b, 1]) > eyi + bs[b, 3]:
                continue
            j = o[b]
            if m == out.shape[0]:
                grown = np.empty((2 * m, 2), np.int64)
                grown[:m] = out
                out = grown
            out[m, 0] = min(i, j)
            out[m, 1] = max(i, j)
            m += 1
    return out[:m]


def sweep_pairs(x, y, ex, ey):
    """The pairs of ``grid_pairs`` (the same set, the same box test), in another order.

    Sorted along the axis the box centres spread over more (by their lower ends, quantised
    to ``QBITS`` bits and radix sorted), then swept.  Non-finite boxes
    go to ``grid_pairs``.
    """
    n = x.size
    if n < 2:
        return np.empty((0, 2), np.int64)
    if not (np.isfinite(x).all() and np.isfinite(y).all() and np.isfinite(ex).all()
            and np.isfinite(ey).all()):
        return grid_pairs(x, y, ex, ey)
    return _sweep(x, y, ex, ey)


@nb.njit(cache=True)
def _brute(x, y, ex, ey):
    n = x.size
    out = []
    for i in range(n):
        for j in range(i + 1, n):
            if abs(x[i] - x[j]) <= ex[i] + ex[j] and abs(y[i] - y[j]) <= ey[i] + ey[j]:
                out.append((i, j))
    return out


def brute_pairs(x, y, ex, ey):
    """All overlapping box pairs by testing every pair (the reference for tests)."""
    p = _brute(x, y, ex, ey)
    return np.array(p, np.int64).reshape(-1, 2)


@nb.njit(cache=True)
def log_boxes(S, length, radius, margin, ex, ey):
    """Half extents of the logs' boxes: capsule plus ``margin`` (per log)."""
    for i in range(S.shape[0]):
        h = 0.5 * length[i]
        ex[i] = h * abs(np.cos(S[i, THETA])) + radius[i] + margin[i]
        ey[i] = h * abs(np.sin(S[i, THETA])) + radius[i] + margin[i]


# --------------------------------------------------------------------- static obstacles
@nb.njit(cache=True)
def _bin_boxes(lo_x, lo_y, hi_x, hi_y, cell, mask):
    m = lo_x.size
    start = np.zeros(mask + 2, np.int64)
    for k in range(m):
        for ix in range(int(np.floor(lo_x[k] / cell)), int(np.floor(hi_x[k] / cell)) + 1):
            for iy in range(int(np.floor(lo_y[k] / cell)), int(np.floor(hi_y[k] / cell)) + 1):
                start[_key(ix, iy, mask) + 1] += 1
    for q in range(mask + 1):
        start[q + 1] += start[q]
    fill = start[:-1].copy()
    items = np.empty((start[-1], 3), np.int64)  # capsule, and the cell it was binned for
    for k in range(m):
        for ix in range(int(np.floor(lo_x[k] / cell)), int(np.floor(hi_x[k] / cell)) + 1):
            for iy in range(int(np.floor(lo_y[k] / cell)), int(np.floor(hi_y[k] / cell)) + 1):
                q = _key(ix, iy, mask)
                items[fill[q], 0] = k
                items[fill[q], 1] = ix
                items[fill[q], 2] = iy
                fill[q] += 1
    return start, items


@kernel
def _query_static(x, y, ex, ey, lo_x, lo_y, hi_x, hi_y, cell, mask, start, items, offsets,
                  pairs, fill):
    n = x.size
    for i in nb.prange(n):
        c = 0
        ax0, ax1 = x[i] - ex[i], x[i] + ex[i]
        ay0, ay1 = y[i] - ey[i], y[i] + ey[i]
        ix0, ix1 = int(np.floor(ax0 / cell)), int(np.floor(ax1 / cell))
        iy0, iy1 = int(np.floor(ay0 / cell)), int(np.floor(ay1 / cell))
        for ix in range(ix0, ix1 + 1):
            for iy in range(iy0, iy1 + 1):
                q = _key(ix, iy, mask)
                for p in range(start[q], start[q + 1]):
                    k = items[p, 0]
                    if items[p, 1] != ix or items[p, 2] != iy:
                        continue  # another cell hashed to the same bucket
                    if ax0 > hi_x[k] or ax1 < lo_x[k] or ay0 > hi_y[k] or ay1 < lo_y[k]:
                        continue
                    # report from the first cell both boxes cover (never twice)
                    fx = max(ix0, int(np.floor(lo_x[k] / cell)))
                    fy = max(iy0, int(np.floor(lo_y[k] / cell)))
                    if fx != ix or fy != iy:
                        continue
                    if fill:
                        pairs[offsets[i] + c, 0] = i
                        pairs[offsets[i] + c, 1] = k
                    c += 1
        if not fill:
            offsets[i] = c


# at most 2**MAX_BUCKET_BITS buckets in a StaticGrid (32 MB of bucket starts)
MAX_BUCKET_BITS = 22


class StaticGrid:
    """Static capsules (obstacles) binned once; ``query`` returns (log, capsule) pairs.

    Parameters
    ----------
    capsules : (m, 5) array
        ax, ay, bx, by, r of each static capsule.
    cell : float
        Grid cell size (about the size of a log's box); enlarged so that the grid holds at
        most about 64 cells per capsule.
    """

    def __init__(self, capsules, cell):
        c = np.asarray(capsules, float).reshape(-1, 5)
        self.capsules = c
        r = c[:, CAP_R]
        self.lo_x = np.minimum(c[:, CAP_AX], c[:, CAP_BX]) - r
        self.hi_x = np.maximum(c[:, CAP_AX], c[:, CAP_BX]) + r
        self.lo_y = np.minimum(c[:, CAP_AY], c[:, CAP_BY]) - r
        self.hi_y = np.maximum(c[:, CAP_AY], c[:, CAP_BY]) + r
        m = max(c.shape[0], 1)
        items = m
        if c.shape[0]:
            cover = ((self.hi_x - self.lo_x) / cell + 1) * ((self.hi_y - self.lo_y) / cell + 1)
            while cover.sum() > 64 * m:
                cell *= 2.0
                cover = ((self.hi_x - self.lo_x) / cell + 1) * ((self.hi_y - self.lo_y) / cell + 1)
            items = max(items, int(cover.sum()))
        self.cell = float(cell)
        # buckets for the (capsule, cell) items, not the capsules: a query scans its cells'
        # buckets, and with up to 64 items per capsule in 2 m buckets it read about 30 items
        # of other cells per bucket (the pairs and their order do not depend on the buckets)
        self.mask = (1 << min(int(np.ceil(np.log2(2 * items + 1))), MAX_BUCKET_BITS)) - 1
        self.start, self.items = _bin_boxes(self.lo_x, self.lo_y, self.hi_x, self.hi_y,
                                            self.cell, self.mask)

    def query(self, x, y, ex, ey):
        """Pairs (i, k) of boxes i (centre, half extents) overlapping capsule k's box."""
        n = x.size
        empty = np.empty((0, 2), np.int64)
        if n == 0 or self.capsules.shape[0] == 0:
            return empty
        counts = np.zeros(n, np.int64)
        args = (self.lo_x, self.lo_y, self.hi_x, self.hi_y, self.cell, self.mask, self.start,
                self.items)
        _query_static(x, y, ex, ey, *args, counts, empty, False)
        offsets = np.zeros(n, np.int64)
        np.cumsum(counts[:-1], out=offsets[1:])
        pairs = np.empty((int(counts.sum()), 2), np.int64)
        _query_static(x, y, ex, ey, *args, offsets, pairs, True)
        return pairs


# --------------------------------------------------------------------- kept between sub-steps
@nb.njit(cache=True)
def _inside(x, y, ex, ey, x0, y0, exb, eyb):
    """Whether every current box lies inside its kept (inflated) box."""
    for i in range(x.size):
        if abs(x[i] - x0[i]) + ex[i] > exb[i] or abs(y[i] - y0[i]) + ey[i] > eyb[i]:
            return False
    return True


@nb.njit(cache=True)
def _sort_segment(keys, rows, lo, hi):
    """Insertion sort of rows[lo:hi] by keys[lo:hi] (segments hold a few pairs)."""
    for a in range(lo + 1, hi):
        k, r = keys[a], rows[a]
        b = a - 1
        while b >= lo and keys[b] > k:
            keys[b + 1] = keys[b]
            rows[b + 1] = rows[b]
            b -= 1
        keys[b + 1] = k
        rows[b + 1] = r


@nb.njit(cache=True)
def _kept_log_pairs(x, y, ex, ey, kept, cell):
    """Kept pairs whose current boxes overlap, in ``grid_pairs``' order for the current boxes.

    ``kept`` is sorted by its first column; within each log's run the pairs are put in the
    fresh grid's order: neighbour cell (column by column) of j around i, then j.
    """
    m = kept.shape[0]
    n = x.size
    out = np.empty((m, 2), np.int64)
    keys = np.empty(16, np.int64)
    rows = np.empty(16, np.int64)
    cx = np.empty(n, np.int64)
    cy = np.empty(n, np.int64)
    for i in range(n):
        cx[i] = np.int64(np.floor(x[i] / cell))
        cy[i] = np.int64(np.floor(y[i] / cell))
    c = 0
    a = 0
    while a < m:
        i = kept[a, 0]
        xi, yi, exi, eyi, ix, iy = x[i], y[i], ex[i], ey[i], cx[i], cy[i]
        s = 0
        while a < m and kept[a, 0] == i:
            j = kept[a, 1]
            a += 1
            if abs(xi - x[j]) > exi + ex[j] or abs(yi - y[j]) > eyi + ey[j]:
                continue
            dx, dy = cx[j] - ix, cy[j] - iy
            if abs(dx) > 1 or abs(dy) > 1:
                continue  # (round-off at a cell's edge) the fresh grid does not see it either
            if s == keys.size:
                keys = np.concatenate((keys, np.empty(s, np.int64)))
                rows = np.concatenate((rows, np.empty(s, np.int64)))
            keys[s] = ((dx + 1) * 3 + dy + 1) * n + j
            rows[s] = j
            s += 1
        _sort_segment(keys, rows, 0, s)
        for q in range(s):
            out[c, 0] = i
            out[c, 1] = rows[q]
            c += 1
    return out[:c].copy()


@nb.njit(cache=True)
def _kept_static_pairs(x, y, ex, ey, kept, lo_x, lo_y, hi_x, hi_y, cell):
    """Kept (log, capsule) pairs whose boxes overlap now, in ``StaticGrid.query``'s order.

    The query visits the cells of the log's box column by column and reports a capsule from
    the first cell both boxes cover, capsules of one cell in increasing index.
    """
    m = kept.shape[0]
    out = np.empty((m, 2), np.int64)
    keys = np.empty(m, np.float64)
    rows = np.empty(m, np.int64)
    ncap = lo_x.size
    c = 0
    a = 0
    while a < m:
        i = kept[a, 0]
        start = c
        ax0, ax1 = x[i] - ex[i], x[i] + ex[i]
        ay0, ay1 = y[i] - ey[i], y[i] + ey[i]
        ix0, ix1 = np.floor(ax0 / cell), np.floor(ax1 / cell)
        iy0, iy1 = np.floor(ay0 / cell), np.floor(ay1 / cell)
        while a < m and kept[a, 0] == i:
            k = kept[a, 1]
            a += 1
            if ax0 > hi_x[k] or ax1 < lo_x[k] or ay0 > hi_y[k] or ay1 < lo_y[k]:
                continue
            fx = max(ix0, np.floor(lo_x[k] / cell))
            fy = max(iy0, np.floor(lo_y[k] / cell))
            if fx > ix1 or fy > iy1:
                continue  # (round-off at a cell's edge) as the query
            # cells visited column by column: (fx - ix0) columns of (iy1 - iy0 + 1) cells
            keys[c] = (((fx - ix0) * (iy1 - iy0 + 1.0) + (fy - iy0)) * ncap) + k
            rows[c] = k
            c += 1
        _sort_segment(keys, rows, start, c)
        for q in range(start, c):
            out[q, 0] = i
            out[q, 1] = rows[q]
    return out[:c].copy()


class PairCache:
    """The broad phase kept between sub-steps: boxes inflated by a skin, pairs found once.

    ``pairs`` returns exactly what ``grid_pairs`` (and ``StaticGrid.query``) return for the
    current boxes, in the same order; it searches the grid again only when a log's current
    box leaves its kept box (or the set of logs changes).  Cost per call while kept: one test
    per log and one per kept pair.

    Parameters
    ----------
    skin_factor : float
        The kept boxes are the boxes of the first call inflated by ``skin_factor`` times the
        per-log ``skin`` passed (how far a log moves in a sub-step).
    adapt : bool
        Adjust ``skin_factor`` at each search: halved when the kept list has served 16 calls
        (the grid is then searched again, with thinner boxes), doubled when it served fewer
        than 4; within 1/256 .. 4.  Fewer kept pairs to filter where sub-steps are much
        shorter than the step the skin was given for (event-driven contact in a crowd).
    """

    def __init__(self, skin_factor=1.0, adapt=True):
        self.skin_factor = float(skin_factor)
        self.adapt = bool(adapt)
        self.builds = 0
        self.reuses = 0
        self._served = 0
        self._kept = None

    def clear(self):
        """Forget the kept pairs (the next call searches the grid)."""
        self._kept = None

    def pairs(self, x, y, ex, ey, skin, ids=None, static=None, grow=None):
        """Overlapping (log, log) pairs and, with ``static`` (a ``StaticGrid``), (log, capsule).

        Parameters
        ----------
        x, y, ex, ey : (n,) arrays
            Box centres and half extents now.
        skin : (n,) array
            How far each log may move before the next call (inflates the kept boxes).
        ids : (n,) array, optional
            Identity of the logs (a change of the set searches again).
        static : StaticGrid, optional
        grow : (n,) array, optional
            Extra half extent the kept boxes hold beyond the current boxes and the skin (the
            margin of a wider query to come: a sub-step's motion after a contact check).

        Returns
        -------
        (ll (k, 2), lo (m, 2)) : int64 arrays, as ``grid_pairs`` and ``static.query``.
        """
        n = x.size
        k = self._kept
        fresh = (k is None or k["n"] != n or k["static"] is not static
                 or (self.adapt and self._served >= 16 and self.skin_factor > 1.0 / 256.0)
                 or (ids is not None and not np.array_equal(k["ids"], ids))
                 or not _inside(x, y, ex, ey, k["x"], k["y"], k["ex"], k["ey"]))
        if fresh:
            if self.adapt and self._kept is not None:
                if self._served >= 16:
                    self.skin_factor = max(self.skin_factor * 0.5, 1.0 / 256.0)
                elif self._served < 4:
                    self.skin_factor = min(self.skin_factor * 2.0, 4.0)
            self._served = 0
            s = self.skin_factor * np.asarray(skin, float)
            if grow is not None:
                s = s + grow
            exb, eyb = ex + s, ey + s
            k = self._kept = dict(n=n, static=static, x=x.copy(), y=y.copy(), ex=exb, ey=eyb,
                                  ids=None if ids is None else np.array(ids),
                                  ll=grid_pairs(x, y, exb, eyb),
                                  lo=None if static is None else static.query(x, y, exb, eyb))
            self.builds += 1
        else:
            self.reuses += 1
            self._served += 1
        if n < 2:
            ll = np.empty((0, 2), np.int64)
        else:
            cell = 2.0 * max(float(ex.max()), float(ey.max()))
            ll = _kept_log_pairs(x, y, ex, ey, k["ll"], cell)
        if static is None:
            return ll, None
        if n == 0 or static.capsules.shape[0] == 0:
            return ll, np.empty((0, 2), np.int64)
        lo = _kept_static_pairs(x, y, ex, ey, k["lo"], static.lo_x, static.lo_y, static.hi_x,
                                static.hi_y, static.cell)
        return ll, lo
