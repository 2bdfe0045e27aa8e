"""Running an ensemble: members as independent Dask tasks, reduced as they finish, resumable.

Where it runs.  A ``distributed.LocalCluster`` on this machine (``workers`` processes of one
thread each), or any running scheduler (``scheduler="tcp://host:8786"``); ``workers=0`` runs
the members one after the other in this process, without Dask.

The flow is never shipped in a task.  A task carries the base scenario (scattered to the
workers once), the member's overrides and its parameters; each worker opens the flow itself
(a flow file, or an analytic field) and keeps it in a per-process cache keyed by the [flow]
section, so a worker opens it once for all its members.  Flows from the solver or imported
from another model are written once to ``output/flow.nc`` and the workers open that.  On a
multi-node cluster the flow file's path must be the same on every node (a shared filesystem).

Durable progress.  The client writes each finished member's summary to
``output/members/member_<i>.npz`` (atomically: a temporary file, fsync, rename; a file that
exists is complete) and adds it to the running aggregate.  ``output/manifest.json`` names the
ensemble (a fingerprint of everything that determines the members).  A rerun with ``resume``
reads the finished members back into the aggregate and runs only the others; a failed
member (``output/failed/member_<i>.json``: its parameters and the error) is reported, does not
stop the others, and is tried again on resume.  The aggregate is rewritten every
``checkpoint_interval`` seconds and at the end (also after an interrupt).
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import os
import re
import shutil
import sys
import threading
import time
import traceback
import uuid
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from driftlog._version import __version__
from driftlog.api import logs_from_scenario, track
from driftlog.ensemble.aggregate import Aggregate
from driftlog.ensemble.spec import Ensemble, describe_parameters, load_ensemble
from driftlog.ensemble.summary import MemberRecorder, MemberSummary
from driftlog.errors import DriftlogError, ScenarioError
from driftlog.scenario import load_scenario
from driftlog.schema import merge

__all__ = ["run_ensemble", "run_member", "run_member_task", "EnsembleResult",
           "aggregation_grid", "open_member", "summarize_trajectories"]

MEMBER_FILE = re.compile(r"^member_(\d+)\.npz$")
AGGREGATE_NAME = "ensemble.nc"


# --------------------------------------------------------------------- worker side
_FLOWS: OrderedDict = OrderedDict()  # (flow section, grid, thread) -> (flow, mesh)
_FLOWS_LOCK = threading.Lock()
_FLOWS_KEEP = 4


def _grid_mesh(grid):
    from driftlog.mesh import Mesh

    return Mesh.regular_grid(grid["nx"], grid["ny"], grid["cell"], grid["cell"],
                             grid["x0"], grid["y0"])


def _worker_flow(scenario, grid: dict | None):
    """The flow of a member scenario and the mesh to aggregate on, opened once per worker.

    Cached by the ``[flow]`` section (the same for every member) and by thread too: a
    MeshFlowField holds the snapshot pair it last read, so threads of one process
    (``processes=False``) each get their own.
    """
    flow_section = scenario["flow"]
    stamp = None
    if flow_section.get("path") and os.path.exists(flow_section["path"]):
        st = os.stat(flow_section["path"])  # a file rewritten in place is opened again
        stamp = (st.st_mtime_ns, st.st_size)
    key = (json.dumps(flow_section, sort_keys=True), json.dumps(grid, sort_keys=True), stamp,
           threading.get_ident())
    with _FLOWS_LOCK:
        if key in _FLOWS:
            _FLOWS.move_to_end(key)
            return _FLOWS[key]
    from driftlog.sources import flow_from_scenario

    flow = flow_from_scenario(scenario)
    mesh = _grid_mesh(grid) if grid else flow.mesh
    with _FLOWS_LOCK:
        _FLOWS[key] = (flow, mesh)
        while len(_FLOWS) > _FLOWS_KEEP:
            _FLOWS.popitem(last=False)
    return flow, mesh


def run_member_task(base: dict, member: int, overrides: dict, parameters: dict,
                    options: dict) -> MemberSummary:
    """Run one member and reduce it (the Dask task; also run in-process with workers = 0)."""
    from driftlog.trajectory import TrajectoryWriter

    wall, cpu = time.perf_counter(), time.process_time()
    scen = load_scenario(merge(base, overrides))
    flow, mesh = _worker_flow(scen, options.get("grid"))
    keep = options.get("trajectories")
    out = Path(keep) / f"member_{member:06d}.nc" if keep else Path(f"member_{member:06d}.nc")

    def recorder(path, logs, attrs=None, flush_interval=10, obstacle_names=()):
        inner = None
        if keep:
            a = dict(attrs or {}, ensemble_member=member,
                     ensemble_parameters=json.dumps(parameters, default=str))
            inner = TrajectoryWriter(path, logs, attrs=a, flush_interval=flush_interval,
                                     obstacle_names=obstacle_names)
        return MemberRecorder(mesh, logs, scen["time"]["start"], obstacle_names, inner,
                              obstacles=scenario_obstacles(scen),
                              blocked_gap=options.get("blocked_gap", 0.1))

    res = track(scen, flow=flow, output=out, writer=recorder)
    info = dict(physics_level=res.physics["level"], rotation=bool(res.physics["rotation"]),
                substeps=int(res.stats["substeps"]),
                wall_seconds=time.perf_counter() - wall,
                cpu_seconds=time.process_time() - cpu, driftlog_version=__version__,
                worker_pid=os.getpid())
    return res.writer.summary(member, parameters, info)


CLOGGING_NAME = "clogging.csv"


def scenario_obstacles(scen):
    """The ``[[obstacles]]`` of a loaded scenario as geometry (no walls), or None.

    None when contacts are off (the tracker then has no obstacles and records no hits).
    """
    from driftlog.contact.obstacles import Obstacles

    if not scen["contact"]["enabled"] or not scen["obstacles"]:
        return None
    return Obstacles.from_tables(scen["obstacles"])


# --------------------------------------------------------------------- client side
@dataclass
class EnsembleResult:
    """What an ensemble run produced."""

    path: Path  # the aggregated results (UGRID NetCDF)
    output: Path  # the output folder
    members: int
    done: int
    failed: list  # dicts: member, parameters, error
    ran: list  # members run by this call (not resumed)
    resumed: int  # finished members read back from an earlier run
    figures: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    aggregate: Aggregate | None = field(default=None, repr=False)

    def dataset(self):
        """The aggregated results as an xarray Dataset."""
        import xarray as xr

        return xr.open_dataset(self.path)

    def ugrid(self):
        """The aggregated results as an xugrid UgridDataset (maps on the mesh)."""
        import xugrid

        return xugrid.open_dataset(self.path)


def aggregation_grid(ensemble: Ensemble, flow_mesh):
    """The regular aggregation grid of [ensemble] grid_* (a dict), or None for the flow mesh."""
    s = ensemble.section
    if s["grid_cell"] is None:
        if flow_mesh is None:
            raise ScenarioError("ensemble.grid_cell", None, "the flow has no mesh (an "
                                "analytic field): give grid_cell, grid_origin and grid_size, "
                                "the regular grid the maps are counted on")
        return None
    cell = s["grid_cell"]
    if s["grid_origin"] is None or s["grid_size"] is None:
        if flow_mesh is None:
            key = "grid_origin" if s["grid_origin"] is None else "grid_size"
            raise ScenarioError(f"ensemble.{key}", None, "is required for a flow without a "
                                "mesh (analytic): the extent of the aggregation grid")
        x0, y0, x1, y1 = flow_mesh.bounds
    else:
        x0, y0 = s["grid_origin"]
        x1, y1 = x0 + s["grid_size"][0], y0 + s["grid_size"][1]
    nx = max(int(np.ceil((x1 - x0) / cell - 1e-9)), 1)
    ny = max(int(np.ceil((y1 - y0) / cell - 1e-9)), 1)
    return dict(nx=nx, ny=ny, cell=float(cell), x0=float(x0), y0=float(y0))


def _write_json(path: Path, data: dict):
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=str))
    os.replace(tmp, path)


def _prepare_flow(ensemble: Ensemble, base: dict, out: Path):
    """The [flow] section the members run on, and its mesh (None for analytic flows).

    A flow file or an analytic field is used as it is.  A solved or imported flow is written
    once to ``out/flow.nc`` and the members' ``[flow]`` names that file, except node-located
    data (TELEMAC Selafin), which the members read from the source itself.  The mesh is read
    from the file the members open (without its snapshots), so the maps are counted on the
    mesh the members see.
    """
    from driftlog.flowfile import read_flow_mesh, write_flow
    from driftlog.sources import flow_from_scenario

    sec = base["flow"]
    if sec["source"] == "analytic":
        return sec, None
    if sec["source"] == "file":
        return sec, read_flow_mesh(sec["path"])
    # solved or imported: once here, then every worker opens the flow file
    path = out / "flow.nc"
    if not path.is_file():
        field_ = flow_from_scenario(ensemble.scenario)
        if getattr(field_, "mesh", None) is None:
            raise ScenarioError("flow.source", sec["source"], "gives a flow without a mesh; "
                                "an ensemble needs a flow file or an analytic flow")
        if getattr(field_, "location", "face") == "node":
            # node-located data (TELEMAC Selafin): a flow file holds face values, so the
            # members open the source itself and sample its own nodes, as `track` does
            if hasattr(field_.source, "close"):
                field_.source.close()
            return sec, field_.mesh
        write_flow(path, field_, attrs={"source": f"{sec['source']} (for the ensemble)"})
    new = dict(sec, source="file", path=str(path), steady_at=None)
    return new, read_flow_mesh(path)


MEMBER_BYTES = 512  # memory held per member before any runs (estimate; check_fits)


def _finished(members_dir: Path, n: int) -> list[int]:
    out = []
    if members_dir.is_dir():
        for p in members_dir.iterdir():
            m = MEMBER_FILE.match(p.name)
            if m and int(m.group(1)) < n:
                out.append(int(m.group(1)))
    return sorted(out)


def open_member(output, member: int) -> MemberSummary:
    """The summary of a finished member from an ensemble's output folder."""
    return MemberSummary.from_npz(Path(output) / "members" / f"member_{member:06d}.npz")


def _bad_scheduler(address, exc):
    return DriftlogError(f"scheduler {address!r} is not a Dask scheduler address ({exc}): it "
                         "looks like tcp://HOST:PORT, e.g. tcp://head:8786 (--scheduler or "
                         "[ensemble] scheduler)")


def check_scheduler(address):
    """Refuse a scheduler address that distributed cannot parse, before anything is computed."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, loc = parse_address(address)
        if scheme in ("tcp", "tls"):
            parse_host_port(loc)
    except (ValueError, TypeError) as exc:
        raise _bad_scheduler(address, exc) from None


def _start_client(workers, scheduler, processes):
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="30s"), None
        except OSError as exc:
            raise DriftlogError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        except (ValueError, TypeError) as exc:  # not an address (distributed's own parser)
            raise _bad_scheduler(scheduler, exc) from None
    kw = dict(n_workers=workers, threads_per_worker=1, processes=processes,
              dashboard_address=None, silence_logs=logging.ERROR)
    if processes:  # one thread per worker process: no oversubscription by numba or BLAS
        kw["env"] = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
                     "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    cluster = LocalCluster(**kw)
    return Client(cluster), cluster


def _dask_results(client, tasks, token):
    """Submit (member, args) tasks in a sliding window; yield (member, summary, error)."""
    from distributed import as_completed

    base_future = None
    it = iter(tasks)
    pending = {}
    ac = as_completed()
    window = 2 * max(sum(client.nthreads().values()), 1) + 2

    def submit_next():
        nonlocal base_future
        try:
            i, (base, *rest) = next(it)
        except StopIteration:
            return False
        if base_future is None:  # the base scenario travels once, not in every task
            base_future = client.scatter(base, broadcast=True)
        fut = client.submit(run_member_task, base_future, *rest,
                            key=f"driftlog-member-{token}-{i}", retries=0)
        pending[fut] = i
        ac.add(fut)
        return True

    for _ in range(window):
        if not submit_next():
            break
    try:
        for fut in ac:
            i = pending.pop(fut)
            if fut.status == "error":
                exc, tb = fut.exception(), fut.traceback()
                yield i, None, (exc, "".join(traceback.format_tb(tb)) if tb else "")
            elif fut.status == "cancelled":
                yield i, None, (DriftlogError("the task was cancelled (worker lost?)"), "")
            else:
                yield i, fut.result(), None
            fut.release()
            submit_next()
    finally:
        for fut in pending:
            fut.cancel()


def _local_results(tasks):
    for i, args in tasks:
        try:
            yield i, run_member_task(*args), None
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # noqa: BLE001 - a failing member must not stop the others
            yield i, None, (exc, traceback.format_exc())


def run_ensemble(ensemble, workers=None, scheduler=None, client=None, resume=False,
                 overwrite=False, progress=True, output=None, members=None, processes=True,
                 figures=True, overrides=None) -> EnsembleResult:
    """Run an ensemble (see the module docstring) and write its aggregated results.

    Parameters
    ----------
    ensemble : path, TOML text, dict, Scenario or Ensemble
    workers : int, optional
        Local Dask workers (default: ``[ensemble] workers``, else the CPU count); 0 runs the
        members in this process without Dask.
    scheduler : str, optional
        Address of a running Dask scheduler (default: ``[ensemble] scheduler``).
    client : distributed.Client, optional
        Use this client (its cluster is left running).
    resume : bool
        Keep the finished members found in the output folder and run only the others.
    overwrite : bool
        Delete an earlier run's results in the output folder first.
    output : path, optional
        Output folder (default: ``[ensemble] output``).
    members : iterable of int, optional
        Run only these members (the aggregate holds the finished ones).
    processes : bool
        LocalCluster workers as processes (default) or threads of this process.
    figures : bool
        Draw the PNG figures of the aggregate.
    """
    started = time.perf_counter()
    if resume and overwrite:
        raise DriftlogError("resume and overwrite (--resume --overwrite) together: resume keeps "
                            "the finished members of the output folder, overwrite deletes them "
                            "first; give one of them")
    if workers is not None and int(workers) < 0:
        raise DriftlogError(f"--workers {workers}: must be >= 0 (0: the members in this "
                            "process, without Dask), as [ensemble] workers")
    ens = load_ensemble(ensemble, overrides)
    sec = ens.section
    if client is None and (scheduler or sec["scheduler"]):
        check_scheduler(scheduler or sec["scheduler"])
    out = Path(output or sec["output"]).resolve()
    n = ens.members
    from driftlog.resources import check_fits

    # the member table, the list of members to run and their parameters: a few hundred bytes
    # per member, allocated before the first one runs
    check_fits(MEMBER_BYTES * n, f"an ensemble of {n} members", "give fewer members "
               "([ensemble] members, or --members)")
    members_dir, failed_dir = out / "members", out / "failed"
    manifest_path = out / "manifest.json"
    fp = ens.fingerprint()
    if overwrite and out.is_dir():
        for sub in ("members", "failed", "trajectories"):
            shutil.rmtree(out / sub, ignore_errors=True)
        for name in ("manifest.json", AGGREGATE_NAME):
            (out / name).unlink(missing_ok=True)
    if manifest_path.is_file():
        old = json.loads(manifest_path.read_text())
        if old.get("fingerprint") != fp:
            raise DriftlogError(f"{out} holds the results of a different ensemble (fingerprint "
                                f"{old.get('fingerprint')}, this one {fp}): choose another "
                                "output folder, or overwrite (--overwrite)")
    done_before = _finished(members_dir, n)
    if done_before and not resume:
        raise DriftlogError(f"{out} already holds {len(done_before)} finished members of this "
                            "ensemble: resume (--resume) to run only the others, or overwrite "
                            "(--overwrite) to start again")
    for d in (members_dir, failed_dir):
        d.mkdir(parents=True, exist_ok=True)
    for p in members_dir.glob("*.tmp"):  # left by a run killed while writing
        p.unlink(missing_ok=True)
    base = ens.base()
    flow_section, flow_mesh = _prepare_flow(ens, base, out)
    base["flow"] = flow_section
    grid = aggregation_grid(ens, flow_mesh)
    mesh = _grid_mesh(grid) if grid else flow_mesh
    manifest = dict(fingerprint=fp, members=n, sampling=sec["sampling"], seed=ens.seed,
                    parameters=[p.path for p in ens.parameters], aggregation_faces=mesh.n_faces,
                    driftlog_version=__version__, ensemble=json.loads(ens.scenario.to_json()),
                    created=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"))
    if manifest_path.is_file():
        manifest["created"] = json.loads(manifest_path.read_text()).get("created")
    _write_json(manifest_path, manifest)

    tm = base["time"]
    agg = Aggregate(mesh, n, ens.parameters, sec["confidence"],
                    blocked_after=sec["blocked_after"],
                    run_span=None if tm["end"] is None else tm["end"] - tm["start"])
    agg.set_obstacles(scenario_obstacles(load_scenario(base)))
    for i in done_before:  # read back: memory stays bounded, one member at a time
        agg.add(MemberSummary.from_npz(members_dir / f"member_{i:06d}.npz"))
    wanted = range(n) if members is None else sorted(set(int(i) for i in members))
    todo = [i for i in wanted if agg.member_state[i] != 1]
    if resume and not done_before:  # once the ensemble is checked and about to run
        from driftlog.files import nothing_to_resume

        nothing_to_resume(members_dir, "finished member", "the ensemble starts from the "
                          "beginning")
    options = dict(grid=grid, trajectories=str(out / "trajectories")
                   if sec["keep_trajectories"] else None, blocked_gap=sec["blocked_gap"])
    if options["trajectories"]:
        Path(options["trajectories"]).mkdir(parents=True, exist_ok=True)
    # nothing left to run (a resume after the end): no sample (of shape (0, k)) to draw
    params = dict(zip(todo, ens.sample(todo), strict=True)) if todo else {}

    def tasks():
        for i in todo:
            yield i, (base, i, ens.member_overrides(i, base, params[i]), params[i], options)

    workers = sec["workers"] if workers is None else workers
    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    scheduler = scheduler if scheduler is not None else (sec["scheduler"] or None)
    attrs = dict(ensemble=ens.scenario.to_json(), ensemble_fingerprint=fp,
                 sampling=sec["sampling"], seed=ens.seed,
                 flow_source=json.dumps(flow_section, default=str),
                 aggregation_mesh="regular grid " + json.dumps(grid) if grid else "flow mesh")
    table = ens.parameter_table()
    agg_path = out / AGGREGATE_NAME
    failures, ran = [], []
    timings = dict(start_seconds=0.0)
    own = None
    bar = None
    results = None
    interrupted = False
    try:
        if todo:
            if client is None and (workers > 0 or scheduler):
                client, own = _start_client(workers, scheduler, processes)
            timings["start_seconds"] = time.perf_counter() - started
            results = (_dask_results(client, tasks(), f"{fp[:8]}-{uuid.uuid4().hex[:6]}")
                       if client is not None else _local_results(tasks()))
            if progress:
                from tqdm import tqdm

                bar = tqdm(total=len(todo) + len(done_before), initial=len(done_before),
                           unit="member", desc="ensemble", mininterval=0.5, file=sys.stderr)
            last_checkpoint = time.perf_counter()
            t_run = time.perf_counter()
            for i, summary, error in results:
                if error is None:
                    summary.to_npz(members_dir / f"member_{i:06d}.npz")
                    (failed_dir / f"member_{i:06d}.json").unlink(missing_ok=True)
                    agg.add(summary)
                    ran.append(i)
                    timings.setdefault("first_result_seconds", time.perf_counter() - started)
                    timings["last_result_seconds"] = time.perf_counter() - started
                else:
                    exc, tb = error
                    msg = (f"member {i} failed ({describe_parameters(params[i])}): "
                           f"{type(exc).__name__}: {exc}")
                    _write_json(failed_dir / f"member_{i:06d}.json",
                                dict(member=i, parameters=params[i], error=str(exc),
                                     type=type(exc).__name__, traceback=tb))
                    agg.fail(i, f"{type(exc).__name__}: {exc}")
                    failures.append(dict(member=i, parameters=params[i],
                                         error=f"{type(exc).__name__}: {exc}"))
                    (bar.write if bar is not None else _stderr)("driftlog: " + msg)
                if bar is not None:
                    bar.update(1)
                if time.perf_counter() - last_checkpoint > sec["checkpoint_interval"]:
                    agg.to_netcdf(agg_path, attrs, table)
                    last_checkpoint = time.perf_counter()
            timings["run_seconds"] = time.perf_counter() - t_run
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        if bar is not None:
            bar.close()
        if results is not None:
            results.close()  # cancels the tasks still pending
        if own is not None:
            client.close()
            own.close()
        timings["wall_seconds"] = time.perf_counter() - started
        if ran and timings.get("run_seconds"):
            timings["members_per_minute"] = 60.0 * len(ran) / timings["run_seconds"]
        if len(ran) > 1 and timings["last_result_seconds"] > timings["first_result_seconds"]:
            # after the first result: workers warm (imports, numba cache, flow opened)
            timings["steady_members_per_minute"] = 60.0 * (len(ran) - 1) / (
                timings["last_result_seconds"] - timings["first_result_seconds"])
        agg.to_netcdf(agg_path, dict(attrs, interrupted=int(interrupted)), table)
        if agg.sites():
            agg.write_clogging_csv(out / CLOGGING_NAME)
        manifest.update(done=agg.done, failed=agg.failed, timings=timings,
                        updated=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"))
        _write_json(manifest_path, manifest)
    figs = []
    if figures and agg.done:
        from driftlog.ensemble.figures import plot_ensemble

        figs = plot_ensemble(agg_path, out)
    return EnsembleResult(agg_path, out, n, agg.done, failures, ran, len(done_before), figs,
                          timings, agg)


def summarize_trajectories(path, mesh, member=0, parameters=None,
                           blocked_gap=0.1) -> MemberSummary:
    """Summarize a trajectory file as an ensemble member (the same numbers as the recorder).

    ``blocked_gap``: as ``[ensemble] blocked_gap`` (held obstacles).  The release points are
    re-seeded from the scenario stored in the file (seeding is reproducible bit for bit);
    records are replayed in time order.
    """
    import netCDF4

    with netCDF4.Dataset(path) as ds:
        ds.set_auto_mask(False)
        scen = load_scenario(json.loads(ds.getncattr("scenario_resolved")))
        names = json.loads(ds.getncattr("obstacle_names")) if "obstacle_names" in ds.ncattrs() \
            else []
        t = ds["time"][:]
        if "trajectory_index" in ds.variables:
            ti = ds["trajectory_index"][:]
        else:
            ti = np.repeat(np.arange(len(ds.dimensions["trajectory"])), ds["rowSize"][:])
        x, y, theta, status = ds["x"][:], ds["y"][:], ds["theta"][:], ds["status"][:]
        hits = {}
        if "hit" in ds.dimensions and len(ds.dimensions["hit"]):
            hits = {"log_id": ds["hit_log"][:], "other": ds["hit_other"][:]}
    logs = logs_from_scenario(scen)
    rec = MemberRecorder(mesh, logs, scen["time"]["start"], obstacle_names=names,
                         obstacles=scenario_obstacles(scen), blocked_gap=blocked_gap)
    order = np.lexsort((ti, t))  # by time, then log: the order the tracker records in
    t, ti, x, y, theta, status = (a[order] for a in (t, ti, x, y, theta, status))
    bounds = np.flatnonzero(np.diff(t)) + 1
    for a, b in zip(np.r_[0, bounds], np.r_[bounds, t.size], strict=True):
        if b > a:
            rec.record(t[a], ti[a:b], {"x": x[a:b], "y": y[a:b], "theta": theta[a:b],
                                       "status": status[a:b]})
    if hits:
        rec.hits(hits)
    return rec.summary(member, parameters)


def _stderr(msg):
    print(msg, file=sys.stderr)


def run_member(ensemble, member: int, grid="auto") -> MemberSummary:
    """Run one member in this process and return its summary (for checks and debugging)."""
    ens = load_ensemble(ensemble)
    base = ens.base()
    # the flow as run_ensemble prepares it (a solved or imported flow written once to
    # <output>/flow.nc and reused; a flow file or an analytic field as they are)
    base["flow"], mesh = _prepare_flow(ens, base, ens.output.resolve())
    if grid == "auto":
        grid = aggregation_grid(ens, mesh)
    values = ens.parameters_of(member)
    return run_member_task(base, member, ens.member_overrides(member, base, values), values,
                           dict(grid=grid, trajectories=None,
                                blocked_gap=ens.section["blocked_gap"]))
