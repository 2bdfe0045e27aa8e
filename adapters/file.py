"""driftlog's own flow file (UGRID-1.0 + CF NetCDF, ``driftlog.flowfile``) as a reader."""

from __future__ import annotations

from driftlog.flow import MeshFlowField
from driftlog.flowfile import open_flow

from ._common import SubsetSnapshots, select_times
from ._netcdf import netcdf_matches
from .ugrid import is_ugrid

__all__ = ["KIND", "SUFFIXES", "OPTIONS", "can_open", "open"]

KIND = "file"
SUFFIXES = (".nc",)
OPTIONS = []

_OWN = ("water_depth", "velocity_x", "velocity_y", "bed_level")


def can_open(path) -> bool:
    """Whether ``path`` is a flow file written by driftlog (UGRID with driftlog's variables)."""
    return netcdf_matches(path, lambda ds: is_ugrid(ds) and "driftlog_version" in ds.ncattrs()
                          and all(v in ds.variables for v in _OWN))


def open(path, *, time_range=None, variables=None, dry_depth=1e-3):
    """Open a driftlog flow file as a MeshFlowField.

    ``variables`` do not apply: the file's names are driftlog's.
    """
    field = open_flow(path, dry_depth=dry_depth)
    if time_range is not None:
        idx = select_times(field.times, time_range, str(path))
        field = MeshFlowField(field.mesh, field.bed, SubsetSnapshots(field.source, idx),
                              field.dry_depth, field.name, field.attrs)
    return field
