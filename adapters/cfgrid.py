"""CF NetCDF regular grids (rasters) as driftlog flows: LISFLOOD-FP, HEC-RAS exports, ...

A grid has 1-D coordinates ``x``, ``y`` (cell centres, uniform spacing, projected metres;
either direction) and fields on (time, y, x), or (y, x) for one steady snapshot:
depth or water level (with a bed), and velocities or unit discharges.  Staggered fields as
LISFLOOD-FP writes them, ``Qx`` / ``Vx`` on the nx + 1 cell edges along x and ``Qy`` / ``Vy``
on the ny + 1 edges along y, are averaged to the cells (Q in m3/s is divided by the edge
length to give a unit discharge).  The raster becomes a ``GridFlowField``: sampled
bilinearly between the cell centres (``driftlog.gridflow``), on ``Mesh.regular_grid`` (face
``j * nx + i`` is cell (row j, column i), rows from south to north).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError
from driftlog.flow import check_times
from driftlog.gridflow import GridFlowField
from driftlog.schema import Key

from ._common import (
    SubsetSnapshots,
    geographic_attribute,
    geographic_error,
    select_times,
    unit_factor,
)
from ._netcdf import (
    ROLES,
    NetCDFSource,
    find_roles,
    netcdf_matches,
    open_dataset,
    read_times,
    time_attrs,
    variable_attrs,
)

__all__ = ["open_cf_grid", "is_cf_grid", "GridSnapshots"]

_X = ("x", "X", "easting", "x_c", "xc", "lon", "longitude")
_Y = ("y", "Y", "northing", "y_c", "yc", "lat", "latitude")


def _axis(ds, which):
    names = _X if which == "x" else _Y
    std = f"projection_{which}_coordinate"
    cands = []
    for name, var in ds.variables.items():
        if var.ndim != 1 or name not in ds.dimensions:
            continue
        if (getattr(var, "axis", "").upper() == which.upper()
                or getattr(var, "standard_name", "") in (std, "longitude" if which == "x"
                                                         else "latitude")
                or name in names):
            cands.append(name)
    return cands[0] if cands else None


def is_cf_grid(ds) -> bool:
    """Whether an open NetCDF dataset has 1-D x and y coordinates (a regular grid)."""
    return _axis(ds, "x") is not None and _axis(ds, "y") is not None


def _uniform(c, name, path):
    d = np.diff(c)
    if c.size < 2:
        raise FlowFileError(f"{path}: coordinate {name!r} has {c.size} value(s); a grid needs 2+")
    if not (np.all(d > 0) or np.all(d < 0)):
        raise FlowFileError(f"{path}: coordinate {name!r} is not monotonic")
    if np.max(np.abs(np.abs(d) - abs(d[0]))) > 1e-6 * abs(d[0]):
        raise FlowFileError(f"{path}: unknown layout: coordinate {name!r} is not evenly spaced "
                            f"(spacings from {np.abs(d).min():g} to {np.abs(d).max():g}); "
                            "driftlog reads regular grids")
    return float(abs(d[0])), bool(d[0] < 0)


class GridSnapshots(NetCDFSource):
    """Lazy snapshots of a CF grid: ``read(i)`` reads time i of each field.

    ``spec``: role -> (variable, unit factor, stagger None | 'x' | 'y', divisor).
    """

    def __init__(self, ds, path, times, spec, bed, flip, has_time, fill="error"):
        super().__init__(ds, path, times, spec, bed, fill)
        self.flip, self.has_time = flip, has_time

    def _get(self, role, i):
        """One variable at snapshot i on the cells, in SI units, as a face array."""
        name, factor, stagger, scale = self.spec[role]
        var = self.ds.variables[name]
        arr = np.asarray(var[i] if self.has_time and var.ndim == 3 else var[:], np.float64)
        arr = self._values(var, i, arr) * factor
        if stagger == "x":
            arr = 0.5 * (arr[:, :-1] + arr[:, 1:])
        elif stagger == "y":
            arr = 0.5 * (arr[:-1, :] + arr[1:, :])
        arr = arr / scale
        if self.flip[0]:
            arr = arr[::-1, :]
        if self.flip[1]:
            arr = arr[:, ::-1]
        return arr.ravel()

    field = _get


def open_cf_grid(path, time_range=None, variables=None, dry_depth=1e-3, fill="error",
                 units=None, layout="auto"):
    """Open a CF regular-grid NetCDF file as a GridFlowField (snapshots read lazily).

    Parameters
    ----------
    variables : dict, optional
        driftlog name (depth, level, bed, u, v, hu, hv) -> variable name.
    fill : 'error' or 'dry'
        Fill values / NaN (cells outside the flood extent): an error, or dry cells.
    units : dict, optional
        Units for variables without a units attribute, e.g. ``{"hu": "m3 s-1"}``.
    layout : 'auto', 'cell' or 'node'
        Values at the cell centres (auto: CF coordinates are) or at the cell corners.
    """
    path = Path(path)
    ds = open_dataset(path)
    try:
        return _open(ds, path, time_range, variables or {}, dry_depth, fill, units or {},
                     layout)
    except BaseException:
        ds.close()
        raise


def _open(ds, path, time_range, mapping, dry_depth, fill, units_override, layout="auto"):
    xn, yn = _axis(ds, "x"), _axis(ds, "y")
    if xn is None or yn is None:
        raise FlowFileError(f"{path}: unknown layout: no 1-D x and y coordinate variables "
                            "(axis = 'X' / 'Y' or standard_name projection_x_coordinate)")
    for n in (xn, yn):
        var = ds.variables[n]
        geo = geographic_attribute(n, {k: var.getncattr(k) for k in var.ncattrs()})
        if geo is None and n in ("lon", "longitude", "lat", "latitude"):
            geo = ("coordinate name", n)
        if geo is not None:
            raise geographic_error(path, *geo)
    x = np.asarray(ds.variables[xn][:], np.float64)
    y = np.asarray(ds.variables[yn][:], np.float64)
    notes = []
    fx, _ = unit_factor(getattr(ds.variables[xn], "units", None), "length", f"{path}: {xn}",
                        notes)
    fy, _ = unit_factor(getattr(ds.variables[yn], "units", None), "length", f"{path}: {yn}",
                        notes)
    x, y = x * fx, y * fy
    dx, flip_x = _uniform(x, xn, path)
    dy, flip_y = _uniform(y, yn, path)
    nx, ny = x.size, y.size
    # the time dimension: that of 3-D variables ending in (y, x)
    tdims = {v.dimensions[0] for v in ds.variables.values()
             if v.ndim == 3 and v.dimensions[1:] == (yn, xn)}
    has_time = bool(tdims)
    tdim = sorted(tdims)[0] if tdims else None
    lead = (tdim,) if has_time else ()
    centred = variable_attrs(ds, lead + (yn, xn))
    stag_x, stag_y = {}, {}
    for name, var in ds.variables.items():
        d = var.dimensions
        if len(d) == len(lead) + 2 and d[:len(lead)] == lead and name not in centred:
            ysz, xsz = var.shape[-2:]
            if (ysz, xsz) == (ny, nx + 1):
                stag_x[name] = variable_attrs(ds)[name]
            elif (ysz, xsz) == (ny + 1, nx):
                stag_y[name] = variable_attrs(ds)[name]
    allvars = dict(centred)
    allvars.update(stag_x)
    allvars.update(stag_y)
    for role, name in mapping.items():
        if role != "bed" and name in ds.variables and name not in allvars:
            var = ds.variables[name]
            raise FlowFileError(f"{path}: {name!r} (given for {role!r}) has shape {var.shape}; "
                                f"the grid is {ny} x {nx} (y, x) with {nx + 1} / {ny + 1} "
                                "edges for staggered fields")
    if not centred and not stag_x:
        raise FlowFileError(f"{path}: unknown layout: no variable on "
                            f"{lead + (yn, xn)}")
    roles = find_roles(allvars, mapping, str(path), need_bed=True)
    for role in ("depth", "level"):
        if role in roles and roles[role] not in centred:
            raise FlowFileError(f"{path}: {roles[role]!r} ({role}) is not on the cells "
                                f"({ny} x {nx})")
    spec = {}
    for role, name in roles.items():
        kind = ROLES[role][0]
        u = units_override.get(role, getattr(ds.variables[name], "units", None))
        stagger = "x" if name in stag_x else "y" if name in stag_y else None
        if kind == "unit_discharge" and stagger and u is None:
            raise FlowFileError(f"{path}: {name!r} has no units: say whether it is a discharge "
                                "through each edge (m3 s-1) or per unit width (m2 s-1) with "
                                f"units = {{{role} = \"m3 s-1\"}}")
        f, got = unit_factor(u, kind, f"{path}: {name}", notes)
        scale = 1.0
        if got == "discharge":  # m3/s through an edge -> per unit width
            if not stagger:
                raise FlowFileError(f"{path}: {name!r} is a discharge ({u}) on cells; driftlog "
                                    "needs unit discharges (m2 s-1) or edge discharges")
            scale = dy if role == "hu" else dx
            notes.append(f"{name}: edge discharge divided by the edge length {scale:g} m")
        if stagger:
            notes.append(f"{name}: staggered on {stagger} edges, averaged to cells")
        spec[role] = (name, f, stagger, scale)
    times = np.zeros(1)
    origin = None
    if has_time:
        times, origin = read_times(ds, path, tdim)
        check_times(times, str(path))
    else:
        notes.append("no time dimension: one steady snapshot")
    bed = None
    bed_name = _find_bed(ds, yn, xn, lead, mapping, path)
    src = GridSnapshots(ds, path, times, spec, None, (flip_y, flip_x), has_time, fill)
    if bed_name is not None:
        var = ds.variables[bed_name]
        u = units_override.get("bed", getattr(var, "units", None))
        f, _ = unit_factor(u, "length", f"{path}: {bed_name}", notes)
        src.spec["bed"] = (bed_name, f, None, 1.0)
        bed = src.field("bed", 0)
        notes.append(f"bed from {bed_name}")
    elif "depth" in spec and _has_level(allvars, mapping, str(path)):
        lvl = _has_level(allvars, mapping, str(path))
        var = ds.variables[lvl]
        f, _ = unit_factor(getattr(var, "units", None), "length", f"{path}: {lvl}", notes)
        src.spec["level"] = (lvl, f, None, 1.0)
        bed = src.field("level", 0) - src.field("depth", 0)
        notes.append(f"bed from {lvl} - {spec['depth'][0]} at the first time")
    else:
        raise FlowFileError(f"{path}: no bed elevation (a (y, x) variable with standard_name "
                            f"'altitude' or names like {ROLES['bed'][2][:4]}); map it with "
                            "[flow] variables = {bed = \"NAME\"}")
    bed = _fill_bed(bed, ny, nx, path, notes)
    src.bed = bed
    layout = "cell" if layout in (None, "auto") else layout
    if layout == "node":  # the values are at the corners of the cells: the domain ends there
        if nx < 2 or ny < 2:
            raise FlowFileError(f"{path}: layout = 'node' needs 2 or more points each way, "
                                f"the grid has {ny} x {nx}")
        x0, y0 = min(x[0], x[-1]), min(y[0], y[-1])
        src.location = "node"
        notes.append("node layout: values at the cell corners, the domain is their hull")
    else:
        x0 = min(x[0], x[-1]) - dx / 2
        y0 = min(y[0], y[-1]) - dy / 2
    idx = select_times(times, time_range, str(path))
    source = SubsetSnapshots(src, idx) if idx.size != times.size else src
    attrs = {"source": "cf_grid" + (f" ({ds.source})" if hasattr(ds, "source") else ""),
             "source_path": str(path.resolve()), "time_origin": origin or "",
             "variables": ", ".join(f"{k}={v[0]}" for k, v in spec.items()),
             "import_notes": "; ".join(notes), "grid_shape": f"{ny} {nx}"}
    if has_time:
        attrs.update(time_attrs(ds, path, tdim, origin))
    return GridFlowField(nx, ny, dx, dy, x0, y0, bed, source, dry_depth=dry_depth,
                         name=str(path), attrs=attrs, layout=layout)


def _fill_bed(bed, ny, nx, path, notes):
    """Bed cells at fill values (land read with fill = 'dry') take the nearest valid bed.

    Those cells are dry; a NaN bed there would make the water level, and so the free-surface
    slope the full model uses, NaN in the cells around them.
    """
    bad = ~np.isfinite(bed)
    if not bad.any():
        return bed
    if bad.all():
        raise FlowFileError(f"{path}: the bed is a fill value / NaN everywhere")
    from scipy.ndimage import distance_transform_edt

    grid = bed.reshape(ny, nx)
    idx = distance_transform_edt(bad.reshape(ny, nx), return_distances=False,
                                 return_indices=True)
    notes.append(f"{int(bad.sum())} bed cells at fill values: dry, with the nearest valid bed")
    return grid[tuple(idx)].ravel()


def _find_bed(ds, yn, xn, lead, mapping, path):
    from ._common import find_variable

    static = variable_attrs(ds, (yn, xn))
    timed = variable_attrs(ds, lead + (yn, xn)) if lead else {}
    _, std, alias = ROLES["bed"]
    if "bed" in mapping:
        name = mapping["bed"]
        if name not in ds.variables:
            raise FlowFileError(f"{path}: variable {name!r} (given for 'bed') is missing")
        if name not in static and name not in timed:
            raise FlowFileError(f"{path}: bed {name!r} has shape {ds.variables[name].shape}, "
                                f"not the grid's")
        return name
    name = find_variable(static, alias, "bed", {}, std, str(path), required=False)
    if name is None and timed:
        name = find_variable(timed, alias, "bed", {}, std, str(path), required=False)
    return name


def _has_level(allvars, mapping, where):
    from ._common import find_variable

    _, std, alias = ROLES["level"]
    return find_variable(allvars, alias, "level", mapping, std, where, required=False)


# --------------------------------------------------------------------- the reader contract
KIND = "cf_grid"
SUFFIXES = (".nc",)
OPTIONS = [
    Key("fill", "str", "error", "fill values / NaN (cells outside the flood extent): an error, "
        "or dry cells", choices=("error", "dry")),
    Key("units", "table", None, "units for variables without a units attribute "
        "({hu = 'm3 s-1'})"),
    Key("layout", "str", "auto", "where the values sit: at the cell centres (the cells extend "
        "half a cell beyond the outermost values), or at the cell corners (the domain ends at "
        "the outermost values); auto: the centres (CF coordinates)",
        choices=("auto", "cell", "node")),
]


def can_open(path) -> bool:
    """Whether ``path`` is a NetCDF file with 1-D x and y coordinates (a regular grid)."""
    return netcdf_matches(path, is_cf_grid)


def open(path, *, time_range=None, variables=None, dry_depth=1e-3, **options):
    """``open_cf_grid`` under the reader contract (``options``: ``OPTIONS``)."""
    return open_cf_grid(path, time_range=time_range, variables=variables, dry_depth=dry_depth,
                        **options)
