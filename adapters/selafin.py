"""TELEMAC-2D Selafin (Serafin) results as driftlog flows, read with ``xarray-selafin``.

A Selafin file holds a mesh of triangles (or quadrilaterals) given by its nodes, and per time
frame one value per node of each variable, named in English or French (16 characters, with
16 characters of units): WATER DEPTH / HAUTEUR D'EAU (H), VELOCITY U / VITESSE U (U),
VELOCITY V / VITESSE V (V), BOTTOM / FOND (B), FREE SURFACE / SURFACE LIBRE (S),
FLOWRATE ALONG X / DEBIT SUIVANT X (I), FLOWRATE ALONG Y / DEBIT SUIVANT Y (J).

The data stay on the nodes: the field's source says ``location = "node"``, so the sampler
interpolates them P1 on their own nodes (``driftlog.flow``), without the face-and-back
averaging of face-located data.  Depth is WATER DEPTH, or FREE SURFACE - BOTTOM; velocity
is VELOCITY U, V, or the flow rates divided by the depth; the bed is BOTTOM (or FREE SURFACE -
WATER DEPTH) of the first frame.  When the bed evolves (morphodynamics), depths stay exact
and the free surface uses the first frame's bed (a note gives the largest change).  Depths
in (-dry_depth, 0), which TELEMAC's treatment of negative depths leaves on dry nodes, are
read as 0; a lower depth is an error.

Times are the file's seconds; when the header has a date (``params[9] == 1``) it is the
reference epoch (``attrs["time_reference"] = "seconds since ..."``).

3D files (TELEMAC-3D, ``nb_planes > 0``) are refused unless ``depth_average = true``: then
depth = Z(top plane) - Z(bottom plane) and the velocity is the trapezoidal depth average
(1/H) sum_k (U_k + U_k+1)/2 (Z_k+1 - Z_k) over the planes of each vertical (ELEVATION Z /
COTE Z needed), the bed the bottom plane's Z of the first frame.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField, check_times
from driftlog.schema import Key

from ._common import SubsetSnapshots, reference_epoch, select_times, unit_factor

__all__ = ["KIND", "SUFFIXES", "OPTIONS", "can_open", "open", "describe",
           "open_selafin", "SelafinSnapshots", "ROLES", "write", "triangles"]

KIND = "selafin"
SUFFIXES = (".slf", ".srf", ".sel", ".res", ".selafin")
OPTIONS = [
    Key("depth_average", "bool", False, "read a TELEMAC-3D file as its depth average "
        "(trapezoidal over the planes in ELEVATION Z); false: a 3D file is refused"),
]

#: role -> (English name, French name, variable id); units kind
ROLES = {
    "depth": (("WATER DEPTH", "HAUTEUR D'EAU", "H"), "length"),
    "u": (("VELOCITY U", "VITESSE U", "U"), "velocity"),
    "v": (("VELOCITY V", "VITESSE V", "V"), "velocity"),
    "bed": (("BOTTOM", "FOND", "B"), "length"),
    "level": (("FREE SURFACE", "SURFACE LIBRE", "S"), "length"),
    "hu": (("FLOWRATE ALONG X", "DEBIT SUIVANT X", "I"), "unit_discharge"),
    "hv": (("FLOWRATE ALONG Y", "DEBIT SUIVANT Y", "J"), "unit_discharge"),
    "z": (("ELEVATION Z", "COTE Z", "Z"), "length"),
}


def can_open(path) -> bool:
    """Whether ``path`` starts like a Selafin file (never raises).

    The header is Fortran unformatted: a record of 80 bytes (the title, ending with
    SERAFIN or SERAFIND), then a record of two integers (the numbers of variables), in either
    byte order.
    """
    try:
        with Path(path).open("rb") as f:
            head = f.read(104)
    except OSError:
        return False
    if len(head) < 104:
        return False
    for e in (">", "<"):
        if (struct.unpack(e + "i", head[:4])[0] == 80
                and struct.unpack(e + "i", head[84:88])[0] == 80
                and struct.unpack(e + "i", head[88:92])[0] == 8
                and struct.unpack(e + "i", head[100:104])[0] == 8):
            return True
    return False


def _open_dataset(path):
    import xarray as xr
    import xarray_selafin.xarray_backend  # noqa: F401  (registers the engine and accessor)

    if not can_open(path):
        raise FlowFileError(f"{path}: not a Selafin file (its first bytes are not the "
                            "80-byte title record and the 2-integer record of a TELEMAC "
                            "Serafin header)")
    try:
        return xr.open_dataset(path, engine="selafin")
    except Exception as exc:  # the library's own errors (truncated records, sizes)
        raise FlowFileError(f"{path}: unreadable Selafin file ({type(exc).__name__}: {exc}); "
                            "a truncated or corrupted file?") from None


def _variables(ds):
    """{variable id: (name, units)} of an open Selafin dataset."""
    return {vid: (str(n).strip(), str(u).strip()) for vid, (n, u) in
            ds.attrs.get("variables", {}).items()}


def _find(ds, role, mapping, path, required=True):
    """Variable id playing ``role``.

    The user's mapping (a name or an id) first, else the English, French or id name.
    """
    names = _variables(ds)
    by_name = {n.upper(): vid for vid, (n, _) in names.items()}
    if role in mapping:
        want = str(mapping[role]).strip()
        if want in names:
            return want
        if want.upper() in by_name:
            return by_name[want.upper()]
        raise FlowFileError(f"{path}: variable {want!r} (given for {role!r} in [flow] "
                            f"variables) is not in the file; it has "
                            f"{', '.join(n for n, _ in names.values())}")
    english, french, vid = ROLES[role][0]
    for n in (english, french):
        if n in by_name:
            return by_name[n]
    if vid in names and names[vid][0].upper() in (english, french):
        return vid
    if required:
        raise FlowFileError(f"{path}: no {role} variable: expected {english!r} (or "
                            f"{french!r}); the file has "
                            f"{', '.join(n for n, _ in names.values())}; map another with "
                            f"[flow] variables = {{{role} = \"NAME\"}}")
    return None


def _factor(ds, vid, role, path, notes):
    name, units = _variables(ds)[vid]
    kind = ROLES[role][1]
    where = f"{path}: variable {name!r} ({role})"
    f, got = unit_factor(units, kind, where, notes)
    if got != kind:
        raise FlowFileError(f"{where}: units {units!r} are {got.replace('_', ' ')}, expected "
                            f"{kind.replace('_', ' ')}")
    return f


class SelafinSnapshots:
    """Lazy node snapshots of a Selafin file: one frame read per ``read(i)``.

    ``read(i)`` returns node arrays (h, hu, hv) (``location = "node"``).
    """

    location = "node"

    def __init__(self, ds, path, times, roles, factors, dry_depth, plan_average=False):
        self.ds, self.path, self.times = ds, Path(path), times
        self.roles, self.factors = roles, factors
        self.dry_depth = dry_depth
        self.plan_average = plan_average
        self.name = str(path)

    def _get(self, role, i):
        vid = self.roles[role]
        try:
            # the Variable, not the DataArray: no coordinate indexes built (0.05 against
            # 0.15 ms a frame on 24,000 nodes)
            arr = np.asarray(self.ds.variables[vid].isel(time=i).values, dtype=np.float64)
        except Exception as exc:
            raise FlowFileError(f"{self.path}: frame {i} of {self._label(role)} unreadable "
                                f"({type(exc).__name__}: {exc})") from None
        return arr * self.factors[role]

    def _label(self, role):
        return _variables(self.ds)[self.roles[role]][0]

    def read(self, i):
        """Node arrays (h, hu, hv) of frame i."""
        if self.plan_average:
            return self._read_3d(i)
        r = self.roles
        if "depth" in r:
            h = self._get("depth", i)
        else:
            h = self._get("level", i) - self._get("bed", i)
        h = self._clip(h, i)
        if "u" in r:
            u, v = self._get("u", i), self._get("v", i)
            return h, h * u, h * v
        return h, self._get("hu", i), self._get("hv", i)

    def _clip(self, h, i):
        if h.size and h.min() < 0:
            low = h.min()
            if low <= -self.dry_depth:
                bad = np.flatnonzero(h <= -self.dry_depth)
                raise FlowFileError(f"{self.path}: frame {i} (t = {self.times[i]:g} s): "
                                    f"{bad.size} nodes with depth below -dry_depth = "
                                    f"{-self.dry_depth:g} m (min {low:g} m, first at nodes "
                                    f"{bad[:5].tolist()}); depths must be >= 0")
            h = np.maximum(h, 0.0)
        return h

    def _read_3d(self, i):
        z = self._get("z", i)  # (planes, nodes)
        u, v = self._get("u", i), self._get("v", i)
        dz = np.diff(z, axis=0)
        if np.any(dz < -1e-9 * max(1.0, np.abs(z).max())):
            bad = np.flatnonzero((dz < 0).any(axis=0))
            raise FlowFileError(f"{self.path}: frame {i}: ELEVATION Z decreases upwards at "
                                f"nodes {bad[:5].tolist()} (planes out of order)")
        h = self._clip(z[-1] - z[0], i)
        hu = (0.5 * (u[1:] + u[:-1]) * dz).sum(axis=0)
        hv = (0.5 * (v[1:] + v[:-1]) * dz).sum(axis=0)
        return h, hu, hv

    def close(self):
        """Close the file."""
        self.ds.close()


def open(path, *, time_range=None, variables=None, dry_depth=1e-3, depth_average=False):
    """Open a TELEMAC Selafin result file as a node-located MeshFlowField (frames read lazily).

    Parameters
    ----------
    path : path
        The Selafin file (2D results; 3D with ``depth_average``).
    time_range : (start, end), optional
        Only the frames in [start, end] (s, the file's own times).
    variables : dict, optional
        driftlog role (depth, level, bed, u, v, hu, hv) -> the file's variable name or id.
    dry_depth : float
        Depth below which a node is dry (m).
    depth_average : bool
        Read a TELEMAC-3D file as its depth average (trapezoidal over the planes).
    """
    path = Path(path)
    if not path.is_file():
        raise FlowFileError(f"{path}: file not found")
    ds = _open_dataset(path)
    try:
        return _open(ds, path, time_range, dict(variables or {}), float(dry_depth),
                     bool(depth_average))
    except BaseException:
        ds.close()
        raise


open_selafin = open


def _open(ds, path, time_range, mapping, dry_depth, depth_average):
    unknown = set(mapping) - set(ROLES)
    if unknown:
        raise FlowFileError(f"{path}: [flow] variables {sorted(unknown)} are not roles of a "
                            f"Selafin file (allowed: {', '.join(r for r in ROLES if r != 'z')})")
    is3d = "plan" in ds.dims
    if is3d and not depth_average:
        raise FlowFileError(f"{path}: a 3D Selafin file (TELEMAC-3D, {ds.sizes['plan']} "
                            "planes); driftlog reads 2D results: give [flow.options] "
                            "depth_average = true for the depth-averaged flow, or extract a "
                            "2D result with TELEMAC's own tools")
    notes = []
    ikle = np.asarray(ds.attrs["ikle2"], dtype=np.int64)
    if ikle.ndim != 2 or ikle.shape[1] not in (3, 4):
        raise FlowFileError(f"{path}: elements with {ikle.shape[-1]} nodes; driftlog reads "
                            "triangles and quadrilaterals")
    x = np.asarray(ds["x"].values, dtype=np.float64)
    y = np.asarray(ds["y"].values, dtype=np.float64)
    try:
        from driftlog.mesh import Mesh

        mesh = Mesh(x, y, ikle, start_index=1)
    except MeshError as exc:
        raise FlowFileError(f"{path}: the elements do not make a valid mesh: {exc}") from None
    if mesh.n_reversed:
        notes.append(f"{mesh.n_reversed} clockwise elements reversed")
    if ds.sizes.get("time", 0) == 0:
        raise FlowFileError(f"{path}: no time frame (a mesh or geometry file without "
                            "results); driftlog needs at least one frame of results")
    t = ds["time"].values
    date = tuple(int(v) for v in ds.attrs.get("date_start", ()))
    params = tuple(ds.attrs.get("params", ()))
    has_date = len(params) > 9 and params[9] == 1
    if len(date) >= 6:
        y, mo, d, hh, mi, ss = date[:6]
        t0 = np.datetime64(f"{y:04d}-{mo:02d}-{d:02d}T{hh:02d}:{mi:02d}:{ss:02d}")
    else:
        t0 = t[0]
    times = (t - t0) / np.timedelta64(1, "us") * 1e-6
    check_times(times, str(path))
    roles, factors = {}, {}

    def need(role, required=True):
        vid = _find(ds, role, mapping, path, required)
        if vid is not None:
            roles[role] = vid
            factors[role] = _factor(ds, vid, role, path, notes)
        return vid

    if is3d:
        need("z"), need("u"), need("v")
        notes.append(f"depth average of {ds.sizes['plan']} planes (trapezoidal in ELEVATION Z)")
    else:
        have_h = need("depth", required=False)
        have_s = need("level", required=False)
        have_b = need("bed", required=False)
        if have_h is None and not (have_s and have_b):
            raise FlowFileError(f"{path}: no depth: expected 'WATER DEPTH' (or \"HAUTEUR "
                                "D'EAU\"), or both 'FREE SURFACE' and 'BOTTOM'; the file has "
                                + ", ".join(n for n, _ in _variables(ds).values()))
        if have_b is None and not (have_s and have_h):
            raise FlowFileError(f"{path}: no bed: expected 'BOTTOM' (or 'FOND'), or both "
                                "'FREE SURFACE' and 'WATER DEPTH'; the file has "
                                + ", ".join(n for n, _ in _variables(ds).values()))
        if need("u", required=False) is not None:
            need("v")
        elif need("hu", required=False) is not None:
            need("hv")
        else:
            raise FlowFileError(f"{path}: no velocity: expected 'VELOCITY U' and 'VELOCITY V' "
                                "(or 'VITESSE U', 'VITESSE V'), or 'FLOWRATE ALONG X' and "
                                "'FLOWRATE ALONG Y'; the file has "
                                + ", ".join(n for n, _ in _variables(ds).values()))
    src = SelafinSnapshots(ds, path, times, roles, factors, dry_depth, plan_average=is3d)
    last = times.size - 1
    if is3d:
        bed, bed_last = src._get("z", 0)[0], src._get("z", last)[0]
    elif "bed" in roles:
        bed, bed_last = src._get("bed", 0), src._get("bed", last)
    else:
        bed = src._get("level", 0) - src._get("depth", 0)
        bed_last = src._get("level", last) - src._get("depth", last)
        notes.append("bed = FREE SURFACE - WATER DEPTH of the first frame")
    change = float(np.abs(bed_last - bed).max()) if bed.size else 0.0
    if change > 1e-6 * max(1.0, float(np.abs(bed).max())):
        notes.append(f"the bed evolves (up to {change:.3g} m by the last frame): depths are "
                     "each frame's, the free surface uses the first frame's bed")
    idx = select_times(times, time_range, str(path))
    source = SubsetSnapshots(src, idx) if idx.size != times.size else src
    title = str(ds.attrs.get("title", "")).strip()
    attrs = {"source": "telemac selafin", "source_path": str(path.resolve()),
             "title": title, "data_location": "node",
             "import_notes": "; ".join(notes)}
    if has_date:
        attrs["time_reference"] = "seconds since " + str(t0).replace("T", " ")
    if ds.attrs.get("float_size") == 4:
        attrs["precision"] = "single"
    return MeshFlowField(mesh, bed, source, dry_depth=dry_depth, name=str(path), attrs=attrs)


def describe(path) -> list[str]:
    """A few lines on a Selafin file for ``driftlog info`` (header only, no frame read)."""
    path = Path(path)
    with _open_dataset(path) as ds:
        ikle = np.asarray(ds.attrs["ikle2"])
        nt = ds.sizes.get("time", 0)
        dim = f"3D, {ds.sizes['plan']} planes" if "plan" in ds.dims else "2D"
        lines = [f"{path}: TELEMAC Selafin, {dim}, "
                 f"{'double' if ds.attrs.get('float_size') == 8 else 'single'} precision, "
                 f"language {ds.attrs.get('language', '?')}",
                 f"  title: {str(ds.attrs.get('title', '')).strip()}",
                 f"  mesh: {ds.sizes['node']} nodes, {ikle.shape[0]} elements of "
                 f"{ikle.shape[1]} nodes (data on nodes, sampled P1)"]
        if nt:
            t = ds["time"].values
            params = tuple(ds.attrs.get("params", ()))
            dated = len(params) > 9 and params[9] == 1
            lines.append(f"  times: {nt} frames, {t[0]} to {t[-1]}"
                         + ("" if dated else " (no date in the header: times from 0)"))
        else:
            lines.append("  times: none (no result frame)")
        lines.append("  variables: " + ", ".join(f"{n} [{u}]" for n, u in
                                                 _variables(ds).values()))
    return lines


# --------------------------------------------------------------------- writing
def triangles(mesh):
    """The mesh's faces as triangles, quadrilaterals fanned from their first node.

    The sampler splits quadrilaterals the same way, so P1 on these triangles is its
    interpolant.
    """
    fn = mesh.face_nodes
    tri = fn[:, :3]
    if fn.shape[1] == 4:
        q = np.flatnonzero(mesh.face_n == 4)
        tri = np.vstack([tri, fn[q][:, [0, 2, 3]]])
    return np.ascontiguousarray(tri)


def write(field, path, precision="double", title=None):
    """Write a mesh flow as a TELEMAC-2D Selafin result file with xarray-selafin.

    Node values are the ones the sampler interpolates (``MeshFlowField.node_snapshot``): the
    data themselves for a node-located flow, the nodes' least-squares fits of the face values
    for a face-located one, so that the file read back is sampled with the same depth and
    velocity (the recovered gradients differ: see ``driftlog.nodal``); for a cell-centred
    grid (CF grids, rasters), whose bilinear interpolant is not P1 on triangles, the nodes'
    fits of the cell values, as for a face-located mesh flow.  Variables WATER
    DEPTH, VELOCITY U, VELOCITY V, FREE SURFACE and BOTTOM; quadrilaterals are split into the
    sampler's two triangles.  Frames are computed one at a time while writing.

    Parameters
    ----------
    field : MeshFlowField
    path : path
    precision : 'double' (SERAFIND) or 'single' (SERAFIN, TELEMAC's default)
    title : str, optional
        The file's title (80 characters at most).

    Notes
    -----
    xarray-selafin stores times as whole seconds after the header's date: the field's times
    (relative to its ``time_reference``, or to 1900-01-01 without one) must be whole seconds.
    """
    import dask.array as da
    import xarray as xr
    import xarray_selafin.xarray_backend  # noqa: F401

    if precision not in ("double", "single"):
        raise FlowFileError(f"{path}: precision {precision!r}: 'double' or 'single'")
    times = np.asarray(field.times, dtype=np.float64)
    if np.any(np.abs(times - np.round(times)) > 1e-6):
        raise FlowFileError(f"{path}: the flow's times are not whole seconds (e.g. "
                            f"{times[np.abs(times - np.round(times)) > 1e-6][0]:g} s); "
                            "xarray-selafin writes whole seconds after the header date")
    epoch = reference_epoch(field.attrs, str(path)) or np.datetime64("1900-01-01T00:00:00",
                                                                      "us")
    date = epoch.astype(object)
    stamps = epoch + np.round(times).astype(np.int64).astype("timedelta64[s]")
    mesh = field.mesh
    n = mesh.n_nodes
    if field.location == "node":
        bed = field.node_bed
    else:
        bed = mesh.node_operators()[0] @ field.bed
    dtype = np.float64 if precision == "double" else np.float32
    # a cell-centred grid (CF grid, raster: GridFlowField) holds its values at the cells'
    # centres, which are not its mesh's nodes: the nodes' fits of the cell values, as for a
    # face-located mesh flow
    cells = getattr(field, "layout", None) == "cell"

    def node_snapshot(i):
        if not cells:
            return field.node_snapshot(i)
        h, hu, hv = field.read_snapshot(i)
        u, v = field._velocity(h, hu, hv)
        nodes = mesh.node_operators()[0] @ np.column_stack([h, u, v, h + field.bed])
        return {"h": np.maximum(nodes[:, 0], 0.0), "u": nodes[:, 1], "v": nodes[:, 2],
                "eta": nodes[:, 3]}

    def frame(key, block_info=None):
        i = block_info[None]["chunk-location"][0]
        snap = node_snapshot(i)
        val = snap[key] if key != "B" else bed
        if key == "eta":
            val = snap["h"] + bed
        return np.asarray(val, dtype=dtype)[None, :]

    data = {}
    for vid, key in (("H", "h"), ("U", "u"), ("V", "v"), ("S", "eta"), ("B", "B")):
        arr = da.map_blocks(frame, key, dtype=dtype, chunks=((1,) * times.size, (n,)),
                            meta=np.empty((0, 0), dtype))
        data[vid] = (("time", "node"), arr)
    ds = xr.Dataset(data, coords={"x": ("node", mesh.node_x), "y": ("node", mesh.node_y),
                                  "time": stamps.astype("datetime64[ns]")})
    ds.attrs.update(
        title=(title or f"driftlog flow {field.name}")[:72],
        float_size=8 if precision == "double" else 4,
        ikle2=(triangles(mesh) + 1).astype(np.int32),
        date_start=(date.year, date.month, date.day, date.hour, date.minute, date.second),
        variables={"H": ("WATER DEPTH", "M"), "U": ("VELOCITY U", "M/S"),
                   "V": ("VELOCITY V", "M/S"), "S": ("FREE SURFACE", "M"),
                   "B": ("BOTTOM", "M")})
    import dask

    with dask.config.set(scheduler="synchronous"):
        ds.selafin.write(str(path))
    return Path(path)
