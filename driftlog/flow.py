"""Flow fields: a mesh, a bed and snapshots of h, hu, hv, sampled at arrays of points in numba.

Every flow field, on a mesh or analytic, answers ``sample(x, y, t)`` with the same columns
(``FlowSample``): depth, velocity, its local time derivative, the velocity gradient
J_ij = dU_i/dx_j, the free-surface gradient, and a wet / dry / outside flag.

Spatial reconstruction on meshes (``MeshFlowField``): piecewise linear (P1) on the faces, split
into triangles (quadrilaterals fanned from their first node), from node values that are
least-squares linear fits of the surrounding face values (``Mesh.node_operators``).  We chose
it over a per-face least-squares gradient because it is continuous (a log crossing a face edge
sees no jump in velocity, which event-driven contact and the integrators' step control need),
and it reproduces a linear field exactly, as the per-face fit does.

Velocity gradient J and free-surface slope: by default *recovered*: the least-squares slopes of
the same node fits, interpolated P1, so J is continuous too (and exact for linear fields).  The
gradient of the P1 interpolant itself (``gradient = "p1"``) is constant per triangle and jumps
at every edge; the full model's pressure-gradient force uses J, so its acceleration jumps too,
and RK4 then stops converging (measured in benchmarks/integrator_convergence.py).

Node-located data (TELEMAC and other node-based models: a snapshot source whose ``location``
is ``"node"``) are sampled P1 on their own node values, used as they are (no averaging onto
faces and back); their recovered gradients are area-weighted means of the faces' Green-Gauss
gradients (``driftlog.nodal``), and their face values, where a face array is needed (flow file,
plots, solver initial state), are the means of each face's node values.

Time: linear between the two snapshots around t; only those two are held in memory, so a flow
file larger than memory works.  Depth, velocity and free surface are each interpolated on
their own; velocity on a face is hu/h where h > ``dry_depth`` and 0 elsewhere (no division by
zero on dry faces).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import (
    DETADX,
    DETADY,
    DRY,
    DUDT,
    DUDX,
    DUDY,
    DVDT,
    DVDX,
    DVDY,
    ETA,
    NQ,
    NVAR,
    OUTSIDE,
    Q_ETA,
    Q_EX,
    Q_EY,
    Q_H,
    Q_U,
    Q_UX,
    Q_UY,
    Q_V,
    Q_VX,
    Q_VY,
    WET,
    H,
    U,
    V,
)
from driftlog.errors import FlowDomainError, FlowFileError
from driftlog.locate import Locator, locate_one

__all__ = [
    "FlowField", "FlowSample", "MeshFlowField", "MeshKernel", "InMemorySnapshots", "SAMPLE_COLUMNS",
    "sample_point", "sample_point_columns",
    "H", "U", "V", "DUDT", "DVDT", "DUDX", "DUDY", "DVDX", "DVDY", "DETADX", "DETADY", "ETA",
    "NVAR", "OUTSIDE", "DRY", "WET", "time_in_seconds", "DRY_DEPTH_MAX",
]

# names of the columns of a sample (driftlog.columns H ... ETA), as written to files
SAMPLE_COLUMNS = ("water_depth", "velocity_x", "velocity_y", "dudt", "dvdt", "dudx", "dudy",
                  "dvdx", "dvdy", "detadx", "detady", "water_level")
FLAG_MEANINGS = "outside dry wet"

DRY_DEPTH_MAX = 1.0
"""Largest dry depth (m) a scenario may give ([flow] and [solver] dry_depth, ``driftlog import
--dry-depth``).  A dry depth is a thin-film threshold (hydro models use 1e-6 to 0.1 m): at 1 m
most logs already float, and above it every face of a river would count as dry (1e6 m silently
stranded every log)."""


@dataclass
class FlowSample:
    """Flow sampled at n points: ``values`` (n, NVAR) in the column order of SAMPLE_COLUMNS."""

    values: np.ndarray
    flag: np.ndarray
    face: np.ndarray

    @classmethod
    def empty(cls, n):
        """A sample of n points, zeros, flags 0, no face hints (-1)."""
        return cls(np.zeros((n, NVAR)), np.zeros(n, np.int8), np.full(n, -1, np.int64))

    h = property(lambda s: s.values[:, H], doc="water depth (m)")
    u = property(lambda s: s.values[:, U], doc="x velocity (m/s)")
    v = property(lambda s: s.values[:, V], doc="y velocity (m/s)")
    eta = property(lambda s: s.values[:, ETA], doc="water level (m)")
    dudt = property(lambda s: s.values[:, DUDT:DVDT + 1], doc="local dU/dt (n, 2) (m/s2)")
    grad_eta = property(lambda s: s.values[:, DETADX:DETADY + 1], doc="free-surface slope (n, 2)")

    @property
    def jacobian(self):
        """Velocity gradient J_ij = dU_i/dx_j, shape (n, 2, 2) (1/s)."""
        return self.values[:, DUDX:DVDY + 1].reshape(-1, 2, 2)

    @property
    def omega(self):
        """Flow rotation rate omega_w = (dv/dx - du/dy) / 2 (rad/s)."""
        return 0.5 * (self.values[:, DVDX] - self.values[:, DUDY])

    @property
    def wet(self):
        """True where the point is wet."""
        return self.flag == WET


class MeshKernel(NamedTuple):
    """What the fused tracking kernels (``driftlog.fused``) need of a mesh flow.

    ``node_values(t) -> (values (n_nodes, 2 NQ), time weight a, 1 / snapshot gap)``: the
    snapshot pair around t at the nodes; ``dry_depth``; ``recovered``: gradients are the P1
    interpolation of recovered node gradients (else the P1 interpolant's own); ``locator``:
    the mesh's ``Locator``; ``node_pair(t) -> (values, t_i, gap, t_next)``: the same pair with
    its start time, length (0 for a steady flow) and the time from which the next pair applies
    (the per-log clocks, ``driftlog.clocks``, weight each stage time themselves).  A flow whose
    ``sample_into`` is exactly ``sample_mesh_kernel``
    over these gives it (the fused step then reproduces the general path bit for bit).
    """

    node_values: Callable[[float], tuple]
    dry_depth: float
    recovered: bool
    locator: Locator
    node_pair: Callable[[float], tuple] | None = None


class FlowField:
    """Base of the flow fields: sampling at points and the time span.

    Implements the ``driftlog.protocols.FlowFieldLike`` contract: a subclass provides
    ``sample_into`` (and ``times``/``time_span`` when it has snapshots); ``sample`` is built on
    it; ``mesh_kernel`` is None (no fused mesh kernel) unless the subclass says otherwise.
    """

    mesh = None
    dry_depth = 1e-3
    name = "flow"

    @property
    def time_span(self) -> tuple[float, float]:
        """(first, last) time the field covers (s); infinite for steady analytic fields."""
        return (-np.inf, np.inf)

    @property
    def times(self) -> np.ndarray:
        """Snapshot times (s); the hydrodynamic steps that sub-steps must land on."""
        return np.empty(0)

    def sample(self, x, y, t, face=None) -> FlowSample:
        """Sample the flow at points (x, y) and time(s) t; ``face`` are location hints."""
        x = np.ascontiguousarray(x, dtype=np.float64).ravel()
        y = np.ascontiguousarray(y, dtype=np.float64).ravel()
        s = FlowSample.empty(x.size)
        if face is not None:
            s.face[:] = face
        t = np.asarray(t, dtype=np.float64)
        if t.ndim == 0:
            self.sample_into(x, y, float(t), s.face, s.values, s.flag)
            return s
        t = np.broadcast_to(t.ravel(), x.shape)
        for tk in np.unique(t):  # one call per distinct time, not per point
            idx = np.flatnonzero(t == tk)
            sub = FlowSample(np.empty((idx.size, NVAR)), np.empty(idx.size, np.int8),
                             s.face[idx].copy())
            self.sample_into(x[idx], y[idx], float(tk), sub.face, sub.values, sub.flag)
            s.values[idx], s.flag[idx], s.face[idx] = sub.values, sub.flag, sub.face
        return s

    def shifted(self, origin) -> FlowField:
        """The same flow on a clock starting at ``origin``: ``t_new = t - origin`` (s).

        The tracker runs on such a clock when the run is far from the flow's time zero
        (absolute epochs, ``time.start = 1e17``), so that its times keep full precision.
        """
        return TimeShiftedField(self, origin) if origin else self

    def sample_into(self, x, y, t, face, out, flag) -> None:
        """Kernel entry: fill ``out`` (n, NVAR) and ``flag`` (n,), update hints ``face``."""
        raise NotImplementedError

    def mesh_kernel(self) -> MeshKernel | None:
        """The arrays of the fused mesh kernels (``driftlog.fused``) if they apply, else None.

        Only a field whose ``sample_into`` is ``sample_mesh_kernel`` over a mesh's P1 node
        values answers with a ``MeshKernel``: the tracker then advances each log through a
        whole step in one kernel, with the same numbers as sampling stage by stage.
        """
        return None

    def step_interval(self, t_mid):
        """Stages of the sub-step around ``t_mid`` read the snapshot pair around ``t_mid``.

        Sub-steps land on every snapshot (``integrator.land_on_snapshots``), so a step lies in
        one pair of snapshots; its last stage, at the pair's end, takes the pair's value there
        (its left limit: the flow's time derivative jumps at each snapshot), where a time
        alone would give the next pair's.  ``None`` ends it.  A field without snapshot pairs
        ignores it.
        """

    def check_time(self, t):
        """FlowDomainError if t is outside the field's time span (to 1e-9 of the span)."""
        t0, t1 = self.time_span
        span = max(t1 - t0, 1.0) if np.isfinite(t1 - t0) else 1.0
        if not (t0 - 1e-9 * span <= t <= t1 + 1e-9 * span):
            raise FlowDomainError(f"{self.name}: time {t} s is outside the flow's span "
                                  f"[{t0}, {t1}] s")


class TimeShiftedField(FlowField):
    """A flow field seen on a shifted clock.

    Sampled at t, it answers the base field at ``t + origin``; its times and span are the
    base's minus ``origin``.
    """

    def __init__(self, base, origin):
        self.base, self.origin = base, float(origin)
        self.mesh, self.dry_depth = base.mesh, base.dry_depth
        self.name = getattr(base, "name", "flow")
        self.attrs = dict(getattr(base, "attrs", {}) or {})

    def __getattr__(self, name):
        return getattr(self.base, name)

    @property
    def time_span(self):
        t0, t1 = self.base.time_span
        return (t0 - self.origin, t1 - self.origin)

    @property
    def times(self):
        return np.asarray(self.base.times, np.float64) - self.origin

    def sample_into(self, x, y, t, face, out, flag):
        self.base.sample_into(x, y, t + self.origin, face, out, flag)

    def step_interval(self, t_mid):
        self.base.step_interval(None if t_mid is None else t_mid + self.origin)

    def shifted(self, origin):
        return self.base.shifted(self.origin + float(origin))


# --------------------------------------------------------------------- mesh sampling kernel
@nb.njit(cache=True, inline="always")
def _triangle_weights(px, py, xa, ya, xb, yb, xc, yc):
    d = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
    inv = 1.0 / d
    la = ((xb - px) * (yc - py) - (xc - px) * (yb - py)) * inv
    lb = ((xc - px) * (ya - py) - (xa - px) * (yc - py)) * inv
    lc = 1.0 - la - lb
    # gradients of the barycentric coordinates
    gax, gay = (yb - yc) * inv, (xc - xb) * inv
    gbx, gby = (yc - ya) * inv, (xa - xc) * inv
    gcx, gcy = -gax - gbx, -gay - gby
    return la, lb, lc, gax, gay, gbx, gby, gcx, gcy


@nb.njit(cache=True, inline="always")
def _p1(nodevals, q, n0, n1, n2, a, b, inv_dt, w):
    """Value, gradient and time derivative of column q on the triangle (n0, n1, n2)."""
    la, lb, lc, gax, gay, gbx, gby, gcx, gcy = w
    va = b * nodevals[n0, q] + a * nodevals[n0, q + NQ]
    vb = b * nodevals[n1, q] + a * nodevals[n1, q + NQ]
    vc = b * nodevals[n2, q] + a * nodevals[n2, q + NQ]
    td = inv_dt * (la * (nodevals[n0, q + NQ] - nodevals[n0, q])
                   + lb * (nodevals[n1, q + NQ] - nodevals[n1, q])
                   + lc * (nodevals[n2, q + NQ] - nodevals[n2, q]))
    return (la * va + lb * vb + lc * vc, gax * va + gbx * vb + gcx * vc,
            gay * va + gby * vb + gcy * vc, td)


@nb.njit(cache=True, inline="always")
def sample_point(x, y, hint, a, inv_dt, nodevals, dry_depth, recovered, loc):
    """Locate and sample one point: (face, flag, values) with values the NVAR columns as a tuple.

    The per-point body of ``sample_mesh_kernel``, shared with the fused tracking kernels
    (``driftlog.fused``) so that both compute the same numbers.  ``loc``: the mesh's
    ``Locator``.
    """
    return sample_point_columns(x, y, hint, a, inv_dt, nodevals, dry_depth, recovered, loc,
                                True, True, True, True, True)


@nb.njit(cache=True, inline="always")
def sample_point_columns(x, y, hint, a, inv_dt, nodevals, dry_depth, recovered, loc, depth,
                         rotation, full, slope, level):
    """``sample_point`` computing only the columns asked for; the others are 0.

    U and V always; H (and the wet/dry flag: without ``depth`` a located point is flagged
    wet) with ``depth``; DUDY and DVDX with ``rotation``; DUDT, DVDT, DUDX and DVDY with
    ``full``; DETADX and DETADY with ``slope``; ETA with ``level``.  The columns computed are
    the same numbers as ``sample_point``'s (the fused stages sample only what the forces read:
    ``physics.stage_columns``).
    """
    f = locate_one(x, y, hint, loc)
    if f < 0:
        return f, OUTSIDE, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    b = 1.0 - a
    face_nodes, face_n, node_x, node_y = loc.face_nodes, loc.face_n, loc.node_x, loc.node_y
    # fan triangle (n0, nk, nk+1) that holds the point
    n0 = face_nodes[f, 0]
    k = 1
    while k < face_n[f] - 2:
        nk1 = face_nodes[f, k + 1]
        c = ((node_x[nk1] - node_x[n0]) * (y - node_y[n0])
             - (node_y[nk1] - node_y[n0]) * (x - node_x[n0]))
        if c <= 0.0:
            break
        k += 1
    n1 = face_nodes[f, k]
    n2 = face_nodes[f, k + 1]
    la, lb, lc, gax, gay, gbx, gby, gcx, gcy = _triangle_weights(
        x, y, node_x[n0], node_y[n0], node_x[n1], node_y[n1], node_x[n2], node_y[n2])
    w = (la, lb, lc, gax, gay, gbx, gby, gcx, gcy)
    h = eval_ = ut = vt = ux = uy = vx = vy = ex = ey = ex_ = ey_ = 0.0
    if depth:
        hval = _p1(nodevals, Q_H, n0, n1, n2, a, b, inv_dt, w)[0]
        h = max(hval, 0.0)
    uval, ux_, uy_, ut_ = _p1(nodevals, Q_U, n0, n1, n2, a, b, inv_dt, w)
    vval, vx_, vy_, vt_ = _p1(nodevals, Q_V, n0, n1, n2, a, b, inv_dt, w)
    if full:
        ut, vt = ut_, vt_
    if level or (slope and not recovered):
        eval_, ex_, ey_, _ = _p1(nodevals, Q_ETA, n0, n1, n2, a, b, inv_dt, w)
        if not level:
            eval_ = 0.0
    if recovered:
        if full:
            ux = _p1(nodevals, Q_UX, n0, n1, n2, a, b, inv_dt, w)[0]
            vy = _p1(nodevals, Q_VY, n0, n1, n2, a, b, inv_dt, w)[0]
        if rotation:
            uy = _p1(nodevals, Q_UY, n0, n1, n2, a, b, inv_dt, w)[0]
            vx = _p1(nodevals, Q_VX, n0, n1, n2, a, b, inv_dt, w)[0]
        if slope:
            ex = _p1(nodevals, Q_EX, n0, n1, n2, a, b, inv_dt, w)[0]
            ey = _p1(nodevals, Q_EY, n0, n1, n2, a, b, inv_dt, w)[0]
    else:
        if full:
            ux, vy = ux_, vy_
        if rotation:
            uy, vx = uy_, vx_
        if slope:
            ex, ey = ex_, ey_
    flag = (WET if h > dry_depth else DRY) if depth else WET
    # in the column order H, U, V, DUDT, DVDT, DUDX, DUDY, DVDX, DVDY, DETADX, DETADY, ETA
    return f, flag, (h, uval, vval, ut, vt, ux, uy, vx, vy, ex, ey, eval_)


@kernel(nrt=False)
def sample_mesh_kernel(px, py, face, out, flag, a, inv_dt, nodevals, dry_depth, recovered, loc):
    """Locate and sample n points; nodevals (n_nodes, 2 NQ): the NQ node columns at t0 then t1.

    ``recovered``: gradients are the P1 interpolation of the nodes' least-squares gradients
    (continuous); otherwise the gradient of the P1 interpolant (constant per triangle).
    """
    for i in nb.prange(px.shape[0]):
        f, fl, vals = sample_point(px[i], py[i], face[i], a, inv_dt, nodevals, dry_depth,
                                   recovered, loc)
        face[i] = f
        flag[i] = fl
        for k in range(NVAR):
            out[i, k] = vals[k]


@nb.njit(cache=True)
def node_columns(h, hu, hv, bed, dry_depth, nodes):
    """A node-located snapshot's node columns: h, u, v (0 where h <= dry_depth), eta = h + bed.

    The gradient columns (Q_UX ...) are set to NaN (filled when asked for).
    """
    for j in range(h.shape[0]):
        hj = h[j]
        wet = hj > dry_depth
        nodes[j, Q_H] = hj
        nodes[j, Q_U] = hu[j] / hj if wet else 0.0
        nodes[j, Q_V] = hv[j] / hj if wet else 0.0
        nodes[j, Q_ETA] = hj + bed[j]
        for q in range(Q_UX, NQ):
            nodes[j, q] = np.nan


class _NodeEntry:
    """A node-located snapshot in ``MeshFlowField``'s cache: ``(h, hu, hv, nodes)``.

    As a face-located snapshot's tuple (face arrays, node columns), but the face means of the
    node data are computed when first read: the fused kernels read the node columns only.
    """

    __slots__ = ("_mean", "_data", "_faces", "nodes")

    def __init__(self, mean, data, nodes):
        self._mean, self._data, self._faces, self.nodes = mean, data, None, nodes

    def faces(self):
        """The face means (h, hu, hv) of the node data."""
        if self._faces is None:
            A = self._mean
            self._faces = tuple(A @ a for a in self._data)
            self._data = None
        return self._faces

    def __getitem__(self, k):
        return self.nodes if k == 3 else self.faces()[k]

    def __iter__(self):
        return iter((*self.faces(), self.nodes))

    def __len__(self):
        return 4


# --------------------------------------------------------------------- snapshot sources
class InMemorySnapshots:
    """Snapshots held as arrays (n_times, n_faces) of h, hu, hv (n_nodes with location='node')."""

    def __init__(self, times, h, hu, hv, name="in-memory flow", location="face"):
        self.location = location
        self.times = np.asarray(times, dtype=np.float64).ravel()
        self.h = np.atleast_2d(np.asarray(h, dtype=np.float64))
        self.hu = np.atleast_2d(np.asarray(hu, dtype=np.float64))
        self.hv = np.atleast_2d(np.asarray(hv, dtype=np.float64))
        self.name = name
        nt = self.times.size
        for arr, nm in ((self.h, "h"), (self.hu, "hu"), (self.hv, "hv")):
            if arr.shape[0] != nt:
                raise FlowFileError(f"{name}: {nm} has {arr.shape[0]} snapshots for {nt} times")

    def read(self, i):
        """Snapshot i: (h, hu, hv)."""
        return self.h[i], self.hu[i], self.hv[i]


_TIME_UNITS = {"s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
               "min": 60.0, "mins": 60.0, "minute": 60.0, "minutes": 60.0,
               "h": 3600.0, "hr": 3600.0, "hrs": 3600.0, "hour": 3600.0, "hours": 3600.0,
               "d": 86400.0, "day": 86400.0, "days": 86400.0}


_CALENDARS = ("standard", "gregorian", "proleptic_gregorian", "julian", "noleap", "365_day",
              "all_leap", "366_day", "360_day", "none")


def time_in_seconds(values, units, where, calendar=None):
    """Times in seconds on the axis' own reference, and that reference (the date after 'since').

    ``values`` are numbers with CF ``units`` ('seconds since 1970-01-01', 'days since
    2001-02-30 00:00' with ``calendar = '360_day'``, 'hours', 's'), or date stamps (ISO
    strings or numpy datetime64), taken as seconds since the first stamp.  Any CF calendar:
    a CF time unit is a fixed number of seconds in every calendar, so the seconds need no
    calendar; the reference date is checked against it (cftime).  Float64 seconds since the
    reference keep the file's own precision (the reference is not added in).
    """
    raw = np.asarray(values)
    if raw.dtype.kind in "SUOM":  # date stamps: seconds since the first one
        try:
            stamps = raw.astype("datetime64[ms]") if raw.dtype.kind != "M" else raw
        except ValueError as exc:
            raise FlowFileError(f"{where}: time stamps not understood ({exc}); expected ISO "
                                "dates such as '2024-01-01T00:00:00'") from None
        if stamps.size == 0 or np.any(np.isnat(stamps)):
            raise FlowFileError(f"{where}: empty or missing (NaT) time stamps")
        sec = (stamps - stamps.flat[0]).astype("timedelta64[ms]").astype(np.int64) / 1000.0
        return sec, str(stamps.flat[0].astype("datetime64[ms]")).replace(".000", "")
    values = np.asarray(raw, dtype=np.float64)
    if units is None:
        return values, None
    u = str(units).strip()
    unit, _, origin = u.partition(" since ")
    f = _TIME_UNITS.get(unit.strip().lower())
    if f is None:
        hint = (" (months and years are not fixed durations in CF: not accepted)"
                if unit.strip().lower() in ("month", "months", "year", "years") else "")
        raise FlowFileError(f"{where}: time units {units!r} not understood (expected "
                            f"'seconds since ...', 'hours since ...' or 'days since ...'){hint}")
    origin = origin.strip() or None
    if calendar is not None and origin is not None:
        cal = str(calendar).strip().lower()
        if cal not in _CALENDARS:
            raise FlowFileError(f"{where}: calendar {calendar!r} unknown (CF calendars: "
                                f"{', '.join(_CALENDARS)})")
        if cal != "none":
            import cftime

            try:
                cftime.num2date(0.0, f"seconds since {origin}", calendar=cal)
            except (ValueError, TypeError) as exc:
                raise FlowFileError(f"{where}: reference date {origin!r} is not a date of the "
                                    f"{cal!r} calendar ({exc})") from None
    return values * f, origin


def check_times(times, name):
    """Snapshot times must be finite and strictly increasing."""
    times = np.asarray(times, dtype=np.float64)
    if times.size == 0:
        raise FlowFileError(f"{name}: no snapshots (empty time axis)")
    if not np.all(np.isfinite(times)):
        bad = np.flatnonzero(~np.isfinite(times))
        raise FlowFileError(f"{name}: non-finite snapshot times at {bad[:5].tolist()}")
    bad = np.flatnonzero(np.diff(times) <= 0)
    if bad.size:
        i = int(bad[0])
        raise FlowFileError(f"{name}: times not increasing: t[{i}] = {times[i]} then "
                            f"t[{i + 1}] = {times[i + 1]}")
    return times


def _set_gradients(nodes, Gx, Gy, uve):
    """Node gradient columns Q_UX ... Q_EY from operators Gx, Gy applied to (u, v, eta)."""
    gx, gy = Gx @ uve, Gy @ uve
    nodes[:, Q_UX], nodes[:, Q_UY] = gx[:, 0], gy[:, 0]
    nodes[:, Q_VX], nodes[:, Q_VY] = gx[:, 1], gy[:, 1]
    nodes[:, Q_EX], nodes[:, Q_EY] = gx[:, 2], gy[:, 2]


class MeshFlowField(FlowField):
    """Flow on a mesh: bed on faces and a time series of (h, hu, hv) snapshots on faces.

    Parameters
    ----------
    mesh : Mesh
    bed : array (n_faces,), or (n_nodes,) for a node-located source
        Bed elevation where the source's data are (m).
    source : object with ``times`` and ``read(i) -> (h, hu, hv)``
        Where snapshots come from (``InMemorySnapshots``, a flow file, another model's output).
        Its optional ``location`` attribute says where its arrays are: ``"face"`` (default) or
        ``"node"`` (sampled P1 on those node values as they are; ``bed`` then on nodes too,
        ``self.bed`` the faces' mean and ``self.node_bed`` the given one).
    dry_depth : float
        Depth (m) below which a face is dry: velocity 0 there, and samples flagged dry.
    attrs : dict
        Provenance (source model, scenario), written to flow files.
    """

    def __init__(self, mesh, bed, source, dry_depth=1e-3, name=None, attrs=None,
                 gradient="recovered"):
        self.mesh = mesh
        self.location = getattr(source, "location", "face")
        if self.location not in ("face", "node"):
            raise FlowFileError(f"{name or 'flow'}: snapshot location {self.location!r}: must "
                                "be 'face' or 'node'")
        self.bed = np.ascontiguousarray(bed, dtype=np.float64)
        self.node_bed = None
        n_loc = mesh.n_faces if self.location == "face" else mesh.n_nodes
        if self.bed.shape != (n_loc,):
            raise FlowFileError(f"{name or 'flow'}: bed has shape {self.bed.shape}, the mesh "
                                f"has {n_loc} {self.location}s")
        if self.location == "node":
            from driftlog.nodal import face_mean_operator

            self._face_mean = face_mean_operator(mesh)
            self.node_bed = self.bed
            self.bed = self._face_mean @ self.node_bed
        self.source = source
        self.name = name or getattr(source, "name", "flow")
        self._times = check_times(source.times, self.name)
        self.dry_depth = float(dry_depth)
        if gradient not in ("recovered", "p1"):
            raise FlowFileError(f"{self.name}: gradient = {gradient!r}: must be 'recovered' or "
                                "'p1'")
        self.gradient = gradient
        self.attrs = dict(attrs or {})
        self._snap = OrderedDict()  # i -> (h, hu, hv, nodevals(n_nodes, 4)); two at most
        self._nograd = set()  # cached snapshots whose recovered gradients are not computed
        self._pair = None
        self._pair_vals = None
        self._pair_grad = True

    @classmethod
    def from_arrays(cls, mesh, bed, times, h, hu, hv, location="face", **kwargs):
        """A field from arrays (n_times, n_faces) held in memory.

        With ``location="node"``: arrays (n_times, n_nodes) and a node bed.
        """
        return cls(mesh, bed, InMemorySnapshots(times, h, hu, hv, kwargs.get("name", "flow"),
                                                location=location), **kwargs)

    @property
    def times(self):
        """Snapshot times (s)."""
        return self._times

    @property
    def time_span(self):
        """(first, last) snapshot time (s); infinite for one snapshot (steady)."""
        return (float(self._times[0]), float(self._times[-1])) if self._times.size > 1 else \
            (-np.inf, np.inf)

    @property
    def steady(self) -> bool:
        """One snapshot: the flow is the same at all times."""
        return self._times.size == 1

    # ----------------------------------------------------------------- snapshots
    def snapshot(self, i):
        """Face arrays of snapshot i: dict of h, hu, hv, u, v, eta (read and checked once)."""
        h, hu, hv, _ = self._load(i)
        u, v = self._velocity(h, hu, hv)
        return {"h": h, "hu": hu, "hv": hv, "u": u, "v": v, "eta": h + self.bed}

    def node_snapshot(self, i):
        """Node arrays of snapshot i as the sampler interpolates them: dict of h, u, v, eta.

        For node-located data, the data themselves; for face-located data, the nodes'
        least-squares fits of the face values.
        """
        nodes = self._load(i)[3]
        return {"h": nodes[:, Q_H].copy(), "u": nodes[:, Q_U].copy(),
                "v": nodes[:, Q_V].copy(), "eta": nodes[:, Q_ETA].copy()}

    def _velocity(self, h, hu, hv):
        wet = h > self.dry_depth
        safe = np.where(wet, h, 1.0)
        return np.where(wet, hu / safe, 0.0), np.where(wet, hv / safe, 0.0)

    def read_snapshot(self, i):
        """Snapshot i from the source as face arrays (h, hu, hv), checked.

        Checked: sizes, finite values, no negative depth (no node interpolation, no caching).
        A node-located source's arrays are averaged on each face (``read_source`` gives them
        as they are).
        """
        h, hu, hv = self.read_source(i)
        if self.location == "node":
            return self._face_mean @ h, self._face_mean @ hu, self._face_mean @ hv
        return h, hu, hv

    def read_source(self, i):
        """Snapshot i as the source holds it (on faces, or on nodes), checked (sizes, values)."""
        h, hu, hv = (np.ascontiguousarray(a, dtype=np.float64) for a in self.source.read(i))
        where = self.location
        nf = self.mesh.n_faces if where == "face" else self.mesh.n_nodes
        for arr, nm in ((h, "h"), (hu, "hu"), (hv, "hv")):
            if arr.shape != (nf,):
                raise FlowFileError(f"{self.name}: snapshot {i} {nm} has shape {arr.shape}, "
                                    f"the mesh has {nf} {where}s")
            if not np.all(np.isfinite(arr)):
                bad = np.flatnonzero(~np.isfinite(arr))
                raise FlowFileError(f"{self.name}: snapshot {i} (t = {self._times[i]} s): "
                                    f"{bad.size} non-finite {nm} values, first at {where}s "
                                    f"{bad[:5].tolist()}")
        if np.any(h < 0):
            bad = np.flatnonzero(h < 0)
            raise FlowFileError(f"{self.name}: snapshot {i}: negative depth at {where}s "
                                f"{bad[:5].tolist()} (min {h.min()})")
        return h, hu, hv

    def _load(self, i, gradients=True):
        """Snapshot i's (h, hu, hv on faces, node columns), read once and cached.

        ``gradients=False``: the recovered gradient columns (Q_UX ...) may be left unset (NaN)
        for a reader that does not use them (tracer mode without rotation); they are
        computed when a later call asks for them, the same numbers.
        """
        if i in self._snap:
            self._snap.move_to_end(i)
            if gradients and i in self._nograd:
                self._fill_gradients(i)
            return self._snap[i]
        if self.location == "node":
            return self._load_nodes(i, gradients)
        h, hu, hv = self.read_snapshot(i)
        P = self.mesh.node_operators()[0]
        u, v = self._velocity(h, hu, hv)
        nodes = np.empty((self.mesh.n_nodes, NQ))
        # Q_H, Q_U, Q_V, Q_ETA: the first four columns
        nodes[:, Q_H:Q_ETA + 1] = P @ np.column_stack([h, u, v, h + self.bed])
        np.maximum(nodes[:, Q_H], 0.0, out=nodes[:, Q_H])
        return self._keep(i, (h, hu, hv, nodes), gradients)

    def _fill_gradients(self, i):
        """The gradient columns of cached snapshot i.

        Recovered (left out until asked for when ``_keep`` had ``gradients=False``), or
        zeros for ``gradient = "p1"``.
        """
        entry = self._snap[i]
        nodes = entry[3]
        self._nograd.discard(i)
        if self.gradient != "recovered":
            nodes[:, Q_UX:] = 0.0
        elif self.location == "node":
            if getattr(self, "_node_grad", None) is None:
                from driftlog.nodal import node_gradient_operators

                self._node_grad = node_gradient_operators(self.mesh)
            _set_gradients(nodes, *self._node_grad, nodes[:, Q_U:Q_ETA + 1])
        else:
            _, Px, Py = self.mesh.node_operators()
            h, hu, hv = entry[0], entry[1], entry[2]
            u, v = self._velocity(h, hu, hv)
            _set_gradients(nodes, Px, Py, np.column_stack([u, v, h + self.bed]))

    def _keep(self, i, entry, gradients=True, unset=False):
        """Cache snapshot i's (h, hu, hv, node columns): the two latest are kept.

        Its gradient columns are filled now, or NaN until asked for (``gradients=False``;
        ``unset``: they are NaN already).
        """
        self._snap[i] = entry
        while len(self._snap) > 2:
            self._nograd.discard(self._snap.popitem(last=False)[0])
        if gradients or self.gradient != "recovered":
            self._fill_gradients(i)
        else:
            if not unset:
                entry[3][:, Q_UX:] = np.nan
            self._nograd.add(i)
        return entry

    def _load_nodes(self, i, gradients=True):
        """``_load`` for node-located data: the node columns are the data themselves."""
        h, hu, hv = self.read_source(i)
        nodes = np.empty((self.mesh.n_nodes, NQ))
        # the numbers of _velocity and h + node_bed, in one pass (one snapshot per tracer
        # step is common: several numpy passes over the node rows cost a fifth of a 1e4-tracer
        # run); the gradient columns NaN until _keep fills them
        node_columns(h, hu, hv, self.node_bed, self.dry_depth, nodes)
        return self._keep(i, _NodeEntry(self._face_mean, (h, hu, hv), nodes), gradients,
                          unset=True)

    def _interval(self, t):
        """Snapshot pair (i, i+1) around t, and the weight of i+1."""
        nt = self._times.size
        if nt == 1:
            return 0, 0, 0.0, 0.0
        self.check_time(t)
        m = self._step_middle  # the pair of the current sub-step (step_interval)
        i = int(np.searchsorted(self._times, t if m is None else m, side="right")) - 1
        i = min(max(i, 0), nt - 2)
        dt = self._times[i + 1] - self._times[i]
        a = min(max((t - self._times[i]) / dt, 0.0), 1.0)
        return i, i + 1, a, 1.0 / dt

    _step_middle = None

    def step_interval(self, t_mid):
        """The pair of snapshots of the sub-step around ``t_mid`` (``FlowField``'s)."""
        self._step_middle = t_mid

    def node_snapshot_pair(self, t, gradients=True):
        """The node columns (n_nodes, NQ) of the snapshots around t, the time weight, 1 / dt.

        ``node_values(t)`` is the two side by side; a reader that takes them apart (tracer
        mode's packed rows) is spared building that copy at every new pair.  ``gradients``
        as for ``node_values``.
        """
        i, j, a, inv_dt = self._interval(t)
        ni = self._load(i, gradients)[3]
        return ni, self._load(j, gradients)[3], a, inv_dt

    def node_values(self, t, gradients=True):
        """(n_nodes, 2 NQ) node columns at the snapshots around t; the time weight, 1 / dt.

        ``gradients=False``: the recovered gradient columns may be NaN (``_load``).
        """
        i, j, a, inv_dt = self._interval(t)
        if self._pair != (i, j) or (gradients and not self._pair_grad):
            ni = self._load(i, gradients)[3]
            nj = self._load(j, gradients)[3]
            self._pair_vals = np.ascontiguousarray(np.hstack([ni, nj]))
            self._pair = (i, j)
            self._pair_grad = gradients
        return self._pair_vals, a, inv_dt

    def node_pair(self, t):
        """The node values of ``node_values(t)`` with the pair's start, length and end (s).

        ``node_values(t')`` is this pair's values with weight ``(t' - start) / length`` for
        ``start <= t' < end``; length 0 and end inf for a steady flow (one snapshot).
        """
        i, j, _, _ = self._interval(t)
        vals, _, _ = self.node_values(t)
        if i == j:
            return vals, 0.0, 0.0, np.inf
        return vals, float(self._times[i]), float(self._times[j] - self._times[i]), float(
            self._times[j])

    def mesh_kernel(self) -> MeshKernel | None:
        """Node values, dry depth, gradient choice and locator for the fused kernels.

        A subclass that samples otherwise (its own ``sample_into``) must return None.
        """
        return MeshKernel(self.node_values, self.dry_depth, self.gradient == "recovered",
                          self.mesh.locator(), self.node_pair)

    def sample_into(self, x, y, t, face, out, flag):
        """Locate and sample P1 on the node values of the snapshots around t (in numba)."""
        vals, a, inv_dt = self.node_values(t)
        sample_mesh_kernel(x, y, face, out, flag, a, inv_dt, vals, self.dry_depth,
                           self.gradient == "recovered", self.mesh.locator())

    # ----------------------------------------------------------------- derived fields
    def face_values(self, t):
        """Face arrays (h, u, v) linearly interpolated in time at t."""
        i, j, a, _ = self._interval(t)
        si, sj = self.snapshot(i), self.snapshot(j)
        return {k: (1 - a) * si[k] + a * sj[k] for k in ("h", "u", "v", "hu", "hv", "eta")}

    def shifted(self, origin) -> MeshFlowField:
        """The same field on a clock starting at ``origin`` (``t_new = t - origin``).

        A shallow copy whose snapshot times are shifted (same source, same snapshots, its own
        cache), so it stays a ``MeshFlowField`` (fused tracking kernels included).
        """
        if not origin:
            return self
        import copy

        new = copy.copy(self)
        new._times = self._times - float(origin)
        new._snap = OrderedDict()
        new._nograd = set()
        new._pair = new._pair_vals = None
        new.attrs = dict(self.attrs)
        return new

    def freeze(self, t) -> MeshFlowField:
        """The flow at time t as a steady field (one snapshot; on nodes for node data)."""
        if self.location == "node":
            i, j, a, _ = self._interval(t)
            si, sj = self.read_source(i), self.read_source(j)
            h, hu, hv = ((1 - a) * p + a * q for p, q in zip(si, sj, strict=True))
            src = InMemorySnapshots([t], h, hu, hv, name=f"{self.name} at t={t}",
                                    location="node")
            return MeshFlowField(self.mesh, self.node_bed, src, self.dry_depth, attrs=self.attrs,
                                 gradient=self.gradient)
        fv = self.face_values(t)
        src = InMemorySnapshots([t], fv["h"], fv["hu"], fv["hv"], name=f"{self.name} at t={t}")
        return MeshFlowField(self.mesh, self.bed, src, self.dry_depth, attrs=self.attrs,
                             gradient=self.gradient)

    def __repr__(self):
        t0, t1 = self._times[0], self._times[-1]
        return (f"<MeshFlowField {self.name!r}: {self.mesh.n_faces} faces, "
                f"{self._times.size} snapshots from {t0} to {t1} s>")
