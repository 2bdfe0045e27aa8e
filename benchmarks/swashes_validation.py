"""The shallow-water solver against SWASHES exact solutions (1D cases run as 2D strips).

Every case runs on a strip one cell wide (squares, walls on the banks) at three or more
resolutions, first and second order; the L1 error of the depth against SWASHES at the cell
centres and the observed order go into a table (Markdown + JSON) and one figure:

    python benchmarks/swashes_validation.py            # 4 resolutions per case
    python benchmarks/swashes_validation.py --quick    # 3 coarser resolutions (the report)

Steady cases start from the exact solution and run until the scheme has settled to its own
steady state (SWASHES starts them from rest; the steady state is the same and the runs are
shorter).  Dam breaks start from the dam at rest and stop at SWASHES' time (6 s).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import RESULTS, machine  # noqa: E402

from driftlog.mesher import channel_mesh  # noqa: E402
from driftlog.solver import ShallowWaterSolver  # noqa: E402
from driftlog.solver.swashes import macdonald_bed, swashes_solution  # noqa: E402


def bump(x):
    return np.maximum(0.0, 0.2 - 0.05 * (x - 10.0) ** 2)


# name, SWASHES (type, domain, choice), length (m), how to run, resolution factor
CASES = [
    dict(name="lake at rest, immersed bump", sw=(1, 1, 4), length=25.0, kind="rest", level=0.5,
         t_end=20.0, factor=1),
    dict(name="lake at rest, emerged bump", sw=(1, 1, 5), length=25.0, kind="rest", level=0.1,
         t_end=20.0, factor=1),
    dict(name="subcritical over a bump", sw=(1, 1, 1), length=25.0, kind="steady", q=4.42,
         outflow={"type": "level", "value": 2.0}, t_end=60.0, factor=1),
    dict(name="transcritical, no shock", sw=(1, 1, 2), length=25.0, kind="steady", q=1.53,
         outflow={"type": "free"}, t_end=60.0, factor=1),
    dict(name="transcritical with shock", sw=(1, 1, 3), length=25.0, kind="steady", q=0.18,
         outflow={"type": "level", "value": 0.33}, t_end=200.0, factor=1),
    dict(name="MacDonald long channel, Manning", sw=(2, 1, 2), length=1000.0, kind="steady",
         q=2.0, outflow={"type": "level", "value": 0.748324}, manning=0.033, t_end=1500.0,
         factor=1, bed=macdonald_bed),
    dict(name="Stoker dam break (wet)", sw=(3, 1, 1), length=10.0, kind="dam", h=(0.005, 0.001),
         t_end=6.0, factor=2),
    dict(name="Ritter dam break (dry)", sw=(3, 1, 2), length=10.0, kind="dam", h=(0.005, 0.0),
         t_end=6.0, factor=2),
]


def run_case(case, n, order):
    length = case["length"]
    dx = length / n
    mesh = channel_mesh(length, dx, dx, structured=True)
    exact = swashes_solution(*case["sw"], n)
    assert np.allclose(exact["x"], mesh.face_x, atol=1e-9 * length)
    if "bed" in case:  # the exact bed (SWASHES' printed one is O(dx) off: macdonald_bed)
        bed = case["bed"](mesh.face_x)
    elif case["kind"] == "steady":
        bed = exact["topo"].copy()
    else:
        bed = bump(mesh.face_x) if case["kind"] == "rest" else np.zeros(n)
    bc = {}
    if case["kind"] == "steady":
        bc = {"inflow": {"type": "discharge", "value": case["q"] * dx},
              "outflow": case["outflow"]}
    s = ShallowWaterSolver(mesh, bed=bed, order=order, manning=case.get("manning"),
                           boundaries=bc)
    if case["kind"] == "rest":
        s.set_level(case["level"])
    elif case["kind"] == "steady":
        s.set_state(exact["h"], exact["q"], 0.0)
    else:
        hl, hr = case["h"]
        s.set_state(np.where(mesh.face_x < 5.0, hl, hr))
    t0 = time.perf_counter()
    res = s.run(case["t_end"])
    wall = time.perf_counter() - t0
    err = float(np.mean(np.abs(s.h - exact["h"])))
    speed = np.hypot(s.hu, s.hv) / np.maximum(s.h, 1e-300)
    return dict(case=case["name"], order=order, n=n, dx=dx, l1_h=err,
                max_speed=float(speed.max()), steps=res.steps, wall_s=wall,
                rel_volume_error=res.relative_volume_error,
                x=mesh.face_x.tolist(), h=s.h.tolist(), exact=exact["h"].tolist(),
                bed=bed.tolist())


def observed_orders(rows):
    """log2(e(n) / e(2n)) between successive resolutions, and the least-squares slope."""
    for r in rows:
        r["order_obs"] = ""
    for i in range(1, len(rows)):
        a, b = rows[i - 1], rows[i]
        if a["l1_h"] > 0 and b["l1_h"] > 0:
            b["order_obs"] = float(np.log(a["l1_h"] / b["l1_h"]) / np.log(a["dx"] / b["dx"]))
    dx = np.array([r["dx"] for r in rows])
    e = np.array([r["l1_h"] for r in rows])
    return float(np.polyfit(np.log(dx), np.log(e), 1)[0]) if np.all(e > 0) else float("nan")


NOTES = {
    "lake at rest, immersed bump": "well balanced: error and speed at round-off, no order",
    "lake at rest, emerged bump": "well balanced with a dry bump top: round-off, no order",
    "transcritical with shock": "a shock: order 1 at most in L1 asymptotically (second order "
                                "still gains on the smooth parts at these sizes)",
    "Stoker dam break (wet)": "shock and contact discontinuities: order < 1 expected",
    "Ritter dam break (dry)": "dry front (h ~ (x_f - x)^2 kink): order about 1 or less",
    "subcritical over a bump": "smooth (but for the bed's kinks at x = 8 and 12 m): order 1 "
                               "and 2 expected",
    "transcritical, no shock": "smooth but sonic at the crest (limiter clips there)",
    "MacDonald long channel, Manning": "smooth on a steep bed (0.07 m per 10 m cell on "
                                       "0.75 m depth), near critical (Fr 0.98 at the ends); "
                                       "the exact bed (macdonald_bed), not SWASHES' O(dx) "
                                       "printed one: order 1 and 2 expected",
}


def figure(table, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [c["name"] for c in CASES]
    fig, axes = plt.subplots(3, 3, figsize=(15, 12))
    for ax, name in zip(axes.flat, names, strict=False):
        rows = [r for r in table if r["case"] == name]
        if not rows:
            ax.set_visible(False)
            continue
        finest = max(r["n"] for r in rows)
        for r in rows:
            if r["n"] != finest:
                continue
            x = np.array(r["x"])
            if r["order"] == 1:
                ax.plot(x, np.array(r["exact"]) + np.array(r["bed"]), "k-", lw=1.5,
                        label="SWASHES")
                ax.fill_between(x, np.min(r["bed"]) - 0.02 * (np.ptp(r["exact"]) + 1e-3),
                                np.array(r["bed"]), color="0.85")
            ax.plot(x, np.array(r["h"]) + np.array(r["bed"]), "--" if r["order"] == 2 else ":",
                    lw=1.3, label=f"order {r['order']}, {finest} cells")
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("level (m)")
        ax.legend(fontsize=7)
    ax = axes.flat[-1]
    for name in names:
        for order, style in ((1, "o-"), (2, "s--")):
            rows = [r for r in table if r["case"] == name and r["order"] == order]
            if not rows or not all(r["l1_h"] > 1e-14 for r in rows):
                continue
            ax.loglog([r["dx"] / rows[0]["dx"] for r in rows], [r["l1_h"] for r in rows],
                      style, ms=3, label=f"{name[:18]} o{order}")
    ax.set_xlabel("dx / coarsest dx")
    ax.set_ylabel("L1 error of h (m)")
    ax.set_title("convergence")
    ax.legend(fontsize=5, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 coarser resolutions")
    ap.add_argument("--cases", nargs="*", help="only cases whose name contains these words")
    args = ap.parse_args(argv)
    base = [25, 50, 100] if args.quick else [50, 100, 200, 400]
    table, summary = [], []
    cases = [c for c in CASES if not args.cases or any(w in c["name"] for w in args.cases)]
    for case in cases:
        for order in (1, 2):
            rows = [run_case(case, n * case["factor"], order) for n in base]
            slope = observed_orders(rows)
            if case["kind"] == "rest":  # round-off (and SWASHES' 7 printed digits): no order
                slope = float("nan")
                for r in rows:
                    r["order_obs"] = ""
            for r in rows:
                o = "" if r["order_obs"] == "" else f"{r['order_obs']:.2f}"
                print(f"{r['case']:<33} o{order} n={r['n']:<5} L1(h)={r['l1_h']:.3e} "
                      f"order={o} max|u|={r['max_speed']:.1e} steps={r['steps']} "
                      f"{r['wall_s']:.1f}s", flush=True)
            table += rows
            summary.append(dict(case=case["name"], order=order, slope=slope,
                                finest_l1=rows[-1]["l1_h"], note=NOTES.get(case["name"], "")))
    RESULTS.mkdir(parents=True, exist_ok=True)
    stem = "swashes_validation" + ("_quick" if args.quick else "")
    lines = [f"### Solver vs SWASHES ({'quick' if args.quick else 'full'})", "",
             f"Measured on {machine()}. Strips one cell wide (squares), walls on the banks; "
             "L1(h) = mean |h - h_exact| over the cells (m); order = log(e_coarse / e_fine) / "
             "log(dx_coarse / dx_fine).", "",
             "| case | order | cells | dx (m) | L1(h) (m) | observed order | max speed (m/s) "
             "| steps | wall (s) |", "|---|---|---|---|---|---|---|---|---|"]
    for r in table:
        o = f"{r['order_obs']:.2f}" if r["order_obs"] != "" else ""
        lines.append(f"| {r['case']} | {r['order']} | {r['n']} | {r['dx']:.4g} | "
                     f"{r['l1_h']:.3e} | {o} | {r['max_speed']:.1e} | {r['steps']} | "
                     f"{r['wall_s']:.1f} |")
    lines += ["", "| case | order | fitted order | L1(h), finest | expected |",
              "|---|---|---|---|---|"]
    for s in summary:
        lines.append(f"| {s['case']} | {s['order']} | {s['slope']:.2f} | "
                     f"{s['finest_l1']:.3e} | {s['note']} |")
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{stem}.md").write_text(text)
    slim = [{k: v for k, v in r.items() if k not in ("x", "h", "exact", "bed")} for r in table]
    (RESULTS / f"{stem}.json").write_text(json.dumps(dict(machine=machine(), rows=slim,
                                                          summary=summary), indent=1))
    figure(table, RESULTS / f"{stem}.png")
    print(text)
    print(f"wrote {RESULTS / stem}.md, .json, .png")


if __name__ == "__main__":
    main()
