"""Set up and run a small interFoam (VOF, 3D) channel from a driftlog 2D mesh.

The 3D route to a driftlog flow: the 2D mesh (a channel with an obstacle cut out, say) is
extruded into ``n_layers`` cells over a flat bed up to a lid at ``height`` (prisms and
hexahedra, written directly as a polyMesh), water fills it to ``level`` moving at
``velocity``, and interFoam runs it; ``driftlog.adapters.openfoam.open_openfoam`` then
depth-averages the 3D result back onto the 2D mesh (column by column: sum(h A) = sum(alpha V)).

Boundary conditions, by the 2D mesh's boundary tags:

==========  ======================================  ==========================================
tag          alpha.water                             U / p_rgh
==========  ======================================  ==========================================
inflow       fixedValue: water up to ``level``        U fixedValue: discharge / (width x level)
                                                     in the water; p_rgh fixedFluxPressure
outflow      zeroGradient                            U pressureInletOutletVelocity; p_rgh
                                                     fixedValue hydrostatic for ``level``:
                                                     (rho_w - rho_a) g level in the water, 0
                                                     above (OpenFOAM's p_rgh = p + rho g z)
wall (and    zeroGradient                            U slip (no friction, as the shallow-water
bed)                                                 solution it is compared with); p_rgh
                                                     fixedFluxPressure
lid          inletOutlet 0 (air comes in)            U pressureInletOutletVelocity; p_rgh
(atmosphere)                                         totalPressure 0
==========  ======================================  ==========================================

Laminar, Euler in time, adjustable time step (maxCo 0.5); the schemes of the damBreak tutorial.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError
from driftlog.mesh import Mesh

from ._foam_case import clean_case
from .foam_io import format_list, write_foam_file, write_polymesh_files

__all__ = ["channel_with_block", "write_extruded_polymesh", "write_interfoam_channel",
           "run_interfoam_channel"]

RHO_WATER, RHO_AIR = 1000.0, 1.0


def channel_with_block(length, width, cell_size, block, x0=0.0, y0=0.0) -> Mesh:
    """A channel of squares with a rectangular obstacle ``block`` = (x0, y0, x1, y1) cut out.

    Squares (hexahedra once extruded: interFoam runs well on them, where the prisms of a
    triangle mesh with non-orthogonal faces need more care); the obstacle's sides should lie
    on grid lines (cells whose centre is inside are removed).  Tags as ``channel_mesh``: x0
    side ``inflow``, the other end ``outflow``, banks and obstacle ``wall``.
    """
    nx = max(int(round(length / cell_size)), 1)
    ny = max(int(round(width / cell_size)), 1)
    g = Mesh.regular_grid(nx, ny, length / nx, width / ny, x0, y0)
    bx0, by0, bx1, by1 = block
    inside = (g.face_x > bx0) & (g.face_x < bx1) & (g.face_y > by0) & (g.face_y < by1)
    if not inside.any() or inside.all():
        raise FlowFileError(f"obstacle {tuple(block)} removes no cell, or all of them, from the "
                            f"{length} x {width} m channel")
    fn = g.face_nodes[~inside]
    used = np.unique(fn[fn >= 0])
    node = np.full(g.n_nodes, -1, np.int64)
    node[used] = np.arange(used.size)
    mesh = Mesh(g.node_x[used], g.node_y[used], node[fn])
    eps = 1e-9 * length
    mesh.tag_boundary("inflow", lambda x, y: x < x0 + eps)
    mesh.tag_boundary("outflow", lambda x, y: x > x0 + length - eps)
    return mesh


def write_extruded_polymesh(case_dir, mesh: Mesh, z_levels, bottom="bed", top="atmosphere"):
    """Write ``constant/polyMesh`` of the 2D mesh extruded through ``z_levels`` (increasing).

    Cell ``k * n_faces + f`` is face f of the mesh in layer k.  Boundary edges become patches
    named by their tags (one patch per tag over all layers; 'wall' typed wall), then the
    ``bottom`` (wall) and ``top`` (patch) patches.  Returns the patch names in order.
    """
    z = np.asarray(z_levels, float)
    if z.ndim != 1 or z.size < 2 or np.any(np.diff(z) <= 0):
        raise FlowFileError(f"z_levels must increase, at least 2 levels: {z.tolist()}")
    folder = Path(case_dir) / "constant" / "polyMesh"
    folder.mkdir(parents=True, exist_ok=True)
    nn, nf, nl = mesh.n_nodes, mesh.n_faces, z.size - 1
    pts = np.vstack([np.column_stack([mesh.node_x, mesh.node_y, np.full(nn, zk)]) for zk in z])
    ef, en = mesh.edge_faces, mesh.edge_nodes
    faces, owner, nbr = [], [], []
    # internal faces: lateral (between faces of a layer) and horizontal (between layers)
    inner = np.flatnonzero(ef[:, 1] >= 0)
    for k in range(nl):
        for e in inner:
            a, b = en[e]
            o, n2 = sorted((ef[e, 0], ef[e, 1]))
            q = [a + k * nn, b + k * nn, b + (k + 1) * nn, a + (k + 1) * nn]
            faces.append(q if ef[e, 0] == o else q[::-1])  # normal out of edge_faces[e, 0]
            owner.append(k * nf + o)
            nbr.append(k * nf + n2)
    for k in range(nl - 1):
        for f in range(nf):
            fn = mesh.face_nodes[f, :mesh.face_n[f]]
            faces.append((fn + (k + 1) * nn).tolist())  # counter-clockwise from above: up
            owner.append(k * nf + f)
            nbr.append((k + 1) * nf + f)
    order = np.lexsort((np.array(nbr), np.array(owner)))
    faces = [faces[i] for i in order]
    owner = np.array(owner)[order].tolist()
    nbr_sorted = np.array(nbr)[order]
    patches = []
    for tag_id, name in enumerate(mesh.tag_names):
        edges = np.flatnonzero((mesh.edge_tag == tag_id) & (ef[:, 1] < 0))
        if edges.size == 0:
            continue
        start = len(faces)
        for k in range(nl):
            for e in edges:
                a, b = en[e]
                faces.append([a + k * nn, b + k * nn, b + (k + 1) * nn, a + (k + 1) * nn])
                owner.append(k * nf + ef[e, 0])
        patches.append((name, "wall" if name == "wall" else "patch", start, nl * edges.size))
    start = len(faces)
    for f in range(nf):
        faces.append(mesh.face_nodes[f, :mesh.face_n[f]][::-1].tolist())  # down
        owner.append(f)
    patches.append((bottom, "wall", start, nf))
    start = len(faces)
    for f in range(nf):
        faces.append((mesh.face_nodes[f, :mesh.face_n[f]] + nl * nn).tolist())  # up
        owner.append((nl - 1) * nf + f)
    patches.append((top, "patch", start, nf))
    return write_polymesh_files(folder, pts, faces, owner, nbr_sorted, patches, nf * nl)


def _fraction(z0, z1, level):
    """Fraction of [z0, z1] below ``level``."""
    return np.clip((level - z0) / (z1 - z0), 0.0, 1.0)


def _uniform_or_list(values, vector=False):
    a = np.asarray(values, float)
    kind = "vector" if vector else "scalar"
    return f"nonuniform List<{kind}> {format_list(a)}"


_SCHEMES = """ddtSchemes { default Euler; }
gradSchemes { default Gauss linear; }
divSchemes
{
    div(rhoPhi,U) Gauss linearUpwind grad(U);
    div(phi,alpha) Gauss vanLeer;
    div(phirb,alpha) Gauss linear;
    div(((rho*nuEff)*dev2(T(grad(U))))) Gauss linear;
}
laplacianSchemes { default Gauss linear corrected; }
interpolationSchemes { default linear; }
snGradSchemes { default corrected; }"""

_SOLUTION = """solvers
{
    "alpha.water.*" { nAlphaCorr 2; nAlphaSubCycles 1; cAlpha 1; MULESCorr yes;
                      nLimiterIter 5; solver smoothSolver; smoother symGaussSeidel;
                      tolerance 1e-8; relTol 0; }
    "pcorr.*" { solver PCG; preconditioner DIC; tolerance 1e-5; relTol 0; }
    p_rgh { solver PCG; preconditioner DIC; tolerance 1e-07; relTol 0.05; }
    p_rghFinal { $p_rgh; relTol 0; }
    U { solver smoothSolver; smoother symGaussSeidel; tolerance 1e-06; relTol 0; }
}
PIMPLE { momentumPredictor no; nOuterCorrectors 1; nCorrectors 3;
         nNonOrthogonalCorrectors 0; }
relaxationFactors { equations { ".*" 1; } }"""


def write_interfoam_channel(case_dir, mesh: Mesh, level, discharge, height, n_layers,
                            velocity=None, end_time=10.0, write_interval=1.0, gravity=9.81,
                            max_courant=0.5):
    """Write an interFoam case of a flat-bed channel (bed at z = 0) from a 2D mesh.

    Parameters
    ----------
    mesh : Mesh
        2D mesh with boundary tags ``inflow``, ``outflow`` and walls (``channel_mesh``).
    level : float
        Water level (m) at the start everywhere and imposed at the outflow.
    discharge : float
        Inflow (m3/s), uniform over the water part of the inflow patch.
    height : float
        Lid of the domain (m), above ``level``; ``n_layers`` cells from 0 to it.
    velocity : float, optional
        Initial velocity along +x in the water (default: discharge / (inflow width x level)).
    end_time, write_interval : float
        Simulated time and interval between written times (s).

    Returns
    -------
    dict: case path, z levels, number of cells, the inflow velocity.
    """
    case = Path(case_dir)
    clean_case(case)
    if not 0 < level < height:
        raise FlowFileError(f"interFoam channel: level {level} m must lie between the bed (0) "
                            f"and the lid (height {height} m)")
    for tag in ("inflow", "outflow"):
        if tag not in mesh.tag_names or mesh.edges_with_tag(tag).size == 0:
            raise FlowFileError(f"interFoam channel: the mesh has no {tag!r} boundary edges "
                                f"(tags: {mesh.tag_names})")
    z = np.linspace(0.0, float(height), int(n_layers) + 1)
    patches = write_extruded_polymesh(case, mesh, z)
    nf, nl = mesh.n_faces, int(n_layers)
    zc0, zc1 = np.repeat(z[:-1], nf), np.repeat(z[1:], nf)
    alpha = _fraction(zc0, zc1, level)
    inflow_edges = mesh.edges_with_tag("inflow")
    width = float(mesh.edge_length[inflow_edges].sum())
    u_in = float(discharge) / (width * level)
    u0 = u_in if velocity is None else float(velocity)
    U = np.zeros((nf * nl, 3))
    U[:, 0] = u0 * alpha
    # per boundary face, layer by layer (the order write_extruded_polymesh gives them)

    def layer_fraction(edges):
        return _fraction(np.repeat(z[:-1], edges.size), np.repeat(z[1:], edges.size), level)

    a_in = layer_fraction(inflow_edges)
    a_out = layer_fraction(mesh.edges_with_tag("outflow"))
    g = float(gravity)
    bc_a, bc_u, bc_p = {}, {}, {}
    for name in patches:
        if name == "inflow":
            bc_a[name] = {"type": "fixedValue", "value": _uniform_or_list(a_in)}
            bc_u[name] = {"type": "fixedValue", "value": _uniform_or_list(
                np.column_stack([u_in * a_in, 0 * a_in, 0 * a_in]), vector=True)}
            bc_p[name] = {"type": "fixedFluxPressure", "value": "uniform 0"}
        elif name == "outflow":
            bc_a[name] = {"type": "zeroGradient"}
            bc_u[name] = {"type": "pressureInletOutletVelocity", "value": "uniform (0 0 0)"}
            bc_p[name] = {"type": "fixedValue",
                          "value": _uniform_or_list((RHO_WATER - RHO_AIR) * g * level * a_out)}
        elif name == "atmosphere":
            bc_a[name] = {"type": "inletOutlet", "inletValue": "uniform 0", "value": "uniform 0"}
            bc_u[name] = {"type": "pressureInletOutletVelocity", "value": "uniform (0 0 0)"}
            bc_p[name] = {"type": "totalPressure", "p0": "uniform 0", "value": "uniform 0"}
        else:  # banks, obstacle walls, the bed: frictionless
            bc_a[name] = {"type": "zeroGradient"}
            bc_u[name] = {"type": "slip"}
            bc_p[name] = {"type": "fixedFluxPressure", "value": "uniform 0"}

    def field(cls, obj, dims, internal, bcs):
        kind = "vector" if cls == "volVectorField" else "scalar"
        body = [f"dimensions      {dims};", "",
                f"internalField   nonuniform List<{kind}>\n{format_list(internal)};", "",
                "boundaryField", "{"]
        for name, entries in bcs.items():
            body += [f"    {name}", "    {"]
            body += [f"        {k:<15} {v};" for k, v in entries.items()]
            body.append("    }")
        body.append("}")
        write_foam_file(case / "0" / obj, cls, obj, "\n".join(body), "0")

    field("volScalarField", "alpha.water", "[0 0 0 0 0 0 0]", alpha, bc_a)
    field("volVectorField", "U", "[0 1 -1 0 0 0 0]", U, bc_u)
    # hydrostatic start: p_rgh = p + rho g z is (rho_w - rho_a) g level in the water
    field("volScalarField", "p_rgh", "[1 -1 -2 0 0 0 0]",
          (RHO_WATER - RHO_AIR) * g * level * alpha, bc_p)
    write_foam_file(case / "constant" / "g", "uniformDimensionedVectorField", "g",
                    f"dimensions [0 1 -2 0 0 0 0];\nvalue (0 0 {-g:.17g});", "constant")
    write_foam_file(case / "constant" / "transportProperties", "dictionary",
                    "transportProperties",
                    "phases (water air);\n"
                    f"water {{ transportModel Newtonian; nu 1e-06; rho {RHO_WATER:g}; }}\n"
                    f"air {{ transportModel Newtonian; nu 1.48e-05; rho {RHO_AIR:g}; }}\n"
                    "sigma 0.07;", "constant")
    write_foam_file(case / "constant" / "turbulenceProperties", "dictionary",
                    "turbulenceProperties", "simulationType laminar;", "constant")
    size = 2.0 * float(mesh.face_inradius.min())
    dt0 = 0.1 * min(size, z[1] - z[0]) / max(abs(u0), abs(u_in), 0.1)
    control = f"""application     interFoam;
startFrom       startTime;
startTime       0;
stopAt          endTime;
endTime         {float(end_time):.17g};
deltaT          {dt0:.6g};
writeControl    adjustableRunTime;
writeInterval   {float(write_interval):.17g};
purgeWrite      0;
writeFormat     binary;
writePrecision  10;
writeCompression off;
timeFormat      general;
timePrecision   8;
runTimeModifiable no;
adjustTimeStep  yes;
maxCo           {max_courant:g};
maxAlphaCo      {max_courant:g};
maxDeltaT       {float(write_interval):.17g};"""
    write_foam_file(case / "system" / "controlDict", "dictionary", "controlDict", control,
                    "system")
    write_foam_file(case / "system" / "fvSchemes", "dictionary", "fvSchemes", _SCHEMES,
                    "system")
    write_foam_file(case / "system" / "fvSolution", "dictionary", "fvSolution", _SOLUTION,
                    "system")
    return {"case": case, "z": z, "n_cells": nf * nl, "inflow_velocity": u_in,
            "patches": patches}


def run_interfoam_channel(case_dir, mesh: Mesh, timeout=600, dry_depth=1e-3, **options):
    """Write and run the interFoam channel; return its flow depth-averaged onto ``mesh``.

    ``options`` are those of ``write_interfoam_channel``.  Each face of ``mesh`` gets the
    column of cells above it (the cells whose centroid lies in it): sum(h A) = sum(alpha V).
    """
    from .openfoam import open_openfoam
    from .openfoam_case import run_case

    info = write_interfoam_channel(case_dir, mesh, **options)
    run_case(case_dir, solver="interFoam", timeout=timeout)
    field = open_openfoam(case_dir, mode="vof", mesh2d=mesh, dry_depth=dry_depth)
    field.attrs["interfoam_cells"] = info["n_cells"]
    return field
