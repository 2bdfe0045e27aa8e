"""driftlog's flow file: UGRID-1.0 + CF NetCDF, written snapshot by snapshot, read lazily.

Layout (readable by ``xugrid.open_dataset`` and xarray)::

    mesh2d                      UGRID topology (cf_role = mesh_topology)
    mesh2d_node_x, _node_y      node coordinates (m)
    mesh2d_face_nodes           (mesh2d_nFaces, mesh2d_nMax_face_nodes), 0-based, _FillValue -1
    mesh2d_face_x, _face_y      face centroids
    mesh2d_edge_nodes           (mesh2d_nEdges, 2)
    mesh2d_edge_type            boundary tag per edge (-1 interior), flag_values / flag_meanings
    mesh2d_node_z               bed at nodes (if known)
    bed_level                   (mesh2d_nFaces) bed on faces (m)
    time                        (time) seconds since the reference date
    water_depth                 (time, mesh2d_nFaces)
    velocity_x, velocity_y      (time, mesh2d_nFaces), velocity (0 on dry faces)

Unit discharges are h * u.  Global attributes carry the provenance: ``source`` (the model),
``driftlog_version``, ``scenario`` (the TOML text that made it) and any given attrs.  Each
snapshot is flushed as it is written: a run that stops loses nothing written before.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import netCDF4
import numpy as np

from driftlog._version import __version__
from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField, check_times, time_in_seconds
from driftlog.mesh import Mesh, read_ugrid_mesh

__all__ = ["FlowFileWriter", "write_flow", "open_flow", "read_flow_mesh", "NetCDFSnapshots",
           "TIME_UNITS", "write_mesh"]

TIME_UNITS = "seconds since 2000-01-01 00:00:00"
FACE_DIM, NODE_DIM, EDGE_DIM, MAXN_DIM = ("mesh2d_nFaces", "mesh2d_nNodes", "mesh2d_nEdges",
                                          "mesh2d_nMax_face_nodes")
FIELDS = {
    "water_depth": dict(standard_name="sea_floor_depth_below_sea_surface",
                        long_name="water depth", units="m"),
    "velocity_x": dict(standard_name="sea_water_x_velocity",
                       long_name="depth-averaged velocity, x component", units="m s-1"),
    "velocity_y": dict(standard_name="sea_water_y_velocity",
                       long_name="depth-averaged velocity, y component", units="m s-1"),
}


def _attrs_for_netcdf(attrs):
    out = {}
    for k, v in (attrs or {}).items():
        if v is None:
            continue
        if isinstance(v, bool):
            v = int(v)
        if isinstance(v, (str, int, float, np.integer, np.floating)):
            out[k] = v
        else:
            out[k] = str(v)
    return out


def write_mesh(ds, mesh: Mesh) -> None:
    """Write the UGRID-1.0 topology of ``mesh`` into an open netCDF4 Dataset.

    The ``mesh2d`` variable, node and face coordinates, face-node and edge-node tables and the
    boundary tags; used by flow files and by other outputs on the flow mesh (ensembles).
    """
    ds.createDimension(NODE_DIM, mesh.n_nodes)
    ds.createDimension(FACE_DIM, mesh.n_faces)
    ds.createDimension(EDGE_DIM, mesh.n_edges)
    ds.createDimension(MAXN_DIM, mesh.max_face_nodes)
    ds.createDimension("Two", 2)
    topo = ds.createVariable("mesh2d", "i4")
    topo.setncatts(dict(
        cf_role="mesh_topology", long_name="topology of the 2D mesh", topology_dimension=2,
        node_coordinates="mesh2d_node_x mesh2d_node_y",
        face_node_connectivity="mesh2d_face_nodes",
        face_coordinates="mesh2d_face_x mesh2d_face_y",
        edge_node_connectivity="mesh2d_edge_nodes",
        face_dimension=FACE_DIM, edge_dimension=EDGE_DIM, max_face_nodes_dimension=MAXN_DIM))
    for axis, arr, dim in (("x", mesh.node_x, NODE_DIM), ("y", mesh.node_y, NODE_DIM),
                           ("x", mesh.face_x, FACE_DIM), ("y", mesh.face_y, FACE_DIM)):
        loc = "node" if dim == NODE_DIM else "face"
        v = ds.createVariable(f"mesh2d_{loc}_{axis}", "f8", (dim,))
        v.setncatts(dict(standard_name=f"projection_{axis}_coordinate", units="m",
                         long_name=f"{axis} coordinate of mesh {loc}s"))
        v[:] = arr
    fn = ds.createVariable("mesh2d_face_nodes", "i4", (FACE_DIM, MAXN_DIM), fill_value=-1)
    fn.setncatts(dict(cf_role="face_node_connectivity", start_index=0,
                      long_name="nodes of each face, counter-clockwise"))
    fn[:] = mesh.face_nodes
    en = ds.createVariable("mesh2d_edge_nodes", "i4", (EDGE_DIM, "Two"))
    en.setncatts(dict(cf_role="edge_node_connectivity", start_index=0))
    en[:] = mesh.edge_nodes
    et = ds.createVariable("mesh2d_edge_type", "i2", (EDGE_DIM,))
    et.setncatts(dict(mesh="mesh2d", location="edge", long_name="boundary tag of each edge",
                      flag_values=np.arange(-1, len(mesh.tag_names), dtype=np.int16),
                      flag_meanings=" ".join(["interior"] + mesh.tag_names)))
    et[:] = mesh.edge_tag
    if mesh.node_z is not None:
        nz = ds.createVariable("mesh2d_node_z", "f8", (NODE_DIM,))
        nz.setncatts(dict(mesh="mesh2d", location="node", standard_name="altitude",
                          long_name="bed elevation at nodes", units="m"))
        nz[:] = mesh.node_z


class FlowFileWriter:
    """Write a flow file snapshot by snapshot (or reopen one to append, for resuming a run).

    Parameters
    ----------
    path : path
    mesh : Mesh
    bed : array (n_faces,)
    attrs : dict
        Global attributes (``source``, ``scenario``, ...).
    extra_series : dict name -> attrs
        Scalar time series written beside each snapshot (e.g. volume balance of the solver).
    append : bool
        Open an existing file and append after its last snapshot.
    compress : bool
        zlib level 1 with shuffle (dry areas compress well).
    """

    def __init__(self, path, mesh: Mesh, bed, attrs=None, extra_series=None, append=False,
                 compress=True, dtype="f8"):
        self.path = Path(path)
        self.mesh = mesh
        self._last_t = None  # the last snapshot's time (read from the file when appending)
        if append:
            self.ds = netCDF4.Dataset(self.path, "a")
            self.n = len(self.ds.dimensions["time"])
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        ds = self.ds = netCDF4.Dataset(self.path, "w", format="NETCDF4")
        self.n = 0
        ds.Conventions = "CF-1.11 UGRID-1.0"
        ds.title = (attrs or {}).get("title", "driftlog flow")
        ds.driftlog_version = __version__
        now = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
        ds.history = f"{now} driftlog {__version__}"
        ds.setncatts(_attrs_for_netcdf({k: v for k, v in (attrs or {}).items() if k != "title"}))
        write_mesh(ds, mesh)
        ds.createDimension("time", None)
        bv = ds.createVariable("bed_level", "f8", (FACE_DIM,))
        bv.setncatts(dict(mesh="mesh2d", location="face", standard_name="altitude",
                          long_name="bed elevation", units="m",
                          coordinates="mesh2d_face_x mesh2d_face_y"))
        bv[:] = np.asarray(bed, dtype=float)
        tv = ds.createVariable("time", "f8", ("time",))
        # the source's own reference ("seconds since 1999-01-01T12:00:00"), kept with its calendar
        units = str((attrs or {}).get("time_reference") or TIME_UNITS)
        tatt = dict(standard_name="time", long_name="time", units=units, axis="T")
        if (attrs or {}).get("calendar"):
            tatt["calendar"] = str(attrs["calendar"])
        tv.setncatts(tatt)
        comp = dict(zlib=True, complevel=1, shuffle=True) if compress else {}
        chunks = (1, mesh.n_faces)
        for name, a in FIELDS.items():
            v = ds.createVariable(name, dtype, ("time", FACE_DIM), chunksizes=chunks, **comp)
            v.setncatts(dict(a, mesh="mesh2d", location="face",
                             coordinates="mesh2d_face_x mesh2d_face_y"))
        for name, a in (extra_series or {}).items():
            v = ds.createVariable(name, "f8", ("time",))
            v.setncatts(_attrs_for_netcdf(a))
        ds.sync()

    def write(self, t, h, hu=None, hv=None, u=None, v=None, dry_depth=1e-3, sync=True,
              **series):
        """Append the snapshot at time t (give hu, hv or u, v); flushed to disk at once.

        ``sync=False``: not flushed (the caller writes more beside it, then syncs ``ds``).
        """
        h = np.asarray(h, dtype=float)
        if u is None:
            wet = h > dry_depth
            safe = np.where(wet, h, 1.0)
            u = np.where(wet, np.asarray(hu) / safe, 0.0)
            v = np.where(wet, np.asarray(hv) / safe, 0.0)
        i = self.n
        if i > 0 and self._last_t is None:
            self._last_t = float(self.ds.variables["time"][i - 1])
        if i > 0 and not t > self._last_t:
            raise FlowFileError(f"{self.path}: snapshot time {t} s is not after the last "
                                f"written, {self._last_t} s")
        self.ds.variables["time"][i] = t
        self._last_t = float(t)
        self.ds.variables["water_depth"][i, :] = h
        self.ds.variables["velocity_x"][i, :] = u
        self.ds.variables["velocity_y"][i, :] = v
        for k, val in series.items():
            self.ds.variables[k][i] = val
        self.n += 1
        if sync:
            self.ds.sync()

    def set_attrs(self, **attrs):
        """Add or replace global attributes of the file."""
        self.ds.setncatts(_attrs_for_netcdf(attrs))
        self.ds.sync()

    def close(self):
        """Close the file (once)."""
        if self.ds.isopen():
            self.ds.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def write_flow(path, field: MeshFlowField, attrs=None, compress=True):
    """Write a whole MeshFlowField to a flow file (snapshot by snapshot: bounded memory)."""
    a = dict(field.attrs)
    a.update(attrs or {})
    a.setdefault("source", field.name)
    a.setdefault("dry_depth", field.dry_depth)
    with FlowFileWriter(path, field.mesh, field.bed, attrs=a, compress=compress) as w:
        for i, t in enumerate(field.times):
            s = field.snapshot(i)
            w.write(float(t), s["h"], u=s["u"], v=s["v"])
    return Path(path)


class NetCDFSnapshots:
    """Lazy snapshot source over a flow file: reads one snapshot when asked, keeps the file open."""

    def __init__(self, path, depth="water_depth", u="velocity_x", v="velocity_y"):
        self.path = Path(path)
        self.name = str(self.path)
        self.ds = netCDF4.Dataset(self.path)
        self.ds.set_auto_mask(False)
        for name in (depth, u, v, "time"):
            if name not in self.ds.variables:
                raise FlowFileError(f"{self.path}: variable {name!r} is missing (a driftlog flow "
                                    "file has time, water_depth, velocity_x, velocity_y)")
        self.vars = (self.ds.variables[depth], self.ds.variables[u], self.ds.variables[v])
        # CF units as the other readers take them ('days since ...' in seconds, unknown
        # units refused); ``origin``: the date after 'since', None without one
        tvar = self.ds.variables["time"]
        seconds, self.origin = time_in_seconds(tvar[:], getattr(tvar, "units", None),
                                               f"{self.path}: time",
                                               calendar=getattr(tvar, "calendar", None))
        self.times = check_times(seconds, self.name)

    def read(self, i):
        """Snapshot i as face arrays (h, hu, hv); fill values are an error."""
        h, u, v = (np.asarray(var[i, :], dtype=np.float64) for var in self.vars)
        for arr, var in zip((h, u, v), self.vars, strict=True):
            fill = var.getncattr("_FillValue") if "_FillValue" in var.ncattrs() else None
            if fill is not None and np.any(arr == fill):
                raise FlowFileError(f"{self.path}: {var.name} at snapshot {i} holds fill values "
                                    f"({fill}) at faces {np.flatnonzero(arr == fill)[:5].tolist()}")
        return h, h * u, h * v

    def close(self):
        """Close the file (once)."""
        if self.ds.isopen():
            self.ds.close()


def _read_edge_tags(ds, mesh: Mesh) -> None:
    """Give ``mesh`` the boundary tags stored in an open flow file (same edges only)."""
    if "mesh2d_edge_type" in ds.variables:
        var = ds.variables["mesh2d_edge_type"]
        tags = np.asarray(var[:], dtype=np.int16)
        names = var.getncattr("flag_meanings").split()[1:]
        same_edges = ("mesh2d_edge_nodes" in ds.variables and tags.shape == (mesh.n_edges,)
                      and np.array_equal(ds.variables["mesh2d_edge_nodes"][:], mesh.edge_nodes))
        if same_edges:
            mesh.tag_names = names or ["wall"]
            mesh.edge_tag = tags


def _read_mesh(path: Path) -> Mesh:
    from driftlog.files import require

    if not path.is_file() and not path.is_dir():
        raise FlowFileError(f"{path}: flow file not found")
    require(path, ("flow", "model_output", "netcdf"), "flow file", error=FlowFileError,
            expected="a driftlog flow file")  # (the others: what is missing is said below)
    try:
        return read_ugrid_mesh(path)
    except MeshError as exc:
        msg = str(exc).removeprefix(f"{path}: ")  # the file named once
        raise FlowFileError(f"{path}: not a driftlog flow file: {msg}") from None


def read_flow_mesh(path) -> Mesh:
    """The mesh of a driftlog flow file, with its boundary tags, as ``open_flow`` gives it.

    Only the mesh is read (no snapshot source is opened).
    """
    path = Path(path)
    mesh = _read_mesh(path)
    try:
        with netCDF4.Dataset(path) as ds:
            _read_edge_tags(ds, mesh)
    except OSError as exc:
        raise FlowFileError(f"{path}: cannot read ({exc})") from None
    return mesh


def open_flow(path, dry_depth=None) -> MeshFlowField:
    """Open a driftlog flow file as a MeshFlowField (snapshots read lazily, two at a time)."""
    path = Path(path)
    mesh = _read_mesh(path)
    try:
        src = NetCDFSnapshots(path)
    except OSError as exc:
        raise FlowFileError(f"{path}: cannot read ({exc})") from None
    ds = src.ds
    attrs = {k: ds.getncattr(k) for k in ds.ncattrs()}
    if src.origin is not None:  # the time axis' own reference (the default one is implied)
        ref = f"seconds since {src.origin}"
        if "time_reference" in attrs or ref != TIME_UNITS:
            attrs["time_reference"] = ref
    _read_edge_tags(ds, mesh)
    if "bed_level" not in ds.variables:
        raise FlowFileError(f"{path}: variable 'bed_level' is missing")
    bed = np.asarray(ds.variables["bed_level"][:], dtype=float)
    if dry_depth is None:
        dry_depth = float(attrs.get("dry_depth", 1e-3))
    return MeshFlowField(mesh, bed, src, dry_depth=dry_depth, name=str(path), attrs=attrs)
