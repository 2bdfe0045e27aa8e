"""Contact islands: the logs that may touch each other, directly or through other logs.

An island is a connected component of the graph whose nodes are the logs and whose edges are
the candidate pairs (boxes inflated by the motion of a step overlap).  Logs of different
islands cannot exchange an impulse within the step, so each island can be detected, solved
(sequential impulses, Moreau-Jean) and, with per-log clocks, advanced on its own.  Fixed
obstacles do not join islands: a wall has infinite mass, so two logs pressed on the same wall
do not push each other through it.

``islands`` labels them with a union-find (path halving, union by the smaller root) in one
pass over the pairs; ``island_runs`` groups the contacts of each island in their given order;
``swept_islands`` finds the pairs first, from the boxes the logs' centres swept over a time
(per-log clocks: ``driftlog.clocks``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.errors import ArgumentError

__all__ = ["islands", "island_labels", "island_runs", "labels_into", "runs_into",
           "swept_islands"]


@nb.njit(cache=True, inline="always")
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]  # path halving
        i = parent[i]
    return i


@nb.njit(cache=True)
def island_labels(n, body1, body2):
    """Island label of each of n logs from contacts body1[c] - body2[c] (body2 < 0: a wall).

    Labels are 0 .. count - 1, numbered by the smallest log of each island (log 0's island is
    0; a log without contacts is an island of its own).  Returns (labels, count).
    """
    labels = np.empty(n, np.int64)
    count = labels_into(n, body1, body2, body1.size, np.empty(n, np.int64), labels)
    return labels, count


@nb.njit(cache=True, _nrt=False)
def labels_into(n, body1, body2, k, parent, labels):
    """``island_labels`` of the first k contacts into ``labels`` (work: ``parent``, >= n); count.

    No allocation and no reference counting, for kernels that solve many small islands.
    """
    for i in range(n):
        parent[i] = i
    for c in range(k):
        i, j = body1[c], body2[c]
        if i < 0 or j < 0:
            continue
        a, b = _root(parent, i), _root(parent, j)
        if a == b:
            continue
        if a < b:
            parent[b] = a
        else:
            parent[a] = b
    count = 0
    for i in range(n):
        r = _root(parent, i)
        if r == i:  # roots are the smallest log of their island: met before the others
            labels[i] = count
            count += 1
        else:
            labels[i] = labels[r]
    return count


def islands(pairs, n):
    """Island label per log from a pair list.

    Parameters
    ----------
    pairs : (k, 2) int array
        Candidate pairs (i, j) of logs; an entry < 0 (a wall or obstacle) links nothing.
    n : int
        Number of logs.

    Returns
    -------
    (n,) int64 array
        Labels 0 .. count - 1, numbered by the smallest log of each island.
    """
    p = np.asarray(pairs)
    if p.size == 0:
        p = np.empty((0, 2), np.int64)
    if p.ndim != 2 or p.shape[1] != 2 or not np.issubdtype(p.dtype, np.integer):
        raise ArgumentError(f"islands: pairs must be a (k, 2) array of log indices, got shape "
                            f"{p.shape} of {p.dtype}")
    p = p.astype(np.int64, copy=False)
    if p.size and p.max() >= n:
        raise ArgumentError(f"islands: pairs hold log index {int(p.max())}, not below n = {n} "
                            "(the number of logs)")
    labels, _ = island_labels(int(n), np.ascontiguousarray(p[:, 0]),
                              np.ascontiguousarray(p[:, 1]))
    return labels


@nb.njit(cache=True)
def island_runs(labels, count, body1):
    """Contacts grouped by the island of their first body, in their given order within each.

    Returns (order, start): the contacts of island q are order[start[q]:start[q + 1]].
    """
    start = np.empty(count + 1, np.int64)
    order = np.empty(body1.size, np.int64)
    runs_into(labels, count, body1, body1.size, order, start, np.empty(count, np.int64))
    return order, start


@nb.njit(cache=True, _nrt=False)
def runs_into(labels, count, body1, k, order, start, fill):
    """``island_runs`` of the first k contacts into ``order``, ``start`` (work: ``fill``)."""
    for q in range(count + 1):
        start[q] = 0
    for c in range(k):
        start[labels[body1[c]] + 1] += 1
    for q in range(count):
        start[q + 1] += start[q]
    for q in range(count):
        fill[q] = start[q]
    for c in range(k):
        q = labels[body1[c]]
        order[fill[q]] = c
        fill[q] += 1


def swept_islands(swept, reach):
    """Islands of logs from the boxes their centres swept: (labels, pairs).

    Parameters
    ----------
    swept : (n, 4) array
        xmin, ymin, xmax, ymax of each log's centre over the time considered.
    reach : (n,) array or float
        How far the log's surface reaches from its centre (L / 2 + r), plus any margin.

    Returns
    -------
    labels : (n,) int64
        As ``islands``.
    pairs : (k, 2) int64
        The logs whose swept capsule boxes overlap (``broadphase.grid_pairs``' order).
    """
    from driftlog.contact.broadphase import grid_pairs

    b = np.asarray(swept, float)
    if b.ndim != 2 or b.shape[1] != 4:
        raise ArgumentError(f"swept_islands: swept must be an (n, 4) array of xmin, ymin, "
                            f"xmax, ymax, got shape {b.shape}")
    n = b.shape[0]
    r = np.broadcast_to(np.asarray(reach, float), (n,))
    if not (np.all(np.isfinite(b)) and np.all(np.isfinite(r)) and np.all(r >= 0)
            and np.all(b[:, 2:] >= b[:, :2])):
        raise ArgumentError("swept_islands: boxes must be finite with xmax >= xmin and "
                            "ymax >= ymin, reach finite and >= 0")
    x, y = 0.5 * (b[:, 0] + b[:, 2]), 0.5 * (b[:, 1] + b[:, 3])
    ex, ey = 0.5 * (b[:, 2] - b[:, 0]) + r, 0.5 * (b[:, 3] - b[:, 1]) + r
    pairs = grid_pairs(x, y, ex, ey)
    return islands(pairs, n), pairs
