"""OpenFOAM adapter: the file parser alone, then real shallowWaterFoam and interFoam runs."""

import gzip
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from driftlog.adapters import foam_io
from driftlog.adapters.openfoam import open_openfoam
from driftlog.adapters.openfoam_case import (
    foam_available,
    foam_env,
    run_shallow_water,
    write_shallow_water_case,
)

from driftlog.errors import FlowFileError

DATA = Path(__file__).parent / "data" / "openfoam"
needs_foam = pytest.mark.skipif(not foam_available(),
                                reason="OpenFOAM not installed (Debian: apt-get install openfoam)")


def header(cls, fmt="ascii", arch="LSB;label=32;scalar=64"):
    return (f'FoamFile\n{{\n    version 2.0;\n    format {fmt};\n    class {cls};\n'
            f'    arch "{arch}";\n    object x;\n}}\n// * * //\n').encode()


# --------------------------------------------------------------------- parser, no OpenFOAM
def test_ascii_lists_uniform_lists_and_gzip(tmp_path):
    (tmp_path / "owner").write_bytes(header("labelList") + b"5\n(\n0\n0\n1\n2\n2\n)\n")
    np.testing.assert_array_equal(foam_io.read_label_list(tmp_path / "owner"), [0, 0, 1, 2, 2])
    (tmp_path / "u").write_bytes(header("labelList") + b"4{7}\n")
    np.testing.assert_array_equal(foam_io.read_label_list(tmp_path / "u"), [7, 7, 7, 7])
    with gzip.open(tmp_path / "points.gz", "wb") as f:
        f.write(header("vectorField") + b"2 ( (0 1.5 -2e-3) (3 4 5) )")
    np.testing.assert_array_equal(foam_io.read_points(tmp_path / "points"),
                                  [[0, 1.5, -2e-3], [3, 4, 5]])
    (tmp_path / "faces").write_bytes(header("faceList") + b"3\n(\n4(0 1 2 3)\n3(3 2 4)\n"
                                     b"4(5 6 7 8)\n)\n")
    off, lab = foam_io.read_faces(tmp_path / "faces")
    np.testing.assert_array_equal(off, [0, 4, 7, 11])
    np.testing.assert_array_equal(lab, [0, 1, 2, 3, 3, 2, 4, 5, 6, 7, 8])


@pytest.mark.parametrize("label,scalar", [(32, 64), (64, 64), (32, 32)])
def test_binary_lists_follow_the_arch_header(tmp_path, label, scalar):
    li, sc = np.dtype(f"<i{label // 8}"), np.dtype(f"<f{scalar // 8}")
    arch = f"LSB;label={label};scalar={scalar}"
    offsets = np.array([0, 3, 7], li)
    labels = np.array([0, 1, 2, 2, 1, 3, 4], li)
    (tmp_path / "faces").write_bytes(header("faceCompactList", "binary", arch)
                                     + b"\n3\n(" + offsets.tobytes() + b")\n\n7\n("
                                     + labels.tobytes() + b")\n")
    off, lab = foam_io.read_faces(tmp_path / "faces")
    np.testing.assert_array_equal(off, offsets)
    np.testing.assert_array_equal(lab, labels)
    vals = np.array([[0.1, 0.2, 0.0], [1.5, -2.5, 0.0]], sc)
    (tmp_path / "U").write_bytes(header("volVectorField", "binary", arch)
                                 + b"dimensions [0 1 -1 0 0 0 0];\ninternalField nonuniform "
                                   b"List<vector> 2(" + vals.tobytes() + b");\n"
                                 + b"boundaryField { }\n")
    np.testing.assert_array_equal(foam_io.read_internal_field(tmp_path / "U", 2), vals)


def test_field_errors_name_the_file(tmp_path):
    (tmp_path / "h").write_bytes(header("volScalarField") + b"internalField nonuniform "
                                 b"List<scalar> 3(1 2 3);\n")
    with pytest.raises(FlowFileError, match=r"h: list of 3 values where 4 were expected"):
        foam_io.read_internal_field(tmp_path / "h", 4)
    with pytest.raises(FlowFileError, match=r"nope: file not found"):
        foam_io.read_internal_field(tmp_path / "nope", 4)
    (tmp_path / "t").write_bytes(b"just text")
    with pytest.raises(FlowFileError, match="no FoamFile header"):
        foam_io.read_internal_field(tmp_path / "t", 4)
    (tmp_path / "s").write_bytes(header("volSymmTensorField") + b"internalField nonuniform "
                                 b"List<symmTensor> 1((1 2 3 4 5 6));")
    with pytest.raises(FlowFileError, match="List<symmTensor> is not supported"):
        foam_io.read_internal_field(tmp_path / "s", 1)


def test_missing_case_and_case_that_never_ran(tmp_path):
    with pytest.raises(FlowFileError, match="not found"):
        open_openfoam(tmp_path / "nope")
    case = tmp_path / "case"
    shutil.copytree(DATA / "squarebump", case)
    (case / "constant" / "polyMesh").mkdir()
    # initial fields only: the case never ran
    with pytest.raises(FlowFileError, match="never ran"):
        open_openfoam(case)
    shutil.rmtree(case / "0")
    with pytest.raises(FlowFileError, match="no time directories: the case never ran"):
        open_openfoam(case)


# --------------------------------------------------------------------- real runs
def foam(case, *cmd):
    out = subprocess.run(list(cmd) + ["-case", str(case)], env=foam_env(), capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    return out.stdout


@pytest.fixture(scope="module")
def squarebump(tmp_path_factory):
    """The squareBump tutorial, 20 x 20 cells, 1 s: ascii results at 0, 0.2, ..., 1 s."""
    if not foam_available():
        pytest.skip("OpenFOAM not installed (Debian: apt-get install openfoam)")
    case = tmp_path_factory.mktemp("foam") / "squarebump"
    shutil.copytree(DATA / "squarebump", case)
    foam(case, "blockMesh")
    foam(case, "setFields")
    foam(case, "shallowWaterFoam")
    return case


def foam_values(case, time, field):
    """A field's internal values as printed by OpenFOAM's own foamDictionary."""
    out = foam(case, "foamDictionary", f"{case}/{time}/{field}", "-entry", "internalField",
               "-value")
    body = out[out.index("(") + 1:out.rindex(")")]
    return np.fromstring(body.replace("(", " ").replace(")", " "), sep=" ")


@needs_foam
@pytest.mark.openfoam
def test_shallow_water_serial_ascii(squarebump):
    f = open_openfoam(squarebump)
    np.testing.assert_allclose(f.times, [0, 0.2, 0.4, 0.6, 0.8, 1.0])
    assert f.mesh.n_faces == 400 and f.mesh.face_n.min() == 4
    np.testing.assert_allclose(f.mesh.face_area, 0.0025)
    # cell c is face c: blockMesh numbers cells x fastest, as the face centroids show
    np.testing.assert_allclose(f.mesh.face_x[:20], 0.025 + 0.05 * np.arange(20))
    np.testing.assert_allclose(f.mesh.face_y[::20], 0.025 + 0.05 * np.arange(20))
    # the bump of setFields is the bed, from constant/h0
    bump = (np.abs(f.mesh.face_x - 0.5) < 0.05) & (np.abs(f.mesh.face_y - 0.5) < 0.05)
    assert bump.sum() == 4
    np.testing.assert_array_equal(f.bed, np.where(bump, 0.001, 0.0))
    # values equal what OpenFOAM's own foamDictionary prints (to its 6 digits)
    s = f.snapshot(3)
    np.testing.assert_allclose(s["h"], foam_values(squarebump, "0.6", "h"), rtol=5e-6)
    hu = foam_values(squarebump, "0.6", "hU").reshape(-1, 3)
    np.testing.assert_allclose(s["hu"], hu[:, 0], rtol=5e-6, atol=1e-12)
    np.testing.assert_allclose(s["hv"], hu[:, 1], rtol=5e-6, atol=1e-12)
    np.testing.assert_allclose(s["eta"], foam_values(squarebump, "0.6", "hTotal"), rtol=5e-6)
    assert np.ptp(s["h"]) > 1e-5  # the bump disturbs the flow: not a trivial field
    # boundary patches tag the 2D edges
    assert set(f.mesh.tag_names) >= {"sides", "inlet", "outlet"}
    assert f.mesh.edges_with_tag("inlet").size == 20
    np.testing.assert_allclose(f.mesh.edge_x[f.mesh.edges_with_tag("inlet")], 0.0)
    # a time range reads only those snapshots
    g = open_openfoam(squarebump, time_range=(0.3, 0.8))
    np.testing.assert_allclose(g.times, [0.4, 0.6, 0.8])
    np.testing.assert_array_equal(g.snapshot(1)["h"], s["h"])


@needs_foam
@pytest.mark.openfoam
def test_shallow_water_binary_compressed_and_decomposed(squarebump, tmp_path):
    ref = open_openfoam(squarebump)
    # binary, gzip-compressed (foamFormatConvert for the fields; gzip for the mesh)
    case = tmp_path / "binary"
    shutil.copytree(squarebump, case)
    ctl = case / "system" / "controlDict"
    ctl.write_text(re.sub(r"writeFormat\s+\w+;", "writeFormat binary;",
                          re.sub(r"writeCompression\s+\w+;", "writeCompression on;",
                                 ctl.read_text())))
    foam(case, "foamFormatConvert")
    assert b"format      binary" in (case / "1" / "h").read_bytes()[:1000]
    for p in list((case / "constant" / "polyMesh").iterdir()) + list((case / "1").iterdir()):
        if p.is_file():
            p.with_name(p.name + ".gz").write_bytes(gzip.compress(p.read_bytes()))
            p.unlink()
    (case / "constant" / "h0").unlink()  # bed from hTotal - h instead
    f = open_openfoam(case)
    assert "hTotal - h" in f.attrs["import_notes"]
    np.testing.assert_allclose(f.bed, ref.bed, atol=1e-12)
    for i in range(len(f.times)):
        for k in ("h", "hu", "hv"):
            # OpenFOAM's own ascii parse (in foamFormatConvert) is off by 1 ulp at times
            np.testing.assert_allclose(f.snapshot(i)[k], ref.snapshot(i)[k], rtol=4e-16,
                                       atol=0)
    # decomposed: decomposePar splits every written time; read the processors directly
    case = tmp_path / "decomposed"
    shutil.copytree(squarebump, case)
    foam(case, "decomposePar", "-time", "0:")  # v1912 decomposes the start time alone by default
    for t in ("0.2", "0.4", "0.6", "0.8", "1"):
        shutil.rmtree(case / t)
    f = open_openfoam(case)
    assert f.attrs["decomposed"] == 1
    np.testing.assert_allclose(f.mesh.face_x, ref.mesh.face_x)
    np.testing.assert_allclose(f.mesh.face_y, ref.mesh.face_y)
    np.testing.assert_array_equal(f.bed, ref.bed)
    np.testing.assert_array_equal(f.mesh.edge_tag[np.argsort(f.mesh.edge_x * 7 + f.mesh.edge_y)],
                                  ref.mesh.edge_tag[np.argsort(ref.mesh.edge_x * 7
                                                               + ref.mesh.edge_y)])
    for i in (0, 5):
        for k in ("h", "hu", "hv"):
            np.testing.assert_array_equal(f.snapshot(i)[k], ref.snapshot(i)[k])


@needs_foam
@pytest.mark.openfoam
def test_bad_shallow_water_cases(squarebump, tmp_path):
    case = tmp_path / "c"
    shutil.copytree(squarebump, case)
    # a field whose size differs from the mesh
    p = case / "0.4" / "h"
    text = p.read_text()
    p.write_text(text.replace("400\n(", "399\n(").replace("\n0.01\n)", "\n)", 1)
                 if "400\n(" in text else text)
    with pytest.raises(FlowFileError, match=r"0.4/h: list of 399 values where 400"):
        open_openfoam(case).snapshot(2)
    # NaN in a field: found when the snapshot is read, with its time
    p = case / "0.6" / "h"
    lines = p.read_text().splitlines()
    i = lines.index("(", lines.index(next(ln for ln in lines if "internalField" in ln)))
    lines[i + 5] = "nan"
    p.write_text("\n".join(lines))
    with pytest.raises(FlowFileError, match=r"snapshot 3 \(t = 0.6 s\).*non-finite h"):
        open_openfoam(case).snapshot(3)
    # a missing field
    with pytest.raises(FlowFileError, match=r"neither 'hU' nor 'U'"):
        (case / "0.8" / "hU").unlink()
        (case / "0.8" / "U").unlink()
        open_openfoam(case).snapshot(4)


def channel(nx=20, ny=4, dx=0.5):
    from driftlog.mesh import Mesh

    m = Mesh.regular_grid(nx, ny, dx)
    m.tag_boundary("inflow", lambda x, y: x < 1e-9)
    m.tag_boundary("outflow", lambda x, y: x > nx * dx - 1e-9)
    return m


@needs_foam
@pytest.mark.openfoam
def test_driftlog_case_gives_the_discharge_imposed(tmp_path):
    """A channel from rest, 1 m3/s in, level 1 m out: at steady state every cross-section
    carries 1 m3/s and the water is flat (shallowWaterFoam has no friction)."""
    m = channel()
    f = run_shallow_water(tmp_path / "chan", m, depth=1.0, end_time=120, write_interval=40,
                          boundaries={"inflow": {"type": "inflow", "discharge": 1.0},
                                      "outflow": {"type": "outflow", "level": 1.0}})
    np.testing.assert_allclose(f.times, [0, 40, 80, 120])
    s = f.snapshot(3)
    q = (s["hu"].reshape(4, 20) * 0.5).sum(axis=0)  # discharge through each column of cells
    np.testing.assert_allclose(q, 1.0, rtol=2e-3)
    np.testing.assert_allclose(np.abs(s["hv"]).max(), 0.0, atol=1e-4)
    np.testing.assert_allclose(s["eta"], 1.0, atol=1e-3)
    assert f.mesh.edges_with_tag("inflow").size == 4  # tags survive the round trip


@needs_foam
@pytest.mark.openfoam
def test_driftlog_case_triangles_sloping_bed_in_parallel(tmp_path):
    """Triangles, a sloping bed, run on 2 processes: the bed reaches every processor (h0 is
    decomposed), and the decomposed result matches the serial one."""
    from driftlog.mesher import channel_mesh

    m = channel_mesh(4.0, 1.0, 0.25)
    assert m.face_n.max() == 3
    bed = -0.05 * m.face_x
    opts = dict(bed=bed, level=0.5, end_time=2.0, write_interval=1.0,
                boundaries={"inflow": {"type": "inflow", "unit_discharge": 0.2},
                            "outflow": {"type": "outflow", "level": 0.5}})
    serial = run_shallow_water(tmp_path / "serial", m, **opts)
    par = run_shallow_water(tmp_path / "par", m, n_procs=2, **opts)
    assert par.attrs["decomposed"] == 1 and (tmp_path / "par" / "processor1").is_dir()
    np.testing.assert_allclose(serial.bed, bed, atol=1e-15)
    np.testing.assert_allclose(par.bed, bed, atol=1e-15)
    for k in (1, 2):  # hTotal - h written by the parallel solver is the bed we gave
        lvl = par.source.level(k) if hasattr(par.source, "level") else None
        if lvl is not None:
            np.testing.assert_allclose(lvl - par.snapshot(k)["h"], bed, atol=1e-9)
    s, p = serial.snapshot(2), par.snapshot(2)
    np.testing.assert_allclose(p["h"], s["h"], atol=1e-6)
    np.testing.assert_allclose(p["hu"], s["hu"], atol=1e-6)
    # volume: in - out over 2 s balances the change of storage to the solver's accuracy
    assert np.all(s["h"] > 0.4)


@needs_foam
@pytest.mark.openfoam
def test_driftlog_case_errors(tmp_path):
    m = channel()
    with pytest.raises(FlowFileError, match="initial depth must be > 0"):
        write_shallow_water_case(tmp_path / "c", m, bed=np.where(m.face_x > 5, 2.0, 0.0),
                                 level=1.0, boundaries={"inflow": {"type": "wall"},
                                                        "outflow": {"type": "wall"}})
    with pytest.raises(FlowFileError, match="inflow needs 'discharge'"):
        write_shallow_water_case(tmp_path / "c", m, depth=1.0,
                                 boundaries={"inflow": {"type": "inflow"},
                                             "outflow": {"type": "wall"}})
    with pytest.raises(FlowFileError, match="'outflow' has no condition"):
        write_shallow_water_case(tmp_path / "c", m, depth=1.0,
                                 boundaries={"inflow": {"type": "wall"}})


# --------------------------------------------------------------------- interFoam
@pytest.fixture(scope="module")
def dambreak(tmp_path_factory):
    """A water column 0.2 x 0.2 x 0.15 m released in a closed 0.6 x 0.2 x 0.3 m box."""
    if not foam_available():
        pytest.skip("OpenFOAM not installed (Debian: apt-get install openfoam)")
    case = tmp_path_factory.mktemp("foam") / "dambreak3d"
    shutil.copytree(DATA / "dambreak3d", case)
    foam(case, "blockMesh")
    foam(case, "setFields")
    log = foam(case, "interFoam")
    return case, log


@needs_foam
@pytest.mark.openfoam
def test_interfoam_depth_average_on_columns(dambreak):
    case, log = dambreak
    f = open_openfoam(case)
    assert f.mesh.n_faces == 12 * 4
    np.testing.assert_allclose(f.times, [0, 0.1, 0.2])
    np.testing.assert_allclose(f.bed, 0.0)
    dz, area = 0.05, 0.05 * 0.05
    # the water volume interFoam reports (phase fraction x domain volume) at the last step
    frac = float(re.findall(r"Phase-1 volume fraction = ([0-9.e+-]+)", log)[-1])
    for i, t in enumerate(f.times):
        s = f.snapshot(i)
        alpha = foam_io.read_internal_field(case / f"{t:g}" / "alpha.water", 288)
        u = foam_io.read_internal_field(case / f"{t:g}" / "U", 288)
        # blockMesh numbers cells x fastest, then y, then z: columns are sums over z
        np.testing.assert_allclose(s["h"], np.maximum(alpha.reshape(6, 48).sum(0), 0) * dz,
                                   atol=1e-14)
        np.testing.assert_allclose(s["hu"], (alpha * u[:, 0]).reshape(6, 48).sum(0) * dz,
                                   atol=1e-14)
        vol = np.sum(s["h"] * f.mesh.face_area)
        np.testing.assert_allclose(vol, np.sum(alpha) * dz * area, rtol=1e-7)
    np.testing.assert_allclose(np.sum(f.snapshot(0)["h"]) * area, 0.2 * 0.2 * 0.15, rtol=1e-12)
    np.testing.assert_allclose(np.sum(f.snapshot(2)["h"]) * area, frac * 0.6 * 0.2 * 0.3,
                               rtol=1e-9)
    # the front moved downstream and the water flows in +x
    s = f.snapshot(2)
    assert s["h"].reshape(4, 12)[:, 6].min() > 0.01 and s["hu"].sum() > 0


@needs_foam
@pytest.mark.openfoam
def test_interfoam_depth_average_on_a_raster_and_a_mesh(dambreak):
    from driftlog.mesher import channel_mesh

    case, _ = dambreak
    cols = open_openfoam(case)
    r = open_openfoam(case, raster=(0.0, 0.0, 0.1, 6, 2))
    tri = open_openfoam(case, mesh2d=channel_mesh(0.6, 0.2, 0.04))
    for i in range(3):
        ref = np.sum(cols.snapshot(i)["h"] * cols.mesh.face_area)
        for g in (r, tri):
            np.testing.assert_allclose(np.sum(g.snapshot(i)["h"] * g.mesh.face_area), ref,
                                       rtol=1e-12)
    # raster cells of 0.1 x 0.1 hold exactly 2 x 2 columns
    c = cols.snapshot(2)["h"].reshape(4, 12)
    np.testing.assert_allclose(r.snapshot(2)["h"].reshape(2, 6),
                               c.reshape(2, 2, 6, 2).mean(axis=(1, 3)), atol=1e-14)


@needs_foam
@pytest.mark.openfoam
def test_interfoam_decomposed_onto_a_raster(dambreak, tmp_path):
    case = tmp_path / "dec"
    shutil.copytree(dambreak[0], case)
    (case / "system" / "decomposeParDict").write_text(
        "FoamFile { version 2.0; format ascii; class dictionary; object decomposeParDict; }\n"
        "numberOfSubdomains 2;\nmethod simple;\nsimpleCoeffs { n (2 1 1); delta 0.001; }\n")
    foam(case, "decomposePar", "-time", "0:")
    for t in ("0.1", "0.2"):
        shutil.rmtree(case / t)
    serial = open_openfoam(dambreak[0], raster=(0.0, 0.0, 0.1, 6, 2))
    f = open_openfoam(case, raster=(0.0, 0.0, 0.1, 6, 2))
    assert f.attrs["decomposed"] == 1
    for i in range(3):
        for k in ("h", "hu", "hv"):
            np.testing.assert_allclose(f.snapshot(i)[k], serial.snapshot(i)[k], rtol=1e-12,
                                       atol=1e-15)
    with pytest.raises(FlowFileError, match="reconstructPar the case, or pass mesh2d= or raster="):
        open_openfoam(case)
