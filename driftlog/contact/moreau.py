"""Time-stepping non-smooth contact (Moreau-Jean), solved by projected Gauss-Seidel.

Where event-driven impulses stall (a jam: many persistent contacts, restitution below one,
each sub-step cut short by the next contact), Moreau-Jean's scheme takes the step whole and
solves for the contact impulses P >= 0 of every contact at once, at the velocity level:

    V+ = V_free + M^-1 H^T P,      q+ = q_free + dt M^-1 H^T P      (theta = 1)
    0 <= P  _|_  u_n+ - target >= 0

with u_n = H V the relative normal velocity of each contact (H from the geometry at the start
of the step), V_free and q_free the free motion over the step (flow forces, the integrator).
The target keeps the linearised gap at the end of the step above -slop (speculative for
contacts still apart, a position correction for those overlapping) and applies Newton's
restitution to contacts touching at the start that approach:

    target = max(u_n_free - (max(g_start, -slop) + dg_free + slop) / dt,  -eps u_n_start)

Newton's law at several simultaneous contacts can make energy; an island whose impulses
raised its kinetic energy is solved again with eps = 0 (docs/model.md eq. (87)).

``moreau_solve`` sweeps the contacts (Gauss-Seidel, in a fixed order), projecting each P on
P >= 0, until no velocity changes by more than ``vtol`` or ``max_iterations`` sweeps: bounded
cost whatever the number of contacts.  Overlaps deeper than the slop (left by an unconverged
solve or by the linearisation) are removed a share per step by moving positions only (split
impulse), never by a velocity that would throw the logs apart.  Last, contacts touching at
the step's start or end hold at the velocity level too (u_n+ >= 0, or Newton's law for one
that closed within the step; positions kept: docs/model.md eq. (90)).  The targets above hold
a gap: a log pressed on a post by the flow would otherwise end every step moving into it at
its free acceleration times dt / 2, and Newton's law applied at the step's start to a log
that reaches a post within the step would put it back where it started.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.columns import (
    CX,
    CY,
    GAP,
    GOMEGA,
    GU,
    GV,
    NX,
    NY,
    OMEGA,
    THETA,
    UB,
    VB,
    X,
    Y,
)
from driftlog.contact.islands import labels_into, runs_into

__all__ = ["NNCG", "PGS", "SOLVERS", "moreau_solve", "moreau_solve_into", "solve_workspace"]

# moreau_solve_into's work rows: floats (per contact, then per island), integers (per contact,
# then per body or island), flags (per island); NNCG's own float rows after the NFW
NFW, NIW, NBW, NCG = 15, 11, 2, 7
# the contact solvers (``[contact] solver``)
PGS, NNCG = 0, 1
SOLVERS = ("pgs", "nncg")
# from this sweep on, a sweep that moved no body by more than vtol also ends the solve (each
# body's net change; before it, only every contact's update below vtol does: ``_sweeps_into``)
NET_FROM = 8


@nb.njit(cache=True, _nrt=False, inline="always")
def _sweep(a0, a1, order, body1, body2, res, rn1, rn2, w, target, inv_m, inv_i, V, P, seen,
           quiet, tick):
    """One Gauss-Seidel sweep of contacts order[a0:a1].

    Returns (changed, tick, the sum of the squared changes of P, the largest change of a
    contact's normal velocity |dP| w).

    Each contact's impulse P[c] becomes max(P[c] + (target - u_n) / w, 0) and both bodies'
    velocities follow.  A contact whose last update changed nothing is skipped until one of
    its two bodies' velocities changes: its update reads only P, target, w and those
    velocities, so it would change nothing again (the same numbers bit for bit).  Speculative
    contacts of a large island (pairs near each other but apart, P = 0) cost a few integer
    compares a sweep, not a gather of both bodies and a division.  ``tick`` counts the
    velocity changes; ``seen[b]`` is the tick of body b's last change, ``quiet[c]`` the tick
    at which contact c last changed nothing (-1: it has to be evaluated).
    """
    changed = False
    g2 = 0.0
    rmax = 0.0
    for a in range(a0, a1):
        # unsigned indices where they are >= 0: no negative-index wraparound (the sweep is
        # the hot loop of a packed crowd; driftlog.solver.fluxes)
        c = np.uint64(order[a])
        wc = w[c]
        if wc <= 0.0:
            continue
        i, j = np.uint64(body1[c]), body2[c]
        qc = quiet[c]
        if qc >= seen[i] and (j < 0 or qc >= seen[np.uint64(j)]):
            continue
        nx, ny = res[c, NX], res[c, NY]
        r1 = rn1[c]
        u = V[i, GU] * nx + V[i, GV] * ny + V[i, GOMEGA] * r1
        if j >= 0:
            ju = np.uint64(j)
            u -= V[ju, GU] * nx + V[ju, GV] * ny + V[ju, GOMEGA] * rn2[c]
        pc = P[c]
        p_new = max(pc + (target[c] - u) / wc, 0.0)
        d = p_new - pc
        if d == 0.0:
            quiet[c] = tick
            continue
        quiet[c] = -1
        changed = True
        tick += 1
        g2 += d * d
        P[c] = p_new
        V[i, GU] += d * nx * inv_m[i]
        V[i, GV] += d * ny * inv_m[i]
        V[i, GOMEGA] += d * r1 * inv_i[i]
        seen[i] = tick
        if j >= 0:
            ju = np.uint64(j)
            V[ju, GU] -= d * nx * inv_m[ju]
            V[ju, GV] -= d * ny * inv_m[ju]
            V[ju, GOMEGA] -= d * rn2[c] * inv_i[ju]
            seen[ju] = tick
        rmax = max(rmax, abs(d) * wc)
    return changed, tick, g2, rmax


@nb.njit(cache=True, _nrt=False, inline="always")
def _snapshot(b0, b1, border, V, snap):
    """The velocities of bodies border[b0:b1] into snap (3 rows)."""
    for a in range(b0, b1):
        b = border[a]
        snap[0, b] = V[b, GU]
        snap[1, b] = V[b, GV]
        snap[2, b] = V[b, GOMEGA]


@nb.njit(cache=True, _nrt=False, inline="always")
def _moved(b0, b1, border, V, snap, inv_m, inv_i):
    """The largest change of the bodies border[b0:b1]'s velocities since ``_snapshot``.

    Each body's change is its speed change over its mass, sqrt(du^2 + dv^2 + (k domega)^2),
    k = sqrt(I / m) its radius of gyration; fixed bodies (inv_m = 0) do not move, logs that
    do not rotate (inv_i = 0: ``physics.rotation = "off"``) do not turn.
    """
    r2 = 0.0
    for a in range(b0, b1):
        b = border[a]
        if inv_m[b] == 0.0:
            continue
        du, dv, do = V[b, GU] - snap[0, b], V[b, GV] - snap[1, b], V[b, GOMEGA] - snap[2, b]
        turn = do * do * (inv_m[b] / inv_i[b]) if inv_i[b] > 0.0 else 0.0
        r2 = max(r2, du * du + dv * dv + turn)
    return np.sqrt(r2)


@nb.njit(cache=True, _nrt=False)
def _sweeps_into(solver, order, start, count, body1, body2, res, rn1, rn2, w, target, inv_m,
                 inv_i, V, n, P, k, vtol, max_iterations, island_stop, active, seen, quiet, border,
                 bstart, fw):
    """The contact solve: P >= 0 _|_ u_n(V) - target >= 0; V changed in place.

    ``solver`` PGS: projected Gauss-Seidel.  Island by island (contacts
    order[start[q]:start[q + 1]] of island q, in their given order; its bodies
    border[bstart[q]:bstart[q + 1]]), in lockstep, until a sweep changed no contact's normal
    velocity by more than vtol, or, from sweep NET_FROM + 1 on, moved no body by more than
    vtol (its net change over the sweep, ``_moved``), or max_iterations sweeps.  An island
    whose sweep changes nothing is left (further sweeps would not change it either), so the
    result is the sweep over all contacts, at the cost of the islands still moving.
    ``island_stop``: an island is also left once its own measure is below vtol (each island
    converged to vtol on its own, not in lockstep).

    Why the bodies' net change: near duplicate contacts of a pile (a pair's closest points
    and its axis ends, a log pressed on the deck and on its neighbour) trade impulse back and
    forth by updates of 1e-8 m/s sweep after sweep while no velocity changes any more, and
    the per-update measure alone never fell below vtol there (BENCHMARKS.md, "Gauss-Seidel
    on piles").  It is measured from sweep NET_FROM + 1 only (a copy of the island's
    velocities before each sweep): the many small islands that converge in a few sweeps pay
    nothing for it, and give the numbers they gave before it bit for bit.

    ``solver`` NNCG: nonsmooth nonlinear conjugate gradients, fewer sweeps on piles.
    Silcowitz, Niebe and Erleben (2010, "A nonsmooth nonlinear conjugate gradient method for
    interactive contact force problems", The Visual Computer 26) take the projected
    Gauss-Seidel sweep as the gradient step of the contact problem's quadratic program
    (min 1/2 P^T A P + P^T (u_free - target), P >= 0, A = H M^-1 H^T) and add to each sweep
    a conjugate direction, Fletcher-Reeves: with d_k the sweep's change of P,

        beta = |d_k|^2 / |d_{k-1}|^2,   p_k = beta p_{k-1} + d_k,   P += beta p_{k-1}

    restarted (beta = 0) where beta > 1.  The velocities follow the impulses exactly (V
    changes by M^-1 H^T of every change of P), island by island (each its own beta).  The
    sweep after the added step projects P >= 0 again; no step is added after the last sweep,
    nor once an island converged, so the result satisfies P >= 0 and is a fixed point of the
    sweep to the same measures.

    ``count`` islands, n bodies and k contacts; ``active`` (>= count), ``seen`` (>= n),
    ``quiet`` (>= k) and ``fw`` (``solve_workspace``'s float rows: the copy of the
    velocities, NNCG's per contact direction and start impulses, per island |d|^2 and beta,
    and the direction's velocities) are work arrays: no allocation, no reference counting.
    Returns (sweeps, the last sweep's largest change).
    """
    conjugate = solver == NNCG
    snap = fw[NFW - 3:NFW]
    # NNCG's rows (PGS: its workspace has none; never read then)
    cw = fw[NFW:NFW + 4] if conjugate else fw[NFW - 3:NFW - 3]
    vdir = fw[NFW + 4:NFW + NCG] if conjugate else fw[NFW - 3:NFW - 3]
    for q in range(count):
        active[q] = start[q + 1] > start[q]
    for b in range(n):
        seen[b] = 0
    for c in range(k):
        quiet[c] = -1
    if conjugate:
        for q in range(count):
            cw[2, q] = 0.0
        for b in range(n):
            vdir[0, b] = vdir[1, b] = vdir[2, b] = 0.0
        for c in range(k):
            cw[0, c] = 0.0
            cw[1, c] = P[c]
    tick = 0
    it = 0
    residual = 0.0
    while it < max_iterations:
        it += 1
        residual = 0.0
        net = it > NET_FROM
        for q in range(count):
            if not active[q]:
                continue
            if net or conjugate:
                _snapshot(bstart[q], bstart[q + 1], border, V, snap)
            changed, tick, g2, rq = _sweep(start[q], start[q + 1], order, body1, body2, res, rn1,
                                           rn2, w, target, inv_m, inv_i, V, P, seen, quiet, tick)
            if net:
                rq = min(rq, _moved(bstart[q], bstart[q + 1], border, V, snap, inv_m, inv_i))
            residual = max(residual, rq)
            if not changed or (island_stop and rq <= vtol):
                active[q] = False
            if conjugate:
                beta = g2 / cw[2, q] if cw[2, q] > 0.0 else 0.0
                cw[3, q] = beta if beta <= 1.0 else 0.0  # > 1: restart, the sweep alone
                cw[2, q] = g2
        if residual <= vtol or it == max_iterations:
            break
        if conjugate:  # the step of each island still sweeping (none after the last sweep)
            tick = _conjugate_step(count, active, start, order, bstart, border, P, V, snap, cw,
                                   vdir, quiet, seen, tick)
    return it, residual


@nb.njit(cache=True, _nrt=False, inline="always")
def _conjugate_step(count, active, start, order, bstart, border, P, V, snap, cw, vdir, quiet,
                    seen, tick):
    """NNCG's step after a sweep, for each island still active: P and V along the direction.

    ``cw``: per contact the direction p and the impulse entering the sweep, per island beta
    (row 3); ``snap``: the velocities entering the sweep; ``vdir``: the direction's
    velocities.  Contacts whose impulse changed and bodies that moved are evaluated again by
    the next sweep (``quiet``, ``seen``).  Returns the tick.
    """
    tick += 1
    for q in range(count):
        if not active[q]:
            continue
        beta = cw[3, q]
        for a in range(start[q], start[q + 1]):
            c = np.uint64(order[a])
            step = beta * cw[0, c]
            cw[0, c] = step + (P[c] - cw[1, c])
            if step != 0.0:
                P[c] += step
                quiet[c] = -1
            cw[1, c] = P[c]
        for a in range(bstart[q], bstart[q + 1]):
            b = border[a]
            moved = False
            for m in range(3):
                step = beta * vdir[m, b]
                vdir[m, b] = step + (V[b, GU + m] - snap[m, b])
                if step != 0.0:
                    V[b, GU + m] += step
                    moved = True
            if moved:
                seen[b] = tick
    return tick


@nb.njit(cache=True, _nrt=False)
def _body_runs(labels, count, n, border, bstart, fill):
    """The bodies of each island: border[bstart[q]:bstart[q + 1]] (ascending); work: fill."""
    for q in range(count + 1):
        bstart[q] = 0
    for b in range(n):
        bstart[labels[b] + 1] += 1
    for q in range(count):
        bstart[q + 1] += bstart[q]
    for q in range(count):
        fill[q] = bstart[q]
    for b in range(n):
        q = labels[b]
        border[fill[q]] = b
        fill[q] += 1


@nb.njit(cache=True, _nrt=False)
def _gained_into(labels, count, n, S, V, inv_m, inv_i, e0, e1, floor, out):
    """Per island: whether the velocities V hold more kinetic energy than the free ones in S.

    Into ``out`` (>= count), for n bodies; beyond round-off: 1e-9 of the free energy plus a
    speed of 1e-9 m/s over the island's mass.  ``e0``, ``e1``, ``floor`` (>= count): work.
    """
    for q in range(count):
        e0[q] = e1[q] = floor[q] = 0.0
    for b in range(n):
        if inv_m[b] == 0.0:  # a fixed body (a log stopped in its window) gains nothing
            continue
        q = labels[b]
        m = 1.0 / inv_m[b]
        i = 1.0 / inv_i[b] if inv_i[b] > 0.0 else 0.0  # a log that does not rotate
        e0[q] += 0.5 * (m * (S[b, UB] ** 2 + S[b, VB] ** 2) + i * S[b, OMEGA] ** 2)
        e1[q] += 0.5 * (m * (V[b, GU] ** 2 + V[b, GV] ** 2) + i * V[b, GOMEGA] ** 2)
        floor[q] += 0.5 * m * 1e-18
    for q in range(count):
        out[q] = e1[q] > e0[q] * (1.0 + 1e-9) + floor[q]


@nb.njit(cache=True)
def moreau_solve(S0, S, inv_m, inv_i, body1, body2, res, dt, eps, tol, slop, vtol,
                 max_iterations, P, recovery=0.2, island_stop=False, solver=PGS):
    """Solve the contact impulses of one step and apply them to S (free state, in place).

    Parameters
    ----------
    S0 : (n, 6) state at the start of the step.
    S : (n, 6) state after the free step; velocities and positions are corrected in place.
    inv_m, inv_i : (n,) inverse masses and inertias.
    body1, body2 : (k,) bodies of each contact (body2 < 0: a fixed obstacle).
    res : (k, >= 5) gap, normal, contact point at the start of the step.
    dt, eps : step and restitution.
    tol : a contact with a start gap below this is touching (restitution applies).
    slop : tolerated overlap.
    vtol : convergence: largest velocity change of a sweep.
    max_iterations : sweeps at most (each of the two solves).
    P : (k,) impulses (output).
    recovery : share of an overlap deeper than slop removed per step, by moving the positions
        only (split impulse: pushing overlaps apart through the velocities would add energy).
    island_stop : solve each contact island (``islands.island_labels``) to vtol on its own
        (False: the islands are swept in lockstep until all have converged, which is the
        sweep over all contacts bit for bit; islands that stopped changing are skipped either
        way).
    solver : ``PGS`` (projected Gauss-Seidel) or ``NNCG`` (the same sweeps with conjugate
        steps, ``_sweeps_into``: far fewer sweeps on piles) for the velocity solves; the
        position pass is Gauss-Seidel's either way.

    Returns
    -------
    (iterations, residual): sweeps of the velocity solve and its last largest velocity change.
    """
    k = body1.size
    n = S.shape[0]
    fw, iw, bw, V, Vp = solve_workspace(max(k, n + 1), solver)
    return moreau_solve_into(S0, S, inv_m, inv_i, n, body1, body2, res, k, dt, eps, tol, slop,
                             vtol, max_iterations, P, recovery, island_stop, solver, fw, iw, bw,
                             V, Vp)



@nb.njit(cache=True)
def solve_workspace(cap, solver=PGS):
    """Work arrays for ``moreau_solve_into`` of up to cap - 1 bodies and cap contacts."""
    # every entry that moreau_solve_into reads it has written first
    return (np.empty((NFW + (NCG if solver == NNCG else 0), cap)),
            np.empty((NIW, cap), np.int64), np.empty((NBW, cap), np.bool_),
            np.empty((cap, 3)), np.empty((cap, 3)))


@nb.njit(cache=True, _nrt=False)
def moreau_solve_into(S0, S, inv_m, inv_i, n, body1, body2, res, k, dt, eps, tol, slop, vtol,
                      max_iterations, P, recovery, island_stop, solver, fw, iw, bw, V, Vp):
    """``moreau_solve`` of the first n bodies and k contacts, on work arrays.

    ``fw``, ``iw``, ``bw``, ``V``, ``Vp``: ``solve_workspace(cap, solver)`` with cap >= k and
    cap > n.  No allocation and no reference counting (a crowd's island kernel solves
    millions of small islands; BENCHMARKS.md, "Islands of speculative contacts").  The same
    numbers as ``moreau_solve``, which calls it.
    """
    plain = fw[0]  # the targets without restitution (eq. (87))
    rn1 = fw[1]
    rn2 = fw[2]
    w = fw[3]
    target = fw[4]
    g_free = fw[5]
    u_free = fw[6]
    Pp = fw[7]
    e0, e1, floor = fw[8], fw[9], fw[10]
    bounce = fw[11]  # each contact's target in the velocity pass, if it touches
    order, quiet, keep = iw[0], iw[1], iw[2]
    parent, labels, start, fill, seen, start2 = iw[3], iw[4], iw[5], iw[6], iw[7], iw[8]
    border, bstart = iw[9], iw[10]
    active, redo = bw[0], bw[1]
    for c in range(k):
        rn2[c] = 0.0
    for c in range(k):
        i, j = body1[c], body2[c]
        nx, ny = res[c, NX], res[c, NY]
        rn1[c] = (res[c, CX] - S0[i, X]) * ny - (res[c, CY] - S0[i, Y]) * nx
        w[c] = inv_m[i] + rn1[c] * rn1[c] * inv_i[i]
        uf = S[i, UB] * nx + S[i, VB] * ny + S[i, OMEGA] * rn1[c]
        u0 = S0[i, UB] * nx + S0[i, VB] * ny + S0[i, OMEGA] * rn1[c]
        dg = ((S[i, X] - S0[i, X]) * nx + (S[i, Y] - S0[i, Y]) * ny
              + (S[i, THETA] - S0[i, THETA]) * rn1[c])
        if j >= 0:
            rn2[c] = (res[c, CX] - S0[j, X]) * ny - (res[c, CY] - S0[j, Y]) * nx
            w[c] += inv_m[j] + rn2[c] * rn2[c] * inv_i[j]
            uf -= S[j, UB] * nx + S[j, VB] * ny + S[j, OMEGA] * rn2[c]
            u0 -= S0[j, UB] * nx + S0[j, VB] * ny + S0[j, OMEGA] * rn2[c]
            dg -= ((S[j, X] - S0[j, X]) * nx + (S[j, Y] - S0[j, Y]) * ny
                   + (S[j, THETA] - S0[j, THETA]) * rn2[c])
        # the end gap g0 + dg + dt (u+ - u_free) must stay >= -slop; an overlap deeper than
        # slop at the start must not deepen (it is removed by the position pass below)
        g0 = max(res[c, GAP], -slop)
        g_free[c] = res[c, GAP] + dg
        u_free[c] = uf
        target[c] = uf - (g0 + dg + slop) / dt
        plain[c] = target[c]
        # the velocity pass's target: 0, or Newton's law for one that closes within the step
        bounce[c] = -eps * u0 if u0 < 0.0 and res[c, GAP] > tol else 0.0
        if res[c, GAP] <= tol and u0 < 0.0:
            # an impact at the step's start: Newton's law, the impulse given then (a contact
            # that closes within the step ends touching: its law is the velocity pass's)
            target[c] = max(target[c], -eps * u0)
            plain[c] = max(plain[c], 0.0)
        P[c] = 0.0
    count = labels_into(n, body1, body2, k, parent, labels)
    runs_into(labels, count, body1, k, order, start, fill)
    _body_runs(labels, count, n, border, bstart, fill)
    for b in range(n):
        for m in range(GOMEGA + 1):
            V[b, m] = S[b, UB + m]
    it, residual = _sweeps_into(solver, order, start, count, body1, body2, res, rn1, rn2, w,
                                target, inv_m, inv_i, V, n, P, k, vtol, max_iterations,
                                island_stop, active, seen, quiet, border, bstart, fw)
    if eps > 0.0:
        # Newton's law at simultaneous contacts can make energy (a log spinning between two
        # fixed bodies, both contacts approaching: eq. (87)); an island whose impulses raised
        # its kinetic energy is solved again without restitution, which cannot
        _gained_into(labels, count, n, S, V, inv_m, inv_i, e0, e1, floor, redo)
        anyredo = False
        for q in range(count):
            anyredo = anyredo or redo[q]
        if anyredo:
            m = _runs_of(count, redo, order, start, keep, start2)
            for a in range(m):
                c = keep[a]
                target[c] = plain[c]
                P[c] = 0.0
            for b in range(n):
                if redo[labels[b]]:
                    for q in range(GOMEGA + 1):
                        V[b, q] = S[b, UB + q]
            it2, residual = _sweeps_into(solver, keep, start2, count, body1, body2, res, rn1,
                                         rn2, w, target, inv_m, inv_i, V, n, P, k, vtol,
                                         max_iterations, island_stop, active, seen, quiet,
                                         border, bstart, fw)
            it += it2
    # position pass: pseudo-velocities that remove a share of the remaining overlap, always
    # by Gauss-Seidel (NNCG's iterates are not monotone: at the 1e5-log flood's raft, capped,
    # they left overlaps of 0.25 m against 0.19; BENCHMARKS.md, "Gauss-Seidel on piles")
    for b in range(n):
        for m in range(GOMEGA + 1):
            Vp[b, m] = 0.0
    for c in range(k):
        Pp[c] = 0.0
    deep = 0
    for c in range(k):
        u = _normal_velocity(c, body1, body2, res, rn1, rn2, V)
        g_end = g_free[c] + dt * (u - u_free[c])
        g_free[c] = g_end  # for the velocity pass
        if -g_end - slop > 0.0:
            target[c] = recovery * (-g_end - slop) / dt
            deep += 1
        else:
            # a pair still apart at the step's end may close up to touching, one in touch
            # (within the slop) holds: held as if touching, pairs merely near each other
            # passed the push on through a whole pile (docs/model.md eq. (88))
            target[c] = -max(g_end, 0.0) / dt
    if deep:
        _sweeps_into(PGS, order, start, count, body1, body2, res, rn1, rn2, w, target, inv_m,
                     inv_i, Vp, n, Pp, k, vtol, max_iterations, island_stop, active, seen, quiet,
                     border, bstart, fw)
    for b in range(n):  # q+ = q_free + dt (V+ - V_free) + dt Vp
        for m in range(GOMEGA + 1):  # position X + m has the rate UB + m (GU + m in V)
            S[b, X + m] += dt * (V[b, m] - S[b, UB + m] + Vp[b, m])
    # velocity pass (eq. (90)): a contact touching at the step's start or end holds at the
    # velocity level too, positions kept.  The solve above holds gaps, and moves positions as
    # if its impulses were given at the step's start: a log pressed on a post by the flow
    # would end every step moving into it at its free acceleration times dt / 2 (its position
    # pinned by the gap), and one that reaches a post within the step would be put back
    # behind where it started, at rest.  The end velocities are projected on u_n+ >= 0 at
    # those contacts (u_n+ >= -eps u_n,0 where a contact closed within the step: Newton's
    # law); its impulses are added to P (the force held).  Started from what would bring each
    # contact alone to its target, at most the first solve's impulse there (a log held at
    # rest on one contact needs exactly that again: one sweep), solved as the first solve is,
    # in at most a tenth of its sweeps (a pile's first solve stops at its cap anyway)
    m = 0
    start2[0] = 0
    for q in range(count):
        need = False
        for a in range(start[q], start[q + 1]):
            c = order[a]
            if res[c, GAP] <= tol or g_free[c] <= tol:
                u = _normal_velocity(c, body1, body2, res, rn1, rn2, V)
                if u < bounce[c] - vtol:
                    need = True
                    break
        if need:
            for a in range(start[q], start[q + 1]):
                c = order[a]
                if res[c, GAP] <= tol or g_free[c] <= tol:
                    keep[m] = c
                    m += 1
                    target[c] = bounce[c]
        start2[q + 1] = m
    if m:
        if eps > 0.0:  # the end velocities before the pass, to solve it again (eq. (87))
            for b in range(n):
                for mm in range(GOMEGA + 1):
                    Vp[b, mm] = V[b, mm]
        pcap = max(max_iterations // 10, 1)
        _pass_start(keep, m, body1, body2, res, rn1, rn2, w, target, inv_m, inv_i, V, P, Pp)
        it2, _ = _sweeps_into(solver, keep, start2, count, body1, body2, res, rn1, rn2, w,
                              target, inv_m, inv_i, V, n, Pp, k, vtol, pcap, island_stop,
                              active, seen, quiet, border, bstart, fw)
        it += it2
        if eps > 0.0:
            # Newton's law at contacts that closed within the step, several at once, can make
            # energy as at the start (eq. (87)): such an island's pass again, all targets 0
            _gained_into(labels, count, n, S, V, inv_m, inv_i, e0, e1, floor, redo)
            m3 = _runs_of(count, redo, keep, start2, parent, fill)
            for a in range(m3):
                target[parent[a]] = 0.0
            if m3:
                for b in range(n):
                    if redo[labels[b]]:
                        for mm in range(GOMEGA + 1):
                            V[b, mm] = Vp[b, mm]
                _pass_start(parent, m3, body1, body2, res, rn1, rn2, w, target, inv_m, inv_i,
                            V, P, Pp)
                it3, _ = _sweeps_into(solver, parent, fill, count, body1, body2, res, rn1, rn2,
                                      w, target, inv_m, inv_i, V, n, Pp, k, vtol, pcap,
                                      island_stop, active, seen, quiet, border, bstart, fw)
                it += it3
        for a in range(m):
            c = keep[a]
            P[c] += Pp[c]
    for b in range(n):
        for m in range(GOMEGA + 1):
            S[b, UB + m] = V[b, m]
    return it, residual


@nb.njit(cache=True, _nrt=False, inline="always")
def _runs_of(count, pick, order, start, out, out_start):
    """The contacts order[start[q]:start[q + 1]] of the islands q with pick[q], into out.

    Island by island, in order (island q's: out[out_start[q]:out_start[q + 1]]); returns
    their number.
    """
    m = 0
    out_start[0] = 0
    for q in range(count):
        if pick[q]:
            for a in range(start[q], start[q + 1]):
                out[m] = order[a]
                m += 1
        out_start[q + 1] = m
    return m


@nb.njit(cache=True, _nrt=False, inline="always")
def _pass_start(keep, m, body1, body2, res, rn1, rn2, w, target, inv_m, inv_i, V, P, Pp):
    """The velocity pass's first impulses, applied to V.

    For each contact keep[:m], what would bring it alone to its target, at most the first
    solve's impulse there.
    """
    for a in range(m):
        c = keep[a]
        u = _normal_velocity(c, body1, body2, res, rn1, rn2, V)
        Pp[c] = min(P[c], max(target[c] - u, 0.0) / w[c]) if w[c] > 0.0 else 0.0
    for a in range(m):
        c = keep[a]
        d = Pp[c]
        if d == 0.0:
            continue
        i, j = body1[c], body2[c]
        V[i, GU] += d * res[c, NX] * inv_m[i]
        V[i, GV] += d * res[c, NY] * inv_m[i]
        V[i, GOMEGA] += d * rn1[c] * inv_i[i]
        if j >= 0:
            V[j, GU] -= d * res[c, NX] * inv_m[j]
            V[j, GV] -= d * res[c, NY] * inv_m[j]
            V[j, GOMEGA] -= d * rn2[c] * inv_i[j]


@nb.njit(cache=True, _nrt=False, inline="always")
def _normal_velocity(c, body1, body2, res, rn1, rn2, V):
    """Contact c's relative normal velocity u_n = H V (positive: separating)."""
    i, j = body1[c], body2[c]
    nx, ny = res[c, NX], res[c, NY]
    u = V[i, GU] * nx + V[i, GV] * ny + V[i, GOMEGA] * rn1[c]
    if j >= 0:
        u -= V[j, GU] * nx + V[j, GV] * ny + V[j, GOMEGA] * rn2[c]
    return u
