"""The checks a run makes before it starts.

Shared by ``driftlog track`` and ``driftlog scenario check``, so that "valid" means "the run
will start".  In order: the output path can be written; the run fits in memory and on
disk; the flow can be read (its mesh built, every snapshot of the run's time window finite);
the logs can be seeded (finite positions and properties); every log starts inside the flow's
mesh; and logs against obstacles at the start, by this rule:

- **error**: a log's centre lies inside an obstacle (a circle pier or a polygon) while contacts
  are on; the contact model has no side to push it out to.
- **error**: a log's axis enters an obstacle or crosses a wall (an overlap deeper than the
  log's radius) while contacts are on; the contact model separates bodies whose axes are
  apart, and such a log would stay pinned where it starts.
- **warning**: a log's body (its capsule) overlaps an obstacle or a wall, less deep than its
  radius; the contact model separates them on the first step, with an impulse that does not
  come from the flow.
- **warning**: obstacles are given but ``[contact] enabled = false``: the logs pass through them.

And the logs' release times against the run's span:

- **error**: a ``[[logs]]`` group released before ``[time] start`` (it would enter at the start,
  not at its release time) or after the run's end (``[time] end``, else the flow's): the run
  would record nothing of it.

Warnings are ``DriftlogWarning`` (the CLI prints ``driftlog: warning: ...``); errors are
``DriftlogError`` subclasses naming the key, the value and what is allowed.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from driftlog.columns import THETA, X, Y
from driftlog.errors import DriftlogWarning, ScenarioError

__all__ = ["check_start", "check_scenario", "check_flow_values", "count_logs", "estimate_run",
           "run_end", "run_inputs"]


def _log_capsules(logs):
    from driftlog.contact.geometry import log_capsules

    return log_capsules(logs.state[:, X], logs.state[:, Y], logs.state[:, THETA], logs.length,
                        logs.radius)


_PAIRS = 1 << 20  # (log, obstacle) pairs measured at a time: bounded memory


def _capsule_gaps(logs, caps, deepest=False):
    """Smallest signed gap between each log capsule and the obstacle capsules near it (n,).

    Exact (``contact.geometry.capsule_gap``, the contact model's own measure: a log whose axis
    crosses a wall segment gets the depth of the crossing, minus both radii).  Only the pairs
    whose boxes touch are measured (the contact broad phase's static grid): a log far from
    every obstacle gets +inf, as its gap is positive anyway; time and memory grow with the
    logs, not logs x obstacles.  ``deepest``: also the row of ``caps`` giving each gap (-1
    where none is near).
    """
    from driftlog.columns import GAP, NRES
    from driftlog.contact.broadphase import StaticGrid
    from driftlog.contact.geometry import capsule_pair_gaps

    lc = _log_capsules(logs)
    best = np.full(len(logs), np.inf)
    which = np.full(len(logs), -1, np.int64)
    if caps.shape[0] == 0 or len(logs) == 0:
        return (best, which) if deepest else best
    ex = 0.5 * np.abs(lc[:, 2] - lc[:, 0]) + lc[:, 4]
    ey = 0.5 * np.abs(lc[:, 3] - lc[:, 1]) + lc[:, 4]
    cx, cy = 0.5 * (lc[:, 0] + lc[:, 2]), 0.5 * (lc[:, 1] + lc[:, 3])
    pairs = StaticGrid(caps, 2.0 * max(float(ex.max()), float(ey.max()))).query(cx, cy, ex, ey)
    for p0 in range(0, pairs.shape[0], _PAIRS):
        i, k = pairs[p0:p0 + _PAIRS, 0], pairs[p0:p0 + _PAIRS, 1]
        res = np.empty((i.size, NRES))
        capsule_pair_gaps(np.ascontiguousarray(lc[i]), np.ascontiguousarray(caps[k]), res)
        gap = res[:, GAP]
        np.minimum.at(best, i, gap)
        if deepest:
            hit = gap == best[i]
            which[i[hit]] = k[hit]
    return (best, which) if deepest else best


def _inside_obstacle(scen, x, y):
    """(n,) index of the [[obstacles]] entry holding each point (circle or polygon), or -1."""
    from matplotlib.path import Path as MplPath

    where = np.full(x.size, -1)
    for i, o in enumerate(scen["obstacles"]):
        if o["type"] == "circle" and o["center"] is not None and o["radius"] is not None:
            inside = np.hypot(x - o["center"][0], y - o["center"][1]) < o["radius"]
        elif o["type"] == "polygon" and o["points"] and len(o["points"]) >= 3:
            inside = MplPath(np.asarray(o["points"], float)).contains_points(
                np.column_stack([x, y]))
        else:
            continue
        where = np.where((where < 0) & inside, i, where)
    return where


def _check_span(scen, flow):
    """``[time] end`` within the flow's span (a run past it stops there, after the work before).

    The flow's last time when it is open (a held flow, ``[flow] steady_at``, has none), the
    solver's ``[solver] end`` before the solver's flow is computed; a coupled run computes its
    flow as it goes (its own check: ``coupling``).
    """
    from driftlog.errors import FlowDomainError

    end = scen["time"]["end"]
    if end is None or scen["coupling"]["enabled"] or scen["flow"]["steady_at"] is not None:
        return
    what = None
    if flow is not None:
        t1 = flow.time_span[1]
        try:
            if end > t1:  # the flow's own test, with its round-off tolerance
                flow.check_time(end)
        except FlowDomainError:
            what = f"the flow's last time ({t1:g} s)"
    elif scen["flow"]["source"] == "solver" and scen["solver"]["end"] is not None:
        # the solver's flow will span [solver] start to end: the same test on that span
        s0, s1 = scen["solver"].get("start") or 0.0, float(scen["solver"]["end"])
        if end > s1 + 1e-9 * max(s1 - s0, 1.0):
            what = f"the solver's end ({s1:g} s, [solver] end)"
    if what is not None:
        raise ScenarioError("time.end", end, f"is after {what}, where the flow stops: lower "
                            "[time] end, compute or import a longer flow, or hold the flow "
                            "after a time ([flow] steady_at)")


def _check_release(scen, flow, logs):
    """Each group's release time within the run's span: ``[time] start`` to its end."""
    rt = np.asarray(logs.release_time, float)
    if rt.size == 0:
        return
    t0, t1 = float(scen["time"]["start"]), run_end(scen, flow)
    tol = 1e-9 * max(abs(t0), abs(t1 or 0.0), 1.0)
    end = f"{t1:g} s" if t1 is not None else "its end"
    span = f"between time.start = {t0:g} s and the run's end ({end})"
    early = np.flatnonzero(rt < t0 - tol)
    if early.size:
        i = int(early[0])
        raise ScenarioError(f"logs[{logs.group[i]}].release_time", float(rt[i]),
                            f"is before time.start = {t0:g} s: its logs would enter at the "
                            f"start, not at their release time; release them {span}")
    if t1 is not None:
        late = np.flatnonzero(rt > t1 + tol)
        if late.size:
            i = int(late[0])
            what = ("time.end" if scen["time"]["end"] is not None else "the end of the flow")
            raise ScenarioError(f"logs[{logs.group[i]}].release_time", float(rt[i]),
                                f"is after {what} ({t1:g} s): its logs would never be "
                                "released and the run would record nothing of them; release "
                                f"them {span}")


def _check_landings(scen, flow):
    """The run's stops within ``tracker.MAX_LANDINGS``, as the tracker checks them.

    Its outputs, and the steps of ``[time] hydro_step`` on a flow without snapshots.
    """
    from driftlog.tracker import check_landings

    end = run_end(scen, flow)
    if end is None:
        return
    tm = scen["time"]
    steady = (flow is not None and not scen["coupling"]["enabled"]
              and np.asarray(getattr(flow, "times", ())).size <= 1)
    check_landings(tm["start"], end, tm["output_interval"], tm["hydro_step"] if steady else None)


def _dry_flow_note(scen, flow):
    """A note when no face of the flow at the run's start is deeper than its dry depth.

    ``[flow] dry_depth`` is a thin-film threshold; set above the deepest water of the flow
    (a depth in the wrong unit, a decimal point) it makes every face dry: no log floats and
    the run records logs resting where they were released.  Checked on the snapshot at the
    start (one read), for flows stored as snapshots.
    """
    times = np.asarray(getattr(flow, "times", ()), float)
    read = getattr(flow, "read_snapshot", None)
    dd = getattr(flow, "dry_depth", None)
    if read is None or dd is None or times.size == 0:
        return None
    i = int(np.clip(np.searchsorted(times, float(scen["time"]["start"])), 0, times.size - 1))
    h = np.asarray(read(i)[0], float)
    if h.size == 0 or float(h.max()) > dd:
        return None
    return (f"[flow] dry_depth = {dd:g} m is at or above the deepest water of the flow at "
            f"t = {times[i]:g} s ({float(h.max()):.3g} m): every face counts as dry there "
            "(velocity zero, no log floats); dry_depth is a thin-film threshold (1e-4 to "
            "1e-2 m in flood models)")


def check_start(scen, flow, logs, mesh=None, warn=True):
    """Logs against the flow's mesh and the obstacles at the start (the module's rule).

    Parameters
    ----------
    scen : Scenario
    flow : FlowField or None
        The run's flow (its ``mesh`` locates the logs); None with ``mesh`` given.
    logs : Logs
    mesh : Mesh, optional
        The mesh when the flow is not computed yet (a solver flow checked before solving).
    warn : bool
        Issue the warnings (``DriftlogWarning``); they are returned either way.

    Returns
    -------
    list of str
        The warnings.
    """
    from driftlog.tracker import outside_error

    _check_span(scen, flow)
    _check_release(scen, flow, logs)
    _check_landings(scen, flow)
    mesh = mesh if mesh is not None else getattr(flow, "mesh", None)
    if mesh is not None:
        face = mesh.locate(logs.state[:, X], logs.state[:, Y])
        out = np.flatnonzero(face < 0)
        if out.size:
            raise outside_error(flow if flow is not None else _MeshOnly(mesh), logs, out)
    notes = []
    dry = _dry_flow_note(scen, flow) if flow is not None else None
    if dry:
        notes.append(dry)
    obst = scen["obstacles"]
    contact = scen["contact"]["enabled"]
    if obst and not contact:
        notes.append(f"{len(obst)} [[obstacles]] are given but [contact] enabled = false: the "
                     "logs pass through them")
    if contact:
        where = _inside_obstacle(scen, logs.state[:, X], logs.state[:, Y])
        bad = np.flatnonzero(where >= 0)
        if bad.size:
            i, k = int(bad[0]), int(where[bad[0]])
            name = obst[k]["name"] or f"{obst[k]['type']}_{k}"
            raise ScenarioError(f"logs[{logs.group[i]}]", f"x = {logs.state[i, X]:.6g}, "
                                f"y = {logs.state[i, Y]:.6g}",
                                f"log {i} starts with its centre inside obstacles[{k}] "
                                f"({name!r}; {bad.size} logs in all); move the logs out of "
                                "the obstacles")
        from driftlog.contact.obstacles import Obstacles

        obs = Obstacles.from_tables(scen["obstacles"],
                                    walls=mesh if scen["contact"]["walls"] else None)
        gap, cap = _capsule_gaps(logs, obs.capsules, deepest=True)
        # an overlap as deep as the log's radius or deeper: its axis enters the obstacle or
        # crosses a wall segment (whose own depth may be nil where the log crosses at a
        # vertex between two segments, hence <=); the contact model separates bodies whose
        # axes are apart, not these (such a log stays pinned where it starts)
        across = np.flatnonzero(gap <= -logs.radius)
        if across.size:
            i = int(across[0])
            k = int(obs.owner[cap[i]])
            what = ("the mesh's boundary (a wall)" if obs.kinds[k] == "walls"
                    else f"obstacle {obs.names[k]!r}")
            raise ScenarioError(f"logs[{logs.group[i]}]", f"x = {logs.state[i, X]:.6g}, "
                                f"y = {logs.state[i, Y]:.6g}, theta = "
                                f"{logs.state[i, THETA]:.6g}",
                                f"log {i} (length {logs.length[i]:.6g} m) starts with its axis "
                                f"across {what} ({across.size} logs in all); the contact "
                                "model cannot push it out; release every log with its whole "
                                "length inside the flow domain and clear of the obstacles")
        over = np.flatnonzero(gap < 0)
        if over.size:
            i = int(over[np.argmin(gap[over])])
            notes.append(f"{over.size} logs overlap an obstacle or a wall at their release "
                         f"(log {i} of logs[{logs.group[i]}] at x = {logs.state[i, X]:.6g}, "
                         f"y = {logs.state[i, Y]:.6g} by {-gap[i]:.3g} m); the contact model "
                         "pushes them apart on the first step")
    if warn:
        for n in notes:
            warnings.warn(n, DriftlogWarning, stacklevel=2)
    return notes


class _MeshOnly:
    def __init__(self, mesh):
        self.mesh = mesh


def check_flow_values(flow, t0, t1):
    """Read every snapshot of ``flow`` that a run from t0 to t1 uses.

    A non-finite, negative or ill-sized snapshot raises ``FlowFileError``.  Returns the number
    of snapshots read.
    """
    times = np.asarray(getattr(flow, "times", ()), float)
    if times.size == 0 or not hasattr(flow, "read_snapshot"):
        return 0
    lo = max(int(np.searchsorted(times, t0, side="right")) - 1, 0)
    hi = times.size - 1 if t1 is None else min(int(np.searchsorted(times, t1, side="left")),
                                               times.size - 1)
    for i in range(lo, hi + 1):
        flow.read_snapshot(i)
    return hi - lo + 1


def run_inputs(scen) -> list:
    """The files a run reads, as ``check_output``'s ``inputs``: its scenario and its flow.

    The flow counts by its path when it is not written yet (a solver flow the run computes):
    a trajectory file there would be overwritten by the flow, or the flow by it.
    """
    inputs = [(scen.path, "the scenario file")] if scen.path else []
    sec = scen["flow"]
    if sec["source"] == "solver":
        from driftlog.solving import default_flow_path

        inputs.append((default_flow_path(scen), "the scenario's flow file ([flow] path, "
                       "computed by the solver)"))
    elif sec["source"] != "analytic" and sec["path"]:
        inputs.append((sec["path"], "the scenario's flow file ([flow] path)"))
    return inputs


def check_scenario(scen, logs, output=None, read_flow=True):
    """Every check ``track`` makes before it starts, without tracking (``scenario check``).

    ``logs``: the scenario's seeded logs (``driftlog.api.logs_from_scenario``).  Returns
    (warnings, what was checked: a list of short phrases).  A solver flow not computed yet is
    not computed: its mesh is built (after a size estimate) and the logs located on it.
    """
    from driftlog.files import check_output
    done = []
    out = Path(output or scen["output"]["path"])
    role = "trajectory file" if output else "trajectory file ([output] path)"
    check_output(out, role, inputs=run_inputs(scen), suffixes=(".nc", ".nc4"),
                 create=False)
    n, nobs, mem = estimate_run(scen, out)
    done.append(f"output {out} writable; {n} logs, {nobs:.3g} observations, about "
                f"{mem / 2**20:.3g} MiB")
    if scen["coupling"]["enabled"]:
        from driftlog.coupling import coupled_flow_path

        cflow = check_output(coupled_flow_path(scen, out), "flow file", create=False)
        done.append(f"coupled flow file {cflow} writable")
    src = scen["flow"]["source"]
    flow = mesh = None
    if src == "solver":
        from driftlog.solver.config import solver_hash
        from driftlog.solving import default_flow_path, stored_flow

        sec = scen["solver"]
        if sec["end"] is None:
            raise ScenarioError("solver.end", None, "is required with [flow] source = 'solver':"
                                " the end time of the flow computation (s)")
        path = default_flow_path(scen)
        state, t_last = stored_flow(path, solver_hash(sec))
        if state is not None and t_last is not None and t_last >= sec["end"]:
            from driftlog.sources import flow_from_scenario

            flow = flow_from_scenario(scen)
            done.append(f"solver flow {path} stored and up to date")
        else:
            from driftlog.solver.config import build_mesh, build_solver, estimate_mesh

            cells = estimate_mesh(sec)
            mesh = build_mesh(sec)
            # the solver as the run builds it: its checks of the boundary tags, the initial
            # state (a flow file on this mesh), the sea
            build_solver(sec, mesh)
            done.append(f"solver mesh built ({mesh.n_faces} cells"
                        + (f", estimated {cells:.3g}" if cells else "") + ") with its "
                        "boundaries and initial state; the flow is computed by the run")
    else:
        from driftlog.sources import flow_from_scenario

        flow = flow_from_scenario(scen)
        done.append(f"flow {getattr(flow, 'name', src)} readable")
        if scen["time"]["end"] is None:  # the run ends with the flow: its size known now
            n, nobs, mem = estimate_run(scen, out, flow)
            done[0] = (f"output {out} writable; {n} logs, {nobs:.3g} observations to the "
                       f"flow's end ({run_end(scen, flow):g} s), about {mem / 2**20:.3g} MiB")
    if flow is not None and read_flow:
        k = check_flow_values(flow, scen["time"]["start"], scen["time"]["end"])
        if k:
            done.append(f"{k} snapshots finite")
    notes = check_start(scen, flow, logs, mesh=mesh, warn=False)
    done.append("logs inside the mesh" if (mesh is not None or getattr(flow, "mesh", None)
                                          is not None) else "logs seeded")
    return notes, done


def count_logs(scen) -> int:
    """The number of logs a validated scenario seeds, without seeding them."""
    n = 0
    for g in scen["logs"]:
        if g.get("seeding", "list") == "list":
            x = g.get("x")
            n += len(x) if isinstance(x, (list, tuple)) else 1
        else:
            n += int(g.get("count") or 0)
    return n


def run_end(scen, flow=None):
    """The end of the debris run (s): ``[time] end``, else the end of the flow.

    The flow's end is the solver's ``end`` for a solver or coupled flow, else the last time of
    ``flow`` once it is open; None when it is not known yet (a flow file not opened, an
    analytic flow, which needs ``[time] end``).
    """
    tm = scen["time"]
    if tm["end"] is not None:
        return float(tm["end"])
    if scen["flow"]["source"] == "solver" or scen["coupling"]["enabled"]:
        return scen["solver"]["end"]
    if flow is not None:
        t1 = float(flow.time_span[1])
        return t1 if np.isfinite(t1) else None
    return None


def _log_keys(scen, most=3) -> str:
    """The [[logs]] keys that give the run its logs, largest groups first, with their values.

    ``[logs[0].count] = 10000000``, ``[logs[1].x] = 3 positions``: what a size message names.
    """
    sizes = []
    for i, g in enumerate(scen["logs"]):
        if g.get("seeding", "list") == "list":
            x = g.get("x")
            k = len(x) if isinstance(x, (list, tuple)) else 1
            sizes.append((k, f"[logs[{i}].x] = {k} positions"))
        else:
            sizes.append((int(g.get("count") or 0), f"[logs[{i}].count] = {g.get('count')}"))
    sizes.sort(key=lambda s: -s[0])
    shown = [s for _, s in sizes[:most]]
    if len(sizes) > most:
        shown.append(f"{len(sizes) - most} more groups")
    return ", ".join(shown) or "no [[logs]]"


def _record_keys(scen, end) -> str:
    """The keys that give the run its records, with their values (a size message names them)."""
    tm = scen["time"]
    every = f"[time.output_interval] = {tm['output_interval']:g} s"
    if end is None:
        return f"{every}; the end is not known before the flow is read"
    if tm["end"] is not None:
        until = f"[time.end] = {end:g} s"
    elif scen["flow"]["source"] == "solver" or scen["coupling"]["enabled"]:
        until = f"[solver.end] = {end:g} s"
    else:
        until = f"the flow's end, {end:g} s"
    return f"{every} from [time.start] = {tm['start']:g} s to {until}"


def estimate_run(scen, output=None, flow=None):
    """Refuse (``SizeError``) a run too large for this machine, before anything is allocated.

    Memory: about 2 kB per log for the tracker (state, integrator stages, flow samples,
    contacts) and the buffered records (``flush_interval`` records of 85 bytes per log, at most
    ``trajectory.MAX_BUFFERED_OBS`` observations), and the final rewrite of the trajectory
    file, 16 bytes per observation (one variable at a time, with its sort order).  Disk: 85
    bytes per observation, twice (the ``.partial`` file and the final file).  Without
    ``[time] end`` the run ends with the flow (``run_end``): before the flow is open (``flow``
    None) only the logs' own memory is counted, and the caller estimates again once it is.
    Returns (logs, observations, bytes of memory).
    """
    import shutil

    from driftlog.resources import check_fits

    n = count_logs(scen)
    tm = scen["time"]
    end = run_end(scen, flow)
    records = 2 if end is None else int(max(end - tm["start"], 0.0) / tm["output_interval"]) + 2
    nobs = float(n) * records
    from driftlog.trajectory import MAX_BUFFERED_OBS

    buffered = min(float(n) * scen["output"]["flush_interval"], MAX_BUFFERED_OBS)
    mem = n * 2000.0 + 85.0 * buffered + 16.0 * nobs
    advice = ("fewer logs (count), a longer [time] output_interval, or an ensemble "
              "(driftlog ensemble) that runs the logs in members")
    what = (f"tracking {n:.3g} logs ({_log_keys(scen)}) over {records} records "
            f"({_record_keys(scen, end)})")
    check_fits(mem, f"{what} ({nobs:.3g} observations)", advice)
    out = Path(output or scen["output"]["path"])
    try:
        free = shutil.disk_usage(out.parent if out.parent.exists() else Path.cwd()).free
    except OSError:
        free = None
    if free is not None and 2 * 85.0 * nobs > 0.9 * free:
        from driftlog.errors import SizeError

        raise SizeError(f"{what} writes about "
                        f"{2 * 85 * nobs / 2**30:.3g} GiB, more than the {free / 2**30:.3g} GiB "
                        f"free on the disk of {out.parent}; {advice}")
    return n, nobs, mem
