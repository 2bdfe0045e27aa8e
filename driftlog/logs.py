"""Log state as flat arrays (structure of arrays), log properties, and seeding.

A log is a horizontal cylinder (docs/model.md section 5): radius r, length L, density rho_b;
centre (x, y), axis angle theta, velocity (u, v), angular velocity omega.  In plan view, for
contacts, it is a capsule: a segment of length L with radius r.

Seeding (explicit lists, along a line, in a polygon, random in a polygon, a grid in a polygon)
is reproducible bit for bit from the seed.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.columns import NSTATE, OMEGA, THETA, UB, VB, X, Y
from driftlog.errors import ScenarioError
from driftlog.schema import Key, Section

__all__ = ["Logs", "STATUS_MEANINGS", "WAITING", "FLOATING", "RESTING", "STRANDED", "LEFT",
           "seed_logs", "logs_from_groups", "flotation_depth", "flotation_depths",
           "submerged_volume", "spatial_order"]

# status codes, written to trajectory files with flag_meanings
WAITING, FLOATING, RESTING, STRANDED, LEFT = 0, 1, 2, 3, 4
STATUS_MEANINGS = "waiting floating resting stranded left_domain"
# columns of the state array: driftlog.columns X, Y, THETA, UB, VB, OMEGA


@nb.njit(cache=True)
def submerged_volume(h, r, L):
    """V_sub(h) = L r^2 (delta - sin delta cos delta), delta = arccos(1 - h / r).

    docs/model.md eq. (32).
    """
    if h <= 0.0:
        return 0.0
    if h >= 2.0 * r:
        return np.pi * r * r * L
    d = np.arccos(1.0 - h / r)
    return L * r * r * (d - np.sin(d) * np.cos(d))


@nb.njit(cache=True)
def flotation_depth(r, rho_b, rho):
    """Depth h* at which rho V_sub(h*) = rho_b V_b (infinite if rho_b > rho: never floats)."""
    if rho_b > rho:
        return np.inf
    if rho_b == rho:
        return 2.0 * r
    target = rho_b / rho * np.pi  # V_sub / (L r^2) at flotation
    lo, hi = 0.0, np.pi  # delta
    for _ in range(200):  # bisection on delta - sin(delta) cos(delta), increasing in delta
        mid = 0.5 * (lo + hi)
        if mid - np.sin(mid) * np.cos(mid) < target:
            if mid == lo:
                break  # a fixed point: the remaining iterations would change nothing
            lo = mid
        else:
            if mid == hi:
                break
            hi = mid
    return r * (1.0 - np.cos(0.5 * (lo + hi)))


@nb.njit(cache=True)
def flotation_depths(radius, density, rho):
    """``flotation_depth`` of every log (a Python loop over a million logs took seconds).

    A log with the radius and density of the log before it takes that log's depth, the same
    number without the bisection (about 0.5 us a log): a group of logs of one size is solved
    once.
    """
    out = np.empty(radius.shape[0])
    r0 = d0 = np.nan
    h0 = 0.0
    for i in range(radius.shape[0]):
        r, d = radius[i], density[i]
        if not (r == r0 and d == d0):
            h0 = flotation_depth(r, d, rho)
            r0, d0 = r, d
        out[i] = h0
    return out


class Logs:
    """All logs of a run as flat arrays.

    ``state`` is (n, 6): x, y, theta, u, v, omega.  Properties are arrays of length n.
    """

    def __init__(self, x, y, theta=0.0, length=1.0, radius=0.1, density=720.0,
                 release_time=0.0, group=0, u=0.0, v=0.0, omega=0.0, water_density=1000.0):
        x = np.atleast_1d(np.asarray(x, dtype=np.float64))
        n = x.size
        # writable copies (waterlogging changes densities; broadcast_to views are read-only)
        b = lambda a, dt=np.float64: np.array(np.broadcast_to(np.asarray(a, dt), n))  # noqa: E731
        self.id = np.arange(n, dtype=np.int64)
        self.state = np.zeros((n, NSTATE))
        self.state[:, X] = x
        self.state[:, Y] = b(y)
        self.state[:, THETA] = b(theta)
        self.state[:, UB] = b(u)
        self.state[:, VB] = b(v)
        self.state[:, OMEGA] = b(omega)
        self.length = b(length)
        self.radius = b(radius)
        self.density = b(density)
        self.release_time = b(release_time)
        self.group = b(group, np.int32)
        self.status = np.full(n, WAITING, dtype=np.int8)
        self.face = np.full(n, -1, dtype=np.int64)
        self.water_density = float(water_density)
        for name in ("length", "radius", "density"):
            a = getattr(self, name)
            if not np.all((a > 0) & np.isfinite(a)):
                i = int(np.flatnonzero(~((a > 0) & np.isfinite(a)))[0])
                raise ScenarioError(f"logs.{name}", float(a[i]),
                                    f"must be a finite number > 0 (log {i})")
        for k, name in enumerate(("x", "y", "theta", "u", "v", "omega")):
            bad = ~np.isfinite(self.state[:, k])
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ScenarioError(f"logs.{name}", float(self.state[i, k]),
                                    f"must be a finite number (log {i}; {int(bad.sum())} logs)")
        if not np.all(np.isfinite(self.release_time)):
            i = int(np.flatnonzero(~np.isfinite(self.release_time))[0])
            raise ScenarioError("logs.release_time", float(self.release_time[i]),
                                f"must be a finite number (log {i})")
        self.volume = np.pi * self.radius ** 2 * self.length
        self.mass = self.density * self.volume
        self.inertia = self.mass * (self.length ** 2 / 12.0 + self.radius ** 2 / 4.0)
        self.float_depth = flotation_depths(np.ascontiguousarray(self.radius, float),
                                            np.ascontiguousarray(self.density, float),
                                            float(self.water_density))

    def __len__(self):
        return self.id.size

    x = property(lambda s: s.state[:, X])
    y = property(lambda s: s.state[:, Y])
    theta = property(lambda s: s.state[:, THETA])
    u = property(lambda s: s.state[:, UB])
    v = property(lambda s: s.state[:, VB])
    omega = property(lambda s: s.state[:, OMEGA])

    @classmethod
    def concatenate(cls, parts):
        """One Logs from several (their non-empty parts, in order, ids renumbered)."""
        parts = [p for p in parts if len(p)]
        out = cls.__new__(cls)
        for name in ("state", "length", "radius", "density", "release_time", "group", "status",
                     "face", "volume", "mass", "inertia", "float_depth"):
            setattr(out, name, np.concatenate([getattr(p, name) for p in parts]))
        out.id = np.arange(out.length.size, dtype=np.int64)
        out.water_density = parts[0].water_density
        return out

    def take(self, order):
        """The logs ``order`` (an index array) as a new Logs.

        Every per-log array is taken in that order, ids included: log ``k`` of the result is
        log ``order[k]``, its ``id`` and all.
        """
        order = np.asarray(order, dtype=np.int64)
        n = len(self)
        out = type(self).__new__(type(self))
        for name, v in vars(self).items():
            per_log = isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n
            setattr(out, name, np.ascontiguousarray(v[order]) if per_log else v)
        return out

    def __repr__(self):
        counts = np.bincount(self.status, minlength=5)
        names = STATUS_MEANINGS.split()
        parts = ", ".join(f"{c} {n}" for c, n in zip(counts, names, strict=False) if c)
        return f"<Logs {len(self)}: " + parts + ">"


def spatial_order(x, y):
    """An order of the logs along a Hilbert curve through their positions (index array).

    Logs listed in this order sit near their neighbours in memory, so consecutive logs read
    the same mesh rows (node values, faces) from the caches: 1e5 logs seeded at random over
    the Malpasset mesh run 1.56x (tracer) and 1.27x (full physics) faster so listed
    (BENCHMARKS.md, "Logs listed along a space-filling curve").  Ties keep their order.
    """
    from driftlog.solver.layout import hilbert_order

    return hilbert_order(x, y)


# --------------------------------------------------------------------- seeding
def _polygon_area_sampler(poly, n, rng):
    """Draw n points uniformly in a simple polygon (triangulated, area-weighted)."""
    import triangle

    poly = np.asarray(poly, dtype=float)
    m = len(poly)
    segments = np.column_stack([np.arange(m), (np.arange(m) + 1) % m])
    tri = triangle.triangulate({"vertices": poly, "segments": segments}, "p")
    v, t = tri["vertices"], tri["triangles"]
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                        - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))
    k = rng.choice(len(t), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    return (1 - s)[:, None] * a[k] + (s * (1 - r2))[:, None] * b[k] + (s * r2)[:, None] * c[k]


def seed_positions(group: dict, prefix: str = "logs[0]"):
    """(x, y, theta) of the logs of one validated [[logs]] group."""
    rng = np.random.default_rng(group["seed"])
    s = group["seeding"]
    if s == "list":
        x, y = np.array(group["x"], float), np.array(group["y"], float)
    elif s == "line":
        n = group["count"]
        f = (np.arange(n) + 0.5) / n
        a, b = np.array(group["start"]), np.array(group["end"])
        x, y = a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])
    elif s in ("polygon", "random"):
        p = _polygon_area_sampler(group["polygon"], group["count"], rng)
        x, y = p[:, 0], p[:, 1]
    elif s == "grid":
        poly = np.asarray(group["polygon"], float)
        from matplotlib.path import Path as MplPath

        lo, hi = poly.min(axis=0), poly.max(axis=0)
        area = 0.5 * abs(np.dot(poly[:, 0], np.roll(poly[:, 1], -1))
                         - np.dot(poly[:, 1], np.roll(poly[:, 0], -1)))
        n = group["count"]
        d = np.sqrt(area / n)
        inside = MplPath(poly)
        while True:  # spacing sqrt(area / count), made finer until the grid holds count logs
            gx, gy = np.meshgrid(np.arange(lo[0] + d / 2, hi[0], d),
                                 np.arange(lo[1] + d / 2, hi[1], d))
            pts = np.column_stack([gx.ravel(), gy.ravel()])
            pts = pts[inside.contains_points(pts)]
            if len(pts) >= n:
                break
            d *= 0.99
        pts = pts[:n]
        x, y = pts[:, 0], pts[:, 1]
    else:  # validated upstream
        raise ScenarioError(f"{prefix}.seeding", s, "unknown seeding")
    th = group["theta"]
    if isinstance(th, str):
        if th != "random":
            raise ScenarioError(f"{prefix}.theta", th, "must be a number, a list or 'random'")
        theta = rng.uniform(0.0, np.pi, x.size)
    elif isinstance(th, list):
        theta = np.broadcast_to(np.array(th, float), x.size).copy()
    elif isinstance(th, (int, float)) and not isinstance(th, bool):
        theta = np.full(x.size, float(th))
    else:
        raise ScenarioError(f"{prefix}.theta", th, "must be a number, a list or 'random'")
    return x, y, theta


def logs_from_groups(groups: list, water_density: float, start: float) -> Logs:
    """Validated ``[[logs]]`` tables (``LOGS_SECTION``) as one Logs.

    ``water_density`` (kg/m3) sets the logs' flotation; a group without ``release_time``
    enters at ``start`` (s).
    """
    if not groups:
        raise ScenarioError("logs", [], "a scenario needs at least one [[logs]] group")
    rho, t0 = water_density, start
    parts = []
    for i, g in enumerate(groups):
        x, y, theta = seed_positions(g, f"logs[{i}]")
        rt = g["release_time"] if g["release_time"] is not None else t0
        parts.append(Logs(x, y, theta, g["length"], g["radius"], g["density"], rt, i,
                          water_density=rho))
    return Logs.concatenate(parts) if len(parts) > 1 else parts[0]


# aliases used by callers who think in terms of the seeding
seed_logs = seed_positions


# --------------------------------------------------------------------- the scenario section
SEEDINGS = ("list", "line", "polygon", "random", "grid")


def _check_logs(t, prefix, scen):
    s = t["seeding"]
    if s == "list":
        if not t["x"] or not t["y"] or len(t["x"]) != len(t["y"]):
            raise ScenarioError(f"{prefix}.x", t["x"],
                                "seeding = 'list' needs x and y lists of the same length")
        for key in ("theta",):
            if isinstance(t[key], list) and len(t[key]) not in (1, len(t["x"])):
                raise ScenarioError(f"{prefix}.{key}", t[key],
                                    f"must have 1 or {len(t['x'])} values (one per log)")
    elif s == "line":
        for key in ("start", "end"):
            if t[key] is None:
                raise ScenarioError(f"{prefix}.{key}", None, "is required for seeding = 'line'")
    elif s in ("polygon", "random"):
        if t["polygon"] is None:
            raise ScenarioError(f"{prefix}.polygon", None,
                                f"is required for seeding = {s!r} (at least 3 [x, y] points)")
    if s != "list" and t["count"] < 1:
        raise ScenarioError(f"{prefix}.count", t["count"], "must be >= 1")


LOGS_SECTION = Section("logs", [
    Key("name", "str", "", "a label for this group of logs"),
    Key("seeding", "str", "list", "how the logs are placed", choices=SEEDINGS),
    Key("x", "floats", [], "x of each log centre", "m", when="seeding = list"),
    Key("y", "floats", [], "y of each log centre", "m", when="seeding = list"),
    Key("theta", "numbers_or_str", 0.0, "angle of the log axis to the x axis: a number, a "
        "list (one per log), or 'random'", "rad", choices=("random",)),
    Key("count", "int", 1, "number of logs", min=1, when="seeding = line, polygon, random, grid"),
    Key("start", "point", None, "first end of the release line", "m", when="seeding = line"),
    Key("end", "point", None, "second end of the release line", "m", when="seeding = line"),
    Key("polygon", "points", None, "release area", "m", length=3,
        when="seeding = polygon, random, grid"),
    Key("seed", "int", 0, "random seed (the same seed gives the same logs, bit for bit)",
        min=0),
    Key("length", "float", 1.0, "log length L", "m", min=0.0, exclusive_min=True),
    Key("radius", "float", 0.1, "log radius r", "m", min=0.0, exclusive_min=True),
    Key("density", "float", 720.0, "log density rho_b", "kg/m3", min=0.0, exclusive_min=True),
    Key("release_time", "float", None, "when the logs enter (default: time.start), from "
        "time.start to the run's end", "s"),
    Key("velocity", "str", "flow", "initial velocity: the flow's at release, or rest",
        choices=("flow", "rest")),
], doc="logs to release (repeat [[logs]] for several groups)", repeated=True, check=_check_logs)
