"""Kernels of the two-way coupling (``driftlog.coupling``): per solver step, over flat arrays.

- ``mark_region``: the nodes of the faces within a distance of the logs (a box around each,
  through the locator's bin grid), the only nodes whose values the logs can sample in a step;
- ``node_rows``: the node columns (value and recovered gradients) of chosen nodes from the
  solver's face state, the same sums in the same order as ``MeshFlowField._load``'s sparse
  products, so the values are those of the whole-mesh projection bit for bit;
- ``shift_rows``: a new step's interval starts where the last one ended: the end columns of
  the region's nodes become its start columns, nodes that left the region are poisoned (NaN);
- ``region_points`` and ``refocus``: the points the logs may be sampled at, and the whole
  change of region before a step in one call (the kernels above and the copy of the state);
- ``gather_reaction``: the logs with a reaction to hand over and their rows, from the
  tracker's compact arrays (floating logs) or the full ones (the others), without scattering;
- ``spread_footprint``, ``spread_reaction`` and ``give_share``: the logs' reaction shared
  among the faces under their plans by area (``footprint_area``: each face cut to the log's
  rectangle), or spread over points along their axes (a log whose two ends lie well inside
  its centre's face has every point there, without locating them), then given to their
  water, all of it or a share (``driftlog.solver.momentum.add_face_momentum``'s arithmetic);
- ``account_advance`` and ``account_contacts``: the momentum the water gave each floating log
  over a free sub-step, and the entrained water's share of the contacts' velocity changes;
- ``keep_linearisation`` and ``held_drag``: the drag a contact-held log bears beyond what its
  free sub-step integrated (docs/model.md (73a));
- ``contact_changes``: ``held_drag`` then ``account_contacts``, in one call;
- ``all_finite``: whether a sub-step's logs stayed in the region (no NaN in their state or
  flow), without numpy's temporaries.
"""

import numba as nb
import numpy as np

from driftlog.columns import (
    NQ,
    Q_ETA,
    Q_EX,
    Q_EY,
    Q_H,
    Q_U,
    Q_UX,
    Q_UY,
    Q_V,
    Q_VX,
    Q_VY,
    THETA,
    UB,
    VB,
    X,
    Y,
)
from driftlog.locate import _edge_side, locate_one

__all__ = ["mark_region", "node_rows", "shift_rows", "poison_rows", "spread_reaction",
           "spread_footprint", "footprint_area", "give_share",
           "region_points", "refocus",
           "gather_reaction",
           "account_advance", "account_contacts", "keep_linearisation", "held_drag",
           "contact_changes", "all_finite"]


@nb.njit(cache=True)
def mark_region(x, y, margin, loc, bin_mark, face_mark, node_mark, stamp, old_stamp, rows,
                fresh):
    """Nodes of every face that may hold a point within ``margin`` of a point (x[i], y[i]).

    A face is taken when it is listed in a bin of the locator's grid that overlaps the box
    [x - margin, x + margin] x [y - margin, y + margin] of a point (every face that holds a
    point of the box is listed in the bin of that point).  Each node is written once into
    ``rows`` (its count returned) and marked ``stamp`` in ``node_mark``; ``fresh[k]`` says
    whether ``rows[k]`` was not marked ``old_stamp`` before (not in the previous region).
    """
    nbx, nby = loc.nbx, loc.nby
    x0, y0, idx, idy = loc.x0, loc.y0, loc.inv_dx, loc.inv_dy
    bin_start, bin_faces = loc.bin_start, loc.bin_faces
    face_nodes, face_n = loc.face_nodes, loc.face_n
    count = 0
    for p in range(x.shape[0]):
        px, py = x[p], y[p]
        if not (np.isfinite(px) and np.isfinite(py)):
            continue
        i0 = max(int(np.floor((px - margin - x0) * idx)), 0)
        i1 = min(int(np.floor((px + margin - x0) * idx)), nbx - 1)
        j0 = max(int(np.floor((py - margin - y0) * idy)), 0)
        j1 = min(int(np.floor((py + margin - y0) * idy)), nby - 1)
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                b = j * nbx + i
                if bin_mark[b] == stamp:
                    continue
                bin_mark[b] = stamp
                for k in range(bin_start[b], bin_start[b + 1]):
                    f = bin_faces[k]
                    if face_mark[f] == stamp:
                        continue
                    face_mark[f] = stamp
                    for q in range(face_n[f]):
                        n = face_nodes[f, q]
                        if node_mark[n] != stamp:
                            fresh[count] = node_mark[n] != old_stamp
                            node_mark[n] = stamp
                            rows[count] = n
                            count += 1
    return count


@nb.njit(cache=True)
def node_rows(rows, count, col, vp, vx, vy, indptr, face, state_face, h, hu, hv, bed, dry_depth,
              recovered, vals):
    """Node columns of nodes ``rows[:count]`` into ``vals[:, col:col + NQ]``.

    ``vp``, ``vx``, ``vy``: the data of the value and gradient operators (one sparsity
    pattern: ``indptr``, ``face`` the mesh's face of each entry, ``state_face`` its index in
    the state arrays ``h``, ``hu``, ``hv``); ``bed`` in the mesh's numbering.  Velocity 0 on
    faces not deeper than ``dry_depth``.  Each sum starts from 0 and adds the entries in their
    order, as scipy's sparse product does: the same numbers as the whole-mesh projection.
    Returns the largest node speed sqrt(u^2 + v^2) among them (m/s).
    """
    vmax = 0.0
    for k in range(count):
        r = rows[k]
        sh = su = sv = se = 0.0
        xu = xv = xe = yu = yv = ye = 0.0
        for e in range(indptr[r], indptr[r + 1]):
            s = state_face[e]
            d = h[s]
            if d > dry_depth:
                u = hu[s] / d
                v = hv[s] / d
            else:
                u = 0.0
                v = 0.0
            eta = d + bed[face[e]]
            w = vp[e]
            sh += w * d
            su += w * u
            sv += w * v
            se += w * eta
            if recovered:
                w = vx[e]
                xu += w * u
                xv += w * v
                xe += w * eta
                w = vy[e]
                yu += w * u
                yv += w * v
                ye += w * eta
        vals[r, col + Q_H] = sh if sh >= 0.0 else 0.0  # np.maximum(h, 0)
        vals[r, col + Q_U] = su
        vals[r, col + Q_V] = sv
        vals[r, col + Q_ETA] = se
        vals[r, col + Q_UX] = xu
        vals[r, col + Q_UY] = yu
        vals[r, col + Q_VX] = xv
        vals[r, col + Q_VY] = yv
        vals[r, col + Q_EX] = xe
        vals[r, col + Q_EY] = ye
        vmax = max(vmax, np.sqrt(su * su + sv * sv))
    return vmax


@nb.njit(cache=True)
def shift_rows(rows, count, fresh, vals):
    """The end columns of the region's nodes that were in it before become start columns.

    Returns the nodes that were not (``fresh``), to be computed from the state, packed at the
    start of a new array.
    """
    todo = np.empty(count, np.int64)
    m = 0
    for k in range(count):
        r = rows[k]
        if fresh[k]:
            todo[m] = r
            m += 1
        else:
            for q in range(NQ):
                vals[r, q] = vals[r, q + NQ]
    return todo[:m]


@nb.njit(cache=True)
def poison_rows(rows, count, node_mark, stamp, vals):
    """NaN in every column of nodes ``rows[:count]`` not marked ``stamp`` (out of the region).

    A log that samples them gets NaN values, hence a non-finite state or flow sample, which
    the coupled tracker detects (and then computes the whole mesh): never a stale value.
    """
    for k in range(count):
        r = rows[k]
        if node_mark[r] != stamp:
            for q in range(2 * NQ):
                vals[r, q] = np.nan


@nb.njit(cache=True)
def region_points(state, all_state, status, recorded_left, floating, x, y):
    """The points the tracker may sample in a step: every floating log, then the others.

    The floating logs' centres from their compact rows ``state``; the other logs' (resting,
    stranded, waiting, gone and not recorded yet: ``status != floating`` and not
    ``recorded_left``) from ``all_state``, in their order, into ``x``, ``y``.  Returns their
    count and the largest squared speed of the floating logs (-1.0 with none).
    """
    n = 0
    v2 = -1.0
    for i in range(state.shape[0]):
        x[n] = state[i, X]
        y[n] = state[i, Y]
        n += 1
        w = state[i, UB] * state[i, UB] + state[i, VB] * state[i, VB]
        if w > v2 or w != w:
            v2 = w
    for j in range(status.shape[0]):
        if status[j] != floating and not recorded_left[j]:
            x[n] = all_state[j, X]
            y[n] = all_state[j, Y]
            n += 1
    return n, v2


@nb.njit(cache=True)
def refocus(x, y, margin, loc, bin_mark, face_mark, node_mark, stamp, old_stamp, rows, fresh,
            spare, spare_count, vals, vp, vx, vy, indptr, face, state_face, h, hu, hv, bed,
            dry_depth, recovered, start_h, start_hu, start_hv):
    """A new step's region, in one call: what ``SolverFlow.focus`` does.

    The region's nodes (``mark_region`` into ``rows``), the end columns of those that were
    in the old one become start columns and the start columns of the others are computed
    from the state (``shift_rows``, ``node_rows``), the nodes of the old region ``spare[:
    spare_count]`` that left it are poisoned (``poison_rows``), and the state is copied to
    ``start_*`` (the interval's start, for ``widen``).  Returns the region's node count.
    """
    n = mark_region(x, y, margin, loc, bin_mark, face_mark, node_mark, stamp, old_stamp, rows,
                    fresh)
    todo = shift_rows(rows, n, fresh, vals)
    node_rows(todo, todo.shape[0], 0, vp, vx, vy, indptr, face, state_face, h, hu, hv, bed,
              dry_depth, recovered, vals)
    poison_rows(spare, spare_count, node_mark, stamp, vals)
    for f in range(h.shape[0]):
        start_h[f] = h[f]
        start_hu[f] = hu[f]
        start_hv[f] = hv[f]
    return n


@nb.njit(cache=True)
def _well_inside(px, py, f, loc):
    """Whether (px, py) is inside face f by a margin far above round-off on every edge.

    Two such points have every point between them inside f (a convex face; the sides are
    linear along a segment) with room to spare: ``locate_one`` from f returns f for each.
    """
    face_nodes = loc.face_nodes
    n = loc.face_n[f]
    for k in range(n):
        a = face_nodes[f, k]
        b = face_nodes[f, k + 1] if k + 1 < n else face_nodes[f, 0]
        c, s = _edge_side(px, py, loc.node_x[a], loc.node_y[a], loc.node_x[b], loc.node_y[b])
        if not c > 1e-9 * s:
            return False
    return True


@nb.njit(cache=True, inline="always")
def _add_share(sx, sy, touched, nt, f, mx, my):
    """Add (mx, my) to face f's sums, listing f in ``touched`` if they were zero; new nt."""
    if sx[f] == 0.0 and sy[f] == 0.0:
        touched[nt] = f
        nt += 1
    sx[f] += mx
    sy[f] += my
    return nt


@nb.njit(cache=True)
def spread_reaction(got, x, y, cos_t, sin_t, length, hint, points, loc, h, state_face,
                    dry_depth, sx, sy, touched, nt):
    """The opposite of the momentum ``got`` (n, 2) of each log, summed per face into sx, sy.

    Each log's share is spread evenly over ``points`` points along its axis (centre (x, y),
    direction (cos_t, sin_t)) and added to the face under each point; a point outside the
    mesh or on a face not deeper than ``dry_depth`` gives its share to the log's own face
    (located from ``hint``).  The sums per face are made in the order of the logs and points
    (as ``np.bincount``); a face whose sums are zero on entry is listed in ``touched`` from
    ``nt`` on.  Returns (nt, undelivered x, undelivered y): the faces listed, and what found
    no face (a log outside the mesh).
    """
    ux = uy = 0.0
    for i in range(got.shape[0]):
        gx, gy = got[i, 0], got[i, 1]
        if gx == 0.0 and gy == 0.0:
            continue
        hi = hint[i]
        centre = locate_one(x[i], y[i], hi if 0 <= hi < sx.shape[0] else -1, loc)
        mx = -gx / points
        my = -gy / points
        # both ends well inside the log's face: every point is in it (no walk to make)
        within = False
        if centre >= 0:
            s = (0.5 / points - 0.5) * length[i]
            e = ((points - 0.5) / points - 0.5) * length[i]
            within = (_well_inside(x[i] + s * cos_t[i], y[i] + s * sin_t[i], centre, loc)
                      and _well_inside(x[i] + e * cos_t[i], y[i] + e * sin_t[i], centre, loc))
        for k in range(points):
            if within:
                f = centre
            else:
                s = ((k + 0.5) / points - 0.5) * length[i]
                f = locate_one(x[i] + s * cos_t[i], y[i] + s * sin_t[i], centre, loc)
            if f < 0 or h[state_face[max(f, 0)]] <= dry_depth:
                f = centre
            if f < 0:
                ux += mx
                uy += my
                continue
            nt = _add_share(sx, sy, touched, nt, f, mx, my)
    return nt, ux, uy


@nb.njit(cache=True, inline="always")
def _clip_half(ps, pt, n, qs, qt, a, b, c):
    """Sutherland-Hodgman: the polygon (ps, pt)[:n] cut to a s + b t <= c, into (qs, qt).

    A convex polygon gains at most one vertex; round-off on vertices lying on the line could
    make more sign changes, so writes stop at the buffer's end (such vertices bound slivers
    of round-off: no area is lost that matters).
    """
    cap = qs.shape[0]
    m = 0
    for k in range(n):
        j = k + 1 if k + 1 < n else 0
        s0, t0, s1, t1 = ps[k], pt[k], ps[j], pt[j]
        d0 = a * s0 + b * t0 - c
        d1 = a * s1 + b * t1 - c
        if d0 <= 0.0 and m < cap:
            qs[m] = s0
            qt[m] = t0
            m += 1
        if ((d0 < 0.0 < d1) or (d1 < 0.0 < d0)) and m < cap:
            w = d0 / (d0 - d1)
            qs[m] = s0 + w * (s1 - s0)
            qt[m] = t0 + w * (t1 - t0)
            m += 1
    return m


@nb.njit(cache=True)
def footprint_area(f, cx, cy, ct, st, half_l, half_w, loc, work):
    """Area of face f inside the rectangle of centre (cx, cy), axis (ct, st), half-sides.

    The face's nodes in the rectangle's frame (s along the axis, t across), cut to the four
    sides (``_clip_half``), the shoelace area of what is left.  ``work`` (4, >= nmax + 4).
    """
    n = loc.face_n[f]
    ps, pt, qs, qt = work[0], work[1], work[2], work[3]
    smin = tmin = np.inf
    smax = tmax = -np.inf
    for k in range(n):
        a = loc.face_nodes[f, k]
        dx = loc.node_x[a] - cx
        dy = loc.node_y[a] - cy
        ps[k] = dx * ct + dy * st
        pt[k] = -dx * st + dy * ct
        smin = min(smin, ps[k])
        smax = max(smax, ps[k])
        tmin = min(tmin, pt[k])
        tmax = max(tmax, pt[k])
    if smin >= half_l or smax <= -half_l or tmin >= half_w or tmax <= -half_w:
        return 0.0
    if not (smin >= -half_l and smax <= half_l and tmin >= -half_w and tmax <= half_w):
        n = _clip_half(ps, pt, n, qs, qt, 1.0, 0.0, half_l)
        n = _clip_half(qs, qt, n, ps, pt, -1.0, 0.0, half_l)
        n = _clip_half(ps, pt, n, qs, qt, 0.0, 1.0, half_w)
        n = _clip_half(qs, qt, n, ps, pt, 0.0, -1.0, half_w)
    area = 0.0
    for k in range(n):
        j = k + 1 if k + 1 < n else 0
        area += ps[k] * pt[j] - ps[j] * pt[k]
    return max(0.5 * area, 0.0)


@nb.njit(cache=True)
def spread_footprint(got, x, y, cos_t, sin_t, length, radius, hint, loc, h, state_face,
                     dry_depth, sx, sy, touched, nt, mark, stamp, queue, area, work):
    """The opposite of the momentum ``got`` (n, 2) of each log, spread over its footprint.

    The footprint is the log's plan, the rectangle ``length`` x 2 ``radius`` about its
    centre (x, y) and axis (cos_t, sin_t); each face takes the share of its area inside it
    (``footprint_area``; docs/model.md eq. (72)).  The faces are found by a walk over
    neighbours from the face of the centre (located from ``hint``), through the faces that
    overlap the footprint.  What lies outside the mesh or on a face not deeper than
    ``dry_depth`` goes to the centre's face, which takes what the others leave, so that the
    shares sum to the whole.  A log whose footprint lies inside its centre's face (the four
    corners) gives it all there, without a walk.  ``mark`` (n_faces, int64), a stamp per
    log from ``stamp`` on (returned, with nt, undelivered x and y); ``queue``, ``area``
    (n_faces) and ``work`` (4, >= nmax + 4) are buffers; sums per face and ``touched`` as
    ``spread_reaction``'s.
    """
    ux = uy = 0.0
    for i in range(got.shape[0]):
        gx, gy = got[i, 0], got[i, 1]
        if gx == 0.0 and gy == 0.0:
            continue
        hi = hint[i]
        centre = locate_one(x[i], y[i], hi if 0 <= hi < sx.shape[0] else -1, loc)
        if centre < 0:
            ux -= gx
            uy -= gy
            continue
        cx, cy, ct, st = x[i], y[i], cos_t[i], sin_t[i]
        half_l, half_w = 0.5 * length[i], radius[i]
        whole = 4.0 * half_l * half_w
        nq = 0
        inside = True
        for a in (-1.0, 1.0):
            for b in (-1.0, 1.0):
                px = cx + a * half_l * ct - b * half_w * st
                py = cy + a * half_l * st + b * half_w * ct
                if inside and not _well_inside(px, py, centre, loc):
                    inside = False
        if not inside:
            stamp += 1
            mark[centre] = stamp
            queue[0] = centre
            nq = 1
            k = 0
            while k < nq:
                f = queue[k]
                a_f = footprint_area(f, cx, cy, ct, st, half_l, half_w, loc, work)
                area[k] = a_f
                k += 1
                if a_f <= 0.0:
                    continue
                for e in range(loc.face_n[f]):
                    g = loc.face_nbr[f, e]
                    if g >= 0 and mark[g] != stamp:
                        mark[g] = stamp
                        queue[nq] = g
                        nq += 1
        # the other faces' shares, in the order found; the centre's face takes the rest
        rx, ry = -gx, -gy
        for k in range(1, nq):
            f = queue[k]
            if area[k] <= 0.0 or h[state_face[f]] <= dry_depth:
                continue
            w = area[k] / whole
            mx, my = -gx * w, -gy * w
            nt = _add_share(sx, sy, touched, nt, f, mx, my)
            rx -= mx
            ry -= my
        nt = _add_share(sx, sy, touched, nt, centre, rx, ry)
    return nt, ux, uy, stamp


@nb.njit(cache=True)
def give_share(frac, sx, sy, touched, nt, h, state_face, area, density, dry_depth, hu, hv,
               out, seen, stamp):
    """Give the water the share ``frac`` of the momentum pending on faces touched[:nt].

    The pending momentum (kg m/s) per face is (sx, sy) (``spread_reaction``); a wet face's
    unit discharges change by frac P / (rho A) (``driftlog.solver.momentum.add_face_momentum``;
    ``h``, ``hu``, ``hv`` the solver's state arrays, ``state_face`` the index there of each
    mesh face) and its pending momentum falls by what it gave
    (with frac = 1 it is then zero exactly); a face not deeper than ``dry_depth`` keeps its
    share for later, unless ``frac`` is 1 (the last share: then it is undelivered).  The list
    keeps the faces with momentum still pending, once each (a face listed twice is given
    once: ``seen[f]`` is set to ``stamp``, a number not in ``seen`` before the call).
    ``out``: (given x, given y, undelivered x, undelivered y) are added to it.  Returns the
    faces still listed.
    """
    m = 0
    for k in range(nt):
        f = touched[k]
        if seen[f] == stamp:
            continue  # listed twice: given once
        seen[f] = stamp
        px, py = sx[f], sy[f]
        if px == 0.0 and py == 0.0:
            continue  # nothing pending
        s = state_face[f]
        if h[s] <= dry_depth:
            if frac >= 1.0:
                out[2] += px
                out[3] += py
                sx[f] = sy[f] = 0.0
                continue
            gx = gy = 0.0
        else:
            gx, gy = frac * px, frac * py
            scale = 1.0 / (density * area[f])
            hu[s] += gx * scale
            hv[s] += gy * scale
            out[0] += gx
            out[1] += gy
        sx[f] = px - gx
        sy[f] = py - gy
        if sx[f] != 0.0 or sy[f] != 0.0:
            touched[m] = f
            m += 1
        else:
            sx[f] = sy[f] = 0.0  # no negative zero left behind
    return m


@nb.njit(cache=True)
def gather_reaction(got, act, state, face, all_state, all_face, length, radius, where, g, x, y,
                    theta, ln, rd, hint):
    """The logs with a reaction to hand over, in their order, and their rows; ``got`` cleared.

    ``act``: the floating logs, whose current state and face hint are the compact rows
    ``state``, ``face``; the others' are ``all_state``, ``all_face`` (what
    ``Tracker._scatter`` would make of them).  ``where``: -1 for every log on entry and on
    return (a buffer).  Writes, for each log with ``got`` not zero, its reaction, centre,
    angle, length, radius and face hint into ``g``, ``x``, ``y``, ``theta``, ``ln``, ``rd``,
    ``hint``; returns their count.
    """
    for p in range(act.shape[0]):
        where[act[p]] = p
    m = 0
    for j in range(got.shape[0]):
        gx, gy = got[j, 0], got[j, 1]
        if gx == 0.0 and gy == 0.0:
            continue
        p = where[j]
        if p >= 0:
            x[m], y[m], theta[m] = state[p, X], state[p, Y], state[p, THETA]
            hint[m] = face[p]
        else:
            x[m], y[m], theta[m] = all_state[j, X], all_state[j, Y], all_state[j, THETA]
            hint[m] = all_face[j]
        g[m, 0] = gx
        g[m, 1] = gy
        ln[m] = length[j]
        rd[m] = radius[j]
        got[j, 0] = 0.0
        got[j, 1] = 0.0
        m += 1
    for p in range(act.shape[0]):
        where[act[p]] = -1
    return m


@nb.njit(cache=True)
def account_advance(act, state, u0, v0, mass, added_mass, received, last_u, stamp, advances):
    """After a free sub-step: each floating log received m_eff (U_b - U_b0) from the water.

    ``act`` the logs' indices, ``state`` their compact states, (u0, v0) their velocities
    before, ``mass`` their compact masses, ``added_mass`` over all logs.
    """
    for i in range(act.shape[0]):
        j = act[i]
        m = mass[i] + added_mass[j]
        received[j, 0] += m * (state[i, UB] - u0[i])
        received[j, 1] += m * (state[i, VB] - v0[i])
        last_u[j, 0] = state[i, UB]
        last_u[j, 1] = state[i, VB]
        stamp[j] = advances


@nb.njit(cache=True)
def account_contacts(act, state, last_u, stamp, advances, added_mass, to_contacts):
    """The entrained water's share m_a dU_b of velocity changes made since the last sub-step.

    For the floating logs whose last free sub-step was the latest one (``stamp``), summed in
    their order into ``to_contacts`` (subtracted), and their ``last_u`` brought up to date.
    """
    sx = sy = 0.0
    any_ = False
    for i in range(act.shape[0]):
        j = act[i]
        if stamp[j] != advances:
            continue
        ma = added_mass[j]
        dx = ma * (state[i, UB] - last_u[j, 0])
        dy = ma * (state[i, VB] - last_u[j, 1])
        if any_:
            sx += dx
            sy += dy
        else:
            sx, sy = dx, dy
            any_ = True
        last_u[j, 0] = state[i, UB]
        last_u[j, 1] = state[i, VB]
    if any_:
        to_contacts[0] -= sx
        to_contacts[1] -= sy


@nb.njit(cache=True)
def keep_linearisation(act, lin, dt, lin_last, dt_last):
    """Keep each log's drag linearisation at the start of its free sub-step, and the step."""
    for i in range(act.shape[0]):
        j = act[i]
        for k in range(4):  # L_PAR, L_PERP, L_WX, L_WY
            lin_last[j, k] = lin[i, k]
        dt_last[j] = dt


@nb.njit(cache=True)
def held_drag(act, state, last_u, stamp, advances, mass, added_mass, lin_last, dt_last,
              received, to_contacts):
    """The drag a contact-held log bears beyond what its free sub-step integrated.

    A free sub-step integrates the fluid forces along the log's unconstrained path (it
    accelerates, its relative velocity and drag fall); the contacts then take back the velocity
    change dU_c = U_b - U_b,free.  Along the path the contacts held it on, the fluid force is
    larger by the linearised drag times the velocity difference, which grows linearly over the
    step from 0 to -dU_c (the contact force acting over the step):

        dJ = -(dt / 2) m_eff A dU_c,   A = l_par n n^T + l_perp (I - n n^T)

    (docs/model.md (73a); exact for a quadratic drag law held at rest).  The log's velocity is
    the contacts' (it is held), so dJ is passed on to them: added to what the log received
    from the water and to ``to_contacts``.  Call before ``account_contacts`` (which brings
    ``last_u`` up to date).
    """
    sx = sy = 0.0
    for i in range(act.shape[0]):
        j = act[i]
        if stamp[j] != advances:
            continue
        dux = state[i, UB] - last_u[j, 0]
        duy = state[i, VB] - last_u[j, 1]
        if dux == 0.0 and duy == 0.0:
            continue
        lp, lq, nx, ny = lin_last[j, 0], lin_last[j, 1], lin_last[j, 2], lin_last[j, 3]
        dn = (lp - lq) * (nx * dux + ny * duy)
        c = -0.5 * dt_last[j] * (mass[j] + added_mass[j])
        jx = c * (lq * dux + dn * nx)
        jy = c * (lq * duy + dn * ny)
        received[j, 0] += jx
        received[j, 1] += jy
        sx += jx
        sy += jy
    to_contacts[0] += sx
    to_contacts[1] += sy


@nb.njit(cache=True)
def contact_changes(act, state, last_u, stamp, advances, mass, added_mass, lin_last, dt_last,
                    received, to_contacts):
    """``held_drag`` then ``account_contacts`` (``CoupledTracker._contact_changes``), one call."""
    held_drag(act, state, last_u, stamp, advances, mass, added_mass, lin_last, dt_last,
              received, to_contacts)
    account_contacts(act, state, last_u, stamp, advances, added_mass, to_contacts)


@nb.njit(cache=True)
def _finite_2d(x):
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            if not np.isfinite(x[i, j]):
                return False
    return True


@nb.njit(cache=True)
def all_finite(a, b):
    """``np.isfinite(a).all() and np.isfinite(b).all()`` for two 2-D arrays, in one pass each."""
    return _finite_2d(a) and _finite_2d(b)
