"""From a scenario's ``[flow]`` section to a FlowField, whatever the hydro source."""

from __future__ import annotations

from driftlog.analytic import FreeVortex, SolidBodyRotation, UniformFlow
from driftlog.errors import ScenarioError

__all__ = ["flow_from_scenario"]


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

        field = open_flow(sec["path"], dry_depth=sec["dry_depth"])
    elif src == "solver":
        from driftlog.solver import flow_from_scenario as solve

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
