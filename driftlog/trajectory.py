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

__all__ = ["TrajectoryWriter", "RenumberedWriter", "open_trajectories", "write_vtk",
           "write_flow_vtk", "last_states", "check_resume", "require_observations"]

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
# observations written only by runs that need them (the tracker passes the column)
EXTRA_OBS_VARS = {
    "log_density": ("f8", dict(long_name="log density rho_b (waterlogging, docs/model.md 6.2)",
                               units="kg m-3")),
}
TRAJ_VARS = {
    "length": ("f8", dict(long_name="log length L", units="m")),
    "radius": ("f8", dict(long_name="log radius r", units="m")),
    "density": ("f8", dict(long_name="log density rho_b", units="kg m-3")),
    "release_time": ("f8", dict(long_name="release time", units="s")),
    "group": ("i4", dict(long_name="index of the [[logs]] group of the scenario")),
    "flotation_depth": ("f8", dict(long_name="depth at which the log floats "
                                             "(docs/model.md section 6)", units="m")),
}
HIT_VARS = {
    "hit_time": ("f8", dict(long_name="time of contact", units="s")),
    "hit_log": ("i8", dict(long_name="log (trajectory id) in contact")),
    "hit_other": ("i8", dict(long_name="other body: a log id (>= 0) or -(obstacle index + 1)")),
    "hit_impulse": ("f8", dict(long_name="normal impulse", units="N s")),
    "hit_x": ("f8", dict(long_name="contact point x", units="m")),
    "hit_y": ("f8", dict(long_name="contact point y", units="m")),
}


# observations buffered at most before a flush, whatever flush_interval says: the buffer of a
# run with many logs stays bounded (1e6 logs x 10 records would hold 1e7 observations, 0.85 GB)
MAX_BUFFERED_OBS = 1 << 20

HIT_KEYS = (("time", "hit_time"), ("log_id", "hit_log"), ("other", "hit_other"),
            ("impulse", "hit_impulse"), ("x", "hit_x"), ("y", "hit_y"))

# observations per HDF5 chunk of the obs variables (512 kB of float64).  netCDF-C's defaults
# are far off for this file: 512 observations per chunk while a run appends (a chunk index
# entry and a compressor call per 4 kB), and the whole dimension in one chunk in the final
# file (each block written there recompressed all of it)
OBS_CHUNK = 1 << 16
# the running file's smallest chunk: each sync compresses the chunk being filled again, so a
# run that flushes few observations at a time (a coupled run flushes every record) gets chunks
# of about four flushes (``running_chunk``), not OBS_CHUNK
MIN_RUNNING_CHUNK = 1 << 12


def running_chunk(n_logs, records_per_flush):
    """Observations per chunk of a ``.partial`` file flushed every ``records_per_flush`` records.

    About four flushes' worth (a power of two from ``MIN_RUNNING_CHUNK`` to ``OBS_CHUNK``): at
    each sync HDF5 compresses the partly filled chunk again, so a chunk much larger than a
    flush costs a compression of up to ``OBS_CHUNK`` observations per record written.
    """
    want = 4 * max(1, int(n_logs)) * max(1, int(records_per_flush))
    return int(min(OBS_CHUNK, max(MIN_RUNNING_CHUNK, 1 << (want - 1).bit_length())))


def _obs_storage(ds, partial, nobs=None, chunk=None):
    """The storage arguments (to ``createVariable``) of an obs variable of ``ds``.

    The final file: zlib level 1 with shuffle, which every netCDF-4 reader decodes.  The
    ``.partial`` file of a running run, which driftlog rewrites at the end (and reads again
    to resume): Zstandard level 1 where the netCDF library has the filter (the netCDF4 wheels
    carry it): 12 % larger than zlib's on the trajectories of a flood, five times faster;
    zlib where it has not.  (Blosc's LZ4 was as fast, but its HDF5 filter prints an error
    for every chunk it cannot shrink.)
    """
    if chunk is None:
        chunk = OBS_CHUNK if nobs is None else max(1, min(OBS_CHUNK, nobs))
    kw = dict(chunksizes=(chunk,), complevel=1, shuffle=True, compression="zlib")
    if partial and ds.has_zstd_filter():
        kw.update(compression="zstd", shuffle=False)  # netCDF4 sets no shuffle with zstd
    return kw


def _small_chunk_cache(var):
    """Give an obs variable a chunk cache of 4 chunks (netCDF-C's default: 64 MiB each).

    Records are appended, and the contiguous file written, in order: only the chunk being
    filled is ever read again.  With the default caches a million-log run held 300 MB more.
    """
    if var.dimensions == ("obs",) and var.chunking() != "contiguous":
        var.set_var_chunk_cache(size=4 * var.chunking()[0] * var.dtype.itemsize)
    return var


class RenumberedWriter:
    """A writer seen by a tracker whose logs are listed in another order.

    The tracker's log ``i`` is log ``order[i]`` of the writer (a ``TrajectoryWriter`` or an
    ensemble's recorder).

    Each record reaches the writer as the tracker would have sent it with the logs in the
    writer's order (its logs ascending, their columns taken along), so the file is the same
    byte for byte.  Everything else (``hits``: contact events carry log ids, which a
    renumbering keeps; ``flush``, ``set_attrs``, ``close``...) goes to the writer unchanged.
    """

    def __init__(self, writer, order):
        self._writer = writer
        self._order = np.asarray(order, dtype=np.int64)
        self._inverse = np.empty_like(self._order)  # the writer's log -> the tracker's
        self._inverse[self._order] = np.arange(self._order.size)

    def record(self, t, index, columns: dict):
        """``TrajectoryWriter.record`` of the tracker's logs ``index``, in the writer's order."""
        index = np.asarray(index, dtype=np.int64)
        if index.size == self._order.size:  # every log (the index ascending: all of them)
            take = self._inverse
        else:
            # each row's place in the record, read along the writer's logs: linear time, no
            # sort (which took several times as long on a million logs)
            pos = np.full(self._order.size, -1, np.int64)
            pos[index] = np.arange(index.size)
            take = pos[self._inverse]
            take = take[take >= 0]
        self._writer.record(t, self._order[index[take]],
                            {k: np.asarray(v)[take] for k, v in columns.items()})

    def __getattr__(self, name):
        return getattr(self._writer, name)


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
        Records between flushes (sooner when ``MAX_BUFFERED_OBS`` observations are buffered).
    resume : bool
        Append to an existing ``.partial`` file (after a crash) instead of starting afresh.
    until : float, optional
        With ``resume``: continue after the records up to this time only (a coupled run
        resumes where its flow was kept, which may be one output before its last record):
        the records after it are written again by the resumed run.
    flush_every_record : bool
        The caller flushes after every record (a coupled run, with its flow file): the
        running file's chunks are sized for that (``running_chunk``).
    """

    # ``keep_counts``' latest entries, and what it reads, for subclasses too whose __init__ of
    # their own records elsewhere (tests' spies, users' recorders)
    _counts = None
    nhit = 0
    _hbuf = ()

    def __init__(self, path, logs, attrs=None, flush_interval=10, resume=False,
                 obstacle_names=(), until=None, flush_every_record=False):
        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.flush_interval = int(flush_interval)
        # observations per chunk of the obs variables created here (running_chunk)
        self._chunk = running_chunk(len(logs), 1 if flush_every_record else flush_interval)
        self._buf = []
        self._nbuf = 0  # observations in _buf
        self._hbuf = []
        if resume:
            reopen_partial(self.partial)  # killed while open: HDF5 refuses to write it again
            self.ds = netCDF4.Dataset(self.partial, "a")
            self.ds.set_auto_maskandscale(False)  # times are written on the run's clock
            for v in self.ds.variables.values():
                _small_chunk_cache(v)
            chunks = self.ds["time"].chunking()
            if isinstance(chunks, list):  # the file's own, for obs variables created later
                self._chunk = int(chunks[0])
            self.nobs = _obs_count(self.ds)
            # hits belong to the records up to their time: those after the last record are
            # recomputed by the resumed run (and overwritten here)
            t = self.ds["time"][:self.nobs]
            if until is not None:  # records are appended in time order
                self.nobs = int(np.searchsorted(t, until, side="right"))
                t = t[:self.nobs]
            t_last = float(t.max()) if t.size else -np.inf
            self.nhit = int(np.sum(self.ds["hit_time"][:] <= t_last)) if t.size else 0
            kept = _counts_at(self.ds, t_last) if t.size else None
            if kept is not None and "hits" in kept:  # exact: the hits drained up to t_last
                self.nhit = int(kept["hits"])
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
        obs = _obs_storage(ds, True, chunk=self._chunk)
        ti = ds.createVariable("trajectory_index", "i8", ("obs",), **obs)
        ti.setncatts(dict(long_name="which trajectory this observation is for",
                          instance_dimension="trajectory"))
        t = ds.createVariable("time", "f8", ("obs",), **obs)
        t.setncatts(dict(standard_name="time", long_name="time", axis="T", **time_attrs))
        for name, (dt, a) in OBS_VARS.items():
            v = ds.createVariable(name, dt, ("obs",), **obs)
            v.setncatts(a)
            v.coordinates = "time x y"
        for name, (dt, a) in HIT_VARS.items():
            v = ds.createVariable(name, dt, ("hit",))
            v.setncatts(dict(a, **shift) if name == "hit_time" else a)
        ds.set_auto_maskandscale(False)  # times are written on the run's clock (add_offset)
        for v in ds.variables.values():
            _small_chunk_cache(v)
        ds.sync()

    def record(self, t, index, columns: dict):
        """Append one record: observations of logs ``index`` at time t (columns by name).

        Records are buffered and written every ``flush_interval`` records (one write per
        variable, not per record), or as soon as ``MAX_BUFFERED_OBS`` observations are
        buffered.
        """
        if len(index) == 0:
            return
        names = [*OBS_VARS, *(k for k in EXTRA_OBS_VARS if k in columns)]
        self._buf.append((t, np.asarray(index).copy(),
                          {k: np.asarray(columns[k]).copy() for k in names}))
        self._nbuf += len(index)
        if len(self._buf) >= self.flush_interval or self._nbuf >= MAX_BUFFERED_OBS:
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
        for name in (k for k in EXTRA_OBS_VARS if k in self._buf[0][2]):
            if name not in self.ds.variables:  # created with the first record that has it
                dt, a = EXTRA_OBS_VARS[name]
                v = _small_chunk_cache(self.ds.createVariable(name, dt, ("obs",),
                                                              **_obs_storage(self.ds, True,
                                                                             chunk=self._chunk)))
                v.setncatts(a)
                v.coordinates = "time x y"
                v.set_auto_maskandscale(False)
            self.ds[name][sl] = np.concatenate([b[2][name] for b in self._buf])
        self.nobs += k
        self._buf = []
        self._nbuf = 0
        if self._hbuf:
            k = sum(len(h["time"]) for h in self._hbuf)
            sl = slice(self.nhit, self.nhit + k)
            for key, name in HIT_KEYS:
                self.ds[name][sl] = np.concatenate([np.asarray(h[key]) for h in self._hbuf])
            self.nhit += k
            self._hbuf = []
        self.ds.hit_count = self.nhit
        self.ds.obs_count = self.nobs
        if self._counts is not None:
            self.ds.resume_counts = "[" + ", ".join(self._counts) + "]"

    def hits(self, hits: dict):
        """Append contact events (dict of arrays time, log_id, other, impulse, x, y).

        Buffered with the records and written with them, in the same flush: a run killed
        between two flushes loses the records and the hits of the same intervals, which a
        resumed run recomputes together.
        """
        k = len(hits.get("time", ()))
        if k == 0:
            return
        self._hbuf.append({key: np.asarray(hits[key]).copy() for key, _ in HIT_KEYS})

    def keep_counts(self, t, tracker, contact=None, active=None):
        """The run's statistics up to its record at ``t`` (dicts of numbers), written with it.

        ``active``: the contact model's pairs in contact at ``t`` (integer keys), so that a
        resumed run does not take a contact that goes on pushing for a new hit.  Kept as the
        attribute ``resume_counts`` at the next flush, with those of the record before (a
        coupled run may resume one output before its last record), so that a resumed run adds
        to them (``kept_counts``).
        """
        # the hits up to this record: those drained for it are buffered already
        hits = self.nhit + sum(len(h["time"]) for h in self._hbuf)
        entry = json.dumps({"time": float(t), "hits": hits, "tracker": tracker,
                            "contact": contact,
                            "contact_active": None if active is None else
                            np.asarray(active, np.int64).tolist()}, default=float)
        self._counts = (self._counts or [])[-1:] + [entry]

    def flush(self):
        """Write buffered records and hits, and sync the file to disk."""
        self._write_buffer()
        self.ds.sync()

    def set_attrs(self, **attrs):
        """Set global attributes of the file."""
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


def reopen_partial(partial):
    """Make a ``.partial`` trajectory file writable again; True if a killed process left it open.

    ``driftlog.files.reopen_partial``: such a file is copied to a fresh one, each obs variable
    with the running file's storage and a small chunk cache.
    """
    from driftlog.files import reopen_partial as reopen

    return reopen(partial, storage=_copy_storage, prepare=_small_chunk_cache)


def _copy_storage(ds, var):
    """The storage of ``var`` in the copy of a killed ``.partial`` file (None: its own)."""
    if var.dimensions != ("obs",):
        return None
    chunks = var.chunking()  # the file's own chunks (sized to its flushes: running_chunk)
    return _obs_storage(ds, True, chunk=chunks[0] if isinstance(chunks, list) else None)


_BLOCK = 1 << 20  # observations per write when rewriting contiguous


def _to_contiguous(src, dst):
    """Rewrite an indexed ragged trajectory file as a contiguous ragged one (stable by time)."""
    tmp = Path(str(dst) + ".tmp")
    with netCDF4.Dataset(src) as a, netCDF4.Dataset(tmp, "w", format="NETCDF4") as b:
        a.set_auto_maskandscale(False)  # copied as stored (times on the run's clock)
        nobs = _obs_count(a)  # rows after obs_count: stale, from before a resume
        idx = a["trajectory_index"][:nobs]
        ntraj = len(a.dimensions["trajectory"])
        rows = np.bincount(idx, minlength=ntraj)
        nobs = idx.size
        order = np.argsort(idx, kind="stable")
        del idx  # memory: the sort order and one variable at a time (16 bytes per observation)
        b.setncatts({k: a.getncattr(k) for k in a.ncattrs()
                     if k not in ("hit_count", "obs_count", "resume_counts")})
        b.createDimension("trajectory", ntraj)
        b.createDimension("obs", nobs)
        nhit = int(a.getncattr("hit_count")) if "hit_count" in a.ncattrs() else \
            len(a.dimensions["hit"])  # rows after hit_count: stale, from before a resume
        b.createDimension("hit", nhit)
        for name, var in a.variables.items():
            if name == "trajectory_index":
                continue
            attrs = {k: var.getncattr(k) for k in var.ncattrs()}
            kw = _obs_storage(b, False, nobs) if var.dimensions == ("obs",) else {}
            v = _small_chunk_cache(b.createVariable(name, var.dtype, var.dimensions, **kw))
            v.setncatts(attrs)
            v.set_auto_maskandscale(False)
            data = var[:]
            if var.dimensions == ("obs",):
                data = data[:nobs]
                for start in range(0, nobs, _BLOCK):  # permuted block by block
                    v[start:start + _BLOCK] = data[order[start:start + _BLOCK]]
                continue
            if var.dimensions == ("hit",):
                data = data[:nhit]
            v[:] = data
        rs = b.createVariable("rowSize", "i8", ("trajectory",))
        rs.setncatts(dict(long_name="number of observations for this trajectory",
                          sample_dimension="obs"))
        rs[:] = rows
    os.replace(tmp, dst)


def open_trajectories(path):
    """Open a trajectory file (contiguous or indexed/partial) as an xarray Dataset.

    Times are kept in seconds (``time`` float, s since the run's reference); ``obs`` gets a
    ``trajectory_index`` coordinate in both layouts, for easy selection of one log.
    """
    import xarray as xr

    from driftlog.files import require

    path = Path(path)
    if not path.exists() and Path(str(path) + ".partial").exists():
        path = Path(str(path) + ".partial")
    require(path, ("trajectories", "partial"), "trajectory file")
    ds = xr.open_dataset(path, decode_times=False)
    nhit = ds.attrs.get("hit_count")
    if nhit is not None and int(nhit) < ds.sizes.get("hit", 0):  # a partial file's stale rows
        ds = ds.isel(hit=slice(0, int(nhit)))
    nobs = ds.attrs.get("obs_count")
    if nobs is not None and int(nobs) < ds.sizes.get("obs", 0):  # the same for records
        ds = ds.isel(obs=slice(0, int(nobs)))
    _check_structure(path, ds)
    if "trajectory_index" not in ds and "rowSize" in ds:
        ds = ds.assign_coords(trajectory_index=("obs", np.repeat(
            np.arange(ds.sizes["trajectory"]), ds["rowSize"].values)))
    elif "trajectory_index" in ds:
        ds = ds.set_coords("trajectory_index")
    ds["time"].attrs["units"] = "s"
    return ds


# what the readers (info, plot, animate, vtk, compare) use, by dimension
REQUIRED = {"obs": ("time", "x", "y", "theta", "u", "v", "status"),
            "trajectory": ("trajectory", "length", "radius", "density")}
# global attributes holding JSON, and the type each holds
JSON_ATTRS = {"scenario_resolved": dict, "obstacle_names": list, "physics_options": dict,
              "resume_counts": list}


def _check_structure(path, ds):
    """Refuse a trajectory file whose structure the readers cannot use (``InputFileError``).

    The variables the readers use, on their dimension; which log each observation belongs to
    (``rowSize``: one count >= 0 per log, summing to the observations; or ``trajectory_index``
    of a ``.partial`` file: log numbers in range); the status codes; the JSON attributes.
    """
    from driftlog.errors import InputFileError

    def bad(what):
        return InputFileError(f"{path}: a damaged trajectory file: {what}; it cannot be read "
                              "(write it again with driftlog track or run)")

    for dim, names in REQUIRED.items():
        if dim not in ds.dims:
            raise bad(f"no dimension {dim!r}")
        for name in names:
            if name not in ds.variables:
                raise bad(f"no variable {name!r} (one value per "
                          f"{'observation' if dim == 'obs' else 'log'})")
            if ds[name].dims != (dim,):
                raise bad(f"the variable {name!r} has dimensions {ds[name].dims}, not "
                          f"({dim!r},)")
    ntraj, nobs = ds.sizes["trajectory"], ds.sizes["obs"]
    if "rowSize" in ds.variables and "trajectory_index" not in ds.variables:
        rows = ds["rowSize"].values
        if ds["rowSize"].dims != ("trajectory",) or not np.issubdtype(rows.dtype, np.integer):
            raise bad(f"rowSize must be integers, one per log ({ntraj}): it is "
                      f"{rows.dtype} of dimensions {ds['rowSize'].dims}")
        if rows.size and rows.min() < 0:
            i = int(np.argmin(rows))
            raise bad(f"rowSize[{i}] = {int(rows[i])}: a count of observations must be >= 0")
        if int(rows.sum()) != nobs:
            raise bad(f"rowSize sums to {int(rows.sum())} observations, the obs dimension "
                      f"holds {nobs}")
    elif "trajectory_index" in ds.variables:
        idx = ds["trajectory_index"].values
        if ds["trajectory_index"].dims != ("obs",) or not np.issubdtype(idx.dtype, np.integer):
            raise bad("trajectory_index must be integers, one per observation: it is "
                      f"{idx.dtype} of dimensions {ds['trajectory_index'].dims}")
        out = np.flatnonzero((idx < 0) | (idx >= ntraj))
        if out.size:
            i = int(out[0])
            raise bad(f"trajectory_index[{i}] = {int(idx[i])}: must be a log number from 0 to "
                      f"{ntraj - 1} ({out.size} observations out of range)")
    else:
        raise bad("neither rowSize (a finished file) nor trajectory_index (a .partial file): "
                  "which log each observation belongs to is unknown")
    st = ds["status"].values
    codes = len(STATUS_MEANINGS.split())
    wrong = np.flatnonzero(~np.isfinite(st) | (st < 0) | (st >= codes)) if st.size else st
    if wrong.size:
        i = int(wrong[0])
        raise bad(f"status[{i}] = {st[i]}: the status codes are 0 to {codes - 1} "
                  f"({STATUS_MEANINGS}); {wrong.size} observations have another")
    for name, kind in JSON_ATTRS.items():
        if name not in ds.attrs:
            continue
        try:
            value = json.loads(str(ds.attrs[name]))
        except ValueError as exc:
            raise bad(f"the attribute {name} is not JSON ({exc}): "
                      f"{_clip(str(ds.attrs[name]))!r}") from None
        if not isinstance(value, kind):
            raise bad(f"the attribute {name} must hold a JSON "
                      f"{'object' if kind is dict else 'list'}: {_clip(str(ds.attrs[name]))!r}")


def require_observations(ds, path, what):
    """Refuse (``InputFileError``) a trajectory file without observations; ``what``: why it matters.

    Its logs are released after the run's end, or the run stopped before its first record.
    """
    if ds.sizes.get("obs", 0) == 0:
        from driftlog.errors import InputFileError

        raise InputFileError(f"{path}: the trajectory file holds no observations "
                             f"({ds.sizes.get('trajectory', 0)} logs, none recorded: released "
                             f"after the run's end, or the run stopped before its first "
                             f"record): {what}")


def _clip(text, n=60):
    return text if len(text) <= n else text[:n] + "..."


def check_resume(partial, scenario, logs):
    """Refuse (``InputFileError``) a ``.partial`` file that a run of ``scenario`` cannot resume.

    It must be a driftlog trajectory file of a stopped run (not a flow file, a finished or a
    damaged file), of the same logs (their number, ids and groups) and, as it stores its
    scenario (``scenario_resolved``), of the same scenario, as a coupled run's flow file must
    (``coupling.resume_coupling``): appended to, anything else would mix two runs in one file.
    """
    from driftlog.errors import InputFileError
    from driftlog.files import require

    again = "rerun it from the start, without --resume (or remove the .partial file)"
    require(partial, ("partial",), "file a run resumes from", hint=again,
            expected="the .partial trajectory file of a stopped run")
    ds = open_trajectories(partial)  # its structure
    try:
        cannot = f"{partial}: cannot resume the run from it"
        n = ds.sizes["trajectory"]
        if n != len(logs):
            raise InputFileError(f"{cannot}: it holds {n} logs, the scenario seeds {len(logs)}; "
                                 f"{again}")
        ids, groups = ds["trajectory"].values, ds["group"].values if "group" in ds else None
        if not np.array_equal(ids, logs.id) or (groups is not None
                                                and not np.array_equal(groups, logs.group)):
            raise InputFileError(f"{cannot}: its logs (ids and groups) are not the scenario's; "
                                 f"{again}")
        resolved = ds.attrs.get("scenario_resolved")
        if resolved is not None and resolved != scenario.to_json():
            raise InputFileError(f"{cannot}: it was computed from another scenario (its "
                                 f"scenario_resolved differs); {again}")
    finally:
        ds.close()


def kept_counts(path, t):
    """The statistics a stopped run kept with its record at ``t`` (``keep_counts``), or None.

    None when the file kept none at that time: the resumed run then counts its own part only.
    """
    with netCDF4.Dataset(path) as ds:
        return _counts_at(ds, t)


def _counts_at(ds, t):
    """``kept_counts`` of an open dataset."""
    if "resume_counts" not in ds.ncattrs():
        return None
    kept = json.loads(ds.getncattr("resume_counts"))
    return next((c for c in kept if c.get("time") == float(t)), None)


def _obs_count(ds):
    """Rows of ``obs`` that hold records (``obs_count``; rows after it are stale)."""
    n = len(ds.dimensions["obs"])
    if "obs_count" in ds.ncattrs():
        n = min(n, int(ds.getncattr("obs_count")))
    return n


def last_states(path, until=None):
    """Where a stopped run can resume: the time of its last record and each log's last state.

    Returns (time, index, columns) with the last observation of every log that has one (logs
    that left the domain earlier keep their last, 'left_domain', observation), or None if the
    file holds no record.  ``until``: the records up to this time only.
    """
    with netCDF4.Dataset(path) as ds:
        ds.set_auto_maskandscale(False)  # times on the run's clock (as the tracker counts)
        n = _obs_count(ds)
        t = ds["time"][:n]
        if until is not None:  # records are appended in time order
            n = int(np.searchsorted(t, until, side="right"))
            t = t[:n]
        if t.size == 0:
            return None
        ti = ds["trajectory_index"][:n]
        order = np.lexsort((t, ti))
        last = order[np.flatnonzero(np.diff(np.append(ti[order], -1)) != 0)]
        names = [*OBS_VARS, *(k for k in EXTRA_OBS_VARS if k in ds.variables)]
        cols = {name: ds[name][:n][last] for name in names}
        return float(t.max()), ti[last], cols


def _write_vtu(path, mesh):
    """Write a meshio Mesh as .vtu under a temporary name, renamed when complete."""
    import meshio

    from driftlog.files import atomic_output

    with atomic_output(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")


def _write_pvd(pvd, entries):
    from driftlog.files import atomic_output

    with atomic_output(pvd) as tmp:
        tmp.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                       "  <Collection>\n" + "\n".join(entries)
                       + "\n  </Collection>\n</VTKFile>\n")


def write_vtk(path, out_dir=None, every=1):
    """ParaView files for a trajectory file: one .vtu per record time and a .pvd collection.

    The logs are line segments (their axis); ``radius``, ``log_id``, ``status`` and ``speed``
    are point data (on both ends of each segment: what ParaView's Tube filter, after Extract
    Surface, with "Vary Radius: By Absolute Scalar" on ``radius``, and pyvista's
    ``extract_surface().tube(scalars="radius", absolute=True)`` use to draw the logs as
    cylinders), and also
    cell data.  Each file is written under a temporary name and renamed when complete; the
    .pvd last.  Returns the .pvd path.
    """
    import meshio

    from driftlog.files import check_output_dir

    ds = open_trajectories(path)
    require_observations(ds, path, "nothing to export to ParaView")
    out_dir = check_output_dir(Path(out_dir or Path(path).with_suffix("")).resolve(),
                               "ParaView folder")
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
        per_log = {"log_id": ti[sel].astype(np.int64), "radius": r[sel],
                   "status": ds["status"].values[sel].astype(np.int32),
                   "speed": np.hypot(ds["u"].values[sel], ds["v"].values[sel])}
        cd = {k2: [v] for k2, v in per_log.items()}
        pd = {k2: np.repeat(v, 2) for k2, v in per_log.items()}
        name = f"logs_{k:06d}.vtu"
        _write_vtu(out_dir / name, meshio.Mesh(pts, cells, point_data=pd, cell_data=cd))
        entries.append(f'    <DataSet timestep="{tk:.9g}" part="0" file="{name}"/>')
    pvd = out_dir / "logs.pvd"
    _write_pvd(pvd, entries)
    return pvd


def write_flow_vtk(path, out_dir=None, every=1):
    """ParaView files for a flow file (or any hydro source): the flow on its mesh.

    One .vtu per snapshot (polygons of the mesh, the bed ``z`` as the nodes' third
    coordinate): cell data ``depth``, ``velocity`` (3 components), ``speed``, ``level`` and
    ``bed``; and a .pvd collection by time.  Returns the .pvd path.
    """
    import meshio

    from driftlog.files import check_output_dir, require

    fk = require(path, ("flow", "model_output", "openfoam"), "flow file",
                 hint="driftlog vtk --flow exports a flow file or another model's output")
    if fk.kind == "flow":
        from driftlog.flowfile import open_flow

        field = open_flow(path)
    else:
        from driftlog.adapters import open_flow_source

        field = open_flow_source("auto", path)
    mesh = field.mesh
    src = Path(path)
    default = src.with_name((src.stem if src.is_file() else src.name) + "_vtk")
    out_dir = check_output_dir(Path(out_dir or default).resolve(), "ParaView folder")
    z = mesh.node_z if mesh.node_z is not None else np.zeros(mesh.n_nodes)
    pts = np.column_stack([mesh.node_x, mesh.node_y, z])
    fn = mesh.face_nodes
    cells, order = [], []
    for n, kind in ((3, "triangle"), (4, "quad")):
        sel = np.flatnonzero(mesh.face_n == n)
        if sel.size:
            cells.append((kind, fn[sel, :n]))
            order.append(sel)
    for n in np.unique(mesh.face_n):
        if n > 4:
            sel = np.flatnonzero(mesh.face_n == n)
            cells.append(("polygon", fn[sel, :n]))
            order.append(sel)
    order = np.concatenate(order)
    entries = []
    for k, i in enumerate(range(0, field.times.size, every)):
        snap = field.snapshot(i)
        h, u, v = snap["h"], snap["u"], snap["v"]
        data = {"depth": h, "speed": np.hypot(u, v), "level": h + field.bed, "bed": field.bed,
                "velocity": np.column_stack([u, v, np.zeros_like(u)])}
        cd = {}
        for name, arr in data.items():
            start = 0
            parts = []
            for _, block in cells:
                parts.append(arr[order[start:start + len(block)]])
                start += len(block)
            cd[name] = parts
        name = f"flow_{k:06d}.vtu"
        _write_vtu(out_dir / name, meshio.Mesh(pts, cells, cell_data=cd))
        entries.append(f'    <DataSet timestep="{field.times[i]:.9g}" part="0" file="{name}"/>')
    pvd = out_dir / "flow.pvd"
    _write_pvd(pvd, entries)
    return pvd


# --------------------------------------------------------------------- the scenario section
OUTPUT_SECTION = Section("output", [
    Key("path", "path", "trajectories.nc", "trajectory file (CF-1.11 trajectory NetCDF)"),
    Key("vtk", "bool", False, "also write VTK (ParaView) files beside the trajectory file"),
    Key("figure", "bool", False, "draw a figure of the trajectories"),
    Key("animation", "bool", False, "write an animation (MP4 if ffmpeg is there, else GIF)"),
    Key("flush_interval", "int", 10, "records between flushes to disk (a coupled run flushes "
        "every record, with its flow file's snapshot)", min=1),
], doc="what is written")
