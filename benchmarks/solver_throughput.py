"""Throughput of the shallow-water solver: cell-updates per second on unstructured triangles.

cell-updates/s = faces x time steps / seconds (a second-order step, two flux passes, counts
once), for meshes of about 1e4, 1e5 and 1e6 triangles, 1 and 2 numba threads, first and
second order (HLLC); 1 thread runs the serial kernels, 2 threads the prange ones.  The state
is a dam break over the whole square (every face wet, fluxes non-trivial).  Wall and process
(CPU) time are both reported: on a shared machine the wall time also counts waiting for a core.

    python benchmarks/solver_throughput.py            # 1e4, 1e5, 1e6 faces
    python benchmarks/solver_throughput.py --quick    # 1e4, 1e5 faces
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

from _common import RESULTS, machine, write_table  # noqa: E402

from driftlog.mesher import polygon_mesh, rectangle  # noqa: E402
from driftlog.solver import ShallowWaterSolver  # noqa: E402

ANUGA_DE0 = 4.7e6  # ANUGA's first-order DE0 per core on this kind of machine (issue 3)


def square_mesh(n_faces):
    """Quality triangles (min angle 30 degrees) filling a 1 km square, about n_faces of them."""
    # Triangle's 30-degree meshes come out about 1 face per 0.63 x (sqrt(3)/4) cell_size^2
    cell = np.sqrt(1e6 / (n_faces * np.sqrt(3) / 4 * 0.63))
    return polygon_mesh(rectangle(0, 0, 1000, 1000), cell)


def measure(mesh, order, threads, steps):
    numba.set_num_threads(threads)
    s = ShallowWaterSolver(mesh, order=order, manning=0.03, parallel=threads > 1)
    s.set_state(np.where(mesh.face_x < 500.0, 2.0, 1.0) + 0.1 * np.sin(mesh.face_y / 50.0))
    s.step()  # compile / load the kernels
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        s.step()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    n = mesh.n_faces * steps
    return dict(faces=mesh.n_faces, order=order, threads=threads, steps=steps, wall_s=wall,
                cpu_s=cpu, updates_per_s=n / wall, updates_per_cpu_s=n / cpu,
                per_core=n / wall / threads)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1e4 and 1e5 faces only")
    args = ap.parse_args(argv)
    sizes = [(1e4, 200), (1e5, 30)] + ([] if args.quick else [(1e6, 4)])
    rows = []
    start = machine()
    for target, steps in sizes:
        t0 = time.perf_counter()
        mesh = square_mesh(int(target))
        print(f"mesh of {mesh.n_faces} faces in {time.perf_counter() - t0:.1f} s", flush=True)
        for order in (1, 2):
            for threads in (1, 2):
                if threads > numba.config.NUMBA_NUM_THREADS:
                    continue
                r = measure(mesh, order, threads, steps if order == 1 else max(steps // 2, 2))
                r["load_after"] = os.getloadavg()[0]
                rows.append(r)
                print(f"{r['faces']:>8} faces order {order} threads {threads}: "
                      f"{r['updates_per_s']:.3g} cell-updates/s wall, "
                      f"{r['updates_per_cpu_s']:.3g} per CPU second (load {r['load_after']:.1f})",
                      flush=True)
    name = "solver_throughput" + ("_quick" if args.quick else "")
    write_table(name, rows, ["faces", "order", "threads", "steps", "wall_s", "cpu_s",
                             "updates_per_s", "updates_per_cpu_s", "per_core", "load_after"],
                "Shallow-water solver throughput (cell-updates/s, triangles, HLLC)",
                notes=f"Started on {start}. ANUGA DE0 (first order) does about "
                      f"{ANUGA_DE0:.2g} per core on this kind of machine; the goal is 1e7 per "
                      "core at first order. load_after: the 1-minute load average after each "
                      "measurement (2 cores; above 2, other processes shared the cores).")
    (RESULTS / f"{name}.json").write_text(json.dumps(dict(machine=start, rows=rows), indent=1))


if __name__ == "__main__":
    main()
