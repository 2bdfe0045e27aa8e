"""The malpasset case's logs: where the 1959 flood carried them, where they stranded, when
they reached the sea.

Runs the case (cases/malpasset/scenario.toml: the flood on driftlog's solver, computed once and
stored in its flow file, then 40 logs released on the dry valley floor) and summarises each
release line: logs stranded (on ground the flood left), still floating at 4000 s, reaching the
sea (a face of the sea: bed below 0 m, connected to the coast), the time they reach it, and
how far down the valley they end.  Writes benchmarks/results/malpasset_logs{.md,.json,.png}.

    python benchmarks/malpasset_logs.py                       # the case as it is
    python benchmarks/malpasset_logs.py --flow /tmp/m.nc      # on a stored flow of the flood
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
CASE = ROOT / "cases" / "malpasset" / "scenario.toml"
STATUS = ["waiting", "floating", "resting", "stranded", "left_domain"]
FREJUS_X = 13000.0  # m: transformer C, at the western edge of Frejus and its coastal plain


def fates(traj, flow, observations, dam):
    """Per log: group, final status, chainage at the end, first time on a sea face."""
    from malpasset_compare import chainage

    from driftlog.floodsetup import low_boundary_edges, sea_faces
    from driftlog.mesh import read_mesh
    from driftlog.trajectory import open_trajectories

    mesh = read_mesh(flow)
    bed = mesh.face_bed()
    sea = sea_faces(mesh, bed, 0.0, low_boundary_edges(mesh, 0.0))
    ds = open_trajectories(traj)
    x, y, t = ds["x"].values, ds["y"].values, ds["time"].values
    st, idx = ds["status"].values, ds["trajectory_index"].values
    group = ds["group"].values if "group" in ds else np.zeros(ds.sizes["trajectory"], int)
    rows = []
    for i in range(ds.sizes["trajectory"]):
        k = idx == i
        xi, yi, ti, si = x[k], y[k], t[k], st[k]
        f = mesh.locate(xi, yi)
        on_sea = (f >= 0) & sea[np.where(f >= 0, f, 0)]
        moved = np.hypot(xi - xi[0], yi - yi[0]) > 0.0
        rows.append({"log": i, "group": int(group[i]), "status": STATUS[int(si[-1])],
                     "start_km": float(chainage([(xi[0], yi[0])], observations, dam)[0] / 1e3),
                     "end_km": float(chainage([(xi[-1], yi[-1])], observations, dam)[0] / 1e3),
                     "x_end": float(xi[-1]), "y_end": float(yi[-1]),
                     "lift_off_s": float(ti[np.argmax(moved)]) if moved.any() else np.nan,
                     "sea_s": float(ti[np.argmax(on_sea)]) if on_sea.any() else np.nan,
                     "frejus_s": float(ti[np.argmax(xi >= FREJUS_X)]) if np.any(
                         xi >= FREJUS_X) else np.nan})
    return rows, mesh


def summary(rows, names):
    """Per release line: counts of each fate and the times to the sea."""
    out = []
    for g, name in enumerate(names):
        rs = [r for r in rows if r["group"] == g]
        sea = np.array([r["sea_s"] for r in rs if np.isfinite(r["sea_s"])])
        frejus = np.array([r["frejus_s"] for r in rs if np.isfinite(r["frejus_s"])])
        lift = np.array([r["lift_off_s"] for r in rs if np.isfinite(r["lift_off_s"])])
        strand = [r["end_km"] for r in rs if r["status"] == "stranded"
                  and not np.isfinite(r["sea_s"])]
        out.append({"line": name, "logs": len(rs), "lifted": int(lift.size),
                    "reached_frejus": int(frejus.size),
                    "first_at_frejus_s": float(frejus.min()) if frejus.size else None,
                    "median_at_frejus_s": float(np.median(frejus)) if frejus.size else None,
                    "lift_off_s": [float(lift.min()), float(lift.max())] if lift.size else None,
                    "reached_sea": int(sea.size),
                    "first_at_sea_s": float(sea.min()) if sea.size else None,
                    "median_at_sea_s": float(np.median(sea)) if sea.size else None,
                    "stranded_on_land": len(strand),
                    "stranded_km": [float(min(strand)), float(max(strand))] if strand else None,
                    "final": {s: sum(r["status"] == s for r in rs) for s in STATUS}})
    return out


def _figure(rows, mesh, names, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    tri = Triangulation(mesh.node_x, mesh.node_y, mesh.face_nodes[:, :3])
    fig, ax = plt.subplots(figsize=(11, 5))
    ax.tripcolor(tri, facecolors=mesh.face_bed(), cmap="Greys", alpha=0.5)
    for g, name in enumerate(names):
        rs = [r for r in rows if r["group"] == g]
        sc = ax.scatter([r["x_end"] for r in rs], [r["y_end"] for r in rs], s=14,
                        label=f"{name}: end positions", marker="osd^"[g % 4])
        sea = [r for r in rs if np.isfinite(r["sea_s"])]
        ax.scatter([r["x_end"] for r in sea], [r["y_end"] for r in sea], s=40,
                   facecolors="none", edgecolors=sc.get_facecolor()[0], lw=0.6)
    ax.set(aspect="equal", xlabel="x (m)", ylabel="y (m)",
           title="Malpasset: where the logs ended at 4000 s (circled: reached the sea)")
    ax.axvline(FREJUS_X, color="k", lw=0.6, ls=":")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--flow", help="a stored flow file of the flood (else the case computes "
                   "or reuses its own)")
    p.add_argument("--out", default="/tmp/malpasset_logs.nc", help="trajectory file")
    a = p.parse_args(argv)
    import tomllib

    from driftlog.api import track
    from driftlog.floodsetup import MALPASSET_DAM, read_observations

    over = {"flow": {"source": "file", "path": a.flow}} if a.flow else None
    t0 = time.perf_counter()
    res = track(CASE, output=a.out, overrides=over, progress=True)
    wall = time.perf_counter() - t0
    names = [g["name"] for g in tomllib.loads(CASE.read_text())["logs"]]
    obs = read_observations(CASE.parent / "data" / "observations.csv")
    flow = a.flow or str(CASE.parent / "malpasset_flow.nc")
    rows, mesh = fates(res.path, flow, obs, MALPASSET_DAM)
    summ = summary(rows, names)
    lines = ["### Malpasset case: the logs", "",
             f"{len(rows)} logs (8 m, r = 0.2 m, 700 kg/m3) released at t = 0 on the dry "
             f"valley floor, tracked {res.stats.get('substeps', '?')} sub-steps in {wall:.0f} s "
             f"(physics {res.physics['level']}: {res.physics['reason'] or 'as set'}) on "
             f"{machine()}. Sea: faces below 0 m connected to the coast. Chainage: along the "
             "valley from the dam (dam, G6, ..., G14, C).", "",
             f"Frejus: x >= {FREJUS_X:g} m (transformer C, the coastal plain).", "",
             "| release line | logs | lifted | lift-off (s) | reached Frejus | first there (s) "
             "| median there (s) | reached the sea | stranded on land | stranded at (km) "
             "| final status |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]

    def num(v):
        return "-" if v is None else str(round(v))

    def rng(v, nd=0):
        return "-" if v is None else f"{v[0]:.{nd}f}-{v[1]:.{nd}f}"

    for s in summ:
        fin = ", ".join(f"{k} {v}" for k, v in s["final"].items() if v)
        lines.append(f"| {s['line']} | {s['logs']} | {s['lifted']} | {rng(s['lift_off_s'])} | "
                     f"{s['reached_frejus']} | "
                     f"{num(s['first_at_frejus_s'])} | {num(s['median_at_frejus_s'])} | "
                     f"{s['reached_sea']} | "
                     f"{s['stranded_on_land']} | {rng(s['stranded_km'], 1)} | {fin} |")
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "malpasset_logs.md").write_text(text)
    (RESULTS / "malpasset_logs.json").write_text(json.dumps(
        {"summary": summ, "logs": rows, "physics": res.physics, "wall_s": wall}, indent=1,
        default=float))
    _figure(rows, mesh, names, RESULTS / "malpasset_logs.png")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
