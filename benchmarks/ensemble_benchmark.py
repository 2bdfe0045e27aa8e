"""Ensemble throughput: members per minute on 1 and 2 Dask workers, scaling, time to first result.

    python benchmarks/ensemble_benchmark.py                        # a small mesh flow built here
    python benchmarks/ensemble_benchmark.py river_piers --members 100
    python benchmarks/ensemble_benchmark.py my_scenario.toml --workers 1 2 4
    python benchmarks/ensemble_benchmark.py my_ensemble.toml       # an ensemble file as it is

SCENE is a case name (cases/<name>/scenario.toml), a debris scenario file, or an ensemble file
(a scenario with an [ensemble] section, run as it is with --members members).  A scenario is
wrapped into a Latin-hypercube ensemble that varies the release time (over the first fifth
of the run), the log length (0.5 to 1.5 times the scenario's), the density (500 to 900
kg/m3), and the restitution when contacts are on.  The default scene: a 60 m x 20 m channel
with two bridge piers (holes in the mesh), 1 m/s flow on the mesh, 20 to 60 logs per member
released upstream, drag or full physics, 60 s in sub-steps of at most 0.1 s.

Each configuration runs the whole ensemble afresh on a LocalCluster of n worker processes
(one thread each) after a warm-up member that fills numba's cache.  Reported: the time to
start the cluster, the time from the call to the first finished member (cluster start
included), members per minute over the run (first submission to last result, cluster start
excluded), the same after the first result (steady: every worker has imported driftlog,
loaded the compiled kernels and opened the flow), the scaling efficiency
rate(n) / (n rate(1)) of each, and the mean wall and CPU time of a member inside its task
(wall above CPU: the worker waited for a core, on a machine shared with other jobs).  Results:
benchmarks/results/ensemble.json and ensemble.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE.parent))


def default_scene(folder: Path) -> dict:
    """A channel with two piers and a steady 1 m/s flow on its mesh; an ensemble over it."""
    from driftlog.analytic import UniformFlow, on_mesh
    from driftlog.flowfile import write_flow
    from driftlog.mesher import channel_mesh, circle

    flow = folder / "channel_flow.nc"
    if not flow.is_file():
        mesh = channel_mesh(60.0, 20.0, 0.5, holes=[circle((30.0, 7.0), 1.0, cell_size=0.25),
                                                    circle((30.0, 13.0), 1.0, cell_size=0.25)])
        write_flow(flow, on_mesh(UniformFlow(1.0, 0.0, depth=1.5), mesh, times=[0.0, 100.0]))
    return {
        "title": "benchmark: channel with two piers",
        "flow": {"source": "file", "path": str(flow)},
        "time": {"start": 0.0, "end": 60.0, "output_interval": 1.0},
        "logs": [{"seeding": "random", "polygon": [[2, 2], [10, 2], [10, 18], [2, 18]],
                  "count": 40, "length": 1.0, "radius": 0.1, "density": 700.0}],
        "physics": {"level": "drag"},
        "integrator": {"max_step": 0.1},
        "ensemble": {"sampling": "latin_hypercube", "seed": 1, "vary": {
            "logs.release_time": {"uniform": [0.0, 10.0]},
            "logs.count": {"integers": [20, 60]},
            "logs.length": {"uniform": [0.5, 2.0]},
            "logs.density": {"uniform": [500.0, 900.0]},
            "physics.level": {"values": ["drag", "full"]}}},
    }


def wrap_scenario(path: Path) -> dict:
    """An ensemble over a debris scenario: release time, length, density (and restitution)."""
    from driftlog.api import as_scenario

    scen = as_scenario(path)
    t0 = scen["time"]["start"]
    t1 = scen["time"]["end"]
    if t1 is None:
        from driftlog.sources import flow_from_scenario

        t1 = flow_from_scenario(scen).time_span[1]
    L = scen["logs"][0]["length"]
    vary = {"logs.release_time": {"uniform": [t0, t0 + 0.2 * (t1 - t0)]},
            "logs.length": {"uniform": [0.5 * L, 1.5 * L]},
            "logs.density": {"uniform": [500.0, 900.0]}}
    if scen["contact"]["enabled"]:
        vary["contact.restitution"] = {"uniform": [0.2, 1.0]}
    return {"ensemble": {"base": str(Path(path).resolve()), "sampling": "latin_hypercube",
                         "seed": 1, "vary": vary}}


def scene_ensemble(scene: str | None, folder: Path) -> tuple[dict | Path, str]:
    if scene is None:
        return default_scene(folder), "default: 60 m x 20 m channel, two piers, mesh flow"
    p = Path(scene)
    if not p.exists():
        from driftlog.api import find_case

        p = find_case(scene)
    import tomllib

    if "ensemble" in tomllib.loads(p.read_text()):
        return p, str(p)
    return wrap_scenario(p), str(p)


MEMORY_SCENARIO = """
[flow]
source = "analytic"
kind = "uniform"
velocity = [1.0, 0.2]
[time]
end = 4.0
[[logs]]
seeding = "random"
polygon = [[1, 1], [3, 1], [3, 3], [1, 3]]
count = 3
[physics]
level = "tracer"
[ensemble]
members = {n}
workers = 0
output = "{out}"
grid_cell = 0.05
grid_origin = [0.0, 0.0]
grid_size = [10.0, 5.0]
[ensemble.vary]
"logs.release_time" = {{ uniform = [0.0, 2.0] }}
"""

MEMORY_SCRIPT = """
import resource, sys, time
from driftlog.ensemble import run_ensemble
t = time.perf_counter()
r = run_ensemble(sys.argv[1], progress=False, figures=False, overwrite=True)
print(r.done, time.perf_counter() - t, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def memory_check(folder: Path, sizes=(200, 2000)) -> list[dict]:
    """Peak memory of whole ensembles of tiny members (in-process), against their size."""
    import subprocess

    rows = []
    env = dict(os.environ, PYTHONPATH=str(HERE.parent) + os.pathsep
               + os.environ.get("PYTHONPATH", ""))
    for n in sizes:
        out = folder / f"memory_{n}"
        text = MEMORY_SCENARIO.format(n=n, out=out)
        res = subprocess.run([sys.executable, "-c", MEMORY_SCRIPT, text], capture_output=True,
                             text=True, env=env, check=True).stdout.split()
        size = sum(p.stat().st_size for p in (out / "members").iterdir())
        rows.append(dict(members=int(res[0]), wall_s=round(float(res[1]), 1),
                         peak_rss_mb=round(float(res[2])), member_files_mb=round(size / 2**20, 1)))
        print(rows[-1])
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="example:\n  python benchmarks/ensemble_benchmark.py "
                                        "river_piers --members 100")
    ap.add_argument("scene", nargs="?", help="case name, scenario or ensemble file "
                    "(default: a small mesh flow built here)")
    ap.add_argument("--members", type=int, default=40)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--out", help="scratch folder (default: a temporary one)")
    ap.add_argument("--name", default="ensemble", help="results file name (default: ensemble)")
    ap.add_argument("--memory", action="store_true", help="also measure the peak memory of "
                    "ensembles of 200 and 2000 tiny members (maps on 20,000 faces)")
    args = ap.parse_args(argv)

    from driftlog.ensemble import load_ensemble, run_ensemble, run_member
    from driftlog.scenario import merge

    folder = Path(args.out or tempfile.mkdtemp(prefix="driftlog-ensemble-bench-"))
    folder.mkdir(parents=True, exist_ok=True)
    spec, label = scene_ensemble(args.scene, folder)
    over = {"ensemble": {"members": args.members}}
    ens = load_ensemble(spec if not isinstance(spec, dict) else merge(spec, over),
                        over if not isinstance(spec, dict) else None)
    load = os.getloadavg()[0]
    t = time.perf_counter()
    warm = run_member(ens, 0)  # fills numba's cache: workers load compiled kernels from it
    print(f"warm-up member: {time.perf_counter() - t:.1f} s ({warm.n_logs} logs)")
    rows = []
    for n in args.workers:
        res = run_ensemble(ens, workers=n, output=folder / f"run_w{n}", overwrite=True,
                           progress=False, figures=False)
        tm = res.timings
        ds = res.dataset()
        wall, cpu = ds["member_wall_seconds"].values, ds["member_cpu_seconds"].values
        rows.append(dict(workers=n, members=res.done, failed=len(res.failed),
                         cluster_start_s=round(tm["start_seconds"], 2),
                         first_result_s=round(tm["first_result_seconds"], 2),
                         run_s=round(tm["run_seconds"], 2),
                         members_per_minute=round(tm["members_per_minute"], 1),
                         steady_members_per_minute=round(
                             tm.get("steady_members_per_minute", np.nan), 1),
                         member_wall_s=round(float(np.nanmean(wall)), 3),
                         member_cpu_s=round(float(np.nanmean(cpu)), 3),
                         total_wall_s=round(tm["wall_seconds"], 2)))
        print(rows[-1])
    r1 = next((r for r in rows if r["workers"] == 1), None)
    for r in rows:
        for k, e in (("members_per_minute", "scaling_efficiency"),
                     ("steady_members_per_minute", "steady_scaling_efficiency")):
            r[e] = round(r[k] / (r["workers"] * r1[k]), 2) if r1 else None
    logs = int(res.aggregate.total_logs)
    info = dict(scene=label, members=args.members, logs_total=logs,
                aggregation_faces=int(res.aggregate.mesh.n_faces),
                parameters=[p.path for p in ens.parameters], sampling=ens.section["sampling"],
                machine=f"{platform.machine()}, {os.cpu_count()} cores, Python "
                        f"{platform.python_version()}, load average {load:.2f} at start",
                rows=rows)
    if args.memory:
        info["memory"] = memory_check(folder)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(info, indent=1))
    cols = ["workers", "members", "cluster_start_s", "first_result_s", "run_s",
            "members_per_minute", "scaling_efficiency", "steady_members_per_minute",
            "steady_scaling_efficiency", "member_wall_s", "member_cpu_s"]
    lines = [f"Scene: {label}; {args.members} members ({logs} logs in all), "
             f"{info['sampling']} over {', '.join(info['parameters'])}; maps on "
             f"{info['aggregation_faces']} faces.  Measured on {info['machine']}.", "",
             "| " + " | ".join(cols) + " |", "|" + "|".join("---:" for _ in cols) + "|"]
    lines += ["| " + " | ".join(str(r[c]) for c in cols) + " |" for r in rows]
    if args.memory:
        lines += ["", "Memory (tiny members in one process, maps on 20,000 faces):", "",
                  "| members | wall (s) | peak RSS (MB) | member files (MB) |",
                  "|---:|---:|---:|---:|"]
        lines += [f"| {r['members']} | {r['wall_s']} | {r['peak_rss_mb']} | "
                  f"{r['member_files_mb']} |" for r in info["memory"]]
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{args.name}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
