"""Validation of two-way coupling: backwater of a fixed log array and of a jam at a bridge.

(a) + (c): a fixed array of two logs (1.8 m, 0.15 m radius, broadside, held by posts) across a
4 m channel carrying 1 m2/s on 1 m of water: the rise of the level 3-8 m upstream against the
one-dimensional momentum balance with the logs' drag (docs/model.md eq. (76)), at three mesh
sizes (the test runs the middle one, tests/test_coupling.py).

(b): cases/bridge_jam/coupled.toml: 30 logs jam at a deck across a 7 m channel; the level
along the channel at the end against the same flow without logs (a figure), the backwater
2-12 m upstream of the deck, the deck's force (contact impulses and the entrained water's,
(73)), and the backwater the momentum balance (76) gives for that force.

Writes benchmarks/results/coupling_validation{.md,.csv,.json} and coupling_backwater.png.

    python benchmarks/coupling_validation.py             # all
    python benchmarks/coupling_validation.py --skip-fine # without the 0.25 m mesh
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from _common import RESULTS, machine, write_table  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
JAM = ROOT / "cases" / "bridge_jam" / "coupled.toml"
G = 9.81


def fixed_array(cells):
    """Rows of (a)/(c): measured and predicted backwater at each mesh size."""
    from test_coupling import array_backwater

    rows = []
    for cell in cells:
        t0 = time.perf_counter()
        measured, predicted, force, drag = array_backwater(cell)
        rows.append(dict(case="(a) fixed array of 2 logs", cell_m=cell,
                         measured_mm=1e3 * measured, predicted_mm=1e3 * predicted,
                         error_pct=100 * (measured / predicted - 1), force_N=force, drag_N=drag,
                         wall_s=time.perf_counter() - t0))
        print(rows[-1], flush=True)
    return rows


def bridge_jam(out_dir):
    """(b): the coupled bridge_jam case and the same flow without logs; profile figure."""
    import netCDF4

    from driftlog.api import as_scenario, track
    from driftlog.flowfile import open_flow
    from driftlog.solver.config import build_solver

    scen = as_scenario(str(JAM))
    t0 = time.perf_counter()
    res = track(scen, output=out_dir / "bridge_jam_coupled.nc")
    wall = time.perf_counter() - t0
    t1 = scen["time"]["end"]
    ref = build_solver(scen["solver"])
    ref.advance_to(t1)
    with netCDF4.Dataset(res.path) as ds:
        flow_path = Path(ds.getncattr("coupled_flow"))
    flow = open_flow(flow_path)
    snap = flow.snapshot(flow.times.size - 1)
    mesh = flow.mesh
    fx, fy = mesh.face_x, mesh.face_y
    mid = np.abs(fy) < 1.0
    order = np.argsort(fx[mid])
    x = fx[mid][order]
    eta_jam = snap["eta"][mid][order]
    eta_ref = (ref.h + ref.bed)[mid][order]
    up = (fx > 15.0 - 12.0) & (fx < 15.0 - 2.0)
    rise = float((snap["eta"][up] - (ref.h + ref.bed)[up]).mean())
    # the deck's force over the last 60 s: from the trajectory file's contact hits is not a
    # force; the coupled run's momentum given to the water over its last part is
    L = res.logs
    at_deck = int(((L.state[:, 0] > 10.0) & (L.state[:, 0] < 15.0)).sum())
    with netCDF4.Dataset(res.path) as ds:
        given = float(ds.getncattr("coupling_momentum_given_x"))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.plot(x, eta_ref, ".", ms=2, color="0.5", label="without logs")
    ax.plot(x, eta_jam, ".", ms=2, color="C0", label=f"with the jam ({at_deck} logs at the deck)")
    ax.axvspan(15.0, 16.0, color="C3", alpha=0.3, label="deck")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("water level (m), |y| < 1 m")
    ax.set_title(f"bridge_jam, coupled: level at t = {t1:g} s")
    ax.legend(loc="upper right")
    fig.tight_layout()
    RESULTS.mkdir(parents=True, exist_ok=True)
    fig.savefig(RESULTS / "coupling_backwater.png", dpi=130)
    # the jam's force from the level difference it holds, (76) reversed, at the mean depth
    h_up = float(snap["h"][up].mean())
    q = 1.0
    force_from_levels = G * h_up * rise * (1 - q * q / (G * h_up ** 3)) * 1000 * 7.0
    return dict(case="(b) bridge_jam coupled, 30 logs", cell_m=scen["solver"]["cell_size"],
                measured_mm=1e3 * rise, logs_at_deck=at_deck, wall_s=wall,
                momentum_given_x=given, force_from_levels_N=force_from_levels)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-fine", action="store_true", help="no 0.25 m mesh")
    ap.add_argument("--only", choices=("array", "jam"), default=None)
    a = ap.parse_args(argv)
    import tempfile

    rows = []
    if a.only in (None, "array"):
        rows += fixed_array([1.0, 0.5] + ([] if a.skip_fine else [0.25]))
    if a.only in (None, "jam"):
        rows.append(bridge_jam(Path(tempfile.mkdtemp(prefix="driftlog-jam-"))))
        print(rows[-1], flush=True)
    cols = ["case", "cell_m", "measured_mm", "predicted_mm", "error_pct", "force_N", "drag_N",
            "logs_at_deck", "momentum_given_x", "force_from_levels_N", "wall_s"]
    write_table("coupling_validation", rows, cols, "Two-way coupling: backwater (issue 16)",
                "Backwater = level with logs minus level without, 3-8 m (a) or 2-12 m (b) "
                "upstream; predicted by the 1D momentum balance docs/model.md (76).")
    (RESULTS / "coupling_validation.json").write_text(json.dumps(
        dict(machine=machine(), rows=rows), indent=1, default=float))


if __name__ == "__main__":
    main()
