"""Malpasset beside ANUGA: driftlog orders 1 and 2 and ANUGA DE0 and DE1 on the same mesh.

Issue 14 ("Measured"): the Malpasset dam break of ``benchmarks/malpasset.py`` (the 46,691
triangles of shared/data/malpasset, ``driftlog.floodsetup.malpasset_solver``: reservoir at
100 m in its polygon, sea at 0 m on the faces below it connected to the coast, Manning
n = 0.033, reflective walls except the coast) run by four solvers, one after the other, each
in its own process on one thread (``NUMBA_NUM_THREADS=1``, ``OMP_NUM_THREADS=1`` set before
anything is imported; ANUGA's ``set_omp_num_threads(1)``):

- driftlog order 1 (HLLC, first order) and order 2 (MUSCL + Heun), the solver of this checkout;
- ANUGA (``pip install anuga``, 4.2) DE0 (its default: Euler in time, limited second-order
  reconstruction with beta 0.5) and DE1 (RK2, beta 1), on the very same triangles
  (``driftlog.adapters.anuga_case.anuga_domain``: triangle i = face i), the same bed (the
  face bed at the centroids), the same initial depth (driftlog's array, reservoir and sea),
  Manning 0.033 and reflective walls.  The coast: driftlog imposes the sea level through a
  ghost state that keeps the outgoing Riemann invariant; ANUGA's counterpart is its
  characteristic (Flather-type) boundary with the sea's stage and zero outside velocity
  (``Flather_external_stage_zero_velocity_boundary``, stage 0 m).

Both write a snapshot every 30 s (driftlog's flow file, ANUGA's sww; to a scratch folder,
deleted afterwards) and fold the state of every time step into the per-face extremes: driftlog
in the solver; ANUGA through a fractional-step operator (numpy, after each full step) that
keeps the maximum level, the maximum depth and the first time the depth exceeds 0.05 m (the
solver's arrival depth).  The extremes of both go through the same comparison as
``malpasset.py`` (``malpasset_compare.extremes_points`` and ``headline``): the maximum-level
RMSE over the police points and gauges the run wets, the worst of them, and the arrival RMS
over the 12 timed points (gauges G6-G14, transformers A-C).  A run shorter than 4000 s
(``--end``) is compared on the points up to where the observed front is at half its end time
(``observed_reach``, the same points for every solver).

Timing: the run itself (driftlog's ``run`` after its kernels are compiled or loaded from
numba's cache; ANUGA's ``evolve`` loop): wall time and CPU time (``time.process_time`` in the
child); beside them the child process's whole CPU time (``resource.getrusage`` of the
children: imports, mesh, set-up included).  Each run's extremes and facts are kept under
``--work`` (default /tmp/malpasset_peers_<end>), so that a later call with ``--reuse`` only
runs what is missing and ``--report-only`` tables whatever finished.

    python benchmarks/malpasset_peers.py --end 600          # reduced: the first 600 s
    python benchmarks/malpasset_peers.py                    # 4000 s (hours on 2 busy cores)
    python benchmarks/malpasset_peers.py --runs anuga-DE0 driftlog-o1 --reuse
    python benchmarks/malpasset_peers.py --report-only      # table what finished
    python benchmarks/malpasset_peers.py --quick            # 120 s, a smoke run (minutes)

writes benchmarks/results/malpasset_peers{,_<end>s}.{md,json,csv} and the work-precision chart
malpasset_peers{,_<end>s}.png (error against CPU time: level RMSE and arrival RMS).
"""

import os

# single thread each, before numba, numpy or ANUGA are imported (children inherit these)
os.environ["NUMBA_NUM_THREADS"] = "1"
os.environ["OMP_NUM_THREADS"] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine, write_table  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FULL_END = 4000.0
INTERVAL = 30.0  # s between snapshots, every solver
SEA_LEVEL = 0.0
# run name -> (solver, order / flow algorithm, label)
RUNS = {
    "driftlog-o1": ("driftlog", 1, "driftlog order 1"),
    "driftlog-o2": ("driftlog", 2, "driftlog order 2"),
    "anuga-DE0": ("anuga", "DE0", "ANUGA DE0"),
    "anuga-DE1": ("anuga", "DE1", "ANUGA DE1"),
}


def data_dir():
    """The Malpasset data folder (as ``malpasset.py`` finds it)."""
    from malpasset import data_dir as find

    return find()


# --------------------------------------------------------------------------- the runs (child)
def extremes_operator(dom, arrival_depth):
    """An ANUGA fractional-step operator keeping per-triangle extremes after every step.

    The same quantities as driftlog's ``Extremes``: maximum level (stage) where the depth is
    positive, maximum depth, and the first time the depth exceeds ``arrival_depth``.  ANUGA
    calls it after each full step with its clock still at the step's start, hence
    ``t + timestep``.
    """
    from anuga.operators.base_operator import Operator

    class Extremes(Operator):
        def __init__(self, domain):
            super().__init__(domain, description="driftlog benchmark: per-face extremes",
                             label="extremes")
            n = len(self.stage_c)
            self.max_level = np.full(n, -np.inf)
            self.max_depth = np.zeros(n)
            self.arrival = np.full(n, np.nan)
            self.fold(self.domain.get_time())

        def fold(self, t):
            h = self.stage_c - self.elev_c
            np.maximum(self.max_level, np.where(h > 0.0, self.stage_c, -np.inf),
                       out=self.max_level)
            np.maximum(self.max_depth, h, out=self.max_depth)
            new = (h > arrival_depth) & np.isnan(self.arrival)
            self.arrival[new] = t

        def __call__(self):
            self.fold(self.domain.get_time() + self.domain.get_timestep())

        def parallel_safe(self):
            return True

        def statistics(self):
            return "per-face extremes"

        def timestepping_statistics(self):
            return "per-face extremes"

    return Extremes(dom)


def run_one(name, end, work, anuga_bed="centroids", thin_fraction=None):
    """Run ``name`` to ``end`` s in this process; write its extremes (.npz) and facts (.json).

    ``anuga_bed``: ANUGA's elevation is driftlog's face bed at the centroids ('centroids',
    constant per triangle: the very same bed) or the mesh's node elevations at the vertices
    ('vertices', continuous, piecewise linear); both have the same centroid values.
    ``thin_fraction``: driftlog order 2's thin-water fraction k of docs/model.md (69)
    (None: the solver's default).
    """
    from driftlog.floodsetup import MALPASSET_MANNING, malpasset_solver

    kind, order, label = RUNS[name]
    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    cpu_start = time.process_time()
    # the set-up of malpasset.py; ANUGA takes its mesh, bed and initial depth
    opts = {"thin_fraction": thin_fraction} if kind == "driftlog" and order == 2 \
        and thin_fraction is not None else {}
    solver = malpasset_solver(data_dir() / "malpasset_mesh.nc",
                              order=order if kind == "driftlog" else 1, sea_level=SEA_LEVEL,
                              **opts)
    if opts:
        label = f"{label}, k = {thin_fraction:g}"
    mesh, bed, h0 = solver.mesh, solver.bed.copy(), solver.h.copy()
    facts = {"run": name, "label": label, "end_s": end, "faces": mesh.n_faces,
             "interval_s": INTERVAL, "sea_level_m": SEA_LEVEL,
             "initial_volume_m3": float(np.sum(h0 * mesh.face_area)),
             "machine": machine()}
    if kind == "driftlog":
        flow = work / f"{name}.nc"
        solver.step(1e-3)  # compile or load the kernels outside the timed run
        solver.set_state(h0)
        setup_cpu = time.process_time() - cpu_start
        cpu = time.process_time()
        res = solver.run(end, output=flow, output_interval=INTERVAL)
        cpu = time.process_time() - cpu
        ex = solver.extremes.arrays()
        max_level, max_depth, arrival = (np.array(ex[k]) for k in (
            "max_water_level", "max_water_depth", "arrival_time"))
        facts.update(steps=int(res.steps), wall_s=float(res.wall_time), cpu_s=cpu,
                     volume_m3=float(res.volume),
                     relative_volume_error=float(res.relative_volume_error),
                     sea_outflow_m3=float(solver.outflow_volume.sum()),
                     sea_inflow_m3=float(solver.inflow_volume.sum()),
                     arrival_depth_m=float(solver.arrival_depth),
                     scheme={1: "HLLC, first order, Euler",
                             2: "HLLC, MUSCL (limited least squares), Heun, thin-water k "
                                f"{solver.thin_fraction:g}"}[order],
                     thin_fraction=float(solver.thin_fraction),
                     cfl=float(solver.cfl))
        flow.unlink(missing_ok=True)
    else:
        import anuga
        from driftlog.adapters.anuga_case import anuga_domain

        arrival_depth = float(solver.arrival_depth)
        del solver

        def sea(dom):
            return anuga.Flather_external_stage_zero_velocity_boundary(
                dom, lambda t: SEA_LEVEL, default_boundary=SEA_LEVEL)

        dom = anuga_domain(mesh, bed=bed, depth=h0, flow_algorithm=order,
                           boundaries={"sea": sea}, manning=MALPASSET_MANNING, name=name,
                           datadir=str(work), threads=1)
        if anuga_bed == "vertices":
            # the mesh's node elevations at the triangles' vertices (ANUGA's usual bed:
            # continuous, piecewise linear); the centroid values stay driftlog's face bed
            # (mean of the nodes), the stage is set again on them
            dom.set_quantity("elevation", mesh.node_z[mesh.face_nodes[:, :3]],
                             location="vertices")
            if not np.allclose(dom.quantities["elevation"].centroid_values, bed, atol=1e-9):
                raise RuntimeError("ANUGA's centroid bed differs from driftlog's face bed")
            dom.set_quantity("stage", bed + h0, location="centroids")
        op = extremes_operator(dom, arrival_depth)
        setup_cpu = time.process_time() - cpu_start
        steps = 0
        cpu = time.process_time()
        t0 = time.perf_counter()
        for _ in dom.evolve(yieldstep=INTERVAL, finaltime=end):
            steps += dom.number_of_steps  # counted since the last yield
        wall = time.perf_counter() - t0
        cpu = time.process_time() - cpu
        q = dom.quantities
        h = q["stage"].centroid_values - q["elevation"].centroid_values
        max_level, max_depth, arrival = op.max_level, op.max_depth, op.arrival
        max_level = np.where(np.isfinite(max_level), max_level, np.nan)
        facts.update(steps=int(steps), wall_s=wall, cpu_s=cpu,
                     volume_m3=float(np.nansum(h * mesh.face_area)),
                     arrival_depth_m=arrival_depth, anuga=anuga.__version__,
                     scheme=f"{order}: {dom.get_timestepping_method()}, beta_w "
                            f"{float(dom.beta_w):g}, CFL {float(dom.CFL):g}",
                     cfl=float(dom.CFL), sea_boundary="Flather_external_stage_zero_velocity",
                     anuga_bed=anuga_bed, nan_faces=int(np.isnan(h).sum()))
        Path(work, dom.get_name() + ".sww").unlink(missing_ok=True)
    facts["setup_cpu_s"] = setup_cpu
    facts["cell_updates_per_cpu_s"] = mesh.n_faces * facts["steps"] / facts["cpu_s"]
    np.savez(work / f"{name}.npz", max_level=max_level, max_depth=max_depth, arrival=arrival,
             bed=bed)
    (work / f"{name}.json").write_text(json.dumps(facts, indent=1))
    print(json.dumps(facts, indent=1), flush=True)


def _children_cpu():
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_child(name, end, work, anuga_bed="centroids", thin_fraction=None):
    """Run ``name`` in a child process; add its process's wall and CPU time to its facts."""
    cpu0, t0 = _children_cpu(), time.perf_counter()
    Path(work).mkdir(parents=True, exist_ok=True)
    log = Path(work) / f"{name}.log"
    with open(log, "w") as f:
        rc = subprocess.call([sys.executable, str(Path(__file__).resolve()), "--child", name,
                              "--end", str(end), "--work", str(work), "--anuga-bed", anuga_bed]
                             + ([] if thin_fraction is None
                                else ["--thin-fraction", repr(thin_fraction)]),
                             stdout=f,
                             stderr=subprocess.STDOUT)
    if rc != 0:
        print(log.read_text()[-3000:])
        raise SystemExit(f"{name}: the run failed (exit {rc}); log {log}")
    path = Path(work) / f"{name}.json"
    facts = json.loads(path.read_text())
    facts["process_wall_s"] = time.perf_counter() - t0
    facts["process_cpu_s"] = _children_cpu() - cpu0
    path.write_text(json.dumps(facts, indent=1))
    return facts


# --------------------------------------------------------------------------- the comparison
def compare_run(name, work, end, mesh, observations):
    """The comparison of one finished run: its facts, point rows and headline numbers."""
    from malpasset_compare import extremes_points, headline, observed_reach

    from driftlog.floodsetup import MALPASSET_DAM

    facts = json.loads((Path(work) / f"{name}.json").read_text())
    ex = np.load(Path(work) / f"{name}.npz")
    rows, _ = extremes_points(mesh, ex["bed"], ex["max_level"], ex["max_depth"], ex["arrival"],
                              observations, MALPASSET_DAM, facts["arrival_depth_m"],
                              facts["end_s"])
    if end < FULL_END:
        rows = observed_reach(rows, end / 2)
    # a face whose state became NaN keeps a NaN maximum depth (np.maximum propagates it)
    facts["nan_faces"] = int(np.isnan(ex["max_depth"]).sum())
    return facts, rows, headline(rows)


def _ratio(a, b):
    return a / b if a and b else np.nan


def report(work, end, names, stem, notes=""):
    """Table, json, csv and chart of the finished runs among ``names``."""
    from driftlog.floodsetup import read_observations
    from driftlog.mesh import read_mesh

    observations = read_observations(data_dir() / "observations.csv")
    mesh = read_mesh(data_dir() / "malpasset_mesh.nc")
    done = [n for n in names if (Path(work) / f"{n}.npz").is_file()]
    if not done:
        raise SystemExit(f"no finished run in {work}")
    out, table = {}, []
    for n in done:
        facts, rows, head = compare_run(n, work, end, mesh, observations)
        out[n] = {"facts": facts, "headline": head, "points": rows}
        table.append({
            "run": facts["label"], "steps": facts["steps"], "cpu_s": facts["cpu_s"],
            "wall_s": facts["wall_s"], "process_cpu_s": facts.get("process_cpu_s", np.nan),
            "level_rmse_m": head["level_rmse_m"], "level_n": head["level_n"],
            "worst_point": f"{head['worst_point']} {head['worst_error_m']:+.1f} m",
            "arrival_rms_s": head["arrival_rms_s"], "arrival_n": head["arrival_n"],
            "cell_updates_per_cpu_s": facts["cell_updates_per_cpu_s"],
            "nan_faces": facts["nan_faces"], "dry": ", ".join(head["dry"]) or "-",
            "not_reached": ", ".join(head["not_reached"]) or "-"})
    # the same points for every run: those every finished run wets (levels) or reaches
    # (arrivals), so that a point one run leaves dry does not change the others' sample
    from malpasset_compare import headline

    def ids(rows, key):
        return {r["id"] for r in rows if np.isfinite(r[key])}

    lev_ids = set.intersection(*(ids(out[n]["points"], "level_error_m") for n in done))
    arr_ids = set.intersection(*(ids(out[n]["points"], "arrival_error_s") for n in done))
    for n, row in zip(done, table, strict=True):
        pts = out[n]["points"]
        lev = headline([r for r in pts if r["id"] in lev_ids])
        arr = headline([r for r in pts if r["id"] in arr_ids])
        out[n]["common"] = {"level_rmse_m": lev["level_rmse_m"], "level_n": lev["level_n"],
                            "worst_point": lev["worst_point"],
                            "worst_error_m": lev["worst_error_m"],
                            "arrival_rms_s": arr["arrival_rms_s"], "arrival_n": arr["arrival_n"]}
        row["level_rmse_common_m"] = lev["level_rmse_m"]
        row["arrival_rms_common_s"] = arr["arrival_rms_s"]
    ratios = {}
    cpu = {n: out[n]["facts"]["cpu_s"] for n in done}
    head = {n: out[n]["headline"] for n in done}
    common = {n: out[n]["common"] for n in done}
    if "anuga-DE0" in cpu:
        for n in ("driftlog-o1", "driftlog-o2"):
            if n in cpu:
                ratios[f"{n} speed vs DE0 (DE0 CPU / its CPU)"] = _ratio(cpu["anuga-DE0"], cpu[n])
    if "anuga-DE1" in head and "driftlog-o2" in head:
        for k in ("level_rmse_m", "arrival_rms_s"):
            ratios[f"driftlog-o2 {k} / DE1's"] = _ratio(head["driftlog-o2"][k],
                                                        head["anuga-DE1"][k])
            ratios[f"driftlog-o2 {k} / DE1's, common points"] = _ratio(
                common["driftlog-o2"][k], common["anuga-DE1"][k])
    missing = [n for n in names if n not in done]
    scope = (f"all points with an observed value ({FULL_END:g} s)" if end >= FULL_END else
             f"the points up to where the observed front is at {end / 2:g} s (half the run)")
    text_notes = (
        f"Malpasset, {end:g} s simulated, {mesh.n_faces} triangles, one thread each, one run "
        f"after the other. CPU: the run's own CPU time (driftlog `run`, ANUGA `evolve`); "
        f"process CPU: the whole child process (imports, mesh, set-up). Level RMSE over the "
        f"police points and gauges the run wets; arrival RMS over the timed points it reaches "
        f"(arrival: depth > 0.05 m); compared on {scope}. `_common`: over the points every "
        f"run here wets ({len(lev_ids)}: {', '.join(sorted(lev_ids))}) or reaches "
        f"({len(arr_ids)}: {', '.join(sorted(arr_ids))}). nan_faces: triangles whose state "
        f"became NaN during the run."
        + (f" Not finished: {', '.join(missing)}." if missing else "")
        + (f" {notes}" if notes else ""))
    columns = ["run", "steps", "cpu_s", "wall_s", "process_cpu_s", "level_rmse_m", "level_n",
               "worst_point", "arrival_rms_s", "arrival_n", "level_rmse_common_m",
               "arrival_rms_common_s", "cell_updates_per_cpu_s", "nan_faces", "dry",
               "not_reached"]
    write_table(stem, table, columns, f"Malpasset beside ANUGA ({end:g} s)", text_notes)
    lines = ["", "| ratio | value |", "|---|---|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in ratios.items()]
    lines += ["", "| run | scheme | commit / version | load at start |", "|---|---|---|---|"]
    for n in done:
        f = out[n]["facts"]
        lines.append(f"| {f['label']} | {f.get('scheme', '-')} | "
                     f"{f.get('commit', f.get('anuga', '-'))} | {f['machine']} |")
    extra = "\n".join(lines) + "\n"
    with open(RESULTS / f"{stem}.md", "a") as fh:
        fh.write(extra)
    print(extra)
    (RESULTS / f"{stem}.json").write_text(json.dumps(
        {"end_s": end, "runs": out, "ratios": ratios, "missing": missing,
         "common_level_points": sorted(lev_ids), "common_arrival_points": sorted(arr_ids),
         "notes": text_notes}, indent=1, default=float))
    plot(out, RESULTS / f"{stem}.png", end)
    return out, ratios


def plot(out, path, end):
    """Work-precision: level RMSE and arrival RMS (over the points every run wets / reaches)
    against the run's CPU time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

    style = {"driftlog-o1": "o", "driftlog-o2": "s", "anuga-DE0": "^", "anuga-DE1": "v"}
    colour = {"driftlog-o1": "C0", "driftlog-o2": "C0", "anuga-DE0": "C3", "anuga-DE1": "C3"}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    n_lev = next(iter(out.values()))["common"]["level_n"]
    n_arr = next(iter(out.values()))["common"]["arrival_n"]
    for ax, key, what in ((axes[0], "level_rmse_m", f"maximum-level RMSE, {n_lev} points (m)"),
                          (axes[1], "arrival_rms_s", f"arrival-time RMS, {n_arr} points (s)")):
        for n, r in out.items():
            x, y = r["facts"]["cpu_s"], r["common"][key]
            ax.plot(x, y, style[n], color=colour[n], ms=9, mfc="none" if "o1" in n
                    or "DE0" in n else colour[n], label=r["facts"]["label"])
            ax.annotate(r["facts"]["label"], (x, y), fontsize=8, xytext=(6, 4),
                        textcoords="offset points")
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(f"CPU time of the run, one thread (s), {end:g} s simulated")
        ax.set_ylabel(what)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title("Malpasset: peak levels against the field and the scale model", fontsize=10)
    axes[1].set_title("Malpasset: arrival of the flood (gauges, transformers)", fontsize=10)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _commit():
    try:
        def last(*paths):
            return subprocess.run(["git", "-C", str(ROOT), "log", "-1", "--format=%h", "--",
                                   *paths], capture_output=True, text=True,
                                  check=True).stdout.strip()

        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--",
                                "driftlog"], capture_output=True, text=True).stdout.strip()
        return (f"HEAD {last()}, driftlog/solver at {last('driftlog/solver')}"
                + (" (driftlog/ modified)" if dirty else ""))
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--end", type=float, default=None, help=f"end time (s), default "
                   f"{FULL_END:g}")
    p.add_argument("--quick", action="store_true", help="120 s: a smoke run")
    p.add_argument("--runs", nargs="+", default=list(RUNS), choices=list(RUNS))
    p.add_argument("--work", default=None, help="folder of the runs' extremes and facts "
                   "(default /tmp/malpasset_peers_<end>)")
    p.add_argument("--reuse", action="store_true", help="skip runs already finished in --work")
    p.add_argument("--report-only", action="store_true", help="table the finished runs only")
    p.add_argument("--notes", default="", help="a line for the table's notes")
    p.add_argument("--tag", default="", help="appended to the results' names (e.g. a "
                   "solver branch), so that they do not replace the plain run's")
    p.add_argument("--anuga-bed", default="centroids", choices=("centroids", "vertices"),
                   help="ANUGA's bed: driftlog's face bed, constant per triangle (default), or "
                   "the node elevations at the vertices")
    p.add_argument("--thin-fraction", type=float, default=None,
                   help="driftlog order 2: the thin-water fraction k of docs/model.md (69) "
                   "(default: the solver's, 0.03); give a --work and --tag per value")
    p.add_argument("--child", choices=list(RUNS), help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    end = a.end or (120.0 if a.quick else FULL_END)
    work = Path(a.work or f"/tmp/malpasset_peers_{end:g}")
    if a.child:
        run_one(a.child, end, work, a.anuga_bed, a.thin_fraction)
        return 0
    if not a.report_only:
        try:
            import anuga  # noqa: F401
        except ImportError as e:
            raise SystemExit(f"ANUGA not importable ({e}): pip install anuga") from e
        for n in a.runs:
            if a.reuse and (work / f"{n}.npz").is_file():
                print(f"{n}: reused from {work}")
                continue
            print(f"{n}: running to {end:g} s ...", flush=True)
            facts = run_child(n, end, work, a.anuga_bed, a.thin_fraction)
            facts["commit"] = _commit() if n.startswith("driftlog") else facts.get("anuga")
            (work / f"{n}.json").write_text(json.dumps(facts, indent=1))
            print(f"{n}: {facts['steps']} steps, {facts['cpu_s']:.1f} CPU s, "
                  f"{facts['wall_s']:.1f} wall s", flush=True)
    stem = "malpasset_peers" + ("" if end >= FULL_END else f"_{end:g}s") + (
        f"_{a.tag}" if a.tag else "")
    report(work, end, a.runs if not a.report_only else list(RUNS), stem, a.notes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
