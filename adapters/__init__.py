"""Readers of other models' flow outputs, each returning a driftlog ``FlowField``.

Imported as ``driftlog.adapters`` (the folder sits at the top of the repository, DESIGN.md).

=========  ===============================================  ===========================
kind        what                                             module
=========  ===============================================  ===========================
file        driftlog's own flow file                         driftlog.flowfile
openfoam    shallowWaterFoam case; interFoam depth-averaged   openfoam, openfoam_vof
ugrid       UGRID NetCDF (D-Flow FM map files...)             ugrid
anuga       ANUGA .sww                                        anuga
cf_grid     CF regular grid NetCDF (LISFLOOD-FP...)           cfgrid
=========  ===============================================  ===========================

``open_flow_source(kind, path, **options)`` opens any of them ('auto' detects the kind);
``flow_from_scenario(scenario)`` does it for a scenario's ``[flow]`` section;
``import_flow(source, output)`` converts to a driftlog flow file (``driftlog import``).
Each returns a ``MeshFlowField`` whose snapshots are read when the sampler asks for them.
"""

from __future__ import annotations

from pathlib import Path

from driftlog.errors import FlowFileError

__all__ = ["KINDS", "open_flow_source", "detect_format", "flow_from_scenario", "import_flow",
           "checked_snapshot"]

KINDS = ("file", "openfoam", "ugrid", "anuga", "cf_grid")

# options each kind accepts (beyond time_range, variables, dry_depth)
_OPTIONS = {
    "file": set(),
    "openfoam": {"decomposed", "mode", "mesh2d", "raster", "include_initial",
                 "allow_initial_only"},
    "ugrid": {"topology", "fill", "units"},
    "anuga": {"use_centroids"},
    "cf_grid": {"fill", "units"},
}


def detect_format(path) -> str:
    """The kind of a hydro source from its layout (directory or NetCDF contents)."""
    p = Path(path)
    if p.is_dir():
        from driftlog.adapters.openfoam import is_openfoam_case

        if is_openfoam_case(p):
            return "openfoam"
        raise FlowFileError(f"{p}: unknown layout: a directory that is not an OpenFOAM case "
                            "(no system/controlDict, constant/polyMesh or processor*)")
    if not p.exists():
        raise FlowFileError(f"{p}: file or directory not found")
    if p.name == "controlDict" and p.parent.name == "system":
        return "openfoam"
    from driftlog.adapters._netcdf import open_dataset

    with open_dataset(p) as ds:
        from driftlog.adapters.anuga import is_sww
        from driftlog.adapters.cfgrid import is_cf_grid
        from driftlog.adapters.ugrid import is_ugrid

        if p.suffix.lower() == ".sww" or is_sww(ds):
            return "anuga"
        if is_ugrid(ds):
            own = all(v in ds.variables for v in ("water_depth", "velocity_x", "velocity_y",
                                                  "bed_level"))
            return "file" if own and "driftlog_version" in ds.ncattrs() else "ugrid"
        if is_cf_grid(ds):
            return "cf_grid"
        names = sorted(ds.variables)[:12]
    raise FlowFileError(f"{p}: unknown layout: not a UGRID mesh (no cf_role = mesh_topology), "
                        f"not an ANUGA sww (x, y, volumes, stage), not a CF grid (1-D x, y "
                        f"coordinates); variables: {names}")


def open_flow_source(kind, path, time_range=None, variables=None, dry_depth=1e-3, **options):
    """Open a hydro source as a MeshFlowField.

    Parameters
    ----------
    kind : 'auto', 'file', 'openfoam', 'ugrid', 'anuga' or 'cf_grid'
    path : path
        File, or OpenFOAM case directory.
    time_range : (start, end), optional
        Only the snapshots in [start, end] (s).
    variables : dict, optional
        driftlog name (depth, level, bed, u, v, hu, hv, alpha) -> the source's variable name.
    dry_depth : float
        Depth below which a face is dry (m).
    **options
        Kind-specific: openfoam ``decomposed``, ``mode`` ('shallow_water' | 'vof'), ``mesh2d``,
        ``raster``; ugrid / cf_grid ``fill`` ('error' | 'dry'), ``units``; anuga
        ``use_centroids``.
    """
    path = Path(path)
    if kind in (None, "auto"):
        kind = detect_format(path)
    if kind not in KINDS:
        raise FlowFileError(f"{path}: format {kind!r} unknown; one of {', '.join(KINDS)} "
                            "or 'auto'")
    unknown = set(options) - _OPTIONS[kind]
    if unknown:
        raise FlowFileError(f"{path}: options {sorted(unknown)} do not apply to {kind!r} "
                            f"(allowed: {sorted(_OPTIONS[kind]) or 'none'})")
    variables = dict(variables or {})
    if kind == "file":
        from driftlog.adapters._common import SubsetSnapshots, select_times

        from driftlog.flow import MeshFlowField
        from driftlog.flowfile import open_flow

        field = open_flow(path, dry_depth=dry_depth)
        if time_range is not None:
            idx = select_times(field.times, time_range, str(path))
            field = MeshFlowField(field.mesh, field.bed, SubsetSnapshots(field.source, idx),
                                  field.dry_depth, field.name, field.attrs)
        return field
    if kind == "openfoam":
        from driftlog.adapters.openfoam import open_openfoam

        return open_openfoam(path, time_range=time_range, variables=variables,
                             dry_depth=dry_depth, **options)
    if kind == "ugrid":
        from driftlog.adapters.ugrid import open_ugrid

        return open_ugrid(path, time_range=time_range, variables=variables,
                          dry_depth=dry_depth, **options)
    if kind == "anuga":
        from driftlog.adapters.anuga import open_anuga

        return open_anuga(path, time_range=time_range, variables=variables,
                          dry_depth=dry_depth, **options)
    from driftlog.adapters.cfgrid import open_cf_grid

    return open_cf_grid(path, time_range=time_range, variables=variables, dry_depth=dry_depth,
                        **options)


def flow_from_scenario(scenario):
    """The FlowField of a validated scenario's ``[flow]`` section.

    For the sources file, openfoam, ugrid, anuga and cf_grid; frozen at ``steady_at`` if set.

    ``scenario``: a ``driftlog.scenario.Scenario`` or its ``[flow]`` table (a dict).
    """
    flow = scenario["flow"] if not isinstance(scenario, dict) or "flow" in scenario else scenario
    kind = flow["source"]
    if kind not in KINDS:
        raise FlowFileError(f"[flow] source = {kind!r} is not read by driftlog.adapters (it "
                            f"reads {', '.join(KINDS)}); 'analytic' and 'solver' are built "
                            "elsewhere")
    options = dict(flow.get("options") or {})
    field = open_flow_source(kind, flow["path"], time_range=flow.get("time_range"),
                             variables=flow.get("variables") or {},
                             dry_depth=flow.get("dry_depth", 1e-3), **options)
    if flow.get("steady_at") is not None:
        field = field.freeze(float(flow["steady_at"]))
    return field


def import_flow(source, output, kind="auto", compress=True, progress=None, keep_open=False,
                **options):
    """Convert a hydro source to a driftlog flow file, snapshot by snapshot (bounded memory).

    Returns (the written path, the field that was read); the field's source file is closed
    unless ``keep_open``.
    """
    import os

    from driftlog.files import check_output, temporary_name
    from driftlog.flowfile import FlowFileWriter

    output = check_output(output, "flow file", inputs=[source], suffixes=(".nc", ".nc4"))
    field = open_flow_source(kind, source, **options)
    attrs = dict(field.attrs)
    attrs.setdefault("source", field.name)
    attrs["dry_depth"] = field.dry_depth
    attrs["imported_from"] = str(Path(source).resolve())
    tmp = temporary_name(output)  # renamed when complete: never a truncated flow file
    try:
        writer = FlowFileWriter(tmp, field.mesh, field.bed, attrs=attrs, compress=compress)
    except OSError as exc:
        raise FlowFileError(f"{output}: cannot write the flow file ({exc})") from None
    try:
        with writer as w:
            for i, t in enumerate(field.times):
                h, hu, hv = checked_snapshot(field, i)
                w.write(float(t), h, hu=hu, hv=hv, dry_depth=field.dry_depth)
                if progress is not None:
                    progress(i + 1, field.times.size)
        os.replace(tmp, output)
    finally:
        tmp.unlink(missing_ok=True)
        if not keep_open and hasattr(field.source, "close"):
            field.source.close()
    return Path(output), field


def checked_snapshot(field, i):
    """Snapshot i of a field's source as face arrays (h, hu, hv), checked as the sampler checks
    them (sizes, finite values, no negative depth), without the node interpolation."""
    return field.read_snapshot(i)
