"""OpenFOAM cases as driftlog flows: shallowWaterFoam results, and interFoam depth-averaged.

shallowWaterFoam solves the 2D equations on a 3D mesh one cell thick (an ``empty`` patch on
the top and bottom).  The reader takes the bottom faces as the 2D mesh: cell c is face c, the
boundary patches tag the 2D boundary edges by name.  Fields ``h`` (depth), ``hU`` (unit
discharge; ``U`` times ``h`` if ``hU`` is absent), bed from ``constant/h0`` or else
``hTotal - h``.

interFoam results are 3D (``alpha.water``, ``U``); they are depth-averaged onto 2D faces::

    h = sum(alpha V) / A_column,   (hu, hv) = sum(alpha U V) / A_column

over the cells of each column of an extruded mesh (cells stacked through horizontal faces),
or over the cells whose centroid falls in each face of a chosen 2D mesh or raster.  Volume is
conserved exactly: sum(h A) = sum(alpha V).

Cases may be serial or decomposed (``processor*`` directories, read with their
``cellProcAddressing`` and ``pointProcAddressing``, no reconstructPar needed); files ascii or
binary, gzip-compressed or not; all written times or a chosen range.  Snapshots are read when
asked (``FoamSnapshots.read``), so a long run is not loaded at once.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField
from driftlog.mesh import Mesh
from driftlog.schema import Key

from ._common import select_times
from ._foam_case import (
    FoamCase,
    PolyMesh,
    check_ran,
    is_openfoam_case,
    processor_dirs,
    time_dirs,
)
from .foam_io import foam_path, read_internal_field, read_label_list
from .openfoam_vof import depth_average_columns, open_vof

__all__ = ["open_openfoam", "FoamCase", "FoamSnapshots", "depth_average_columns",
           "is_openfoam_case"]

SHALLOW_WATER_NAMES = {"depth": "h", "hu": "hU", "u": "U", "level": "hTotal", "bed": "h0"}
VOF_NAMES = {"alpha": "alpha.water", "u": "U"}


def _bottom_faces(pm: PolyMesh):
    """For a one-cell-thick mesh: the bottom face of each cell (from the empty patches).

    Returns (face ids in cell order, node table (n_cells, kmax) counter-clockwise from above).
    """
    empty = pm.patch_faces(types=("empty",))
    where = pm.folder
    if empty.size == 0:
        raise FlowFileError(f"{where}: no 'empty' patch; a shallowWaterFoam mesh is one cell "
                            "thick with empty top and bottom patches (for a 3D interFoam "
                            "case, the reader depth-averages alpha.water instead)")
    table, count = pm.face_table(empty)
    z = np.where(table >= 0, pm.points[np.maximum(table, 0), 2], 0.0).sum(1) / count
    own = pm.owner[empty]
    n_cells = pm.n_cells
    per_cell = np.bincount(own, minlength=n_cells)
    if np.any(per_cell != 2):
        bad = np.flatnonzero(per_cell != 2)
        raise FlowFileError(f"{where}: {bad.size} cells do not have exactly two faces on the "
                            f"empty patches (e.g. cells {bad[:5].tolist()}): not a one-cell-"
                            "thick extruded mesh")
    order = np.lexsort((z, own))  # by cell, lowest face first
    bottom = order[0::2]
    top = order[1::2]
    # the plane must be x-y: the bottom and top faces of a cell differ in z only
    dz = z[top] - z[bottom]
    if np.any(dz <= 0):
        raise FlowFileError(f"{where}: the empty patches are not horizontal (the 2D plane "
                            "must be x-y, extruded along z)")
    faces = empty[bottom]
    table, count = table[bottom], count[bottom]
    if count.max() > 4:
        bad = np.flatnonzero(count > 4)
        raise FlowFileError(f"{where}: unsupported element type: {bad.size} cells have a "
                            f"{int(count.max())}-sided footprint (e.g. cells {bad[:5].tolist()}); "
                            "driftlog reads triangles and quadrilaterals")
    # bottom faces point down (outward): reverse to counter-clockwise seen from above
    for k in (3, 4):
        rows = count == k
        table[rows, :k] = table[rows, :k][:, ::-1]
    return faces, table


class _TwoDMesh:
    """The 2D mesh of a one-cell-thick case (serial or assembled from processors)."""

    def __init__(self, case: FoamCase):
        self.case = case
        parts = case.parts()
        self.cell_maps = []
        tables, cells, pts_global = [], [], {}
        side = []  # (patch name, type, (n, 2) global node pairs)
        n_points = 0
        for part in parts:
            pm = PolyMesh(part / "constant" / "polyMesh")
            faces, table = _bottom_faces(pm)
            if case.decomposed:
                addr = part / "constant" / "polyMesh"
                cmap = read_label_list(addr / "cellProcAddressing")
                pmap = read_label_list(addr / "pointProcAddressing")
                if cmap.size != pm.n_cells or pmap.size != pm.points.shape[0]:
                    raise FlowFileError(f"{addr}: cellProcAddressing / pointProcAddressing do "
                                        "not match the processor mesh")
            else:
                cmap = np.arange(pm.n_cells)
                pmap = np.arange(pm.points.shape[0])
            self.cell_maps.append(cmap)
            tables.append(np.where(table >= 0, pmap[np.maximum(table, 0)], -1))
            cells.append(cmap)
            pts_global[part] = (pmap, pm.points)
            n_points = max(n_points, int(pmap.max()) + 1)
            for p in pm.patches:
                if p.get("type") in ("empty", "processor", "processorCyclic") or p["nFaces"] == 0:
                    continue
                ft, cnt = pm.face_table(np.arange(p["startFace"], p["startFace"] + p["nFaces"]))
                side.append((p["name"], p.get("type"), np.where(ft >= 0, pmap[np.maximum(ft, 0)],
                                                                -1), pm.points, pmap))
        points = np.zeros((n_points, 3))
        for pmap, pts in pts_global.values():
            points[pmap] = pts
        n_cells = int(max(c.max() for c in cells)) + 1
        kmax = max(t.shape[1] for t in tables)
        table = np.full((n_cells, kmax), -1, np.int64)
        seen = np.zeros(n_cells, bool)
        for t, c in zip(tables, cells, strict=True):
            table[c, :t.shape[1]] = t
            seen[c] = True
        if not seen.all():
            raise FlowFileError(f"{case.path}: the processor meshes do not cover cells "
                                f"{np.flatnonzero(~seen)[:5].tolist()}")
        used = np.unique(table[table >= 0])
        node_of_point = np.full(n_points, -1, np.int64)
        node_of_point[used] = np.arange(used.size)
        fn = np.where(table >= 0, node_of_point[np.maximum(table, 0)], -1)
        self.node_z = points[used, 2]
        try:
            self.mesh = Mesh(points[used, 0], points[used, 1], fn)
        except MeshError as exc:
            raise FlowFileError(f"{case.path}: the bottom faces do not make a valid 2D mesh: "
                                f"{exc}") from None
        self.n_cells = n_cells
        self._tag(side, node_of_point)

    def _tag(self, side, node_of_point):
        m = self.mesh
        b = m.boundary_edges
        e = m.edge_nodes[b]
        key = np.minimum(e[:, 0], e[:, 1]) * m.n_nodes + np.maximum(e[:, 0], e[:, 1])
        order = np.argsort(key)
        key_sorted = key[order]
        for name, _typ, ft, _pts, _pmap in side:
            nodes = np.where(ft >= 0, node_of_point[np.maximum(ft, 0)], -1)
            bottom = np.sort(np.where(nodes >= 0, nodes, np.iinfo(np.int64).max), axis=1)[:, :2]
            ok = bottom[:, 1] < np.iinfo(np.int64).max
            k = bottom[ok, 0] * m.n_nodes + bottom[ok, 1]
            pos = np.searchsorted(key_sorted, k)
            pos = np.minimum(pos, key_sorted.size - 1)
            hit = key_sorted[pos] == k
            if np.any(hit):
                m.tag_edges(name, b[order[pos[hit]]])


class FoamSnapshots:
    """Lazy snapshots of a shallowWaterFoam case: ``read(i)`` reads h and hU of time i."""

    def __init__(self, case: FoamCase, n_cells, cell_maps, names):
        self.case = case
        self.n_cells = n_cells
        self.cell_maps = cell_maps
        self.names = names
        self.times = case.times
        self.name = str(case.path)

    def _read(self, i, field, required=True):
        tname = self.case.time_name(i)
        out = None
        for part, cmap in zip(self.case.parts(), self.cell_maps, strict=True):
            arr = read_internal_field(part / tname / field, cmap.size, required=required)
            if arr is None:
                return None
            if out is None:
                out = np.empty((self.n_cells,) + arr.shape[1:])
            out[cmap] = arr
        return out

    def read(self, i):
        """Face arrays (h, hu, hv) of written time i."""
        h = self._read(i, self.names["depth"])
        hu = self._read(i, self.names["hu"], required=False)
        if hu is None:
            u = self._read(i, self.names["u"], required=False)
            if u is None:
                raise FlowFileError(f"{self.case.path}/{self.case.time_name(i)}: neither "
                                    f"{self.names['hu']!r} nor {self.names['u']!r} is there")
            hu = h[:, None] * u
        return h, hu[:, 0], hu[:, 1]

    def level(self, i):
        """HTotal at written time i (None if not written)."""
        return self._read(i, self.names["level"], required=False)


def _bed(case: FoamCase, snaps: FoamSnapshots, two_d: _TwoDMesh, names, notes):
    """Bed on faces: constant/h0, else hTotal - h of the first time that has hTotal."""
    bed = np.empty(two_d.n_cells)
    found = True
    for part, cmap in zip(case.parts(), two_d.cell_maps, strict=True):
        arr = read_internal_field(part / "constant" / names["bed"], cmap.size,
                                          required=False)
        if arr is None:
            found = False
            break
        bed[cmap] = arr
    if not found and case.decomposed:  # decomposePar leaves constant/h0 in the case root
        arr = read_internal_field(case.path / "constant" / names["bed"], two_d.n_cells,
                                          required=False)
        if arr is not None:
            bed[:], found = arr, True
    if found:
        notes.append(f"bed from constant/{names['bed']}")
        return bed
    for i in range(case.times.size):
        level = snaps.level(i)
        if level is not None:
            notes.append(f"bed from {names['level']} - {names['depth']} at t = "
                         f"{case.times[i]:g} s")
            return level - snaps._read(i, names["depth"])
    notes.append("no constant/h0 nor hTotal: bed taken as 0 (as shallowWaterFoam does)")
    return np.zeros(two_d.n_cells)


def open_openfoam(path, time_range=None, decomposed=None, variables=None, dry_depth=1e-3,
                  mode="auto", mesh2d=None, raster=None, include_initial=True,
                  allow_initial_only=False):
    """Open an OpenFOAM case as a MeshFlowField.

    Parameters
    ----------
    path : path
        Case directory.
    time_range : (start, end), optional
        Only the written times in [start, end] (s).
    decomposed : bool, optional
        Read processor* directories (True), the root (False), or decide (None).
    variables : dict, optional
        driftlog name -> OpenFOAM field name: depth (h), hu (hU), u (U), level (hTotal),
        bed (h0), alpha (alpha.water).
    mode : 'auto', 'shallow_water' or 'vof'
        shallowWaterFoam fields, or interFoam's 3D fields depth-averaged; 'auto' picks the
        one whose fields are there.
    mesh2d : Mesh, optional (vof)
        Depth-average onto this 2D mesh instead of the columns of an extruded mesh.
    raster : (x0, y0, dx, nx, ny) or dict, optional (vof)
        Depth-average onto a raster of nx by ny cells of size dx.
    include_initial : bool
        Keep the initial time (the fields the case started from) as the first snapshot.
    allow_initial_only : bool
        Accept a case that never ran (only its initial fields), as a steady flow.
    """
    path = Path(path)
    names = dict(SHALLOW_WATER_NAMES)
    vof = dict(VOF_NAMES)
    for k, v in (variables or {}).items():
        names[k] = v
        vof[k] = v
    if mode == "auto":
        mode = _detect_mode(path, names, vof)
    if mode == "vof":
        return open_vof(path, time_range=time_range, decomposed=decomposed, names=vof,
                        dry_depth=dry_depth, mesh2d=mesh2d, raster=raster)
    if mode != "shallow_water":
        raise FlowFileError(f"{path}: mode {mode!r} unknown (auto, shallow_water, vof)")
    case = FoamCase(path, decomposed=decomposed, field=names["depth"])
    if not allow_initial_only:
        check_ran(case, "shallowWaterFoam")
    two_d = _TwoDMesh(case)
    snaps = FoamSnapshots(case, two_d.n_cells, two_d.cell_maps, names)
    notes = []
    bed = _bed(case, snaps, two_d, names, notes)
    idx = select_times(case.times, time_range, str(path))
    if not include_initial and idx.size > 1 and idx[0] == 0:
        idx = idx[1:]
    if case.times.size == 1 and time_range is None:
        notes.append(f"only one written time ({case.times[0]:g} s): a steady flow")
    from ._common import SubsetSnapshots

    source = SubsetSnapshots(snaps, idx) if idx.size != case.times.size else snaps
    attrs = {"source": "openfoam shallowWaterFoam", "source_path": str(path.resolve()),
             "decomposed": int(case.decomposed), "import_notes": "; ".join(notes)}
    return MeshFlowField(two_d.mesh, bed, source, dry_depth=dry_depth, name=str(path),
                         attrs=attrs)


def _detect_mode(path, names, vof):
    for folder in [path] + (processor_dirs(path)[:1] if path.is_dir() else []):
        for _, tname in time_dirs(folder):
            if foam_path(folder / tname / names["depth"]):
                return "shallow_water"
            if foam_path(folder / tname / vof["alpha"]):
                return "vof"
    if not path.is_dir():
        raise FlowFileError(f"{path}: OpenFOAM case directory not found")
    if not (path / "constant" / "polyMesh").is_dir() and not processor_dirs(path):
        raise FlowFileError(f"{path}: not an OpenFOAM case (no constant/polyMesh, no "
                            "processor* directories)")
    times = [n for _, n in time_dirs(path)]
    raise FlowFileError(f"{path}: no time directory holds {names['depth']!r} "
                        f"(shallowWaterFoam) or {vof['alpha']!r} (interFoam)" +
                        (f"; time directories: {times}" if times else
                         "; there are no time directories: the case never ran"))


# --------------------------------------------------------------------- the reader contract
KIND = "openfoam"
SUFFIXES = ()
OPTIONS = [
    Key("decomposed", "bool", None, "read the processor* directories (true), the root (false), "
        "or decide (default)"),
    Key("mode", "str", "auto", "shallowWaterFoam fields, or interFoam's 3D fields "
        "depth-averaged; 'auto' picks the one whose fields are there",
        choices=("auto", "shallow_water", "vof")),
    Key("mesh2d", "any", None, "vof: depth-average onto this 2D mesh (a driftlog Mesh) instead "
        "of the columns of an extruded mesh"),
    Key("raster", "any", None, "vof: depth-average onto a raster [x0, y0, dx, nx, ny]"),
    Key("include_initial", "bool", True, "keep the initial time as the first snapshot"),
    Key("allow_initial_only", "bool", False, "accept a case that never ran (only its initial "
        "fields), as a steady flow"),
]


def can_open(path) -> bool:
    """Whether ``path`` is an OpenFOAM case directory or its system/controlDict."""
    try:
        p = Path(path)
        return is_openfoam_case(p) or (p.name == "controlDict" and p.parent.name == "system")
    except Exception:
        return False


def open(path, *, time_range=None, variables=None, dry_depth=1e-3, **options):
    """``open_openfoam`` under the reader contract (``options``: ``OPTIONS``)."""
    return open_openfoam(path, time_range=time_range, variables=variables, dry_depth=dry_depth,
                         **options)
