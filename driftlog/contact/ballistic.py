"""Logs in free (force-free) motion, with the tracker's contact interface.

On still water with no forces a log moves in a straight line at constant velocity and spins
at a constant rate; the exact solution of the motion lets tests and benchmarks check contacts
alone (conservation of energy and momenta to round-off, collision counts) without the flow.
``BallisticLogs`` offers what ``Tracker`` offers a contact model (the
``driftlog.protocols.ContactBodies`` contract): ``state``, ``length``, ``radius``, ``mass``,
``inertia``, ``ids``, ``t``, ``min_step``, ``save``/``restore``, ``advance``,
``invalidate_flow``.
"""

from __future__ import annotations

import numpy as np

from driftlog.columns import OMEGA, THETA, UB, VB, X, Y

__all__ = ["BallisticLogs", "run_contacts"]


class BallisticLogs:
    """Force-free logs: x += u dt, theta += omega dt.

    Parameters
    ----------
    state : (n, 6) array
        x, y, theta, u, v, omega.
    length, radius, density : float or (n,) arrays
    """

    def __init__(self, state, length, radius, density=720.0, t=0.0):
        from driftlog.errors import ArgumentError

        self.state = np.ascontiguousarray(state, dtype=float).copy()
        if self.state.ndim != 2 or self.state.shape[1] != 6:
            raise ArgumentError(f"BallisticLogs(state=...): shape {self.state.shape}; must be "
                                "(n, 6): x, y, theta, u, v, omega")
        if not np.all(np.isfinite(self.state)):
            raise ArgumentError("BallisticLogs(state=...): holds NaN or inf values; must be "
                                "finite")
        n = self.state.shape[0]
        self.length = np.broadcast_to(np.asarray(length, float), n).copy()
        self.radius = np.broadcast_to(np.asarray(radius, float), n).copy()
        dens = np.broadcast_to(np.asarray(density, float), n)
        for name, a in (("length", self.length), ("radius", self.radius), ("density", dens)):
            bad = ~((a > 0) & np.isfinite(a))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ArgumentError(f"BallisticLogs({name}={float(a[i])!r}) (log {i}): must be a "
                                    "finite number > 0")
        if not np.isfinite(t):
            raise ArgumentError(f"BallisticLogs(t={t!r}): must be a finite time (s)")
        volume = np.pi * self.radius ** 2 * self.length
        self.mass = np.broadcast_to(np.asarray(density, float), n) * volume
        self.inertia = self.mass * (self.length ** 2 / 12.0 + self.radius ** 2 / 4.0)
        self.ids = np.arange(n, dtype=np.int64)
        self.t = float(t)
        self.min_step = 1e-12  # s: contact steps below this are a jam
        self.advances = 0

    def save(self):
        """A copy of the state and time."""
        return self.state.copy(), self.t

    def restore(self, saved):
        """Back to a ``save()``."""
        np.copyto(self.state, saved[0])
        self.t = saved[1]

    def advance(self, dt):
        """Free motion over dt."""
        s = self.state
        s[:, X] += dt * s[:, UB]
        s[:, Y] += dt * s[:, VB]
        s[:, THETA] += dt * s[:, OMEGA]
        self.t += dt
        self.advances += 1

    def invalidate_flow(self):
        """Nothing to do: no flow is sampled."""

    def max_step(self, length_fraction=1.0, angle_step=np.pi / 4):
        """The paper's sub-step bound min(L / |U_b|, (pi/4) / |omega_b|) (docs/model.md (44))."""
        s = self.state
        sp = np.hypot(s[:, UB], s[:, VB])
        with np.errstate(divide="ignore"):
            a = np.where(sp > 0, length_fraction * self.length / sp, np.inf).min()
            b = np.where(s[:, OMEGA] != 0, angle_step / np.abs(s[:, OMEGA]), np.inf).min()
        return float(min(a, b))


def run_contacts(model, bodies, t_end, max_step=None):
    """Advance ``bodies`` to ``t_end`` through ``model.substep``.

    The tracker's loop, minus the flow; ``max_step`` bounds the sub-step (default: the
    paper's bound).
    """
    while bodies.t < t_end - 1e-12 * max(1.0, abs(t_end)):
        dt = min(bodies.max_step() if max_step is None else max_step, t_end - bodies.t)
        model.substep(bodies, dt)
    return bodies
