"""The solver's momentum: its total, and momentum added to faces from outside (a source term).

The hook through which floating debris acts on the flow (``driftlog.coupling``,
docs/model.md section 3.9): an explicit momentum source applied between two steps as impulses
on faces, ``A_f (q_f^+ - q_f) = P_f / rho``, P_f the momentum (kg m/s) given to the water of face
f.  Nothing else in the solver changes: with no impulses the scheme is the one of section 3.
"""

from __future__ import annotations

import numpy as np

__all__ = ["face_momentum", "add_face_momentum"]


def face_momentum(solver) -> tuple[float, float]:
    """Momentum of the water in the domain per unit density, (sum A h u, sum A h v) (m4/s).

    Summed in the mesh's numbering (the round-off does not depend on the internal one).
    """
    area = solver.mesh.face_area
    return float(np.dot(area, solver.hu)), float(np.dot(area, solver.hv))


def add_face_momentum(solver, face, px, py, density):
    """Give the water of faces ``face`` the momenta (px, py) (kg m/s; repeated faces add up).

    Only wet faces (h > dry depth) hold momentum: the share of dry ones is not applied and
    is returned, so that a caller's momentum balance stays exact.

    Parameters
    ----------
    solver : ShallowWaterSolver
    face : (k,) int array
        Faces of the impulses (>= 0), in the mesh's numbering.
    px, py : (k,) arrays
        Momentum given to the water at each (kg m/s).
    density : float
        Water density (kg/m3): q changes by P / (rho A).

    Returns
    -------
    (float, float)
        The momentum not applied (on dry faces), x and y (kg m/s).
    """
    face = np.asarray(face, dtype=np.int64)
    if face.size == 0:
        return 0.0, 0.0
    nf = solver.mesh.n_faces
    sx = np.bincount(face, weights=px, minlength=nf)
    sy = np.bincount(face, weights=py, minlength=nf)
    hit = np.flatnonzero((sx != 0.0) | (sy != 0.0))
    inv = getattr(solver, "_inv", None)
    k = hit if inv is None or getattr(solver, "_identity", True) else inv[hit]
    h, hu, hv = _arrays(solver)
    dry = h[k] <= solver.dry_depth
    lost = hit[dry]
    wet, kw = hit[~dry], k[~dry]
    scale = 1.0 / (density * solver.mesh.face_area[wet])
    hu[kw] += sx[wet] * scale
    hv[kw] += sy[wet] * scale
    return float(sx[lost].sum()), float(sy[lost].sum())


def _arrays(solver):
    """The solver's own state arrays (internal numbering where it renumbers faces)."""
    if hasattr(solver, "_hu"):
        return solver._h, solver._hu, solver._hv
    return solver.h, solver.hu, solver.hv
