"""MIKE 21 FM (DHI) ``.dfsu`` results as driftlog flows, read with ``mikeio``.

Read with mikeio's engine, ``mikecore`` (header, mesh and items in one pass; each step from
the file kept open), item types and units as mikeio's ``EUMType`` / ``EUMUnit``; written
(``write``, ``driftlog export``) with mikeio's ``Dataset.to_dfs`` and ``Dfsu.append``.

A 2D horizontal dfsu file holds a flexible mesh of triangles and quadrilaterals (mixed), node
coordinates with the bathymetry Z at the nodes, and per time step one value per element of
each item.  MIKE 21 FM is a cell-centred finite-volume model: element values are face values
for driftlog (``location = "face"``), sampled as every face-located flow is.

Items are found by their EUM type first (language independent), then by their usual names:
Total water depth (Water_Depth), Surface elevation (Surface_Elevation), U velocity and
V velocity (u/v_velocity_component), or P flux and Q flux (m3/s/m) for unit discharges.
Depth is Total water depth, or Surface elevation minus the element bathymetry.  The bed is the
element bathymetry: Surface elevation - Total water depth of the first step when the file has
both (the engine's own element value, to float32), else the mean of the element's node Z
(as mikeio's element coordinates).  Units are converted from the items' EUM units (meter, feet,
US feet, cm, mm; m/s, ft/s, cm/s...) with a note; any other unit is an error.  An element
holding MIKE's delete value (or NaN) in any item of a step has no data there: it is read as
dry (depth and discharge 0) for that step.

Times are seconds since the first time step, kept as the reference epoch
(``attrs["time_reference"]``); the projection string is kept in ``attrs["projection"]``.
Geographic coordinates (projection 'LONG/LAT', or a WKT that is a GEOGCS) are refused:
driftlog needs projected metres.  Node x, y are in the projection's unit: a WKT projected in
another unit (a State Plane in US survey feet...) is converted to metres with a note, and the
WKT is then kept as ``attrs["crs_wkt"]`` with ``attrs["crs_note"]`` giving the factor (not as
``projection``, which ``write`` would put back on the metre coordinates); MIKE's own names
('UTM-32', 'NON-UTM') are metres.  Node Z is in the file's Z unit (meter, feet; undefined:
metres), converted the same way.
3D (layered), vertical-profile and spectral dfsu files are refused with a clear error.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField, check_times

from ._common import (
    SubsetSnapshots,
    crs_length_unit,
    geographic_error,
    reference_epoch,
    refuse_geographic_wkt,
    select_times,
)

__all__ = ["KIND", "SUFFIXES", "OPTIONS", "can_open", "open", "describe", "open_dfsu",
           "DfsuSnapshots", "ROLES", "write"]

KIND = "dfsu"
SUFFIXES = (".dfsu",)
OPTIONS = []  # no options of its own

MAGIC = b"DHI_DFS_"
#: role -> (EUM type names, item names, units kind)
ROLES = {
    "depth": (("Water_Depth", "Total_Water_Depth"), ("Total water depth", "Water depth"),
              "length"),
    "level": (("Surface_Elevation",), ("Surface elevation", "Water level"), "length"),
    "u": (("u_velocity_component",), ("U velocity", "U-velocity"), "velocity"),
    "v": (("v_velocity_component",), ("V velocity", "V-velocity"), "velocity"),
    "hu": ((), ("P flux", "P-flux"), "unit_discharge"),
    "hv": ((), ("Q flux", "Q-flux"), "unit_discharge"),
    "bed": (("Bathymetry",), ("Bathymetry", "Bed level"), "length"),
}
_FT, _USFT = 0.3048, 1200.0 / 3937.0
UNITS = {
    "length": {"meter": 1.0, "centimeter": 0.01, "millimeter": 1e-3, "kilometer": 1e3,
               "feet": _FT, "feet_US": _USFT, "millifeet": 1e-3 * _FT},
    "velocity": {"meter_per_sec": 1.0, "feet_per_sec": _FT, "feet_US_per_sec": _USFT,
                 "cm_per_sec": 0.01, "mm_per_sec": 1e-3},
    "unit_discharge": {"meter_pow_3_per_sec_per_meter": 1.0, "meter_pow_2_per_sec": 1.0,
                       "square_meter_per_sec": 1.0, "feet_pow_3_per_sec_per_feet": _FT ** 2,
                       "feet_pow_2_per_sec": _FT ** 2, "square_feet_per_sec": _FT ** 2,
                       "feet_US_pow_3_per_sec_per_feet_US": _USFT ** 2},
}


def can_open(path) -> bool:
    """Whether ``path`` is a dfsu file (DHI DFS header with a dfsu data type; never raises)."""
    try:
        with Path(path).open("rb") as f:
            if f.read(len(MAGIC)) != MAGIC:
                return False
        from mikecore.DfsFileFactory import DfsFileFactory

        dfs = DfsFileFactory.DfsGenericOpen(str(path))
        try:
            return 2001 <= int(dfs.FileInfo.DataType) <= 2099
        finally:
            dfs.Close()
    except Exception:
        return False


class _Header:
    """What the reader needs from a dfsu file, read in one pass with mikecore (mikeio's engine).

    ``mikeio.Dfsu`` would do, but it opens the file three times and builds its own geometry
    objects: 10 s and 0.6 GB more at 1e6 elements.  Item types and units are mikeio's
    ``EUMType`` / ``EUMUnit``; times a pandas DatetimeIndex, as mikeio gives them.
    """

    def __init__(self, path):
        import mikeio
        import pandas as pd
        from mikecore.DfsFile import TimeAxisType
        from mikecore.DfsuFile import DfsuFile, DfsuFileType

        f = DfsuFile.Open(str(path))
        try:
            self.kind = DfsuFileType(f.DfsuFileType).name  # Dfsu2D, Dfsu3DSigma...
            self.n_layers = int(f.NumberOfLayers or 0)
            self.x = np.asarray(f.X, dtype=np.float64)
            self.y = np.asarray(f.Y, dtype=np.float64)
            self.z = np.asarray(f.Z, dtype=np.float64)
            self.z_unit = _eum(mikeio.EUMUnit, int(f.ZUnit))  # meter, feet or undefined
            self.element_table = f.ElementTable  # node numbers from 1
            self.n_elements, self.n_nodes = int(f.NumberOfElements), int(f.NumberOfNodes)
            self.items = [_Item(it.Name, _eum(mikeio.EUMType, it.Quantity.Item),
                                _eum(mikeio.EUMUnit, it.Quantity.Unit)) for it in f.ItemInfo]
            self.n_timesteps = int(f.NumberOfTimeSteps)
            axis = f.FileInfo.TimeAxis
            start = pd.Timestamp(axis.StartDateTime)
            if axis.TimeAxisType == TimeAxisType.CalendarEquidistant:
                self.time = start + pd.to_timedelta(np.arange(self.n_timesteps)
                                                    * f.TimeStepInSeconds, unit="s")
            else:  # non-equidistant: each step carries its time (seconds from the start)
                f.Reset()
                secs = [f.ReadItemTimeStep(1, k).Time for k in range(self.n_timesteps)]
                self.time = start + pd.to_timedelta(np.asarray(secs, np.float64), unit="s")
            self.projection = str(f.Projection.WKTString or "")
        finally:
            f.Close()


class _Item:
    def __init__(self, name, type_, unit):
        self.name, self.type, self.unit = name, type_, unit


def _eum(enum, value):
    """A mikeio EUM enum member, or a stand-in named 'undefined_<value>' for unknown codes."""
    try:
        return enum(value)
    except ValueError:
        return _Item(f"undefined_{value}", None, None)


def _open_dfsu(path):
    with Path(path).open("rb") as f:
        magic = f.read(len(MAGIC))
    if magic != MAGIC:
        raise FlowFileError(f"{path}: not a dfsu file (it does not start with the DHI DFS "
                            f"header {MAGIC.decode()!r})")
    if not can_open(path):
        raise FlowFileError(f"{path}: a DHI DFS file but not a dfsu (a dfs0, dfs1, dfs2 or "
                            "dfs3?): driftlog reads MIKE 21 FM flexible-mesh .dfsu results")
    try:
        dfs = _Header(path)
    except Exception as exc:
        raise FlowFileError(f"{path}: unreadable dfsu file ({type(exc).__name__}: {exc}); "
                            "a truncated or corrupted file?") from None
    # MIKE's name for geographic coordinates (mikeio's ``geometry.is_geo``), or a WKT GEOGCS
    if dfs.projection.strip().upper() == "LONG/LAT":
        raise geographic_error(path, "projection", dfs.projection)
    refuse_geographic_wkt(dfs.projection, path, "projection")
    return dfs


def _find(items, role, mapping, path, required=True):
    """Index of the item playing ``role``: the user's mapping, else EUM type, else name."""
    names = [it.name for it in items]
    if role in mapping:
        want = str(mapping[role]).strip().lower()
        for k, n in enumerate(names):
            if n.strip().lower() == want:
                return k
        raise FlowFileError(f"{path}: item {mapping[role]!r} (given for {role!r} in [flow] "
                            f"variables) is not in the file; it has {', '.join(names)}")
    types, cands, _ = ROLES[role]
    for k, it in enumerate(items):
        if it.type.name in types:
            return k
    low = [n.strip().lower() for n in names]
    for c in cands:
        if c.lower() in low:
            return low.index(c.lower())
    if required:
        raise FlowFileError(f"{path}: no {role} item: expected {cands[0]!r} (EUM type "
                            f"{types[0] if types else 'any'}); the file has "
                            f"{', '.join(names)}; map another with [flow] variables = "
                            f"{{{role} = \"NAME\"}}")
    return None


def _factor(item, role, path, notes):
    kind = ROLES[role][2]
    unit = item.unit.name
    table = UNITS[kind]
    if unit not in table:
        raise FlowFileError(f"{path}: item {item.name!r} ({role}) has units {unit!r}, not "
                            f"units of {kind.replace('_', ' ')} (expected one of "
                            f"{', '.join(table)})")
    f = table[unit]
    if f != 1.0:
        notes.append(f"{item.name}: converted from {unit} to SI (x {f:g})")
    return f


def _z_factor(dfs, path, notes):
    """Metres per unit of the node Z (the file's Z unit; undefined: metres, as MIKE's default)."""
    unit = dfs.z_unit.name
    if unit == "undefined":
        return 1.0
    table = UNITS["length"]
    if unit not in table:
        raise FlowFileError(f"{path}: the node Z unit is {unit!r}, not a unit of length "
                            f"(expected one of {', '.join(table)})")
    f = table[unit]
    if f != 1.0:
        notes.append(f"node Z: converted from {unit} to m (x {f:g})")
    return f


class DfsuSnapshots:
    """Lazy element snapshots of a dfsu file: one time step read per ``read(i)``."""

    location = "face"

    def __init__(self, dfs, path, times, roles, factors, bed, dry_depth):
        self.path, self.times = Path(path), times
        self.n_elements = int(dfs.n_elements)
        self.roles, self.factors, self.bed = roles, factors, bed
        self.dry_depth = dry_depth
        self.name = str(path)
        self._file = None
        self.deleted = None  # elements with MIKE's delete value in the last step read

    def _items(self, i, roles):
        """Item arrays of step i, read with mikecore (mikeio's engine) from a file kept open.

        Not ``Dfsu.read``: it rebuilds the mesh geometry at every call.
        """
        try:
            if self._file is None:
                from mikecore.DfsFileFactory import DfsFileFactory

                self._file = DfsFileFactory.DfsGenericOpen(str(self.path))
            out = []
            dv = np.float32(self._file.FileInfo.DeleteValueFloat)
            self.deleted = None
            for r in roles:
                data = self._file.ReadItemTimeStep(self.roles[r] + 1, int(i)).Data
                gone = (data == dv) | ~np.isfinite(data)
                if gone.any():
                    self.deleted = gone if self.deleted is None else self.deleted | gone
                out.append(np.where(gone, 0.0, np.asarray(data, dtype=np.float64))
                           * self.factors[r])
        except Exception as exc:
            raise FlowFileError(f"{self.path}: time step {i} unreadable "
                                f"({type(exc).__name__}: {exc}); a truncated file?") from None
        n = self.n_elements
        for r, a in zip(roles, out, strict=True):
            if a.shape != (n,):
                raise FlowFileError(f"{self.path}: time step {i}: item {r} has {a.size} values "
                                    f"for {n} elements; a truncated file?")
        return out

    def read(self, i):
        """Element arrays (h, hu, hv) of time step i."""
        r = self.roles
        vel = ("u", "v") if "u" in r else ("hu", "hv")
        if "depth" in r:
            h, a, b = self._items(i, ("depth", *vel))
        else:
            eta, a, b = self._items(i, ("level", *vel))
            h = np.where(self.deleted if self.deleted is not None else False, 0.0,
                         eta - self.bed)
        if self.deleted is not None:  # MIKE's delete value: no data there, read as dry
            h = np.where(self.deleted, 0.0, h)
            a = np.where(self.deleted, 0.0, a)
            b = np.where(self.deleted, 0.0, b)
        if h.size and h.min() < 0:
            if h.min() <= -self.dry_depth:
                bad = np.flatnonzero(h <= -self.dry_depth)
                raise FlowFileError(f"{self.path}: time step {i}: {bad.size} elements with "
                                    f"depth below -dry_depth (min {h.min():g} m, first at "
                                    f"{bad[:5].tolist()}); depths must be >= 0")
            h = np.maximum(h, 0.0)
        if "u" in r:
            return h, h * a, h * b
        return h, a, b

    def close(self):
        """Close the file."""
        if self._file is not None:
            self._file.Close()
            self._file = None


def open(path, *, time_range=None, variables=None, dry_depth=1e-3):
    """Open a MIKE 21 FM 2D dfsu result file as a MeshFlowField (steps read lazily).

    Parameters
    ----------
    path : path
        The .dfsu file (2D horizontal).
    time_range : (start, end), optional
        Only the steps in [start, end] (s since the first step).
    variables : dict, optional
        driftlog role (depth, level, bed, u, v, hu, hv) -> the file's item name.
    dry_depth : float
        Depth below which an element is dry (m).
    """
    path = Path(path)
    if not path.is_file():
        raise FlowFileError(f"{path}: file not found")
    dfs = _open_dfsu(path)
    return _open(dfs, path, time_range, dict(variables or {}), float(dry_depth))


open_dfsu = open


def _open(dfs, path, time_range, mapping, dry_depth):
    unknown = set(mapping) - set(ROLES)
    if unknown:
        raise FlowFileError(f"{path}: [flow] variables {sorted(unknown)} are not roles of a "
                            f"dfsu file (allowed: {', '.join(ROLES)})")
    if dfs.kind != "Dfsu2D":
        layers = dfs.n_layers
        raise FlowFileError(f"{path}: a {dfs.kind} file"
                            + (f" ({layers} layers)" if layers else "")
                            + "; driftlog reads 2D horizontal (MIKE 21 FM) dfsu results: "
                            "extract a depth-averaged 2D result with MIKE's own tools")
    table = dfs.element_table
    lens = np.fromiter((len(e) for e in table), np.int64, len(table))
    nmax = int(lens.max())
    if nmax > 4 or lens.min() < 3:
        raise FlowFileError(f"{path}: elements with {lens.min()} to {nmax} nodes; dfsu 2D "
                            "meshes are triangles and quadrilaterals")
    flat = np.concatenate(table).astype(np.int64) - 1  # mikecore numbers nodes from 1
    starts = np.cumsum(lens) - lens
    fn = np.full((lens.size, nmax), -1, dtype=np.int64)
    fn[np.repeat(np.arange(lens.size), lens), np.arange(flat.size) - np.repeat(starts, lens)] = flat
    notes = []
    unit = crs_length_unit(dfs.projection)  # node x, y are in the projection's unit
    fxy = 1.0 if unit is None or abs(unit[1] - 1.0) <= 1e-12 else unit[1]
    if fxy != 1.0:
        notes.append(f"node x, y: converted from the projection's {unit[0]} to m "
                     f"(x {fxy:.10g})")
    fz = _z_factor(dfs, path, notes)
    try:
        from driftlog.mesh import Mesh

        mesh = Mesh(dfs.x * fxy, dfs.y * fxy, fn, node_z=dfs.z * fz)
    except MeshError as exc:
        raise FlowFileError(f"{path}: the elements do not make a valid mesh: {exc}") from None
    if mesh.n_reversed:
        notes.append(f"{mesh.n_reversed} clockwise elements reversed")
    n_t = int(dfs.n_timesteps)
    if n_t == 0:
        raise FlowFileError(f"{path}: no time step (a mesh file without results)")
    items = dfs.items
    roles, factors = {}, {}

    def need(role, required=True):
        k = _find(items, role, mapping, path, required)
        if k is not None:
            roles[role] = k
            factors[role] = _factor(items[k], role, path, notes)
        return k

    have_h = need("depth", required=False)
    have_s = need("level", required=False)
    if have_h is None and have_s is None:
        raise FlowFileError(f"{path}: no depth: expected item 'Total water depth' or "
                            f"'Surface elevation'; the file has "
                            f"{', '.join(it.name for it in items)}")
    if need("u", required=False) is not None:
        need("v")
    elif need("hu", required=False) is not None:
        need("hv")
    else:
        raise FlowFileError(f"{path}: no velocity: expected items 'U velocity' and "
                            "'V velocity' (or 'P flux' and 'Q flux'); the file has "
                            f"{', '.join(it.name for it in items)}")
    time = dfs.time
    t0 = time[0]
    times = np.asarray((time - t0).total_seconds(), dtype=np.float64)
    check_times(times, str(path))
    src = DfsuSnapshots(dfs, path, times, roles, factors, None, dry_depth)
    geo_bed = mesh.face_bed()
    if have_h is not None and have_s is not None:
        eta, h = src._items(0, ("level", "depth"))
        bed = eta - h
        if src.deleted is not None:  # no data there at the first step: the node Z mean
            bed = np.where(src.deleted, geo_bed, bed)
        notes.append("bed = Surface elevation - Total water depth of the first step (the "
                     "engine's element bathymetry; it differs from the mean of the node Z by "
                     f"{np.abs(bed - geo_bed).max():.3g} m at most)")
    else:
        bed = geo_bed
        notes.append("bed = mean of the element's node Z")
    src.bed = bed
    idx = select_times(times, time_range, str(path))
    source = SubsetSnapshots(src, idx) if idx.size != times.size else src
    attrs = {"source": "mike21 fm dfsu", "source_path": str(path.resolve()),
             "data_location": "face",
             "time_reference": "seconds since " + t0.strftime("%Y-%m-%d %H:%M:%S"),
             "import_notes": "; ".join(notes)}
    if dfs.projection and fxy != 1.0:  # not a projection of the (metre) coordinates any more
        attrs["crs_wkt"] = dfs.projection
        attrs["crs_note"] = f"x, y are the projection's coordinates x {fxy:.10g} (metres)"
    elif dfs.projection:
        attrs["projection"] = dfs.projection
    return MeshFlowField(mesh, bed, source, dry_depth=dry_depth, name=str(path), attrs=attrs)


def describe(path) -> list[str]:
    """A few lines on a dfsu file for ``driftlog info`` (header only)."""
    path = Path(path)
    dfs = _open_dfsu(path)
    n = np.bincount(np.fromiter((len(e) for e in dfs.element_table), np.int64,
                                len(dfs.element_table)), minlength=7)
    shape = (f"{n[3]} triangles, {n[4]} quadrilaterals" if dfs.kind == "Dfsu2D" else
             f"{dfs.n_layers} layers")
    lines = [f"{path}: MIKE dfsu ({dfs.kind}), projection {dfs.projection[:40] or '?'}",
             f"  mesh: {dfs.n_nodes} nodes, {dfs.n_elements} elements ({shape}; data on "
             "elements)"]
    unit = crs_length_unit(dfs.projection)
    if unit is not None and abs(unit[1] - 1.0) > 1e-12:
        lines.append(f"  coordinates: in {unit[0]}, read in metres (x {unit[1]:.10g})")
    if dfs.n_timesteps:
        lines.append(f"  times: {dfs.n_timesteps} steps, {dfs.time[0]} to {dfs.time[-1]}")
    else:
        lines.append("  times: none (no result step)")
    lines.append("  items: " + ", ".join(f"{it.name} [{it.unit.name}]" for it in dfs.items))
    return lines


# --------------------------------------------------------------------- writing
def write(field, path, chunk=8, projection=None):
    """Write a mesh flow as a MIKE 21 FM dfsu file with mikeio (element values).

    Items Surface elevation, Total water depth, U velocity and V velocity on the faces (the
    field's face values: for a node-located flow, the means of each face's node values);
    node Z is the bed at the nodes (least-squares fits of the face bed).  Times are the
    field's ``time_reference`` epoch (2000-01-01 without one) plus its times.  Written
    ``chunk`` steps at a time (``Dataset.to_dfs``, then ``Dfsu.append``), so memory stays
    bounded.  dfsu stores float32.
    """
    import mikeio
    import pandas as pd

    mesh = field.mesh
    times = np.asarray(field.times, dtype=np.float64)
    epoch = reference_epoch(field.attrs, str(path)) or np.datetime64("2000-01-01T00:00:00",
                                                                      "us")
    stamps = pd.DatetimeIndex(epoch + np.round(times * 1e6).astype(np.int64)
                              .astype("timedelta64[us]"))
    if field.location == "node":
        zn = field.node_bed
    else:
        zn = mesh.node_operators()[0] @ field.bed
    proj = projection or field.attrs.get("projection") or "NON-UTM"
    table = [row[:k] for row, k in zip(mesh.face_nodes, mesh.face_n, strict=True)]
    geometry = mikeio.spatial.GeometryFM2D(
        node_coordinates=np.column_stack([mesh.node_x, mesh.node_y, zn]),
        element_table=table, projection=proj)
    E, U = mikeio.EUMType, mikeio.EUMUnit
    items = [mikeio.ItemInfo("Surface elevation", E.Surface_Elevation, U.meter),
             mikeio.ItemInfo("Total water depth", E.Water_Depth, U.meter),
             mikeio.ItemInfo("U velocity", E.u_velocity_component, U.meter_per_sec),
             mikeio.ItemInfo("V velocity", E.v_velocity_component, U.meter_per_sec)]
    path = Path(path)
    dfs = None
    for start in range(0, times.size, chunk):
        idx = range(start, min(start + chunk, times.size))
        snaps = [field.snapshot(i) for i in idx]
        cols = [np.array([sn[k] for sn in snaps], dtype=np.float32)
                for k in ("eta", "h", "u", "v")]
        t = stamps[start:start + len(idx)]
        ds = mikeio.Dataset([mikeio.DataArray(c, time=t, geometry=geometry, item=it)
                             for c, it in zip(cols, items, strict=True)])
        if start == 0:
            ds.to_dfs(str(path))
            dfs = mikeio.Dfsu(str(path))
            geometry = dfs.geometry  # the file's own (as stored), for the appended steps
        else:
            dfs.append(ds)
    return path
