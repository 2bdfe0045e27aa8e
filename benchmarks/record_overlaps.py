"""Logs overlapping at the records of a trajectory file: how deep, when, and between whom.

A contact model should keep the logs' capsules apart (to its tolerance); a pair that overlaps
at a record shows where it did not.  For every record time, every pair of logs that take part
(floating, resting, stranded) whose capsules come within reach is measured with the contact
model's own capsule gap (``contact.geometry.capsule_pair_gaps``); pairs deeper than
``--depth`` are counted, the ``--per-record`` deepest of each record kept, by the pair's
statuses (F floating, R resting, S stranded).  Prints a table and writes
``benchmarks/results/<name>.md``/``.json``.

    python benchmarks/million_logs.py --flow F --logs 10000 --end 4000 --output-interval 20 \\
        --grounded on --out T.nc --keep
    python benchmarks/record_overlaps.py T.nc --name overlaps_grounded_4000s
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402
from _common import RESULTS, machine  # noqa: E402

from driftlog.logs import FLOATING, RESTING, STRANDED  # noqa: E402

STATUS = {FLOATING: "F", RESTING: "R", STRANDED: "S"}


def record_overlaps(path, depth=0.02, per_record=3, until=None):
    """[(gap, time, log a, log b, statuses)] of the deepest overlapping pairs of each record."""
    import netCDF4
    from scipy.spatial import cKDTree

    from driftlog.columns import GAP, NRES
    from driftlog.contact.geometry import capsule_pair_gaps, log_capsules

    with netCDF4.Dataset(path) as ds:
        L, R = (np.asarray(ds[v][:], float) for v in ("length", "radius"))
        if "rowSize" in ds.variables:
            owner = np.repeat(np.arange(L.size), ds["rowSize"][:])
        else:  # a .partial file: ragged by index
            owner = np.asarray(ds["trajectory_index"][:], dtype=np.int64)
        time, x, y, th = (np.asarray(ds[v][:], float) for v in ("time", "x", "y", "theta"))
        st = np.asarray(ds["status"][:])
    reach = float(L.max() + 2.0 * R.max())
    out = []
    times = np.unique(time)
    if until is not None:
        times = times[times <= until]
    for t in times:
        k = np.flatnonzero((time == t) & np.isin(st, list(STATUS)))
        if k.size < 2:
            continue
        o = owner[k]
        caps = log_capsules(x[k], y[k], th[k], L[o], R[o])
        pr = cKDTree(np.c_[x[k], y[k]]).query_pairs(reach, output_type="ndarray")
        if pr.size == 0:
            continue
        gaps = np.empty((pr.shape[0], NRES))
        capsule_pair_gaps(np.ascontiguousarray(caps[pr[:, 0]]),
                          np.ascontiguousarray(caps[pr[:, 1]]), gaps)
        g = gaps[:, GAP]
        for q in np.argsort(g)[:per_record]:
            if g[q] < -depth:
                i, j = k[pr[q, 0]], k[pr[q, 1]]
                out.append((float(g[q]), float(t), int(owner[i]), int(owner[j]),
                            STATUS[int(st[i])] + STATUS[int(st[j])]))
    return out, times.size


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trajectories", help="trajectory file (or its .partial)")
    ap.add_argument("--depth", type=float, default=0.02, help="overlaps deeper than this (m)")
    ap.add_argument("--per-record", type=int, default=3, help="deepest pairs kept per record")
    ap.add_argument("--until", type=float, default=None, help="records up to this time (s)")
    ap.add_argument("--name", default="record_overlaps")
    a = ap.parse_args(argv)
    pairs, n = record_overlaps(a.trajectories, a.depth, a.per_record, a.until)
    kinds = Counter(p[4] for p in pairs)
    first = min((p[1] for p in pairs), default=None)
    lines = [f"### Logs overlapping at the records: {Path(a.trajectories).name}", "",
             f"Measured on {machine()}.  {n} records; pairs overlapping by more than "
             f"{a.depth:g} m (the {a.per_record} deepest of each record): {len(pairs)}, by "
             f"statuses {dict(kinds)}; the first at t = {first} s.", "",
             "| gap (m) | t (s) | log | log | statuses |", "|---:|---:|---:|---:|---|"]
    lines += [f"| {g:.3f} | {t:g} | {i} | {j} | {s} |" for g, t, i, j, s in sorted(pairs)[:25]]
    text = "\n".join(lines) + "\n"
    print(text)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{a.name}.md").write_text(text)
    (RESULTS / f"{a.name}.json").write_text(json.dumps(dict(
        machine=machine(), trajectories=str(a.trajectories), records=int(n), depth=a.depth,
        per_record=a.per_record, until=a.until, count=len(pairs), by_statuses=dict(kinds),
        first_time=first, pairs=sorted(pairs)), indent=1))


if __name__ == "__main__":
    main()
