"""Raster series: LISFLOOD-FP ASCII results and GeoTIFF series (adapters/raster.py).

The test files are written with rioxarray (GDAL's AAIGrid and GTiff drivers).  The flow is
linear in x, y and t (depth, u, v), so the grid field, bilinear between the cell centres and
linear in time, must give it back exactly between the outermost centres; LISFLOOD's face
velocities (Vx on ncols + 1 faces, Vy on nrows + 1 faces, positive south) averaged to the
cells are exact for a linear field too.
"""

import numpy as np
import pytest

pytest.importorskip("rioxarray")
# rioxarray 0.19 / affine: "Use `@` matmul instead of `*`" (their code, not ours)
pytestmark = pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")
import xarray as xr  # noqa: E402
from driftlog.adapters import detect_format, open_flow_source  # noqa: E402

from driftlog.errors import FlowFileError  # noqa: E402
from driftlog.flowfile import open_flow  # noqa: E402
from driftlog.gridflow import GridFlowField  # noqa: E402

NX, NY, DX, X0, Y0 = 9, 6, 10.0, 1000.0, 5000.0  # lower-left corner (X0, Y0)
SAVEINT, NT = 60.0, 4


def depth(x, y, t):
    return 1.0 + 0.01 * (x - X0) - 0.005 * (y - Y0) + 0.002 * t


def u(x, y, t):
    return 0.3 + 0.004 * (x - X0) - 0.002 * (y - Y0) + 0.001 * t


def v(x, y, t):
    return -0.2 + 0.001 * (x - X0) + 0.003 * (y - Y0) - 0.0005 * t


def bed(x, y):
    return 5.0 - 0.01 * (x - X0) + 0.005 * (y - Y0)


def write(arr, x, y, path, nodata=-9999.0, driver="AAIGrid", crs="EPSG:32631"):
    """A raster with cell centres x (west to east) and y (north to south)."""
    da = xr.DataArray(np.asarray(arr, np.float64), dims=("y", "x"), coords={"x": x, "y": y})
    da = da.rio.write_nodata(nodata)
    da.rio.write_crs(crs, inplace=True)
    da.rio.to_raster(path, driver=driver)
    return path


# cell centres (rows from the north, as rasters store them), faces
XC = X0 + DX * (np.arange(NX) + 0.5)
YC = Y0 + DX * (NY - np.arange(NY) - 0.5)
XF = X0 + DX * np.arange(NX + 1)
YF = Y0 + DX * (NY - np.arange(NY + 1))


def write_lisflood(folder, resroot="res", dem_nodata=None, vy_north=False, with_vy=True):
    folder.mkdir(exist_ok=True)
    X, Y = np.meshgrid(XC, YC)
    dem = bed(X, Y)
    if dem_nodata is not None:
        dem[dem_nodata] = -9999.0
    write(dem, XC, YC, folder / "dem.asc")
    res = folder / "results"
    res.mkdir(exist_ok=True)
    for k in range(NT):
        t = k * SAVEINT
        h = depth(X, Y, t)
        if dem_nodata is not None:
            h[dem_nodata] = -9999.0
        write(h, XC, YC, res / f"{resroot}-{k:04d}.wd")
        # Vx on the ncols + 1 faces of each row (written as a grid shifted by half a cell)
        XFx, YFx = np.meshgrid(XF, YC)
        write(u(XFx, YFx, t), XF, YC, res / f"{resroot}-{k:04d}.Vx")
        if with_vy:
            XFy, YFy = np.meshgrid(XC, YF)
            sign = 1.0 if vy_north else -1.0  # LISFLOOD: positive south
            write(sign * v(XFy, YFy, t), XC, YF, res / f"{resroot}-{k:04d}.Vy")
    par = folder / "run.par"
    par.write_text(f"# LISFLOOD-FP parameter file\nDEMfile dem.asc\nresroot {resroot}\n"
                   f"dirroot results\nsim_time {SAVEINT * (NT - 1):g}\n"
                   f"saveint {SAVEINT:g}   # seconds\nvoutput\n")
    return par


def inner(n, rng):
    x = XC[0] + (XC[-1] - XC[0]) * rng.random(n)
    y = YC[-1] + (YC[0] - YC[-1]) * rng.random(n)
    return x, y


def check_linear(field, rng, times=(0.0, 30.0, 95.0, 180.0)):
    x, y = inner(300, rng)
    for t in times:
        s = field.sample(x, y, t)
        assert np.all(s.wet)
        np.testing.assert_allclose(s.h, depth(x, y, t), atol=1e-9)
        np.testing.assert_allclose(s.u, u(x, y, t), atol=1e-9)
        np.testing.assert_allclose(s.v, v(x, y, t), atol=1e-9)
        # derivatives: differences of values stored as ASCII text (about 1e-8 m/s apart)
        np.testing.assert_allclose(s.jacobian[:, 0, 0], 0.004, atol=1e-7)
        np.testing.assert_allclose(s.jacobian[:, 1, 1], 0.003, atol=1e-7)
        np.testing.assert_allclose(s.dudt[:, 0], 0.001, atol=1e-7)
        np.testing.assert_allclose(s.eta, depth(x, y, t) + bed(x, y), atol=1e-9)


def test_lisflood_par_file(tmp_path):
    par = write_lisflood(tmp_path / "run")
    assert detect_format(par) == "raster"
    f = open_flow_source("auto", par)
    assert isinstance(f, GridFlowField)
    assert f.grid == (NX, NY, X0, Y0, DX, DX)
    np.testing.assert_allclose(f.times, SAVEINT * np.arange(NT))
    check_linear(f, np.random.default_rng(1))
    g = open_flow_source("auto", tmp_path / "run")  # the run folder: its .par file
    np.testing.assert_allclose(g.times, f.times)
    notes = f.attrs["import_notes"]
    assert ".Vx on cell faces" in notes and "Vy positive south" in notes
    assert "32631" in f.attrs["crs"]


def test_lisflood_results_folder_with_options(tmp_path):
    write_lisflood(tmp_path / "run", vy_north=True)
    res = tmp_path / "run" / "results"
    with pytest.raises(FlowFileError, match="need the DEM"):
        open_flow_source("raster", res)
    with pytest.raises(FlowFileError, match="interval = SECONDS"):
        open_flow_source("raster", res, dem=str(tmp_path / "run" / "dem.asc"))
    f = open_flow_source("raster", res / "res-0002.wd", dem=str(tmp_path / "run" / "dem.asc"),
                         interval=SAVEINT, vy_positive="north", time_range=(60, 180))
    np.testing.assert_allclose(f.times, [60, 120, 180])
    check_linear(f, np.random.default_rng(2), times=(60.0, 100.0, 180.0))


def test_lisflood_dem_nodata_is_dry_land(tmp_path):
    mask = np.zeros((NY, NX), bool)
    mask[2:4, 5:7] = True  # rows from the north
    par = write_lisflood(tmp_path / "run", dem_nodata=mask)
    f = open_flow_source("raster", par)
    assert "4 nodata DEM cells" in f.attrs["import_notes"]
    snap = f.snapshot(1)
    flat = mask[::-1].ravel()  # the field's rows run from the south
    assert np.all(snap["h"][flat] == 0) and np.all(snap["u"][flat] == 0)
    assert np.all(snap["h"][~flat] > 0)
    # bed there: the nearest valid cell's (no -9999 cliff in the water level)
    assert f.bed.min() > 0
    s = f.sample(np.array([X0 + 60.0]), np.array([Y0 + 30.0]), 60.0)  # centre of a land cell
    assert not s.wet[0] and s.u[0] == 0.0


def test_lisflood_errors(tmp_path):
    par = write_lisflood(tmp_path / "run", with_vy=False)
    with pytest.raises(FlowFileError, match=r"res-0000.wd has no Vy file: run LISFLOOD-FP "
                                            r"with velocity output"):
        open_flow_source("raster", par)
    par = write_lisflood(tmp_path / "neg")
    X, Y = np.meshgrid(XC, YC)
    h = depth(X, Y, 120.0)
    h[1, 2] = -1.0
    write(h, XC, YC, tmp_path / "neg" / "results" / "res-0002.wd")
    f = open_flow_source("raster", par)
    f.snapshot(1)
    with pytest.raises(FlowFileError, match=r"res-0002.wd: negative water depth -1 m at "
                                            r"snapshot 2 \(t = 120 s\)"):
        f.snapshot(2)
    par.write_text("DEMfile dem.asc\nresroot res\ndirroot results\n")
    with pytest.raises(FlowFileError, match="no saveint in the parameter file"):
        open_flow_source("raster", par)
    wrong = tmp_path / "wrong"
    write_lisflood(wrong)
    write(np.zeros((NY, NX + 3)), X0 + DX * (np.arange(NX + 3) + 0.5), YC,
          wrong / "results" / "res-0000.Vx")
    with pytest.raises(FlowFileError, match=r"res-0000.Vx: 6 x 12; the DEM is 6 x 9, so .Vx "
                                            r"must be 6 x 10 \(faces\)"):
        open_flow_source("raster", wrong / "run.par")


def write_geotiff(folder, nodata_cells=None, names=("depth", "u", "v"), times=(0, 60, 120),
                  seconds=1.0):
    """depth_<t>.tif, u_<t>.tif, v_<t>.tif and dem.tif; the flow at t x ``seconds``."""
    folder.mkdir(exist_ok=True)
    X, Y = np.meshgrid(XC, YC)
    write(bed(X, Y), XC, YC, folder / "dem.tif", driver="GTiff")
    for t in times:
        ts = t * seconds
        h = depth(X, Y, ts)
        if nodata_cells is not None:
            h[nodata_cells] = -9999.0
        for name, arr in zip(names, (h, u(X, Y, ts), v(X, Y, ts)), strict=True):
            write(arr, XC, YC, folder / f"{name}_{t:g}.tif", driver="GTiff")
    return folder


def test_geotiff_series(tmp_path):
    folder = write_geotiff(tmp_path / "tif")
    assert detect_format(folder / "depth_60.tif") == "raster"
    f = open_flow_source("raster", folder)
    np.testing.assert_allclose(f.times, [0, 60, 120])
    check_linear(f, np.random.default_rng(3), times=(0.0, 45.0, 120.0))
    # the same series under other names, mapped, times in minutes
    other = write_geotiff(tmp_path / "other", names=("wd", "vel_x", "vel_y"), times=(0, 1, 2),
                          seconds=60.0)
    g = open_flow_source("raster", other, variables={"depth": "wd_*.tif", "u": "vel_x_*.tif",
                                                     "v": "vel_y_*.tif"}, time_units="min")
    np.testing.assert_allclose(g.times, [0, 60, 120])
    check_linear(g, np.random.default_rng(4), times=(0.0, 45.0, 120.0))


def test_geotiff_nodata_dry_or_error(tmp_path):
    cells = np.zeros((NY, NX), bool)
    cells[0, :3] = True
    folder = write_geotiff(tmp_path / "tif", nodata_cells=cells)
    f = open_flow_source("raster", folder)
    snap = f.snapshot(0)
    flat = cells[::-1].ravel()
    assert np.all(snap["h"][flat] == 0) and np.all(snap["u"][flat] == 0)
    g = open_flow_source("raster", folder, fill="error")
    with pytest.raises(FlowFileError, match=r"depth_0.tif: 3 nodata / NaN cells \(first at row "
                                            r"0, column 0\)"):
        g.snapshot(0)


def test_geotiff_errors(tmp_path):
    folder = write_geotiff(tmp_path / "tif")
    (folder / "v_60.tif").unlink()
    with pytest.raises(FlowFileError, match=r"the v rasters \('v_\*.tif': 2 times\) and the "
                                            r"depth rasters \('depth_\*.tif': 3 times\)"):
        open_flow_source("raster", folder)
    (folder / "dem.tif").unlink()
    with pytest.raises(FlowFileError, match="no bed raster"):
        open_flow_source("raster", folder)
    shifted = write_geotiff(tmp_path / "shift")
    X, Y = np.meshgrid(XC, YC)
    write(u(X, Y, 0), XC + 5.0, YC, shifted / "u_0.tif", driver="GTiff")
    with pytest.raises(FlowFileError, match="u_0.tif: not on the grid of dem.tif"):
        open_flow_source("raster", shifted)
    with pytest.raises(FlowFileError, match="no file matches 'x_\\*.tif'"):
        open_flow_source("raster", shifted, variables={"u": "x_*.tif"})


def test_geotiff_in_geographic_crs_refused(tmp_path, capsys):
    """A series in EPSG:4326 (cells in degrees): refused, not read as 1e-4 m cells."""
    from driftlog.cli import main

    folder = tmp_path / "wgs84"
    folder.mkdir()
    lon = 3.0 + 1e-4 * (np.arange(NX) + 0.5)  # ~10 m cells near 3 E, 43 N
    lat = 43.0 + 1e-4 * (NY - np.arange(NY) - 0.5)
    X, Y = np.meshgrid(XC, YC)
    write(bed(X, Y), lon, lat, folder / "dem.tif", driver="GTiff", crs="EPSG:4326")
    for t in (0, 60):
        for name, arr in (("depth", depth(X, Y, t)), ("u", u(X, Y, t)), ("v", v(X, Y, t))):
            write(arr, lon, lat, folder / f"{name}_{t}.tif", driver="GTiff", crs="EPSG:4326")
    msg = (r"dem.tif: CRS = 'EPSG:4326': the coordinates are geographic \(longitude/latitude "
           r"in degrees\); driftlog needs projected coordinates in metres")
    with pytest.raises(FlowFileError, match=msg):
        open_flow_source("raster", folder)
    with pytest.raises(FlowFileError, match=msg):
        open_flow_source("auto", folder / "depth_0.tif")
    assert main(["info", str(folder / "depth_0.tif")]) == 2
    assert "dem.tif: CRS = 'EPSG:4326': the coordinates are geographic" in \
        capsys.readouterr().err
    # the same series in EPSG:32631 is read (test_geotiff_series)


FEET = (r"the coordinates are in US survey foot \(0.3048006096 m\), not metres, and a raster "
        r"does not say the units of its values \(depths, velocities: feet too\?\); driftlog "
        "needs projected coordinates in metres: reproject the rasters to a CRS in metres")


@pytest.mark.parametrize("crs", ["EPSG:2272", "EPSG:6565"])
def test_geotiff_in_feet_crs_refused(tmp_path, capsys, crs):
    """A series in a State Plane in US survey feet: refused (are the depths and velocities in
    feet too? a raster does not say), never read as metres; `driftlog import` says so."""
    from driftlog.cli import main

    folder = tmp_path / "feet"
    folder.mkdir()
    xf, yf = XC / 0.3048006096012192, YC / 0.3048006096012192  # the metre grid, in feet
    X, Y = np.meshgrid(XC, YC)
    write(bed(X, Y), xf, yf, folder / "dem.tif", driver="GTiff", crs=crs)
    for t in (0, 60):
        for name, arr in (("depth", depth(X, Y, t)), ("u", u(X, Y, t)), ("v", v(X, Y, t))):
            write(arr, xf, yf, folder / f"{name}_{t}.tif", driver="GTiff", crs=crs)
    msg = rf"dem.tif: CRS = '{crs}': {FEET}"
    with pytest.raises(FlowFileError, match=msg):
        open_flow_source("raster", folder)
    with pytest.raises(FlowFileError, match=msg):
        open_flow_source("auto", folder / "depth_0.tif")
    out = tmp_path / "flow.nc"
    capsys.readouterr()
    assert main(["import", str(folder / "depth_0.tif"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("driftlog: error: ") and "Traceback" not in err, err
    assert f"dem.tif: CRS = '{crs}': the coordinates are in US survey foot" in err, err
    assert not out.exists()
    # the same series in EPSG:32631 (metres) is read (test_geotiff_series)


def test_lisflood_ascii_with_a_feet_prj_refused(tmp_path):
    """A LISFLOOD-FP run whose DEM's .prj is a State Plane in feet: refused (elevations in
    feet too? LISFLOOD-FP itself takes the cell size as metres)."""
    par = write_lisflood(tmp_path / "run")
    X, Y = np.meshgrid(XC, YC)
    dem = tmp_path / "run" / "dem.asc"
    write(bed(X, Y), XC / 0.3048006096012192, YC / 0.3048006096012192, dem, crs="EPSG:2272")
    assert dem.with_suffix(".prj").is_file()
    with pytest.raises(FlowFileError, match=rf"dem.asc: CRS = .*: {FEET}"):
        open_flow_source("raster", par)


def test_import_and_track_on_a_lisflood_run(tmp_path):
    """`driftlog import` of a LISFLOOD run, and a tracer on it moving with the flow."""
    from driftlog.cli import main
    from driftlog.logs import Logs
    from driftlog.physics import PhysicsOptions
    from driftlog.tracker import StepOptions, Tracker

    par = write_lisflood(tmp_path / "run")
    out = tmp_path / "flow.nc"
    assert main(["import", str(par), "-o", str(out)]) == 0
    back = open_flow(out)
    assert back.mesh.n_faces == NX * NY and back.times.size == NT
    f = open_flow_source("raster", par)
    np.testing.assert_allclose(back.snapshot(2)["u"], f.snapshot(2)["u"], atol=1e-6)
    logs = Logs([X0 + 20.0], [Y0 + 30.0], 0.0, 0.5, 0.05, 500.0)
    Tracker(f, logs, PhysicsOptions(level="tracer"), "rk4", StepOptions(max_step=5.0),
            t_end=60.0, output_interval=60.0).run()
    # u > 0 and v < 0 about the release point: east and south
    assert logs.state[0, 0] > X0 + 30.0 and logs.state[0, 1] < Y0 + 30.0


def test_geotiff_pixel_is_point_is_node_layout(tmp_path):
    """AREA_OR_POINT = Point: the values are point values, the cells' corners; the domain
    ends at the outermost points, and the field is still exact for a linear flow there."""
    folder = tmp_path / "pt"
    folder.mkdir()
    X, Y = np.meshgrid(XC, YC)

    def put(arr, name):
        da = xr.DataArray(arr, dims=("y", "x"), coords={"x": XC, "y": YC})
        da.attrs["AREA_OR_POINT"] = "Point"
        da.rio.to_raster(folder / name, driver="GTiff")

    put(bed(X, Y), "dem.tif")
    for t in (0, 60, 120):
        put(depth(X, Y, t), f"depth_{t}.tif")
        put(u(X, Y, t), f"u_{t}.tif")
        put(v(X, Y, t), f"v_{t}.tif")
    f = open_flow_source("raster", folder)
    assert f.layout == "node" and "AREA_OR_POINT = Point" in f.attrs["import_notes"]
    assert f.mesh.n_faces == (NX - 1) * (NY - 1)
    check_linear(f, np.random.default_rng(5), times=(0.0, 45.0, 120.0))
    s = f.sample(np.array([XC[0] - 1.0, XC[0] + 1.0]), np.array([YC[3], YC[3]]), 30.0)
    assert s.flag.tolist() == [0, 2]  # outside the points' hull; inside
    g = open_flow_source("raster", folder, layout="cell")  # the user says otherwise
    assert g.layout == "cell" and g.mesh.n_faces == NX * NY
