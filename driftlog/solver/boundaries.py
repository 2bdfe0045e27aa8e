"""Boundary conditions by tag: wall, water level, depth, discharge, Froude, rating curve, free.

A boundary condition applies to every boundary edge that carries its tag (``mesh.edge_tag``).
Per time step, the Python side turns each condition into one number per edge (``value``:
a level, a depth, a unit discharge or a Froude number); the flux kernel turns that number and
the inside state into the flux across the edge (``boundary_flux``), in the edge's normal
frame (normal pointing out of the domain):

- ``wall``: the mirror state (normal velocity reversed): no mass crosses, to round-off.
- ``level`` / ``depth``: a ghost state with the imposed depth and the velocity that keeps the
  outgoing Riemann invariant ``u_n + 2 c`` of the inside state (subcritical in- or outflow).
- ``discharge`` (inflow): the imposed total discharge Q(t) is shared between the tag's edges in
  proportion to their conveyance ``h^(5/3)`` (Manning, equal slope); the mass flux is imposed
  exactly, the depth at the edge solves ``q_n / h + 2 sqrt(g h) = u_n + 2 c`` of the inside.
- ``froude``: outflow with ``u_n = Fr sqrt(g h)`` at the inside depth (the reference flume has
  Fr = 0.18 downstream).
- ``rating``: outflow Q(level) from a table, the level being the tag's mean wet water level,
  shared by conveyance like a discharge.
- ``free``: zero-gradient (transmissive) outflow: the ghost copies the inside state where
  the water at the edge leaves (``u_n >= 0``); where it flows inwards (an eddy reaching the
  boundary) the ghost is the mirror state, as at a wall, so that no water enters that the
  outside does not carry (OpenFOAM's ``inletOutlet`` with a zero inlet value does the same).
  A zero-gradient ghost would let in whatever the eddy draws: on a channel whose outlet
  crosses the wake of a block, 7 % of the inflow at second order (1.5 % at first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from driftlog.errors import ScenarioError
from driftlog.solver.riemann import riemann_flux

__all__ = ["Boundary", "BoundarySet", "boundary_flux", "KINDS", "WALL", "LEVEL", "DEPTH",
           "DISCHARGE", "FROUDE", "RATING", "FREE"]

WALL, LEVEL, DEPTH, DISCHARGE, FROUDE, RATING, FREE = range(7)
KINDS = {"wall": WALL, "level": LEVEL, "depth": DEPTH, "discharge": DISCHARGE,
         "froude": FROUDE, "rating": RATING, "free": FREE}
# what each kind needs from the user
NEEDS = {"wall": "", "free": "", "level": "value or series", "depth": "value or series",
         "discharge": "value or series", "froude": "value", "rating": "table"}


@dataclass
class Boundary:
    """One boundary condition.

    Parameters
    ----------
    kind : str
        One of ``wall``, ``level``, ``depth``, ``discharge``, ``froude``, ``rating``, ``free``.
    value : float, optional
        Constant level (m), depth (m), discharge (m3/s, total over the tag, entering) or
        Froude number.
    series : (n, 2) array_like, optional
        Time series ``[[t, value], ...]`` (s, then the value's unit), linear between points,
        constant beyond the ends; for level, depth and discharge.
    table : (n, 2) array_like, optional
        Rating curve ``[[level, discharge], ...]`` (m, m3/s), levels increasing.
    """

    kind: str
    value: float | None = None
    series: object = None
    table: object = None

    def __post_init__(self):
        self.check()

    def check(self, key="boundary"):
        """Raise ScenarioError naming ``key`` when the condition is not usable."""
        if self.kind not in KINDS:
            raise ScenarioError(f"{key}.type", self.kind, "must be one of "
                                + ", ".join(repr(k) for k in KINDS))
        need = NEEDS[self.kind]
        if need == "value or series":
            if (self.value is None) == (self.series is None):
                raise ScenarioError(f"{key}.value", self.value, f"a {self.kind} boundary needs "
                                    "either value or series (not both)")
            if self.value is not None and (isinstance(self.value, bool) or not isinstance(
                    self.value, (int, float)) or not math.isfinite(self.value)):
                raise ScenarioError(f"{key}.value", self.value, f"a {self.kind} boundary value "
                                    "must be a finite number")
            if self.series is not None:
                s = _table(self.series, f"{key}.series", "[[t, value], ...]")
                if np.any(np.diff(s[:, 0]) <= 0):
                    raise ScenarioError(f"{key}.series", self.series,
                                        "times must increase strictly")
                self.series = s
            if self.kind in ("depth", "discharge"):
                vals = self.series[:, 1] if self.series is not None else [self.value]
                if np.any(np.asarray(vals) < 0):
                    raise ScenarioError(f"{key}.{'series' if self.series is not None else 'value'}",
                                        self.value if self.series is None else vals.tolist(),
                                        f"a {self.kind} must be >= 0 (discharge boundaries are "
                                        "inflows; use rating, froude or free for outflows)")
        elif need == "value":
            if self.value is None or not self.value >= 0 or not math.isfinite(self.value):
                raise ScenarioError(f"{key}.value", self.value,
                                    "a Froude number >= 0 is required")
        elif need == "table":
            if self.table is None:
                raise ScenarioError(f"{key}.table", None, "a rating boundary needs table = "
                                    "[[level, discharge], ...]")
            t = _table(self.table, f"{key}.table", "[[level, discharge], ...]")
            if np.any(np.diff(t[:, 0]) <= 0) or np.any(t[:, 1] < 0):
                raise ScenarioError(f"{key}.table", self.table, "levels must increase strictly "
                                    "and discharges be >= 0")
            self.table = t

    def at(self, t):
        """The imposed value at time t (level, depth, discharge or Froude number)."""
        if self.series is not None:
            return float(np.interp(t, self.series[:, 0], self.series[:, 1]))
        return 0.0 if self.value is None else float(self.value)


def _table(value, key, form):
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(key, value, f"must be a table {form}") from None
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 1 or not np.all(np.isfinite(a)):
        raise ScenarioError(key, value, f"must be a table {form} of finite numbers")
    return a


def as_boundary(spec, key="boundary") -> Boundary:
    """A Boundary from a Boundary, a kind name or a dict ``{type, value, series, table}``."""
    if isinstance(spec, Boundary):
        return spec
    if isinstance(spec, str):
        return Boundary(spec)
    if isinstance(spec, dict):
        unknown = set(spec) - {"type", "value", "series", "table"}
        if unknown:
            raise ScenarioError(f"{key}.{sorted(unknown)[0]}", spec[sorted(unknown)[0]],
                                "unknown key; a boundary has type, value, series, table")
        if "type" not in spec:
            raise ScenarioError(f"{key}.type", None, "is required: one of "
                                + ", ".join(repr(k) for k in KINDS))
        b = Boundary.__new__(Boundary)
        b.kind, b.value, b.series, b.table = (spec.get("type"), spec.get("value"),
                                              spec.get("series"), spec.get("table"))
        if b.value is not None and (isinstance(b.value, bool)
                                    or not isinstance(b.value, (int, float))):
            raise ScenarioError(f"{key}.value", b.value, "must be a number")
        b.check(key)
        return b
    raise ScenarioError(key, spec, "must be a boundary type name or a table")


class BoundarySet:
    """The boundary edges of a mesh with their conditions, as flat arrays for the kernels.

    Tags without a condition are walls.  ``slot[e]`` is the boundary slot of edge e (-1 for an
    interior edge); ``kind[s]``, ``value[s]``, ``tag[s]`` describe slot s.
    """

    def __init__(self, mesh, conditions=None, key="boundaries"):
        conditions = dict(conditions or {})
        for tag in conditions:
            if tag not in mesh.tag_names:
                raise ScenarioError(f"{key}.{tag}", "{...}", "no boundary edge has this tag; "
                                    "the mesh's tags are " + ", ".join(mesh.tag_names))
        self.conditions = {t: as_boundary(c, f"{key}.{t}") for t, c in conditions.items()}
        self.tag_names = list(mesh.tag_names)
        self.edges = mesh.boundary_edges
        self.slot = np.full(mesh.n_edges, -1, dtype=np.int64)
        self.slot[self.edges] = np.arange(self.edges.size)
        self.tag = mesh.edge_tag[self.edges].astype(np.int64)
        self.kind = np.full(self.edges.size, WALL, dtype=np.int64)
        for t, c in self.conditions.items():
            self.kind[self.tag == self.tag_names.index(t)] = KINDS[c.kind]
        self.value = np.zeros(self.edges.size)
        self.length = mesh.edge_length[self.edges]
        self.face = mesh.edge_faces[self.edges, 0]
        self._members = {t: np.flatnonzero(self.tag == self.tag_names.index(t))
                         for t in self.conditions}
        self.open_tags = [t for t, c in self.conditions.items() if c.kind != "wall"]

    def renumber(self, new_face, edge_perm, new_edge):
        """Go over to a solver's internal numbering (``driftlog.solver.layout``).

        ``new_face[f]``: the new number of face f; ``edge_perm[j]``: the old edge that
        becomes edge j; ``new_edge[e]``: the new number of edge e.  The slots keep their
        order (the volumes through each tag are summed in the same order), ``edges``,
        ``slot`` and ``face`` are then in the new numbering, and ``update`` takes the state
        in it.
        """
        self.edges = np.asarray(new_edge)[self.edges]
        self.slot = np.ascontiguousarray(self.slot[np.asarray(edge_perm)])
        self.face = np.asarray(new_face)[self.face]

    def update(self, t, h, bed, dry_depth):
        """Fill ``value`` for time t from the inside depths ``h`` (discharges by conveyance)."""
        for tag, c in self.conditions.items():
            s = self._members[tag]
            if c.kind in ("wall", "free") or s.size == 0:
                continue
            if c.kind in ("level", "depth", "froude"):
                self.value[s] = c.at(t)
                continue
            hin = h[self.face[s]]
            if c.kind == "discharge":
                q_total = -c.at(t)  # entering: negative along the outward normal
            else:
                wet = hin > dry_depth
                if not np.any(wet):
                    self.value[s] = 0.0
                    continue
                w = self.length[s][wet]
                level = float(np.sum(w * (hin[wet] + bed[self.face[s]][wet])) / np.sum(w))
                q_total = float(np.interp(level, c.table[:, 0], c.table[:, 1]))
            self.value[s] = _by_conveyance(q_total, hin, self.length[s], dry_depth,
                                           inflow=c.kind == "discharge")

    def tag_index(self, name):
        """Index of a tag name."""
        return self.tag_names.index(name)


def _by_conveyance(q_total, h, length, dry_depth, inflow):
    """Unit discharges (m2/s) along edges, proportional to h^(5/3), summing to q_total."""
    k = np.where(h > dry_depth, h, 0.0) ** (5.0 / 3.0)
    if not np.any(k > 0):
        if not inflow:
            return np.zeros_like(h)
        k = np.ones_like(h)  # a dry inflow boundary: spread evenly along it
    return q_total * k / np.sum(k * length)


# plain calls from the flux kernels, not inlined: see solver.riemann
@nb.njit(cache=True)
def _inflow_depth(qn, rplus, g):
    """Depth at an inflow edge with unit discharge qn < 0 and outgoing invariant rplus.

    Solves qn / h + 2 sqrt(g h) = rplus for x = sqrt(h): increasing and concave in x, so Newton
    from a point where the function is negative climbs to the root without overshooting.
    """
    sg = math.sqrt(g)
    x = (-qn / (2.0 * sg)) ** (1.0 / 3.0)
    for _ in range(200):
        if qn / (x * x) + 2.0 * sg * x - rplus < 0.0:
            break
        x *= 0.5
    for _ in range(60):
        f = qn / (x * x) + 2.0 * sg * x - rplus
        dx = -f / (-2.0 * qn / (x * x * x) + 2.0 * sg)
        x += dx
        if abs(dx) <= 1e-14 * x:
            break
    return x * x


@nb.njit(cache=True)
def boundary_flux(kind, value, hL, zL, unL, utL, g, hdry, riemann):
    """Flux (mass, normal, tangential momentum per unit length; max speed) at a boundary edge.

    ``hL, unL, utL`` is the inside state at the edge (reconstructed), ``zL`` its bed.
    """
    if kind == DISCHARGE or kind == RATING or kind == FROUDE:
        cL = math.sqrt(g * hL)
        if kind == FROUDE:
            qn = value * cL * hL if hL > hdry else 0.0
        else:
            qn = value
        if qn < 0.0:  # inflow
            hb = _inflow_depth(qn, unL + 2.0 * cL, g)
            un = qn / hb
            return qn, qn * un + 0.5 * g * hb * hb, 0.0, abs(un) + math.sqrt(g * hb)
        if hL <= hdry:
            return 0.0, 0.5 * g * hL * hL, 0.0, cL
        un = qn / hL
        return qn, qn * un + 0.5 * g * hL * hL, qn * utL, abs(un) + cL
    if kind == LEVEL or kind == DEPTH:
        hR = value - zL if kind == LEVEL else value
        if hR < 0.0:
            hR = 0.0
        unR = unL + 2.0 * (math.sqrt(g * hL) - math.sqrt(g * hR))
        return riemann_flux(riemann, hL, unL, utL, hR, unR, utL, g)
    if kind == FREE:
        if unL < 0.0:  # flowing in: the outside carries nothing, so no water enters
            return riemann_flux(riemann, hL, unL, utL, hL, -unL, utL, g)
        return riemann_flux(riemann, hL, unL, utL, hL, unL, utL, g)
    return riemann_flux(riemann, hL, unL, utL, hL, -unL, utL, g)  # wall: mirror state
