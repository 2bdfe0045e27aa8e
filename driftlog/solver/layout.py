"""Memory layout of the solver: faces and edges renumbered for locality, and the active set.

Renumbering
    On a large mesh the flux pass is memory-bound: each edge reads the state of its two faces
    and each face gathers the fluxes of its edges, and a mesher's numbering (Triangle adds the
    faces of each refinement at the end) sends those reads all over memory.  The solver
    renumbers the faces by reverse Cuthill-McKee on the face adjacency graph (George & Liu
    1981; ``scipy.sparse.csgraph.reverse_cuthill_mckee``), which keeps neighbours within a
    narrow band of indices, and sorts the edges by their faces (smaller face, then larger),
    so that the edge loop walks the faces in order.  Every face keeps the order of its own
    edges and every edge its orientation, so that each face sums the same fluxes in the same
    order: the results are bit for bit those of the mesh's own numbering.  A Hilbert curve on
    the centroids (``hilbert_order``, the default) and RCM do as well on the throughput
    benchmark's wet squares (``benchmarks/solver_throughput.py --ordering``); on a partly dry
    mesh the Hilbert curve keeps the active set's blocks compact (below), where RCM's levels
    cross the whole mesh (Malpasset's flooded 14 % of faces lie in 18 % of its 64-face blocks
    by the Hilbert curve, 40 % by RCM).  The user never sees the internal numbering: the
    solver's public state, its flow files, boundaries and extremes are in the mesh's
    numbering.

Active set
    A face with no water (h = 0 exactly) whose neighbours have none either gets no flux
    through any edge (both sides of every edge are empty: zero flux, zero wave speed), so its
    state cannot change in a stage.  ``active_set`` marks the wet faces, their neighbours and
    the faces of open boundaries that can bring water in (level, depth and discharge), and
    lists the marked faces and the edges touching them; the gradient, flux and residual
    kernels loop over those lists only.  Faces that leave the set get their residuals and time
    step bounds zeroed and, at second order, the edge states of a dry face (what the full pass
    would compute there: an active face's edge reads them).  The Euler stage, Heun's two
    stages and the extremes run on the faces of the blocks (below) that held an active face at
    the stage's passes (``face_runs``: runs of consecutive faces): outside them every face is
    empty with zero residuals and discharges, which a stage leaves as they are.  Heun's
    predicted state must hold there what the predictor would write, zeros: the corrector
    zeroes it where it empties a face.  Results are bit for bit those of the full pass; a
    dam-break valley that is mostly dry costs little.

    Finding the set scans only blocks of ``BLOCK`` consecutive faces next to the blocks that
    held active faces at the last two passes (``mark_blocks``): a stage moves water no
    further than a face's neighbours, and the corrector writes the faces of both of Heun's
    passes.  The edges, sorted by their smaller face, are found block by block.  The scan of
    the whole mesh (``active_set``) runs after the state is set from outside and while half
    the blocks or more are active.  On Malpasset's first 200 s this took the active set from
    a quarter of a first-order step to under a tenth.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from driftlog._numba import kernel
from driftlog.solver.reconstruction import first_order_states

__all__ = ["ORDERINGS", "face_order", "rcm_order", "hilbert_order", "edge_order", "BLOCK",
           "block_tables", "mark_blocks", "active_blocks", "face_runs", "all_runs", "RUN",
           "active_set", "mark_active"]

ORDERINGS = ("rcm", "hilbert", "none")


def rcm_order(edge_faces, n_faces):
    """Reverse Cuthill-McKee order of the faces (array: new position -> old face)."""
    ef = np.asarray(edge_faces)
    inner = ef[:, 1] >= 0
    a, b = ef[inner, 0], ef[inner, 1]
    adj = sp.csr_matrix((np.ones(2 * a.size, dtype=np.int8),
                         (np.concatenate([a, b]), np.concatenate([b, a]))),
                        shape=(n_faces, n_faces))
    return np.asarray(reverse_cuthill_mckee(adj, symmetric_mode=True), dtype=np.int64)


def hilbert_order(x, y, bits=16):
    """Faces sorted along a Hilbert curve through their centroids ``x, y``."""
    def grid(v):
        span = float(np.ptp(v)) or 1.0
        return ((v - v.min()) / span * (2 ** bits - 1)).astype(np.int64)

    gx, gy = grid(np.asarray(x, dtype=float)), grid(np.asarray(y, dtype=float))
    key = np.zeros_like(gx)
    s = 2 ** (bits - 1)
    while s > 0:
        rx = (gx & s) > 0
        ry = (gy & s) > 0
        key += s * s * ((3 * rx.astype(np.int64)) ^ ry.astype(np.int64))
        flip = ~ry
        mirror = flip & rx
        gx = np.where(mirror, s - 1 - gx, gx)
        gy = np.where(mirror, s - 1 - gy, gy)
        gx, gy = np.where(flip, gy, gx), np.where(flip, gx, gy)
        s //= 2
    return np.argsort(key, kind="stable")


def face_order(mesh, ordering="rcm"):
    """New position -> old face for ``ordering`` ('rcm', 'hilbert' or 'none')."""
    if ordering == "rcm":
        return rcm_order(mesh.edge_faces, mesh.n_faces)
    if ordering == "hilbert":
        return hilbert_order(mesh.face_x, mesh.face_y)
    return np.arange(mesh.n_faces, dtype=np.int64)


def edge_order(edge_faces_new):
    """Edges sorted by their faces (new numbering): smaller face first, then the larger one.

    ``edge_faces_new`` holds the edges' faces already in the new face numbering (-1 beyond a
    boundary); returns new position -> old edge.
    """
    a, b = edge_faces_new[:, 0], edge_faces_new[:, 1]
    lo = np.where(b >= 0, np.minimum(a, b), a)
    hi = np.where(b >= 0, np.maximum(a, b), -1)
    return np.lexsort((hi, lo)).astype(np.int64)


@nb.njit(cache=True)
def _leave(f, h, face_n, dh, dhu, dhv, rate, z, hdry, edge_offset, rows, est):
    """Face f left the active set: what the full pass computes for a face with no water about.

    The residuals are zeroed and, at second order, the edge states are a dry face's (first
    order: ``rows`` has no rows).  The marking rule itself is written out in ``mark_active``
    and ``mark_blocks``, and this rare branch is a plain call: the whole rule as one inlined
    helper (its 15 arrays) made the block pass 6x slower on Malpasset (1.07 against 0.17 ms
    a step, and Malpasset's whole first-order flood 93 against 50 CPU s).
    """
    dh[f] = 0.0
    dhu[f] = 0.0
    dhv[f] = 0.0
    rate[f] = 0.0
    if f < rows.shape[0]:
        first_order_states(est, rows, f, face_n[f], h[f], z[f], 0.0, 0.0, 0.0, 0.0,
                           edge_offset, hdry)


@kernel
def mark_active(h, always, face_n, neighbours, state, dh, dhu, dhv, rate, z, hdry, edge_offset,
                rows, est):
    """Mark the faces a stage can change; zero the residuals of the faces that leave.

    ``state[f]``: bit 0 set when face f is active now, bit 1 when it was before this call.  A
    face is active when it or a neighbour holds water (h > 0) or ``always[f]``.  Returns the
    number of active faces.  At second order a face that leaves gets the edge states of a dry
    face (``est``, ``reconstruction.limited_gradients``; first order: ``rows`` has no rows).
    """
    n = 0
    for f in nb.prange(h.shape[0]):
        was = state[f] & 1
        on = h[f] > 0.0 or always[f]
        if not on:
            for k in range(face_n[f]):
                j = neighbours[f, k]
                if j >= 0 and h[j] > 0.0:
                    on = True
                    break
        if on:
            state[f] = 1
            n += 1
        else:
            state[f] = 0
            if was:
                _leave(f, h, face_n, dh, dhu, dhv, rate, z, hdry, edge_offset, rows, est)
    return n


@nb.njit(cache=True)
def _compact(state, edge_faces, faces, edges):
    nf = 0
    for f in range(state.shape[0]):
        if state[f]:
            faces[nf] = f
            nf += 1
    ne = 0
    for e in range(edge_faces.shape[0]):
        a = edge_faces[e, 0]
        b = edge_faces[e, 1]
        if state[a] or (b >= 0 and state[b]):
            edges[ne] = e
            ne += 1
    return nf, ne


def active_set(mark, h, always, face_n, neighbours, edge_faces, state, all_faces, all_edges, faces,
               edges, dh, dhu, dhv, rate, z, hdry, edge_offset, rows, est):
    """The active faces and edges of state ``h``: (faces, edges), views of index arrays.

    ``mark``: ``mark_active.serial`` or ``.parallel``.  ``all_faces``/``all_edges``
    (aranges) are returned when every face is active; otherwise
    the lists are written into ``faces``/``edges`` (work arrays of full length), in
    increasing order.
    """
    n = mark(h, always, face_n, neighbours, state, dh, dhu, dhv, rate, z, hdry, edge_offset,
             rows, est)
    if n == h.shape[0]:
        return all_faces, all_edges
    nf, ne = _compact(state, edge_faces, faces, edges)
    return faces[:nf], edges[:ne]


BLOCK = 64  # faces per block of the active set's block pass (``mark_blocks``)


def block_tables(edge_faces, neighbours, n_faces, size=BLOCK):
    """Blocks of ``size`` consecutive faces for ``mark_blocks``, or None.

    Returns (adjacency start, adjacency, edge start): block b's neighbouring blocks (itself
    included, those holding a face next to one of b's) are ``adjacency[start[b]:start[b+1]]``;
    its edges (those whose smaller face is in b) ``edge start[b]`` to ``edge start[b+1]``.
    None when the edges are not sorted by their smaller face (the mesher's numbering).
    """
    a, b = edge_faces[:, 0], edge_faces[:, 1]
    lo = np.where(b >= 0, np.minimum(a, b), a)
    if lo.size and np.any(np.diff(lo) < 0):
        return None
    nb_ = (n_faces + size - 1) // size
    f = np.repeat(np.arange(n_faces), neighbours.shape[1])
    g = neighbours.ravel()
    keep = g >= 0
    pairs = np.unique(np.concatenate([
        np.column_stack([f[keep] // size, g[keep] // size]),
        np.column_stack([np.arange(nb_), np.arange(nb_)])]), axis=0)
    start = np.searchsorted(pairs[:, 0], np.arange(nb_ + 1)).astype(np.int64)
    estart = np.searchsorted(lo, np.arange(nb_ + 1) * size).astype(np.int64)
    return start, np.ascontiguousarray(pairs[:, 1], dtype=np.int64), estart


@nb.njit(cache=True)
def mark_blocks(h, always, face_n, neighbours, state, dh, dhu, dhv, rate, z, hdry, edge_offset,
                rows, est, edge_faces, size, bstart, badj, estart, prev, prev2, cand, new,
                faces, edges):
    """``mark_active`` and ``_compact`` on the blocks where water may be, not the whole mesh.

    Faces come in blocks of ``size`` (``block_tables``).  A stage moves water no further than
    a face's neighbours, and every face holding water was active at one of the last two passes
    (the corrector writes the faces of both), so the faces active now, and those leaving, lie
    in the blocks next to the blocks active then (``prev``, ``prev2``: 1 for a block that held
    an active face; ``always`` faces' blocks must be set in them).  Those blocks are marked as
    ``mark_active`` marks (the same state, the same residuals zeroed); ``new`` gets this pass's
    active blocks; the active faces and the edges touching them are written in increasing
    order (``_compact``'s lists).  Returns (faces, edges, active blocks).  ``cand``: zero on
    entry and on return.
    """
    nbk = prev.shape[0]
    nf_all = h.shape[0]
    for b in range(nbk):
        if prev[b] or prev2[b]:
            for q in range(bstart[b], bstart[b + 1]):
                cand[np.uint64(badj[q])] = 1
    nf = 0
    nblk = 0
    for b in range(nbk):
        new[b] = 0
        if not cand[b]:
            continue
        cand[b] = 0
        for f in range(b * size, min((b + 1) * size, nf_all)):
            fu = np.uint64(f)  # unsigned indices: no negative-index wraparound (fluxes.py)
            was = state[fu] & 1
            on = h[fu] > 0.0 or always[fu]
            if not on:
                for k in range(face_n[fu]):
                    j = neighbours[fu, k]
                    if j >= 0 and h[np.uint64(j)] > 0.0:
                        on = True
                        break
            if on:
                state[fu] = 1
                faces[nf] = f
                nf += 1
                new[b] = 1
            else:
                state[fu] = 0
                if was:
                    _leave(f, h, face_n, dh, dhu, dhv, rate, z, hdry, edge_offset, rows, est)
        nblk += new[b]
    # the edges touching an active face have their smaller face in an active block or next to
    # one: sorted by that face, they are found block by block in increasing order
    for b in range(nbk):
        if new[b]:
            for q in range(bstart[b], bstart[b + 1]):
                cand[np.uint64(badj[q])] = 1
    ne = 0
    for b in range(nbk):
        if not cand[b]:
            continue
        cand[b] = 0
        for e in range(estart[b], estart[b + 1]):
            eu = np.uint64(e)
            a = np.uint64(edge_faces[eu, 0])
            c = edge_faces[eu, 1]
            if state[a] or (c >= 0 and state[np.uint64(c)]):
                edges[ne] = e
                ne += 1
    return nf, ne, nblk


@nb.njit(cache=True)
def active_blocks(state, size, new):
    """``new[b]`` = 1 where block b of ``size`` faces holds an active face; their number."""
    n = 0
    for b in range(new.shape[0]):
        v = 0
        for f in range(b * size, min((b + 1) * size, state.shape[0])):
            if state[f] & 1:
                v = 1
                break
        new[b] = v
        n += v
    return n


RUN = 64 * BLOCK  # the longest run of ``face_runs`` (faces): a share of a prange's work


def all_runs(n_faces, longest=RUN):
    """``face_runs`` of every face: (k, 2) runs of at most ``longest`` faces."""
    lo = np.arange(0, n_faces, longest, dtype=np.int64)
    return np.ascontiguousarray(np.column_stack([lo, np.minimum(lo + longest, n_faces)]))


@nb.njit(cache=True)
def face_runs(last, before, size, n_faces, longest, out):
    """The faces of the blocks flagged in ``last`` or ``before``, as runs of consecutive faces.

    Writes run k as faces ``out[k, 0]`` to ``out[k, 1] - 1`` (in increasing order, none longer
    than ``longest``, a multiple of ``size``, so that a prange shares them out) and returns
    their number: the stage kernels' runs (``ShallowWaterSolver._stage_runs``).  ``out`` has a
    row per block.
    """
    k = 0
    nbk = last.shape[0]
    b = 0
    while b < nbk:
        if not (last[b] or before[b]):
            b += 1
            continue
        lo = b * size
        while b < nbk and (last[b] or before[b]):
            b += 1
        hi = min(b * size, n_faces)
        while lo < hi:
            end = min(lo + longest, hi)
            out[k, 0] = lo
            out[k, 1] = end
            k += 1
            lo = end
    return k
