"""Per-log clocks with Moreau-Jean contacts, the kernel: every contact island on its own clock.

``driftlog.clocks.contact_window`` finds the contact islands of a contact window (the logs whose
swept boxes may touch each other or an obstacle, connected components); with
``contact.method = "moreau"`` this kernel then runs each island from the window's start to its
end with the Moreau-Jean steps of ``driftlog.contact.ContactModel`` (docs/model.md 13.6) among
the island's own logs, the island on its own clock (docs/model.md 11.1, eqs. (81)-(83)):

1. the island's own bound (eq. (70) over its logs) and, where two of its bodies are near (boxes
   grown by their motion over the step overlap), no such pair moves against each other by more
   than ``motion_share`` of the smallest radius (eq. (81); a log against a fixed obstacle by
   its own motion);
2. the free step of its logs (the fused RK4 / Euler step, the flow sampled P1 at each stage
   time, as ``driftlog.clock_kernel``);
3. its contacts at the start of the step, boxes grown by the motion of the step at the larger of
   the start and free-end speeds: the closest points of each pair and the four axis-end
   contacts within the pair's margin (eq. (82));
4. the impulses of all its contacts together (``contact.moreau.moreau_solve``: eqs. (52)-(54),
   projected Gauss-Seidel, then the split-impulse position pass), the impulses passed to the
   fixed obstacles, hits (contacts that start pushing), the flow sampled again where the
   contacts moved the logs;
5. the statuses (a log that stops floating leaves its island).

An island's contacts never shorten another island's step, and islands share no log: on
several threads (``moreau_islands_parallel``) each island runs on one of them and writes to its
own range of the kernel's buffers, gathered afterwards in the islands' order (the serial
kernel's results bit for bit).  Islands are flat CSR arrays
(``members[start[q]:start[q + 1]]``, obstacle capsules ``ocaps[ostart[q]:ostart[q + 1]]``), its
bodies in local arrays (``moreau_solve`` on the island alone); the candidate pairs of an island
are found by testing all pairs (small islands) or by sorting the boxes along x and sweeping
(eq. (83)): the same pairs, put in the order of the logs, then of the capsules.

The numbers equal those of the Python contact model run island by island on the same islands
(``ContactModel.island_kernel = False``) to round-off, except for the order of the contacts
within an island (pairs by member order here, by the broad phase's grid order there), which
changes where Gauss-Seidel stops: within its tolerance (1e-9 of the largest speed).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.clock_kernel import _own_bound
from driftlog.columns import CX, CY, GAP, NRES, NX, NY, OMEGA, THETA, UB, VB, X, Y
from driftlog.contact.geometry import capsule_gap, capsule_row, log_endpoints
from driftlog.contact.moreau import moreau_solve_into, solve_workspace
from driftlog.contact.native import _ends_against
from driftlog.integrators import row
from driftlog.island_kernel import (
    ALL_PAIRS,
    DIVERGED,
    HIT_FULL,
    OBST_BIT,
    OK,
    TOO_SMALL,
    _diverged,
    _first_stage,
    _log_cap_apart,
    _log_log_apart,
    _pair_key,
    _resample,
    _step_members,
    _still_floating,
    add_hit,
    island_pairs,
    split_stopped,
)

__all__ = ["moreau_islands", "moreau_islands_parallel", "island_pairs", "NSTAT", "OK",
           "TOO_SMALL", "DIVERGED", "HIT_FULL"]

# moreau_islands' statistics (stats[k]); ST_RERUNS: islands that moreau_islands_parallel ran
# again, alone, because they filled their range of its buffers; ST_CAPPED: contact steps whose
# Gauss-Seidel solve stopped at its cap of sweeps without converging
(ST_STEPS, ST_ADVANCES, ST_PGS, ST_PGS_MAX, ST_MAX_CONTACTS, ST_LOG_STEPS, ST_RERUNS,
 ST_CAPPED) = range(8)
NSTAT = 8


@nb.njit(cache=True, inline="always")
def _pair_speed(Sl, ln, rd, a, e):
    """How fast the geometry of pair (a, e) changes: relative speed plus both turning rates.

    e >= 0 a log, e < 0 a fixed obstacle capsule (eq. (81)): |U_a - U_e| + |omega_a| (L_a/2
    + r_a) + |omega_e| (L_e/2 + r_e), the obstacle's terms zero.
    """
    s = abs(Sl[a, OMEGA]) * (0.5 * ln[a] + rd[a])
    if e >= 0:
        return (np.hypot(Sl[a, UB] - Sl[e, UB], Sl[a, VB] - Sl[e, VB]) + s
                + abs(Sl[e, OMEGA]) * (0.5 * ln[e] + rd[e]))
    return np.hypot(Sl[a, UB], Sl[a, VB]) + s


@nb.njit(cache=True, _nrt=False)
def _manifold_rows(Sl, ln, rd, pairs, m, caps, ocaps, margin, res, b1, b2, cap, tmp):
    """``ContactModel.detect_manifold`` on an island's first m candidate pairs at states Sl.

    The closest points of every pair, then the four axis-end contacts of every pair (ends of
    body 1 on body 2, of body 2 on body 1) whose gap is within the pair's margins, into
    ``res``, ``b1``, ``b2``, ``cap`` (at most 5 rows per pair): local bodies (b2 = -1 for a
    capsule, whose index in ``caps`` is cap).  Returns how many.  Compiled without reference
    counting: the row views and the calls per pair counted references at every pair
    (BENCHMARKS.md, "Islands of speculative contacts").
    """
    for c in range(m):
        a, e = pairs[c, 0], pairs[c, 1]
        ax, ay, bx, by = log_endpoints(Sl[a, X], Sl[a, Y], Sl[a, THETA], ln[a])
        b1[c] = a
        if e >= 0:
            cx, cy, dx, dy = log_endpoints(Sl[e, X], Sl[e, Y], Sl[e, THETA], ln[e])
            capsule_gap(ax, ay, bx, by, rd[a], cx, cy, dx, dy, rd[e], res[c])
            b2[c], cap[c] = e, -1
        else:
            k = ocaps[-e - 1]
            qa, qb, qc, qd, qr = capsule_row(caps, k)
            capsule_gap(ax, ay, bx, by, rd[a], qa, qb, qc, qd, qr, res[c])
            b2[c], cap[c] = -1, k
    k = m
    for c in range(m):
        a, e = pairs[c, 0], pairs[c, 1]
        ax, ay, bx, by = log_endpoints(Sl[a, X], Sl[a, Y], Sl[a, THETA], ln[a])
        if e >= 0:
            cx, cy, dx, dy = log_endpoints(Sl[e, X], Sl[e, Y], Sl[e, THETA], ln[e])
            _ends_against(ax, ay, bx, by, rd[a], cx, cy, dx, dy, rd[e], False, tmp, 0)
            _ends_against(cx, cy, dx, dy, rd[e], ax, ay, bx, by, rd[a], True, tmp, 2)
            m1 = margin[a] + margin[e]
        else:
            qa, qb, qc, qd, qr = capsule_row(caps, cap[c])
            _ends_against(ax, ay, bx, by, rd[a], qa, qb, qc, qd, qr, False, tmp, 0)
            _ends_against(qa, qb, qc, qd, qr, ax, ay, bx, by, rd[a], True, tmp, 2)
            m1 = margin[a]
        for r in range(4):
            # an end across the other body's axis (crossed axes) would be pushed through it:
            # only the ends whose normal agrees with the pair's (eq. (86))
            if tmp[r, GAP] <= m1 and tmp[r, NX] * res[c, NX] + tmp[r, NY] * res[c, NY] >= 0.0:
                for q in range(NRES):
                    res[k, q] = tmp[r, q]
                b1[k], b2[k], cap[k] = a, b2[c], cap[c]
                k += 1
    return k


@nb.njit(cache=True)
def _moving_pairs(Sl, ln, rd, na, nt, margin, caps, ocaps):
    """``island_pairs`` of the nt bodies whose first is one of the na moving logs.

    The bodies na .. nt - 1 are fixed (stopped logs, ``island_kernel.split_stopped``): a
    pair of two fixed bodies, or of a fixed body and an obstacle, has nothing to solve.
    """
    pairs, _ = island_pairs(Sl, ln, rd, nt, margin, caps, ocaps)
    if nt == na:
        return pairs
    keep = np.empty(pairs.shape[0], np.bool_)
    for c in range(pairs.shape[0]):
        keep[c] = pairs[c, 0] < na  # log pairs are (a, b) with a < b
    return pairs[keep]


@nb.njit(cache=True)
def _min_gap(Sl, ln, rd, na, caps, ocaps, tol):
    """The least gap of the candidate pairs within tol (``ContactModel.check_overlap``)."""
    margin = np.full(na, tol)
    pairs, _ = island_pairs(Sl, ln, rd, na, margin, caps, ocaps)
    return _least_gap(Sl, ln, rd, pairs, pairs.shape[0], caps, ocaps, np.empty(NRES))


@nb.njit(cache=True, _nrt=False)
def _least_gap(Sl, ln, rd, pairs, m, caps, ocaps, out):
    """The least gap of the first m pairs (``out``: a row of ``NRES``, work)."""
    g = np.inf
    for c in range(m):
        a, e = pairs[c, 0], pairs[c, 1]
        ax, ay, bx, by = log_endpoints(Sl[a, X], Sl[a, Y], Sl[a, THETA], ln[a])
        if e >= 0:
            cx, cy, dx, dy = log_endpoints(Sl[e, X], Sl[e, Y], Sl[e, THETA], ln[e])
            g = min(g, capsule_gap(ax, ay, bx, by, rd[a], cx, cy, dx, dy, rd[e], out))
        else:
            qa, qb, qc, qd, qr = capsule_row(caps, ocaps[-e - 1])
            g = min(g, capsule_gap(ax, ay, bx, by, rd[a], qa, qb, qc, qd, qr, out))
    return g


@nb.njit(cache=True, _nrt=False)
def _near_pairs(Sl, ln, rd, nt, na, margin, caps, ocaps, ex, ey, out):
    """``_moving_pairs`` of an island of at most ``ALL_PAIRS`` bodies, into ``out``; how many.

    The same pairs in the same order (every pair tested, log pairs by a then b, then the
    capsule pairs by a then c), with no allocation: ``ex``, ``ey`` (>= nt) are work rows and
    ``out`` has room for every pair of the island (``island_workspace``).
    """
    no = ocaps.size
    for a in range(nt):
        h = 0.5 * ln[a]
        ex[a] = h * abs(np.cos(Sl[a, THETA])) + rd[a] + margin[a]
        ey[a] = h * abs(np.sin(Sl[a, THETA])) + rd[a] + margin[a]
    m = 0
    for a in range(na):
        for b in range(a + 1, nt):
            if not _log_log_apart(Sl, a, b, ex, ey):
                out[m, 0], out[m, 1] = a, b
                m += 1
    for a in range(na):
        for c in range(no):
            if not _log_cap_apart(Sl, a, ex, ey, caps, ocaps[c]):
                out[m, 0], out[m, 1] = a, -(c + 1)
                m += 1
    return m


@nb.njit(cache=True, inline="always")
def _candidates(small, Sl, ln, rd, nt, na, margin, caps, ocaps, ex, ey, pb):
    """The candidate pairs of the moving logs and how many.

    ``_near_pairs`` into ``pb`` for an island of at most ``ALL_PAIRS`` bodies (``small``),
    else ``_moving_pairs``.
    """
    if small:
        return pb, _near_pairs(Sl, ln, rd, nt, na, margin, caps, ocaps, ex, ey, pb)
    pairs = _moving_pairs(Sl, ln, rd, na, nt, margin, caps, ocaps)
    return pairs, pairs.shape[0]


@nb.njit(cache=True, _nrt=False)
def _near_gap(Sl, ln, rd, nt, caps, ocaps, tol, margin, ex, ey, pairs, out):
    """``_min_gap`` of at most ``ALL_PAIRS`` bodies, on work arrays.

    ``margin``, ``ex``, ``ey``, ``pairs``: ``_near_pairs``' work rows; ``out``: one row of
    ``NRES``.
    """
    for a in range(nt):
        margin[a] = tol
    m = _near_pairs(Sl, ln, rd, nt, nt, margin, caps, ocaps, ex, ey, pairs)
    return _least_gap(Sl, ln, rd, pairs, m, caps, ocaps, out)


@nb.njit(cache=True, _nrt=False)
def _island_rows(S, lin0, mem, na, nt, length, radius, mass, inertia, S0l, Sl, ln, rd, lm, li,
                 lf, ang, drag_fraction, explicit, max_step):
    """An island step's local rows and its own bound (eq. (70)): (dt, r_min).

    The rows: states at the step's start, lengths, radii, inverse masses and inertias (the
    stopped logs mem[na:nt] fixed).

    Here and in ``_near_speed`` and ``_free_margins`` without reference counting: in
    ``_islands`` itself the inlined helpers counted the references of their arrays at every
    log and pair of every step.
    """
    dt = max_step
    rmin = np.inf
    for a in range(na, nt):  # a stopped log: at rest, immovable (zero inverse mass)
        i = mem[a]
        for k in range(6):
            S0l[a, k] = Sl[a, k] = S[i, k]
        ln[a], rd[a] = length[i], radius[i]
        lm[a] = li[a] = 0.0
        rmin = min(rmin, radius[i])
    for a in range(na):
        i = mem[a]
        lnr = (lin0[i, 0], lin0[i, 1], lin0[i, 2], lin0[i, 3], lin0[i, 4])
        dt = min(dt, _own_bound(row(S, i), length[i], lnr, lf, ang, drag_fraction, explicit,
                                np.inf))
        rmin = min(rmin, radius[i])
        for k in range(6):
            S0l[a, k] = S[i, k]
        ln[a], rd[a] = length[i], radius[i]
        lm[a], li[a] = 1.0 / mass[i], 1.0 / inertia[i]
    return dt, rmin


@nb.njit(cache=True, _nrt=False)
def _near_speed(S0l, ln, rd, pairs, npair, na, near, relative_motion):
    """The speed that bounds a step near contacts (eq. (81)) over the first npair pairs."""
    speed = 0.0
    if relative_motion:
        # the speed at which each near pair's geometry changes
        for c in range(npair):
            a, e = pairs[c, 0], pairs[c, 1]
            speed = max(speed, _pair_speed(S0l, ln, rd, a, e))
    else:
        for c in range(npair):
            near[pairs[c, 0]] = True
            if pairs[c, 1] >= 0:
                near[pairs[c, 1]] = True
        for a in range(na):
            if near[a]:
                speed = max(speed, np.hypot(S0l[a, UB], S0l[a, VB])
                            + abs(S0l[a, OMEGA]) * (0.5 * ln[a] + rd[a]))
    return speed


@nb.njit(cache=True, _nrt=False)
def _free_margins(S, mem, na, S0l, Sl, ln, rd, margin, dt, tol):
    """The free step's states into Sl and the pairs' margins over it; the largest speed."""
    vmax = 0.0
    for a in range(na):
        i = mem[a]
        for k in range(6):
            Sl[a, k] = S[i, k]
        vmax = max(vmax, max(abs(Sl[a, UB]), abs(Sl[a, VB])))
        # candidates over the motion of the step: the larger of the two speeds
        fu = max(abs(S0l[a, UB]), abs(Sl[a, UB]))
        fv = max(abs(S0l[a, VB]), abs(Sl[a, VB]))
        fo = max(abs(S0l[a, OMEGA]), abs(Sl[a, OMEGA]))
        margin[a] = (np.hypot(fu, fv) + fo * (0.5 * ln[a] + rd[a])) * dt + tol
    return vmax


@nb.njit(cache=True)
def island_workspace(nmax, nobst, solver):
    """``_islands``' work arrays for islands of up to nmax logs and nobst obstacle capsules.

    For the contact ``solver`` (``contact.moreau.PGS`` or ``NNCG``).

    An island step used to allocate some forty arrays (candidate pairs twice, the contact
    manifold, the solver's rows, the least gap), and a crowd's windows take millions of steps
    of islands of a few logs (BENCHMARKS.md, "Islands of speculative contacts"): made once per
    kernel call instead.  The pair and contact rows hold what such an island can have, up to
    ``ALL_PAIRS`` bodies; a larger island grows its own copy (``_islands``).
    """
    n = min(nmax, ALL_PAIRS)
    npair = max(min(n * (n - 1) // 2 + n * nobst, ALL_PAIRS * ALL_PAIRS // 2), 1)
    ncon = 5 * npair
    cap = max(ncon, nmax + 1)
    return (np.empty(16, np.int64), np.empty(ALL_PAIRS), np.empty(ALL_PAIRS),
            np.empty(ALL_PAIRS), np.empty((npair, 2), np.int64), np.empty((ncon, NRES)),
            np.empty(ncon, np.int64), np.empty(ncon, np.int64), np.empty(ncon, np.int64),
            np.empty((4, NRES)), np.empty(cap)) + solve_workspace(cap, solver)


@nb.njit(cache=True)
def island_work(n, nob, solver):
    """``_islands``' work arrays for islands of up to n logs and nob obstacle capsules (solver).

    (mem, S0l, Sl, ln, rd, lm, li, margin, near, ws): the island's members, start and free
    states, lengths, radii, inverse masses and inertias, motion margins, near flags, and
    ``island_workspace``'s arrays.
    """
    return (np.empty(n, np.int64), np.empty((n, 6)), np.empty((n, 6)), np.empty(n), np.empty(n),
            np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.bool_),
            island_workspace(n, nob, solver))


@nb.njit(cache=True)
def _grow(a, n):
    """The int64 array a, grown to hold at least n entries."""
    if n <= a.size:
        return a
    b = np.empty(max(n, 2 * a.size), np.int64)
    b[:a.size] = a
    return b


@nb.njit(cache=True)
def _islands(q0, q1, members, start, S, F, flag, face, D0, lin0, P, opt, length, radius, mass,
             inertia, ids, caps, owner, ocaps, ostart, t0, t_stop, time_tol, method, lf, ang,
             drag_fraction, explicit, max_step, min_step, tracer, rotation, thr, friction, vals_c,
             T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc, tolerance, eps,
             iterations, motion_share, relative_motion, island_stop, solver, keep_stopped,
             active_in, fx, fy, box, obst_impulse, direct, rec_o, rec_j, nrec, hit_t, hit_log,
             hit_other, hit_j, hit_x, hit_y, nhit, active_out, nactive, stats, lim, code, t_code,
             mem, S0l, Sl, ln, rd, lm, li, margin, near, ws):
    """Islands q0 .. q1 - 1 of ``moreau_islands`` from t0 to t_stop, one after another.

    Returns -1, or the island whose output buffer was full (the islands before it done).
    Each island writes its logs' rows, code[q], t_code[q], its hits from ``nhit[0]`` on, its
    pairs in touch from ``nactive[0]`` on and adds to ``stats`` and ``lim``.  The impulses on
    the fixed obstacles go to ``obst_impulse`` (``direct``) or, in the order they are made, to
    the records ``rec_o`` (obstacle), ``rec_j`` (impulse) from ``nrec[0]`` on, so that they can
    be added to ``obst_impulse`` later in the serial kernel's order.  mem .. near: work arrays
    of at least the largest island's size; ``ws``: ``island_workspace``'s.
    One call for many islands: a call counts the references of its sixty-odd array arguments
    on entry, and the islands of a crowd take one or two steps each on average (BENCHMARKS.md,
    "Islands of speculative contacts").
    """
    prev, ex, ey, mg, pb, mres, mb1, mb2, mcap, mtmp, Pc, fw, iw, bw, V, Vp = ws
    for q in range(q0, q1):
        code[q] = OK
        t_code[q] = t0
        na = start[q + 1] - start[q]
        for a in range(na):
            mem[a] = members[start[q] + a]
        oc = ocaps[ostart[q]:ostart[q + 1]]
        # pairs touching or pushing at t0 (a hit is a contact that starts pushing)
        npv = 0
        for a in range(na):
            lo = np.searchsorted(active_in, _pair_key(ids[mem[a]], 0))
            hi = np.searchsorted(active_in, _pair_key(ids[mem[a]] + 1, 0))
            prev = _grow(prev, npv + hi - lo)
            for k in range(lo, hi):
                prev[npv] = active_in[k]
                npv += 1
        t = t0
        nx = 0  # logs that stopped floating in the window: mem[na:na + nx], fixed (keep_stopped)
        while t < t_stop and na > 0:
            nt = na + nx
            # the island's own bound (Tracker.max_step over its logs)
            _first_stage(S, F, D0, lin0, P, opt, mem, na)
            dt, rmin = _island_rows(S, lin0, mem, na, nt, length, radius, mass, inertia, S0l, Sl,
                                    ln, rd, lm, li, lf, ang, drag_fraction, explicit, max_step)
            dt = min(dt, t_stop - t)
            if dt < min_step and t_stop - t > min_step:
                code[q], t_code[q] = TOO_SMALL, t
                break
            tol = tolerance * rmin
            # near contacts: no pair moves against each other by more than motion_share r_min
            # (eq. (81))
            for a in range(nt):
                sp = (np.hypot(S0l[a, UB], S0l[a, VB])
                      + abs(S0l[a, OMEGA]) * (0.5 * ln[a] + rd[a]))
                margin[a] = sp * dt + tol
                near[a] = False
            small = nt + oc.size <= ALL_PAIRS
            pairs, npair = _candidates(small, S0l, ln, rd, nt, na, margin, caps, oc, ex, ey, pb)
            if npair:
                speed = _near_speed(S0l, ln, rd, pairs, npair, na, near, relative_motion)
                if speed > 0.0:
                    dt = min(dt, motion_share * rmin / speed)
            # the free step
            _step_members(S, D0, F, flag, face, lin0, mem, na, P, opt, t, dt, method, tracer,
                          rotation, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
                          recovered, loc)
            stats[ST_ADVANCES] += 1
            vmax = _free_margins(S, mem, na, S0l, Sl, ln, rd, margin, dt, tol)
            t_prev = t
            t = t + dt
            if t_stop - t <= time_tol:
                t = t_stop
            pairs, npair = _candidates(small, S0l, ln, rd, nt, na, margin, caps, oc, ex, ey, pb)
            if 5 * npair > mb1.size:  # a large island: its own, larger rows
                mres = np.empty((10 * npair, NRES))
                mb1 = np.empty(10 * npair, np.int64)
                mb2 = np.empty(10 * npair, np.int64)
                mcap = np.empty(10 * npair, np.int64)
            nc = _manifold_rows(S0l, ln, rd, pairs, npair, caps, oc, margin, mres, mb1, mb2, mcap,
                                mtmp)
            b1, b2, cap, res = mb1, mb2, mcap, mres
            if nc:
                if nc > Pc.size or nt + 1 > Pc.size:
                    Pc = np.empty(2 * max(nc, nt + 1))
                    fw, iw, bw, V, Vp = solve_workspace(Pc.size, solver)
                vtol = 1e-9 * (vmax + 1e-3)
                it, resid = moreau_solve_into(S0l, Sl, lm, li, nt, b1, b2, res, nc, dt, eps, tol,
                                              tol, vtol, iterations, Pc, 0.2, island_stop, solver,
                                              fw, iw, bw, V, Vp)
                stats[ST_PGS] += it
                stats[ST_CAPPED] += 1 if resid > vtol else 0
                stats[ST_PGS_MAX] = max(stats[ST_PGS_MAX], it)
                stats[ST_MAX_CONTACTS] = max(stats[ST_MAX_CONTACTS], nc)
                for c in range(nc):
                    if b2[c] < 0 and Pc[c] != 0.0 and obst_impulse.shape[0]:
                        o = owner[cap[c]]
                        if direct:
                            obst_impulse[o, 0] -= Pc[c] * res[c, NX]
                            obst_impulse[o, 1] -= Pc[c] * res[c, NY]
                        else:
                            if nrec[0] == rec_o.size:
                                return q
                            rec_o[nrec[0]] = o
                            rec_j[nrec[0], 0] = Pc[c] * res[c, NX]
                            rec_j[nrec[0], 1] = Pc[c] * res[c, NY]
                            nrec[0] += 1
                # the contacts moved the logs: the flow sampled again where they are
                _resample(S, Sl, F, flag, face, mem, na, t, vals_c, T0c, gap_c, vals_n, T0n,
                          gap_n, t_split, dry_depth, recovered, loc)
                if small:
                    gap = _near_gap(Sl, ln, rd, nt, caps, oc, tol, mg, ex, ey, pb, mtmp[0])
                else:
                    gap = _min_gap(Sl, ln, rd, nt, caps, oc, tol)
                lim[2] = min(lim[2], gap)
                # hits: contacts that start pushing, one per (log, other body) at the step's
                # start, impulses summed, point impulse-weighted
                first = nhit[0]
                for c in range(nc):
                    if not Pc[c] > 0.0:
                        continue
                    lid = ids[mem[b1[c]]]
                    other = ids[mem[b2[c]]] if b2[c] >= 0 else OBST_BIT + owner[cap[c]]
                    key = _pair_key(lid, other)
                    seen = False
                    for k in range(npv):
                        if prev[k] == key:
                            seen = True
                            break
                    if seen:
                        continue
                    oth = ids[mem[b2[c]]] if b2[c] >= 0 else -(owner[cap[c]] + 1)
                    if not add_hit(first, nhit, hit_t, hit_log, hit_other, hit_j, hit_x, hit_y,
                                   t_prev, lid, oth, Pc[c], res[c, CX], res[c, CY]):
                        return q
                for k in range(first, nhit[0]):
                    hit_x[k] /= hit_j[k]
                    hit_y[k] /= hit_j[k]
                # touching or pushing: a contact that flickers within the tolerance is one hit
                npv = 0
                prev = _grow(prev, nc)
                for c in range(nc):
                    if Pc[c] > 0.0 or res[c, GAP] <= tol:
                        other = ids[mem[b2[c]]] if b2[c] >= 0 else OBST_BIT + owner[cap[c]]
                        prev[npv] = _pair_key(ids[mem[b1[c]]], other)
                        npv += 1
            else:
                npv = 0
            taken = t - t_prev
            lim[0] = min(lim[0], taken)
            lim[1] = max(lim[1], taken)
            stats[ST_STEPS] += 1
            stats[ST_LOG_STEPS] += na
            if _diverged(S, mem, na):
                code[q], t_code[q] = DIVERGED, t
                break
            # swept boxes; statuses: a log that stops floating leaves the island's motion; with
            # keep_stopped it stays in the island as a fixed body to the window's end (as it is a
            # grounded obstacle from then on, docs/model.md 13), else the others pass over it
            if keep_stopped:
                na, nx = split_stopped(S, F, flag, P, thr, friction, opt, box, mem, na, nx,
                                        length, fx, fy, t - t0)
            else:
                na = _still_floating(S, F, flag, P, thr, friction, opt, box, mem, na, length, fx,
                                     fy, t - t0)
        # the pairs touching or pushing at the end, each once
        keys = prev[:npv]
        keys.sort()
        nk = 0
        for k in range(npv):
            nk += k == 0 or keys[k] != keys[k - 1]
        if nactive[0] + nk > active_out.size:
            return q
        for k in range(npv):
            if k == 0 or keys[k] != keys[k - 1]:
                active_out[nactive[0]] = keys[k]
                nactive[0] += 1
    return -1


@nb.njit(cache=True)
def moreau_islands(S, F, flag, face, D0, lin0, P, opt, length, radius, mass, inertia, ids,
                   members, start, caps, owner, ocaps, ostart, t0, t_stop, time_tol, method,
                   lf, ang, drag_fraction, explicit, max_step, min_step, tracer, rotation,
                   thr, friction, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
                   recovered, loc, tolerance, eps, iterations, motion_share, relative_motion,
                   island_stop, solver, keep_stopped, active_in, fx, fy, box, obst_impulse,
                   hit_t, hit_log, hit_other, hit_j, hit_x, hit_y, nhit, active_out, nactive,
                   stats, lim, code, t_code):
    """Run each island of ``members``/``start`` from t0 to t_stop with Moreau-Jean steps.

    One island after another (``moreau_islands_parallel``: the same results on several
    threads).

    Parameters
    ----------
    S, F, flag, face, D0, lin0, P, opt, length, radius, mass, inertia, ids, members, start,
    caps, owner, ocaps, ostart, t0, t_stop, time_tol, method, lf, ang, drag_fraction,
    explicit, max_step, min_step, tracer, rotation, thr, friction, vals_c, T0c, gap_c,
    vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc
        As ``island_kernel.island_advance``.
    tolerance, eps, iterations, motion_share, relative_motion, island_stop, solver
        The contact model's tolerance (share of the smallest radius), restitution,
        Gauss-Seidel sweeps at most, motion per step near contacts (share of the smallest
        radius), whether that motion is the pairs' relative motion (eq. (81)) or each near
        log's own, ``island_stop`` and the solver (``contact.moreau.PGS`` or ``NNCG``).
    keep_stopped : bool
        A log that stops floating within the window stays in its island as a fixed body (at
        rest, zero inverse mass) to the window's end, as it is a grounded obstacle from the
        next window on (``[contact] grounded``, docs/model.md 13); False: it leaves the island
        and the others pass over it.
    active_in : sorted int64
        Pair keys (``model._body_pairs``) touching or pushing at t0 (a hit is a contact that
        starts pushing).
    fx, fy, box, obst_impulse, hit_*, nhit
        As ``island_kernel.island_advance``.
    active_out, nactive : the pair keys touching or pushing at t_stop (each once per island);
        code HIT_FULL when the buffer is too small.
    stats : (NSTAT) int64, added to; lim : [shortest, longest step, least gap after a step].
    code, t_code : per island outcome (OK, TOO_SMALL, DIVERGED, HIT_FULL) and its time.
    """
    nmax = nob = 0
    for q in range(start.size - 1):
        nmax = max(nmax, start[q + 1] - start[q])
        nob = max(nob, ostart[q + 1] - ostart[q])
    mem, S0l, Sl, ln, rd, lm, li, margin, near, ws = island_work(nmax, nob, solver)
    rec_o = np.empty(0, np.int64)
    rec_j = np.empty((0, 2))
    nrec = np.zeros(1, np.int64)
    nh, na_ = hit_t.size, active_out.size
    # the buffers as the parallel kernel passes them (views), made once
    ht, hl, ho, hj, hx, hy = (hit_t[0:nh], hit_log[0:nh], hit_other[0:nh], hit_j[0:nh],
                              hit_x[0:nh], hit_y[0:nh])
    ao = active_out[0:na_]
    full = _islands(0, start.size - 1, members, start, S, F, flag, face, D0, lin0, P, opt,
                    length, radius, mass, inertia, ids, caps, owner, ocaps, ostart, t0, t_stop,
                    time_tol, method, lf, ang, drag_fraction, explicit, max_step, min_step,
                    tracer, rotation, thr, friction, vals_c, T0c, gap_c, vals_n, T0n, gap_n,
                    t_split, dry_depth, recovered, loc, tolerance, eps, iterations, motion_share,
                    relative_motion, island_stop, solver, keep_stopped, active_in, fx, fy, box,
                    obst_impulse, True, rec_o, rec_j, nrec, ht, hl, ho, hj, hx, hy, nhit, ao,
                    nactive, stats, lim, code, t_code, mem, S0l, Sl, ln, rd, lm, li, margin,
                    near, ws)
    if full >= 0:
        code[full] = HIT_FULL


@nb.njit(cache=True, inline="always")
def _row(dst, a, src, i):
    """Row i of the 2-d array src into row a of dst."""
    for k in range(src.shape[1]):
        dst[a, k] = src[i, k]


@nb.njit(cache=True)
def apart_arena(n, nob, S, F, flag, face, D0, lin0, box, P, length, radius, mass, inertia, ids,
                thr, solver):
    """A thread's memory for ``_island_apart``: room for islands of up to n logs, nob capsules.

    The copies of an island's rows (S .. thr, its members' and obstacles' lists),
    ``island_work`` and the island's own counters, made once per thread and kernel call: made
    per island, they were forty-odd allocations for islands of five logs and one or two steps
    on average (the replayed crowd: 0.73-0.76 s on two threads before, 0.68-0.70 after;
    BENCHMARKS.md, "The front of the 1e5-log flood").  n >= 1 and at most the number of logs.
    """
    return ((np.empty_like(S[:n]), np.empty_like(F[:n]), np.empty_like(flag[:n]),
             np.empty_like(face[:n]), np.empty_like(D0[:n]), np.empty_like(lin0[:n]),
             np.empty_like(box[:n]), np.empty_like(P[:n]), np.empty_like(length[:n]),
             np.empty_like(radius[:n]), np.empty_like(mass[:n]), np.empty_like(inertia[:n]),
             np.empty_like(ids[:n]), np.empty_like(thr[:n]), np.empty(n, np.int64),
             np.empty(max(nob, 1), np.int64)) + island_work(n, nob, solver)
            + (np.empty(2, np.int64), np.empty(2, np.int64), np.empty(1, np.int64), np.empty(1),
               np.empty(NSTAT, np.int64), np.empty(3), np.empty(3, np.int64)))


@nb.njit(cache=True)
def _island_apart(q, members, start, S, F, flag, face, D0, lin0, P, opt, length, radius, mass,
                  inertia, ids, caps, owner, ocaps, ostart, t0, t_stop, time_tol, method, lf,
                  ang, drag_fraction, explicit, max_step, min_step, tracer, rotation, thr,
                  friction, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth,
                  recovered, loc, tolerance, eps, iterations, motion_share, relative_motion,
                  island_stop, solver, keep_stopped, active_in, fx, fy, box, obst_impulse,
                  rec_o, rec_j, hit_t, hit_log, hit_other, hit_j, hit_x, hit_y, act, cnt, st, lm,
                  code, t_code, ar):
    """``_islands`` of island q on copies of its logs' rows (a thread's own memory), copied back.

    Islands on other threads write, every step, the rows of their own logs; neighbouring
    islands' logs are neighbouring rows, so working in place would share cache lines between
    threads.  The rows go back only when the island fitted its ranges (True); its counts of
    hits, pairs in touch and obstacle impulses go to cnt, its statistics to st, lm.
    ``ar``: the thread's ``apart_arena``, large enough for the island.
    """
    (aS, aF, aflag, aface, aD0, alin0, abox, aP, aln, ard, ams, ain, aid, ath, amem0, aoc, mem,
     S0l, Sl, ln, rd, lmw, li, margin, near, ws, st0, ost0, cx, tx, stl, lml, c3) = ar
    na = start[q + 1] - start[q]
    no = ostart[q + 1] - ostart[q]
    g = members[start[q]:start[q + 1]]
    Sx, Fx, flagx, facex, D0x = aS[:na], aF[:na], aflag[:na], aface[:na], aD0[:na]
    lin0x, boxx, Px, lnx, rdx = alin0[:na], abox[:na], aP[:na], aln[:na], ard[:na]
    msx, inx, idx, thx, mem0, oc = ams[:na], ain[:na], aid[:na], ath[:na], amem0[:na], aoc[:no]
    for a in range(na):
        i = g[a]
        _row(Sx, a, S, i)
        _row(Fx, a, F, i)
        flagx[a], facex[a] = flag[i], face[i]
        _row(D0x, a, D0, i)
        _row(lin0x, a, lin0, i)
        _row(boxx, a, box, i)
        _row(Px, a, P, i)
        lnx[a], rdx[a], msx[a], inx[a] = length[i], radius[i], mass[i], inertia[i]
        idx[a], thx[a] = ids[i], thr[i]
        mem0[a] = a
    for k in range(no):
        oc[k] = ocaps[ostart[q] + k]
    st0[0], st0[1], ost0[0], ost0[1], cx[0], tx[0] = 0, na, 0, no, 0, 0.0
    for k in range(NSTAT):
        stl[k] = 0
    for k in range(3):
        lml[k] = lm[k]
        c3[k] = 0
    full = _islands(0, 1, mem0, st0, Sx, Fx, flagx, facex, D0x, lin0x, Px, opt, lnx, rdx, msx,
                    inx, idx, caps, owner, oc, ost0, t0, t_stop, time_tol, method, lf, ang,
                    drag_fraction, explicit, max_step, min_step, tracer, rotation, thx, friction,
                    vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc,
                    tolerance, eps, iterations, motion_share, relative_motion, island_stop, solver,
                    keep_stopped, active_in, fx, fy, boxx, obst_impulse, False, rec_o, rec_j,
                    c3[2:3], hit_t, hit_log, hit_other, hit_j, hit_x, hit_y, c3[0:1], act,
                    c3[1:2], stl, lml, cx, tx, mem, S0l, Sl, ln, rd, lmw, li, margin, near, ws)
    if full >= 0:
        return False
    for a in range(na):
        i = g[a]
        _row(S, i, Sx, a)
        _row(F, i, Fx, a)
        _row(D0, i, D0x, a)
        _row(lin0, i, lin0x, a)
        _row(box, i, boxx, a)
        flag[i], face[i] = flagx[a], facex[a]
    code[q], t_code[q] = cx[0], tx[0]
    for k in range(3):
        cnt[k] = c3[k]
        lm[k] = lml[k]
    for k in range(NSTAT):
        st[k] = stl[k]
    return True


# the parallel kernel's room per island in its own buffers: hits and pairs in touch, twice
# the island's share (by its logs) of the caller's buffers plus ROOM_EXTRA; impulses on the
# obstacles (islands near one): ROOM_OBST per log plus ROOM_EXTRA_OBST.  An island that fills
# one is run again afterwards, alone, into the caller's buffers (stats[ST_RERUNS]).
ROOM_EXTRA = 16
ROOM_OBST = 64
ROOM_EXTRA_OBST = 512


@nb.njit(cache=True, parallel=True)
def moreau_islands_parallel(S, F, flag, face, D0, lin0, P, opt, length, radius, mass, inertia,
                            ids, members, start, caps, owner, ocaps, ostart, t0, t_stop,
                            time_tol, method, lf, ang, drag_fraction, explicit, max_step,
                            min_step, tracer, rotation, thr, friction, vals_c, T0c, gap_c,
                            vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc, tolerance,
                            eps, iterations, motion_share, relative_motion, island_stop, solver,
                            keep_stopped, active_in, fx, fy, box, obst_impulse, hit_t, hit_log,
                            hit_other, hit_j, hit_x, hit_y, nhit, active_out, nactive, stats, lim,
                            code, t_code, room, nthreads):
    """``moreau_islands`` with the islands on numba's threads: the same results, bit for bit.

    Each island runs on one thread (the islands share no log), on copies of its logs' rows
    (``_island_apart``), the largest first, each thread given islands until it holds its
    share of the logs (longest processing time first); an island writes its hits, pairs in
    touch, obstacle impulses (in the order they are made) and statistics to its own range of
    the kernel's buffers, laid out beforehand (prefix sums of each island's room).
    Afterwards, island by island in order, these are copied to the caller's buffers and the
    obstacle impulses added up: the same numbers in the same order as ``moreau_islands`` for
    any number of threads.  An island that fills its range (its rows left as they were) runs
    again afterwards, alone, into the caller's buffers.
    Parameters and outputs as ``moreau_islands``; stats[ST_RERUNS] counts the islands run
    again.  ``room``: the rooms (``ROOM_*``) scaled by it (1; 0: every island with a hit, a
    pair in touch or an obstacle impulse runs again, tests); ``nthreads``: numba's threads
    (``numba.get_num_threads()``, given: called in the kernel it keeps numba from caching it).
    """
    # no array expression, np.zeros or np.argmin here: in a parallel kernel numba makes each a
    # parallel region of its own, and waking the threads for each (np.argmin once per island
    # below) made two threads 2.4x slower than one on a packed crowd (BENCHMARKS.md)
    nisl = start.size - 1
    nlog = start[nisl] - start[0]
    size = np.empty(nisl, np.int64)
    hoff = np.empty(nisl + 1, np.int64)
    aoff = np.empty(nisl + 1, np.int64)
    roff = np.empty(nisl + 1, np.int64)
    hoff[0] = aoff[0] = roff[0] = 0
    for q in range(nisl):
        na = start[q + 1] - start[q]
        size[q] = na
        hoff[q + 1] = hoff[q] + int(room * ((2 * hit_t.size * na) // max(nlog, 1) + ROOM_EXTRA))
        aoff[q + 1] = aoff[q] + int(room * ((2 * active_out.size * na) // max(nlog, 1)
                                            + ROOM_EXTRA))
        near_obst = ostart[q + 1] > ostart[q] and obst_impulse.shape[0] > 0
        roff[q + 1] = roff[q] + (int(room * (ROOM_OBST * na + ROOM_EXTRA_OBST)) if near_obst
                                 else 0)
    h_t = np.empty(hoff[nisl])
    h_log = np.empty(hoff[nisl], np.int64)
    h_other = np.empty(hoff[nisl], np.int64)
    h_j = np.empty(hoff[nisl])
    h_x = np.empty(hoff[nisl])
    h_y = np.empty(hoff[nisl])
    act = np.empty(aoff[nisl], np.int64)
    rec_o = np.empty(roff[nisl], np.int64)
    rec_j = np.empty((roff[nisl], 2))
    # counts per island: hits, pairs in touch, obstacle impulses
    cnt = np.empty((nisl, 3), np.int64)
    st = np.empty((nisl, NSTAT), np.int64)
    lm_ = np.empty((nisl, 3))
    done = np.empty(nisl, np.bool_)
    neg = np.empty(nisl, np.int64)
    nmax = 1
    for q in range(nisl):
        for k in range(3):
            cnt[q, k] = 0
        for k in range(NSTAT):
            st[q, k] = 0
        lm_[q, 0], lm_[q, 1], lm_[q, 2] = lim[0], lim[1], lim[2]
        done[q] = False
        neg[q] = -size[q]
        nmax = max(nmax, size[q])
    # longest processing time first: the islands by size, each to the least loaded thread
    nw = max(1, min(nthreads, nisl))
    order = np.argsort(neg, kind="mergesort")
    load = np.empty(nw, np.int64)
    wstart = np.empty(nw + 1, np.int64)
    wstart[0] = 0
    for w in range(nw):
        load[w] = 0
        wstart[w + 1] = 0
    worker = np.empty(nisl, np.int64)
    for k in range(nisl):
        w = 0  # np.argmin(load): the first least loaded
        for j in range(1, nw):
            if load[j] < load[w]:
                w = j
        worker[order[k]] = w
        load[w] += size[order[k]] + 1
    for q in range(nisl):
        wstart[worker[q] + 1] += 1
    for w in range(nw):
        wstart[w + 1] += wstart[w]
    wlist = np.empty(nisl, np.int64)
    fill = np.empty(nw, np.int64)
    for w in range(nw):
        fill[w] = wstart[w]
    for k in range(nisl):
        q = order[k]
        wlist[fill[worker[q]]] = q
        fill[worker[q]] += 1
    for w in nb.prange(nw):
        # the thread's memory, for its largest island and most obstacle capsules
        n = 1
        nob = 0
        for k in range(wstart[w], wstart[w + 1]):
            n = max(n, size[wlist[k]])
            nob = max(nob, ostart[wlist[k] + 1] - ostart[wlist[k]])
        ar = apart_arena(n, nob, S, F, flag, face, D0, lin0, box, P, length, radius, mass,
                         inertia, ids, thr, solver)
        for k in range(wstart[w], wstart[w + 1]):
            q = wlist[k]
            h0, h1, a0, a1 = hoff[q], hoff[q + 1], aoff[q], aoff[q + 1]
            r0, r1 = roff[q], roff[q + 1]
            done[q] = _island_apart(
                q, members, start, S, F, flag, face, D0, lin0, P, opt, length, radius, mass,
                inertia, ids, caps, owner, ocaps, ostart, t0, t_stop, time_tol, method, lf, ang,
                drag_fraction, explicit, max_step, min_step, tracer, rotation, thr, friction,
                vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split, dry_depth, recovered, loc,
                tolerance, eps, iterations, motion_share, relative_motion, island_stop, solver,
                keep_stopped, active_in, fx, fy, box, obst_impulse, rec_o[r0:r1], rec_j[r0:r1],
                h_t[h0:h1], h_log[h0:h1], h_other[h0:h1], h_j[h0:h1], h_x[h0:h1], h_y[h0:h1],
                act[a0:a1], cnt[q], st[q], lm_[q], code, t_code, ar)
    # island by island in order: into the caller's buffers, as moreau_islands
    rec_none = np.empty(0, np.int64)
    recj_none = np.empty((0, 2))
    nrec = np.empty(1, np.int64)
    nrec[0] = 0
    nh, na_ = hit_t.size, active_out.size
    for q in range(nisl):
        if done[q]:
            if nhit[0] + cnt[q, 0] > hit_t.size or nactive[0] + cnt[q, 1] > active_out.size:
                code[q] = HIT_FULL
                return
            for k in range(cnt[q, 0]):
                s, d = hoff[q] + k, nhit[0] + k
                hit_t[d], hit_log[d], hit_other[d] = h_t[s], h_log[s], h_other[s]
                hit_j[d], hit_x[d], hit_y[d] = h_j[s], h_x[s], h_y[s]
            nhit[0] += cnt[q, 0]
            for k in range(cnt[q, 1]):
                active_out[nactive[0] + k] = act[aoff[q] + k]
            nactive[0] += cnt[q, 1]
            for k in range(roff[q], roff[q] + cnt[q, 2]):
                obst_impulse[rec_o[k], 0] -= rec_j[k, 0]
                obst_impulse[rec_o[k], 1] -= rec_j[k, 1]
            for k in range(NSTAT):
                if k == ST_PGS_MAX or k == ST_MAX_CONTACTS:
                    stats[k] = max(stats[k], st[q, k])
                else:
                    stats[k] += st[q, k]
            lim[0] = min(lim[0], lm_[q, 0])
            lim[1] = max(lim[1], lm_[q, 1])
            lim[2] = min(lim[2], lm_[q, 2])
            continue
        # its range was full (its rows untouched): again, alone, into the caller's buffers
        stats[ST_RERUNS] += 1
        mem, S0l, Sl, ln, rd, lm, li, margin, near, ws = island_work(nmax, ocaps.size, solver)
        if _islands(q, q + 1, members, start, S, F, flag, face, D0, lin0, P, opt, length,
                    radius, mass, inertia, ids, caps, owner, ocaps, ostart, t0, t_stop, time_tol,
                    method, lf, ang, drag_fraction, explicit, max_step, min_step, tracer,
                    rotation, thr, friction, vals_c, T0c, gap_c, vals_n, T0n, gap_n, t_split,
                    dry_depth, recovered, loc, tolerance, eps, iterations, motion_share,
                    relative_motion, island_stop, solver, keep_stopped, active_in, fx, fy, box,
                    obst_impulse, True, rec_none, recj_none, nrec, hit_t[0:nh], hit_log[0:nh],
                    hit_other[0:nh], hit_j[0:nh], hit_x[0:nh], hit_y[0:nh], nhit,
                    active_out[0:na_], nactive, stats, lim, code, t_code, mem, S0l, Sl, ln,
                    rd, lm, li, margin, near, ws) >= 0:
            code[q] = HIT_FULL
            return
