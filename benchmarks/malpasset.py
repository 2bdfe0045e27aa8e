"""The Malpasset dam break (1959) on driftlog's solver, against the field and scale-model data.

Set-up from shared/data/malpasset/README.md (``driftlog.floodsetup.malpasset_solver``):
reservoir at 100 m in its polygon where the bed is below, sea at 0 m (TELEMAC's example;
GeoClaw uses -0.5 m) on the faces below it connected to the sea boundary, the sea boundary
(boundary edges with both nodes at or below 0 m, found from the mesh) an imposed level of 0 m,
reflective walls elsewhere, Manning n = 0.033, first order HLLC.  The flood runs 4000 s; the
flow file (snapshots every 30 s, large) goes to ``--flow`` (default /tmp), never the repository.

Compared with ``observations.csv``: the solver's per-face maximum water level at the face
holding each police point P1-P17 and gauge G6-G14, and the per-face arrival time (first time
the depth exceeds the solver's arrival depth, 0.05 m) at the gauges and the transformers
A, B, C.  Writes benchmarks/results/malpasset{.md,.json} and malpasset_{levels,arrival,map}.png.

    python benchmarks/malpasset.py                 # 4000 s (about 40 min on 2 busy cores)
    python benchmarks/malpasset.py --quick         # 600 s, the first gauges only
    python benchmarks/malpasset.py --flow /tmp/m.nc --compare-only   # re-plot a stored run
    python benchmarks/malpasset.py --order 2 --end 300 --flow /tmp/o2.nc --solve-only
    python benchmarks/malpasset.py --flow /tmp/m.nc --compare-only --versus /tmp/o2.nc
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine  # noqa: E402

from driftlog.floodsetup import (  # noqa: E402
    MALPASSET_DAM,
    malpasset_solver,
    read_observations,
)

ROOT = Path(__file__).resolve().parent.parent


def data_dir():
    """The Malpasset data: shared/data/malpasset beside the checkout, or the case's copy."""
    for d in (ROOT.parent.parent / "shared" / "data" / "malpasset",
              ROOT.parent / "shared" / "data" / "malpasset",
              ROOT / "cases" / "malpasset" / "data"):
        if (d / "malpasset_mesh.nc").is_file():
            return d
    raise SystemExit("Malpasset data not found (cases/malpasset/data/malpasset_mesh.nc)")


def solve(end, flow, order, interval, sea_level, sea):
    """Run the flood to ``end`` s writing ``flow``; returns the run facts (dict)."""
    solver = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=order,
                              sea_level=sea_level, sea=sea)
    v0 = solver.volume()
    h0 = solver.h.copy()
    solver.step(1e-3)  # compile the kernels outside the timed run
    solver.set_state(h0)
    res = solver.run(end, output=flow, output_interval=interval, progress=True,
                     attrs={"title": "Malpasset dam break (driftlog solver)"})
    facts = {"end_s": end, "order": order, "sea_level_m": sea_level, "sea_boundary": sea,
             "faces": solver.mesh.n_faces, "steps": res.steps, "wall_s": res.wall_time,
             "cell_updates_per_s": res.cell_updates_per_s, "initial_volume_m3": v0,
             "volume_m3": res.volume, "volume_error_m3": res.volume_error,
             "relative_volume_error": res.relative_volume_error,
             "sea_outflow_m3": float(solver.outflow_volume.sum()),
             "sea_inflow_m3": float(solver.inflow_volume.sum()),
             "arrival_depth_m": solver.arrival_depth, "dry_depth_m": solver.dry_depth,
             "machine": machine(), "flow": str(flow)}
    Path(str(flow) + ".json").write_text(json.dumps(facts, indent=1))
    return facts


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="600 s only (report and tests)")
    p.add_argument("--end", type=float, default=None, help="end time (s), default 4000")
    p.add_argument("--order", type=int, default=1, choices=(1, 2))
    p.add_argument("--interval", type=float, default=30.0, help="snapshot interval (s)")
    p.add_argument("--sea-level", type=float, default=0.0)
    p.add_argument("--sea", default="level", choices=("level", "free"))
    p.add_argument("--flow", default=None, help="flow file (default /tmp/malpasset_<end>.nc)")
    p.add_argument("--compare-only", action="store_true", help="compare a stored run")
    p.add_argument("--solve-only", action="store_true", help="run, do not compare")
    p.add_argument("--versus", help="another stored run (e.g. --order 2 --end 300) whose "
                   "arrival times join the table")
    p.add_argument("--notes", default="", help="a finding to print under the table")
    a = p.parse_args(argv)
    end = a.end or (600.0 if a.quick else 4000.0)
    flow = Path(a.flow or f"/tmp/malpasset_o{a.order}_{end:g}.nc")
    if not a.compare_only:
        facts = solve(end, flow, a.order, a.interval, a.sea_level, a.sea)
        print(json.dumps(facts, indent=1))
    if a.solve_only:
        return 0
    from malpasset_compare import compare

    compare(flow, data_dir(), quick=a.quick or end < 4000.0, dam=MALPASSET_DAM,
            observations=read_observations(data_dir() / "observations.csv"), results=RESULTS,
            notes=a.notes, versus=a.versus)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
