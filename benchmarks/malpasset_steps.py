"""Why order 2 costs what it does on Malpasset: steps, the face that sets each step, time per step.

Issue 14 (item 2): the second order's time step should be the first order's CFL step.  This
runs the Malpasset dam break (``driftlog.floodsetup.malpasset_solver``, the set-up of
``benchmarks/malpasset.py``) at order 1 and/or 2 on one thread and records, for every step:
the step dt, whether the corrector redid it, the face whose bound set it (its depth, speed,
wet neighbours, the largest edge contribution to its bound and that edge's neighbour), the
active set's size and the CPU time of the step.  Per window of ``--window`` simulated seconds
it tables steps per simulated second, CPU per step, active faces, redone steps, and the faces
that set the most steps (how deep, how fast, how often).

    python benchmarks/malpasset_steps.py --end 1200 --orders 1 2
    python benchmarks/malpasset_steps.py --end 4000 --orders 2 --tag after

writes benchmarks/results/malpasset_steps{_<tag>}.md and .json (per window, both orders).
"""

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine  # noqa: E402
from malpasset import data_dir  # noqa: E402


def _setter(solver):
    """The face that sets the step now (internal index) and the details of its bound."""
    m = solver
    rate = m._res[3]
    f = int(np.argmax(rate))
    h = m._h[f]
    spd = float(np.hypot(m._hu[f], m._hv[f]) / h) if h > m.dry_depth else 0.0
    # the edge contributing most to the face's bound
    sp, sp1 = m._flux[5], m._flux[6]
    best, kbest = -1.0, -1
    for k in range(m._fn[f]):
        e = m._fe[f, k]
        c = sp[e] if (m.order == 1 or m._side[f, k]) else sp1[e]
        if c > best:
            best, kbest = c, k
    e = m._fe[f, kbest]
    j = int(m._nbr[f, kbest])
    hj = float(m._h[j]) if j >= 0 else -1.0
    sj = float(np.hypot(m._hu[j], m._hv[j]) / m._h[j]) if j >= 0 and m._h[j] > m.dry_depth \
        else 0.0
    share = 1.0
    he = h
    if m.order == 2:
        he = float(m._est[m._rows[f, kbest], 0])
        share = max(1.0, he / h) if h > 0 else 1.0
    wave = best / m._len[e] / share  # the edge's wave speed s_e
    return dict(face=int(m._perm[f]) if not m._identity else f, h=float(h), speed=spd,
                rate=float(rate[f]), frac_edge=float(best / m._area[f] / rate[f]),
                s_e=float(wave), share=float(share), h_edge=float(he), nbr_h=hj, nbr_speed=sj,
                nbr=int(m._perm[j]) if (j >= 0 and not m._identity) else j,
                length=float(m._len[e]), area=float(m._area[f]))


def run(order, end, window, options):
    from driftlog.floodsetup import malpasset_solver

    solver = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=order, **options)
    h0 = solver.h.copy()
    solver.step(1e-3)  # compile / load kernels
    solver.set_state(h0)
    solver.rejected_steps = 0
    rows = []
    t_next = window
    cur = dict(steps=0, cpu=0.0, active=0, rejected=0, setters=Counter(), details={})
    cpu_total = 0.0
    while solver.t < end - 1e-9:
        sample = (cur["steps"] + 1) % 5 == 0
        if sample:  # the rates of this step's first stage (the step recomputes the same)
            solver._rates(solver._h, solver._hu, solver._hv, solver.t)
            d = _setter(solver)
            cur["setters"][d["face"]] += 1
            cur["details"].setdefault(d["face"], []).append(d)
        rej0 = solver.rejected_steps
        c0 = time.process_time()
        solver.step(min(t_next, end) - solver.t)
        c1 = time.process_time()
        cpu_total += c1 - c0
        cur["steps"] += 1
        cur["cpu"] += c1 - c0
        cur["active"] += solver.active_faces
        cur["rejected"] += solver.rejected_steps - rej0
        if solver.t >= t_next - 1e-9:
            top = []
            for face, n in cur["setters"].most_common(4):
                ds = cur["details"][face]
                top.append(dict(face=face, samples=n,
                                h=float(np.median([x["h"] for x in ds])),
                                speed=float(np.median([x["speed"] for x in ds])),
                                s_e=float(np.median([x["s_e"] for x in ds])),
                                share=float(np.median([x["share"] for x in ds])),
                                nbr_h=float(np.median([x["nbr_h"] for x in ds])),
                                nbr_speed=float(np.median([x["nbr_speed"] for x in ds])),
                                length=ds[0]["length"], area=ds[0]["area"]))
            wet = int(np.count_nonzero(solver._h > solver.dry_depth))
            row = dict(t=float(solver.t), steps=cur["steps"], cpu_s=cur["cpu"],
                       cpu_per_step_ms=1e3 * cur["cpu"] / cur["steps"],
                       mean_active=cur["active"] / cur["steps"], wet=wet,
                       rejected=cur["rejected"], dt_mean=window / cur["steps"], top=top,
                       samples=sum(cur["setters"].values()))
            rows.append(row)
            t0 = top[0] if top else {}
            print(f"o{order} t={solver.t:6.0f} steps={cur['steps']:5d} "
                  f"cpu/step={row['cpu_per_step_ms']:6.2f}ms active={row['mean_active']:7.0f} "
                  f"wet={wet:6d} rej={cur['rejected']:4d} | top setter face {t0.get('face')} "
                  f"{t0.get('samples')}/{row['samples']} h={t0.get('h', 0):.3g} "
                  f"u={t0.get('speed', 0):.3g} s_e={t0.get('s_e', 0):.3g} "
                  f"share={t0.get('share', 0):.3g} nbr_h={t0.get('nbr_h', 0):.3g} "
                  f"L={t0.get('length', 0):.3g} A={t0.get('area', 0):.3g}", flush=True)
            cur = dict(steps=0, cpu=0.0, active=0, rejected=0, setters=Counter(), details={})
            t_next += window
    return dict(order=order, steps=solver.steps, cpu_s=cpu_total,
                rejected=solver.rejected_steps, windows=rows,
                volume_error=solver.volume_error() / solver.initial_volume)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--end", type=float, default=1200.0)
    p.add_argument("--window", type=float, default=60.0)
    p.add_argument("--orders", type=int, nargs="+", default=[1, 2])
    p.add_argument("--tag", default="")
    p.add_argument("--thin-fraction", type=float, default=None)
    a = p.parse_args(argv)
    out = {"machine": machine(), "end_s": a.end, "window_s": a.window, "runs": []}
    for order in a.orders:
        opts = {}
        if order == 2 and a.thin_fraction is not None:
            opts["thin_fraction"] = a.thin_fraction
        out["runs"].append(run(order, a.end, a.window, opts))
    name = "malpasset_steps" + (f"_{a.tag}" if a.tag else "")
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))
    lines = [f"# Malpasset: steps and the faces that set them ({a.end:g} s)", "",
             f"{out['machine']}", ""]
    for r in out["runs"]:
        lines += [f"## order {r['order']}: {r['steps']} steps, {r['cpu_s']:.1f} CPU s, "
                  f"{r['rejected']} redone, volume error {r['volume_error']:.2g}", "",
                  "| window end (s) | steps | CPU/step (ms) | active faces | wet faces | redone "
                  "| top setter: face, share of samples, h (m), |u| (m/s), s_e (m/s), "
                  "h_e/h, neighbour h (m) |",
                  "|---:|---:|---:|---:|---:|---:|---|"]
        for w in r["windows"]:
            t0 = w["top"][0] if w["top"] else None
            s = (f"{t0['face']}, {t0['samples']}/{w['samples']}, {t0['h']:.3g}, "
                 f"{t0['speed']:.3g}, {t0['s_e']:.3g}, {t0['share']:.3g}, {t0['nbr_h']:.3g}"
                 if t0 else "")
            lines.append(f"| {w['t']:.0f} | {w['steps']} | {w['cpu_per_step_ms']:.2f} | "
                         f"{w['mean_active']:.0f} | {w['wet']} | {w['rejected']} | {s} |")
        lines.append("")
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {RESULTS / name}.md, .json")


if __name__ == "__main__":
    main()
