"""Kernel time against Python time in each part of a coupled run (issue 16, cost of coupling).

One coupled Malpasset run (``coupling_cost.scenario``: ``--logs`` logs in the reservoir, no
contacts) to ``--end``, with the main numba kernels of the tracker and of the coupling timed
where the Python code calls them.  Prints each part of ``Coupling.cpu`` (CPU s), the kernels'
seconds inside it and what is left: the Python work (and numpy's small passes) around them,
per solver step.  The kernels are timed in wall seconds (perf_counter) and the parts in CPU
seconds, so on a loaded machine compare runs made side by side.

    NUMBA_NUM_THREADS=1 python benchmarks/coupling_overhead.py --end 300 --clock per_log

Nothing is written; the trajectories and flow file go to a temporary folder.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

# part -> (module, kernel names called from it); a name missing in a version is skipped
KERNELS = {
    "tracker": [("driftlog.clocks", ("per_log_mesh_advance",)),
                ("driftlog.tracker", ("rk4_mesh_step", "euler_mesh_step"))],
    "flow_nodes": [("driftlog.coupling", ("refocus", "node_rows", "region_points"))],
    "handover": [("driftlog.coupling", ("spread_reaction", "give_share", "gather_reaction"))],
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--end", type=float, default=300.0)
    ap.add_argument("--logs", type=int, default=1000)
    ap.add_argument("--clock", default="per_log", choices=("global", "per_log"))
    a = ap.parse_args(argv)
    import importlib

    import netCDF4
    from coupling_cost import PARTS, scenario

    from driftlog.api import track

    tmp = Path(tempfile.mkdtemp(prefix="driftlog-overhead-"))
    track(scenario(20.0, 10, True, clock=a.clock), output=tmp / "warm.nc")  # numba's cache
    spent = {}

    def timed(f, key):
        def call(*args):
            c = time.perf_counter()
            try:
                return f(*args)
            finally:
                spent[key] = spent.get(key, 0.0) + time.perf_counter() - c
        return call

    for part, mods in KERNELS.items():
        for mod, names in mods:
            m = importlib.import_module(mod)
            for n in names:
                if hasattr(m, n):
                    setattr(m, n, timed(getattr(m, n), part))
    c0 = time.process_time()
    track(scenario(a.end, a.logs, True, clock=a.clock), output=tmp / "c.nc")
    cpu = time.process_time() - c0
    with netCDF4.Dataset(tmp / "c.nc") as ds:
        parts = {k: float(ds.getncattr(f"coupling_cpu_{k}_s")) for k in PARTS}
        steps = int(ds.getncattr("coupling_solver_steps"))
    print(f"coupled run, {a.logs} logs, {a.clock} clock, to {a.end:g} s: {cpu:.2f} CPU s, "
          f"{steps} solver steps")
    print(f"{'part':<32}{'CPU s':>8}{'kernels s':>11}{'rest s':>9}{'rest us/step':>14}")
    for k, label in PARTS.items():
        kern = spent.get(k, 0.0)
        print(f"{label:<32.32}{parts[k]:8.2f}{kern:11.2f}{parts[k] - kern:9.2f}"
              f"{1e6 * (parts[k] - kern) / steps:14.0f}")


if __name__ == "__main__":
    main()
