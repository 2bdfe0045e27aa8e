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

import re
from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField
from driftlog.mesh import Mesh
from driftlog.schema import Key

from . import foam_io
from ._common import select_times

__all__ = ["open_openfoam", "FoamCase", "FoamSnapshots", "depth_average_columns",
           "is_openfoam_case"]

SHALLOW_WATER_NAMES = {"depth": "h", "hu": "hU", "u": "U", "level": "hTotal", "bed": "h0"}
VOF_NAMES = {"alpha": "alpha.water", "u": "U"}
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def is_openfoam_case(path) -> bool:
    """Whether a directory looks like an OpenFOAM case."""
    p = Path(path)
    return p.is_dir() and ((p / "system" / "controlDict").is_file()
                           or (p / "constant" / "polyMesh").is_dir()
                           or (p / "processor0").is_dir())


def _time_dirs(folder: Path):
    """(value, name) of the time directories in a folder, sorted by time."""
    out = []
    if not folder.is_dir():
        return out
    for d in folder.iterdir():
        if d.is_dir() and _NUMBER.match(d.name):
            out.append((float(d.name), d.name))
    return sorted(out)


def _processor_dirs(case: Path):
    dirs = [d for d in case.iterdir() if d.is_dir() and re.fullmatch(r"processor\d+", d.name)]
    return sorted(dirs, key=lambda d: int(d.name[9:]))


class _PolyMesh:
    """The arrays of a polyMesh directory (points, faces, owner, boundary), read once."""

    def __init__(self, folder: Path):
        self.folder = folder
        if not folder.is_dir():
            raise FlowFileError(f"{folder}: no polyMesh directory (run blockMesh first?)")
        for name in ("points", "faces", "owner", "boundary"):
            if foam_io.foam_path(folder / name) is None:
                raise FlowFileError(f"{folder}: polyMesh file {name!r} is missing")
        self.points = foam_io.read_points(folder / "points")
        self.offsets, self.labels = foam_io.read_faces(folder / "faces")
        self.owner = foam_io.read_label_list(folder / "owner")
        self.patches = foam_io.read_boundary(folder / "boundary")
        self.n_faces = self.offsets.size - 1
        self.n_cells = int(self.owner.max()) + 1 if self.owner.size else 0
        if self.owner.size != self.n_faces:
            raise FlowFileError(f"{folder}: owner has {self.owner.size} entries for "
                                f"{self.n_faces} faces")
        self._neighbour = None

    @property
    def neighbour(self):
        if self._neighbour is None:
            self._neighbour = foam_io.read_label_list(self.folder / "neighbour")
            self.n_cells = max(self.n_cells, int(self._neighbour.max(initial=-1)) + 1)
        return self._neighbour

    def face_table(self, faces):
        """Padded (n, kmax) node table of the given faces, and their node counts."""
        start, stop = self.offsets[faces], self.offsets[faces + 1]
        count = stop - start
        kmax = int(count.max(initial=0))
        k = np.arange(kmax)
        idx = start[:, None] + np.minimum(k[None, :], np.maximum(count[:, None] - 1, 0))
        table = self.labels[idx]
        table[k[None, :] >= count[:, None]] = -1
        return table, count

    def patch_faces(self, types=None, names=None):
        out = []
        for p in self.patches:
            if (types is None or p.get("type") in types) and (names is None or p["name"] in names):
                out.append(np.arange(p["startFace"], p["startFace"] + p["nFaces"]))
        return np.concatenate(out) if out else np.empty(0, np.int64)


def _bottom_faces(pm: _PolyMesh):
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


class FoamCase:
    """An OpenFOAM case directory: its time directories, serial or decomposed.

    Parameters
    ----------
    path : path
        The case directory.
    decomposed : bool or None
        Read the ``processor*`` directories (True), the case root (False), or whichever has
        more written times holding ``field`` (None).
    field : str
        A field that a written time must hold to count.
    """

    def __init__(self, path, decomposed=None, field="h"):
        self.path = Path(path)
        if not self.path.is_dir():
            raise FlowFileError(f"{self.path}: OpenFOAM case directory not found")
        self.processors = _processor_dirs(self.path)
        self.field = field
        root_times = [t for t in _time_dirs(self.path)
                      if foam_io.foam_path(self.path / t[1] / field)]
        proc_times = []
        if self.processors:
            proc_times = [t for t in _time_dirs(self.processors[0])
                          if foam_io.foam_path(self.processors[0] / t[1] / field)]
        if decomposed is None:
            decomposed = bool(self.processors) and len(proc_times) > len(root_times)
        if decomposed and not self.processors:
            raise FlowFileError(f"{self.path}: decomposed = True but there are no processor* "
                                "directories")
        self.decomposed = bool(decomposed)
        self.time_entries = proc_times if self.decomposed else root_times
        if not self.time_entries:
            where = self.processors[0] if self.decomposed else self.path
            others = [n for _, n in _time_dirs(where)]
            raise FlowFileError(
                f"{where}: no time directory holds the field {field!r} " +
                (f"(time directories: {others}) " if others else "(no time directories) ") +
                "— the case never ran, or wrote other fields")

    @property
    def times(self) -> np.ndarray:
        """The written times (s)."""
        return np.array([t for t, _ in self.time_entries])

    def time_name(self, i) -> str:
        """The directory name of written time i."""
        return self.time_entries[i][1]

    def parts(self):
        """The folders that hold meshes and fields: the processors, or the case itself."""
        return self.processors if self.decomposed else [self.path]


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
            pm = _PolyMesh(part / "constant" / "polyMesh")
            faces, table = _bottom_faces(pm)
            if case.decomposed:
                addr = part / "constant" / "polyMesh"
                cmap = foam_io.read_label_list(addr / "cellProcAddressing")
                pmap = foam_io.read_label_list(addr / "pointProcAddressing")
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
            arr = foam_io.read_internal_field(part / tname / field, cmap.size, required=required)
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
        arr = foam_io.read_internal_field(part / "constant" / names["bed"], cmap.size,
                                          required=False)
        if arr is None:
            found = False
            break
        bed[cmap] = arr
    if not found and case.decomposed:  # decomposePar leaves constant/h0 in the case root
        arr = foam_io.read_internal_field(case.path / "constant" / names["bed"], two_d.n_cells,
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
        from .openfoam_vof import open_vof

        return open_vof(path, time_range=time_range, decomposed=decomposed, names=vof,
                        dry_depth=dry_depth, mesh2d=mesh2d, raster=raster)
    if mode != "shallow_water":
        raise FlowFileError(f"{path}: mode {mode!r} unknown (auto, shallow_water, vof)")
    case = FoamCase(path, decomposed=decomposed, field=names["depth"])
    if not allow_initial_only:
        _check_ran(case, "shallowWaterFoam")
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


def _check_ran(case: FoamCase, solver):
    """Ran: more than one written time, or a time written by a solver (with uniform/time)."""
    part = case.parts()[0]
    written = any((part / name / "uniform" / "time").is_file() for _, name in case.time_entries)
    if len(case.time_entries) < 2 and not written:
        names = [n for _, n in case.time_entries]
        raise FlowFileError(f"{part}: only initial fields (time directory {names[0]}, not "
                            f"written by a solver): the case never ran; run {solver} first, "
                            "or pass allow_initial_only=True to import the initial fields")


def _detect_mode(path, names, vof):
    for folder in [path] + (_processor_dirs(path)[:1] if path.is_dir() else []):
        for _, tname in _time_dirs(folder):
            if foam_io.foam_path(folder / tname / names["depth"]):
                return "shallow_water"
            if foam_io.foam_path(folder / tname / vof["alpha"]):
                return "vof"
    if not path.is_dir():
        raise FlowFileError(f"{path}: OpenFOAM case directory not found")
    if not (path / "constant" / "polyMesh").is_dir() and not _processor_dirs(path):
        raise FlowFileError(f"{path}: not an OpenFOAM case (no constant/polyMesh, no "
                            "processor* directories)")
    times = [n for _, n in _time_dirs(path)]
    raise FlowFileError(f"{path}: no time directory holds {names['depth']!r} "
                        f"(shallowWaterFoam) or {vof['alpha']!r} (interFoam)" +
                        (f"; time directories: {times}" if times else
                         "; there are no time directories: the case never ran"))


def depth_average_columns(*args, **kwargs):
    """See ``driftlog.adapters.openfoam_vof.depth_average_columns``."""
    from .openfoam_vof import depth_average_columns as f

    return f(*args, **kwargs)


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
