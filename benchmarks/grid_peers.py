"""Regular-grid sampling: driftlog's bilinear grid field beside Parcels on one CF file (issue 12).

The drifting Gaussian eddy of ``peers_tracking.py`` (exact trajectories known) written as a CF
grid of cell-centred values (snapshots every ``SNAPSHOT`` s) with cells of 40, 20 and 10 m.
On each file, the same particles are advected with classical RK4 at the same fixed step over
the same time by

- driftlog, ``adapters.cfgrid.open_cf_grid``: the ``GridFlowField`` (bilinear between the cell
  centres, linear in time; ``driftlog.gridflow``), tracer physics;
- driftlog, the same file on the triangulated mesh path it used before (``MeshFlowField`` on
  the grid's quadrilaterals: P1 on least-squares node values), for reference;
- Parcels v4 (A grid, bilinear, linear in time, float64 positions; ``peers_tracking``'s field
  set).

Measured: each tool's maximum and mean distance to the exact positions after ``DURATION`` s,
the distance between driftlog and Parcels, and the run's CPU time (process time, set-up apart).

    python benchmarks/grid_peers.py [--quick]

writes benchmarks/results/grid_peers.{json,md} (grid_peers_quick.* with --quick).
"""

from __future__ import annotations

import argparse
import json
import logging
import tempfile
import time
from pathlib import Path

import numba as nb
import numpy as np
import peers_tracking as pt
from _common import RESULTS, machine

from driftlog.columns import X, Y
from driftlog.flow import MeshFlowField
from driftlog.logs import Logs
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

DT = 5.0


def _mesh_path(field):
    """The grid's data on the triangulated mesh path (the cf_grid reader before issue 12)."""
    return MeshFlowField(field.mesh, field.bed, field.source, field.dry_depth, name=field.name)


def run_driftlog(flow, x, y, dt, duration):
    """Tracer RK4 at a fixed step on ``flow``; returns (x, y, run CPU s)."""
    nb.set_num_threads(1)
    logs = Logs(x, y, 0.0, 0.5, 0.05, 500.0)
    tr = Tracker(flow, logs, PhysicsOptions(level="tracer", rotation=False), "rk4",
                 StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9, drag_fraction=0.0),
                 t_start=0.0, t_end=duration, output_interval=duration, hydro_step=duration)
    c0 = time.process_time()
    tr.run()
    cpu = time.process_time() - c0
    if not np.all(logs.status == 1):
        raise RuntimeError(f"driftlog: {np.sum(logs.status != 1)} particles stopped floating")
    return logs.state[:, X].copy(), logs.state[:, Y].copy(), cpu


def sampling_speed(n_cells, n_points, repeat=5):
    """Warm samples per second (one thread) of the grid field and of the triangulated mesh
    path on one n_cells x n_cells grid (two snapshots), at n_points random points."""
    from driftlog.gridflow import GridFlowField

    rng = np.random.default_rng(3)
    n = n_cells * n_cells
    h = np.full((2, n), 2.0)
    hu = rng.normal(size=(2, n))
    hv = rng.normal(size=(2, n))
    grid = GridFlowField.from_arrays(n_cells, n_cells, 1.0, 1.0, 0.0, 0.0, np.zeros(n),
                                     [0.0, 10.0], h, hu, hv)
    mesh = _mesh_path(grid)
    x, y = n_cells * rng.random(n_points), n_cells * rng.random(n_points)
    rows = []
    nb.set_num_threads(1)
    for name, flow in (("driftlog (bilinear grid)", grid),
                       ("driftlog (triangulated, before)", mesh)):
        s = flow.sample(x, y, 3.0)  # warm: compilation, snapshots, location from scratch
        face = s.face.copy()
        best = np.inf
        for _ in range(repeat):
            f = face.copy()
            c0 = time.process_time()
            flow.sample(x, y, 3.0 + 1e-3 * _, face=f)
            best = min(best, time.process_time() - c0)
        rows.append(dict(tool=name, cells=n, points=n_points, cpu_s=best,
                         samples_per_cpu_s=n_points / best))
        print(rows[-1], flush=True)
    return rows


def main(quick=False):
    from driftlog.adapters.cfgrid import open_cf_grid

    logging.getLogger("parcels").setLevel(logging.ERROR)
    RESULTS.mkdir(parents=True, exist_ok=True)
    vers = pt.versions()
    has_parcels = not vers["Parcels"].startswith("unavailable")
    n = 200 if quick else 1000
    sizes = (40.0, 20.0) if quick else (40.0, 20.0, 10.0)
    rng = np.random.default_rng(7)
    x, y = pt.seed(n, rng)
    xx, yy = pt.exact(x, y, pt.DURATION)
    rows, pairs = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for dx in sizes:
            path = pt.write_grid(Path(tmp) / f"eddy_{dx:g}.nc", dx)
            grid = open_cf_grid(path)
            # warm-up (numba compilation) on a few particles
            run_driftlog(grid, x[:8], y[:8], DT, 4 * DT)
            run_driftlog(_mesh_path(grid), x[:8], y[:8], DT, 4 * DT)
            pos = {}
            for tool in ("driftlog (bilinear grid)", "driftlog (triangulated, before)",
                         "Parcels"):
                if tool == "Parcels":
                    if not has_parcels:
                        continue
                    pt.run_parcels(path, x[:8], y[:8], DT, 4 * DT)
                    xe, ye, _, (_, cpu) = pt.run_parcels(path, x, y, DT, pt.DURATION)
                else:
                    flow = open_cf_grid(path)
                    flow = flow if "bilinear" in tool else _mesh_path(flow)
                    xe, ye, cpu = run_driftlog(flow, x, y, DT, pt.DURATION)
                err = np.hypot(xe - xx, ye - yy)
                pos[tool] = (xe, ye)
                rows.append(dict(cell_m=dx, tool=tool, particles=n,
                                 steps=int(round(pt.DURATION / DT)),
                                 max_error_m=float(err.max()), mean_error_m=float(err.mean()),
                                 run_cpu_s=cpu))
                print(rows[-1], flush=True)
            if "Parcels" in pos:
                a, b = pos["driftlog (bilinear grid)"], pos["Parcels"]
                d = np.hypot(a[0] - b[0], a[1] - b[1])
                pairs.append(dict(cell_m=dx, max_distance_m=float(d.max()),
                                  mean_distance_m=float(d.mean())))
                print(pairs[-1], flush=True)
    speed = sampling_speed(300 if quick else 1000, 100_000 if quick else 1_000_000)
    info = dict(machine=machine(), versions=", ".join(f"{k} {v}" for k, v in vers.items()),
                duration=pt.DURATION, dt=DT, snapshot=pt.SNAPSHOT, particles=n)
    stem = "grid_peers_quick" if quick else "grid_peers"  # --quick keeps the full results
    (RESULTS / f"{stem}.json").write_text(json.dumps(
        {"info": info, "rows": rows, "pairs": pairs, "sampling": speed}, indent=1))

    def g(v):
        return f"{v:.3g}" if isinstance(v, float) else str(v)

    lines = ["### Regular grids: driftlog's bilinear grid field beside Parcels", "",
             f"Measured on {info['machine']}; {info['versions']}.", "",
             f"The drifting eddy of `peers_tracking.py` on a {pt.NX * pt.DX:g} x "
             f"{pt.NY * pt.DX:g} m CF grid (cell-centred values, snapshots every "
             f"{pt.SNAPSHOT:g} s); {n} particles over a disk of radius {pt.SEED_RADIUS:g} m, "
             f"RK4 at dt = {DT:g} s for {pt.DURATION:g} s, one thread.  Error: distance to the "
             "exact positions at the end; CPU: the run's process time (set-up apart).  "
             "Re-create: `python benchmarks/grid_peers.py`.", "",
             "| cell (m) | tool | max error (m) | mean error (m) | run CPU (s) |",
             "|---:|---|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {g(r['cell_m'])} | {r['tool']} | {g(r['max_error_m'])} | "
                     f"{g(r['mean_error_m'])} | {g(r['run_cpu_s'])} |")
    if pairs:
        lines += ["", "Distance between driftlog (bilinear grid) and Parcels, same particles:",
                  "", "| cell (m) | max distance (m) | mean distance (m) |", "|---:|---:|---:|"]
        for r in pairs:
            lines.append(f"| {g(r['cell_m'])} | {g(r['max_distance_m'])} | "
                         f"{g(r['mean_distance_m'])} |")
    lines += ["", "Sampling speed (warm, one thread, location hints from the previous call; "
              "CPU time; random points, two snapshots, a grid of 1 m cells):", "",
              "| sampler | cells | points | CPU (s) | samples per CPU s |",
              "|---|---:|---:|---:|---:|"]
    for r in speed:
        lines.append(f"| {r['tool']} | {r['cells']} | {r['points']} | {g(r['cpu_s'])} | "
                     f"{g(r['samples_per_cpu_s'])} |")
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{stem}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="fewer particles, no 10 m grid")
    main(p.parse_args().quick)
