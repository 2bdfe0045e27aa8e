"""Scenario files (TOML): a self-describing schema, validated up front.

Every key carries its type, default, units, allowed range or choices and a description (as
OpenDrift's configuration does); ``driftlog scenario keys`` prints them all.  Validation names
the key, the value and what is allowed for every bad value, before anything runs.  The
validated scenario (defaults filled in) is written into every output, so a run can be
reproduced from its output alone.

Sections: ``[flow]``, ``[time]``, ``[[logs]]``, ``[physics]``, ``[integrator]``, ``[contact]``,
``[[obstacles]]``, ``[output]``, ``[solver]`` for flows computed by driftlog's solver, and
``[ensemble]`` for ensembles (many members on one flow: ``driftlog.ensemble``).
"""

from __future__ import annotations

import difflib
import json
import math
from dataclasses import dataclass
from pathlib import Path

from driftlog import adapters
from driftlog.errors import ScenarioError
from driftlog.schema import (
    Key,
    Section,
    check_tables,
    describe_sections,
    merge,
    read_toml,
    run_checks,
)

__all__ = ["Key", "Section", "SECTIONS", "Scenario", "load_scenario", "register_section",
           "describe_keys", "merge", "read_toml"]

SECTIONS: dict[str, Section] = {}
TOP_KEYS = [
    Key("title", "str", "", "a short name for the scenario"),
    Key("description", "str", "", "what the scenario shows"),
]


def register_section(section: Section) -> Section:
    """Add or replace a section of the schema."""
    SECTIONS[section.name] = section
    return section


# --------------------------------------------------------------------- the scenario
@dataclass
class Scenario:
    """A validated scenario: ``data`` has every section with defaults filled in."""

    data: dict
    path: Path | None = None
    text: str = ""

    @property
    def base_dir(self) -> Path:
        """The folder relative paths of the scenario are taken from."""
        return self.path.parent if self.path else Path.cwd()

    def __getitem__(self, name):
        return self.data[name]

    def get(self, name, default=None):
        """A section (or top key) by name, ``default`` if absent."""
        return self.data.get(name, default)

    def to_json(self) -> str:
        """The validated data as JSON (sorted keys)."""
        return json.dumps(self.data, sort_keys=True, default=str)

    def attrs(self) -> dict:
        """Global attributes that make a run reproducible from its output."""
        return {"scenario": self.text or self.to_json(), "scenario_resolved": self.to_json(),
                "scenario_path": str(self.path) if self.path else ""}


def load_scenario(source, overrides: dict | None = None) -> Scenario:
    """Read and validate a scenario from a TOML file path, TOML text or a dict.

    ``overrides`` is a nested dict merged over the file (used by ensembles and the CLI's --set).
    """
    raw, path, text = read_toml(source)
    try:
        return _validate(raw, path, text, overrides)
    except ScenarioError as exc:
        if exc.source is None and path is not None:  # name the file in the message
            shown = source if isinstance(source, (str, Path)) else path
            raise ScenarioError(exc.key, exc.value, exc.allowed, source=str(shown)) from None
        raise


def _validate(raw, path, text, overrides):
    if overrides:
        raw = merge(raw, overrides)
    base = path.parent if path else Path.cwd()
    sections = list(SECTIONS.values())
    data = check_tables(raw, sections, TOP_KEYS, base)
    scen = Scenario(data, path, text)
    run_checks(sections, data, scen)
    return scen


def describe_keys(section: str | None = None) -> str:
    """A text table of every key: name, type, default, units, rule, description."""
    if section and section not in SECTIONS:
        close = difflib.get_close_matches(section, list(SECTIONS), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ScenarioError("--section", section, f"unknown section{hint}; the sections are: "
                            + ", ".join(SECTIONS))
    return describe_sections(SECTIONS.values(), section)


# --------------------------------------------------------------------- the sections
# driftlog's own flow file, then what is built here, 'auto' (a reader chosen by the file's
# contents), then the other readers (the registry)
FLOW_SOURCES = (adapters.KINDS[0], "solver", "analytic", "auto") + adapters.KINDS[1:]
ANALYTIC_KINDS = ("uniform", "solid_body_rotation", "free_vortex")


def _check_flow(t, prefix, scen):
    src = t["source"]
    read = src in adapters.KINDS or src == "auto"
    if read and not t["path"]:
        raise ScenarioError(f"{prefix}.path", None,
                            f"is required when source = {src!r}: the flow file or case to read")
    if read and not Path(t["path"]).exists():
        raise ScenarioError(f"{prefix}.path", t["path"], "file not found")
    t["options"] = adapters.check_flow_options(t, prefix, scen.base_dir)
    if src == "analytic" and t["kind"] not in ANALYTIC_KINDS:
        raise ScenarioError(f"{prefix}.kind", t["kind"],
                            "must be one of " + ", ".join(map(repr, ANALYTIC_KINDS)))


register_section(Section("flow", [
    Key("source", "str", "analytic", "where the flow comes from", choices=FLOW_SOURCES),
    Key("path", "path", "", "flow file (source = file), or model output to import; for "
        "source = solver, where the computed flow is stored (reused if present)"),
    Key("kind", "str", "solid_body_rotation", "analytic flow", choices=ANALYTIC_KINDS,
        when="source = analytic"),
    Key("velocity", "point", [1.0, 0.0], "uniform velocity", "m/s", when="kind = uniform"),
    Key("acceleration", "point", [0.0, 0.0], "uniform acceleration", "m/s2",
        when="kind = uniform"),
    Key("omega", "float", 0.0628318530717959, "rotation rate", "rad/s",
        when="kind = solid_body_rotation"),
    Key("circulation", "float", 10.0, "circulation Gamma", "m2/s", when="kind = free_vortex"),
    Key("core_radius", "float", 0.0, "solid-body core radius", "m", min=0.0,
        when="kind = free_vortex"),
    Key("center", "point", [0.0, 0.0], "centre of rotation", "m"),
    Key("depth", "float", 1.0, "water depth of analytic flows", "m", min=0.0,
        exclusive_min=True),
    Key("dry_depth", "float", 1e-3, "depth below which a face is dry", "m", min=0.0,
        exclusive_min=True),
    Key("steady_at", "float", None, "freeze the flow at this time and treat it as steady", "s"),
    Key("variables", "table", {}, "map of driftlog names (depth, level, u, v, hu, hv, bed) to "
        "the variable names of an imported file"),
    Key("time_range", "floats", None, "import only snapshots in [start, end]", "s", length=2),
    Key("options", "table", {}, "options of the importer (driftlog.adapters): openfoam "
        "decomposed, mode ('shallow_water' | 'vof'), raster ([x0, y0, dx, nx, ny]); ugrid and "
        "cf_grid fill ('error' | 'dry'), units ({hu = 'm3 s-1'}); anuga use_centroids; "
        "selafin depth_average",
        when="source = auto, openfoam, ugrid, anuga, cf_grid, selafin"),
], doc="the hydro source", check=_check_flow))


def _check_time(t, prefix, scen):
    if t["end"] is not None and not t["end"] > t["start"]:
        raise ScenarioError(f"{prefix}.end", t["end"],
                            f"must be after time.start = {t['start']} s (time span reversed)")


register_section(Section("time", [
    Key("start", "float", 0.0, "start of the debris run", "s"),
    Key("end", "float", None, "end of the debris run (default: end of the flow)", "s"),
    Key("output_interval", "float", 1.0, "interval between trajectory records", "s", min=0.0,
        exclusive_min=True),
    Key("hydro_step", "float", 1.0, "hydrodynamic step for flows without snapshots (analytic)",
        "s", min=0.0, exclusive_min=True),
], doc="the time span", check=_check_time))

SEEDINGS = ("list", "line", "polygon", "random", "grid")


def _check_logs(t, prefix, scen):
    s = t["seeding"]
    if s == "list":
        if not t["x"] or not t["y"] or len(t["x"]) != len(t["y"]):
            raise ScenarioError(f"{prefix}.x", t["x"],
                                "seeding = 'list' needs x and y lists of the same length")
        for key in ("theta",):
            if isinstance(t[key], list) and len(t[key]) not in (1, len(t["x"])):
                raise ScenarioError(f"{prefix}.{key}", t[key],
                                    f"must have 1 or {len(t['x'])} values (one per log)")
    elif s == "line":
        for key in ("start", "end"):
            if t[key] is None:
                raise ScenarioError(f"{prefix}.{key}", None, "is required for seeding = 'line'")
    elif s in ("polygon", "random"):
        if t["polygon"] is None:
            raise ScenarioError(f"{prefix}.polygon", None,
                                f"is required for seeding = {s!r} (at least 3 [x, y] points)")
    if s != "list" and t["count"] < 1:
        raise ScenarioError(f"{prefix}.count", t["count"], "must be >= 1")


register_section(Section("logs", [
    Key("name", "str", "", "a label for this group of logs"),
    Key("seeding", "str", "list", "how the logs are placed", choices=SEEDINGS),
    Key("x", "floats", [], "x of each log centre", "m", when="seeding = list"),
    Key("y", "floats", [], "y of each log centre", "m", when="seeding = list"),
    Key("theta", "any", 0.0, "angle of the log axis to the x axis: a number, a list (one per "
        "log), or 'random'", "rad"),
    Key("count", "int", 1, "number of logs", min=1, when="seeding = line, polygon, random, grid"),
    Key("start", "point", None, "first end of the release line", "m", when="seeding = line"),
    Key("end", "point", None, "second end of the release line", "m", when="seeding = line"),
    Key("polygon", "points", None, "release area", "m", length=3,
        when="seeding = polygon, random, grid"),
    Key("seed", "int", 0, "random seed (the same seed gives the same logs, bit for bit)",
        min=0),
    Key("length", "float", 1.0, "log length L", "m", min=0.0, exclusive_min=True),
    Key("radius", "float", 0.1, "log radius r", "m", min=0.0, exclusive_min=True),
    Key("density", "float", 720.0, "log density rho_b", "kg/m3", min=0.0, exclusive_min=True),
    Key("release_time", "float", None, "when the logs enter (default: time.start)", "s"),
    Key("velocity", "str", "flow", "initial velocity: the flow's at release, or rest",
        choices=("flow", "rest")),
], doc="logs to release (repeat [[logs]] for several groups)", repeated=True, check=_check_logs))

PHYSICS_LEVELS = ("tracer", "drag", "full", "auto")
register_section(Section("physics", [
    Key("level", "str", "full", "tracer (U_b = U_w), drag only, the full reference model, or "
        "auto (chosen from the drag relaxation time against the flow time scale)",
        choices=PHYSICS_LEVELS),
    Key("rotation", "str", "on", "rotation of the logs (eq. 8-10)", choices=("on", "off", "auto")),
    Key("fluid_volume", "str", "body", "volume in the pressure-gradient and added-mass terms: "
        "the paper's V_b, or the submerged volume", choices=("body", "submerged")),
    Key("surface_slope", "bool", False, "add -rho g V grad(eta) in place of the steady part of "
        "DU_w/Dt"),
    Key("drag_law", "str", "ganser", "drag coefficient: Ganser (1993), constant, or linear F = k w",
        choices=("ganser", "constant", "linear")),
    Key("drag_area", "str", "paper", "reference area of C_D: the paper's S_eff, Ganser's "
        "pi d_v^2 / 4, or the wetted projected area", choices=("paper", "ganser", "wetted")),
    Key("drag_coefficient", "float", 1.0, "C_D when drag_law = constant", min=0.0),
    Key("linear_drag", "float", 1.0, "k when drag_law = linear", "kg/s", min=0.0),
    Key("torque_force", "str", "total", "force applied at the centre of pressure (eq. 8): the "
        "total hydrodynamic force (MODEL.md 6), or the drag alone (pressure-gradient and "
        "added-mass forces then act at the centre of mass; well posed when the log moves with "
        "the flow)", choices=("total", "drag")),
    Key("water_density", "float", 1000.0, "rho", "kg/m3", min=0.0, exclusive_min=True),
    Key("gravity", "float", 9.81, "g", "m/s2", min=0.0, exclusive_min=True),
    Key("viscosity", "float", 1.0e-3, "dynamic viscosity mu", "Pa s", min=0.0,
        exclusive_min=True),
], doc="the log transport model (MODEL.md sections 3-6)"))

register_section(Section("integrator", [
    Key("method", "str", "rk4", "time integrator: explicit Euler, RK4 (the paper), or "
        "exponential (RK4 with drag integrated exactly over the step: stable on stiff drag)",
        choices=("euler", "rk4", "exponential")),
    Key("length_fraction", "float", 1.0, "dt <= length_fraction * L / |U_b| (paper: 1)",
        min=0.0, exclusive_min=True),
    Key("angle_step", "float", math.pi / 4, "dt <= angle_step / |omega_b| (paper: pi/4)", "rad",
        min=0.0, exclusive_min=True),
    Key("drag_fraction", "float", 0.5, "dt <= drag_fraction * tau_D for explicit methods (0: no "
        "bound, as the paper)", min=0.0),
    Key("max_step", "float", None, "upper bound of the sub-step", "s", min=0.0,
        exclusive_min=True),
    Key("min_step", "float", 1e-9, "sub-steps below this are an error (the run stops with a "
        "message)", "s", min=0.0, exclusive_min=True),
], doc="time integration (MODEL.md sections 8-9)"))

register_section(Section("contact", [
    Key("enabled", "bool", False, "contacts between logs and with walls and obstacles"),
    Key("method", "str", "event", "event-driven impulses (the paper) or time-stepping "
        "non-smooth contact (Moreau-Jean, for jams)", choices=("event", "moreau")),
    Key("time_of_impact", "str", "conservative", "contact time: the paper's dichotomy or "
        "conservative advancement on the capsule distance",
        choices=("dichotomy", "conservative")),
    Key("restitution", "float", 1.0, "coefficient of restitution eps", min=0.0, max=1.0),
    Key("backend", "str", "native", "distance queries: numba kernels or python-fcl",
        choices=("native", "fcl")),
    Key("walls", "bool", True, "the mesh's wall boundaries are obstacles"),
    Key("tolerance", "float", 1e-4, "contact distance tolerance, relative to the log radius",
        min=0.0, exclusive_min=True),
    Key("max_events", "int", 10000, "contact events per sub-step above which the event-driven "
        "method stops with a jam message", min=1),
    Key("rest_speed", "float", 0.01, "event-driven: approach speeds below this do not bounce "
        "(resting contact: a log held on a wall by the flow would otherwise bounce ever less, "
        "ever more often, and stall the method; 0 = the paper)", "m/s", min=0.0),
    Key("iterations", "int", 200, "moreau: projected Gauss-Seidel sweeps at most per step",
        min=1),
], doc="contacts (MODEL.md section 7)"))

register_section(Section("obstacles", [
    Key("name", "str", "", "label used in hit counts"),
    Key("type", "str", "circle", "obstacle shape", choices=("circle", "polygon", "segments",
                                                            "mesh")),
    Key("center", "point", None, "circle centre", "m", when="type = circle"),
    Key("radius", "float", None, "circle radius", "m", min=0.0, exclusive_min=True,
        when="type = circle"),
    Key("points", "points", None, "polygon vertices or polyline points", "m", length=2,
        when="type = polygon, segments"),
    Key("path", "path", "", "3D obstacle mesh file (meshio formats)", must_exist=True,
        when="type = mesh"),
    Key("z", "float", 0.0, "elevation of the plane that cuts 3D obstacle meshes", "m",
        when="type = mesh"),
], doc="bridge piers, walls and other obstacles", repeated=True))

register_section(Section("output", [
    Key("path", "path", "trajectories.nc", "trajectory file (CF-1.11 trajectory NetCDF)"),
    Key("vtk", "bool", False, "also write VTK (ParaView) files beside the trajectory file"),
    Key("figure", "bool", False, "draw a figure of the trajectories"),
    Key("animation", "bool", False, "write an animation (MP4 if ffmpeg is there, else GIF)"),
    Key("flush_interval", "int", 10, "records between flushes to disk", min=1),
], doc="what is written"))


def _check_ensemble(t, prefix, scen):
    if not t["vary"] and t["members"] is None:
        return  # not an ensemble: a plain scenario
    # the parser of [ensemble.vary] lives with the sampler that uses it
    from driftlog.ensemble.spec import check_ensemble_section

    check_ensemble_section(t, prefix, scen)


register_section(Section("ensemble", [
    Key("base", "path", "", "base debris scenario; the other sections of this file are merged "
        "over it (leave empty when this file is the whole scenario)", must_exist=True),
    Key("members", "int", None, "number of members (for grid sampling: the number of "
        "combinations, leave it out)", min=1),
    Key("sampling", "str", "monte_carlo", "how the varied parameters are drawn: independently "
        "per member (monte_carlo), stratified (latin_hypercube, scipy.stats.qmc), or every "
        "combination of explicit lists (grid)", choices=("monte_carlo", "latin_hypercube",
                                                        "grid")),
    Key("seed", "int", 0, "seed of the sampling: member i is reproducible from the seed and i",
        min=0),
    Key("vary", "table", {}, "parameters to vary: \"section.key\" (every [[logs]] group) or "
        "\"logs[i].key\" = { values | range | uniform | loguniform | normal | lognormal | "
        "integers = [...] } (see driftlog.ensemble.spec)"),
    Key("reseed_logs", "bool", True, "give each member's random seeding its own seed, from "
        "(seed, member, group)"),
    Key("output", "path", "", "output folder (default: 'ensemble' beside the ensemble file)"),
    Key("workers", "int", None, "workers of the local Dask cluster (default: the CPU count; "
        "0: the members one after the other in this process, without Dask)", min=0),
    Key("scheduler", "str", "", "address of a running Dask scheduler (tcp://host:8786); "
        "empty: start a LocalCluster"),
    Key("keep_trajectories", "bool", False, "also write each member's trajectory file "
        "(output/trajectories/; on a cluster the workers need the shared filesystem)"),
    Key("confidence", "float", 0.95, "confidence level of the intervals", min=0.5, max=0.9999),
    Key("grid_cell", "float", None, "aggregate on a regular grid of this cell size instead of "
        "the flow mesh (required for analytic flows, which have no mesh)", "m", min=0.0,
        exclusive_min=True),
    Key("grid_origin", "point", None, "lower-left corner of the aggregation grid", "m"),
    Key("grid_size", "point", None, "extent of the aggregation grid", "m"),
    Key("checkpoint_interval", "float", 60.0, "seconds between rewrites of the aggregated "
        "results while the ensemble runs", "s", min=0.0, exclusive_min=True),
], doc="ensembles: many members on one flow (driftlog ensemble)", check=_check_ensemble))


# --------------------------------------------------------------------- [solver]
def _check_solver(t, prefix, scen):
    # the cross-key rules (boundaries, initial state) live with the solver that uses them
    from driftlog.solver.config import check_solver_section

    check_solver_section(t, prefix, scen)


register_section(Section("solver", [
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
    Key("cfl", "float", None, "fraction of the positivity-preserving time step (default 0.9 "
        "at order 1, 0.8 at order 2)", min=0.0, max=1.0, exclusive_min=True),
    Key("dry_depth", "float", 1e-6, "depth below which a face has no velocity", "m", min=0.0,
        exclusive_min=True),
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
], doc="driftlog's shallow-water solver ([flow] source = 'solver')", check=_check_solver))
