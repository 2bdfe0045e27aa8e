"""HEC-RAS 2D results (HEC-RAS 6.x plan and geometry HDF5 files) as driftlog flows.

A HEC-RAS 2D flow area is a mesh of polygonal cells (3 to 8 sides; HEC-RAS's ``Cells FacePoint
Indexes`` pads with -1) whose faces join *face points*.  The plan output stores, per output
time, the ``Water Surface`` of each cell and the ``Face Velocity``: the velocity normal to each
face (HEC-RAS stores no cell velocity vector; RAS Mapper reconstructs one).  This reader:

- builds each cell's polygon from its faces (``Cells Face and Orientation``), face points and
  the intermediate points of perimeter faces (``Faces Perimeter Values``), so the polygon's area
  is HEC-RAS's own ``Cells Surface Area``.  A cell whose polygon is convex with at most 8 nodes
  is one driftlog mesh face; a non-convex perimeter cell (or one with more nodes) is split into
  triangles (ear clipping) that all carry the cell's values;
- reads every 2D flow area in the file, or those named (option ``areas``), into one mesh;
- takes the bed from ``Cells Minimum Elevation`` (the cell's lowest terrain point, HEC-RAS's
  own bed), in the plan or in a geometry file the user names (option ``geometry``), or from a
  terrain raster the user names (option ``terrain``: the lowest raster pixel in each cell); a
  plan without any of these is an error that says which option to give.  ``bed =
  "min_water_surface"`` takes the plan's summary ``Minimum Water Surface`` instead: exact for
  cells that went dry during the run (HEC-RAS reports a dry cell's water surface at its
  minimum elevation), above the bed for cells wet throughout; a documented approximation the
  user must ask for;
- depth = water surface - bed (a float32 round-off below the bed is clipped; more is an error);
- reconstructs the cell velocity from the faces' normal velocities by least squares over the
  cell's faces weighted by face length: ``(sum L n n^T) u = sum L n v_n``, exact for a uniform
  flow, applied as two precomputed sparse operators (one matrix product per snapshot);
- reads the time axis from ``Time Date Stamp`` (times in seconds since the first stamp, kept as
  ``attrs["time_reference"] = "seconds since YYYY-MM-DDTHH:MM:SS"``);
- converts US Customary files (ft, ft/s) to SI, coordinates included, with the foot of the
  file's Projection (the last UNIT of its WKT: a State Plane projection in US survey feet,
  x_m = 0.3048006096 x_ft, is 1.2 m from the international foot at 2e6 ft), else the
  international foot (x_m = 0.3048 x_ft); keeps the projection (WKT), the factor and which
  foot it is (``import_notes``) in the flow's attributes.
- refuses a file whose ``Projection`` WKT is geographic (longitude/latitude in degrees), and a
  terrain raster in a geographic CRS: driftlog needs projected coordinates.

The plan's time series may sit in a separate file (the option ``results``), as in the trimmed
Bald Eagle Creek example of ``../shared/data/hecras``.
"""

from __future__ import annotations

import datetime as _dt
import re
from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError, geographic_error
from driftlog.schema import Key

from ._hecras_geometry import (
    AREAS,
    FT,
    HDF5_SIGNATURE,
    HecrasGeometry,
    area_table,
    as_text,
    check_projection,
    open_h5,
    read_dataset,
    read_geometry,
    units,
)

__all__ = ["KIND", "SUFFIXES", "OPTIONS", "can_open", "open", "open_hecras", "describe",
           "read_geometry", "HecrasGeometry", "FT"]

KIND = "hecras"
SUFFIXES = (".hdf", ".h5", ".hdf5")
_OUTPUT = "Results/Unsteady/Output/Output Blocks/Base Output"
_SERIES = _OUTPUT + "/Unsteady Time Series"
_SUMMARY = _OUTPUT + "/Summary Output/2D Flow Areas"

OPTIONS = [
    Key("areas", "any", None, "2D flow areas to read: a name or a list of names (default: all "
        "of the file's)"),
    Key("bed", "str", "auto", "'auto': Cells Minimum Elevation of the plan, else of the "
        "'geometry' file, else the lowest pixel of 'terrain' in each cell (an error if none); "
        "'min_water_surface': the lowest water surface the plan reports per cell (the bed where "
        "a cell went dry, above it elsewhere)", choices=("auto", "min_water_surface")),
    Key("geometry", "path", None, "HEC-RAS geometry HDF (*.gNN.hdf) whose Cells Minimum "
        "Elevation is the bed, when the plan file lacks it", must_exist=True),
    Key("terrain", "path", None, "terrain raster (GeoTIFF...) in the project's coordinates and "
        "units: the bed is its lowest pixel in each cell (needs rasterio)", must_exist=True),
    Key("results", "path", None, "HDF file holding the plan's 'Unsteady Time Series' when the "
        "plan file given has none", must_exist=True),
]

# --------------------------------------------------------------------- small helpers
def can_open(path) -> bool:
    """Whether ``path`` is a HEC-RAS HDF5 file (cheap sniff; never raises)."""
    try:
        p = Path(path)
        if not p.is_file():
            return False
        with p.open("rb") as fh:
            if fh.read(8) != HDF5_SIGNATURE:
                return False
        import h5py

        with h5py.File(p, "r") as f:
            return as_text(f.attrs.get("File Type", b"")).startswith("HEC-RAS") or AREAS in f
    except Exception:  # a sniff never raises
        return False


# --------------------------------------------------------------------- time axis
_STAMP = re.compile(r"^(\d{1,2})([A-Za-z]{3})(\d{4})\s+"
                    r"(\d{2}):?(\d{2})(?::?(\d{2}))?(?::(\d{1,3}))?$")
_MONTHS = {m: i for i, m in enumerate(["JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG",
                                       "SEP", "OCT", "NOV", "DEC"], start=1)}


def parse_stamp(text, where="time stamp") -> np.datetime64:
    """A HEC-RAS date stamp ('01JAN1999 12:00:00:000', '01JAN1999 2400') as datetime64[ms]."""
    s = as_text(text)
    m = _STAMP.match(s)
    if m is None or m.group(2).upper() not in _MONTHS:
        raise FlowFileError(f"{where}: date stamp {s!r} not understood (expected "
                            "'DDMONYYYY HH:MM:SS[:mmm]', e.g. '01JAN1999 12:00:00:000')")
    day, mon, year, hh, mm, ss, ms = m.groups()
    base = np.datetime64(_dt.date(int(year), _MONTHS[mon.upper()], int(day)), "ms")
    # HEC-RAS writes midnight as 24:00 of the day before
    off = ((int(hh) * 60 + int(mm)) * 60 + int(ss or 0)) * 1000 + int((ms or "0").ljust(3, "0"))
    return base + np.timedelta64(off, "ms")


def read_time_axis(f, path):
    """(seconds since the first stamp, the first stamp as ISO text) of the time series."""
    for key in (_SERIES + "/Time Date Stamp (ms)", _SERIES + "/Time Date Stamp"):
        if key in f:
            stamps = read_dataset(f, key, path)
            t = np.array([parse_stamp(s, f"{path}: {key}") for s in stamps])
            sec = (t - t[0]).astype("timedelta64[ms]").astype(np.int64) / 1000.0
            return sec, str(t[0].astype("datetime64[s]"))
    if _SERIES + "/Time" in f:  # days since the simulation start
        days = read_dataset(f, _SERIES + "/Time", path).astype(np.float64)
        return (days - days[0]) * 86400.0, None
    raise FlowFileError(f"{path}: the time series has no 'Time Date Stamp' nor 'Time' dataset "
                        f"under {_SERIES!r}")


# --------------------------------------------------------------------- results
class HecrasSnapshots:
    """Lazy snapshots of a HEC-RAS time series on the driftlog mesh faces: (h, hu, hv)."""

    def __init__(self, f, path, geom, bed_cells, times, index, name):
        self.f, self.path, self.geom, self.bed_cells = f, path, geom, bed_cells
        self.times = np.asarray(times, np.float64)
        self.index = np.asarray(index, np.int64)
        self.name = name
        self.depth_tolerance = 1e-3  # m: float32 round-off of a water surface near the bed

    def cell_arrays(self, i):
        """Cell arrays (water surface, depth, u, v) of snapshot i (SI units)."""
        g, k = self.geom, int(self.index[i])
        ws, vn = [], []
        for name, nreal in zip(g.areas, g.n_real, strict=True):
            base = f"{_SERIES}/2D Flow Areas/{name}"
            try:
                ws.append(self.f[base + "/Water Surface"][k, :nreal])
                vn.append(self.f[base + "/Face Velocity"][k, :])
            except OSError as exc:
                raise FlowFileError(f"{self.path}: cannot read snapshot {k} of area {name!r}: "
                                    f"the file is truncated or damaged ({exc})") from None
        ws = np.concatenate(ws).astype(np.float64) * g.length_factor
        vn = np.concatenate(vn).astype(np.float64) * g.length_factor
        if vn.size != g.face_normal.shape[0]:
            raise FlowFileError(f"{self.path}: snapshot {k}: {vn.size} face velocities for "
                                f"{g.face_normal.shape[0]} faces")
        for arr, what in ((ws, "Water Surface"), (vn, "Face Velocity")):
            if not np.all(np.isfinite(arr)):
                bad = np.flatnonzero(~np.isfinite(arr))
                raise FlowFileError(f"{self.path}: snapshot {k}: {bad.size} non-finite "
                                    f"{what} values (first cells/faces {bad[:5].tolist()})")
        h = ws - self.bed_cells
        low = h < -self.depth_tolerance
        if np.any(low):
            bad = np.flatnonzero(low)
            raise FlowFileError(f"{self.path}: snapshot {k}: the water surface is below the bed "
                                f"in {bad.size} cells (first {bad[:5].tolist()}, by up to "
                                f"{-h.min():.3g} m): the bed does not belong to this plan")
        h = np.maximum(h, 0.0)
        u, v = g.cell_velocity(vn)
        return ws, h, u, v

    def read(self, i):
        _, h, u, v = self.cell_arrays(i)
        c = self.geom.cell_of_face
        return h[c], (h * u)[c], (h * v)[c]

    def close(self):
        try:
            self.f.close()
        except Exception:  # already closed
            pass


def _bed_from_geometry_file(gpath, geom, path):
    gf = open_h5(gpath, "geometry file")
    with gf:
        names, counts = area_table(gf, gpath)
        factor, _ = units(gf, gpath)
        beds = []
        for name, nreal in zip(geom.areas, geom.n_real, strict=True):
            if name not in names:
                raise FlowFileError(f"{gpath}: no 2D flow area {name!r} (the plan {path} has "
                                    f"it); the geometry file has {', '.join(map(repr, names))}")
            key = f"{AREAS}/{name}/Cells Minimum Elevation"
            if key not in gf:
                raise FlowFileError(f"{gpath}: area {name!r} has no 'Cells Minimum Elevation'")
            z = read_dataset(gf, key, gpath)
            if counts[names.index(name)] != nreal:
                raise FlowFileError(f"{gpath}: area {name!r} has {counts[names.index(name)]} "
                                    f"cells, the plan {path} has {nreal}: not the plan's "
                                    "geometry")
            beds.append(z[:nreal].astype(np.float64) * factor)
        return np.concatenate(beds)


def _bed_from_terrain(tpath, geom, path):
    try:
        import rasterio
    except ImportError:
        raise FlowFileError(f"{path}: terrain = {str(tpath)!r} needs the package rasterio "
                            "(pip install rasterio)") from None
    tpath = Path(tpath)
    if not tpath.is_file():
        raise FlowFileError(f"{tpath}: terrain raster not found")
    mesh, fac = geom.mesh, geom.length_factor
    try:
        with rasterio.open(tpath) as r:
            if r.crs is not None and r.crs.is_geographic:
                raise geographic_error(tpath, "CRS", r.crs.to_string())
            x0, y0, x1, y1 = (np.asarray(mesh.bounds) / fac)
            win = rasterio.windows.from_bounds(x0, y0, x1, y1, r.transform).round_offsets() \
                .round_lengths()
            z = r.read(1, window=win, masked=True, boundless=True).astype(np.float64)
            tr = r.window_transform(win)
    except rasterio.errors.RasterioError as exc:
        raise FlowFileError(f"{tpath}: cannot read the terrain raster ({exc})") from None
    rows, cols = np.indices(z.shape)
    px = (tr.c + (cols + 0.5) * tr.a + (rows + 0.5) * tr.b) * fac
    py = (tr.f + (cols + 0.5) * tr.d + (rows + 0.5) * tr.e) * fac
    ok = ~np.ma.getmaskarray(z)
    face = mesh.locate(px[ok], py[ok])
    inside = face >= 0
    cell = geom.cell_of_face[face[inside]]
    zc = np.full(geom.n_cells, np.inf)
    np.minimum.at(zc, cell, z.data[ok][inside] * fac)
    empty = ~np.isfinite(zc)
    if np.any(empty):  # cells smaller than a pixel: the pixel at the cell's centroid
        cx = np.bincount(geom.cell_of_face, mesh.face_area * mesh.face_x, geom.n_cells)
        cy = np.bincount(geom.cell_of_face, mesh.face_area * mesh.face_y, geom.n_cells)
        cx, cy = cx[empty] / geom.cell_area[empty], cy[empty] / geom.cell_area[empty]
        det = tr.a * tr.e - tr.b * tr.d  # invert the affine transform (no rotation assumed)
        dx, dy = cx / fac - tr.c, cy / fac - tr.f
        cc, rr = (tr.e * dx - tr.b * dy) / det, (tr.a * dy - tr.d * dx) / det
        rr, cc = np.floor(rr).astype(int), np.floor(cc).astype(int)
        good = (rr >= 0) & (rr < z.shape[0]) & (cc >= 0) & (cc < z.shape[1])
        vals = np.full(rr.size, np.nan)
        vals[good] = np.where(ok[rr[good], cc[good]], z.data[rr[good], cc[good]] * fac, np.nan)
        zc[empty] = vals
    if not np.all(np.isfinite(zc)):
        bad = np.flatnonzero(~np.isfinite(zc))
        raise FlowFileError(f"{tpath}: the terrain raster does not cover {bad.size} cells of "
                            f"{path} (first {bad[:5].tolist()}): nodata or outside the raster")
    return zc


def _bed(f, rf, path, geom, bed, geometry, terrain):
    """Bed per cell (SI) and a sentence saying where it comes from."""
    if bed not in ("auto", "min_water_surface"):
        raise FlowFileError(f"{path}: option bed = {bed!r}: must be 'auto' or "
                            "'min_water_surface'")
    if bed == "min_water_surface":
        out = []
        for name, nreal in zip(geom.areas, geom.n_real, strict=True):
            ds = rf[f"{_SERIES}/2D Flow Areas/{name}/Water Surface"]
            low = np.full(nreal, np.inf)
            for k in range(ds.shape[0]):  # one output time at a time (bounded memory)
                try:
                    np.minimum(low, ds[k, :nreal], out=low)
                except OSError as exc:
                    raise FlowFileError(f"{rf.filename}: cannot read {ds.name!r}: the file is "
                                        f"truncated or damaged ({exc})") from None
            key = f"{_SUMMARY}/{name}/Minimum Water Surface"
            if key in f:
                np.minimum(low, read_dataset(f, key, path)[0, :nreal], out=low)
            out.append(low * geom.length_factor)
        return np.concatenate(out), ("bed = 'min_water_surface': the lowest water surface the "
                                     "plan reports per cell (summary Minimum Water Surface and "
                                     "every output time): the bed where a cell went dry, above "
                                     "it elsewhere")
    keys = [f"{AREAS}/{n}/Cells Minimum Elevation" for n in geom.areas]
    if all(k in f for k in keys):
        z = np.concatenate([read_dataset(f, k, path)[:n]
                            for k, n in zip(keys, geom.n_real, strict=True)])
        return z.astype(np.float64) * geom.length_factor, "Cells Minimum Elevation (plan)"
    if geometry is not None:
        return (_bed_from_geometry_file(geometry, geom, path),
                f"Cells Minimum Elevation of {geometry}")
    if terrain is not None:
        return _bed_from_terrain(terrain, geom, path), f"lowest pixel of {terrain} in each cell"
    missing = [n for n, k in zip(geom.areas, keys, strict=True) if k not in f]
    raise FlowFileError(f"{path}: no bed: the areas {missing} have no 'Cells Minimum "
                        "Elevation'; name its source with the option geometry = \"<the plan's "
                        "geometry .gNN.hdf>\" or terrain = \"<terrain raster>\" (or, knowingly, "
                        "bed = \"min_water_surface\")")


def _results_file(f, path, results):
    if results is not None:
        rf = open_h5(results, "results file")
        if _SERIES + "/2D Flow Areas" not in rf:
            rf.close()
            raise FlowFileError(f"{results}: no HEC-RAS 2D time series (no {_SERIES!r}/2D Flow "
                                "Areas)")
        return rf, Path(results)
    if _SERIES + "/2D Flow Areas" not in f:
        ftype = "a geometry file" if "Results" not in f else "a plan without 2D time series"
        raise FlowFileError(f"{path}: no 2D results: {ftype} (no {_SERIES!r}/2D Flow Areas); "
                            "give the plan's output (*.pNN.hdf) or name the file holding the "
                            "time series with the option results = \"...\"")
    return f, Path(path)


def open_hecras(path, time_range=None, variables=None, dry_depth=1e-3, areas=None, bed="auto",
                geometry=None, terrain=None, results=None):
    """Open a HEC-RAS 2D plan output as a MeshFlowField (snapshots read lazily).

    Parameters
    ----------
    path : path
        HEC-RAS plan HDF (``*.pNN.hdf``) with 2D flow areas.
    time_range : (start, end), optional
        Only the snapshots in [start, end] (s since the first output time).
    variables : dict, optional
        Not used (HEC-RAS names its datasets itself); must be empty.
    dry_depth : float
        Depth (m) below which a face is dry.
    areas, bed, geometry, terrain, results
        See ``OPTIONS``.

    Returns
    -------
    MeshFlowField
        Times in seconds since the first output time; ``attrs`` holds ``time_reference``,
        ``crs_wkt``, the areas read and the bed's source.
    """
    from driftlog.flow import MeshFlowField

    from ._common import select_times

    if variables:
        raise FlowFileError(f"{path}: [flow] variables do not apply to HEC-RAS files (the "
                            f"reader knows its dataset names), got {sorted(variables)}")
    path = Path(path)
    f = open_h5(path)
    rf = None
    try:
        geom = read_geometry(path, areas, f=f)
        rf, rpath = _results_file(f, path, results)
        for name in geom.areas:
            base = f"{_SERIES}/2D Flow Areas/{name}"
            for ds in ("Water Surface", "Face Velocity"):
                if f"{base}/{ds}" not in rf:
                    raise FlowFileError(f"{rpath}: area {name!r} has no {ds!r} time series "
                                        f"(looked for {base + '/' + ds!r})")
        times, epoch = read_time_axis(rf, rpath)
        nt = rf[f"{_SERIES}/2D Flow Areas/{geom.areas[0]}/Water Surface"].shape[0]
        if nt != times.size:
            raise FlowFileError(f"{rpath}: {nt} water-surface snapshots for {times.size} times")
        bed_cells, bed_source = _bed(f, rf, path, geom, bed, geometry, terrain)
        idx = select_times(times, time_range, str(rpath))
        name = f"HEC-RAS {path.name}"
        src = HecrasSnapshots(rf, rpath, geom, bed_cells, times[idx], idx, name)
        attrs = dict(geom.attrs, source="hecras", hecras_bed=bed_source,
                     hecras_results=str(rpath), hecras_split_cells=geom.n_split)
        if epoch is not None:
            attrs["time_reference"] = f"seconds since {epoch}"
        if "Plan Data/Plan Information" in f:
            plan = f["Plan Data/Plan Information"].attrs.get("Plan Name")
            if plan is not None:
                attrs["hecras_plan"] = as_text(plan)
        if rf is not f:
            f.close()
        return MeshFlowField(geom.mesh, bed_cells[geom.cell_of_face], src, dry_depth, name=name,
                             attrs=attrs)
    except BaseException:
        if rf is not None and rf is not f:
            rf.close()
        if f.id.valid:
            f.close()
        raise


open = open_hecras  # the reader contract's name (module-level: ``hecras.open(path)``)


def describe(path) -> list[str]:
    """A few lines on a HEC-RAS file for ``driftlog info``."""
    path = Path(path)
    f = open_h5(path)
    with f:
        names, counts = area_table(f, path)
        check_projection(f, path)
        factor, system = units(f, path)
        lines = [f"HEC-RAS file ({as_text(f.attrs.get('File Version', b'?'))}), {system}"]
        for n, c in zip(names, counts, strict=True):
            has_bed = f"{AREAS}/{n}/Cells Minimum Elevation" in f
            lines.append(f"  2D area {n!r}: {c} cells" + ("" if has_bed else " (no bed)"))
        if _SERIES + "/2D Flow Areas" in f:
            t, epoch = read_time_axis(f, path)
            lines.append(f"  time series: {t.size} outputs over {t[-1] - t[0]:g} s"
                         + (f" from {epoch}" if epoch else ""))
        else:
            lines.append("  no 2D time series (geometry only)")
        return lines
