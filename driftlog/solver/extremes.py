"""Per-face extremes of a flood: maximum level, depth and speed, and the arrival time.

Updated after every time step (not only at outputs), so that a peak between two outputs is
kept; stored in the flow file at every output, so that a resumed run continues them.  The
arrival time is the first time the depth exceeds ``arrival_depth`` (NaN: never reached).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from driftlog._numba import kernel, written_zeros
from driftlog.solver.layout import all_runs

__all__ = ["Extremes", "update_extremes", "volume_sum", "ARRIVAL_DEPTH", "EXTREME_FIELDS"]

ARRIVAL_DEPTH = 0.05  # m: a wave front, not the film a wet/dry front leaves ahead of it



@nb.njit(cache=True)
def volume_sum(h, area):
    """sum(h * area), compensated (Neumaier), in the given order on the calling thread.

    The volume of the balance (20): the same number on every machine, whatever its cores
    (``np.dot`` splits a long sum between the BLAS's threads, and waking them cost 4-7 ms of
    CPU per call on the shared machine, for microseconds of arithmetic).
    """
    s = 0.0
    c = 0.0
    for i in range(h.shape[0]):
        x = h[i] * area[i]
        t = s + x
        if abs(s) >= abs(x):
            c += (s - t) + x
        else:
            c += (x - t) + s
        s = t
    return s + c


# flow-file variable name -> attributes
EXTREME_FIELDS = {
    "max_water_level": dict(long_name="maximum free-surface level", units="m"),
    "max_water_depth": dict(long_name="maximum water depth", units="m"),
    "max_speed": dict(long_name="maximum depth-averaged speed", units="m s-1"),
    "arrival_time": dict(long_name="first time the depth exceeds arrival_depth "
                         "(NaN: never)", units="s"),
}


@kernel
def update_extremes(h, hu, hv, z, t, hdry, arrival_depth, max_level, max_depth, max_speed,
                    arrival, runs):
    """Fold the state at time t into the running extremes, on the faces of ``runs``.

    Run k: faces ``runs[k, 0]`` to ``runs[k, 1] - 1`` (``layout.face_runs``); faces outside
    them must be empty (h = 0: nothing to fold in), as the solver's active set guarantees.
    """
    for r in nb.prange(runs.shape[0]):
        for g in range(runs[r, 0], runs[r, 1]):
            f = np.uint64(g)  # unsigned: no negative-index wraparound, the loop vectorises
            hf = h[f]
            if hf <= 0.0:
                continue
            level = hf + z[f]
            if level > max_level[f]:
                max_level[f] = level
            if hf > max_depth[f]:
                max_depth[f] = hf
            if hf > hdry:
                speed = math.sqrt(hu[f] * hu[f] + hv[f] * hv[f]) / hf
                if speed > max_speed[f]:
                    max_speed[f] = speed
            if hf > arrival_depth and math.isnan(arrival[f]):
                arrival[f] = t


class Extremes:
    """The running extremes of a run (arrays of n_faces).

    ``order``: the solver's internal numbering (``order[i]`` is the mesh's face of internal
    face i; None: the mesh's own).  The arrays are kept in it, ``update`` takes the state in
    it, ``arrays`` and ``load`` speak the mesh's numbering.
    """

    def __init__(self, n_faces, parallel=False, order=None):
        self._kernel = update_extremes.parallel if parallel else update_extremes.serial
        self._all = all_runs(n_faces)  # every face
        self._order = order
        if order is not None:
            self._inv = np.empty_like(order)
            self._inv[order] = np.arange(order.size)
        self.max_level = np.full(n_faces, -np.inf)
        self.max_depth = written_zeros(n_faces)  # not np.zeros: see written_zeros
        self.max_speed = written_zeros(n_faces)
        self.arrival = np.full(n_faces, np.nan)

    def update(self, h, hu, hv, z, t, hdry, arrival_depth, serial=False, runs=None):
        """Fold the state at time t in (``serial``: the serial kernel, same numbers).

        ``runs``: only the faces of these runs may hold water (``update_extremes``; None: any
        face).
        """
        (update_extremes.serial if serial else self._kernel)(
            h, hu, hv, z, t, hdry, arrival_depth, self.max_level, self.max_depth, self.max_speed,
            self.arrival, self._all if runs is None else runs)

    def arrays(self):
        """Flow-file variable name -> array (in the mesh's numbering)."""
        arrs = (self.max_level, self.max_depth, self.max_speed, self.arrival)
        if self._order is not None:
            arrs = tuple(a[self._inv] for a in arrs)
        return dict(zip(EXTREME_FIELDS, arrs, strict=True))

    def load(self, arrays):
        """Continue from stored extremes (a resumed run; the mesh's numbering)."""
        pick = (lambda a: a) if self._order is None else (lambda a: np.asarray(a)[self._order])
        self.max_level[:], self.max_depth[:], self.max_speed[:], self.arrival[:] = (
            pick(arrays[k]) for k in EXTREME_FIELDS)

