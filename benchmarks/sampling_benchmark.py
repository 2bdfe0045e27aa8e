"""Point location and flow sampling throughput (issue 2).

Samples per second for 1e5 and 1e6 points on the Malpasset mesh (46,691 triangles) and on a
1e6-triangle mesh, cold (no hint: bin-grid look-up) and warm (hint = the previous face, points
moved by 0.3 of a cell), on 1 and 2 threads.  "locate" is point location alone; "sample" is
location plus the full sample (depth, velocity, dU/dt, velocity gradient, surface gradient).

    python benchmarks/sampling_benchmark.py [--quick]

writes benchmarks/results/sampling.csv and .md.
"""

import argparse
import time

import numba
import numpy as np
from _common import best_time, malpasset_mesh, write_table

from driftlog.analytic import FreeVortex, on_mesh
from driftlog.flow import NVAR, sample_mesh_kernel
from driftlog.locate import locate_points
from driftlog.mesher import polygon_mesh, rectangle


def big_mesh(n_faces):
    # equilateral-ish triangles: area sqrt(3)/4 s^2, about 1.0 n_faces of them in a square
    side = 1000.0
    s = np.sqrt(side * side / (n_faces * np.sqrt(3) / 4)) * 1.0
    return polygon_mesh(rectangle(0, 0, side, side), s, min_angle=25)


def points(mesh, n, rng):
    f = rng.integers(0, mesh.n_faces, n)
    # random points inside the chosen faces (barycentric on the first triangle of the fan)
    fn = mesh.face_nodes[f]
    a, b = rng.random(n), rng.random(n)
    swap = a + b > 1
    a[swap], b[swap] = 1 - a[swap], 1 - b[swap]
    x = mesh.node_x[fn[:, 0]] * (1 - a - b) + mesh.node_x[fn[:, 1]] * a + mesh.node_x[fn[:, 2]] * b
    y = mesh.node_y[fn[:, 0]] * (1 - a - b) + mesh.node_y[fn[:, 1]] * a + mesh.node_y[fn[:, 2]] * b
    order = np.argsort(f, kind="stable")  # logs released along a line are near each other
    return x[order], y[order]


def run(quick=False):
    rng = np.random.default_rng(1)
    meshes = {"Malpasset (46,691 tri)": malpasset_mesh()}
    if not quick:
        t0 = time.perf_counter()
        m = big_mesh(1_000_000)
        meshes[f"square ({m.n_faces:,} tri)"] = m
        print(f"1e6-face mesh built in {time.perf_counter() - t0:.1f} s")
    sizes = [100_000] if quick else [100_000, 1_000_000]
    rows = []
    for name, mesh in meshes.items():
        x0, y0, x1, y1 = mesh.bounds
        field = on_mesh(FreeVortex(2e4, center=((x0 + x1) / 2, (y0 + y1) / 2), core_radius=200.0),
                        mesh, times=[0.0, 10.0])
        vals, a, inv_dt = field.node_values(5.0)
        locator = mesh.locator()
        for n in sizes:
            x, y = points(mesh, n, rng)
            hint0 = mesh.locate(x, y)
            step = 0.3 * np.median(mesh.face_inradius)
            xw, yw = x + rng.normal(0, step, n), y + rng.normal(0, step, n)
            out = np.empty((n, NVAR))
            flag = np.empty(n, np.int8)
            for threads in (1, 2):
                numba.set_num_threads(threads)
                for mode in ("cold", "warm"):
                    px, py = (x, y) if mode == "cold" else (xw, yw)
                    face = np.empty(n, np.int64)

                    start = -1 if mode == "cold" else hint0

                    def loc(px=px, py=py, face=face, start=start, locator=locator):
                        face[:] = start
                        locate_points.parallel(px, py, face, locator)

                    def samp(px=px, py=py, face=face, start=start, locator=locator, out=out,
                             flag=flag, vals=vals, a=a, inv_dt=inv_dt):
                        face[:] = start
                        sample_mesh_kernel.parallel(px, py, face, out, flag, a, inv_dt, vals,
                                                    1e-3, True, locator)

                    loc()
                    samp()  # compile
                    tl = best_time(loc)
                    ts = best_time(samp)
                    rows.append(dict(mesh=name, points=n, threads=threads, mode=mode,
                                     locate_per_s=n / tl, sample_per_s=n / ts,
                                     sample_per_s_per_core=n / ts / threads))
                    print(rows[-1])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("sampling", rows, ["mesh", "points", "threads", "mode", "locate_per_s",
                                   "sample_per_s", "sample_per_s_per_core"],
                "Point location and flow sampling throughput (samples/s)",
                "warm: hint = previous face, points moved by 0.3 of a cell inradius (normal "
                "noise); cold: no hint. Points sorted by face (as logs released together are). "
                "Re-create: `python benchmarks/sampling_benchmark.py`.")


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="Malpasset and 1e5 points only")
    run(p.parse_args().quick)
