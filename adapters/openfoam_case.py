"""Set up, run and read back a shallowWaterFoam case from a driftlog mesh, bed and boundaries.

So that the same scene can be computed by driftlog's solver and by OpenFOAM's
shallowWaterFoam.  The 2D mesh (triangles and quadrilaterals) is extruded one cell thick
(OpenFOAM needs a 3D polyMesh: prisms and hexahedra with ``empty`` top and bottom), written
directly as a polyMesh (internal faces in upper-triangular order, then one patch per boundary
tag, then the empty patch).  Boundary conditions by tag:

=========  ==========================================  ====================================
type        keys                                        fields
=========  ==========================================  ====================================
wall        -                                           h zeroGradient, hU slip
inflow      discharge (m3/s) | unit_discharge (m2/s)    hU fixedValue (into the domain,
            | velocity (m/s) with depth (m)             uniform along the boundary), h
            | discharge_series [[t, Q], ...]            zeroGradient; a series:
                                                        flowRateInletVelocity on hU
outflow     level (m) | depth (m) | level_series |      h fixedValue level - bed (or
            depth_series [[t, m], ...]                  depth; a series: uniformFixedValue),
                                                        hU zeroGradient
open        -                                           h, hU zeroGradient
=========  ==========================================  ====================================

shallowWaterFoam (v1912) has no bed friction and fails on dry cells (U = hU/h): the initial
depth must be positive everywhere.  It runs with a fixed time step, chosen here from a Courant
number on the gravity-wave speed.  Parallel runs use decomposePar (method simple) and mpirun;
``constant/h0`` is decomposed too (decomposePar alone leaves it out, and shallowWaterFoam then
silently runs on a flat bed).
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np

from driftlog.errors import DriftlogError, FlowFileError
from driftlog.mesh import Mesh

from ._foam_case import clean_case
from .foam_io import format_list, write_foam_file, write_polymesh_files

__all__ = ["foam_available", "foam_env", "write_polymesh", "write_shallow_water_case",
           "run_case", "run_shallow_water", "OpenFOAMError", "BASHRC"]

BASHRC = "/usr/share/openfoam/etc/bashrc"


class OpenFOAMError(DriftlogError, RuntimeError):
    """OpenFOAM is missing, or one of its tools failed (the message quotes its log)."""


@functools.lru_cache(maxsize=1)
def foam_env() -> dict | None:
    """The environment after sourcing OpenFOAM's bashrc (None if OpenFOAM is not installed)."""
    bashrc = os.environ.get("DRIFTLOG_OPENFOAM_BASHRC", BASHRC)
    if Path(bashrc).is_file():
        out = subprocess.run(["bash", "-c", f"source {bashrc} >/dev/null 2>&1; env -0"],
                             capture_output=True, timeout=60)
        env = dict(kv.split("=", 1) for kv in out.stdout.decode().split("\0") if "=" in kv)
        if shutil.which("shallowWaterFoam", path=env.get("PATH")):
            return env
    if shutil.which("shallowWaterFoam"):
        return dict(os.environ)
    return None


def foam_available() -> bool:
    """Whether OpenFOAM (shallowWaterFoam) can be run here."""
    return foam_env() is not None


# --------------------------------------------------------------------- polyMesh
def write_polymesh(case_dir, mesh: Mesh, thickness=1.0, empty_patch="frontAndBack",
                   patch_types=None):
    """Write ``constant/polyMesh`` of the 2D mesh extruded one cell thick along z.

    Cell i is face i of the mesh.  Boundary edges become patches named by their tags (type
    ``wall`` for the tag 'wall' and those in ``patch_types``, else ``patch``).
    Returns the patch names in order.
    """
    folder = Path(case_dir) / "constant" / "polyMesh"
    folder.mkdir(parents=True, exist_ok=True)
    n = mesh.n_nodes
    pts = np.vstack([np.column_stack([mesh.node_x, mesh.node_y, np.zeros(n)]),
                     np.column_stack([mesh.node_x, mesh.node_y, np.full(n, float(thickness))])])
    ef, en = mesh.edge_faces, mesh.edge_nodes
    internal = np.flatnonzero(ef[:, 1] >= 0)
    own = np.minimum(ef[internal, 0], ef[internal, 1])
    nbr = np.maximum(ef[internal, 0], ef[internal, 1])
    order = np.lexsort((nbr, own))
    internal, own, nbr = internal[order], own[order], nbr[order]
    faces, owner = [], []
    for e, o in zip(internal, own, strict=True):
        a, b = en[e]
        q = [a, b, b + n, a + n]  # normal out of edge_faces[e, 0]
        faces.append(q if ef[e, 0] == o else q[::-1])
    owner.extend(own.tolist())
    patches = []
    types = dict(patch_types or {})
    for tag_id, name in enumerate(mesh.tag_names):
        edges = np.flatnonzero((mesh.edge_tag == tag_id) & (ef[:, 1] < 0))
        if edges.size == 0:
            continue
        start = len(faces)
        for e in edges:
            a, b = en[e]
            faces.append([a, b, b + n, a + n])
            owner.append(ef[e, 0])
        typ = types.get(name, "wall" if name == "wall" else "patch")
        patches.append((name, typ, start, edges.size))
    start = len(faces)
    for i in range(mesh.n_faces):
        f = mesh.face_nodes[i, :mesh.face_n[i]]
        faces.append(f[::-1].tolist())  # bottom: normal down
        owner.append(i)
    for i in range(mesh.n_faces):
        f = mesh.face_nodes[i, :mesh.face_n[i]]
        faces.append((f + n).tolist())  # top: normal up
        owner.append(i)
    patches.append((empty_patch, "empty", start, 2 * mesh.n_faces))
    return write_polymesh_files(folder, pts, faces, owner, nbr, patches, mesh.n_faces)


# --------------------------------------------------------------------- fields
def _field(cls, obj, dims, internal, boundary, location="0"):
    body = [f"dimensions      {dims};", ""]
    kind = "vector" if cls == "volVectorField" else "scalar"
    body.append(f"internalField   nonuniform List<{kind}>\n{format_list(internal)};")
    body += ["", "boundaryField", "{"]
    for name, entries in boundary.items():
        body += [f"    {name}", "    {"]
        for k, v in entries.items():
            body.append(f"        {k:<15} {v};")
        body.append("    }")
    body.append("}")
    return cls, obj, "\n".join(body), location


def _nonuniform(values, vector=False):
    kind = "vector" if vector else "scalar"
    return f"nonuniform List<{kind}> {format_list(np.asarray(values))}"


_FV_SCHEMES = """ddtSchemes { default Euler; }
gradSchemes { default Gauss linear; }
divSchemes { default none; div(phiv,hU) Gauss LUST un; }
laplacianSchemes { default Gauss linear corrected; }
interpolationSchemes { default linear; }
snGradSchemes { default corrected; }"""

_FV_SOLUTION = """solvers
{
    h { solver PCG; preconditioner DIC; tolerance 1e-10; relTol 0.01; }
    hFinal { solver PCG; preconditioner DIC; tolerance 1e-10; relTol 0; }
    hU { solver smoothSolver; smoother GaussSeidel; tolerance 1e-10; relTol 0.1; }
    hUFinal { solver smoothSolver; smoother GaussSeidel; tolerance 1e-10; relTol 0; }
}
PIMPLE
{
    nOuterCorrectors 3;
    nCorrectors 1;
    nNonOrthogonalCorrectors 0;
    momentumPredictor yes;
}"""


def _boundary_spec(mesh, boundaries):
    spec = {}
    for tag_id, name in enumerate(mesh.tag_names):
        edges = np.flatnonzero((mesh.edge_tag == tag_id) & (mesh.edge_faces[:, 1] < 0))
        if edges.size == 0:
            continue
        b = dict((boundaries or {}).get(name, {"type": "wall" if name == "wall" else None}))
        if b.get("type") is None:
            raise FlowFileError(f"boundary tag {name!r} has no condition: give boundaries"
                                f"[{name!r}] = {{'type': 'wall' | 'inflow' | 'outflow' | "
                                "'open', ...}")
        if b["type"] not in ("wall", "inflow", "outflow", "open"):
            raise FlowFileError(f"boundary {name!r}: type {b['type']!r} unknown (wall, inflow, "
                                "outflow, open)")
        spec[name] = (b, edges)
    unknown = set(boundaries or {}) - set(spec)
    if unknown:
        raise FlowFileError(f"boundaries {sorted(unknown)} name no boundary tag of the mesh "
                            f"(tags with edges: {sorted(spec)})")
    return spec


def write_shallow_water_case(case_dir, mesh: Mesh, bed=None, boundaries=None, depth=None,
                             level=None, velocity=(0.0, 0.0), end_time=10.0, write_interval=1.0,
                             courant=0.5, dt=None, gravity=9.81, thickness=1.0,
                             n_procs=1, write_format="ascii", compression=False):
    """Write a shallowWaterFoam case.

    The mesh, the bed (constant/h0), initial and boundary fields, the system dictionaries.

    Parameters
    ----------
    mesh : Mesh
        2D mesh; its boundary tags name the conditions in ``boundaries``.
    bed : array (n_faces,) or float, optional
        Bed elevation on faces (m); default: the mesh's ``face_bed()`` or 0.
    boundaries : dict tag -> dict
        ``{'type': 'inflow', 'discharge': 2.0}``, ``{'type': 'outflow', 'level': 1.0}``...
        (see the module's table).  Untagged edges (tag 'wall') are walls.
    depth, level : float or array (n_faces,)
        Initial depth, or initial water level (depth = level - bed); must be > 0 everywhere.
    velocity : (u, v) or array (n_faces, 2)
        Initial velocity (m/s).
    end_time, write_interval : float
        Simulated time and the interval between written times (s); end_time is rounded up to
        a whole number of intervals.
    courant : float
        Time step from courant * min(cell size) / max(|u| + sqrt(g h)), unless ``dt`` is given;
        either way rounded so that a whole number of steps fills a write interval.
    n_procs : int
        Writes system/decomposeParDict for that many processors.
    write_format, compression : str, bool
        How shallowWaterFoam writes its results (ascii or binary; gzip or not).

    Returns
    -------
    dict with the case path, the time step and the patch names.
    """
    case = Path(case_dir)
    clean_case(case)
    nf = mesh.n_faces
    if bed is None:
        bed = mesh.face_bed() if mesh.node_z is not None else np.zeros(nf)
    bed = np.broadcast_to(np.asarray(bed, float), (nf,)).copy()
    if (depth is None) == (level is None):
        raise FlowFileError("give the initial depth or the initial level (one of them)")
    h = (np.broadcast_to(np.asarray(depth, float), (nf,)).copy() if depth is not None
         else np.asarray(level, float) - bed)
    h = np.broadcast_to(h, (nf,)).copy()
    if not np.all(h > 0):
        bad = np.flatnonzero(~(h > 0))
        raise FlowFileError(f"initial depth must be > 0 on every face for shallowWaterFoam "
                            f"(U = hU/h): {bad.size} faces have h <= 0, e.g. {bad[:5].tolist()}")
    vel = np.broadcast_to(np.asarray(velocity, float), (nf, 2))
    spec = _boundary_spec(mesh, boundaries)
    g = float(gravity)
    hmax = h.max()
    speed = np.hypot(vel[:, 0], vel[:, 1]).max()
    hb, hub = {}, {}
    for name, (b, edges) in spec.items():
        typ = b["type"]
        out_n = mesh.edge_normal[edges]  # out of the domain for boundary edges
        length = mesh.edge_length[edges]
        if typ == "wall":
            hb[name] = {"type": "zeroGradient"}
            hub[name] = {"type": "slip"}
        elif typ == "open":
            hb[name] = {"type": "zeroGradient"}
            hub[name] = {"type": "zeroGradient"}
        elif typ == "outflow":
            hb[name], hout = _fixed_depth(name, b, bed[mesh.edge_faces[edges, 0]])
            hub[name] = {"type": "zeroGradient"}
            hmax = max(hmax, hout.max())
        else:  # inflow
            if "discharge" in b:
                q = float(b["discharge"]) / length.sum()
                qv = -q * out_n
            elif "discharge_series" in b:
                ser = _series(name, b["discharge_series"], "discharge_series")
                qv = -float(np.max(np.abs(ser[:, 1]))) / length.sum() * out_n
            elif "unit_discharge" in b:
                qv = -float(b["unit_discharge"]) * out_n
            elif "velocity" in b:
                if "depth" not in b:
                    raise FlowFileError(f"boundary {name!r}: inflow velocity needs 'depth' (m): "
                                        "shallowWaterFoam imposes the unit discharge hU")
                v = np.asarray(b["velocity"], float)
                uvec = -float(v) * out_n if v.ndim == 0 else np.broadcast_to(v, out_n.shape)
                qv = float(b["depth"]) * uvec
                hmax = max(hmax, float(b["depth"]))
            else:
                raise FlowFileError(f"boundary {name!r}: inflow needs 'discharge' (m3/s), "
                                    "'unit_discharge' (m2/s) or 'velocity' (m/s) with 'depth'")
            hb[name] = {"type": "zeroGradient"}
            if "discharge_series" in b:  # Q(t) spread uniformly over the patch's area
                table = " ".join(f"({t:.17g} {q / thickness:.17g})" for t, q in ser)
                hub[name] = {"type": "flowRateInletVelocity",
                             "volumetricFlowRate": f"table ({table})",
                             "value": "uniform (0 0 0)"}
            else:
                hub[name] = {"type": "fixedValue",
                             "value": _nonuniform(np.column_stack([qv, np.zeros(len(edges))]),
                                                  vector=True)}
            speed = max(speed, float(np.max(np.hypot(qv[:, 0], qv[:, 1]) / np.maximum(
                h[mesh.edge_faces[edges, 0]], 1e-12))))
    empty = {"type": "empty"}
    patches = write_polymesh(case, mesh, thickness=thickness)
    hb["frontAndBack"] = empty
    hub["frontAndBack"] = empty
    hu0 = np.column_stack([h * vel[:, 0], h * vel[:, 1], np.zeros(nf)])
    for cls, obj, body, loc in (
            _field("volScalarField", "h", "[0 1 0 0 0 0 0]", h, hb),
            _field("volVectorField", "hU", "[0 2 -1 0 0 0 0]", hu0, hub)):
        write_foam_file(case / "0" / obj, cls, obj, body, loc)
    h0b = {p: ({"type": "zeroGradient"} if p != "frontAndBack" else empty) for p in patches}
    cls, obj, body, loc = _field("volScalarField", "h0", "[0 1 0 0 0 0 0]", bed, h0b,
                                 "constant")
    write_foam_file(case / "constant" / "h0", cls, obj, body, loc)
    write_foam_file(case / "constant" / "gravitationalProperties", "dictionary",
                    "gravitationalProperties",
                    f"g g [0 1 -2 0 0 0 0] (0 0 {-g:.17g});\nrotating false;\n"
                    "Omega Omega [0 0 -1 0 0 0 0] (0 0 0);", "constant")
    if dt is None:
        size = 2.0 * mesh.face_inradius.min()
        dt = courant * size / (speed + np.sqrt(g * hmax))
    steps_per_write = max(int(np.ceil(write_interval / dt - 1e-9)), 1)
    dt = write_interval / steps_per_write
    n_writes = max(int(np.ceil(end_time / write_interval - 1e-9)), 1)
    end = n_writes * write_interval
    control = f"""application     shallowWaterFoam;
startFrom       startTime;
startTime       0;
stopAt          endTime;
endTime         {end:.17g};
deltaT          {dt:.17g};
writeControl    timeStep;
writeInterval   {steps_per_write};
purgeWrite      0;
writeFormat     {write_format};
writePrecision  12;
writeCompression {"on" if compression else "off"};
timeFormat      general;
timePrecision   10;
runTimeModifiable false;"""
    write_foam_file(case / "system" / "controlDict", "dictionary", "controlDict", control,
                    "system")
    write_foam_file(case / "system" / "fvSchemes", "dictionary", "fvSchemes", _FV_SCHEMES,
                    "system")
    write_foam_file(case / "system" / "fvSolution", "dictionary", "fvSolution", _FV_SOLUTION,
                    "system")
    write_foam_file(case / "system" / "decomposeParDict", "dictionary", "decomposeParDict",
                    f"numberOfSubdomains {int(n_procs)};\nmethod simple;\n"
                    f"coeffs {{ n ({int(n_procs)} 1 1); delta 0.001; }}\n"
                    f"simpleCoeffs {{ n ({int(n_procs)} 1 1); delta 0.001; }}", "system")
    return {"case": case, "dt": dt, "end_time": end, "steps_per_write": steps_per_write,
            "patches": patches}


def _series(name, series, key):
    a = np.asarray(series, float)
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 1 or np.any(np.diff(a[:, 0]) <= 0):
        raise FlowFileError(f"boundary {name!r}: {key} must be [[t, value], ...] with t "
                            "increasing")
    return a


def _fixed_depth(name, b, bed):
    """Depth on a boundary with an imposed level or depth (constant or a series in time)."""
    keys = [k for k in ("level", "depth", "level_series", "depth_series") if k in b]
    if len(keys) != 1:
        raise FlowFileError(f"boundary {name!r}: outflow needs one of 'level' (m), 'depth' "
                            "(m), 'level_series' or 'depth_series' ([[t, m], ...])")
    key = keys[0]
    if key.endswith("_series"):
        ser = _series(name, b[key], key)
        if key == "level_series":
            if np.ptp(bed) > 1e-9 * max(1.0, np.abs(bed).max()):
                raise FlowFileError(f"boundary {name!r}: a level series needs a flat bed along "
                                    f"the boundary (bed from {bed.min():g} to {bed.max():g} m): "
                                    "OpenFOAM's uniformFixedValue imposes one depth on a patch")
            ser = np.column_stack([ser[:, 0], ser[:, 1] - bed[0]])
        if np.any(ser[:, 1] <= 0):
            raise FlowFileError(f"boundary {name!r}: {key} gives depths <= 0 (shallowWaterFoam "
                                "needs water on every face)")
        table = " ".join(f"({t:.17g} {v:.17g})" for t, v in ser)
        return ({"type": "uniformFixedValue", "uniformValue": f"table ({table})",
                 "value": f"uniform {ser[0, 1]:.17g}"}, np.full(bed.size, ser[:, 1].max()))
    hout = (float(b["level"]) - bed) if key == "level" else np.full(bed.size, float(b["depth"]))
    if np.any(hout <= 0):
        raise FlowFileError(f"boundary {name!r}: {key} {b[key]} leaves no water on "
                            f"{np.sum(hout <= 0)} edges (level below the bed, or depth <= 0)")
    return {"type": "fixedValue", "value": _nonuniform(hout)}, hout




# --------------------------------------------------------------------- running
def _run(args, case, log_name, env, timeout):
    log = Path(case) / f"log.{log_name}"
    with open(log, "w") as f:
        try:
            proc = subprocess.run(args, cwd=case, env=env, stdout=f, stderr=subprocess.STDOUT,
                                  timeout=timeout)
        except subprocess.TimeoutExpired:
            raise OpenFOAMError(f"{case}: {args[0]} ran past {timeout} s (log: {log})") from None
    if proc.returncode != 0:
        tail = log.read_text(errors="replace").strip().splitlines()[-15:]
        raise OpenFOAMError(f"{case}: {' '.join(args)} failed (exit {proc.returncode}); end of "
                            f"{log}:\n" + "\n".join(tail))
    return log


def run_case(case_dir, solver="shallowWaterFoam", n_procs=1, timeout=600, reconstruct=False):
    """Run a case: serial, or decomposePar + ``mpirun -np n_procs solver -parallel``."""
    env = foam_env()
    if env is None:
        raise OpenFOAMError(f"OpenFOAM is not installed (no {BASHRC}; on Debian: apt-get "
                            "install openfoam)")
    case = Path(case_dir).resolve()  # the tools run in it: a relative -case would double
    if n_procs <= 1:
        _run([solver, "-case", str(case)], case, solver, env, timeout)
        return case
    mpirun = shutil.which("mpirun", path=env.get("PATH"))
    if mpirun is None:
        raise OpenFOAMError("mpirun not found: cannot run a decomposed case")
    h0 = case / "constant" / "h0"
    if h0.is_file():  # decomposePar decomposes time directories only
        shutil.copy(h0, case / "0" / "h0")
    for d in case.glob("processor*"):
        shutil.rmtree(d)
    try:
        _run(["decomposePar", "-case", str(case)], case, "decomposePar", env, timeout)
    finally:
        if (case / "0" / "h0").is_file():
            (case / "0" / "h0").unlink()
    for d in case.glob("processor*"):
        if (d / "0" / "h0").is_file():
            (d / "constant").mkdir(exist_ok=True)
            shutil.move(d / "0" / "h0", d / "constant" / "h0")
    env = dict(env, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_mpi_yield_when_idle="1")
    _run([mpirun, "-np", str(int(n_procs)), solver, "-parallel", "-case", str(case)], case,
         solver, env, timeout)
    if reconstruct:
        _run(["reconstructPar", "-case", str(case)], case, "reconstructPar", env, timeout)
    return case


def run_shallow_water(case_dir, mesh: Mesh, n_procs=1, timeout=600, dry_depth=1e-3,
                      reconstruct=False, **case_options):
    """Write, run and read back a shallowWaterFoam case; returns the MeshFlowField.

    ``case_options`` are those of ``write_shallow_water_case``.
    """
    from .openfoam import open_openfoam

    info = write_shallow_water_case(case_dir, mesh, n_procs=n_procs, **case_options)
    run_case(case_dir, n_procs=n_procs, timeout=timeout, reconstruct=reconstruct)
    field = open_openfoam(case_dir, dry_depth=dry_depth,
                          decomposed=(n_procs > 1 and not reconstruct))
    field.attrs["openfoam_dt"] = info["dt"]
    return field
