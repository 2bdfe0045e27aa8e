"""Two-way coupling: the logs act on driftlog's own flow (docs/model.md section 17).

``[coupling] enabled = true`` with ``[flow] source = "solver"``: the solver and the tracker
advance together, as in the paper's Figure 3: one hydrodynamic step [t_n, t_n+1] of the solver,
then the logs' sub-steps inside it on the flow interpolated between the two states, then the
reaction of the fluid forces the logs received over the step returned to the water as a
momentum source (``driftlog.solver.momentum``), before the next hydrodynamic step.

The reaction is exact: over a free sub-step the tracker's integrator changes a floating log's
velocity by the fluid forces only (drag, pressure gradient and added mass, docs/model.md
(33)-(35)), so the momentum a log receives from the water is m_b dU_b summed over its free
sub-steps (contact impulses are applied outside them).  It is spread evenly over ``points``
points along the log's axis and given, with the opposite sign, to the water of the faces under
them (a point on a dry face or outside the mesh gives its share to the log's own face).  So
the momentum the flow loses is what the logs gain plus what the contacts pass on to fixed
obstacles, to round-off.  Logs held against obstacles or one another (a jam) return the drag
they bear like any floating log: that is the jam's head loss, spread over its footprint
(section 17.2).

``[coupling] interval``: the solver takes several of its steps per exchange, the logs follow
over the whole interval, and the reaction they received is given to the water over the next
interval's steps at the rate it was received (docs/model.md 17.6): fewer landings, node
values and hand-overs; first order in the interval.

Spin-up: the solver runs alone from its ``[solver] start`` to ``[time] start``; the coupled
run then goes to ``[time] end``.  The flow file of the coupled run (snapshots at the
trajectory's output times, the volume balance, the momentum given by the logs) is written
beside the trajectories (``coupling.flow_path``).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from driftlog.columns import NQ, UB, VB
from driftlog.coupling_kernels import (
    account_advance,
    all_finite,
    contact_changes,
    gather_reaction,
    give_share,
    keep_linearisation,
    node_rows,
    refocus,
    region_points,
    spread_footprint,
    spread_reaction,
)
from driftlog.errors import ScenarioError
from driftlog.flow import InMemorySnapshots, MeshFlowField
from driftlog.logs import FLOATING
from driftlog.schema import Key, Section
from driftlog.solver.momentum import _arrays, face_momentum
from driftlog.tracker import Tracker, check_landings

__all__ = ["COUPLING_SECTION", "CoupledTracker", "SolverFlow", "Coupling", "FlowOutput",
           "start_coupling", "resume_coupling", "coupled_flow_path"]


class SolverFlow(MeshFlowField):
    """The solver's states at the start and end of its current step, as a flow field.

    Sampled like any mesh flow (P1 on recovered node values, linear in time between the two
    states), fused kernels included.  ``push(solver)`` makes the solver's state the end of
    the interval (the old end becomes its start).

    The node values are computed only where the logs can sample them (docs/model.md 17.5):
    ``focus(x, y, margin)``, before a step, restricts them to the nodes of the faces within
    ``margin`` of the points given (the logs); the other nodes hold NaN, so that a log that
    strays out of the region samples NaN, never a stale value: ``sample_into`` and the
    coupled tracker detect it and ``widen`` to the whole mesh for the step (exact: the
    interval's start state is kept).  The values at the region's nodes are those of the
    whole-mesh projection bit for bit (``driftlog.coupling_kernels.node_rows``).
    """

    def __init__(self, solver, dry_depth, name="coupled solver flow"):
        t = float(solver.t)
        src = InMemorySnapshots([t], solver.h.copy(), solver.hu.copy(), solver.hv.copy(), name)
        super().__init__(solver.mesh, solver.bed, src, dry_depth=dry_depth, name=name)
        self.solver = solver
        mesh = self.mesh
        P, Px, Py = mesh.node_operators()
        for M in (Px, Py):
            if not (np.array_equal(M.indptr, P.indptr) and np.array_equal(M.indices, P.indices)):
                raise RuntimeError("the node operators do not share one sparsity pattern")
        self._state_face = _state_index(solver)
        face = np.ascontiguousarray(P.indices, dtype=np.int64)
        self._ops = (np.ascontiguousarray(P.data, dtype=np.float64),
                     np.ascontiguousarray(Px.data, dtype=np.float64),
                     np.ascontiguousarray(Py.data, dtype=np.float64),
                     np.ascontiguousarray(P.indptr, dtype=np.int64), face,
                     np.ascontiguousarray(self._state_face[face]))
        nn = mesh.n_nodes
        loc = mesh.locator()
        self._bin_mark = np.full(loc.nbx * loc.nby, -1, np.int64)
        self._face_mark = np.full(mesh.n_faces, -1, np.int64)
        self._node_mark = np.zeros(nn, np.int64)  # the region: nodes marked ``_stamp``
        self._stamp = 0
        self._rows = np.arange(nn, dtype=np.int64)  # the region's nodes (all at first)
        self._count = nn
        self._spare = np.empty(nn, np.int64)
        self._fresh = np.empty(nn, np.bool_)
        self._start = tuple(np.empty(mesh.n_faces) for _ in range(3))  # the interval's start
        self._vals = np.empty((nn, 2 * NQ))
        self.speed = self._compute(self._rows, nn, 0)
        self._vals[:, NQ:] = self._vals[:, :NQ]
        self._t0 = self._t1 = t
        self.region_nodes = 0  # nodes computed over the run (the whole mesh: nn per step)
        self.widenings = 0  # steps where a log strayed out of the region

    @property
    def partial(self) -> bool:
        """Whether the node values cover a region only (not every node)."""
        return self._count < self.mesh.n_nodes

    def _compute(self, rows, count, col, state=None):
        """Node columns of ``rows[:count]`` from a face state (default: the solver's now)."""
        h, hu, hv = _arrays(self.solver) if state is None else state
        vp, vx, vy, indptr, face, state_face = self._ops
        return node_rows(rows, count, col, vp, vx, vy, indptr, face, state_face, h, hu, hv,
                         self.bed, self.dry_depth, self.gradient == "recovered", self._vals)

    def focus(self, x, y, margin):
        """Before a step: the region is the nodes of the faces within ``margin`` of (x, y).

        The interval's start columns of nodes new to the region are computed from the
        solver's state (the start of the coming step); nodes that leave it get NaN.
        """
        old, stamp = self._stamp, self._stamp + 1
        rows, spare = self._spare, self._rows
        h, hu, hv = _arrays(self.solver)
        vp, vx, vy, indptr, face, state_face = self._ops
        # the start state is kept in case the step must widen the region (``widen``)
        n = refocus(np.ascontiguousarray(x, dtype=np.float64),
                    np.ascontiguousarray(y, dtype=np.float64), float(margin),
                    self.mesh.locator(), self._bin_mark, self._face_mark, self._node_mark,
                    stamp, old, rows, self._fresh, spare, self._count, self._vals, vp, vx, vy,
                    indptr, face, state_face, h, hu, hv, self.bed, self.dry_depth,
                    self.gradient == "recovered", *self._start)
        self._spare = spare
        self._rows, self._count, self._stamp = rows, n, stamp

    def focus_all(self):
        """Before a step: every node (the end columns of the last step become start columns)."""
        nn = self.mesh.n_nodes
        if self.partial:
            out = np.flatnonzero(self._node_mark != self._stamp)
            self._compute(out, out.size, NQ)  # the state now, as at the last push
            self._node_mark[:] = self._stamp
            self._rows, self._spare = np.arange(nn, dtype=np.int64), self._rows
            self._count = nn
        self._vals[:, :NQ] = self._vals[:, NQ:]

    def widen(self):
        """Every node, for the current interval (a log strayed out of the region)."""
        nn = self.mesh.n_nodes
        out = np.flatnonzero(self._node_mark != self._stamp)
        self._compute(out, out.size, 0, self._start)
        self._compute(out, out.size, NQ)
        self._node_mark[:] = self._stamp
        self._rows, self._spare = np.arange(nn, dtype=np.int64), self._rows
        self._count = nn
        self.widenings += 1

    def push(self, solver):
        """The solver has stepped: its state ends the interval, the previous end starts it."""
        self._t0 = self._t1
        self._t1 = float(solver.t)
        self.speed = self._compute(self._rows, self._count, NQ)
        self.region_nodes += self._count

    def mesh_kernel(self):
        """``MeshFlowField.mesh_kernel``: the fused kernels sample the same P1 node values.

        A point outside the region reads NaN there too; ``CoupledTracker`` sees the non-finite
        state, calls ``widen`` and redoes the sub-step from its kept start state, as
        ``sample_into`` does for a sample (tests/test_coupling_region.py: identical logs and
        water on the fused and the general paths with a region around one log only).
        """
        return super().mesh_kernel()

    def sample_into(self, x, y, t, face, out, flag):
        """``MeshFlowField.sample_into``; over the whole mesh if a point left the region."""
        hint = face.copy() if self.partial else None
        super().sample_into(x, y, t, face, out, flag)
        if hint is not None and not np.isfinite(out).all():
            self.widen()
            np.copyto(face, hint)
            super().sample_into(x, y, t, face, out, flag)

    @property
    def times(self):
        """The current interval's (start, end) (s)."""
        return np.array([self._t0, self._t1])

    @property
    def time_span(self):
        """Unbounded: the solver extends the flow as the run goes."""
        return (-np.inf, np.inf)

    def check_time(self, t):
        """Any time: the interval is the solver's current step."""

    def _interval(self, t):
        dt = self._t1 - self._t0
        if dt <= 0.0:
            return 0, 0, 0.0, 0.0
        return 0, 1, min(max((t - self._t0) / dt, 0.0), 1.0), 1.0 / dt

    def node_values(self, t):
        """Node columns of the interval's two states, the time weight of t and 1 / dt."""
        _, _, a, inv_dt = self._interval(t)
        return self._vals, a, inv_dt

    def node_pair(self, t):
        """``MeshFlowField.node_pair``: the interval's two states, its start and length.

        The interval is the solver's current step, the only pair there is (its end: inf,
        so the per-log kernels never ask for a next one).
        """
        return self._vals, self._t0, self._t1 - self._t0, np.inf


def _state_index(solver):
    """Index in the solver's state arrays of each mesh face (it may renumber them)."""
    inv = getattr(solver, "_inv", None)
    if inv is None or getattr(solver, "_identity", True):
        return np.arange(solver.mesh.n_faces, dtype=np.int64)
    return np.ascontiguousarray(inv, dtype=np.int64)


class CoupledTracker(Tracker):
    """The tracker of a coupled run: its landing times come from the solver's steps.

    It keeps, per log, the momentum (kg m/s) the water gave it since the last hand-over
    (``received``): m_eff dU_b over each free sub-step (``advance``), m_eff = m_b + rho V_b / 2
    the log and the water it entrains (docs/model.md (33)), i.e. the impulse of the fluid
    forces F_D + F_P.  A contact changes a log's velocity by impulses on m_b only (the paper's
    eq. 11-15); the entrained water's share m_a dU_b (m_a = rho V_b / 2) of that change is
    passed on to the contact too (``to_contacts``, kg m/s): a log held on a pier then passes the
    whole drag to it, as a log at rest would.  So is the drag a held log bore beyond what its
    free sub-step integrated (``held_drag``, docs/model.md (73a)), added to ``received``.
    """

    # every stopped log's row goes at once: the hand-over's sums run over the compact rows
    lazy_drop = False

    def __init__(self, coupling, logs, *args, **kwargs):
        self.coupling = coupling
        n = len(logs)
        self.received = np.zeros((n, 2))
        self.to_contacts = np.zeros(2)
        self._last_u = np.zeros((n, 2))  # velocity at the end of each log's last free sub-step
        self._stamp = np.full(n, -1, np.int64)  # which free sub-step that was
        self._advances = 0
        self._lin = np.zeros((n, 4))  # drag linearisation at the start of that sub-step
        self._dt = np.zeros(n)  # and its length
        self._u0 = self._v0 = np.empty(0)  # velocities before a sub-step (buffers)
        super().__init__(coupling.flow, logs, *args, **kwargs)
        if getattr(self.step_options, "clock", "global") != "global" and self.contact is not None:
            raise ScenarioError("integrator.clock", self.step_options.clock, "[coupling] with "
                                "contacts takes the global clock: every log lands on each "
                                "hydrodynamic step")
        if not getattr(self.step_options, "land_on_snapshots", True):
            raise ScenarioError("integrator.land_on_snapshots", False, "[coupling] lands "
                                "every log on each hydrodynamic step: set it to true")
        if self.physics.fluid_volume != "body":
            raise ScenarioError("physics.fluid_volume", self.physics.fluid_volume, "[coupling] "
                                "needs fluid_volume = 'body' (a constant added mass)")
        self.added_mass = 0.5 * self.physics.water_density * logs.volume

    def _contact_changes(self):
        """Account the velocity changes the contacts made since the last advance.

        The drag the held logs bore beyond their free sub-step (``held_drag``), then the
        entrained water's share (``account_contacts``).
        """
        contact_changes(self.act, self.state, self._last_u, self._stamp, self._advances,
                        self.logs.mass, self.added_mass, self._lin, self._dt, self.received,
                        self.to_contacts)

    def advance(self, dt, have_d0=False):
        """``Tracker.advance``, keeping the momentum the water gives each floating log.

        Where the flow's node values cover a region only, a sub-step whose logs sampled out
        of it (NaN in their state or flow) is done again on the whole mesh.
        """
        n = self.state.shape[0]
        saved = None
        if n:
            self._contact_changes()
            if self._u0.shape[0] < n:
                self._u0, self._v0 = np.empty(n), np.empty(n)
            u0, v0 = self._u0[:n], self._v0[:n]
            np.copyto(u0, self.state[:, UB])
            np.copyto(v0, self.state[:, VB])
            if not have_d0:  # the first stage, as Tracker.advance would: its drag linearisation
                self._rhs(self.state, self.t, self.D0, self.lin0)
                have_d0 = True
            keep_linearisation(self.act, self.lin0, dt, self._lin, self._dt)
            if self.coupling.flow.partial:
                saved = Tracker.save(self)
        super().advance(dt, have_d0)
        if saved is not None and not all_finite(self.state, self.F):
            Tracker.restore(self, saved)
            self.coupling.flow.widen()
            self._rhs(self.state, self.t, self.D0, self.lin0)
            keep_linearisation(self.act, self.lin0, dt, self._lin, self._dt)
            super().advance(dt, True)
        self._advances += 1
        if n:
            account_advance(self.act, self.state, u0, v0, self.mass, self.added_mass,
                            self.received, self._last_u, self._stamp, self._advances)

    def _per_log_free(self, stop):
        """Per-log clocks over the solver's step (no contacts), keeping the momentum accounts.

        Each floating log runs on its own sub-steps to the step's end (``clocks.
        relift_advance``); what the water gave it is m_eff dU_b over each of its free paths
        (from its start, or its lift off the bed, to the end or to where it stopped), as
        ``advance`` accounts it over each sub-step of the global clock.  Where the flow's node
        values cover a region only and a log sampled out of it (NaN: an integration error or a
        non-finite state), the interval is done again on the whole mesh from its kept start.
        """
        from driftlog.clocks import relift_advance
        from driftlog.stepping import IntegrationError, StepTooSmallError

        L = self.logs
        flow = self.coupling.flow
        kept = None
        if flow.partial:
            if self.act.size:
                self._scatter()
            kept = (Tracker.save(self), self.act.copy(), L.status.copy(), L.state.copy(),
                    L.face.copy(), self.received.copy(), self._last_u.copy(),
                    self._stamp.copy(), self._advances, dict(self.stats))
        try:
            relift_advance(self, stop, self._gain)
            ok = kept is None or all_finite(self.state, self.F)
        except (IntegrationError, StepTooSmallError):
            if kept is None:
                raise
            ok = False
        if ok or kept is None:
            return
        saved, act, status, state, face, rec, lu, st, adv, stats = kept
        L.status[:], L.state[:], L.face[:] = status, state, face
        self._set_active(act)
        Tracker.restore(self, saved)
        np.copyto(self.received, rec)
        np.copyto(self._last_u, lu)
        np.copyto(self._stamp, st)
        self._advances = adv
        self.stats = stats
        flow.widen()
        relift_advance(self, stop, self._gain)

    def _gain(self, rows, u0):
        """``relift_advance``'s ``gain``: m_eff (U_b - U_b0) of the rows given, received."""
        self._advances += 1
        S = self.state if rows is None else self.state[rows]
        act = self.act if rows is None else self.act[rows]
        mass = self.mass if rows is None else self.mass[rows]
        u0 = np.zeros((S.shape[0], 2)) if u0 is None else u0
        account_advance(act, S, np.ascontiguousarray(u0[:, 0]), np.ascontiguousarray(u0[:, 1]),
                        mass, self.added_mass, self.received, self._last_u, self._stamp,
                        self._advances)

    def save(self):
        """``Tracker.save`` and the momentum accounts (a rejected sub-step gives nothing)."""
        return super().save() + (self.received.copy(), self.to_contacts.copy(),
                                 self._last_u.copy(), self._stamp.copy(), self._lin.copy(),
                                 self._dt.copy(), self._advances)

    def restore(self, saved):
        """Put back what ``save`` returned."""
        super().restore(saved[:-7])
        rec, tc, lu, st, lin, dt, adv = saved[-7:]
        np.copyto(self._lin, lin)
        np.copyto(self._dt, dt)
        np.copyto(self.received, rec)
        np.copyto(self.to_contacts, tc)
        np.copyto(self._last_u, lu)
        np.copyto(self._stamp, st)
        self._advances = adv

    def momentum(self):
        """Momentum of the logs and the water they entrain, sum of m_eff U_b (kg m/s)."""
        L = self.logs
        if self.act.size:
            self._scatter()
        m = L.mass + self.added_mass
        return np.array([np.dot(m, L.state[:, UB]), np.dot(m, L.state[:, VB])])

    def _landing_times(self, t_origin=None):
        """Outputs, releases and the end as before; hydrodynamic steps from the solver."""
        t0, t1 = (self.t if t_origin is None else t_origin), self.t_end
        self._steady = False
        check_landings(t0, t1, self.output_interval)
        n_out = int(np.floor((t1 - t0) / self.output_interval + 1e-9))
        outs = t0 + self.output_interval * np.arange(n_out + 1)
        self._outputs = np.unique(np.append(outs, t1))
        fixed = np.concatenate([self._outputs, self.logs.release_time, [t1]])
        fixed = np.unique(fixed[(fixed > self.t) & (fixed <= t1)])
        keep = np.ones(fixed.size, bool)
        keep[1:] = np.diff(fixed) > self.time_tol
        return self.coupling.stops(self, fixed[keep])

    def resume_from(self, t, index, columns, counts=None):
        """``Tracker.resume_from``, and the momentum accounts kept with the flow's restart.

        ``t`` must be the restart's time (``resume_coupling``): the solver is there.
        """
        kept = self.coupling.resumed
        if kept is None or t != kept["t"]:
            raise RuntimeError(f"resuming the logs at {t} s, the coupled flow at "
                               f"{None if kept is None else kept['t']} s")
        super().resume_from(t, index, columns, counts)
        sc = kept["scalars"]
        np.copyto(self.received, kept["received"])
        self.to_contacts[:] = sc["to_contacts_x"], sc["to_contacts_y"]


# the region of the flow's node values: margin = REGION_MARGIN x (distance the fastest log or
# water covers in a solver step) + half the longest log; doubled after a step that strayed out
REGION_MARGIN = 3.0
# the exchange Courant number |u| interval / dx under the logs beyond which a run warns
# (docs/model.md 17.6: the fixed array's backwater within 2.4 % of the balance at 1, 6-11 %
# off at 2)
EXCHANGE_COURANT_MAX = 1.0
CPU_PARTS = ("solver", "flow nodes", "tracker", "hand-over", "flow file")
# the coupling's counters a restart keeps (``Coupling._keep``, ``restore``): the name in the
# flow file (``coupling_restart_<name>``), whether on the flow (else the coupling), the
# attribute and its type
KEPT_COUNTERS = (("solver_steps", False, "solver_steps", int),
                 ("handovers", False, "handovers", int),
                 ("exchange_courant", False, "exchange_courant", float),
                 ("t_rem", False, "_t_rem", float), ("span", False, "_span", float),
                 ("step", False, "_step", float), ("dt", False, "_dt", float),
                 ("margin_factor", False, "margin_factor", float),
                 ("widenings", False, "_widenings", int),
                 ("flow_widenings", True, "widenings", int),
                 ("region_nodes", True, "region_nodes", int))


# how a log's reaction is shared among the faces (``[coupling] spread``)
SPREADS = ("footprint", "points")


class Coupling:
    """Drive a solver and a ``CoupledTracker`` together; hand the logs' reaction to the water.

    Parameters
    ----------
    solver : ShallowWaterSolver
        At the coupled run's start time.
    points : int
        Points along each log over which its reaction is spread (``spread = "points"``).
    water_density : float
        kg/m3 (the physics section's).
    dry_depth : float
        The flow's dry depth for sampling (``[flow] dry_depth``).
    writer : callable, optional
        ``writer(solver)`` called at each output time (after the hand-over): the flow file.
    interval : float
        Exchange interval (s, ``[coupling] interval``): the solver takes as many whole steps
        as fit in it (at least one) before the logs follow and hand their reaction over
        (docs/model.md 17.6); 0: every step, the paper's Figure 3.
    spread : str
        How a log's reaction is shared among faces (``SPREADS``; docs/model.md eq. (72)):
        "footprint", by the area of each face inside the log's plan (length x diameter);
        "points", evenly over ``points`` points along its axis (the code before 2026-12-07).

    Attributes
    ----------
    given : (2,) array
        Momentum given to the water so far (kg m/s).
    undelivered : (2,) array
        Momentum the logs received that found no wet face to go back to (kg m/s): zero
        unless a log's water dried up under it within a step.
    """

    def __init__(self, solver, points=8, water_density=1000.0, dry_depth=1e-3, writer=None,
                 interval=0.0, spread="footprint"):
        self.solver = solver
        self.interval = float(interval)
        if spread not in SPREADS:
            raise ValueError(f"spread {spread!r}: one of {', '.join(SPREADS)}")
        self.spread = spread
        self.points = int(points)
        self.rho = float(water_density)
        self.flow = SolverFlow(solver, dry_depth)
        self.writer = writer
        self.given = np.zeros(2)
        self.undelivered = np.zeros(2)
        self.solver_steps = 0
        self.handovers = 0
        self.margin_factor = REGION_MARGIN
        self.cpu = dict.fromkeys(CPU_PARTS, 0.0)
        nf = solver.mesh.n_faces
        self._sx, self._sy = np.zeros(nf), np.zeros(nf)
        # the footprint's walk (``spread_footprint``): a stamp per log, the faces found, their
        # areas, the clipping's polygons
        self._fmark = np.zeros(nf, np.int64)
        self._fstamp = 0
        self._fqueue = np.empty(nf, np.int64)
        self._farea = np.empty(nf)
        self._fwork = np.empty((4, solver.mesh.face_nodes.shape[1] + 4))
        self._touched = np.empty(0, np.int64)
        self._rows = None  # hand-over buffers (``gather_reaction``), one row per log
        self._dt = 0.0  # recent solver steps (s), for the region's margin
        self._xy = None  # the region's points (``focus``), one column per log
        self._length = 0.0  # the longest log (m)
        self._widenings = 0
        # exchange intervals (``interval`` > 0): the reaction pending per face (in _sx, _sy,
        # faces _touched[:_npend]), given over the next interval's steps at the rate it was
        # received: _t_rem seconds of it are left to give
        self._npend = 0
        self._t_rem = 0.0
        self._span = 0.0  # the last interval's length
        self._step = 0.0  # the last solver step's length
        self._seen = np.zeros(nf, np.int64)
        self._shares = 0
        self._out = np.zeros(4)
        self._kept = None  # a restart kept before the hand-over at an output time (``_keep``)
        self.resumed = None  # the restart a resumed run started from (``restore``)
        # the largest exchange Courant number |u| span / sqrt(area) met at a face under the
        # logs (interval mode; docs/model.md 17.6: validated up to EXCHANGE_COURANT_MAX)
        self.exchange_courant = 0.0

    def _give(self, frac, ux=0.0, uy=0.0):
        """Give the water the share ``frac`` of the pending reaction (``give_share``).

        ``ux``, ``uy``: momentum already found undelivered, summed with what this share
        finds (kg m/s).
        """
        s = self.solver
        h, hu, hv = _arrays(s)
        out = self._out
        out[0] = out[1] = 0.0
        out[2], out[3] = ux, uy
        self._shares += 1
        self._npend = give_share(frac, self._sx, self._sy, self._touched, self._npend, h,
                                 self.flow._state_face, s.mesh.face_area, self.rho,
                                 s.dry_depth, hu, hv, out, self._seen, self._shares)
        self.given[0] += out[0]
        self.given[1] += out[1]
        self.undelivered[0] += out[2]
        self.undelivered[1] += out[3]

    def _share_before_step(self):
        """Interval mode: the pending reaction's share of the coming step, at a constant rate.

        The step's length is not known before it is taken: the last step's stands for it;
        what an interval leaves pending joins the next one's reaction.
        """
        if self._npend == 0:
            return
        dt = self._step if self._step > 0.0 else self.interval
        frac = 1.0 if dt >= self._t_rem else dt / self._t_rem
        self._give(frac)
        self._t_rem = max(self._t_rem - dt, 0.0)

    def stops(self, tracker, fixed):
        """Yield the end of each hydrodynamic step; between two, hand the reaction over.

        ``fixed``: times a step must land on (outputs, releases, the end), increasing.
        CPU seconds per part go to ``cpu`` (the tracker's: from a yield to the next step).
        """
        s = self.solver
        tol = tracker.time_tol
        k = 0
        outputs = tracker._outputs
        clock, cpu = time.process_time, self.cpu
        c = clock()
        while k < fixed.size:
            if self._dt > 0.0:
                self.focus(tracker)
            else:  # the first step computes every node (no step known yet)
                self.flow.focus_all()
            c1 = clock()
            cpu["flow nodes"] += c1 - c
            # the reaction enters the solver's next step; the logs' interval starts from the
            # state before it (one node projection per step, not two)
            out_now = self.writer is not None and bool(np.any(np.abs(outputs - s.t) <= tol))
            self.handover(tracker, keep=out_now)
            c2 = clock()
            cpu["hand-over"] += c2 - c1
            if out_now:
                self._write_output(tracker)
            c3 = clock()
            cpu["flow file"] += c3 - c2
            # the solver's steps of one exchange interval: one step, or as many whole steps
            # as fit in ``interval`` (at least one), ending early on a time to land on
            t_start = s.t
            spread = self.interval > 0.0
            while True:
                target = fixed[k]
                if spread:  # the last interval's reaction, a share before each step
                    c5 = clock()
                    self._share_before_step()
                    c6 = clock()
                    cpu["hand-over"] += c6 - c5
                    c3 += c6 - c5
                t0 = s.t
                s.step(target - s.t)
                self._step = s.t - t0
                self.solver_steps += 1
                landed = target - s.t <= tol
                if landed:
                    s.t = float(target)  # land exactly, as the tracker does
                    k += 1
                if landed or (s.t - t_start) + (s.t - t0) > self.interval:
                    break
            # a step cut short to land on a time does not shrink the margin at once
            self._dt = max(s.t - t_start, 0.9 * self._dt)
            self._span = s.t - t_start
            c4 = clock()
            cpu["solver"] += c4 - c3
            self.flow.push(s)
            if tracker.physics.level == "full":
                # the flow's dU/dt is the new step's (full physics reads it: the pressure
                # gradient and added mass): the flow at the logs and the first stage kept from
                # the last sub-step, on the old step's, are sampled again, as at a snapshot of
                # a stored flow (Tracker.advance, docs/model.md section 11)
                tracker.invalidate_flow()
                tracker._d0_valid = False
            c = clock()
            cpu["flow nodes"] += c - c4
            yield s.t
            c5 = clock()
            cpu["tracker"] += c5 - c
            c = c5
        self.handover(tracker, keep=self.writer is not None)
        if self._npend:  # interval mode: what is pending goes now, at the end
            self._give(1.0)
        if self.writer is not None:
            self._write_output(tracker)

    def _write_output(self, tracker):
        """The flow file's snapshot now, and the restart kept before the hand-over.

        The trajectories are flushed first: a run stopped between the two files resumes from
        the flow's restart, at most one output before the trajectories' last record (whose
        later records it writes again; ``resume_coupling``).
        """
        if tracker.writer is not None:
            tracker.writer.flush()
        if getattr(self.writer, "keeps_restart", False):
            self.writer(self.solver, self._kept)
        else:  # any callable writer(solver)
            self.writer(self.solver)
        self._kept = None

    def _keep(self, tracker):
        """What a resumed run needs at an output time, before the hand-over (``restart``).

        The solver's state before the reaction enters it (the logs' next interval starts
        from it), the momentum each log received and the reaction still pending, and the
        coupling's counters.
        """
        s = self.solver
        f = self._touched[:self._npend].copy()
        scalars = dict(given_x=self.given[0], given_y=self.given[1],
                       undelivered_x=self.undelivered[0], undelivered_y=self.undelivered[1],
                       to_contacts_x=tracker.to_contacts[0], to_contacts_y=tracker.to_contacts[1],
                       **{name: getattr(self.flow if on_flow else self, attr)
                          for name, on_flow, attr, _ in KEPT_COUNTERS},
                       **{f"cpu_{i}": v for i, v in enumerate(self.cpu.values())})
        self._kept = dict(t=float(s.t), hu=np.array(s.hu), hv=np.array(s.hv),
                          received=tracker.received.copy(), pending_face=f,
                          pending_x=self._sx[f], pending_y=self._sy[f], scalars=scalars)

    def restore(self, kept):
        """Put back the counters and the pending reaction ``_keep`` kept (``resume_coupling``).

        The solver's state is set by ``load_restart``, the logs' accounts by
        ``CoupledTracker.resume_from``.
        """
        self.resumed = kept
        sc = kept["scalars"]
        self.given[:] = sc["given_x"], sc["given_y"]
        self.undelivered[:] = sc["undelivered_x"], sc["undelivered_y"]
        for name, on_flow, attr, kind in KEPT_COUNTERS:
            setattr(self.flow if on_flow else self, attr, kind(sc[name]))
        for i, k in enumerate(self.cpu):
            self.cpu[k] = float(sc.get(f"cpu_{i}", 0.0))
        f = np.asarray(kept["pending_face"], np.int64)
        self._touched = np.empty(self.solver.mesh.n_faces, np.int64)
        self._touched[:f.size] = f
        self._npend = f.size
        self._sx[f] = kept["pending_x"]
        self._sy[f] = kept["pending_y"]

    def focus(self, tracker):
        """Restrict the flow's node values to where the logs can sample in the coming step.

        The logs that the tracker may sample (all but those gone and recorded) with a margin
        ``margin_factor`` times the distance the fastest of them, or the fastest water in
        the current region, covers in a recent solver step, plus half the longest log.
        """
        L = tracker.logs
        n = len(L)
        if self._xy is None or self._xy.shape[1] < n:
            self._xy = np.empty((2, n))
            self._length = float(L.length.max()) if n else 0.0
        x, y = self._xy[0], self._xy[1]
        m, v2 = region_points(tracker.state, L.state, L.status, tracker._recorded_left,
                              FLOATING, x, y)
        speed = self.flow.speed
        if v2 >= 0.0 or v2 != v2:  # a floating log (max ignores a NaN speed, as before)
            speed = max(speed, float(np.sqrt(v2)))
        if self.flow.widenings > self._widenings:  # a log strayed out: a wider margin
            self._widenings = self.flow.widenings
            self.margin_factor *= 2.0
        self.flow.focus(x[:m], y[:m], self.margin_factor * self._dt * speed
                        + 0.5 * self._length)

    def handover(self, tracker, keep=False):
        """Give the water the opposite of what the logs received since the last call.

        ``keep``: an output time; what a resumed run needs is kept first (``_keep``).
        Returns True when the solver's state changed.
        """
        tracker._contact_changes()
        if keep:
            self._keep(tracker)
        L = tracker.logs
        s = self.solver
        b = self._rows
        if b is None or b[0].shape[0] < len(L):
            n = len(L)
            b = self._rows = (np.empty((n, 2)), np.empty(n), np.empty(n), np.empty(n),
                              np.empty(n), np.empty(n), np.empty(n, np.int64),
                              np.full(n, -1, np.int64), np.empty(n), np.empty(n))
            # the faces of the reaction pending (kept) and of the new one: each face once,
            # again only after its sums cancelled to zero (a few per log and hand-over)
            kept = self._touched[:self._npend]
            extra = self.points if self.spread == "points" else 8
            self._touched = np.empty(s.mesh.n_faces + n * extra, np.int64)
            self._touched[:kept.size] = kept
        g, x, y, theta, length, radius, hint, where, cos_t, sin_t = b
        m = gather_reaction(tracker.received, tracker.act, tracker.state, tracker.face,
                            L.state, L.face, L.length, L.radius, where, g, x, y, theta, length,
                            radius, hint)
        if m == 0:
            return False
        h, hu, hv = _arrays(s)
        th = theta[:m]
        # numpy's cos and sin (into buffers), as before: numba's may differ in the last bit
        c, sn = np.cos(th, out=cos_t[:m]), np.sin(th, out=sin_t[:m])
        if self.spread == "footprint":
            self._npend, ux, uy, self._fstamp = spread_footprint(
                g[:m], x[:m], y[:m], c, sn, length[:m], radius[:m], hint[:m],
                s.mesh.locator(), h, self.flow._state_face, s.dry_depth, self._sx, self._sy,
                self._touched, self._npend, self._fmark, self._fstamp, self._fqueue,
                self._farea, self._fwork)
        else:
            self._npend, ux, uy = spread_reaction(
                g[:m], x[:m], y[:m], c, sn, length[:m], hint[:m], self.points,
                s.mesh.locator(), h, self.flow._state_face, s.dry_depth, self._sx, self._sy,
                self._touched, self._npend)
        self.handovers += 1
        if self.interval > 0.0:
            # pending: given over the coming interval's steps at the rate it was received
            # over the last one (docs/model.md 17.6)
            self._t_rem = self._span
            self._courant(h, hu, hv)
            self.undelivered[0] += ux
            self.undelivered[1] += uy
            return False
        self._give(1.0, ux, uy)  # every step: all of it, now
        return True

    def _courant(self, h, hu, hv):
        """Track the exchange Courant number at the faces the pending reaction goes to.

        |u| span / sqrt(A) of the water there: how many cells it crosses in an exchange
        interval (one pass over the few faces under the logs, once per interval).
        """
        f = self._touched[:self._npend]
        if f.size == 0 or self._span <= 0.0:
            return
        s = self.solver
        hf = h[f]
        wet = hf > s.dry_depth
        if not wet.any():
            return
        f, hf = f[wet], hf[wet]
        c = np.hypot(hu[f], hv[f]) / hf * self._span / np.sqrt(s.mesh.face_area[f])
        self.exchange_courant = max(self.exchange_courant, float(c.max()))

    def summary(self) -> dict:
        """Numbers of the run: solver steps, hand-overs, momentum given and not delivered.

        Also the flow's node values computed per step on average (``region_nodes``), the
        steps widened to the whole mesh, and the CPU seconds of each part (``cpu_*_s``).
        """
        out = dict(solver_steps=self.solver_steps, handovers=self.handovers,
                   momentum_given_x=float(self.given[0]), momentum_given_y=float(self.given[1]),
                   momentum_undelivered_x=float(self.undelivered[0]),
                   momentum_undelivered_y=float(self.undelivered[1]),
                   region_nodes=self.flow.region_nodes / max(self.solver_steps, 1),
                   region_widenings=self.flow.widenings)
        if self.interval > 0.0:
            out["exchange_interval"] = self.interval
            out["exchange_courant"] = self.exchange_courant
        out.update({f"cpu_{k.replace(' ', '_').replace('-', '')}_s": v
                    for k, v in self.cpu.items()})
        return out

    def water_momentum(self):
        """Momentum of the water in the domain (kg m/s)."""
        return self.rho * np.array(face_momentum(self.solver))


class FlowOutput:
    """The coupled run's flow file: a snapshot (and the volume balance) per call.

    Written as ``<path>.partial`` (each snapshot flushed) and renamed to ``path`` when the run
    completes, as the solver's own flow files: a run that stops leaves no file at ``path``
    that a later run could take for the whole coupled flood.  Beside the last snapshot, the
    restart a stopped run resumes from (``Coupling._keep``): the solver's exact momentum
    before that time's hand-over (``restart_momentum_x/_y``), the momentum each log received
    (``coupling_received_x/_y``), the reaction pending on faces (``coupling_pending_*``) and
    the coupling's counters (attributes ``coupling_restart_*``, ``coupling_restart_time``
    last).  ``resume``: reopen the partial file and write after its snapshot number
    ``resume`` (its restart's, ``resume_coupling``).
    """

    keeps_restart = True  # ``Coupling`` passes it the restart kept before the hand-over

    def __init__(self, path, solver, attrs, resume=None):
        from driftlog.solver.run import _create

        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.snapshots = 0
        self._last = None
        self._closed = None  # the path once closed
        if resume is None:
            self._w = _create(self.partial, solver, attrs)
            return
        from driftlog.flowfile import FlowFileWriter

        self._w = FlowFileWriter(self.partial, solver.mesh, solver.bed, append=True)
        self._w.n = self.snapshots = int(resume)  # later snapshots are written again
        self._w._last_t = self._last = float(solver.t)

    def __call__(self, solver, kept=None):
        """Write the solver's state as the next snapshot (once per time), with its restart."""
        from driftlog.solver.run import _write

        if self.snapshots and self._last == solver.t:
            return
        _write(self._w, solver, sync=False,
               momentum=None if kept is None else (kept["hu"], kept["hv"]))
        if kept is not None:
            self._write_restart(kept)
        self._w.ds.sync()
        self._last = solver.t
        self.snapshots += 1

    def _write_restart(self, kept):
        ds = self._w.ds
        rec = kept["received"]
        if "coupling_received_x" not in ds.variables:
            ds.createDimension("coupling_log", rec.shape[0])
            ds.createDimension("coupling_pending", None)
            for axis in "xy":
                v = ds.createVariable(f"coupling_received_{axis}", "f8", ("coupling_log",))
                v.setncatts(dict(long_name=f"momentum each log received from the water since "
                                 f"the last hand-over, {axis} component (for resuming)",
                                 units="kg m s-1"))
                v = ds.createVariable(f"coupling_pending_{axis}", "f8", ("coupling_pending",))
                v.setncatts(dict(long_name=f"reaction pending on a face, {axis} component "
                                 "(for resuming)", units="kg m s-1"))
            v = ds.createVariable("coupling_pending_face", "i8", ("coupling_pending",))
            v.setncatts(dict(long_name="faces of the pending reaction, in their order"))
        ds.variables["coupling_received_x"][:] = rec[:, 0]
        ds.variables["coupling_received_y"][:] = rec[:, 1]
        f = kept["pending_face"]
        if f.size:
            ds.variables["coupling_pending_face"][:f.size] = f
            ds.variables["coupling_pending_x"][:f.size] = kept["pending_x"]
            ds.variables["coupling_pending_y"][:f.size] = kept["pending_y"]
        ds.setncatts({"coupling_restart_pending": f.size,
                      **{f"coupling_restart_{k}": v for k, v in kept["scalars"].items()}})
        ds.setncattr("coupling_restart_time", kept["t"])

    def close(self, finalize=True, **attrs):
        """Add global attributes and close the file; returns its path.

        ``finalize``: the run completed, the file is renamed to ``path``; otherwise it stays
        at ``partial`` (the snapshots up to where the run stopped).
        """
        if self._closed is not None:
            return self._closed
        if attrs:
            self._w.ds.setncatts(attrs)
        self._w.close()
        self._closed = self.partial
        if finalize:
            os.replace(self.partial, self.path)
            self._closed = self.path
        return self._closed


def _coupled_attrs(scenario):
    attrs = dict(scenario.attrs())
    attrs["title"] = (scenario["title"] or "driftlog") + " (coupled flow)"
    attrs["coupled"] = 1
    return attrs


def _coupling(scenario, solver, out):
    c = scenario["coupling"]
    return Coupling(solver, points=c["points"], spread=c["spread"],
                    water_density=scenario["physics"]["water_density"],
                    dry_depth=scenario["flow"]["dry_depth"], writer=out, interval=c["interval"])


def start_coupling(scenario, trajectory_path):
    """The solver of a coupled scenario run alone to ``[time] start``, and its ``Coupling``.

    The flow file (``coupled_flow_path``) is opened and gets the spun-up state as its first
    snapshot.
    """
    from driftlog.files import check_output
    from driftlog.solver.config import build_solver, estimate_mesh

    sec = scenario["solver"]
    estimate_mesh(sec)
    path = check_output(coupled_flow_path(scenario, trajectory_path), "flow file")
    solver = build_solver(sec)
    t0 = float(scenario["time"]["start"])
    if t0 < solver.t:
        raise ScenarioError("time.start", t0, f"a coupled run starts at or after the solver's "
                            f"start ({solver.t} s, [solver] start)")
    solver.advance_to(t0)  # spin-up, uncoupled
    return _coupling(scenario, solver, FlowOutput(path, solver, _coupled_attrs(scenario)))


def resume_coupling(scenario, trajectory_path):
    """The ``Coupling`` of a stopped coupled run, at the restart its flow file kept.

    The solver takes the state of the restart's snapshot (the last complete one), the coupling
    its counters and pending reaction (``Coupling.restore``); the logs take theirs from the
    trajectories at the same time (``CoupledTracker.resume_from``; the trajectories, flushed
    before each snapshot, may hold one more output, written again).  The flow file is
    continued after that snapshot.  Refused, naming the file, when the partial flow file is
    missing, kept no restart, or was computed from another scenario.
    """
    import netCDF4

    from driftlog.errors import FlowFileError
    from driftlog.files import reopen_partial
    from driftlog.solver.config import build_solver, estimate_mesh
    from driftlog.solver.run import load_restart

    sec = scenario["solver"]
    estimate_mesh(sec)
    path = coupled_flow_path(scenario, trajectory_path)
    partial = path.with_name(path.name + ".partial")
    if not partial.is_file():
        raise FlowFileError(f"{partial}: cannot resume the coupled run: its flow file is "
                            "missing (the logs need the flow they acted on); rerun it from "
                            "the start, without --resume")
    try:
        netCDF4.Dataset(partial).close()
    except OSError as exc:
        raise FlowFileError(f"{partial}: cannot resume the coupled run from it: not readable "
                            f"as netCDF ({exc}); rerun it from the start, without --resume") \
            from None
    reopen_partial(partial)  # killed while open: HDF5 refuses to write it again, reads it
    with netCDF4.Dataset(partial) as ds:
        ds.set_auto_maskandscale(False)
        a = {k: ds.getncattr(k) for k in ds.ncattrs()}
        if "coupling_restart_time" not in a or "coupling_received_x" not in ds.variables:
            raise FlowFileError(f"{partial}: cannot resume the coupled run from it: it kept no "
                                "restart (written by a driftlog before 2026-12-07, or stopped "
                                "before its first output); rerun it from the start")
        if a.get("scenario_resolved") != scenario.to_json():
            raise FlowFileError(f"{partial}: cannot resume the coupled run from it: it was "
                                "computed from another scenario (its scenario_resolved "
                                "differs); rerun it from the start, without --resume")
        sc = {k[len("coupling_restart_"):]: v for k, v in a.items()
              if k.startswith("coupling_restart_")}
        npend = int(sc.pop("pending"))
        kept = dict(t=float(sc.pop("time")),
                    received=np.column_stack([ds.variables["coupling_received_x"][:],
                                              ds.variables["coupling_received_y"][:]]),
                    pending_face=np.array(ds.variables["coupling_pending_face"][:npend]),
                    pending_x=np.array(ds.variables["coupling_pending_x"][:npend]),
                    pending_y=np.array(ds.variables["coupling_pending_y"][:npend]),
                    scalars=sc)
    solver = build_solver(sec)
    n = load_restart(solver, partial, at=kept["t"])
    coupling = _coupling(scenario, solver, FlowOutput(path, solver, None, resume=n))
    coupling.restore(kept)
    return coupling


def coupled_flow_path(scenario, trajectory_path) -> Path:
    """Where a coupled run writes its flow: ``coupling.flow_path`` or ``<trajectories>_flow.nc``."""
    p = scenario["coupling"]["flow_path"]
    t = Path(trajectory_path)
    if not p:
        return t.with_name(t.stem + "_flow.nc")
    from driftlog.solving import default_flow_path

    path = Path(p)
    for other, what in ((t, "the trajectory file"),
                        (default_flow_path(scenario), "the uncoupled flow file ([flow] path)")):
        if path.resolve() == Path(other).resolve():
            raise ScenarioError("coupling.flow_path", p, f"is {what}: the coupled run's flow "
                                "needs a file of its own (or leave flow_path out: "
                                "<trajectories>_flow.nc)",
                                str(scenario.path) if getattr(scenario, "path", None) else None)
    return path


# --------------------------------------------------------------------- the scenario section
def _check_coupling(t, prefix, scen):
    if not t["enabled"]:
        return
    flow = scen.get("flow") or {}
    if flow.get("source") != "solver":
        raise ScenarioError(f"{prefix}.enabled", True, "needs [flow] source = 'solver': the "
                            f"logs act on driftlog's own flow only (source is "
                            f"{flow.get('source')!r})")
    solver = scen.get("solver") or {}
    if solver.get("engine", "driftlog") != "driftlog":
        raise ScenarioError(f"{prefix}.enabled", True, "needs [solver] engine = 'driftlog' (not "
                            f"{solver.get('engine')!r})")
    phys = scen.get("physics") or {}
    if phys.get("level") == "tracer":
        raise ScenarioError("physics.level", "tracer", "a tracer has no inertia and exerts no "
                            "force on the flow: use 'full' or 'drag' with [coupling]")
    if phys.get("motion", "floating") != "floating":
        raise ScenarioError("physics.motion", phys.get("motion"), "[coupling] takes the paper's "
                            "floating condition only (motion = 'floating'): bed friction "
                            "forces on a log are not returned to the flow yet")
    if phys.get("waterlogging", "off") != "off":
        raise ScenarioError("physics.waterlogging", phys.get("waterlogging"), "[coupling] with "
                            "waterlogging is not supported yet (the logs' mass changes outside "
                            "the momentum balance)")
    clock = (scen.get("integrator") or {}).get("clock", "global")
    if clock != "global" and (scen.get("contact") or {}).get("enabled", False):
        raise ScenarioError("integrator.clock", clock, "[coupling] with contacts takes the "
                            "global clock (the paper's Algorithm 1: every log lands on each "
                            "hydrodynamic step, the contacts' impulses accounted sub-step by "
                            "sub-step); per-log clocks are for coupled runs without contacts")
    if phys.get("fluid_volume", "body") != "body":
        raise ScenarioError("physics.fluid_volume", phys.get("fluid_volume"), "[coupling] needs "
                            "fluid_volume = 'body' (a constant added mass)")
    if flow.get("steady_at") is not None:
        raise ScenarioError("flow.steady_at", flow.get("steady_at"), "a coupled flow cannot be "
                            "frozen: remove steady_at or [coupling]")
    if not (scen.get("integrator") or {}).get("land_on_snapshots", True):
        raise ScenarioError("integrator.land_on_snapshots", False, "[coupling] lands every "
                            "log on each hydrodynamic step: set it to true")
    tm = scen.get("time") or {}
    s0, s1 = solver.get("start", 0.0), solver.get("end")
    if tm.get("start") is not None and s0 is not None and tm["start"] < s0:
        raise ScenarioError("time.start", tm["start"], f"a coupled run starts at or after the "
                            f"solver's start ({s0:g} s, [solver] start)")
    if tm.get("end") is not None and s1 is not None and tm["end"] > s1:
        raise ScenarioError("time.end", tm["end"], f"a coupled run ends at or before the "
                            f"solver's end ({s1:g} s, [solver] end): raise [solver] end or "
                            f"lower [time] end")


COUPLING_SECTION = Section("coupling", [
    Key("enabled", "bool", False, "two-way coupling: the logs' fluid forces act back on the "
        "solver's flow (needs [flow] source = 'solver')"),
    Key("spread", "str", "footprint", "how a log's reaction on the water is shared among "
        "faces: footprint, by the area of each face under the log's plan (length x diameter); "
        "points, evenly over [coupling] points along its axis (docs/model.md eq. (72))",
        choices=SPREADS),
    Key("points", "int", 8, "with spread = 'points': points along a log over which its "
        "reaction on the water is spread", min=1, max=1000),
    Key("flow_path", "path", "", "flow file of the coupled run, relative to the scenario's "
        "folder (default: beside the trajectories, <name>_flow.nc)"),
    Key("interval", "float", 0.0, "exchange interval: the solver takes as many whole steps "
        "as fit in it before the logs follow on the flow between its two ends and hand their "
        "reaction back (fewer exchanges, cheaper; 0 = every hydrodynamic step, the paper's "
        "Figure 3; docs/model.md 17.6)", "s", min=0.0),
], doc="two-way coupling of logs and flow (docs/model.md section 17)", check=_check_coupling)
