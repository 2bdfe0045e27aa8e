"""Analytic flow fields with exact gradients and time derivatives, for tests and cases.

Each has the sampling interface of every flow field (``FlowField.sample``).  Depth is constant;
the free-surface slope is the one that balances the flow's steady (advective) acceleration,
g grad(eta) = -(U . grad) U, as in frictionless steady flow, so that the ``surface_slope``
physics option (docs/model.md eq. (34'): -g grad(eta) in place of the steady part of DU_w/Dt) and
the pressure-gradient term agree on these fields.  A uniform flow may be given a surface slope
of its own (a sloping uniform flow held by bed friction, where DU_w/Dt = 0 but g S is not).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import (
    DETADX,
    DETADY,
    DUDT,
    DUDX,
    DUDY,
    DVDT,
    DVDX,
    DVDY,
    ETA,
    NVAR,
    WET,
    H,
    U,
    V,
)
from driftlog.errors import ScenarioError
from driftlog.flow import FlowField, InMemorySnapshots, MeshFlowField

__all__ = ["UniformFlow", "SolidBodyRotation", "FreeVortex", "DriftingEddy", "AnalyticField",
           "on_mesh"]

G = 9.81
UNIFORM, SOLID_BODY, FREE_VORTEX, DRIFTING_EDDY = 0, 1, 2, 3
# slots of each kind's parameter vector
UNI_U, UNI_V, UNI_AX, UNI_AY, UNI_DEPTH, UNI_G, UNI_SX, UNI_SY = range(8)
SB_OMEGA, SB_XC, SB_YC, SB_DEPTH, SB_G = range(5)
FV_GAMMA, FV_XC, FV_YC, FV_DEPTH, FV_CORE, FV_G = range(6)
DE_XC, DE_YC, DE_DRIFT, DE_SIGMA, DE_OMEGA0, DE_DEPTH, DE_SNAPSHOT = range(7)


@nb.njit(cache=True, inline="always")
def _eddy(p, x, y, t):
    """The drifting eddy's velocity and its gradient J at (x, y, t) (``DriftingEddy``)."""
    dx, dy = x - (p[DE_XC] + p[DE_DRIFT] * t), y - p[DE_YC]
    s2 = p[DE_SIGMA] * p[DE_SIGMA]
    om = p[DE_OMEGA0] * np.exp(-(dx * dx + dy * dy) / (2.0 * s2))
    # d om / dx = -om dx / sigma^2, d om / dy = -om dy / sigma^2
    return (p[DE_DRIFT] - om * dy, om * dx, om * dx * dy / s2, om * (dy * dy / s2 - 1.0),
            om * (1.0 - dx * dx / s2), -om * dx * dy / s2)


@kernel(size_arg=2)
def _sample_analytic(kind, p, px, py, t, out, flag):
    for i in nb.prange(px.shape[0]):
        for k in range(NVAR):
            out[i, k] = 0.0
        flag[i] = WET
        if kind == UNIFORM:
            out[i, H] = p[UNI_DEPTH]
            out[i, U] = p[UNI_U] + p[UNI_AX] * t
            out[i, V] = p[UNI_V] + p[UNI_AY] * t
            out[i, DUDT] = p[UNI_AX]
            out[i, DVDT] = p[UNI_AY]
            out[i, DETADX] = p[UNI_SX]
            out[i, DETADY] = p[UNI_SY]
            out[i, ETA] = p[UNI_DEPTH] + p[UNI_SX] * px[i] + p[UNI_SY] * py[i]
        elif kind == SOLID_BODY:
            om = p[SB_OMEGA]
            dx, dy = px[i] - p[SB_XC], py[i] - p[SB_YC]
            out[i, H] = p[SB_DEPTH]
            out[i, U] = -om * dy
            out[i, V] = om * dx
            out[i, DUDY] = -om
            out[i, DVDX] = om
            out[i, DETADX] = om * om * dx / p[SB_G]
            out[i, DETADY] = om * om * dy / p[SB_G]
            out[i, ETA] = p[SB_DEPTH] + 0.5 * om * om * (dx * dx + dy * dy) / p[SB_G]
        elif kind == FREE_VORTEX:
            # Rankine core inside the core radius
            k = p[FV_GAMMA] / (2.0 * np.pi)
            dx, dy = px[i] - p[FV_XC], py[i] - p[FV_YC]
            r2 = dx * dx + dy * dy
            rc2 = p[FV_CORE] * p[FV_CORE]
            g = p[FV_G]
            out[i, H] = p[FV_DEPTH]
            if r2 < rc2:
                om = k / rc2
                out[i, U] = -om * dy
                out[i, V] = om * dx
                out[i, DUDY] = -om
                out[i, DVDX] = om
                out[i, DETADX] = om * om * dx / g
                out[i, DETADY] = om * om * dy / g
                out[i, ETA] = p[FV_DEPTH] - k * k / (g * rc2) + 0.5 * om * om * r2 / g
            else:
                r4 = r2 * r2
                out[i, U] = -k * dy / r2
                out[i, V] = k * dx / r2
                out[i, DUDX] = 2.0 * k * dx * dy / r4
                out[i, DUDY] = -k * (dx * dx - dy * dy) / r4
                out[i, DVDX] = k * (dy * dy - dx * dx) / r4
                out[i, DVDY] = -2.0 * k * dx * dy / r4
                out[i, DETADX] = k * k * dx / (g * r4)
                out[i, DETADY] = k * k * dy / (g * r4)
                out[i, ETA] = p[FV_DEPTH] - 0.5 * k * k / (g * r2)
        else:  # DRIFTING_EDDY
            out[i, H] = p[DE_DEPTH]
            out[i, ETA] = p[DE_DEPTH]
            c = p[DE_DRIFT]
            snap = p[DE_SNAPSHOT]
            if snap > 0.0:
                # linear in time between the formula at the multiples of snap (as on a grid)
                t0 = np.floor(t / snap) * snap
                a = (t - t0) / snap
                u0, v0, ux0, uy0, vx0, vy0 = _eddy(p, px[i], py[i], t0)
                u1, v1, ux1, uy1, vx1, vy1 = _eddy(p, px[i], py[i], t0 + snap)
                out[i, U], out[i, V] = (1.0 - a) * u0 + a * u1, (1.0 - a) * v0 + a * v1
                out[i, DUDT], out[i, DVDT] = (u1 - u0) / snap, (v1 - v0) / snap
                out[i, DUDX] = (1.0 - a) * ux0 + a * ux1
                out[i, DUDY] = (1.0 - a) * uy0 + a * uy1
                out[i, DVDX] = (1.0 - a) * vx0 + a * vx1
                out[i, DVDY] = (1.0 - a) * vy0 + a * vy1
            else:
                u, v, ux, uy, vx, vy = _eddy(p, px[i], py[i], t)
                out[i, U], out[i, V] = u, v
                out[i, DUDX], out[i, DUDY], out[i, DVDX], out[i, DVDY] = ux, uy, vx, vy
                # the pattern moves at c along x: dU/dt = -c dU/dx
                out[i, DUDT], out[i, DVDT] = -c * ux, -c * vx


class AnalyticField(FlowField):
    """A flow given by formulas; ``kind`` selects the kernel branch, ``params`` its constants."""

    kind = -1

    def __init__(self, params, name):
        self.params = np.asarray(params, dtype=np.float64)
        if not np.all(np.isfinite(self.params)):
            from driftlog.errors import ArgumentError

            raise ArgumentError(f"{type(self).__name__}: parameters must be finite numbers; "
                                f"got {name}")
        self.name = name

    def sample_into(self, x, y, t, face, out, flag):
        """Fill ``out`` (n, NVAR) and ``flag`` from the formulas; no faces (hints set to -1)."""
        face[:] = -1
        _sample_analytic(self.kind, self.params, x, y, float(t), out, flag)

    def __repr__(self):
        return f"<{type(self).__name__} {self.name}>"


class UniformFlow(AnalyticField):
    """U = (u + ax t, v + ay t), depth constant, free surface with gradient ``surface_slope``."""

    kind = UNIFORM

    def __init__(self, u=1.0, v=0.0, depth=1.0, acceleration=(0.0, 0.0), surface_slope=(0.0, 0.0),
                 g=G):
        # in the order UNI_U ... UNI_SY
        super().__init__([u, v, acceleration[0], acceleration[1], depth, g, surface_slope[0],
                          surface_slope[1]],
                         f"uniform flow ({u}, {v}) m/s")


class SolidBodyRotation(AnalyticField):
    """U = omega (-(y - yc), x - xc): rotation at rate omega (rad/s) about (xc, yc)."""

    kind = SOLID_BODY

    def __init__(self, omega=2 * np.pi / 100.0, center=(0.0, 0.0), depth=1.0, g=G):
        super().__init__([omega, center[0], center[1], depth, g],  # SB_OMEGA ... SB_G
                         f"solid-body rotation {omega} rad/s")

    @property
    def omega(self):
        """The rotation rate (rad/s)."""
        return self.params[SB_OMEGA]


class FreeVortex(AnalyticField):
    """Irrotational vortex u_theta = circulation / (2 pi R), solid-body inside ``core_radius``."""

    kind = FREE_VORTEX

    def __init__(self, circulation=10.0, center=(0.0, 0.0), depth=1.0, core_radius=0.0, g=G):
        super().__init__([circulation, center[0], center[1], depth, core_radius, g],  # FV_*
                         f"free vortex, circulation {circulation} m2/s")


class DriftingEddy(AnalyticField):
    """A Gaussian eddy drifting along x at speed c, with exact trajectories (``exact``).

    U(x, t) = (c, 0) + Omega(R) (-(y - y_c), x - x_c(t)),  Omega(R) = Omega_0 exp(-R^2 / 2 sigma^2),

    R the distance to the centre x_c(t) = x_c0 + c t.  In the frame moving with the eddy the
    flow is steady and circular, so every particle circles the moving centre at the rate
    Omega(R) of its distance: positions are known exactly, and the field is neither linear in
    space nor steady (the tests of grid interpolation and the peers benchmark use it).  The
    velocity gradient and dU/dt are exact; the depth is constant and the free surface flat
    (not balanced: the eddy is meant for tracers and drag).

    Parameters
    ----------
    center : (float, float)
        Centre at t = 0 (m).
    drift : float
        c (m/s).
    sigma : float
        Radius of the Gaussian (m).
    omega0 : float
        Rotation rate at the centre (rad/s).
    depth : float
        Constant depth (m).
    snapshot : float
        0: the formula at every time.  > 0: linear in time between the formula at multiples of
        ``snapshot`` (s), as a reader interpolates between a grid's snapshots.
    """

    kind = DRIFTING_EDDY

    def __init__(self, center=(0.0, 0.0), drift=0.5, sigma=150.0, omega0=0.01, depth=2.0,
                 snapshot=0.0):
        for name, value, ok in (("sigma", sigma, sigma > 0.0), ("depth", depth, depth > 0.0),
                                ("snapshot", snapshot, snapshot >= 0.0)):
            if not ok:
                raise ScenarioError(f"DriftingEddy.{name}", value,
                                    "must be > 0" if name != "snapshot" else "must be >= 0")
        self.center = (float(center[0]), float(center[1]))
        self.drift, self.sigma, self.omega0 = float(drift), float(sigma), float(omega0)
        self.depth, self.snapshot = float(depth), float(snapshot)
        super().__init__([center[0], center[1], drift, sigma, omega0, depth, snapshot],  # DE_*
                         "drifting Gaussian eddy (formula)")

    def velocity(self, x, y, t):
        """The velocity (u, v) (m/s) at points x, y (m) and time t (s), from the formula."""
        dx, dy = x - (self.center[0] + self.drift * t), y - self.center[1]
        om = self.omega0 * np.exp(-(dx * dx + dy * dy) / (2 * self.sigma ** 2))
        return self.drift - om * dy, om * dx

    def exact(self, x0, y0, t):
        """Exact positions at time t of particles released at (x0, y0) at time 0."""
        dx, dy = x0 - self.center[0], y0 - self.center[1]
        r = np.hypot(dx, dy)
        a = np.arctan2(dy, dx) + self.omega0 * np.exp(-r * r / (2 * self.sigma ** 2)) * t
        return self.center[0] + self.drift * t + r * np.cos(a), self.center[1] + r * np.sin(a)


def on_mesh(field: FlowField, mesh, times=(0.0,), name=None) -> MeshFlowField:
    """Sample a field at the face centroids of a mesh, at the given times: a MeshFlowField."""
    times = np.atleast_1d(np.asarray(times, dtype=float))
    hs, hus, hvs = [], [], []
    for t in times:
        s = field.sample(mesh.face_x, mesh.face_y, t)
        hs.append(s.h)
        hus.append(s.h * s.u)
        hvs.append(s.h * s.v)
    eta = field.sample(mesh.face_x, mesh.face_y, times[0]).eta
    bed = eta - hs[0]
    src = InMemorySnapshots(times, np.array(hs), np.array(hus), np.array(hvs),
                            name=name or f"{field.name} on mesh")
    return MeshFlowField(mesh, bed, src, attrs={"source": field.name})
