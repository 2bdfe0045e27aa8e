"""Compile time of driftlog's kernels from a cold numba cache: numba's inliner against driftlog's.

Each variant runs the chosen tests in a process of its own with an empty ``NUMBA_CACHE_DIR``
(nothing loaded from a cache) and records numba's compile events: per kernel, the CPU time
spent compiling it excluding the kernels it calls (compiled separately, counted under their
own name).  Variants: ``driftlog`` (the inliner copying a callee's scope once per IR copy,
``driftlog._numba``) and ``numba`` (numba's own inliner, one scope copy per block).  The
machine code is the same (``tests/test_numba_inline.py``); only the compiling differs.

    python benchmarks/compile_times.py                      # tests/test_fused.py, both
    python benchmarks/compile_times.py --tests tests/test_grounded.py --variants driftlog

Results: ``benchmarks/results/compile_times.{md,csv}``.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
VARIANTS = ("driftlog", "numba")


def _worker(variant, tests, out):
    """In this process: compile from an empty cache while running ``tests``; write the times."""
    import copy

    from numba.core import event
    from numba.core import inline_closurecall as icc

    import driftlog._numba  # noqa: F401  (installs the inliner's scope sharing)

    if variant == "numba":
        icc.copy = copy
        icc.InlineWorker.inline_ir = icc.InlineWorker.inline_ir.__wrapped__
    stack, rec = [], {}

    class Listener(event.Listener):
        def on_start(self, ev):
            f = getattr(ev.data.get("dispatcher"), "py_func", None)
            name = f"{getattr(f, '__module__', '?')}.{getattr(f, '__qualname__', '?')}"
            stack.append([time.process_time(), name, 0.0])

        def on_end(self, ev):
            t0, name, inner = stack.pop()
            total = time.process_time() - t0
            if stack:
                stack[-1][2] += total
            r = rec.setdefault(name, [0, 0.0])
            r[0] += 1
            r[1] += total - inner

    event.register("numba:compile", Listener())
    import pytest

    t0 = time.process_time()
    code = pytest.main(["-q", "-p", "no:cacheprovider", "-p", "no:xdist", *tests])
    Path(out).write_text(json.dumps({"exit": int(code), "cpu_s": time.process_time() - t0,
                                     "kernels": rec}))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tests", nargs="+", default=["tests/test_fused.py"],
                    help="pytest arguments (files, -k ...) run in each variant")
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=list(VARIANTS))
    ap.add_argument("--top", type=int, default=8, help="kernels listed per variant")
    ap.add_argument("--worker", nargs=2, metavar=("VARIANT", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        _worker(a.worker[0], a.tests, a.worker[1])
        return

    from _common import write_table

    rows, totals = [], {}
    for v in a.variants:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "times.json"
            env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / "numba"))
            t0 = time.perf_counter()
            subprocess.run([sys.executable, __file__, "--worker", v, str(out), "--tests",
                            *a.tests], env=env, cwd=HERE.parent, check=True)
            wall = time.perf_counter() - t0
            r = json.loads(out.read_text())
        if r["exit"] != 0:
            sys.exit(f"compile_times: the tests failed under variant {v} (exit {r['exit']})")
        ker = sorted(r["kernels"].items(), key=lambda kv: -kv[1][1])
        compile_s = sum(t for _, t in r["kernels"].values())
        totals[v] = compile_s
        rows.append({"inliner": v, "kernel": "(all, compiling)", "compile_cpu_s": compile_s,
                     "run_cpu_s": r["cpu_s"], "run_wall_s": wall})
        for name, (n, t) in ker[:a.top]:
            rows.append({"inliner": v, "kernel": name.replace("driftlog.", ""),
                         "compilations": n, "compile_cpu_s": t})
    ratio = ""
    if set(totals) == set(VARIANTS) and totals["driftlog"] > 0:
        ratio = (f"numba's own inliner / driftlog's: {totals['numba'] / totals['driftlog']:.2f}x "
                 "the compile CPU time.")
    write_table("compile_times", rows,
                ["inliner", "kernel", "compilations", "compile_cpu_s", "run_cpu_s",
                 "run_wall_s"],
                "Compile time from a cold numba cache, per inliner",
                f"Tests: `{' '.join(a.tests)}`, one process per inliner, an empty "
                "NUMBA_CACHE_DIR each; compile_cpu_s: CPU s compiling the kernel, excluding the "
                "kernels it calls.  " + ratio + "  Re-create: `python "
                "benchmarks/compile_times.py`.")


if __name__ == "__main__":
    main()
