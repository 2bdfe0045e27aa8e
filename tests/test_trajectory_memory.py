"""The trajectory writer's memory does not grow with the number of logs beyond one bounded
buffer: it flushes when ``MAX_BUFFERED_OBS`` observations are buffered, whatever
``flush_interval`` says, and the final contiguous rewrite writes block by block.  The file is
the same as with one flush at the end (benchmarks/million_logs.py measures the memory)."""

import netCDF4
import numpy as np

from driftlog import trajectory
from driftlog.logs import Logs
from driftlog.trajectory import OBS_VARS, TrajectoryWriter, open_trajectories


def _write(path, n, records, rng):
    logs = Logs(rng.random(n), rng.random(n))
    w = TrajectoryWriter(path, logs, flush_interval=1000)
    written = []
    for k in range(records):
        idx = np.sort(rng.choice(n, size=n - k, replace=False))  # logs leave: fewer each time
        cols = {name: rng.random(idx.size) for name in OBS_VARS}
        cols["status"] = np.ones(idx.size, np.int8)
        w.record(float(k), idx, cols)
        written.append(w.nobs)
    w.close()
    return written


def test_buffer_bounded_and_file_unchanged(tmp_path, monkeypatch):
    n, records = 50, 8
    _write(tmp_path / "ref.nc", n, records, np.random.default_rng(3))
    monkeypatch.setattr(trajectory, "MAX_BUFFERED_OBS", 120)
    monkeypatch.setattr(trajectory, "_BLOCK", 7)
    written = _write(tmp_path / "small.nc", n, records, np.random.default_rng(3))
    # flushed as soon as 120 observations were buffered (flush_interval = 1000 records)
    sizes = np.arange(n, n - records, -1)
    assert written[1] == 0 and written[2] == sizes[:3].sum()
    assert max(np.diff([0, *written])) <= 120 + n
    a, b = open_trajectories(tmp_path / "ref.nc"), open_trajectories(tmp_path / "small.nc")
    for name in [*OBS_VARS, "time", "rowSize"]:
        np.testing.assert_array_equal(a[name].values, b[name].values)
    # contiguous: each log's observations together, in time order
    with netCDF4.Dataset(tmp_path / "small.nc") as ds:
        rows = ds["rowSize"][:]
        t = ds["time"][:]
    assert rows.sum() == sizes.sum()
    for i, (s, r) in enumerate(zip(np.cumsum(rows) - rows, rows, strict=True)):
        assert np.all(np.diff(t[s:s + r]) > 0), i
