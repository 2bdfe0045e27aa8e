"""Raster series as driftlog flows: LISFLOOD-FP ASCII results and GeoTIFF series (rioxarray).

Both give one raster per quantity and output time on one regular grid; they become a
``GridFlowField`` (``driftlog.gridflow``: bilinear between the cell centres, linear in time).
Rasters are read with ``rioxarray`` (GDAL: ESRI ASCII grids, GeoTIFF, anything GDAL reads).

LISFLOOD-FP
    ``path``: the run's parameter file (``.par``: ``DEMfile``, ``resroot``, ``dirroot``,
    ``saveint``) or the run folder holding it, or a results directory / one result file with the
    options ``dem`` and ``interval``. Snapshot k is ``<resroot>-<kkkk>.wd`` (water depth, m),
    ``.Vx`` and ``.Vy`` (velocity, m/s) at t = k ``saveint``. LISFLOOD computes velocities on
    the cell faces: ``.Vx`` on the ncols + 1 faces of each row and ``.Vy`` on the nrows + 1
    faces of each column; each cell gets the mean of its two faces (a velocity raster the size
    of the DEM is taken as cell values). LISFLOOD's rows run from north to south and its ``Vy``
    is positive in that direction (southward: ``vy_positive = "south"``, the default; say
    ``"north"`` for a file written the other way). DEM cells at nodata are outside the model:
    dry, with the nearest valid bed elevation (so the water level has no cliff there).
GeoTIFF series
    ``path``: a directory (or a file in it).  The rasters of each quantity are found by a file
    pattern with one ``*`` standing for the time: ``depth_*.tif`` (or a water ``level``),
    ``u_*.tif`` and ``v_*.tif`` (or ``hu`` / ``hv`` unit discharges), and a static bed
    ``dem.tif`` / ``bed.tif``; ``[flow] variables = {depth = "wd_*.tif", bed = "terrain.tif"}``
    names other patterns.  The ``*`` part of each name is the time in ``time_units`` (seconds
    by default).  Velocities are cell values, north positive (GeoTIFF y is a map coordinate).
    A raster whose AREA_OR_POINT is Point holds values at points: they are taken as the
    corners of the cells (``layout = "node"``: the domain ends at the outermost values).

A raster whose CRS is geographic (EPSG:4326...: cells in degrees) is refused: driftlog needs
projected coordinates in metres.  So is a raster whose projected CRS has another unit (a
State Plane in US survey feet, EPSG:2272...): its coordinates could be converted, but a
raster does not say the units of its values (depths and velocities in ft and ft/s, or m and
m/s?), and the reader has no option to say them: reproject the rasters to a CRS in metres.
A raster without a CRS (an ASCII grid without .prj) is taken as metres.

Nodata (the raster's nodata value, or NaN): with ``fill = "dry"`` (the default for rasters,
whose nodata marks cells outside the flood extent or the model) a dry cell (depth 0, velocity
0); with ``fill = "error"`` an error naming the file and the cells.  Depths below
-1 mm are refused (``driftlog.adapters._netcdf.NEGATIVE_DEPTH_TOLERANCE``), as in every reader.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError
from driftlog.flow import check_times
from driftlog.gridflow import GridFlowField
from driftlog.schema import Key

from ._common import SubsetSnapshots, crs_length_unit, geographic_error, select_times
from ._netcdf import NEGATIVE_DEPTH_TOLERANCE

__all__ = ["KIND", "SUFFIXES", "OPTIONS", "can_open", "open", "open_raster_series",
           "read_lisflood_par", "RasterSnapshots"]

KIND = "raster"
SUFFIXES = (".par", ".wd", ".asc", ".tif", ".tiff")
OPTIONS = [
    Key("dem", "path", None, "LISFLOOD-FP: the DEM (ESRI ASCII or any raster) when the path is "
        "not a .par file"),
    Key("interval", "float", None, "LISFLOOD-FP: the time between result files (the .par "
        "file's saveint) when the path is not a .par file", units="s", min=0.0,
        exclusive_min=True),
    Key("fill", "str", "dry", "nodata / NaN cells: dry cells, or an error",
        choices=("dry", "error")),
    Key("vy_positive", "str", "south", "LISFLOOD-FP: the direction of positive Vy "
        "(LISFLOOD's rows run north to south)", choices=("south", "north")),
    Key("time_units", "str", "s", "GeoTIFF series: units of the time in the file names",
        choices=("s", "min", "h", "d")),
    Key("layout", "str", "auto", "where the values sit: the cell centres (pixel is area), or "
        "the cell corners (pixel is point: the domain ends at the outermost values); auto: "
        "the rasters' AREA_OR_POINT", choices=("auto", "cell", "node")),
]

_TIME_FACTOR = {"s": 1.0, "min": 60.0, "h": 3600.0, "d": 86400.0}
_GEOTIFF_DEFAULTS = {"depth": ("depth_*.tif", "h_*.tif", "wd_*.tif"),
                     "level": ("level_*.tif", "wse_*.tif", "elev_*.tif"),
                     "u": ("u_*.tif", "vx_*.tif"), "v": ("v_*.tif", "vy_*.tif"),
                     "hu": ("hu_*.tif", "qx_*.tif"), "hv": ("hv_*.tif", "qy_*.tif"),
                     "bed": ("dem.tif", "bed.tif", "dem.asc", "elevation.tif")}
_LISFLOOD_RESULT = re.compile(r"^(?P<root>.+)-(?P<k>\d{4,})\.(?P<ext>wd|Vx|Vy)$")


# --------------------------------------------------------------------- raster reading
def _read(path, what="raster"):
    """(array float64 (rows, cols) as stored, nodata value or None, geometry dict)."""
    import rasterio

    with rasterio.Env():  # GDAL's messages (a file cut short...) to logging, not to stderr
        return _read_raster(path, what)


def _read_raster(path, what):
    import rioxarray

    path = Path(path)
    if not path.is_file():
        raise FlowFileError(f"{path}: {what} not found")
    try:
        da = rioxarray.open_rasterio(path, masked=False)
    except Exception as exc:  # rasterio raises many kinds
        raise FlowFileError(f"{path}: not a raster GDAL can read ({type(exc).__name__}: "
                            f"{exc})") from None
    with da:
        if da.sizes.get("band", 1) != 1:
            raise FlowFileError(f"{path}: {da.sizes['band']} bands; driftlog reads one raster "
                                "per quantity and time (one band)")
        try:
            arr = np.asarray(da.values[0] if "band" in da.dims else da.values, np.float64)
        except Exception as exc:  # noqa: BLE001 - a file cut short: GDAL's read errors
            raise FlowFileError(f"{path}: a {what} whose values cannot be read: truncated or "
                                "damaged (an interrupted copy or download?) "
                                f"({exc.__cause__ or exc})") from None
        x = np.asarray(da.x.values, np.float64)
        y = np.asarray(da.y.values, np.float64)
        nodata = da.rio.nodata
        rcrs = da.rio.crs
        crs, geographic = "", False
        try:
            crs = rcrs.to_string() if rcrs is not None else ""
            geographic = rcrs is not None and bool(rcrs.is_geographic)
        except Exception:  # noqa: BLE001 - an odd CRS is not a reason to refuse the data
            pass
        if geographic:  # EPSG:4326...: cells in degrees
            raise geographic_error(path, "CRS", crs)
        unit = crs_length_unit(rcrs)
        if unit is not None and abs(unit[1] - 1.0) > 1e-12:  # a State Plane in feet...
            raise _length_unit_error(path, crs, *unit)
        point = str(da.attrs.get("AREA_OR_POINT", "Area"))
    if x.size > 1 and not np.allclose(np.diff(x), x[1] - x[0], rtol=1e-6):
        raise FlowFileError(f"{path}: the columns are not evenly spaced (a rotated or warped "
                            "raster); driftlog reads north-up regular rasters")
    dx = abs(x[1] - x[0]) if x.size > 1 else None
    dy = abs(y[1] - y[0]) if y.size > 1 else None
    geo = dict(x=x, y=y, dx=dx, dy=dy, crs=crs, point=point)
    return arr, (None if nodata is None else float(nodata)), geo


def _length_unit_error(path, crs, unit, factor):
    """The error refusing a raster whose projected CRS is not in metres (feet, km...).

    The coordinates could be converted, but a raster says nothing of the units of its values:
    depths and velocities next to a CRS in feet may be in ft and ft/s (a US model's export) or
    in m and m/s, and reading them wrong moves the logs by the wrong distance.
    """
    text = " ".join(str(crs).split())
    shown = text if len(text) <= 80 else text[:77] + "..."
    return FlowFileError(f"{path}: CRS = {shown!r}: the coordinates are in {unit} "
                         f"({factor:.10g} m), not metres, and a raster does not say the units "
                         "of its values (depths, velocities: feet too?); driftlog needs "
                         "projected coordinates in metres: reproject the rasters to a CRS in "
                         "metres (e.g. gdalwarp -t_srs with the UTM zone), with depths in m "
                         "and velocities in m/s, then read those")


def _bad(arr, nodata):
    bad = ~np.isfinite(arr)
    if nodata is not None:
        bad |= arr == nodata
    return bad


class RasterSnapshots:
    """Lazy snapshots of a raster series: ``read(i)`` reads the rasters of time i.

    ``files``: role -> list of paths (one per time); ``stagger``: role -> None, 'x' or 'y';
    ``sign``: role -> factor (LISFLOOD's southward Vy); arrays are turned to rows from the
    south (``flip``) and flattened x fastest, as ``GridFlowField`` wants them.
    """

    location = "face"

    def __init__(self, name, times, files, stagger, sign, flip, shape, bed, fill, outside):
        self.name, self.times, self.files = name, np.asarray(times, np.float64), files
        self.stagger, self.sign, self.flip, self.shape = stagger, sign, flip, shape
        self.bed, self.fill, self.outside = bed, fill, outside

    def _get(self, role, i):
        path = self.files[role][i]
        arr, nodata, _ = _read(path)
        ny, nx = self.shape
        want = {None: (ny, nx), "x": (ny, nx + 1), "y": (ny + 1, nx)}[self.stagger[role]]
        if arr.shape != want:
            raise FlowFileError(f"{path}: {arr.shape[0]} rows x {arr.shape[1]} columns; the "
                                f"grid is {ny} x {nx}, so {role} needs {want[0]} x {want[1]}")
        bad = _bad(arr, nodata)
        if bad.any():
            if self.fill == "error":
                r, c = np.argwhere(bad)[0]
                raise FlowFileError(f"{path}: {int(bad.sum())} nodata / NaN cells (first at "
                                    f"row {r}, column {c}); set [flow.options] fill = 'dry' "
                                    "to take them as dry cells")
            arr = np.where(bad, np.nan, arr)
        if self.stagger[role] == "x":  # faces along x -> cells; a missing face counts 0
            f = np.where(np.isnan(arr), 0.0, arr)
            arr = 0.5 * (f[:, :-1] + f[:, 1:])
        elif self.stagger[role] == "y":
            f = np.where(np.isnan(arr), 0.0, arr)
            arr = 0.5 * (f[:-1, :] + f[1:, :])
        arr = arr * self.sign.get(role, 1.0)
        if self.flip:
            arr = arr[::-1, :]
        return arr.ravel()

    def read(self, i):
        """Cell arrays (h, hu, hv) of snapshot i, rows from the south."""
        h = self._get("depth", i) if "depth" in self.files else self._get("level", i) - self.bed
        dry = ~np.isfinite(h) | self.outside
        h = np.where(dry, 0.0, h)
        k = int(np.argmin(h))
        if h[k] < -NEGATIVE_DEPTH_TOLERANCE:
            src = self.files["depth" if "depth" in self.files else "level"][i]
            raise FlowFileError(f"{src}: negative water depth {h[k]:g} m at snapshot {i} "
                                f"(t = {self.times[i]:g} s), cell {k} (row {k // self.shape[1]}"
                                f" from the south, column {k % self.shape[1]}); a depth must "
                                f"be >= 0 (down to -{NEGATIVE_DEPTH_TOLERANCE:g} m is "
                                "round-off, clipped to 0)")
        h = np.maximum(h, 0.0)
        if "hu" in self.files:
            hu, hv = self._get("hu", i), self._get("hv", i)
        else:
            hu, hv = h * self._get("u", i), h * self._get("v", i)
        ok = ~dry
        return (h, np.where(ok & np.isfinite(hu), hu, 0.0), np.where(ok & np.isfinite(hv), hv, 0.0))

    def close(self):
        """Nothing is kept open (each raster is read when asked for)."""


# --------------------------------------------------------------------- LISFLOOD-FP
def read_lisflood_par(path):
    """The keys of a LISFLOOD-FP parameter file (``key value`` lines, '#' comments)."""
    out = {}
    try:
        text = Path(path).read_text(errors="replace")
    except OSError as exc:
        raise FlowFileError(f"{path}: cannot read the parameter file ({exc})") from None
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split(None, 1)
        out[parts[0].lower()] = parts[1].strip() if len(parts) > 1 else ""
    return out


def _lisflood_files(folder, resroot=None):
    """{k: {ext: path}} of the LISFLOOD result files in a folder (one resroot)."""
    found = {}
    roots = set()
    for p in Path(folder).iterdir():
        m = _LISFLOOD_RESULT.match(p.name)
        if m and (resroot is None or m["root"] == resroot):
            roots.add(m["root"])
            found.setdefault(m["root"], {}).setdefault(int(m["k"]), {})[m["ext"]] = p
    if not roots:
        return None, {}
    if len(roots) > 1:
        raise FlowFileError(f"{folder}: results of several runs ({sorted(roots)}); open the "
                            "run's .par file or one of its result files")
    root = roots.pop()
    return root, found[root]


def _open_lisflood(path, options, notes):
    path = Path(path)
    if path.is_dir() and not any(_LISFLOOD_RESULT.match(q.name) for q in path.iterdir()):
        path = _run_par(path)  # a run folder: its parameter file
    interval = options.get("interval")
    dem = options.get("dem")
    resroot = None
    if path.suffix.lower() == ".par":
        par = read_lisflood_par(path)
        base = path.parent
        if "demfile" not in par:
            raise FlowFileError(f"{path}: no DEMfile in the parameter file")
        dem = dem or base / par["demfile"]
        resroot = par.get("resroot", "res")
        folder = base / par.get("dirroot", "results")
        if interval is None:
            if "saveint" not in par:
                raise FlowFileError(f"{path}: no saveint in the parameter file: give "
                                    "[flow.options] interval (s)")
            try:
                interval = float(par["saveint"])
            except ValueError:
                raise FlowFileError(f"{path}: saveint = {par['saveint']!r} is not a number") \
                    from None
        notes.append(f"LISFLOOD-FP run {path.name}: saveint {interval:g} s")
    else:
        folder = path if path.is_dir() else path.parent
        if not path.is_dir():
            m = _LISFLOOD_RESULT.match(path.name)
            resroot = m["root"] if m else None
    root, files = _lisflood_files(folder, resroot)
    if not files:
        raise FlowFileError(f"{folder}: no LISFLOOD-FP result files "
                            f"({resroot or '<resroot>'}-NNNN.wd, .Vx, .Vy)")
    if dem is None:
        raise FlowFileError(f"{path}: LISFLOOD-FP results need the DEM: open the run's .par "
                            "file, or give [flow.options] dem = \"PATH\"")
    if interval is None:
        raise FlowFileError(f"{path}: LISFLOOD-FP results need the time between them: open "
                            "the run's .par file, or give [flow.options] interval = SECONDS "
                            "(saveint)")
    ks = sorted(k for k, f in files.items() if "wd" in f)
    for k in ks:
        missing = [e for e in ("Vx", "Vy") if e not in files[k]]
        if missing:
            raise FlowFileError(f"{folder}: {root}-{k:04d}.wd has no {' nor '.join(missing)} "
                                "file: run LISFLOOD-FP with velocity output (voutput)")
    if not ks:
        raise FlowFileError(f"{folder}: no {root}-NNNN.wd depth files")
    times = np.array(ks, np.float64) * float(interval)
    bed, nodata, geo = _read(dem, "DEM")
    ny, nx = bed.shape
    probe = {e: _read(files[ks[0]][e])[0].shape for e in ("Vx", "Vy")}
    stagger = {"depth": None}
    for e, role, st, face_shape in (("Vx", "u", "x", (ny, nx + 1)), ("Vy", "v", "y",
                                                                      (ny + 1, nx))):
        if probe[e] == face_shape:
            stagger[role] = st
            notes.append(f".{e} on cell faces, the mean of each cell's two faces")
        elif probe[e] == (ny, nx):
            stagger[role] = None
            notes.append(f".{e} on cells (the DEM's size)")
        else:
            raise FlowFileError(f"{files[ks[0]][e]}: {probe[e][0]} x {probe[e][1]}; the DEM is "
                                f"{ny} x {nx}, so .{e} must be {face_shape[0]} x "
                                f"{face_shape[1]} (faces) or {ny} x {nx} (cells)")
    sign = {"v": -1.0 if options.get("vy_positive", "south") == "south" else 1.0}
    roles = {"depth": [files[k]["wd"] for k in ks], "u": [files[k]["Vx"] for k in ks],
             "v": [files[k]["Vy"] for k in ks]}
    notes.append(f"{len(ks)} result files {root}-NNNN (t = NNNN x {float(interval):g} s); "
                 f"Vy positive {options.get('vy_positive', 'south')}")
    return roles, stagger, sign, times, (bed, nodata, geo, Path(dem)), folder


# --------------------------------------------------------------------- GeoTIFF series
def _series(folder, pattern, role):
    """(times, paths) of the files matching ``pattern`` (one '*': the time)."""
    if pattern.count("*") != 1:
        raise FlowFileError(f"{folder}: the pattern {pattern!r} for {role} needs exactly one "
                            "'*' (the time in the file names)")
    head, tail = pattern.split("*")
    rx = re.compile(re.escape(head) + r"(?P<t>[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"
                    + re.escape(tail) + "$")
    got = []
    for p in Path(folder).glob(pattern):
        m = rx.match(p.name)
        if m:
            got.append((float(m["t"]), p))
    got.sort()
    return np.array([t for t, _ in got]), [p for _, p in got]


def _open_geotiff(path, options, variables, notes):
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    pats = {}
    for role, cands in _GEOTIFF_DEFAULTS.items():
        if role in variables:
            pats[role] = [variables[role]]
        else:
            pats[role] = list(cands)
    found = {}
    for role, cands in pats.items():
        for pat in cands:
            if role == "bed":
                if (folder / pat).is_file():
                    found[role] = folder / pat
                    break
                continue
            t, files = _series(folder, pat, role)
            if files:
                found[role] = (t, files, pat)
                break
        if role in variables and role not in found:
            raise FlowFileError(f"{folder}: no file matches {variables[role]!r} (given for "
                                f"{role!r})")
    water = "depth" if "depth" in found else "level" if "level" in found else None
    if water is None:
        raise FlowFileError(f"{folder}: no depth nor water level rasters (looked for "
                            f"{pats['depth'] + pats['level']}); name them with [flow] "
                            "variables = {depth = \"PATTERN_*.tif\"}")
    vel = ("u", "v") if "u" in found and "v" in found else (
        ("hu", "hv") if "hu" in found and "hv" in found else None)
    if vel is None:
        raise FlowFileError(f"{folder}: no velocity (u, v) nor unit discharge (hu, hv) rasters "
                            f"(looked for {pats['u']} / {pats['v']}); name them with [flow] "
                            "variables = {u = \"...\", v = \"...\"}")
    if "bed" not in found:
        raise FlowFileError(f"{folder}: no bed raster (looked for {pats['bed']}); name it with "
                            "[flow] variables = {bed = \"FILE.tif\"}")
    times = found[water][0]
    for role in vel:
        t = found[role][0]
        if t.size != times.size or not np.allclose(t, times):
            raise FlowFileError(f"{folder}: the {role} rasters ({found[role][2]!r}: "
                                f"{t.size} times) and the {water} rasters "
                                f"({found[water][2]!r}: {times.size} times) are not at the "
                                "same times")
    factor = _TIME_FACTOR[options.get("time_units", "s")]
    roles = {r: found[r][1] for r in (water, *vel)}
    notes.append(f"GeoTIFF series: {', '.join(f'{r}={found[r][2]}' for r in roles)}, "
                 f"bed={found['bed'].name}; times from the file names in "
                 f"{options.get('time_units', 's')}")
    bed, nodata, geo = _read(found["bed"], "bed raster")
    return roles, {r: None for r in roles}, {}, times * factor, \
        (bed, nodata, geo, found["bed"]), folder


# --------------------------------------------------------------------- the reader
def _run_par(folder):
    """The one LISFLOOD-FP parameter file (with a DEMfile) of a run folder, or None."""
    pars = [q for q in Path(folder).glob("*.par") if "demfile" in read_lisflood_par(q)]
    return pars[0] if len(pars) == 1 else None


def _is_lisflood(path):
    p = Path(path)
    if p.suffix.lower() == ".par":
        return "demfile" in read_lisflood_par(p)
    if p.is_dir():
        return (any(_LISFLOOD_RESULT.match(q.name) for q in p.iterdir())
                or _run_par(p) is not None)
    return bool(_LISFLOOD_RESULT.match(p.name))


def open_raster_series(path, time_range=None, variables=None, dry_depth=1e-3, **options):
    """Open a LISFLOOD-FP run or a GeoTIFF series as a ``GridFlowField`` (read lazily).

    Parameters
    ----------
    path : path
        LISFLOOD-FP: the .par file, or a results directory / result file (with ``dem`` and
        ``interval``); GeoTIFF: the directory of the series, or a file in it.
    time_range : (start, end), optional
        Only the snapshots in [start, end] (s).
    variables : dict, optional
        GeoTIFF: driftlog name (depth, level, u, v, hu, hv, bed) -> file pattern.
    dry_depth : float
        Depth below which a cell is dry (m).
    **options
        ``OPTIONS``: dem, interval, fill, vy_positive, time_units.
    """
    path = Path(path)
    if not path.exists():
        raise FlowFileError(f"{path}: file or directory not found")
    variables = dict(variables or {})
    notes = []
    lisflood = _is_lisflood(path)
    if lisflood:
        if variables:
            raise FlowFileError(f"{path}: [flow] variables do not apply to LISFLOOD-FP results "
                                "(.wd, .Vx, .Vy)")
        roles, stagger, sign, times, dem, folder = _open_lisflood(path, options, notes)
    else:
        roles, stagger, sign, times, dem, folder = _open_geotiff(path, options, variables,
                                                                 notes)
    check_times(times, str(path))
    bed, nodata, geo, dem_path = dem
    ny, nx = bed.shape
    if nx < 2 or ny < 2:
        raise FlowFileError(f"{dem_path}: {ny} x {nx} cells; a grid needs 2 or more each way")
    dx, dy = geo["dx"], geo["dy"]
    if abs(dx - dy) > 1e-6 * dx:
        notes.append(f"cells of {dx:g} x {dy:g} m")
    flip = geo["y"][0] > geo["y"][-1]  # rows from the north: turn them
    layout = options.get("layout", "auto")
    if layout in (None, "auto"):
        layout = "node" if geo["point"].lower() == "point" else "cell"
        if layout == "node":
            notes.append("AREA_OR_POINT = Point: values at the cell corners (node layout)")
    outside = _bad(bed, nodata)
    if outside.all():
        raise FlowFileError(f"{dem_path}: every cell is nodata")
    if outside.any():
        from scipy.ndimage import distance_transform_edt

        idx = distance_transform_edt(outside, return_distances=False, return_indices=True)
        bed = bed[tuple(idx)]
        notes.append(f"{int(outside.sum())} nodata DEM cells: outside the model, dry (bed "
                     "from the nearest valid cell)")
    if flip:
        bed, outside = bed[::-1, :], outside[::-1, :]
    for role, paths in roles.items():  # the rasters must lie on the bed's grid
        if stagger.get(role) is None:
            _, _, g = _read(paths[0])
            if (g["x"].size, g["y"].size) == (nx, ny) and not (
                    np.allclose(g["x"], geo["x"], atol=1e-6 * dx, rtol=0)
                    and np.allclose(g["y"], geo["y"], atol=1e-6 * dy, rtol=0)):
                raise FlowFileError(f"{paths[0]}: not on the grid of {dem_path.name} (cell "
                                    f"centres from ({g['x'][0]:g}, {g['y'][0]:g}), the bed's "
                                    f"from ({geo['x'][0]:g}, {geo['y'][0]:g}))")
    shift = 0.0 if layout == "node" else 0.5
    x0 = float(geo["x"].min()) - shift * dx
    y0 = float(geo["y"].min()) - shift * dy
    src = RasterSnapshots(str(path), times, roles, stagger, sign, flip, (ny, nx), bed.ravel(),
                          options.get("fill", "dry"), outside.ravel())
    src.location = "node" if layout == "node" else "face"
    idx = select_times(times, time_range, str(path))
    source = SubsetSnapshots(src, idx) if idx.size != times.size else src
    attrs = {"source": "lisflood-fp" if lisflood else "geotiff series",
             "source_path": str(path.resolve()), "import_notes": "; ".join(notes),
             "grid_shape": f"{ny} {nx}", "crs": geo["crs"]}
    return GridFlowField(nx, ny, dx, dy, x0, y0, bed.ravel(), source, dry_depth=dry_depth,
                         name=str(path), attrs=attrs, layout=layout)


def can_open(path) -> bool:
    """Whether ``path`` is a LISFLOOD-FP run (.par, results) or a GeoTIFF series (never raises)."""
    try:
        p = Path(path)
        if not p.exists():
            return False
        if _is_lisflood(p):
            return True
        folder = p if p.is_dir() else p.parent
        if p.is_file() and p.suffix.lower() not in (".tif", ".tiff"):
            return False
        return any(_series(folder, pat, "depth")[1] or _series(folder, lp, "level")[1]
                   for pat, lp in zip(_GEOTIFF_DEFAULTS["depth"], _GEOTIFF_DEFAULTS["level"],
                                      strict=True))
    except Exception:  # noqa: BLE001 - a sniff never raises
        return False


def open(path, *, time_range=None, variables=None, dry_depth=1e-3, **options):
    """``open_raster_series`` under the reader contract (``options``: ``OPTIONS``)."""
    return open_raster_series(path, time_range=time_range, variables=variables,
                              dry_depth=dry_depth, **options)


def describe(path) -> list[str]:
    """A few lines for ``driftlog info``."""
    f = open_raster_series(path)
    nx, ny, x0, y0, dx, dy = f.grid
    return [f"{f.attrs['source']}: {ny} x {nx} cells of {dx:g} x {dy:g} m from ({x0:g}, {y0:g})"
            f"{', CRS ' + f.attrs['crs'] if f.attrs.get('crs') else ''}",
            f"{f.times.size} snapshots from {f.times[0]:g} to {f.times[-1]:g} s",
            *(f"note: {n}" for n in f.attrs["import_notes"].split("; ") if n)]
