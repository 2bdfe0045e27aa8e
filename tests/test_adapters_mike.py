"""MIKE 21 FM dfsu reader (adapters/mike.py): files written with mikeio, and real MIKE files."""

from pathlib import Path

import numpy as np
import pytest

mikeio = pytest.importorskip("mikeio")
pd = pytest.importorskip("pandas")

from driftlog.adapters import mike  # noqa: E402

from driftlog.errors import FlowFileError  # noqa: E402
from driftlog.flow import WET  # noqa: E402

DATA = Path(__file__).parent / "data" / "mike"
E, U = mikeio.EUMType, mikeio.EUMUnit


def _geometry():
    """A 6 x 4 grid of 2 m squares, the right half split into triangles, jittered."""
    nx, ny, d = 6, 4, 2.0
    x, y = np.meshgrid(np.arange(nx + 1) * d, np.arange(ny + 1) * d)
    x, y = x.ravel(), y.ravel()
    inner = (x > 0) & (x < nx * d) & (y > 0) & (y < ny * d)
    r = np.random.default_rng(5)
    x = x + np.where(inner, r.uniform(-0.3, 0.3, x.size), 0.0)
    y = y + np.where(inner, r.uniform(-0.3, 0.3, y.size), 0.0)
    z = -3.0 + 0.1 * x - 0.05 * y
    table = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            q = [a, a + 1, a + nx + 2, a + nx + 1]
            table += [np.array(q)] if i < nx // 2 else [np.array(q[:3]), np.array([a, q[2], q[3]])]
    return mikeio.spatial.GeometryFM2D(node_coordinates=np.column_stack([x, y, z]),
                                       element_table=table, projection="UTM-32")


GEOM = _geometry()
ZE = GEOM.element_coordinates[:, 2]  # mean of the node Z, as mikeio (and MIKE) define it


def _centroids():
    """Area centroids of the elements (where the sampler puts element values)."""
    from driftlog.mesh import Mesh

    fn = np.full((GEOM.n_elements, 4), -1)
    for k, e in enumerate(GEOM.element_table):
        fn[k, :len(e)] = e
    m = Mesh(GEOM.node_coordinates[:, 0], GEOM.node_coordinates[:, 1], fn)
    return m.face_x, m.face_y


XE, YE = _centroids()
TIMES = pd.date_range("2021-06-01 12:00:00", periods=3, freq="30min")


def linear(x, y, t):
    """Surface elevation, U, V linear in x, y and t (s)."""
    return (0.5 + 0.01 * x - 0.02 * y + 1e-5 * t, 0.3 + 0.02 * x - 0.01 * y + 1e-5 * t,
            -0.2 + 0.03 * x + 0.01 * y)


ITEMS = {"eta": mikeio.ItemInfo("Surface elevation", E.Surface_Elevation, U.meter),
         "h": mikeio.ItemInfo("Total water depth", E.Water_Depth, U.meter),
         "u": mikeio.ItemInfo("U velocity", E.u_velocity_component, U.meter_per_sec),
         "v": mikeio.ItemInfo("V velocity", E.v_velocity_component, U.meter_per_sec)}


def write_dfsu(path, keep=("eta", "h", "u", "v"), items=None, times=TIMES, factor=None,
               geometry=GEOM):
    sec = (times - times[0]).total_seconds().to_numpy()
    vals = {"eta": [], "h": [], "u": [], "v": []}
    for t in sec:
        eta, u, v = linear(XE, YE, t)
        vals["eta"].append(eta)
        vals["h"].append(eta - ZE)
        vals["u"].append(u)
        vals["v"].append(v)
    items = dict(ITEMS, **(items or {}))
    das = [mikeio.DataArray(np.array(vals[k]) * (factor or {}).get(k, 1.0), time=times,
                            geometry=geometry, item=items[k]) for k in keep]
    mikeio.Dataset(das).to_dfs(str(path))
    return path


def test_can_open(tmp_path):
    p = write_dfsu(tmp_path / "a.dfsu")
    assert mike.can_open(p) and mike.can_open(DATA / "HD2D.dfsu")
    q = tmp_path / "renamed.bin"
    q.write_bytes(p.read_bytes())
    assert mike.can_open(q)
    (tmp_path / "x.dfsu").write_bytes(b"\x00\x00\x00P" + bytes(300))
    assert not mike.can_open(tmp_path / "x.dfsu")


def test_mixed_elements_values_and_times(tmp_path, rng):
    f = mike.open(write_dfsu(tmp_path / "a.dfsu"))
    n = np.bincount(f.mesh.face_n)
    assert n[3] == 24 and n[4] == 12  # triangles and quadrilaterals kept as they are
    np.testing.assert_array_equal(f.times, [0.0, 1800.0, 3600.0])
    assert f.attrs["time_reference"] == "seconds since 2021-06-01 12:00:00"
    assert f.attrs["projection"] == "UTM-32"
    # element values are the field's face values (float32 in the file)
    h, hu, hv = f.read_snapshot(2)
    eta, u, v = linear(XE, YE, 3600.0)
    np.testing.assert_allclose(h, eta - ZE, atol=1e-6)
    np.testing.assert_allclose(hu / h, u, atol=1e-6)
    # bed = Surface elevation - Total water depth, equal to the mean of the node Z here
    np.testing.assert_allclose(f.bed, ZE, atol=1e-6)
    # the sampler reproduces linear fields from element values
    x, y, t = rng.uniform(0, 12, 400), rng.uniform(0, 8, 400), 2700.0
    s = f.sample(x, y, t)
    eta, u, v = linear(x, y, t)
    assert np.all(s.flag == WET)
    np.testing.assert_allclose(s.eta, eta, atol=1e-5)
    np.testing.assert_allclose(s.u, u, atol=1e-5)
    np.testing.assert_allclose(s.v, v, atol=1e-5)
    np.testing.assert_allclose(s.jacobian, np.broadcast_to([[0.02, -0.01], [0.03, 0.01]],
                                                           (x.size, 2, 2)), atol=1e-5)


def test_surface_elevation_with_bathymetry(tmp_path):
    """No total water depth: depth = Surface elevation - element bathymetry (node Z mean)."""
    f = mike.open(write_dfsu(tmp_path / "a.dfsu", keep=("eta", "u", "v")))
    assert "mean of the element's node Z" in f.attrs["import_notes"]
    h = f.read_snapshot(1)[0]
    np.testing.assert_allclose(h, linear(XE, YE, 1800.0)[0] - ZE, atol=1e-6)


def test_feet_converted(tmp_path):
    items = {"h": mikeio.ItemInfo("Total water depth", E.Water_Depth, U.feet),
             "u": mikeio.ItemInfo("U velocity", E.u_velocity_component, U.feet_per_sec),
             "v": mikeio.ItemInfo("V velocity", E.v_velocity_component, U.feet_per_sec)}
    f = mike.open(write_dfsu(tmp_path / "a.dfsu", keep=("h", "u", "v"), items=items,
                             factor={"h": 1 / 0.3048, "u": 1 / 0.3048, "v": 1 / 0.3048}))
    assert "converted from feet" in f.attrs["import_notes"]
    h, hu, _ = f.read_snapshot(0)
    eta, u, _ = linear(XE, YE, 0.0)
    np.testing.assert_allclose(h, eta - ZE, atol=1e-6)
    np.testing.assert_allclose(hu / h, u, atol=1e-6)


def test_real_mike21_file():
    """HD2D.dfsu (a real MIKE 21 FM result): values as mikeio reads them, dates, projection."""
    p = DATA / "HD2D.dfsu"
    f = mike.open(p)
    ref = mikeio.read(str(p))
    assert f.mesh.n_faces == 884 and f.times.size == 9
    np.testing.assert_array_equal(f.times, np.arange(9) * 9000.0)
    assert f.attrs["time_reference"] == "seconds since 1985-08-06 07:00:00"
    assert f.attrs["projection"] == "UTM-29"
    zb = ref.geometry.element_coordinates[:, 2]
    h, hu, hv = f.read_snapshot(4)
    np.testing.assert_allclose(h, ref["Surface elevation"].values[4] - zb, rtol=1e-12)
    np.testing.assert_allclose(hu, h * ref["U velocity"].values[4], rtol=1e-12)
    np.testing.assert_allclose(f.mesh.face_area.sum(),
                               ref.geometry.get_element_area().sum(), rtol=1e-9)
    text = "\n".join(mike.describe(p))
    assert "884 elements (884 triangles" in text and "9 steps" in text


# ----------------------------------------------------------------------------- bad input
def test_missing_velocity(tmp_path):
    p = write_dfsu(tmp_path / "a.dfsu", keep=("eta", "h"))
    with pytest.raises(FlowFileError, match=r"a.dfsu: no velocity: expected items "
                                            "'U velocity' and 'V velocity'"):
        mike.open(p)


def test_missing_depth(tmp_path):
    p = write_dfsu(tmp_path / "a.dfsu", keep=("u", "v"))
    with pytest.raises(FlowFileError, match=r"a.dfsu: no depth: expected item 'Total water "
                                            "depth' or 'Surface elevation'"):
        mike.open(p)


def test_wrong_units(tmp_path):
    items = {"u": mikeio.ItemInfo("U velocity", E.u_velocity_component, U.meter_per_day)}
    with pytest.raises(FlowFileError, match=r"a.dfsu: item 'U velocity' \(u\) has units "
                                            "'meter_per_day', not units of velocity"):
        mike.open(write_dfsu(tmp_path / "a.dfsu", items=items))


def test_mapping_to_a_missing_item(tmp_path):
    with pytest.raises(FlowFileError, match=r"item 'Depth' \(given for 'depth'"):
        mike.open(write_dfsu(tmp_path / "a.dfsu"), variables={"depth": "Depth"})


def test_3d_file():
    with pytest.raises(FlowFileError, match=r"basin_3d.dfsu: a Dfsu3DSigma file \(10 layers\); "
                                            "driftlog reads 2D horizontal"):
        mike.open(DATA / "basin_3d.dfsu")


def test_another_format(tmp_path):
    q = tmp_path / "a.dfsu"
    q.write_bytes(b":SERAFIN" + bytes(200))
    with pytest.raises(FlowFileError, match="a.dfsu: not a dfsu file"):
        mike.open(q)
    # a DHI DFS file that is not a dfsu: a dfs0 time series
    ds = mikeio.Dataset([mikeio.DataArray(np.arange(3.0), time=TIMES,
                                          item=mikeio.ItemInfo("WL", E.Water_Level))])
    ds.to_dfs(str(tmp_path / "wl.dfs0"))
    (tmp_path / "wl.dfsu").write_bytes((tmp_path / "wl.dfs0").read_bytes())
    with pytest.raises(FlowFileError, match="wl.dfsu: a DHI DFS file but not a dfsu"):
        mike.open(tmp_path / "wl.dfsu")


WGS84 = ('GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,'
         '298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]')


@pytest.mark.parametrize("projection", ["LONG/LAT", WGS84], ids=["long_lat", "wkt_geogcs"])
def test_geographic_projection_refused(tmp_path, projection):
    """A dfsu in longitude/latitude (mikeio's ``is_geo``, or a GEOGCS WKT): refused."""
    nc = GEOM.node_coordinates
    geo = mikeio.spatial.GeometryFM2D(  # the mesh near 10 E, 55 N, 2e-5 degrees per metre
        node_coordinates=np.column_stack([10.0 + 2e-5 * nc[:, 0], 55.0 + 2e-5 * nc[:, 1],
                                          nc[:, 2]]),
        element_table=GEOM.element_table, projection=projection)
    assert geo.is_geo == (projection == "LONG/LAT")
    h = np.ones((TIMES.size, GEOM.n_elements))
    ds = mikeio.Dataset([mikeio.DataArray(h, time=TIMES, geometry=geo, item=ITEMS[k])
                         for k in ("h", "u", "v")])
    p = tmp_path / "geo.dfsu"
    ds.to_dfs(str(p))
    shown = "'LONG/LAT'" if projection == "LONG/LAT" else r"'GEOGCS\[\"GCS_WGS_1984"
    msg = (rf"geo.dfsu: projection = {shown}.*: the coordinates are geographic "
           r"\(longitude/latitude in degrees\); driftlog needs projected coordinates in metres")
    with pytest.raises(FlowFileError, match=msg):
        mike.open(p)
    with pytest.raises(FlowFileError, match=msg):  # driftlog info
        mike.describe(p)
    # the same file in UTM-32 is read (test_mixed_elements_values_and_times)


USFT = 1200.0 / 3937.0  # the US survey foot in metres
PA_SOUTH_FT = (  # EPSG:2272, NAD83 / Pennsylvania South (ftUS), as ESRI WKT (MIKE's form)
    'PROJCS["NAD_1983_StatePlane_Pennsylvania_South_FIPS_3702_Feet",GEOGCS['
    '"GCS_North_American_1983",DATUM["D_North_American_1983",SPHEROID["GRS_1980",6378137.0,'
    '298.257222101]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],'
    'PROJECTION["Lambert_Conformal_Conic"],PARAMETER["False_Easting",1968500.0],'
    'PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",-77.75],'
    'PARAMETER["Standard_Parallel_1",40.9666666666667],PARAMETER["Standard_Parallel_2",'
    '39.9333333333333],PARAMETER["Latitude_Of_Origin",39.3333333333333],'
    'UNIT["US survey foot",0.304800609601219]]')


@pytest.mark.parametrize("z_feet", [False, True], ids=["z_meter", "z_feet"])
def test_projection_in_feet_converted(tmp_path, rng, monkeypatch, z_feet):
    """Node x, y in a State Plane in US survey feet (the projection's unit) and node Z in the
    file's Z unit (mikeio writes meter; MIKE may write feet): read in metres, the same flow as
    the metre file at the same metre positions."""
    nc = GEOM.node_coordinates
    zf = 0.3048 if z_feet else 1.0
    feet = mikeio.spatial.GeometryFM2D(
        node_coordinates=np.column_stack([nc[:, 0] / USFT, nc[:, 1] / USFT, nc[:, 2] / zf]),
        element_table=GEOM.element_table, projection=PA_SOUTH_FT)
    if z_feet:  # as MIKE Zero writes a mesh in feet (mikeio always says meter)
        from mikecore.DfsuBuilder import DfsuBuilder
        from mikecore.eum import eumUnit

        set_z_unit = DfsuBuilder.SetZUnit
        monkeypatch.setattr(DfsuBuilder, "SetZUnit",
                            lambda self, unit: set_z_unit(self, eumUnit.eumUfeet))
    keep = ("eta", "u", "v")  # the bed is the mean of the node Z: Z's unit matters
    f = mike.open(write_dfsu(tmp_path / "ft.dfsu", keep=keep, geometry=feet))
    monkeypatch.undo()
    ref = mike.open(write_dfsu(tmp_path / "m.dfsu", keep=keep))
    np.testing.assert_allclose(f.mesh.node_x, ref.mesh.node_x, rtol=1e-12)
    np.testing.assert_allclose(f.mesh.node_y, ref.mesh.node_y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(f.bed, ref.bed, atol=1e-5)  # float32 node Z
    notes = f.attrs["import_notes"]
    assert "node x, y: converted from the projection's US survey foot to m (x 0.3048006096)" \
        in notes, notes
    assert ("node Z: converted from feet to m (x 0.3048)" in notes) == z_feet, notes
    # the WKT is not the projection of the metre coordinates: kept as crs_wkt, with the factor
    assert "projection" not in f.attrs and f.attrs["crs_wkt"] == PA_SOUTH_FT
    assert f.attrs["crs_note"] == "x, y are the projection's coordinates x 0.3048006096 (metres)"
    x, y, t = rng.uniform(0, 12, 300), rng.uniform(0, 8, 300), 2700.0  # metres
    s, r = f.sample(x, y, t), ref.sample(x, y, t)
    eta, u, v = linear(x, y, t)
    np.testing.assert_allclose(s.u, u, atol=1e-5)
    for k in ("eta", "h", "u", "v", "jacobian"):
        np.testing.assert_allclose(getattr(s, k), getattr(r, k), atol=1e-5)
    assert any("US survey foot, read in metres" in line for line in mike.describe(
        tmp_path / "ft.dfsu"))
    # MIKE's own names (UTM-32 here) are metres: nothing converted (the tests above)
    assert "converted" not in ref.attrs["import_notes"] and ref.attrs["projection"] == "UTM-32"


def test_truncated_file(tmp_path):
    raw = write_dfsu(tmp_path / "a.dfsu").read_bytes()
    (tmp_path / "cut.dfsu").write_bytes(raw[:len(raw) - 200])
    with pytest.raises(FlowFileError, match="cut.dfsu: .*truncated"):
        f = mike.open(tmp_path / "cut.dfsu")
        for i in range(f.times.size):
            f.read_snapshot(i)


def test_no_time_axis(tmp_path):
    """A mesh file (bathymetry, one step, no flow): refused with the items it has."""
    ds = mikeio.Dataset([mikeio.DataArray(ZE[None, :], time=TIMES[:1], geometry=GEOM,
                                          item=mikeio.ItemInfo("Bathymetry", E.Bathymetry))])
    ds.to_dfs(str(tmp_path / "mesh.dfsu"))
    with pytest.raises(FlowFileError, match="mesh.dfsu: no depth.*Bathymetry"):
        mike.open(tmp_path / "mesh.dfsu")


def test_delete_values_read_as_dry(tmp_path):
    """Elements without data (MIKE's delete value; mikeio writes NaN as it) are dry."""
    p = write_dfsu(tmp_path / "a.dfsu")
    ds = mikeio.read(str(p))
    gone = np.zeros(GEOM.n_elements, bool)
    gone[[3, 17, 30]] = True
    for item in ("Surface elevation", "Total water depth", "U velocity", "V velocity"):
        vals = ds[item].values.copy()
        vals[1:, gone] = np.nan  # from the second step on
        ds[item].values[:] = vals
    ds.to_dfs(str(tmp_path / "b.dfsu"))
    f = mike.open(tmp_path / "b.dfsu")
    np.testing.assert_allclose(f.bed, ZE, atol=1e-6)  # the first step has data everywhere
    h, hu, hv = f.read_snapshot(2)
    assert np.all(h[gone] == 0) and np.all(hu[gone] == 0) and np.all(hv[gone] == 0)
    eta, u, v = linear(XE, YE, 3600.0)
    np.testing.assert_allclose(h[~gone], (eta - ZE)[~gone], atol=1e-6)


def test_non_equidistant_times(tmp_path):
    times = pd.DatetimeIndex(["2021-06-01 12:00:00", "2021-06-01 12:10:00",
                              "2021-06-01 13:00:30"])
    f = mike.open(write_dfsu(tmp_path / "a.dfsu", times=times))
    np.testing.assert_array_equal(f.times, [0.0, 600.0, 3630.0])
    h = f.read_snapshot(2)[0]
    np.testing.assert_allclose(h, linear(XE, YE, 3630.0)[0] - ZE, atol=1e-6)
