"""Readers of flow outputs (driftlog's own and other models'), each returning a ``FlowField``.

Imported as ``driftlog.adapters`` (the folder sits at the top of the repository,
docs/design.md section 4.3).

Every reader is one module that declares (the reader contract):

``KIND``
    the name used in ``[flow] source = "..."`` and ``driftlog import --format``;
``SUFFIXES``
    typical file suffixes (documentation only);
``OPTIONS``
    its own keys (``driftlog.schema.Key``), validated under ``[flow.options]``;
``can_open(path) -> bool``
    a cheap look at the contents for ``source = "auto"`` (never raises);
``open(path, *, time_range=None, variables=None, dry_depth=1e-3, **options) -> FlowField``.

``READERS`` is the ordered registry ('auto' takes the first reader whose ``can_open`` is true);
a new reader is added by writing its module and adding it to that list, nothing else.

=========  ===============================================  ===========================
kind        what                                             module
=========  ===============================================  ===========================
file        driftlog's own flow file                         file (driftlog.flowfile)
openfoam    shallowWaterFoam case; interFoam depth-averaged   openfoam, openfoam_vof
ugrid       UGRID NetCDF (D-Flow FM map files...)             ugrid
anuga       ANUGA .sww                                        anuga
cf_grid     CF regular grid NetCDF (LISFLOOD-FP...)           cfgrid
selafin     TELEMAC-2D Selafin results (node-located data)    selafin (xarray-selafin)
dfsu        MIKE 21 FM 2D dfsu results (element values)       mike (mikeio)
raster      LISFLOOD-FP ASCII results, GeoTIFF series         raster (rioxarray)
hecras      HEC-RAS 2D plan output (HDF5)                     hecras
=========  ===============================================  ===========================

``open_flow_source(kind, path, **options)`` opens any of them ('auto' detects the kind);
``flow_from_scenario(scenario)`` does it for a scenario's ``[flow]`` section;
``import_flow(source, output)`` converts to a driftlog flow file (``driftlog import``).
Each returns a ``MeshFlowField`` whose snapshots are read when the sampler asks for them.
"""

from __future__ import annotations

from pathlib import Path

from driftlog.errors import FlowFileError
from driftlog.schema import Section, check_table

from . import anuga, cfgrid, file, hecras, mike, openfoam, raster, selafin, ugrid
from ._netcdf import open_dataset

__all__ = ["READERS", "KINDS", "VARIABLE_NAMES", "reader", "options_section", "open_flow_source",
           "detect_format", "flow_from_scenario", "import_flow", "checked_snapshot"]

READERS = [file, hecras, openfoam, ugrid, anuga, cfgrid, selafin, mike, raster]
"""The reader modules, in the order 'auto' tries them."""

KINDS = tuple(r.KIND for r in READERS)


def _variable_names():
    from . import _netcdf

    names = {}
    for roles in (_netcdf.ROLES, mike.ROLES, selafin.ROLES, openfoam.SHALLOW_WATER_NAMES,
                  openfoam.VOF_NAMES, raster._GEOTIFF_DEFAULTS):
        names.update(dict.fromkeys(roles))
    return tuple(names)


VARIABLE_NAMES = _variable_names()
"""The driftlog names ``variables`` maps to a source's variables (the readers' roles)."""


def _register_with_files():
    """Tell ``driftlog.files.sniff`` about the readers of other models' files."""
    from driftlog.files import CONTENT_CHECKS, register_reader

    from ._netcdf import check_netcdf3_size

    for r in READERS:
        if r.KIND not in ("file", "ugrid", "cf_grid", "anuga"):  # NetCDF: sniffed by content
            register_reader(r.KIND, r.can_open)
    if check_netcdf3_size not in CONTENT_CHECKS:
        CONTENT_CHECKS.append(check_netcdf3_size)


_register_with_files()


def reader(kind):
    """The reader module of a kind (FlowFileError naming the known kinds if none)."""
    for r in READERS:
        if r.KIND == kind:
            return r
    raise FlowFileError(f"format {kind!r} unknown; one of {', '.join(KINDS)} or 'auto'")


def options_section(kind) -> Section:
    """The ``[flow.options]`` section of a reader (its ``OPTIONS`` keys)."""
    return Section("flow.options", list(reader(kind).OPTIONS), doc=f"options of {kind!r}")


def detect_format(path) -> str:
    """The kind of a hydro source: the first reader of ``READERS`` that can open it."""
    p = Path(path)
    if not p.exists():
        raise FlowFileError(f"{p}: file or directory not found")
    for r in READERS:
        if r.can_open(p):
            return r.KIND
    from driftlog.files import sniff

    fk = sniff(p)  # what it is, when no reader opens it: a clearer message than "unknown"
    if fk.kind in ("trajectories", "partial", "scenario", "empty", "binary", "ensemble",
                   "mesh", "mesh_file"):  # (truncated NetCDF, text: the NetCDF opener says why)
        raise _not_a_hydro_source(fk)
    if p.is_dir():
        raise FlowFileError(f"{p}: unknown layout: a directory that is not an OpenFOAM case "
                            "(no system/controlDict, constant/polyMesh or processor*)")
    with open_dataset(p) as ds:
        names = sorted(ds.variables)[:12]
    raise FlowFileError(f"{p}: unknown layout: not a UGRID mesh (no cf_role = mesh_topology), "
                        f"not an ANUGA sww (x, y, volumes, stage), not a CF grid (1-D x, y "
                        f"coordinates); variables: {names}")


def _not_a_hydro_source(fk):
    return FlowFileError(f"{fk.path}: {fk.describe()}; a hydro source must be a driftlog flow "
                         "file, another model's output (" + ", ".join(KINDS[1:])
                         + ") or an OpenFOAM case")


def check_options(kind, options: dict, path) -> dict:
    """Options checked against the reader's ``OPTIONS`` (unknown ones refused)."""
    r = reader(kind)
    allowed = sorted(k.name for k in r.OPTIONS)
    unknown = set(options) - set(allowed)
    if unknown:
        raise FlowFileError(f"{path}: options {sorted(unknown)} do not apply to {kind!r} "
                            f"(allowed: {allowed or 'none'})")
    base = Path(path).parent
    return check_table(options_section(kind), options, "options", base, fill=False)


def open_flow_source(kind, path, time_range=None, variables=None, dry_depth=1e-3, **options):
    """Open a hydro source as a MeshFlowField.

    Parameters
    ----------
    kind : str
        'auto' or a reader's KIND (``KINDS``: 'file', 'openfoam', 'ugrid', 'anuga',
        'cf_grid'...).
    path : path
        File, or OpenFOAM case directory.
    time_range : (start, end), optional
        Only the snapshots in [start, end] (s).
    variables : dict, optional
        driftlog name (depth, level, bed, u, v, hu, hv, alpha) -> the source's variable name.
    dry_depth : float
        Depth below which a face is dry (m).
    **options
        The reader's own ``OPTIONS``: openfoam ``decomposed``, ``mode`` ('shallow_water' |
        'vof'), ``mesh2d``, ``raster``; ugrid / cf_grid ``fill`` ('error' | 'dry'), ``units``;
        anuga ``use_centroids``.
    """
    path = Path(path)
    auto = kind in (None, "auto")
    if auto:
        kind = detect_format(path)
    if kind not in KINDS:
        raise FlowFileError(f"{path}: format {kind!r} unknown; one of {', '.join(KINDS)} "
                            "or 'auto'")
    options = check_options(kind, options, path)
    unknown = sorted(set(variables or {}) - set(VARIABLE_NAMES))
    if unknown:
        raise FlowFileError(f"{path}: variables {unknown}: not names driftlog knows (one of "
                            f"{', '.join(VARIABLE_NAMES)})")
    try:
        return reader(kind).open(path, time_range=time_range, variables=dict(variables or {}),
                                 dry_depth=dry_depth, **options)
    except FlowFileError:
        if auto and kind == "ugrid":  # a UGRID mesh without a flow: said so, not "unknown layout"
            from driftlog.files import sniff

            fk = sniff(path)
            if fk.kind == "mesh":
                raise _not_a_hydro_source(fk) from None
        raise


def check_flow_options(section: dict, prefix: str, base_dir: Path) -> dict:
    """Check the ``[flow.options]`` of a validated ``[flow]`` table.

    Checked against its reader's ``OPTIONS`` (ScenarioError naming ``flow.options.<key>``);
    sources that are not readers take them unchecked.
    """
    kind = section["source"]
    if kind not in KINDS:
        return section["options"]
    return check_table(options_section(kind), section["options"], f"{prefix}.options", base_dir,
                       fill=False)


def flow_from_scenario(scenario):
    """The FlowField of a validated scenario's ``[flow]`` section.

    For the sources of ``KINDS`` (file, openfoam, ugrid, anuga, cf_grid...), or 'auto' (the
    reader whose ``can_open`` takes the file); frozen at ``steady_at`` if set.

    ``scenario``: a ``driftlog.scenario.Scenario`` or its ``[flow]`` table (a dict).
    """
    flow = scenario["flow"] if not isinstance(scenario, dict) or "flow" in scenario else scenario
    kind = flow["source"]
    if kind not in KINDS and kind != "auto":
        raise FlowFileError(f"[flow] source = {kind!r} is not read by driftlog.adapters (it "
                            f"reads {', '.join(KINDS)}); 'analytic' and 'solver' are built "
                            "elsewhere")
    field = open_flow_source(kind, flow["path"], time_range=flow["time_range"],
                             variables=flow["variables"], dry_depth=flow["dry_depth"],
                             **flow["options"])
    if flow["steady_at"] is not None:
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
    if getattr(field, "location", "face") == "node":
        note = "node values averaged on each face (a driftlog flow file holds face values)"
        attrs["import_notes"] = "; ".join(filter(None, [attrs.get("import_notes"), note]))
    tmp = temporary_name(output)  # renamed when complete: never a truncated flow file
    try:
        writer = FlowFileWriter(tmp, field.mesh, field.bed, attrs=attrs, compress=compress)
    except OSError as exc:
        raise FlowFileError(f"{output}: cannot write the flow file ({exc})") from None
    try:
        deepest = 0.0
        with writer as w:
            for i, t in enumerate(field.times):
                h, hu, hv = checked_snapshot(field, i)
                w.write(float(t), h, hu=hu, hv=hv, dry_depth=field.dry_depth)
                deepest = max(deepest, float(h.max(initial=0.0)))
                if progress is not None:
                    progress(i + 1, field.times.size)
        if 0.0 < deepest <= field.dry_depth:  # every velocity zeroed: not a flow any more
            raise FlowFileError(f"{output}: not written: dry_depth = {field.dry_depth:g} m is "
                                f"at or above the deepest water of {source} ({deepest:g} m), "
                                "every face would be dry; give a dry depth below it "
                                "(--dry-depth)")
        os.replace(tmp, output)
    finally:
        tmp.unlink(missing_ok=True)
        if not keep_open and hasattr(field.source, "close"):
            field.source.close()
    return Path(output), field


def checked_snapshot(field, i):
    """Snapshot i of a field's source as face arrays (h, hu, hv).

    Checked as the sampler checks them (sizes, finite values, no negative depth), without the
    node interpolation.
    """
    return field.read_snapshot(i)

