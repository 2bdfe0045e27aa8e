"""Memory that does not grow with the number of logs beyond their own arrays
(benchmarks/million_logs.py measures it):

- the trajectory writer flushes when ``MAX_BUFFERED_OBS`` observations are buffered, whatever
  ``flush_interval`` says, and the final contiguous rewrite writes block by block; the file is
  the same as with one flush at the end;
- the start check of logs against walls and obstacles measures only the pairs whose boxes
  touch (was: every log against every wall capsule, (n, 2048) arrays at a time): the same
  overlaps and gaps as the brute-force check (the contact model's exact gap, every pair).
"""

import netCDF4
import numpy as np

from driftlog import trajectory
from driftlog.logs import Logs
from driftlog.preflight import _capsule_gaps, _log_capsules
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


def _exact_gaps(logs, caps):
    """Every log against every capsule, the contact model's exact signed gap."""
    from driftlog.columns import GAP, NRES
    from driftlog.contact.geometry import capsule_pair_gaps

    lc = _log_capsules(logs)
    n, m = len(logs), caps.shape[0]
    res = np.empty((n * m, NRES))
    capsule_pair_gaps(np.repeat(lc, m, axis=0), np.tile(caps, (n, 1)), res)
    return res[:, GAP].reshape(n, m).min(axis=1)


def _brute_gaps(logs, caps):
    """Every log against every capsule, 9 samples on each log axis (the check before)."""
    lc = _log_capsules(logs)
    best = np.full(len(logs), np.inf)
    for s in np.linspace(0.0, 1.0, 9):
        px = (lc[:, 0] + s * (lc[:, 2] - lc[:, 0]))[:, None]
        py = (lc[:, 1] + s * (lc[:, 3] - lc[:, 1]))[:, None]
        ax, ay, bx, by = (caps[None, :, k] for k in range(4))
        dx, dy = bx - ax, by - ay
        ll = dx * dx + dy * dy
        t = np.clip(((px - ax) * dx + (py - ay) * dy) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
        d = np.hypot(px - (ax + t * dx), py - (ay + t * dy)) - caps[None, :, 4] - lc[:, 4:5]
        best = np.minimum(best, d.min(axis=1))
    return best


def test_start_overlaps_found_pairwise(monkeypatch):
    rng = np.random.default_rng(8)
    n, m = 3000, 400
    logs = Logs(rng.uniform(0, 100, n), rng.uniform(0, 100, n), rng.uniform(0, np.pi, n),
                rng.uniform(0.5, 4.0, n), rng.uniform(0.05, 0.3, n))
    a = rng.uniform(0, 100, (m, 2))
    b = a + rng.uniform(-3, 3, (m, 2))
    b[:20] = a[:20]  # points (circles)
    caps = np.column_stack([a, b, rng.uniform(0.0, 1.0, m)])
    import driftlog.preflight as pf

    monkeypatch.setattr(pf, "_PAIRS", 257)  # several blocks of pairs
    gap, ref = _capsule_gaps(logs, caps), _exact_gaps(logs, caps)
    # the exact gap is at most the distance from 9 samples of the axis (an upper bound)
    assert np.all(ref <= _brute_gaps(logs, caps) + 1e-12)
    assert np.sum(ref < 0) > 100 and np.sum(ref >= 0) > 100
    np.testing.assert_array_equal(gap < 0, ref < 0)
    # overlaps: the same depth (the deepest capsule's box touches the log's); elsewhere only
    # nearby capsules are measured, so the gap found is >= the smallest, both positive
    over = ref < 0
    np.testing.assert_allclose(gap[over], ref[over], rtol=0, atol=1e-12)
    assert np.all(gap[~over] >= ref[~over]) and np.all(ref[~over] >= 0)
    assert _capsule_gaps(logs, caps[:0]).min() == np.inf
