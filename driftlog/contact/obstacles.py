"""Obstacles as static capsules: piers, polygons, polylines, mesh walls, cut 3D meshes.

Bridge piers are circles, 3D obstacle meshes (meshio formats) are cut by the horizontal plane
of the logs.

Every obstacle becomes a set of static capsules (ax, ay, bx, by, r): a circle is a capsule of
zero length, an edge a capsule of zero radius.  ``owner`` gives each capsule's obstacle index,
which hit records carry as ``-(index + 1)``; ``names`` labels the obstacles.  3D meshes are
kept whole (``meshes``) for the FCL backend, which measures distances to the real geometry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from driftlog.errors import ScenarioError
from driftlog.schema import Key, Section

__all__ = ["Obstacles", "cut_triangles", "read_obstacle_mesh"]


def _edges(points, closed):
    p = np.asarray(points, float)
    q = np.roll(p, -1, axis=0) if closed else p[1:]
    p = p if closed else p[:-1]
    return np.column_stack([p, q, np.zeros(len(p))])


def cut_triangles(vertices, triangles, z):
    """Segments (k, 4) where triangles of a 3D mesh cross the plane at height z.

    A vertex exactly on the plane counts as above it, so a triangle touching the plane at one
    vertex gives no segment and one lying in the plane gives none either (it has no thickness).
    """
    v = np.asarray(vertices, float)
    t = np.asarray(triangles, np.int64)
    d = v[t, 2] - z  # (m, 3) heights above the plane
    above = d >= 0.0
    cut = above.any(axis=1) & ~above.all(axis=1)
    t, d, above = t[cut], d[cut], above[cut]
    # the lone vertex (the one on its own side) and the two others
    lone = np.where(above.sum(axis=1) == 1, np.argmax(above, axis=1), np.argmin(above, axis=1))
    a = t[np.arange(len(t)), lone]
    b = t[np.arange(len(t)), (lone + 1) % 3]
    c = t[np.arange(len(t)), (lone + 2) % 3]
    da, db, dc = (d[np.arange(len(t)), lone], d[np.arange(len(t)), (lone + 1) % 3],
                  d[np.arange(len(t)), (lone + 2) % 3])
    s1 = (da / (da - db))[:, None]
    s2 = (da / (da - dc))[:, None]
    p1 = v[a, :2] + s1 * (v[b, :2] - v[a, :2])
    p2 = v[a, :2] + s2 * (v[c, :2] - v[a, :2])
    return np.column_stack([p1, p2])


def read_obstacle_mesh(path, key="obstacles.path"):
    """(vertices (n, 3), triangles (m, 3)) of a 3D surface mesh file (quads are split)."""
    import meshio

    try:
        m = meshio.read(path)
    except (Exception, SystemExit) as exc:  # meshio raises many kinds (ansys: SystemExit)
        raise ScenarioError(key, str(path),
                            f"cannot be read as a mesh by meshio ({exc})") from None
    v = np.asarray(m.points, float)
    if v.ndim != 2 or len(v) == 0:  # a text file meshio reads as an empty STL
        raise ScenarioError(key, str(path), "holds no points: not a surface mesh (an empty or "
                            "text file?); obstacle meshes need 3D points and triangle or quad "
                            "cells")
    if v.shape[1] == 2:
        raise ScenarioError(key, str(path), "is a 2D mesh; obstacle meshes need 3D points "
                            "(x, y, z) to be cut by the logs' plane")
    tris = []
    for block in m.cells:
        if block.type == "triangle":
            tris.append(block.data)
        elif block.type == "quad":
            q = block.data
            tris += [q[:, [0, 1, 2]], q[:, [0, 2, 3]]]
    if not tris:
        raise ScenarioError(key, str(path), "has no triangle or quad cells (a surface mesh "
                            "is needed)")
    return v, np.concatenate(tris).astype(np.int64)


@dataclass
class Obstacles:
    """Static obstacles: capsules, their owner obstacle, names, and whole 3D meshes."""

    capsules: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    owner: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    names: list = field(default_factory=list)
    kinds: list = field(default_factory=list)
    groups: list = field(default_factory=list)  # reporting group of each obstacle ("" none)
    meshes: dict = field(default_factory=dict)  # obstacle index -> (vertices, triangles, z)

    def add(self, name, kind, capsules, group=""):
        """Add one obstacle made of capsules (k, 5); returns its index."""
        k = len(self.names)
        c = np.asarray(capsules, float).reshape(-1, 5)
        self.capsules = np.vstack([self.capsules, c])
        self.owner = np.concatenate([self.owner, np.full(len(c), k, np.int64)])
        self.names.append(name)
        self.kinds.append(kind)
        self.groups.append(str(group or ""))
        return k

    def add_circle(self, center, radius, name="pier"):
        """A circle (a bridge pier): a capsule of zero length."""
        cx, cy = center
        return self.add(name, "circle", [cx, cy, cx, cy, radius])

    def add_polygon(self, points, name="polygon"):
        """A closed polygon: its edges (zero radius)."""
        return self.add(name, "polygon", _edges(points, closed=True))

    def add_segments(self, points, name="segments"):
        """An open polyline: its segments (zero radius)."""
        return self.add(name, "segments", _edges(points, closed=False))

    def add_mesh(self, path, z, name="mesh", key="obstacles.path"):
        """A 3D surface mesh cut by the plane at height z (kept whole for FCL)."""
        v, t = read_obstacle_mesh(path, key)
        seg = cut_triangles(v, t, z)
        if len(seg) == 0:
            raise ScenarioError(key.replace("path", "z"), z,
                                f"the plane z = {z} does not cut the mesh {Path(path).name} "
                                f"(its z range is {v[:, 2].min():.6g} to {v[:, 2].max():.6g})")
        k = self.add(name, "mesh", np.column_stack([seg, np.zeros(len(seg))]))
        self.meshes[k] = (v, t, float(z))
        return k

    def add_walls(self, mesh, name="walls"):
        """The mesh's boundary edges tagged ``wall`` (open boundaries are not walls)."""
        seg = mesh.boundary_segments(tags=["wall"])
        if len(seg) == 0:
            return None
        return self.add(name, "walls", np.column_stack([seg, np.zeros(len(seg))]))

    @classmethod
    def from_tables(cls, tables: list, walls=None):
        """Obstacles from validated ``[[obstacles]]`` tables (``OBSTACLES_SECTION``).

        Then the wall boundaries of the mesh ``walls``, if given.
        """
        obs = cls()
        for i, o in enumerate(tables):
            p = f"obstacles[{i}]"
            name = o["name"] or f"{o['type']}_{i}"
            kind = o["type"]
            if kind == "circle":
                if o["center"] is None or o["radius"] is None:
                    raise ScenarioError(f"{p}.center" if o["center"] is None else f"{p}.radius",
                                        None, "type = 'circle' needs center and radius")
                obs.add_circle(o["center"], o["radius"], name)
            elif kind in ("polygon", "segments"):
                pts = o["points"]
                need = 3 if kind == "polygon" else 2
                if pts is None or len(pts) < need:
                    raise ScenarioError(f"{p}.points", pts, f"type = {kind!r} needs at least "
                                        f"{need} [x, y] points")
                (obs.add_polygon if kind == "polygon" else obs.add_segments)(pts, name)
            elif kind == "mesh":
                if not o["path"]:
                    raise ScenarioError(f"{p}.path", None, "type = 'mesh' needs a 3D mesh file")
                obs.add_mesh(o["path"], o["z"], name, key=f"{p}.path")
            obs.groups[-1] = o["group"]
        if walls is not None:
            obs.add_walls(walls)
        return obs


# --------------------------------------------------------------------- the scenario section
def _check_obstacle(t, prefix, scen):
    """A name labels one obstacle: the hit counts and the clogging table report by name."""
    name = t["name"]
    if not name:
        return
    i = int(prefix[prefix.index("[") + 1:-1])
    earlier = [o.get("name") for o in (scen["obstacles"] or [])[:i]]
    if name in earlier:
        raise ScenarioError(f"{prefix}.name", name, f"is also obstacles[{earlier.index(name)}]"
                            "'s name: each obstacle needs its own (hits and the clogging table "
                            "report by name; a bridge's piers share a group, not a name)")
    groups = {o.get("group") for o in (scen["obstacles"] or [])} - {"", None}
    if name in groups:
        raise ScenarioError(f"{prefix}.name", name, "is also a group's name: the clogging "
                            "table reports obstacles and groups together, give them different "
                            "names")


OBSTACLES_SECTION = Section("obstacles", [
    Key("name", "str", "", "label used in hit counts"),
    Key("group", "str", "", "obstacles of the same group (the piers of one bridge) are also "
        "reported together in an ensemble's clogging table"),
    Key("type", "str", "circle", "obstacle shape", choices=("circle", "polygon", "segments",
                                                            "mesh")),
    Key("center", "point", None, "circle centre", "m", when="type = circle"),
    Key("radius", "float", None, "circle radius", "m", min=0.0, exclusive_min=True,
        when="type = circle"),
    Key("points", "points", None, "polygon vertices or polyline points", "m", length=2,
        when="type = polygon, segments"),
    Key("path", "path", "", "3D obstacle mesh file (meshio formats)", must_exist=True,
        when="type = mesh"),
    Key("z", "float", 0.0, "elevation of the plane that cuts 3D obstacle meshes", "m",
        when="type = mesh"),
], doc="bridge piers, walls and other obstacles", repeated=True, check=_check_obstacle)
