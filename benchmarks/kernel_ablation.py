"""The solver's flux-pass kernels on their own, beside variants of themselves (issue 14 item 2).

Runs Malpasset (``driftlog.floodsetup.malpasset_solver``, serial kernels, 1 thread) to each
time of ``--at`` at orders 1 and 2, captures the arguments of one call of each kernel of the
next step, then times each kernel on them beside variants built from its module's own source
by text substitutions (written to a temporary folder and compiled there):

- ``signed``: the ``np.uint64`` casts of the indices removed, so that numba wraps every index
  that may be negative (the flux kernels' code before 2026-12-05);
- ``refcount`` (the gradient kernel only): compiled with numba's reference counting
  (``kernel(nrt=False)`` -> ``kernel``);
- ``before`` (the gradient kernel only): both (its code at b279288);
- ``products`` (the gradient kernel only): the divisions of its usual path (the limiter's
  two per quantity, the neighbours' and the edges' velocities) made products: other
  numbers, what those divisions cost.

Each round times every variant (best of 3 x ``--calls`` calls, CPU time), the variants
alternated; the table gives the median over ``--rounds`` rounds, the ratio to the kernel as it
is, and whether the variant's outputs equal the kernel's bit for bit.  It also counts the gather
instructions and packed divisions in the machine code of the gradient kernel and of a plain
indexed copy ``out[i] = h[idx[i]]`` on this host (whether LLVM vectorises them).

    python benchmarks/kernel_ablation.py --at 100 1000

writes benchmarks/results/kernel_ablation{.md,.csv}.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402
import numpy as np  # noqa: E402
from _common import write_table  # noqa: E402

SOLVER = Path(__file__).resolve().parent.parent / "driftlog" / "solver"
# kernel -> (module, the solver attribute that calls it, order)
KERNELS = {
    "edge_fluxes_1": ("fluxes", "_k_edges", 1),
    "face_residuals (order 1)": ("fluxes", "_k_faces", 1),
    "limited_gradients": ("reconstruction", "_k_grad", 2),
    "edge_fluxes_2": ("fluxes", "_k_edges", 2),
    "face_residuals (order 2)": ("fluxes", "_k_faces", 2),
}
# the divisions of limited_gradients' usual path, made products (``products``)
PRODUCTS = (
    ("    rp = (qmax + 0.0 - qc) / (dmax if dmax > 0.0 else 1.0)\n"
     "    rm = (qmin - 0.0 - qc) / (dmin if dmin < 0.0 else 1.0)",
     "    rp = (qmax + 0.0 - qc) * (dmax if dmax > 0.0 else 1.0)\n"
     "    rm = (qmin - 0.0 - qc) * (dmin if dmin < 0.0 else 1.0)"),
    ("            uj = q2 / hj\n            vj = q3 / hj",
     "            uj = q2 * hj\n            vj = q3 * hj"),
    ("            ue = qe / he\n            ve = re / he",
     "            ue = qe * he\n            ve = re * he"),
)


def _unsigned_removed(src):
    out, n = re.subn(r"np\.uint64\(([^()]*)\)", r"\1", src)
    if n == 0:
        raise SystemExit("kernel_ablation: no np.uint64 cast found to remove (source changed?)")
    return out


def _refcount(src):
    out, n = re.subn(r"^@kernel\(nrt=False\)$", "@kernel", src, flags=re.M)
    if n == 0:
        raise SystemExit("kernel_ablation: no kernel(nrt=False) found (source changed?)")
    return out


def _products(src):
    for old, new in PRODUCTS:
        if old not in src:
            raise SystemExit(f"kernel_ablation: the gradient kernel's source changed: {old!r}")
        src = src.replace(old, new)
    return src


VARIANTS = {"signed": (_unsigned_removed,), "refcount": (_refcount,),
            "before": (_unsigned_removed, _refcount), "products": (_products,)}
# the variants of each module (the flux kernels count references as before: ``signed`` is
# their code before)
MODULE_VARIANTS = {"fluxes": ("signed",),
                   "reconstruction": ("signed", "refcount", "before", "products")}


def variant_module(module, name, folder):
    """The solver's ``module`` with the substitutions of variant ``name``, imported.

    Written to ``folder`` (put on ``sys.path``) as ``ablation_<module>_<name>``; also used by
    tests/test_solver_layout.py (the unsigned casts change no number).
    """
    src = (SOLVER / f"{module}.py").read_text()
    for f in VARIANTS[name]:
        src = f(src)
    mod = f"ablation_{module}_{name}"
    (Path(folder) / f"{mod}.py").write_text(src)
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    sys.modules.pop(mod, None)
    return importlib.import_module(mod)


def capture(at):
    """{(order, attr): args} of one call of each kernel of the step after ``at`` s."""
    from malpasset import data_dir

    from driftlog.floodsetup import malpasset_solver

    cap = {}
    for order in (1, 2):
        s = malpasset_solver(data_dir() / "malpasset_mesh.nc", order=order, parallel=False)
        s.advance_to(at)
        for attr in {a for _, a, o in KERNELS.values() if o == order}:
            k = getattr(s, attr)

            def grab(*a, _k=k, _key=(order, attr)):
                if _key not in cap:
                    cap[_key] = [x.copy() if isinstance(x, np.ndarray) else x for x in a]
                return _k(*a)

            setattr(s, attr, grab)
        s.step()
    return cap


def _copy(args):
    return [x.copy() if isinstance(x, np.ndarray) else x for x in args]


def _same(a, b):
    return all(np.array_equal(x.view(np.uint8), y.view(np.uint8))
               for x, y in zip(a, b, strict=True) if isinstance(x, np.ndarray))


def time_kernels(fns, args, rounds, calls):
    """Median over ``rounds`` of each function's best-of-3 ms per call, alternated."""
    work = {k: _copy(args) for k in fns}
    for k, f in fns.items():
        f(*work[k])  # compiles / loads
    per = {k: [] for k in fns}
    for _ in range(rounds):
        for k, f in fns.items():
            best = np.inf
            for _ in range(3):
                c0 = time.process_time()
                for _ in range(calls):
                    f(*work[k])
                best = min(best, (time.process_time() - c0) / calls)
            per[k].append(best * 1e3)
    return {k: float(np.median(v)) for k, v in per.items()}


def _vector_ops(fn, args):
    """(gathers, packed divisions) in the machine code numba compiles for fn(*args) here."""
    jit = numba.njit(fn)  # not cached: numba shows the assembly of fresh compilations only
    jit(*args)
    asm = next(iter(jit.inspect_asm().values()))
    # instructions only (a symbol's name may hold the word): vgatherqpd, vpgatherdd...
    return (len(re.findall(r"^\s*vp?gather", asm, re.M)),
            len(re.findall(r"^\s*vdivpd", asm, re.M)))


def _indexed_copy(idx, h, out):
    for i in range(idx.shape[0]):
        out[i] = h[np.uint64(idx[i])]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--at", type=float, nargs="+", default=[100.0, 1000.0],
                    help="flood times (s) whose state the kernels run on")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--calls", type=int, default=100)
    a = ap.parse_args(argv)
    numba.set_num_threads(1)
    folder = Path(tempfile.mkdtemp(prefix="driftlog-ablation-"))
    import driftlog.solver.fluxes as fluxes
    import driftlog.solver.reconstruction as reconstruction

    here = {"fluxes": fluxes, "reconstruction": reconstruction}
    mods = {(m, v): variant_module(m, v, folder) for m in here for v in MODULE_VARIANTS[m]}
    rows, caps = [], {}
    for at in a.at:
        cap = caps[at] = capture(at)
        for label, (m, attr, order) in KERNELS.items():
            fn = label.split(" ")[0]
            args = cap[(order, attr)]
            fns = {"as is": getattr(here[m], fn).serial}
            fns.update({v: getattr(mods[(m, v)], fn).serial for (mm, v) in mods if mm == m})
            ms = time_kernels(fns, args, a.rounds, a.calls)
            ref = _copy(args)
            fns["as is"](*ref)
            for v, f in fns.items():
                out = _copy(args)
                f(*out)
                rows.append(dict(at_s=at, order=order, kernel=fn, items=args[0].shape[0],
                                 variant=v, ms_per_call=ms[v], ratio=ms[v] / ms["as is"],
                                 bit_for_bit=_same(ref, out), load=os.getloadavg()[0]))
                print(rows[-1], flush=True)
    g_plain = _vector_ops(_indexed_copy, (np.arange(64), np.ones(64), np.zeros(64)))[0]
    g_grad, d_grad = _vector_ops(reconstruction.limited_gradients.serial.py_func,
                                 _copy(caps[a.at[0]][(2, "_k_grad")]))
    write_table("kernel_ablation", rows,
                ["at_s", "order", "kernel", "items", "variant", "ms_per_call", "ratio",
                 "bit_for_bit", "load"],
                "The solver's kernels beside variants of themselves (1 thread, serial)",
                "Arguments captured from Malpasset (serial kernels) at at_s seconds; items: the "
                "active faces or edges of the call.  ms_per_call: median over "
                f"{a.rounds} rounds of the best of 3 x {a.calls} calls (CPU time), the "
                "variants alternated; ratio: to the kernel as it is.  signed: the np.uint64 "
                "index casts removed (the flux kernels' code at b279288); refcount: with "
                "numba's reference counting; before: both (the gradient kernel's code at "
                "b279288); products: the gradient kernel's usual divisions made "
                f"products (other numbers).  Machine code on this host: the loop out[i] = "
                f"h[idx[i]] has {g_plain} gather instructions, the gradient kernel "
                f"{g_grad} gathers and {d_grad} packed divisions.  Re-create: "
                "`python benchmarks/kernel_ablation.py --at "
                + " ".join(f"{t:g}" for t in a.at) + "`.")


if __name__ == "__main__":
    main()
