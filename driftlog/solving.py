"""A scenario's [solver] section turned into a stored flow: solve it, or reuse what is stored.

The top of the data flow (docs/design.md section 2): the solver (``driftlog.solver``) and the
OpenFOAM engine (``driftlog.adapters.openfoam_engine``) take the validated [solver] section;
this module adds what needs the whole scenario: where the flow file goes (``[flow] path``, or
``solver_flow.nc`` beside the scenario, with the engine's suffix), the scenario written into
the flow's attributes (provenance), and the reuse of a stored flow while its section's hash
is unchanged.
"""

from __future__ import annotations

from pathlib import Path

from driftlog.errors import ScenarioError
from driftlog.solver.config import build_solver, estimate_mesh, partial_path, solver_hash

__all__ = ["solve_scenario", "flow_from_scenario", "default_flow_path", "stored_flow",
           "solver_inputs"]


def default_flow_path(scenario, engine=None):
    """The flow file of the section's engine.

    [flow] path (or solver_flow.nc beside the scenario) for driftlog, with ``_<engine>``
    added to its stem for another engine.
    """
    from driftlog.adapters.openfoam_engine import engine_flow_path

    p = scenario["flow"].get("path") or ""
    path = Path(p) if p else scenario.base_dir / "solver_flow.nc"
    return engine_flow_path(path, engine or scenario["solver"]["engine"])


def solver_inputs(scenario) -> list:
    """The files the solver reads, as ``check_output``'s ``inputs``.

    The scenario, the mesh file (mesh = 'file') and the initial flow file (initial type =
    'file').
    """
    sec = scenario["solver"]
    inputs = [(scenario.path, "the scenario file")] if scenario.path else []
    if sec["mesh"] == "file" and sec["mesh_file"]:
        inputs.append((sec["mesh_file"], "the solver's mesh file ([solver] mesh_file)"))
    ini = sec.get("initial") or {}
    if ini.get("type") == "file" and ini.get("path"):
        inputs.append((ini["path"], "the solver's initial flow file ([solver.initial] path)"))
    return inputs


def stored_flow(path, digest):
    """('stored', last time) for a flow file computed from the same section, else (None, None)."""
    import netCDF4

    if not path.is_file():
        return None, None
    try:
        with netCDF4.Dataset(path) as ds:
            if getattr(ds, "solver_hash", None) != digest:
                return None, None
            n = len(ds.dimensions["time"])
            return "stored", float(ds.variables["time"][n - 1]) if n else None
    except OSError:
        return None, None


def _cannot_resume(path, digest):
    """The error for a file ``--resume`` cannot continue: what it is, or whose flow it is.

    Another kind of file (a trajectory file, another model's output, a truncated file...) is
    named as such, not as a flow of another [solver] section.
    """
    from driftlog.errors import FlowFileError, InputFileError
    from driftlog.files import sniff

    fk = sniff(path)
    if fk.kind != "flow":
        return InputFileError(f"{path}: {fk.describe()}; the file driftlog solve --resume "
                              "continues must be a flow file of driftlog solve (the .partial of "
                              "a stopped run): run without --resume (or remove the file)")
    return FlowFileError(f"{path}: cannot resume: it was not computed from this [solver] "
                         f"section (solver_hash differs from {digest}); run without --resume")


def solve_scenario(scenario, output=None, resume=False, progress=False):
    """Run the solver of a validated scenario; returns (SolveResult, path of the flow file)."""
    sec = scenario["solver"]
    if sec["end"] is None:
        raise ScenarioError("solver.end", None, "is required to run the solver: the end time "
                            "of the flow computation (s), in a [solver] section (driftlog "
                            "scenario keys --section solver lists its keys)")
    import os

    from driftlog.files import check_output

    path = check_output(Path(output) if output else default_flow_path(scenario),
                        "flow file" if output else "flow file ([flow] path)",
                        inputs=solver_inputs(scenario), suffixes=(".nc", ".nc4"))
    partial = partial_path(path)
    digest = solver_hash(sec)
    attrs = dict(scenario.attrs())
    attrs["solver_hash"] = digest
    attrs["title"] = scenario["title"] or "driftlog solver flow"
    if sec["engine"] != "driftlog":
        from driftlog.adapters.openfoam_engine import solve_with_shallow_water_foam

        if resume:  # an OpenFOAM run is not continued: not silently
            import warnings

            from driftlog.errors import DriftlogWarning

            warnings.warn(DriftlogWarning(f"--resume: a run of the engine {sec['engine']!r} "
                                          f"cannot be continued; {path} is computed from the "
                                          "beginning"), stacklevel=2)

        return solve_with_shallow_water_foam(sec, path, attrs, build_solver,
                                             progress=progress), path
    if resume and not partial.exists() and path.exists():
        if stored_flow(path, digest)[0] is None:
            raise _cannot_resume(path, digest)
        os.replace(path, partial)  # a finished flow extended to a later end
    if resume and not partial.exists():
        from driftlog.files import nothing_to_resume

        nothing_to_resume(partial, "partial flow file", "the flow is computed from the "
                          "beginning")
    resume = resume and partial.exists()
    if resume and stored_flow(partial, digest)[0] is None:
        raise _cannot_resume(partial, digest)
    estimate_mesh(sec)
    if progress:
        from driftlog._numba import announce_compile

        announce_compile(["solver"])
    s = build_solver(sec)
    try:
        res = s.run(sec["end"], output=partial, output_interval=sec["output_interval"],
                    progress=progress, resume=resume, attrs=attrs)
    except KeyboardInterrupt as exc:
        _, t_last = stored_flow(partial, digest)
        exc.add_note(f"kept {partial}: the flow up to t = {t_last} s of {sec['end']} s; "
                     "driftlog solve SCENARIO --resume continues it")
        raise
    os.replace(partial, path)  # complete: under its final name
    res.path = path
    return res, path


def flow_from_scenario(scenario, progress=False):
    """The flow of a scenario with [flow] source = 'solver', as a MeshFlowField.

    Reuses ``[flow] path`` when it was computed from the same [solver] section and reaches the
    end time, resumes it when it stopped before, and computes it otherwise.
    """
    from driftlog.flowfile import open_flow

    sec = scenario["solver"]
    if sec["end"] is None:
        raise ScenarioError("solver.end", None, "is required with [flow] source = 'solver': "
                            "the end time of the flow computation (s)")
    path = default_flow_path(scenario)
    digest = solver_hash(sec)
    state, t_last = stored_flow(path, digest)
    if sec["engine"] != "driftlog":  # no resuming an OpenFOAM run
        if state is None or t_last is None or t_last < sec["end"] - 1e-9 * abs(sec["end"]):
            solve_scenario(scenario, output=path, progress=progress)
        return open_flow(path, dry_depth=scenario["flow"]["dry_depth"])
    if state is None or t_last is None or t_last < sec["end"]:
        p_state, p_last = stored_flow(partial_path(path), digest)
        resume = (p_state is not None and p_last is not None) or \
            (state is not None and t_last is not None)
        solve_scenario(scenario, output=path, resume=resume, progress=progress)
    return open_flow(path, dry_depth=scenario["flow"]["dry_depth"])
