"""Operators for flows whose data are located on the mesh nodes (TELEMAC, node-based models).

A node-located flow is sampled P1 on its own node values (``driftlog.flow.MeshFlowField`` with a
source whose ``location`` is ``"node"``); two sparse operators complete it:

- ``face_mean_operator``: face value = mean of the face's node values (for the face arrays that
  the flow file writer, the plots and the solver's initial state use);
- ``node_gradient_operators``: the recovered gradient at a node = the area-weighted mean of the
  Green-Gauss gradients of the faces around it (each face's gradient is the exact gradient of a
  linear field on any polygon; for a triangle it is the gradient of its P1 interpolant), so the
  recovered gradient is exact for linear fields and continuous once interpolated P1, as the
  face-located path's least-squares gradients are.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["face_mean_operator", "node_gradient_operators", "lsq_node_operators"]


def _face_node_pairs(mesh):
    valid = mesh.face_nodes >= 0
    faces = np.broadcast_to(np.arange(mesh.n_faces)[:, None], mesh.face_nodes.shape)[valid]
    return faces, mesh.face_nodes[valid], valid


def face_mean_operator(mesh):
    """Sparse (n_faces, n_nodes) operator: the mean of each face's node values."""
    faces, nodes, _ = _face_node_pairs(mesh)
    w = 1.0 / mesh.face_n[faces]
    return sp.csr_matrix((w, (faces, nodes)), shape=(mesh.n_faces, mesh.n_nodes))


def node_gradient_operators(mesh):
    """Sparse (n_nodes, n_nodes) operators (d/dx, d/dy): recovered node gradients of P1 data.

    Face f's Green-Gauss gradient, with nodes n_0..n_{k-1} counter-clockwise and area A:
    d/dx = sum_j u_j (y_{j+1} - y_{j-1}) / (2 A), d/dy = -sum_j u_j (x_{j+1} - x_{j-1}) / (2 A);
    node gradient = sum_f A_f grad_f / sum_f A_f over the faces around the node.
    """
    fn, k = mesh.face_nodes, mesh.face_n
    nmax = fn.shape[1]
    j = np.arange(nmax)[None, :]
    nxt = np.where(j + 1 < k[:, None], j + 1, 0)
    prv = np.where(j > 0, j - 1, k[:, None] - 1)
    safe = np.where(fn >= 0, fn, fn[:, :1])
    x, y = mesh.node_x[safe], mesh.node_y[safe]
    xn, yn = np.take_along_axis(x, nxt, axis=1), np.take_along_axis(y, nxt, axis=1)
    xp, yp = np.take_along_axis(x, prv, axis=1), np.take_along_axis(y, prv, axis=1)
    area = mesh.face_area[:, None]
    cx = (yn - yp) / (2.0 * area)
    cy = -(xn - xp) / (2.0 * area)
    faces, nodes, valid = _face_node_pairs(mesh)
    shape = (mesh.n_faces, mesh.n_nodes)
    Dx = sp.csr_matrix((cx[valid], (faces, nodes)), shape=shape)
    Dy = sp.csr_matrix((cy[valid], (faces, nodes)), shape=shape)
    # area-weighted mean over the faces around each node
    wsum = np.bincount(nodes, weights=mesh.face_area[faces], minlength=mesh.n_nodes)
    R = sp.csr_matrix((mesh.face_area[faces] / wsum[nodes], (nodes, faces)),
                      shape=(mesh.n_nodes, mesh.n_faces))
    return (R @ Dx).tocsr(), (R @ Dy).tocsr()


# ------------------------------------------- face-located data: node values by least squares
def _node_face_pairs(mesh):
    valid = mesh.face_nodes >= 0
    nodes = mesh.face_nodes[valid]
    faces = np.broadcast_to(np.arange(mesh.n_faces)[:, None], mesh.face_nodes.shape)[valid]
    return nodes, faces


def _lsq_weights(nodes, faces, mesh):
    """Least-squares weights (value, d/dx, d/dy) for (node, face) stencil pairs; nodes that fit."""
    dx = mesh.face_x[faces] - mesh.node_x[nodes]
    dy = mesh.face_y[faces] - mesh.node_y[nodes]
    nn = mesh.n_nodes
    cnt = np.bincount(nodes, minlength=nn).astype(float)
    s2 = np.bincount(nodes, weights=dx * dx + dy * dy, minlength=nn) / np.maximum(cnt, 1)
    s = np.sqrt(np.maximum(s2, 1e-300))
    dx, dy = dx / s[nodes], dy / s[nodes]
    M = np.zeros((nn, 3, 3))
    cols = [np.ones_like(dx), dx, dy]
    for i in range(3):
        for j in range(i, 3):
            M[:, i, j] = np.bincount(nodes, weights=cols[i] * cols[j], minlength=nn)
            M[:, j, i] = M[:, i, j]
    # well conditioned when the smallest eigenvalue is a fair share of the stencil size
    ev = np.linalg.eigvalsh(M)
    ok = ev[:, 0] > 1e-6 * np.maximum(cnt, 1)
    Minv = np.zeros_like(M)
    Minv[ok] = np.linalg.inv(M[ok])
    w = [Minv[nodes, r, 0] + Minv[nodes, r, 1] * dx + Minv[nodes, r, 2] * dy for r in range(3)]
    w[1] = w[1] / s[nodes]  # undo the scaling of the coordinates
    w[2] = w[2] / s[nodes]
    return w, ok


def lsq_node_operators(mesh):
    """Sparse (n_nodes, n_faces) operators: value, d/dx, d/dy at the nodes from face values.

    Least squares over the faces around each node (a second ring where the first does not
    span the plane, a plain average where even that is collinear); exact for linear fields.
    """
    nn, nf = mesh.n_nodes, mesh.n_faces
    nodes, faces = _node_face_pairs(mesh)
    w, ok = _lsq_weights(nodes, faces, mesh)
    keep = ok[nodes]
    rows, cols, vals = [nodes[keep]], [faces[keep]], [[wk[keep]] for wk in w]
    bad = np.flatnonzero(~ok)
    if bad.size:
        # second ring: faces that share a node with a face around the node
        n2f = sp.csr_matrix((np.ones(nodes.size), (nodes, faces)), shape=(nn, nf))
        ring2 = ((n2f[bad] @ n2f.T) @ n2f).tocoo()
        bn, bf = bad[ring2.row], ring2.col
        w2, ok2 = _lsq_weights(bn, bf, mesh)
        keep2 = ok2[bn]
        rows.append(bn[keep2])
        cols.append(bf[keep2])
        for k in range(3):
            vals[k].append(w2[k][keep2])
        worst = np.setdiff1d(bad, bn[keep2])
        if worst.size:  # collinear even so: plain average of the faces around the node
            sel = np.isin(nodes, worst)
            cnt = np.bincount(nodes[sel], minlength=nn)
            rows.append(nodes[sel])
            cols.append(faces[sel])
            vals[0].append(1.0 / cnt[nodes[sel]])
            vals[1].append(np.zeros(sel.sum()))
            vals[2].append(np.zeros(sel.sum()))
    r, c = np.concatenate(rows), np.concatenate(cols)
    ops = []
    for k in range(3):
        P = sp.csr_matrix((np.concatenate(vals[k]), (r, c)), shape=(nn, nf))
        P.sum_duplicates()
        ops.append(P)
    return tuple(ops)
