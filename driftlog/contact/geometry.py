"""Narrow phase: exact distance between 2D capsules (logs, piers, walls) in plan view.

Every body is a capsule: a segment [a, b] swept by a disc of radius r.  A log is a capsule
of axis length L and radius r; a bridge pier (circle) is a capsule of zero length; a wall or
polygon edge is a capsule of zero radius.  One kernel therefore serves capsule-capsule,
capsule-circle and capsule-segment.

The signed gap is the distance between the surfaces (negative when they overlap).  When the
axes cross the segment distance is zero and gives no direction; the gap is then minus the
penetration depth, taken along the axis normals (the Minkowski difference of two segments is
a parallelogram whose edges are parallel to the segments, so the least translation that
separates them is along one of the two normals).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.columns import CAP_AX, CAP_AY, CAP_BX, CAP_BY, CAP_R, CX, CY, GAP, NRES, NX, NY

__all__ = ["segment_closest_points", "capsule_gap", "log_endpoints", "log_capsules",
           "capsule_pair_gaps",
           "GAP", "NX", "NY", "CX", "CY", "NRES"]

# columns of a contact result: driftlog.columns GAP, NX, NY, CX, CY (NRES); of a capsule: CAP_*
_PARALLEL = 1e-12  # |sin| between the axes below which they are treated as parallel


@nb.njit(cache=True, inline="always")
def capsule_row(caps, k):
    """Capsule k of an array (n, NCAP) as (ax, ay, bx, by, r)."""
    return caps[k, CAP_AX], caps[k, CAP_AY], caps[k, CAP_BX], caps[k, CAP_BY], caps[k, CAP_R]


@nb.njit(cache=True, inline="always")
def _clamp01(v):
    return 0.0 if v < 0.0 else (1.0 if v > 1.0 else v)


@nb.njit(cache=True)
def segment_closest_points(ax, ay, bx, by, cx, cy, dx, dy):
    """Parameters (s, t) of the closest points of segments [a, b] and [c, d].

    Robust for degenerate segments (points) and parallel segments; for parallel overlapping
    segments the middle of the overlap is returned (a side-by-side contact pushes at its
    middle, not at an arbitrary end).  Crossing segments give the crossing point.
    """
    d1x, d1y = bx - ax, by - ay
    d2x, d2y = dx - cx, dy - cy
    rx, ry = ax - cx, ay - cy
    a = d1x * d1x + d1y * d1y
    e = d2x * d2x + d2y * d2y
    f = d2x * rx + d2y * ry
    tiny = 1e-300
    if a <= tiny and e <= tiny:
        return 0.0, 0.0
    if a <= tiny:
        return 0.0, _clamp01(f / e)
    c = d1x * rx + d1y * ry
    if e <= tiny:
        return _clamp01(-c / a), 0.0
    b = d1x * d2x + d1y * d2y
    denom = a * e - b * b  # = |d1 x d2|^2 >= 0
    if denom > _PARALLEL * a * e:
        s = _clamp01((b * f - c * e) / denom)
    else:
        # parallel: the projection of [c, d] on [a, b] is [t0, t1]; middle of the overlap
        t0 = -c / a
        t1 = (-c + b) / a
        lo, hi = min(t0, t1), max(t0, t1)
        lo, hi = max(lo, 0.0), min(hi, 1.0)
        s = 0.5 * (lo + hi) if lo <= hi else (0.0 if hi < 0.0 else 1.0)
        s = _clamp01(s)
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = _clamp01(-c / a)
    elif t > 1.0:
        t = 1.0
        s = _clamp01((b - c) / a)
    return s, t


@nb.njit(cache=True, inline="always")
def _crossing_depth(ax, ay, bx, by, cx, cy, dx, dy):
    """Least translation (depth, nx, ny) of segment 1 that separates crossing segments."""
    best, bnx, bny = np.inf, 0.0, 0.0
    for k in range(2):
        if k == 0:
            tx, ty = bx - ax, by - ay
        else:
            tx, ty = dx - cx, dy - cy
        nrm = np.sqrt(tx * tx + ty * ty)
        if nrm == 0.0:
            continue
        nx, ny = -ty / nrm, tx / nrm
        pa0, pa1 = ax * nx + ay * ny, bx * nx + by * ny
        pc0, pc1 = cx * nx + cy * ny, dx * nx + dy * ny
        # move 1 by +s n: min(1) + s >= max(2); or by -s n: max(1) - s <= min(2)
        s_plus = max(pc0, pc1) - min(pa0, pa1)
        s_minus = max(pa0, pa1) - min(pc0, pc1)
        if s_plus < best:
            best, bnx, bny = s_plus, nx, ny
        if s_minus < best:
            best, bnx, bny = s_minus, -nx, -ny
    return best, bnx, bny


@nb.njit(cache=True, _nrt=False)
def capsule_gap(ax, ay, bx, by, r1, cx, cy, dx, dy, r2, out):
    """Signed gap between capsule 1 ([a, b], r1) and capsule 2 ([c, d], r2).

    Fills ``out`` (NRES): gap, normal (unit, from body 2 to body 1), contact point (the middle
    of the gap or of the overlap).  Returns the gap.
    """
    s, t = segment_closest_points(ax, ay, bx, by, cx, cy, dx, dy)
    p1x, p1y = ax + s * (bx - ax), ay + s * (by - ay)
    p2x, p2y = cx + t * (dx - cx), cy + t * (dy - cy)
    wx, wy = p1x - p2x, p1y - p2y
    dist = np.sqrt(wx * wx + wy * wy)
    scale = max(abs(bx - ax) + abs(by - ay), abs(dx - cx) + abs(dy - cy), r1 + r2)
    if dist > 1e-12 * scale:
        nx, ny = wx / dist, wy / dist
        gap = dist - r1 - r2
        # middle of the gap (or of the overlap) between the two surfaces
        m = 0.5 * (r2 - r1 + dist)
        out[CX], out[CY] = p2x + m * nx, p2y + m * ny
    else:
        depth, nx, ny = _crossing_depth(ax, ay, bx, by, cx, cy, dx, dy)
        if not np.isfinite(depth):  # two coincident points: any direction
            depth, nx, ny = 0.0, 1.0, 0.0
        gap = -depth - r1 - r2
        out[CX], out[CY] = 0.5 * (p1x + p2x), 0.5 * (p1y + p2y)
    out[GAP], out[NX], out[NY] = gap, nx, ny
    return gap


@nb.njit(cache=True, inline="always")
def log_endpoints(x, y, theta, length):
    """Axis ends (ax, ay, bx, by) of a log centred at (x, y) at angle theta."""
    hx, hy = 0.5 * length * np.cos(theta), 0.5 * length * np.sin(theta)
    return x - hx, y - hy, x + hx, y + hy


def log_capsules(x, y, theta, length, radius):
    """Capsules (n, 5) = ax, ay, bx, by, r of logs (arrays) in plan view."""
    return np.column_stack([*log_endpoints(x, y, theta, length),
                            np.broadcast_to(radius, np.shape(x))])


@nb.njit(cache=True)
def capsule_pair_gaps(caps1, caps2, out):
    """Gaps of capsule pairs row by row: caps (n, 5) = ax, ay, bx, by, r; out (n, NRES)."""
    for k in range(caps1.shape[0]):
        ax, ay, bx, by, r1 = capsule_row(caps1, k)
        cx, cy, dx, dy, r2 = capsule_row(caps2, k)
        capsule_gap(ax, ay, bx, by, r1, cx, cy, dx, dy, r2, out[k])
