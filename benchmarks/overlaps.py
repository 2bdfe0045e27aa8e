"""The deepest log-log overlaps in a trajectory file, and what the two logs were doing before.

For every record time, the capsule gap of each pair of logs whose centres are closer than
their lengths plus radii (scipy's cKDTree, then shapely's segment distances); the deepest
overlaps over the run, each with the pair's gap and statuses at the records before it.  Made
to look at what the contacts' ``min_gap`` reports in `million_logs.py` runs (BENCHMARKS.md,
"Toward 1e5 and 1e6 logs"):

    python benchmarks/million_logs.py --flow F --logs 2000 --density 100000 --end 900 \\
        --output-interval 2 --keep --out /tmp/ov.nc
    python benchmarks/overlaps.py /tmp/ov.nc --worst 3 --before 6

writes benchmarks/results/overlaps.md (``--name``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import netCDF4
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS  # noqa: E402

STATUS = ["waiting", "floating", "resting", "stranded", "left_domain"]


def read(path):
    """Per observation: log index, time, x, y, theta, status; per log: length and radius."""
    with netCDF4.Dataset(path) as ds:
        ds.set_auto_maskandscale(False)
        rows = np.asarray(ds["rowSize"][:])
        obs = {k: np.asarray(ds[k][:]) for k in ("time", "x", "y", "theta", "status")}
        length = np.asarray(ds["length"][:]) if "length" in ds.variables else None
        radius = np.asarray(ds["radius"][:]) if "radius" in ds.variables else None
    obs["log"] = np.repeat(np.arange(rows.size), rows)
    return obs, length, radius


def segments(obs, m, length):
    """shapely segments of the logs' axes at observations m."""
    import shapely

    h = 0.5 * length[obs["log"][m]]
    c, s = np.cos(obs["theta"][m]), np.sin(obs["theta"][m])
    x, y = obs["x"][m], obs["y"][m]
    ends = np.stack([np.c_[x - h * c, y - h * s], np.c_[x + h * c, y + h * s]], axis=1)
    return shapely.linestrings(ends)


def pair_gaps(obs, m, length, radius):
    """(gap, log a, log b) of the near pairs among the observations m (one record time)."""
    import shapely
    from scipy.spatial import cKDTree

    reach = float((length + 2 * radius).max())
    pairs = cKDTree(np.c_[obs["x"][m], obs["y"][m]]).query_pairs(reach, output_type="ndarray")
    if not len(pairs):
        return np.empty(0), np.empty(0, int), np.empty(0, int)
    seg = segments(obs, m, length)
    a, b = obs["log"][m[pairs[:, 0]]], obs["log"][m[pairs[:, 1]]]
    gap = shapely.distance(seg[pairs[:, 0]], seg[pairs[:, 1]]) - radius[a] - radius[b]
    return gap, a, b


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("trajectories", help="trajectory file (CF contiguous ragged array)")
    p.add_argument("--worst", type=int, default=3, help="how many of the deepest overlaps")
    p.add_argument("--before", type=int, default=6, help="records shown before each")
    p.add_argument("--name", default="overlaps", help="results name")
    a = p.parse_args(argv)
    obs, length, radius = read(a.trajectories)
    n = int(obs["log"].max()) + 1
    if length is None:  # files without per-log sizes: the million_logs logs
        length, radius = np.full(n, 0.8), np.full(n, 0.08)
    times = np.unique(obs["time"])
    deepest = []  # (gap, time, a, b), the deepest pair of each record time
    for t in times:
        gap, la, lb = pair_gaps(obs, np.flatnonzero(obs["time"] == t), length, radius)
        if gap.size:
            k = int(np.argmin(gap))
            deepest.append((float(gap[k]), float(t), int(la[k]), int(lb[k])))
    deepest.sort()
    key = {(int(i), float(t)): j for j, (i, t) in enumerate(zip(obs["log"], obs["time"],
                                                                strict=True))}
    lines = [f"### Deepest log-log overlaps in {Path(a.trajectories).name}", "",
             f"Re-create: `python benchmarks/overlaps.py {a.trajectories} --worst {a.worst} "
             f"--before {a.before}`.  Gap: capsule gap of the pair (negative: overlap); "
             "status of each log at that record.", ""]
    for gap, t, la, lb in deepest[:a.worst]:
        if gap >= 0:
            break
        lines += [f"Logs {la} and {lb}, {-gap:.3f} m deep at t = {t:g} s:", "",
                  "| t (s) | gap (m) | status a | status b |", "|---:|---:|---|---|"]
        k0 = int(np.searchsorted(times, t))
        for tk in times[max(0, k0 - a.before):k0 + 2]:
            ja, jb = key.get((la, float(tk))), key.get((lb, float(tk)))
            if ja is None or jb is None:
                continue
            sa, sb = segments(obs, np.array([ja, jb]), length)
            g = sa.distance(sb) - radius[la] - radius[lb]
            lines.append(f"| {tk:g} | {g:+.3f} | {STATUS[obs['status'][ja]]} | "
                         f"{STATUS[obs['status'][jb]]} |")
        lines.append("")
    below = sum(g < -0.01 for g, *_ in deepest)
    lines.append(f"Record times with an overlap deeper than 1 cm: {below} of {len(times)}.")
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{a.name}.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
