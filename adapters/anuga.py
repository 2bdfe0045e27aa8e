"""ANUGA ``.sww`` results as driftlog flows.

An sww file holds a triangle mesh (``volumes``, 0-based, three ``number_of_points`` indices)
with node coordinates ``x``, ``y`` relative to the global attributes ``xllcorner``,
``yllcorner``; per time: ``stage``, ``xmomentum``, ``ymomentum`` at the vertices, and at the
centroids (``stage_c``...) when the run stored them (``domain.set_store_centroids(True)``);
``elevation`` (static, or per time), ``time`` relative to the ``starttime`` attribute.  The
georeference attributes say UTM metres (``projection``, ``units``); coordinates whose ``units``
are degrees are refused.

Face values are the centroid values when present (ANUGA's conserved quantities), else the mean
of the three vertex values of each triangle (equal to the centroid value for ANUGA's linear
reconstruction when vertices are stored uniquely; an approximation when they were smoothed).
Depth is stage - elevation, unit discharges are the momenta.  Vertices stored uniquely (one copy
per triangle) are merged by position so that the mesh is connected.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError, MeshError
from driftlog.flow import MeshFlowField, check_times
from driftlog.mesh import mesh_merging_seams
from driftlog.schema import Key

from ._common import SubsetSnapshots, geographic_error, select_times
from ._netcdf import NetCDFSource, netcdf_matches, open_dataset

__all__ = ["open_anuga", "is_sww", "AnugaSnapshots"]

REQUIRED = ("x", "y", "volumes", "time", "stage", "xmomentum", "ymomentum", "elevation")


def is_sww(ds) -> bool:
    """Whether an open NetCDF dataset has the layout of an ANUGA sww file."""
    return all(v in ds.variables for v in ("x", "y", "volumes", "stage"))


class AnugaSnapshots(NetCDFSource):
    """Lazy snapshots of an sww file: one time of stage and momenta read per ``read(i)``."""

    def __init__(self, ds, path, times, volumes, names, bed_static, centroids):
        super().__init__(ds, path, times, {"level": 0, "hu": 0, "hv": 0}, bed_static)
        self.volumes, self.names, self.centroids = volumes, names, centroids

    def _get(self, role, i):
        var = self.ds.variables[self.names[role]]
        arr = self._values(var, i, np.asarray(var[i] if var.ndim == 2 else var[:], np.float64))
        if not self.centroids:
            arr = arr[self.volumes].mean(axis=1)
        return arr

    def read(self, i):
        """Face arrays (h, hu, hv) of snapshot i (with that time's elevation if it changes)."""
        if self.bed is None or self.dynamic_bed:
            self.bed = self._get("bed", i)
        return super().read(i)

    dynamic_bed = False


def open_anuga(path, time_range=None, dry_depth=1e-3, use_centroids=None, variables=None):
    """Open an ANUGA .sww file as a MeshFlowField (snapshots read lazily).

    ``use_centroids``: True/False forces centroid or vertex values (default: centroids when
    the file has them).  ``variables`` maps driftlog names (level, bed, hu, hv) to other
    variable names.
    """
    path = Path(path)
    ds = open_dataset(path)
    try:
        return _open(ds, path, time_range, dry_depth, use_centroids, variables or {})
    except BaseException:
        ds.close()
        raise


def _open(ds, path, time_range, dry_depth, use_centroids, mapping):
    names = {"level": mapping.get("level", "stage"), "hu": mapping.get("hu", "xmomentum"),
             "hv": mapping.get("hv", "ymomentum"), "bed": mapping.get("bed", "elevation")}
    missing = [v for v in ("x", "y", "volumes", "time", *names.values())
               if v not in ds.variables]
    if missing:
        raise FlowFileError(f"{path}: not an ANUGA sww file, or an incomplete one: variables "
                            f"{missing} are missing (an sww has {', '.join(REQUIRED)})")
    # ANUGA's georeference: projection 'UTM', units 'm' (ANUGA warns that it does not correct
    # for other units); degrees would be longitude / latitude
    units = str(getattr(ds, "units", "")).strip()
    if units.lower().startswith("degree"):
        raise geographic_error(path, "global attribute 'units'", units)
    xll = float(getattr(ds, "xllcorner", 0.0))
    yll = float(getattr(ds, "yllcorner", 0.0))
    x = np.asarray(ds.variables["x"][:], np.float64) + xll
    y = np.asarray(ds.variables["y"][:], np.float64) + yll
    vols = np.asarray(ds.variables["volumes"][:], np.int64)
    if vols.ndim != 2 or vols.shape[1] != 3:
        raise FlowFileError(f"{path}: unsupported element type: volumes has shape {vols.shape}, "
                            "ANUGA meshes are triangles (n, 3)")
    if vols.size and (vols.min() < 0 or vols.max() >= x.size):
        raise FlowFileError(f"{path}: volumes refer to points outside 0..{x.size - 1}")
    notes = []
    if xll or yll:
        notes.append(f"coordinates shifted by (xllcorner, yllcorner) = ({xll:g}, {yll:g})")
    # merge vertices stored once per triangle (and the seams of parallel runs' merged files),
    # so that neighbours share their nodes: within 1e-6 of the local edge length
    try:
        mesh = mesh_merging_seams(x, y, vols)
        if mesh.merged_nodes[0]:
            notes.append(f"{mesh.merged_nodes[0]} duplicate vertices merged (closer than "
                         f"{mesh.merged_nodes[1]:g} x the local edge length)")
    except MeshError as exc:
        raise FlowFileError(f"{path}: the triangles do not make a valid mesh: {exc}") from None
    times = np.asarray(ds.variables["time"][:], np.float64) + float(getattr(ds, "starttime", 0))
    check_times(times, str(path))
    centroid_names = {k: v + "_c" for k, v in names.items()}
    have_c = all(v in ds.variables for v in centroid_names.values())
    centroids = have_c if use_centroids is None else bool(use_centroids)
    if centroids and not have_c:
        raise FlowFileError(f"{path}: no centroid values ({sorted(centroid_names.values())}); "
                            "the run did not call set_store_centroids(True): use vertex values")
    if centroids:
        names = centroid_names
        notes.append("centroid values")
    else:
        notes.append("vertex values averaged on triangles")
    for role in ("level", "hu", "hv"):
        var = ds.variables[names[role]]
        nloc = vols.shape[0] if centroids else x.size
        if var.ndim != 2 or var.shape != (times.size, nloc):
            raise FlowFileError(f"{path}: {var.name} has shape {var.shape}, expected "
                                f"({times.size}, {nloc}) (times, "
                                f"{'volumes' if centroids else 'points'})")
    bvar = ds.variables[names["bed"]]
    src = AnugaSnapshots(ds, path, times, vols, names, None, centroids)
    bed = src._get("bed", 0)
    src.bed = bed
    if bvar.ndim == 2:
        src.dynamic_bed = True
        notes.append("elevation changes with time: depth uses each time's elevation, the bed "
                     "shown is the first")
    idx = select_times(times, time_range, str(path))
    source = SubsetSnapshots(src, idx) if idx.size != times.size else src
    attrs = {"source": f"anuga {getattr(ds, 'anuga_version', '')}".strip(),
             "source_path": str(path.resolve()), "import_notes": "; ".join(notes),
             "xllcorner": xll, "yllcorner": yll}
    return MeshFlowField(mesh, bed, source, dry_depth=dry_depth, name=str(path), attrs=attrs)


# --------------------------------------------------------------------- the reader contract
KIND = "anuga"
SUFFIXES = (".sww",)
OPTIONS = [
    Key("use_centroids", "bool", None, "true/false forces centroid or vertex values (default: "
        "centroids when the file has them)"),
]


def can_open(path) -> bool:
    """Whether ``path`` is an ANUGA sww file (by suffix or layout; never raises)."""
    p = Path(path)
    if p.suffix.lower() == ".sww" and p.is_file():
        return True
    return netcdf_matches(p, is_sww)


def open(path, *, time_range=None, variables=None, dry_depth=1e-3, **options):
    """``open_anuga`` under the reader contract (``options``: ``OPTIONS``)."""
    return open_anuga(path, time_range=time_range, variables=variables, dry_depth=dry_depth,
                      **options)
