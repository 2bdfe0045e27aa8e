"""Solving a scenario's flow: the ``[solver]`` section's checks, mesh, solver and runs.

The keys are declared here (``SOLVER_SECTION``, ``driftlog scenario keys --section solver``).

    [flow]
    source = "solver"
    path = "flow.nc"                  # where the computed flow is kept (reused when current)

    [solver]
    mesh = "channel"
    channel = [0.0, 0.0, 10.0, 1.0]   # x0, y0, length, width (m)
    cell_size = 0.05
    piers = [[5.0, 0.5, 0.05]]        # circular piers: x, y, radius (holes, tagged wall)
    bed = "slope"
    slope = 0.001
    manning = 0.012
    end = 60.0
    output_interval = 1.0
    [solver.boundaries.inflow]
    type = "discharge"
    value = 0.018                     # or series = [[t, Q], ...]
    [solver.boundaries.outflow]
    type = "froude"
    value = 0.18
    [solver.initial]
    type = "level"
    value = 0.05

A flow computed from a ``[solver]`` section stores a hash of the section in its attributes
(``solver_hash``); ``driftlog.solving.flow_from_scenario`` reuses the file when the hash
matches and it reaches the end time, resumes it when it stopped early, and recomputes it
otherwise.

``engine = "shallowWaterFoam"`` computes the same section with OpenFOAM instead
(``driftlog.adapters.openfoam_engine``): its flow file is ``[flow] path`` with
``_shallowWaterFoam`` added to the stem, reused by the same hash (the engine, ``n_procs`` and
``openfoam_friction`` included), recomputed from scratch otherwise (no resuming).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from driftlog.errors import ScenarioError
from driftlog.flow import DRY_DEPTH_MAX
from driftlog.schema import Key, Section
from driftlog.solver.boundaries import KINDS, as_boundary

__all__ = ["build_mesh", "build_solver", "solver_hash", "check_solver_section", "partial_path",
           "estimate_mesh", "INITIAL_TYPES"]

INITIAL_TYPES = ("dry", "level", "depth", "file")
INITIAL_KEYS = ("type", "value", "polygon", "outside", "velocity", "path", "time")


def check_solver_section(t, prefix, scen):
    """Cross-key checks of the [solver] section (the ``check`` of ``SOLVER_SECTION``)."""
    flow = scen.get("flow") or {}
    if flow.get("source") != "solver" and t["end"] is None:
        return  # not used
    if t["end"] is None:
        raise ScenarioError(f"{prefix}.end", None, "is required when [flow] source = 'solver': "
                            "the end time of the computation (s)")
    if not t["end"] > t["start"]:
        raise ScenarioError(f"{prefix}.end", t["end"], f"must be after {prefix}.start = "
                            f"{t['start']:g} s (nothing to compute)")
    from driftlog.solver.run import check_snapshots

    check_snapshots(t["start"], t["end"], t["output_interval"], f"{prefix}.output_interval")
    if t.get("energy_bound", "off") != "off" and t["order"] != 2:
        raise ScenarioError(f"{prefix}.energy_bound", t["energy_bound"], "applies at order 2 "
                            "only")
    if t["mesh"] == "file" and not t["mesh_file"]:
        raise ScenarioError(f"{prefix}.mesh_file", "", "is required when mesh = 'file'")
    if t["mesh"] == "channel":
        if t["channel"] is None:
            raise ScenarioError(f"{prefix}.channel", None, "is required when mesh = 'channel': "
                                "[x0, y0, length, width] (m)")
        if t["channel"][2] <= 0 or t["channel"][3] <= 0:
            raise ScenarioError(f"{prefix}.channel", t["channel"], "length and width must be > 0")
        if t["cell_size"] is None:
            raise ScenarioError(f"{prefix}.cell_size", None, "is required when mesh = 'channel'")
    if t["mesh"] == "polygon":
        _check_outline(t, prefix)
    if t["bed"] == "mesh" and t["mesh"] != "file":
        raise ScenarioError(f"{prefix}.bed", "mesh", "bed = 'mesh' needs mesh = 'file' (node "
                            "elevations of the mesh file)")
    if t["bed"] == "profile" and (t["bed_profile"] is None or len(t["bed_profile"]) < 2
                                  or np.any(np.diff([p[0] for p in t["bed_profile"]]) <= 0)):
        raise ScenarioError(f"{prefix}.bed_profile", t["bed_profile"], "bed = 'profile' needs "
                            "at least two [x, z] points with x increasing")
    if t["manning"] is not None and t["strickler"] is not None:
        raise ScenarioError(f"{prefix}.strickler", t["strickler"], "give manning or "
                            "strickler, not both")
    for i, p in enumerate(t["piers"] or []):
        if (not isinstance(p, list) or len(p) != 3
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in p)
                or p[2] <= 0):
            raise ScenarioError(f"{prefix}.piers[{i}]", p, "must be [x, y, radius] with "
                                "radius > 0 (m)")
    for i, h in enumerate(t["holes"] or []):
        a = np.asarray(h, dtype=object)
        if (a.ndim != 2 or a.shape[0] < 3 or a.shape[1] != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           and np.isfinite(v) for v in a.ravel())):
            raise ScenarioError(f"{prefix}.holes[{i}]", h, "must be a polygon [[x, y], ...] "
                                "of at least 3 points")
    if t["mesh"] in ("channel", "polygon") and not (t["mesh"] == "channel" and t["structured"]):
        _check_rings(t, prefix)
    for tag, spec in (t["boundaries"] or {}).items():
        if not isinstance(spec, dict):
            raise ScenarioError(f"{prefix}.boundaries.{tag}", spec, "must be a table with "
                                "type = " + " | ".join(KINDS))
        as_boundary(spec, f"{prefix}.boundaries.{tag}")
    _check_initial(t["initial"] or {}, f"{prefix}.initial")
    if t.get("sea"):
        from driftlog.solver.sea import check_sea

        check_sea(t["sea"], f"{prefix}.sea")
    if t["engine"] != "driftlog":
        from driftlog.adapters.openfoam_engine import check_engine_section

        check_engine_section(t, prefix)


def _check_outline(t, prefix):
    if t["outline"] is None:
        raise ScenarioError(f"{prefix}.outline", None, "is required when mesh = 'polygon': "
                            "[[x, y], ...] (at least 3 points)")
    if t["cell_size"] is None:
        raise ScenarioError(f"{prefix}.cell_size", None, "is required when mesh = 'polygon'")
    n = len(t["outline"])
    for tag, sides in (t["side_tags"] or {}).items():
        if not isinstance(sides, list) or not sides or not all(
                isinstance(i, int) and not isinstance(i, bool) and 0 <= i < n for i in sides):
            raise ScenarioError(f"{prefix}.side_tags.{tag}", sides, f"must be a list of side "
                                f"indices 0 to {n - 1} (side i runs from outline point i to i + 1)")


def _check_initial(ini, key):
    for k in ini:
        if k not in INITIAL_KEYS:
            raise ScenarioError(f"{key}.{k}", ini[k], "unknown key; [solver.initial] has "
                                + ", ".join(INITIAL_KEYS))
    kind = ini.get("type", "dry")
    if kind not in INITIAL_TYPES:
        raise ScenarioError(f"{key}.type", kind, "must be one of "
                            + ", ".join(repr(k) for k in INITIAL_TYPES))
    if kind in ("level", "depth"):
        v = ini.get("value")
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ScenarioError(f"{key}.value", v, f"initial type {kind!r} needs a number (m)")
        if kind == "depth" and v < 0:
            raise ScenarioError(f"{key}.value", v, "a depth must be >= 0 m")
    if kind == "file" and not ini.get("path"):
        raise ScenarioError(f"{key}.path", None, "initial type 'file' needs the path of a "
                            "flow file on the same mesh")
    if "polygon" in ini:
        p = ini["polygon"]
        if (not isinstance(p, list) or len(p) < 3
                or not all(isinstance(q, list) and len(q) == 2 for q in p)):
            raise ScenarioError(f"{key}.polygon", p, "must be [[x, y], ...] with >= 3 points")
    if "velocity" in ini:
        v = ini["velocity"]
        if not isinstance(v, list) or len(v) != 2:
            raise ScenarioError(f"{key}.velocity", v, "must be [u, v] (m/s)")


def _check_rings(t, prefix):
    """The outline (or channel), piers and holes as the mesher needs them.

    No side crossing or touching another (Triangle fails on them, or crashes the process),
    every pier and hole inside the outline and outside the others (a pier outside the channel
    was left out of the mesh without a word).
    """
    from driftlog.mesher import circle, find_crossing, find_misplaced_hole, rectangle

    if t["mesh"] == "polygon":
        rings, keys, values = [np.asarray(t["outline"], float)], [f"{prefix}.outline"], \
            [t["outline"]]
    else:
        x0, y0, length, width = t["channel"]
        rings, keys, values = [rectangle(x0, y0, x0 + length, y0 + width)], \
            [f"{prefix}.channel"], [t["channel"]]
    polygons = {0}  # rings whose sides the message numbers (not the piers' circles)
    for i, p in enumerate(t["piers"] or []):
        rings.append(circle((p[0], p[1]), p[2], t["cell_size"]))
        keys.append(f"{prefix}.piers[{i}]")
        values.append(p)
    for i, h in enumerate(t["holes"] or []):
        polygons.add(len(rings))
        rings.append(np.asarray(h, float))
        keys.append(f"{prefix}.holes[{i}]")
        values.append(h)

    def side(k, i):
        return f" (side {i}, from point {i} to point {(i + 1) % len(rings[k])})" \
            if k in polygons else ""

    crossing = find_crossing(rings)
    if crossing is not None:
        a, i, b, j = crossing
        what = (f"crosses itself: side {i} meets side {j} (side i runs from point i to point "
                "i + 1)" if a == b else f"crosses or touches {keys[a]}{side(a, i)}")
        raise ScenarioError(keys[b], values[b], f"{what}{side(b, j) if a != b else ''}; the "
                            "mesher needs simple polygons, piers and holes inside the outline "
                            "apart from it and from each other")
    misplaced = find_misplaced_hole(rings[0], rings[1:])
    if misplaced is not None:
        k, j = misplaced
        where = f"outside {keys[0]}" if j is None else f"inside {keys[j + 1]}"
        raise ScenarioError(keys[k + 1], values[k + 1], f"lies {where}: piers and holes must "
                            f"lie inside {keys[0]}, apart from each other")


def solver_hash(section) -> str:
    """A hash of the validated [solver] section (what decides whether a stored flow is current)."""
    if section["engine"] == "driftlog":  # keys of OpenFOAM runs only
        section = {k: v for k, v in section.items()
                   if k not in ("engine", "n_procs", "openfoam_friction")}
    for k, v in (("energy_bound", "off"), ("energy_widen", 0.0)):
        if section.get(k, v) == v:  # the default: the hashes from before the key
            section = {j: w for j, w in section.items() if j != k}
    text = json.dumps(section, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def build_mesh(sec):
    """The mesh of a [solver] section, node elevations set from its bed keys."""
    from driftlog.mesh import read_mesh
    from driftlog.mesher import channel_mesh, circle

    if sec["mesh"] == "file":
        mesh = read_mesh(sec["mesh_file"])
        x0 = float(mesh.node_x.min())
    elif sec["mesh"] == "polygon":
        from driftlog.mesher import polygon_mesh

        outline = np.asarray(sec["outline"], dtype=float)
        holes = [circle((p[0], p[1]), p[2], sec["cell_size"]) for p in sec["piers"] or []]
        holes += [np.asarray(h, dtype=float) for h in sec["holes"] or []]
        tags = {i: tag for tag, sides in (sec["side_tags"] or {}).items() for i in sides}
        mesh = polygon_mesh(outline, sec["cell_size"], holes=holes, side_tags=tags)
        x0 = float(outline[:, 0].min())
    else:
        x0, y0, length, width = sec["channel"]
        holes = [circle((p[0], p[1]), p[2], sec["cell_size"]) for p in sec["piers"] or []]
        holes += [np.asarray(h, dtype=float) for h in sec["holes"] or []]
        mesh = channel_mesh(length, width, sec["cell_size"], x0=x0, y0=y0, holes=holes,
                            structured=sec["structured"])
    x = mesh.node_x
    if sec["bed"] == "flat":
        mesh.node_z = np.full(mesh.n_nodes, sec["bed_level"])
    elif sec["bed"] == "slope":
        mesh.node_z = sec["bed_level"] - sec["slope"] * (x - x0)
    elif sec["bed"] == "profile":
        p = np.asarray(sec["bed_profile"], dtype=float)
        mesh.node_z = np.interp(x, p[:, 0], p[:, 1])
    elif mesh.node_z is None:
        raise ScenarioError("solver.bed", "mesh", f"{sec['mesh_file']} has no node elevations")
    return mesh


def build_solver(sec, mesh=None):
    """A ShallowWaterSolver from a validated [solver] section, with its initial state."""
    from driftlog.solver.model import ShallowWaterSolver

    mesh = build_mesh(sec) if mesh is None else mesh
    boundaries, coast = sec["boundaries"], None
    if sec.get("sea"):  # a sea found from the bed: its coast tagged, its water filled below
        from driftlog.solver.sea import apply_sea

        boundaries = dict(boundaries or {})
        coast = apply_sea(mesh, sec["sea"], boundaries)
    s = ShallowWaterSolver(mesh, order=sec["order"], riemann=sec["riemann"], cfl=sec["cfl"],
                           manning=sec["manning"], strickler=sec["strickler"],
                           dry_depth=sec["dry_depth"], boundaries=boundaries,
                           arrival_depth=sec["arrival_depth"],
                           energy_bound=sec.get("energy_bound", "off"),
                           energy_widen=sec.get("energy_widen", 0.0))
    ini = sec["initial"] or {}
    kind = ini.get("type", "dry")
    vel = ini.get("velocity", [0.0, 0.0])
    if kind == "file":
        s.set_from_flow(ini["path"], ini.get("time"))
        return s
    if kind == "level":
        h = np.maximum(float(ini["value"]) - s.bed, 0.0)
    elif kind == "depth":
        h = np.full(mesh.n_faces, float(ini["value"]))
    else:
        h = np.zeros(mesh.n_faces)
    if "polygon" in ini:
        h = np.where(mesh.faces_in_polygon(ini["polygon"]), h, 0.0)
    if coast is not None:
        from driftlog.solver.sea import fill_sea

        h = fill_sea(mesh, s.bed, h, float(sec["sea"]["level"]), coast)
    s.set_state(h, h * vel[0], h * vel[1], t=sec["start"])
    return s


def partial_path(path) -> Path:
    """Where the solver writes a flow file until it is complete (``NAME.partial``)."""
    path = Path(path)
    return path.with_name(path.name + ".partial")


def estimate_mesh(sec, max_cells=None):
    """Refuse (``SizeError``) a [solver] mesh too large to build, before the mesher runs.

    Cells ~ 1.55 area / (sqrt(3)/4 cell_size^2) for the triangle mesher (area over the area of
    an equilateral triangle of side cell_size, times 1.55 measured on the shipped cases); the
    memory of a solver run is about 1.5 kB per
    cell (mesh, state, fluxes, operators); the limit is half the machine's available memory,
    or ``max_cells``.  Returns the estimated number of cells.
    """
    from driftlog.errors import SizeError
    from driftlog.resources import available_memory

    if sec["mesh"] == "file":
        return None
    if sec["mesh"] == "polygon":
        o = np.asarray(sec["outline"], dtype=float)
        area = 0.5 * abs(np.dot(o[:, 0], np.roll(o[:, 1], 1))
                         - np.dot(o[:, 1], np.roll(o[:, 0], 1)))
    else:
        area = abs(sec["channel"][2] * sec["channel"][3])
    h = float(sec["cell_size"])
    # the mesher's triangles are smaller than equilateral ones of side cell_size (quality
    # constraints, refinement at piers): 1.55 x more, calibrated on the shipped cases
    # (river_piers 3562 cells, flume 16353)
    cells = 1.55 * area / (np.sqrt(3) / 4 * h * h)
    per_cell = 1500.0
    limit = max_cells if max_cells is not None else 0.5 * available_memory() / per_cell
    if cells > limit:
        raise SizeError(f"[solver.cell_size] = {h:g} m: about {cells:.3g} cells on "
                        f"{area:.4g} m2, more than this machine can hold ({limit:.3g} cells, "
                        f"~{per_cell:g} bytes each, half of the available memory); use a "
                        f"cell_size >= {h * np.sqrt(cells / limit):.3g} m")
    return cells


# --------------------------------------------------------------------- the scenario section
SOLVER_SECTION = Section("solver", [
    Key("engine", "str", "driftlog", "what computes the flow: driftlog's solver, or "
        "OpenFOAM's shallowWaterFoam on the same mesh, bed, initial state and boundaries "
        "(flow file [flow] path + '_shallowWaterFoam', case folder beside it)",
        choices=("driftlog", "shallowWaterFoam")),
    Key("n_procs", "int", 1, "processes of an OpenFOAM engine run (decomposePar + mpirun when "
        "> 1)", min=1),
    Key("openfoam_friction", "str", "refuse", "shallowWaterFoam has no bed friction: refuse a "
        "section with manning/strickler, or omit the friction in the OpenFOAM run (recorded in "
        "the flow's attributes)", choices=("refuse", "omit")),
    Key("mesh", "str", "channel", "the mesh: a channel built here, a polygon (outline with "
        "tagged sides) built here, or a mesh file", choices=("channel", "polygon", "file")),
    Key("outline", "points", None, "outer boundary [[x, y], ...] of mesh = 'polygon'; side i "
        "runs from point i to point i + 1 (the last back to the first)", "m", length=3,
        when="mesh = polygon"),
    Key("side_tags", "table", {}, "boundary tags of outline sides: {tag = [side indices]}, "
        "e.g. {inflow = [0], outflow = [5]}; untagged sides are walls", when="mesh = polygon"),
    Key("channel", "floats", None, "channel [x0, y0, length, width]; x0 side tagged inflow, "
        "the other end outflow, banks wall", "m", length=4),
    Key("cell_size", "float", None, "target triangle edge length of the channel or polygon "
        "mesh", "m",
        min=0.0, exclusive_min=True),
    Key("structured", "bool", False, "channel of squares instead of triangles (no holes)"),
    Key("piers", "any", [], "circular piers [[x, y, radius], ...] cut out of the channel "
        "(tagged wall)", "m"),
    Key("holes", "any", [], "polygonal holes [[[x, y], ...], ...] cut out of the channel", "m"),
    Key("mesh_file", "path", "", "mesh file read by driftlog.mesh.read_mesh (mesh = 'file')",
        must_exist=True),
    Key("bed", "str", "flat", "bed elevation: flat at bed_level, a slope falling along +x from "
        "bed_level at x0, a piecewise-linear profile along x, or the mesh file's node "
        "elevations", choices=("flat", "slope", "profile", "mesh")),
    Key("bed_level", "float", 0.0, "bed level (flat) or bed level at x0 (slope)", "m"),
    Key("slope", "float", 0.0, "bed slope, positive falling towards +x (bed = 'slope')", "m/m"),
    Key("bed_profile", "points", None, "bed [[x, z], ...] along x, linear between points, "
        "constant beyond (bed = 'profile')", "m"),
    Key("manning", "float", None, "Manning coefficient n (or give strickler)", "s m-1/3",
        min=0.0),
    Key("strickler", "float", None, "Strickler coefficient K = 1/n", "m1/3 s-1", min=0.0,
        exclusive_min=True),
    Key("order", "int", 1, "1: first order (explicit Euler); 2: MUSCL + Heun", min=1, max=2),
    Key("riemann", "str", "hllc", "Riemann solver", choices=("hllc", "hll")),
    Key("energy_bound", "str", "off", "order 2 on a bed given at the nodes: bound each edge's "
        "speed and total head by the largest of the face and its neighbours (docs/model.md "
        "eq. (85)), falling back to first-order depth and discharges where exceeded: g2 (at "
        "every edge), rising (only where the node bed makes the edge shallower than the "
        "limited depth), velocity (the edge first takes the face's limited velocity "
        "reconstruction), hr (no bound: where the node bed makes the edge shallower than the "
        "limited depth, the velocity of the limited depth and discharge).  Experimental: it "
        "costs accuracy on smooth flows (BENCHMARKS.md)",
        choices=("off", "g2", "rising", "velocity", "hr")),
    Key("energy_widen", "float", 0.0, "energy_bound's speed and head bounds widened by this "
        "fraction of the neighbourhood's speed and head ranges", min=0.0),
    Key("cfl", "float", None, "fraction of the positivity-preserving time step (default 0.9 "
        "at order 1, 0.8 at order 2)", min=0.0, max=1.0, exclusive_min=True),
    Key("dry_depth", "float", 1e-6, "depth below which a face has no velocity (a thin-film "
        "threshold, as [flow] dry_depth)", "m", min=0.0, exclusive_min=True, max=DRY_DEPTH_MAX),
    Key("arrival_depth", "float", 0.05, "depth marking the flood's arrival at a face "
        "(arrival_time output)", "m", min=0.0, exclusive_min=True),
    Key("start", "float", 0.0, "start time", "s"),
    Key("end", "float", None, "end time of the computation (required with [flow] source = "
        "'solver')", "s"),
    Key("output_interval", "float", None, "time between snapshots of the flow file (default: "
        "start and end only)", "s", min=0.0, exclusive_min=True),
    Key("boundaries", "table", {}, "conditions by boundary tag: [solver.boundaries.<tag>] "
        "type = wall | level | depth | discharge | froude | rating | free; "
        "value = number or series = [[t, v], ...]; rating: "
        "table = [[level, Q], ...]; tags not listed are walls"),
    Key("initial", "table", {}, "initial state: type = dry | level | depth | file; value (m); "
        "polygon = [[x, y], ...] (level or depth only inside); velocity = [u, v]; path and "
        "time (file)"),
    Key("sea", "table", {}, "a sea found from the bed: level = sea surface (m); boundary "
        "edges at or below it are tagged (tag, default 'sea') with an imposed level (boundary "
        "= 'level', default) or a free outflow ('free'); faces below it connected to them "
        "start filled to it"),
], doc="driftlog's shallow-water solver ([flow] source = 'solver')", check=check_solver_section)
