"""Kernels compiled twice: serial for small arrays, parallel (prange) for large ones.

Starting numba's thread pool costs tens to hundreds of microseconds per call, more than the
work itself for a few logs (one log in a vortex, a handful at a bridge); above
``PARALLEL_MIN`` items the parallel version wins.  Call through the returned wrapper with the
array whose length decides as first argument.
"""

import functools
import os
import types

# numba's OpenMP layer (GNU libgomp) spins its idle workers by default; on a machine whose
# cores are shared with other jobs the spinning threads take the cores the working thread
# needs (measured: 2 threads 10-20x slower than 1 on 1e3 logs, benchmarks/peers_tracking.py).
# Passive waiting costs 50-100 us per parallel region on a virtual machine (a sleeping worker
# is woken; BENCHMARKS.md, "Two threads on the real flood").  Set before libgomp loads; a
# value the user gave wins (GOMP_SPINCOUNT too, which libgomp lets override the policy).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def workers_spin(environ=os.environ):
    """Whether libgomp's idle workers spin before they sleep, as the user asked.

    ``GOMP_SPINCOUNT`` above 0 or ``OMP_WAIT_POLICY=ACTIVE``: waking them between parallel
    regions then costs little.  False under driftlog's default, passive waiting.
    """
    count = environ.get("GOMP_SPINCOUNT", "").strip().lower()
    if count:
        return count == "infinite" or (count.isdigit() and int(count) > 0)
    return environ.get("OMP_WAIT_POLICY", "").strip().upper() == "ACTIVE"

import copy  # noqa: E402
import threading  # noqa: E402

import numba as nb  # noqa: E402

__all__ = ["kernel", "PARALLEL_MIN", "announce_compile", "kernels_cached", "workers_spin",
           "written_zeros"]


def written_zeros(shape, dtype=float):
    """An array of zeros whose memory is written, not ``np.zeros``' untouched pages.

    ``np.zeros`` of more than a few hundred kB gets fresh pages from the kernel that all map
    the one shared, read-only zero page until first written.  LLVM vectorises a kernel's
    conditional stores (``if level > max_level[f]: max_level[f] = level``) into AVX-512
    masked stores, and a masked store onto a read-only page costs a microcode assist even
    where its mask is all zero: a dry face, never written, stays on the zero page and costs
    so at every call.  Measured on this machine (AMD EPYC, Malpasset's 46,691 faces, the
    extremes' kernel): 3.5 ms a call against 0.048 ms on written memory, and a first-order
    Malpasset solve 5.3x slower (the whole flood 2.8x) on such pages (BENCHMARKS.md,
    "Untouched zero pages"; ``benchmarks/solver_throughput.py --zero-pages``).  Arrays that
    kernels store to conditionally are allocated here.
    """
    import numpy as np

    return np.full(shape, 0, dtype=dtype)


class _InlineCopy:
    """numba's inliner's ``copy`` module, with one copy of the callee's scope per IR copy.

    numba inlines an ``inline="always"`` function by deep-copying the callee's IR one block at
    a time (``InlineWorker.inline_ir``, twice per call site).  Every variable holds the
    function's scope, and the scope holds every variable: each block's copy copies the whole
    scope again, so one call site costs (blocks x variables) copies, and the kernels that
    inline a whole RK4 step with its sampling and forces spent half their compile time there
    (cProfile: 59 of 123 s compiling ``fused.euler_mesh_step``).  Inside ``inline_ir`` this
    copies each scope once and lets the blocks' copies share it, as the blocks of the
    original share theirs (numba asserts one scope per inlined function).  The IR it makes is
    the same; only the copying is cheaper.  Anything else is ``copy``'s own.
    """

    installed = None  # the instance in numba's inliner

    def __init__(self):
        self._local = threading.local()

    def __getattr__(self, name):
        return getattr(copy, name)

    def deepcopy(self, x, memo=None):
        scopes = getattr(self._local, "scopes", None)
        if scopes is None or memo is not None or not hasattr(x, "scope"):
            return copy.deepcopy(x, memo)
        key = id(x.scope)
        memo = {}
        if key in scopes:
            memo[key] = scopes[key][1]
        out = copy.deepcopy(x, memo)
        if key not in scopes and key in memo:
            scopes[key] = (x.scope, memo[key])  # the original kept alive: its id stays unique
        return out

    def inline_ir(self, original):
        """``InlineWorker.inline_ir`` with scopes shared within it."""

        def inline_ir(worker, *args, **kwargs):
            outer = getattr(self._local, "scopes", None)
            self._local.scopes = {}
            try:
                return original(worker, *args, **kwargs)
            finally:
                self._local.scopes = outer

        inline_ir.__wrapped__ = original
        return inline_ir


def _share_inlined_scopes():
    """Install ``_InlineCopy`` in numba's inliner (once; left alone if numba's layout differs)."""
    try:
        from numba.core import inline_closurecall as icc

        worker = icc.InlineWorker
        if isinstance(icc.copy, _InlineCopy) or icc.copy is not copy:
            return
        if not hasattr(worker, "inline_ir"):
            return
    except (ImportError, AttributeError):
        return
    shim = _InlineCopy.installed = _InlineCopy()
    icc.copy = shim
    worker.inline_ir = shim.inline_ir(worker.inline_ir)


_share_inlined_scopes()

PARALLEL_MIN = 2048


def _renamed(f, suffix):
    g = types.FunctionType(f.__code__, f.__globals__, f.__name__ + suffix, f.__defaults__,
                           f.__closure__)
    g.__qualname__ = f.__qualname__ + suffix
    g.__module__ = f.__module__
    return g


def kernel(func=None, *, size_arg=0, nrt=True):
    """Decorator: ``f(*args)`` runs the serial or the parallel compilation of ``func``.

    ``nrt=False`` compiles both without numba's reference counting (``_nrt=False``): for a
    kernel that allocates nothing and has no parallel reduction (numba then refuses to
    compile it) but inlines helpers taking arrays.  numba's inliner gives an inlined
    callee's array arguments new variables, and where the callee branches the optimised
    code keeps an atomic increment and decrement of each array's count at every call (seen
    in the LLVM of ``fused.rk4_tracer_step``: 71 increments, 9 per flow sample in its loop;
    more than half of that kernel's time, BENCHMARKS.md).  The arithmetic, and so the
    results, are the same bit for bit.
    """

    def wrap(f):
        serial = nb.njit(cache=True, _nrt=nrt)(f)
        # numba's cache index does not tell parallel from serial compilations of one function:
        # under one name, whichever was cached last is loaded for both (the "serial" kernel then
        # wakes the thread pool on every call).  The parallel copy gets its own name.
        parallel = nb.njit(cache=True, parallel=True, _nrt=nrt)(_renamed(f, "_parallel"))

        @functools.wraps(f)
        def call(*args):
            if args[size_arg].shape[0] >= PARALLEL_MIN:
                return parallel(*args)
            return serial(*args)

        call.serial, call.parallel = serial, parallel
        return call

    return wrap(func) if func is not None else wrap


# first-run compile times of each family of kernels (CPU s on the 2-core reference machine;
# measured: river_piers with an empty NUMBA_CACHE_DIR and a stored flow, tracking and contacts
# compiled, 45 CPU s for the whole run against about 10 s warm; numba writes the kernels to
# __pycache__ and loads them on the next runs)
COMPILE_SECONDS = {"tracking": 20, "solver": 20, "contacts": 15}
# the tracker's multi-threaded kernels (from PARALLEL_MIN floating logs on: the fused steps of
# the global clock, the per-log kernels) take far longer (measured: a 1e4-log Malpasset run on
# per-log clocks with Moreau contacts, 900 s of flood, 1 thread: 309 CPU s from an empty cache
# against 62 cached, so about 4 CPU minutes compiling; 1033 CPU s before the inliner's scope
# sharing above, BENCHMARKS.md "Compile time"); any of them cached counts
_PROBES = {"tracking": ("", ("physics.rhs_kernel",)),
           "solver": ("solver", ("fluxes.edge_fluxes_1",)),
           "contacts": ("contact", ("geometry.capsule_gap",)),
           "parallel": ("", ("fused.*_parallel", "clock_kernel.*_parallel"))}
PARALLEL_COMPILE = "the multi-threaded ones (over 2,048 logs) up to about 4 min"


def kernels_cached(part: str) -> bool:
    """Whether numba's cache holds the kernels of ``part``.

    'tracking', 'solver', 'contacts', or 'parallel' (the tracker's multi-threaded kernels).
    """
    from pathlib import Path

    sub, probes = _PROBES[part]
    here = Path(__file__).resolve().parent
    src = here / sub if sub else here
    env = os.environ.get("NUMBA_CACHE_DIR")
    pattern = "{}-*.nbi"
    if env:
        # numba's folder for this source folder, named from its absolute path (numba's own
        # rule): another checkout of the same sources shares NUMBA_CACHE_DIR (driftlog keys
        # it on the sources' hash, ``_cache``) but not its kernels, so its index files do not
        # count.  A numba whose private locator moved: any folder under it, as before
        try:
            from numba.core.caching import _CacheLocator

            d = Path(env) / _CacheLocator.get_suitable_cache_subpath(str(src / "x.py"))
        except (ImportError, AttributeError):
            d, pattern = Path(env), "**/{}-*.nbi"
    else:
        d = src / "__pycache__"
    # an index there means compiled
    if not d.is_dir():
        return False
    return any(any(d.glob(pattern.format(p))) for p in probes)


def announce_compile(parts, stream=None, many=False) -> int:
    """Print "compiling kernels, once, about N s" when ``parts`` are not in numba's cache yet.

    The first run after an install compiles them, and a progress bar standing at 0 for that
    long is explained.  ``many``: the run has at least ``PARALLEL_MIN`` logs, so it may also
    compile the tracker's multi-threaded kernels, said when none is cached.  Returns N (0:
    all of ``parts`` cached).
    """
    import sys

    missing = [p for p in parts if not kernels_cached(p)]
    n = sum(COMPILE_SECONDS[p] for p in missing)
    said = [f"about {n} s ({', '.join(missing)})"] if missing else []
    if many and not kernels_cached("parallel"):
        said.append(PARALLEL_COMPILE)
    if said:
        print(f"driftlog: compiling kernels, once, {'; '.join(said)}; cached for the next runs",
              file=stream or sys.stderr, flush=True)
    return n
