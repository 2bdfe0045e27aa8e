"""Fused tracking steps on mesh flows: one per-log kernel for a whole integrator step.

The general path (``Integrator.step`` with the tracker's ``_rhs``) passes whole arrays
between stages: sample the flow at every log (n, NVAR), evaluate the forces (n, 6), form the
next stage state (n, 6), and so on, four times per RK4 step.  At 1e5 logs and more these
arrays leave the caches and every pass streams them through memory.  Here each log runs all
its stages in registers: for each stage the flow is sampled at the stage position
(``flow.sample_point``: point location walk from the log's face, P1 in space, linear in
time) and the forces evaluated (``physics.log_rhs``), the same inline functions the general
path calls, with the same arithmetic in the same order, so both paths give the same
trajectories bit for bit.  The step also samples the flow at the new position (the tracker's
``F``, ``flag`` and face hints) and evaluates the next step's first stage and drag
linearisation (``D0``, ``lin0``), which the tracker's step bound then reuses.

Within a sub-step the node values do not change except when the step ends on a snapshot
time: there the end-of-step stage uses the next snapshot pair (as the general path does, the
flow's ``node_values`` chooses), so the stage times get their own (node values, weight).

The integrator arithmetic is ``driftlog.integrators``' own (``euler_row``, ``rk4_stage_row``,
``rk4_sum_row``, which ``rk4_final_row`` calls): one RK4 for both paths.  The three RK4
stages run as one loop, so that the inlined sampling and forces are compiled once per kernel.

In the tracker's own loop (no contact model, motion "floating", no waterlogging) the step
also *settles* each log: what the tracker did before in separate passes over the arrays after
every sub-step (tracer velocities set to the flow's, the status from the flow at the new
position, ``stepping.classify``; the next sub-step's bound, ``stepping.step_bound``; the
divergence check) is done in the same loop, with the same arithmetic, into a status and a
bound per log (``settle_summary`` reduces them).  Tracer mode has kernels of its own
(``rk4_tracer_step``, ``euler_tracer_step``): no force evaluation, and the flow read from
packed node rows (``pack_tracer_nodes``: coordinates and the pair's u, v, h in one 64-byte
row per node) instead of the mesh's coordinate arrays and the 20-column node values; the
samples are the general path's numbers bit for bit (each stage's point location walks on
from the previous stage's face: ``rk4_tracer_step``).
"""

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import (
    DRY,
    DUDY,
    DVDX,
    L_PAR,
    L_PERP,
    L_ROT,
    NLIN,
    NSTATE,
    NVAR,
    OMEGA,
    OUTSIDE,
    P_HSTAR,
    Q_H,
    Q_U,
    Q_UY,
    Q_V,
    Q_VX,
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
from driftlog.flow import _triangle_weights, sample_point, sample_point_columns
from driftlog.integrators import (
    FUSED_METHODS,
    RK4_C,
    add_row,
    euler_row,
    put_row,
    rk4_stage_row,
    rk4_sum_row,
    row,
)
from driftlog.locate import MAX_WALK, _bin_search, _edge_side
from driftlog.logs import FLOATING, LEFT, RESTING, STRANDED
from driftlog.physics import O_LEVEL, O_MOTION, O_ROT, TRACER, log_rhs, stage_columns

__all__ = ["euler_mesh_step", "rk4_mesh_step", "rk4_tracer_step", "euler_tracer_step",
           "sample_tracer",
           "pack_tracer_nodes", "aligned_rows", "settle_summary", "FUSED_METHODS", "NCTL",
           "take_rows", "drop_rows", "drop_items", "subset_positions", "skip_hole",
           "HOLE", "PK_N", "PR_N"]

# the step control a settling step reads (``ctl``): length fraction, angle step, drag
# fraction, and 1.0 where the drag relaxation bound applies (explicit integrator, not tracer)
C_LF, C_ANG, C_DRAG, C_EXPLICIT = range(4)
NCTL = 4

# A settling step's ``status`` is read as well as written: a row whose status is HOLE plus a
# log status is a *hole*, a log that stopped (stranded, rested, left) and whose row the
# tracker has left in its compact arrays rather than move every row after it
# (``Tracker._make_holes``).  The step copies a hole's state unchanged and nothing else; the
# holes are dropped together once they are a sixteenth of the rows.
HOLE = 64


@nb.njit(cache=True, inline="always")
def skip_hole(i, S0, out, settle, status):
    """True (and the state copied to ``out``) where row i of a settling step is a hole."""
    if not (settle and status[i] >= HOLE):
        return False
    for k in range(NSTATE):
        out[i, k] = S0[i, k]
    return True


@nb.njit(cache=True, inline="always")
def _finish(i, s, hint, out, face, F, flag, D0, lin0, P, opt, want_next, a, inv_dt, vals,
            dry_depth, recovered, loc, settle, ctl, length, status, bound):
    """Store the new state s, sample the flow there, and the next step's first stage.

    With ``settle`` (the tracker's own loop, no contact model), also what the tracker would
    otherwise do in separate passes over the arrays, with the same arithmetic: tracer mode's
    velocities set to the flow's (``Tracker._sync_tracer``), the log's new status from the flow
    there (``stepping.classify``, motion "floating") into ``status``, and its sub-step bound
    (``stepping.step_bound``'s terms, from the synced state and ``lin0``) into ``bound``, NaN
    where the new state is not finite (the tracker then raises its divergence error).
    """
    if opt[O_LEVEL] == TRACER:
        # what tracer mode reads of the flow at the logs: the depth (status), the velocity and
        # its rotation (the synced state), and the slope when the bed friction test needs it
        f, fg, fl = sample_point_columns(s[X], s[Y], hint, a, inv_dt, vals, dry_depth,
                                         recovered, loc, True, opt[O_ROT] > 0.0, False,
                                         opt[O_MOTION] != 0.0, False)
    else:
        f, fg, fl = sample_point(s[X], s[Y], hint, a, inv_dt, vals, dry_depth, recovered, loc)
    face[i] = f
    flag[i] = fg
    for k in range(NVAR):
        F[i, k] = fl[k]
    lam = 0.0
    if want_next:
        d, ln = log_rhs(s, fl, P[i], opt, True)
        put_row(D0, i, d)
        for k in range(NLIN):
            lin0[i, k] = ln[k]
        lam = max(ln[L_PAR], max(ln[L_PERP], ln[L_ROT]))
    if not settle:
        put_row(out, i, s)
        return
    ub, vb, om = s[UB], s[VB], s[OMEGA]
    if opt[O_LEVEL] == TRACER:
        ub, vb = fl[U], fl[V]
        om = 0.5 * (fl[DVDX] - fl[DUDY]) if opt[O_ROT] > 0.0 else 0.0
    out[i, X] = s[X]
    out[i, Y] = s[Y]
    out[i, THETA] = s[THETA]
    out[i, UB] = ub
    out[i, VB] = vb
    out[i, OMEGA] = om
    if fg == OUTSIDE:
        status[i] = LEFT
    elif fg == DRY:
        status[i] = STRANDED
    elif fl[H] < P[i, P_HSTAR]:
        status[i] = RESTING
    else:
        status[i] = FLOATING
    b = np.inf
    sp = np.sqrt(ub ** 2 + vb ** 2)
    if sp > 0.0:
        b = min(b, ctl[C_LF] * length[i] / sp)
    aom = abs(om)
    if aom > 0.0:
        b = min(b, ctl[C_ANG] / aom)
    if ctl[C_EXPLICIT] != 0.0 and ctl[C_DRAG] > 0.0 and lam > 0.0:
        b = min(b, ctl[C_DRAG] / lam)
    for k in range(NSTATE):
        if not np.isfinite(out[i, k]):
            b = np.nan
    bound[i] = b


@nb.njit(cache=True)
def settle_summary(status, bound):
    """(smallest floating bound, logs no longer floating, logs whose state is not finite).

    Holes (``HOLE``) are left out, and so is the bound of a log that stopped in the step,
    whose row the tracker then drops or leaves as a hole.
    """
    dt = np.inf
    moved = bad = 0
    for i in range(bound.shape[0]):
        if status[i] >= HOLE:
            continue
        b = bound[i]
        if b != b:
            bad += 1
        elif b < dt and status[i] == FLOATING:
            dt = b
        if status[i] != FLOATING:
            moved += 1
    return dt, moved, bad


@nb.njit(cache=True, inline="always")
def _rk4_stage(s0, k, dt, d, hint, a, inv_dt, vals, dry_depth, recovered, loc, p, opt):
    """(face, derivative) at RK4 stage k: its state from s0 and d, the flow there, forces."""
    return _stage_rhs(rk4_stage_row(s0, k, dt, d), hint, a, inv_dt, vals, dry_depth, recovered,
                      loc, p, opt)


@nb.njit(cache=True, inline="always")
def rk4_row(s0, d0, dt, hint, a_m, inv_m, vals_m, a_3, inv_3, vals_3, dry_depth, recovered,
            loc, p, opt):
    """One log's classical RK4 step from s0 with first stage d0 (eq. (46)).

    Stages 1 and 2 read the flow at t0 + dt/2 (``a_m``, ``inv_m``, ``vals_m``), stage 3 at
    t0 + dt (``a_3``, ...).  The first stage's point location starts from the face ``hint``,
    each next one from the face the stage before found (as ``rk4_tracer_step``'s: the same
    face, and numbers, wherever a point is inside one face).  Returns the new state and the
    last stage's face, where the end's point location starts.
    """
    # the three stages in one loop, so that the inlined sampling and forces are compiled once
    # rather than three times (the kernels that inline a step compile several times faster);
    # the same arithmetic in the same order as rk4_final_row
    d = d0
    d1 = d0
    d12 = d0
    for k in range(1, 4):
        a, inv, vals = a_m, inv_m, vals_m
        if k == 3:
            a, inv, vals = a_3, inv_3, vals_3
        f, d = _rk4_stage(s0, k, dt, d, hint, a, inv, vals, dry_depth, recovered, loc, p, opt)
        hint = f if f >= 0 else hint
        if k == 1:
            d1 = d
        elif k == 2:
            d12 = add_row(d1, d)
    s = rk4_sum_row(s0, dt, d0, d12, d)
    # one flat tuple: numba's parfors array analysis fails on a nested one (the state tuple
    # and the face) returned by an inlined function in a prange loop
    return s[0], s[1], s[2], s[3], s[4], s[5], hint


@nb.njit(cache=True, inline="always")
def _stage_rhs(s, hint, a, inv_dt, vals, dry_depth, recovered, loc, p, opt):
    """(face, derivative) at stage state s: the flow there (the columns the forces read)."""
    depth, rot, full, slope = stage_columns(opt)
    f, _, fl = sample_point_columns(s[X], s[Y], hint, a, inv_dt, vals, dry_depth, recovered,
                                    loc, depth, rot, full, slope, False)
    dk, _ = log_rhs(s, fl, p, opt, False)
    return f, dk


@kernel(nrt=False)
def euler_mesh_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, want_next,
                    a_e, inv_e, vals_e, dry_depth, recovered, loc, settle, ctl, length, status,
                    bound):
    """Explicit Euler step of every log from states S0 with first stage D0 (eq. 16).

    Writes the new states into ``out``; the flow at the new positions (time t0 + dt, node
    values ``vals_e`` with weight ``a_e``) into ``F``, ``flag``, ``face``; with
    ``want_next``, the derivative and drag linearisation there into ``D0``, ``lin0``; with
    ``settle``, the statuses and step bounds of ``_finish`` into ``status`` and ``bound``
    (``ctl``: the step control, C_LF ... C_EXPLICIT; ``length``: the logs' lengths).
    """
    for i in nb.prange(S0.shape[0]):
        if skip_hole(i, S0, out, settle, status):
            continue
        s = euler_row(row(S0, i), dt, row(D0, i))
        _finish(i, s, face[i], out, face, F, flag, D0, lin0, P, opt, want_next, a_e, inv_e,
                vals_e, dry_depth, recovered, loc, settle, ctl, length, status, bound)


@kernel(nrt=False)
def rk4_mesh_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, want_next,
                  a_m, inv_m, vals_m, a_e, inv_e, vals_e, dry_depth, recovered, loc, settle, ctl,
                  length, status, bound):
    """Classical RK4 step of every log from states S0 with first stage D0.

    Stages at t0 + dt/2 (node values ``vals_m``, weight ``a_m``) and t0 + dt (``vals_e``,
    ``a_e``); each stage's point location walks on from the previous stage's face
    (``rk4_row``), the general path's from the log's face at t0 (the same faces and numbers
    but for a point on an edge two faces share).  Outputs as ``euler_mesh_step``.
    """
    for i in nb.prange(S0.shape[0]):
        if skip_hole(i, S0, out, settle, status):
            continue
        hint = face[i]
        # stages 1 and 2 at t0 + dt/2, stage 3 at t0 + dt (RK4_C)
        r = rk4_row(row(S0, i), row(D0, i), dt, hint, a_m, inv_m, vals_m, a_e, inv_e, vals_e,
                    dry_depth, recovered, loc, P[i], opt)
        s = (r[0], r[1], r[2], r[3], r[4], r[5])
        hint = r[6]
        _finish(i, s, hint, out, face, F, flag, D0, lin0, P, opt, want_next, a_e, inv_e,
                vals_e, dry_depth, recovered, loc, settle, ctl, length, status, bound)



# --------------------------------------------------------------------- tracer mode
# Tracer mode reads little of the flow (u, v; the depth at the step's end; the rotation's two
# gradient terms with rotation on), but the general sampling finds it in the mesh's node
# coordinates and the snapshot pair's node rows (20 columns: 2-3 cache lines a node) and the
# point location in further arrays: about a dozen cache lines per sample.  Packed per node in
# one row of PK_N columns (coordinates, then each value at the pair's two snapshots), a
# sample reads the face's nodes and one 64-byte row per node.  The values are copies and the
# arithmetic is ``sample_point_columns``' (and the walk ``locate._walk``'s), so the samples are
# the same numbers bit for bit.
PK_X, PK_Y, PK_H0, PK_H1, PK_U0, PK_U1, PK_V0, PK_V1 = range(8)
PK_N = 8
# rotation (recovered gradients): dU/dy and dV/dx at the two snapshots, a row of their own
PR_UY0, PR_UY1, PR_VX0, PR_VX1 = range(4)
PR_N = 4


@kernel
def take_rows(pos, src, out):
    """``out[i] = src[pos[i]]`` for the rows of a 2-D array.

    numpy's fancy indexing takes milliseconds per array at 1e5 logs, on one thread, and the
    tracker gathers several whenever a log stops.
    """
    m = src.shape[1]
    for i in nb.prange(pos.shape[0]):
        k = pos[i]
        for j in range(m):
            out[i, j] = src[k, j]


@kernel
def drop_rows(pos, a, chunks):
    """``a[i] = a[pos[i]]`` in place for the rows of a 2-D array, ``pos`` ascending.

    Rows only move up (pos[i] >= i): the compact arrays lose the rows of logs that stopped
    without a new allocation.  In chunks of rows, in parallel: a chunk's rows are written
    by its own thread only, in order, and read from the chunk itself before they are
    written, except the sources past the chunk's end (at most as many rows as were
    dropped), which another chunk may overwrite: those are copied aside first.  ``chunks``:
    how many (a few per thread).
    """
    n = pos.shape[0]
    m = a.shape[1]
    nc = min(n, max(chunks, 1))
    if nc == 0:
        return
    lo = np.empty(nc + 1, np.int64)
    for c in range(nc + 1):
        lo[c] = c * n // nc
    first = np.empty(nc, np.int64)  # first row of each chunk whose source is past its end
    off = np.zeros(nc + 1, np.int64)
    for c in range(nc):
        hi = lo[c + 1]
        first[c] = lo[c] + np.searchsorted(pos[lo[c]:hi], hi)
        off[c + 1] = off[c] + hi - first[c]
    aside = np.empty((off[nc], m))
    for c in nb.prange(nc):
        for i in range(first[c], lo[c + 1]):
            r = off[c] + i - first[c]
            for j in range(m):
                aside[r, j] = a[pos[i], j]
    for c in nb.prange(nc):
        for i in range(lo[c], first[c]):
            k = pos[i]
            if k != i:
                for j in range(m):
                    a[i, j] = a[k, j]
        for i in range(first[c], lo[c + 1]):
            r = off[c] + i - first[c]
            for j in range(m):
                a[i, j] = aside[r, j]


@nb.njit(cache=True)
def drop_items(pos, a):
    """``drop_rows`` for a 1-D array."""
    for i in range(pos.shape[0]):
        a[i] = a[pos[i]]


@nb.njit(cache=True)
def subset_positions(old, idx, pos):
    """Where each of ``idx`` stands in ``old`` (both ascending), into ``pos`` (-1: not there).

    True when every one of ``idx`` is in ``old``.
    """
    j, n = 0, old.shape[0]
    found = True
    for i in range(idx.shape[0]):
        v = idx[i]
        while j < n and old[j] < v:
            j += 1
        if j < n and old[j] == v:
            pos[i] = j
        else:
            pos[i] = -1
            found = False
    return found


def aligned_rows(n, m):
    """An uninitialised (n, m) float64 array whose rows start on 64-byte boundaries (m = 4, 8)."""
    buf = np.empty(n * m + 8)
    off = (-buf.ctypes.data % 64) // 8
    return buf[off:off + n * m].reshape(n, m)


@nb.njit(cache=True)
def pack_tracer_nodes(vi, vj, cj, node_x, node_y, pk, pr, rot):
    """Fill the packed node rows ``pk`` (and ``pr`` with ``rot``) from a snapshot pair.

    The pair's node columns: snapshot i's in ``vi[:, :NQ]``, snapshot j's in ``vj[:, cj:]``
    (one array of both side by side: ``vi`` = ``vj``, ``cj`` = NQ).
    """
    for j in range(pk.shape[0]):
        pk[j, PK_X] = node_x[j]
        pk[j, PK_Y] = node_y[j]
        pk[j, PK_H0] = vi[j, Q_H]
        pk[j, PK_H1] = vj[j, Q_H + cj]
        pk[j, PK_U0] = vi[j, Q_U]
        pk[j, PK_U1] = vj[j, Q_U + cj]
        pk[j, PK_V0] = vi[j, Q_V]
        pk[j, PK_V1] = vj[j, Q_V + cj]
        if rot:
            pr[j, PR_UY0] = vi[j, Q_UY]
            pr[j, PR_UY1] = vj[j, Q_UY + cj]
            pr[j, PR_VX0] = vi[j, Q_VX]
            pr[j, PR_VX1] = vj[j, Q_VX + cj]


@nb.njit(cache=True, inline="always")
def _walk_packed(px, py, f, loc, pk):
    """``locate._walk`` reading the node coordinates from the packed rows."""
    face_nodes, face_n, face_nbr = loc.face_nodes, loc.face_n, loc.face_nbr
    for _ in range(MAX_WALK):
        n = face_n[f]
        worst = 0.0
        kworst = -1
        for k in range(n):
            a = face_nodes[f, k]
            b = face_nodes[f, k + 1] if k + 1 < n else face_nodes[f, 0]
            c, s = _edge_side(px, py, pk[a, PK_X], pk[a, PK_Y], pk[b, PK_X], pk[b, PK_Y])
            if c < -1e-12 * s:
                d = c / np.sqrt(s)
                if d < worst:
                    worst = d
                    kworst = k
        if kworst < 0:
            return f
        g = face_nbr[f, kworst]
        if g < 0:
            return -1
        f = g
    return -1


@nb.njit(cache=True, inline="always")
def _p1v(pk, c0, n0, n1, n2, a, b, la, lb, lc):
    """``flow._p1``'s value of the column pair (c0, c0 + 1) of the packed rows."""
    va = b * pk[n0, c0] + a * pk[n0, c0 + 1]
    vb = b * pk[n1, c0] + a * pk[n1, c0 + 1]
    vc = b * pk[n2, c0] + a * pk[n2, c0 + 1]
    return la * va + lb * vb + lc * vc, va, vb, vc


@nb.njit(cache=True, inline="always")
def sample_tracer(x, y, hint, a, pk, pr, loc, dry_depth, recovered, depth, rot):
    """Locate and sample what tracer mode reads: (face, flag, h, u, v, dU/dy, dV/dx).

    The same numbers as ``sample_point_columns(..., depth, rot, False, False, False)``: h
    only with ``depth`` (else 0, the flag then wet where located), the gradient terms only
    with ``rot``.
    """
    f = -1
    if np.isfinite(x) and np.isfinite(y):
        if hint >= 0:
            f = _walk_packed(x, y, hint, loc, pk)
        if f < 0:
            f = _bin_search(x, y, loc)
    if f < 0:
        return f, OUTSIDE, 0.0, 0.0, 0.0, 0.0, 0.0
    b = 1.0 - a
    face_nodes, face_n = loc.face_nodes, loc.face_n
    n0 = face_nodes[f, 0]
    k = 1
    while k < face_n[f] - 2:
        nk1 = face_nodes[f, k + 1]
        c = ((pk[nk1, PK_X] - pk[n0, PK_X]) * (y - pk[n0, PK_Y])
             - (pk[nk1, PK_Y] - pk[n0, PK_Y]) * (x - pk[n0, PK_X]))
        if c <= 0.0:
            break
        k += 1
    n1 = face_nodes[f, k]
    n2 = face_nodes[f, k + 1]
    la, lb, lc, gax, gay, gbx, gby, gcx, gcy = _triangle_weights(
        x, y, pk[n0, PK_X], pk[n0, PK_Y], pk[n1, PK_X], pk[n1, PK_Y], pk[n2, PK_X],
        pk[n2, PK_Y])
    h = uy = vx = 0.0
    if depth:
        h = max(_p1v(pk, PK_H0, n0, n1, n2, a, b, la, lb, lc)[0], 0.0)
    u, ua, ub, uc = _p1v(pk, PK_U0, n0, n1, n2, a, b, la, lb, lc)
    v, va, vb, vc = _p1v(pk, PK_V0, n0, n1, n2, a, b, la, lb, lc)
    if rot:
        if recovered:
            uy = _p1v(pr, PR_UY0, n0, n1, n2, a, b, la, lb, lc)[0]
            vx = _p1v(pr, PR_VX0, n0, n1, n2, a, b, la, lb, lc)[0]
        else:
            uy = gay * ua + gby * ub + gcy * uc
            vx = gax * va + gbx * vb + gcx * vc
    flag = (WET if h > dry_depth else DRY) if depth else WET
    return f, flag, h, u, v, uy, vx


@nb.njit(cache=True, inline="always")
def _tracer_finish(i, x, y, th, c6, hint, S0, D0, lin0, out, face, F, flag, P, rot, a_e, pk_e,
                   pr_e, dry_depth, recovered, loc, settle, ctl, length, status, bound):
    """A tracer's new position (x, y, th): the flow there, the next first stage, the rest.

    ``c6``: the factor of the integrator's update of the velocity columns (their derivative
    is 0; the general step leaves s + c6 (0 + 2 (0 + 0) + 0) for RK4, s + dt 0 for Euler);
    with ``settle``, ``_finish``'s status and bound.
    """
    f, fg, h, u, v, uy, vx = sample_tracer(x, y, hint, a_e, pk_e, pr_e, loc, dry_depth,
                                           recovered, True, rot)
    om = 0.5 * (vx - uy) if rot else 0.0
    face[i] = f
    flag[i] = fg
    for k in range(NVAR):
        F[i, k] = 0.0
    F[i, H] = h
    F[i, U] = u
    F[i, V] = v
    F[i, DUDY] = uy
    F[i, DVDX] = vx
    # the next step's first stage (physics.log_rhs in tracer mode) and its linearisation
    D0[i, X] = u
    D0[i, Y] = v
    D0[i, THETA] = om
    D0[i, UB] = 0.0
    D0[i, VB] = 0.0
    D0[i, OMEGA] = 0.0
    for k in range(NLIN):
        lin0[i, k] = 0.0
    out[i, X] = x
    out[i, Y] = y
    out[i, THETA] = th
    if not settle:
        out[i, UB] = S0[i, UB] + c6
        out[i, VB] = S0[i, VB] + c6
        out[i, OMEGA] = S0[i, OMEGA] + c6
        return
    out[i, UB] = u
    out[i, VB] = v
    out[i, OMEGA] = om
    if fg == OUTSIDE:
        status[i] = LEFT
    elif fg == DRY:
        status[i] = STRANDED
    elif h < P[i, P_HSTAR]:
        status[i] = RESTING
    else:
        status[i] = FLOATING
    b = np.inf
    sp = np.sqrt(u ** 2 + v ** 2)
    if sp > 0.0:
        b = min(b, ctl[C_LF] * length[i] / sp)
    aom = abs(om)
    if aom > 0.0:
        b = min(b, ctl[C_ANG] / aom)
    if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(th) and np.isfinite(u)
            and np.isfinite(v) and np.isfinite(om)):
        b = np.nan
    bound[i] = b


@kernel(nrt=False)
def rk4_tracer_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, a_m, pk_m, pr_m, a_e, pk_e,
                    pr_e, dry_depth, recovered, loc, settle, ctl, length, status, bound):
    """``rk4_mesh_step`` in tracer mode (``opt`` level tracer, motion "floating"), same numbers.

    The flow on the packed node rows of the snapshot pairs at t0 + dt/2 (``pk_m``, ``pr_m``,
    weight ``a_m``) and t0 + dt (``pk_e``, ``pr_e``, ``a_e``): ``pack_tracer_nodes``.  A
    tracer's derivative is the flow's velocity (and rotation rate): the stages need no force
    evaluation; the columns of ``F`` written are those tracer mode computes (the others 0).
    Each stage's point location (and the new position's) starts from the face the previous
    stage found: the same face as a walk from t0's face wherever a point is inside one face,
    so the same numbers (a point on an edge two faces share, within the walk's tolerance,
    may be placed in the other face, whose P1 values agree there to round-off).
    """
    rot = opt[O_ROT] > 0.0
    for i in nb.prange(S0.shape[0]):
        if skip_hole(i, S0, out, settle, status):
            continue
        hint = face[i]
        x0, y0, th0 = S0[i, X], S0[i, Y], S0[i, THETA]
        dx0, dy0, dth0 = D0[i, X], D0[i, Y], D0[i, THETA]
        # stages 1 and 2 at t0 + dt/2, stage 3 at t0 + dt (the state arithmetic of
        # integrators.rk4_stage_row: s0 + c dt d)
        # each stage's point location walks from the face the stage before it found (the
        # log's face at t0 for the first): the stage points follow one another, a step of a
        # tracer may cross many faces, and a walk from t0's face would cross them again
        c = RK4_C[1] * dt
        f, _, _, u1, v1, uy, vx = sample_tracer(x0 + c * dx0, y0 + c * dy0, hint, a_m, pk_m,
                                                pr_m, loc, dry_depth, recovered, False, rot)
        w1 = 0.5 * (vx - uy) if rot else 0.0
        hint = f if f >= 0 else hint
        c = RK4_C[2] * dt
        f, _, _, u2, v2, uy, vx = sample_tracer(x0 + c * u1, y0 + c * v1, hint, a_m, pk_m,
                                                pr_m, loc, dry_depth, recovered, False, rot)
        w2 = 0.5 * (vx - uy) if rot else 0.0
        hint = f if f >= 0 else hint
        c = RK4_C[3] * dt
        f, _, _, u3, v3, uy, vx = sample_tracer(x0 + c * u2, y0 + c * v2, hint, a_e, pk_e,
                                                pr_e, loc, dry_depth, recovered, False, rot)
        w3 = 0.5 * (vx - uy) if rot else 0.0
        hint = f if f >= 0 else hint
        # integrators.rk4_final_row
        c6 = dt / 6.0
        x = x0 + c6 * (dx0 + 2.0 * (u1 + u2) + u3)
        y = y0 + c6 * (dy0 + 2.0 * (v1 + v2) + v3)
        th = th0 + c6 * (dth0 + 2.0 * (w1 + w2) + w3)
        _tracer_finish(i, x, y, th, c6 * (0.0 + 2.0 * (0.0 + 0.0) + 0.0), hint, S0, D0, lin0,
                       out, face, F, flag, P, rot, a_e, pk_e, pr_e, dry_depth, recovered, loc,
                       settle, ctl, length, status, bound)


@kernel(nrt=False)
def euler_tracer_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, a_e, pk_e, pr_e,
                      dry_depth, recovered, loc, settle, ctl, length, status, bound):
    """``euler_mesh_step`` in tracer mode, same numbers (see ``rk4_tracer_step``)."""
    rot = opt[O_ROT] > 0.0
    for i in nb.prange(S0.shape[0]):
        if skip_hole(i, S0, out, settle, status):
            continue
        # integrators.euler_row: s0 + dt d0
        _tracer_finish(i, S0[i, X] + dt * D0[i, X], S0[i, Y] + dt * D0[i, Y],
                       S0[i, THETA] + dt * D0[i, THETA], dt * 0.0, face[i], S0, D0, lin0, out,
                       face, F, flag, P, rot, a_e, pk_e, pr_e, dry_depth, recovered, loc,
                       settle, ctl, length, status, bound)
