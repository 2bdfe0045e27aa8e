"""Per-log clocks (``[integrator] clock = "per_log"``, docs/model.md section 11.1).

Algorithm 1 of the reference paper (docs/model.md section 11) advances all floating logs
together with the smallest sub-step any of them needs (``clock = "global"``).  With
``clock = "per_log"`` the logs meet only at the synchronisation times (hydrodynamic snapshots,
output times, releases, the end); between two of them each log takes its own sub-steps, from
its own bounds (eq. (70)), in one kernel over all logs (``driftlog.clock_kernel``).  Each
log's sub-steps are exactly the ones the global clock would give it alone: one log has the
same trajectory, bit for bit, under both clocks.

With contacts, the interval is cut into contact windows; in each, the logs whose swept boxes
(in the frame of their mean drift) may touch each other or an obstacle form contact islands
(connected components of the overlap graph); every island runs the event-driven contact steps
among its own logs, all islands in one kernel (``driftlog.island_kernel``), so an island's next
contact ends only its own step (``contact_advance``, ``contact_window``).  Moreau-Jean, the
dichotomy and the fcl backend run the islands through the Python contact model
(``python_islands``).
"""

from __future__ import annotations

import numpy as np

from driftlog.clock_kernel import (
    CLOCKS,
    DIVERGED,
    EULER,
    RK4,
    STOPPED,
    free_summary,
    idle_lift,
    per_log_mesh_advance,
)
from driftlog.columns import VELOCITY
from driftlog.contact.islands import island_labels
from driftlog.logs import FLOATING

__all__ = ["CLOCKS", "per_log_interval", "free_advance", "relift_advance", "contact_advance",
           "contact_window"]


# --------------------------------------------------------------------- the tracker's side
def per_log_interval(tr, stop, bar=None):
    """Advance the tracker ``tr``'s floating logs to ``stop`` on their own clocks.

    Without contacts every log takes its own sub-steps (``free_advance``); with contacts the
    logs whose swept boxes may touch each other or an obstacle share the global clock's
    contact steps (``contact_advance``).  Then, at ``stop``: waterlogging over the interval,
    releases, statuses (as the global clock does after each sub-step).
    """
    t0 = tr.t
    if tr.contact is None:
        tr._per_log_free(stop)
    else:
        contact_advance(tr, stop)
    tr.t = stop
    tr._soak(stop - t0)
    tr.stats["substeps"] += 1
    tr._release()
    tr._update_status()
    if bar is not None:
        bar.update(stop - t0)


def free_advance(tr, stop, frame=(0.0, 0.0), pairs=None):
    """Every floating log of ``tr`` to ``stop`` with its own sub-steps (one kernel).

    Returns each log's swept box (n, 4: xmin, ymin, xmax, ymax of its axis ends at the start
    and its sub-step ends, in a frame moving at ``frame`` (m/s) from the start).  A log
    whose status changes on the way stops there; the tracker then
    classifies it from the flow sampled where it stopped (``F``, as the global clock would).
    """
    return _advance_rows(tr, stop, None, None, False, frame, pairs)[0]


def _pairs_of(tr, stop):
    """The node-value snapshot pairs of the interval from ``tr.t`` to ``stop``.

    (vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split): stage times before t_split use the
    first pair, the others the second (an interval holds no snapshot time inside).  Taken
    once per interval: the flow keeps one pair, and asking for the two in turn loads them
    again from the file each time.
    """
    kern = tr._kernel
    vals_c, T0c, gap_c, t_split = kern.node_pair(tr.t)
    if stop >= t_split:
        vals_n, T0n, gap_n, _ = kern.node_pair(stop)
    else:
        vals_n, T0n, gap_n = vals_c, T0c, gap_c
    return vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split


def _advance_rows(tr, stop, rows, t_from, restart, frame=(0.0, 0.0), pairs=None):
    """``per_log_mesh_advance`` on the compact rows ``rows`` (None: all) from ``t_from``.

    ``t_from``: each row's start time (None: ``tr.t``); ``restart``: the rows start from rest
    there (lifted off the bed); ``pairs``: ``_pairs_of(tr, stop)`` when already taken.
    Returns (box, t_log, code, dt_min) of those rows; the rows of the tracker's compact arrays
    are updated in place.
    """
    from driftlog.columns import P_HSTAR
    from driftlog.stepping import IntegrationError, StepTooSmallError

    so, kern = tr.step_options, tr._kernel
    t0 = tr.t
    if rows is None and not (tr._d0_valid or tr._d0_window):
        tr._rhs(tr.state, tr.t, tr.D0, tr.lin0)
    vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split = pairs or _pairs_of(tr, stop)
    friction = tr.physics.motion != "floating"
    if rows is None:
        S, D0, lin0, face, F, flag = tr.state, tr.D0, tr.lin0, tr.face, tr.F, tr.flag
        P, length, ids = tr.P, np.ascontiguousarray(tr.length), tr.ids
    else:
        S, D0, lin0 = tr.state[rows], tr.D0[rows], tr.lin0[rows]
        face, F, flag = tr.face[rows], tr.F[rows], tr.flag[rows]
        P, length, ids = tr.P[rows], np.ascontiguousarray(tr.length[rows]), tr.ids[rows]
    n = S.shape[0]
    thr = (P[:, P_HSTAR].copy() if friction
           else np.ascontiguousarray(tr.logs.float_depth[tr.act if rows is None
                                                         else tr.act[rows]]))
    t_from = np.full(n, t0) if t_from is None else np.ascontiguousarray(t_from, dtype=float)
    t_log, dt_min, dt_max = np.empty(n), np.empty(n), np.empty(n)
    nsteps, code = np.empty(n, np.int64), np.empty(n, np.int8)
    box = np.empty((n, 4))
    tracer = tr.physics.level == "tracer"
    explicit = not tr.integrator.stiff_stable and not tracer
    method = RK4 if tr.integrator.name == "rk4" else EULER
    per_log_mesh_advance(
        S, D0, lin0, face, F, flag, P, tr.opt, t_from, t0, stop,
        tr.time_tol, method, length, so.length_fraction,
        so.angle_step, so.drag_fraction, explicit, so.max_step if so.max_step else np.inf,
        so.min_step, tracer, bool(tr.physics.rotation), thr, friction, vals_c, T0c, gap_c,
        vals_n, T0n, gap_n, t_split, kern.dry_depth, kern.recovered, kern.locator,
        float(frame[0]), float(frame[1]), bool(restart), t_log, nsteps, dt_min, dt_max, box,
        code)
    if rows is None:
        tr._F_valid = tr._d0_valid = True
    else:
        tr.state[rows], tr.D0[rows], tr.lin0[rows] = S, D0, lin0
        tr.face[rows], tr.F[rows], tr.flag[rows] = face, F, flag
    # the sums, extremes and first failures in one pass (``free_summary``: the same numbers
    # as the numpy reductions, fewer calls per solver step in a coupled run)
    own = np.empty(n)
    k, lo, hi, small, diverged = free_summary(nsteps, dt_min, dt_max, code, own)
    st = tr.stats
    st["log_substeps"] = st.get("log_substeps", 0) + k
    st["rhs_evaluations"] += k * (4 if method == RK4 else 1)
    if k:
        st["min_dt"] = min(st["min_dt"], float(lo))
        st["max_dt"] = max(st["max_dt"], float(hi))
    if small >= 0:
        i = small
        raise StepTooSmallError(
            f"sub-step below integrator.min_step = {so.min_step} s for log {int(ids[i])} "
            f"at t = {t_log[i]} s; a log spins or moves too fast for its length (check the "
            "flow at the logs) or lower integrator.min_step")
    if diverged >= 0:
        bad = np.flatnonzero(code == DIVERGED)
        raise IntegrationError(
            f"the {tr.integrator.name} integration diverged at t = {t_log[bad[0]]:.6g} s "
            f"(logs {ids[bad[:5]].tolist()}): the step is too long for the drag "
            "relaxation time; use integrator.method = 'exponential' or set "
            "integrator.drag_fraction > 0")
    return box, t_log, code, own


# a log that keeps landing and lifting within one interval is followed this many times; after
# that it waits for the synchronisation time (as before the fix of issue 15's idle checks)
RELIFT_ROUNDS = 16


def _lift_times(tr, S, face, idx, t_from, stop, dt_check, pairs):
    """``clock_kernel.idle_lift`` for the logs ``idx`` (full arrays) at states S from t_from."""
    from driftlog.columns import P_HSTAR

    kern = tr._kernel
    vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split = pairs
    friction = tr.physics.motion != "floating"
    P = np.ascontiguousarray(tr.P_all[idx])
    thr = (P[:, P_HSTAR].copy() if friction
           else np.ascontiguousarray(tr.logs.float_depth[idx]))
    t_lift = np.empty(idx.size)
    idle_lift(np.ascontiguousarray(S), np.ascontiguousarray(face, dtype=np.int64), P, tr.opt,
              thr, friction, np.ascontiguousarray(t_from, dtype=float), float(stop),
              float(dt_check), tr.time_tol, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split,
              kern.dry_depth, kern.recovered, kern.locator, t_lift)
    return t_lift


def relift_advance(tr, stop, gain=None):
    """Per-log clocks without contacts: the floating logs, and the idle logs the flow lifts.

    The floating logs run to ``stop`` on their own clocks (``free_advance``).  An idle log
    (resting or stranded at the interval's start, or a floating log that stopped on the way)
    is checked for refloating over the whole interval, not only at ``stop``
    (``clock_kernel.idle_lift``: the first time the flow at its place floats it); one that
    lifts at t_l starts from rest there and runs on its own clock from t_l to ``stop``, and
    may stop and lift again (up to ``RELIFT_ROUNDS`` times).  So an idle log lifts at the
    same time as under the global clock, within that clock's sub-step (docs/model.md 11.1).

    ``gain(rows, u0)``, if given, is called after each run of free sub-steps with the compact
    rows that ran (None: all) and their velocities (n, 2) before it (None: from rest, a lifted
    log): a coupled run accounts there what the water gave each log (``driftlog.coupling``),
    one log's free path from its start or lift to its end or stop at a time.
    """
    from driftlog.columns import UB, VB
    from driftlog.logs import RESTING, STRANDED

    L = tr.logs
    t0 = tr.t
    pairs = _pairs_of(tr, stop)
    u0 = tr.state[:, [UB, VB]] if gain is not None else None
    _, t_log, code, dtm = _advance_rows(tr, stop, None, None, False, pairs=pairs)
    if gain is not None:
        gain(None, u0)
    # the finest check interval of the global clock: the floating logs' shortest own step
    dt_check = min(float(dtm.min(initial=np.inf)), stop - t0)
    idle = np.flatnonzero((L.status == RESTING) | (L.status == STRANDED))
    if idle.size:
        t_lift = _lift_times(tr, L.state[idle], L.face[idle], idle, np.full(idle.size, t0),
                             stop, dt_check, pairs)
        up = np.flatnonzero(np.isfinite(t_lift))
        if up.size:
            new, t_new = idle[up], t_lift[up]
            old = tr.act
            kept = (tr.F.copy(), tr.flag.copy(), tr.D0.copy(), tr.lin0.copy(), t_log, code)
            tr._scatter()
            L.status[new] = FLOATING
            L.state[new, VELOCITY] = 0.0  # a lifted log starts from rest
            tr._d0_valid = tr._F_valid = False
            tr._set_active(_union(old, new))
            pos = np.searchsorted(tr.act, old)
            tr.F[pos], tr.flag[pos], tr.D0[pos], tr.lin0[pos] = kept[:4]
            t_log = np.full(tr.act.size, stop)
            code = np.zeros(tr.act.size, np.int8)
            t_log[pos], code[pos] = kept[4], kept[5]
            rows = np.searchsorted(tr.act, new)
            _, t_log[rows], code[rows], _ = _advance_rows(tr, stop, rows, t_new, True,
                                                          pairs=pairs)
            tr._F_valid = tr._d0_valid = True
            if gain is not None:
                gain(rows, None)
    for _ in range(RELIFT_ROUNDS):
        # floating logs that stopped on the way (landed, stranded): lifted again before stop?
        rows = np.flatnonzero((code == STOPPED) & (t_log < stop - tr.time_tol))
        if rows.size == 0:
            break
        S = tr.state[rows].copy()
        S[:, VELOCITY] = 0.0
        t_lift = _lift_times(tr, S, tr.face[rows], tr.act[rows], t_log[rows], stop, dt_check,
                             pairs)
        up = np.flatnonzero(np.isfinite(t_lift))
        code[rows] = 0  # checked: idle up to stop unless lifted
        if up.size == 0:
            break
        rows = rows[up]
        _, t_log[rows], code[rows], _ = _advance_rows(tr, stop, rows, t_lift[up], True,
                                                      pairs=pairs)
        if gain is not None:
            gain(rows, None)
    return t_log


# --------------------------------------------------------------------- contact windows
# A contact window lasts WINDOW times the logs' typical time to move their own length (the
# median over the floating logs of L / |U|): long enough for many own sub-steps, short enough
# that the boxes the logs sweep in it (in the frame of their mean drift) stay apart, so that
# the contact islands stay small.
WINDOW = 0.5
HIT_BUFFER = 4096
# Moreau-Jean islands on several threads (``moreau_kernel.moreau_islands_parallel``, the same
# results bit for bit) from this many logs in the contact set on, as the per-log kernels
# (``driftlog._numba.PARALLEL_MIN``), when numba has more than one thread and there are at
# least two islands; None: so, True / False: always / never (tests)
ISLANDS_PARALLEL = None
# moreau_islands_parallel's room per island in its own buffers, scaled (tests: 0 runs every
# island with a hit, a pair in touch or an obstacle impulse again, alone)
ISLAND_ROOM = 1.0


def contact_advance(tr, stop, max_tries=3):
    """Per-log clocks with contacts: free logs on their own clocks, each island on its own.

    The interval to ``stop`` is cut into contact windows (``WINDOW``); in each
    (``contact_window``) every floating log first runs free on its own clock, then the logs
    whose swept boxes may touch each other or an obstacle run again from the window's start
    as contact islands, all islands in one kernel (``driftlog.island_kernel``,
    ``driftlog.moreau_kernel``), each on its own clock.  The floating logs meet at the window
    ends (and their statuses are updated there, as the global clock does after each
    sub-step).

    Idle logs (resting, stranded) are not sampled at every window end: once per interval
    (``clock_kernel.idle_lift``) each finds the first time the flow at its place floats it,
    and a log that stops floating at a window end finds its own from there; a log lifts
    (from rest) at the first window end at or after that time, or, when no log floats, the
    interval jumps to it (docs/model.md 11.1).
    """
    from driftlog.logs import RESTING, STRANDED

    C, L = tr.contact, tr.logs
    kernel = C.backend.name == "native" and (
        C.method == "moreau" or (C.method == "event" and C.time_of_impact == "conservative"))
    tol = tr.time_tol
    pairs = _pairs_of(tr, stop)
    # friction: checks every contact window (its length at the start) or the interval
    dt_check = (_window_end(tr, stop) - tr.t) if tr.act.size else stop - tr.t
    idle = np.flatnonzero((L.status == RESTING) | (L.status == STRANDED))
    pend, t_pend = _pending_lifts(tr, idle, stop, dt_check, pairs)
    while stop - tr.t > tol:
        if tr.act.size:
            before = tr.act
            end = _window_end(tr, stop)
            if kernel:
                contact_window(tr, end, max_tries)
            else:
                python_islands(tr, end, max_tries)
                tr.stats["windows"] = tr.stats.get("windows", 0) + 1
            tr._update_status(idle=False)
            st = L.status[before]
            stopped = before[(st == RESTING) | (st == STRANDED)]
            if stopped.size:  # landed in this window: when does the flow lift them again?
                p2, t2 = _pending_lifts(tr, stopped, stop, dt_check, pairs)
                pend, t_pend = np.concatenate([pend, p2]), np.concatenate([t_pend, t2])
        elif pend.size:  # nobody floats: on to the next lift
            tr.t = min(float(t_pend.min()), stop)
            if stop - tr.t <= tol:
                tr.t = stop
        else:
            break
        due = t_pend <= tr.t + tol
        if due.any():
            new = pend[due]
            pend, t_pend = pend[~due], t_pend[~due]
            if tr.act.size:
                tr._scatter()
            L.status[new] = FLOATING
            L.state[new, VELOCITY] = 0.0  # a lifted log starts from rest
            tr._d0_valid = tr._F_valid = False
            tr._set_active(_union(tr.act, new))
            tr.stats["lifted"] = tr.stats.get("lifted", 0) + int(new.size)
    tr.t = stop


def _pending_lifts(tr, idx, stop, dt_check, pairs):
    """The idle logs ``idx`` the flow lifts before ``stop``, and when (``idle_lift``)."""
    if idx.size == 0:
        return np.empty(0, np.int64), np.empty(0)
    L = tr.logs
    t_lift = _lift_times(tr, L.state[idx], L.face[idx], idx, np.full(idx.size, tr.t), stop,
                         dt_check, pairs)
    up = np.isfinite(t_lift)
    return idx[up], t_lift[up]


def _window_end(tr, stop):
    """The next contact window's end: WINDOW median L / |U| ahead (the last one reaches stop).

    |U|: a log's own speed (translation and turning), or the flow's at its centre where that
    is faster: logs lifted from rest start moving at once (before 2026-12-02 their own speed
    alone, so a window that started with every log at rest lasted to ``stop``, up to a whole
    interval, and idle logs lifted only at its end).
    """
    from driftlog.columns import U, V

    tr._sample_current()
    sp = np.maximum(np.hypot(tr.state[:, 3], tr.state[:, 4]) + np.abs(tr.state[:, 5]) * 0.5
                    * tr.length, np.hypot(tr.F[:, U], tr.F[:, V]))
    moving = sp > 0.0
    if not moving.any():
        return stop
    w = WINDOW * float(np.median(tr.length[moving] / sp[moving]))
    return stop if tr.t + 1.5 * w >= stop else tr.t + w


def _reach(tr):
    """How far a log's surface reaches beyond its swept axis box (radius, path bulge, tol)."""
    so = tr.step_options
    L = tr.length
    tol = tr.contact.tolerance * float(tr.radius.min())
    return (1.25 * tr.radius + 0.1 * so.length_fraction * L
            + 0.5 * L * (1.0 - np.cos(0.5 * min(so.angle_step, np.pi))) + tol)


def _pairs(box, reach):
    """Log pairs whose swept boxes grown by ``reach`` overlap (``broadphase.sweep_pairs``).

    In no particular order: the windows use them as a set (the contact set, the islands'
    labels by their smallest log, the closure's new pairs).
    """
    from driftlog.contact.broadphase import sweep_pairs

    cx = 0.5 * (box[:, 0] + box[:, 2])
    cy = 0.5 * (box[:, 1] + box[:, 3])
    return sweep_pairs(cx, cy, 0.5 * (box[:, 2] - box[:, 0]) + reach,
                       0.5 * (box[:, 3] - box[:, 1]) + reach)


def _obstacle_pairs(tr, box, reach, frame, span, rows=None):
    """(log, capsule) pairs whose swept boxes (absolute frame) meet an obstacle's box.

    ``rows``: only these logs' boxes are queried (the closure's: the other logs' boxes are
    those of the window's first query, which met no obstacle); the grid's cell is chosen
    from every box all the same, so that both queries keep one grid.
    """
    caps = tr.contact.capsules
    if caps.shape[0] == 0 or box.shape[0] == 0:
        return np.empty((0, 2), np.int64)
    # the frame's drift over the window, added back: the boxes in the ground's frame
    dx, dy = frame[0] * span, frame[1] * span
    x0, x1 = box[:, 0] + min(dx, 0.0), box[:, 2] + max(dx, 0.0)
    y0, y1 = box[:, 1] + min(dy, 0.0), box[:, 3] + max(dy, 0.0)
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    ex, ey = 0.5 * (x1 - x0) + reach, 0.5 * (y1 - y0) + reach
    grid = _obstacle_grid(tr, 2.0 * max(float(ex.max()), float(ey.max())))
    if rows is None:
        return grid.query(cx, cy, ex, ey)
    lo = grid.query(cx[rows], cy[rows], ex[rows], ey[rows])
    lo[:, 0] = rows[lo[:, 0]]
    return lo


def _union(a, b):
    """``np.union1d`` of two int arrays: sorted, each value once.

    The compact rows (``tr.act``) and the logs joining them are each sorted: their
    concatenation is two runs, which the stable sort (timsort) merges in linear time
    (``np.union1d`` hashes, then sorts).
    """
    c = np.concatenate([np.asarray(a, np.int64), np.asarray(b, np.int64)])
    c.sort(kind="stable")
    if c.size < 2:
        return c
    keep = np.empty(c.size, bool)
    keep[0] = True
    np.not_equal(c[1:], c[:-1], out=keep[1:])
    return c[keep]


def _csr(labels, pool, lo):
    """Islands of the pool logs as CSR (members, start) and their obstacle capsules."""
    order = pool[np.argsort(labels[pool], kind="stable")]
    lab = labels[order]
    cuts = np.flatnonzero(np.diff(lab)) + 1
    start = np.concatenate([[0], cuts, [order.size]]).astype(np.int64)
    q_of = np.full(labels.size, -1, np.int64)
    q_of[order] = np.repeat(np.arange(start.size - 1), np.diff(start))
    if lo.shape[0]:
        q = q_of[lo[:, 0]]
        keep = q >= 0
        qc = np.unique(np.column_stack([q[keep], lo[keep, 1]]), axis=0)
        ocaps = np.ascontiguousarray(qc[:, 1], dtype=np.int64)
        ostart = np.searchsorted(qc[:, 0], np.arange(start.size)).astype(np.int64)
    else:
        ocaps = np.empty(0, np.int64)
        ostart = np.zeros(start.size, np.int64)
    return order.astype(np.int64), start, ocaps, ostart


def contact_window(tr, stop, max_tries=3):
    """One contact window of ``contact_advance``: free logs, then the islands (one kernel).

    1. Every floating log runs free to ``stop`` (``free_advance``): the box its axis swept, in
       the frame of the logs' mean velocity.
    2. Logs whose boxes (grown by the radius, the path's bulge between sub-step ends and the
       tolerance) overlap another log's, or an obstacle's, are the contact set; the connected
       components of the overlap graph are its islands.  The others keep their free motion.
    3. Every island restarts from the window's start and runs the contact steps among its own
       logs, on its own clock, all islands in one kernel: event-driven
       (``island_kernel.island_advance``: impulses, conservative advancement, rejected
       steps) or Moreau-Jean (``moreau_kernel.moreau_islands``; on several threads for large
       contact sets: ``moreau_islands_parallel``, ``ISLANDS_PARALLEL``), as ``ContactModel``;
       its next contact ends only its step.  ``ContactModel.island_kernel = False`` runs the
       same islands through the Python contact model instead, one after another
       (``_reference_islands``: the reference the kernels are tested against).
    4. Closure: if an island's actual sweep reaches a free log's box or another island's, those
       join and the window is computed again; after ``max_tries``, the whole contact set and
       the logs it reaches are one island.
    """
    import driftlog.island_kernel as ik
    import driftlog.moreau_kernel as mk
    from driftlog.contact.model import ContactJamError, rotates
    from driftlog.stepping import IntegrationError, StepTooSmallError

    C, so, kern = tr.contact, tr.step_options, tr._kernel
    moreau = C.method == "moreau"
    in_kernel = getattr(C, "island_kernel", True)
    t0 = tr.t
    tr._sample_current()
    n = tr.act.size
    S0, face0, F0, flag0 = tr.state.copy(), tr.face.copy(), tr.F.copy(), tr.flag.copy()
    frame = (float(S0[:, 3].mean()), float(S0[:, 4].mean())) if n else (0.0, 0.0)
    pairs = _pairs_of(tr, stop)
    box = free_advance(tr, stop, frame, pairs)
    E = (tr.state.copy(), tr.face.copy(), tr.F.copy(), tr.flag.copy())
    free_d0 = (tr.D0, tr.lin0)  # the free logs' first stage at their ends (``_d0_window``)
    reach = _reach(tr)
    span = stop - t0
    edges = _pairs(box, reach)
    lo = _obstacle_pairs(tr, box, reach, frame, span)
    pool_mask = np.zeros(n, bool)
    pool_mask[edges.ravel()] = True
    pool_mask[lo[:, 0]] = True
    if not pool_mask.any():  # nobody near anybody: the free motion stands
        tr.t = stop
        tr._scatter()
        return
    # what the islands need of the flow and the model
    vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split = pairs
    friction = tr.physics.motion != "floating"
    from driftlog.columns import P_HSTAR

    thr = (tr.P[:, P_HSTAR].copy() if friction
           else np.ascontiguousarray(tr.logs.float_depth[tr.act]))
    caps = np.ascontiguousarray(C.capsules, dtype=float)
    owner = np.ascontiguousarray(C.owner, dtype=np.int64)
    active_in = np.sort(np.asarray(C._active if isinstance(C._active, np.ndarray)
                                   else np.empty(0), dtype=np.int64))
    length = np.ascontiguousarray(tr.length, dtype=float)
    radius = np.ascontiguousarray(tr.radius, dtype=float)
    mass = np.ascontiguousarray(tr.mass, dtype=float)
    # rotation off: an infinite inertia, no contact turns a log (ContactModel._inverse_masses)
    inertia = (np.ascontiguousarray(tr.inertia, dtype=float) if rotates(tr)
               else np.full(tr.inertia.shape, np.inf))
    ids = np.ascontiguousarray(tr.ids, dtype=np.int64)
    method = 1 if tr.integrator.name == "rk4" else 0
    tracer = tr.physics.level == "tracer"
    explicit = not tr.integrator.stiff_stable and not tracer
    cap_hits = HIT_BUFFER
    act_room = 8
    one_pool = False
    kept = (len(C._hits), C.obstacle_impulse.copy(), C.ground_impulse.copy())
    for attempt in range(max_tries + 1):
        labels = (np.where(pool_mask, 0, np.arange(1, n + 1)) if one_pool
                  else island_labels(n, np.ascontiguousarray(edges[:, 0]),
                                     np.ascontiguousarray(edges[:, 1]))[0])
        pool = np.flatnonzero(pool_mask)
        members, start, ocaps, ostart = _csr(labels, pool, lo)
        while True:
            S = np.where(pool_mask[:, None], S0, E[0])
            face = np.where(pool_mask, face0, E[1])
            F = np.where(pool_mask[:, None], F0, E[2])
            flag = np.where(pool_mask, flag0, E[3]).astype(np.int8)
            D0, lin0 = np.empty_like(tr.D0), np.empty_like(tr.lin0)
            sw = box.copy()
            ends = _axis_box(S0[pool], tr.length[pool])
            sw[pool] = ends
            obst = np.zeros((C.n_owners, 2))  # per obstacle, then per grounded log's row
            hits = [np.empty(cap_hits) for _ in range(6)]
            hits[1], hits[2] = np.empty(cap_hits, np.int64), np.empty(cap_hits, np.int64)
            nhit = np.zeros(1, np.int64)
            active_out = np.empty(max(16, act_room * pool.size + active_in.size), np.int64)
            nactive = np.zeros(1, np.int64)
            stats = np.zeros(mk.NSTAT if moreau else ik.NSTAT, np.int64)
            dt_lim = np.array([np.inf, 0.0, np.inf])
            code = np.zeros(start.size - 1, np.int64)
            t_code = np.zeros(start.size - 1)
            head = (S, F, flag, face, D0, lin0, tr.P, tr.opt, length, radius, mass, inertia, ids,
                    members, start, caps, owner, ocaps, ostart, t0, stop, tr.time_tol, method,
                    so.length_fraction, so.angle_step, so.drag_fraction, explicit,
                    so.max_step if so.max_step else np.inf, so.min_step, tracer,
                    bool(tr.physics.rotation), thr, friction, vals_c, T0c, gap_c, vals_n, T0n,
                    gap_n, t_split, kern.dry_depth, kern.recovered, kern.locator)
            tail = (frame[0], frame[1], sw, obst, hits[0], hits[1], hits[2], hits[3], hits[4],
                    hits[5], nhit, active_out, nactive, stats, dt_lim, code, t_code)
            if not in_kernel:
                _reference_islands(tr, members, start, S, face, F, flag, sw, frame, t0, stop,
                                   active_in, code, t_code, active_out, nactive)
            elif moreau:
                args = (*head, C.tolerance, C.restitution, C.iterations, C.motion_share,
                        bool(C.relative_motion), bool(C.island_stop), C.solver,
                        bool(getattr(C, "grounded", False)), active_in, *tail)
                if _islands_parallel(pool.size, start.size - 1):
                    import numba

                    mk.moreau_islands_parallel(*args, float(ISLAND_ROOM),
                                               numba.get_num_threads())
                else:
                    mk.moreau_islands(*args)
            else:
                ik.island_advance(*head, C.tolerance, C.restitution, C.rest_speed, C.near,
                                  C.max_events, bool(getattr(C, "grounded", False)),
                                  active_in, *tail)
            if not np.any(code == ik.HIT_FULL):
                break
            if not in_kernel:
                del C._hits[kept[0]:]
                C.obstacle_impulse[:], C.ground_impulse[:] = kept[1], kept[2]
            cap_hits *= 4
            act_room *= 4
        for kind, exc in ((ik.TOO_SMALL, StepTooSmallError), (ik.DIVERGED, IntegrationError),
                          (ik.JAM, ContactJamError)):
            bad = np.flatnonzero(code == kind)
            if bad.size:
                q = bad[0]
                logs = ids[members[start[q]:start[q + 1]]][:10].tolist()
                raise exc(_island_message(kind, float(t_code[q]), logs, tr, C))
        # closure: the islands' actual sweeps against the free boxes and each other
        cross = _pairs(sw, reach)
        cross = cross[labels[cross[:, 0]] != labels[cross[:, 1]]]
        lo2 = _obstacle_pairs(tr, sw, reach, frame, span, pool)
        ncap = max(caps.shape[0], 1)
        new_lo = lo2[~np.isin(lo2[:, 0] * ncap + lo2[:, 1], lo[:, 0] * ncap + lo[:, 1])]
        if cross.size == 0 and new_lo.size == 0:
            break
        # a deflected path reaches a free log or another island: compute the window again
        tr.stats["clock_retries"] = tr.stats.get("clock_retries", 0) + 1
        if not in_kernel:  # the Python model's hits and impulses of this try
            del C._hits[kept[0]:]
            C.obstacle_impulse[:], C.ground_impulse[:] = kept[1], kept[2]
        pool_mask[cross.ravel()] = True
        pool_mask[new_lo[:, 0]] = True
        edges = np.vstack([edges, cross])
        lo = np.unique(np.vstack([lo, lo2]), axis=0)
        if attempt + 1 >= max_tries:  # the last try: every floating log in one island
            pool_mask[:] = True
            one_pool = True
    else:
        raise RuntimeError("contact_window: the closure did not settle")  # unreachable
    # the window's result: the logs, the model's hits, impulses, contacts in touch, stats
    tr.state, tr.face, tr.F, tr.flag = S, face, F, flag
    tr.t = stop
    tr._F_valid, tr._d0_valid = True, False
    # the first stage at the window's end, for the next window's free advance, if the compact
    # rows stay as they are (``Tracker._d0_window``, cleared by ``_set_active``): the free
    # logs' is the one their last sub-step left in ``tr.D0`` (``per_log_mesh_advance``
    # evaluates it on the state and flow sample it leaves), the islands' logs get theirs from
    # the state and flow sample the island kernel left (``_first_stage_rows``): what
    # ``_rhs`` computes for every row from the same rows.  ``_d0_valid`` stays False: the
    # paths that keep rows across a change of the set (``_kept_stage``) sample them again.
    # Not after the Python model's islands (``_reference_islands``), which gather each
    # island's rows anew (the compact arrays are new ones).
    if tr.D0 is free_d0[0] and tr.lin0 is free_d0[1]:
        tr._first_stage_rows(np.flatnonzero(pool_mask))
        tr._d0_window = True
    tr._scatter()
    k = int(nhit[0])
    if k:
        other = hits[2][:k].copy()
        fixed = other < 0  # -(owner + 1): an obstacle, or a grounded log (its id)
        other[fixed] = C.other_body(-other[fixed] - 1)
        C._hits.append(dict(time=hits[0][:k].copy(), log_id=hits[1][:k].copy(),
                            other=other, impulse=hits[3][:k].copy(),
                            x=hits[4][:k].copy(), y=hits[5][:k].copy()))
    C.pass_impulse(obst)
    keys = active_out[:int(nactive[0])]
    C._active = np.unique(np.concatenate([keys, active_in[~np.isin(
        active_in // (1 << 32), ids[pool])]]))
    cs, st = C.stats, tr.stats
    if in_kernel and moreau:
        cs["substeps"] += int(stats[mk.ST_STEPS])
        cs["advances"] += int(stats[mk.ST_ADVANCES])
        cs["pgs_iterations"] += int(stats[mk.ST_PGS])
        cs["pgs_max_iterations"] = max(cs["pgs_max_iterations"], int(stats[mk.ST_PGS_MAX]))
        cs["pgs_capped"] += int(stats[mk.ST_CAPPED])
        cs["max_contacts"] = max(cs["max_contacts"], int(stats[mk.ST_MAX_CONTACTS]))
        cs["min_gap"] = min(cs["min_gap"], float(dt_lim[2]))
        if stats[mk.ST_RERUNS]:
            st["island_reruns"] = st.get("island_reruns", 0) + int(stats[mk.ST_RERUNS])
        steps, log_steps = int(stats[mk.ST_STEPS]), int(stats[mk.ST_LOG_STEPS])
    elif in_kernel:
        cs["substeps"] += int(stats[ik.ST_STEPS])
        cs["advances"] += int(stats[ik.ST_ADVANCES])
        cs["rejected"] += int(stats[ik.ST_REJECTED])
        cs["events"] += int(stats[ik.ST_EVENTS])
        cs["separations"] += int(stats[ik.ST_SEPARATIONS])
        cs["max_contacts"] = max(cs["max_contacts"], int(stats[ik.ST_MAX_CONTACTS]))
        steps, log_steps = int(stats[ik.ST_STEPS]), int(stats[ik.ST_LOG_STEPS])
    else:
        steps = log_steps = 0  # counted by _reference_islands
    if in_kernel:
        st["substeps"] += steps
        st["log_substeps"] = st.get("log_substeps", 0) + log_steps
        st["rhs_evaluations"] += log_steps * (4 if method else 1)
        if steps:
            st["min_dt"] = min(st["min_dt"], float(dt_lim[0]))
            st["max_dt"] = max(st["max_dt"], float(dt_lim[1]))
    st["contact_set"] = max(st.get("contact_set", 0), int(pool.size))
    st["islands"] = st.get("islands", 0) + int(start.size - 1)
    st["largest_island"] = max(st.get("largest_island", 0), int(np.diff(start).max()))
    st["windows"] = st.get("windows", 0) + 1


def _islands_parallel(nlogs, nislands):
    """Whether a window's Moreau-Jean islands run on several threads (``ISLANDS_PARALLEL``)."""
    if ISLANDS_PARALLEL is not None:
        return bool(ISLANDS_PARALLEL)
    import numba

    from driftlog._numba import PARALLEL_MIN

    return nlogs >= PARALLEL_MIN and nislands >= 2 and numba.get_num_threads() > 1


def _reference_islands(tr, members, start, S, face, F, flag, sw, frame, t0, stop, active_in,
                       code, t_code, active_out, nactive):
    """The islands of a contact window through the Python contact model, one after another.

    What the island kernels compute (``contact_window``, ``ContactModel.island_kernel =
    False``), with the contact model's own steps: each island from the window's start on its
    own clock (``ContactModel.substep`` on the island's logs alone), its swept boxes ``sw``,
    its end states, flow and statuses' samples written into S, face, F, flag (the compact rows
    of ``tr.act``), the pair keys in contact at the end into ``active_out``; the model's hits
    and obstacle impulses go straight into it.  The tracker is left at ``tr.act``.
    """
    from driftlog.island_kernel import DIVERGED, HIT_FULL, TOO_SMALL

    L, C, so = tr.logs, tr.contact, tr.step_options
    act0 = tr.act.copy()
    status0 = L.status[act0].copy()
    L.state[act0], L.face[act0] = S, face
    fx, fy = frame
    for q in range(start.size - 1):
        g = members[start[q]:start[q + 1]]
        tr.t = t0
        _island_start(C, (0, active_in))
        C._cache = None
        tr._d0_valid = tr._F_valid = False
        tr._set_active(act0[g])
        tr.F[:], tr.flag[:] = F[g], flag[g]
        tr._F_valid = True
        while tr.t < stop and tr.act.size:
            t_before = tr.t
            dt = min(tr.max_step(), stop - tr.t)
            if dt < so.min_step and stop - tr.t > so.min_step:
                code[q], t_code[q] = TOO_SMALL, tr.t
                break
            C.substep(tr, dt)
            if not np.all(np.isfinite(tr.state)):
                code[q], t_code[q] = DIVERGED, tr.t
                break
            if stop - tr.t <= tr.time_tol:
                tr.t = stop
            st = tr.stats
            st["substeps"] += 1
            st["log_substeps"] = st.get("log_substeps", 0) + tr.act.size
            st["min_dt"] = min(st["min_dt"], tr.t - t_before)
            st["max_dt"] = max(st["max_dt"], tr.t - t_before)
            tr._sample_current()
            rows = np.searchsorted(act0, tr.act)
            S[rows], face[rows], F[rows], flag[rows] = tr.state, tr.face, tr.F, tr.flag
            # the axis ends in the frame moving at (fx, fy) from t0
            tau = tr.t - t0
            hx = 0.5 * tr.length * np.cos(tr.state[:, 2])
            hy = 0.5 * tr.length * np.sin(tr.state[:, 2])
            x, y = tr.state[:, 0] - fx * tau, tr.state[:, 1] - fy * tau
            sw[rows, 0] = np.minimum(sw[rows, 0], np.minimum(x - hx, x + hx))
            sw[rows, 1] = np.minimum(sw[rows, 1], np.minimum(y - hy, y + hy))
            sw[rows, 2] = np.maximum(sw[rows, 2], np.maximum(x - hx, x + hx))
            sw[rows, 3] = np.maximum(sw[rows, 3], np.maximum(y - hy, y + hy))
            tr._update_status(act0[g])
        keys = np.unique(np.asarray(C._active, dtype=np.int64))
        k = int(nactive[0])
        if k + keys.size > active_out.size:
            code[q] = HIT_FULL
            break
        active_out[k:k + keys.size] = keys
        nactive[0] = k + keys.size
        if code[q]:
            break
    # statuses are set at the window's end from the samples where each log stopped
    L.status[act0] = status0
    tr.t = t0
    tr._d0_valid = tr._F_valid = False
    tr._set_active(act0)


def _axis_box(S, length):
    """Boxes (xmin, ymin, xmax, ymax) of the logs' axes at states S."""
    hx = 0.5 * length * np.cos(S[:, 2])
    hy = 0.5 * length * np.sin(S[:, 2])
    return np.column_stack([S[:, 0] - np.abs(hx), S[:, 1] - np.abs(hy), S[:, 0] + np.abs(hx),
                            S[:, 1] + np.abs(hy)])


def _island_message(kind, t, logs, tr, C):
    """The error of an island that could not go on (the global clock's messages)."""
    from driftlog.island_kernel import DIVERGED as I_DIV
    from driftlog.island_kernel import JAM

    so = tr.step_options
    if kind == JAM:
        return (f"event-driven contact stalls at t = {t:.6g} s in a contact island: the "
                f"contact sub-step fell below min_step = {so.min_step:.3g} s or exceeded "
                f"contact.max_events = {C.max_events}; logs {logs} are in persistent contact "
                f"(restitution {C.restitution}): a jam, where impulses and contact times "
                "cannot make progress.  Use contact.method = \"moreau\" (time-stepping "
                "contact, stable in jams), or raise contact.max_events")
    if kind == I_DIV:
        return (f"the {tr.integrator.name} integration diverged at t = {t:.6g} s (logs "
                f"{logs[:5]}): the step is too long for the drag relaxation time; use "
                "integrator.method = 'exponential' or set integrator.drag_fraction > 0")
    return (f"sub-step below integrator.min_step = {so.min_step} s for the contact island of "
            f"logs {logs} at t = {t} s; a log spins or moves too fast for its length (check "
            "the flow at the logs) or lower integrator.min_step")


# ------------------------------------------------ the Python islands (Moreau-Jean, fcl)
def _boxes(box, half):
    """Centres and half extents of swept boxes (xmin, ymin, xmax, ymax) grown by ``half``."""
    cx = 0.5 * (box[:, 0] + box[:, 2])
    cy = 0.5 * (box[:, 1] + box[:, 3])
    return cx, cy, 0.5 * (box[:, 2] - box[:, 0]) + half, 0.5 * (box[:, 3] - box[:, 1]) + half


def _obstacle_grid(tr, cell):
    """The contact model's fixed capsules binned for the swept boxes.

    Kept while the cell fits and the grounded logs stay (``ContactModel.set_grounded``).
    """
    from driftlog.contact.broadphase import StaticGrid

    g = getattr(tr, "_clock_grid", None)
    version = tr.contact.ground_version
    if g is None or cell > 2.0 * g[0] or cell < 0.25 * g[0] or g[2] != version:
        g = tr._clock_grid = (cell, StaticGrid(tr.contact.capsules, cell), version)
    return g[1]


def touching(tr, box, half):
    """Logs whose swept boxes overlap another's or an obstacle's, and the log pairs."""
    from driftlog.contact.broadphase import grid_pairs

    cx, cy, ex, ey = _boxes(box, half)
    pairs = grid_pairs(cx, cy, ex, ey)
    hit = np.zeros(box.shape[0], bool)
    hit[pairs.ravel()] = True
    caps = tr.contact.capsules
    if caps.shape[0] and box.shape[0]:
        lo = _obstacle_grid(tr, 2.0 * max(float(ex.max()), float(ey.max()))).query(cx, cy, ex,
                                                                                     ey)
        hit[lo[:, 0]] = True
    return hit, pairs


def python_islands(tr, stop, max_tries=3, together=True):
    """Per-log clocks with contacts, islands through the Python contact model (Moreau-Jean).

    The path of ``contact.method = "moreau"``, the dichotomy time of impact and the fcl
    backend (``contact_advance`` runs the event-driven conservative method in a kernel).

    1. Every floating log runs free to ``stop`` (``free_advance``): its swept box.
    2. Logs whose boxes (grown by half a length, the radius and a margin) overlap another
       log's or an obstacle's are the contact set; the connected components of the overlap
       graph are its islands.  The others keep their free motion.
    3. The islands restart from the window's start and run the global clock's contact
       steps among their own logs (``Tracker._global_steps`` on them): impulses, times of
       impact and the step of the contact model, as before.  ``together`` (default): all the
       islands of the window in one pass, sharing its steps (``contact_advance`` cuts the
       interval into short contact windows, so the islands are few logs and their steps
       many only where logs are close); False: one island after another, each on its own
       clock (a Python pass per island).
    4. Closure: if an island's actual sweep reaches a free log's box or another island's
       sweep, those join (one island) and the interval is computed again; after
       ``max_tries``, the whole contact set and the logs it reaches share one step.
    """
    L, C = tr.logs, tr.contact
    t0 = tr.t
    tr._d0_valid = False  # velocities may have been changed by impulses since
    tr._sample_current()
    act0 = tr.act.copy()
    n = act0.size
    S0, face0 = tr.state.copy(), tr.face.copy()
    status0 = L.status[act0].copy()
    kept = _contact_checkpoint(C)
    box = free_advance(tr, stop)
    tr._scatter()
    E_state, E_face, E_F, E_flag = tr.state.copy(), tr.face.copy(), tr.F.copy(), tr.flag.copy()
    # between sub-step ends a centre's path bulges by at most about a tenth of a step (at
    # most length_fraction L long, turning by less than a radian)
    margin = 0.1 * tr.step_options.length_fraction * tr.length + 0.25 * tr.radius
    half = 0.5 * tr.length + tr.radius + margin
    pool_mask, edges = touching(tr, box, half)
    F_end, flag_end = E_F, E_flag
    one_pool = False
    k = islands = 0
    for attempt in range(max_tries + 1):
        if not pool_mask.any():
            break
        sub = np.flatnonzero(pool_mask)
        L.state[act0] = np.where(pool_mask[:, None], S0, E_state)
        L.face[act0] = np.where(pool_mask, face0, E_face)
        L.status[act0] = status0
        F_end, flag_end = E_F.copy(), E_flag.copy()
        labels = (np.where(pool_mask, 0, np.arange(1, n + 1)) if one_pool
                  else island_labels(n, np.ascontiguousarray(edges[:, 0]),
                                     np.ascontiguousarray(edges[:, 1]))[0])
        order = sub[np.argsort(labels[sub], kind="stable")]
        cuts = np.flatnonzero(np.diff(labels[order])) + 1
        swept = np.column_stack([S0[:, 0], S0[:, 1], S0[:, 0], S0[:, 1]])
        active = []
        # the islands of a contact window share its contact steps: one pass of the contact
        # model over all of them (a Python pass per island costs more than the steps it saves
        # once the islands are many: the 1e4 logs of benchmarks/million_logs.py)
        groups = [sub] if together else np.split(order, cuts)
        for group in groups:
            pool = act0[group]
            tr.t = t0
            tr._d0_valid = tr._F_valid = False
            _island_start(C, kept)
            tr._set_active(pool)
            sw = swept[group]
            tr._global_steps(stop, None, pool=pool, swept=sw)
            swept[group] = sw
            if tr.act.size:
                tr._scatter()
                tr._sample_current()
                pos = np.searchsorted(act0, tr.act)
                F_end[pos], flag_end[pos] = tr.F, tr.flag
            if isinstance(getattr(C, "_active", None), np.ndarray):
                active.append(C._active)
        if active:
            C._active = np.unique(np.concatenate(active))
        k, islands = sub.size, cuts.size + 1
        # closure: actual sweeps of the islands against the free boxes and each other
        _, pairs = touching_pairs(np.where(pool_mask[:, None], swept, box), half)
        cross = pairs[labels[pairs[:, 0]] != labels[pairs[:, 1]]]
        if cross.size == 0:
            break
        # a deflected path reaches a free log or another island: compute the interval again
        tr.stats["clock_retries"] = tr.stats.get("clock_retries", 0) + 1
        _contact_rollback(C, kept)
        pool_mask[cross.ravel()] = True
        edges = np.vstack([edges, cross])
        if attempt + 1 >= max_tries:  # the last try: every floating log in one island
            pool_mask[:] = True
            one_pool = True
    st = tr.stats
    st["contact_set"] = max(st.get("contact_set", 0), k)
    st["islands"] = st.get("islands", 0) + islands
    final = act0[L.status[act0] == FLOATING]
    tr.t = stop
    tr._d0_valid = tr._F_valid = False
    tr._set_active(final)
    pos = np.searchsorted(act0, final)
    tr.F[:], tr.flag[:] = F_end[pos], flag_end[pos]
    tr._F_valid = True


def _island_start(model, kept):
    """Contact model state at the interval's start, for the next island (its own clock)."""
    _, active = kept
    for name, value in (("_active", active), ("_window", None), ("_bracket", None)):
        if hasattr(model, name):
            setattr(model, name, value)


def _contact_checkpoint(model):
    """What a contact run changes in the contact model besides the logs (hits, caches)."""
    hits = getattr(model, "_hits", None)
    active = getattr(model, "_active", None)
    return (len(hits) if hits is not None else 0,
            active.copy() if isinstance(active, np.ndarray) else active)


def _contact_rollback(model, kept):
    """Forget the hits and caches of a contact run computed again (``contact_advance``)."""
    n_hits, active = kept
    if getattr(model, "_hits", None) is not None:
        del model._hits[n_hits:]
    for name, value in (("_active", active), ("_cache", None), ("_window", None),
                        ("_bracket", None)):
        if hasattr(model, name):
            setattr(model, name, value)


def touching_pairs(box, half):
    """``grid_pairs`` of swept boxes grown by ``half`` (for the closure check)."""
    from driftlog.contact.broadphase import grid_pairs

    cx, cy, ex, ey = _boxes(box, half)
    return None, grid_pairs(cx, cy, ex, ey)
