"""TELEMAC Selafin reader (adapters/selafin.py): files written with xarray-selafin itself."""

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("xarray_selafin")
import xarray_selafin.xarray_backend  # noqa: E402,F401
from driftlog.adapters import selafin  # noqa: E402

from driftlog.errors import FlowFileError  # noqa: E402
from driftlog.flow import WET  # noqa: E402
from driftlog.mesh import Mesh  # noqa: E402

ENGLISH = {"H": ("WATER DEPTH", "M"), "U": ("VELOCITY U", "M/S"), "V": ("VELOCITY V", "M/S"),
           "B": ("BOTTOM", "M"), "S": ("FREE SURFACE", "M")}
FRENCH = {"H": ("HAUTEUR D'EAU", "M"), "U": ("VITESSE U", "M/S"), "V": ("VITESSE V", "M/S"),
          "B": ("FOND", "M"), "S": ("SURFACE LIBRE", "M")}
TIMES = np.array([0.0, 60.0, 120.0])


def _mesh():
    g = Mesh.regular_grid(8, 5, 2.0)
    tri = np.vstack([g.face_nodes[:, [0, 1, 2]], g.face_nodes[:, [0, 2, 3]]])
    x, y = g.node_x.copy(), g.node_y.copy()
    inner = (x > 0) & (x < 16) & (y > 0) & (y < 10)
    r = np.random.default_rng(3)
    x[inner] += r.uniform(-0.3, 0.3, inner.sum())
    y[inner] += r.uniform(-0.3, 0.3, inner.sum())
    return Mesh(x, y, tri)


MESH = _mesh()


def linear(x, y, t):
    """Depth, velocity and bed linear in x, y, t."""
    return (1.0 + 0.05 * x - 0.02 * y + 1e-3 * t, 0.4 + 0.03 * x + 0.01 * y - 1e-3 * t,
            -0.1 + 0.02 * x - 0.04 * y + 2e-3 * t, -2.0 + 0.01 * x + 0.02 * y)


def write_slf(path, names=ENGLISH, keep=("H", "U", "V", "B", "S"), float_size=8, units=None,
              date=(2024, 3, 1, 6, 0, 0), times=TIMES, values=None, planes=0):
    """A Selafin file of the linear field on MESH, written with xarray-selafin."""
    x, y = MESH.node_x, MESH.node_y
    data = {}
    for t in times:
        h, u, v, b = linear(x, y, t) if values is None else values(x, y, t)
        for k, a in (("H", h), ("U", u), ("V", v), ("B", b), ("S", h + b), ("I", h * u),
                     ("J", h * v)):
            data.setdefault(k, []).append(a)
    dims = ("time", "node")
    if planes:
        dims = ("time", "plan", "node")
        z = []
        for t in times:
            h, u, v, b = linear(x, y, t)
            z.append(np.array([b + h * k / (planes - 1) for k in range(planes)]))
        data["Z"] = z
        for k in ("U", "V"):  # u varies along the vertical: u (0.5 + s), s in [0, 1]
            data[k] = [np.array([a * (0.5 + k2 / (planes - 1)) for k2 in range(planes)])
                       for a in data[k]]
        names = dict(names, Z=("ELEVATION Z", "M"))
    yy, mo, dd, hh, mi, ss = date
    t0 = np.datetime64(f"{yy:04d}-{mo:02d}-{dd:02d}T{hh:02d}:{mi:02d}:{ss:02d}")
    ds = xr.Dataset({k: (dims, np.array(data[k])) for k in keep},
                    coords={"x": ("node", x), "y": ("node", y),
                            "time": t0 + (np.asarray(times) * 1e6).astype("timedelta64[us]")})
    variables = {k: names[k] for k in keep}
    for k, u in (units or {}).items():
        variables[k] = (variables[k][0], u)
    ds.attrs.update(ikle2=(MESH.face_nodes + 1).astype(np.int32), float_size=float_size,
                    date_start=date, variables=variables)
    ds.selafin.write(str(path))
    return path


def test_can_open_sniffs_the_header(tmp_path):
    p = write_slf(tmp_path / "a.slf")
    assert selafin.can_open(p)
    q = tmp_path / "renamed.bin"
    q.write_bytes(p.read_bytes())
    assert selafin.can_open(q)
    (tmp_path / "b.nc").write_bytes(b"CDF\x01" + bytes(200))
    assert not selafin.can_open(tmp_path / "b.nc")
    assert not selafin.can_open(tmp_path / "missing.slf")


@pytest.mark.parametrize("names", [ENGLISH, FRENCH], ids=["english", "french"])
def test_node_data_sampled_p1_exactly(tmp_path, rng, names):
    f = selafin.open(write_slf(tmp_path / "a.slf", names=names))
    assert f.location == "node" and f.mesh.n_faces == MESH.n_faces
    np.testing.assert_array_equal(f.times, TIMES)
    assert f.attrs["time_reference"] == "seconds since 2024-03-01 06:00:00"
    x, y, t = rng.uniform(0, 16, 500), rng.uniform(0, 10, 500), 75.0
    s = f.sample(x, y, t)
    h, u, v, b = linear(x, y, t)
    assert np.all(s.flag == WET)
    np.testing.assert_allclose(s.h, h, atol=1e-12)
    np.testing.assert_allclose(s.u, u, atol=1e-12)
    np.testing.assert_allclose(s.v, v, atol=1e-12)
    np.testing.assert_allclose(s.eta, h + b, atol=1e-12)
    np.testing.assert_allclose(s.jacobian, np.broadcast_to([[0.03, 0.01], [0.02, -0.04]],
                                                           (x.size, 2, 2)), atol=1e-11)
    np.testing.assert_allclose(s.dudt, np.broadcast_to([-1e-3, 2e-3], (x.size, 2)), atol=1e-13)


def test_single_precision_flowrates_and_depth_from_surface(tmp_path, rng):
    """TELEMAC's default SERAFIN (float32); depth = FREE SURFACE - BOTTOM; velocity from the
    flow rates over the depth."""
    p = write_slf(tmp_path / "a.slf", keep=("S", "B", "I", "J"), float_size=4,
                  names=dict(ENGLISH, I=("FLOWRATE ALONG X", "M2/S"),
                             J=("FLOWRATE ALONG Y", "M2/S")))
    f = selafin.open(p)
    assert f.attrs["precision"] == "single"
    x, y, t = rng.uniform(0, 16, 300), rng.uniform(0, 10, 300), 120.0
    s = f.sample(x, y, t)
    h, u, v, b = linear(x, y, t)
    np.testing.assert_allclose(s.h, h, atol=2e-6)
    np.testing.assert_allclose(s.u, u, atol=1e-5)
    np.testing.assert_allclose(s.eta, h + b, atol=2e-6)
    # the bed from BOTTOM, the face bed the mean of its nodes
    nb = f.node_bed
    np.testing.assert_allclose(nb, linear(MESH.node_x, MESH.node_y, 0)[3], atol=1e-6)


def test_user_mapping_and_unit_conversion(tmp_path):
    p = write_slf(tmp_path / "a.slf", keep=("H", "U", "V", "B"),
                  names=dict(ENGLISH, H=("PROFONDEUR", "CM")))
    with pytest.raises(FlowFileError, match="no depth"):
        selafin.open(p)
    f = selafin.open(p, variables={"depth": "PROFONDEUR"})
    assert "x 0.01" in f.attrs["import_notes"]
    h = f.read_source(0)[0]
    np.testing.assert_allclose(h, 0.01 * linear(MESH.node_x, MESH.node_y, 0)[0], rtol=1e-12)


def test_time_range_keeps_node_location(tmp_path, rng):
    f = selafin.open(write_slf(tmp_path / "a.slf"), time_range=(50, 130))
    np.testing.assert_array_equal(f.times, [60.0, 120.0])
    assert f.location == "node"
    s = f.sample([5.0], [5.0], 100.0)
    assert s.h[0] == pytest.approx(linear(5.0, 5.0, 100.0)[0], abs=1e-12)


def test_3d_file_refused_or_depth_averaged(tmp_path, rng):
    p = write_slf(tmp_path / "r3d.slf", keep=("Z", "U", "V"), planes=5)
    with pytest.raises(FlowFileError, match=r"r3d.slf: a 3D Selafin file .* 5 planes.*"
                                            "depth_average"):
        selafin.open(p)
    f = selafin.open(p, depth_average=True)
    x, y, t = rng.uniform(0, 16, 300), rng.uniform(0, 10, 300), 60.0
    s = f.sample(x, y, t)
    h, u, v, b = linear(x, y, t)
    # u (0.5 + s) averaged over s in [0, 1] (linear: the trapezoidal rule is exact) = u
    np.testing.assert_allclose(s.h, h, atol=1e-12)
    np.testing.assert_allclose(s.u, u, atol=1e-12)
    np.testing.assert_allclose(s.v, v, atol=1e-12)
    np.testing.assert_allclose(f.node_bed, linear(MESH.node_x, MESH.node_y, 0)[3], atol=1e-12)


def test_describe(tmp_path):
    lines = selafin.describe(write_slf(tmp_path / "a.slf", names=FRENCH))
    text = "\n".join(lines)
    assert "TELEMAC Selafin, 2D, double precision" in text
    assert f"{MESH.n_nodes} nodes, {MESH.n_faces} elements of 3 nodes" in text
    assert "3 frames" in text and "HAUTEUR D'EAU [M]" in text


# ----------------------------------------------------------------------------- bad input
def test_missing_velocity(tmp_path):
    p = write_slf(tmp_path / "a.slf", keep=("H", "B"))
    with pytest.raises(FlowFileError, match=r"a.slf: no velocity: expected 'VELOCITY U'"):
        selafin.open(p)


def test_missing_bed(tmp_path):
    p = write_slf(tmp_path / "a.slf", keep=("H", "U", "V"))
    with pytest.raises(FlowFileError, match=r"a.slf: no bed: expected 'BOTTOM'"):
        selafin.open(p)


def test_wrong_units(tmp_path):
    p = write_slf(tmp_path / "a.slf", units={"U": "M"})
    with pytest.raises(FlowFileError, match=r"a.slf: variable 'VELOCITY U' \(u\): units 'M' "
                                            "are not units of velocity"):
        selafin.open(p)


def test_no_time_axis(tmp_path):
    p = write_slf(tmp_path / "a.slf", times=[0.0])
    # keep the header only: a geometry file has no frame
    raw = p.read_bytes()
    import serafin

    with serafin.SerafinReader(str(p), "en") as r:
        r.read_header()
        size = r.header.header_size
    (tmp_path / "geo.slf").write_bytes(raw[:size])
    with pytest.raises(FlowFileError, match="geo.slf: no time frame"):
        selafin.open(tmp_path / "geo.slf")


def test_another_format(tmp_path):
    q = tmp_path / "flow.slf"
    q.write_bytes(b"CDF\x01" + bytes(300))
    with pytest.raises(FlowFileError, match="flow.slf: not a Selafin file"):
        selafin.open(q)
    with pytest.raises(FlowFileError, match="nope.slf: file not found"):
        selafin.open(tmp_path / "nope.slf")


@pytest.mark.parametrize("cut", [40, 5000])
def test_truncated_file(tmp_path, cut):
    p = write_slf(tmp_path / "a.slf")
    raw = p.read_bytes()
    (tmp_path / "cut.slf").write_bytes(raw[:min(cut, len(raw) - 16)] if cut > 100
                                       else raw[:len(raw) - cut])
    with pytest.raises(FlowFileError, match="cut.slf: unreadable Selafin file.*truncated"):
        selafin.open(tmp_path / "cut.slf")


def test_negative_depth(tmp_path):
    def deep_hole(x, y, t):
        h, u, v, b = linear(x, y, t)
        return np.where(x > 10, -0.5, h), u, v, b

    def damp(x, y, t):
        h, u, v, b = linear(x, y, t)
        return np.where(x > 10, -1e-5, h), u, v, b

    f = selafin.open(write_slf(tmp_path / "a.slf", values=deep_hole))
    with pytest.raises(FlowFileError, match=r"a.slf: frame 0 .* depth below -dry_depth"):
        f.sample([1.0], [1.0], 0.0)
    # TELEMAC's tiny negative depths on dry nodes read as 0 (dry)
    g = selafin.open(write_slf(tmp_path / "b.slf", values=damp))
    h = g.read_source(0)[0]
    assert h.min() == 0.0 and np.all(h[MESH.node_x > 10] == 0.0)
