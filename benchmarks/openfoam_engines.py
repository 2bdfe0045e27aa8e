"""The river_piers scene on two engines, side by side: driftlog's solver and shallowWaterFoam.

``python benchmarks/openfoam_engines.py`` (full size: 16 m triangles, 3,500 faces, 2400 s of
flow, 900 s of logs; about 5-10 min on the shared 2-core machine) or ``--quick`` (30 m, 1200 s
of flow, 600 s of logs; written to ``openfoam_engines_quick.*``).

Both engines compute ``cases/river_piers/compare_engines.toml``'s [solver] section from
scratch in a temporary folder (no stored flow reused), one after the other in this process:
wall time (``time.perf_counter``) and CPU time (driftlog: this process's, one numba thread,
kernels compiled beforehand on a tiny run; OpenFOAM: its child processes' rusage).  Then the
8 logs are tracked on both steady flows (``driftlog.compare.compare_runs``) and their fates
compared.  Reported: per engine cells, steps, wall, CPU, cell-updates per CPU second; the flows'
difference at the piers and in the bridge openings; the logs' end distances, arrivals at the
bridges, hits and statuses.  Results: ``benchmarks/results/openfoam_engines.md`` and ``.json``,
the figure ``openfoam_engines.png`` (trajectories over the speed difference).
"""

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._common import RESULTS, machine  # noqa: E402

CASE = Path(__file__).resolve().parents[1] / "cases" / "river_piers" / "compare_engines.toml"
PIERS = [(600.0, 56.67), (600.0, 113.33), (900.0, 42.5), (900.0, 127.5)]
R = 15.0
GATES = {"bridge_A": (600.0, 0.0, 600.0, 170.0), "bridge_B": (900.0, 0.0, 900.0, 170.0),
         "x1200": (1200.0, 0.0, 1200.0, 170.0)}


def children_cpu():
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def solve(scen):
    """Compute the section with its engine; (SolveResult, wall s, CPU s)."""
    from driftlog.solving import solve_scenario

    w0, c0, k0 = time.perf_counter(), time.process_time(), children_cpu()
    res, path = solve_scenario(scen)
    wall = time.perf_counter() - w0
    cpu = (time.process_time() - c0) + (children_cpu() - k0)
    return res, path, wall, cpu


def flow_difference(flows):
    """Speed difference shallowWaterFoam - driftlog on the faces, near the piers and elsewhere;
    mean speed in the openings of each bridge."""
    d, f = flows["driftlog"], flows["shallowWaterFoam"]
    m = d.mesh
    sd, sf = d.snapshot(0), f.snapshot(0)
    spd, spf = np.hypot(sd["u"], sd["v"]), np.hypot(sf["u"], sf["v"])
    dist = np.min([np.hypot(m.face_x - x, m.face_y - y) for x, y in PIERS], axis=0)
    near = dist < 3 * R
    wake = np.zeros(m.n_faces, bool)
    for x, y in PIERS:  # two pier diameters downstream, one diameter wide
        wake |= (m.face_x > x + R) & (m.face_x < x + 5 * R) & (np.abs(m.face_y - y) < R)
    out = {"speed_rms_near_piers": float(np.sqrt(np.mean((spf - spd)[near] ** 2))),
           "speed_max_abs_near_piers": float(np.max(np.abs(spf - spd)[near])),
           "speed_rms_elsewhere": float(np.sqrt(np.mean((spf - spd)[~near] ** 2))),
           "wake_speed_driftlog": float(spd[wake].mean()),
           "wake_speed_shallowWaterFoam": float(spf[wake].mean()),
           "mean_speed_driftlog": float(np.sum(spd * m.face_area) / m.face_area.sum()),
           "mean_speed_shallowWaterFoam": float(np.sum(spf * m.face_area) / m.face_area.sum()),
           "level_drop_driftlog": float(_level(sd, m, 100) - _level(sd, m, 1400)),
           "level_drop_shallowWaterFoam": float(_level(sf, m, 100) - _level(sf, m, 1400))}
    for name, xb, ys in (("A", 600.0, [0, 56.67, 113.33, 170]),
                         ("B", 900.0, [0, 42.5, 127.5, 170])):
        for k in range(len(ys) - 1):
            lo, hi = ys[k] + (R if k else 0), ys[k + 1] - (R if k < len(ys) - 2 else 0)
            y = np.linspace(lo + 0.5, hi - 0.5, 60)
            for eng, fl in flows.items():
                s = fl.sample(np.full(y.size, xb), y, np.full(y.size, fl.times[-1]))
                out[f"opening_{name}{k}_speed_{eng}"] = float(np.nanmean(np.hypot(s.u, s.v)))
    return out


def _level(s, m, x0):
    sel = np.abs(m.face_x - x0) < 40
    return np.sum(s["eta"][sel] * m.face_area[sel]) / np.sum(m.face_area[sel])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="30 m cells, 1200 s of flow")
    ap.add_argument("--n-procs", type=int, default=1, help="OpenFOAM processes")
    args = ap.parse_args()
    from driftlog.adapters.openfoam_case import foam_available

    from driftlog.compare import compare_runs
    from driftlog.scenario import load_scenario
    from driftlog.sources import flow_from_scenario

    if not foam_available():
        sys.exit("OpenFOAM is not installed (Debian: apt-get install openfoam)")
    tmp = Path(tempfile.mkdtemp(prefix="engines_"))
    size = {"solver": {"cell_size": 30.0, "end": 1200.0, "output_interval": 600.0},
            "flow": {"steady_at": 1200.0}, "time": {"end": 600.0}} if args.quick else {}
    tag = "_quick" if args.quick else ""
    info = machine()
    print(info, flush=True)
    # compile driftlog's kernels first (numba cache), on a tiny run
    warm = load_scenario(CASE, overrides={"flow": {"path": str(tmp / "warm.nc")},
                                          "solver": {"cell_size": 80.0, "end": 20.0}})
    solve(warm)
    rows, flows, results = [], {}, {}
    for engine in ("driftlog", "shallowWaterFoam"):
        ov = {"flow": {"path": str(tmp / "flow.nc")},
              "solver": {"engine": engine, "n_procs": args.n_procs}}
        for k, v in size.items():
            ov[k] = {**ov.get(k, {}), **v}
        scen = load_scenario(CASE, overrides=ov)
        res, path, wall, cpu = solve(scen)
        n = scen["solver"]
        flows[engine] = flow_from_scenario(scen)  # the stored flow, frozen at steady_at
        faces = flows[engine].mesh.n_faces
        rows.append({"engine": engine, "faces": faces, "steps": res.steps,
                     "wall (s)": wall, "CPU (s)": cpu,
                     "cell-updates per CPU s": faces * res.steps / cpu,
                     "flow end (s)": res.t_end})
        results[engine] = dict(rows[-1], flow=str(path), cell_size=n["cell_size"])
        # how steady: speed change between the last two snapshots (one output interval)
        from driftlog.flowfile import open_flow

        full = open_flow(path)
        a, b = full.snapshot(full.times.size - 2), full.snapshot(full.times.size - 1)
        change = np.hypot(b["u"], b["v"]) - np.hypot(a["u"], a["v"])
        rows[-1]["speed change, last interval (RMS m/s)"] = float(np.sqrt(np.mean(change ** 2)))
        results[engine]["unsteadiness_interval_s"] = float(full.times[-1] - full.times[-2])
        print(rows[-1], flush=True)
    ov = {k: v for k, v in size.items() if k != "solver"}
    ov["flow"] = {**ov.get("flow", {}), "path": str(tmp / "flow.nc")}
    scen = load_scenario(CASE, overrides=ov)  # the logs; the flows are given below
    t0 = time.perf_counter()
    rep = compare_runs(scen, list(flows.items()), tmp / "compare", lines=GATES)
    track_wall = time.perf_counter() - t0
    diff = flow_difference(flows)
    c = rep["comparisons"]["shallowWaterFoam"]
    RESULTS.mkdir(parents=True, exist_ok=True)
    shutil.copy(tmp / "compare" / "compare.png", RESULTS / f"openfoam_engines{tag}.png")
    out = {"machine": info, "engines": results, "flow_difference": diff,
           "tracking_wall_s_both": track_wall, "comparison": c, "gates": GATES}
    (RESULTS / f"openfoam_engines{tag}.json").write_text(json.dumps(out, indent=2,
                                                                    default=float))
    md = [f"### river_piers on two engines{' (quick)' if args.quick else ''}", "",
          f"Measured on {info}.", "",
          "| engine | faces | steps | wall (s) | CPU (s) | cell-updates per CPU s | speed change "
          "over the last output interval (RMS, m/s) |",
          "|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        md.append(f"| {r['engine']} | {r['faces']} | {r['steps']} | {r['wall (s)']:.1f} | "
                  f"{r['CPU (s)']:.1f} | {r['cell-updates per CPU s']:.3g} | "
                  f"{r['speed change, last interval (RMS m/s)']:.3g} |")
    md += ["", "Flows (steady, shallowWaterFoam minus driftlog):", "",
           f"- speed RMS difference within 3 pier radii: {diff['speed_rms_near_piers']:.3f} m/s "
           f"(max {diff['speed_max_abs_near_piers']:.3f}); elsewhere "
           f"{diff['speed_rms_elsewhere']:.3f} m/s",
           f"- mean speed {diff['mean_speed_driftlog']:.3f} vs "
           f"{diff['mean_speed_shallowWaterFoam']:.3f} m/s; in the piers' wakes (2 diameters "
           f"downstream) {diff['wake_speed_driftlog']:.3f} vs "
           f"{diff['wake_speed_shallowWaterFoam']:.3f} m/s",
           f"- level drop x = 100 -> 1400 m: {diff['level_drop_driftlog']:.4f} vs "
           f"{diff['level_drop_shallowWaterFoam']:.4f} m"]
    for k in sorted(k for k in diff if k.startswith("opening_") and k.endswith("_driftlog")):
        base = k[:-len("_driftlog")]
        md.append(f"- {base.replace('_speed', '')}: speed {diff[k]:.3f} vs "
                  f"{diff[base + '_shallowWaterFoam']:.3f} m/s")
    md += ["", "Logs (driftlog reference vs shallowWaterFoam):", "",
           f"- end distance: mean {c['end_distance_mean']:.1f} m, max "
           f"{c['end_distance_max']:.1f} m; flow at the logs: speed RMS "
           f"{c['flow_at_logs']['speed_rms']:.3f} m/s",
           f"- statuses: {c['final_status']}",
           f"- hits: {c['hits']}"]
    for g, v in c["arrival_at_lines"].items():
        md.append(f"- {g}: crossed by {v['driftlog']['crossed']} / "
                  f"{v['shallowWaterFoam']['crossed']} logs, mean time "
                  f"{_f(v['driftlog']['mean_time'])} / {_f(v['shallowWaterFoam']['mean_time'])} s")
    md += ["", f"Tracking both (8 logs, contacts): {track_wall:.1f} s wall.", ""]
    text = "\n".join(md) + "\n"
    (RESULTS / f"openfoam_engines{tag}.md").write_text(text)
    print(text)
    print((tmp / "compare" / "compare.md").read_text())
    shutil.rmtree(tmp, ignore_errors=True)


def _f(v):
    return "-" if v is None else f"{v:.0f}"


if __name__ == "__main__":
    main()
