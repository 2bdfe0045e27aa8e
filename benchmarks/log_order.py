"""Logs tracked in the order they were seeded against along a space-filling curve (issue 15).

``driftlog.api.track`` lists the logs of a run without contacts or coupling along a Hilbert
curve through their start positions (``driftlog.logs.spatial_order``), so that consecutive
logs read the same mesh rows from the caches; the trajectory file stays in the scenario's
order.  This runs the same scenario both ways, alternately in one process on one numba
thread, best CPU time of ``--repeat`` of the tracker's run inside each ``track`` call (the
release and the records included), and checks that the two trajectory files are identical
variable by variable:

- ``mesh``: ``--logs`` points drawn at random over the whole Malpasset mesh (46,691
  triangles), listed in the order drawn (``seeding = "list"``);
- ``valley``: ``seeding = "random"`` in the valley polygon of ``million_logs.py`` (a
  scenario's own random seeding).

The flow is the tracking benchmark's free vortex on the Malpasset mesh (two snapshots); the
logs take 40 sub-steps of 0.5 s (20 s, records at 0 and 20 s), tracer RK4 and full-physics
RK4 (rotation on).  Writes benchmarks/results/log_order{.md,.csv}.

    python benchmarks/log_order.py                  # 1e5 logs
    python benchmarks/log_order.py --logs 1000000 --repeat 2
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402
import numpy as np  # noqa: E402
from _common import malpasset_mesh, write_table  # noqa: E402
from million_logs import valley_polygon  # noqa: E402
from tracking_benchmark import vortex_flow  # noqa: E402

STEPS = 40  # sub-steps of 0.5 s, a record at the start and one at the end


def scattered(mesh, n, rng):
    """n points at random in random faces of ``mesh``, in the order drawn (not sorted)."""
    f = rng.integers(0, mesh.n_faces, n)
    fn = mesh.face_nodes[f, :3]
    a, b = rng.random(n), rng.random(n)
    swap = a + b > 1
    a[swap], b[swap] = 1 - a[swap], 1 - b[swap]
    w = np.stack([1 - a - b, a, b], 1)
    return (mesh.node_x[fn] * w).sum(1), (mesh.node_y[fn] * w).sum(1)


def scenario(seeding, level, out):
    return {
        "flow": {"source": "analytic", "kind": "uniform"},
        "time": {"start": 0.0, "end": STEPS * 0.5, "output_interval": STEPS * 0.5},
        "integrator": {"method": "rk4", "max_step": 0.5, "length_fraction": 1e9,
                       "angle_step": 1e9},
        "physics": {"level": level, "rotation": "on" if level == "full" else "off"},
        "logs": [dict(seeding, length=2.0, radius=0.2, density=700.0, theta=0.3)],
        "output": {"path": str(out), "flush_interval": 10},
    }


def files_equal(a, b):
    import netCDF4

    with netCDF4.Dataset(a) as da, netCDF4.Dataset(b) as db:
        da.set_auto_maskandscale(False)
        db.set_auto_maskandscale(False)
        if set(da.variables) != set(db.variables):
            return False
        return all(np.array_equal(da[k][:], db[k][:]) for k in da.variables)


def main(n=100_000, repeat=3):
    import driftlog.api as api
    from driftlog.logs import spatial_order
    from driftlog.tracker import Tracker

    run, spent = Tracker.run, []

    def timed_run(self):  # the tracker's own run: what the order changes
        c0 = time.process_time()
        out = run(self)
        spent.append(time.process_time() - c0)
        return out

    curve = api.spatial_order
    numba.set_num_threads(1)
    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    x, y = scattered(mesh, n, np.random.default_rng(7))
    placements = {
        "mesh (list, drawn order)": {"seeding": "list", "x": x.tolist(), "y": y.tolist()},
        "valley (seeding random)": {"seeding": "random", "polygon": valley_polygon(mesh),
                                    "count": n, "seed": 1},
    }
    t0 = time.process_time()
    spatial_order(x, y)
    order_cpu = time.process_time() - t0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for place, seeding in placements.items():
            for level in ("tracer", "full"):
                best, paths = {}, {}
                small = dict(seeding, **({"x": x[:2000].tolist(), "y": y[:2000].tolist()}
                                         if seeding["seeding"] == "list" else {"count": 2000}))
                api.track(scenario(small, level, tmp / "warm.nc"), flow=flow)  # compile
                for _ in range(repeat):
                    for arm in ("as seeded", "along a Hilbert curve"):
                        api.spatial_order = (curve if arm != "as seeded"
                                             else (lambda a, b: np.arange(len(a))))
                        out = tmp / f"{arm[:2]}.nc"
                        c0 = time.process_time()
                        Tracker.run = timed_run
                        try:
                            api.track(scenario(seeding, level, out), flow=flow)
                        finally:
                            Tracker.run = run
                        cpu = time.process_time() - c0
                        print(f"  {place}, {level}, {arm}: run {spent[-1]:.3f} CPU s", flush=True)
                        if spent[-1] < best.get(arm, (np.inf,))[0]:
                            best[arm] = (spent[-1], cpu)
                        paths[arm] = out
                api.spatial_order = curve
                same = files_equal(*paths.values())
                for arm, (cpu, whole) in best.items():
                    rows.append(dict(placement=place, logs=n, level=level, order=arm,
                                     run_cpu_s=cpu, log_steps_per_cpu_s=n * STEPS / cpu,
                                     gain=best["as seeded"][0] / cpu, track_cpu_s=whole,
                                     same_file=same))
                    print(rows[-1], flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    write_table("log_order" + ("" if n == 100_000 else f"_{n}"), rows,
                ["placement", "logs", "level", "order", "run_cpu_s", "log_steps_per_cpu_s",
                 "gain", "track_cpu_s", "same_file"],
                f"Logs tracked as seeded and along a Hilbert curve (1 thread, best of {repeat}, "
                "alternately in one process)",
                "run_cpu_s: CPU s of `Tracker.run` (release, 40 RK4 sub-steps of 0.5 s, two "
                "records) inside `driftlog.api.track` on the free vortex over the Malpasset "
                "mesh, the best run of each arm (log_steps_per_cpu_s: 40 sub-steps of every log "
                "over it); track_cpu_s: the whole `track` call of that run (with the scenario's "
                "checks and the set-up, which the order does not change); same_file: the two "
                "trajectory files equal variable by variable.  The order itself took "
                f"{order_cpu:.3f} CPU s for the {n} points.  "
                "Re-create: `python benchmarks/log_order.py` (`--logs 1000000`).")
    return rows


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--logs", type=int, default=100_000)
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args()
    main(a.logs, a.repeat)
