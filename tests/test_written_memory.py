"""Work arrays that kernels store to conditionally live on written memory, not zero pages.

A large ``np.zeros`` maps pages that all share the kernel's read-only zero page until first
written; AVX-512 masked stores onto them cost a microcode assist even with an empty mask, so
a mostly dry mesh made the extremes' kernel 70x slower (BENCHMARKS.md, "Untouched zero
pages").  Linux's /proc/self/pagemap tells, page by page, whether a page is mapped by this
process alone (bit 56, readable without privileges): a written private page is; the shared
zero page is not.
"""

from __future__ import annotations

import mmap
import os
import struct

import numpy as np
import pytest

from driftlog._numba import written_zeros
from driftlog.mesher import channel_mesh
from driftlog.solver.model import ShallowWaterSolver

PAGEMAP = "/proc/self/pagemap"
pytestmark = pytest.mark.skipif(not os.access(PAGEMAP, os.R_OK), reason="no /proc/self/pagemap")


def exclusive_pages(a) -> np.ndarray:
    """For each whole page of array a: mapped by this process alone (a written private page)."""
    size = mmap.PAGESIZE
    start = -(-a.ctypes.data // size) * size
    end = (a.ctypes.data + a.nbytes) // size * size
    n = max((end - start) // size, 0)
    with open(PAGEMAP, "rb") as f:
        f.seek(start // size * 8)
        entries = struct.unpack(f"{n}Q", f.read(8 * n))
    return np.array([(e >> 63) & 1 and (e >> 56) & 1 for e in entries], dtype=bool)


def test_the_check_tells_the_zero_page_from_written_memory():
    untouched = np.frombuffer(  # what malloc maps for a large np.zeros
        mmap.mmap(-1, 1 << 20, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS), dtype=np.float64)
    assert float(untouched.sum()) == 0.0  # read: every page maps the zero page now
    assert not exclusive_pages(untouched).any()
    untouched[::512] = 0.0  # one store per page
    assert exclusive_pages(untouched).all()


def test_written_zeros_are_zeros_on_written_pages():
    a = written_zeros((300_000, 2), dtype=np.int64)
    assert a.shape == (300_000, 2) and a.dtype == np.int64 and not a.any()
    assert exclusive_pages(a).all()


def untouched_zeros(shape, dtype=float, order="C"):
    """np.zeros at its worst: fresh private pages, never written (what malloc maps when it
    takes new memory from the kernel; whether it does depends on the process's history)."""
    dtype = np.dtype(dtype)
    nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    if nbytes < mmap.PAGESIZE:
        return np.full(shape, 0, dtype=dtype)
    buf = mmap.mmap(-1, nbytes, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    return np.frombuffer(buf, dtype=dtype).reshape(shape, order=order)


@pytest.mark.parametrize("order", [1, 2])
def test_solver_extremes_and_work_arrays_are_written(order, monkeypatch):
    # whatever np.zeros hands out, the arrays kernels store to conditionally are written
    monkeypatch.setattr(np, "zeros", untouched_zeros)
    mesh = channel_mesh(400.0, 100.0, 1.0)  # ~1e5 faces: arrays of ~0.8 MB
    s = ShallowWaterSolver(mesh, order=order)
    s.set_state(np.where(mesh.face_x < 10.0, 1.0, 0.0))  # mostly dry, as a dam-break valley
    e = s.extremes
    arrays = [e.max_depth, e.max_speed, s._h, s._hu, s._hv, *s._res, *s._flux, *s._save]
    assert all(exclusive_pages(a).all() for a in arrays)
