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
steps, coupled / solve and coupled / (solve + offline track) ratios.  The full flood is
4000 s (about 15 min per solve on 2 cores); ``--end 300`` (the default) is labelled as a
shortened run.

    python benchmarks/coupling_cost.py --end 300 --logs 1000
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine, write_table  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
CASE = ROOT / "cases" / "malpasset" / "scenario.toml"
# in the reservoir, just upstream of the dam line (bed below 100 m: wet at t = 0)
RESERVOIR = [[4350.0, 3850.0], [4550.0, 4000.0], [4450.0, 4250.0], [4250.0, 4100.0]]


def scenario(end, n_logs, coupled, flow_path=None):
    """The Malpasset case to ``end`` with ``n_logs`` logs in the reservoir."""
    from driftlog.api import as_scenario

    over = {"time": {"start": 0.0, "end": end, "output_interval": 10.0},
            "logs": [{"name": "reservoir", "seeding": "random", "count": n_logs,
                      "polygon": RESERVOIR, "seed": 7, "theta": "random", "length": 8.0,
                      "radius": 0.2, "density": 700.0, "velocity": "rest"}],
            "solver": {"end": end, "output_interval": 10.0},
            "coupling": {"enabled": coupled}}
    if flow_path is not None:
        over["flow"] = {"path": str(flow_path)}
    scen = as_scenario(str(CASE), overrides=over)
    return scen


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--end", type=float, default=300.0, help="end of the flood run (s)")
    ap.add_argument("--logs", type=int, default=1000)
    ap.add_argument("--name", default="coupling_cost")
    a = ap.parse_args(argv)
    from driftlog.api import track
    from driftlog.solver.config import build_solver
    from driftlog.solving import solve_scenario

    tmp = Path(tempfile.mkdtemp(prefix="driftlog-coupling-"))
    rows = []
    # warm the kernels (numba cache) on a few steps, so no run pays for compiling
    warm = scenario(20.0, 10, True)
    track(warm, output=tmp / "warm.nc")

    scen = scenario(a.end, a.logs, False, flow_path=tmp / "flow.nc")
    s = build_solver(scen["solver"])
    t0 = time.perf_counter()
    s.advance_to(a.end)
    t_solve = time.perf_counter() - t0
    rows.append(dict(run="solve (solver alone, no output)", wall_s=t_solve, solver_steps=s.steps,
                     ratio_to_solve=1.0))

    t0 = time.perf_counter()
    solve_scenario(scen, output=tmp / "flow.nc")
    t_solve_out = time.perf_counter() - t0
    t0 = time.perf_counter()
    off = track(scen, output=tmp / "offline.nc")
    t_track = time.perf_counter() - t0
    rows.append(dict(run="offline: solve with output + track", wall_s=t_solve_out + t_track,
                     solver_steps=s.steps, ratio_to_solve=(t_solve_out + t_track) / t_solve))

    cscen = scenario(a.end, a.logs, True)
    t0 = time.perf_counter()
    res = track(cscen, output=tmp / "coupled.nc")
    t_coupled = time.perf_counter() - t0
    import netCDF4

    with netCDF4.Dataset(tmp / "coupled.nc") as ds:
        steps = int(ds.getncattr("coupling_solver_steps"))
        given = float(ds.getncattr("coupling_momentum_given_x")), \
            float(ds.getncattr("coupling_momentum_given_y"))
    rows.append(dict(run=f"coupled: {a.logs} logs acting on the flood", wall_s=t_coupled,
                     solver_steps=steps, ratio_to_solve=t_coupled / t_solve))
    floating = int((res.logs.status == 1).sum())
    label = "" if a.end >= 4000.0 else f" (shortened run: {a.end:g} s of the 4000-s flood)"
    notes = (f"Malpasset, 46,691 triangles, order 1, {a.logs} logs released in the reservoir, no "
             f"contacts{label}.  Coupled / offline pipeline: "
             f"{t_coupled / (t_solve_out + t_track):.2f}; offline track alone {t_track:.1f} s "
             f"({off.stats['substeps']} sub-steps); coupled run: {floating} logs floating at the "
             f"end, momentum given to the water ({given[0]:.3g}, {given[1]:.3g}) kg m/s.")
    write_table(a.name, rows, ["run", "wall_s", "solver_steps", "ratio_to_solve"],
                f"Cost of two-way coupling: Malpasset with {a.logs} logs{label}", notes)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{a.name}.json").write_text(json.dumps(dict(
        machine=machine(), end=a.end, logs=a.logs, solve_s=t_solve,
        solve_with_output_s=t_solve_out, offline_track_s=t_track, coupled_s=t_coupled,
        coupled_over_solve=t_coupled / t_solve,
        coupled_over_offline=t_coupled / (t_solve_out + t_track), floating_at_end=floating,
        momentum_given=given), indent=1))


if __name__ == "__main__":
    main()
