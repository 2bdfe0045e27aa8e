"""numba's inliner with one scope copy per IR copy (``driftlog._numba._InlineCopy``).

The change only makes inlining cheaper: the machine code must stay the same.
"""

import copy
import re

import numba as nb
from numba.core import inline_closurecall as icc
from numba.core.compiler import run_frontend

from driftlog import _numba


@nb.njit(inline="always")
def _branchy(x, n):
    # several blocks and many variables: each block copy used to copy them all
    y = 0.0
    for k in range(n):
        if x > k:
            y += x * k
        elif x < -k:
            y -= x / (k + 1.0)
        else:
            y = y * 0.5 + k
    return y


@nb.njit(inline="always")
def _twice(x, n):
    return _branchy(x, n) + _branchy(-x, n + 1)


def _caller(x, n):
    return _twice(x, n) - _twice(0.5 * x, n)


def _asm(dispatcher):
    (asm,) = dispatcher.inspect_asm().values()
    asm = re.sub(r"\.L\w+", "L", asm)  # local labels
    return re.sub(r"_ZN\S+|\b\w*_caller\w*", "SYM", asm)  # the dispatcher's own names


def test_installed_and_same_machine_code():
    assert isinstance(icc.copy, _numba._InlineCopy)
    shared = nb.njit(_caller)
    b = _branchy.py_func
    for x, n in ((2.5, 7), (-1.25, 4)):
        ref = (b(x, n) + b(-x, n + 1)) - (b(0.5 * x, n) + b(-0.5 * x, n + 1))
        assert shared(x, n) == ref
    worker = icc.InlineWorker
    patched = worker.inline_ir
    try:  # numba's own inliner
        icc.copy = copy
        worker.inline_ir = patched.__wrapped__
        plain = nb.njit(_caller)
        plain(2.5, 7)
    finally:
        icc.copy = _numba._InlineCopy.installed
        worker.inline_ir = patched
    assert shared(2.5, 7) == plain(2.5, 7)
    assert shared(-1.25, 4) == plain(-1.25, 4)
    assert _asm(shared) == _asm(plain)


def test_one_scope_copy_per_ir_copy():
    fir = run_frontend(_branchy.py_func)
    blocks = list(fir.blocks.values())
    assert len(blocks) > 3
    shim = _numba._InlineCopy.installed

    def copy_blocks(worker, the_ir):
        return [shim.deepcopy(b) for b in the_ir.blocks.values()]

    inside = shim.inline_ir(copy_blocks)(None, fir)
    scopes = {id(b.scope) for b in inside}
    assert len(scopes) == 1  # one copy, shared by the blocks' copies, as in the original
    assert inside[0].scope is not blocks[0].scope  # a copy: the inliner mutates it
    assert inside[0].scope == blocks[0].scope
    again = shim.inline_ir(copy_blocks)(None, fir)  # another call site: a fresh copy
    assert again[0].scope is not inside[0].scope
    # outside the inliner, copy's own behaviour: a scope copy per block
    outside = copy_blocks(None, fir)
    assert len({id(b.scope) for b in outside}) == len(blocks)


@nb.njit(inline="always")
def _active(f, h, nbr):
    # branches on array reads: the inlined call kept a count update of each array argument
    on = h[f] > 0.0
    if not on:
        for k in range(nbr.shape[1]):
            j = nbr[f, k]
            if j >= 0 and h[j] > 0.0:
                on = True
                break
    return on


def _count_active(h, nbr, out):
    n = 0
    for f in range(h.shape[0]):
        if _active(f, h, nbr):
            out[n] = f
            n += 1
    return n


def test_kernels_without_reference_counting():
    """``kernel(nrt=False)``: the same results, and the tracker's kernels compiled so."""
    import numpy as np

    rng = np.random.default_rng(0)
    h = np.where(rng.random(500) < 0.3, 1.0, 0.0)
    nbr = rng.integers(-1, 500, (500, 3))
    counted = nb.njit(_count_active)  # numba's default, reference counts kept
    k = _numba.kernel(nrt=False)(_count_active)
    out0, out1 = np.empty(500, np.int64), np.empty(500, np.int64)
    n0, n1 = counted(h, nbr, out0), k.serial(h, nbr, out1)
    wet = (h > 0) | ((nbr >= 0) & (h[np.maximum(nbr, 0)] > 0)).any(axis=1)
    assert np.array_equal(out0[:n0], np.flatnonzero(wet))
    assert np.array_equal(out1[:n1], out0[:n0])
    # the tracker's per-log kernels are compiled so
    from driftlog import clock_kernel, flow, fused, physics

    for kern in (k, fused.rk4_tracer_step, fused.euler_tracer_step, fused.rk4_mesh_step,
                 fused.euler_mesh_step, clock_kernel.per_log_mesh_advance,
                 flow.sample_mesh_kernel, physics.rhs_kernel):
        for d in (kern.serial, kern.parallel):
            assert d.targetoptions.get("_nrt") is False, d
