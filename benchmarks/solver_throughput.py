"""Throughput of the shallow-water solver: cell-updates per second on unstructured triangles.

cell-updates/s = faces x time steps / seconds (a second-order step, two flux passes, counts
once), for meshes of about 1e4, 1e5 and 1e6 triangles, 1 and 2 numba threads, first and
second order (HLLC); 1 thread runs the serial kernels, 2 threads the prange ones.  The state
is a dam break over the whole square (every face wet, fluxes non-trivial, so the active set
is the whole mesh).  Wall and process (CPU) time are both reported: on a shared machine the
wall time also counts waiting for a core, and the 1-minute load average is recorded after each
measurement.

The solver's default internal numbering (reverse Cuthill-McKee, ``driftlog.solver.layout``)
is measured against the mesher's own (``none``) and a Hilbert curve on 1 thread
(``--orderings``); all give the same results bit for bit.

Then Malpasset's first ``--malpasset`` seconds (default 300 s) at first order, with and
without the active set (``benchmarks/malpasset.py``'s set-up): wall and CPU time, the mean
fraction of faces in the flux passes, and a check that both runs end in the same state.

    python benchmarks/solver_throughput.py            # 1e4, 1e5, 1e6 faces + Malpasset 300 s
    python benchmarks/solver_throughput.py --quick    # 1e4, 1e5 faces, Malpasset 60 s
    python benchmarks/solver_throughput.py --malpasset 0 --orderings rcm   # throughput only
    python benchmarks/solver_throughput.py --breakdown 1e6   # CPU time per kernel, 1 thread

``--breakdown`` times every kernel of a step (1 thread, serial kernels, best of ``--repeat``
runs of the steps) on a mesh of about the given size, orders 1 and 2, and writes
``solver_breakdown.md``: the CPU seconds per step of each kernel, in ns per face, and the
share of the step (``other``: the Python between the kernels, boundary volumes, the CFL max).
"""

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, machine, write_table  # noqa: E402

from driftlog.mesher import polygon_mesh, rectangle  # noqa: E402
from driftlog.solver import ShallowWaterSolver  # noqa: E402

ANUGA_DE0 = 4.7e6  # ANUGA's first-order DE0 per core on this kind of machine (issue 3)


def square_mesh(n_faces):
    """Quality triangles (min angle 30 degrees) filling a 1 km square, about n_faces of them."""
    # Triangle's 30-degree meshes come out about 1 face per 0.63 x (sqrt(3)/4) cell_size^2
    cell = np.sqrt(1e6 / (n_faces * np.sqrt(3) / 4 * 0.63))
    return polygon_mesh(rectangle(0, 0, 1000, 1000), cell)


def measure(mesh, order, threads, steps, ordering="rcm", repeat=1):
    """Time ``steps`` steps of the dam break (best CPU time of ``repeat`` runs); a row (dict)."""
    numba.set_num_threads(threads)
    t0 = time.perf_counter()
    s = ShallowWaterSolver(mesh, order=order, manning=0.03, parallel=threads > 1,
                           renumber=ordering)
    setup = time.perf_counter() - t0
    h0 = np.where(mesh.face_x < 500.0, 2.0, 1.0) + 0.1 * np.sin(mesh.face_y / 50.0)
    s.set_state(h0)
    s.step()  # compile / load the kernels
    wall = cpu = np.inf
    for _ in range(repeat):
        s.set_state(h0)
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(steps):
            s.step()
        w, c = time.perf_counter() - t0, time.process_time() - c0
        if c < cpu:
            wall, cpu = w, c
    n = mesh.n_faces * steps
    return dict(faces=mesh.n_faces, order=order, threads=threads, ordering=ordering,
                steps=steps, setup_s=setup, wall_s=wall, cpu_s=cpu, updates_per_s=n / wall,
                updates_per_cpu_s=n / cpu, per_core=n / wall / threads,
                load_after=os.getloadavg()[0])


# the solver's kernel attributes, in the order a step calls them
KERNELS = {"_k_mark": "active set", "_k_grad": "gradients + limiter", "_k_edges": "edge fluxes",
           "_k_faces": "face residuals", "_k_euler": "Euler stage",
           "_k_pred": "predictor (Euler + thin layer)",
           "_k_corr": "corrector (Euler + Heun + thin layer)"}


class _Timed:
    """A kernel wrapper that adds each call's time (``clock``: CPU time) to ``acc[name]``."""

    def __init__(self, fn, acc, name, clock=time.process_time):
        self.fn, self.acc, self.name, self.clock = fn, acc, name, clock

    def __call__(self, *args):
        c0 = self.clock()
        out = self.fn(*args)
        self.acc[self.name] += self.clock() - c0
        return out


def breakdown(mesh, order, steps, repeat, threads=0):
    """Seconds per step of each kernel, best of ``repeat``: CPU time of the serial kernels on
    1 thread (``threads`` 0), or wall time of the prange kernels on ``threads`` threads."""
    numba.set_num_threads(max(threads, 1))
    s = ShallowWaterSolver(mesh, order=order, manning=0.03, parallel=threads > 0)
    clock = time.perf_counter if threads else time.process_time
    h0 = np.where(mesh.face_x < 500.0, 2.0, 1.0) + 0.1 * np.sin(mesh.face_y / 50.0)
    names = list(KERNELS.values()) + ["extremes"]
    best = None
    for _ in range(repeat + 1):  # the first run compiles / loads the kernels
        s.set_state(h0)
        acc = dict.fromkeys(names, 0.0)
        for attr, name in KERNELS.items():
            k = getattr(s, attr)
            setattr(s, attr, _Timed(k.fn if isinstance(k, _Timed) else k, acc, name, clock))
        e = s.extremes._kernel
        s.extremes._kernel = _Timed(e.fn if isinstance(e, _Timed) else e, acc, "extremes", clock)
        c0 = clock()
        for _ in range(steps):
            s.step()
        acc["total"] = clock() - c0
        if best is None or acc["total"] < best["total"]:
            best = acc
    best["other"] = best["total"] - sum(best[n] for n in names)
    nf = mesh.n_faces
    rows = [dict(faces=nf, order=order, threads=threads, kernel=k, ms_per_step=1e3 * v / steps,
                 ns_per_face=1e9 * v / steps / nf, share=v / best["total"])
            for k, v in best.items() if k != "total" and (v > 0 or k == "other")]
    rows.append(dict(faces=nf, order=order, threads=threads, kernel="step",
                     ms_per_step=1e3 * best["total"] / steps,
                     ns_per_face=1e9 * best["total"] / steps / nf, share=1.0,
                     updates_per_cpu_s=nf * steps / best["total"], load_after=os.getloadavg()[0]))
    return rows


def malpasset_breakdown(end, repeat):
    """CPU seconds per step of each kernel on Malpasset's first ``end`` s (order 1) and
    ``end`` / 2 s (order 2): serial kernels, 1 thread, best of ``repeat`` by total CPU time.

    The active set is split into the whole mesh's marking (``mark_active``) and compaction
    (the face and edge lists, ``layout._compact``) and the block pass that replaces both
    while the set is small (``mark_blocks``); the faces of the flux passes are reported as a
    share of the mesh (the valley is mostly dry early in the flood).
    """
    from malpasset import data_dir

    import driftlog.solver.layout as layout
    import driftlog.solver.model as model
    from driftlog.floodsetup import malpasset_solver

    numba.set_num_threads(1)
    names = list(KERNELS.values()) + ["active set compaction", "active set (block pass)",
                                      "extremes"]
    compact, blocks, active_blocks = layout._compact, model.mark_blocks, model.active_blocks
    rows = []
    try:
        for order, stop in ((1, end), (2, 0.5 * end)):
            best = None
            for _ in range(repeat + 1):  # the first run compiles / loads the kernels
                s = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=order,
                                     parallel=False)
                acc = dict.fromkeys(names, 0.0)
                for attr, name in KERNELS.items():
                    setattr(s, attr, _Timed(getattr(s, attr), acc, name))
                s.extremes._kernel = _Timed(s.extremes._kernel, acc, "extremes")
                layout._compact = _Timed(compact, acc, "active set compaction")
                model.mark_blocks = _Timed(blocks, acc, "active set (block pass)")
                model.active_blocks = _Timed(active_blocks, acc, "active set (block pass)")
                c0 = time.process_time()
                s.advance_to(stop)
                acc["total"] = time.process_time() - c0
                acc["active"] = s.face_updates / (s.steps * order * s.mesh.n_faces)
                acc["steps"] = s.steps
                if best is None or acc["total"] < best["total"]:
                    best = acc
            n, active = best.pop("steps"), best.pop("active")
            best["other"] = best["total"] - sum(best[k] for k in names)
            rows += [dict(faces=s.mesh.n_faces, order=order, end_s=stop, steps=n,
                          active_fraction=active, kernel=k, ms_per_step=1e3 * v / n,
                          share=v / best["total"], load_after=os.getloadavg()[0])
                     for k, v in best.items() if v > 0 or k == "other"]
    finally:
        layout._compact = compact
        model.mark_blocks, model.active_blocks = blocks, active_blocks
    return rows


def malpasset(end):
    """Malpasset's first ``end`` s at first order, with and without the active set."""
    from malpasset import data_dir

    from driftlog.floodsetup import malpasset_solver

    rows, states = [], []
    for active in (True, False):
        s = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=1, active_set=active)
        h0 = s.h.copy()
        s.step(1e-3)  # compile / load the kernels outside the timed run
        s.set_state(h0)
        s.face_updates = 0
        t0, c0 = time.perf_counter(), time.process_time()
        s.advance_to(end)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        nf = s.mesh.n_faces
        rows.append(dict(case=f"Malpasset 0-{end:g} s, order 1", active_set=active,
                         faces=nf, steps=s.steps, wall_s=wall, cpu_s=cpu,
                         active_fraction=s.face_updates / (s.steps * nf),
                         updates_per_cpu_s=nf * s.steps / cpu,
                         volume_error_m3=s.volume_error(), load_after=os.getloadavg()[0]))
        states.append((s.h, s.hu, s.hv, s.extremes.arrays()))
        print(f"Malpasset {end:g} s, active set {active}: {s.steps} steps, {wall:.1f} s wall, "
              f"{cpu:.1f} s CPU, mean active fraction {rows[-1]['active_fraction']:.3f}",
              flush=True)
    (a, b) = states
    same = all(np.array_equal(x, y) for x, y in zip(a[:3], b[:3], strict=True)) and all(
        np.array_equal(a[3][k], b[3][k], equal_nan=True) for k in a[3])
    for r in rows:
        r["same_as_full_pass"] = bool(same)
    return rows


def untouched_zeros(n):
    """n float64 zeros on fresh anonymous pages, never written: what malloc hands out for a
    large ``np.zeros`` when it maps new memory (every page the kernel's shared zero page)."""
    import mmap

    return np.frombuffer(mmap.mmap(-1, 8 * n, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS),
                         dtype=np.float64)


def zero_pages(end, repeat):
    """The extremes' arrays on untouched zero pages against written memory (``written_zeros``).

    In one process, the arms alternated ``repeat`` times: the extremes kernel alone on
    Malpasset's start state (ms per call, serial), then Malpasset's first ``end`` s at order 1
    on one thread (CPU s), with ``max_depth`` and ``max_speed`` on untouched pages where they
    are zero (as ``np.zeros`` gave them before, when malloc mapped new memory) or written.
    """
    from malpasset import data_dir

    from driftlog.floodsetup import malpasset_solver
    from driftlog.solver.extremes import update_extremes

    numba.set_num_threads(1)
    arms = ("untouched zero pages", "written (written_zeros)")
    kern = {a: [] for a in arms}
    solve = {a: [] for a in arms}
    state = {}
    for _ in range(repeat):
        for arm in arms:
            s = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=1, parallel=False)
            e = s.extremes
            n = s.mesh.n_faces
            if arm == arms[0]:  # the same values, the zero entries' pages left untouched
                for name in ("max_depth", "max_speed"):
                    old, new = getattr(e, name), untouched_zeros(n)
                    nz = np.flatnonzero(old)
                    new[nz] = old[nz]
                    setattr(e, name, new)
            # the kernel alone on the start state (already folded in: nothing is written), on
            # every face
            args = (s._h, s._hu, s._hv, s._z, s.t, s.dry_depth, s.arrival_depth, e.max_level,
                    e.max_depth, e.max_speed, e.arrival, e._all)
            update_extremes.serial(*args)  # compile / load
            c0 = time.perf_counter()
            for _ in range(200):
                update_extremes.serial(*args)
            kern[arm].append((time.perf_counter() - c0) / 200)
            c0 = time.process_time()
            s.advance_to(end)
            solve[arm].append(time.process_time() - c0)
            state[arm] = (s.steps, s.h.copy(), s.extremes.arrays())
    (n0, h0, x0), (n1, h1, x1) = state[arms[0]], state[arms[1]]
    same = n0 == n1 and np.array_equal(h0, h1) and all(
        np.array_equal(x0[k], x1[k], equal_nan=True) for k in x0)
    rows = [dict(arm=a, faces=n, end_s=end, steps=state[a][0],
                 extremes_ms_per_call=1e3 * min(kern[a]),
                 extremes_ms_median=1e3 * float(np.median(kern[a])),
                 solve_cpu_s=min(solve[a]), solve_cpu_s_median=float(np.median(solve[a])),
                 same_results=bool(same), load_after=os.getloadavg()[0]) for a in arms]
    return rows


WAIT_POLICIES = {"passive": {"OMP_WAIT_POLICY": "PASSIVE"},
                 "spin": {"GOMP_SPINCOUNT": "30000"}}


def threads_worker(end, repeat):
    """In this process (its wait policy set by the caller): one thread against two.

    Malpasset's first ``end`` s at order 1 (1 thread on the serial kernels; 2 threads with
    the serial kernels below PARALLEL_ACTIVE active faces, the default, and with the prange
    kernels at every step, ``parallel=True``, as before the default changed) and the dam
    break on about 1e4 and 1e5 triangles, orders 1 and 2.  Best wall time of ``repeat``
    runs, the arms alternated; rows to stdout.
    """
    from malpasset import data_dir

    from driftlog.floodsetup import malpasset_solver

    # parallel: False (serial kernels), None (the default: parallel from PARALLEL_FACES
    # faces, serial steps while fewer than PARALLEL_ACTIVE are active -- 0 under spinning
    # workers, _numba.workers_spin, where this arm is the next one), True (always)
    arms = [("serial", 1, False), ("2 threads", 2, None),
            ("2 threads, every step parallel", 2, True)]
    best = {}
    for _ in range(repeat):
        for arm in arms:
            name, threads, parallel = arm
            numba.set_num_threads(threads)
            s = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=1, parallel=parallel)
            s.step(1e-4)  # compile / load the kernels
            t0, c0 = time.perf_counter(), time.process_time()
            s.advance_to(end)
            w, c = time.perf_counter() - t0, time.process_time() - c0
            if arm not in best or w < best[arm][0]:
                best[arm] = (w, c, s.steps, s.h.copy())
    rows = []
    w1, _, _, h1 = best[arms[0]]
    for arm in arms:
        w, c, n, h = best[arm]
        rows.append(dict(case=f"Malpasset 0-{end:g} s", order=1, kernels=arm[0],
                         threads=arm[1], steps=n, wall_s=w, cpu_s=c, speed_up=w1 / w,
                         same=bool(np.array_equal(h, h1))))
    for target, steps in ((1e4, 300), (1e5, 40)):
        mesh = square_mesh(int(target))
        for order in (1, 2):
            n = steps if order == 1 else steps // 2
            r = {t: measure(mesh, order, t, n, "rcm", repeat) for t in (1, 2)}
            for t in (1, 2):
                rows.append(dict(case=f"dam break, {mesh.n_faces} faces", order=order,
                                 kernels="serial" if t == 1 else "2 threads", threads=t,
                                 steps=n, wall_s=r[t]["wall_s"], cpu_s=r[t]["cpu_s"],
                                 speed_up=r[1]["wall_s"] / r[t]["wall_s"]))
    for r in rows:
        r["load_after"] = os.getloadavg()[0]
    print("ROWS " + json.dumps(rows), flush=True)


def threads_wait(end, repeat, busy):
    """``threads_worker`` in a fresh process per libgomp wait policy (set before it loads),
    with ``busy`` busy-looping processes beside it (another job taking cores)."""
    import subprocess

    start = machine()
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(busy)]
    rows = []
    try:
        for policy, env in WAIT_POLICIES.items():
            e = {k: v for k, v in os.environ.items()
                 if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
            e.update(env)
            out = subprocess.run([sys.executable, __file__, "--threads-worker", str(end),
                                  "--repeat", str(repeat)], env=e, capture_output=True,
                                 text=True, check=True).stdout
            got = json.loads(out.split("ROWS ", 1)[1])
            for r in got:
                r["policy"] = policy
                r["busy_processes"] = busy
                print(f"{policy:>8} {r['case']:>26} order {r['order']} {r['kernels']:>31}: "
                      f"{r['wall_s']:.3f} s wall, {r['cpu_s']:.3f} s CPU, x{r['speed_up']:.2f}",
                      flush=True)
            rows += got
    finally:
        for h in hogs:
            h.kill()
    name = f"solver_threads_wait_{end:g}s" + (f"_busy{busy}" if busy else "")
    write_table(name, rows, ["policy", "busy_processes", "case", "order", "kernels", "threads",
                             "steps", "wall_s", "cpu_s", "speed_up", "same", "load_after"],
                "Shallow-water solver, two threads against one, by libgomp's wait policy",
                notes=f"Started on {start}. Each policy in its own process, set before "
                      "libgomp loads: passive (OMP_WAIT_POLICY=PASSIVE, driftlog's default: an "
                      "idle worker sleeps at once) or spin (GOMP_SPINCOUNT=30000: it spins "
                      "about 1 ms first). speed_up: wall time of the serial run / this one "
                      f"(best of {repeat}, arms alternated); same: the final depths equal bit "
                      "for bit to the serial run's. busy_processes: busy-looping processes "
                      "run beside it. Re-create: `python benchmarks/solver_throughput.py "
                      f"--threads-wait {end:g} --repeat {repeat}"
                      + (f" --busy {busy}`." if busy else "`."))
    (RESULTS / f"{name}.json").write_text(json.dumps(dict(machine=start, rows=rows), indent=1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1e4 and 1e5 faces only")
    ap.add_argument("--orderings", default="rcm,none,hilbert",
                    help="internal numberings to compare on 1 thread at order 1 (the first "
                         "one is used for everything else); default rcm,none,hilbert")
    ap.add_argument("--malpasset", type=float, default=None,
                    help="Malpasset's first seconds, with and without the active set "
                         "(default 300, --quick 60; 0: skip)")
    ap.add_argument("--breakdown", type=float, default=None, metavar="FACES",
                    help="only the CPU time per kernel of a step on a mesh of about FACES "
                         "triangles, orders 1 and 2, 1 thread")
    ap.add_argument("--breakdown-malpasset", type=float, default=None, metavar="END",
                    help="only the CPU time per kernel of a step on Malpasset's first END s "
                         "(order 2: END / 2), 1 thread")
    ap.add_argument("--repeat", type=int, default=3,
                    help="best of N runs of the steps (by CPU time; default 3)")
    ap.add_argument("--threads-wait", type=float, default=None, metavar="END",
                    help="only two threads against one by libgomp's wait policy (passive, "
                         "spin), each in its own process: Malpasset's first END s at order 1 "
                         "and the dam break on 1e4 and 1e5 triangles")
    ap.add_argument("--busy", type=int, default=0,
                    help="with --threads-wait: this many busy-looping processes beside it")
    ap.add_argument("--threads-worker", type=float, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--zero-pages", type=float, default=None, metavar="END",
                    help="only the extremes' arrays on untouched zero pages against written "
                         "memory: the kernel alone and Malpasset's first END s, order 1")
    ap.add_argument("--breakdown-threads", action="store_true",
                    help="with --breakdown: order 1 only, the serial kernels (CPU time) beside "
                         "the prange kernels on 1 and 2 threads (wall time), kernel by kernel")
    args = ap.parse_args(argv)
    if args.breakdown and args.breakdown_threads:
        start = machine()
        mesh = square_mesh(int(args.breakdown))
        steps = max(2, int(4e6 / mesh.n_faces))
        rows = [r for t in (0, 1, 2) for r in breakdown(mesh, 1, steps, args.repeat, t)]
        for r in rows:
            print(f"{r['faces']:>8} faces threads {r['threads']} {r['kernel']:>20}: "
                  f"{r['ms_per_step']:8.3f} ms/step", flush=True)
        write_table(f"solver_breakdown_threads_{mesh.n_faces // 1000}k", rows,
                    ["faces", "order", "threads", "kernel", "ms_per_step", "ns_per_face",
                     "share", "load_after"],
                    "Shallow-water solver: time per kernel of a first-order step, serial "
                    "kernels and prange kernels on 1 and 2 threads",
                    notes=f"Started on {start}. threads 0: the serial kernels, CPU time; 1, 2: "
                          "the prange kernels on that many numba threads, wall time (workers "
                          "waiting as set in the environment, driftlog's default passive). Best "
                          f"of {args.repeat} runs of the steps. Re-create: `python "
                          "benchmarks/solver_throughput.py --breakdown "
                          f"{args.breakdown:g} --breakdown-threads --repeat {args.repeat}`.")
        return
    if args.zero_pages:
        start = machine()
        rows = zero_pages(args.zero_pages, args.repeat)
        write_table(f"solver_zero_pages_{args.zero_pages:g}s", rows,
                    ["arm", "faces", "end_s", "steps", "extremes_ms_per_call",
                     "extremes_ms_median", "solve_cpu_s", "solve_cpu_s_median",
                     "same_results", "load_after"],
                    "Shallow-water solver: the extremes' arrays on untouched zero pages "
                    "against written memory (Malpasset, order 1, 1 thread)",
                    notes=f"Started on {start}. One process, the two arms alternated "
                          f"{args.repeat} times: extremes_ms: the extremes kernel (serial) "
                          "alone on the start state, 200 calls, best and median of the "
                          "repetitions; solve_cpu_s: the first "
                          f"{args.zero_pages:g} s of the flood, best and median. "
                          "same_results: steps, depths and extremes identical. Re-create: "
                          "`python benchmarks/solver_throughput.py --zero-pages "
                          f"{args.zero_pages:g} --repeat {args.repeat}`.")
        return
    if args.threads_worker is not None:
        threads_worker(args.threads_worker, args.repeat)
        return
    if args.threads_wait is not None:
        threads_wait(args.threads_wait, args.repeat, args.busy)
        return
    if args.breakdown_malpasset:
        start = machine()
        rows = malpasset_breakdown(args.breakdown_malpasset, args.repeat)
        for r in rows:
            print(f"order {r['order']} {r['kernel']:>38}: {r['ms_per_step']:7.3f} ms/step "
                  f"{100 * r['share']:5.1f} %", flush=True)
        write_table("solver_breakdown_malpasset", rows,
                    ["faces", "order", "end_s", "steps", "active_fraction", "kernel",
                     "ms_per_step", "share", "load_after"],
                    "Shallow-water solver on Malpasset: CPU time per kernel of a step (1 "
                    "thread, serial kernels)",
                    notes=f"Started on {start}. Best of {args.repeat} runs by total CPU time, "
                          "each kernel call timed in CPU time within the run; "
                          "active_fraction: the faces of the flux passes as a share of the "
                          "mesh (mean); total: the whole step; other: the Python between the "
                          "kernels (boundary volumes, the CFL max, the volume balance). "
                          "Re-create: `python benchmarks/solver_throughput.py "
                          f"--breakdown-malpasset {args.breakdown_malpasset:g}`.")
        return
    if args.breakdown:
        start = machine()
        mesh = square_mesh(int(args.breakdown))
        steps = max(2, int(4e6 / mesh.n_faces))
        rows = breakdown(mesh, 1, steps, args.repeat) + breakdown(mesh, 2, max(steps // 2, 1),
                                                                   args.repeat)
        for r in rows:
            print(f"{r['faces']:>8} faces order {r['order']} {r['kernel']:>20}: "
                  f"{r['ms_per_step']:8.2f} ms/step {r['ns_per_face']:7.1f} ns/face "
                  f"{100 * r['share']:5.1f} %", flush=True)
        write_table(f"solver_breakdown_{mesh.n_faces // 1000}k", rows,
                    ["faces", "order", "kernel", "ms_per_step", "ns_per_face", "share",
                     "updates_per_cpu_s", "load_after"],
                    "Shallow-water solver: CPU time per kernel of a step (1 thread, serial "
                    "kernels, triangles, HLLC)",
                    notes=f"Started on {start}. Best of {args.repeat} runs of the steps, CPU "
                          "(process) time of each kernel call; an order-2 step runs the "
                          "gradients, fluxes and residuals twice (Heun); other: the Python "
                          "between the kernels (boundary volumes, the CFL max).")
        return
    orderings = args.orderings.split(",")
    sizes = [(1e4, 300), (1e5, 40)] + ([] if args.quick else [(1e6, 8)])
    rows = []
    start = machine()
    for target, steps in sizes:
        t0 = time.perf_counter()
        mesh = square_mesh(int(target))
        print(f"mesh of {mesh.n_faces} faces in {time.perf_counter() - t0:.1f} s", flush=True)
        runs = [(1, 1, o) for o in orderings] + [(1, 2, orderings[0]), (2, 1, orderings[0]),
                                                 (2, 2, orderings[0])]
        for order, threads, ordering in runs:
            if threads > numba.config.NUMBA_NUM_THREADS:
                continue
            r = measure(mesh, order, threads, steps if order == 1 else max(steps // 2, 2),
                        ordering, args.repeat)
            rows.append(r)
            print(f"{r['faces']:>8} faces order {order} threads {threads} {ordering:>7}: "
                  f"{r['updates_per_s']:.3g} cell-updates/s wall, "
                  f"{r['updates_per_cpu_s']:.3g} per CPU second (load {r['load_after']:.1f})",
                  flush=True)
    name = "solver_throughput" + ("_quick" if args.quick else "")
    write_table(name, rows, ["faces", "order", "threads", "ordering", "steps", "setup_s",
                             "wall_s", "cpu_s", "updates_per_s", "updates_per_cpu_s",
                             "per_core", "load_after"],
                "Shallow-water solver throughput (cell-updates/s, triangles, HLLC)",
                notes=f"Started on {start}. ANUGA DE0 (first order) does about "
                      f"{ANUGA_DE0:.2g} per core on this kind of machine; the goal is 1e7 per "
                      "core at first order. ordering: the solver's internal numbering (rcm: "
                      "reverse Cuthill-McKee, the default from 20,000 faces; none: the "
                      "mesher's). setup_s: building the solver (renumbering included). "
                      "load_after: the 1-minute load average after each measurement (2 "
                      "cores; above 2, other processes shared the cores). Best of "
                      f"{args.repeat} runs of the steps by CPU time (wall of that run).")
    out = dict(machine=start, rows=rows)
    end = args.malpasset if args.malpasset is not None else (60.0 if args.quick else 300.0)
    if end > 0:
        numba.set_num_threads(1)
        mrows = malpasset(end)
        write_table(name + "_malpasset", mrows,
                    ["case", "active_set", "faces", "steps", "wall_s", "cpu_s",
                     "active_fraction", "updates_per_cpu_s", "volume_error_m3",
                     "same_as_full_pass", "load_after"],
                    "Malpasset, first order, 1 thread: with and without the active set",
                    notes="active_fraction: faces in the flux passes over all faces, averaged "
                          "over the steps; updates_per_cpu_s counts every face of every step "
                          "(the work the full pass would do); same_as_full_pass: h, hu, hv "
                          "and the extremes identical bit for bit.")
        out["malpasset"] = mrows
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
