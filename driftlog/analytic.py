"""Analytic flow fields with exact gradients and time derivatives, for tests and cases.

Each has the sampling interface of every flow field (``FlowField.sample``).  Depth is constant;
the free-surface slope is the one that balances the flow's steady (advective) acceleration,
g grad(eta) = -(U . grad) U, as in frictionless steady flow, so that the ``surface_slope``
physics option (MODEL.md section 4: -g grad(eta) in place of the steady part of DU_w/Dt) and
the pressure-gradient term agree on these fields.  A uniform flow may be given a surface slope
of its own (a sloping uniform flow held by bed friction, where DU_w/Dt = 0 but g S is not).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.flow import (
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
    FlowField,
    H,
    InMemorySnapshots,
    MeshFlowField,
    U,
    V,
)

__all__ = ["UniformFlow", "SolidBodyRotation", "FreeVortex", "AnalyticField", "on_mesh"]

G = 9.81
UNIFORM, SOLID_BODY, FREE_VORTEX = 0, 1, 2


@kernel(size_arg=2)
def _sample_analytic(kind, p, px, py, t, out, flag):
    for i in nb.prange(px.shape[0]):
        for k in range(NVAR):
            out[i, k] = 0.0
        flag[i] = WET
        if kind == UNIFORM:
            # p = u0, v0, ax, ay, depth, g, slope x, slope y
            out[i, H] = p[4]
            out[i, U] = p[0] + p[2] * t
            out[i, V] = p[1] + p[3] * t
            out[i, DUDT] = p[2]
            out[i, DVDT] = p[3]
            out[i, DETADX] = p[6]
            out[i, DETADY] = p[7]
            out[i, ETA] = p[4] + p[6] * px[i] + p[7] * py[i]
        elif kind == SOLID_BODY:
            # p = omega, xc, yc, depth, g
            om = p[0]
            dx, dy = px[i] - p[1], py[i] - p[2]
            out[i, H] = p[3]
            out[i, U] = -om * dy
            out[i, V] = om * dx
            out[i, DUDY] = -om
            out[i, DVDX] = om
            out[i, DETADX] = om * om * dx / p[4]
            out[i, DETADY] = om * om * dy / p[4]
            out[i, ETA] = p[3] + 0.5 * om * om * (dx * dx + dy * dy) / p[4]
        else:
            # p = Gamma, xc, yc, depth, core radius, g; Rankine core inside the core radius
            k = p[0] / (2.0 * np.pi)
            dx, dy = px[i] - p[1], py[i] - p[2]
            r2 = dx * dx + dy * dy
            rc2 = p[4] * p[4]
            out[i, H] = p[3]
            if r2 < rc2:
                om = k / rc2
                out[i, U] = -om * dy
                out[i, V] = om * dx
                out[i, DUDY] = -om
                out[i, DVDX] = om
                out[i, DETADX] = om * om * dx / p[5]
                out[i, DETADY] = om * om * dy / p[5]
                out[i, ETA] = p[3] - k * k / (p[5] * rc2) + 0.5 * om * om * r2 / p[5]
            else:
                r4 = r2 * r2
                out[i, U] = -k * dy / r2
                out[i, V] = k * dx / r2
                out[i, DUDX] = 2.0 * k * dx * dy / r4
                out[i, DUDY] = -k * (dx * dx - dy * dy) / r4
                out[i, DVDX] = k * (dy * dy - dx * dx) / r4
                out[i, DVDY] = -2.0 * k * dx * dy / r4
                out[i, DETADX] = k * k * dx / (p[5] * r4)
                out[i, DETADY] = k * k * dy / (p[5] * r4)
                out[i, ETA] = p[3] - 0.5 * k * k / (p[5] * r2)


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
        face[:] = -1
        _sample_analytic(self.kind, self.params, x, y, float(t), out, flag)

    def __repr__(self):
        return f"<{type(self).__name__} {self.name}>"


class UniformFlow(AnalyticField):
    """U = (u + ax t, v + ay t), depth constant, free surface with gradient ``surface_slope``."""

    kind = UNIFORM

    def __init__(self, u=1.0, v=0.0, depth=1.0, acceleration=(0.0, 0.0), surface_slope=(0.0, 0.0),
                 g=G):
        super().__init__([u, v, acceleration[0], acceleration[1], depth, g, surface_slope[0],
                          surface_slope[1]],
                         f"uniform flow ({u}, {v}) m/s")


class SolidBodyRotation(AnalyticField):
    """U = omega (-(y - yc), x - xc): rotation at rate omega (rad/s) about (xc, yc)."""

    kind = SOLID_BODY

    def __init__(self, omega=2 * np.pi / 100.0, center=(0.0, 0.0), depth=1.0, g=G):
        super().__init__([omega, center[0], center[1], depth, g],
                         f"solid-body rotation {omega} rad/s")

    @property
    def omega(self):
        return self.params[0]


class FreeVortex(AnalyticField):
    """Irrotational vortex u_theta = circulation / (2 pi R), solid-body inside ``core_radius``."""

    kind = FREE_VORTEX

    def __init__(self, circulation=10.0, center=(0.0, 0.0), depth=1.0, core_radius=0.0, g=G):
        super().__init__([circulation, center[0], center[1], depth, core_radius, g],
                         f"free vortex, circulation {circulation} m2/s")


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
