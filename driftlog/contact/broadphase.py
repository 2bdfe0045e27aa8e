"""Broad phase: which axis-aligned boxes overlap, on a hashed uniform grid.

Logs are boxed by their capsule inflated by how far they can move in the step; two logs are a
candidate pair when their boxes overlap.  The grid's cell is as large as the largest box, so
each box centre is binned once and a query looks at the 3 x 3 cells around its own; the grid
is hashed (cells to a table of about 2 n buckets), so an unbounded domain costs no memory.
Static obstacles (walls, piers, cut meshes) are binned once into every cell their box covers;
a pair is reported only from the first cell both boxes share, so never twice.

``brute_pairs`` (all n (n - 1) / 2 box tests) is the reference the tests compare against.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import CAP_AX, CAP_AY, CAP_BX, CAP_BY, CAP_R, THETA

__all__ = ["grid_pairs", "brute_pairs", "StaticGrid", "log_boxes"]

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


def grid_pairs(x, y, ex, ey):
    """Pairs (i, j), i < j, of boxes (centre x, y; half extents ex, ey) that overlap.

    Sorted by i, then by grid order; the same input gives the same order.
    """
    n = x.size
    empty = np.empty((0, 2), np.int64)
    if n < 2:
        return empty
    cell = 2.0 * max(float(ex.max()), float(ey.max()))
    mask = (1 << int(np.ceil(np.log2(2 * n)))) - 1
    ix, iy, start, order = _bin_centres(x, y, cell, mask)
    counts = np.zeros(n, np.int64)
    _count_or_fill(x, y, ex, ey, ix, iy, start, order, mask, counts, empty, False)
    offsets = np.zeros(n, np.int64)
    np.cumsum(counts[:-1], out=offsets[1:])
    pairs = np.empty((int(counts.sum()), 2), np.int64)
    _count_or_fill(x, y, ex, ey, ix, iy, start, order, mask, offsets, pairs, True)
    return pairs


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
        if c.shape[0]:
            cover = ((self.hi_x - self.lo_x) / cell + 1) * ((self.hi_y - self.lo_y) / cell + 1)
            while cover.sum() > 64 * m:
                cell *= 2.0
                cover = ((self.hi_x - self.lo_x) / cell + 1) * ((self.hi_y - self.lo_y) / cell + 1)
        self.cell = float(cell)
        self.mask = (1 << int(np.ceil(np.log2(2 * m + 1)))) - 1
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
