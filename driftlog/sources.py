"""From a scenario's ``[flow]`` section to a FlowField, whatever the hydro source."""

from __future__ import annotations

from pathlib import Path

import driftlog.adapters as adapters
from driftlog.analytic import FreeVortex, SolidBodyRotation, UniformFlow
from driftlog.errors import ScenarioError
from driftlog.flow import DRY_DEPTH_MAX
from driftlog.schema import Key, Section

__all__ = ["flow_from_scenario", "FLOW_SECTION"]


def analytic_flow(section):
    """The analytic field a [flow] section describes."""
    kind = section["kind"]
    if kind == "uniform":
        return UniformFlow(*section["velocity"], depth=section["depth"],
                           acceleration=section["acceleration"])
    if kind == "solid_body_rotation":
        return SolidBodyRotation(section["omega"], center=section["center"],
                                 depth=section["depth"])
    if kind == "free_vortex":
        return FreeVortex(section["circulation"], center=section["center"],
                          depth=section["depth"], core_radius=section["core_radius"])
    raise ScenarioError("flow.kind", kind, "unknown analytic flow")


def flow_from_scenario(scenario, progress=False):
    """The FlowField of a validated scenario (solving or importing the flow if needed)."""
    sec = scenario["flow"]
    src = sec["source"]
    if src == "analytic":
        field = analytic_flow(sec)
    elif src == "file":
        from driftlog.flowfile import open_flow

        _refuse_other_models_output(sec["path"])
        field = open_flow(sec["path"], dry_depth=sec["dry_depth"])
    elif src == "solver":
        from driftlog.solving import flow_from_scenario as solve

        field = solve(scenario, progress=progress)
    else:
        from driftlog.adapters import flow_from_scenario as imported

        field = imported(scenario)
    if sec["steady_at"] is not None:
        if not hasattr(field, "freeze"):
            raise ScenarioError("flow.steady_at", sec["steady_at"],
                                f"only flows on a mesh can be frozen, not source = {src!r}")
        field = field.freeze(sec["steady_at"])
    return field


def _refuse_other_models_output(path):
    """``[flow] source = 'file'`` given another model's output: one error saying how to read it.

    'file' reads driftlog's own flow files; a HEC-RAS, dfsu, Selafin, raster, UGRID, sww or
    CF grid file or an OpenFOAM case (not written by driftlog) is read by ``source = 'auto'``
    or its reader's kind, or converted by ``driftlog import``.
    """
    from driftlog.errors import FlowFileError
    from driftlog.files import sniff

    fk = sniff(path)
    if fk.kind not in ("model_output", "openfoam") or \
            "driftlog_version" in fk.info.get("attributes", ()):
        return  # a flow file, or one written by driftlog: open_flow says what is wrong
    kind = "openfoam" if fk.kind == "openfoam" else fk.info.get("reader") or next(
        (r.KIND for r in adapters.READERS if r.KIND != "file" and r.can_open(path)), "")
    raise FlowFileError(f"{path}: another model's output{f' ({kind})' if kind else ''}, not a "
                        "driftlog flow file: [flow] source = 'file' reads driftlog's own flow "
                        "files; set source = 'auto'" + (f" (or {kind!r})" if kind else "")
                        + f" to read it, or convert it first: driftlog import {path} -o flow.nc")


# --------------------------------------------------------------------- the scenario section
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
    for k, v in t["variables"].items():
        if k not in adapters.VARIABLE_NAMES:
            raise ScenarioError(f"{prefix}.variables.{k}", v, "not a name driftlog knows; one "
                                f"of {', '.join(adapters.VARIABLE_NAMES)}")
    if src == "analytic" and t["kind"] not in ANALYTIC_KINDS:
        raise ScenarioError(f"{prefix}.kind", t["kind"],
                            "must be one of " + ", ".join(map(repr, ANALYTIC_KINDS)))


FLOW_SECTION = Section("flow", [
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
    Key("dry_depth", "float", 1e-3, "depth below which a face is dry: no velocity there and "
        "the logs strand (a thin-film threshold: hydro models use 1e-6 to 0.1 m)", "m",
        min=0.0, exclusive_min=True, max=DRY_DEPTH_MAX),
    Key("steady_at", "float", None, "freeze the flow at this time and treat it as steady", "s"),
    Key("variables", "table", {}, "map of driftlog names (depth, level, u, v, hu, hv, bed) to "
        "the variable names of an imported file"),
    Key("time_range", "floats", None, "import only snapshots in [start, end]", "s", length=2),
    Key("options", "table", {}, "options of the importer (driftlog.adapters): openfoam "
        "decomposed, mode ('shallow_water' | 'vof'), raster ([x0, y0, dx, nx, ny]); ugrid and "
        "cf_grid fill ('error' | 'dry'), units ({hu = 'm3 s-1'}); anuga use_centroids; "
        "selafin depth_average",
        when="source = auto, openfoam, ugrid, anuga, cf_grid, selafin"),
], doc="the hydro source", check=_check_flow)
