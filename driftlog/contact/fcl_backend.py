"""The FCL backend (python-fcl): exact distances by ``fcl.distance()``, 3D obstacle meshes.

Logs are ``fcl.Capsule`` lying in the horizontal plane z = 0 (FCL's capsule axis is z; it is
turned onto (cos theta, sin theta, 0)); piers are standing capsules (a cylinder near z = 0;
``fcl.Cylinder`` distances are off by centimetres); walls and polygon
edges are vertical quads (two-triangle ``fcl.BVHModel``); a 3D obstacle mesh is one
``fcl.BVHModel`` of the whole mesh, at its own elevation, the logs' plane being its cut height
z (so the distance is to the real geometry, not to the cut).

Only ``fcl.distance()`` is used, with signed distances and nearest points: measured on
python-fcl 0.7 (BENCHMARKS.md, Contacts), ``collide()`` returns wrong normals and depths for
capsules whose axes cross, and ``continuousCollide()`` misses plain crossings (conservative
advancement) or refuses the settings (ray shooting, polynomial solver).  When two shapes
overlap, FCL's nearest points are witness points of the penetration (the normal is reversed,
and undefined when the capsule axes cross; for capsule-mesh pairs the two points come in
swapped order, put back by which one lies on the log): overlapping pairs take their normal
and depth from the native kernel, which is exact there.  So do pairs touching within
``_TOUCH``: FCL's penetration solver can throw an uncaught C++ exception there and abort the
process (seen on two log capsules touching).

Broad phase: the native hashed grid (the narrow phase is what differs between backends).
"""

from __future__ import annotations

import fcl
import numpy as np

from driftlog.columns import CAP_AX, CAP_BY, CAP_R, THETA, X, Y
from driftlog.contact.geometry import NRES, capsule_gap, log_endpoints
from driftlog.contact.native import NativeBackend

__all__ = ["FCLBackend", "horizontal_rotation", "log_object"]

_HEIGHT = 20.0  # vertical extent of prisms standing for 2D obstacles, m
# pairs whose native gap (exact for capsules; to the cut for a 3D mesh, which the mesh then
# touches as well) is at most this are measured by the native kernel, never by FCL
_TOUCH = 1e-5


def horizontal_rotation(theta):
    """Rotation taking FCL's capsule axis (z) onto (cos theta, sin theta, 0)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[0.0, -s, c], [0.0, c, s], [-1.0, 0.0, 0.0]])


def log_object(x, y, theta, length, radius, z=0.0):
    """A log as an ``fcl.CollisionObject`` (capsule in the plane at height z)."""
    return fcl.CollisionObject(fcl.Capsule(float(radius), float(length)),
                               fcl.Transform(horizontal_rotation(theta), [x, y, z]))


def _quad(ax, ay, bx, by, z):
    v = np.array([[ax, ay, z - _HEIGHT / 2], [bx, by, z - _HEIGHT / 2],
                  [bx, by, z + _HEIGHT / 2], [ax, ay, z + _HEIGHT / 2]])
    m = fcl.BVHModel()
    m.beginModel(4, 2)
    m.addSubModel(v, np.array([[0, 1, 2], [0, 2, 3]]))
    m.endModel()
    return fcl.CollisionObject(m, fcl.Transform())


def _mesh(vertices, triangles):
    m = fcl.BVHModel()
    m.beginModel(len(vertices), len(triangles))
    m.addSubModel(np.asarray(vertices, float), np.asarray(triangles, np.int64))
    m.endModel()
    return fcl.CollisionObject(m, fcl.Transform())


def _axis_distance(p, seg):
    a, b = np.asarray(seg[:2]), np.asarray(seg[2:4])
    d = b - a
    dd = d @ d
    t = 0.0 if dd == 0.0 else min(max((p[:2] - a) @ d / dd, 0.0), 1.0)
    return np.hypot(*(p[:2] - a - t * d))


def _patch_middle(out, seg1, seg2):
    """Move the contact point of a side-by-side contact to the middle of the patch.

    Such contacts touch along a segment, where FCL's witness point is anywhere; the impulse
    acts at the middle of the patch (as the native kernel's) lest it spin the logs.
    """
    nx, ny = out[1], out[2]
    tx, ty = -ny, nx
    d1 = (seg1[2] - seg1[0]) * nx + (seg1[3] - seg1[1]) * ny
    d2 = (seg2[2] - seg2[0]) * nx + (seg2[3] - seg2[1]) * ny
    l1 = np.hypot(seg1[2] - seg1[0], seg1[3] - seg1[1])
    l2 = np.hypot(seg2[2] - seg2[0], seg2[3] - seg2[1])
    if l1 == 0.0 or l2 == 0.0 or abs(d1) > 1e-6 * l1 or abs(d2) > 1e-6 * l2:
        return
    a = sorted((seg1[0] * tx + seg1[1] * ty, seg1[2] * tx + seg1[3] * ty))
    b = sorted((seg2[0] * tx + seg2[1] * ty, seg2[2] * tx + seg2[3] * ty))
    lo, hi = max(a[0], b[0]), min(a[1], b[1])
    if lo > hi:
        return
    shift = 0.5 * (lo + hi) - (out[3] * tx + out[4] * ty)
    out[3] += shift * tx
    out[4] += shift * ty


class FCLBackend:
    """Distances by ``fcl.distance()``; same interface as ``NativeBackend``.

    Parameters
    ----------
    obstacles : Obstacles
    """

    name = "fcl"

    def __init__(self, obstacles):
        self.obstacles = obstacles
        self.native = NativeBackend(obstacles)
        self.request = fcl.DistanceRequest(enable_nearest_points=True,
                                           enable_signed_distance=True)
        self.z = np.zeros(len(obstacles.names))  # the logs' plane, per obstacle
        mesh_obj = {}
        for k, (v, t, z) in obstacles.meshes.items():
            mesh_obj[k] = _mesh(v, t)
            self.z[k] = z
        self._objects = self._capsule_objects(obstacles.capsules, obstacles.owner, mesh_obj)
        self._static = list(self._objects)
        self.capsules, self.owner = obstacles.capsules, obstacles.owner

    def set_capsules(self, capsules, owner):
        """The fixed capsules from now on: the obstacles', then the grounded logs'."""
        ns = len(self._static)
        self.native.set_capsules(capsules, owner)
        self.capsules, self.owner = capsules, owner
        self._objects = self._static + self._capsule_objects(capsules[ns:], owner[ns:], {})

    @staticmethod
    def _capsule_objects(capsules, owner, mesh_obj):
        objects = []
        for c, k in zip(capsules, owner, strict=True):
            if k in mesh_obj:
                objects.append(mesh_obj[k])
            elif c[4] > 0 and c[0] == c[2] and c[1] == c[3]:
                # a standing capsule, not fcl.Cylinder: FCL's capsule-cylinder distance (GJK)
                # is off by centimetres (BENCHMARKS.md, Contacts), capsule-capsule is exact
                objects.append(fcl.CollisionObject(
                    fcl.Capsule(float(c[4]), _HEIGHT), fcl.Transform([c[0], c[1], 0.0])))
            elif c[4] > 0:
                x, y = 0.5 * (c[0] + c[2]), 0.5 * (c[1] + c[3])
                length = float(np.hypot(c[2] - c[0], c[3] - c[1]))
                th = float(np.arctan2(c[3] - c[1], c[2] - c[0]))
                objects.append(log_object(x, y, th, length, c[4]))
            else:
                objects.append(_quad(*c[:4], 0.0))
        return objects

    def candidates(self, S, length, radius, margin, skin=None, ids=None):
        """The native broad phase (kept between calls with ``skin``: ``NativeBackend``)."""
        return self.native.candidates(S, length, radius, margin, skin, ids)

    def _measure(self, o1, o2, out, fallback, seg1, seg2):
        fallback(out)
        if out[0] <= _TOUCH:
            # touching or overlapping: the native result.  FCL's penetration solver (EPA)
            # may throw there, which python-fcl does not catch: the process aborts (fcl
            # issues 390, 445, 493; seen on two capsules 1e-6 m apart)
            return
        res = fcl.DistanceResult()
        d = fcl.distance(o1, o2, self.request, res)
        if d <= 0.0:
            return  # overlap: FCL's witness points give no normal (module doc)
        p1, p2 = res.nearest_points
        if _axis_distance(p1, seg1) > _axis_distance(p2, seg1):
            p1, p2 = p2, p1  # python-fcl 0.7 swaps them for shape-mesh pairs
        w = (p1 - p2)[:2]
        nrm = np.hypot(w[0], w[1])
        if nrm <= 1e-6 * d:
            return  # nearest above or below (a 3D mesh): no direction in the plane
        out[0] = d
        out[1], out[2] = w / nrm
        out[3], out[4] = 0.5 * (p1[:2] + p2[:2])
        _patch_middle(out, seg1, seg2)

    def gaps(self, S, length, radius, ll, lo):
        """Gaps, normals and contact points (k, NRES) of log-log and log-obstacle pairs."""
        r_ll = np.empty((ll.shape[0], NRES))
        r_lo = np.empty((lo.shape[0], NRES))
        used = np.unique(np.concatenate([ll.ravel(), lo[:, 0]])) if len(ll) + len(lo) else []
        logs = {int(i): log_object(S[i, X], S[i, Y], S[i, THETA], length[i], radius[i])
                for i in used}
        ends = {int(i): log_endpoints(S[i, X], S[i, Y], S[i, THETA], length[i]) for i in used}
        for k, (i, j) in enumerate(ll):
            self._measure(logs[int(i)], logs[int(j)], r_ll[k], lambda o, i=i, j=j: capsule_gap(
                *ends[int(i)], radius[i], *ends[int(j)], radius[j], o), ends[int(i)],
                ends[int(j)])
        caps, owner = self.capsules, self.owner
        for k, (i, c) in enumerate(lo):
            obj = self._objects[c]
            zi = self.z[owner[c]] if owner[c] < self.z.size else 0.0  # a grounded log: 0
            o1 = logs[int(i)]
            if zi != 0.0:  # a 3D mesh: the log lies at the cut height
                o1 = log_object(S[i, X], S[i, Y], S[i, THETA], length[i], radius[i], zi)
            seg = caps[c, CAP_AX:CAP_BY + 1]  # a, b
            self._measure(o1, obj, r_lo[k], lambda o, i=i, c=c, seg=seg: capsule_gap(
                *ends[int(i)], radius[i], *seg, caps[c, CAP_R], o), ends[int(i)], seg)
        return r_ll, r_lo
