"""Many logs on the Malpasset flood: wall time, CPU time, peak memory and output size.

The malpasset case (cases/malpasset/scenario.toml: the 1959 flood on driftlog's solver, read
from its stored flow file) with its 40 logs replaced by N logs on a grid (``seeding =
"grid"``) over the valley floor: the polygon through the ends of the case's four release
lines, clipped to the mesh and 5 m inside it (its largest piece: x 7.4 to 9.7 km, 3 to 5.7 km
below the dam, 1.17 km2, where the wave arrives after 300 to 700 s): logs 0.8 m long of
radius 0.08 m
(pine, 700 kg/m3) at random angles, on a grid spacing of sqrt(area / N) (1.08 m at N = 1e6:
no two logs touch at the start).  Full physics,
contacts on (logs, the mesh's walls; Moreau-Jean by default), RK4 on per-log clocks (``--clock
global``: the paper's), trajectories streamed to a CF trajectory file.

Each N runs in its own process (so that the peak resident memory, ``ru_maxrss``, is that run's
alone); a thread samples the resident memory every 0.2 s, so the table gives the memory after
the set-up (flow open, logs seeded) and the peak during the run.  Checked after each run: the
file holds N trajectories and N final states; every log is in the mesh or reported out
(status left_domain); counts of each final status.

    python benchmarks/million_logs.py --flow /tmp/malpasset_o1_4000.nc --logs 10000 --end 300
    python benchmarks/million_logs.py --flow F --sweep 1e4 1e5 1e6 --end 120   # a table

writes benchmarks/results/million_logs.{json,md} (sweep).

``--threads 1 2``: the same run once per thread count, each in its own process with
``NUMBA_NUM_THREADS`` set, one after the other: wall and CPU time, cores used (CPU / wall),
the time in the Moreau-Jean island kernel (``moreau_kernel.moreau_islands`` or, from 2,048
logs in the contact set and two threads on, ``moreau_islands_parallel``), the load average,
and a digest of the trajectory file's records and hits (the same for every thread count: the
parallel kernels give the serial results bit for bit); writes
benchmarks/results/<name or million_logs_threads>.{json,md}:

    python benchmarks/million_logs.py --logs 10000 --density 100000 --end 900 --threads 1 2

The flow file comes from ``python benchmarks/malpasset.py --flow F --solve-only`` (4000 s,
17 s wall on 2026-12-06).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
CASE = ROOT / "cases" / "malpasset" / "scenario.toml"
# the valley floor between the case's release lines G7, G8, G10 and G11 (m)
VALLEY = [[5670.0, 4200.0], [6600.0, 3670.0], [8580.0, 3260.0], [9560.0, 2400.0],
          [9720.0, 3380.0], [8593.0, 3720.0], [6820.0, 3920.0], [5760.0, 4600.0]]
STATUS = ["waiting", "floating", "resting", "stranded", "left_domain"]


def valley_polygon(mesh):
    """VALLEY clipped to the mesh (the union of its faces near VALLEY), 5 m inside its edge,
    its largest piece, as a list of [x, y] (shapely)."""
    import shapely

    valley = shapely.Polygon(VALLEY)
    x0, y0, x1, y1 = valley.bounds
    fn = mesh.face_nodes[:, :3]
    fx, fy = mesh.node_x[fn], mesh.node_y[fn]
    near = np.flatnonzero((fx.max(1) >= x0) & (fx.min(1) <= x1) & (fy.max(1) >= y0)
                          & (fy.min(1) <= y1))
    faces = shapely.polygons(np.stack([fx[near], fy[near]], axis=-1))
    clipped = valley.intersection(shapely.union_all(faces)).buffer(-5.0).simplify(1.0)
    if clipped.geom_type != "Polygon":
        clipped = max(clipped.geoms, key=lambda g: g.area)
    return np.asarray(clipped.exterior.coords)[:-1].tolist()


def overrides(flow, n, end, output_interval, method, flush_interval, clock="per_log",
              density=None, grounded=False, solver="pgs"):
    """The malpasset case with N logs on a grid over the valley, contacts on.

    ``density``: seed them as densely as that many logs over the whole valley floor (the
    polygon shrunk about its centroid by sqrt(n / density)), e.g. 2000 logs at the spacing of
    1e5 (3.4 m) in a twentieth of the area.  ``grounded``: resting and stranded logs are
    fixed obstacles to the floating ones (docs/model.md 13; False, the default of
    ``[contact] grounded`` and of ``--grounded``: passed over, as before 2026-12-02).
    ``solver``: ``[contact] solver`` (Moreau-Jean's impulses: "pgs" or "nncg").
    """
    from driftlog.flowfile import open_flow

    poly = valley_polygon(open_flow(flow).mesh)
    if density:
        import shapely

        xy = np.asarray(poly)
        c = np.asarray(shapely.Polygon(xy).centroid.coords[0])
        poly = ((xy - c) * np.sqrt(n / density) + c).tolist()
    return {
        "flow": {"source": "file", "path": str(flow)},
        "time": {"start": 0.0, "end": float(end), "output_interval": float(output_interval)},
        "logs": [{"name": f"{n} logs over the valley", "seeding": "grid", "polygon": poly,
                  "count": int(n), "theta": "random", "seed": 1, "length": 0.8,
                  "radius": 0.08, "density": 700.0, "velocity": "rest"}],
        "physics": {"level": "full"},
        "integrator": {"method": "rk4", "clock": clock},
        "contact": {"enabled": True, "method": method, "grounded": bool(grounded),
                    "solver": solver},
        "output": {"flush_interval": int(flush_interval)},
    }


class RSSMonitor(threading.Thread):
    """Samples this process's resident memory (bytes) every ``interval`` s.

    With ``ledger`` (a path) it also writes, every ``every`` s, this segment's wall and CPU
    time and peak memory after the ``before`` segments of earlier, interrupted attempts
    (``--resume``), so that a run killed without warning still counts what it spent.
    """

    def __init__(self, interval=0.2, ledger=None, before=(), every=30.0):
        super().__init__(daemon=True)
        self.interval, self.peak, self.samples = interval, 0, []
        self.ledger, self.before, self.every = ledger, list(before), every
        self.w0, self.c0 = time.perf_counter(), time.process_time()
        self._halt = threading.Event()

    def rss(self):
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

    def segment(self):
        """This attempt so far: wall and CPU seconds, peak RSS (MB)."""
        return dict(wall_s=time.perf_counter() - self.w0, cpu_s=time.process_time() - self.c0,
                    peak_rss_mb=self.peak / 2**20, load=os.getloadavg()[0])

    def write(self):
        if self.ledger is not None:
            tmp = Path(str(self.ledger) + ".tmp")
            tmp.write_text(json.dumps({"segments": [*self.before, self.segment()]}))
            tmp.replace(self.ledger)

    def run(self):
        last = time.perf_counter()
        while not self._halt.is_set():
            r = self.rss()
            self.peak = max(self.peak, r)
            self.samples.append((time.perf_counter() - self.w0, r))
            if time.perf_counter() - last >= self.every:
                self.write()
                last = time.perf_counter()
            self._halt.wait(self.interval)

    def stop(self):
        self._halt.set()
        self.join()
        self.write()


def check_output(path, n, flow):
    """Facts about the trajectory file; raises if a log is missing or lost."""
    import netCDF4

    from driftlog.flowfile import open_flow

    with netCDF4.Dataset(path) as ds:
        ds.set_auto_maskandscale(False)
        ntraj = len(ds.dimensions["trajectory"])
        nobs = len(ds.dimensions["obs"])
        rows = np.asarray(ds["rowSize"][:])
        last = np.cumsum(rows) - 1
        has = rows > 0
        status = np.full(ntraj, 0, np.int8)
        x = np.full(ntraj, np.nan)
        y = np.full(ntraj, np.nan)
        status[has] = np.asarray(ds["status"][:])[last[has]]
        x[has] = np.asarray(ds["x"][:])[last[has]]
        y[has] = np.asarray(ds["y"][:])[last[has]]
        nhit = len(ds.dimensions["hit"])
    if ntraj != n or int(rows.sum()) != nobs:
        raise RuntimeError(f"{path}: {ntraj} trajectories, {rows.sum()} rows for {nobs} "
                           f"observations; expected {n} trajectories")
    mesh = open_flow(flow).mesh
    inside = mesh.locate(x, y) >= 0
    lost = np.flatnonzero(has & (status != 4) & ~inside)
    if lost.size:
        raise RuntimeError(f"{path}: {lost.size} logs outside the mesh without status "
                           f"left_domain (first: log {lost[0]})")
    return dict(trajectories=ntraj, observations=nobs, hits=nhit,
                never_recorded=int(np.sum(~has)),
                final_status={s: int(np.sum(status[has] == k)) for k, s in enumerate(STATUS)})


# the parts of a per-log run timed in ``run_one`` (module, function): inclusive CPU seconds
# (``contact_window`` holds the other three and the island kernel; what it spends beside them
# is its own Python: copies, masks, set operations)
PARTS = (("clocks", "contact_window"), ("clocks", "free_advance"), ("clocks", "_pairs"),
         ("clocks", "_obstacle_pairs"))


def time_island_kernels():
    """Wall and CPU time in the Moreau-Jean island kernels (and calls of each), from now on,
    and the CPU time of each part in ``PARTS`` (``part_<name>_cpu_s``).

    Wraps ``moreau_kernel.moreau_islands`` and ``moreau_islands_parallel`` (looked up by
    ``clocks.contact_window`` at each call) and the functions of ``PARTS`` (module globals
    of ``driftlog.clocks``, looked up at each call); returns the dict the wrappers add to.
    """
    import importlib

    import driftlog.moreau_kernel as mk

    acc = dict(kernel_wall_s=0.0, kernel_cpu_s=0.0, kernel_calls_serial=0,
               kernel_calls_parallel=0)
    for name, key in (("moreau_islands", "kernel_calls_serial"),
                      ("moreau_islands_parallel", "kernel_calls_parallel")):
        f = getattr(mk, name)

        def timed(*args, _f=f, _key=key):
            w, c = time.perf_counter(), time.process_time()
            try:
                return _f(*args)
            finally:
                acc["kernel_wall_s"] += time.perf_counter() - w
                acc["kernel_cpu_s"] += time.process_time() - c
                acc[_key] += 1

        setattr(mk, name, timed)
    for mod, name in PARTS:
        m = importlib.import_module(f"driftlog.{mod}")
        key = f"part_{name.lstrip('_')}_cpu_s"
        acc[key] = 0.0
        f = getattr(m, name)

        def part(*args, _f=f, _key=key, **kw):
            c = time.process_time()
            try:
                return _f(*args, **kw)
            finally:
                acc[_key] += time.process_time() - c

        setattr(m, name, part)
    return acc


def records_digest(path):
    """sha256 (first 16 hex digits) of the trajectory file's records and hits."""
    import hashlib

    import netCDF4

    h = hashlib.sha256()
    with netCDF4.Dataset(path) as ds:
        ds.set_auto_maskandscale(False)
        for name in sorted(ds.variables):
            v = ds[name]
            if v.dimensions and v.dimensions[0] in ("obs", "hit", "trajectory"):
                h.update(name.encode())
                h.update(np.ascontiguousarray(v[:]).tobytes())
    return h.hexdigest()[:16]


def run_one(a):
    """One run in this process; prints one JSON line of facts."""
    from driftlog.api import as_scenario, track
    from driftlog.contact.model import ContactModel

    ContactModel.relative_motion = a.motion == "relative"
    out = Path(a.out)
    ledger = Path(str(out) + ".run.json")  # time and memory of each attempt (--resume)
    before = []
    if a.resume and Path(str(out) + ".partial").is_file() and ledger.is_file():
        before = json.loads(ledger.read_text())["segments"]
    else:
        for p in (out, Path(str(out) + ".partial"), ledger):
            p.unlink(missing_ok=True)
    mon = RSSMonitor(ledger=ledger, before=before)
    rss0 = mon.rss()
    mon.start()
    load0 = os.getloadavg()[0]
    scen = as_scenario(CASE, overrides(a.flow, a.logs, a.end, a.output_interval, a.method,
                                       a.flush_interval, a.clock, a.density,
                                       a.grounded == "on", a.solver))
    kern = time_island_kernels()
    res = track(scen, output=out, progress=a.progress, resume=a.resume)
    mon.stop()
    segments = [*before, mon.segment()]
    wall = sum(g["wall_s"] for g in segments)
    cpu = sum(g["cpu_s"] for g in segments)
    facts = check_output(out, a.logs, a.flow)
    import netCDF4

    with netCDF4.Dataset(out) as ds:  # the contacts' statistics (least gap: deepest overlap)
        cs = json.loads(ds.getncattr("contact_stats")) if "contact_stats" in ds.ncattrs() else {}
    floating = [r for r in res.stats.items() if r[0] in (
        "substeps", "rhs_evaluations", "log_substeps", "windows", "islands", "largest_island",
        "contact_set", "clock_retries", "lifted", "island_reruns")]
    row = dict(logs=a.logs, end_s=a.end, output_interval_s=a.output_interval,
               contact_method=a.method, clock=a.clock, motion=a.motion, grounded=a.grounded,
               solver=a.solver,
               wall_s=wall, cpu_s=cpu,
               rss_start_mb=rss0 / 2**20,
               peak_rss_mb=max([resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024]
                               + [g["peak_rss_mb"] for g in before]),
               sampled_peak_mb=max(g["peak_rss_mb"] for g in segments),
               attempts=len(segments), density=a.density,
               contact_min_gap_m=cs.get("min_gap"), contact_steps=cs.get("substeps"),
               contact_sweeps=cs.get("pgs_iterations"), contact_capped=cs.get("pgs_capped"),
               max_contacts=cs.get("max_contacts"),
               output_mb=out.stat().st_size / 2**20, physics=res.physics["level"],
               load_start=load0, load_end=os.getloadavg()[0],
               threads=int(os.environ.get("NUMBA_NUM_THREADS", os.cpu_count())),
               records_digest=records_digest(out), **kern,
               **dict(floating), **facts)
    print("RESULT " + json.dumps(row), flush=True)
    if not a.keep:
        out.unlink(missing_ok=True)
    return row


def sweep(a):
    rows = []
    for n in a.sweep:
        cmd = [sys.executable, __file__, "--flow", str(a.flow), "--logs", str(int(n)), "--end",
               str(a.end), "--output-interval", str(a.output_interval), "--method", a.method,
               "--flush-interval", str(a.flush_interval), "--clock", a.clock, "--out", a.out,
               *(["--density", str(a.density)] if a.density else []),
               "--motion", a.motion, "--grounded", a.grounded, "--solver", a.solver]
        print(" ".join(cmd), flush=True)
        p = subprocess.run(cmd, capture_output=True, text=True)
        line = [q for q in p.stdout.splitlines() if q.startswith("RESULT ")]
        if p.returncode or not line:
            print(p.stdout[-3000:], p.stderr[-3000:])
            rows.append(dict(logs=int(n), end_s=a.end, error=(p.stderr or p.stdout)[-500:]))
            continue
        rows.append(json.loads(line[-1][7:]))
        print(rows[-1], flush=True)
    write_results(a, rows)


def threads(a):
    """The same run once per thread count in ``a.threads``, each in its own process."""
    rows = []
    for t in a.threads:
        cmd = [sys.executable, __file__, "--flow", str(a.flow), "--logs", str(a.logs), "--end",
               str(a.end), "--output-interval", str(a.output_interval), "--method", a.method,
               "--flush-interval", str(a.flush_interval), "--clock", a.clock, "--out", a.out,
               *(["--density", str(a.density)] if a.density else []), "--motion", a.motion,
               "--grounded", a.grounded, "--solver", a.solver,
               # a child without --resume would delete the partial run it is asked to continue
               *[f"--{k}" for k in ("resume", "keep", "progress") if getattr(a, k)]]
        env = dict(os.environ, NUMBA_NUM_THREADS=str(t))
        print(f"NUMBA_NUM_THREADS={t} " + " ".join(cmd), flush=True)
        # --progress: the child's progress bar (stderr) shown as it goes
        p = subprocess.run(cmd, stdout=subprocess.PIPE,
                           stderr=None if a.progress else subprocess.PIPE, text=True, env=env)
        line = [q for q in p.stdout.splitlines() if q.startswith("RESULT ")]
        if p.returncode or not line:
            print(p.stdout[-3000:], (p.stderr or "")[-3000:])
            rows.append(dict(logs=a.logs, threads=t, error=(p.stderr or p.stdout)[-500:]))
            continue
        rows.append(json.loads(line[-1][7:]))
        print({k: rows[-1].get(k) for k in ("threads", "wall_s", "cpu_s", "kernel_wall_s",
                                             "kernel_cpu_s", "records_digest")}, flush=True)
    write_threads(a, rows)


def write_threads(a, rows):
    """benchmarks/results/<name>.{json,md}: the thread counts side by side."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = a.name or "million_logs_threads"
    info = dict(machine=machine(), flow=str(a.flow), logs=a.logs, density=a.density,
                end_s=a.end, output_interval_s=a.output_interval, contact_method=a.method,
                clock=a.clock, motion=a.motion)
    (RESULTS / f"{name}.json").write_text(json.dumps({"info": info, "runs": rows}, indent=1))
    ok = [r for r in rows if "error" not in r]
    # against the last 1-thread run (a first run may compile the kernels: ``--threads 2 1 2``)
    base = next((r for r in ok[::-1] if r["threads"] == 1), ok[-1] if ok else None)
    seeded = f", seeded as {a.density:g} over the valley" if a.density else ""
    args = (f"--logs {a.logs} " + (f"--density {a.density:g} " if a.density else "")
            + f"--end {a.end:g} --output-interval {a.output_interval:g} --threads "
            + " ".join(str(t) for t in a.threads))
    lines = [f"### {a.logs:,} logs on the Malpasset flood{seeded} (first {a.end:g} s): "
             "threads side by side", "",
             f"Measured on {info['machine']}.  Each thread count in its own process "
             "(`NUMBA_NUM_THREADS`), one after the other, cached kernels unless said; RK4 "
             f"({a.clock} clock), contacts ({a.method}, bound on the {a.motion} motion).  "
             "Cores used: CPU / wall.  Island kernel: the time inside "
             "`moreau_kernel.moreau_islands` (serial) and `moreau_islands_parallel` (from "
             "2,048 logs in a window's contact set, two threads or more).  Speed-up: the "
             "last 1-thread run's wall time over this one's.  Re-create: `python "
             f"benchmarks/million_logs.py --flow F {args}`.", "",
             "| run | threads | wall (s) | CPU (s) | cores used | speed-up (wall) | island "
             "kernel wall (s) | island kernel CPU (s) | kernel cores used | kernel speed-up "
             "(wall) | kernel calls serial / parallel | share of wall in the kernel | load avg "
             "start / end | sub-steps | hits | records digest |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for k, r in enumerate(rows, 1):
        if "error" in r:
            lines.append(f"| {k} | {r['threads']} | failed: {r['error'][-200:]!r} |")
            continue
        kw, kc = r["kernel_wall_s"], r["kernel_cpu_s"]
        lines.append(
            f"| {k} | {r['threads']} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | "
            f"{r['cpu_s'] / r['wall_s']:.2f} | {base['wall_s'] / r['wall_s']:.2f} | "
            f"{kw:.1f} | {kc:.1f} | {kc / max(kw, 1e-9):.2f} | "
            f"{base['kernel_wall_s'] / max(kw, 1e-9):.2f} | "
            f"{r['kernel_calls_serial']} / {r['kernel_calls_parallel']} | "
            f"{kw / r['wall_s']:.0%} | {r['load_start']:.1f} / {r['load_end']:.1f} | "
            f"{r.get('substeps', '?')} | {r['hits']} | `{r['records_digest']}` |")
    same = len({r["records_digest"] for r in ok}) == 1
    lines += ["", "Records and hits " + ("identical for every thread count (same digest)."
                                        if same else "DIFFER between thread counts.")]
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{name}.md").write_text(text)
    print(text)


def recreate(a, rows):
    """The command(s) that make these rows."""
    tail = f"--end {a.end:g} --output-interval {a.output_interval:g}"
    if not any(r.get("density") for r in rows):
        return (f"`python benchmarks/million_logs.py --flow F --sweep "
                f"{' '.join(str(int(r['logs'])) for r in rows)} {tail}`.")
    runs = [f"--logs {int(r['logs'])}" + (f" --density {r['density']:g}" if r.get("density")
                                         else "")
            + (" --grounded on" if r.get("grounded") == "on" else "") for r in rows]
    return (f"`python benchmarks/million_logs.py --flow F {tail} ARGS` with ARGS "
            + ", ".join(f"`{q}`" for q in runs) + " (one run each).")


def write_results(a, rows):
    """benchmarks/results/<name>.json and .md from the runs' RESULT rows."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    info = dict(machine=machine(), flow=str(a.flow), end_s=a.end,
                output_interval_s=a.output_interval, contact_method=a.method, clock=a.clock,
                threads=os.environ.get("NUMBA_NUM_THREADS", "all"))
    name = a.name or "million_logs"
    (RESULTS / f"{name}.json").write_text(json.dumps({"info": info, "runs": rows}, indent=1))
    lines = [f"### Many logs on the Malpasset flood (first {a.end:g} s)", "",
             f"Measured on {info['machine']}; NUMBA_NUM_THREADS={info['threads']}.  Logs 0.8 m "
             "long, radius 0.08 m, on a grid over the valley 3 to 5.7 km below the dam, "
             "full physics, "
             f"RK4 ({a.clock} clock), contacts ({a.method}), records every "
             f"{a.output_interval:g} s.  "
             "Re-create: " + recreate(a, rows), "",
             "Moreau bound: the step near contacts bounded by each near pair's relative "
             "motion (docs/model.md eq. (81)) or, before 2026-12-02, by each log's own "
             "(`--motion absolute`).  Grounded logs: resting and stranded logs fixed "
             "obstacles to the floating ones (docs/model.md 13), or passed over (`--grounded "
             "off`, before 2026-12-02).  Wall and CPU time include numba's compilation when "
             "the kernels were not cached yet.", "",
             "Seeded as: the density of that many logs over the whole valley floor (`--density`;"
             " the logs themselves fill a proportionally smaller area).  Deepest overlap: the "
             "least capsule gap after any contact step (the contacts' `min_gap`).", "",
             "| logs | seeded as | Moreau bound | grounded logs | wall (s) | CPU (s) "
             "| load avg start/end "
             "| RSS after imports (MB) | peak RSS (MB) | output (MB) | observations | sub-steps "
             "| windows | lifted | hits | deepest overlap (m) | final status |",
             "|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['logs']} | failed: {r['error'][-200:]!r} |")
            continue
        fin = ", ".join(f"{k} {v}" for k, v in r["final_status"].items() if v)
        load = (f"{r['load_start']:.1f} / {r['load_end']:.1f}" if "load_start" in r
                else "?")
        tries = f" ({r['attempts']} attempts)" if r.get("attempts", 1) > 1 else ""
        gap = r.get("contact_min_gap_m")
        gap = f"{-gap:.3f}" if gap is not None and gap < 0 else ("none" if gap else "?")
        lines.append(f"| {r['logs']:.0f} | {r.get('density') or r['logs']:.0f} | "
                     f"{r.get('motion', 'absolute')} | "
                     f"{'fixed' if r.get('grounded', 'off') == 'on' else 'passed over'} | "
                     f"{r['wall_s']:.0f}{tries} | "
                     f"{r['cpu_s']:.0f} | {load} | "
                     f"{r['rss_start_mb']:.0f} | {r['peak_rss_mb']:.0f} | {r['output_mb']:.1f} | "
                     f"{r['observations']} | {r.get('substeps', '?')} | "
                     f"{r.get('windows', '?')} | {r.get('lifted', '?')} | {r['hits']} | "
                     f"{gap} | {fin} |")
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{name}.md").write_text(text)
    print(text)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--flow", default="/tmp/malpasset_o1_4000.nc",
                   help="stored flow file of the flood (benchmarks/malpasset.py --flow)")
    p.add_argument("--logs", type=float, default=1e4, help="number of logs")
    p.add_argument("--sweep", type=float, nargs="+", help="several N, each in a new process")
    p.add_argument("--end", type=float, default=4000.0, help="end of the run (s)")
    p.add_argument("--output-interval", type=float, default=60.0, help="record interval (s)")
    p.add_argument("--method", default="moreau", choices=("event", "moreau"),
                   help="contact method")
    p.add_argument("--flush-interval", type=int, default=10, help="records between flushes")
    p.add_argument("--clock", default="per_log", choices=("global", "per_log"),
                   help="[integrator] clock")
    p.add_argument("--motion", default="relative", choices=("relative", "absolute"),
                   help="Moreau's step bound near contacts on the pairs' relative motion "
                        "(docs/model.md eq. (81)) or, as before 2026-12-02, each log's own")
    p.add_argument("--grounded", default="off", choices=("on", "off"),
                   help="resting and stranded logs fixed obstacles to the floating ones "
                        "([contact] grounded; off: passed over, as before 2026-12-02)")
    p.add_argument("--solver", default="pgs", choices=("pgs", "nncg"),
                   help="Moreau-Jean's contact impulses ([contact] solver)")
    p.add_argument("--out", default="/tmp/million_logs.nc", help="trajectory file")
    p.add_argument("--name", help="results name (default million_logs)")
    p.add_argument("--keep", action="store_true", help="keep the trajectory file")
    p.add_argument("--density", type=float,
                   help="seed the logs as densely as this many over the valley floor (the "
                        "polygon shrunk about its centroid)")
    p.add_argument("--threads", type=int, nargs="+",
                   help="the run once per thread count (NUMBA_NUM_THREADS), each in a new "
                        "process, side by side in one table")
    p.add_argument("--progress", action="store_true")
    p.add_argument("--resume", action="store_true",
                   help="continue a stopped run of the same arguments from its last record "
                        "(the .partial file); wall and CPU time add up over the attempts")
    p.add_argument("--results-from", nargs="+", metavar="LOG",
                   help="write the results table from the RESULT lines of these run logs "
                   "(runs made with --logs N, e.g. to watch --progress)")
    a = p.parse_args(argv)
    if not Path(a.flow).is_file():
        raise SystemExit(f"flow file {a.flow} not found: python benchmarks/malpasset.py "
                         f"--flow {a.flow} --solve-only")
    try:
        import shapely  # noqa: F401  (the valley polygon, in every child process)
    except ImportError:
        raise SystemExit("million_logs.py needs shapely, in the bench extra: "
                         "pip install -e '.[bench]' (or pip install 'shapely>=2.0')") from None
    a.logs = int(a.logs)
    if a.resume and a.sweep:
        p.error("--resume continues one run (one --logs); it cannot go with --sweep")
    if a.results_from:
        rows = []
        for path in a.results_from:
            rows += [json.loads(q[7:]) for q in Path(path).read_text().splitlines()
                     if q.startswith("RESULT ")]
        write_results(a, rows)
    elif a.threads:
        threads(a)
    elif a.sweep:
        sweep(a)
    else:
        run_one(a)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
