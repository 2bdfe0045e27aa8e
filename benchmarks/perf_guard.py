"""Before merging a kernel change: each hot kernel's time against its committed figure.

A change that keeps every result bit for bit (``scripts/bitwise_check.py``) can still make a
kernel several times slower: an inlined helper with array arguments made the solver's active
set 6x slower on 2026-12-03 and nobody timed it again (BENCHMARKS.md, the solver section).
This reruns two committed measurements on this machine and prints each kernel's time beside
the committed one:

- the solver's kernels on Malpasset's first 200 s (``solver_throughput.py
  --breakdown-malpasset 200``, committed in ``results/solver_breakdown_malpasset.csv``);
- the fused tracking steps, 1e5 logs on the Malpasset vortex (``tracking_benchmark.py
  --targets``, committed in ``results/tracking_targets_nrt.csv``).

The machine's speed moves by up to 40 % within an hour (a shared host), so a kernel is
flagged only when it takes more than ``--factor`` (default 2) times its committed time (run it
with nothing else running: a second process on the 2 cores doubled the short tracer steps);
the exit status is 1 when one is.  Nothing is written under ``results/``.

    python benchmarks/perf_guard.py [--factor 2] [--skip-tracker]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numba

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine  # noqa: E402


def _committed(name, key):
    with open(RESULTS / f"{name}.csv", newline="") as f:
        return {key(r): r for r in csv.DictReader(f)}


def solver_rows():
    """(what, committed ms per step, now) for every solver kernel above 0.05 ms per step."""
    from solver_throughput import malpasset_breakdown

    ref = _committed("solver_breakdown_malpasset", lambda r: (int(r["order"]), r["kernel"]))
    end = float(ref[(1, "total")]["end_s"])  # order 2 runs half of it
    now = {(r["order"], r["kernel"]): r["ms_per_step"] for r in malpasset_breakdown(end, 1)}
    return [(f"solver order {o}: {k} (ms per step)", float(r["ms_per_step"]), now[(o, k)])
            for (o, k), r in ref.items() if float(r["ms_per_step"]) > 0.05 and (o, k) in now]


def tracker_rows():
    """(what, committed ns per log-step, now) for the fused RK4 and Euler steps."""
    import numpy as np
    from _common import malpasset_mesh
    from sampling_benchmark import points
    from tracking_benchmark import one, vortex_flow

    ref = _committed("tracking_targets_nrt", lambda r: (r["level"], r["integrator"]))
    mesh = malpasset_mesh()
    flow = vortex_flow(mesh)
    n = int(next(iter(ref.values()))["logs"])
    x, y = points(mesh, n, np.random.default_rng(3))
    numba.set_num_threads(1)
    rows = []
    for (level, method), r in ref.items():
        if r["path"] != "fused":
            continue
        one(flow, x[:2049], y[:2049], level, method, 2)  # compile / load the cache
        best = min(one(flow, x, y, level, method, int(r["substeps"]))[2] for _ in range(3))
        rows.append((f"tracker {level} {method} (ns per log-step)", float(r["ns_per_step"]),
                     best / (n * int(r["substeps"])) * 1e9))
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--factor", type=float, default=2.0,
                   help="flag a kernel slower than this many times its committed time")
    p.add_argument("--skip-tracker", action="store_true", help="the solver's kernels only")
    a = p.parse_args(argv)
    if a.factor <= 1.0:
        p.error(f"--factor {a.factor}: must be above 1")
    numba.set_num_threads(1)
    rows = solver_rows() + ([] if a.skip_tracker else tracker_rows())
    print(f"{machine()}; 1 thread; flagged: more than {a.factor:g}x the committed time\n")
    print(f"| {'kernel':<58} | committed | now | ratio |")
    print(f"|{'-' * 60}|---:|---:|---:|")
    slow = []
    for what, ref, now in rows:
        ratio = now / ref
        flag = " SLOWER" if ratio > a.factor else ""
        print(f"| {what:<58} | {ref:.3g} | {now:.3g} | {ratio:.2f}{flag} |")
        if flag:
            slow.append(what)
    if slow:
        print(f"\n{len(slow)} kernel(s) above {a.factor:g}x: {', '.join(slow)}")
        return 1
    print("\nno kernel above the factor")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
