"""driftlog's shallow-water solver side by side with ANUGA and OpenFOAM's shallowWaterFoam.

Issue 3 ("Measured"): the same case on the same mesh, in one run, single thread each, the
same end time and the same number of outputs; wall time, L1 error of the depth against the
exact solution (SWASHES), cell-updates per second.

A. Ritter's dam break on a dry bed (SWASHES ``1 3 1 2``: 5 mm of still water on x < 5 m,
   dry beyond, 6 s) in a 10 m x 0.2 m strip of unstructured triangles (driftlog's mesher):
   driftlog at first and second order, and ANUGA on the very same triangles
   (``anuga.Domain(points, triangles, boundary)``): its default flow algorithm DE0 (explicit
   Euler in time, limited second-order reconstruction in space with beta = 0.5), DE1 (second
   order in time and space: Runge-Kutta 2, beta = 1), and DE0 with every limiter beta set to 0
   (slopes zeroed: first order in space), so that each order has its peer.
C. Stoker's dam break on a wet bed (below) on the triangles of A, the same five runs (a shock
   instead of a dry front).
B. Stoker's dam break on a wet bed (SWASHES ``1 3 1 1``: 5 mm against 1 mm, 6 s) on a strip
   of square cells one cell wide, which OpenFOAM extrudes to hexahedra: driftlog at first and
   second order and shallowWaterFoam (v1912, written and read back by
   ``driftlog.adapters.openfoam_case``; it needs water everywhere, hence the wet case).

Every solver writes its results at t = 0, 1, ..., 6 s (7 snapshots: driftlog's flow file,
ANUGA's sww, OpenFOAM's time directories); numba's caches and ANUGA's extensions are warmed on
the coarsest mesh first; a run shorter than a few seconds is repeated and the best time kept.
Threads: ``NUMBA_NUM_THREADS=1`` and ``OMP_NUM_THREADS=1`` (ANUGA's OpenMP kernels), set
before anything is imported; OpenFOAM runs serial.

    python benchmarks/solver_peers.py            # 3 to 5 resolutions (about 9 min)
    python benchmarks/solver_peers.py --quick    # 3 coarse resolutions (under 2 min)

writes benchmarks/results/shallow_water_peers_{triangles,triangles_stoker,strip}.{csv,md},
shallow_water_peers.json, shallow_water_peers.png (work-precision: L1 error of h against
wall and CPU time, one curve per solver and order) and shallow_water_peers_profiles.png
(depth profiles against the exact ones); ``--quick`` writes shallow_water_peers_quick*.
"""

import os

# single thread each, before numba, numpy or ANUGA are imported
os.environ["NUMBA_NUM_THREADS"] = "1"
os.environ["OMP_NUM_THREADS"] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import resource  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _common import RESULTS, machine, write_table  # noqa: E402

from driftlog.mesh import Mesh  # noqa: E402
from driftlog.mesher import channel_mesh  # noqa: E402
from driftlog.solver import ShallowWaterSolver  # noqa: E402
from driftlog.solver.swashes import swashes_solution  # noqa: E402

LENGTH, WIDTH, DAM = 10.0, 0.2, 5.0  # m: the SWASHES dam-break domain, a strip of it
H_LEFT = 0.005  # m, both SWASHES dam breaks
H_RIGHT = {"ritter": 0.0, "stoker": 0.001}
CHOICE = {"stoker": 1, "ritter": 2}  # SWASHES 1 3 1 <choice>
T_END, N_OUT = 6.0, 6  # s, output intervals (7 snapshots with the initial one)
EXACT_CELLS = 20000  # the exact solution's sampling (0.5 mm): far below any mesh here
TRI_CELLS = {"full": (0.1, 0.05, 0.025, 0.015), "quick": (0.1, 0.05, 0.025)}
STRIP_CELLS = {"full": (100, 200, 400, 800, 1600), "quick": (100, 200, 400)}
ANUGA_RUNS = (("DE0", None), ("DE1", None), ("DE0", 0.0))  # algorithm, limiter beta override
BETAS = ("beta_w", "beta_w_dry", "beta_uh", "beta_uh_dry", "beta_vh", "beta_vh_dry")
FOAM_COURANT = 0.5  # shallowWaterFoam's fixed step: Courant number on |u| + sqrt(g h)
TRI_STOKER_CELLS = {"full": (0.1, 0.05, 0.025), "quick": (0.1, 0.07, 0.05)}
# the resolution whose profiles are plotted: cell size (m) on triangles, cells on the strip
PROFILE_AT = {"triangles": 0.05, "triangles_stoker": 0.05, "strip": 400}
REPEAT_BUDGET = 3.0  # s: repeat a run while the repeats so far took less than this


# --------------------------------------------------------------------------- the cases
_EXACT = {}


def exact_depth(case, x):
    """SWASHES' depth of the dam break ``case`` at t = 6 s, at the points x (m)."""
    if case not in _EXACT:
        sol = swashes_solution(3, 1, CHOICE[case], EXACT_CELLS)
        _EXACT[case] = (sol["x"], sol["h"])
    xs, hs = _EXACT[case]
    return np.interp(x, xs, hs)


def initial_depth(case, mesh):
    return np.where(mesh.face_x < DAM, H_LEFT, H_RIGHT[case])


def l1_error(case, mesh, h):
    """Area-weighted mean |h - h_exact| at the face centroids (m)."""
    a = mesh.face_area
    return float(np.sum(a * np.abs(h - exact_depth(case, mesh.face_x))) / a.sum())


def triangle_strip(cell):
    return channel_mesh(LENGTH, WIDTH, cell)


def square_strip(nx):
    dx = LENGTH / nx
    return Mesh.regular_grid(nx, 1, dx, dx)


def bore(mesh, h):
    """How sharp the computed Stoker bore is: cells in its 10-90 % rise, overshoot.

    The exact bore at t = 6 s jumps from the plateau h_m down to h_r at x_s; counted are the
    cells within 0.5 m of x_s whose depth lies between h_r + 0.1 (h_m - h_r) and
    h_r + 0.9 (h_m - h_r), and the largest depth there above h_m, as a fraction of the jump.
    """
    exact_depth("stoker", 0.0)
    xs, hs = _EXACT["stoker"]
    i = int(np.argmin(np.diff(hs)))  # the steepest drop: the bore
    x_s, h_m, h_r = 0.5 * (xs[i] + xs[i + 1]), hs[i], hs[i + 1]
    jump = h_m - h_r
    near = np.abs(mesh.face_x - x_s) < 0.5
    hn = h[near]
    rise = (hn > h_r + 0.1 * jump) & (hn < h_r + 0.9 * jump)
    return {"bore_cells": int(rise.sum()),
            "bore_overshoot": float(max(hn.max() - h_m, 0.0) / jump)}


def best_of(fn):
    """Run ``fn`` (returns a dict with 'wall'); repeat short runs, keep the fastest."""
    best, spent = None, 0.0
    while best is None or (spent < REPEAT_BUDGET and len(best["walls"]) < 3):
        r = fn()
        spent += r["wall"]
        walls = ([] if best is None else best["walls"]) + [r["wall"]]
        if best is None or r["wall"] < best["wall"]:
            best = r
        best["walls"] = walls
    return best


# --------------------------------------------------------------------------- driftlog
def run_driftlog(case, mesh, order, workdir):
    """driftlog's solver to T_END writing N_OUT + 1 snapshots; wall time of ``run``."""
    s = ShallowWaterSolver(mesh, order=order)
    s.set_state(initial_depth(case, mesh))
    out = Path(workdir) / f"driftlog_{case}_o{order}.nc"
    cpu = time.process_time()
    res = s.run(T_END, output=out, output_interval=T_END / N_OUT)
    cpu = time.process_time() - cpu
    out.unlink()
    return {"wall": res.wall_time, "cpu": cpu, "steps": res.steps, "h": s.h.copy(),
            "volume_error": res.relative_volume_error}


# --------------------------------------------------------------------------- ANUGA
def run_anuga(case, mesh, algorithm, beta, workdir):
    """ANUGA to T_END on the mesh's triangles (walls all round), N_OUT + 1 sww frames."""
    from driftlog.adapters.anuga_case import anuga_domain

    dom = anuga_domain(mesh, bed=0.0, depth=initial_depth(case, mesh), flow_algorithm=algorithm,
                       name=f"anuga_{case}_{algorithm}", datadir=workdir, threads=1)
    if beta is not None:
        for name in BETAS:
            setattr(dom, name, beta)
    steps = 0
    cpu = time.process_time()
    t0 = time.perf_counter()
    for _ in dom.evolve(yieldstep=T_END / N_OUT, finaltime=T_END):
        steps += dom.number_of_steps  # counted since the last yield
    wall = time.perf_counter() - t0
    cpu = time.process_time() - cpu
    q = dom.quantities
    h = q["stage"].centroid_values - q["elevation"].centroid_values
    Path(workdir, dom.get_name() + ".sww").unlink()
    return {"wall": wall, "cpu": cpu, "steps": steps, "h": np.array(h), "cfl": float(dom.CFL),
            "timestepping": dom.get_timestepping_method(), "beta_w": float(dom.beta_w)}


# --------------------------------------------------------------------------- OpenFOAM
def _children_cpu():
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_foam(case, mesh, workdir):
    """shallowWaterFoam on the strip extruded to hexahedra; wall time of the solver process."""
    from driftlog.adapters.openfoam import open_openfoam
    from driftlog.adapters.openfoam_case import run_case, write_shallow_water_case

    folder = Path(workdir) / f"foam_{case}_{mesh.n_faces}"
    info = write_shallow_water_case(folder, mesh, depth=initial_depth(case, mesh),
                                    end_time=T_END, write_interval=T_END / N_OUT,
                                    courant=FOAM_COURANT)
    cpu = _children_cpu()
    t0 = time.perf_counter()
    run_case(folder)
    wall = time.perf_counter() - t0
    cpu = _children_cpu() - cpu
    log = (folder / "log.shallowWaterFoam").read_text()
    exec_time = float(re.findall(r"ExecutionTime = ([0-9.eE+-]+) s", log)[-1])
    flow = open_openfoam(folder, dry_depth=1e-9)
    h = flow.read_snapshot(len(flow.times) - 1)[0]
    if abs(flow.times[-1] - T_END) > 1e-9:
        raise RuntimeError(f"{folder}: last written time {flow.times[-1]}, expected {T_END}")
    # the case's cells come back as the faces of a 2D mesh rebuilt from the polyMesh: match
    # them to ours by centroid
    order = np.lexsort((flow.mesh.face_y, flow.mesh.face_x))
    ours = np.lexsort((mesh.face_y, mesh.face_x))
    h_ours = np.empty(mesh.n_faces)
    h_ours[ours] = h[order]
    steps = int(round(info["end_time"] / info["dt"]))
    return {"wall": wall, "cpu": cpu, "solver_time": exec_time, "steps": steps, "h": h_ours,
            "dt": info["dt"]}


# --------------------------------------------------------------------------- the runs
def _row(solver, order_label, part, case, mesh, size, r):
    err = l1_error(case, mesh, r["h"])
    row = {"solver": solver, "order": order_label, "cell_size_mm": 1e3 * size,
           "cells": mesh.n_faces, "steps": r["steps"], "wall_s": r["wall"], "cpu_s": r["cpu"],
           "l1_error_m": err, "cell_updates_per_s": mesh.n_faces * r["steps"] / r["wall"],
           "cell_updates_per_cpu_s": mesh.n_faces * r["steps"] / r["cpu"],
           "repeats": len(r["walls"])}
    if "solver_time" in r:
        row["solver_time_s"] = r["solver_time"]
    if part == "strip":
        row.update(bore(mesh, r["h"]))
    if (mesh.n_faces if part == "strip" else size) == PROFILE_AT[part]:
        row["_profile"] = (mesh.face_x, r["h"])
    print(f"  {solver:<28} {order_label:<26} {mesh.n_faces:>7} cells {r['steps']:>6} steps "
          f"{r['wall']:8.3f} s  L1 {err:.3e} m  {row['cell_updates_per_s']:.3g} cell-updates/s",
          flush=True)
    return row


def anuga_label(algorithm, beta):
    if beta is not None:
        return f"ANUGA {algorithm}, beta 0", "1 in space, Euler"
    return f"ANUGA {algorithm}", {"DE0": "2 in space (beta 0.5), Euler",
                                  "DE1": "2 (beta 1), RK2"}[algorithm]


def triangles_part(case, part, cells, workdir, with_anuga):
    rows, meta = [], {}
    warm = triangle_strip(cells[0])
    for order in (1, 2):
        run_driftlog(case, warm, order, workdir)
    if with_anuga:
        run_anuga(case, warm, "DE0", None, workdir)
    for size in cells:
        mesh = triangle_strip(size)
        print(f"{case}, triangles, {size} m: {mesh.n_faces} triangles", flush=True)
        for order in (1, 2):
            r = best_of(lambda o=order, m=mesh: run_driftlog(case, m, o, workdir))
            rows.append(_row("driftlog", {1: "1", 2: "2 (MUSCL, Heun)"}[order], part, case,
                             mesh, size, r))
        if not with_anuga:
            continue
        for algorithm, beta in ANUGA_RUNS:
            r = best_of(lambda a=algorithm, b=beta, m=mesh: run_anuga(case, m, a, b, workdir))
            name, label = anuga_label(algorithm, beta)
            rows.append(_row(name, label, part, case, mesh, size, r))
            meta[name] = {"cfl": r["cfl"], "timestepping": r["timestepping"],
                          "beta_w": r["beta_w"]}
    return rows, meta


def strip_part(cells, workdir, with_foam):
    case, part = "stoker", "strip"
    rows = []
    warm = square_strip(cells[0])
    for order in (1, 2):
        run_driftlog(case, warm, order, workdir)
    for nx in cells:
        mesh = square_strip(nx)
        size = LENGTH / nx
        print(f"strip of squares, {size} m: {nx} cells", flush=True)
        for order in (1, 2):
            r = best_of(lambda o=order, m=mesh: run_driftlog(case, m, o, workdir))
            rows.append(_row("driftlog", {1: "1", 2: "2 (MUSCL, Heun)"}[order], part, case,
                             mesh, size, r))
        if with_foam:
            r = best_of(lambda m=mesh: run_foam(case, m, workdir))
            rows.append(_row("shallowWaterFoam", "2 in space (LUST), Euler", "strip", case, mesh,
                             size, r))
    return rows


def observed_orders(rows):
    """Order between successive resolutions of each solver: log(e1/e2) / log(dx1/dx2)."""
    last = {}
    for r in rows:
        key = (r["solver"], r["order"])
        if key in last:
            p = last[key]
            r["observed_order"] = (np.log(p["l1_error_m"] / r["l1_error_m"])
                                   / np.log(p["cell_size_mm"] / r["cell_size_mm"]))
        last[key] = r


def ratios(rows, reference):
    """Wall time of each run over driftlog's run of ``reference`` order at the same mesh."""
    ref = {r["cells"]: r["wall_s"] for r in rows
           if r["solver"] == "driftlog" and r["order"].startswith(reference)}
    for r in rows:
        r[f"wall_vs_driftlog_o{reference}"] = r["wall_s"] / ref[r["cells"]]


def time_to_error(rows, second_order_only=False, key="wall_s"):
    """Time (``key``: wall_s or cpu_s) each solver needs for the same L1 error.

    The target is the largest of the curves' finest errors (the least accurate curve's best;
    only the second-order curves with ``second_order_only``), so that every curve reaches
    it; the time is interpolated log-log along each curve, or, for a curve already below
    the target at its coarsest mesh, that run's time (an upper bound).
    """
    curves = {}
    for r in rows:
        if second_order_only and not r["order"].startswith("2"):
            continue
        curves.setdefault((r["solver"], r["order"]), []).append((r["l1_error_m"], r[key]))
    target = max(min(e for e, _ in pts) for pts in curves.values())
    out = {}
    for k, pts in curves.items():
        pts.sort()
        e, w = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
        name = f"{k[0]}, order {k[1]}"
        if np.log(target) > e[-1]:
            out[name] = {key: pts[-1][1], "bound": "at most (coarsest run)"}
        else:
            out[name] = {key: float(np.exp(np.interp(np.log(target), e, w))),
                         "bound": "interpolated"}
    return target, out


def plot(parts, path):
    """Work-precision: L1 error against wall time (top) and CPU time (bottom), one panel per
    part."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(parts)
    fig, axes = plt.subplots(2, n, figsize=(6 * n, 10), squeeze=False)
    style = {"driftlog": "o-", "ANUGA": "s--", "shallowWaterFoam": "^:"}
    for row, (tkey, what) in enumerate((("wall_s", "wall time (s)"), ("cpu_s", "CPU time (s)"))):
        for col, part in enumerate(parts):
            ax = axes[row, col]
            rows = part["rows"]
            for key in dict.fromkeys((r["solver"], r["order"]) for r in rows):
                sel = [r for r in rows if (r["solver"], r["order"]) == key]
                mark = next(v for k, v in style.items() if key[0].startswith(k))
                ax.loglog([r[tkey] for r in sel], [r["l1_error_m"] for r in sel], mark,
                          label=f"{key[0]}, order {key[1]}")
            ax.set_xlabel(f"{what}, one thread, 6 s simulated, 7 outputs")
            ax.set_ylabel("L1 error of h against SWASHES (m)")
            ax.set_title(part["panel"], fontsize=10)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_cpu(result, path):
    """Work-precision on CPU time, the triangles (Ritter and Stoker): driftlog orders 1 and 2
    against ANUGA DE0 and DE1 (and DE0 with beta 0), one panel per dam break.

    Made from the results' JSON (``result``: what ``main`` writes), so that
    ``--plot-only`` redraws it from a stored run; the same layout as
    ``malpasset_peers.py``'s chart (issue 14: error against CPU time).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(k, t) for k, t in (("triangles", "Ritter's dam break, dry bed (SWASHES 1 3 1 2)"),
                                  ("triangles_stoker",
                                   "Stoker's dam break, wet bed (SWASHES 1 3 1 1)"))
              if result.get(k)]
    style = {("driftlog", "1"): ("C0", "o", "none"), ("driftlog", "2"): ("C0", "s", "C0"),
             ("ANUGA DE0", "2"): ("C3", "^", "none"), ("ANUGA DE1", "2"): ("C3", "v", "C3"),
             ("ANUGA DE0, beta 0", "1"): ("0.6", "^", "none")}
    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 4.8), squeeze=False)
    for ax, (key, title) in zip(axes[0], panels, strict=True):
        rows = result[key]
        for solver, order in dict.fromkeys((r["solver"], r["order"]) for r in rows):
            sel = sorted((r for r in rows if (r["solver"], r["order"]) == (solver, order)),
                         key=lambda r: r["cells"])
            colour, mark, face = style.get((solver, order[0]), ("k", "x", "none"))
            ax.loglog([r["cpu_s"] for r in sel], [r["l1_error_m"] for r in sel],
                      color=colour, marker=mark, mfc=face, ls="-" if solver == "driftlog"
                      else "--", label=f"{solver}, order {order}")
            last = sel[-1]
            ax.annotate(f"{last['cells']}", (last["cpu_s"], last["l1_error_m"]), fontsize=7,
                        xytext=(4, -8), textcoords="offset points", color=colour)
        ax.set_xlabel(f"CPU time, one thread (s), {result.get('end_time_s', T_END):g} s "
                      "simulated")
        ax.set_ylabel("L1 error of h against SWASHES (m)")
        ax.set_title(f"{title}\nunstructured triangles, the same for every solver",
                     fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"Work-precision on CPU time ({result.get('machine', '')}; "
                 f"{', '.join(f'{k} {v}' for k, v in result.get('versions', {}).items())})",
                 fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_profiles(parts, path):
    """Depth at 6 s against x, every cell of one resolution, beside the exact profile."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(parts)
    fig, axes = plt.subplots(1, n, figsize=(6.5 * n, 4.5), squeeze=False)
    for ax, part in zip(axes[0], parts, strict=True):
        case = part["case"]
        at = PROFILE_AT[part["key"]]
        where = f"{at} cells" if part["key"] == "strip" else f"{at * 1e3:g} mm triangles"
        x = np.linspace(0.0, LENGTH, 4001)
        ax.plot(x, 1e3 * exact_depth(case, x), "k-", lw=1.0, label="exact (SWASHES)")
        for r in part["rows"]:
            if "_profile" not in r:
                continue
            fx, h = r["_profile"]
            o = np.argsort(fx)
            ax.plot(fx[o], 1e3 * h[o], ".", ms=2 if part["key"] != "strip" else 3,
                    label=f"{r['solver']}, order {r['order']}")
        ax.set_xlim(3.0, 9.0)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("depth h (mm)")
        ax.set_title(f"{part['panel'].split(',')[0]} at 6 s, {where} (every cell)", fontsize=10)
        ax.legend(fontsize=7, markerscale=3)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def versions():
    import numba

    v = {"numpy": np.__version__, "numba": numba.__version__}
    try:
        import anuga

        v["anuga"] = anuga.__version__
    except ImportError:
        pass
    return v


COLUMNS = ["solver", "order", "cell_size_mm", "cells", "steps", "wall_s", "cpu_s", "l1_error_m",
           "observed_order", "cell_updates_per_s", "cell_updates_per_cpu_s",
           "wall_vs_driftlog_o1", "wall_vs_driftlog_o2", "repeats"]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="3 coarse resolutions (< 2 min)")
    p.add_argument("--skip-anuga", action="store_true")
    p.add_argument("--skip-openfoam", action="store_true")
    p.add_argument("--plot-only", action="store_true", help="redraw the CPU-time chart "
                   "(shallow_water_peers[_quick]_cpu.png) from the stored JSON")
    args = p.parse_args(argv)
    mode = "quick" if args.quick else "full"
    base = "shallow_water_peers" + ("_quick" if args.quick else "")  # quick keeps the full run
    if args.plot_only:
        stored = RESULTS / f"{base}.json"
        if not stored.is_file():
            raise SystemExit(f"{stored}: no stored run to plot (run without --plot-only)")
        plot_cpu(json.loads(stored.read_text()), RESULTS / f"{base}_cpu.png")
        print(f"wrote {RESULTS / f'{base}_cpu.png'}")
        return
    with_anuga, with_foam = not args.skip_anuga, not args.skip_openfoam
    notes = {}
    if with_anuga:
        try:
            import anuga  # noqa: F401
        except ImportError as e:
            with_anuga = False
            notes["anuga"] = f"not run: {e!r} (pip install anuga)"
    if with_foam:
        from driftlog.adapters.openfoam_case import foam_available

        if not foam_available():
            with_foam = False
            notes["openfoam"] = "not run: shallowWaterFoam not found"
    common = ("7 outputs each; one thread each. L1 error: area-weighted mean |h - h_exact| at "
              "the centroids. `wall_vs_driftlog_oN`: wall time over driftlog's at order N on "
              "the same mesh.")
    parts = [
        {"key": "triangles", "case": "ritter",
         "panel": "A. Ritter dry dam break, unstructured triangles",
         "title": "Solver peers A: ANUGA on the same triangles (Ritter, dry bed)",
         "note": f"Ritter's dam break (SWASHES 1 3 1 2) at t = {T_END:g} s in a {LENGTH:g} m x "
                 f"{WIDTH:g} m strip of unstructured triangles (driftlog's mesher), walls all "
                 "round, the same triangles for every solver; " + common},
        {"key": "triangles_stoker", "case": "stoker",
         "panel": "C. Stoker wet dam break, unstructured triangles",
         "title": "Solver peers C: ANUGA on the same triangles (Stoker, wet bed)",
         "note": f"Stoker's dam break (SWASHES 1 3 1 1) at t = {T_END:g} s on the triangles "
                 "of A; " + common},
        {"key": "strip", "case": "stoker",
         "panel": "B. Stoker wet dam break, strip of squares / hexahedra",
         "title": "Solver peers B: shallowWaterFoam on the same cells (Stoker, wet bed)",
         "note": f"Stoker's dam break (SWASHES 1 3 1 1) at t = {T_END:g} s on a strip of "
                 "square cells one cell wide (hexahedra, one cell thick, for OpenFOAM); "
                 f"shallowWaterFoam with a fixed step at Courant {FOAM_COURANT} on "
                 "|u| + sqrt(g h), wall time of the whole process (mesh and field reading "
                 "included); " + common,
         "extra": ["solver_time_s", "bore_cells", "bore_overshoot"]},
    ]
    t0 = time.perf_counter()
    anuga_meta = {}
    with tempfile.TemporaryDirectory(prefix="solver_peers_") as work:
        cells = {"triangles": TRI_CELLS[mode], "triangles_stoker": TRI_STOKER_CELLS[mode]}
        for part in parts:
            if part["key"] == "strip":
                part["rows"] = strip_part(STRIP_CELLS[mode], work, with_foam)
            else:
                part["rows"], meta = triangles_part(part["case"], part["key"], cells[part["key"]],
                                                    work, with_anuga)
                anuga_meta.update(meta)
    targets = {}
    for part in parts:
        rows = part["rows"]
        observed_orders(rows)
        ratios(rows, "1")
        ratios(rows, "2")
        write_table(f"{base}_{part['key']}", rows, COLUMNS + part.get("extra", []),
                    part["title"], part["note"])
        lines = []
        targets[part["key"]] = []
        for second, what in ((False, "curves"), (True, "second-order curves")):
            target, times = time_to_error(rows, second)
            _, cpus = time_to_error(rows, second, "cpu_s")
            targets[part["key"]].append({"l1_error_m": target, "curves": what, "wall_s": times,
                                         "cpu_s": cpus})
            lines += ["", f"Time to reach the same L1 error, {target:.3g} m (the finest error "
                      f"of the least accurate of the {what}), log-log interpolated along "
                      "each curve:", "", "| solver, order | wall time (s) | CPU time (s) | how |",
                      "|---|---|---|---|"]
            lines += [f"| {k} | {v['wall_s']:.3g} | {cpus[k]['cpu_s']:.3g} | {v['bound']} |"
                      for k, v in times.items()]
        text = "\n".join(lines) + "\n"
        with open(RESULTS / f"{base}_{part['key']}.md", "a") as f:
            f.write(text)
        print(text)
    plot(parts, RESULTS / f"{base}.png")
    plot_profiles(parts, RESULTS / f"{base}_profiles.png")
    result = {"machine": machine(), "mode": mode, "versions": versions(), "notes": notes,
              "threads": "NUMBA_NUM_THREADS=1, OMP_NUM_THREADS=1, OpenFOAM serial",
              "end_time_s": T_END, "outputs": N_OUT + 1, "anuga_settings": anuga_meta,
              "openfoam_courant": FOAM_COURANT, "time_to_error": targets}
    for part in parts:
        result[part["key"]] = [{k: v for k, v in r.items() if not k.startswith("_")}
                               for r in part["rows"]]
    result["total_wall_s"] = time.perf_counter() - t0
    (RESULTS / f"{base}.json").write_text(json.dumps(result, indent=1))
    plot_cpu(result, RESULTS / f"{base}_cpu.png")
    print(f"total {result['total_wall_s']:.0f} s; results in {RESULTS}")


if __name__ == "__main__":
    main()
