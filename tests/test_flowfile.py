import netCDF4
import numpy as np
import pytest

from driftlog.analytic import SolidBodyRotation, on_mesh
from driftlog.errors import FlowFileError
from driftlog.flowfile import FlowFileWriter, open_flow, write_flow
from driftlog.mesh import Mesh


@pytest.fixture
def field(mixed_mesh):
    mixed_mesh.tag_boundary("inflow", lambda x, y: x < 1e-9)
    return on_mesh(SolidBodyRotation(0.1, center=(3, 2)), mixed_mesh, times=[0.0, 5.0, 10.0])


def test_roundtrip(tmp_path, field, rng):
    p = write_flow(tmp_path / "flow.nc", field, attrs={"scenario": "title = 'x'"})
    g = open_flow(p)
    assert g.attrs["scenario"] == "title = 'x'"
    assert g.attrs["Conventions"].startswith("CF-1.11")
    np.testing.assert_array_equal(g.times, field.times)
    np.testing.assert_array_equal(g.bed, field.bed)
    assert g.mesh.tag_names == ["wall", "inflow"]
    np.testing.assert_array_equal(g.mesh.edge_tag, field.mesh.edge_tag)
    x, y = rng.uniform(0, 6, 100), rng.uniform(0, 4, 100)
    np.testing.assert_allclose(g.sample(x, y, 7.5).values, field.sample(x, y, 7.5).values,
                               atol=1e-12)


def test_xugrid_and_xarray_open_it(tmp_path, field):
    import xarray as xr
    import xugrid

    p = write_flow(tmp_path / "flow.nc", field)
    uds = xugrid.open_dataset(p)
    assert uds.ugrid.grid.n_face == field.mesh.n_faces
    assert uds["water_depth"].shape == (3, field.mesh.n_faces)
    assert uds["velocity_x"].attrs["units"] == "m s-1"
    ds = xr.open_dataset(p)
    assert ds["bed_level"].attrs["standard_name"] == "altitude"


def test_incremental_write_survives_a_crash(tmp_path, mixed_mesh):
    p = tmp_path / "flow.nc"
    w = FlowFileWriter(p, mixed_mesh, np.zeros(mixed_mesh.n_faces))
    h = np.ones(mixed_mesh.n_faces)
    w.write(0.0, h, hu=h * 0.1, hv=h * 0)
    w.write(1.0, h, hu=h * 0.2, hv=h * 0)
    # no close(): what was written is already on disk
    with netCDF4.Dataset(p) as ds:
        assert ds.dimensions["time"].size == 2
    w.close()
    w = FlowFileWriter(p, mixed_mesh, None, append=True)
    w.write(2.0, h, hu=h * 0.3, hv=h * 0)
    with pytest.raises(FlowFileError, match="not after"):
        w.write(1.5, h, hu=h, hv=h)
    w.close()
    g = open_flow(p)
    np.testing.assert_allclose(g.snapshot(2)["u"], 0.3)


def test_bad_files(tmp_path, field):
    with pytest.raises(FlowFileError, match="not found"):
        open_flow(tmp_path / "nope.nc")
    bad = tmp_path / "trunc.nc"
    good = write_flow(tmp_path / "good.nc", field)
    bad.write_bytes(good.read_bytes()[:2000])
    with pytest.raises(FlowFileError):
        open_flow(bad)
    # missing variable
    p = write_flow(tmp_path / "f.nc", field)
    with netCDF4.Dataset(p, "a") as ds:
        ds.renameVariable("velocity_y", "vy")
    with pytest.raises(FlowFileError, match="'velocity_y' is missing"):
        open_flow(p)
    # non-monotonic times
    p = write_flow(tmp_path / "t.nc", field)
    with netCDF4.Dataset(p, "a") as ds:
        ds["time"][:] = [0.0, 10.0, 5.0]
    with pytest.raises(FlowFileError, match="not increasing"):
        open_flow(p)
    # NaN in a snapshot: found when the snapshot is read, with the time
    p = write_flow(tmp_path / "n.nc", field)
    with netCDF4.Dataset(p, "a") as ds:
        ds["water_depth"][2, 4] = np.nan
    f = open_flow(p)
    f.sample([1.0], [1.0], 1.0)
    with pytest.raises(FlowFileError, match=r"snapshot 2 \(t = 10.0 s\).*non-finite h"):
        f.sample([1.0], [1.0], 6.0)


def test_mesh_mismatch(tmp_path, field):
    other = Mesh.regular_grid(3, 3, 1.0)
    from driftlog.flow import MeshFlowField

    with pytest.raises(FlowFileError, match="bed has shape"):
        MeshFlowField.from_arrays(other, field.bed, [0.0], [field.bed], [field.bed], [field.bed])
    f = MeshFlowField.from_arrays(other, np.zeros(9), [0.0], [np.ones(4)], [np.ones(4)],
                                  [np.ones(4)])
    with pytest.raises(FlowFileError, match="has shape"):
        f.sample([1.0], [1.0], 0.0)


def test_time_units_are_honoured(tmp_path, field):
    """The flow-file reader takes CF time units as the ugrid reader does (it read every value
    as seconds: 'days since' gave a flow 86400 times too short) and refuses unknown ones."""
    from driftlog.adapters import open_flow_source

    p = write_flow(tmp_path / "days.nc", field)
    with netCDF4.Dataset(p, "a") as ds:
        ds["time"][:] = [0.0, 10.0, 20.0]
        ds["time"].units = "days since 2000-01-01"
    g = open_flow(p)
    np.testing.assert_array_equal(g.times, [0.0, 864000.0, 1728000.0])
    assert g.attrs["time_reference"] == "seconds since 2000-01-01"
    np.testing.assert_array_equal(open_flow_source("file", p).times, g.times)
    np.testing.assert_array_equal(open_flow_source("ugrid", p).times, g.times)
    assert "time_reference" not in open_flow(write_flow(tmp_path / "s.nc", field)).attrs
    bad = write_flow(tmp_path / "fortnights.nc", field)
    with netCDF4.Dataset(bad, "a") as ds:
        ds["time"].units = "fortnights since 2000-01-01"
    with pytest.raises(FlowFileError, match=r"fortnights.nc: time: time units 'fortnights "
                       r"since 2000-01-01' not understood"):
        open_flow(bad)
