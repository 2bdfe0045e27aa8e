"""The native backend: hashed-grid broad phase and the numba capsule narrow phase.

``candidates`` boxes the logs (capsule plus a per-log margin: how far the log can move in the
step) and returns the overlapping log-log and log-obstacle pairs; ``gaps`` measures them
exactly (``geometry.capsule_gap``), in parallel over pairs when there are many.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import NX, NY, THETA, X, Y
from driftlog.contact.broadphase import PairCache, StaticGrid, grid_pairs, log_boxes
from driftlog.contact.geometry import NRES, capsule_gap, capsule_row, log_endpoints

__all__ = ["NativeBackend", "end_contacts"]


@kernel
def _log_log_gaps(pairs, S, length, radius, out):
    for k in nb.prange(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        ax, ay, bx, by = log_endpoints(S[i, X], S[i, Y], S[i, THETA], length[i])
        cx, cy, dx, dy = log_endpoints(S[j, X], S[j, Y], S[j, THETA], length[j])
        capsule_gap(ax, ay, bx, by, radius[i], cx, cy, dx, dy, radius[j], out[k])


@kernel
def _log_obstacle_gaps(pairs, S, length, radius, caps, out):
    for k in nb.prange(pairs.shape[0]):
        i, c = pairs[k, 0], pairs[k, 1]
        ax, ay, bx, by = log_endpoints(S[i, X], S[i, Y], S[i, THETA], length[i])
        cax, cay, cbx, cby, cr = capsule_row(caps, c)
        capsule_gap(ax, ay, bx, by, radius[i], cax, cay, cbx, cby, cr, out[k])


@nb.njit(cache=True, _nrt=False)
def _ends_against(ax, ay, bx, by, r1, cx, cy, dx, dy, r2, flip, out, row):
    """Gaps of the two axis ends of capsule 1 (as discs) to capsule 2, in out[row:row+2].

    ``flip``: capsule 1 is body 2 of the contact (normal reversed).
    """
    for e in range(2):
        px, py = (ax, ay) if e == 0 else (bx, by)
        capsule_gap(px, py, px, py, r1, cx, cy, dx, dy, r2, out[row + e])
        if flip:
            out[row + e, NX] = -out[row + e, NX]
            out[row + e, NY] = -out[row + e, NY]


@kernel
def _log_log_manifold(pairs, S, length, radius, out):
    for k in nb.prange(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        ax, ay, bx, by = log_endpoints(S[i, X], S[i, Y], S[i, THETA], length[i])
        cx, cy, dx, dy = log_endpoints(S[j, X], S[j, Y], S[j, THETA], length[j])
        _ends_against(ax, ay, bx, by, radius[i], cx, cy, dx, dy, radius[j], False, out[k], 0)
        _ends_against(cx, cy, dx, dy, radius[j], ax, ay, bx, by, radius[i], True, out[k], 2)


@kernel
def _log_obstacle_manifold(pairs, S, length, radius, caps, out):
    for k in nb.prange(pairs.shape[0]):
        i, c = pairs[k, 0], pairs[k, 1]
        ax, ay, bx, by = log_endpoints(S[i, X], S[i, Y], S[i, THETA], length[i])
        cax, cay, cbx, cby, cr = capsule_row(caps, c)
        _ends_against(ax, ay, bx, by, radius[i], cax, cay, cbx, cby, cr, False, out[k], 0)
        # the obstacle's ends against the log (a wall's corner pressing on a log's side)
        _ends_against(cax, cay, cbx, cby, cr, ax, ay, bx, by, radius[i], True, out[k], 2)


def end_contacts(S, length, radius, caps, ll, lo):
    """Contacts of the capsules' axis ends (4 per pair: ends of 1 on 2, ends of 2 on 1).

    A log lying along a wall or along another log touches it on a line; one contact point
    (the closest) lets it rock from end to end in a time-stepping solve, the ends hold it.
    """
    r_ll = np.empty((ll.shape[0], 4, NRES))
    r_lo = np.empty((lo.shape[0], 4, NRES))
    if ll.shape[0]:
        _log_log_manifold(ll, S, length, radius, r_ll)
    if lo.shape[0]:
        _log_obstacle_manifold(lo, S, length, radius, caps, r_lo)
    return r_ll, r_lo


class NativeBackend:
    """Broad and narrow phase in numba.

    Parameters
    ----------
    obstacles : Obstacles
    """

    name = "native"

    def __init__(self, obstacles):
        self.obstacles = obstacles
        self.capsules = obstacles.capsules
        self._grid = None
        self._grid_cell = 0.0
        self.cache = PairCache()

    def set_capsules(self, capsules, owner):
        """The fixed capsules from now on: the obstacles', then the grounded logs'."""
        self.capsules = capsules
        self._grid = None  # a new grid: the kept broad phase searches again

    def _static(self, cell):
        if self._grid is None or cell > 2.0 * self._grid_cell or cell < 0.25 * self._grid_cell:
            self._grid = StaticGrid(self.capsules, cell)
            self._grid_cell = cell
        return self._grid

    def candidates(self, S, length, radius, margin, skin=None, ids=None):
        """(log pairs (k, 2), log-capsule pairs (m, 2)) whose boxes overlap.

        With ``skin`` (per log: how far it may move before the next call) the broad phase is
        kept between calls (``broadphase.PairCache``): the same pairs in the same order as a
        fresh search, the grid searched again only when a log leaves its kept box.
        """
        n = S.shape[0]
        ex, ey = np.empty(n), np.empty(n)
        log_boxes(S, length, radius, margin, ex, ey)
        x = np.ascontiguousarray(S[:, X])
        y = np.ascontiguousarray(S[:, Y])
        has_static = self.capsules.shape[0] > 0 and n > 0
        grid = self._static(2.0 * max(float(ex.max()), float(ey.max()))) if has_static else None
        if skin is not None:
            # skin: how far logs drift before the next call, or (drift, reach): and how far
            # the boxes of a later, wider query reach (held from the start)
            drift, grow = (skin, None) if not isinstance(skin, tuple) else (
                skin[0], np.maximum(skin[1] - margin, 0.0))
            ll, lo = self.cache.pairs(x, y, ex, ey, drift, ids, grid, grow)
            return ll, (lo if has_static else np.empty((0, 2), np.int64))
        ll = grid_pairs(x, y, ex, ey)
        if not has_static:
            return ll, np.empty((0, 2), np.int64)
        return ll, grid.query(x, y, ex, ey)

    def gaps(self, S, length, radius, ll, lo):
        """Exact gaps, normals and contact points (k, NRES) of both kinds of pairs."""
        r_ll = np.empty((ll.shape[0], NRES))
        r_lo = np.empty((lo.shape[0], NRES))
        if ll.shape[0]:
            _log_log_gaps(ll, S, length, radius, r_ll)
        if lo.shape[0]:
            _log_obstacle_gaps(lo, S, length, radius, self.capsules, r_lo)
        return r_ll, r_lo
