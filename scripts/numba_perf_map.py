r"""Run a Python script so that Linux ``perf`` names the numba kernels in its profile.

``perf`` sees compiled numba code as anonymous addresses.  It names them from
``/tmp/perf-PID.map`` ("START SIZE NAME" per line), which this script writes when the run
ends, from every function that numba compiled in the process.  Only a function compiled in the
process has a module to list (one loaded from numba's on-disk cache has none), so the run uses
an empty cache of its own (``NUMBA_CACHE_DIR``, a temporary folder unless given), and its first
calls compile: profile a run long enough that compiling is a small share, or read the kernels'
own lines only.

    perf record -F 500 -o /tmp/perf.data -- \
        python scripts/numba_perf_map.py benchmarks/million_logs.py --flow F --logs 10000 --end 900
    perf report -i /tmp/perf.data --stdio --sort symbol | head -40

Each function's size is the distance to the next one's start (numba does not give sizes), so
a sample in memory after the last function of a library may be named after it.  Found with this
on 2026-12-06: reference counting (``NRT_incref`` / ``NRT_decref``) took a quarter of the
Moreau-Jean island kernel's samples (BENCHMARKS.md, "Islands of speculative contacts").
"""

from __future__ import annotations

import atexit
import os
import runpy
import sys
import tempfile


def compiled_functions():
    """(address, symbol) of every function numba compiled in this process, by address."""
    import gc

    from numba.core.registry import CPUDispatcher

    found = {}
    for obj in gc.get_objects():
        # type(), not isinstance(): gc also lists weak proxies, and isinstance() on a proxy
        # whose object is gone raises ReferenceError
        if not issubclass(type(obj), CPUDispatcher):
            continue
        for cres in list(obj.overloads.values()):
            lib = cres.library
            try:
                module = lib._final_module  # absent where the code came from the disk cache
            except AttributeError:
                continue
            for fn in module.functions:
                if fn.is_declaration:
                    continue
                try:
                    address = lib.get_pointer_to_function(fn.name)
                except Exception:  # noqa: BLE001 - a function LLVM did not emit
                    continue
                if address:
                    found[address] = fn.name
    return sorted(found.items())


def write_perf_map(path=None):
    """Write the perf map of this process's compiled numba functions; returns its path."""
    path = path or f"/tmp/perf-{os.getpid()}.map"
    funcs = compiled_functions()
    with open(path, "w") as fh:
        for k, (start, name) in enumerate(funcs):
            end = funcs[k + 1][0] if k + 1 < len(funcs) else start + 4096
            fh.write(f"{start:x} {min(end - start, 1 << 20):x} {name}\n")
    return path


def main(argv=None):
    """Run ``argv[0]`` as ``__main__`` with ``argv`` as its arguments; the map at exit."""
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    script = argv[0]
    if not os.path.isfile(script):
        print(f"numba_perf_map: no script {script!r} to run", file=sys.stderr)
        return 2
    if "numba" in sys.modules:  # the cache folder is read when numba is imported
        print("numba_perf_map: numba is already imported; run this script directly",
              file=sys.stderr)
        return 2
    os.environ.setdefault("NUMBA_CACHE_DIR", tempfile.mkdtemp(prefix="numba_perf_"))
    atexit.register(lambda: print(f"numba_perf_map: wrote {write_perf_map()}",
                                  file=sys.stderr))
    sys.argv = list(argv)
    sys.path.insert(0, os.path.dirname(os.path.abspath(script)))
    runpy.run_path(script, run_name="__main__")
    return 0


if __name__ == "__main__":
    sys.exit(main())
