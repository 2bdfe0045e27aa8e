"""Round trips (issue 12 item 9): a driftlog solver flow written to Selafin with xarray-selafin
and to dfsu with mikeio, read back through `source = "auto"`, gives the original trajectories.

What differs, and by how much:

- Selafin keeps node values.  The writer stores the node values the sampler of the original
  (face-located) flow interpolates, so depth, velocity, free surface and dU/dt are sampled
  identically (double precision file: to 1e-12).  The velocity gradient J and the free-surface
  slope are recovered differently: from the face values' least-squares fits in the original,
  from the P1 node data's Green-Gauss gradients read back (``driftlog.nodal``): that is the
  interpolation difference between face- and node-based data, O(cell size x |grad J|).
  Tracer and drag-level logs (no rotation) do not use J: identical trajectories.  Full-level
  logs feel J through the added-mass / pressure-gradient force rho V J (U_b/2 + U_w) (docs/model.md
  eq. (34)): the acceleration differs by da = rho V |dJ (U_b/2 + U_w)| / m_eff, measured along
  the original trajectories; to first order the position differs by the double time integral
  of da, int_0^T (T - t) da(t) dt; the test checks the measured difference against it.
- dfsu keeps element (face) values, in float32: all sampled columns differ by float32
  round-off, and so do the trajectories (bounded through dU: |dx| <= T max|dU| e^{L T}, L
  the flow's largest velocity gradient, for tracers; measured for the full model).
"""

import numpy as np
import pytest

pytest.importorskip("xarray_selafin")
pytest.importorskip("mikeio")

from driftlog.adapters import detect_format, mike, open_flow_source, selafin  # noqa: E402

from driftlog.cli import main  # noqa: E402
from driftlog.flowfile import open_flow  # noqa: E402
from driftlog.logs import Logs  # noqa: E402
from driftlog.mesher import channel_mesh  # noqa: E402
from driftlog.physics import PhysicsOptions  # noqa: E402
from driftlog.solver import ShallowWaterSolver  # noqa: E402
from driftlog.tracker import StepOptions, Tracker  # noqa: E402

RHO, RHO_B = 1000.0, 700.0
EPOCH = "seconds since 2024-03-01 00:00:00"


@pytest.fixture(scope="module")
def flows(tmp_path_factory):
    """A solved channel flow over a bed hump (driftlog's solver) and its two exports."""
    d = tmp_path_factory.mktemp("roundtrip")
    mesh = channel_mesh(16.0, 4.0, 0.5)
    x, y = mesh.face_x, mesh.face_y
    bed = -0.005 * x + 0.1 * np.exp(-((x - 6.0) ** 2 + (y - 1.5) ** 2) / 2.0)
    s = ShallowWaterSolver(mesh, bed=bed, order=2, manning=0.02,
                           boundaries={"inflow": {"type": "discharge", "value": 0.3 * 4.0},
                                       "outflow": {"type": "level", "value": 0.5 - 0.08}})
    s.set_state(np.maximum(0.5 - bed, 0.0), 0.3, 0.0)
    s.run(10.0)
    s.run(25.0, output=d / "flow.nc", output_interval=1.0, attrs={"time_reference": EPOCH})
    orig = open_flow(d / "flow.nc")
    assert orig.attrs["time_reference"] == EPOCH
    selafin.write(orig, d / "flow.slf", precision="double")
    selafin.write(orig, d / "flow32.slf", precision="single")
    mike.write(orig, d / "flow.dfsu", chunk=6)
    # the copies are read back by content ('auto'), whatever their names
    for name in ("flow.slf", "flow32.slf", "flow.dfsu"):
        (d / (name + ".bin")).write_bytes((d / name).read_bytes())
    out = {"orig": orig}
    for key, name in (("slf", "flow.slf"), ("slf32", "flow32.slf"), ("dfsu", "flow.dfsu")):
        out[key] = open_flow_source("auto", d / (name + ".bin"))
    out["dir"] = d
    return out


class Recorder:
    """Trajectory records (t, x, y, u_b, v_b) of every log, in memory."""

    def __init__(self):
        self.rows = []

    def record(self, t, idx, cols):
        self.rows.append((t, idx.copy(), {k: np.array(v) for k, v in cols.items()}))

    def hits(self, _):
        pass


def track(flow, level, rotation=False, shift=0.0, recorder=None):
    rng = np.random.default_rng(7)
    n = 40
    logs = Logs(rng.uniform(0.5, 5.0, n), rng.uniform(0.5, 3.5, n), rng.uniform(0, np.pi, n),
                1.0, 0.08, RHO_B)
    t0, t1 = flow.times[0], flow.times[-1]
    tr = Tracker(flow, logs, PhysicsOptions(level=level, rotation=rotation), "rk4",
                 StepOptions(max_step=0.25), t_start=t0, t_end=t1,
                 output_interval=0.25, writer=recorder)
    tr.run()
    return logs


def test_exports_are_detected_by_content(flows):
    d = flows["dir"]
    assert detect_format(d / "flow.slf.bin") == "selafin"
    assert detect_format(d / "flow.dfsu.bin") == "dfsu"
    assert flows["slf"].location == "node" and flows["dfsu"].location == "face"
    # times: Selafin keeps the file's date and seconds; dfsu counts from its first step
    np.testing.assert_array_equal(flows["slf"].times, flows["orig"].times)
    assert flows["slf"].attrs["time_reference"] == EPOCH
    np.testing.assert_array_equal(flows["dfsu"].times, flows["orig"].times - 10.0)
    assert flows["dfsu"].attrs["time_reference"] == "seconds since 2024-03-01 00:00:10"


def test_selafin_samples_the_same_depth_and_velocity(flows, rng):
    orig, slf = flows["orig"], flows["slf"]
    x, y = rng.uniform(0, 16, 5000), rng.uniform(0, 4, 5000)
    for t in (10.0, 13.4, 25.0):
        a, b = orig.sample(x, y, t), slf.sample(x, y, t)
        assert np.array_equal(a.flag, b.flag) and np.all(a.flag > 0)
        for col in ("h", "u", "v", "eta", "dudt"):
            np.testing.assert_allclose(getattr(b, col), getattr(a, col), atol=1e-12,
                                       err_msg=col)
        # the recovered gradients differ (node- against face-based recovery), but only by
        # a fraction of the gradients themselves
        dj = np.abs(b.jacobian - a.jacobian).max()
        assert 1e-4 < dj < 1.0 * np.abs(a.jacobian).max()
        assert np.median(np.abs(b.jacobian - a.jacobian)) < 0.2 * np.median(np.abs(a.jacobian))


@pytest.mark.parametrize("level", ["tracer", "drag"])
def test_selafin_trajectories_identical_without_gradients(flows, level):
    a = track(flows["orig"], level)
    b = track(flows["slf"], level)
    np.testing.assert_array_equal(a.status, b.status)
    assert np.abs(b.state[:, :2] - a.state[:, :2]).max() < 1e-9
    # float32 file: velocities to float32 round-off, positions to ~1e-6 m
    c = track(flows["slf32"], level)
    assert np.abs(c.state[:, :2] - a.state[:, :2]).max() < 1e-4


def test_selafin_full_model_difference_bounded_by_the_gradient_difference(flows):
    orig, slf = flows["orig"], flows["slf"]
    rec = Recorder()
    a = track(orig, "full", recorder=rec)
    b = track(slf, "full")
    np.testing.assert_array_equal(a.status, b.status)
    dx = np.hypot(*(b.state[:, :2] - a.state[:, :2]).T)
    # the acceleration difference along the original trajectories, and its double integral
    T = orig.times[-1]
    est = np.zeros(len(a))
    ratio = RHO / (RHO_B + 0.5 * RHO)  # rho V / m_eff (fluid volume = the log's, C_m = 1/2)
    dts = np.diff([r[0] for r in rec.rows])
    for (t, idx, cols), dt in zip(rec.rows[:-1], dts, strict=True):
        p, q = orig.sample(cols["x"], cols["y"], t), slf.sample(cols["x"], cols["y"], t)
        dJ = q.jacobian - p.jacobian
        w = np.column_stack([0.5 * cols["u"] + cols["flow_u"], 0.5 * cols["v"] + cols["flow_v"]])
        da = ratio * np.hypot(*np.einsum("nij,nj->ni", dJ, w).T)
        est[idx] += (T - t) * da * dt
    assert dx.max() > 1e-6  # the full model does feel the gradients
    # first-order estimate, with a factor 2 for the feedback of the displacement on the flow
    # seen and on the drag (the drag damps velocity differences: the estimate is conservative;
    # measured: 9.5 cm at most over 15 s, at most 0.15 of each log's estimate)
    assert np.all(dx <= 2.0 * est + 1e-9), (dx.max(), est[np.argmax(dx)])


def test_dfsu_trajectories_match_to_float32(flows, rng):
    orig, dfsu = flows["orig"], flows["dfsu"]
    x, y = rng.uniform(0, 16, 5000), rng.uniform(0, 4, 5000)
    a, b = orig.sample(x, y, 17.3), dfsu.sample(x, y, 7.3)
    eps = 2.0 ** -23  # float32
    diff = np.abs(b.values - a.values).max(axis=0)
    vals = [0, 1, 2, 11]  # depth, u, v, free surface: float32 round-off of each
    assert np.all(diff[vals] <= 4 * eps * np.abs(a.values[:, vals]).max(axis=0))
    # derivatives: round-off of the values over a cell (or a snapshot interval)
    small = min(orig.mesh.face_inradius.min(), 1.0)
    assert np.all(diff[3:11] <= 16 * eps * np.abs(a.values[:, vals]).max() / small)
    du = np.abs(b.values[:, 1:3] - a.values[:, 1:3]).max()
    L = 2 * np.abs(a.jacobian).max()
    T = orig.times[-1] - orig.times[0]
    for level in ("tracer", "drag", "full"):
        p = track(orig, level)
        q = track(dfsu, level)
        np.testing.assert_array_equal(p.status, q.status)
        d = np.abs(q.state[:, :2] - p.state[:, :2]).max()
        bound = T * du * np.exp(L * T)  # Gronwall, for a tracer
        assert d <= (bound if level == "tracer" else 100 * bound), (level, d, bound)


def test_cli_import_and_info(flows, capsys):
    d = flows["dir"]
    assert main(["info", str(d / "flow.slf.bin")]) == 0
    out = capsys.readouterr().out
    assert "TELEMAC Selafin, 2D, double precision" in out and "WATER DEPTH [M]" in out
    assert main(["info", str(d / "flow.dfsu")]) == 0
    assert "MIKE dfsu (Dfsu2D)" in capsys.readouterr().out
    assert main(["import", str(d / "flow.dfsu.bin"), "-o", str(d / "back.nc")]) == 0
    back = open_flow(d / "back.nc")
    h, hu, _ = back.read_snapshot(3)
    h0, hu0, _ = flows["orig"].read_snapshot(3)
    np.testing.assert_allclose(h, h0, atol=1e-6)
    np.testing.assert_allclose(hu, hu0, atol=1e-6)
    # a Selafin file imports as face means of its nodes (a driftlog flow file holds faces)
    assert main(["import", str(d / "flow.slf"), "-o", str(d / "slf.nc")]) == 0
    fh = open_flow(d / "slf.nc").read_snapshot(2)[0]
    np.testing.assert_allclose(fh, flows["slf"].read_snapshot(2)[0], rtol=1e-12)


def test_scenario_sources(flows, rng):
    """source = 'selafin', 'dfsu' and 'auto' in a scenario; reader options validated."""
    from driftlog.errors import DriftlogError
    from driftlog.scenario import load_scenario
    from driftlog.sources import flow_from_scenario

    d = flows["dir"]
    x, y = rng.uniform(1, 15, 50), rng.uniform(0.5, 3.5, 50)
    ref = flows["orig"].sample(x, y, 12.0)
    for src, name, t in (("selafin", "flow.slf", 12.0), ("auto", "flow.slf.bin", 12.0),
                         ("dfsu", "flow.dfsu", 2.0), ("auto", "flow.dfsu.bin", 2.0)):
        scen = load_scenario({"flow": {"source": src, "path": str(d / name)}})
        f = flow_from_scenario(scen)
        np.testing.assert_allclose(f.sample(x, y, t).u, ref.u, atol=1e-6)
    scen = load_scenario({"flow": {"source": "selafin", "path": str(d / "flow.slf"),
                                   "options": {"depth_average": True}, "steady_at": 15.0}})
    f = flow_from_scenario(scen)
    assert f.steady and f.location == "node"
    np.testing.assert_allclose(f.sample(x, y, 0.0).h, flows["orig"].sample(x, y, 15.0).h,
                               atol=1e-12)
    with pytest.raises(DriftlogError, match="depth_average"):
        load_scenario({"flow": {"source": "selafin", "path": str(d / "flow.slf"),
                                "options": {"depth_average": "yes"}}})
    with pytest.raises(DriftlogError, match=r"options \['fill'\] do not apply to 'dfsu'"):
        flow_from_scenario(load_scenario({"flow": {"source": "auto",
                                                   "path": str(d / "flow.dfsu.bin"),
                                                   "options": {"fill": "dry"}}}))


def test_cli_export(flows, capsys, rng):
    d = flows["dir"]
    src = str(d / "flow.nc")
    assert main(["export", src, "-o", str(d / "cli.slf"), "--precision", "double"]) == 0
    assert main(["export", src, "-o", str(d / "cli.dfsu")]) == 0
    x, y = rng.uniform(1, 15, 50), rng.uniform(0.5, 3.5, 50)
    ref = flows["orig"].sample(x, y, 20.5)
    np.testing.assert_allclose(selafin.open(d / "cli.slf").sample(x, y, 20.5).u, ref.u,
                               atol=1e-12)
    np.testing.assert_allclose(mike.open(d / "cli.dfsu").sample(x, y, 10.5).u, ref.u,
                               atol=1e-6)
    capsys.readouterr()
    assert main(["export", src, "-o", str(d / "cli.xyz")]) == 2
    assert "give --format selafin or --format dfsu" in capsys.readouterr().err
    # a missing folder is created, as import, solve and track create theirs
    assert main(["export", src, "-o", str(d / "nodir" / "a.slf")]) == 0
    assert [p.name for p in (d / "nodir").iterdir()] == ["a.slf"]


def test_ensemble_members_read_node_data_from_the_source(flows, tmp_path):
    """An ensemble on a Selafin source does not convert it to a (face-valued) flow file."""
    from driftlog.ensemble import load_ensemble, run_member
    from driftlog.ensemble.runner import _prepare_flow

    text = f"""
[flow]
source = "selafin"
path = "{flows['dir'] / 'flow.slf'}"
[time]
start = 10.0
end = 20.0
[[logs]]
x = [2.0, 2.0]
y = [1.0, 3.0]
length = 1.0
radius = 0.08
[ensemble]
members = 2
output = "{tmp_path / 'out'}"
[ensemble.vary]
"logs.density" = {{ uniform = [500.0, 900.0] }}
"""
    ens = load_ensemble(text)
    sec, mesh = _prepare_flow(ens, ens.scenario, tmp_path / "out")
    assert sec["source"] == "selafin" and mesh.n_faces == flows["orig"].mesh.n_faces
    assert not (tmp_path / "out" / "flow.nc").exists()
    (tmp_path / "e.toml").write_text(text)
    summary = run_member(tmp_path / "e.toml", 1)
    assert summary.n_logs == 2 and summary.faces.size >= 2
