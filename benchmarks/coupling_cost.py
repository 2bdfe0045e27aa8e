"""Cost of two-way coupling: the Malpasset flood with logs acting on it, against the plain solve.

One scenario (cases/malpasset, 46,691 triangles, first order), three runs from the dam break
to ``--end``:

- ``solve``: the solver alone (no output), the uncoupled flood;
- ``coupled``: ``[coupling] enabled``: solver and tracker together, ``--logs`` logs (8 m,
  0.2 m radius, pine) released at rest in the reservoir near the dam (wet from the start, so
  every one is carried and acts on the flood from the first step), no contacts;
- ``offline``: the same logs tracked afterwards on the solve's flow file (snapshots every
  10 s), the one-way pipeline (solve with output, then track).

Prints and writes benchmarks/results/coupling_cost{.md,.csv,.json}: wall seconds, solver
steps, coupled / solve and coupled / (solve + offline track) ratios; and
coupling_cost_parts{.md,.csv}: the coupled run's CPU time per part (the solver's steps, the
flow's node values, the tracker's sub-steps, the hand-over of the logs' reaction, the flow
file, the rest: setup, spin-up, trajectory file), in total and per solver step.  The full flood is
4000 s (the three runs about 330 CPU s per repetition: 10 min wall on the shared 2 cores); a
shorter ``--end`` (300 s by default) is labelled as a shortened run.

    python benchmarks/coupling_cost.py --end 120 --logs 1000 --repeat 3
    python benchmarks/coupling_cost.py --end 4000 --logs 1000 --checkpoints 600,1800 \
        --repeat 2 --name coupling_cost_4000s

``--clocks``: the coupled runs, one per entry: ``[integrator] clock``, optionally with ``@``
and a ``[coupling] interval`` in seconds (``per_log@1``: per-log clocks, exchanges every
second, docs/model.md 17.6); the first is the reference, ``global`` (every step).

``--checkpoints``: the cumulative CPU seconds of each run at these times of the same run
(output times), so one run gives the ratios at several ends (written as
``<name>_evolution{.md,.csv}``).  The json also holds SHA-256 digests of the coupled run's
trajectories and flow file (state arrays), to check that a faster coupling gives the same
results bit for bit.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402
from _common import RESULTS, machine, write_table  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
CASE = ROOT / "cases" / "malpasset" / "scenario.toml"
CLOCKS = (time.perf_counter, time.process_time)
# the coupled run's parts (driftlog.coupling.Coupling.cpu, written as coupling_cpu_<key>_s)
PARTS = {"solver": "solver steps", "flow_nodes": "flow node values (region, push)",
         "tracker": "tracker sub-steps", "handover": "hand-over of the reaction",
         "flow_file": "flow file (snapshots)"}


# the variables whose bytes the digests cover
TRAJ_VARS = ["time", "trajectory_index", "x", "y", "theta", "u", "v", "omega", "status",
             "water_depth", "flow_u", "flow_v"]
FLOW_VARS = ["time", "water_depth", "velocity_x", "velocity_y", "restart_momentum_x",
             "restart_momentum_y"]


def timed(fn):
    """(result, wall s, CPU s) of fn(): CPU time is the fair measure on a loaded machine."""
    w, c = (f() for f in CLOCKS)
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


# in the reservoir, just upstream of the dam line (bed below 100 m: wet at t = 0)
RESERVOIR = [[4350.0, 3850.0], [4550.0, 4000.0], [4450.0, 4250.0], [4250.0, 4100.0]]


def scenario(end, n_logs, coupled, flow_path=None, clock="global"):
    """The Malpasset case to ``end`` with ``n_logs`` logs in the reservoir.

    ``clock``: ``[integrator] clock``, optionally with ``@`` and a ``[coupling] interval``
    (s): "per_log@1" exchanges every second.
    """
    from driftlog.api import as_scenario

    clock, _, interval = clock.partition("@")

    over = {"time": {"start": 0.0, "end": end, "output_interval": 10.0},
            "logs": [{"name": "reservoir", "seeding": "random", "count": n_logs,
                      "polygon": RESERVOIR, "seed": 7, "theta": "random", "length": 8.0,
                      "radius": 0.2, "density": 700.0, "velocity": "rest"}],
            "solver": {"end": end, "output_interval": 10.0},
            "coupling": {"enabled": coupled, "interval": float(interval or 0.0)},
            "integrator": {"clock": clock}}
    if flow_path is not None:
        over["flow"] = {"path": str(flow_path)}
    scen = as_scenario(str(CASE), overrides=over)
    return scen


class Checkpoints:
    """Cumulative CPU seconds of a run at chosen times (its flow or trajectory writes).

    Wraps, for the runs of this script only, the two places every run passes at its output
    times: ``Tracker._record`` (the offline and the coupled tracker: the coupled run's CPU
    parts are copied too) and the solver's flow-file write ``driftlog.solver.run._write``.
    """

    def __init__(self, times):
        import driftlog.solver.run as run
        from driftlog.tracker import Tracker

        self.times = sorted(times)
        self.log = {}  # time -> (CPU s, coupling parts or None)
        self.c0 = time.process_time()
        rec, write = Tracker._record, run._write
        cp = self

        def _record(tracker):
            rec(tracker)
            c = getattr(tracker, "coupling", None)
            cp.hit(tracker.t, None if c is None else (
                {k.replace(" ", "_").replace("-", ""): v for k, v in c.cpu.items()},
                c.solver_steps))

        def _write(w, solver, **kw):
            write(w, solver, **kw)
            cp.hit(solver.t, None)

        Tracker._record, run._write = _record, _write

    def start(self):
        """A new run starts now."""
        self.log = {}
        self.c0 = time.process_time()

    def hit(self, t, extra):
        c = time.process_time() - self.c0
        for tc in self.times:
            if abs(t - tc) < 1e-6 and tc not in self.log:
                self.log[tc] = (c, extra)


def digest(path, names):
    """SHA-256 of the named variables of a netCDF file (their bytes, in order)."""
    import netCDF4

    h = hashlib.sha256()
    with netCDF4.Dataset(path) as ds:
        for n in names:
            if n in ds.variables:
                h.update(np.ascontiguousarray(ds.variables[n][:].filled(np.nan)).tobytes())
    return h.hexdigest()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--end", type=float, default=300.0, help="end of the flood run (s)")
    ap.add_argument("--logs", type=int, default=1000)
    ap.add_argument("--name", default="coupling_cost")
    ap.add_argument("--repeat", type=int, default=1,
                    help="repetitions of the three runs; the fastest (CPU) of each is kept")
    ap.add_argument("--clocks", default="global,per_log",
                    help="[integrator] clock of the coupled run, one run each (comma-separated), "
                    "optionally @ an exchange interval in s (per_log@1)")
    ap.add_argument("--checkpoints", default="",
                    help="comma-separated times (s, multiples of 10) at which the ratios are "
                    "also reported, from the same runs")
    a = ap.parse_args(argv)
    cps = sorted({float(v) for v in a.checkpoints.split(",") if v.strip()} - {a.end})
    if any(t <= 0.0 or t > a.end or abs(t / 10.0 - round(t / 10.0)) > 1e-9 for t in cps):
        raise SystemExit(f"--checkpoints {a.checkpoints}: times in (0, {a.end:g}] s, "
                         "multiples of the 10-s output interval")
    check = Checkpoints(cps)
    from driftlog.api import track
    from driftlog.solver.config import build_solver
    from driftlog.solving import solve_scenario

    tmp = Path(tempfile.mkdtemp(prefix="driftlog-coupling-"))
    rows = []
    clocks = [c.strip() for c in a.clocks.split(",") if c.strip()]
    if clocks[0] != "global":
        raise SystemExit(f"--clocks {a.clocks}: the first is the reference, 'global'")
    # warm the kernels (numba cache) on a few steps under each clock, so no run pays for
    # compiling
    for c in clocks:
        track(scenario(20.0, 10, True, clock=c), output=tmp / "warm.nc")

    scen = scenario(a.end, a.logs, False, flow_path=tmp / "flow.nc")
    cscens = {c: scenario(a.end, a.logs, True, clock=c) for c in clocks}
    import netCDF4

    best = {}  # run -> (CPU s, wall s, extra, checkpoints): the fastest of the repetitions

    def keep(key, cpu, wall, extra=None, at=None):
        if key not in best or cpu < best[key][0]:
            best[key] = (cpu, wall, extra, at)

    def solve_alone(s):
        at = {}
        c0 = time.process_time()
        for t in cps:  # the same steps as one advance_to(end) but landing on the checkpoints
            s.advance_to(t)
            at[t] = (time.process_time() - c0, None)
        s.advance_to(a.end)
        return at

    for _ in range(a.repeat):  # the three runs side by side, interleaved
        s = build_solver(scen["solver"])
        at, w, c = timed(lambda s=s: solve_alone(s))
        keep("solve", c, w, None, at)
        check.start()
        _, w_out, c_out = timed(lambda: solve_scenario(scen, output=tmp / "flow.nc"))
        at_out = check.log
        check.start()
        off, w_track, c_track = timed(lambda: track(scen, output=tmp / "offline.nc"))
        at = {t: (at_out[t][0] + check.log[t][0], None) for t in cps}
        keep("offline", c_out + c_track, w_out + w_track, (c_track, off.stats["substeps"]), at)
        keep("solve_out", c_out, w_out)
        for clock, cscen in cscens.items():
            check.start()
            res, w, c = timed(lambda cscen=cscen: track(cscen, output=tmp / "coupled.nc"))
            at = dict(check.log)
            with netCDF4.Dataset(tmp / "coupled.nc") as ds:
                steps = int(ds.getncattr("coupling_solver_steps"))
                given = (float(ds.getncattr("coupling_momentum_given_x")),
                         float(ds.getncattr("coupling_momentum_given_y")))
                region = float(ds.getncattr("coupling_region_nodes"))
                widened = int(ds.getncattr("coupling_region_widenings"))
                parts = {k: float(ds.getncattr(f"coupling_cpu_{k}_s")) for k in PARTS}
            with netCDF4.Dataset(tmp / "coupled_flow.nc") as ds:  # the flood at the end
                h_end = np.asarray(ds["water_depth"][-1], dtype=float)
            digests = dict(
                trajectories=digest(tmp / "coupled.nc", TRAJ_VARS),
                flow=digest(tmp / "coupled_flow.nc", FLOW_VARS))
            keep(f"coupled {clock}", c, w, dict(parts=parts, digests=digests, res=res,
                                                steps=steps, given=given, region=region,
                                                widened=widened, h_end=h_end), at)
    c_solve, w_solve, _, at_solve = best["solve"]
    c_off, w_off, (c_track, substeps), at_off = best["offline"]
    c_c, w_c, ref, at_c = best["coupled global"]
    parts, digests, res, steps = ref["parts"], ref["digests"], ref["res"], ref["steps"]
    given, region, widened = ref["given"], ref["region"], ref["widened"]
    per = {c: best[f"coupled {c}"] for c in clocks[1:]}  # (CPU s, wall s, extra, checkpoints)
    rows.append(dict(run="solve (solver alone, no output)", wall_s=w_solve, cpu_s=c_solve,
                     solver_steps=s.steps, cpu_ratio_to_solve=1.0))
    c_so, w_so = best["solve_out"][:2]
    rows.append(dict(run="solve with output (its flow file, snapshots every 10 s)",
                     wall_s=w_so, cpu_s=c_so, solver_steps=s.steps,
                     cpu_ratio_to_solve=c_so / c_solve))
    rows.append(dict(run="offline: solve with output + track", wall_s=w_off, cpu_s=c_off,
                     solver_steps=s.steps, cpu_ratio_to_solve=c_off / c_solve))
    rows.append(dict(run=f"coupled: {a.logs} logs acting on the flood", wall_s=w_c, cpu_s=c_c,
                     solver_steps=steps, cpu_ratio_to_solve=c_c / c_solve))
    for c, (cp_, wp, ex, _) in per.items():
        clock, _, interval = c.partition("@")
        what = (f"coupled, {clock} clock{'s' if clock == 'per_log' else ''}, exchanges every "
                f"{interval} s" if interval else f"coupled, {c} clocks (no contacts)")
        rows.append(dict(run=what, wall_s=wp, cpu_s=cp_, solver_steps=ex["steps"],
                         cpu_ratio_to_solve=cp_ / c_solve))
    for r in rows:
        r["cpu_ratio_to_solve_with_output"] = r["cpu_s"] / c_so
    # exchange intervals against every-step exchanges on the same clock: the flood at the end
    # and the momentum the logs gave the water
    every = {c: best[f"coupled {c}"][2] for c in clocks if "@" not in c}
    diffs = []
    for c in clocks:
        base = c.partition("@")[0]
        if "@" in c and base in every:
            ex, ref_ = best[f"coupled {c}"][2], every[base]
            dh = np.abs(ex["h_end"] - ref_["h_end"])
            diffs.append(f"  {c} against {base} every step at {a.end:g} s: water depth "
                         f"{dh.max():.2g} m apart at most ({dh.mean():.2g} m on average), "
                         f"momentum given ({ex['given'][0]:.4g}, {ex['given'][1]:.4g}) against "
                         f"({ref_['given'][0]:.4g}, {ref_['given'][1]:.4g}) kg m/s.")
    floating = int((res.logs.status == 1).sum())
    label = "" if a.end >= 4000.0 else f" (shortened run: {a.end:g} s of the 4000-s flood)"
    notes = (f"Malpasset, 46,691 triangles, order 1, {a.logs} logs released in the reservoir, no "
             f"contacts{label}; 1 numba thread, CPU seconds (the machine is shared), the "
             f"fastest of {a.repeat} interleaved repetitions of each run.  Coupled / "
             f"offline pipeline (CPU): {c_c / c_off:.2f}; offline track alone "
             f"{c_track:.1f} CPU s ({substeps} sub-steps); coupled run: {floating} "
             f"logs floating at the end, momentum given to the water ({given[0]:.3g}, "
             f"{given[1]:.3g}) kg m/s."
             + "".join(f"  Coupled, {c} clocks / global clock: {v[0] / c_c:.3f} (CPU); "
                       f"log sub-steps {v[2]['res'].stats.get('log_substeps', 0):,} against "
                       f"{res.stats['substeps']:,} shared sub-steps of up to {a.logs} logs; "
                       f"momentum given ({v[2]['given'][0]:.4g}, {v[2]['given'][1]:.4g}) kg m/s"
                       for c, v in per.items()) + "".join(diffs))
    write_table(a.name, rows, ["run", "wall_s", "cpu_s", "solver_steps", "cpu_ratio_to_solve",
                               "cpu_ratio_to_solve_with_output"],
                f"Cost of two-way coupling: Malpasset with {a.logs} logs{label}", notes)
    parts["rest"] = c_c - sum(parts.values())
    prow = [dict(part=PARTS.get(k, "rest: setup, spin-up, trajectory file, outputs"), cpu_s=v,
                 ms_per_solver_step=1e3 * v / steps, share_of_solve=v / c_solve)
            for k, v in parts.items()]
    pcols = ["part", "cpu_s", "ms_per_solver_step", "share_of_solve"]
    for c, v in per.items():
        pp = dict(v[2]["parts"])
        pp["rest"] = v[0] - sum(pp.values())
        for row, k in zip(prow, parts, strict=True):
            row[f"cpu_s_{c}"] = pp[k]
            row[f"share_of_solve_{c}"] = pp[k] / c_solve
        pcols += [f"cpu_s_{c}", f"share_of_solve_{c}"]
    prow.append(dict(part="solve alone (for comparison)", cpu_s=c_solve,
                     ms_per_solver_step=1e3 * c_solve / s.steps, share_of_solve=1.0))
    pnotes = (f"CPU seconds of each part of the coupled run above ({steps} solver steps, "
              f"{a.logs} logs); the flow's node values were computed on {region:.0f} of "
              f"{s.mesh.n_nodes} nodes per step on average (the region around the logs; "
              f"{widened} steps widened to the whole mesh).")
    write_table(f"{a.name}_parts", prow, pcols,
                f"Where the coupled run's time goes{label}", pnotes)
    evo = []
    for t in cps + [a.end]:
        cs, co, cc = ((v[0], None) if t == a.end else at[t] for v, at in
                      ((best["solve"], at_solve), (best["offline"], at_off),
                       (best["coupled global"], at_c)))
        row = dict(end_s=t, solve_cpu_s=cs[0], offline_cpu_s=co[0], coupled_cpu_s=cc[0],
                   coupled_over_solve=cc[0] / cs[0], coupled_over_offline=cc[0] / co[0])
        cparts, csteps = (parts, steps) if t == a.end else cc[1]
        row["solver_steps"] = csteps
        for k in PARTS:
            row[f"{k}_cpu_s"] = cparts[k]
        evo.append(row)
    if cps:
        write_table(f"{a.name}_evolution", evo,
                    ["end_s", "solver_steps", "solve_cpu_s", "offline_cpu_s", "coupled_cpu_s",
                     "coupled_over_solve", "coupled_over_offline"]
                    + [f"{k}_cpu_s" for k in PARTS],
                    f"Cost of coupling as the flood goes on: Malpasset with {a.logs} logs",
                    f"The same runs as {a.name}.md, cumulative CPU seconds from their start "
                    "to each time (the coupled run and the one-way track include their "
                    "setup); the last columns are the coupled run's parts (see "
                    f"{a.name}_parts.md).")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{a.name}.json").write_text(json.dumps(dict(
        machine=machine(), end=a.end, logs=a.logs, solve_cpu_s=c_solve, solve_wall_s=w_solve,
        solve_with_output_cpu_s=c_so,
        offline_cpu_s=c_off, offline_track_cpu_s=c_track, coupled_cpu_s=c_c,
        coupled_wall_s=w_c, coupled_over_solve=c_c / c_solve,
        coupled_over_offline=c_c / c_off, repeat=a.repeat, floating_at_end=floating,
        momentum_given=given, region_nodes=region, n_nodes=s.mesh.n_nodes,
        region_widenings=widened, coupled_parts_cpu_s=parts, coupled_digests=digests,
        coupled_other_clocks={c: dict(cpu_s=v[0], wall_s=v[1], solver_steps=v[2]["steps"],
                                      log_substeps=v[2]["res"].stats.get("log_substeps", 0),
                                      over_global=v[0] / c_c, momentum_given=v[2]["given"],
                                      parts_cpu_s=v[2]["parts"], digests=v[2]["digests"],
                                      region_widenings=v[2]["widened"])
                              for c, v in per.items()},
        coupled_substeps=res.stats["substeps"],
        evolution=evo), indent=1))
    shutil.rmtree(tmp, ignore_errors=True)  # the flow files: 175 MB each over the whole flood


if __name__ == "__main__":
    main()
