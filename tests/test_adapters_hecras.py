"""HEC-RAS 2D reader on real HEC-RAS 6.5 files (../shared/data/hecras, see its README).

- Muncie.g05.hdf: a complete geometry (two 2D areas, polygon cells of 3 to 8 sides, cell
  areas, face normals and lengths, cell minimum elevations), no results.
- BaldEagleDamBrk.p18.hdf: the Bald Eagle Creek dam-break plan, trimmed by rashdf's authors:
  geometry of two 2D areas but no `Cells Minimum Elevation` (bed); its time series (37 outputs)
  is in BaldEagleDamBrk.p18.timeseries.hdf.  The bed used for the tracking test is stated
  there: bed = "min_water_surface", the lowest water surface the plan itself reports per cell
  (the bed wherever the cell went dry, above it in the always-wet channel), a documented user
  option, not invented data.
"""

import os

import h5py
import numpy as np
import pytest

from driftlog.errors import FlowFileError

hecras = pytest.importorskip("driftlog.adapters.hecras")

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "hecras")
MUNCIE = os.path.join(DATA, "Muncie.g05.hdf")
PLAN = os.path.join(DATA, "BaldEagleDamBrk.p18.hdf")
SERIES = os.path.join(DATA, "BaldEagleDamBrk.p18.timeseries.hdf")
AREAS = "Geometry/2D Flow Areas"
TS = "Results/Unsteady/Output/Output Blocks/Base Output/Unsteady Time Series"

pytestmark = pytest.mark.skipif(not os.path.isfile(MUNCIE) or not os.path.isfile(SERIES),
                                reason="HEC-RAS data (../shared/data/hecras) not found")
FT = 0.3048  # the international foot: the synthetic files, which name no projection
# the files' own feet, from the last UNIT of their Projection (WKT): State Plane coordinates in
# US survey feet, 2 ppm longer than the international foot (1.1 m at Muncie's y ~ 1.8e6 ft)
MUNCIE_FT = 0.304800609601219  # UNIT["US survey foot",0.304800609601219]
PLAN_FT = 0.3048006096012192  # UNIT["Foot_US",0.3048006096012192]


@pytest.fixture(scope="module")
def muncie():
    return hecras.read_geometry(MUNCIE)


@pytest.fixture(scope="module")
def bald_eagle():
    return hecras.open(PLAN, results=SERIES, bed="min_water_surface")


def _areas(geom):
    starts = zip(geom.cell_start[:-1], geom.cell_start[1:], geom.face_start[:-1],
                 geom.face_start[1:], strict=True)
    return list(zip(geom.areas, starts, strict=True))


def test_muncie_cell_areas_equal_hecras_surface_area(muncie):
    assert muncie.areas == ["2D Interior Area", "Perimeter_NW"]
    assert muncie.n_real == [5271, 519]
    with h5py.File(MUNCIE) as f:
        for name, (c0, c1, _, _) in _areas(muncie):
            ref = f[f"{AREAS}/{name}/Cells Surface Area"][: c1 - c0].astype(float) * MUNCIE_FT ** 2
            # HEC-RAS stores float32: agreement to its round-off, perimeter cells included
            np.testing.assert_allclose(muncie.cell_area[c0:c1], ref, rtol=1e-6)
    # the mesh faces tile the cells exactly (split cells included)
    assert muncie.mesh.face_area.sum() == pytest.approx(muncie.cell_area.sum(), rel=1e-13)
    assert muncie.n_split > 0  # non-convex perimeter cells were split into triangles


def test_muncie_face_normals_and_lengths(muncie):
    with h5py.File(MUNCIE) as f:
        for name, (_, _, f0, f1) in _areas(muncie):
            ref = f[f"{AREAS}/{name}/Faces NormalUnitVector and Length"][()].astype(float)
            np.testing.assert_allclose(muncie.face_normal[f0:f1], ref[:, :2], atol=1e-7)
            np.testing.assert_allclose(muncie.face_length[f0:f1], ref[:, 2] * MUNCIE_FT, rtol=1e-6)
            # HEC-RAS's normal points from the face's cell 0 to its cell 1
            cells = f[f"{AREAS}/{name}/Faces Cell Indexes"][()]
            cc = f[f"{AREAS}/{name}/Cells Center Coordinate"][()] * MUNCIE_FT
            d = cc[cells[:, 1]] - cc[cells[:, 0]]
            assert np.all(np.einsum("ij,ij->i", d, muncie.face_normal[f0:f1]) > 0)


def test_muncie_polygons_of_3_to_8_sides(muncie):
    mesh = muncie.mesh
    assert set(np.unique(mesh.face_n)) <= set(range(3, 9))
    assert mesh.face_n.max() == 8 and np.any(mesh.face_n > 4)
    with h5py.File(MUNCIE) as f:
        name, (c0, c1, _, _) = _areas(muncie)[0]
        cfp = f[f"{AREAS}/{name}/Cells FacePoint Indexes"][: c1 - c0]
        fp = f[f"{AREAS}/{name}/FacePoints Coordinate"][()] * MUNCIE_FT
        perim = f[f"{AREAS}/{name}/Faces Perimeter Info"][()][:, 1] > 0
        vals = f[f"{AREAS}/{name}/Cells Face and Orientation Values"][()][:, 0]
        info = f[f"{AREAS}/{name}/Cells Face and Orientation Info"][: c1 - c0]
    # interior cells (no perimeter face) are one mesh face with HEC-RAS's face points, in order
    whole = np.bincount(muncie.cell_of_face, minlength=muncie.n_cells) == 1
    checked = 0
    for c in np.flatnonzero(whole[c0:c1])[:400]:
        if perim[vals[info[c, 0]:info[c, 0] + info[c, 1]]].any():
            continue
        f_ = int(np.flatnonzero(muncie.cell_of_face == c)[0])
        nodes = mesh.face_nodes[f_, :mesh.face_n[f_]]
        ref = cfp[c][cfp[c] >= 0]
        np.testing.assert_array_equal(mesh.node_x[nodes], fp[ref, 0])
        np.testing.assert_array_equal(mesh.node_y[nodes], fp[ref, 1])
        checked += 1
    assert checked > 300


def test_feet_are_the_projections_own(muncie):
    """US Customary coordinates are converted with the foot of the file's Projection (WKT):
    these State Plane projections are in US survey feet, and the international foot (0.3048
    m) put every point of Muncie 1.1 m off (2 ppm of y ~ 1.8e6 ft), logs and obstacles placed
    from GIS data in the wrong cell."""
    assert muncie.length_factor == MUNCIE_FT
    with h5py.File(MUNCIE) as f:
        fp = np.concatenate([f[f"{AREAS}/{name}/FacePoints Coordinate"][()]
                             for name in muncie.areas])
    y = muncie.mesh.node_y  # the face points (and perimeter points) in metres
    assert np.isin(fp[:, 1] * MUNCIE_FT, y).mean() > 0.9
    assert not np.isin(fp[:, 1] * FT, y).any()
    assert y.max() - y.max() / MUNCIE_FT * FT > 1.0  # metres: what the other foot made of it
    notes = muncie.attrs["import_notes"]
    assert "0.304800609601219 m, the US survey foot of the Projection's UNIT['US survey " \
        "foot']" in notes
    assert "x 0.304800609601219 (metres; 1 ft = 0.304800609601219 m, the US survey foot" \
        in muncie.attrs["crs_note"]
    assert "US survey foot" in hecras.describe(MUNCIE)[0]
    plan = hecras.read_geometry(PLAN)
    assert plan.length_factor == PLAN_FT and "UNIT['Foot_US']" in plan.attrs["import_notes"]


def test_projection_unit_of_wkt():
    from driftlog.adapters._hecras_geometry import projection_unit

    assert projection_unit('PROJCRS["x",BASEGEOGCRS["y",ANGLEUNIT["degree",0.0174532925199433]]'
                           ',CS[Cartesian,2],LENGTHUNIT["US survey foot",0.304800609601219]]') \
        == ("US survey foot", 0.304800609601219)
    assert projection_unit('GEOGCS["x",UNIT["Degree",0.0174532925199433]]') is None
    assert projection_unit('PROJCS["a",GEOGCS["b",UNIT["Degree",0.01745]],UNIT["Meter",1.0]]') \
        == ("Meter", 1.0)
    assert projection_unit("") is None


@pytest.mark.parametrize("path", [MUNCIE, PLAN])
def test_uniform_flow_is_reconstructed_to_round_off(path):
    geom = hecras.read_geometry(path)
    for U, V in ((1.3, -0.4), (-2.0, 0.7)):
        vn = geom.face_normal @ np.array([U, V])
        u, v = geom.cell_velocity(vn)
        assert np.abs(u - U).max() < 1e-13 and np.abs(v - V).max() < 1e-13


def test_linear_flow_reconstruction_is_first_order(muncie):
    """A linear field is not exact (one vector per cell) but close: error O(cell size)."""
    mesh, g = muncie.mesh, muncie
    with h5py.File(MUNCIE) as f:
        mids = []
        for name, _ in _areas(g):
            fp = f[f"{AREAS}/{name}/FacePoints Coordinate"][()] * MUNCIE_FT
            ffp = f[f"{AREAS}/{name}/Faces FacePoint Indexes"][()]
            mids.append(0.5 * (fp[ffp[:, 0]] + fp[ffp[:, 1]]))
    mid = np.concatenate(mids)
    x0 = mesh.node_x.mean()
    k = 1e-3  # 1/s
    vn = g.face_normal[:, 0] * k * (mid[:, 0] - x0)
    u, _ = g.cell_velocity(vn)
    cx = np.bincount(g.cell_of_face, mesh.face_area * mesh.face_x, g.n_cells) / g.cell_area
    size = np.sqrt(g.cell_area)
    assert np.all(np.abs(u - k * (cx - x0)) <= k * size)


def test_bald_eagle_time_series(bald_eagle):
    fl = bald_eagle
    assert fl.times.size == 37
    np.testing.assert_array_equal(np.diff(fl.times), 7200.0)
    assert fl.times[0] == 0.0
    assert fl.attrs["time_reference"] == "seconds since 1999-01-01T12:00:00"
    assert "Pennsylvania" in fl.attrs["crs_wkt"]
    assert fl.attrs["hecras_areas"] == "BaldEagleCr, Upper 2D Area"
    assert "min_water_surface" in fl.attrs["hecras_bed"]
    g = fl.source.geom
    assert g.n_real == [3359, 1066] and g.n_cells == 3359 + 1066
    # depth = water surface - bed, in SI, on every mesh face of the cell
    with h5py.File(SERIES) as f:
        ws = np.concatenate([f[f"{TS}/2D Flow Areas/BaldEagleCr/Water Surface"][20, :3359],
                             f[f"{TS}/2D Flow Areas/Upper 2D Area/Water Surface"][20, :1066]])
    ws = ws.astype(float)
    h, hu, hv = fl.read_snapshot(20)
    bed_cells = np.zeros(g.n_cells)
    bed_cells[g.cell_of_face] = fl.bed
    np.testing.assert_allclose(h, np.maximum(ws * PLAN_FT - bed_cells, 0)[g.cell_of_face],
                               atol=1e-9)
    assert h.max() > 5.0  # the dam-break flood
    # the bed is the lowest water surface: no snapshot goes below it
    for i in (0, 18, 36):
        assert fl.read_snapshot(i)[0].min() >= 0.0


def test_areas_option_reads_one_area():
    fl = hecras.open(PLAN, results=SERIES, bed="min_water_surface", areas="Upper 2D Area")
    g = fl.source.geom
    assert g.areas == ["Upper 2D Area"] and g.n_cells == 1066
    full = hecras.read_geometry(PLAN)
    u, v = g.cell_velocity(np.ones(g.face_normal.shape[0]))
    uf, vf = full.cell_velocity(np.r_[np.zeros(full.face_start[1]), np.ones(2286)])
    np.testing.assert_allclose(u, uf[3359:], atol=1e-12)
    np.testing.assert_allclose(v, vf[3359:], atol=1e-12)


def test_log_released_in_the_channel_moves_downstream(bald_eagle, tmp_path):
    """A log released in Bald Eagle Creek during the flood drifts down the valley.

    Downstream is measured with HEC-RAS's own summary Maximum Water Surface of the cells the
    log crosses: the flood's peak water surface falls along the valley.
    """
    from driftlog.api import track

    fl = bald_eagle
    x0, y0 = 618646.677, 102034.111  # a channel cell of BaldEagleCr
    scen = f"""
title = "Bald Eagle Creek"
[flow]
source = "analytic"
kind = "uniform"
[time]
start = 72000.0
end = 86400.0
output_interval = 1800.0
[[logs]]
seeding = "list"
x = [{x0}]
y = [{y0}]
length = 5.0
radius = 0.2
density = 600.0
[output]
path = "{tmp_path / 'be.nc'}"
"""
    ds = track(scen, flow=fl).dataset()
    x, y, status = ds["x"].values, ds["y"].values, ds["status"].values
    assert x.size == 9 and np.all(status == 1)  # floating throughout
    with h5py.File(PLAN) as f:
        s = "Results/Unsteady/Output/Output Blocks/Base Output/Summary Output/2D Flow Areas"
        peak = np.concatenate([f[f"{s}/BaldEagleCr/Maximum Water Surface"][0, :3359],
                               f[f"{s}/Upper 2D Area/Maximum Water Surface"][0, :1066]]) * PLAN_FT
    cells = fl.source.geom.cell_of_face[fl.sample(x, y, 72000.0).face]
    assert np.hypot(x[-1] - x[0], y[-1] - y[0]) > 2000.0
    assert np.all(np.diff(peak[cells]) <= 0.0) and peak[cells[-1]] < peak[cells[0]] - 1.0


# --------------------------------------------------------------------- bad input
def test_not_a_hecras_file(tmp_path):
    p = tmp_path / "notes.hdf"
    p.write_text("not HDF5")
    with pytest.raises(FlowFileError, match="not a HEC-RAS file"):
        hecras.open(p)
    q = tmp_path / "other.h5"
    with h5py.File(q, "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(FlowFileError, match="not a HEC-RAS 2D file"):
        hecras.open(q)
    assert not hecras.can_open(p) and not hecras.can_open(q)
    assert hecras.can_open(PLAN) and hecras.can_open(MUNCIE)


def test_unknown_area_lists_the_areas():
    with pytest.raises(FlowFileError, match="no 2D flow area named 'Main'.*'BaldEagleCr', "
                                            "'Upper 2D Area'"):
        hecras.open(PLAN, results=SERIES, areas=["Main"])


def test_geometry_file_has_no_results():
    with pytest.raises(FlowFileError, match="no 2D results: a geometry file.*results ="):
        hecras.open(MUNCIE)


def test_missing_bed_says_which_option_to_give():
    with pytest.raises(FlowFileError, match="no bed.*geometry = .*terrain = "):
        hecras.open(PLAN, results=SERIES)
    with pytest.raises(FlowFileError, match="no 2D flow area 'BaldEagleCr'"):
        hecras.open(PLAN, results=SERIES, geometry=MUNCIE)


def test_truncated_file(tmp_path):
    data = open(SERIES, "rb").read()
    p = tmp_path / "cut.hdf"
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(FlowFileError, match="truncated"):
        hecras.open(PLAN, results=p, bed="min_water_surface")


def test_date_stamps():
    assert str(hecras.parse_stamp("01JAN1999 2400")) == "1999-01-02T00:00:00.000"
    assert str(hecras.parse_stamp(b"05Feb2024 13:45:07:250")) == "2024-02-05T13:45:07.250"
    with pytest.raises(FlowFileError, match="not understood"):
        hecras.parse_stamp("1999-01-01 00:00")


def test_describe():
    lines = hecras.describe(MUNCIE)
    assert "US Customary" in lines[0] and "'2D Interior Area': 5271 cells" in lines[1]
    assert "37 outputs" in hecras.describe(SERIES)[-1]


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")  # rasterio's own affine use
def test_terrain_bed_is_the_lowest_pixel_in_each_cell(tmp_path, muncie):
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import from_origin

    mesh = muncie.mesh
    x0, y0, x1, y1 = np.asarray(mesh.bounds) / MUNCIE_FT
    res = 10.0  # ft pixels, cells are ~50 ft across
    nx, ny = int((x1 - x0) / res) + 2, int((y1 - y0) / res) + 2
    tr = from_origin(x0 - res, y1 + res, res, res)
    cols, rows = np.meshgrid(np.arange(nx), np.arange(ny))
    px, py = x0 - res + (cols + 0.5) * res, y1 + res - (rows + 0.5) * res
    z = 900.0 + 0.01 * (px - x0) - 0.02 * (py - y0)  # a plane, ft
    p = tmp_path / "terrain.tif"
    with rasterio.open(p, "w", driver="GTiff", width=nx, height=ny, count=1, dtype="float64",
                       transform=tr) as r:
        r.write(z, 1)
    bed = hecras._bed_from_terrain(p, muncie, MUNCIE)
    # on a plane, the lowest pixel centre in a cell lies between the lowest and the highest
    # point of the cell's polygon (nodes), and mostly within one pixel's rise of the lowest
    fn = mesh.face_nodes
    zn = 900.0 + 0.01 * (mesh.node_x / MUNCIE_FT - x0) - 0.02 * (mesh.node_y / MUNCIE_FT - y0)
    zmin = np.where(fn >= 0, zn[np.maximum(fn, 0)], np.inf).min(axis=1)
    zmax = np.where(fn >= 0, zn[np.maximum(fn, 0)], -np.inf).max(axis=1)
    low, high = np.full(muncie.n_cells, np.inf), np.full(muncie.n_cells, -np.inf)
    np.minimum.at(low, muncie.cell_of_face, zmin)
    np.maximum.at(high, muncie.cell_of_face, zmax)
    assert np.all(bed >= low * MUNCIE_FT - 1e-9) and np.all(bed <= high * MUNCIE_FT + 1e-9)
    rise = np.hypot(0.01, 0.02) * res * np.sqrt(2) * MUNCIE_FT
    assert np.mean(bed <= low * MUNCIE_FT + rise) > 0.99


WGS84 = ('GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,'
         '298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]')
GEOGRAPHIC = (r"the coordinates are geographic \(longitude/latitude in degrees\); driftlog "
              "needs projected coordinates in metres")


def test_geographic_projection_refused(tmp_path):
    """A 'Projection' WKT that is a GEOGCS (RAS Mapper set to WGS 84): refused."""
    import shutil

    geo = tmp_path / "Muncie_wgs84.g05.hdf"
    shutil.copy(MUNCIE, geo)
    with h5py.File(geo, "r+") as f:
        f.attrs["Projection"] = np.bytes_(WGS84)
    msg = rf"Muncie_wgs84.g05.hdf: attribute 'Projection' = 'GEOGCS\[.*: {GEOGRAPHIC}"
    with pytest.raises(FlowFileError, match=msg):
        hecras.read_geometry(geo)
    with pytest.raises(FlowFileError, match=msg):  # driftlog info
        hecras.describe(geo)
    plan = tmp_path / "wgs84.p01.hdf"
    _write_plan(plan)
    with h5py.File(plan, "r+") as f:
        f.attrs["Projection"] = np.bytes_(WGS84)
    with pytest.raises(FlowFileError, match=rf"wgs84.p01.hdf: attribute 'Projection'.*"
                                            f"{GEOGRAPHIC}"):
        hecras.open(plan)
    # the same files in a projected CRS (StatePlane feet; none) are read (tests above)


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")  # rasterio's own affine use
def test_terrain_in_geographic_crs_refused(tmp_path, muncie):
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import from_origin

    p = tmp_path / "terrain.tif"
    with rasterio.open(p, "w", driver="GTiff", width=4, height=4, count=1, dtype="float64",
                       transform=from_origin(-85.4, 40.2, 1e-3, 1e-3), crs="EPSG:4326") as r:
        r.write(np.full((4, 4), 280.0), 1)
    with pytest.raises(FlowFileError, match=rf"terrain.tif: CRS = 'EPSG:4326': {GEOGRAPHIC}"):
        hecras._bed_from_terrain(p, muncie, MUNCIE)


def test_import_cli_auto_and_scenario_source(tmp_path, capsys):
    """`driftlog import plan.hdf`, `source = "auto"` and `source = "hecras"` all read it."""
    import netCDF4
    from driftlog.adapters import detect_format

    from driftlog.cli import main
    from driftlog.scenario import load_scenario
    from driftlog.sources import flow_from_scenario

    assert detect_format(PLAN) == "hecras" and detect_format(MUNCIE) == "hecras"
    out = tmp_path / "flow.nc"
    assert main(["import", PLAN, "-o", str(out), "--option", f"results={SERIES}",
                 "--option", "bed=min_water_surface"]) == 0
    assert "  note: US Customary lengths converted to metres with 1 ft = 0.3048006096012192 " \
        "m, the US survey foot of the Projection's UNIT['Foot_US']" in capsys.readouterr().out
    with netCDF4.Dataset(out) as ds:
        assert ds["time"].units == "seconds since 1999-01-01T12:00:00"
        assert ds["time"].size == 37 and "Pennsylvania" in ds.crs_wkt
        assert ds.dimensions["mesh2d_nMax_face_nodes"].size == 8
    # a plan without bed: the error names the options (exit code 2, no traceback)
    assert main(["import", PLAN, "-o", str(tmp_path / "x.nc"), "--option",
                 f"results={SERIES}"]) == 2
    for source in ("auto", "hecras"):
        scen = load_scenario(f"""
[flow]
source = "{source}"
path = "{PLAN}"
[flow.options]
results = "{SERIES}"
bed = "min_water_surface"
areas = ["BaldEagleCr"]
[time]
end = 3600.0
[[logs]]
x = [618646.677]
y = [102034.111]
""")
        fl = flow_from_scenario(scen)
        assert fl.source.geom.areas == ["BaldEagleCr"] and fl.times.size == 37
    with pytest.raises(Exception, match="bed"):
        load_scenario(f"""
[flow]
source = "hecras"
path = "{PLAN}"
[flow.options]
bed = "terrain_please"
[time]
end = 1.0
[[logs]]
x = [0.0]
y = [0.0]
""")


def _write_plan(path, n=6, snapshots=3, with_bed=True, with_results=True, si=True):
    """A small HEC-RAS 6 layout file of one n x n area (SI), as HEC-RAS writes its datasets.

    Water surface = bed + 1 + 0.01 k; face velocities: the normal projection of the linear
    field u = 0.3 + 0.01 y, v = -0.2 (cells' least squares give it at the cell centres).
    """
    nn = n + 1
    X, Y = np.meshgrid(np.arange(nn) * 10.0, np.arange(nn) * 10.0)
    nid = np.arange(nn * nn).reshape(nn, nn)
    h_a, h_b = nid[:, :-1].ravel(), nid[:, 1:].ravel()
    v_a, v_b = nid[:-1, :].ravel(), nid[1:, :].ravel()
    faces = np.column_stack([np.r_[h_a, v_a], np.r_[h_b, v_b]]).astype(np.int32)
    hid = np.arange(h_a.size).reshape(nn, n)
    vid = h_a.size + np.arange(v_a.size).reshape(n, nn)
    cf = np.stack([hid[:-1, :], vid[:, 1:], hid[1:, :], vid[:, :-1]], -1).reshape(-1, 4)
    orient = np.broadcast_to(np.array([1, 1, -1, -1]), cf.shape)
    ncell = n * n
    bed = 50.0 + 0.1 * np.arange(ncell)
    xy = np.column_stack([X.ravel(), Y.ravel()])
    mid = 0.5 * (xy[faces[:, 0]] + xy[faces[:, 1]])
    d = xy[faces[:, 1]] - xy[faces[:, 0]]
    nrm = np.column_stack([d[:, 1], -d[:, 0]]) / 10.0
    with h5py.File(path, "w") as f:
        f.attrs["File Type"] = np.bytes_("HEC-RAS Geometry" if not with_results else
                                          "HEC-RAS Results")
        f.attrs["Units System"] = np.bytes_("SI Units" if si else "US Customary")
        att = np.zeros(1, dtype=[("Name", "S16"), ("Cell Count", "<i4")])
        att["Name"], att["Cell Count"] = b"Main", ncell
        g = f.create_group(AREAS)
        g["Attributes"] = att
        a = g.create_group("Main")
        a["FacePoints Coordinate"] = xy
        a["Faces FacePoint Indexes"] = faces
        a["Cells Face and Orientation Info"] = np.column_stack(
            [np.arange(ncell) * 4, np.full(ncell, 4)]).astype(np.int32)
        a["Cells Face and Orientation Values"] = np.column_stack(
            [cf.ravel(), orient.ravel()]).astype(np.int32)
        if with_bed:
            a["Cells Minimum Elevation"] = bed.astype(np.float32)
        if with_results:
            ts = f.create_group(TS)
            ts["Time Date Stamp (ms)"] = np.array(
                [f"01MAR2024 0{k}:00:00:000" for k in range(snapshots)], dtype="S22")
            r = ts.create_group("2D Flow Areas/Main")
            r["Water Surface"] = np.array([bed + 1.0 + 0.01 * k for k in range(snapshots)],
                                          np.float32)
            u, v = 0.3 + 0.01 * mid[:, 1], np.full(len(mid), -0.2)
            r["Face Velocity"] = np.array([nrm[:, 0] * u + nrm[:, 1] * v] * snapshots,
                                          np.float32)
    return bed


def test_plan_with_its_own_bed_and_a_geometry_file(tmp_path):
    plan = tmp_path / "model.p01.hdf"
    bed = _write_plan(plan)
    fl = hecras.open(plan)
    assert fl.attrs["hecras_bed"] == "Cells Minimum Elevation (plan)"
    assert fl.attrs["time_reference"] == "seconds since 2024-03-01T00:00:00"
    np.testing.assert_array_equal(fl.times, [0.0, 3600.0, 7200.0])
    g = fl.source.geom
    assert g.length_factor == 1.0 and g.mesh.n_faces == 36 and g.n_split == 0
    np.testing.assert_allclose(fl.bed[np.argsort(g.cell_of_face)], bed.astype(np.float32))
    ws, h, u, v = fl.source.cell_arrays(2)
    np.testing.assert_allclose(h, 1.02, atol=1e-5)  # float32 water surface
    # the linear field u = 0.3 + 0.01 y: exact at the centre of these square cells
    cy = np.bincount(g.cell_of_face, g.mesh.face_y, g.n_cells)
    np.testing.assert_allclose(u, 0.3 + 0.01 * cy, atol=1e-6)
    np.testing.assert_allclose(v, -0.2, atol=1e-6)
    # a plan without bed, with its geometry file named: the same flow
    bare = tmp_path / "bare.p01.hdf"
    _write_plan(bare, with_bed=False)
    geo = tmp_path / "model.g01.hdf"
    _write_plan(geo, with_results=False)
    with pytest.raises(FlowFileError, match="no bed"):
        hecras.open(bare)
    fl2 = hecras.open(bare, geometry=geo)
    assert fl2.attrs["hecras_bed"] == f"Cells Minimum Elevation of {geo}"
    np.testing.assert_array_equal(fl2.bed, fl.bed)
    np.testing.assert_array_equal(fl2.read_snapshot(1)[0], fl.read_snapshot(1)[0])
    # a geometry file of another mesh is refused
    other = tmp_path / "other.g01.hdf"
    _write_plan(other, n=5, with_results=False)
    with pytest.raises(FlowFileError, match="has 25 cells, the plan .* has 36"):
        hecras.open(bare, geometry=other)
    # US Customary: lengths and velocities in feet are converted
    us = tmp_path / "us.p01.hdf"
    _write_plan(us, si=False)
    flu = hecras.open(us)
    np.testing.assert_allclose(flu.mesh.face_area, fl.mesh.face_area * FT ** 2, rtol=1e-12)
    np.testing.assert_allclose(flu.read_snapshot(0)[1], fl.read_snapshot(0)[1] * FT ** 2,
                               rtol=1e-6)
    # the foot: the international one without a foot in the Projection, else the Projection's
    assert "the international foot (the file names no projection unit)" in \
        flu.attrs["import_notes"]
    flu.source.close()
    for wkt, factor, words in (
            ('PROJCS["p",GEOGCS["g",UNIT["Degree",0.0174532925199433]],UNIT["Meter",1.0]]',
             FT, "the Projection's unit 'Meter' (1.0 m) is not a foot"),
            ('PROJCS["p",GEOGCS["g",UNIT["Degree",0.0174532925199433]],'
             'UNIT["Foot_US",0.3048006096012192]]', PLAN_FT, "the US survey foot"),
            ('PROJCS["p",GEOGCS["g",UNIT["Degree",0.0174532925199433]],UNIT["Foot",0.3048]]',
             FT, "the international foot of the Projection's UNIT['Foot']")):
        with h5py.File(us, "a") as f:
            f.attrs["Projection"] = np.bytes_(wkt)
        g = hecras.read_geometry(us)
        assert g.length_factor == factor and words in g.attrs["import_notes"], g.attrs
        np.testing.assert_allclose(g.mesh.node_x.max(), 60.0 * factor, rtol=1e-15)
