"""Per-face extremes of a flood: maximum level, depth and speed, and the arrival time.

Updated after every time step (not only at outputs), so that a peak between two outputs is
kept; stored in the flow file at every output, so that a resumed run continues them.  The
arrival time is the first time the depth exceeds ``arrival_depth`` (NaN: never reached).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from driftlog._numba import kernel

__all__ = ["Extremes", "update_extremes", "ARRIVAL_DEPTH", "EXTREME_FIELDS"]

ARRIVAL_DEPTH = 0.05  # m: a wave front, not the film a wet/dry front leaves ahead of it

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
                    arrival):
    """Fold the state at time t into the running extremes."""
    for f in nb.prange(h.shape[0]):
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
    """The running extremes of a run (arrays of n_faces)."""

    def __init__(self, n_faces):
        self.max_level = np.full(n_faces, -np.inf)
        self.max_depth = np.zeros(n_faces)
        self.max_speed = np.zeros(n_faces)
        self.arrival = np.full(n_faces, np.nan)

    def update(self, h, hu, hv, z, t, hdry, arrival_depth):
        """Fold the state at time t in."""
        update_extremes(h, hu, hv, z, t, hdry, arrival_depth, self.max_level, self.max_depth,
                        self.max_speed, self.arrival)

    def arrays(self):
        """Flow-file variable name -> array."""
        return dict(zip(EXTREME_FIELDS, (self.max_level, self.max_depth, self.max_speed,
                                         self.arrival), strict=True))

    def load(self, arrays):
        """Continue from stored extremes (a resumed run)."""
        self.max_level[:], self.max_depth[:], self.max_speed[:], self.arrival[:] = (
            arrays[k] for k in EXTREME_FIELDS)

