"""Order 2's energy bound on a smooth moving shoreline: Thacker's paraboloid on a node bed.

``[solver] energy_bound`` (docs/model.md eq. (85)) acts only on a bed given at the nodes, so
neither SWASHES nor ``thacker_convergence.py`` (beds on the faces) sees it.  Here the planar
surface in a paraboloid (SWASHES 2 1 1 2: a = 1 m, h0 = 0.1 m, eta = 0.5; unstructured
triangles, one period) runs with its bed at the mesh nodes, at order 2 with each bound, at
three resolutions: the L1 error of the depth against the closed form (on the solver's own face
bed, the exact level minus it), the observed order, the largest speed in faces under 1 mm
deep, the lowest depth and the volume error.  Writes
benchmarks/results/thacker_energy_bound.{md,json}.

    python benchmarks/thacker_energy_bound.py
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import RESULTS, machine  # noqa: E402
from thacker_convergence import G, _run  # noqa: E402

from driftlog.mesher import polygon_mesh, rectangle  # noqa: E402
from driftlog.solver import ShallowWaterSolver  # noqa: E402
from driftlog.solver.swashes import thacker_paraboloid  # noqa: E402

BOUNDS = (("off", 0.0), ("g2", 0.0), ("rising", 0.0), ("rising", 0.4), ("velocity", 0.0),
          ("hr", 0.0))
SIZES = (0.2, 0.1, 0.05)


def paraboloid_node_bed(size, bound, widen):
    """One period of the paraboloid, bed at the nodes, order 2 with ``bound``."""
    mesh = polygon_mesh(rectangle(-1.6, -1.6, 1.6, 1.6), size)
    mesh.node_z = thacker_paraboloid(mesh.node_x, mesh.node_y, 0.0)[0]
    z, h, u, v, om = thacker_paraboloid(mesh.face_x, mesh.face_y, 0.0)
    s = ShallowWaterSolver(mesh, order=2, energy_bound=bound, energy_widen=widen)
    h0 = np.maximum(h + z - s.bed, 0.0)  # the exact level on the solver's face bed

    def exact():
        ze, he = thacker_paraboloid(mesh.face_x, mesh.face_y, s.t)[:2]
        return np.maximum(he + ze - s.bed, 0.0)

    s.set_state(h0, h0 * u, h0 * v)
    row = _run(s, 2 * np.pi / om, exact, float(np.abs(v).max()) + np.sqrt(G * h.max()))
    row.update(bound=bound, widen=widen, n=mesh.n_faces,
               dx=float(np.sqrt(2 * mesh.face_area.mean())))
    return row


def main(argv=None):
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    paraboloid_node_bed(0.4, "off", 0.0)  # compile first: CPU times without it
    rows = []
    for bound, widen in BOUNDS:
        group = [paraboloid_node_bed(d, bound, widen) for d in SIZES]
        for i, r in enumerate(group):
            r["order_obs"] = (float(np.log(group[i - 1]["l1_h"] / r["l1_h"])
                                    / np.log(group[i - 1]["dx"] / r["dx"])) if i else None)
            print(f"{bound} w{widen:g} n={r['n']:<6} L1={r['l1_h']:.3e} "
                  f"order={r['order_obs'] and round(r['order_obs'], 2)} "
                  f"thin max {r['fastest_thin']:.2f} lowest {r['lowest_depth']:.1e} "
                  f"steps {r['steps']} {r['cpu_s']:.1f} s", flush=True)
        rows += group
    lines = ["### Order 2's energy bound on Thacker's paraboloid (bed at the nodes)", "",
             f"Measured on {machine()}. `benchmarks/thacker_energy_bound.py`: SWASHES 2 1 1 2, "
             "one period, order 2. L1(h): area-weighted mean |h - h_exact| (m); observed "
             "order between successive resolutions; 'thin max': the largest speed in faces "
             "under 1 mm deep over the run (m/s); 'lowest': the smallest depth at any step.",
             "", "| energy_bound | energy_widen | cells | L1(h) (m) | observed order | "
             "thin max (m/s) | lowest depth (m) | steps | CPU (s) | volume error |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        o = f"{r['order_obs']:.2f}" if r["order_obs"] is not None else ""
        lines.append(f"| {r['bound']} | {r['widen']:g} | {r['n']} | {r['l1_h']:.3e} | {o} | "
                     f"{r['fastest_thin']:.2f} | {r['lowest_depth']:.1e} | {r['steps']} | "
                     f"{r['cpu_s']:.1f} | {r['rel_volume_error']:.1e} |")
    (RESULTS / "thacker_energy_bound.md").write_text("\n".join(lines) + "\n")
    (RESULTS / "thacker_energy_bound.json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
