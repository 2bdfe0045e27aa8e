"""The finite-volume flux pass: per-edge Godunov fluxes, then a per-face gather.

``edge_fluxes`` runs over edges (``prange``: each edge writes only its own slots, so there is
no race; one kernel per order, ``edge_fluxes_1`` and ``edge_fluxes_2``) and stores,
multiplied by the edge length, the mass flux, the momentum flux seen by each side and the
largest wave speed.  With the hydrostatic reconstruction (Audusse, Bouchut,
Bristeau, Klein & Perthame 2004) the two sides see different momentum fluxes: each side adds
``g/2 (h_side^2 - h_side*^2)``, the bed-slope source in flux form, so that a lake at rest is
an exact discrete steady state and depths stay non-negative under the CFL condition below.
At second order the centred source ``g/2 (h_e + h) (z_e - z)`` of the face's own linear bed
is added on each side (Audusse et al. 2004, sect. 4), which keeps the scheme well balanced.
At second order the sides' states at the edge (and that source) come ready from the gradient
kernel (``reconstruction.limited_gradients``, computed once per face and edge per stage).

``face_residuals`` then sums, for each face, the fluxes of its edges (``prange`` over faces,
reading edge arrays only) into d(h, hu, hv)/dt and the face's time-step bound: at first order
``sum(len_e s_e) / area`` (dt times it <= 1 keeps h >= 0: the outflow through each edge is at
most s_e h* dt len_e), at second order ``sum(len_e s_e max(1, h_e / h)) / area`` with h_e
the face's reconstructed depth at the edge (the outflow is at most s_e h_e dt len_e): the
first order's bound where the depth is flat, as at every wet/dry front.

Indices known to be >= 0 (a face or edge of the active set, an edge's inside face, a face's
edges) are cast to ``np.uint64`` before they index: numba wraps a signed index that may be
negative (a compare, a select and the axis length at every access), and the kernels index
six arrays per edge.  The same numbers bit for bit; ``face_residuals`` takes about 0.55x the
time it took, the edge kernels 0.85-0.95x (``benchmarks/kernel_ablation.py``; BENCHMARKS.md,
"Unsigned indices").  Mixing ``uint64`` with ``int64`` makes a float in numba (an index that
then fails to compile): constants in index arithmetic are written ``np.uint64(2)``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.solver.boundaries import boundary_flux
from driftlog.solver.riemann import riemann_flux

__all__ = ["boundary_volumes", "edge_fluxes", "edge_fluxes_1", "edge_fluxes_2",
           "face_residuals", "face_sides", "gather_boundary_flux", "largest_rate"]


def face_sides(face_edges, edge_faces):
    """(n_faces, nmax) uint8: 1 where face f is side 0 of its edge ``face_edges[f, k]``."""
    e = np.maximum(face_edges, 0)
    f = np.arange(face_edges.shape[0])[:, None]
    return np.ascontiguousarray((face_edges >= 0) & (edge_faces[e, 0] == f), dtype=np.uint8)


@nb.njit(cache=True, inline="always")
def _cell_state(f, h, hu, hv, z, hdry):
    """(h, u, v, z) of face f at its centroid: the first order's state at any point."""
    hf = h[f]
    if hf > hdry:
        return hf, hu[f] / hf, hv[f] / hf, z[f]
    return hf, 0.0, 0.0, z[f]


@nb.njit(cache=True, inline="always")
def _share(h_side, h_face):
    """max(1, h_side / h_face): an edge's outflow is at most speed * h_side (1 when dry)."""
    if h_face <= 0.0 or h_side <= h_face:
        return 1.0
    return h_side / h_face


def edge_fluxes(edges, edge_faces, nx, ny, length, h, hu, hv, z, order, riemann, g, hdry, slot,
                bkind, bvalue, fmass, fx0, fy0, fx1, fy1, speed, speed1, edge_state=None):
    """Fluxes of the edges ``edges`` times their length; ``speed``: length x largest wave speed.

    At second order the two sides' states are the faces' reconstructed ones at the edge,
    rows 2 e (face ``edge_faces[e, 0]``) and 2 e + 1 of ``edge_state``
    (``reconstruction.limited_gradients``); ``speed`` and ``speed1`` then hold length x wave
    speed for each side, times max(1, h_side / h_face) (the side's share of the face's
    positivity bound).

    ``edges`` lists the edges to compute (the active set's, ``driftlog.solver.layout``); the
    others keep their values.
    ``fx0, fy0`` is the momentum flux leaving face ``edge_faces[e, 0]``, ``fx1, fy1`` the one
    entering face ``edge_faces[e, 1]`` (they differ by the bed source terms).

    Runs the kernel of the order, ``edge_fluxes_1`` or ``edge_fluxes_2`` (the solver calls
    those directly): one kernel taking the order as an argument took twice their time.
    """
    if order == 1:
        edge_fluxes_1(edges, edge_faces, nx, ny, length, h, hu, hv, z, riemann, g, hdry, slot,
                      bkind, bvalue, fmass, fx0, fy0, fx1, fy1, speed)
    else:
        edge_fluxes_2(edges, edge_faces, nx, ny, length, h, z, edge_state, riemann, g, hdry,
                      slot, bkind, bvalue, fmass, fx0, fy0, fx1, fy1, speed, speed1)


@kernel
def edge_fluxes_2(edges, edge_faces, nx, ny, length, h, z, est, riemann, g, hdry, slot, bkind,
                  bvalue, fmass, fx0, fy0, fx1, fy1, speed, speed1):
    """``edge_fluxes`` at second order: the faces' reconstructed states at the edges, ``est``.

    ``est[2 e + s]``: depth, velocity and bed of the face on side s of edge e at the edge,
    computed once per stage by ``reconstruction.limited_gradients``.
    """
    half_g = 0.5 * g
    for i in nb.prange(edges.shape[0]):
        e = np.uint64(edges[i])
        a = np.uint64(edge_faces[e, 0])
        b = edge_faces[e, 1]
        n1 = nx[e]
        n2 = ny[e]
        ln = length[e]
        ka = np.uint64(2) * e
        hA = est[ka, 0]
        uA = est[ka, 1]
        vA = est[ka, 2]
        zA = est[ka, 3]
        unA = uA * n1 + vA * n2
        utA = -uA * n2 + vA * n1
        if b < 0:
            s = slot[e]
            fh, fn, ft, sp = boundary_flux(bkind[s], bvalue[s], hA, zA, unA, utA, g, hdry,
                                           riemann)
            fnA = fn + half_g * (hA + h[a]) * (zA - z[a])
            fmass[e] = ln * fh
            fx0[e] = ln * (fnA * n1 - ft * n2)
            fy0[e] = ln * (fnA * n2 + ft * n1)
            fx1[e] = 0.0
            fy1[e] = 0.0
            speed[e] = ln * sp * _share(hA, h[a])
            continue
        kb = ka + np.uint64(1)
        b = np.uint64(b)  # b >= 0 here
        hB = est[kb, 0]
        uB = est[kb, 1]
        vB = est[kb, 2]
        zB = est[kb, 3]
        unB = uB * n1 + vB * n2
        utB = -uB * n2 + vB * n1
        zs = max(zA, zB)
        hAs = max(0.0, hA + zA - zs)
        hBs = max(0.0, hB + zB - zs)
        fh, fn, ft, sp = riemann_flux(riemann, hAs, unA, utA, hBs, unB, utB, g)
        fnA = fn + half_g * (hA * hA - hAs * hAs) + half_g * (hA + h[a]) * (zA - z[a])
        fnB = fn + half_g * (hB * hB - hBs * hBs) + half_g * (hB + h[b]) * (zB - z[b])
        fmass[e] = ln * fh
        fx0[e] = ln * (fnA * n1 - ft * n2)
        fy0[e] = ln * (fnA * n2 + ft * n1)
        fx1[e] = ln * (fnB * n1 - ft * n2)
        fy1[e] = ln * (fnB * n2 + ft * n1)
        speed[e] = ln * sp * _share(hA, h[a])
        speed1[e] = ln * sp * _share(hB, h[b])


@kernel
def edge_fluxes_1(edges, edge_faces, nx, ny, length, h, hu, hv, z, riemann, g, hdry, slot, bkind,
                  bvalue, fmass, fx0, fy0, fx1, fy1, speed):
    """``edge_fluxes`` at first order (no gradients, offsets nor ``speed1``)."""
    half_g = 0.5 * g
    for i in nb.prange(edges.shape[0]):
        e = np.uint64(edges[i])
        a = np.uint64(edge_faces[e, 0])
        b = edge_faces[e, 1]
        n1 = nx[e]
        n2 = ny[e]
        ln = length[e]
        hA, uA, vA, zA = _cell_state(a, h, hu, hv, z, hdry)
        unA = uA * n1 + vA * n2
        utA = -uA * n2 + vA * n1
        if b < 0:
            s = slot[e]
            fh, fn, ft, sp = boundary_flux(bkind[s], bvalue[s], hA, zA, unA, utA, g, hdry,
                                           riemann)
            fnA = fn + half_g * (hA + h[a]) * (zA - z[a])
            fmass[e] = ln * fh
            fx0[e] = ln * (fnA * n1 - ft * n2)
            fy0[e] = ln * (fnA * n2 + ft * n1)
            fx1[e] = 0.0
            fy1[e] = 0.0
            speed[e] = ln * sp
            continue
        b = np.uint64(b)  # b >= 0 here
        hB, uB, vB, zB = _cell_state(b, h, hu, hv, z, hdry)
        unB = uB * n1 + vB * n2
        utB = -uB * n2 + vB * n1
        zs = max(zA, zB)
        hAs = max(0.0, hA + zA - zs)
        hBs = max(0.0, hB + zB - zs)
        fh, fn, ft, sp = riemann_flux(riemann, hAs, unA, utA, hBs, unB, utB, g)
        fnA = fn + half_g * (hA * hA - hAs * hAs)
        fnB = fn + half_g * (hB * hB - hBs * hBs)
        fmass[e] = ln * fh
        fx0[e] = ln * (fnA * n1 - ft * n2)
        fy0[e] = ln * (fnA * n2 + ft * n1)
        fx1[e] = ln * (fnB * n1 - ft * n2)
        fy1[e] = ln * (fnB * n2 + ft * n1)
        speed[e] = ln * sp


@kernel
def face_residuals(faces, face_edges, face_n, face_side, area, fmass, fx0, fy0, fx1, fy1,
                   speed, speed1, order, dh, dhu, dhv, rate):
    """d/dt of h, hu, hv on the faces ``faces``, and their time-step bound ``rate``.

    dt * rate <= 1; ``faces``: the active set's faces (``driftlog.solver.layout``);
    ``face_side[f, k]`` is 1 when face f is side 0 of its k-th edge (the normal points out of
    it), 0 when it is side 1 (``face_sides``: a per-face table, not a lookup in the edges').
    """
    for i in nb.prange(faces.shape[0]):
        f = np.uint64(faces[i])
        rh = 0.0
        rx = 0.0
        ry = 0.0
        rs = 0.0
        for k in range(face_n[f]):
            # without branches (a face is side 0 or 1 of its edges at random: a branch on it
            # was mispredicted half the time); a - b is a + (-1 * b) exactly (IEEE 754)
            e = np.uint64(face_edges[f, k])  # every edge of a face exists (k < face_n)
            out = face_side[f, k] != 0
            sign = -1.0 if out else 1.0
            x0 = fx0[e]
            x1 = fx1[e]
            y0 = fy0[e]
            y1 = fy1[e]
            rh += sign * fmass[e]
            rx += sign * (x0 if out else x1)
            ry += sign * (y0 if out else y1)
            if order == 1:
                rs += speed[e]
            else:
                s0 = speed[e]
                s1 = speed1[e]
                rs += s0 if out else s1
        inv = 1.0 / area[f]
        dh[f] = rh * inv
        dhu[f] = rx * inv
        dhv[f] = ry * inv
        rate[f] = rs * inv


@nb.njit(cache=True, _nrt=False)
def largest_rate(rate, faces):
    """The largest ``rate`` of ``faces`` (the active set: every other face's rate is 0).

    ``rate.max()`` over the whole mesh gives the same number (a NaN too: it is kept, so the
    step fails as before), without a pass over every face at every stage (33 us a stage on
    Malpasset's 46,691 faces, where the active set is a few thousand for most of the flood).
    """
    m = 0.0
    for i in range(faces.shape[0]):
        r = rate[np.uint64(faces[i])]
        if r > m or r != r:
            m = r
        if m != m:
            break
    return m


@nb.njit(cache=True, _nrt=False)
def gather_boundary_flux(fmass, edges, share, out, add):
    """out[i] (+)= share * fmass[edges[i]]: a stage's share of the boundary edges' mass fluxes.

    ``add``: added to ``out``, else written (``share`` 1: the fluxes themselves, bit for bit).
    """
    for i in range(edges.shape[0]):
        v = share * fmass[np.uint64(edges[i])]
        out[i] = out[i] + v if add else v


@nb.njit(cache=True, _nrt=False)
def boundary_volumes(flux, dt, tag, out_volume, in_volume, work):
    """Volumes through the boundary edges in a step, summed per boundary tag, added to the totals.

    ``flux * dt`` per edge (m3, > 0 out), its outflows and inflows summed per tag in the
    edges' order from 0 and then added to ``out_volume`` and ``in_volume``: the numbers of
    ``np.bincount(tag, weights=np.maximum(+-flux * dt, 0))`` added, bit for bit, without six
    temporary arrays a step.  ``work``: >= 2 x the number of tags.
    """
    n = out_volume.shape[0]
    for t in range(2 * n):
        work[t] = 0.0
    for i in range(flux.shape[0]):
        v = flux[i] * dt
        t = np.uint64(tag[i])
        a = -v
        # np.maximum(v, 0): v where v >= 0 or v is NaN, else 0
        work[t] += v if (v >= 0.0 or v != v) else 0.0
        work[np.uint64(n) + t] += a if (a >= 0.0 or a != a) else 0.0
    for t in range(n):
        out_volume[t] += work[t]
        in_volume[t] += work[n + t]
