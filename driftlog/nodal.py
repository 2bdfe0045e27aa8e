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

__all__ = ["face_mean_operator", "node_gradient_operators"]


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
