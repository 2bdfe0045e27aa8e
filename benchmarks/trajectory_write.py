"""Writing a trajectory file: the records of a run replayed through ``TrajectoryWriter``.

The cost of driftlog's output for many logs: each record appended to the ``.partial`` file
(indexed ragged, flushed as the run goes), then the rewrite as a contiguous ragged array at
``close()``.  Two storage layouts of the observation variables, alternated in one process:

- ``netcdf defaults`` (driftlog before 2026-12-06): zlib level 1 (with netCDF4's default
  shuffle) on the data columns of both files (time and trajectory index were uncompressed in
  the running file; this arm compresses them as well), netCDF-C's default chunks (512
  observations while the file grows, the whole dimension in the final file);
- ``driftlog`` (``trajectory._obs_storage``): 65,536 observations per chunk; the running file
  in Zstandard level 1 (every column), the final file in zlib level 1 with shuffle.

The records are those of a real run: ``--from FILE`` replays a trajectory file record by
record (e.g. ``benchmarks/million_logs.py --keep`` or a case's output); by default N logs
(``--logs``, 20,000) are first tracked for 300 s in the vortex case's solid-body rotation
(full physics, RK4), a record every second.  CPU time of the writing (records and flushes)
and of the close (the rewrite), the files' sizes, and a check that both layouts hold the same
values::

    python benchmarks/trajectory_write.py --repeat 3
    python benchmarks/trajectory_write.py --from F.nc --name trajectory_write_malpasset

``--every-record``: a flush after every record, as a coupled run flushes with each flow
snapshot; the arms are then the running file's chunks of ``OBS_CHUNK`` observations (driftlog
before 2026-12-08) and chunks sized to the flushes (``trajectory.running_chunk``: about four
records' worth, at least 4,096 observations), both in driftlog's compressors::

    python benchmarks/trajectory_write.py --from F.nc --every-record --name trajectory_flush

writes benchmarks/results/<name, default trajectory_write>.{md,csv}.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import write_table  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def netcdf_defaults(ds, partial, nobs=None):
    """The storage of the obs variables before 2026-12-06 (netCDF-C's default chunks).

    zlib level 1 with netCDF4's default shuffle on every obs variable; before, the running
    file's time and trajectory index were stored uncompressed (this arm compresses them too:
    at most a few per cent of its time, on columns that compress a hundredfold).
    """
    return dict(zlib=True, complevel=1)


def vortex_run(n, out):
    """Track n logs for 300 s in the vortex case's rotation; the trajectory file at out."""
    from driftlog.api import as_scenario, track

    scen = as_scenario(ROOT / "cases" / "vortex" / "scenario.toml", {
        "time": {"end": 300.0, "output_interval": 1.0},
        "logs": [{"seeding": "random", "count": int(n), "seed": 1, "theta": "random",
                  "polygon": [[-50.0, -50.0], [50.0, -50.0], [50.0, 50.0], [-50.0, 50.0]],
                  "length": 0.5, "radius": 0.05, "density": 700.0, "velocity": "flow"}],
        "output": {"path": str(out)}})
    track(scen, output=out)


def load_records(path):
    """The records of a trajectory file: (logs-like object, [(t, index, columns), ...])."""
    import netCDF4

    from driftlog import trajectory as T

    with netCDF4.Dataset(path) as d:
        d.set_auto_maskandscale(False)
        n = len(d.dimensions["trajectory"])
        if "rowSize" in d.variables:
            ti = np.repeat(np.arange(n), d["rowSize"][:])
        else:
            ti = d["trajectory_index"][:]
        t = d["time"][:]
        order = np.lexsort((ti, t))
        names = list(T.OBS_VARS)
        cols = {k: d[k][:][order] for k in names}
        t, ti = t[order], ti[order]

        class Logs:
            def __len__(self):
                return n

        logs = Logs()
        logs.id = d["trajectory"][:]
        for attr, name in (("length", "length"), ("radius", "radius"), ("density", "density"),
                           ("release_time", "release_time"), ("group", "group"),
                           ("float_depth", "flotation_depth")):
            setattr(logs, attr, d[name][:])
    cuts = np.r_[0, np.flatnonzero(np.diff(t)) + 1, t.size]
    recs = [(float(t[a]), ti[a:b], {k: v[a:b] for k, v in cols.items()})
            for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
    return logs, recs


def whole_chunks(storage):
    """driftlog's ``storage`` with the running file in chunks of OBS_CHUNK (before 2026-12-08)."""

    def whole(ds, partial, nobs=None, chunk=None):
        return storage(ds, partial, nobs)

    return whole


def write_once(logs, recs, out, storage, every=False):
    """Replay the records into a TrajectoryWriter with this storage; CPU s and sizes.

    ``every``: flushed after every record (as a coupled run is).
    """
    from driftlog import trajectory as T

    keep = T._obs_storage
    if storage is not keep:
        T._obs_storage = storage
    try:
        c0 = time.process_time()
        w = T.TrajectoryWriter(out, logs, flush_every_record=every)
        for t, idx, cols in recs:
            w.record(t, idx, cols)
            if every:
                w.flush()
        w.flush()
        c1 = time.process_time()
        partial_mb = w.partial.stat().st_size / 2**20
        w.close()
        c2 = time.process_time()
    finally:
        T._obs_storage = keep
    return dict(write_cpu_s=c1 - c0, close_cpu_s=c2 - c1, total_cpu_s=c2 - c0,
                partial_mb=partial_mb, final_mb=Path(out).stat().st_size / 2**20)


def same_values(a, b):
    import netCDF4

    with netCDF4.Dataset(a) as x, netCDF4.Dataset(b) as y:
        return all(np.array_equal(x[k][:], y[k][:]) for k in x.variables)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--from", dest="source", help="a trajectory file whose records to replay")
    p.add_argument("--logs", type=float, default=20000, help="logs of the vortex run")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--name", default="trajectory_write")
    p.add_argument("--every-record", action="store_true",
                   help="flush after every record (a coupled run); arms: the running file's "
                        "chunks of OBS_CHUNK against chunks sized to the flushes")
    a = p.parse_args(argv)
    from driftlog import trajectory as T

    arms = {"netcdf defaults (before)": netcdf_defaults, "driftlog": T._obs_storage}
    if a.every_record:
        arms = {"chunks of OBS_CHUNK (before)": whole_chunks(T._obs_storage),
                "chunks sized to the flushes": T._obs_storage}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        source = Path(a.source) if a.source else tmp / "vortex.nc"
        if not a.source:
            vortex_run(a.logs, source)
        logs, recs = load_records(source)
        nobs = sum(r[1].size for r in recs)
        best = {}
        for _ in range(a.repeat):
            for i, (arm, storage) in enumerate(arms.items()):
                r = write_once(logs, recs, tmp / f"out{i}.nc", storage, a.every_record)
                print(arm, {k: round(v, 3) for k, v in r.items()}, flush=True)
                b = best.setdefault(arm, r)
                for k in ("write_cpu_s", "close_cpu_s", "total_cpu_s"):
                    b[k] = min(b[k], r[k])
        same = same_values(tmp / "out0.nc", tmp / "out1.nc")
    base = best[next(iter(arms))]["total_cpu_s"]
    rows = [dict(layout=arm, **b, us_per_obs=b["total_cpu_s"] / nobs * 1e6,
                 speedup=base / b["total_cpu_s"]) for arm, b in best.items()]
    src = a.source or f"{int(a.logs)} logs tracked 300 s in the vortex case's rotation"
    write_table(a.name, rows, ["layout", "write_cpu_s", "close_cpu_s", "total_cpu_s",
                               "us_per_obs", "speedup", "partial_mb", "final_mb"],
                "Writing a trajectory file: storage of the observations",
                f"Records of {src}: {len(recs)} records, {nobs:,} observations, replayed "
                f"through TrajectoryWriter"
                f"{', flushed after every record' if a.every_record else ''}; CPU seconds, "
                f"the fastest of {a.repeat} "
                "alternated repetitions in one process.  Final files hold the same values "
                f"in both layouts: {same}.")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
