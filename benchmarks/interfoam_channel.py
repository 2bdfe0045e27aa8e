"""The 3D route at more than the test's size: interFoam in a channel with a block, depth-averaged,
against driftlog's shallow-water solution of the same channel.

``python benchmarks/interfoam_channel.py`` (5 cm and 2.5 cm squares, 8 layers; a few minutes
on the shared 2-core machine) or ``--quick`` (5 cm only, the test's size).  The channel of
``tests/test_interfoam_route.py``: 1.6 m x 0.4 m, a 10 cm block in the middle, water 10 cm
deep entering at 6 l/s, level held at the outflow, 8 s, frictionless on both sides.
Reported per mesh: cells, interFoam wall and CPU time (its process's rusage), driftlog's
(order 2), the time-averaged (4-8 s) discharge error per cross-section of each, and the RMS
depth and speed differences between the two at the end.  Results:
``benchmarks/results/interfoam_channel.md`` and ``.csv``.
"""

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._common import write_table  # noqa: E402

LENGTH, WIDTH, BLOCK = 1.6, 0.4, (0.75, 0.15, 0.85, 0.25)
LEVEL, Q, END = 0.10, 0.006, 8.0
SECTIONS = (0.1, 0.4, 0.6, 1.0, 1.3, 1.5)


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def section_discharge(field, x0, t):
    y = np.linspace(0.001, WIDTH - 0.001, 400)
    s = field.sample(np.full(y.size, x0), y, np.full(y.size, t))
    return np.trapezoid(np.where(np.isfinite(s.u), s.h * s.u, 0.0), y)


def run(cell, layers, tmp):
    from driftlog.adapters.interfoam_case import channel_with_block, run_interfoam_channel

    from driftlog.flowfile import open_flow
    from driftlog.solver.model import ShallowWaterSolver

    mesh = channel_with_block(LENGTH, WIDTH, cell, BLOCK)
    w0, c0 = time.perf_counter(), children_cpu()
    vof = run_interfoam_channel(tmp / f"vof_{cell:g}", mesh, level=LEVEL, discharge=Q,
                                height=0.16, n_layers=layers, end_time=END, write_interval=0.5,
                                timeout=3600)
    vof_wall, vof_cpu = time.perf_counter() - w0, children_cpu() - c0
    sw_mesh = channel_with_block(LENGTH, WIDTH, cell, BLOCK)
    s = ShallowWaterSolver(sw_mesh, order=2, boundaries={
        "inflow": {"type": "discharge", "value": Q},
        "outflow": {"type": "level", "value": LEVEL}})
    h = np.full(sw_mesh.n_faces, LEVEL)
    s.set_state(h, h * Q / (WIDTH * LEVEL), 0 * h)
    w0, c0 = time.perf_counter(), time.process_time()
    s.run(END, output=tmp / f"sw_{cell:g}.nc", output_interval=0.5)
    sw_wall, sw_cpu = time.perf_counter() - w0, time.process_time() - c0
    sw = open_flow(tmp / f"sw_{cell:g}.nc")
    late = vof.times >= 4.0 - 1e-9
    err = {}
    for name, f in (("interFoam", vof), ("driftlog", sw)):
        q = [np.mean([section_discharge(f, x0, t) for t in vof.times[late]]) for x0 in SECTIONS]
        err[name] = float(np.max(np.abs(np.array(q) - Q)) / Q)
    a, b = vof.snapshot(vof.times.size - 1), sw.snapshot(sw.times.size - 1)
    return {"cell (m)": cell, "columns": mesh.n_faces, "3D cells": mesh.n_faces * layers,
            "interFoam wall (s)": vof_wall, "interFoam CPU (s)": vof_cpu,
            "driftlog wall (s)": sw_wall, "driftlog CPU (s)": sw_cpu,
            "max discharge error interFoam": err["interFoam"],
            "max discharge error driftlog": err["driftlog"],
            "depth RMS diff (m)": float(np.sqrt(np.mean((a["h"] - b["h"]) ** 2))),
            "speed RMS diff (m/s)": float(np.sqrt(np.mean(
                (np.hypot(a["u"], a["v"]) - np.hypot(b["u"], b["v"])) ** 2)))}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="5 cm squares only")
    args = ap.parse_args()
    from driftlog.adapters.openfoam_case import foam_available

    if not foam_available():
        sys.exit("OpenFOAM is not installed (Debian: apt-get install openfoam)")
    tmp = Path(tempfile.mkdtemp(prefix="vof_"))
    rows = []
    for cell in ((0.05,) if args.quick else (0.05, 0.025)):
        rows.append(run(cell, 8, tmp))
        print(rows[-1], flush=True)
    cols = list(rows[0])
    write_table("interfoam_channel" + ("_quick" if args.quick else ""), rows, cols,
                "interFoam channel with a block, depth-averaged, against driftlog's solver",
                notes="8 layers of 2 cm; discharge errors: time-averaged over 4-8 s, max over "
                      "6 cross-sections, relative to the 6 l/s inflow; differences at 8 s.")


if __name__ == "__main__":
    main()
