"""Moreau-Jean island kernel calls captured from a crowd run, replayed and timed alone.

The island kernel (``moreau_kernel.moreau_islands``) is most of a packed crowd's time but is
called thousands of times per run, between passes of the contact windows; a change to it is
measured here on the calls themselves.  ``--capture`` runs million_logs.py's scene (the
Malpasset flood, N logs over the valley floor, Moreau-Jean contacts, per-log clocks, 1 thread)
and keeps every ``--every``-th call's arguments (copied before the call, which changes them in
place) in a pickle; ``--replay`` runs each kept call ``--repeat`` times on fresh copies and
prints and writes (benchmarks/results/<name>.{md,json}) the best CPU time of each call and of
all, the island statistics the kernel adds up (steps, log sub-steps, Gauss-Seidel sweeps, most
contacts in one solve, the largest island) and a digest of the states and statistics it leaves
(the same digest: the same numbers).  To compare two versions, replay one capture in a
checkout of each (a second worktree, ``PYTHONPATH`` set to it), alternately:

    python benchmarks/island_replay.py --capture /tmp/calls.pkl --flow F --logs 10000 \\
        --density 100000 --end 900 --every 40        # about 0.9 GB at every 40th call
    python benchmarks/island_replay.py --replay /tmp/calls.pkl --name island_replay

``--replay FILE --parallel`` (with ``NUMBA_NUM_THREADS=2`` or more) runs each call by the
serial and by the parallel kernel instead, checks that they leave the same states, and tables
their wall times.  The capture's own run prints the kernel's share of it.  The arguments'
signature is the kernel's: a capture replays only on code whose ``moreau_islands`` takes the
same arguments.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pickle
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine  # noqa: E402


def _copy(args):
    return tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args)


def _load(path, solver=None):
    """The kept calls of a capture; statistics arrays of older captures grown to NSTAT.

    solver: "pgs" or "nncg" replaces the captured contact solver (older captures: the PGS).
    """
    import inspect

    from driftlog import moreau_kernel as mk
    from driftlog.contact.moreau import PGS, SOLVERS

    with open(path, "rb") as fh:
        kept = pickle.load(fh)["calls"]
    names = list(inspect.signature(mk.moreau_islands.py_func).parameters)
    k = names.index("stats")
    s = names.index("solver")
    for n, (i, cpu, args) in enumerate(kept):
        if len(args) == len(names) - 1:  # captured before [contact] solver: the PGS
            args = args[:s] + (PGS,) + args[s:]
            kept[n] = (i, cpu, args)
        if len(args) == len(names) and args[k].size < mk.NSTAT:  # captured before ST_CAPPED
            st = np.zeros(mk.NSTAT, np.int64)
            st[:args[k].size] = args[k]
            kept[n] = (i, cpu, args[:k] + (st,) + args[k + 1:])
        if solver is not None:
            args = kept[n][2]
            kept[n] = (i, cpu, args[:s] + (SOLVERS.index(solver),) + args[s + 1:])
    return kept


def capture(a):
    """Run the scene, keeping every a.every-th island kernel call's arguments."""
    import million_logs as ml

    from driftlog import moreau_kernel as mk
    from driftlog.api import as_scenario, track

    kernel = mk.moreau_islands
    cpu = []
    kept = []

    def counted(*args):
        before = _copy(args) if (len(cpu) + 1) % a.every == 0 else None
        c = time.process_time()
        out = kernel(*args)
        cpu.append(time.process_time() - c)
        if before is not None:
            kept.append((len(cpu) - 1, cpu[-1], before))
        return out

    scen = as_scenario(ml.CASE, ml.overrides(a.flow, a.logs, a.end, 60.0, "moreau", 10,
                                             "per_log", a.density))
    mk.moreau_islands = counted
    try:
        c = time.process_time()
        track(scen, output=str(a.capture) + ".track.nc")
    finally:
        mk.moreau_islands = kernel
        Path(str(a.capture) + ".track.nc").unlink(missing_ok=True)
    total = time.process_time() - c
    with open(a.capture, "wb") as fh:
        pickle.dump({"every": a.every, "calls": kept}, fh, protocol=pickle.HIGHEST_PROTOCOL)
    print(f"run {total:.1f} CPU s, island kernel {sum(cpu):.1f} CPU s in {len(cpu)} calls; "
          f"kept {len(kept)} (every {a.every}-th, {sum(k[1] for k in kept):.2f} CPU s in the "
          f"run) in {a.capture} ({os.path.getsize(a.capture) / 1e6:.0f} MB)")


def replay(a):
    """Time the kept calls; print and write their table."""
    import inspect

    from driftlog import moreau_kernel as mk

    names = list(inspect.signature(mk.moreau_islands.py_func).parameters)
    kept = _load(a.replay, a.solver)
    if not kept:
        sys.exit(f"island_replay: {a.replay} holds no calls")
    if len(kept[0][2]) != len(names):
        sys.exit(f"island_replay: {a.replay} holds calls of {len(kept[0][2])} arguments; "
                 f"this code's moreau_islands takes {len(names)}")
    mk.moreau_islands(*_copy(kept[0][2]))  # compiled or loaded before timing
    digest = hashlib.sha256()
    best = []
    st = dict(islands=0, largest=0, steps=0, log_steps=0, pgs=0, capped=0, max_contacts=0)
    for _, _, args in kept:
        t = np.inf
        for _ in range(a.repeat):
            out = _copy(args)
            c = time.process_time()
            mk.moreau_islands(*out)
            t = min(t, time.process_time() - c)
        best.append(t)
        d = dict(zip(names, out, strict=True))
        s, start = d["stats"], d["start"]
        st["islands"] += start.size - 1
        st["largest"] = max(st["largest"], int(np.diff(start).max(initial=0)))
        st["steps"] += int(s[mk.ST_STEPS])
        st["log_steps"] += int(s[mk.ST_LOG_STEPS])
        st["pgs"] += int(s[mk.ST_PGS])
        st["capped"] += int(s[mk.ST_CAPPED])
        st["max_contacts"] = max(st["max_contacts"], int(s[mk.ST_MAX_CONTACTS]))
        for k in ("S", "stats", "code", "lim"):
            # the statistics before ST_CAPPED: the digests of older captures' replays compare
            v = d[k][:mk.ST_CAPPED] if k == "stats" else d[k]
            digest.update(np.ascontiguousarray(v).tobytes())
    row = dict(calls=len(kept), cpu_s=round(float(sum(best)), 3),
               heaviest_ms=round(1e3 * max(best), 1), **st, digest=digest.hexdigest()[:16])
    cols = list(row)
    text = (f"### Island kernel calls replayed ({a.replay})\n\nMeasured on {machine()}; best "
            f"of {a.repeat} per call, 1 thread.\n\n| " + " | ".join(cols) + " |\n|"
            + "|".join("---" for _ in cols) + "|\n| "
            + " | ".join(str(row[c]) for c in cols) + " |\n")
    print(text)
    if a.name:
        RESULTS.mkdir(parents=True, exist_ok=True)
        (RESULTS / f"{a.name}.md").write_text(text)
        (RESULTS / f"{a.name}.json").write_text(json.dumps(
            {"info": dict(machine=machine(), calls_file=str(a.replay), repeat=a.repeat,
                          solver=a.solver or "as captured"), "runs": [row]}, indent=1))


def replay_parallel(a):
    """Each kept call by the serial and by the parallel kernel: wall times, states compared."""
    import inspect

    import numba

    from driftlog import moreau_kernel as mk
    from driftlog._numba import PARALLEL_MIN

    kept = _load(a.replay, a.solver)
    if not kept:
        sys.exit(f"island_replay: {a.replay} holds no calls")
    nt = numba.get_num_threads()
    start = list(inspect.signature(mk.moreau_islands.py_func).parameters).index("start")
    mk.moreau_islands(*_copy(kept[0][2]))
    mk.moreau_islands_parallel(*_copy(kept[0][2]), 1.0, nt)  # compiled or loaded first
    tot = {"all": [0.0, 0.0, 0], "parallel": [0.0, 0.0, 0]}
    for _, _, args in kept:
        ts = tp = np.inf
        for _ in range(a.repeat):
            x = _copy(args)
            c = time.perf_counter()
            mk.moreau_islands(*x)
            ts = min(ts, time.perf_counter() - c)
            y = _copy(args)
            c = time.perf_counter()
            mk.moreau_islands_parallel(*y, 1.0, nt)
            tp = min(tp, time.perf_counter() - c)
            if x[0].tobytes() != y[0].tobytes():
                sys.exit("island_replay: the parallel kernel's states differ from the serial's")
        nlog = int(args[start][-1])  # the logs of the call's islands
        for key in ("all", "parallel") if nlog >= PARALLEL_MIN else ("all",):
            tot[key][0] += ts
            tot[key][1] += tp
            tot[key][2] += 1
    rows = [dict(calls=key + f" ({v[2]})", serial_wall_s=round(v[0], 3),
                 parallel_wall_s=round(v[1], 3), ratio=round(v[0] / max(v[1], 1e-12), 2))
            for key, v in tot.items()]
    text = (f"### Island kernel calls replayed, serial and parallel kernels ({a.replay})\n\n"
            f"Measured on {machine()}; {nt} numba threads, best of {a.repeat} per call, wall "
            f"time; the states equal call by call.  'parallel': the calls of {PARALLEL_MIN} "
            "logs or more, which the tracker sends to the parallel kernel.\n\n"
            "| calls | serial wall (s) | parallel wall (s) | serial / parallel |\n"
            "|---|---|---|---|\n"
            + "".join(f"| {r['calls']} | {r['serial_wall_s']} | {r['parallel_wall_s']} | "
                      f"{r['ratio']} |\n" for r in rows))
    print(text)
    if a.name:
        RESULTS.mkdir(parents=True, exist_ok=True)
        (RESULTS / f"{a.name}.md").write_text(text)
        (RESULTS / f"{a.name}.json").write_text(json.dumps(
            {"info": dict(machine=machine(), calls_file=str(a.replay), repeat=a.repeat,
                          threads=nt, solver=a.solver or "as captured"), "runs": rows},
            indent=1))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--capture", type=Path, help="run the scene and keep calls in this file")
    g.add_argument("--replay", type=Path, help="time the calls kept in this file")
    p.add_argument("--flow", type=Path, help="the stored Malpasset flow (--capture)")
    p.add_argument("--logs", type=int, default=10000)
    p.add_argument("--density", type=float, default=100000.0)
    p.add_argument("--end", type=float, default=900.0)
    p.add_argument("--every", type=int, default=40, help="keep every k-th call (--capture)")
    p.add_argument("--repeat", type=int, default=2, help="runs of each call (--replay)")
    p.add_argument("--name", default=None, help="results/<name>.{md,json} (--replay)")
    p.add_argument("--solver", choices=("pgs", "nncg"), default=None,
                   help="replay with this contact solver (default: the captured one)")
    p.add_argument("--parallel", action="store_true",
                   help="--replay: each call by the serial and the parallel kernel (run with "
                        "NUMBA_NUM_THREADS=2 or more), wall times")
    a = p.parse_args()
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    if a.capture:
        if a.flow is None or not a.flow.is_file():
            p.error(f"--capture needs --flow, the stored flow file (got {a.flow})")
        if a.every < 1:
            p.error(f"--every must be at least 1 (got {a.every})")
        capture(a)
    else:
        if not a.replay.is_file():
            p.error(f"--replay: no file {a.replay}")
        (replay_parallel if a.parallel else replay)(a)


if __name__ == "__main__":
    main()
