"""``np.dot`` of two long float64 vectors, the BLAS's own sum, without waking its threads.

OpenBLAS splits a dot product of more than 10,000 entries between its threads (each sums a
contiguous part, then the parts are added in order).  Called once in a while, as the solver's
volume is at each flow-file snapshot, the call wakes the sleeping threads: on the shared
2-core machine that cost 4-7 ms of CPU per call (measured), for 0.01 ms of arithmetic.  ``dot``
computes the same parts on the calling thread (the BLAS limited to one thread) and adds them
in the same order, so the result is ``np.dot``'s bit for bit; the split is checked once per
(length, threads) against ``np.dot`` on random vectors, and where it does not match (another
BLAS, another OpenBLAS split) ``dot`` is ``np.dot``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["dot"]

SPLIT_MIN = 10_000  # OpenBLAS's x86_64 ddot: one thread up to this length

_state = {}  # "blas": the OpenBLAS controller or None; (n, threads) -> split checked


def _blas():
    """The OpenBLAS library controller that numpy uses, or None (then plain np.dot)."""
    if "blas" not in _state:
        lib = None
        try:
            from threadpoolctl import ThreadpoolController

            ctl = ThreadpoolController()
            libs = ctl.select(user_api="blas").lib_controllers
            if len(libs) > 1:  # scipy's own OpenBLAS beside numpy's: numpy's (numpy.libs)
                home = Path(np.__file__).resolve().parent
                libs = [c for c in libs if Path(c.filepath).resolve().parent
                        in (home.parent / "numpy.libs", home / ".libs", home)]
            if len(libs) == 1 and libs[0].internal_api == "openblas":
                lib = (ctl, libs[0])
        except Exception:  # noqa: BLE001 - no controller: np.dot, as before
            lib = None
        _state["blas"] = lib
    return _state["blas"]


def _split_dot(ctl, a, b, threads):
    """The parts of a ``threads``-way OpenBLAS dot, each on one thread, added in order."""
    n = a.shape[0]
    out = 0.0
    start = 0
    with ctl.limit(limits=1, user_api="blas"):  # numpy's and any other OpenBLAS
        for k in range(threads):
            left = n - start
            width = min(-(-left // (threads - k)), left)
            out = out + float(np.dot(a[start:start + width], b[start:start + width]))
            start += width
    return out


def _checked(ctl, n, threads):
    key = (n, threads)
    if key not in _state:
        rng = np.random.default_rng(n)
        a, b = rng.standard_normal(n), rng.standard_normal(n)
        _state[key] = all(float(np.dot(x, y)) == _split_dot(ctl, x, y, threads)
                          for x, y in ((a, b), (a * 1e3, b), (np.abs(a), b)))
    return _state[key]


def dot(a, b) -> float:
    """``float(np.dot(a, b))`` of two contiguous float64 vectors, bit for bit.

    Parameters
    ----------
    a, b : (n,) float64 arrays

    Returns
    -------
    float
    """
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    n = a.shape[0]
    blas = _blas() if (a.ndim == 1 and b.shape == a.shape and n > SPLIT_MIN) else None
    if blas is None:
        return float(np.dot(a, b))
    ctl, lib = blas
    threads = int(lib.num_threads)
    if threads <= 1 or not _checked(ctl, n, threads):
        return float(np.dot(a, b))
    return _split_dot(ctl, a, b, threads)
