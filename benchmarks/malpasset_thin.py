"""Malpasset at order 2 against the thin-water fraction k of docs/model.md eq. (69).

Issue 14's hypothesis: the second order's thin-water desingularisation below
h_t,i = k max_j |z_j - z_i| (default k = 0.03: 0.1-0.3 m on 10 % and 1 % of Malpasset's faces,
up to 0.68 m) slows genuine flow a few decimetres deep, the front above all.  This runs
``malpasset_peers.py``'s driftlog order-2 run (the same set-up, process, timing and
comparison) once per k, one after the other, each in its own child process on one thread, and
tables steps, CPU time, the maximum-level RMSE over the 20 points every run wets, the worst
point, the arrival RMS over the 12 timed points and the per-point arrival errors, beside the
order-1 and ANUGA DE0 / DE1 rows of ``malpasset_peers_edgebed.json`` (the same comparison).

    python benchmarks/malpasset_thin.py                          # k = 0.03 0.01 0.003 0, 4000 s
    python benchmarks/malpasset_thin.py --k 0.03 0 --reuse       # skip the finished ones
    python benchmarks/malpasset_thin.py --report-only            # table what finished

Runs go to ``--work`` (default /tmp/malpasset_thin_<end>/k<k>/); writes
benchmarks/results/malpasset_peers_thin.{md,json,csv}.
"""

import os

os.environ["NUMBA_NUM_THREADS"] = "1"
os.environ["OMP_NUM_THREADS"] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, write_table  # noqa: E402
from malpasset_peers import FULL_END, _commit, compare_run, data_dir, run_child  # noqa: E402

K_DEFAULT = (0.03, 0.01, 0.003, 0.0)
LEVEL_POINTS = ("G10", "G11", "G12", "G13", "G14", "G6", "G7", "G8", "G9", "P1", "P10",
                "P11", "P15", "P2", "P3", "P4", "P5", "P6", "P8", "P9")
ARRIVAL_POINTS = ("A", "B", "C", "G10", "G11", "G12", "G13", "G14", "G6", "G7", "G8", "G9")
PEERS = RESULTS / "malpasset_peers_edgebed.json"
GEOCLAW_2011 = (84.56, 87.029, 55.453, 58.175, 48.559, 48.351, 42.064, 36.863, 34.121, 40.172,
                25.962, 27.164, 22.216, 21.827, 19.484, 19.89, 16.679,  # P1-P17
                85.653, 56.364, 53.304, 48.762, 38.684, 26.616, 20.445, 18.218, 13.169)  # G6-G14


def _row(label, facts, points, k=None):
    lev = {p["id"]: p["level_error_m"] for p in points}
    arr = {p["id"]: p["arrival_error_s"] for p in points}
    le = np.array([lev[i] for i in LEVEL_POINTS])
    ae = np.array([arr[i] for i in ARRIVAL_POINTS])
    worst = LEVEL_POINTS[int(np.nanargmax(np.abs(le)))]
    row = {"run": label, "k": "-" if k is None else f"{k:g}",
           "steps": facts.get("steps", np.nan), "cpu_s": facts.get("cpu_s", np.nan),
           "level_rmse_m": float(np.sqrt(np.mean(le ** 2))),
           "worst_point": f"{worst} {lev[worst]:+.1f} m",
           "points_over_6m": int(np.sum(np.abs(le) > 6.0)),
           "level_rmse_without_G9_m": float(np.sqrt(np.mean(
               [lev[i] ** 2 for i in LEVEL_POINTS if i != "G9"]))),
           "arrival_rms_s": float(np.sqrt(np.mean(ae ** 2))),
           "arrival_rms_without_G13_G14_s": float(np.sqrt(np.mean(
               [arr[i] ** 2 for i in ARRIVAL_POINTS if i not in ("G13", "G14")])))}
    for i in ("G9", "P4", "G7", "P1"):
        row[f"{i}_level_m"] = lev[i]
    for i in ("G12", "G13", "G14", "B", "C"):
        row[f"{i}_arrival_s"] = arr[i]
    return row


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--k", type=float, nargs="+", default=list(K_DEFAULT),
                   help="thin-water fractions to run (0: no thin-layer treatment)")
    p.add_argument("--end", type=float, default=FULL_END)
    p.add_argument("--work", default=None, help="folder of the runs (one sub-folder per k)")
    p.add_argument("--reuse", action="store_true", help="skip runs already finished")
    p.add_argument("--report-only", action="store_true", help="table the finished runs only")
    a = p.parse_args(argv)
    work = Path(a.work or f"/tmp/malpasset_thin_{a.end:g}")
    if a.end < FULL_END:
        raise SystemExit("the per-point comparison needs the full flood (--end 4000)")
    for k in a.k:
        wk = work / f"k{k:g}"
        if a.report_only or (a.reuse and (wk / "driftlog-o2.npz").is_file()):
            continue
        print(f"k = {k:g}: running to {a.end:g} s ...", flush=True)
        facts = run_child("driftlog-o2", a.end, wk, thin_fraction=k)
        facts["commit"] = _commit()
        (wk / "driftlog-o2.json").write_text(json.dumps(facts, indent=1))
        print(f"k = {k:g}: {facts['steps']} steps, {facts['cpu_s']:.1f} CPU s", flush=True)

    from driftlog.floodsetup import read_observations
    from driftlog.mesh import read_mesh

    observations = read_observations(data_dir() / "observations.csv")
    mesh = read_mesh(data_dir() / "malpasset_mesh.nc")
    rows, out = [], {}
    for k in a.k:
        wk = work / f"k{k:g}"
        if not (wk / "driftlog-o2.npz").is_file():
            continue
        facts, points, _ = compare_run("driftlog-o2", wk, a.end, mesh, observations)
        rows.append(_row("driftlog order 2", facts, points, k))
        out[f"k{k:g}"] = {"facts": facts, "points": points, "row": rows[-1]}
    if not rows:
        raise SystemExit(f"no finished run under {work}")
    if PEERS.is_file():  # the reference rows, same comparison, from the peers' run
        peers = json.loads(PEERS.read_text())["runs"]
        for n in ("driftlog-o1", "anuga-DE0", "anuga-DE1", "driftlog-o2"):
            if n in peers:
                r = peers[n]
                rows.append(_row(r["facts"]["label"] + " (peers_edgebed)", r["facts"],
                                 r["points"], r["facts"].get("thin_fraction")
                                 if n == "driftlog-o2" else None))
                if n == "driftlog-o2":
                    rows[-1]["k"] = "0.03"
    # GeoClaw's published run (George 2011, Int. J. Numer. Meth. Fluids 66:1000-1018; adaptive
    # Cartesian grids, not this mesh): its maximum levels as digitised in the GeoClaw-landspill
    # reproducibility package (barbagroup/geoclaw-landspill-paper,
    # repro-pack/postprocessing/malpasset_dam_break.py); no arrival times there
    obs = {o["id"]: o["max_level_m"] for o in observations}
    geo = dict(zip([f"P{i}" for i in range(1, 18)] + [f"G{i}" for i in range(6, 15)],
                   GEOCLAW_2011, strict=True))
    pts = [{"id": i, "level_error_m": geo[i] - obs[i] if i in geo else np.nan,
            "arrival_error_s": np.nan} for i in set(LEVEL_POINTS) | set(ARRIVAL_POINTS)]
    rows.append(_row("GeoClaw (George 2011, levels only)", {}, pts))
    machines = sorted({v["facts"]["machine"] for v in out.values()})
    notes = (
        f"Malpasset, {a.end:g} s, 46691 triangles, driftlog order 2 with the thin-water "
        "fraction k of docs/model.md (69) (0: no thin-layer treatment), each in its own "
        "process on one thread, one run after the other (the set-up and comparison of "
        "malpasset_peers.py). level_rmse_m over the 20 points every run wets "
        f"({', '.join(LEVEL_POINTS)}); arrival_rms_s over the 12 timed points "
        f"({', '.join(ARRIVAL_POINTS)}; arrival: depth > 0.05 m); errors computed minus "
        "observed. Rows marked (peers_edgebed): malpasset_peers_edgebed.json, the same "
        "comparison, earlier commits and other load. GeoClaw (George 2011): its published "
        "maximum levels (adaptive Cartesian grids, its own topography) as digitised in "
        "barbagroup/geoclaw-landspill-paper, compared with the same observations. "
        f"Machines: {'; '.join(machines)}. "
        f"Commit: {next(iter(out.values()))['facts'].get('commit', '-')}.")
    columns = ["run", "k", "steps", "cpu_s", "level_rmse_m", "worst_point", "points_over_6m",
               "level_rmse_without_G9_m", "arrival_rms_s", "arrival_rms_without_G13_G14_s",
               "G9_level_m", "P4_level_m", "G7_level_m", "P1_level_m", "G12_arrival_s",
               "G13_arrival_s", "G14_arrival_s", "B_arrival_s", "C_arrival_s"]
    write_table("malpasset_peers_thin", rows, columns,
                "Malpasset at order 2 against the thin-water fraction k (4000 s)", notes)
    (RESULTS / "malpasset_peers_thin.json").write_text(json.dumps(
        {"end_s": a.end, "runs": out, "table": rows, "notes": notes}, indent=1,
        default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
