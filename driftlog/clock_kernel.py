"""Per-log clocks, the kernel: every floating log to the next synchronisation time on its own.

The tracker's side (contact islands, statuses) is ``driftlog.clocks``; the kernel lives apart
so that numba's cache of it survives edits there.

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
from driftlog.contact.geometry import log_endpoints
from driftlog.flow import sample_point
from driftlog.fused import rk4_row
from driftlog.integrators import euler_row, put_row, row
from driftlog.physics import log_rhs, rest_drive

__all__ = ["CLOCKS", "per_log_mesh_advance", "idle_lift", "free_summary", "OK", "TOO_SMALL",
           "DIVERGED", "STOPPED", "EULER", "RK4"]

CLOCKS = ("global", "per_log")
# per-log outcome codes of per_log_mesh_advance (STOPPED: its status would change, left,
# stranded or resting, at t_log)
OK, TOO_SMALL, DIVERGED, STOPPED = 0, 1, 2, 3
EULER, RK4 = 0, 1


@nb.njit(cache=True, inline="always")
def _weight(ts, T0, gap):
    """Time weight and 1 / gap of the snapshot pair starting at T0 (``MeshFlowField._interval``)."""
    if gap == 0.0:  # one snapshot: a steady flow
        return 0.0, 0.0
    a = min(max((ts - T0) / gap, 0.0), 1.0)
    return a, 1.0 / gap


@nb.njit(cache=True, inline="always")
def _pair_at(ts, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, own):
    """The snapshot pair read at time ts: weight, 1 / gap and its node values.

    From t_split on, the next pair; with ``own``, a stage at t_split itself still reads the
    current pair (the last stage of a step ending on that snapshot: dU/dt's left limit,
    docs/model.md 11).
    """
    if ts > t_split or (ts == t_split and not own):
        a, inv = _weight(ts, T0n, gap_n)
        return a, inv, vals_n
    a, inv = _weight(ts, T0c, gap_c)
    return a, inv, vals_c


@nb.njit(cache=True, inline="always")
def _free_step(s, d0, hint, t, dt, method, p, opt, vals_c, T0c, gap_c, vals_n, T0n, gap_n,
               t_split, dry_depth, recovered, loc):
    """One RK4 / Euler step of one log from t (first stage d0), each stage reading its pair.

    Returns the new state, the face to start its end's point location from (the last RK4
    stage's, ``fused.rk4_row``) and the pair its end is sampled on (weight, 1 / gap, node
    values).
    """
    te = t + dt
    a_s, inv_s, vals_s = _pair_at(te, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, True)
    a_e, inv_e, vals_e = _pair_at(te, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, False)
    if method == RK4:
        a_m, inv_m, vals_m = _pair_at(t + 0.5 * dt, vals_c, T0c, gap_c, vals_n, T0n, gap_n,
                                      t_split, False)
        r = rk4_row(s, d0, dt, hint, a_m, inv_m, vals_m, a_s, inv_s, vals_s, dry_depth,
                    recovered, loc, p, opt)
        return (r[0], r[1], r[2], r[3], r[4], r[5]), r[6], a_e, inv_e, vals_e
    return euler_row(s, dt, d0), hint, a_e, inv_e, vals_e


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


@kernel(nrt=False)
def per_log_mesh_advance(S, D0, lin0, face, F, flag, P, opt, t_from, t0, t_stop, tol, method,
                         length, lf, ang, drag_fraction, explicit, max_step, min_step,
                         tracer, rotation, thr, friction,
                         vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split,
                         dry_depth, recovered, loc, fx, fy, restart,
                         t_log, nsteps, dt_min, dt_max, box, code):
    """Advance every log from t_from to t_stop with its own sub-steps (one log per thread).

    Parameters
    ----------
    S, D0, lin0, face, F, flag : arrays
        The logs' states (n, 6), first stage and drag linearisation at S (the tracker's
        ``D0``, ``lin0``), face hints, flow sample and flags; all updated in place to the end
        of each log's last sub-step.
    P, opt : arrays
        Parameter rows and physics options.
    t_from : array
        Each log's start time (t0 for the logs floating at t0; later for a log lifted inside
        the interval, ``idle_lift``).
    t0, t_stop, tol : float
        The interval (t0: the origin of the moving frame of the boxes) and the round-off
        tolerance of landing on t_stop.
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
    vals_n, T0n, gap_n, t_split : the pair stage times after ``t_split`` use, and the flow
        sampled at the end of a step that ends at or after it.
    dry_depth, recovered, loc : as ``driftlog.fused``.
    fx, fy : float
        Velocity of the frame the swept boxes are measured in (contact windows: the logs'
        mean velocity, so that logs drifting together do not sweep over each other).
    restart : bool
        The logs start from rest at t_from (lifted off the bed, docs/model.md section 6): their
        velocity is set to 0 and F, flag, face, D0 and lin0 are computed there first.
    t_log, nsteps, dt_min, dt_max, box, code : outputs
        Each log's end time (t_stop unless it stopped early), sub-steps taken, shortest and
        longest sub-step, bounding box of its axis ends over t_from and its sub-step ends, in
        the frame moving at (fx, fy) from t0 (xmin, ymin, xmax, ymax) and outcome (OK,
        TOO_SMALL, DIVERGED, STOPPED).
    """
    for i in nb.prange(S.shape[0]):
        s = row(S, i)
        p = P[i]
        t = t_from[i]
        k = 0
        lo, hi = np.inf, 0.0
        tau = t - t0
        ax, ay, bx, by = log_endpoints(s[X] - fx * tau, s[Y] - fy * tau, s[THETA], length[i])
        x0, y0, x1, y1 = min(ax, bx), min(ay, by), max(ax, bx), max(ay, by)
        c = OK
        # with ``restart`` the first pass only samples the flow and the forces at the log at
        # rest (one copy of the inlined sampling and forces for both: it compiles faster)
        first = restart
        if restart:
            s = (s[X], s[Y], s[THETA], 0.0, 0.0, 0.0)
        while first or t < t_stop:
            hint = face[i]
            if first:
                a_e, inv_e, vals_e = _pair_at(t, vals_c, T0c, gap_c, vals_n, T0n, gap_n,
                                              t_split, False)
            else:
                ln = (lin0[i, 0], lin0[i, 1], lin0[i, 2], lin0[i, 3], lin0[i, 4])
                dt = min(_own_bound(s, length[i], ln, lf, ang, drag_fraction, explicit,
                                    max_step), t_stop - t)
                if dt < min_step and t_stop - t > min_step:
                    c = TOO_SMALL
                    break
                d0 = row(D0, i)
                s, hint, a_e, inv_e, vals_e = _free_step(
                    s, d0, hint, t, dt, method, p, opt, vals_c, T0c, gap_c, vals_n, T0n,
                    gap_n, t_split, dry_depth, recovered, loc)
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
            if first:
                first = False
                continue
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
            tau = t - t0
            ax, ay, bx, by = log_endpoints(s[X] - fx * tau, s[Y] - fy * tau, s[THETA],
                                           length[i])
            x0, y0 = min(x0, min(ax, bx)), min(y0, min(ay, by))
            x1, y1 = max(x1, max(ax, bx)), max(y1, max(ay, by))
            if not _floats(fg, fl, s, p, thr[i], friction, opt):
                c = STOPPED
                break
        put_row(S, i, s)
        t_log[i] = t
        nsteps[i] = k
        dt_min[i] = lo
        dt_max[i] = hi
        box[i, 0], box[i, 1], box[i, 2], box[i, 3] = x0, y0, x1, y1
        code[i] = c


@nb.njit(cache=True)
def _idle_floats(x, y, th, hint, t, p, opt, thr, friction, vals_c, T0c, gap_c, vals_n, T0n,
                 gap_n, t_split, dry_depth, recovered, loc):
    """Whether an idle log at (x, y, th) floats at time t (``stepping.classify``'s rules)."""
    a, inv, vals = _pair_at(t, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, False)
    f, fg, fl = sample_point(x, y, hint, a, inv, vals, dry_depth, recovered, loc)
    return _floats(fg, fl, (x, y, th, 0.0, 0.0, 0.0), p, thr, friction, opt)


@kernel(nrt=False)
def idle_lift(S, face, P, opt, thr, friction, t_from, t_stop, dt_check, tol, vals_c, T0c,
              gap_c, vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc, t_lift):
    """The first time in (t_from, t_stop] at which each idle (resting, stranded) log floats.

    Per-log clocks (docs/model.md 11.1): an idle log does not move, so whether it floats at a
    time t is the flow at its place at t.  Within a snapshot pair the flow is linear in time
    at a fixed point, so with ``physics.motion = "floating"`` (float where h >= h*) the
    depth crosses h* at most once on each side of the snapshot time t_split: the two ends of
    each piece tell whether it lifts there, and bisection finds when, to ``tol``.  With
    ``friction`` (the flow's force against bed friction: not monotone in time) the pieces are
    cut into checks ``dt_check`` apart (the floating logs' shortest sub-step: at least as
    often as the global clock checks its idle logs) and bisection runs in the first check
    interval where it floats.  ``t_lift``: that time, inf where the log stays idle.
    """
    for i in nb.prange(S.shape[0]):
        x, y, th = S[i, X], S[i, Y], S[i, THETA]
        hint = face[i]
        p = P[i]
        t_lift[i] = np.inf
        ta = t_from[i]
        while ta < t_stop - tol:
            tb = t_stop
            if ta < t_split < t_stop:
                tb = t_split  # the end of this snapshot piece (linear in time before it)
            if friction and tb - ta > dt_check:
                tb = ta + dt_check
            if _idle_floats(x, y, th, hint, tb, p, opt, thr[i], friction, vals_c, T0c, gap_c,
                            vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc):
                lo, hi = ta, tb  # idle at lo (or just before), floating at hi
                while hi - lo > tol:
                    mid = 0.5 * (lo + hi)
                    if mid <= lo or mid >= hi:
                        break
                    if _idle_floats(x, y, th, hint, mid, p, opt, thr[i], friction, vals_c,
                                    T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
                                    recovered, loc):
                        hi = mid
                    else:
                        lo = mid
                t_lift[i] = hi
                break
            ta = tb


@nb.njit(cache=True)
def free_summary(nsteps, dt_min, dt_max, code, own):
    """What ``clocks._advance_rows`` reads of ``per_log_mesh_advance``'s outputs, in one pass.

    Returns (sub-steps in all, the shortest sub-step of the logs that took any, the longest
    over all logs (0 for a log without any), first TOO_SMALL row, first DIVERGED row (-1:
    none)); ``own`` gets each log's shortest sub-step, inf for a log without any.  The same
    numbers as numpy's ``nsteps.sum()``, ``dt_min[nsteps > 0].min()``, ``dt_max.max()`` (a
    NaN propagates), ``np.flatnonzero(code == c)[0]`` and ``np.where(nsteps > 0, dt_min,
    np.inf)``, without their temporaries.
    """
    k = 0
    lo, hi = np.inf, -np.inf
    lo_nan = hi_nan = False
    small = diverged = -1
    for i in range(nsteps.shape[0]):
        v = dt_max[i]
        if v != v:
            hi_nan = True
        elif v > hi:
            hi = v
        if nsteps[i] > 0:
            k += nsteps[i]
            v = dt_min[i]
            own[i] = v
            if v != v:
                lo_nan = True
            elif v < lo:
                lo = v
        else:
            own[i] = np.inf
        if small < 0 and code[i] == TOO_SMALL:
            small = i
        if diverged < 0 and code[i] == DIVERGED:
            diverged = i
    return k, np.nan if lo_nan else lo, np.nan if hi_nan else hi, small, diverged
