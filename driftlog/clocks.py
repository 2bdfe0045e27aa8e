"""Per-log clocks: every floating log advances to the next synchronisation time with its own steps.

Algorithm 1 of the reference paper (docs/model.md section 11) advances all floating logs
together with the smallest sub-step any of them needs (``[integrator] clock = "global"``).
With ``clock = "per_log"`` (docs/model.md section 11.1) the logs meet only at the
synchronisation times (hydrodynamic snapshots, output times, releases, the end); between two of
them each log takes its own sub-steps, from its own bounds (eq. (44): length, angle, drag
relaxation, ``max_step``), in one kernel over all logs (``per_log_mesh_advance``).  Each log's
sub-steps are exactly the ones the global clock would give it alone: one log has the same
trajectory, bit for bit, under both clocks.

A log stops inside the interval when its status would change (left the domain, stranded,
resting: ``driftlog.stepping.classify``'s rules); the tracker classifies it at the
synchronisation time from the flow sampled where it stopped.  Each log's swept box (the
bounding box of its centre over the sub-step ends) comes back for the contact islands
(``driftlog.contact.islands``).

The kernels are the fused mesh steps (``driftlog.fused``: P1 sampling on a mesh flow's node
values, euler or rk4) with the snapshot weight computed per stage time: inside a hydrodynamic
interval the node values are one snapshot pair; a stage that reaches the interval's end uses
the next pair, as ``MeshFlowField.node_values`` does for the global clock.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import (
    DUDY,
    DVDX,
    L_PAR,
    L_PERP,
    L_ROT,
    NLIN,
    NVAR,
    OMEGA,
    THETA,
    UB,
    VB,
    WET,
    H,
    U,
    V,
    X,
    Y,
)
from driftlog.flow import sample_point
from driftlog.fused import _rk4_stage
from driftlog.integrators import euler_row, put_row, rk4_final_row, row
from driftlog.logs import FLOATING
from driftlog.physics import log_rhs, rest_drive

__all__ = ["CLOCKS", "per_log_mesh_advance", "per_log_interval", "free_advance",
           "contact_advance", "touching", "OK", "TOO_SMALL", "DIVERGED"]

CLOCKS = ("global", "per_log")
# per-log outcome codes of per_log_mesh_advance
OK, TOO_SMALL, DIVERGED = 0, 1, 2
EULER, RK4 = 0, 1


@nb.njit(cache=True, inline="always")
def _weight(ts, T0, gap):
    """Time weight and 1 / gap of the snapshot pair starting at T0 (``MeshFlowField._interval``)."""
    if gap == 0.0:  # one snapshot: a steady flow
        return 0.0, 0.0
    a = min(max((ts - T0) / gap, 0.0), 1.0)
    return a, 1.0 / gap


@nb.njit(cache=True, inline="always")
def _own_bound(s, length, ln, lf, ang, drag_fraction, explicit, max_step):
    """One log's sub-step bound: ``StepOptions.max_step`` then ``stepping.step_bound``."""
    dt = max_step
    b = np.inf
    sp = np.sqrt(s[UB] ** 2 + s[VB] ** 2)
    if sp > 0.0:
        b = min(b, lf * length / sp)
    om = abs(s[OMEGA])
    if om > 0.0:
        b = min(b, ang / om)
    if explicit and drag_fraction > 0.0:
        lam = max(ln[L_PAR], max(ln[L_PERP], ln[L_ROT]))
        if lam > 0.0:
            b = min(b, drag_fraction / lam)
    return min(dt, b)


@nb.njit(cache=True, inline="always")
def _floats(fg, fl, s, p, thr, friction, opt):
    """True while the log stays floating (``stepping.classify``'s rules on one log)."""
    if fg != WET:
        return False
    if fl[H] < thr:
        if not friction:
            return False
        fx, fy, ff = rest_drive(s[THETA], fl, p, opt)
        f = np.sqrt(fx * fx + fy * fy)
        return f > 0.0 and f >= ff
    return True


@kernel
def per_log_mesh_advance(S, D0, lin0, face, F, flag, P, opt, t0, t_stop, tol, method,
                         length, lf, ang, drag_fraction, explicit, max_step, min_step,
                         tracer, rotation, thr, friction,
                         vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split,
                         dry_depth, recovered, loc,
                         t_log, nsteps, dt_min, dt_max, box, code):
    """Advance every log from t0 to t_stop with its own sub-steps (one log per thread).

    Parameters
    ----------
    S, D0, lin0, face, F, flag : arrays
        The logs' states (n, 6), first stage and drag linearisation at S (the tracker's
        ``D0``, ``lin0``), face hints, flow sample and flags; all updated in place to the end
        of each log's last sub-step.
    P, opt : arrays
        Parameter rows and physics options.
    t0, t_stop, tol : float
        The interval and the round-off tolerance of landing on t_stop.
    method : int
        EULER or RK4.
    length, lf, ang, drag_fraction, explicit, max_step, min_step
        Each log's length and the bounds of eq. (44) (``max_step`` inf when unset).
    tracer, rotation : bool
        Tracer level (the log takes the flow's velocity after each step), with rotation.
    thr, friction
        Depth below which a log stops floating (flotation depth or h*), and whether it moves
        on the bed when the flow overcomes friction (``physics.motion = "friction"``).
    vals_c, T0c, gap_c : node values, start and length of the snapshot pair at t0.
    vals_n, T0n, gap_n, t_split : the pair stage times at or after ``t_split`` use.
    dry_depth, recovered, loc : as ``driftlog.fused``.
    t_log, nsteps, dt_min, dt_max, box, code : outputs
        Each log's end time (t_stop unless it stopped early), sub-steps taken, shortest and
        longest sub-step, bounding box of its centre over the sub-step ends (xmin, ymin,
        xmax, ymax) and outcome (OK, TOO_SMALL, DIVERGED).
    """
    for i in nb.prange(S.shape[0]):
        s = row(S, i)
        p = P[i]
        t = t0
        k = 0
        lo, hi = np.inf, 0.0
        x0, y0, x1, y1 = s[X], s[Y], s[X], s[Y]
        c = OK
        while t < t_stop:
            ln = (lin0[i, 0], lin0[i, 1], lin0[i, 2], lin0[i, 3], lin0[i, 4])
            dt = min(_own_bound(s, length[i], ln, lf, ang, drag_fraction, explicit, max_step),
                     t_stop - t)
            if dt < min_step and t_stop - t > min_step:
                c = TOO_SMALL
                break
            hint = face[i]
            d0 = row(D0, i)
            te = t + dt
            if te >= t_split:
                a_e, inv_e = _weight(te, T0n, gap_n)
                vals_e = vals_n
            else:
                a_e, inv_e = _weight(te, T0c, gap_c)
                vals_e = vals_c
            if method == RK4:
                tm = t + 0.5 * dt
                if tm >= t_split:
                    a_m, inv_m = _weight(tm, T0n, gap_n)
                    vals_m = vals_n
                else:
                    a_m, inv_m = _weight(tm, T0c, gap_c)
                    vals_m = vals_c
                d1 = _rk4_stage(s, 1, dt, d0, hint, a_m, inv_m, vals_m, dry_depth, recovered,
                                loc, p, opt)
                d2 = _rk4_stage(s, 2, dt, d1, hint, a_m, inv_m, vals_m, dry_depth, recovered,
                                loc, p, opt)
                d3 = _rk4_stage(s, 3, dt, d2, hint, a_e, inv_e, vals_e, dry_depth, recovered,
                                loc, p, opt)
                s = rk4_final_row(s, dt, d0, d1, d2, d3)
            else:
                s = euler_row(s, dt, d0)
            f, fg, fl = sample_point(s[X], s[Y], hint, a_e, inv_e, vals_e, dry_depth,
                                     recovered, loc)
            face[i] = f
            flag[i] = fg
            for q in range(NVAR):
                F[i, q] = fl[q]
            d, ln2 = log_rhs(s, fl, p, opt, True)
            put_row(D0, i, d)
            for q in range(NLIN):
                lin0[i, q] = ln2[q]
            if tracer:
                om = 0.5 * (fl[DVDX] - fl[DUDY]) if rotation else 0.0
                s = (s[X], s[Y], s[THETA], fl[U], fl[V], om)
            t_prev = t
            t = t + dt
            if t_stop - t <= tol:
                t = t_stop
            taken = t - t_prev
            lo = min(lo, taken)
            hi = max(hi, taken)
            k += 1
            ok = True
            for q in range(6):
                if not np.isfinite(s[q]):
                    ok = False
            if not ok:
                c = DIVERGED
                break
            x0, y0 = min(x0, s[X]), min(y0, s[Y])
            x1, y1 = max(x1, s[X]), max(y1, s[Y])
            if not _floats(fg, fl, s, p, thr[i], friction, opt):
                break
        put_row(S, i, s)
        t_log[i] = t
        nsteps[i] = k
        dt_min[i] = lo
        dt_max[i] = hi
        box[i, 0], box[i, 1], box[i, 2], box[i, 3] = x0, y0, x1, y1
        code[i] = c


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
        free_advance(tr, stop)
    else:
        contact_advance(tr, stop)
    tr.t = stop
    tr._soak(stop - t0)
    tr.stats["substeps"] += 1
    tr._release()
    tr._update_status()
    if bar is not None:
        bar.update(stop - t0)


def free_advance(tr, stop):
    """Every floating log of ``tr`` to ``stop`` with its own sub-steps (one kernel).

    Returns each log's swept box (n, 4: xmin, ymin, xmax, ymax of its centre over its
    sub-step ends).  A log whose status changes on the way stops there; the tracker then
    classifies it from the flow sampled where it stopped (``F``, as the global clock would).
    """
    from driftlog.columns import P_HSTAR
    from driftlog.stepping import IntegrationError, StepTooSmallError

    so, kern, n = tr.step_options, tr._kernel, tr.act.size
    if not tr._d0_valid:
        tr._rhs(tr.state, tr.t, tr.D0, tr.lin0)
    vals_c, T0c, gap_c, t_split = kern.node_pair(tr.t)
    if stop >= t_split:
        vals_n, T0n, gap_n, _ = kern.node_pair(stop)
    else:
        vals_n, T0n, gap_n = vals_c, T0c, gap_c
    friction = tr.physics.motion != "floating"
    thr = (tr.P[:, P_HSTAR].copy() if friction
           else np.ascontiguousarray(tr.logs.float_depth[tr.act]))
    t_log, dt_min, dt_max = np.empty(n), np.empty(n), np.empty(n)
    nsteps, code = np.empty(n, np.int64), np.empty(n, np.int8)
    box = np.empty((n, 4))
    tracer = tr.physics.level == "tracer"
    explicit = not tr.integrator.stiff_stable and not tracer
    method = RK4 if tr.integrator.name == "rk4" else EULER
    per_log_mesh_advance(
        tr.state, tr.D0, tr.lin0, tr.face, tr.F, tr.flag, tr.P, tr.opt, tr.t, stop,
        tr.time_tol, method, np.ascontiguousarray(tr.length), so.length_fraction,
        so.angle_step, so.drag_fraction, explicit, so.max_step if so.max_step else np.inf,
        so.min_step, tracer, bool(tr.physics.rotation), thr, friction, vals_c, T0c, gap_c,
        vals_n, T0n, gap_n, t_split, kern.dry_depth, kern.recovered, kern.locator, t_log,
        nsteps, dt_min, dt_max, box, code)
    tr._F_valid = tr._d0_valid = True
    k = int(nsteps.sum())
    st = tr.stats
    st["log_substeps"] = st.get("log_substeps", 0) + k
    st["rhs_evaluations"] += k * (4 if method == RK4 else 1)
    if k:
        st["min_dt"] = min(st["min_dt"], float(dt_min[nsteps > 0].min()))
        st["max_dt"] = max(st["max_dt"], float(dt_max.max()))
    bad = np.flatnonzero(code == TOO_SMALL)
    if bad.size:
        i = bad[0]
        raise StepTooSmallError(
            f"sub-step below integrator.min_step = {so.min_step} s for log {int(tr.ids[i])} "
            f"at t = {t_log[i]} s; a log spins or moves too fast for its length (check the "
            "flow at the logs) or lower integrator.min_step")
    bad = np.flatnonzero(code == DIVERGED)
    if bad.size:
        raise IntegrationError(
            f"the {tr.integrator.name} integration diverged at t = {t_log[bad[0]]:.6g} s "
            f"(logs {tr.ids[bad[:5]].tolist()}): the step is too long for the drag "
            "relaxation time; use integrator.method = 'exponential' or set "
            "integrator.drag_fraction > 0")
    return box


def _boxes(box, half):
    """Centres and half extents of swept boxes (xmin, ymin, xmax, ymax) grown by ``half``."""
    cx = 0.5 * (box[:, 0] + box[:, 2])
    cy = 0.5 * (box[:, 1] + box[:, 3])
    return cx, cy, 0.5 * (box[:, 2] - box[:, 0]) + half, 0.5 * (box[:, 3] - box[:, 1]) + half


def _obstacle_grid(tr, cell):
    """The contact model's obstacles binned for the swept boxes (kept while the cell fits)."""
    from driftlog.contact.broadphase import StaticGrid

    g = getattr(tr, "_clock_grid", None)
    if g is None or cell > 2.0 * g[0] or cell < 0.25 * g[0]:
        g = tr._clock_grid = (cell, StaticGrid(tr.contact.obstacles.capsules, cell))
    return g[1]


def touching(tr, box, half):
    """Logs whose swept boxes overlap another's or an obstacle's, and the log pairs."""
    from driftlog.contact.broadphase import grid_pairs

    cx, cy, ex, ey = _boxes(box, half)
    pairs = grid_pairs(cx, cy, ex, ey)
    hit = np.zeros(box.shape[0], bool)
    hit[pairs.ravel()] = True
    caps = tr.contact.obstacles.capsules
    if caps.shape[0] and box.shape[0]:
        lo = _obstacle_grid(tr, 2.0 * max(float(ex.max()), float(ey.max()))).query(cx, cy, ex,
                                                                                     ey)
        hit[lo[:, 0]] = True
    return hit, pairs


def contact_advance(tr, stop, max_tries=3):
    """Per-log clocks with contacts: free logs on their own clocks, contact logs together.

    1. Every floating log runs free to ``stop`` (``free_advance``): its swept box.
    2. Logs whose boxes (grown by half a length, the radius and a margin) overlap another
       log's or an obstacle's form the contact set (the union of the contact islands); the
       others keep their free motion.
    3. The contact set restarts from the interval's start and runs the global clock's
       contact steps (``Tracker._global_steps`` on the set alone): impulses, times of impact
       and the event-driven step of the contact model, as before, among these logs only.
    4. Closure: if a contact log's actual sweep reaches a free log's box, that log joins the
       set and the interval is computed again (after ``max_tries``, with all logs).
    """
    L, C = tr.logs, tr.contact
    t0 = tr.t
    tr._d0_valid = False  # velocities may have been changed by impulses since
    tr._sample_current()
    act0 = tr.act.copy()
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
    pool_mask, _ = touching(tr, box, half)
    k = 0
    for attempt in range(max_tries + 1):
        if not pool_mask.any():
            break
        sub = np.flatnonzero(pool_mask)
        pool = act0[sub]
        L.state[act0] = np.where(pool_mask[:, None], S0, E_state)
        L.face[act0] = np.where(pool_mask, face0, E_face)
        L.status[act0] = status0
        tr.t = t0
        tr._d0_valid = tr._F_valid = False
        tr._set_active(pool)
        swept = np.column_stack([S0[sub, 0], S0[sub, 1], S0[sub, 0], S0[sub, 1]])
        tr._global_steps(stop, None, pool=pool, swept=swept)
        if tr.act.size:
            tr._scatter()
            tr._sample_current()
        k = sub.size
        free = np.flatnonzero(~pool_mask)
        if free.size == 0:
            break
        both = np.vstack([box[free], swept])
        grown = np.concatenate([half[free], half[sub]])
        _, pairs = touching_pairs(both, grown)
        cross = pairs[(pairs[:, 0] < free.size) & (pairs[:, 1] >= free.size)]
        if cross.size == 0:
            break
        # a contact log's deflected path reaches a free log: compute the interval again
        tr.stats["clock_retries"] = tr.stats.get("clock_retries", 0) + 1
        _contact_rollback(C, kept)
        pool_mask[free[np.unique(cross[:, 0])]] = True
        if attempt + 1 >= max_tries:
            pool_mask[:] = True
    tr.stats["contact_set"] = max(tr.stats.get("contact_set", 0), k)
    # the floating logs at stop: free ones with their own end samples, the contact set's
    F_end, flag_end = E_F, E_flag
    if k:
        pos = np.searchsorted(act0, tr.act)
        F_end, flag_end = E_F.copy(), E_flag.copy()
        F_end[pos], flag_end[pos] = tr.F, tr.flag
    final = act0[L.status[act0] == FLOATING]
    tr.t = stop
    tr._d0_valid = tr._F_valid = False
    tr._set_active(final)
    pos = np.searchsorted(act0, final)
    tr.F[:], tr.flag[:] = F_end[pos], flag_end[pos]
    tr._F_valid = True


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
