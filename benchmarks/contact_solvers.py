"""Moreau-Jean's contact impulses on a pile: projected Gauss-Seidel against NNCG (issue 15).

``[contact] solver`` is "pgs" (projected Gauss-Seidel, the default) or "nncg" (the same sweeps
with nonsmooth nonlinear conjugate gradient steps, Silcowitz, Niebe and Erleben 2010;
docs/model.md (54b)).  On ``cases/bridge_jam`` (30 logs against a bridge deck, restitution 0.3,
40 s):

1. The case (an analytic flow: the global clock) with each solver at its cap of 200 sweeps:
   contact steps, sweeps, steps stopped at the cap unconverged, the deepest overlap and CPU
   time.
2. The steps of the Gauss-Seidel run whose solve stopped at the cap (up to ``--keep``), each
   solved again without a cap by both solvers: the sweeps each needed to converge (median,
   90th percentile, largest), and how far apart their end velocities are.

    python benchmarks/contact_solvers.py [--keep 400]

writes benchmarks/results/contact_solvers.{md,csv} and contact_solvers_uncapped.{md,csv},
contact_solvers.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_table  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
CASE = ROOT / "cases" / "bridge_jam" / "scenario.toml"


def run_case(solver, out, keep=0):
    """The case with this solver: (row, kept solves)."""
    import netCDF4

    from driftlog.api import as_scenario, track
    from driftlog.contact import model as mm

    scen = as_scenario(CASE, {"contact": {"solver": solver}})
    kept = []
    orig = mm.moreau_solve
    if keep:  # the global clock solves through the name moreau_solve of contact.model
        def wrap(*a):
            args = tuple(x.copy() if isinstance(x, np.ndarray) else x for x in a)
            it, r = orig(*a)
            if r > a[11] and len(kept) < keep:
                kept.append(args)
            return it, r
        mm.moreau_solve = wrap
    c = time.process_time()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = track(scen, output=out)
    finally:
        mm.moreau_solve = orig
    cpu = time.process_time() - c
    with netCDF4.Dataset(res.path) as ds:
        cs = json.loads(ds.getncattr("contact_stats"))
    row = dict(solver=solver, contact_steps=int(cs["substeps"]),
               sweeps=int(cs["pgs_iterations"]), capped=int(cs["pgs_capped"]),
               deepest_overlap_mm=round(-1e3 * min(cs["min_gap"], 0.0), 3), cpu_s=round(cpu, 2))
    return row, kept


def uncapped(kept, cap):
    """Each kept solve again by both solvers with a cap of ``cap`` sweeps."""
    from driftlog.contact.moreau import NNCG, PGS, moreau_solve

    its = {PGS: [], NNCG: []}
    diff = []
    for a in kept:
        out = {}
        for solver in (PGS, NNCG):
            S = a[1].copy()
            P = np.zeros_like(a[13])
            it, _ = moreau_solve(*a[:1], S, *a[2:12], cap, P, *a[14:16], solver)
            its[solver].append(it)
            out[solver] = S
        diff.append(float(np.abs(out[PGS][:, 3:] - out[NNCG][:, 3:]).max()))
    rows = []
    for solver, name in ((PGS, "pgs"), (NNCG, "nncg")):
        x = np.array(its[solver])
        rows.append(dict(solver=name, steps=len(x), median_sweeps=float(np.median(x)),
                         p90_sweeps=float(np.percentile(x, 90)), max_sweeps=int(x.max()),
                         within_200=int((x <= 200).sum()), at_cap=int((x >= cap).sum())))
    return rows, diff


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--keep", type=int, default=400, help="capped steps solved again")
    p.add_argument("--cap", type=int, default=100000, help="sweeps at most when solved again")
    a = p.parse_args()
    rows, kept = [], []
    with tempfile.TemporaryDirectory() as tmp:
        run_case("pgs", Path(tmp) / "warm.nc")  # compiled or loaded before timing
        run_case("nncg", Path(tmp) / "warm.nc")
        for solver in ("pgs", "nncg"):
            row, k = run_case(solver, Path(tmp) / "run.nc", a.keep if solver == "pgs" else 0)
            rows.append(row)
            kept += k
    cols = ["solver", "contact_steps", "sweeps", "capped", "deepest_overlap_mm",
            "cpu_s"]
    write_table("contact_solvers", rows, cols,
                "cases/bridge_jam (40 s, 30 logs, cap 200 sweeps): Gauss-Seidel and NNCG")
    urows, diff = uncapped(kept, a.cap)
    note = (f"The {len(kept)} steps of the Gauss-Seidel run that stopped at the "
            f"cap, solved again with a cap of {a.cap}; the two solvers' end velocities differ "
            f"by {np.median(diff):.2g} m/s (median), {max(diff):.2g} m/s at most.")
    write_table("contact_solvers_uncapped", urows, ["solver", "steps", "median_sweeps",
                                                    "p90_sweeps", "max_sweeps", "within_200",
                                                    "at_cap"],
                "Sweeps to converge on the jam's capped steps", note)
    (RESULTS / "contact_solvers.json").write_text(json.dumps(
        {"machine": machine(), "runs": rows, "uncapped": urows,
         "velocity_difference_median": float(np.median(diff)),
         "velocity_difference_max": max(diff)}, indent=1))


if __name__ == "__main__":
    main()
