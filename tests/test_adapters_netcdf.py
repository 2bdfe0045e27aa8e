"""NetCDF adapters: UGRID (D-Flow FM), ANUGA .sww, CF grids (LISFLOOD-FP); the registry, the
scenario hook and `driftlog import`.  Fixtures: tests/data (see the scripts there)."""

import json
import shutil
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from driftlog.adapters import detect_format, flow_from_scenario, import_flow, open_flow_source

from driftlog.errors import FlowFileError
from driftlog.flowfile import open_flow

DATA = Path(__file__).parent / "data"
UGRID = DATA / "ugrid" / "dflowfm_map.nc"
GRID = DATA / "cf_grid" / "lisflood.nc"
SWW_C = DATA / "anuga" / "channel_centroids.sww"
SWW_V = DATA / "anuga" / "channel_vertices.sww"


def copy(src, tmp_path, name=None):
    dst = tmp_path / (name or src.name)
    shutil.copy(src, dst)
    return dst


def level(x, y, t):
    return 1 + 1e-4 * t - 0.02 * x + 0.01 * y


# --------------------------------------------------------------------- UGRID / D-Flow FM
def test_dflowfm_map_file(rng):
    f = open_flow_source("auto", UGRID)
    assert detect_format(UGRID) == "ugrid"
    assert f.mesh.n_faces == 15 and sorted(np.bincount(f.mesh.face_n)[3:]) == [6, 9]
    np.testing.assert_allclose(f.times, [0, 600, 1200])
    assert f.attrs["time_origin"] == "2001-01-01 00:00:00"
    assert "depth=mesh2d_waterdepth" in f.attrs["variables"]
    np.testing.assert_allclose(f.bed, -0.5 + 0.1 * f.mesh.face_x, atol=1e-14)
    # the fields are linear: the P1 sampler gives them exactly anywhere, at any time
    x, y = rng.uniform(0, 4, 200), rng.uniform(0, 3, 200)
    for t in (0.0, 450.0, 1200.0):
        s = f.sample(x, y, t)
        np.testing.assert_allclose(s.eta, level(x, y, t), atol=1e-13)
        np.testing.assert_allclose(s.h, level(x, y, t) + 0.5 - 0.1 * x, atol=1e-13)
        np.testing.assert_allclose(s.u, 0.3 + 0.05 * y + 1e-5 * t, atol=1e-13)
        np.testing.assert_allclose(s.v, -0.02 * x, atol=1e-13)
        np.testing.assert_allclose(s.dudt[:, 0], 1e-5, atol=1e-13)


def test_ugrid_level_and_user_names(tmp_path, rng):
    p = copy(UGRID, tmp_path)
    with netCDF4.Dataset(p, "a") as ds:  # no depth variable, other names, bed on nodes only
        ds.renameVariable("mesh2d_waterdepth", "unused")
        ds["unused"].standard_name = "unused"
        ds.renameVariable("mesh2d_s1", "WL")
        ds["WL"].delncattr("standard_name")
        ds.renameVariable("mesh2d_flowelem_bl", "notbed")
        ds["notbed"].standard_name = "unused"
    with pytest.raises(FlowFileError, match="no water depth nor water level"):
        open_flow_source("ugrid", p)
    f = open_flow_source("ugrid", p, variables={"level": "WL"})
    assert "node elevations" in f.attrs["import_notes"]
    x, y = rng.uniform(0.2, 3.8, 50), rng.uniform(0.2, 2.8, 50)
    np.testing.assert_allclose(f.sample(x, y, 600.0).eta, level(x, y, 600.0), atol=1e-13)
    with pytest.raises(FlowFileError, match=r"'nope' \(given for 'level' in \[flow\] "
                                            r"variables\) is missing"):
        open_flow_source("ugrid", p, variables={"level": "nope"})


def test_ugrid_is_read_lazily(monkeypatch):
    from driftlog.adapters._netcdf import FaceSnapshots

    reads = []
    orig = FaceSnapshots.read
    monkeypatch.setattr(FaceSnapshots, "read", lambda self, i: reads.append(i) or orig(self, i))
    f = open_flow_source("ugrid", UGRID)
    assert reads == []
    f.sample([1.0], [1.0], 300.0)
    assert sorted(reads) == [0, 1]
    g = open_flow_source("ugrid", UGRID, time_range=(500, 1300))
    np.testing.assert_allclose(g.times, [600, 1200])
    reads.clear()
    g.sample([1.0], [1.0], 1200.0)
    assert sorted(reads) == [1, 2]


def test_ugrid_units_converted_with_a_note_or_refused(tmp_path, rng):
    p = copy(UGRID, tmp_path)
    with netCDF4.Dataset(p, "a") as ds:
        ds["mesh2d_ucx"].units = "cm/s"
        ds["mesh2d_ucx"][:] = ds["mesh2d_ucx"][:] * 100
        ds["mesh2d_waterdepth"].units = "mm"
        ds["mesh2d_waterdepth"][:] = ds["mesh2d_waterdepth"][:] * 1000
    f = open_flow_source("ugrid", p)
    assert "mesh2d_ucx: converted from 'cm/s' to m s-1 (x 0.01)" in f.attrs["import_notes"]
    assert "mesh2d_waterdepth: converted from 'mm' to m" in f.attrs["import_notes"]
    ref = open_flow_source("ugrid", UGRID)
    for k in ("h", "u", "v"):
        np.testing.assert_allclose(f.snapshot(2)[k], ref.snapshot(2)[k], rtol=1e-14)
    f.source.close()  # the lazy source keeps the file open for reading
    with netCDF4.Dataset(p, "a") as ds:  # a US model's export: feet per second
        ds["mesh2d_ucy"].units = "ft s-1"
        ds["mesh2d_ucy"][:] = ds["mesh2d_ucy"][:] / 0.3048
    f = open_flow_source("ugrid", p)
    assert "mesh2d_ucy: converted from 'ft s-1' to m s-1 (x 0.3048)" in f.attrs["import_notes"]
    np.testing.assert_allclose(f.snapshot(2)["v"], ref.snapshot(2)["v"], rtol=1e-13,
                               atol=1e-15)
    f.source.close()
    with netCDF4.Dataset(p, "a") as ds:
        ds["mesh2d_ucy"].units = "furlong fortnight-1"
    with pytest.raises(FlowFileError, match=r"dflowfm_map.nc: mesh2d_ucy: units 'furlong "
                                            r"fortnight-1' are not units of velocity "
                                            r"\(expected m s-1"):
        open_flow_source("ugrid", p)


def test_ugrid_bad_values(tmp_path):
    # fill value in a field: found when that snapshot is read, naming variable and time
    p = copy(UGRID, tmp_path, "fill.nc")
    with netCDF4.Dataset(p, "a") as ds:
        ds["mesh2d_ucy"][1, 3] = -999.0
    f = open_flow_source("ugrid", p)
    f.snapshot(0)
    with pytest.raises(FlowFileError, match=r"mesh2d_ucy at snapshot 1 \(t = 600 s\): 1 fill "
                                            r"value -999.0 values \(first at flat index \[3\]"):
        f.snapshot(1)
    # ... or dry faces, if asked
    g = open_flow_source("ugrid", p, fill="dry")
    assert g.snapshot(1)["hv"][3] == 0.0 and g.snapshot(1)["h"][3] > 0
    # NaN
    p = copy(UGRID, tmp_path, "nan.nc")
    with netCDF4.Dataset(p, "a") as ds:
        ds["mesh2d_waterdepth"][2, 0] = np.nan
    with pytest.raises(FlowFileError, match=r"mesh2d_waterdepth at snapshot 2 .*1 NaN values"):
        open_flow_source("ugrid", p).snapshot(2)
    # times not increasing
    p = copy(UGRID, tmp_path, "times.nc")
    with netCDF4.Dataset(p, "a") as ds:
        ds["time"][:] = [0.0, 600.0, 300.0]
    with pytest.raises(FlowFileError, match=r"times.nc: times not increasing: t\[1\] = 600"):
        open_flow_source("ugrid", p)
    # a mapped variable that is not on the faces
    with pytest.raises(FlowFileError, match=r"'mesh2d_node_z' \(given for 'depth'\) has "
                                            r"dimensions \('mesh2d_nNodes',\)"):
        open_flow_source("ugrid", UGRID, variables={"depth": "mesh2d_node_z"})
    # a missing velocity
    p = copy(UGRID, tmp_path, "novel.nc")
    with netCDF4.Dataset(p, "a") as ds:
        ds.renameVariable("mesh2d_ucy", "something")
        ds["something"].standard_name = "unknown"
    with pytest.raises(FlowFileError, match=r"novel.nc: no velocity \(u, v\) nor unit "
                                            r"discharge \(hu, hv\)"):
        open_flow_source("ugrid", p)


def test_ugrid_layout_errors(tmp_path):
    # a pentagon: unsupported element type
    p = tmp_path / "pent.nc"
    with netCDF4.Dataset(p, "w") as ds:
        ds.createDimension("n", 5)
        ds.createDimension("f", 1)
        ds.createDimension("m", 5)
        ds.createDimension("time", None)
        m = ds.createVariable("mesh2d", "i4")
        m.setncatts(dict(cf_role="mesh_topology", topology_dimension=2,
                         node_coordinates="x y", face_node_connectivity="fn",
                         face_dimension="f"))
        a = 2 * np.pi * np.arange(5) / 5
        ds.createVariable("x", "f8", ("n",))[:] = np.cos(a)
        ds.createVariable("y", "f8", ("n",))[:] = np.sin(a)
        v = ds.createVariable("fn", "i4", ("f", "m"), fill_value=-999)
        v.start_index = 1
        v[:] = [[1, 2, 3, 4, 5]]
    # convex polygons beyond quadrilaterals are read (HEC-RAS-style cells); this file then
    # lacks its data variables
    from driftlog.mesh import read_ugrid_mesh

    assert read_ugrid_mesh(p).face_n.tolist() == [5]
    with pytest.raises(FlowFileError, match=r"pent.nc: unknown layout: no \(time, f\) variables"):
        open_flow_source("ugrid", p)
    # not UGRID at all
    p = tmp_path / "plain.nc"
    with netCDF4.Dataset(p, "w") as ds:
        ds.createDimension("n", 3)
        ds.createVariable("whatever", "f8", ("n",))
    with pytest.raises(FlowFileError, match=r"plain.nc: unknown layout: not a UGRID mesh"):
        open_flow_source("auto", p)
    with pytest.raises(FlowFileError, match="not a UGRID file"):
        open_flow_source("ugrid", p)
    (tmp_path / "junk.nc").write_text("not netcdf")
    with pytest.raises(FlowFileError, match="not a readable NetCDF file"):
        open_flow_source("auto", tmp_path / "junk.nc")


GEOGRAPHIC = ("the coordinates are geographic \\(longitude/latitude in degrees\\); driftlog "
              "needs projected coordinates in metres: reproject")


def spherical(tmp_path, name="spherical.nc", standard_name=True):
    """The D-Flow FM map file as a spherical model writes it: node coordinates in degrees."""
    p = copy(UGRID, tmp_path, name)
    with netCDF4.Dataset(p, "a") as ds:
        for axis, sn in (("x", "longitude"), ("y", "latitude")):
            for loc in ("node", "face"):
                var = ds[f"mesh2d_{loc}_{axis}"]
                var.units = f"degrees_{'east' if axis == 'x' else 'north'}"
                if standard_name:
                    var.standard_name = sn
                else:
                    var.delncattr("standard_name")
    return p


def test_ugrid_geographic_coordinates_refused(tmp_path):
    """A spherical D-Flow FM model (degrees): refused, never read as metres."""
    from driftlog.errors import MeshError
    from driftlog.mesh import read_mesh

    p = spherical(tmp_path)
    msg = rf"spherical.nc: mesh2d_node_x:standard_name = 'longitude': {GEOGRAPHIC}"
    for kind in ("auto", "ugrid"):
        with pytest.raises(FlowFileError, match=msg):
            open_flow_source(kind, p)
    with pytest.raises(MeshError, match=msg):  # as a mesh file (a solver's mesh_file)
        read_mesh(p)
    q = spherical(tmp_path, "units_only.nc", standard_name=False)
    with pytest.raises(FlowFileError, match=r"units_only.nc: mesh2d_node_x:units = "
                                            rf"'degrees_east': {GEOGRAPHIC}"):
        open_flow_source("ugrid", q)
    # the same file in metres (projection_x_coordinate, m) is read (test_dflowfm_map_file)
    assert open_flow_source("ugrid", UGRID).mesh.n_faces == 15


@pytest.mark.parametrize("units, factor", [("km", 1e3), ("ft", 0.3048),
                                           ("US_survey_foot", 1200.0 / 3937.0)])
def test_ugrid_node_coordinates_in_other_units_converted(tmp_path, rng, units, factor):
    """Node x, y (and node z) in km or feet: converted to metres, with a note; the same flow
    as the metre file at the same metre positions (values, gradients, bed)."""
    from driftlog.mesh import read_mesh

    p = copy(UGRID, tmp_path, "other_units.nc")
    with netCDF4.Dataset(p, "a") as ds:
        for name in ("mesh2d_node_x", "mesh2d_node_y", "mesh2d_node_z"):
            ds[name][:] = ds[name][:] / factor
            ds[name].units = units
    ref = open_flow_source("ugrid", UGRID)
    f = open_flow_source("ugrid", p)
    np.testing.assert_allclose(f.mesh.node_x, ref.mesh.node_x, rtol=1e-14, atol=1e-13)
    np.testing.assert_allclose(f.mesh.node_y, ref.mesh.node_y, rtol=1e-14, atol=1e-13)
    np.testing.assert_allclose(f.mesh.node_z, ref.mesh.node_z, rtol=1e-14, atol=1e-13)
    np.testing.assert_allclose(f.mesh.face_area, ref.mesh.face_area, rtol=1e-12)
    notes = f.attrs["import_notes"]
    for name in ("mesh2d_node_x", "mesh2d_node_y", "mesh2d_node_z"):
        assert f"{name}: converted from {units!r} to m (x {factor:.10g})" in notes, notes
    x, y = rng.uniform(0, 4, 200), rng.uniform(0, 3, 200)  # metres
    for t in (0.0, 450.0):
        s, r = f.sample(x, y, t), ref.sample(x, y, t)
        np.testing.assert_allclose(s.u, 0.3 + 0.05 * y + 1e-5 * t, atol=1e-12)
        for k in ("h", "eta", "u", "v", "jacobian"):
            np.testing.assert_allclose(getattr(s, k), getattr(r, k), atol=1e-12)
    m = read_mesh(p)  # as a mesh file (a solver's mesh_file): the same conversion
    np.testing.assert_allclose(m.node_x, ref.mesh.node_x, rtol=1e-14, atol=1e-13)


def test_ugrid_node_coordinates_in_unknown_units_refused(tmp_path):
    from driftlog.errors import MeshError
    from driftlog.mesh import read_mesh

    p = copy(UGRID, tmp_path, "furlong.nc")
    with netCDF4.Dataset(p, "a") as ds:
        ds["mesh2d_node_y"].units = "furlong"
    msg = (r"furlong.nc: mesh2d_node_y:units = 'furlong': not a unit of length driftlog knows "
           r"\(m, km, cm, mm, ft, US_survey_foot\); driftlog reads lengths in metres")
    with pytest.raises(FlowFileError, match=msg):
        open_flow_source("ugrid", p)
    with pytest.raises(MeshError, match=msg):
        read_mesh(p)


def test_cli_refuses_geographic_coordinates(tmp_path, capsys):
    """`driftlog import`, `driftlog info` and a scenario's [flow]: the message, status 2."""
    from driftlog.cli import main

    p = spherical(tmp_path)
    scen = tmp_path / "scenario.toml"
    scen.write_text(f"""
[flow]
source = "ugrid"
path = "{p}"
[time]
end = 600.0
[[logs]]
x = [1.0]
y = [1.0]
""")
    for argv in (["import", str(p), "-o", str(tmp_path / "flow.nc")], ["info", str(p)],
                 ["scenario", "check", str(scen)]):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("driftlog: error: ") and "Traceback" not in err, err
        assert "mesh2d_node_x:standard_name = 'longitude': the coordinates are geographic" \
            in err and "projected coordinates in metres" in err, err
    assert not (tmp_path / "flow.nc").exists()


# --------------------------------------------------------------------- ANUGA
@pytest.mark.parametrize("sww", [SWW_C, SWW_V], ids=["centroids", "vertices"])
def test_anuga_sww(sww):
    """Against ANUGA's own numbers (tests/data/anuga/make_fixtures.py stored them)."""
    ref = json.loads(sww.with_suffix(".json").read_text())
    f = open_flow_source("auto", sww)
    assert detect_format(sww) == "anuga"
    assert f.mesh.n_faces == 64 and f.mesh.face_n.max() == 3
    assert f.mesh.n_nodes == 43  # unique vertices merged: the mesh is connected
    np.testing.assert_allclose(f.times, ref["time"])
    # absolute coordinates: x, y + (xllcorner, yllcorner)
    face = f.mesh.locate(np.array(ref["centroid_x"]), np.array(ref["centroid_y"]))
    assert np.all(face >= 0) and np.unique(face).size == 64
    np.testing.assert_allclose(f.mesh.face_x[face], ref["centroid_x"], atol=1e-6)
    np.testing.assert_allclose(f.mesh.face_area[face], ref["area"], rtol=1e-6)
    # the water volume ANUGA reports at each time (float32 storage)
    for i, vol in enumerate(ref["water_volume"]):
        np.testing.assert_allclose(np.sum(f.snapshot(i)["h"] * f.mesh.face_area), vol,
                                   rtol=1e-6)
    s = f.snapshot(4)
    np.testing.assert_allclose(s["eta"][face], ref["stage"], atol=1e-6)
    np.testing.assert_allclose(f.bed[face], ref["elevation"], atol=1e-6)
    if sww == SWW_C:
        np.testing.assert_allclose(s["hu"][face], ref["xmomentum"], atol=1e-6)
        np.testing.assert_allclose(s["hv"][face], ref["ymomentum"], atol=1e-6)
    else:  # vertex momenta are products of reconstructed h and u: their mean is close
        np.testing.assert_allclose(s["hu"][face], ref["xmomentum"], atol=2e-3)


def test_anuga_options_and_errors(tmp_path):
    a = open_flow_source("anuga", SWW_C, use_centroids=False)
    assert "vertex values" in a.attrs["import_notes"]
    with pytest.raises(FlowFileError, match="no centroid values"):
        open_flow_source("anuga", SWW_V, use_centroids=True)
    np.testing.assert_allclose(open_flow_source("anuga", SWW_C, time_range=(1, 3)).times,
                               [1, 2, 3])
    p = copy(SWW_C, tmp_path)
    with netCDF4.Dataset(p, "a") as ds:
        ds.renameVariable("xmomentum", "xmom")
    with pytest.raises(FlowFileError, match=r"variables \['xmomentum'\] are missing"):
        open_flow_source("anuga", p)
    p = copy(SWW_C, tmp_path, "degrees.sww")  # ANUGA's georeference: units 'm' (UTM)
    with netCDF4.Dataset(p, "a") as ds:
        ds.units = "degrees"
    with pytest.raises(FlowFileError, match=rf"degrees.sww: global attribute 'units' = "
                                            rf"'degrees': {GEOGRAPHIC}"):
        open_flow_source("anuga", p)
    p = copy(SWW_C, tmp_path, "nan.sww")
    with netCDF4.Dataset(p, "a") as ds:
        ds["stage_c"][3, 7] = np.nan
    with pytest.raises(FlowFileError, match=r"stage_c at snapshot 3 \(t = 3 s\): 1 NaN"):
        open_flow_source("anuga", p).snapshot(3)


# --------------------------------------------------------------------- CF grids
def test_lisflood_grid_with_staggered_edge_discharges():
    f = open_flow_source("auto", GRID)
    assert detect_format(GRID) == "cf_grid"
    assert f.mesh.n_faces == 24 and f.mesh.grid_shape == (4, 6)
    np.testing.assert_allclose(f.mesh.bounds, (1000, 1000, 1060, 1040))
    np.testing.assert_allclose(f.times, [0, 1800, 3600])
    xr, yr = f.mesh.face_x - 1000, f.mesh.face_y - 1000
    # the raster is north-up (y decreasing): rows were flipped to the mesh's south-to-north
    np.testing.assert_allclose(f.bed, 2 + 0.01 * xr, atol=1e-14)
    s = f.snapshot(1)
    np.testing.assert_allclose(s["h"], 0.5 + 0.001 * xr + 0.05, atol=1e-14)
    # edge discharges (m3/s) averaged to cells and divided by the edge length
    np.testing.assert_allclose(s["hu"], 0.2 + 0.002 * xr, atol=1e-14)
    np.testing.assert_allclose(s["hv"], 0.01 * yr, atol=1e-14)
    assert "staggered on x edges" in f.attrs["import_notes"]


def test_cf_grid_velocities_units_and_errors(tmp_path):
    p = copy(GRID, tmp_path)
    with netCDF4.Dataset(p, "a") as ds:  # cell-centred velocities in cm/s instead
        h = ds["H"][:]
        for nm, std in (("vx", "sea_water_x_velocity"), ("vy", "sea_water_y_velocity")):
            v = ds.createVariable(nm, "f8", ("time", "y", "x"))
            v.setncatts(dict(units="cm s-1", standard_name=std))
        ds["vx"][:] = 100 * 0.3
        ds["vy"][:] = -100 * 0.1 * np.ones_like(h)
    f = open_flow_source("cf_grid", p, variables={"u": "vx", "v": "vy"})
    np.testing.assert_allclose(f.snapshot(2)["u"], 0.3, rtol=1e-14)
    np.testing.assert_allclose(f.snapshot(2)["v"], -0.1, rtol=1e-14)
    assert "converted from 'cm s-1'" in f.attrs["import_notes"]
    # edge discharges without units: ambiguous, refused; given units: accepted
    p2 = copy(GRID, tmp_path, "nounits.nc")
    with netCDF4.Dataset(p2, "a") as ds:
        ds["Qx"].delncattr("units")
    with pytest.raises(FlowFileError, match=r"'Qx' has no units"):
        open_flow_source("cf_grid", p2)
    g = open_flow_source("cf_grid", p2, units={"hu": "m3 s-1"})
    ref = open_flow_source("cf_grid", GRID).snapshot(0)["hu"]
    np.testing.assert_allclose(g.snapshot(0)["hu"], ref)
    # uneven spacing, geographic coordinates
    p3 = copy(GRID, tmp_path, "uneven.nc")
    with netCDF4.Dataset(p3, "a") as ds:
        x = ds["x"][:]
        x[-1] += 3
        ds["x"][:] = x
    with pytest.raises(FlowFileError, match=r"unknown layout: coordinate 'x' is not evenly "
                                            "spaced"):
        open_flow_source("cf_grid", p3)
    p4 = copy(GRID, tmp_path, "geo.nc")
    with netCDF4.Dataset(p4, "a") as ds:
        ds["x"].units = "degrees_east"
    with pytest.raises(FlowFileError, match=rf"geo.nc: x:units = 'degrees_east': {GEOGRAPHIC}"):
        open_flow_source("cf_grid", p4)
    with netCDF4.Dataset(p4, "a") as ds:
        ds["x"].units = "m"
        ds["y"].standard_name = "latitude"
    with pytest.raises(FlowFileError, match=rf"y:standard_name = 'latitude': {GEOGRAPHIC}"):
        open_flow_source("cf_grid", p4)
    # fill values (cells outside the flood) are an error, or dry if asked
    p5 = copy(GRID, tmp_path, "fill.nc")
    with netCDF4.Dataset(p5, "a") as ds:
        ds["H"][0, 0, 0] = -9999.0
    with pytest.raises(FlowFileError, match=r"H at snapshot 0 \(t = 0 s\): 1 fill value"):
        open_flow_source("cf_grid", p5).snapshot(0)
    d = open_flow_source("cf_grid", p5, fill="dry").snapshot(0)
    assert d["h"][18] == 0.0 and d["hu"][18] == 0.0  # north-west cell: last row, first column
    # no bed
    p6 = copy(GRID, tmp_path, "nobed.nc")
    with netCDF4.Dataset(p6, "a") as ds:
        ds.renameVariable("DEM", "thing")
        ds["thing"].standard_name = "unknown"
    with pytest.raises(FlowFileError, match="no bed elevation"):
        open_flow_source("cf_grid", p6)


# --------------------------------------------------------------------- registry, scenario, CLI
def test_cf_grid_coordinates_in_feet_converted(tmp_path, rng):
    """x, y in ft (the length table the UGRID mesh reader shares): converted, edge discharges
    divided by edge lengths in metres, the same flow at the same metre positions."""
    p = copy(GRID, tmp_path, "feet.nc")
    with netCDF4.Dataset(p, "a") as ds:
        for n in ("x", "y"):
            ds[n][:] = ds[n][:] / 0.3048
            ds[n].units = "ft"
    f, ref = open_flow_source("cf_grid", p), open_flow_source("cf_grid", GRID)
    np.testing.assert_allclose(f.grid, ref.grid, rtol=1e-12)
    assert "x: converted from 'ft' to m (x 0.3048)" in f.attrs["import_notes"]
    nx, ny, x0, y0, dx, dy = ref.grid
    x, y = x0 + nx * dx * rng.random(100), y0 + ny * dy * rng.random(100)
    for k in ("h", "u", "v"):
        np.testing.assert_allclose(getattr(f.sample(x, y, 1800.0), k),
                                   getattr(ref.sample(x, y, 1800.0), k), atol=1e-12)


def test_open_flow_source_errors(tmp_path):
    with pytest.raises(FlowFileError, match="format 'hdf' unknown"):
        open_flow_source("hdf", UGRID)
    with pytest.raises(FlowFileError, match=r"options \['decomposed'\] do not apply to 'ugrid'"):
        open_flow_source("ugrid", UGRID, decomposed=True)
    with pytest.raises(FlowFileError, match="not found"):
        open_flow_source("auto", tmp_path / "missing.nc")
    with pytest.raises(FlowFileError, match="no snapshot in the time range"):
        open_flow_source("ugrid", UGRID, time_range=(5000, 6000))
    (tmp_path / "d").mkdir()
    with pytest.raises(FlowFileError, match="not an OpenFOAM case"):
        open_flow_source("auto", tmp_path / "d")


def test_import_round_trip_and_scenario(tmp_path, rng):
    from driftlog.scenario import load_scenario

    for src in (UGRID, GRID, SWW_C):
        out, field = import_flow(src, tmp_path / f"{src.stem}.nc", keep_open=True)
        g = open_flow(out)
        assert detect_format(out) == "file"
        np.testing.assert_array_equal(g.times, field.times)
        np.testing.assert_array_equal(g.bed, field.bed)
        for i in range(g.times.size):
            a, b = g.snapshot(i), field.snapshot(i)
            for k in ("h", "u", "v"):
                np.testing.assert_allclose(a[k], b[k], rtol=1e-15, atol=1e-300)
        assert g.attrs["imported_from"].endswith(src.name)
    toml = f"""
[flow]
source = "ugrid"
path = "{UGRID}"
time_range = [500.0, 1300.0]
variables = {{ level = "mesh2d_s1" }}
steady_at = 900.0
"""
    scen = load_scenario(toml)
    f = flow_from_scenario(scen)
    assert f.steady
    x, y = rng.uniform(0, 4, 20), rng.uniform(0, 3, 20)
    np.testing.assert_allclose(f.sample(x, y, 0.0).eta, level(x, y, 900.0), atol=1e-13)
    scen = load_scenario({"flow": {"source": "cf_grid", "path": str(GRID),
                                   "options": {"fill": "dry"}}})
    assert flow_from_scenario(scen).mesh.n_faces == 24
    scen = load_scenario({"flow": {"source": "analytic"}})
    with pytest.raises(FlowFileError, match="'analytic' is not read by driftlog.adapters"):
        flow_from_scenario(scen)


def test_cli_import(tmp_path, capsys):
    from driftlog.cli import main

    out = tmp_path / "flow.nc"
    assert main(["import", str(GRID), "-o", str(out), "--time-range", "1000", "4000"]) == 0
    text = capsys.readouterr().out
    assert "2 snapshots from 1800 to 3600 s" in text and "note: bed from DEM" in text
    np.testing.assert_allclose(open_flow(out).times, [1800, 3600])
    out2 = tmp_path / "flow2.nc"
    assert main(["import", str(UGRID), "-o", str(out2), "--var", "level=mesh2d_s1",
                 "--option", "fill=dry", "--format", "ugrid"]) == 0
    assert open_flow(out2).attrs["variables"] == "u=mesh2d_ucx, v=mesh2d_ucy, level=mesh2d_s1"
    assert main(["import", str(UGRID), "-o", str(out2), "--option", "decomposed=true"]) == 2
    assert "do not apply to 'ugrid'" in capsys.readouterr().err


def test_flow_differences_between_two_sources(mixed_mesh, rng):
    from driftlog.adapters.compare import flow_differences, summarize_differences

    from driftlog.analytic import SolidBodyRotation, UniformFlow, on_mesh

    a = on_mesh(SolidBodyRotation(0.10, center=(3, 2)), mixed_mesh, times=[0.0, 10.0])
    b = on_mesh(SolidBodyRotation(0.12, center=(3, 2)), mixed_mesh, times=[0.0, 10.0])
    x, y = rng.uniform(0.5, 5.5, 100), rng.uniform(0.5, 3.5, 100)
    d = flow_differences(a, b, x, y, 5.0)
    r = np.hypot(x - 3, y - 2)
    ref = SolidBodyRotation(0.10, center=(3, 2)).sample(x, y, 5.0)
    np.testing.assert_allclose(d["speed"], 0.02 * r, atol=1e-12)
    np.testing.assert_allclose(d["velocity"], 0.2 * np.column_stack([ref.u, ref.v]), atol=1e-12)
    np.testing.assert_allclose(d["direction"], 0.0, atol=1e-9)
    s = summarize_differences(d)
    assert s["wet_in_both"] == 100 and s["wet_mismatch"] == 0
    np.testing.assert_allclose(s["speed_max_abs"], 0.02 * r.max(), rtol=1e-9)
    c = on_mesh(UniformFlow(0.0, 1.0), mixed_mesh, times=[0.0, 10.0])
    e = on_mesh(UniformFlow(1.0, 0.0), mixed_mesh, times=[0.0, 10.0])
    np.testing.assert_allclose(flow_differences(c, e, x, y, 1.0)["direction"], -np.pi / 2)


def test_scenario_flow_file_with_a_time_range(tmp_path):
    from driftlog.scenario import load_scenario

    out, _ = import_flow(UGRID, tmp_path / "flow.nc")
    scen = load_scenario({"flow": {"source": "file", "path": str(out),
                                   "time_range": [600.0, 1200.0]}})
    f = flow_from_scenario(scen)
    np.testing.assert_allclose(f.times, [600, 1200])
    np.testing.assert_allclose(f.snapshot(0)["h"], open_flow(out).snapshot(1)["h"])
