"""Trajectory files: CF-1.11 ``featureType = "trajectory"`` NetCDF, and VTK for ParaView.

While a run goes, records are appended as an *indexed* ragged array (CF 9.3.4: each
observation carries ``trajectory_index``) and flushed every few records, so a crash loses at
most the last flush and a run can resume from the last complete record.  When the run ends the
file is rewritten as a *contiguous* ragged array (CF 9.3.3: ``rowSize`` per trajectory, each
log's observations together), the layout of the final product.  ``open_trajectories`` reads
either layout into an xarray Dataset.

Per-log properties (length, radius, density, release time, group) are trajectory variables;
the status is an integer with ``flag_values`` / ``flag_meanings``; the whole scenario and the
driftlog version are global attributes.  Contacts (hits) are a third dimension ``hit``.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from pathlib import Path

import netCDF4
import numpy as np

from driftlog._version import __version__
from driftlog.flowfile import TIME_UNITS, _attrs_for_netcdf
from driftlog.logs import STATUS_MEANINGS
from driftlog.schema import Key, Section

__all__ = ["TrajectoryWriter", "open_trajectories", "write_vtk", "last_states"]

OBS_VARS = {
    "x": ("f8", dict(standard_name="projection_x_coordinate", long_name="x of the log centre",
                     units="m", axis="X")),
    "y": ("f8", dict(standard_name="projection_y_coordinate", long_name="y of the log centre",
                     units="m", axis="Y")),
    "theta": ("f8", dict(long_name="angle of the log axis to the x axis", units="rad")),
    "u": ("f8", dict(long_name="log velocity, x component", units="m s-1")),
    "v": ("f8", dict(long_name="log velocity, y component", units="m s-1")),
    "omega": ("f8", dict(long_name="log angular velocity (counter-clockwise)", units="rad s-1")),
    "status": ("i1", dict(long_name="log status", flag_values=np.arange(5, dtype=np.int8),
                          flag_meanings=STATUS_MEANINGS)),
    "water_depth": ("f4", dict(long_name="water depth at the log centre", units="m")),
    "flow_u": ("f4", dict(long_name="flow velocity at the log centre, x component",
                          units="m s-1")),
    "flow_v": ("f4", dict(long_name="flow velocity at the log centre, y component",
                          units="m s-1")),
}
TRAJ_VARS = {
    "length": ("f8", dict(long_name="log length L", units="m")),
    "radius": ("f8", dict(long_name="log radius r", units="m")),
    "density": ("f8", dict(long_name="log density rho_b", units="kg m-3")),
    "release_time": ("f8", dict(long_name="release time", units="s")),
    "group": ("i4", dict(long_name="index of the [[logs]] group of the scenario")),
    "flotation_depth": ("f8", dict(long_name="depth at which the log floats (MODEL.md 3)",
                                   units="m")),
}
HIT_VARS = {
    "hit_time": ("f8", dict(long_name="time of contact", units="s")),
    "hit_log": ("i8", dict(long_name="log (trajectory id) in contact")),
    "hit_other": ("i8", dict(long_name="other body: a log id (>= 0) or -(obstacle index + 1)")),
    "hit_impulse": ("f8", dict(long_name="normal impulse", units="N s")),
    "hit_x": ("f8", dict(long_name="contact point x", units="m")),
    "hit_y": ("f8", dict(long_name="contact point y", units="m")),
}


class TrajectoryWriter:
    """Write a trajectory file record by record (indexed ragged), contiguous at ``close()``.

    Parameters
    ----------
    path : path
        Final file; while running, data goes to ``path`` + ``.partial``.
    logs : Logs
    attrs : dict
        Global attributes (scenario, physics choices...).
    flush_interval : int
        Records between flushes.
    resume : bool
        Append to an existing ``.partial`` file (after a crash) instead of starting afresh.
    """

    def __init__(self, path, logs, attrs=None, flush_interval=10, resume=False,
                 obstacle_names=()):
        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.flush_interval = int(flush_interval)
        self._buf = []
        if resume:
            self.ds = netCDF4.Dataset(self.partial, "a")
            self.ds.set_auto_maskandscale(False)  # times are written on the run's clock
            self.nobs = len(self.ds.dimensions["obs"])
            self.nhit = len(self.ds.dimensions["hit"])
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        ds = self.ds = netCDF4.Dataset(self.partial, "w", format="NETCDF4")
        self.nobs = self.nhit = 0
        ds.Conventions = "CF-1.11"
        ds.featureType = "trajectory"
        ds.title = (attrs or {}).get("title") or "driftlog log trajectories"
        ds.driftlog_version = __version__
        ds.history = (f"{_dt.datetime.now(_dt.UTC).isoformat(timespec='seconds')} "
                      f"driftlog {__version__}")
        ds.obstacle_names = json.dumps(list(obstacle_names))
        ds.setncatts(_attrs_for_netcdf({k: v for k, v in (attrs or {}).items() if k != "title"}))
        n = len(logs)
        ds.createDimension("trajectory", n)
        ds.createDimension("obs", None)
        ds.createDimension("hit", None)
        tv = ds.createVariable("trajectory", "i8", ("trajectory",))
        tv.setncatts(dict(cf_role="trajectory_id", long_name="log id"))
        tv[:] = logs.id
        # times: CF units with the flow's own reference (attrs time_units); a run far from the
        # axis' zero is computed on a clock starting at time_offset, and its times are stored
        # on that clock with add_offset = time_offset (CF packing: stored + add_offset is the
        # time on the flow's axis), so the file keeps every digit
        time_attrs = dict(units=str((attrs or {}).get("time_units") or TIME_UNITS))
        offset = float((attrs or {}).get("time_offset") or 0.0)
        shift = dict(add_offset=offset) if offset else {}
        time_attrs.update(shift)
        for name, (dt, a) in TRAJ_VARS.items():
            v = ds.createVariable(name, dt, ("trajectory",))
            v.setncatts(dict(a, **shift) if name == "release_time" else a)
            v.set_auto_maskandscale(False)
            v[:] = {"length": logs.length, "radius": logs.radius, "density": logs.density,
                    "release_time": logs.release_time, "group": logs.group,
                    "flotation_depth": np.where(np.isfinite(logs.float_depth), logs.float_depth,
                                                -1.0)}[name]
        ti = ds.createVariable("trajectory_index", "i8", ("obs",))
        ti.setncatts(dict(long_name="which trajectory this observation is for",
                          instance_dimension="trajectory"))
        t = ds.createVariable("time", "f8", ("obs",))
        t.setncatts(dict(standard_name="time", long_name="time", axis="T", **time_attrs))
        for name, (dt, a) in OBS_VARS.items():
            v = ds.createVariable(name, dt, ("obs",), zlib=True, complevel=1)
            v.setncatts(a)
            v.coordinates = "time x y"
        for name, (dt, a) in HIT_VARS.items():
            v = ds.createVariable(name, dt, ("hit",))
            v.setncatts(dict(a, **shift) if name == "hit_time" else a)
        ds.set_auto_maskandscale(False)  # times are written on the run's clock (add_offset)
        ds.sync()

    def record(self, t, index, columns: dict):
        """Append one record: observations of logs ``index`` at time t (columns by name).

        Records are buffered and written every ``flush_interval`` records (one write per
        variable, not per record).
        """
        if len(index) == 0:
            return
        self._buf.append((t, np.asarray(index).copy(),
                          {k: np.asarray(columns[k]).copy() for k in OBS_VARS}))
        if len(self._buf) >= self.flush_interval:
            self.flush()

    def _write_buffer(self):
        if not self._buf:
            return
        idx = np.concatenate([b[1] for b in self._buf])
        k = idx.size
        sl = slice(self.nobs, self.nobs + k)
        self.ds["trajectory_index"][sl] = idx
        self.ds["time"][sl] = np.concatenate([np.full(b[1].size, b[0]) for b in self._buf])
        for name in OBS_VARS:
            self.ds[name][sl] = np.concatenate([b[2][name] for b in self._buf])
        self.nobs += k
        self._buf = []

    def hits(self, hits: dict):
        """Append contact events (dict of arrays time, log_id, other, impulse, x, y)."""
        k = len(hits.get("time", ()))
        if k == 0:
            return
        sl = slice(self.nhit, self.nhit + k)
        for key, name in (("time", "hit_time"), ("log_id", "hit_log"), ("other", "hit_other"),
                          ("impulse", "hit_impulse"), ("x", "hit_x"), ("y", "hit_y")):
            self.ds[name][sl] = hits[key]
        self.nhit += k

    def flush(self):
        """Write buffered records and sync the file to disk."""
        self._write_buffer()
        self.ds.sync()

    def set_attrs(self, **attrs):
        self.ds.setncatts(_attrs_for_netcdf(attrs))

    def close(self, finalize=True):
        """Close; with ``finalize`` rewrite as a contiguous ragged array at ``path``."""
        if not self.ds.isopen():
            return self.path
        self._write_buffer()
        self.ds.close()
        if finalize:
            _to_contiguous(self.partial, self.path)
            os.remove(self.partial)
            return self.path
        return self.partial


def _to_contiguous(src, dst):
    """Rewrite an indexed ragged trajectory file as a contiguous ragged one (stable by time)."""
    tmp = Path(str(dst) + ".tmp")
    with netCDF4.Dataset(src) as a, netCDF4.Dataset(tmp, "w", format="NETCDF4") as b:
        a.set_auto_maskandscale(False)  # copied as stored (times on the run's clock)
        idx = a["trajectory_index"][:]
        order = np.argsort(idx, kind="stable")
        ntraj = len(a.dimensions["trajectory"])
        b.setncatts({k: a.getncattr(k) for k in a.ncattrs()})
        b.createDimension("trajectory", ntraj)
        b.createDimension("obs", idx.size)
        b.createDimension("hit", len(a.dimensions["hit"]))
        for name, var in a.variables.items():
            if name == "trajectory_index":
                continue
            attrs = {k: var.getncattr(k) for k in var.ncattrs()}
            kw = dict(zlib=True, complevel=1) if var.dimensions == ("obs",) else {}
            v = b.createVariable(name, var.dtype, var.dimensions, **kw)
            v.setncatts(attrs)
            v.set_auto_maskandscale(False)
            data = var[:]
            v[:] = data[order] if var.dimensions == ("obs",) else data
        rs = b.createVariable("rowSize", "i8", ("trajectory",))
        rs.setncatts(dict(long_name="number of observations for this trajectory",
                          sample_dimension="obs"))
        rs[:] = np.bincount(idx, minlength=ntraj)
    os.replace(tmp, dst)


def open_trajectories(path):
    """Open a trajectory file (contiguous or indexed/partial) as an xarray Dataset.

    Times are kept in seconds (``time`` float, s since the run's reference); ``obs`` gets a
    ``trajectory_index`` coordinate in both layouts, for easy selection of one log.
    """
    import xarray as xr

    path = Path(path)
    if not path.exists() and Path(str(path) + ".partial").exists():
        path = Path(str(path) + ".partial")
    ds = xr.open_dataset(path, decode_times=False)
    if "trajectory_index" not in ds and "rowSize" in ds:
        ds = ds.assign_coords(trajectory_index=("obs", np.repeat(
            np.arange(ds.sizes["trajectory"]), ds["rowSize"].values)))
    elif "trajectory_index" in ds:
        ds = ds.set_coords("trajectory_index")
    ds["time"].attrs["units"] = "s"
    return ds


def last_states(path):
    """Where a stopped run can resume: the time of its last record and each log's last state.

    Returns (time, index, columns) with the last observation of every log that has one (logs
    that left the domain earlier keep their last, 'left_domain', observation), or None if the
    file holds no record.
    """
    with netCDF4.Dataset(path) as ds:
        ds.set_auto_maskandscale(False)  # times on the run's clock (as the tracker counts)
        t = ds["time"][:]
        if t.size == 0:
            return None
        ti = ds["trajectory_index"][:]
        order = np.lexsort((t, ti))
        last = order[np.flatnonzero(np.diff(np.append(ti[order], -1)) != 0)]
        cols = {name: ds[name][:][last] for name in OBS_VARS}
        return float(t.max()), ti[last], cols


def write_vtk(path, out_dir=None, every=1):
    """ParaView files for a trajectory file: one .vtu per record time (logs as line segments
    with radius, status and velocity as cell data) and a .pvd collection indexing them by time.

    In ParaView, open the .pvd and apply a Tube filter (radius by the 'radius' array) to draw
    the logs as cylinders.  Returns the .pvd path.
    """
    import meshio

    ds = open_trajectories(path)
    out_dir = Path(out_dir or Path(path).with_suffix("")).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    t = ds["time"].values
    ti = ds["trajectory_index"].values
    x, y, th = ds["x"].values, ds["y"].values, ds["theta"].values
    L = ds["length"].values[ti]
    r = ds["radius"].values[ti]
    times = np.unique(t)[::every]
    entries = []
    for k, tk in enumerate(times):
        sel = np.flatnonzero(t == tk)
        hx, hy = 0.5 * L[sel] * np.cos(th[sel]), 0.5 * L[sel] * np.sin(th[sel])
        pts = np.zeros((2 * sel.size, 3))
        pts[0::2, 0], pts[0::2, 1] = x[sel] - hx, y[sel] - hy
        pts[1::2, 0], pts[1::2, 1] = x[sel] + hx, y[sel] + hy
        cells = [("line", np.arange(2 * sel.size).reshape(-1, 2))]
        cd = {"log_id": [ti[sel].astype(np.int64)], "radius": [r[sel]],
              "status": [ds["status"].values[sel].astype(np.int32)],
              "speed": [np.hypot(ds["u"].values[sel], ds["v"].values[sel])]}
        name = f"logs_{k:06d}.vtu"
        meshio.write(out_dir / name, meshio.Mesh(pts, cells, cell_data=cd))
        entries.append(f'    <DataSet timestep="{tk:.9g}" part="0" file="{name}"/>')
    pvd = out_dir / "logs.pvd"
    pvd.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                   "  <Collection>\n" + "\n".join(entries) + "\n  </Collection>\n</VTKFile>\n")
    return pvd


# --------------------------------------------------------------------- the scenario section
OUTPUT_SECTION = Section("output", [
    Key("path", "path", "trajectories.nc", "trajectory file (CF-1.11 trajectory NetCDF)"),
    Key("vtk", "bool", False, "also write VTK (ParaView) files beside the trajectory file"),
    Key("figure", "bool", False, "draw a figure of the trajectories"),
    Key("animation", "bool", False, "write an animation (MP4 if ffmpeg is there, else GIF)"),
    Key("flush_interval", "int", 10, "records between flushes to disk", min=1),
], doc="what is written")
