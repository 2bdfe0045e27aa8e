"""Per-log clocks with contacts, the kernel: every contact island on its own clock, in one call.

``driftlog.clocks.contact_advance`` finds the contact islands of a contact window (the logs
whose swept boxes may touch each other or an obstacle, connected components); this kernel
then runs each island from the window's start to its end with the event-driven contact steps
of ``driftlog.contact.ContactModel`` (method "event", time of impact "conservative") among the
island's own logs: per step the island's own sub-step bound (eq. (70) over its logs), impulses
on the contacts within the tolerance (sequential sweeps, restitution, resting contacts), the
resting contacts moved apart, conservative advancement on the island's pairs and its
obstacles, the fused RK4 / Euler step of its logs (the flow sampled P1 at each stage time, as
``driftlog.clock_kernel``), the end-of-step overlap check (a rejected step is shortened as
the model does), and the statuses (a log that stops floating leaves its island).  An island's
next contact ends only that island's step.

Islands are flat CSR arrays (``members[start[q]:start[q + 1]]``, their obstacle capsules
``ocaps[ostart[q]:ostart[q + 1]]``); the contacts of an island are found by testing all its
pairs (islands are small: that is the point of them).  Hits (contacts that start with an
impulse, one per log and other body at an instant), the impulses passed to the fixed
obstacles, statistics and each island's outcome come back in arrays.

The numbers equal the Python contact model's to round-off except for the order in which the
contacts of one island are swept (pairs by member order here, by the broad phase's grid order
there): with several simultaneous contacts, sequential impulses in another order are another
admissible solution (docs/model.md section 13).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.clock_kernel import _floats, _free_step, _own_bound, _pair_at
from driftlog.columns import (
    CX,
    CY,
    DUDY,
    DVDX,
    GAP,
    NLIN,
    NRES,
    NVAR,
    NX,
    NY,
    OMEGA,
    OUTSIDE,
    THETA,
    UB,
    VB,
    U,
    V,
    X,
    Y,
)
from driftlog.contact.geometry import capsule_gap, capsule_row, log_endpoints
from driftlog.contact.impulses import pair_impulse, separate_resting
from driftlog.contact.toi import conservative_step
from driftlog.flow import sample_point
from driftlog.integrators import put_row, row
from driftlog.physics import log_rhs

__all__ = ["island_advance", "OK", "TOO_SMALL", "DIVERGED", "JAM", "NSTAT", "HIT_FULL"]

OK, TOO_SMALL, DIVERGED, JAM = 0, 1, 2, 3
HIT_FULL = 4  # the hit buffer is full: the caller grows it and runs the window again
# island_advance's statistics (stats[k])
(ST_STEPS, ST_ADVANCES, ST_REJECTED, ST_EVENTS, ST_SEPARATIONS, ST_MAX_CONTACTS,
 ST_LOG_STEPS) = range(7)
NSTAT = 7
OBST_BIT = 1 << 31


@nb.njit(cache=True, inline="always")
def _pair_key(id1, id2):
    """``contact.model._body_pairs``: one integer per (log id, other body)."""
    return np.int64(id1) * np.int64(1 << 32) + np.int64(id2)


# islands of at most this many bodies (logs and capsules) test all their pairs
ALL_PAIRS = 24


@nb.njit(cache=True, inline="always")
def _boxes_apart(x1, y1, ex1, ey1, x2, y2, ex2, ey2):
    """``broadphase.grid_pairs``' test: boxes (centre, half-extents) 1 and 2 do not overlap."""
    return abs(x1 - x2) > ex1 + ex2 or abs(y1 - y2) > ey1 + ey2


@nb.njit(cache=True, inline="always")
def _box_misses_capsule(x, y, ex, ey, caps, cap):
    """``StaticGrid.query``'s test: a box (centre, half-extents) misses capsule cap's box."""
    qa, qb, qc, qd, qr = capsule_row(caps, cap)
    return (x - ex > max(qa, qc) + qr or x + ex < min(qa, qc) - qr
            or y - ey > max(qb, qd) + qr or y + ey < min(qb, qd) - qr)


@nb.njit(cache=True, inline="always")
def _log_log_apart(Sl, a, b, ex, ey):
    """The boxes of the island's logs a and b (local rows) do not overlap."""
    return _boxes_apart(Sl[a, X], Sl[a, Y], ex[a], ey[a], Sl[b, X], Sl[b, Y], ex[b], ey[b])


@nb.njit(cache=True, inline="always")
def _log_cap_apart(Sl, a, ex, ey, caps, cap):
    """The box of the island's log a (local row) misses capsule cap's box."""
    return _box_misses_capsule(Sl[a, X], Sl[a, Y], ex[a], ey[a], caps, cap)


@nb.njit(cache=True)
def island_pairs(Sl, ln, rd, na, margin, caps, ocaps):
    """Candidate pairs of an island: its logs' boxes (capsule plus ``margin``) that overlap.

    Parameters
    ----------
    Sl : (>= na, 6) the island's states (local rows 0 .. na - 1).
    ln, rd, margin : (>= na) lengths, radii and box margins (``broadphase.log_boxes``).
    caps : (m, 5) all obstacle capsules; ocaps : the island's capsule indices.

    Returns
    -------
    pairs : (k, 2) int64
        Log pairs (a, b), a < b, by a then b; then log-capsule pairs (a, -(c + 1)) for capsule
        ``ocaps[c]``, by a then c.  The box tests of ``broadphase`` (the same pairs as
        ``grid_pairs`` and ``StaticGrid.query``).
    nll : int
        How many are log pairs.
    """
    no = ocaps.size
    ex = np.empty(na)
    ey = np.empty(na)
    for a in range(na):
        h = 0.5 * ln[a]
        ex[a] = h * abs(np.cos(Sl[a, THETA])) + rd[a] + margin[a]
        ey[a] = h * abs(np.sin(Sl[a, THETA])) + rd[a] + margin[a]
    m = 0
    if na + no <= ALL_PAIRS:
        # room for every pair (at most 276): no growing, no call per pair
        out = np.empty((na * (na - 1) // 2 + na * no, 2), np.int64)
        for a in range(na):
            for b in range(a + 1, na):
                if not _log_log_apart(Sl, a, b, ex, ey):
                    out[m, 0], out[m, 1] = a, b
                    m += 1
        nll = m
        for a in range(na):
            for c in range(no):
                if not _log_cap_apart(Sl, a, ex, ey, caps, ocaps[c]):
                    out[m, 0], out[m, 1] = a, -(c + 1)
                    m += 1
        return out[:m].copy(), nll
    # sort and sweep along x or y, whichever the logs spread over more (boxes padded by
    # round-off; the exact tests decide)
    ni = na + no
    x0 = y0 = np.inf
    x1 = y1 = -np.inf
    for a in range(na):
        x0, x1 = min(x0, Sl[a, X]), max(x1, Sl[a, X])
        y0, y1 = min(y0, Sl[a, Y]), max(y1, Sl[a, Y])
    along_x = x1 - x0 >= y1 - y0
    ax = X if along_x else Y
    ext = ex if along_x else ey
    lo = np.empty(ni)
    hi = np.empty(ni)
    for a in range(na):
        pad = 1e-9 * (abs(Sl[a, ax]) + ext[a])
        lo[a], hi[a] = Sl[a, ax] - ext[a] - pad, Sl[a, ax] + ext[a] + pad
    for c in range(no):
        qa, qb, qc, qd, qr = capsule_row(caps, ocaps[c])
        if not along_x:
            qa, qc = qb, qd
        pad = 1e-9 * (abs(qa) + abs(qc) + qr)
        lo[na + c], hi[na + c] = min(qa, qc) - qr - pad, max(qa, qc) + qr + pad
    order = np.argsort(lo)
    keys_ll = np.empty(16, np.int64)
    keys_lo = np.empty(16, np.int64)
    nl = 0
    nk = 0
    for s in range(ni):
        p = order[s]
        for s2 in range(s + 1, ni):
            q = order[s2]
            if lo[q] > hi[p]:
                break
            a, b = (p, q) if p < q else (q, p)
            if a >= na:
                continue  # two capsules
            if b < na:
                if _log_log_apart(Sl, a, b, ex, ey):
                    continue
                if nl == keys_ll.size:
                    keys_ll = np.concatenate((keys_ll, np.empty(nl + 16, np.int64)))
                keys_ll[nl] = a * na + b
                nl += 1
            else:
                c = b - na
                if _log_cap_apart(Sl, a, ex, ey, caps, ocaps[c]):
                    continue
                if nk == keys_lo.size:
                    keys_lo = np.concatenate((keys_lo, np.empty(nk + 16, np.int64)))
                keys_lo[nk] = a * no + c
                nk += 1
    kl = np.sort(keys_ll[:nl])
    ko = np.sort(keys_lo[:nk])
    out = np.empty((nl + nk, 2), np.int64)
    for k in range(nl):
        out[k, 0], out[k, 1] = kl[k] // na, kl[k] % na
    for k in range(nk):
        out[nl + k, 0], out[nl + k, 1] = ko[k] // no, -(ko[k] % no + 1)
    return out, nl


@nb.njit(cache=True, inline="always")
def _log_pair(S, radius, mem, wk, a, b, out):
    """(whether the boxes of members a and b overlap, their gap: rows in ``out``)."""
    i, j = mem[a], mem[b]
    if _boxes_apart(S[i, X], S[i, Y], wk[a, 0], wk[a, 1], S[j, X], S[j, Y], wk[b, 0], wk[b, 1]):
        return False, 0.0
    return True, capsule_gap(wk[a, 2], wk[a, 3], wk[a, 4], wk[a, 5], radius[i], wk[b, 2],
                             wk[b, 3], wk[b, 4], wk[b, 5], radius[j], out)


@nb.njit(cache=True, inline="always")
def _cap_pair(S, radius, mem, wk, a, caps, cap, out):
    """(whether the boxes of member a and capsule ``cap`` meet, their gap: rows in ``out``)."""
    i = mem[a]
    if _box_misses_capsule(S[i, X], S[i, Y], wk[a, 0], wk[a, 1], caps, cap):
        return False, 0.0
    qa, qb, qc, qd, qr = capsule_row(caps, cap)
    return True, capsule_gap(wk[a, 2], wk[a, 3], wk[a, 4], wk[a, 5], radius[i], qa, qb, qc, qd,
                             qr, out)


@nb.njit(cache=True)
def _contacts(S, length, radius, mem, na, nt, caps, ocaps, o0, o1, margin, use_margin, gmax,
              c1, c2, cres, wk):
    """Pairs of active members (and member - obstacle capsule) whose boxes overlap.

    The members mem[:na] move; mem[na:nt] are fixed (logs stopped in the window,
    ``keep_stopped``): a pair needs a moving member (the first), obstacles only moving ones.

    Boxes: ``broadphase.log_boxes`` with ``margin`` per member (``use_margin``) or the scalar
    ``gmax``; kept when the gap is <= gmax (``use_margin`` False: the tolerance check) or the
    boxes overlap (True: the conservative-advancement candidates).  c1, c2: local member
    positions (c2 = -(k + 1) for obstacle capsule ocaps[k]); cres: (NRES) rows.  Returns the
    count.  The pairs come by first member, then its other members by position, then its
    capsules.  Islands of up to ``ALL_PAIRS`` bodies test all their pairs; larger ones
    (a jam of hundreds of logs) take the pairs whose boxes overlap from ``island_pairs``'
    sort and sweep (the same boxes and tests), in the same order, tested by the same
    arithmetic: the same contacts.  wk (>= nt, 6): each member's box half-extents and axis
    ends.
    """
    nc = 0
    out = np.empty(NRES)
    no = o1 - o0
    for a in range(nt):
        i = mem[a]
        mi = margin[a] if use_margin else gmax
        hi = 0.5 * length[i]
        wk[a, 0] = hi * abs(np.cos(S[i, THETA])) + radius[i] + mi
        wk[a, 1] = hi * abs(np.sin(S[i, THETA])) + radius[i] + mi
        wk[a, 2], wk[a, 3], wk[a, 4], wk[a, 5] = log_endpoints(S[i, X], S[i, Y], S[i, THETA],
                                                               length[i])
    small = nt + no <= ALL_PAIRS
    pairs = np.empty((0, 2), np.int64)
    nll = 0
    if not small:  # the members' rows in island_pairs' local layout
        sl, ln, rd, mg = np.empty((nt, 3)), np.empty(nt), np.empty(nt), np.empty(nt)
        for a in range(nt):
            i = mem[a]
            sl[a, X], sl[a, Y], sl[a, THETA] = S[i, X], S[i, Y], S[i, THETA]
            ln[a], rd[a] = length[i], radius[i]
            mg[a] = margin[a] if use_margin else gmax
        pairs, nll = island_pairs(sl, ln, rd, nt, mg, caps, ocaps[o0:o1])
    pl, po = 0, nll
    for a in range(na):
        for k in range(nt - a - 1 if small else _count(pairs, pl, nll, a)):
            if small:
                b = a + 1 + k
            else:
                b = pairs[pl, 1]
                pl += 1
            near, g = _log_pair(S, radius, mem, wk, a, b, out)
            if near and (use_margin or g <= gmax):
                c1[nc], c2[nc] = a, b
                for q in range(NRES):
                    cres[nc, q] = out[q]
                nc += 1
        for m in range(no if small else _count(pairs, po, pairs.shape[0], a)):
            if small:
                k = o0 + m
            else:
                k = o0 - pairs[po, 1] - 1
                po += 1
            near, g = _cap_pair(S, radius, mem, wk, a, caps, ocaps[k], out)
            if near and (use_margin or g <= gmax):
                c1[nc], c2[nc] = a, -(k - o0 + 1)
                for q in range(NRES):
                    cres[nc, q] = out[q]
                nc += 1
    return nc


@nb.njit(cache=True, inline="always")
def _count(pairs, p, n, a):
    """How many of the rows p .. n - 1 of ``pairs`` (sorted by first body) have first body a."""
    k = p
    while k < n and pairs[k, 0] == a:
        k += 1
    return k - p


@nb.njit(cache=True, inline="always")
def add_hit(first, nhit, hit_t, hit_log, hit_other, hit_j, hit_x, hit_y, t, lid, oth, imp, cx,
            cy):
    """Add impulse ``imp`` at (cx, cy) to the hit of log ``lid`` on ``oth``.

    The hit is the one recorded since index ``first`` for that pair, or a new one at time t
    (its point: the impulse-weighted mean, divided by the impulse once the step is done).
    False when the hit arrays are full (nothing added).
    """
    slot = -1
    for k in range(first, nhit[0]):
        if hit_log[k] == lid and hit_other[k] == oth:
            slot = k
            break
    if slot < 0:
        if nhit[0] >= hit_t.size:
            return False
        slot = nhit[0]
        nhit[0] += 1
        hit_t[slot], hit_log[slot], hit_other[slot] = t, lid, oth
        hit_j[slot], hit_x[slot], hit_y[slot] = 0.0, 0.0, 0.0
    hit_j[slot] += imp
    hit_x[slot] += imp * cx
    hit_y[slot] += imp * cy
    return True


@nb.njit(cache=True, _nrt=False)
def _diverged(S, mem, na):
    """True when a state of the island's logs ``mem[:na]`` is not finite."""
    for a in range(na):
        i = mem[a]
        for k in range(6):
            if not np.isfinite(S[i, k]):
                return True
    return False


@nb.njit(cache=True, _nrt=False)
def _still_floating(S, F, flag, P, thr, friction, opt, box, mem, na, length, fx, fy, tau):
    """The island's logs that still float, kept in ``mem`` in order; their number.

    Grows each log's swept box over ``tau`` first; floating: docs/model.md section 6.
    """
    k = 0
    for a in range(na):
        i = mem[a]
        s = row(S, i)
        _grow_box(box, i, s, length[i], fx, fy, tau)
        fl = (F[i, 0], F[i, 1], F[i, 2], F[i, 3], F[i, 4], F[i, 5], F[i, 6], F[i, 7],
              F[i, 8], F[i, 9], F[i, 10], F[i, 11])
        if _floats(flag[i], fl, s, P[i], thr[i], friction, opt):
            mem[k] = i
            k += 1
    return k


@nb.njit(cache=True)
def split_stopped(S, F, flag, P, thr, friction, opt, box, mem, na, nx, length, fx, fy, tau):
    """``_still_floating`` keeping the logs that stop in the mesh: (floating, stopped) counts.

    mem[:na] the floating logs, mem[na:na + nx] those stopped before; after the call the
    floating ones come first, in order, then the newly stopped ones still in the mesh
    (resting or stranded: grounded from the next window on), at rest (their velocity set to
    0, as the tracker sets it after the window), then the earlier stopped.  A log that left
    the mesh leaves the island.
    """
    old = mem[:na].copy()
    k = _still_floating(S, F, flag, P, thr, friction, opt, box, mem, na, length, fx, fy, tau)
    if k == na:
        return na, nx
    j = 0
    b = k
    for a in range(na):
        if j < k and mem[j] == old[a]:
            j += 1
        elif flag[old[a]] != OUTSIDE:
            mem[b] = old[a]
            b += 1
            for q in range(UB, OMEGA + 1):
                S[old[a], q] = 0.0
    for a in range(nx):  # the earlier stopped ones, behind the new (b <= na: moving down)
        mem[b + a] = mem[na + a]
    return k, b - k + nx


@nb.njit(cache=True, inline="always")
def _sample_at(x, y, hint, ts, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
               recovered, loc):
    a, inv, vals = _pair_at(ts, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, False)
    return sample_point(x, y, hint, a, inv, vals, dry_depth, recovered, loc)


@nb.njit(cache=True, _nrt=False)
def _resample(S, Sl, F, flag, face, mem, na, t, vals_c, T0c, gap_c, vals_n, T0n, gap_n,
              t_split, dry_depth, recovered, loc):
    """The island's states Sl[:na] back into S, and the flow sampled again at them.

    Without reference counting: inlined into the island kernels the sampling counted the references
    of the flow's arrays and the locator's at every log.
    """
    for a in range(na):
        i = mem[a]
        for k in range(6):
            S[i, k] = Sl[a, k]
        f, fg, fl = _sample_at(S[i, X], S[i, Y], face[i], t, vals_c, T0c, gap_c, vals_n, T0n,
                               gap_n, t_split, dry_depth, recovered, loc)
        face[i], flag[i] = f, fg
        for k in range(NVAR):
            F[i, k] = fl[k]


@nb.njit(cache=True, _nrt=False)
def _step_members(S, D0, F, flag, face, lin0, mem, na, P, opt, t, dt, method, tracer,
                  rotation, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
                  recovered, loc):
    """``_step_one`` for the logs mem[:na], in one call.

    The step is inlined here rather than called once per member: a call passes some 30
    arguments (arrays, the locator's tuple), and with a call per member the per-log run of a
    Moreau-Jean crowd took 1.2x as long (the same numbers; BENCHMARKS.md, per-log clocks).
    """
    for a in range(na):
        i = mem[a]
        _step_one(S, D0, F, flag, face, lin0, i, P[i], opt, t, dt, method, tracer, rotation,
                  vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc)


@nb.njit(cache=True, inline="always")
def _step_one(S, D0, F, flag, face, lin0, i, p, opt, t, dt, method, tracer, rotation,
              vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc):
    """One integrator step of log i from t (first stage D0[i]); flow and D0 at its end."""
    s = row(S, i)
    d0 = row(D0, i)
    hint = face[i]
    s, hint, a_e, inv_e, vals_e = _free_step(s, d0, hint, t, dt, method, p, opt, vals_c, T0c,
                                             gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
                                             recovered, loc)
    f, fg, fl = sample_point(s[X], s[Y], hint, a_e, inv_e, vals_e, dry_depth, recovered, loc)
    face[i] = f
    flag[i] = fg
    for q in range(NVAR):
        F[i, q] = fl[q]
    if tracer:
        om = 0.5 * (fl[DVDX] - fl[DUDY]) if rotation else 0.0
        s = (s[X], s[Y], s[THETA], fl[U], fl[V], om)
    put_row(S, i, s)


@nb.njit(cache=True, _nrt=False)
def _first_stage(S, F, D0, lin0, P, opt, mem, na):
    """D0, lin0 of the active members at their state and sampled flow (``Tracker._rhs``)."""
    for a in range(na):
        i = mem[a]
        fl = (F[i, 0], F[i, 1], F[i, 2], F[i, 3], F[i, 4], F[i, 5], F[i, 6], F[i, 7],
              F[i, 8], F[i, 9], F[i, 10], F[i, 11])
        d, ln = log_rhs(row(S, i), fl, P[i], opt, True)
        put_row(D0, i, d)
        for q in range(NLIN):
            lin0[i, q] = ln[q]


@nb.njit(cache=True, inline="always")
def _grow_box(box, i, s, length, fx, fy, tau):
    """Swept box (frame moving at fx, fy; tau since the window's start) of log i's axis ends."""
    ax, ay, bx, by = log_endpoints(s[X] - fx * tau, s[Y] - fy * tau, s[THETA], length)
    box[i, 0] = min(box[i, 0], min(ax, bx))
    box[i, 1] = min(box[i, 1], min(ay, by))
    box[i, 2] = max(box[i, 2], max(ax, bx))
    box[i, 3] = max(box[i, 3], max(ay, by))


@nb.njit(cache=True)
def island_advance(S, F, flag, face, D0, lin0, P, opt, length, radius, mass, inertia, ids,
                   members, start, caps, owner, ocaps, ostart, t0, t_stop, time_tol, method,
                   lf, ang, drag_fraction, explicit, max_step, min_step, tracer, rotation,
                   thr, friction, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
                   recovered, loc, tolerance, eps, rest_speed, near_share, max_events,
                   keep_stopped, active_in, fx, fy, box, obst_impulse, hit_t, hit_log,
                   hit_other, hit_j,
                   hit_x, hit_y, nhit, active_out, nactive, stats, dt_lim, code, t_code):
    """Run each island of ``members``/``start`` from t0 to t_stop on its own clock.

    Parameters
    ----------
    S, F, flag, face, D0, lin0 : arrays (n, ...)
        The floating logs' states at t0, flow sampled there (time t0), face hints; the
        members' rows are advanced in place (D0, lin0 are work rows).
    P, opt, length, radius, mass, inertia, ids : the logs' parameters and ids.
    members, start : int64 arrays
        Island q's logs (positions in S) are members[start[q]:start[q + 1]].
    caps, owner, ocaps, ostart
        Obstacle capsules (k, 5) and their obstacle; island q may touch the capsules
        ocaps[ostart[q]:ostart[q + 1]].
    t0, t_stop, time_tol, method, lf, ang, drag_fraction, explicit, max_step, min_step,
    tracer, rotation, thr, friction, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split,
    dry_depth, recovered, loc
        As ``clock_kernel.per_log_mesh_advance``.
    tolerance, eps, rest_speed, near_share, max_events
        The contact model's tolerance (share of the smallest radius), restitution, resting
        speed, ``near`` and ``max_events``.
    keep_stopped : bool
        A log that stops floating within the window, in the mesh, stays in its island as a
        fixed body (its velocity set to 0, zero inverse mass) to the window's end, as it is a
        grounded obstacle from the next window on (``[contact] grounded``, docs/model.md 13);
        False: it leaves the island and the others pass over it.
    active_in : sorted int64
        Pair keys (``model._body_pairs``) in contact at t0 (a hit is a contact that starts).
    fx, fy, box
        Each member's swept box (its axis ends, in a frame moving at fx, fy from t0) grows.
    obst_impulse : (n_obstacles, 2), added to.
    hit_*, nhit : the hit buffer and its fill (nhit[0]); code HIT_FULL when full.
    active_out, nactive : the pair keys in contact at t_stop (nactive[0] of them).
    stats : (NSTAT) int64, added to; dt_lim : [shortest, longest] island step.
    code, t_code : per island outcome (OK, TOO_SMALL, DIVERGED, JAM, HIT_FULL) and its time.
    """
    nmax = 0
    omax = 0
    for q in range(start.size - 1):
        nmax = max(nmax, start[q + 1] - start[q])
        omax = max(omax, ostart[q + 1] - ostart[q])
    cap_c = nmax * (nmax - 1) // 2 + nmax * omax + 1
    c1 = np.empty(cap_c, np.int64)
    c2 = np.empty(cap_c, np.int64)
    cres = np.empty((cap_c, NRES))
    e1 = np.empty(cap_c, np.int64)
    e2 = np.empty(cap_c, np.int64)
    eres = np.empty((cap_c, NRES))
    ckey = np.empty(cap_c, np.int64)
    imp = np.empty(cap_c)
    prev = np.empty(cap_c + active_in.size, np.int64)
    mem = np.empty(nmax, np.int64)
    margin = np.empty(nmax)
    keep_S = np.empty((nmax, 6))
    keep_F = np.empty((nmax, NVAR))
    keep_flag = np.empty(nmax, np.int8)
    keep_face = np.empty(nmax, np.int64)
    inv_m = 1.0 / mass
    inv_i = 1.0 / inertia
    # the contact impulses in local numbering: a (na, 6) view rebuilt per step
    Sl = np.empty((nmax, 6))
    lm = np.empty(nmax)
    li = np.empty(nmax)
    b1 = np.empty(cap_c, np.int64)
    b2 = np.empty(cap_c, np.int64)
    wk = np.empty((nmax, 6))  # _contacts' work rows
    for q in range(start.size - 1):
        code[q] = OK
        t_code[q] = t0
        na = start[q + 1] - start[q]
        for a in range(na):
            mem[a] = members[start[q] + a]
        o0, o1 = ostart[q], ostart[q + 1]
        # pairs in contact at t0 (hits are contacts that start)
        npv = 0
        for a in range(na):
            lo = np.searchsorted(active_in, _pair_key(ids[mem[a]], 0))
            hi = np.searchsorted(active_in, _pair_key(ids[mem[a]] + 1, 0))
            for k in range(lo, hi):
                prev[npv] = active_in[k]
                npv += 1
        t = t0
        w_t, w_dt, w_ev, w_st = -np.inf, 0.0, 0, 0
        nt = na  # mem[na:nt]: logs stopped in the window, fixed (keep_stopped)
        while t < t_stop and na > 0:
            # the island's own bound (Tracker.max_step over its logs)
            _first_stage(S, F, D0, lin0, P, opt, mem, na)
            dt = max_step
            rmin = np.inf
            for a in range(na):
                i = mem[a]
                ln = (lin0[i, 0], lin0[i, 1], lin0[i, 2], lin0[i, 3], lin0[i, 4])
                dt = min(dt, _own_bound(row(S, i), length[i], ln, lf, ang, drag_fraction,
                                        explicit, np.inf))
                rmin = min(rmin, radius[mem[a]])
            dt = min(dt, t_stop - t)
            if dt < min_step and t_stop - t > min_step:
                code[q], t_code[q] = TOO_SMALL, t
                break
            tol = tolerance * rmin
            # contacts within tol: impulses (ContactModel._event)
            nc = _contacts(S, length, radius, mem, na, nt, caps, ocaps, o0, o1, margin, False,
                           tol, c1, c2, cres, wk)
            events = 0
            for c in range(nc):
                i = mem[c1[c]]
                other = ids[mem[c2[c]]] if c2[c] >= 0 else OBST_BIT + owner[ocaps[o0 - c2[c]
                                                                                 - 1]]
                ckey[c] = _pair_key(ids[i], other)
            if nc:
                vmax = 0.0
                for a in range(nt):
                    i = mem[a]
                    for k in range(6):
                        Sl[a, k] = S[i, k]
                    if a < na:
                        lm[a], li[a] = inv_m[i], inv_i[i]
                    else:  # fixed
                        lm[a] = li[a] = 0.0
                    vmax = max(vmax, max(abs(S[i, UB]), abs(S[i, VB])))
                vtol = 1e-10 * (vmax + 1e-3)
                for c in range(nc):
                    imp[c] = 0.0
                    b1[c] = c1[c]
                    b2[c] = c2[c] if c2[c] >= 0 else -1
                while True:  # impulse.resolve_impulses
                    applied = 0
                    for c in range(nc):
                        j = pair_impulse(Sl, lm, li, b1[c], b2[c], cres[c, NX], cres[c, NY],
                                         cres[c, CX], cres[c, CY], eps, vtol, rest_speed)
                        if j != 0.0:
                            imp[c] += j
                            applied += 1
                            events += 1
                    if applied == 0 or events >= max_events:
                        break
                if events >= max_events:
                    code[q], t_code[q] = JAM, t
                    break
                stats[ST_EVENTS] += events
                stats[ST_MAX_CONTACTS] = max(stats[ST_MAX_CONTACTS], nc)
                for c in range(nc):
                    if c2[c] < 0 and imp[c] != 0.0 and obst_impulse.shape[0]:
                        o = owner[ocaps[o0 - c2[c] - 1]]
                        obst_impulse[o, 0] -= imp[c] * cres[c, NX]
                        obst_impulse[o, 1] -= imp[c] * cres[c, NY]
                # hits: contacts that start with an impulse, one per (log, other) at t
                first = nhit[0]
                for c in range(nc):
                    if not imp[c] > 0.0:
                        continue
                    seen = False
                    for k in range(npv):
                        if prev[k] == ckey[c]:
                            seen = True
                            break
                    if seen:
                        continue
                    lid = ids[mem[c1[c]]]
                    oth = ids[mem[c2[c]]] if c2[c] >= 0 else -(owner[ocaps[o0 - c2[c] - 1]]
                                                               + 1)
                    if not add_hit(first, nhit, hit_t, hit_log, hit_other, hit_j, hit_x, hit_y,
                                   t, lid, oth, imp[c], cres[c, CX], cres[c, CY]):
                        code[q] = HIT_FULL
                        break
                if code[q] == HIT_FULL:
                    break
                for k in range(first, nhit[0]):
                    hit_x[k] /= hit_j[k]
                    hit_y[k] /= hit_j[k]
                moved = 0
                if rest_speed > 0.0:
                    moved = separate_resting(Sl, lm, b1[:nc], b2[:nc], cres[:nc], rest_speed)
                if moved:  # moved apart: the flow sampled again where they are
                    stats[ST_SEPARATIONS] += 1
                    _resample(S, Sl, F, flag, face, mem, na, t, vals_c, T0c, gap_c, vals_n,
                              T0n, gap_n, t_split, dry_depth, recovered, loc)
                else:
                    for a in range(na):
                        for k in range(6):
                            S[mem[a], k] = Sl[a, k]
            if events:
                # the impulses changed velocities: the bound of the new ones (as
                # ContactModel._event: a log stopped dead at a pier stepped on past it)
                _first_stage(S, F, D0, lin0, P, opt, mem, na)
                for a in range(na):
                    i = mem[a]
                    ln = (lin0[i, 0], lin0[i, 1], lin0[i, 2], lin0[i, 3], lin0[i, 4])
                    dt = min(dt, _own_bound(row(S, i), length[i], ln, lf, ang, drag_fraction,
                                            explicit, np.inf))
            npv = nc
            for c in range(nc):
                prev[c] = ckey[c]
            # jam watch (ContactModel._count)
            if t - w_t >= w_dt:
                w_t, w_dt, w_ev, w_st = t, dt, 0, 0
            w_ev += events
            w_st += 1
            if w_ev > max_events or w_st > max_events:
                code[q], t_code[q] = JAM, t
                break
            # conservative advancement on the candidates within the motion of dt
            h = dt
            for a in range(nt):
                i = mem[a]
                sp = (np.hypot(S[i, UB], S[i, VB])
                      + abs(S[i, OMEGA]) * (0.5 * length[i] + radius[i]))
                margin[a] = sp * dt + tol
            ncand = _contacts(S, length, radius, mem, na, nt, caps, ocaps, o0, o1, margin, True,
                              tol, e1, e2, eres, wk)
            if ncand:
                h = _conservative(S, length, radius, mem, caps, ocaps, o0, e1, e2, eres, ncand,
                                  tol, dt, near_share * rmin)
            # the step; rejected and shortened while a contact was missed (the first stage
            # again where impulses may have changed the logs: with no contact it is the one
            # computed for the bound, on the same states and flow)
            if nc:
                _first_stage(S, F, D0, lin0, P, opt, mem, na)
            for a in range(na):
                i = mem[a]
                for k in range(6):
                    keep_S[a, k] = S[i, k]
                for k in range(NVAR):
                    keep_F[a, k] = F[i, k]
                keep_flag[a], keep_face[a] = flag[i], face[i]
            gmin = np.inf
            while True:
                if h < min_step:
                    code[q], t_code[q] = JAM, t
                    break
                _step_members(S, D0, F, flag, face, lin0, mem, na, P, opt, t, h, method,
                              tracer, rotation, vals_c, T0c, gap_c, vals_n, T0n, gap_n,
                              t_split, dry_depth, recovered, loc)
                stats[ST_ADVANCES] += 1
                ne = _contacts(S, length, radius, mem, na, nt, caps, ocaps, o0, o1, margin, False,
                               tol, e1, e2, eres, wk)
                gmin = np.inf
                kdeep = -1
                for c in range(ne):
                    if eres[c, GAP] < gmin:
                        gmin, kdeep = eres[c, GAP], c
                ok = gmin >= -tol
                if not ok:
                    ok = _overlaps_kept(mem, ids, owner, ocaps, o0, c1, c2, cres, ckey, nc,
                                        e1, e2, eres, ne, tol)
                if ok:
                    break
                for a in range(na):  # restore
                    i = mem[a]
                    for k in range(6):
                        S[i, k] = keep_S[a, k]
                    for k in range(NVAR):
                        F[i, k] = keep_F[a, k]
                    flag[i], face[i] = keep_flag[a], keep_face[a]
                _first_stage(S, F, D0, lin0, P, opt, mem, na)
                h = _shorter(mem, ids, owner, ocaps, o0, ckey, cres, nc, e1, e2, eres, kdeep,
                             tol, h)
                stats[ST_REJECTED] += 1
            if code[q] != OK:
                break
            t_prev = t
            t = t + h
            if t_stop - t <= time_tol:
                t = t_stop
            taken = t - t_prev
            dt_lim[0] = min(dt_lim[0], taken)
            dt_lim[1] = max(dt_lim[1], taken)
            stats[ST_STEPS] += 1
            stats[ST_LOG_STEPS] += na
            if _diverged(S, mem, na):
                code[q], t_code[q] = DIVERGED, t
                break
            # swept boxes; statuses: a log that stops floating leaves the island's motion;
            # with keep_stopped it stays a fixed body, at rest, to the window's end
            if keep_stopped:
                na, nx = split_stopped(S, F, flag, P, thr, friction, opt, box, mem, na, nt - na,
                                       length, fx, fy, t - t0)
                nt = na + nx
            else:
                na = _still_floating(S, F, flag, P, thr, friction, opt, box, mem, na, length,
                                     fx, fy, t - t0)
                nt = na
        if code[q] == HIT_FULL:
            return
        # the pairs in contact at the end (the model's _active after its last step)
        for c in range(npv):
            if nactive[0] < active_out.size:
                active_out[nactive[0]] = prev[c]
                nactive[0] += 1


@nb.njit(cache=True)
def _other_key(mem, ids, owner, ocaps, o0, a, b):
    i = mem[a]
    other = ids[mem[b]] if b >= 0 else OBST_BIT + owner[ocaps[o0 - b - 1]]
    return _pair_key(ids[i], other)


@nb.njit(cache=True)
def _overlaps_kept(mem, ids, owner, ocaps, o0, c1, c2, cres, ckey, nc, e1, e2, eres, ne, tol):
    """``ContactModel._overlaps_kept``: every deep overlap at the end was one at the start."""
    if nc == 0:
        return False
    for c in range(ne):
        if eres[c, GAP] >= -tol:
            continue
        key = _other_key(mem, ids, owner, ocaps, o0, e1[c], e2[c])
        found = False
        for k in range(nc):
            if ckey[k] == key:
                before = cres[k, GAP]
                if not (before < -tol and eres[c, GAP] >= before - tol):
                    return False
                found = True
                break
        if not found:
            return False
    return True


@nb.njit(cache=True)
def _shorter(mem, ids, owner, ocaps, o0, ckey, cres, nc, e1, e2, eres, kdeep, tol, h):
    """``ContactModel._shorter``: the deepest pair, closing as it did over h, ends above -tol."""
    g_end = eres[kdeep, GAP]
    key = _other_key(mem, ids, owner, ocaps, o0, e1[kdeep], e2[kdeep])
    g0 = tol
    for k in range(nc):
        if ckey[k] == key:
            g0 = cres[k, GAP]
            break
    closing = g0 - g_end
    if closing <= 0.0:
        return 0.5 * h
    return min(0.5 * h, max(h / 16.0, 0.9 * h * max(g0 + tol, 0.0) / closing))


@nb.njit(cache=True)
def _conservative(S, length, radius, mem, caps, ocaps, o0, e1, e2, eres, ncand, tol, dt, near):
    """``toi.conservative_step`` on the island's candidates (global log numbering)."""
    body1 = np.empty(ncand, np.int64)
    body2 = np.empty(ncand, np.int64)
    for c in range(ncand):
        body1[c] = mem[e1[c]]
        body2[c] = mem[e2[c]] if e2[c] >= 0 else -1
    return conservative_step(S, length, radius, body1, body2, eres[:ncand], tol, dt, near)
