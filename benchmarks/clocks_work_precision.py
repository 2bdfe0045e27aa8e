"""Work-precision of the tracking clocks and integrators (issue 15): error against CPU time.

Two cases of ``cases/``: the flume (one log zigzagging between six obstacles, contacts on,
40 s) and the Malpasset logs (40 logs on the 4000-s flood, from a stored flow file,
``--malpasset-flow``).  Each runs with every integrator (euler, rk4, exponential) and both
clocks (``[integrator] clock = "global"``, ``"per_log"``; the exponential integrator runs on the
global clock only: the per-log kernels are euler and rk4), each at step bounds scaled by
``r`` in ``--refine`` (``length_fraction = r``, ``angle_step = r pi / 4``, ``drag_fraction =
r / 2``; r = 1 is the default).  The error of a run is the position error of its records (every
output time) against a reference run (rk4, global clock, ``r = --reference``): per log the RMS
over the times recorded in both, then the median over the logs (the Malpasset flood strands
some logs on one bank or the other, km apart: the median is the typical log, the table also
gives the largest).  CPU time of ``track`` with the flow loaded beforehand and the records kept
in memory (no file), one thread (run with NUMBA_NUM_THREADS=1), best of ``--repeat``.

    python benchmarks/clocks_work_precision.py --malpasset-flow F [--cases flume,malpasset]

Writes benchmarks/results/clocks_work_precision.{md,json,png} (and each case's rows in
clocks_work_precision_<case>.json; ``--table-only`` redraws from those).
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
CASES = {"flume": ROOT / "cases" / "flume" / "scenario.toml",
         "malpasset": ROOT / "cases" / "malpasset" / "scenario.toml"}
SERIES = [("euler", "global"), ("euler", "per_log"), ("rk4", "global"), ("rk4", "per_log"),
          ("exponential", "global")]


class Recorder:
    """A ``TrajectoryWriter`` stand-in that keeps the positions in memory (no file)."""

    def __init__(self, path, logs, attrs=None, flush_interval=None, obstacle_names=(), **kw):
        self.path = path
        self.rows = []

    def record(self, t, idx, cols):
        self.rows.append((float(t), np.asarray(idx).copy(), np.asarray(cols["x"]).copy(),
                          np.asarray(cols["y"]).copy()))

    def hits(self, hits):
        pass

    def flush(self):
        pass

    def set_attrs(self, **attrs):
        pass

    def close(self, finalize=True):
        return None

    def table(self):
        """{(time, log): (x, y)} of every record."""
        out = {}
        for t, idx, x, y in self.rows:
            for k in range(idx.size):
                out[(round(t, 6), int(idx[k]))] = (x[k], y[k])
        return out


def one_run(scen, flow, method, clock, r, repeat):
    """(records, best CPU s, stats) of one run; records None if the integration failed."""
    from driftlog.api import track
    from driftlog.errors import DriftlogError

    over = {"integrator": {"method": method, "clock": clock, "length_fraction": r,
                           "angle_step": r * np.pi / 4, "drag_fraction": 0.5 * r}}
    best, rec, stats = np.inf, None, {}
    for _ in range(repeat):
        holder = {}

        def writer(path, logs, holder=holder, **kw):
            holder["w"] = Recorder(path, logs, **kw)
            return holder["w"]

        cpu = time.process_time()
        try:
            res = track(scen, flow=flow, output="/tmp/clocks_wp.nc", overrides=over,
                        writer=writer)
        except DriftlogError as exc:  # an explicit scheme diverging at long steps: a point lost
            return None, np.nan, {"error": str(exc).splitlines()[0][:120]}
        best = min(best, time.process_time() - cpu)
        rec, stats = holder["w"].table(), dict(res.stats)
    return rec, best, stats


def error(rec, ref):
    """Median over the logs of the RMS position error over their common records; and the max."""
    per_log = {}
    for key, (x, y) in rec.items():
        if key in ref:
            xr, yr = ref[key]
            per_log.setdefault(key[1], []).append((x - xr) ** 2 + (y - yr) ** 2)
    rms = np.array([np.sqrt(np.mean(v)) for v in per_log.values()])
    return float(np.median(rms)), float(rms.max())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--malpasset-flow", help="stored flow file of the Malpasset flood")
    p.add_argument("--cases", default="flume,malpasset")
    p.add_argument("--refine", default="4,2,1,0.5,0.25", help="step-bound factors r")
    p.add_argument("--reference", type=float, default=1 / 32, help="reference run's r")
    p.add_argument("--repeat", type=int, default=2, help="runs per point (best CPU time)")
    p.add_argument("--table-only", action="store_true",
                   help="only the table and chart, from the cases' saved rows")
    a = p.parse_args(argv)
    if a.table_only:
        rows = []
        for case in a.cases.split(","):
            f = RESULTS / f"clocks_work_precision_{case}.json"
            if f.exists():
                rows += json.loads(f.read_text())
        write(rows, a)
        return
    from driftlog.api import as_scenario
    from driftlog.sources import flow_from_scenario

    refine = [float(v) for v in a.refine.split(",")]
    rows = []
    for case in a.cases.split(","):
        over = ({"flow": {"source": "file", "path": a.malpasset_flow}}
                if case == "malpasset" and a.malpasset_flow else {})
        scen = as_scenario(CASES[case], over)
        flow = flow_from_scenario(scen)
        for m, c in (("rk4", "global"), ("rk4", "per_log")):  # compile, load the snapshots
            one_run(as_scenario(CASES[case], {**over, "time": {"end": 50.0}}), flow, m, c, 1.0,
                    1)
        ref, ref_cpu, _ = one_run(scen, flow, "rk4", "global", a.reference, 1)
        print(f"{case}: reference rk4 global r = {a.reference:g}: {ref_cpu:.1f} CPU s",
              flush=True)
        for method, clock in SERIES:
            for r in refine:
                rec, cpu, st = one_run(scen, flow, method, clock, r, a.repeat)
                med, worst = error(rec, ref) if rec is not None else (np.nan, np.nan)
                row = dict(case=case, method=method, clock=clock, r=r, cpu_s=cpu,
                           median_err_m=med, max_err_m=worst,
                           log_steps=st.get("log_substeps", ""),
                           sync_steps=st.get("substeps", 0), failed=st.get("error", ""))
                rows.append(row)
                print(f"  {method:11s} {clock:7s} r={r:<5g} CPU {cpu:7.3f} s  median "
                      f"{med:.3g} m  max {worst:.3g} m {row['failed']}", flush=True)
        (RESULTS / f"clocks_work_precision_{case}.json").write_text(
            json.dumps([r for r in rows if r["case"] == case], indent=1))
    write(rows, a)


def write(rows, a):
    """The table (md, json) and the chart (png)."""
    cols = ["case", "method", "clock", "r", "cpu_s", "median_err_m", "max_err_m", "sync_steps"]
    lines = ["### Work-precision: error against CPU time, every integrator and both clocks", "",
             f"{machine()}; reference: rk4, global clock, r = {a.reference:g}; error: median "
             "over the logs of each log's RMS position error over its records (max: the worst "
             "log); CPU time of `track` (flow loaded, records in memory), best of "
             f"{a.repeat}.", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        lines.append("| " + " | ".join(
            (f"{r[c]:.3g}" if isinstance(r[c], float) else str(r[c])) for c in cols) + " |")
    failed = [r for r in rows if r["failed"]]
    if failed:
        lines += [""] + [f"- {r['case']} {r['method']} {r['clock']} r = {r['r']:g}: "
                         f"{r['failed']}" for r in failed]
    text = "\n".join(lines) + "\n"
    (RESULTS / "clocks_work_precision.md").write_text(text)
    (RESULTS / "clocks_work_precision.json").write_text(json.dumps(rows, indent=1))
    print(text)
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = list(dict.fromkeys(r["case"] for r in rows))
    fig, axes = plt.subplots(1, len(cases), figsize=(6 * len(cases), 4.5), squeeze=False)
    colors = {"euler": "tab:red", "rk4": "tab:blue", "exponential": "tab:green"}
    for ax, case in zip(axes[0], cases, strict=True):
        for method, clock in SERIES:
            pts = [(r["cpu_s"], r["median_err_m"]) for r in rows
                   if r["case"] == case and r["method"] == method and r["clock"] == clock
                   and np.isfinite(r["median_err_m"]) and r["median_err_m"] > 0]
            if pts:
                x, y = zip(*sorted(pts), strict=True)
                ax.loglog(x, y, "o-" if clock == "global" else "s--", color=colors[method],
                          label=f"{method}, {clock}", mfc="none" if clock == "global" else None)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("CPU time of the run (s)")
        ax.set_ylabel("median position error (m)")
        ax.set_title(case)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "clocks_work_precision.png", dpi=120)


if __name__ == "__main__":
    main()
