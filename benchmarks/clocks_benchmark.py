"""Per-log clocks against the global clock (issue 15): simulated log-seconds per CPU second.

Runs each scene twice in one process, ``[integrator] clock = "global"`` (the paper's Algorithm
1) and ``"per_log"`` (docs/model.md section 11.1), and reports CPU time of the tracking run,
sub-steps (global: shared steps; per-log: steps summed over the logs), simulated log-seconds
per CPU second and how far apart the two clocks leave the logs.  A third run per scene at a
quarter of the step bounds (per-log clock) is the reference for the errors of both.

- malpasset: the case's 40 logs on the 4000-s flood (a stored flow file, ``--malpasset-flow``;
  the case computes it otherwise).
- river: the river_piers flow (computed once by the case's solver) with ``--logs`` logs
  (default 1e4) seeded at random over the reach upstream of the first bridge, rk4, no
  contacts, ``--river-end`` s.

    python benchmarks/clocks_benchmark.py [--malpasset-flow F] [--logs N] [--quick]

Writes benchmarks/results/clocks.{md,json}.  Run with NUMBA_NUM_THREADS=1 for per-core rates.
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

from _common import RESULTS, machine  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
MALPASSET = ROOT / "cases" / "malpasset" / "scenario.toml"
RIVER = ROOT / "cases" / "river_piers" / "scenario.toml"


def one_run(scenario, over, clock, span, refine=1.0):
    """Track with the given clock; (final logs state, status, CPU s, stats, n logs, span)."""
    from driftlog.api import track
    from driftlog.schema import merge

    integ = {"clock": clock}
    if refine != 1.0:
        integ.update(length_fraction=refine, angle_step=refine * np.pi / 4,
                     drag_fraction=0.5 * refine)
    over = merge(over, {"integrator": integ})
    out = Path("/tmp") / f"clocks_bench_{clock}_{refine}.nc"
    cpu = time.process_time()
    wall = time.perf_counter()
    res = track(scenario, output=out, overrides=over)
    cpu = time.process_time() - cpu
    wall = time.perf_counter() - wall
    logs = res.logs
    return dict(state=logs.state.copy(), status=logs.status.copy(), cpu=cpu, wall=wall,
                stats=dict(res.stats), n=len(logs), span=span)


def scene(name, scenario, over, span, rows, notes, reference=True):
    """Global, per-log and a refined per-log reference; appends a table row per clock."""
    from driftlog.schema import merge

    # compile and load once (numba caches, the flow's first snapshots) before timing
    short = merge(over, {"time": {"end": min(0.1 * span, 2.0)}})
    for c in ("global", "per_log"):
        one_run(scenario, short, c, span)
    runs = {c: one_run(scenario, over, c, span) for c in ("global", "per_log")}
    ref = one_run(scenario, over, "per_log", span, refine=0.25) if reference else None
    for clock, r in runs.items():
        st = r["stats"]
        err = np.empty(0)
        if ref is not None:
            both = (r["status"] == ref["status"]) & (r["status"] == 1)  # floating in both
            err = np.hypot(*(r["state"][both, :2] - ref["state"][both, :2]).T)
        log_s = r["n"] * r["span"]
        rows.append(dict(scene=name, clock=clock, logs=r["n"], span_s=r["span"],
                         cpu_s=r["cpu"], wall_s=r["wall"], run_s=st.get("wall_seconds"),
                         sync_steps=st["substeps"],
                         log_steps=st.get("log_substeps", st["substeps"] * r["n"]),
                         contact_set=st.get("contact_set", ""),
                         windows=st.get("windows", ""), islands=st.get("islands", ""),
                         largest_island=st.get("largest_island", ""),
                         log_s_per_cpu_s=log_s / r["cpu"],
                         median_err_m=float(np.median(err)) if err.size else float("nan"),
                         max_err_m=float(err.max()) if err.size else float("nan"),
                         floating=int(np.sum(r["status"] == 1))))
    g, p = runs["global"], runs["per_log"]
    same = (g["status"] == p["status"]) & (g["status"] == 1)
    d = np.hypot(*(g["state"][same, :2] - p["state"][same, :2]).T)
    notes.append(f"{name}: per-log / global CPU speed-up {g['cpu'] / p['cpu']:.2f}x; "
                 f"statuses equal for {np.mean(g['status'] == p['status']):.0%} of the logs; "
                 f"floating in both: clocks {np.median(d) if d.size else 0:.3g} m apart "
                 f"(median), {d.max() if d.size else 0:.3g} m at most.")
    print(notes[-1], flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--malpasset-flow", help="stored flow file of the Malpasset flood")
    p.add_argument("--logs", type=int, default=10000, help="logs in the river scene")
    p.add_argument("--river-end", type=float, default=120.0, help="river run length (s)")
    p.add_argument("--contact-end", type=float, default=30.0, help="river run with contacts (s)")
    p.add_argument("--quick", action="store_true", help="1e3 river logs, 30 s, no malpasset")
    p.add_argument("--scenes", default="malpasset,river,crowd",
                   help="comma-separated: malpasset, river (no contacts), crowd (contacts)")
    p.add_argument("--crowd-seeding", default="grid", choices=("grid", "random"),
                   help="how the crowd with contacts is seeded")
    p.add_argument("--dense", action="store_true",
                   help="the crowd with contacts on a 2.4-m grid (1e4 logs; 2.7 m without)")
    p.add_argument("--at-piers", action="store_true",
                   help="with --dense: the crowd's front just upstream of the first bridge")
    p.add_argument("--serial", action="store_true",
                   help="serial kernels at every size (one thread: the parallel copies only add "
                   "their compile time and the thread pool's overhead)")
    p.add_argument("--contact-method", default="event", choices=("event", "moreau"),
                   help="the crowd's contact method (event-driven or Moreau-Jean)")
    p.add_argument("--name", help="results file name (default clocks[_quick][_SCENES])")
    a = p.parse_args(argv)
    from driftlog.schema import merge

    if a.serial:
        import driftlog._numba

        driftlog._numba.PARALLEL_MIN = 1 << 62

    rows, notes = [], []
    scenes = a.scenes.split(",")
    if "malpasset" in scenes and not a.quick:
        over = ({"flow": {"source": "file", "path": a.malpasset_flow}}
                if a.malpasset_flow else {})
        scene("malpasset (40 logs, 4000 s)", MALPASSET, over, 4000.0, rows, notes)
    n, end = (1000, 30.0) if a.quick else (a.logs, a.river_end)
    # driftwood over the reach upstream of the first bridge; the steady flow lands sub-steps
    # only on the outputs (hydro_step = output_interval)
    crowd = {"name": "crowd", "seeding": "random", "count": n, "seed": 3,
             "polygon": [[40.0, 8.0], [560.0, 8.0], [560.0, 162.0], [40.0, 162.0]],
             "theta": "random", "length": 2.0, "radius": 0.15, "density": 700.0}
    river = {"logs": [crowd], "integrator": {"method": "rk4"}, "contact": {"enabled": False},
             "time": {"end": end, "output_interval": 10.0, "hydro_step": 10.0}}
    if "river" in scenes:
        scene(f"river_piers ({n} logs, {end:g} s, no contacts)", RIVER, river, end, rows,
              notes)
    cend = min(end, a.contact_end)
    # the crowd with contacts is seeded on a grid (spacing sqrt(area / n), 2.7 m at 1e4 logs:
    # no two logs across each other); seeded at random, 1e4 logs start with overlapping
    # clusters that jammed the event-driven contacts at t = 0 (seen on the per-log clock, whose
    # islands ran the global clock's contact step; the global clock was not tried)
    river_c = merge(river, {"contact": {"enabled": True, "restitution": 0.5,
                                        "method": a.contact_method},
                            "time": {"end": cend}})
    river_c["logs"] = [{**crowd, "seeding": a.crowd_seeding}]
    if a.dense:  # 2.4 m grid spacing: 2-m logs that turn touch their neighbours
        x0 = 200.0 if a.at_piers else 100.0  # at_piers: the front 3 m from bridge A
        river_c["logs"][0]["polygon"] = [[x0, 8.0], [x0 + 382.0, 8.0], [x0 + 382.0, 162.0],
                                         [x0, 162.0]]
    if "crowd" in scenes:
        how = "event-driven" if a.contact_method == "event" else "Moreau-Jean"
        scene(f"river_piers crowd ({n} logs, {cend:g} s, {how} contacts)", RIVER,
              river_c, cend, rows, notes, reference=False)
    cols = ["scene", "clock", "logs", "span_s", "cpu_s", "run_s", "sync_steps", "log_steps",
            "contact_set", "windows", "islands", "largest_island", "log_s_per_cpu_s",
            "median_err_m", "max_err_m", "floating"]
    lines = ["### Per-log clocks against the global clock", "",
             f"{machine()}; CPU time of the whole `track` (flow reading included); errors: "
             "final positions of the logs floating in both runs against a per-log run at a "
             "quarter of every step bound.", "",
             "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]

    def fmt(v):
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)

    for r in rows:
        lines.append("| " + " | ".join(fmt(r[c]) for c in cols) + " |")
    lines += [""] + [f"- {s}" for s in notes]
    text = "\n".join(lines) + "\n"
    name = "clocks_quick" if a.quick else "clocks"
    if sorted(scenes) != ["crowd", "malpasset", "river"]:
        name += "_" + "_".join(scenes)
    name = a.name or name
    (RESULTS / f"{name}.md").write_text(text)
    (RESULTS / f"{name}.json").write_text(json.dumps(dict(rows=rows, notes=notes), indent=1))
    print(text)


if __name__ == "__main__":
    main()
