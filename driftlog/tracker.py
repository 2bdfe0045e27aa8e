"""The tracker: Algorithm 1 of the reference paper (docs/model.md section 11).

Per hydrodynamic step [t_n, t_n+1] the logs are advanced by sub-steps

    dt = min(length_fraction L / |U_b|, angle_step / |omega_b|, drag bound, t_n+1 - t)

over all floating logs, with the integrator of choice; the flow is sampled at the stage times.
Sub-steps also land exactly on output times and release times.  A contact model (optional)
takes over each sub-step through a small interface (``state``, ``save``/``restore``,
``advance``): see ``driftlog.contact``.

The floating logs are held compactly (structure of arrays, only the floating ones), so that
resting, stranded, waiting or departed logs cost nothing in the integrator.
"""

from __future__ import annotations

import time as _time

import numba
import numpy as np

from driftlog.clocks import CLOCKS, per_log_interval
from driftlog.columns import (
    DUDY,
    DVDX,
    NLIN,
    NQ,
    NSTATE,
    NVAR,
    OMEGA,
    OUTSIDE,
    P_HSTAR,
    STATE_NAMES,
    THETA,
    UB,
    VB,
    VELOCITY,
    U,
    V,
    X,
    Y,
)
from driftlog.errors import ScenarioError
from driftlog.fused import (
    C_ANG,
    C_DRAG,
    C_EXPLICIT,
    C_LF,
    FUSED_METHODS,
    HOLE,
    NCTL,
    PK_N,
    PR_N,
    aligned_rows,
    drop_items,
    drop_rows,
    euler_mesh_step,
    euler_tracer_step,
    pack_tracer_nodes,
    rk4_mesh_step,
    rk4_tracer_step,
    settle_summary,
    subset_positions,
    take_rows,
)
from driftlog.integrators import RK4_C, make_integrator
from driftlog.logs import FLOATING, LEFT, RESTING, STRANDED, WAITING, flotation_depths
from driftlog.physics import (
    PhysicsOptions,
    log_parameters,
    rhs_kernel,
    soak_kernel,
)
from driftlog.schema import Key, Section
from driftlog.stepping import (
    IntegrationError,
    StepOptions,
    StepTooSmallError,
    classify,
    step_bound,
)

__all__ = ["Tracker", "StepOptions", "TIME_SECTION", "StepTooSmallError", "IntegrationError",
           "MAX_LANDINGS", "check_landings"]

MAX_LANDINGS = 1_000_000
"""Output times, and hydrodynamic steps of a flow without snapshots, that a run may land on
(each a stop of every log, ~0.1 ms: a million is minutes)."""


def check_landings(t0, t1, output_interval, hydro_step=None):
    """Refuse (``ScenarioError``) a run from t0 to t1 with more than ``MAX_LANDINGS`` stops.

    ``[time] output_interval`` (a record each) and ``hydro_step`` (given for a flow without
    snapshots, whose steps it sets) so small that the run would not end (1e-7 s over 4 s: 4e7
    stops, hours) or the stop times not fit in memory (1e-300 s).
    """
    span = float(t1) - float(t0)
    for key, step in (("time.output_interval", output_interval), ("time.hydro_step", hydro_step)):
        if step is None or not span > 0:
            continue
        n = span / step
        if n > MAX_LANDINGS:
            raise ScenarioError(key, step, f"makes {n:.3g} stops over the run's {span:g} s, more "
                                f"than {MAX_LANDINGS:g}: must be >= {span / MAX_LANDINGS:.3g} s")


def outside_error(flow, logs, out):
    """The ScenarioError for logs ``out`` released outside the flow's mesh.

    It names the first log's group, x and y, how many in all, and the mesh's extent.
    """
    i = int(out[0])
    x, y = float(logs.state[i, X]), float(logs.state[i, Y])
    mesh = getattr(flow, "mesh", None)
    extent = ""
    if mesh is not None:
        x0, y0, x1, y1 = mesh.bounds
        extent = (f"; the mesh spans x {x0:.6g} to {x1:.6g} m, y {y0:.6g} to {y1:.6g} m "
                  "(holes such as piers excluded)")
    return ScenarioError(f"logs[{logs.group[i]}]", f"x = {x:.6g}, y = {y:.6g}",
                         f"log {int(logs.id[i])} starts outside the flow domain ({out.size} of "
                         f"{len(logs)} logs are outside){extent}; logs must start inside the "
                         "mesh")


class Tracker:
    """Advance logs on a flow field (Algorithm 1) and record their trajectories.

    Parameters
    ----------
    flow : FlowField
    logs : Logs
    physics : PhysicsOptions
    method : str
        Integrator: euler, rk4 or exponential.
    step : StepOptions
    contact : object, optional
        A contact model with ``substep(tracker, dt) -> dt_taken`` and ``drain_hits()``.
    t_start, t_end : float
    output_interval : float
    hydro_step : float
        Hydrodynamic step for flows without snapshots (analytic fields).
    writer : TrajectoryWriter, optional
    progress : bool
        A progress bar over simulated time.
    initial_velocity : str or array of str
        Velocity of a log when released floating: "flow" (the flow's velocity and rotation),
        "rest", or "given" (the velocity in ``logs``).
    fused : bool
        Where the flow offers a fused mesh kernel (``flow.mesh_kernel()``, a mesh flow sampled
        P1) and the integrator is euler or rk4, advance each log through a whole step in one
        kernel (``driftlog.fused``: same results, fewer memory passes); False forces the
        general path (stage by stage over whole arrays).

    The tracker is the ``driftlog.protocols.ContactBodies`` a contact model moves: ``state``,
    ``t``, ``ids``, ``length``, ``radius``, ``mass``, ``inertia``, ``min_step``, ``advance``,
    ``save``/``restore``, ``invalidate_flow``.
    """

    _wall0 = _wall_base = 0.0  # ``run``'s start (perf_counter) and the seconds before it

    # ``advance(dt, have_d0=True)`` takes the first stage ``max_step`` just computed at the
    # same state (``ContactModel._event`` reuses it; ``driftlog.protocols.ContactBodies``)
    keeps_first_stage = True

    def __init__(self, flow, logs, physics=None, method="rk4", step=None, contact=None,
                 t_start=0.0, t_end=None, output_interval=1.0, hydro_step=1.0, writer=None,
                 progress=False, initial_velocity="flow", fused=True):
        self.flow = flow
        self.logs = logs
        self.physics = physics or PhysicsOptions()
        self.opt = self.physics.vector()
        self.integrator = make_integrator(method)
        # the fused kernels inline the mesh sampling: only where the flow offers them
        self._kernel = flow.mesh_kernel() if fused and method in FUSED_METHODS else None
        self.fused = self._kernel is not None
        self._d0_valid = False
        self._F_t = np.nan  # time of the fused step's flow sample (``advance``)
        self._stop = -np.inf  # the stop ``_global_steps`` is heading for
        self.step_options = step or StepOptions()
        self.contact = contact
        self.clock = self.step_options.clock
        if self.clock not in CLOCKS:
            raise ScenarioError("integrator.clock", self.clock,
                                "must be one of " + ", ".join(CLOCKS))
        if self.clock == "per_log" and (self._kernel is None
                                        or self._kernel.node_pair is None):
            raise ScenarioError(
                "integrator.clock", self.clock,
                f"per-log clocks run in the fused mesh kernels: they need a mesh flow sampled P1 "
                f"(this flow: {getattr(flow, 'name', type(flow).__name__)}) and "
                f"integrator.method euler or rk4 (here {method!r}); use clock = 'global'")
        if not self.step_options.land_on_snapshots and self.clock != "global":
            raise ScenarioError("integrator.land_on_snapshots", False,
                                "needs clock = 'global' (per-log clocks meet at every "
                                "snapshot); set land_on_snapshots = true or clock = 'global'")
        self.t = float(t_start)
        t0f, t1f = flow.time_span
        self.t_end = float(t_end if t_end is not None else t1f)
        if not np.isfinite(self.t_end):
            raise ScenarioError("time.end", t_end, "must be given for flows without an end "
                                "(analytic or steady flows)")
        if not self.t_end > self.t:
            raise ScenarioError("time.end", self.t_end, f"must be after time.start = {self.t}")
        # times closer than this are one time (round-off): relative to the run's span, never
        # to |t| (at t ~ 1.7e9 s a tolerance of 1e-9 |t| is 1.7 s and swallows a 64-s run's
        # outputs); plus a few ulps of the largest |t| so that exact landings stay exact
        self.time_tol = (1e-9 * (self.t_end - self.t)
                         + 4.0 * float(np.spacing(max(abs(self.t), abs(self.t_end)))))
        self.output_interval = float(output_interval)
        self.hydro_step = float(hydro_step)
        for key, v in (("time.output_interval", self.output_interval),
                       ("time.hydro_step", self.hydro_step)):
            if not (np.isfinite(v) and v > 0):
                raise ScenarioError(key, v, "must be a finite number > 0 s")
        self.writer = writer
        self.progress = progress
        self.initial_velocity = (np.broadcast_to(np.asarray(initial_velocity), len(logs))
                                 if not isinstance(initial_velocity, str)
                                 else np.full(len(logs), initial_velocity))
        self._no_rows = np.empty((0, 0))  # S, P for _classify when they are not read
        self.P_all = log_parameters(logs.length, logs.radius, logs.density, logs.float_depth)
        self.stats = dict(substeps=0, rhs_evaluations=0, min_dt=np.inf, max_dt=0.0,
                          rejected=0, wall_seconds=0.0)
        self._recorded_left = np.zeros(len(logs), dtype=bool)
        self._settle_next = False
        # tracer mode's own kernels, and the fused step settling the logs (False: the fused
        # step alone and the tracker's passes, as before; for before/after measurements)
        self._tracer_kernels = self._settling = True
        self._nholes = 0  # stopped logs' rows left in the compact arrays (``_make_holes``)
        self._packs = []  # tracer mode's packed node rows of the latest snapshot pairs
        self._next_release = -np.inf
        self._resumed = False
        self._set_active(np.empty(0, dtype=np.int64))
        self._t_start = self.t
        self._stops = self._landing_times()

    # ----------------------------------------------------------------- first stage
    # ``_d0_valid``: D0 and lin0 hold the first stage at every compact row's state (and F the
    # flow there).  ``_d0_window``: they do for the next contact window only (set by
    # ``clocks.contact_window`` at its end; any change of ``_d0_valid``, as every change of the
    # compact rows makes, clears it), so that its free advance need not evaluate them again
    # while the paths that keep rows across a change of the set still sample them anew.
    _d0_window = False

    @property
    def _d0_valid(self):
        return self._d0v

    @_d0_valid.setter
    def _d0_valid(self, value):
        self._d0v = value
        self._d0_window = False

    # ----------------------------------------------------------------- compact arrays
    # Logs that stop may leave their rows in the compact arrays as holes (``_make_holes``),
    # up to a sixteenth of the rows (HOLE_FRACTION); False: every stop drops its rows at once
    # (a coupled run's sums over the rows, or a caller holding rows across a stop)
    lazy_drop = True
    HOLE_FRACTION = 1.0 / 16.0

    def _set_active(self, idx):
        """Gather the floating logs ``idx`` into the compact arrays the kernels use."""
        idx = np.asarray(idx, dtype=np.int64)
        kept = self._kept_stage(idx)
        self.act = idx
        L = self.logs
        n = self.act.size
        self.state = np.empty((n, NSTATE))
        take_rows(idx, L.state, self.state)
        self.P = np.empty((n, self.P_all.shape[1]))
        take_rows(idx, self.P_all, self.P)
        self.face = L.face[idx]
        self.ids = L.id[idx]
        self.length = L.length[idx]
        self.radius = L.radius[idx]
        self.mass = L.mass[idx]
        self.inertia = L.inertia[idx]
        # every row of F is taken from the kept rows below when they are kept
        self.F = np.zeros((n, NVAR)) if kept is None else np.empty((n, NVAR))
        self.flag = np.zeros(n, np.int8)
        self._F_valid = False
        self._stage_F = None  # made when a general-path stage first samples (``_rhs``)
        self._stage_flag = np.zeros(n, np.int8)
        self._stage_face = np.empty(n, np.int64)
        self._sx, self._sy = np.empty(n), np.empty(n)
        self._next = np.empty((n, NSTATE))
        self.D0, self.lin0 = self.integrator.prepare(n)
        self._nolin = np.empty((n, NLIN))
        self._d0_valid = False
        self._st = np.full(n, FLOATING, np.int8)  # read by a settling step: holes
        self._nholes = 0
        self._bound = np.empty(n)
        self._settled = None
        if kept is not None:
            # logs that stay floating keep their flow sample and first stage: the same numbers
            # as sampling them again from their faces, without the pass; logs new to the set
            # (lifted, released) get theirs from their own faces, row by row as the pass would
            pos = kept[0]
            new = np.flatnonzero(pos < 0)
            if new.size:
                pos = np.where(pos < 0, 0, pos)
            for src, out in zip(kept[1:4], (self.F, self.D0, self.lin0), strict=True):
                take_rows(pos, src, out)
            self.flag[:] = kept[-1][pos]
            if new.size:
                self._stage_new(new)
            self._F_valid = self._d0_valid = True
        if self.contact is not None and getattr(self.contact, "grounded", False):
            self._ground()

    def _drop_stopped(self, idx):
        """``_set_active(idx)`` where ``idx`` only loses logs, the compact arrays kept.

        Where every log of ``idx`` was floating and the flow sample and first stage are kept
        (``_kept_stage``), the rows of the logs that stopped are dropped in place
        (``drop_rows``) and every array becomes a view of its first ``idx.size`` rows: the
        same numbers as gathering them again, without allocating and filling some 50 columns
        per log each time a few logs strand or leave.  False (nothing done) otherwise.
        Only for ``_update_status`` over all logs: no caller holds the compact arrays across
        it (contact islands, which do, keep ``_set_active``).
        """
        old = self.act
        if not (self.fused and self._d0_valid and self._F_valid and idx.size and old.size
                and idx.size < old.size):
            return False
        pos = np.empty(idx.size, np.int64)
        if not subset_positions(old, idx, pos) or self._hole_rows(pos):
            return False
        self._compact(pos)
        return True

    def _hole_rows(self, pos):
        """Whether any of the compact rows ``pos`` is a hole (a stopped log lifted again)."""
        return bool(self._nholes) and bool(np.any(self._st[pos] >= HOLE))

    def _compact(self, pos):
        """Keep only the compact rows ``pos`` (ascending), in place (``_drop_stopped``)."""
        idx = self.act[pos]
        n = idx.size
        # the settling step's bounds of the logs kept are the step bound (44) at their state
        settled = self._settled_now() is not None
        chunks = 8 * numba.get_num_threads()
        for a in (self.state, self.P, self.F, self.D0, self.lin0):
            drop_rows(pos, a, chunks)
        for a in (self.face, self.ids, self.length, self.radius, self.mass, self.inertia,
                  self.flag) + ((self._st, self._bound) if settled else ()):
            drop_items(pos, a)
        self.act = idx
        self.state, self.P, self.F = self.state[:n], self.P[:n], self.F[:n]
        self.face, self.ids, self.flag = self.face[:n], self.ids[:n], self.flag[:n]
        self.length, self.radius = self.length[:n], self.radius[:n]
        self.mass, self.inertia = self.mass[:n], self.inertia[:n]
        self.D0, self.lin0 = self.integrator.adopt(self.D0[:n], self.lin0[:n])
        # scratch: written before they are read; the stage samples' array is made (zeros)
        # when a general-path step first needs it (``_rhs``)
        self._stage_F = None
        self._stage_flag = self._stage_flag[:n]
        self._stage_face = self._stage_face[:n]
        self._sx, self._sy = self._sx[:n], self._sy[:n]
        self._next, self._nolin = self._next[:n], self._nolin[:n]
        self._st, self._bound = self._st[:n], self._bound[:n]
        self._st[:] = FLOATING  # every row kept floats; no holes
        self._nholes = 0
        self._settled = None
        if settled:  # the smallest bound of the logs kept, as ``max_step`` would find it
            self._settled = (self.state, self.t, *settle_summary(self._st, self._bound))
        if self.contact is not None and getattr(self.contact, "grounded", False):
            self._ground()

    def _make_holes(self, stopped):
        """Leave the compact rows ``stopped`` (logs that just stopped) in place as holes.

        Dropping a few rows moves every row after them (``drop_rows``: some 50 columns per
        log); at 1e5 tracers that was a sixth of a sub-step whenever a log left or stranded.
        A hole's row stays as it stopped (velocity zeroed, written back by ``_scatter``): the
        settling step skips it and copies its state (``fused.skip_hole``), ``settle_summary``
        leaves it out, and the holes go together once they are HOLE_FRACTION of the rows, or
        before any pass that reads every row (``_fill_holes``).  Only behind a settling step
        of the global clock (``_settled_now``: no contact model, no waterlogging), and not
        for the last floating logs.  False (nothing done) otherwise.
        """
        n, k = self.act.size, self._nholes + stopped.size
        if not (self.lazy_drop and self.clock == "global" and stopped.size and k < n
                and k <= self.HOLE_FRACTION * n and self._settled_now() is not None):
            return False
        self._st[stopped] += HOLE
        self._nholes = k
        # the smallest bound was the floating logs' already (``settle_summary``)
        s = self._settled
        self._settled = (s[0], s[1], s[2], 0, s[4])
        return True

    def _fill_holes(self):
        """Drop the holes' rows (``_make_holes``), the other rows kept as they are."""
        if self._nholes:
            self._compact(np.flatnonzero(self._st < HOLE))

    def _ground(self):
        """Resting and stranded logs: fixed capsules of the contact model (docs/model.md 13)."""
        from driftlog.contact.geometry import log_capsules

        L = self.logs
        rows = np.flatnonzero((L.status == RESTING) | (L.status == STRANDED))
        S = L.state[rows]
        self.contact.set_grounded(rows, log_capsules(S[:, X], S[:, Y], S[:, THETA],
                                                     L.length[rows], L.radius[rows]),
                                  L.id[rows])

    def _kept_stage(self, idx):
        """Where the logs ``idx`` stand in the compact arrays, and the rows there.

        The positions (-1 for a log not floating before), then F, D0, lin0 and flag; None
        when nothing is kept: no valid first stage, or logs new to the set while the stage
        was not sampled at this very time (a landing moved the clock by round-off) or the
        time is the current stop (where a coupled flow changes before the next sub-step).
        """
        old = getattr(self, "act", None)
        if not (self.fused and self._d0_valid and self._F_valid and old is not None
                and old.size and idx.size):
            return None
        pos = np.empty(idx.size, np.int64)
        found = subset_positions(old, idx, pos)
        if self._nholes:
            # a hole's row is a stopped log's: a log lifted again starts anew
            hole = (pos >= 0) & (self._st[np.maximum(pos, 0)] >= HOLE)
            if hole.any():
                pos[hole] = -1
                found = False
        if not found:
            # the pass would sample at the next step bound: here, unless the flow changes
            # first (a coupled run's solver steps at the end of the current stop)
            if self._F_t != self.t or not self.t < self._stop:
                return None
            # copies: the integrator's buffers for as many logs are the same arrays, and
            # rows move up past logs new to the set
            return pos, self.F, self.D0.copy(), self.lin0.copy(), self.flag
        return pos, self.F, self.D0, self.lin0, self.flag

    def _stage_new(self, rows):
        """Flow sample and first stage of the compact rows ``rows`` (logs new to the set).

        What ``_rhs`` at the current state computes for every row, for these rows only: each
        log's sample and derivative depend on its own row alone.
        """
        S = self.state[rows]
        face = self.face[rows]
        F = np.empty((rows.size, NVAR))
        flag = np.empty(rows.size, np.int8)
        self.flow.sample_into(np.ascontiguousarray(S[:, X]), np.ascontiguousarray(S[:, Y]),
                              self.t, face, F, flag)
        self.face[rows] = face
        self.F[rows] = F
        self.flag[rows] = flag
        self._first_stage_rows(rows)

    def _first_stage_rows(self, rows):
        """D0 and lin0 of the compact rows ``rows`` from their state and flow sample ``F``."""
        D = np.empty((rows.size, self.D0.shape[1]))
        lin = np.empty((rows.size, self.lin0.shape[1]))
        rhs_kernel(self.state[rows], self.F[rows], self.P[rows], self.opt, D, lin, True)
        self.D0[rows] = D
        self.lin0[rows] = lin

    def _scatter(self, rows=None):
        """Write the compact state back into the full arrays (only ``rows`` if given)."""
        if rows is None:
            self.logs.state[self.act] = self.state
            self.logs.face[self.act] = self.face
        else:
            self.logs.state[self.act[rows]] = self.state[rows]
            self.logs.face[self.act[rows]] = self.face[rows]

    # ----------------------------------------------------------------- flow at the logs
    def _sample_current(self):
        if not self._F_valid:
            self.flow.sample_into(self.state[:, X], self.state[:, Y], self.t, self.face,
                                  self.F, self.flag)
            self._F_valid = True

    def _rhs(self, S, t, D, lin):
        """Derivative of states S at time t: flow sampled at S's positions (stage sampling)."""
        if S is self.state and t == self.t:
            self._sample_current()
            F = self.F
        else:
            if self._stage_F is None:
                self._stage_F = np.zeros((self.act.size, NVAR))
            np.copyto(self._stage_face, self.face)
            np.copyto(self._sx, S[:, X])  # contiguous coordinates sample faster than strided
            np.copyto(self._sy, S[:, Y])
            self.flow.sample_into(self._sx, self._sy, t, self._stage_face, self._stage_F,
                                  self._stage_flag)
            F = self._stage_F
        want = lin is not None
        rhs_kernel(S, F, self.P, self.opt, D, lin if want else self._nolin, want)
        self.stats["rhs_evaluations"] += 1

    # ----------------------------------------------------------------- contact interface
    def save(self):
        """A copy of what ``advance`` changes (state, time, hints, flow at the logs)."""
        return (self.state.copy(), self.t, self.face.copy(), self.F.copy(), self.flag.copy(),
                self._F_valid)

    def restore(self, saved):
        """Put back what ``save`` returned."""
        state, t, face, F, flag, valid = saved
        np.copyto(self.state, state)
        self.t = t
        np.copyto(self.face, face)
        np.copyto(self.F, F)
        np.copyto(self.flag, flag)
        self._F_valid = valid
        self._d0_valid = False
        self._settled = None

    def invalidate_flow(self):
        """The positions were moved from outside (a contact model): sample the flow again."""
        self._F_valid = False
        self._settled = None

    @property
    def min_step(self):
        """Shortest sub-step accepted (integrator.min_step, s)."""
        return self.step_options.min_step

    def advance(self, dt, have_d0=False):
        """Integrate the free motion of the floating logs over dt (no contacts).

        ``have_d0``: the first stage (``D0``, ``lin0``) was just computed for this very state
        by ``max_step`` (the tracker's own loop; a contact model may change velocities between).
        The tracker's own loop (``_settle_next``) asks the fused step for the logs' new
        statuses and step bounds too (``_can_settle``), which ``_update_status`` and
        ``max_step`` then read.
        """
        fused = self.fused and self.state.shape[0] > 0
        self._settled = None
        settle = self._settle_next and fused and self._can_settle()
        self._settle_next = False
        if not settle:
            self._fill_holes()
        # landing on the snapshots, every stage reads the pair of snapshots of this step, the
        # last one too (docs/model.md section 11: the flow's dU/dt jumps at a snapshot)
        t_mid = self.t + 0.5 * dt
        pair = self.step_options.land_on_snapshots and self._snapshots.size > 1
        if self.state.shape[0]:
            if not have_d0:
                self._rhs(self.state, self.t, self.D0, self.lin0)
            if pair:
                self.flow.step_interval(t_mid)
            try:
                if fused:
                    self._fused_step(dt, settle)
                else:
                    self.integrator.step(self.state, self.t, dt, self._rhs, self._next,
                                         have_d0=True)
            finally:
                if pair:
                    self.flow.step_interval(None)
            self.state, self._next = self._next, self.state
        self.t += dt
        self._F_t = self.t  # when the fused step's sample below was taken
        # the fused step sampled the flow at the new state and computed its first stage; at a
        # snapshot its dU/dt was the ending pair's, and full physics reads dU/dt (the
        # pressure gradient and added mass): sampled again, from the next pair
        fresh = fused and not (pair and self.physics.level == "full"
                               and self._pair_index(self.t) != self._pair_index(t_mid))
        self._F_valid = self._d0_valid = fresh
        if fused and not fresh:
            settle = False
        if settle:
            # statuses, bounds and tracer velocities came with the step (same arithmetic)
            b, moved, bad = settle_summary(self._st, self._bound)
            self._settled = (self.state, self.t, b, moved, bad)
        elif self.state.shape[0]:
            self._fill_holes()
            self._sample_current()
            if self.physics.level == "tracer":
                self._sync_tracer()

    def _per_log_free(self, stop):
        """Per-log clocks without contacts, from t to ``stop`` (``clocks.relift_advance``)."""
        from driftlog.clocks import relift_advance

        relift_advance(self, stop)

    def _can_settle(self):
        """The fused step may also classify the logs and bound the next sub-step.

        Only where those passes read nothing the step does not have: no contact model (it may
        move the logs after the step), motion "floating" (the bed friction test is a force
        evaluation of its own) and no waterlogging (the densities change after the step).
        """
        ph = self.physics
        return (self._settling and self.contact is None and ph.motion == "floating"
                and ph.waterlogging == "off")

    def _settled_now(self):
        """What the last settling step found, if it still describes the current arrays."""
        s = self._settled
        if s is not None and s[0] is self.state and s[1] == self.t and self._d0_valid:
            return s
        return None

    # snapshot times the steps land on (``_landing_times``); none for a coupled run, whose
    # flow pairs are the solver's own steps
    _snapshots = np.empty(0)

    def _pair_index(self, t):
        """Index of the snapshot pair (i, i + 1) that the flow samples at t alone."""
        return int(np.searchsorted(self._snapshots, t, side="right"))

    def _fused_step(self, dt, settle=False):
        """One integrator step of every floating log in one kernel (``driftlog.fused``)."""
        kern, t0 = self._kernel, self.t
        so = self.step_options
        ctl = np.empty(NCTL)
        ctl[C_LF], ctl[C_ANG], ctl[C_DRAG] = so.length_fraction, so.angle_step, so.drag_fraction
        ctl[C_EXPLICIT] = float(not self.integrator.stiff_stable
                                and self.physics.level != "tracer")
        tail = (kern.dry_depth, kern.recovered, kern.locator, settle, ctl, self.length,
                self._st, self._bound)
        head = (self.state, self.D0, self.lin0, self._next, self.face, self.F, self.flag,
                self.P, self.opt, dt, True)
        # node values in the order the general path asks for them (the flow caches one pair)
        tracer = (self._tracer_kernels and self.physics.level == "tracer"
                  and self.physics.motion == "floating")
        if tracer and self.integrator.name == "rk4":
            # tracer mode's own kernels: the flow on packed node rows, no force evaluation
            a_m, pk_m, pr_m = self._packed(t0 + RK4_C[1] * dt)  # stages 1 and 2
            a_e, pk_e, pr_e = self._packed(t0 + RK4_C[3] * dt)
            rk4_tracer_step(*head[:-1], a_m, pk_m, pr_m, a_e, pk_e, pr_e, *tail)
            self.stats["rhs_evaluations"] += 3
        elif tracer:
            euler_tracer_step(*head[:-1], *self._packed(t0 + dt), *tail)
        elif self.integrator.name == "rk4":
            vals_m, a_m, inv_m = kern.node_values(t0 + RK4_C[1] * dt)  # stages 1 and 2
            vals_e, a_e, inv_e = kern.node_values(t0 + RK4_C[3] * dt)
            rk4_mesh_step(*head, a_m, inv_m, vals_m, a_e, inv_e, vals_e, *tail)
            self.stats["rhs_evaluations"] += 3
        else:
            vals_e, a_e, inv_e = kern.node_values(t0 + dt)
            euler_mesh_step(*head, a_e, inv_e, vals_e, *tail)

    def _plain_flow(self):
        """Whether the flow is a plain ``MeshFlowField`` (its node values from its snapshots)."""
        from driftlog.flow import MeshFlowField

        return getattr(self._kernel.node_values, "__func__", None) is MeshFlowField.node_values

    def _tracer_values(self, t):
        """The flow's node columns around t for tracer mode's kernels: (vi, vj, cj, a).

        Snapshot i's columns are ``vi[:, :NQ]``, snapshot j's ``vj[:, cj:cj + NQ]``, a the
        weight of j.  A plain ``MeshFlowField`` gives its two cached snapshots as they are
        (``node_snapshot_pair``: no side-by-side copy of the pair), and without rotation (or
        with the P1 gradient), which those kernels then do not read, without its recovered
        gradients (two sparse products per snapshot, 1.2 ms on 24,000 nodes), to be computed
        if another reader asks.  Another flow (a coupled run's) gives ``node_values``.
        """
        kern = self._kernel
        if self._plain_flow():
            rot = self.physics.rotation and kern.recovered
            vi, vj, a, _ = kern.node_values.__self__.node_snapshot_pair(t, gradients=rot)
            return vi, vj, 0, a
        vals, a, _ = kern.node_values(t)
        return vals, vals, NQ, a

    def _packed(self, t):
        """(a, pk, pr): the packed node rows (``fused.pack_tracer_nodes``) of the pair at t.

        Those of the two latest pairs are kept (a step's stages may use two) where the flow
        is a plain ``MeshFlowField``, whose snapshots' node columns are new arrays whenever
        it loads one; another flow's (a coupled run's, updated in place) are packed at every
        call.
        """
        vi, vj, cj, a = self._tracer_values(t)
        fresh = self._plain_flow()
        for (pi, pj), pk, pr in self._packs if fresh else ():
            if pi is vi and pj is vj:
                return a, pk, pr
        loc = self._kernel.locator
        rot = self.physics.rotation and self._kernel.recovered
        n = vi.shape[0]
        pk = aligned_rows(n, PK_N)
        pr = aligned_rows(n if rot else 1, PR_N)
        pack_tracer_nodes(vi, vj, cj, loc.node_x, loc.node_y, pk, pr, rot)
        self._packs = [((vi, vj), pk, pr)] + self._packs[:1]
        return a, pk, pr

    def _sync_tracer(self):
        self.state[:, UB] = self.F[:, U]
        self.state[:, VB] = self.F[:, V]
        self.state[:, OMEGA] = (0.5 * (self.F[:, DVDX] - self.F[:, DUDY])
                                if self.physics.rotation else 0.0)

    def max_step(self):
        """The sub-step bound at the current state."""
        so = self.step_options
        dt = so.max_step if so.max_step else np.inf
        if self.state.shape[0]:
            settled = self._settled_now() if self.contact is None else None
            if settled is None:
                self._fill_holes()
            if self._d0_valid and self.contact is None:
                self.stats["rhs_evaluations"] += 1  # computed by the fused step, same state
            else:
                self._rhs(self.state, self.t, self.D0, self.lin0)
            if settled is not None:
                return min(dt, settled[2])  # the fused step's bounds of these very logs
            explicit = not self.integrator.stiff_stable and self.physics.level != "tracer"
            dt = min(dt, step_bound(self.state, self.length, self.lin0, so.length_fraction,
                                     so.angle_step, so.drag_fraction, explicit))
        return dt

    # ----------------------------------------------------------------- statuses
    def _classify(self, F, flag, idx, status, S=None, P=None):
        """Statuses of the logs ``idx`` from the flow at them; how many changed.

        ``S``, ``P``: their state and parameter rows when already gathered.
        """
        L = self.logs
        if self.physics.motion == "floating":
            return classify(F, flag, L.float_depth[idx], status, False, self._no_rows,
                             self._no_rows, self.opt)
        S = L.state[idx] if S is None else S
        P = self.P_all[idx] if P is None else P
        return classify(F, flag, P[:, P_HSTAR], status, True, S, P, self.opt)

    def _soak(self, dt):
        """Waterlogging (docs/model.md 6.2): the density of every wet log rises over dt."""
        if self.physics.waterlogging == "off" or dt <= 0.0:
            return
        L = self.logs
        wet = np.flatnonzero((L.status == FLOATING) | (L.status == RESTING))
        if wet.size == 0:
            return
        ph = self.physics
        soak_kernel(wet, dt, ph.saturated_density, ph.waterlogging_time, L.water_density,
                    L.density, L.volume, L.length, L.radius, L.mass, L.inertia, L.float_depth,
                    self.P_all)
        if self.act.size:
            self.P[:] = self.P_all[self.act]
            self.mass = L.mass[self.act]
            self.inertia = L.inertia[self.act]
            self._d0_valid = False  # the first stage depends on the density

    def _set_densities(self, idx, density):
        """Give the logs ``idx`` these densities (a resumed waterlogged run).

        Their mass, inertia, flotation depth and parameter rows follow.
        """
        L = self.logs
        L.density[idx] = density
        L.mass[idx] = L.density[idx] * L.volume[idx]
        L.inertia[idx] = L.mass[idx] * (L.length[idx] ** 2 / 12.0 + L.radius[idx] ** 2 / 4.0)
        L.float_depth[idx] = flotation_depths(np.ascontiguousarray(L.radius[idx], float),
                                              np.ascontiguousarray(L.density[idx], float),
                                              float(L.water_density))
        self.P_all[:] = log_parameters(L.length, L.radius, L.density, L.float_depth)

    def _update_status(self, pool=None, idle=True):
        """Re-classify floating logs (left, stranded, resting) and the resting ones (refloat).

        ``pool``: only these logs move now (a contact island under per-log clocks): the
        floating ones among them stay active, idle logs are left for the synchronisation time.
        ``idle``: False leaves the idle logs alone (per-log clocks' contact windows, which
        know when each idle log lifts: ``clocks.contact_advance``).
        """
        check = idle
        L = self.logs
        changed = scattered = lifted = False
        settled = self._settled_now()
        if settled is None:
            self._fill_holes()
        stopped = None
        if self.act.size:
            if settled is not None:
                st, moved = self._st, settled[3]  # classified by the fused step
            else:
                self._sample_current()
                st = np.full(self.act.size, FLOATING, np.int8)
                moved = self._classify(self.F, self.flag, self.act, st, self.state, self.P)
            if moved:
                changed = True
                if pool is None:
                    # the logs that stopped go back to the full arrays now, the others when
                    # they are gathered again (``_set_active``) or stay in place
                    # (``_drop_stopped``); resting logs do not move (docs/model.md section 6)
                    stopped = np.flatnonzero((st != FLOATING) & (st < HOLE))
                    self.state[stopped, VELOCITY] = 0.0
                    self._scatter(stopped)
                    if self._nholes:  # the other rows are floating logs, or holes
                        L.status[self.act[stopped]] = st[stopped]
                    else:
                        L.status[self.act] = st
                else:
                    self._scatter()
                    scattered = True
                    L.state[self.act[st != FLOATING], VELOCITY] = 0.0
                    L.status[self.act] = st
        # on a steady flow an idle log can only change when it has just stopped
        # (waterlogging changes the logs themselves)
        if pool is None and check:
            idle = np.flatnonzero((L.status == RESTING) | (L.status == STRANDED))
            if idle.size and (not self._steady or changed or self._first_check
                              or self.physics.waterlogging != "off"):
                lifted = self._check_idle(idle)
                changed |= lifted
        self._first_check = False
        if changed and not lifted and stopped is not None and self._make_holes(stopped):
            return
        if changed:
            idx = (np.flatnonzero(L.status == FLOATING) if pool is None
                   else pool[L.status[pool] == FLOATING])
            if pool is not None or not self._drop_stopped(idx):
                if not scattered and self.act.size:
                    self._scatter()
                self._set_active(idx)

    def _check_idle(self, idx):
        L = self.logs
        s = self.flow.sample(L.state[idx, X], L.state[idx, Y], self.t, face=L.face[idx])
        L.face[idx] = s.face
        st = L.status[idx].copy()
        n = self._classify(s.values, s.flag, idx, st)
        if n:
            lifted = idx[(st == FLOATING)]
            L.state[lifted, VELOCITY] = 0.0  # a lifted log starts from rest
            L.status[idx] = st
        return n > 0

    def _release(self):
        """Logs whose release time has come: floating, resting, stranded, or an error outside."""
        L = self.logs
        tol = self.time_tol
        if self.t + tol < self._next_release:
            return False
        waiting = L.status == WAITING
        due = np.flatnonzero(waiting & (L.release_time <= self.t + tol))
        later = L.release_time[waiting & (L.release_time > self.t + tol)]
        self._next_release = later.min() if later.size else np.inf
        if due.size == 0:
            return False
        if self.act.size:
            self._scatter()
        s = self.flow.sample(L.state[due, X], L.state[due, Y], self.t)
        out = due[s.flag == OUTSIDE]
        if out.size:
            raise outside_error(self.flow, L, out)
        L.face[due] = s.face
        st = np.full(due.size, WAITING, np.int8)
        self._classify(s.values, s.flag, due, st)
        L.status[due] = st
        fl = st == FLOATING
        # a log set moving on the bed (motion = friction) starts from rest
        on_bed = fl & (s.h < L.float_depth[due])
        L.state[due[fl & ((self.initial_velocity[due] == "rest") | on_bed)], VELOCITY] = 0.0
        with_flow = fl & (self.initial_velocity[due] == "flow") & ~on_bed
        L.state[due[with_flow], UB] = s.u[with_flow]
        L.state[due[with_flow], VB] = s.v[with_flow]
        if self.physics.rotation:
            L.state[due[with_flow], OMEGA] = s.omega[with_flow]
        self._set_active(np.flatnonzero(L.status == FLOATING))
        return True

    def resume_from(self, t, index, columns, counts=None):
        """Restart from a stopped run's last records (``trajectory.last_states``).

        The logs take their recorded state and status; logs never recorded are still waiting;
        time restarts at ``t`` (an output time, where a sub-step always ends), so the resumed
        run continues exactly as the uninterrupted one would have.  ``counts``: the run's
        statistics and its contact model's up to ``t`` (``trajectory.kept_counts``),
        which the resumed run adds to, and the pairs in contact at ``t`` (a contact still
        pushing after the restart is not recorded as a new hit).
        """
        if counts is not None:
            self.stats.update(counts.get("tracker") or {})
            if self.contact is not None and counts.get("contact"):
                self.contact.stats.update(counts["contact"])
            if self.contact is not None and counts.get("contact_active") is not None:
                # the pairs in contact at t: a contact that goes on pushing is not a new hit
                self.contact._active = np.asarray(counts["contact_active"], np.int64)
        L = self.logs
        if self.physics.waterlogging != "off":
            if "log_density" not in columns:
                raise ScenarioError("physics.waterlogging", self.physics.waterlogging,
                                    "this run cannot be resumed: its trajectory file has no "
                                    "log_density records; rerun it from the start")
            self._set_densities(index, columns["log_density"])
        for k, name in enumerate(STATE_NAMES):
            L.state[index, k] = columns[name]
        L.status[index] = columns["status"]
        self._recorded_left[index[columns["status"] == LEFT]] = True
        self.t = float(t)
        self._resumed = True
        self._stops = self._landing_times(self._t_start)
        self._set_active(np.flatnonzero(L.status == FLOATING))

    # ----------------------------------------------------------------- landing times
    def _landing_times(self, t_origin=None):
        """Sub-step ends: hydrodynamic steps, output times, releases, the end (after self.t).

        Output times are counted from ``t_origin`` (the run's start, also when resuming).
        """
        t0, t1 = (self.t if t_origin is None else t_origin), self.t_end
        hydro = np.asarray(self.flow.times, float)
        self._snapshots = hydro
        self._steady = hydro.size <= 1
        check_landings(t0, t1, self.output_interval, self.hydro_step if self._steady else None)
        if hydro.size <= 1:
            n = int(np.ceil((t1 - t0) / self.hydro_step - 1e-9))
            hydro = t0 + self.hydro_step * np.arange(n + 1)
        elif not self.step_options.land_on_snapshots:
            hydro = hydro[:0]  # each stage samples the pair of snapshots around its own time
        n_out = int(np.floor((t1 - t0) / self.output_interval + 1e-9))
        outs = t0 + self.output_interval * np.arange(n_out + 1)
        self._outputs = np.unique(np.append(outs, t1))
        rel = self.logs.release_time
        stops = np.concatenate([hydro, self._outputs, rel, [t1]])
        stops = np.unique(stops[(stops > self.t) & (stops <= t1)])
        # merge stops closer than round-off
        keep = np.ones(stops.size, bool)
        keep[1:] = np.diff(stops) > self.time_tol
        return stops[keep]

    # ----------------------------------------------------------------- recording
    def _record(self):
        if self.writer is None:
            return
        if self.act.size:
            self._scatter()
        if self.contact is not None:
            # the hits of the interval that ends here go to the writer before its record: a
            # flush that the record triggers writes both together (a kill loses neither alone)
            self.writer.hits(self.contact.drain_hits())
        keep = getattr(self.writer, "keep_counts", None)
        if keep is not None:  # the counts so far, flushed with the record (a resume adds to them)
            self.stats["wall_seconds"] = self._wall_base + _time.perf_counter() - self._wall0
            C = self.contact
            keep(self.t, self.stats, None if C is None else C.stats,
                 None if C is None else getattr(C, "_active", None))
        L = self.logs
        idx = np.flatnonzero((L.status != WAITING) & ~self._recorded_left)
        if idx.size == 0:
            return
        s = self.flow.sample(L.state[idx, X], L.state[idx, Y], self.t, face=L.face[idx])
        cols = {name: L.state[idx, k] for k, name in enumerate(STATE_NAMES)}
        cols.update(status=L.status[idx], water_depth=s.h, flow_u=s.u, flow_v=s.v)
        if self.physics.waterlogging != "off":
            cols["log_density"] = L.density[idx]
        self.writer.record(self.t, idx, cols)
        self._recorded_left[idx[L.status[idx] == LEFT]] = True

    # ----------------------------------------------------------------- the loop
    def _global_steps(self, stop, bar, pool=None, swept=None):
        """Algorithm 1 up to ``stop``: all active logs share each sub-step.

        ``pool``: only these logs (a contact island under per-log clocks, ``driftlog.clocks``):
        no releases, waterlogging or idle checks (the synchronisation time does them);
        ``swept`` (len(pool), 4) grows to the bounding box of their centres.
        """
        so = self.step_options
        self._stop = stop
        while self.t < stop:
            t_before = self.t
            dt = min(self.max_step(), stop - self.t)
            if self.act.size == 0:
                dt = stop - self.t
            if dt < so.min_step and stop - self.t > so.min_step:
                raise StepTooSmallError(
                    f"sub-step {dt:.3g} s below integrator.min_step = {so.min_step} s at "
                    f"t = {self.t} s; a log spins or moves too fast for its length "
                    "(check the flow at the logs) or lower integrator.min_step")
            if self.contact is not None and self.act.size:
                self.contact.substep(self, dt)
            else:
                self._settle_next = True
                self.advance(dt, have_d0=True)
            settled = self._settled_now()
            if (settled[4] if settled is not None else not np.all(np.isfinite(self.state))):
                bad = self.ids[~np.isfinite(self.state).all(axis=1)]
                raise IntegrationError(
                    f"the {self.integrator.name} integration diverged at "
                    f"t = {self.t:.6g} s "
                    f"(logs {bad[:5].tolist()}): the step is too long for the drag "
                    "relaxation time; use integrator.method = 'exponential' or set "
                    "integrator.drag_fraction > 0")
            if stop - self.t <= self.time_tol:
                self.t = stop  # land exactly
            taken = self.t - t_before
            if pool is None:
                self._soak(taken)
            st = self.stats
            st["substeps"] += 1
            st["min_dt"] = min(st["min_dt"], taken)
            st["max_dt"] = max(st["max_dt"], taken)
            if swept is not None and self.act.size:
                k = np.searchsorted(pool, self.act)
                x, y = self.state[:, X], self.state[:, Y]
                swept[k, 0] = np.minimum(swept[k, 0], x)
                swept[k, 1] = np.minimum(swept[k, 1], y)
                swept[k, 2] = np.maximum(swept[k, 2], x)
                swept[k, 3] = np.maximum(swept[k, 3], y)
            if pool is None:
                self._release()
            self._update_status(pool)
            if bar is not None:
                bar.update(taken)

    def run(self):
        """Run to t_end; returns the Logs (their final state)."""
        wall = self._wall0 = _time.perf_counter()
        self._wall_base = self.stats["wall_seconds"]  # a resumed run's before it stopped
        bar = None
        if self.progress:
            from tqdm import tqdm

            bar = tqdm(total=self.t_end - self.t, unit="s", unit_scale=True, desc="tracking",
                       mininterval=0.5,
                       bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]")
        self._first_check = True
        self._release()
        self._update_status()
        if not self._resumed:
            self._record()
        out_i = int(np.searchsorted(self._outputs, self.t + self.time_tol))
        per_log = self.clock == "per_log"
        try:
            for stop in self._stops:
                if per_log and self.act.size and self.t < stop:
                    per_log_interval(self, stop, bar)
                self._global_steps(stop, bar)
                while (out_i < self._outputs.size
                       and self._outputs[out_i] <= self.t + self.time_tol):
                    self._record()
                    out_i += 1
        finally:
            if self.act.size:
                self._scatter()
                self._fill_holes()
            if bar is not None:
                bar.close()
            self.stats["wall_seconds"] = self._wall_base + _time.perf_counter() - wall
        return self.logs


# --------------------------------------------------------------------- the scenario section
def _check_time(t, prefix, scen):
    if t["end"] is not None and not t["end"] > t["start"]:
        raise ScenarioError(f"{prefix}.end", t["end"],
                            f"must be after time.start = {t['start']} s (time span reversed)")


TIME_SECTION = Section("time", [
    Key("start", "float", 0.0, "start of the debris run", "s"),
    Key("end", "float", None, "end of the debris run (default: end of the flow)", "s"),
    Key("output_interval", "float", 1.0, "interval between trajectory records", "s", min=0.0,
        exclusive_min=True),
    Key("hydro_step", "float", 1.0, "hydrodynamic step for flows without snapshots (analytic)",
        "s", min=0.0, exclusive_min=True),
], doc="the time span", check=_check_time)
