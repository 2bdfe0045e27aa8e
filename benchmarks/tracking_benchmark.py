"""Tracking throughput: log-steps per second (issue 4).

A log-step is one integrator step of one log: all its stages, the flow sampled at each stage,
and the tracker's bookkeeping (statuses, step control).  Flow: a free vortex sampled on the
Malpasset mesh (46,691 triangles, two snapshots: a real unstructured mesh, interpolated in
space and time).  Logs: n = 1e3 ... 1e6, L = 2 m, r = 0.2 m, rho_b = 700 kg/m3, spread over the
valley.  Each physics level (tracer, drag, full) and integrator (euler, rk4, exponential), on 1
and 2 threads.

    python benchmarks/tracking_benchmark.py [--quick]

writes benchmarks/results/tracking.csv and .md, and tracking_breakdown.csv and .md (where
an RK4 log-step's time goes).
"""

import argparse
import time

import numba
import numpy as np
from _common import malpasset_mesh, write_table
from sampling_benchmark import points

from driftlog.analytic import FreeVortex, on_mesh
from driftlog.logs import Logs
from driftlog.physics import PhysicsOptions, rhs_kernel
from driftlog.tracker import StepOptions, Tracker


def one(flow, x, y, level, method, steps, dt=0.5):
    logs = Logs(x, y, 0.3, 2.0, 0.2, 700.0)
    tr = Tracker(flow, logs, PhysicsOptions(level=level), method,
                 StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9),
                 t_end=steps * dt, output_interval=steps * dt, hydro_step=steps * dt)
    tr._first_check = True
    tr._release()  # set-up (release, first sampling) is not timed
    tr._update_status()
    t0 = time.perf_counter()
    tr.run()
    wall = time.perf_counter() - t0
    return tr.stats["substeps"], wall, int((logs.status == 1).sum())


def per_log(n, fn, *args, repeat=5):
    """Best time of fn(*args) per log (ns)."""
    fn(*args)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(*args)
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e9


def breakdown(flow, x, y, steps=20, dt=0.5):
    """Where an RK4 log-step goes, per log on one thread: flow sampling, forces, the rest.

    An RK4 step samples the flow 4 times (the step's end, which is the next step's first
    stage, and 3 inner stages) and evaluates the forces 4 times (the first with the drag
    linearisation the step bound needs); the rest is the stage arithmetic, copies and the
    tracker's status bookkeeping.
    """
    numba.set_num_threads(1)
    n = x.size
    rows = []
    for level in ("tracer", "drag", "full"):
        logs = Logs(x, y, 0.3, 2.0, 0.2, 700.0)
        tr = Tracker(flow, logs, PhysicsOptions(level=level), "rk4",
                     StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9),
                     t_end=steps * dt, output_interval=steps * dt, hydro_step=steps * dt)
        t0 = time.perf_counter()
        tr.run()
        total = (time.perf_counter() - t0) / (n * tr.stats["substeps"]) * 1e9
        S, F, D = tr.state.copy(), tr.F.copy(), np.empty_like(tr.state)
        lin = np.empty((S.shape[0], tr.lin0.shape[1]))
        face, out, flag = tr.face.copy(), np.empty_like(F), np.empty(S.shape[0], np.int8)
        sx, sy = S[:, 0].copy(), S[:, 1].copy()
        t_s = steps * dt * 0.5
        sample = per_log(n, flow.sample_into, sx, sy, t_s, face, out, flag)
        rhs_lin = per_log(n, rhs_kernel, S, F, tr.P, tr.opt, D, lin, True)
        rhs = per_log(n, rhs_kernel, S, F, tr.P, tr.opt, D, lin, False)
        rest = total - 4 * sample - rhs_lin - 3 * rhs
        rows.append(dict(level=level, logs=n, sample_ns=sample, forces_lin_ns=rhs_lin,
                         forces_ns=rhs, rest_ns=rest, log_step_ns=total,
                         log_steps_per_s=1e9 / total))
        print(rows[-1])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("tracking_breakdown", rows, ["level", "logs", "sample_ns", "forces_lin_ns",
                                             "forces_ns", "rest_ns", "log_step_ns",
                                             "log_steps_per_s"],
                "Where an RK4 log-step goes (1 thread, ns per log)",
                "log_step = 4 sample + forces_lin + 3 forces + rest (stage arithmetic, copies, "
                "status bookkeeping); the same flow and logs as the throughput table.")


def run(quick=False):
    mesh = malpasset_mesh()
    x0, y0, x1, y1 = mesh.bounds
    flow = on_mesh(FreeVortex(5e3, center=((x0 + x1) / 2, (y0 + y1) / 2), core_radius=300.0,
                              depth=5.0), mesh, times=[0.0, 1000.0])
    rng = np.random.default_rng(3)
    sizes = [1_000, 10_000, 100_000] if quick else [1_000, 10_000, 100_000, 1_000_000]
    combos = [(level, method) for level in ("tracer", "drag", "full")
              for method in ("euler", "rk4", "exponential")]
    rows = []
    for n in sizes:
        x, y = points(mesh, n, rng)
        steps = max(5, min(200, int(2e6 / n)))
        for threads in (1, 2):
            numba.set_num_threads(threads)
            for level, method in combos:
                one(flow, x[:2048 + 1], y[:2048 + 1], level, method, 2)  # compile both variants
                sub, wall, floating = one(flow, x, y, level, method, steps)
                rate = n * sub / wall
                rows.append(dict(logs=n, threads=threads, level=level, integrator=method,
                                 substeps=sub, seconds=wall, log_steps_per_s=rate,
                                 per_core=rate / threads))
                print(rows[-1])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    breakdown(flow, *points(mesh, 100_000, np.random.default_rng(3)))
    write_table("tracking", rows, ["logs", "threads", "level", "integrator", "substeps",
                                   "seconds", "log_steps_per_s", "per_core"],
                "Tracking throughput (log-steps/s, all stages and flow sampling included)",
                "Flow: free vortex on the Malpasset mesh (46,691 triangles), P1 in space, linear "
                "in time. Re-create: `python benchmarks/tracking_benchmark.py`.")


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="up to 1e5 logs")
    run(p.parse_args().quick)
