"""Tracking throughput: log-steps per second (issue 4).

A log-step is one integrator step of one log: all its stages, the flow sampled at each stage,
and the tracker's bookkeeping (statuses, step control).  Flow: a free vortex sampled on the
Malpasset mesh (46,691 triangles, two snapshots: a real unstructured mesh, interpolated in
space and time).  Logs: n = 1e3 ... 1e6, L = 2 m, r = 0.2 m, rho_b = 700 kg/m3, spread over the
valley.  Each physics level (tracer, drag, full) and integrator (euler, rk4, exponential), on 1
and 2 threads; on the fused per-log kernels (``driftlog.fused``, the default on mesh flows) and,
for full physics, on the general stage-by-stage path too.  Rates are per
CPU second of the process (``time.process_time``: the machine is shared, wall time counts
other people's jobs), i.e. per core.

    python benchmarks/tracking_benchmark.py [--quick | --breakdown | --targets | --forces |
                                             --before-after | --threads | --drop-ab |
                                             --holes-ab]
                                            [--label NAME]

writes benchmarks/results/tracking.csv and .md, and tracking_breakdown.csv and .md (where
an RK4 log-step's time goes); ``--targets`` only the issue's two targets at 1e5 logs on one
thread (full-physics RK4, tracer) beside the other combinations, best of 5 rounds, into
tracking_targets_NAME.csv and .md (run it with two versions of the code, e.g. ``git stash``
or a second worktree, for a before/after table from one session).
"""

import argparse
import time

import numba
import numpy as np
from _common import malpasset_mesh, write_table
from sampling_benchmark import points

from driftlog.analytic import FreeVortex, on_mesh
from driftlog.columns import X, Y
from driftlog.fused import NCTL, rk4_mesh_step
from driftlog.logs import Logs
from driftlog.physics import PhysicsOptions, log_parameters, rhs_kernel
from driftlog.tracker import StepOptions, Tracker


def one(flow, x, y, level, method, steps, dt=0.5, fused=True):
    logs = Logs(x, y, 0.3, 2.0, 0.2, 700.0)
    tr = Tracker(flow, logs, PhysicsOptions(level=level), method,
                 StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9),
                 t_end=steps * dt, output_interval=steps * dt, hydro_step=steps * dt,
                 fused=fused)
    tr._first_check = True
    tr._release()  # set-up (release, first sampling) is not timed
    tr._update_status()
    t0, c0 = time.perf_counter(), time.process_time()
    tr.run()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return tr.stats["substeps"], wall, cpu, tr.fused


def per_log(n, fn, *args, repeat=5):
    """Best CPU time of fn(*args) per log (ns)."""
    fn(*args)
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn(*args)
        best = min(best, time.process_time() - t0)
    return best / n * 1e9


def fused_ns(S, D, lin, face, F, flag, P, opt, dt, tail):
    """CPU ns per log of the fused RK4 kernel, with and without the next step's first stage."""
    n = S.shape[0]
    Fk, nxt = np.empty_like(F), np.empty_like(S)

    def step(want_next):
        # the same start state each time (D0, lin0, faces restored)
        Dk, link, fk = D.copy(), lin.copy(), face.copy()
        rk4_mesh_step(S, Dk, link, nxt, fk, Fk, flag, P, opt, dt, want_next, *tail)

    copies = per_log(n, lambda: (D.copy(), lin.copy(), face.copy()))
    return per_log(n, step, True) - copies, per_log(n, step, False) - copies


def breakdown(flow, x, y, steps=20, dt=0.5):
    """Where an RK4 log-step goes, per log on one thread (CPU ns), general and fused paths.

    An RK4 step samples the flow 4 times (the step's end, which is the next step's first
    stage, and 3 inner stages) and evaluates the forces 4 times (the first with the drag
    linearisation the step bound needs).  General path: those kernels timed alone, the rest
    is stage arithmetic, copies and the tracker's bookkeeping.  Fused path: the whole step's
    kernel timed alone (``fused_step_ns``), and the same kernel without the next step's
    sample and first stage (``fused_inner_ns``: the 3 inner stages and the update).
    """
    numba.set_num_threads(1)
    n = x.size
    rows = []
    for level in ("tracer", "drag", "full"):
        for fused in (False, True):
            logs = Logs(x, y, 0.3, 2.0, 0.2, 700.0)
            tr = Tracker(flow, logs, PhysicsOptions(level=level), "rk4",
                         StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9),
                         t_end=steps * dt, output_interval=steps * dt, hydro_step=steps * dt,
                         fused=fused)
            t0 = time.process_time()
            tr.run()
            total = (time.process_time() - t0) / (n * tr.stats["substeps"]) * 1e9
            S, F, D = tr.state.copy(), tr.F.copy(), np.empty_like(tr.state)
            lin = np.empty((S.shape[0], tr.lin0.shape[1]))
            face, out, flag = tr.face.copy(), np.empty_like(F), np.empty(S.shape[0], np.int8)
            sx, sy = S[:, X].copy(), S[:, Y].copy()
            t_s = steps * dt * 0.5
            row = dict(level=level, path="fused" if fused else "general", logs=n)
            if not fused:
                row["sample_ns"] = per_log(n, flow.sample_into, sx, sy, t_s, face, out, flag)
                row["forces_lin_ns"] = per_log(n, rhs_kernel, S, F, tr.P, tr.opt, D, lin, True)
                row["forces_ns"] = per_log(n, rhs_kernel, S, F, tr.P, tr.opt, D, lin, False)
                kern = 4 * row["sample_ns"] + row["forces_lin_ns"] + 3 * row["forces_ns"]
            else:
                rhs_kernel(S, F, tr.P, tr.opt, D, lin, True)
                vals, a, inv_dt = flow.node_values(t_s)
                m = S.shape[0]
                tail = (a, inv_dt, vals, a, inv_dt, vals, flow.dry_depth, True,
                        flow.mesh.locator(), False, np.zeros(NCTL), tr.length,
                        np.empty(m, np.int8), np.empty(m))
                row["fused_step_ns"], row["fused_inner_ns"] = fused_ns(
                    S, D, lin, face, F, flag, tr.P, tr.opt, dt, tail)
                kern = row["fused_step_ns"]
            row.update(rest_ns=total - kern, log_step_ns=total, log_steps_per_s=1e9 / total)
            rows.append(row)
            print(row)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking_breakdown", rows, ["level", "path", "logs", "sample_ns",
                                             "forces_lin_ns", "forces_ns", "fused_step_ns",
                                             "fused_inner_ns", "rest_ns", "log_step_ns",
                                             "log_steps_per_s"],
                "Where an RK4 log-step goes (1 thread, CPU ns per log)",
                "general: log_step = 4 sample + forces_lin + 3 forces + rest (stage "
                "arithmetic, copies, status bookkeeping); fused: log_step = fused_step + rest "
                "(fused_inner: the same kernel without the next step's sample and first "
                "stage); the same flow and logs as the throughput table.")


def vortex_flow(mesh):
    """The benchmark flow: a free vortex on the Malpasset mesh, two snapshots 1000 s apart."""
    x0, y0, x1, y1 = mesh.bounds
    return on_mesh(FreeVortex(5e3, center=((x0 + x1) / 2, (y0 + y1) / 2), core_radius=300.0,
                              depth=5.0), mesh, times=[0.0, 1000.0])


TARGET_RUNS = (("full", "rk4", 2e6), ("full", "euler", None), ("full", "exponential", None),
               ("drag", "rk4", None), ("tracer", "rk4", 1e7), ("tracer", "euler", 1e7))


def targets(n=100_000, steps=20, repeat=5, label=""):
    """The issue's two throughput targets on 1 thread, best CPU time of ``repeat`` runs.

    Full-physics RK4 at 1e5 logs (target 2e6 log-steps per CPU s) and tracer mode at 1e5
    particles (target 1e7 particle-steps per CPU s), with the other level x integrator
    combinations beside them, in ``repeat`` rounds of one run each; the load average before
    and after the rounds is recorded (the machine is shared).  ``label`` names the code
    measured (e.g. a commit), so that the numbers of two versions run in the same session
    sit in one table.
    """
    import os

    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    x, y = points(mesh, n, np.random.default_rng(3))
    numba.set_num_threads(1)
    for level, method, _goal in TARGET_RUNS:
        one(flow, x[:2049], y[:2049], level, method, 2)  # compile / load the cache
    # the combinations in rounds, one run of each per round: the host's speed drifts from one
    # minute to the next, and each combination's best run is drawn from the whole span
    best = {}
    load0 = os.getloadavg()[0]
    for _ in range(repeat):
        for level, method, _goal in TARGET_RUNS:
            sub, wall, cpu, used = one(flow, x, y, level, method, steps)
            if (level, method) not in best or cpu < best[(level, method)][2]:
                best[(level, method)] = (sub, wall, cpu, used)
    load = f"{load0:.1f}-{os.getloadavg()[0]:.1f}"
    rows = []
    for level, method, goal in TARGET_RUNS:
        sub, wall, cpu, used = best[(level, method)]
        rows.append(dict(code=label, logs=n, level=level, integrator=method,
                         path="fused" if used else "general", substeps=sub, cpu_seconds=cpu,
                         seconds=wall, per_cpu_s=n * sub / cpu,
                         ns_per_step=cpu / (n * sub) * 1e9, target=goal or "", load=load))
        print(rows[-1], flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    name = "tracking_targets" + (f"_{label}" if label else "")
    write_table(name, rows, ["code", "logs", "level", "integrator", "path", "substeps",
                             "cpu_seconds", "seconds", "per_cpu_s", "ns_per_step", "target",
                             "load"],
                "Tracking throughput against the issue's targets (1 thread, best of "
                f"{repeat} rounds over the combinations)",
                "per_cpu_s: log-steps (particle-steps in tracer mode) per CPU second of the "
                "process; ns_per_step: CPU ns per log-step; load: the machine's 1-minute load "
                "average before and after the runs.  Flow: free vortex on the Malpasset mesh. "
                "Re-create: `python benchmarks/tracking_benchmark.py --targets`.")
    return rows


def thread_scaling(n=100_000, steps=20, repeat=3):
    """Two threads against one on ``n`` logs (issue 15: >= 1.7x on an idle machine).

    Full-physics RK4 and tracer RK4, fused kernels, best wall time of ``repeat`` runs on 1
    and on 2 threads, alternately, with the load average before and after (only a quiet
    machine gives a meaningful wall-time ratio).
    """
    import os

    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    x, y = points(mesh, n, np.random.default_rng(3))
    rows = []
    for level in ("full", "tracer"):
        best = {}
        load0 = os.getloadavg()[0]
        for threads in (1, 2):
            numba.set_num_threads(threads)
            one(flow, x[:2049], y[:2049], level, "rk4", 2)  # compile / load the cache
        for _ in range(repeat):
            for threads in (1, 2):
                numba.set_num_threads(threads)
                sub, wall, cpu, _used = one(flow, x, y, level, "rk4", steps)
                if threads not in best or wall < best[threads][1]:
                    best[threads] = (sub, wall, cpu)
        load1 = os.getloadavg()[0]
        for threads in (1, 2):
            sub, wall, cpu = best[threads]
            rows.append(dict(logs=n, level=level, integrator="rk4", threads=threads,
                             substeps=sub, seconds=wall, cpu_seconds=cpu,
                             log_steps_per_s=n * sub / wall,
                             speedup=best[1][1] / wall, load=f"{load0:.1f}-{load1:.1f}"))
            print(rows[-1], flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking_threads", rows, ["logs", "level", "integrator", "threads",
                                           "substeps", "seconds", "cpu_seconds",
                                           "log_steps_per_s", "speedup", "load"],
                f"Two threads against one ({n:.0e} logs, fused RK4, best wall time of "
                f"{repeat} runs)",
                "speedup: wall time on 1 thread / wall time on this many threads; load: the "
                "machine's 1-minute load average before and after (2 cores).  Flow: free "
                "vortex on the Malpasset mesh.  Re-create: "
                "`python benchmarks/tracking_benchmark.py --threads`.")
    return rows


def drop_ab(n=100_000, steps=20, repeat=4):
    """Stopped logs dropped in place against gathered again, in one process.

    ``Tracker._drop_stopped`` switched off (every status change gathers the floating logs
    into new arrays, as before it) and on, alternately, tracer and full RK4 on 1 thread and
    on 2, and on 2 threads with numba's dynamic scheduling (``set_parallel_chunksize``) beside
    its static default; best wall time of ``repeat`` runs (on one thread wall = CPU time).
    """
    import os

    from driftlog.tracker import Tracker

    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    x, y = points(mesh, n, np.random.default_rng(3))
    real = Tracker._drop_stopped
    arms = [("gather", 1, 0), ("in place", 1, 0), ("gather", 2, 0), ("in place", 2, 0),
            ("in place", 2, 256), ("in place", 2, 2048)]
    rows = []
    try:
        for level in ("tracer", "full"):
            for threads in (1, 2):
                numba.set_num_threads(threads)
                one(flow, x[:4096], y[:4096], level, "rk4", 2)  # compile / load the cache
            best = {}
            load0 = os.getloadavg()[0]
            for _ in range(repeat):
                for arm in arms:
                    path, threads, chunk = arm
                    Tracker._drop_stopped = real if path == "in place" else (
                        lambda self, idx: False)
                    numba.set_num_threads(threads)
                    numba.set_parallel_chunksize(chunk)
                    sub, wall, cpu, _used = one(flow, x, y, level, "rk4", steps)
                    if arm not in best or wall < best[arm][1]:
                        best[arm] = (sub, wall, cpu)
            load1 = os.getloadavg()[0]
            for arm in arms:
                path, threads, chunk = arm
                sub, wall, cpu = best[arm]
                rows.append(dict(logs=n, level=level, stopped_logs=path, threads=threads,
                                 chunksize=chunk or "static", substeps=sub, seconds=wall,
                                 cpu_seconds=cpu, log_steps_per_s=n * sub / wall,
                                 vs_gather_1_thread=best[("gather", 1, 0)][1] / wall,
                                 load=f"{load0:.1f}-{load1:.1f}"))
                print(rows[-1], flush=True)
    finally:
        Tracker._drop_stopped = real
        numba.set_parallel_chunksize(0)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking_drop_ab", rows,
                ["logs", "level", "stopped_logs", "threads", "chunksize", "substeps",
                 "seconds", "cpu_seconds", "log_steps_per_s", "vs_gather_1_thread", "load"],
                f"Stopped logs dropped in place against gathered again ({n:.0e} logs, fused "
                f"RK4, best wall time of {repeat} alternating runs)",
                "stopped_logs: in place (Tracker._drop_stopped) or gathered into new arrays; "
                "chunksize: numba's parallel schedule (static default, or dynamic chunks); "
                "vs_gather_1_thread: wall time of the gather on 1 thread / this one.  Flow: free "
                "vortex on the Malpasset mesh (a few logs leave at nearly every sub-step).  "
                "Re-create: `python benchmarks/tracking_benchmark.py --drop-ab`.")
    return rows


def holes_ab(n=100_000, steps=20, repeat=5):
    """Stopped logs left as holes (``Tracker.lazy_drop``) against dropped at once, in one
    process.

    The two arms alternate, tracer RK4 and Euler and full RK4, on 1 thread and on 2; best
    wall time and best CPU time of ``repeat`` runs each.  The flow and logs of ``--targets``:
    a few logs leave the mesh at nearly every sub-step, which moved every compact row after
    them each time.
    """
    import os

    from driftlog.tracker import Tracker

    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    x, y = points(mesh, n, np.random.default_rng(3))
    real = Tracker.lazy_drop
    rows = []
    try:
        for level, method in (("tracer", "rk4"), ("tracer", "euler"), ("full", "rk4")):
            for threads in (1, 2):
                numba.set_num_threads(threads)
                one(flow, x[:4096], y[:4096], level, method, 2)  # compile / load the cache
            best = {}
            load0 = os.getloadavg()[0]
            for _ in range(repeat):
                for threads in (1, 2):
                    numba.set_num_threads(threads)
                    for lazy in (False, True):
                        Tracker.lazy_drop = lazy
                        sub, wall, cpu, _used = one(flow, x, y, level, method, steps)
                        b = best.get((lazy, threads))
                        best[(lazy, threads)] = (sub, min(wall, b[1]) if b else wall,
                                                 min(cpu, b[2]) if b else cpu)
            load1 = os.getloadavg()[0]
            for threads in (1, 2):
                for lazy in (False, True):
                    sub, wall, cpu = best[(lazy, threads)]
                    rows.append(dict(
                        logs=n, level=level, integrator=method, threads=threads,
                        stopped_rows="holes" if lazy else "dropped at once", substeps=sub,
                        seconds=wall, cpu_seconds=cpu, per_cpu_s=n * sub / cpu,
                        gain=best[(False, threads)][1] / wall,
                        two_threads_vs_one=(best[(lazy, 1)][1] / wall if threads == 2
                                            else ""),
                        load=f"{load0:.1f}-{load1:.1f}"))
                    print(rows[-1], flush=True)
    finally:
        Tracker.lazy_drop = real
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking_holes_ab", rows,
                ["logs", "level", "integrator", "threads", "stopped_rows", "substeps",
                 "seconds", "cpu_seconds", "per_cpu_s", "gain", "two_threads_vs_one", "load"],
                f"Stopped logs left as holes against dropped at once ({n:.0e} logs, fused "
                f"steps, best of {repeat} alternating runs)",
                "stopped_rows: holes (Tracker.lazy_drop, the default: the rows stay until "
                "they are a sixteenth of the compact arrays) or dropped at once (every row "
                "after them moved at each sub-step in which a log stopped); per_cpu_s: "
                "log-steps per CPU second (best CPU time); gain: wall time dropped at once / "
                "this one, same threads; two_threads_vs_one: this arm's wall time on 1 thread "
                "/ on 2.  Flow: free vortex on the Malpasset mesh.  Re-create: "
                "`python benchmarks/tracking_benchmark.py --holes-ab`.")
    return rows


def before_after(combos=(("tracer", "rk4"), ("full", "rk4"), ("tracer", "euler")),
                 n=100_000, steps=20, repeat=3):
    """The fused step with and without settling and tracer kernels, in one process.

    Before: the fused step alone, then the tracker's separate passes (statuses, step bound,
    divergence check, tracer velocity sync) and, in tracer mode, the general fused kernel;
    after: the default (``Tracker._settling``, ``Tracker._tracer_kernels``).  Alternately,
    best CPU time of ``repeat`` each, 1 thread; the final states compared bit for bit.
    """
    import os

    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    x, y = points(mesh, n, np.random.default_rng(3))
    numba.set_num_threads(1)

    def go(xs, ys, level, method, k, new, dt=0.5):
        logs = Logs(xs, ys, 0.3, 2.0, 0.2, 700.0)
        tr = Tracker(flow, logs, PhysicsOptions(level=level), method,
                     StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9),
                     t_end=k * dt, output_interval=k * dt, hydro_step=k * dt)
        tr._tracer_kernels = tr._settling = new
        tr._first_check = True
        tr._release()  # set-up (release, first sampling) is not timed
        tr._update_status()
        c0 = time.process_time()
        tr.run()
        return tr.stats["substeps"], time.process_time() - c0, logs.state.copy()

    rows = []
    for level, method in combos:
        for new in (False, True):
            go(x[:2049], y[:2049], level, method, 2, new)  # compile / load the cache
        best, states, load0 = {False: np.inf, True: np.inf}, {}, os.getloadavg()[0]
        for _ in range(repeat):
            for new in (False, True):
                sub, cpu, states[new] = go(x, y, level, method, steps, new)
                best[new] = min(best[new], cpu)
        r0, r1 = n * sub / best[False], n * sub / best[True]
        rows.append(dict(logs=n, level=level, integrator=method, before_per_cpu_s=r0,
                         before_ns=1e9 / r0, after_per_cpu_s=r1, after_ns=1e9 / r1,
                         gain=r1 / r0, bit_identical=bool(np.array_equal(states[False],
                                                                         states[True])),
                         load=f"{load0:.1f}-{os.getloadavg()[0]:.1f}"))
        print(rows[-1], flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking_before_after", rows,
                ["logs", "level", "integrator", "before_per_cpu_s", "before_ns",
                 "after_per_cpu_s", "after_ns", "gain", "bit_identical", "load"],
                f"Fused step: tracker passes separate (before) or settled in the step, tracer "
                f"kernels (after); 1 thread, best of {repeat}, one process",
                "per_cpu_s: log-steps per CPU second; ns: CPU ns per log-step; the same flow "
                "and logs as --targets.  Re-create: `python benchmarks/tracking_benchmark.py "
                "--before-after`.")
    return rows


def refcount(n=100_000, steps=20, repeat=7):
    """The tracker's kernels with and without numba's reference counting, in one process.

    Each ``kernel(nrt=False)`` kernel's serial code is compiled again with reference counting
    (as before the change; uncached, so numba's cache is left alone), its arguments captured
    from a tracker run on the vortex (1e5 logs: the fused steps and the forces; per-log clocks
    for ``per_log_mesh_advance``), and both run on copies of
    them alternately, best CPU time of ``repeat``, 1 thread, outputs compared bit for bit.
    """
    import os

    import driftlog._numba as dn
    import driftlog.clock_kernel as clock_kernel
    import driftlog.clocks as clocks
    import driftlog.fused as fused
    import driftlog.physics as physics
    import driftlog.tracker as trk

    numba.set_num_threads(1)
    keep = dn.PARALLEL_MIN
    dn.PARALLEL_MIN = 1 << 62  # serial kernels at every size
    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    x, y = points(mesh, n, np.random.default_rng(3))
    # where each kernel is defined, and the module that calls it by an imported name (the
    # flow's sampling and point location run inside the fused steps, not on their own)
    homes = {"rk4_tracer_step": (fused, trk), "euler_tracer_step": (fused, trk),
             "rk4_mesh_step": (fused, trk), "euler_mesh_step": (fused, trk),
             "rhs_kernel": (physics, trk), "per_log_mesh_advance": (clock_kernel, clocks)}
    kernels = {name: getattr(home, name) for name, (home, _caller) in homes.items()}
    captured = {}

    def capture(name, fn):
        def call(*args):
            if name not in captured or args[0].shape[0] > captured[name][0].shape[0]:
                captured[name] = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
            return fn(*args)
        return call

    saved = {}
    for name, fn in kernels.items():
        caller = homes[name][1]
        saved[(caller, name)] = getattr(caller, name)
        setattr(caller, name, capture(name, fn))
    try:
        for level in ("full", "tracer"):  # the forces captured at full physics
            for method in ("rk4", "euler"):
                one(flow, x, y, level, method, 2)
        logs = Logs(x[:10_000], y[:10_000], 0.3, 2.0, 0.2, 700.0)
        tr = Tracker(flow, logs, PhysicsOptions(level="full"), "rk4",
                     StepOptions(max_step=0.5, length_fraction=1e9, angle_step=1e9,
                                 clock="per_log"), t_end=2.0, output_interval=2.0,
                     hydro_step=2.0)
        tr.run()
    finally:
        for (mod, name), fn in saved.items():
            setattr(mod, name, fn)
        dn.PARALLEL_MIN = keep
    rows = []
    load0 = os.getloadavg()[0]
    for name, args in captured.items():
        py = kernels[name].serial.py_func
        variants = {"with": numba.njit(py), "without": numba.njit(_nrt=False)(py)}
        best, outs = {}, {}
        for _ in range(repeat + 1):  # the first round compiles
            for v, k in variants.items():
                a = [x.copy() if isinstance(x, np.ndarray) else x for x in args]
                c0 = time.process_time()
                k(*a)
                c = time.process_time() - c0
                best[v] = min(best.get(v, np.inf), c)
                outs[v] = a
        same = all(np.array_equal(p, q, equal_nan=True) for p, q in zip(outs["with"],
                   outs["without"], strict=True) if isinstance(p, np.ndarray))
        items = args[0].shape[0]
        rows.append(dict(kernel=name, items=items, with_ns=best["with"] / items * 1e9,
                         without_ns=best["without"] / items * 1e9,
                         gain=best["with"] / best["without"], bit_identical=same,
                         load=f"{load0:.1f}-{os.getloadavg()[0]:.1f}"))
        print(rows[-1], flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking_refcount", rows, ["kernel", "items", "with_ns", "without_ns", "gain",
                                            "bit_identical", "load"],
                "The tracker's kernels with and without numba's reference counting (1 thread, "
                f"serial code, best of {repeat}, one process)",
                "with / without: CPU ns per item (log, point) of one call on the same captured "
                "arguments; the fused steps and the forces on 1e5 logs on the Malpasset "
                "vortex, the per-log clock kernel on 1e4.  Re-create: "
                "`python benchmarks/tracking_benchmark.py --refcount`.")
    return rows


def forces(n=100_000, repeat=7, label=""):
    """CPU ns per force evaluation (``rhs_kernel``, serial), with and without the linearisation.

    1e5 logs (L = 2 m, r = 0.2 m, rho_b = 700 kg/m3) at random angles and velocities in a
    random flow sample 5 m deep; the forces alone, no sampling, best of ``repeat`` runs.
    """
    import os

    rng = np.random.default_rng(3)
    S = np.zeros((n, 6))
    S[:, 2] = rng.uniform(0, np.pi, n)
    S[:, 3:5] = rng.normal(0, 1, (n, 2))
    S[:, 5] = rng.normal(0, 0.1, n)
    F = np.zeros((n, 12))
    F[:, 0] = 5.0
    F[:, 1:3] = rng.normal(0, 1.5, (n, 2))
    F[:, 3:9] = rng.normal(0, 0.01, (n, 6))
    P = log_parameters(np.full(n, 2.0), np.full(n, 0.2), np.full(n, 700.0), np.full(n, 0.3))
    D, lin = np.empty((n, 6)), np.empty((n, 5))
    rows = []
    for level in ("drag", "full"):
        opt = PhysicsOptions(level=level).vector()
        for want in (False, True):
            load0 = os.getloadavg()[0]
            ns = per_log(n, rhs_kernel.serial, S, F, P, opt, D, lin, want, repeat=repeat)
            rows.append(dict(code=label, level=level, linearisation=want, ns_per_log=ns,
                             load=f"{load0:.1f}-{os.getloadavg()[0]:.1f}"))
            print(rows[-1], flush=True)
    write_table("tracking_forces" + (f"_{label}" if label else ""), rows,
                ["code", "level", "linearisation", "ns_per_log", "load"],
                "One force evaluation (rhs_kernel, 1 thread, CPU ns per log, best of "
                f"{repeat})", "1e5 logs, random states and flow; no sampling. Re-create: "
                "`python benchmarks/tracking_benchmark.py --forces`.")
    return rows


def run(quick=False):
    mesh = malpasset_mesh()
    x0, y0, x1, y1 = mesh.bounds
    flow = on_mesh(FreeVortex(5e3, center=((x0 + x1) / 2, (y0 + y1) / 2), core_radius=300.0,
                              depth=5.0), mesh, times=[0.0, 1000.0])
    rng = np.random.default_rng(3)
    sizes = [1_000, 10_000, 100_000] if quick else [1_000, 10_000, 100_000, 1_000_000]
    combos = [(level, method) for level in ("tracer", "drag", "full")
              for method in ("euler", "rk4", "exponential")]
    # the general path beside the fused one, for full physics
    combos += [("full", "euler", False), ("full", "rk4", False), ("full", "exponential", False)]
    rows = []
    for n in sizes:
        x, y = points(mesh, n, rng)
        steps = max(5, min(200, int(2e6 / n)))
        for threads in (1, 2):
            numba.set_num_threads(threads)
            for level, method, *general in combos:
                fused = not general
                one(flow, x[:2048 + 1], y[:2048 + 1], level, method, 2, fused=fused)  # compile
                sub, wall, cpu, used = one(flow, x, y, level, method, steps, fused=fused)
                rows.append(dict(logs=n, threads=threads, level=level, integrator=method,
                                 path="fused" if used else "general", substeps=sub,
                                 seconds=wall, cpu_seconds=cpu,
                                 log_steps_per_s=n * sub / wall,
                                 per_core=n * sub / cpu))
                print(rows[-1])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking", rows, ["logs", "threads", "level", "integrator", "path",
                                   "substeps", "seconds", "cpu_seconds", "log_steps_per_s",
                                   "per_core"],
                "Tracking throughput (log-steps/s, all stages and flow sampling included)",
                "Flow: free vortex on the Malpasset mesh (46,691 triangles), P1 in space, linear "
                "in time. per_core: log-steps per CPU second of the process (all threads). "
                "Re-create: `python benchmarks/tracking_benchmark.py`.")
    breakdown(flow, *points(mesh, 100_000, np.random.default_rng(3)))


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="up to 1e5 logs")
    p.add_argument("--breakdown", action="store_true", help="only where an RK4 step goes")
    p.add_argument("--targets", action="store_true",
                   help="only the issue's 1e5-log targets on 1 thread (full RK4, tracer)")
    p.add_argument("--forces", action="store_true",
                   help="only the cost of one force evaluation (1 thread)")
    p.add_argument("--before-after", action="store_true",
                   help="the fused step with and without settling / tracer kernels (1 thread)")
    p.add_argument("--refcount", action="store_true",
                   help="the tracker's kernels with and without numba's reference counting")
    p.add_argument("--threads", action="store_true",
                   help="only 2 threads against 1 on 1e5 logs (full and tracer RK4)")
    p.add_argument("--drop-ab", action="store_true",
                   help="stopped logs dropped in place against gathered again (1 process)")
    p.add_argument("--holes-ab", action="store_true",
                   help="stopped logs left as holes against dropped at once (1 process)")
    p.add_argument("--label", default="", help="name of the code measured (--targets, --forces)")
    a = p.parse_args()
    if a.holes_ab:
        holes_ab()
    elif a.drop_ab:
        drop_ab()
    elif a.refcount:
        refcount()
    elif a.threads:
        thread_scaling()
    elif a.forces:
        forces(label=a.label)
    elif a.before_after:
        before_after()
    elif a.targets:
        targets(label=a.label)
    elif a.breakdown:
        m = malpasset_mesh()
        bx0, by0, bx1, by1 = m.bounds
        f = on_mesh(FreeVortex(5e3, center=((bx0 + bx1) / 2, (by0 + by1) / 2),
                               core_radius=300.0, depth=5.0), m, times=[0.0, 1000.0])
        breakdown(f, *points(m, 100_000, np.random.default_rng(3)))
    else:
        run(a.quick)
