"""Any time axis (issue 12 item 6): absolute epochs, far-away starts, CF calendars, date stamps.

Internal times keep full precision (a run far from the axis' zero runs on its own clock), the
outputs carry the absolute reference (CF units, add_offset), and every time tolerance is
relative to the run's span, never to |t|.
"""

import netCDF4
import numpy as np
import pytest
from driftlog.adapters._common import select_times, time_in_seconds

from driftlog.errors import FlowFileError
from driftlog.flow import MeshFlowField
from driftlog.flowfile import FlowFileWriter
from driftlog.mesh import Mesh

T_EPOCH = 1.7e9  # s since 1970-01-01: 2023-11-14T22:13:20
U0 = 0.1


def _mesh():
    return Mesh.regular_grid(20, 10, 1.0)


def _flow_file(path, t0, reference="seconds since 1970-01-01 00:00:00", calendar=None):
    m = _mesh()
    n = m.n_faces
    attrs = {"time_reference": reference} if reference else {}
    if calendar:
        attrs["calendar"] = calendar
    with FlowFileWriter(path, m, np.zeros(n), attrs=attrs) as w:
        for t in (0.0, 32.0, 64.0):
            w.write(t0 + t, np.ones(n), u=np.full(n, U0), v=np.zeros(n))
    return path


def _scenario(tmp_path, flow_path, start, end, out="traj.nc"):
    text = f"""
[flow]
source = "file"
path = "{flow_path}"
[time]
start = {start!r}
end = {end!r}
output_interval = 1.0
[[logs]]
seeding = "list"
x = [2.0]
y = [5.0]
length = 0.5
radius = 0.05
density = 600.0
[physics]
level = "tracer"
[output]
path = "{tmp_path / out}"
"""
    p = tmp_path / "scenario.toml"
    p.write_text(text)
    return p


def test_absolute_epoch_axis_runs_the_whole_span(tmp_path):
    """The issue's case: 'seconds since 1970-01-01', t ~ 1.7e9 s, a 64-s run, 1-s outputs."""
    from driftlog.cli import main

    flow = _flow_file(tmp_path / "flow.nc", T_EPOCH)
    scen = _scenario(tmp_path, flow, T_EPOCH, T_EPOCH + 64.0)
    assert main(["track", str(scen), "--quiet"]) == 0
    with netCDF4.Dataset(tmp_path / "traj.nc") as ds:
        t = ds["time"]
        assert t.units == "seconds since 1970-01-01 00:00:00"  # the flow's own reference
        assert t.add_offset == T_EPOCH
        t.set_auto_maskandscale(False)
        raw = t[:]
        x = ds["x"][:]
        # 65 records (was 3): every output time, stored exactly on the run's clock
        np.testing.assert_array_equal(raw, np.arange(65.0))
        np.testing.assert_allclose(x[-1] - x[0], U0 * 64.0, rtol=1e-9)
        dates = netCDF4.num2date(raw[[0, -1]] + T_EPOCH, t.units)
        assert str(dates[0]) == "2023-11-14 22:13:20" and str(dates[1]) == "2023-11-14 22:14:24"
    # the trajectory dataset reads absolute times (add_offset applied)
    from driftlog.trajectory import open_trajectories

    tt = open_trajectories(tmp_path / "traj.nc")["time"].values
    np.testing.assert_allclose(tt - T_EPOCH, np.arange(65.0), atol=1e-6)


def test_far_start_on_a_steady_flow(tmp_path):
    """time.start = 1e17 s (float64 spacing 16 s there): still 65 records, 1 s apart."""
    from driftlog.api import track

    m = _mesh()
    n = m.n_faces
    steady = MeshFlowField.from_arrays(m, np.zeros(n), [0.0], np.ones((1, n)),
                                       np.full((1, n), U0), np.zeros((1, n)))
    scen = _scenario(tmp_path, tmp_path / "unused.nc", 1e17, 1e17 + 64.0)
    (tmp_path / "unused.nc").write_text("")
    ds = track(scen, flow=steady).dataset()
    assert ds["time"].size == 65
    with netCDF4.Dataset(tmp_path / "traj.nc") as nc:
        assert nc["time"].add_offset == 1e17
        nc.set_auto_maskandscale(False)
        np.testing.assert_array_equal(nc["time"][:], np.arange(65.0))
        np.testing.assert_allclose(nc["x"][-1] - nc["x"][0], U0 * 64.0, rtol=1e-9)


def test_tracker_tolerances_follow_the_span():
    """The tracker alone (no clock shift): stops are merged within 1e-9 of the span, not |t|."""
    from driftlog.logs import Logs
    from driftlog.physics import PhysicsOptions
    from driftlog.tracker import Tracker

    m = _mesh()
    n = m.n_faces
    t0 = T_EPOCH
    flow = MeshFlowField.from_arrays(m, np.zeros(n), t0 + np.array([0.0, 32.0, 64.0]),
                                     np.ones((3, n)), np.full((3, n), U0), np.zeros((3, n)))

    class Recorder:
        times = []

        def record(self, t, index, columns):
            self.times.append(t)

        def hits(self, hits):
            pass

    logs = Logs([2.0], [5.0], length=0.5, radius=0.05, density=600.0, release_time=t0)
    rec = Recorder()
    Tracker(flow, logs, PhysicsOptions(level="tracer", rotation=False), "rk4", t_start=t0,
            t_end=t0 + 64.0, output_interval=1.0, writer=rec).run()
    assert len(rec.times) == 65
    np.testing.assert_allclose(np.diff(rec.times), 1.0, atol=1e-6)


def test_select_times_tolerance_is_relative_to_the_span():
    times = T_EPOCH + np.arange(10.0)
    idx = select_times(times, (T_EPOCH + 2, T_EPOCH + 5), "f")
    assert idx.tolist() == [2, 3, 4, 5]  # was [1..6]: 1e-9 |t| = 1.7 s


def test_cf_calendar_360_day(tmp_path):
    """A UGRID file on the 360-day calendar: seconds since its own reference, kept with it."""
    import cftime
    from driftlog.adapters import import_flow, open_flow_source

    p = _flow_file(tmp_path / "cal.nc", 0.0, reference=None)
    with netCDF4.Dataset(p, "a") as ds:
        t = ds["time"]
        t.units = "days since 2001-02-30 00:00:00"  # 30 February: a 360_day date
        t.calendar = "360_day"
        t[:] = np.array([0.0, 0.5, 1.0])
    fl = open_flow_source("ugrid", p)
    np.testing.assert_array_equal(fl.times, [0.0, 43200.0, 86400.0])
    assert fl.attrs["time_reference"] == "seconds since 2001-02-30 00:00:00"
    assert fl.attrs["calendar"] == "360_day"
    d = cftime.num2date(fl.times, fl.attrs["time_reference"], calendar="360_day")
    assert [str(x) for x in d] == ["2001-02-30 00:00:00", "2001-02-30 12:00:00",
                                   "2001-03-01 00:00:00"]
    # imported: the flow file keeps the reference and the calendar
    out, _ = import_flow(p, tmp_path / "imported.nc", kind="ugrid")
    with netCDF4.Dataset(out) as ds:
        assert ds["time"].units == "seconds since 2001-02-30 00:00:00"
        assert ds["time"].calendar == "360_day"
        np.testing.assert_array_equal(ds["time"][:], [0.0, 43200.0, 86400.0])
    # the same date is not a date of the standard calendar: a clear error
    fl.source.close()
    with netCDF4.Dataset(p, "a") as ds:
        ds["time"].calendar = "standard"
    with pytest.raises(FlowFileError, match="not a date of the 'standard' calendar"):
        open_flow_source("ugrid", p)


def test_date_stamp_axes():
    iso = np.array(["2024-03-01T00:00:00", "2024-03-01T00:10:00.250", "2024-03-02T00:00:00"])
    sec, ref = time_in_seconds(iso, None, "f")
    np.testing.assert_array_equal(sec, [0.0, 600.25, 86400.0])
    assert ref == "2024-03-01T00:00:00"
    sec, ref = time_in_seconds(iso.astype("datetime64[ms]"), None, "f")
    np.testing.assert_array_equal(sec, [0.0, 600.25, 86400.0])
    with pytest.raises(FlowFileError, match="months and years"):
        time_in_seconds([0.0, 1.0], "months since 2000-01-01", "f")
    with pytest.raises(FlowFileError, match="calendar 'lunar' unknown"):
        time_in_seconds([0.0], "days since 2000-01-01", "f", calendar="lunar")
