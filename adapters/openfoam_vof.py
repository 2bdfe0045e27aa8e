"""interFoam (volume of fluid) results depth-averaged to a 2D flow.

    h = sum(alpha V) / A,    (hu, hv) = sum(alpha U V) / A

summed over the cells of a column (an extruded mesh: cells stacked through faces whose normal
is mostly vertical; A is the column's horizontal footprint), or over the cells whose centroid
lies in each face of a chosen 2D mesh or raster (A the face area).  Either way
sum_faces(h A) = sum_cells(alpha V): the water volume is kept exactly.  The bed of a face is
the lowest point of its cells.

Cell volumes and centroids come from the polyMesh by OpenFOAM's own construction: faces split
into triangles about their average point, cells into pyramids about the average of their
face centres.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField
from driftlog.mesh import Mesh

from ._common import SubsetSnapshots, select_times
from ._foam_case import FoamCase, PolyMesh, check_ran
from .foam_io import read_internal_field, read_label_list

__all__ = ["open_vof", "cell_geometry", "depth_average_columns", "VofSnapshots"]


def face_geometry(pm: PolyMesh):
    """Face centres (nf, 3) and area vectors (nf, 3) (OpenFOAM's triangle decomposition)."""
    table, count = pm.face_table(np.arange(pm.n_faces))
    pts = pm.points
    valid = table >= 0
    p = pts[np.maximum(table, 0)]  # (nf, k, 3)
    avg = (p * valid[..., None]).sum(1) / count[:, None]
    nxt = np.where(np.arange(table.shape[1])[None, :] + 1 < count[:, None],
                   np.arange(table.shape[1])[None, :] + 1, 0)
    pn = np.take_along_axis(p, nxt[..., None].repeat(3, axis=2), axis=1)
    tri_n = 0.5 * np.cross(p - avg[:, None, :], pn - avg[:, None, :]) * valid[..., None]
    area = tri_n.sum(1)
    unit = area / np.maximum(np.linalg.norm(area, axis=1), 1e-300)[:, None]
    w = np.maximum(np.einsum("fkd,fd->fk", tri_n, unit), 0.0)
    tri_c = (p + pn + avg[:, None, :]) / 3.0
    centre = (tri_c * w[..., None]).sum(1) / np.maximum(w.sum(1), 1e-300)[:, None]
    return centre, area


def cell_geometry(pm: PolyMesh):
    """Cell volumes (nc,), centroids (nc, 3) and lowest node z (nc,) of a polyMesh."""
    fc, fa = face_geometry(pm)
    own, nbr = pm.owner, pm.neighbour
    ni = nbr.size
    nc = pm.n_cells
    cnt = np.bincount(own, minlength=nc) + np.bincount(nbr, minlength=nc)
    est = np.zeros((nc, 3))
    for d in range(3):
        est[:, d] = (np.bincount(own, fc[:, d], nc) + np.bincount(nbr, fc[:ni, d], nc)) / cnt
    pv_o = np.einsum("fd,fd->f", fa, fc - est[own]) / 3.0
    pv_n = -np.einsum("fd,fd->f", fa[:ni], fc[:ni] - est[nbr]) / 3.0
    vol = np.bincount(own, pv_o, nc) + np.bincount(nbr, pv_n, nc)
    cen = np.zeros((nc, 3))
    for d in range(3):
        cen[:, d] = (np.bincount(own, pv_o * (0.75 * fc[:, d] + 0.25 * est[own, d]), nc)
                     + np.bincount(nbr, pv_n * (0.75 * fc[:ni, d] + 0.25 * est[nbr, d]), nc))
    cen /= vol[:, None]
    table, count = pm.face_table(np.arange(pm.n_faces))
    fz = np.where(table >= 0, pm.points[np.maximum(table, 0), 2], np.inf).min(1)
    zmin = np.full(nc, np.inf)
    np.minimum.at(zmin, own, fz)
    np.minimum.at(zmin, nbr, fz[:ni])
    return vol, cen, zmin, fc, fa


def depth_average_columns(pm: PolyMesh, vertical=0.5):
    """Columns of an extruded mesh: (column of each cell, 2D Mesh of the columns' footprints).

    Cells are joined through internal faces whose unit normal has |n_z| > ``vertical``; the
    footprint of a column is the projection of its bottom boundary face.  Raises if the
    columns' cells do not share one footprint (not an extruded mesh).
    """
    fc, fa = face_geometry(pm)
    mag = np.linalg.norm(fa, axis=1)
    nz = fa[:, 2] / np.maximum(mag, 1e-300)
    nbr = pm.neighbour
    ni = nbr.size
    nc = pm.n_cells
    horiz = np.flatnonzero(np.abs(nz[:ni]) > vertical)
    g = sp.coo_matrix((np.ones(horiz.size), (pm.owner[horiz], nbr[horiz])), shape=(nc, nc))
    ncol, col = connected_components(g, directed=False)
    # the bottom of each column: a boundary face pointing down
    bnd = np.arange(ni, pm.n_faces)
    down = bnd[nz[bnd] < -vertical]
    own = pm.owner[down]
    cols_of = col[own]
    # lowest downward boundary face of each column
    order = np.lexsort((fc[down, 2], cols_of))
    first = np.ones(order.size, bool)
    first[1:] = cols_of[order][1:] != cols_of[order][:-1]
    bottom = np.full(ncol, -1, np.int64)
    bottom[cols_of[order][first]] = down[order][first]
    where = pm.folder
    if np.any(bottom < 0):
        raise FlowFileError(f"{where}: {np.sum(bottom < 0)} columns have no bottom boundary "
                            "face: not an extruded mesh; pass mesh2d= or raster= to "
                            "depth-average onto a chosen 2D mesh")
    # every horizontal face of a column must have the column's footprint area
    foot = np.abs(fa[bottom, 2])
    check = np.abs(fa[horiz, 2]) - foot[col[pm.owner[horiz]]]
    if horiz.size and np.max(np.abs(check) / foot[col[pm.owner[horiz]]]) > 1e-6:
        raise FlowFileError(f"{where}: cells stacked in a column have different footprints: "
                            "not an extruded mesh; pass mesh2d= or raster= to depth-average "
                            "onto a chosen 2D mesh")
    table, count = pm.face_table(bottom)
    if count.max() > 4:
        raise FlowFileError(f"{where}: unsupported element type: columns with "
                            f"{int(count.max())}-sided footprints (triangles and quadrilaterals "
                            "only); pass mesh2d= or raster=")
    used = np.unique(table[table >= 0])
    node = np.full(pm.points.shape[0], -1, np.int64)
    node[used] = np.arange(used.size)
    fn = np.where(table >= 0, node[np.maximum(table, 0)], -1)
    try:
        mesh = Mesh(pm.points[used, 0], pm.points[used, 1], fn)
    except MeshError as exc:
        raise FlowFileError(f"{where}: the column footprints do not make a 2D mesh: {exc}") \
            from None
    return col, mesh


def _raster_mesh(raster):
    if isinstance(raster, dict):
        x0, y0, dx = raster["x0"], raster["y0"], raster["dx"]
        nx, ny = raster["nx"], raster["ny"]
        dy = raster.get("dy", dx)
    else:
        x0, y0, dx, nx, ny = raster[:5]
        dy = raster[5] if len(raster) > 5 else dx
    return Mesh.regular_grid(nx, ny, dx, dy, x0=x0, y0=y0)


class VofSnapshots:
    """Lazy depth-averaged snapshots: each ``read(i)`` reads alpha and U of one time."""

    def __init__(self, case: FoamCase, parts, face_of_cell, area, names):
        self.case = case
        self.parts = parts  # (folder, global cell ids, volumes)
        self.face_of_cell = face_of_cell
        self.area = area
        self.names = names
        self.times = case.times
        self.name = str(case.path)

    def read(self, i):
        """Depth-averaged face arrays (h, hu, hv) of written time i."""
        tname = self.case.time_name(i)
        nf = self.area.size
        vol_w = np.zeros(nf)
        qx = np.zeros(nf)
        qy = np.zeros(nf)
        for folder, cells, vol in self.parts:
            alpha = read_internal_field(folder / tname / self.names["alpha"], vol.size)
            u = read_internal_field(folder / tname / self.names["u"], vol.size)
            face = self.face_of_cell[cells]
            keep = face >= 0
            w = alpha * vol  # unclipped: MULES undershoots (~1e-8) cancel in the column sums
            vol_w += np.bincount(face[keep], w[keep], nf)
            qx += np.bincount(face[keep], (w * u[:, 0])[keep], nf)
            qy += np.bincount(face[keep], (w * u[:, 1])[keep], nf)
        # a column of air alone may sum to -1e-9: no negative depths
        return np.maximum(vol_w, 0.0) / self.area, qx / self.area, qy / self.area


def open_vof(path, time_range=None, decomposed=None, names=None, dry_depth=1e-3, mesh2d=None,
             raster=None, allow_initial_only=False):
    """Depth-average an interFoam case onto its columns, a 2D mesh or a raster."""
    names = dict(names or {"alpha": "alpha.water", "u": "U"})
    case = FoamCase(path, decomposed=decomposed, field=names["alpha"])
    if not allow_initial_only:
        check_ran(case, "interFoam")
    parts, geo = [], []
    offset = 0
    for folder in case.parts():
        pm = PolyMesh(folder / "constant" / "polyMesh")
        vol, cen, zmin, _, _ = cell_geometry(pm)
        if case.decomposed:
            cells = read_label_list(folder / "constant" / "polyMesh" /
                                            "cellProcAddressing")
        else:
            cells = np.arange(pm.n_cells)
        parts.append((folder, cells, vol))
        geo.append((pm, cells, vol, cen, zmin))
        offset = max(offset, int(cells.max()) + 1)
    n_cells = offset
    vol = np.zeros(n_cells)
    cen = np.zeros((n_cells, 3))
    zmin = np.zeros(n_cells)
    for _pm, cells, v, c, z in geo:
        vol[cells], cen[cells], zmin[cells] = v, c, z
    notes = []
    if mesh2d is None and raster is None:
        if case.decomposed:
            raise FlowFileError(f"{path}: depth-averaging on columns needs the whole mesh; "
                                "reconstructPar the case, or pass mesh2d= or raster=")
        col, mesh = depth_average_columns(geo[0][0])
        face_of_cell = col
        area = mesh.face_area
        notes.append(f"depth-averaged over {mesh.n_faces} columns of the extruded mesh")
    else:
        mesh = mesh2d if mesh2d is not None else _raster_mesh(raster)
        face_of_cell = mesh.locate(cen[:, 0], cen[:, 1])
        area = mesh.face_area
        outside = np.sum(face_of_cell < 0)
        notes.append(f"depth-averaged onto a given {'mesh' if mesh2d is not None else 'raster'}"
                     f" of {mesh.n_faces} faces (cells by centroid)")
        if outside:
            notes.append(f"{outside} cells lie outside it and are left out")
    bed = np.full(mesh.n_faces, np.inf)
    keep = face_of_cell >= 0
    np.minimum.at(bed, face_of_cell[keep], zmin[keep])
    empty = ~np.isfinite(bed)
    if np.any(empty):
        notes.append(f"{empty.sum()} faces hold no cell centroid: dry, bed 0")
        bed[empty] = 0.0
    snaps = VofSnapshots(case, parts, face_of_cell, area, names)
    idx = select_times(case.times, time_range, str(path))
    source = SubsetSnapshots(snaps, idx) if idx.size != case.times.size else snaps
    attrs = {"source": "openfoam interFoam (depth-averaged)", "source_path": str(path),
             "decomposed": int(case.decomposed), "import_notes": "; ".join(notes),
             "water_volume_cells": float(np.sum(vol))}
    field = MeshFlowField(mesh, bed, source, dry_depth=dry_depth, name=str(path), attrs=attrs)
    field.cell_volume = vol
    field.face_of_cell = face_of_cell
    return field
