"""Time of impact: conservative advancement on the capsule distance (docs/model.md section 13.4).

For two convex bodies at gap d with the closest-point normal n, the separating line through the
gap keeps them apart by at least d + (Delta U . n) t - (|omega_1| R_1 + |omega_2| R_2) t over a
time t of motion at constant velocities (no point of a body rotating about its centre moves
faster than |omega| R, R = L/2 + r the reach of the capsule).  So no contact can happen before

    t = (d - d_target) / max(0, |omega_1| R_1 + |omega_2| R_2 - Delta U . n)

(Mirtich's conservative advancement): stepping by the least such t over the candidate pairs
never skips a contact, grazing ones included, and converges on the first contact time t*.
Pairs already in contact (d <= tol) may close down to -tol (the stated interpenetration
tolerance), so that a log resting against a pier does not stop time; pairs that overlap from
the start (logs seeded across each other) may deepen by tol.

The paper's alternative (dichotomy: halve the step while logs overlap at its end) lives in
``model.py``: it needs no bound, but a pair that passes through another within one step and is
apart again at its end is never seen.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.columns import CX, CY, GAP, NX, NY, OMEGA, UB, VB, X, Y

__all__ = ["conservative_step", "motion_margin", "skin"]


@nb.njit(cache=True)
def conservative_step(S, length, radius, body1, body2, res, tol, h_max, near):
    """Largest step (<= h_max) over which no candidate pair closes below its target gap.

    Pairs closer than ``near`` that separate at their contact point (velocities of the
    contact point, rotation included) are left out: bounding them by their whole rotation
    would make a log that has just bounced crawl away in steps of tol / (omega R) (a Zeno
    crawl); the end-of-step overlap check catches one that turns back.
    """
    h = h_max
    for c in range(body1.size):
        i, j = body1[c], body2[c]
        gap, nx, ny = res[c, GAP], res[c, NX], res[c, NY]
        dux, duy = S[i, UB], S[i, VB]
        rot = abs(S[i, OMEGA]) * (0.5 * length[i] + radius[i])
        r1x, r1y = res[c, CX] - S[i, X], res[c, CY] - S[i, Y]
        vc = (S[i, UB] - S[i, OMEGA] * r1y) * nx + (S[i, VB] + S[i, OMEGA] * r1x) * ny
        if j >= 0:
            dux -= S[j, UB]
            duy -= S[j, VB]
            rot += abs(S[j, OMEGA]) * (0.5 * length[j] + radius[j])
            r2x, r2y = res[c, CX] - S[j, X], res[c, CY] - S[j, Y]
            vc -= (S[j, UB] - S[j, OMEGA] * r2y) * nx + (S[j, VB] + S[j, OMEGA] * r2x) * ny
        if gap < near and vc >= 0.0:
            continue
        vn = dux * nx + duy * ny  # > 0: separating
        rate = rot - vn
        if rate <= 0.0:
            continue
        # apart: stop within the tolerance; touching: may close to -tol; overlapping
        # already (logs seeded so): may deepen by tol at most
        target = 0.5 * tol if gap > tol else (-tol if gap >= -tol else gap - tol)
        h = min(h, max(gap - target, 0.0) / rate)
    return h


def motion_margin(S, length, radius, dt, tol):
    """How far each log's surface can move in dt at its current velocities, plus tol."""
    speed = np.hypot(S[:, UB], S[:, VB]) + np.abs(S[:, OMEGA]) * (0.5 * length + radius)
    return speed * dt + tol


@nb.njit(cache=True)
def skin(S, length, radius, horizon):
    """How far each log may move: its motion over ``horizon``, at least the logs' mean.

    The mean is the floor: a log hit by another changes speed.  The kept broad phase's
    skin: a cost setting only, never a bound the contacts rely on.
    """
    n = S.shape[0]
    out = np.empty(n)
    total = 0.0
    for i in range(n):
        v = abs(S[i, UB]) + abs(S[i, VB]) + abs(S[i, OMEGA]) * (0.5 * length[i] + radius[i])
        out[i] = v * horizon
        total += v
    floor = total / max(n, 1) * horizon
    for i in range(n):
        out[i] = max(out[i], floor)
    return out
