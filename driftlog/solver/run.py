"""Running the solver to an end time: flow-file output, volume balance, extremes, resume.

The flow file (``driftlog.flowfile``) gets a snapshot at the start and every
``output_interval`` seconds (the step before an output is shortened so that it lands exactly),
each flushed at once, with the volume balance as scalar series beside it:

- ``volume``: water in the domain (m3);
- ``inflow_volume_<tag>``, ``outflow_volume_<tag>``: cumulative volumes through each open
  boundary tag since the start (m3);
- ``volume_error``: volume - (initial + inflows - outflows) (m3), round-off only;
- ``time_steps``: steps taken since the start.

Beside the snapshots, face variables without time hold the running extremes
(``max_water_level``, ``max_water_depth``, ``max_speed``, ``arrival_time``) and the exact
momentum of the last snapshot (``restart_momentum_x/_y``; the snapshots store velocities, and
h u / h is not always hu to the last bit), so that ``resume=True`` continues from the last
snapshot bit for bit as if the run had not stopped.
"""

from __future__ import annotations

import math
import sys
import time as _time
from dataclasses import dataclass
from pathlib import Path

import netCDF4
import numpy as np

from driftlog.errors import FlowFileError
from driftlog.files import reopen_partial
from driftlog.flowfile import FACE_DIM, FlowFileWriter
from driftlog.solver.extremes import EXTREME_FIELDS

__all__ = ["SolveResult", "run_solver", "load_restart", "MAX_SNAPSHOTS", "check_snapshots"]

RESTART_FIELDS = ("restart_momentum_x", "restart_momentum_y")

MAX_SNAPSHOTS = 100_000
"""Snapshots a run may write (each one a step landed on and a write flushed to disk)."""


def check_snapshots(t0, t1, output_interval, key="solver.output_interval"):
    """Refuse (``ScenarioError``) an ``output_interval`` giving more than ``MAX_SNAPSHOTS``.

    1e-9 s over 4 s asked for 4e9 snapshots: the run wrote for ever into a growing file.
    """
    span = float(t1) - float(t0)
    if output_interval is None or not span > 0:
        return
    n = span / output_interval
    if n > MAX_SNAPSHOTS:
        from driftlog.errors import ScenarioError

        raise ScenarioError(key, output_interval, f"makes {n:.3g} snapshots over the "
                            f"{span:g} s computed, more than {MAX_SNAPSHOTS:g}: must be >= "
                            f"{span / MAX_SNAPSHOTS:.3g} s")


@dataclass
class SolveResult:
    """What a solver run did.

    ``cell_updates_per_s`` is faces x time steps / wall seconds (a second-order step is two
    flux passes and counts once).
    """

    path: Path | None
    t_end: float
    steps: int
    wall_time: float
    cell_updates_per_s: float
    volume: float
    volume_error: float
    relative_volume_error: float
    snapshots: int

    def summary(self) -> str:
        """A few lines for the command line."""
        if not math.isfinite(self.volume_error):  # an engine that keeps no balance (OpenFOAM)
            return (f"t = {self.t_end:g} s, {self.steps} steps in {self.wall_time:.2f} s "
                    f"({self.cell_updates_per_s:.3g} cell-updates/s), volume {self.volume:.6g} "
                    f"m3 (no volume balance from this engine), {self.snapshots} snapshots")
        return (f"t = {self.t_end:g} s, {self.steps} steps in {self.wall_time:.2f} s "
                f"({self.cell_updates_per_s:.3g} cell-updates/s), volume {self.volume:.6g} m3, "
                f"volume error {self.volume_error:.3g} m3 ({self.relative_volume_error:.2g} "
                f"relative), {self.snapshots} snapshots")


def _series(solver):
    out = {"volume": dict(long_name="water volume in the domain", units="m3"),
           "volume_error": dict(long_name="volume - (initial volume + inflow - outflow)",
                                units="m3"),
           "time_steps": dict(long_name="time steps since the start", units="1")}
    for tag in solver.boundaries.open_tags:
        out[f"inflow_volume_{tag}"] = dict(long_name=f"volume entered through {tag} since "
                                           "the start", units="m3")
        out[f"outflow_volume_{tag}"] = dict(long_name=f"volume left through {tag} since the "
                                            "start", units="m3")
    return out


def _series_values(solver):
    vol = solver.volume()
    vals = {"volume": vol, "volume_error": solver.volume_error(vol),
            "time_steps": float(solver.steps)}
    for tag in solver.boundaries.open_tags:
        i = solver.mesh.tag_names.index(tag)
        vals[f"inflow_volume_{tag}"] = float(solver.inflow_volume[i])
        vals[f"outflow_volume_{tag}"] = float(solver.outflow_volume[i])
    return vals


def _attrs(solver):
    return {"source": "driftlog solver", "dry_depth": solver.dry_depth,
            "solver_order": solver.order, "solver_riemann": solver.riemann,
            "solver_cfl": solver.cfl, "arrival_depth": solver.arrival_depth,
            "gravity": solver.gravity}


def _create(path, solver, attrs):
    a = _attrs(solver)
    a.update(attrs or {})
    w = FlowFileWriter(path, solver.mesh, solver.bed, attrs=a, extra_series=_series(solver))
    for name, meta in EXTREME_FIELDS.items():
        v = w.ds.createVariable(name, "f8", (FACE_DIM,))
        v.setncatts(dict(meta, mesh="mesh2d", location="face",
                         coordinates="mesh2d_face_x mesh2d_face_y"))
    for name, axis in zip(RESTART_FIELDS, "xy", strict=True):
        v = w.ds.createVariable(name, "f8", (FACE_DIM,))
        v.setncatts(dict(long_name=f"unit discharge, {axis} component, of the last snapshot "
                         "(exact, for resuming)", units="m2 s-1", mesh="mesh2d",
                         location="face"))
    return w


def _write(w, solver, sync=True, momentum=None):
    # the state once (on a renumbered mesh each read is a copy), one flush for the snapshot
    # and the fields beside it
    h, hu, hv = solver.h, solver.hu, solver.hv
    for name, arr in (("h", h), ("hu", hu), ("hv", hv)):
        if not np.all(np.isfinite(arr)):
            bad = np.flatnonzero(~np.isfinite(arr))
            x, y = solver.mesh.face_x[bad[0]], solver.mesh.face_y[bad[0]]
            raise FlowFileError(f"{w.path}: the solver's {name} is not finite at t = "
                                f"{solver.t:.6g} s on {bad.size} faces (first at x = {x:.6g}, "
                                f"y = {y:.6g} m); nothing non-finite is written: check the "
                                "boundary values, the initial state and cfl")
    w.write(solver.t, h, hu=hu, hv=hv, dry_depth=solver.dry_depth, sync=False,
            **_series_values(solver))
    ex = solver.extremes.arrays()
    ex["max_water_level"] = np.where(np.isfinite(ex["max_water_level"]),
                                     ex["max_water_level"], np.nan)
    for name, arr in ex.items():
        w.ds.variables[name][:] = arr
    # ``momentum``: the restart's (hu, hv) when not the state's (a coupled run's, before the
    # hand-over; driftlog.coupling.FlowOutput)
    rx, ry = (hu, hv) if momentum is None else momentum
    w.ds.variables[RESTART_FIELDS[0]][:] = rx
    w.ds.variables[RESTART_FIELDS[1]][:] = ry
    w.ds.setncatts({"restart_time": solver.t, "restart_steps": solver.steps,
                    "initial_volume": solver.initial_volume})
    if sync:
        w.ds.sync()


def load_restart(solver, path, at=None):
    """Set the solver to the last snapshot of its flow file ``path`` (state, balance, extremes).

    ``at``: the snapshot at this time instead (a coupled run's restart, whose next snapshot
    may have been cut off while it was written); the restart data must be that time's.
    Returns the number of snapshots up to it.
    """
    path = Path(path)
    with netCDF4.Dataset(path) as ds:
        ds.set_auto_mask(False)
        need = ["time", "water_depth", *RESTART_FIELDS, *EXTREME_FIELDS]
        missing = [n for n in need if n not in ds.variables]
        if missing or "restart_time" not in ds.ncattrs():
            raise FlowFileError(f"{path}: cannot resume from it: not written by the driftlog "
                                f"solver (missing {', '.join(missing) or 'restart_time'})")
        n = len(ds.dimensions["time"])
        if at is not None:
            times = np.asarray(ds.variables["time"][:n])
            hit = np.flatnonzero(times == at)
            if hit.size == 0:
                raise FlowFileError(f"{path}: cannot resume from it: no snapshot at its "
                                    f"restart time {at} s")
            n = int(hit[0]) + 1
        nf = ds.dimensions[FACE_DIM].size
        if nf != solver.mesh.n_faces:
            raise FlowFileError(f"{path}: has {nf} faces, the solver's mesh "
                                f"{solver.mesh.n_faces}: not the same run")
        t = float(ds.variables["time"][n - 1])
        if t != float(ds.getncattr("restart_time")):
            raise FlowFileError(f"{path}: last snapshot at {t} s but restart data at "
                                f"{ds.getncattr('restart_time')} s (interrupted while writing)")
        solver.h = ds.variables["water_depth"][n - 1, :]
        solver.hu = ds.variables[RESTART_FIELDS[0]][:]
        solver.hv = ds.variables[RESTART_FIELDS[1]][:]
        solver.t = t
        solver.steps = int(ds.getncattr("restart_steps"))
        solver.initial_volume = float(ds.getncattr("initial_volume"))
        for tag in solver.boundaries.open_tags:
            i = solver.mesh.tag_names.index(tag)
            solver.inflow_volume[i] = ds.variables[f"inflow_volume_{tag}"][n - 1]
            solver.outflow_volume[i] = ds.variables[f"outflow_volume_{tag}"][n - 1]
        ex = {k: np.array(ds.variables[k][:]) for k in EXTREME_FIELDS}
        ex["max_water_level"] = np.where(np.isnan(ex["max_water_level"]), -np.inf,
                                         ex["max_water_level"])
        solver.extremes.load(ex)
    return n


def run_solver(solver, t_end, output=None, output_interval=None, progress=False, resume=False,
               attrs=None, t_origin=None):
    """Advance ``solver`` to ``t_end``, writing the flow file ``output`` on the way.

    Outputs fall at ``t_origin + k * output_interval`` (``t_origin``: the start time; a
    resumed run keeps the file's origin) and at ``t_end``.  Without ``output_interval`` only
    the start and the end are written.  ``resume=True`` continues from the last snapshot of
    ``output`` (when it exists).
    """
    t_end = float(t_end)
    if output_interval is not None and not output_interval > 0:
        raise ValueError(f"output_interval must be > 0 s, got {output_interval}")
    check_snapshots(solver.t if t_origin is None else t_origin, t_end, output_interval)
    writer = None
    n_snap = 0
    if output is not None:
        output = Path(output)
        if resume and output.exists():
            # a file a killed process left open is copied first: opened with "a", HDF5 may
            # refuse it and leak a file object that crashed a later close (driftlog.files)
            reopen_partial(output)
            n_snap = load_restart(solver, output)
            with netCDF4.Dataset(output) as ds:
                t_origin = float(ds.getncattr("output_origin"))
            writer = FlowFileWriter(output, solver.mesh, solver.bed, append=True)
        else:
            t_origin = solver.t if t_origin is None else float(t_origin)
            a = dict(attrs or {})
            a["output_origin"] = t_origin
            a["output_interval"] = output_interval if output_interval else t_end - t_origin
            writer = _create(output, solver, a)
            _write(writer, solver)
            n_snap = 1
    t_origin = solver.t if t_origin is None else t_origin
    interval = output_interval or max(t_end - t_origin, 0.0) or 1.0
    steps0 = solver.steps
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=max(t_end - solver.t, 0.0), unit="s", unit_scale=True,
                   desc="solving", file=sys.stderr, leave=False)
    wall0 = _time.perf_counter()
    try:
        while solver.t < t_end:
            k = math.floor((solver.t - t_origin) / interval + 1e-9) + 1
            t_next = min(t_origin + k * interval, t_end)
            if t_next <= solver.t:
                t_next = min(solver.t + interval, t_end)
            t_before = solver.t
            solver.advance_to(t_next)
            if writer is not None:
                _write(writer, solver)
                n_snap += 1
            if bar is not None:
                bar.update(solver.t - t_before)
    finally:
        if bar is not None:
            bar.close()
        if writer is not None:
            writer.close()
    wall = _time.perf_counter() - wall0
    steps = solver.steps - steps0
    vol = solver.volume()
    err = solver.volume_error()
    scale = max(abs(solver.initial_volume), float(solver.inflow_volume.sum()), 1e-300)
    return SolveResult(path=output, t_end=solver.t, steps=solver.steps, wall_time=wall,
                       cell_updates_per_s=solver.mesh.n_faces * steps / wall if wall > 0 else 0.0,
                       volume=vol, volume_error=err, relative_volume_error=err / scale,
                       snapshots=n_snap)
