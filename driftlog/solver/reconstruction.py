"""Second-order (MUSCL) reconstruction: limited least-squares gradients on faces.

The free-surface level eta, the depth h and the unit discharges hu, hv get a least-squares gradient
from the centroids of the face's neighbours, limited by Barth & Jespersen (1989) so that the
values at the edge midpoints stay within the range of the face and its neighbours: a
reconstructed depth is never negative, and a constant level (a lake at rest) stays constant.
The velocity at an edge is the reconstructed discharge over the reconstructed depth: limiting
the velocities themselves left standing oscillations behind a stationary hydraulic jump
(SWASHES' transcritical flow with shock: L1 error 1.1e-3 m against 3.3e-4 m at 400 cells).
Where that velocity would go further than one range beyond the range of the face's and its
neighbours' velocities (thin water: a small reconstructed depth), the face's depth and
discharges fall back to first order.
The bed at an edge is eta - h there, which keeps the scheme well balanced with the hydrostatic
reconstruction (Audusse et al. 2004, sect. 4).  Where the bed is given at the nodes
(``edge_bed``), it is continuous: the edge's bed is the mean of its two nodes (``zedge``), the
same from both sides, and the depth there is the limited level minus it (Kurganov & Petrova
2007; docs/model.md eq. (84)); two sides' implied beds that differ made the hydrostatic
reconstruction see a weir at the edge (Malpasset's gorge below the dam filled up, P1 +8.6 m).

Faces that are dry or touch a dry face keep zero gradients (first order at wet/dry fronts,
where a slope would only make spurious overshoots), and every face's gradients are blended
towards first order by the depth ratio to its neighbours (ANUGA DE1's rule, docs/model.md eq.
(80)): a face beside a much shallower or much deeper neighbour (a nearly dry bank, a thin film
beside a deep channel) reconstructs nothing, which stops the flood piling up on Malpasset's
steep valley sides.

The kernel does not store the gradients: it stores what the edge-flux kernel needs of each
face at each of its edges (depth, velocity and bed, ``EDGE_STATE``), once per stage, in the
rows of the two sides of each edge side by side.  The edge kernel then reads two rows per edge
and makes no velocity division (before, it recomputed each side's state from the gradients,
the velocity divisions that the check here had already made, at every edge of every face: the
same numbers, twice the work).

Indices known to be >= 0 are unsigned (``np.uint64``: no negative-index wraparound, see
``driftlog.solver.fluxes``), and the kernel is compiled without reference counting
(``kernel(nrt=False)``: the inlined helpers that take arrays otherwise count references at
every call); together 0.92-0.94x the kernel's time, bit for bit
(``benchmarks/kernel_ablation.py``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.solver.boundaries import DEPTH, LEVEL

__all__ = ["lsq_geometry", "limited_gradients", "first_order_states", "EDGE_STATE", "NSTATE",
           "ENERGY_BOUNDS"]

# what ``limited_gradients`` stores for each side of each edge (``est[2 e + s, :]``, s = 0 for
# the face the edge's normal points out of, 1 for the other)
EDGE_STATE = ("h", "u", "v", "z")
NSTATE = len(EDGE_STATE)
# the energy bound at edges on a bed given at the nodes (docs/model.md eq. (85)), by name: the
# kernel's ``ebound``
ENERGY_BOUNDS = {"off": 0, "g2": 1, "velocity": 4, "rising": 5, "hr": 7}
# depth-ratio blending (eq. (80)), ANUGA DE1's thresholds: the gradients are scaled by
# (r - DEPTH_RATIO_FIRST) / (DEPTH_RATIO_FULL - DEPTH_RATIO_FIRST) clipped to [0, 1], r the
# smaller of h_min / h_i and h_i / h_max over the face and its neighbours
DEPTH_RATIO_FIRST = 0.1
DEPTH_RATIO_FULL = 0.3
DEPTH_RATIO_SLOPE = 1.0 / (DEPTH_RATIO_FULL - DEPTH_RATIO_FIRST)


def lsq_geometry(mesh):
    """Centroid offsets to the neighbours (n_faces, nmax, 2) and the inverse normal matrices.

    Returns ``(offset, minv, edge_offset)``: ``minv`` (n_faces, 3) holds (a, b, c) of the
    symmetric pseudo-inverse of sum d d^T (the gradient along the line of the neighbours
    where they do not span the plane); ``edge_offset`` (n_faces, nmax, 2) goes from the centroid to
    each edge midpoint.
    """
    nb_ = mesh.face_neighbours
    ok = nb_ >= 0
    j = np.where(ok, nb_, 0)
    dx = np.where(ok, mesh.face_x[j] - mesh.face_x[:, None], 0.0)
    dy = np.where(ok, mesh.face_y[j] - mesh.face_y[:, None], 0.0)
    m = np.empty((mesh.n_faces, 2, 2))
    m[:, 0, 0] = (dx * dx).sum(1)
    m[:, 0, 1] = m[:, 1, 0] = (dx * dy).sum(1)
    m[:, 1, 1] = (dy * dy).sum(1)
    # pseudo-inverse: neighbours on one line (a strip one cell wide) still give the gradient
    # along that line
    p = np.linalg.pinv(m, rcond=1e-10, hermitian=True)
    minv = np.column_stack([p[:, 0, 0], p[:, 0, 1], p[:, 1, 1]])
    fe = mesh.face_edges
    e = np.where(fe >= 0, fe, 0)
    ex = np.where(fe >= 0, mesh.edge_x[e] - mesh.face_x[:, None], 0.0)
    ey = np.where(fe >= 0, mesh.edge_y[e] - mesh.face_y[:, None], 0.0)
    return (np.ascontiguousarray(np.stack([dx, dy], -1)), np.ascontiguousarray(minv),
            np.ascontiguousarray(np.stack([ex, ey], -1)))


@nb.njit(cache=True, inline="always")
def _bj(phi, g_x, g_y, ex, ey, qc, qmin, qmax, ext):
    """Barth-Jespersen factor so far ``phi``, tightened by one edge (offset ex, ey)."""
    dq = g_x * ex + g_y * ey
    # the bound has the sign of dq (qmax + ext >= qc >= qmin - ext), so the ratio is >= 0, and
    # >= 1 >= phi unless |bound| < |dq|: only then can the edge tighten phi, and only then is
    # the division made (the same phi; dq = 0 never tightens)
    flat = dq == 0.0
    bound = (qmax + ext - qc) if dq > 0.0 else (qmin - ext - qc)
    r = bound / (1.0 if flat else dq)
    return phi if flat else min(phi, r)


@nb.njit(cache=True, inline="always")
def _bj2(dmax, dmin, qc, qmin, qmax):
    """Barth-Jespersen factor of a face with no open-boundary edge, from its extreme dq.

    Every edge's bound is then qmax - qc where dq > 0 and qmin - qc where dq < 0, so the
    smallest ratio of each sign is the one of the largest |dq| (a correctly rounded division
    is monotone): ``_bj`` over the edges gives the same factor with two divisions, not one
    per edge.  ``dmax`` >= 0 and ``dmin`` <= 0 are the largest and smallest dq (0: none).
    """
    rp = (qmax + 0.0 - qc) / (dmax if dmax > 0.0 else 1.0)
    rm = (qmin - 0.0 - qc) / (dmin if dmin < 0.0 else 1.0)
    p = min(1.0, rp) if dmax > 0.0 else 1.0
    return min(p, rm) if dmin < 0.0 else p


@nb.njit(cache=True, inline="always")
def _slot(est, r, he, ue, ve, ze):
    """Store a face's state at one of its edges in row ``r`` of ``est`` (``EDGE_STATE``)."""
    est[r, 0] = he
    est[r, 1] = ue
    est[r, 2] = ve
    est[r, 3] = ze


@nb.njit(cache=True, inline="always")
def first_order_states(est, rows, f, n, hi, zi, c2, c3, g0, g1, edge_offset, hdry):
    """Edge states of face f with zero depth and discharge gradients, level gradient (g0, g1).

    The values of the general formulas with those gradients (h_e = h + 0 dx + 0 dy = h,
    u_e = (hu + 0 dx + 0 dy) / h_e) without their divisions: hu / h once per face (the
    numerator differs from hu only by the sign of a zero, and then so does the quotient).
    """
    c0 = hi + zi
    u0 = v0 = 0.0
    wet = hi > hdry
    if wet:
        u0 = c2 / hi
        v0 = c3 / hi
    for k in range(n):
        ex = edge_offset[f, k, 0]
        ey = edge_offset[f, k, 1]
        he = hi + 0.0 * ex + 0.0 * ey
        eta = c0 + g0 * ex + g1 * ey
        ue = ve = 0.0
        if wet:
            ue = u0 if c2 != 0.0 else c2 + 0.0 * ex + 0.0 * ey
            ve = v0 if c3 != 0.0 else c3 + 0.0 * ex + 0.0 * ey
        _slot(est, np.uint64(rows[f, k]), he, ue, ve, eta - he)


@kernel(nrt=False)
def limited_gradients(faces, h, hu, hv, z, hdry, face_n, neighbours, offset, minv, edge_offset,
                      rows, est, open_edge, face_edges, slot, bkind, bvalue, zedge, edge_bed,
                      ebound, ewiden, gravity, mark):
    """The reconstructed states of ``faces`` at their edges, from limited gradients.

    Fills row ``rows[f, k]`` of ``est`` (2 n_edges, ``NSTATE``) for face f's k-th edge e
    (row 2 e for the face the edge's normal points out of, 2 e + 1 for the other: the edge
    kernel reads its two sides side by side) with the ``EDGE_STATE`` fields: depth h_e,
    velocity (u_e, v_e) = (hu_e, hv_e) / h_e (0 where h_e <= ``hdry``) and bed
    z_e = eta_e - h_e, so that the edge-flux kernel reads them and computes nothing twice.
    ``faces``: the active set's faces (``driftlog.solver.layout``); other rows keep theirs.
    ``open_edge[f]``: face f has an open-boundary edge (a -1 in ``neighbours``), where the
    limiter's bound is widened edge by edge, except at level and depth boundaries, whose
    ghost state (the imposed level or depth: ``face_edges``, ``slot``, ``bkind`` and
    ``bvalue`` as in ``boundaries.BoundarySet``) joins the range instead.
    ``zedge`` (n_edges,): the bed at each edge midpoint, used where ``edge_bed`` is true (a bed
    given at the nodes: h_e = eta_e - zedge, eq. (84)); otherwise the bed eta_e - h_e implied
    by the limited level and depth.
    ``ebound`` (``ENERGY_BOUNDS``; applied only where ``edge_bed``): 0 none; otherwise an edge
    whose speed |u_e| exceeds the largest speed of the face and its neighbours, or whose head
    eta_e + |u_e|^2 / (2 g) exceeds their largest total head h + z + |u|^2 / (2 g)
    (docs/model.md eq. (85)), makes the face fall back: 1 (``g2``) to first-order depth and
    discharges (the level's gradient kept); 4 (``velocity``) that edge first takes the face's
    limited velocity reconstruction (u_e = u_i + grad u . (x_e - x_i), Barth-Jespersen within
    the neighbourhood's velocities; q_e = h_e u_e), the face falling back as in 1 if the edge
    still breaks the bound; 5 (``rising``) as 1, the bound checked only at edges where the
    node bed makes the depth smaller than the limited depth h_l = h_i + grad h . (x_e - x_i);
    7 (``hr``) no bound, but where h_e < h_l the edge velocity is q_e / h_l (the hydrostatic
    reconstruction's: velocity kept, depth cut by the bed).
    ``ewiden`` >= 0: both bounds of (85) widened by that fraction of the neighbourhood's
    speed range (max_j |u_j| - min_j |u_j|) and head range (0: none).
    ``mark[f]`` (int8) records what face f got: 0 second order, 1 first order (dry, at a
    front, depth ratio), 2 the velocity check's fall-back, 3 the energy bound's full
    fall-back, 4 an edge changed without a full fall-back (``velocity``, ``hr``).
    One pass over the neighbours gathers the four least-squares sums, their ranges and the
    velocities' range; one pass over the edges limits the four gradients; one more computes
    the edge states (and checks the edge velocities).
    """
    eb = ebound if edge_bed else 0
    inv2g = 0.5 / gravity
    for i in nb.prange(faces.shape[0]):
        f = np.uint64(faces[i])  # unsigned indices: no negative-index wraparound
        hi = h[f]
        zi = z[f]
        c2 = hu[f]
        c3 = hv[f]
        n = np.uint64(face_n[f])
        mark[f] = 1
        if hi <= hdry or (minv[f, 0] == 0.0 and minv[f, 2] == 0.0):
            first_order_states(est, rows, f, n, hi, zi, c2, c3, 0.0, 0.0, edge_offset, hdry)
            continue
        front = False
        for k in range(n):
            j = neighbours[f, k]
            if j >= 0 and h[np.uint64(j)] <= hdry:
                front = True
        if front:
            mark[f] = 1
            first_order_states(est, rows, f, n, hi, zi, c2, c3, 0.0, 0.0, edge_offset, hdry)
            continue
        c0 = hi + zi
        rx0 = ry0 = rx1 = ry1 = rx2 = ry2 = rx3 = ry3 = 0.0
        mn0 = mx0 = c0
        mn1 = mx1 = hi
        mn2 = mx2 = c2
        mn3 = mx3 = c3
        umin = umax = c2 / hi
        vmin = vmax = c3 / hi
        # the energy bound's references (eq. (85)): largest speed squared and total head over
        # the face and its neighbours
        s2max = umin * umin + vmin * vmin
        hmax = c0 + s2max * inv2g
        s2min = s2max
        hmin = hmax
        rx4 = ry4 = rx5 = ry5 = 0.0  # velocity least-squares sums (ebound 4)
        ui0 = umin
        vi0 = vmin
        for k in range(n):
            j = neighbours[f, k]
            if j < 0:
                continue
            ju = np.uint64(j)
            hj = h[ju]
            q0 = hj + z[ju]
            q2 = hu[ju]
            q3 = hv[ju]
            ox = offset[f, k, 0]
            oy = offset[f, k, 1]
            d = q0 - c0
            rx0 += ox * d
            ry0 += oy * d
            d = hj - hi
            rx1 += ox * d
            ry1 += oy * d
            d = q2 - c2
            rx2 += ox * d
            ry2 += oy * d
            d = q3 - c3
            rx3 += ox * d
            ry3 += oy * d
            mn0 = min(mn0, q0)
            mx0 = max(mx0, q0)
            mn1 = min(mn1, hj)
            mx1 = max(mx1, hj)
            mn2 = min(mn2, q2)
            mx2 = max(mx2, q2)
            mn3 = min(mn3, q3)
            mx3 = max(mx3, q3)
            uj = q2 / hj
            vj = q3 / hj
            umin = min(umin, uj)
            umax = max(umax, uj)
            vmin = min(vmin, vj)
            vmax = max(vmax, vj)
            if eb:
                s2 = uj * uj + vj * vj
                s2max = max(s2max, s2)
                hmax = max(hmax, q0 + s2 * inv2g)
                s2min = min(s2min, s2)
                hmin = min(hmin, q0 + s2 * inv2g)
                if eb == 4:
                    d = uj - ui0
                    rx4 += ox * d
                    ry4 += oy * d
                    d = vj - vi0
                    rx5 += ox * d
                    ry5 += oy * d
        a = minv[f, 0]
        b = minv[f, 1]
        c = minv[f, 2]
        gx0 = a * rx0 + b * ry0
        gy0 = b * rx0 + c * ry0
        gx1 = a * rx1 + b * ry1
        gy1 = b * rx1 + c * ry1
        gx2 = a * rx2 + b * ry2
        gy2 = b * rx2 + c * ry2
        gx3 = a * rx3 + b * ry3
        gy3 = b * rx3 + c * ry3
        # Barth-Jespersen: edge values within [qmin, qmax]; an open boundary edge (neighbour
        # -1) has no state beyond it, so its value may go one range further (a one-sided
        # gradient extrapolates there; clipping it made boundary faces first order, which cost
        # MacDonald's channel its second order); a wall (-2) is not widened: its mirror state
        # holds the level and the speed, and widening there let Ritter's dry front on
        # triangles grow noisy under refinement
        if open_edge[f]:
            # a level or depth boundary has an outside state, the ghost: its level and depth
            # join the range (Barth & Jespersen's bound with a ghost cell) and its edge is not
            # widened; widening there let the coast faces of Malpasset extrapolate the arriving
            # flood's level and speed one range beyond at every stage, a feedback that blew up
            # (20 m/s at 1800 s, 3e4 m/s seven seconds later; docs/model.md sect. 3.4)
            for k in range(n):
                if neighbours[f, k] == -1:
                    sl = slot[face_edges[f, k]]
                    kd = bkind[sl]
                    if kd == LEVEL or kd == DEPTH:
                        hg = max(bvalue[sl] - zi, 0.0) if kd == LEVEL else bvalue[sl]
                        mn0 = min(mn0, zi + hg)
                        mx0 = max(mx0, zi + hg)
                        mn1 = min(mn1, hg)
                        mx1 = max(mx1, hg)
            p0 = p1 = p2 = p3 = 1.0
            for k in range(n):
                ex = edge_offset[f, k, 0]
                ey = edge_offset[f, k, 1]
                bnd = False
                if neighbours[f, k] == -1:
                    kd = bkind[slot[face_edges[f, k]]]
                    bnd = kd != LEVEL and kd != DEPTH
                p0 = _bj(p0, gx0, gy0, ex, ey, c0, mn0, mx0, mx0 - mn0 if bnd else 0.0)
                p1 = _bj(p1, gx1, gy1, ex, ey, hi, mn1, mx1, mx1 - mn1 if bnd else 0.0)
                p2 = _bj(p2, gx2, gy2, ex, ey, c2, mn2, mx2, mx2 - mn2 if bnd else 0.0)
                p3 = _bj(p3, gx3, gy3, ex, ey, c3, mn3, mx3, mx3 - mn3 if bnd else 0.0)
        else:  # the edges' extreme increments, then two divisions per quantity (_bj2)
            a0 = a1 = a2 = a3 = b0 = b1 = b2 = b3 = 0.0
            for k in range(n):
                ex = edge_offset[f, k, 0]
                ey = edge_offset[f, k, 1]
                d = gx0 * ex + gy0 * ey
                a0 = max(a0, d)
                b0 = min(b0, d)
                d = gx1 * ex + gy1 * ey
                a1 = max(a1, d)
                b1 = min(b1, d)
                d = gx2 * ex + gy2 * ey
                a2 = max(a2, d)
                b2 = min(b2, d)
                d = gx3 * ex + gy3 * ey
                a3 = max(a3, d)
                b3 = min(b3, d)
            p0 = _bj2(a0, b0, c0, mn0, mx0)
            p1 = _bj2(a1, b1, hi, mn1, mx1)
            p2 = _bj2(a2, b2, c2, mn2, mx2)
            p3 = _bj2(a3, b3, c3, mn3, mx3)
        # depth-ratio blending towards first order (docs/model.md eq. (80)): a neighbour far
        # shallower or far deeper than the face marks a wet/dry front or a steep bank
        # (both ratios above 0.31 make both terms > 1 whatever the round-off: beta = 1 without
        # the divisions, the usual case)
        beta = 1.0
        if mn1 < 0.31 * hi or hi < 0.31 * mx1:
            beta = min(DEPTH_RATIO_SLOPE * (mn1 / hi - DEPTH_RATIO_FIRST),
                       DEPTH_RATIO_SLOPE * (hi / mx1 - DEPTH_RATIO_FIRST), 1.0)
        if beta <= 0.0:
            mark[f] = 1
            first_order_states(est, rows, f, n, hi, zi, c2, c3, 0.0, 0.0, edge_offset, hdry)
            continue
        p0 = max(p0, 0.0) * beta
        p1 = max(p1, 0.0) * beta
        p2 = max(p2, 0.0) * beta
        p3 = max(p3, 0.0) * beta
        g0 = p0 * gx0
        g1 = p0 * gy0
        gx1 *= p1
        gy1 *= p1
        gx2 *= p2
        gy2 *= p2
        gx3 *= p3
        gy3 *= p3
        # ebound 4: the velocity's own limited gradient (Barth-Jespersen on u, v within the
        # neighbourhood's range, not widened), for the faces the energy bound catches
        gx4 = gy4 = gx5 = gy5 = 0.0
        if eb == 4:
            gx4 = a * rx4 + b * ry4
            gy4 = b * rx4 + c * ry4
            gx5 = a * rx5 + b * ry5
            gy5 = b * rx5 + c * ry5
            p4 = p5 = 1.0
            for k in range(n):
                ex = edge_offset[f, k, 0]
                ey = edge_offset[f, k, 1]
                p4 = _bj(p4, gx4, gy4, ex, ey, ui0, umin, umax, 0.0)
                p5 = _bj(p5, gx5, gy5, ex, ey, vi0, vmin, vmax, 0.0)
            p4 = max(p4, 0.0) * beta
            p5 = max(p5, 0.0) * beta
            gx4 *= p4
            gy4 *= p4
            gx5 *= p5
            gy5 *= p5
        # the edge velocity hu_e / h_e must stay within the neighbourhood's velocities: in thin
        # water a small h_e would make it arbitrarily large (and the time step tiny); smooth
        # extrema overshoot by O(dx^2): allow one neighbourhood range beyond the range
        tol = 1e-12 * (abs(umin) + abs(umax) + abs(vmin) + abs(vmax)) + 1e-300
        du = umax - umin + tol
        dv = vmax - vmin + tol
        umin -= du
        umax += du
        vmin -= dv
        vmax += dv
        if eb and ewiden > 0.0:  # (85) widened by a fraction of the ranges
            smax = np.sqrt(s2max)
            smax += ewiden * (smax - np.sqrt(s2min))
            s2max = smax * smax
            hmax += ewiden * (hmax - hmin)
        mark[f] = 0
        ui = c2 / hi
        vi = c3 / hi
        ok = True
        hit = False  # the energy bound broken (not the velocity check)
        for k in range(n):
            ex = edge_offset[f, k, 0]
            ey = edge_offset[f, k, 1]
            etae = c0 + g0 * ex + g1 * ey
            hl = hi + gx1 * ex + gy1 * ey  # the limited depth
            if edge_bed:
                # the continuous bed's own value at the edge (Kurganov & Petrova 2007), the
                # same from both sides; depth = limited level minus it
                ze = zedge[np.uint64(face_edges[f, k])]
                if beta < 1.0:
                    ze = zi + beta * (ze - zi)
                he = etae - ze
            else:
                he = hl
                ze = etae - he
            if he <= hdry:
                ok = False
                break
            qe = c2 + gx2 * ex + gy2 * ey
            re = c3 + gx3 * ex + gy3 * ey
            ue = qe / he
            ve = re / he
            if eb == 7 and he < hl:
                # where the node bed makes the edge shallower than the limited depth, the
                # velocity of the limited depth and discharge (the hydrostatic reconstruction
                # keeps the velocity and cuts the depth; Audusse et al. 2004)
                ue = qe / hl
                ve = re / hl
                mark[f] = 4
            if ue < umin or ue > umax or ve < vmin or ve > vmax:
                ok = False
                break
            # (85); ebound 5 checks only where the node bed makes the edge shallower than the
            # limited depth (the bed rises there above the one the limited depth implies)
            if eb and eb != 7 and (eb != 5 or he < hl):
                s2 = ue * ue + ve * ve
                if s2 > s2max or etae + s2 * inv2g > hmax:
                    hit = True
                    if eb == 4:  # this edge only: the limited velocity reconstruction
                        ue = ui + gx4 * ex + gy4 * ey
                        ve = vi + gx5 * ex + gy5 * ey
                        s2 = ue * ue + ve * ve
                        hit = s2 > s2max or etae + s2 * inv2g > hmax
                        mark[f] = 4
                    if hit:
                        ok = False
                        break
            _slot(est, np.uint64(rows[f, k]), he, ue, ve, ze)
        if not ok:
            # depth and discharges at first order here, the level's gradient kept
            mark[f] = 3 if hit else 2
            first_order_states(est, rows, f, n, hi, zi, c2, c3, g0, g1, edge_offset, hdry)
