"""UGRID NetCDF results (D-Flow FM map files and the like) as driftlog flows.

D-Flow FM writes a ``mesh2d`` topology with 1-based ``mesh2d_face_nodes`` (``start_index = 1``,
``_FillValue = -999``), and on faces: ``mesh2d_s1`` (water level), ``mesh2d_waterdepth``,
``mesh2d_ucx`` / ``mesh2d_ucy`` (velocity), bed level ``mesh2d_flowelem_bl`` (or
``mesh2d_node_z`` on nodes), with ``time`` in 'seconds since ...'.  Other UGRID files are read
the same way: variables are found by ``standard_name``, then by known names (``ROLES`` in
``_netcdf``), and any can be named by the user (``variables = {depth = "...", ...}``).

Depth is taken from the depth variable, or level minus bed; velocity from u, v, or unit
discharges hu, hv.  Snapshots are read one time at a time.  Node coordinates (and node
elevations) whose ``units`` are another length (km, ft, US_survey_foot...) are converted to
metres with a note (``driftlog.mesh.read_ugrid_mesh``); unknown units are refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField
from driftlog.mesh import read_ugrid_mesh
from driftlog.schema import Key

from ._common import SubsetSnapshots, check_values, select_times
from ._netcdf import (
    ROLES,
    FaceSnapshots,
    bed_down,
    factors,
    fill_value,
    find_roles,
    netcdf_matches,
    open_dataset,
    read_times,
    time_attrs,
    variable_attrs,
)

__all__ = ["open_ugrid", "is_ugrid"]


def _topology(ds):
    for var in ds.variables.values():
        if getattr(var, "cf_role", "") == "mesh_topology" and \
                int(getattr(var, "topology_dimension", 2)) == 2:
            return var
    return None


def is_ugrid(ds) -> bool:
    """Whether an open NetCDF dataset has a 2D UGRID mesh topology."""
    return _topology(ds) is not None


def open_ugrid(path, time_range=None, variables=None, dry_depth=1e-3, topology=None,
               fill="error", units=None):
    """Open a UGRID NetCDF file (D-Flow FM map file...) as a MeshFlowField, read lazily.

    Parameters
    ----------
    variables : dict, optional
        driftlog name (depth, level, bed, u, v, hu, hv) -> variable name in the file.
    fill : 'error' or 'dry'
        Fill values and NaN in the fields: an error naming the variable and time (default),
        or dry faces.
    units : dict, optional
        Units for variables that lack a units attribute (role -> units).
    """
    path = Path(path)
    ds = open_dataset(path)
    try:
        return _open(ds, path, time_range, variables or {}, dry_depth, topology, fill, units)
    except BaseException:
        ds.close()
        raise


def _open(ds, path, time_range, mapping, dry_depth, topology, fill, units_override):
    topo = _topology(ds)
    if topo is None:
        raise FlowFileError(f"{path}: not a UGRID file (no variable with cf_role = "
                            "'mesh_topology' and topology_dimension = 2)")
    try:
        mesh = read_ugrid_mesh(path, topology)
    except MeshError as exc:
        msg = str(exc)
        if "nodes found; triangles and quadrilaterals only" in msg:
            msg = "unsupported element type: " + msg
        raise FlowFileError(f"{path}: {msg}" if not msg.startswith(str(path)) else msg) \
            from None
    fnc = ds.variables[topo.face_node_connectivity]
    face_dim = getattr(topo, "face_dimension", fnc.dimensions[0])
    if face_dim not in ds.dimensions:
        raise FlowFileError(f"{path}: face dimension {face_dim!r} of {topo.name!r} is missing")
    if len(ds.dimensions[face_dim]) != mesh.n_faces:
        raise FlowFileError(f"{path}: the face dimension {face_dim!r} has "
                            f"{len(ds.dimensions[face_dim])} entries, the mesh {mesh.n_faces}")
    # time-dependent face variables: (time, face)
    time_dims = {v.dimensions[0] for v in ds.variables.values()
                 if len(v.dimensions) == 2 and v.dimensions[1] == face_dim}
    time_dims = [d for d in time_dims if d in ds.dimensions and ds.dimensions[d].isunlimited()
                 or d in ("time", "nTime", "Time")] or sorted(time_dims)
    if not time_dims:
        layered = [n for n, v in ds.variables.items() if face_dim in v.dimensions
                   and len(v.dimensions) > 2]
        raise FlowFileError(f"{path}: unknown layout: no (time, {face_dim}) variables" +
                            (f"; 3D layered variables {layered[:4]} need depth-averaged ones "
                             "(mesh2d_ucxa, mesh2d_ucya)" if layered else ""))
    tdim = time_dims[0]
    where = str(path)
    fvars = variable_attrs(ds, (tdim, face_dim))
    for role, name in mapping.items():  # a variable named by the user, on other dimensions
        if role != "bed" and name in ds.variables and name not in fvars:
            var = ds.variables[name]
            raise FlowFileError(f"{path}: {name!r} (given for {role!r}) has dimensions "
                                f"{var.dimensions} {var.shape}; a field on this mesh has "
                                f"({tdim!r}, {face_dim!r}) ({len(ds.dimensions[tdim])}, "
                                f"{mesh.n_faces})")
    roles = find_roles(fvars, mapping, where, need_bed=True)
    notes = list(getattr(mesh, "unit_notes", ()))  # node coordinates converted to metres
    merged, tol = getattr(mesh, "merged_nodes", (0, 0.0))
    if merged:
        notes.append(f"{merged} coincident nodes merged (closer than {tol:g} x the local edge "
                     "length: the seams of a partitioned mesh are not walls)")
    spec3 = factors(ds, roles, where, notes, units_override)
    bed = _bed(ds, path, mesh, face_dim, mapping, notes, units_override)
    if bed is None:
        both = [find_roles_single(fvars, r, mapping, where) for r in ("depth", "level")]
        if None in both:
            raise FlowFileError(f"{path}: no bed level (looked for a face variable with "
                                f"standard_name 'altitude' or names like "
                                f"{ROLES['bed'][2][:3]}, and node elevations mesh2d_node_z); "
                                "map it with [flow] variables = {bed = \"NAME\"}")
        fd = factors(ds, {"depth": both[0], "level": both[1]}, where, [], units_override)
        bed = (np.asarray(ds.variables[both[1]][0], float) * fd["level"][1]
               - np.asarray(ds.variables[both[0]][0], float) * fd["depth"][1])
        notes.append(f"bed from {both[1]} - {both[0]} at the first time")
    times, origin = read_times(ds, path, tdim)
    if times.size != len(ds.dimensions[tdim]):
        raise FlowFileError(f"{path}: time has {times.size} values for {len(ds.dimensions[tdim])}"
                            " snapshots")
    from driftlog.flow import check_times

    check_times(times, where)
    spec = {role: (name, f) for role, (name, f, _) in spec3.items()}
    src = FaceSnapshots(ds, path, times, spec, bed, fill=fill)
    idx = select_times(times, time_range, where)
    source = SubsetSnapshots(src, idx) if idx.size != times.size else src
    made_by = str(getattr(ds, "source", "") or getattr(ds, "institution", ""))
    attrs = {"source": f"ugrid ({made_by})" if made_by else "ugrid",
             "source_path": str(path.resolve()), "time_origin": origin or "",
             "variables": ", ".join(f"{k}={v[0]}" for k, v in spec.items()),
             "import_notes": "; ".join(notes)}
    attrs.update(time_attrs(ds, path, tdim, origin))
    return MeshFlowField(mesh, bed, source, dry_depth=dry_depth, name=str(path), attrs=attrs)


def _bed(ds, path, mesh, face_dim, mapping, notes, units_override):
    """Bed on faces: a face variable (flowelem_bl...), else node values averaged to faces."""
    from ._common import find_variable, unit_factor

    kind, std, alias = ROLES["bed"]
    face_vars = variable_attrs(ds, (face_dim,))
    name = find_variable(face_vars, alias, "bed", mapping if mapping.get("bed") in face_vars
                         else {}, std + ("sea_floor_depth_below_geoid",), str(path),
                         required=False)
    if name is not None:
        var = ds.variables[name]
        arr = np.asarray(var[:], dtype=np.float64)
        check_values(arr, fill_value(var), f"{path}: {name}")
        f, _ = unit_factor((units_override or {}).get("bed", getattr(var, "units", None)),
                           "length", f"{path}: {name}", notes)
        sign = -1.0 if bed_down(face_vars[name]) else 1.0
        notes.append(f"bed from {name}" + (" (positive down, negated)" if sign < 0 else ""))
        return sign * f * arr
    if "bed" in mapping and mapping["bed"] in ds.variables:
        var = ds.variables[mapping["bed"]]
        if var.shape != (mesh.n_nodes,):
            raise FlowFileError(f"{path}: bed variable {var.name!r} has shape {var.shape}: "
                                f"neither faces ({mesh.n_faces}) nor nodes ({mesh.n_nodes})")
    if mesh.node_z is not None:
        notes.append("bed: node elevations averaged on faces")
        return mesh.face_bed()
    return None


def find_roles_single(fvars, role, mapping, where):
    from ._common import find_variable

    _, std, alias = ROLES[role]
    return find_variable(fvars, alias, role, mapping, std, where, required=False)


# --------------------------------------------------------------------- the reader contract
KIND = "ugrid"
SUFFIXES = (".nc",)
OPTIONS = [
    Key("topology", "str", None, "name of the mesh topology variable (default: the file's 2D "
        "topology)"),
    Key("fill", "str", "error", "fill values and NaN in the fields: an error naming the "
        "variable and time, or dry faces", choices=("error", "dry")),
    Key("units", "table", None, "units for variables that lack a units attribute "
        "({hu = 'm3 s-1'})"),
]


def can_open(path) -> bool:
    """Whether ``path`` is a NetCDF file with a 2D UGRID mesh topology (never raises)."""
    return netcdf_matches(path, is_ugrid)


def open(path, *, time_range=None, variables=None, dry_depth=1e-3, **options):
    """``open_ugrid`` under the reader contract (``options``: ``OPTIONS``)."""
    return open_ugrid(path, time_range=time_range, variables=variables, dry_depth=dry_depth,
                      **options)
