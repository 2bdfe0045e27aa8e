"""Malpasset at order 2: the energy bound (docs/model.md eq. (85)) against accuracy and the front.

Issue 14: order 2 makes energy (heads above the reservoir's 100 m) where the continuous edge
bed (84) leaves the edge depth unbounded; the energy bound removes it but made the flood late
(BENCHMARKS.md).  This runs the flood of ``malpasset.py`` (issue's mesh, 46,691 triangles) at
one order and one ``energy_bound`` for ``--end`` s and records, in one pass:

- the largest total head h + z + |u|^2 / (2 g) over faces deeper than 1 m at every step of the
  first ``HEAD_END`` s (and after the first ``LATE`` s), as ``malpasset_overshoot.py
  --every-step`` does;
- per-point maximum levels and arrival times against the observations (``malpasset_compare``:
  level RMSE over the 20 wetted points, worst point, arrival RMS over the timed points);
- the front's chainage down the valley every ``--every`` s (the farthest face deeper than the
  arrival depth, 0.05 m, on the dam -> G6 ... G14 -> C line of ``malpasset_compare.chainage``);
- what each wet face's reconstruction got (faces dry at the start only: not the reservoir
  nor the sea) at every step (the gradient kernel's ``mark``, after
  the corrector's stage): second order, first order (dry, front, depth ratio), the velocity
  check's fall-back, the energy bound's fall-back (full or partial), as fractions of the wet
  faces (deeper than 0.05 m) and of the front's faces (those the flood reached in the last
  ``FRONT_AGE`` s), per record interval and per 500-m chainage bin.

Each run is an entry of ``benchmarks/results/malpasset_energy.json`` (kept across
invocations: one run at a time), and the tables of every run there go to
``malpasset_energy.md``.

    python benchmarks/malpasset_energy.py --order 2 --bound g2            # 4000 s
    python benchmarks/malpasset_energy.py --order 2 --bound off --end 1500
    python benchmarks/malpasset_energy.py --report-only

One process, one thread (``NUMBA_NUM_THREADS=1``); a 4000-s order-2 run takes 5-10 CPU min.
"""

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine  # noqa: E402
from malpasset import data_dir  # noqa: E402
from malpasset_compare import chainage, extremes_points, headline  # noqa: E402

from driftlog.floodsetup import MALPASSET_DAM, malpasset_solver, read_observations  # noqa: E402

HEAD_DEPTH = 1.0  # m: faces deeper than this count in the largest head
HEAD_END = 300.0  # s: the largest head is tracked at every step up to here
LATE = 30.0  # s: the dam break's first rarefaction is over
FRONT_AGE = 60.0  # s: a face the flood reached this recently is in the front's region
WET = 0.05  # m: a wet face (the arrival depth)
BIN = 500.0  # m: chainage bins of the fall-back map
MARKS = ("second", "first", "velocity", "energy", "energy_partial")
OUT = RESULTS / "malpasset_energy.json"


def run(order, bound, end, every, widen=0.0):
    """One run; returns its record."""
    obs = read_observations(data_dir() / "observations.csv")
    s = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=order, energy_bound=bound,
                         energy_widen=widen)
    mesh = s.mesh
    perm = np.arange(mesh.n_faces) if s._identity else s._perm  # internal -> mesh face
    km = chainage(np.column_stack([mesh.face_x, mesh.face_y])[perm], obs, MALPASSET_DAM)
    nbin = int(km.max() // BIN) + 1
    kbin = (km // BIN).astype(np.int64)
    h0 = s.h.copy()
    dry0 = s._h <= WET  # the flood's faces: the reservoir and the sea start wet
    s.step(1e-3)  # compile or load the kernels
    s.set_state(h0)
    fb = getattr(s, "_fallback", None)
    top = [-np.inf, np.nan, -1, np.nan, np.nan]  # head (m), t, face, depth, speed
    late = list(top)
    # per-face counts over the steps: wet, and each mark while wet
    n_wet = np.zeros(mesh.n_faces, np.int64)
    n_mark = np.zeros((len(MARKS), mesh.n_faces), np.int64)
    acc = np.zeros((2, len(MARKS)))  # this interval's marks summed over steps: wet, front
    series = []
    nxt = every
    cpu = time.process_time()
    while s.t < end - 1e-9:
        s.step(min(end, nxt) - s.t)
        if s.t <= HEAD_END + 1e-9:
            top = _top_head(s, top, perm)
            if s.t >= LATE:
                late = _top_head(s, late, perm)
        wet = (s._h > WET) & dry0
        if fb is not None:
            m = fb[wet].astype(np.int64)
            c = np.bincount(m, minlength=len(MARKS))
            acc[0] += c
            n_wet += wet
            w = np.flatnonzero(wet)
            for k in range(1, len(MARKS)):
                n_mark[k, w[m == k]] += 1
            front = wet & (s.extremes.arrival >= s.t - FRONT_AGE)
            acc[1] += np.bincount(fb[front].astype(np.int64), minlength=len(MARKS))
        if s.t >= nxt - 1e-9:
            nxt += every
            fr = float(km[wet].max()) if wet.any() else 0.0
            tot = acc.sum(1, keepdims=True)
            frac = np.where(tot > 0, acc / np.maximum(tot, 1), np.nan)
            series.append({"t": float(s.t), "front_m": fr, "steps": int(s.steps),
                           "wet_faces": int(wet.sum()),
                           "wet_frac": dict(zip(MARKS, frac[0].tolist(), strict=True)),
                           "front_frac": dict(zip(MARKS, frac[1].tolist(), strict=True))})
            acc[:] = 0.0
    cpu = time.process_time() - cpu
    ex = s.extremes.arrays()
    rows, _ = extremes_points(mesh, s.bed, ex["max_water_level"], ex["max_water_depth"],
                              ex["arrival_time"], obs, MALPASSET_DAM, s.arrival_depth, end)
    bins = []
    if fb is not None:
        wb = np.bincount(kbin, weights=n_wet, minlength=nbin)
        for b in range(nbin):
            r = {"from_m": b * BIN, "wet_face_steps": float(wb[b])}
            for k, name in enumerate(MARKS):
                if k:
                    mk = np.bincount(kbin, weights=n_mark[k], minlength=nbin)[b]
                    r[name] = float(mk / wb[b]) if wb[b] > 0 else np.nan
            bins.append(r)
    return {"order": order, "bound": bound, "widen": widen, "end_s": end, "faces": mesh.n_faces,
            "steps": int(s.steps), "cpu_s": cpu, "top_head": top, "late_head": late,
            "headline": headline(rows),
            "points": [{k: r[k] for k in ("id", "kind", "chainage_m", "observed_level_m",
                                          "level_error_m", "observed_arrival_s",
                                          "computed_arrival_s", "arrival_error_s")}
                       for r in rows],
            "sea_outflow_m3": float(s.outflow_volume.sum()),
            "series": series, "bins": bins, "machine": machine()}


def _top_head(s, top, perm):
    """``top`` updated with this step's largest head over faces deeper than ``HEAD_DEPTH``."""
    deep = np.flatnonzero(s._h > HEAD_DEPTH)
    h = s._h[deep]
    sp2 = (s._hu[deep] ** 2 + s._hv[deep] ** 2) / h ** 2
    head = h + s._z[deep] + sp2 / (2.0 * s.gravity)
    k = int(np.argmax(head))
    if head[k] > top[0]:
        top = [float(head[k]), float(s.t), int(perm[deep[k]]), float(h[k]),
               float(np.sqrt(sp2[k]))]
    return top


def _f(v, nd=1):
    return "-" if v is None or not np.isfinite(v) else f"{v:,.{nd}f}"


def report(runs):
    """Markdown tables of every stored run."""
    keys = sorted(runs, key=lambda k: (runs[k]["end_s"], runs[k]["order"], runs[k]["bound"]))
    lines = ["# Malpasset: order 2's energy bound against accuracy and the front", "",
             "`benchmarks/malpasset_energy.py`; issue's mesh (46,691 triangles), set-up of "
             "`malpasset.py`, one thread.  head: the largest h + z + |u|^2/(2 g) over faces "
             f"deeper than {HEAD_DEPTH:g} m at any step of the first {HEAD_END:g} s (the "
             f"reservoir is at 100 m), and after the first {LATE:g} s.  Level RMSE over the "
             "points the run wets (20), arrival RMS over the timed points (12); arrival: "
             f"depth > {WET:g} m.  Fall-backs: fraction of wet face-steps (deeper than "
             f"{WET:g} m, after each step's corrector) whose reconstruction fell back for the "
             "energy bound in full (first-order depth and discharges), for the velocity check, "
             "or kept second order (no edge touched: 'second order'); partial: faces with an "
             "edge changed but no full fall-back (velocity: an edge's velocity replaced; hr: an "
             "edge given the limited depth's velocity, no fall-back); front: faces the flood "
             "reached in the last "
             f"{FRONT_AGE:g} s (the 10-s interval ending at each step of the front tables).",
             "",
             "| run | end (s) | steps | CPU s | head (m) | when (s) | after 30 s (m) | "
             "level RMSE (m) | worst point | arrival RMS (s) | arrival mean (s) | "
             "sea outflow (Mm3) | energy fall-backs, wet / front | partial, wet | "
             "velocity fall-backs, wet | second order, wet |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for k in keys:
        r = runs[k]
        hl = r["headline"]
        ser = r["series"]
        ew = ef = vw = pw = sw = np.nan
        if r["order"] == 2 and ser:
            ew = np.nanmean([x["wet_frac"]["energy"] for x in ser])
            ef = np.nanmean([x["front_frac"]["energy"] for x in ser])
            pw = np.nanmean([x["wet_frac"]["energy_partial"] for x in ser])
            vw = np.nanmean([x["wet_frac"]["velocity"] for x in ser])
            sw = np.nanmean([x["wet_frac"]["second"] for x in ser])
        lines.append(
            f"| {k} | {r['end_s']:g} | {r['steps']:,} | {r['cpu_s']:.0f} | "
            f"{_f(r['top_head'][0])} | {_f(r['top_head'][1])} | {_f(r['late_head'][0])} | "
            f"{_f(hl['level_rmse_m'], 2)} | {hl['worst_point']} {_f(hl['worst_error_m'], 2)} | "
            f"{_f(hl['arrival_rms_s'], 0)} ({hl['arrival_n']}) | {_f(hl['arrival_mean_s'], 0)} | "
            f"{r['sea_outflow_m3'] / 1e6:.2f} | {_f(100 * ew)} % / {_f(100 * ef)} % | "
            f"{_f(100 * pw)} % | {_f(100 * vw)} % | {_f(100 * sw)} % |")
    # per-point arrivals
    peers = {}
    pf = RESULTS / "malpasset_peers.json"
    if pf.is_file():
        for name, pr in json.loads(pf.read_text())["runs"].items():
            if name.startswith("anuga"):
                peers[pr["facts"]["label"]] = {p["id"]: p for p in pr["points"]}
    timed = [p for p in runs[keys[0]]["points"] if np.isfinite(p["observed_arrival_s"])]
    timed.sort(key=lambda p: p["chainage_m"])
    lines += ["", "Arrival error (computed - observed, s) at the timed points, down the valley "
              "(ANUGA: `malpasset_peers.json`, 4000 s):", "",
              "| point | chainage (m) | observed (s) | " + " | ".join(keys)
              + "".join(f" | {p}" for p in peers) + " |",
              "|---|---:|---:|" + "---:|" * (len(keys) + len(peers))]
    for p in timed:
        cells = []
        for k in keys:
            q = {x["id"]: x for x in runs[k]["points"]}[p["id"]]
            cells.append(_f(q["arrival_error_s"], 0))
        for pp in peers.values():
            cells.append(_f(pp[p["id"]]["arrival_error_s"], 0) if p["id"] in pp else "-")
        lines.append(f"| {p['id']} | {p['chainage_m']:,.0f} | {p['observed_arrival_s']:g} | "
                     + " | ".join(cells) + " |")
    # the front's chainage over time
    ts = sorted({x["t"] for k in keys for x in runs[k]["series"]
                 if abs(x["t"] / 60.0 - round(x["t"] / 60.0)) < 1e-6 and x["t"] <= 1500})
    lines += ["", "The front's chainage (m; the farthest face deeper than 0.05 m) every 60 s:",
              "", "| t (s) | " + " | ".join(keys) + " |", "|---:|" + "---:|" * len(keys)]
    for t in ts:
        cells = []
        for k in keys:
            x = [y for y in runs[k]["series"] if abs(y["t"] - t) < 1e-6]
            cells.append(_f(x[0]["front_m"], 0) if x else "-")
        lines.append(f"| {t:g} | " + " | ".join(cells) + " |")
    # fall-backs down the valley
    o2 = [k for k in keys if runs[k]["order"] == 2 and runs[k]["bins"]]
    if o2:
        lines += ["", "Fall-backs down the valley: per 500-m chainage bin, the fraction of wet "
                  "face-steps with the energy bound's fall-back (full + partial) / the velocity "
                  "check's / first order (dry neighbour, depth ratio):", "",
                  "| chainage (m) | " + " | ".join(o2) + " |", "|---:|" + "---:|" * len(o2)]
        for b in range(max(len(runs[k]["bins"]) for k in o2)):
            cells = []
            for k in o2:
                bb = runs[k]["bins"]
                if b < len(bb) and bb[b]["wet_face_steps"] > 0:
                    x = bb[b]
                    cells.append(f"{_f(100 * (x['energy'] + x['energy_partial']))} / "
                                 f"{_f(100 * x['velocity'])} / {_f(100 * x['first'])} %")
                else:
                    cells.append("-")
            lines.append(f"| {b * BIN:,.0f} | " + " | ".join(cells) + " |")
        lines += ["", "Fall-backs at the front (faces reached in the last 60 s) over time, "
                  "energy (full + partial) / velocity / first order, every 60 s:", "",
                  "| t (s) | " + " | ".join(o2) + " |", "|---:|" + "---:|" * len(o2)]
        for t in ts:
            cells = []
            for k in o2:
                x = [y for y in runs[k]["series"] if abs(y["t"] - t) < 1e-6]
                if x:
                    f = x[0]["front_frac"]
                    cells.append(f"{_f(100 * (f['energy'] + f['energy_partial']))} / "
                                 f"{_f(100 * f['velocity'])} / {_f(100 * f['first'])} %")
                else:
                    cells.append("-")
            lines.append(f"| {t:g} | " + " | ".join(cells) + " |")
    (RESULTS / "malpasset_energy.md").write_text("\n".join(lines) + "\n")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--order", type=int, default=2, choices=(1, 2))
    p.add_argument("--bound", default="off", help="energy_bound (off, g2, rising, velocity, hr)")
    p.add_argument("--end", type=float, default=4000.0)
    p.add_argument("--widen", type=float, default=0.0, help="energy_widen")
    p.add_argument("--every", type=float, default=10.0, help="record interval (s)")
    p.add_argument("--tag", default="", help="suffix of the run's key")
    p.add_argument("--report-only", action="store_true")
    a = p.parse_args(argv)
    runs = json.loads(OUT.read_text()) if OUT.is_file() else {}
    if not a.report_only:
        r = run(a.order, a.bound, a.end, a.every, a.widen)
        key = f"o{a.order}" + ("" if a.order == 1 else f" {a.bound}") + \
            (f" w{a.widen:g}" if a.widen else "") + \
            (f" {a.tag}" if a.tag else "") + f" {a.end:g}s"
        runs = json.loads(OUT.read_text()) if OUT.is_file() else {}
        runs[key] = r
        OUT.write_text(json.dumps(runs, indent=1, default=float))
    print(report(runs))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
