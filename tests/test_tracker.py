"""The tracker: statuses (lift-off, settling, stranding, leaving), release, landing, seeding."""
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import breaking_after

from driftlog.analytic import SolidBodyRotation, UniformFlow, on_mesh
from driftlog.api import choose_physics, track
from driftlog.errors import ScenarioError
from driftlog.flow import MeshFlowField
from driftlog.logs import FLOATING, LEFT, RESTING, STRANDED, Logs, seed_positions
from driftlog.mesh import Mesh
from driftlog.physics import PhysicsOptions
from driftlog.scenario import load_scenario
from driftlog.tracker import StepOptions, Tracker
from driftlog.trajectory import TrajectoryWriter, open_trajectories


def tide(times, depth_of_t, mesh, u=0.0):
    h = np.array([np.full(mesh.n_faces, depth_of_t(t)) for t in times])
    return MeshFlowField.from_arrays(mesh, np.zeros(mesh.n_faces), times, h, h * u, h * 0)


def test_lift_off_and_settling_follow_the_water_level(tmp_path):
    mesh = Mesh.regular_grid(10, 4, 1.0)
    times = np.arange(0.0, 61.0, 1.0)
    def depth(t):  # peaks at 0.10 m at t = 30 s
        return 0.06 + 0.04 * np.sin(np.pi * t / 60)

    flow = tide(times, depth, mesh)
    logs = Logs([5.0], [2.0], 0.0, 1.0, 0.04, 1000.0)  # floats from h = 2 r = 0.08 m
    w = TrajectoryWriter(tmp_path / "t.nc", logs)
    Tracker(flow, logs, PhysicsOptions(), "rk4", t_end=60.0, output_interval=0.5,
            writer=w).run()
    w.close()
    ds = open_trajectories(tmp_path / "t.nc")
    t, st, h = ds["time"].values, ds["status"].values, ds["water_depth"].values
    # exact crossing times of h = 0.08: sin(pi t / 60) = 0.5
    t_up, t_down = 10.0, 50.0
    assert np.all(st[t < t_up - 0.5] == RESTING)
    assert np.all(st[(t > t_up + 0.5) & (t < t_down - 0.5)] == FLOATING)
    assert np.all(st[t > t_down + 0.5] == RESTING)
    assert np.all(h[st == FLOATING] >= 0.08 - 1e-12)


def test_stranded_on_dry_and_refloats():
    mesh = Mesh.regular_grid(10, 4, 1.0)
    times = np.arange(0.0, 31.0, 1.0)
    flow = tide(times, lambda t: max(0.0, 0.2 - 0.02 * t) if t < 15 else 0.02 * (t - 15), mesh)
    logs = Logs([5.0], [2.0], 0.0, 1.0, 0.02, 500.0)
    statuses = []

    class Spy(TrajectoryWriter):
        def __init__(self):
            pass

        def record(self, t, index, columns):
            statuses.append((t, int(columns["status"][0])))

    Tracker(flow, logs, PhysicsOptions(), "rk4", t_end=30.0, output_interval=1.0,
            writer=Spy()).run()
    d = dict(statuses)
    assert d[5.0] == FLOATING and d[12.0] == STRANDED and d[29.0] == FLOATING


def test_log_leaves_the_domain_and_is_recorded_once(tmp_path):
    mesh = Mesh.regular_grid(20, 4, 1.0)
    flow = on_mesh(UniformFlow(1.0, 0.0, depth=1.0), mesh)
    logs = Logs([15.0], [2.0], 0.0, 0.5, 0.05, 600.0)
    w = TrajectoryWriter(tmp_path / "t.nc", logs)
    tr = Tracker(flow, logs, PhysicsOptions(), "rk4", t_end=20.0, output_interval=1.0, writer=w)
    tr.run()
    w.close()
    ds = open_trajectories(tmp_path / "t.nc")
    assert ds["status"].values[-1] == LEFT
    assert np.sum(ds["status"].values == LEFT) == 1
    assert ds["x"].values[-2] == pytest.approx(15.0 + ds["time"].values[-2], abs=1e-9)
    assert ds.sizes["obs"] == 7  # t = 0..5 inside (x = 20 is on the outlet edge), left at t = 6


def test_records_land_exactly_on_output_times(tmp_path):
    logs = Logs([1.0], [0.0], 0.0, 0.5, 0.05, 1000.0)
    w = TrajectoryWriter(tmp_path / "t.nc", logs)
    Tracker(SolidBodyRotation(0.0628), logs, PhysicsOptions(), "rk4",
            StepOptions(max_step=0.3), t_end=10.0, output_interval=0.7, writer=w).run()
    w.close()
    t = open_trajectories(tmp_path / "t.nc")["time"].values
    np.testing.assert_allclose(t, np.append(0.7 * np.arange(15), 10.0), atol=1e-12)


def test_tracer_on_mesh_field_follows_the_exact_circle():
    mesh = Mesh.regular_grid(40, 40, 0.1, x0=-2.0, y0=-2.0)
    flow = on_mesh(SolidBodyRotation(0.1), mesh)  # linear field: P1 reproduces it exactly
    logs = Logs([1.0], [0.0], 0.0, 0.2, 0.02, 600.0)
    Tracker(flow, logs, PhysicsOptions(level="tracer"), "rk4", StepOptions(max_step=0.05),
            t_end=20.0).run()
    assert np.hypot(logs.x[0] - np.cos(2.0), logs.y[0] - np.sin(2.0)) < 1e-9
    assert logs.theta[0] == pytest.approx(2.0, abs=1e-9)  # rotates with the flow
    assert logs.u[0] == pytest.approx(-0.1 * logs.y[0], abs=1e-12)


def test_release_times_and_seeding_outside(tmp_path):
    mesh = Mesh.regular_grid(20, 4, 1.0)
    flow = on_mesh(UniformFlow(0.5, 0.0, depth=1.0), mesh)
    logs = Logs([2.0, 2.0], [1.0, 3.0], 0.0, 0.5, 0.05, 600.0, release_time=[0.0, 3.3])
    tr = Tracker(flow, logs, PhysicsOptions(), "rk4", t_end=6.0, output_interval=1.0)
    tr.run()
    assert logs.x[0] == pytest.approx(2.0 + 0.5 * 6.0)
    assert logs.x[1] == pytest.approx(2.0 + 0.5 * (6.0 - 3.3))
    logs = Logs([25.0], [1.0], 0.0, 0.5, 0.05, 600.0)
    with pytest.raises(ScenarioError, match=r"\[logs\[0\]\] = 'x = 25, y = 1': log 0 starts "
                       r"outside the flow domain.*x 0 to 20 m, y 0 to 4 m"):
        Tracker(flow, logs, PhysicsOptions(), "rk4", t_end=6.0).run()


def test_seeding_is_reproducible_bit_for_bit():
    g = dict(seeding="random", polygon=[[0, 0], [10, 0], [10, 5], [3, 8]], count=50, seed=7,
             theta="random")
    a, b = seed_positions(g), seed_positions(dict(g))
    for u, v in zip(a, b, strict=True):
        assert np.array_equal(u, v)
    c = seed_positions(dict(g, seed=8))
    assert not np.array_equal(a[0], c[0])
    from matplotlib.path import Path as MplPath

    assert MplPath(np.array(g["polygon"])).contains_points(np.column_stack(a[:2])).all()
    x, y, _ = seed_positions(dict(seeding="line", start=[0, 0], end=[10, 0], count=5, seed=0,
                                  theta=0.0))
    np.testing.assert_allclose(x, [1, 3, 5, 7, 9])
    x, y, _ = seed_positions(dict(seeding="grid", polygon=[[0, 0], [4, 0], [4, 4], [0, 4]],
                                  count=16, seed=0, theta=0.0))
    assert x.size == 16 and np.allclose(sorted(set(x)), [0.5, 1.5, 2.5, 3.5])
    # a strip and a triangle: the grid of spacing sqrt(area / count) holds fewer than count
    # (14 of 20 and 10 of 12, without a word); it is made finer until it holds them all
    for poly, n in (([[0, 0], [10, 0], [10, 1], [0, 1]], 20), ([[0, 0], [10, 0], [0, 10]], 12)):
        x, y, _ = seed_positions(dict(seeding="grid", polygon=poly, count=n, seed=0, theta=0.0))
        assert x.size == n and len(set(zip(x, y, strict=True))) == n
        assert MplPath(np.array(poly)).contains_points(np.column_stack([x, y])).all()


def test_auto_physics_chooses_and_explains():
    scen = """
[flow]
source = "analytic"
kind = "solid_body_rotation"
omega = 0.01
[time]
end = 10.0
[[logs]]
x = [5.0]
y = [0.0]
length = 0.05
radius = 0.002
density = 900.0
[physics]
level = "auto"
rotation = "auto"
"""
    s = load_scenario(scen)
    from driftlog.api import logs_from_scenario
    from driftlog.sources import flow_from_scenario

    f = flow_from_scenario(s)
    level, rot, why = choose_physics(f, logs_from_scenario(s), s["physics"], False)
    assert level == "tracer" and "Stokes number" in why
    assert rot is False and "L |J| / |U|" in why
    # a big log in a fast-turning flow needs the full model
    s = load_scenario(scen.replace("omega = 0.01", "omega = 2.0")
                      .replace("length = 0.05", "length = 3.0")
                      .replace("radius = 0.002", "radius = 0.3"))
    level, rot, why = choose_physics(flow_from_scenario(s), logs_from_scenario(s), s["physics"],
                                     False)
    assert level == "full" and rot is True


def test_track_api_writes_a_reproducible_file(tmp_path):
    scen = f"""
title = "api"
[flow]
source = "analytic"
kind = "free_vortex"
circulation = 5.0
core_radius = 0.5
[time]
end = 30.0
output_interval = 2.0
[[logs]]
seeding = "line"
start = [1.0, 0.0]
end = [3.0, 0.0]
count = 4
length = 0.4
radius = 0.05
density = 800.0
[physics]
level = "auto"
[output]
path = "{tmp_path / 'a.nc'}"
vtk = true
"""
    res = track(scen)
    ds = res.dataset()
    assert ds.attrs["featureType"] == "trajectory"
    assert ds.attrs["physics_level"] in ("tracer", "full")
    assert ds.attrs["physics_auto_reason"].startswith("level")
    assert ds["rowSize"].values.tolist() == [16] * 4
    assert ds["status"].attrs["flag_meanings"].split()[1] == "floating"
    # rerun from the scenario stored in the output: the same trajectories, bit for bit
    import json

    again = track(json.loads(ds.attrs["scenario_resolved"]), output=tmp_path / "b.nc")
    np.testing.assert_array_equal(again.dataset()["x"].values, ds["x"].values)
    import meshio

    pvd = res.extra_files[0]
    vtus = sorted(pvd.parent.glob("*.vtu"))
    assert len(vtus) == 16
    m = meshio.read(vtus[-1])
    assert m.cells[0].data.shape == (4, 2)
    seg = m.points[1::2, :2] - m.points[0::2, :2]
    np.testing.assert_allclose(np.hypot(seg[:, 0], seg[:, 1]), 0.4)


def test_crash_keeps_what_was_computed(tmp_path):
    class Failing(UniformFlow):
        def sample_into(self, x, y, t, face, out, flag):
            if t > 5.0:
                raise RuntimeError("flow source broke")
            super().sample_into(x, y, t, face, out, flag)

    logs = Logs([0.0], [0.0], 0.0, 0.5, 0.05, 600.0)
    w = TrajectoryWriter(tmp_path / "c.nc", logs, flush_interval=1)
    with pytest.raises(RuntimeError):
        Tracker(Failing(0.5), logs, PhysicsOptions(), "rk4", t_end=10.0, output_interval=1.0,
                writer=w).run()
    ds = open_trajectories(tmp_path / "c.nc")  # the .partial file
    assert ds["time"].values.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]


def test_resume_after_a_crash_equals_the_uninterrupted_run(tmp_path):
    scen = """
[flow]
source = "analytic"
kind = "free_vortex"
circulation = 4.0
core_radius = 0.5
[time]
end = 20.0
output_interval = 1.0
[[logs]]
seeding = "line"
start = [1.0, 0.0]
end = [3.0, 0.0]
count = 3
length = 0.4
radius = 0.05
density = 800.0
release_time = 2.5
[output]
flush_interval = 1
"""
    from driftlog.scenario import load_scenario
    from driftlog.sources import flow_from_scenario

    full = track(scen, output=tmp_path / "full.nc").dataset()
    flow = flow_from_scenario(load_scenario(scen))

    broken = breaking_after(flow, 11.3)
    with pytest.raises(KeyboardInterrupt):
        track(scen, flow=broken, output=tmp_path / "r.nc")
    assert (tmp_path / "r.nc.partial").is_file() and not (tmp_path / "r.nc").exists()
    res = track(scen, output=tmp_path / "r.nc", resume=True)
    again = res.dataset()
    np.testing.assert_array_equal(again["time"].values, full["time"].values)
    np.testing.assert_array_equal(again["x"].values, full["x"].values)
    np.testing.assert_array_equal(again["theta"].values, full["theta"].values)
    # the run's counts go on from where it stopped
    for k in ("stats_substeps", "stats_rhs_evaluations", "stats_min_dt", "stats_max_dt"):
        assert again.attrs[k] == full.attrs[k], k


def test_a_resumed_jam_records_no_held_contact_as_a_new_hit(tmp_path):
    """A Moreau-Jean jam stopped and resumed: the same records and the same hits.

    A hit is a contact that starts pushing; the contact model's pairs in contact at the
    restart are kept with the records (``keep_counts``).  Without them the resumed run took
    every held contact for a new hit (cases/bridge_jam stopped at 20.3 s: 465 hits against
    451).
    """
    from driftlog.sources import flow_from_scenario

    case = Path(__file__).resolve().parents[1] / "cases" / "bridge_jam" / "scenario.toml"
    full = track(case, output=tmp_path / "full.nc").dataset()
    assert full.sizes["hit"] > 100
    flow = flow_from_scenario(load_scenario(case))
    with pytest.raises(KeyboardInterrupt):
        track(case, flow=breaking_after(flow, 20.3), output=tmp_path / "r.nc")
    again = track(case, output=tmp_path / "r.nc", resume=True).dataset()
    for v in ("x", "y", "theta", "hit_time", "hit_log", "hit_other", "hit_impulse"):
        np.testing.assert_array_equal(again[v].values, full[v].values, err_msg=v)
    assert json.loads(again.attrs["contact_stats"]) == json.loads(full.attrs["contact_stats"])


SCATTERED = """
[flow]
source = "analytic"
kind = "free_vortex"
circulation = 4.0
core_radius = 0.5
[time]
end = 12.0
output_interval = 1.0
[[logs]]
seeding = "random"
polygon = [[-3.0, -3.0], [3.0, -3.0], [3.0, 3.0], [-3.0, 3.0]]
count = 40
seed = 5
length = 0.4
radius = 0.05
density = 800.0
[[logs]]
seeding = "random"
polygon = [[1.0, 1.0], [4.0, 1.0], [4.0, 4.0], [1.0, 4.0]]
count = 25
seed = 6
length = 0.3
radius = 0.04
density = 700.0
release_time = 2.5
[output]
flush_interval = 1
"""


def _file_arrays(path):
    import netCDF4

    with netCDF4.Dataset(path) as ds:
        ds.set_auto_maskandscale(False)
        return {k: v[:] for k, v in ds.variables.items()}


def test_logs_tracked_along_a_space_filling_curve_write_the_scenarios_file(tmp_path,
                                                                          monkeypatch):
    """Logs seeded at random are tracked listed along a Hilbert curve (``api.track``): the
    trajectory file, the logs returned and a resumed run are those of the scenario's order,
    bit for bit."""
    import driftlog.api as api
    from driftlog.logs import spatial_order

    start = api.logs_from_scenario(load_scenario(SCATTERED))
    order = spatial_order(start.x, start.y)
    assert not np.array_equal(order, np.arange(len(start)))  # the test renumbers
    records = {}

    def keeping(name):  # a writer that also keeps what each record received, in its order
        class Keeping(TrajectoryWriter):
            def record(self, t, index, columns):
                records.setdefault(name, []).append((t, np.array(index), columns["x"].copy()))
                super().record(t, index, columns)
        return Keeping

    curve = track(SCATTERED, output=tmp_path / "curve.nc", writer=keeping("curve"))
    with monkeypatch.context() as m:  # the scenario's own order
        m.setattr(api, "spatial_order", lambda x, y: np.arange(len(x)))
        listed = track(SCATTERED, output=tmp_path / "listed.nc", writer=keeping("listed"))
    assert len(records["curve"]) == len(records["listed"]) == 13
    for (t, i, x), (t2, i2, x2) in zip(records["curve"], records["listed"], strict=True):
        assert t == t2
        np.testing.assert_array_equal(i, i2)
        np.testing.assert_array_equal(x, x2)
    a, b = _file_arrays(curve.path), _file_arrays(listed.path)
    assert a.keys() == b.keys() and a["x"].size > 600
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    for k in ("state", "status", "face", "id", "group", "release_time"):
        np.testing.assert_array_equal(getattr(curve.logs, k), getattr(listed.logs, k))
    # stopped and resumed on the curve's order: the same file again
    flow = api.flow_from_scenario(load_scenario(SCATTERED))
    with pytest.raises(KeyboardInterrupt):
        track(SCATTERED, flow=breaking_after(flow, 7.3), output=tmp_path / "r.nc")
    again = track(SCATTERED, output=tmp_path / "r.nc", resume=True)
    c = _file_arrays(again.path)
    assert c.keys() == b.keys()
    for k in b:
        np.testing.assert_array_equal(c[k], b[k], err_msg=k)


def test_auto_physics_judges_logs_by_the_water_that_lifts_them():
    """Logs on a dry floor before a flood: auto judges the flood, not the dry ground."""
    from driftlog.flow import MeshFlowField
    from driftlog.logs import Logs
    from driftlog.mesh import Mesh

    mesh = Mesh.regular_grid(20, 20, 1.0)
    n = mesh.n_faces
    # dry at t = 0, then a fast shear flow 2 m deep (strong gradient: not a tracer flow)
    h = np.stack([np.zeros(n), np.full(n, 2.0), np.full(n, 2.0)])
    u = 0.5 * (mesh.face_y - 10.0)
    hu = np.stack([np.zeros(n), 2.0 * u, 2.0 * u])
    flow = MeshFlowField.from_arrays(mesh, np.zeros(n), [0.0, 10.0, 20.0], h, hu, np.zeros_like(hu))
    logs = Logs(x=[10.0], y=[12.0], theta=0.0, length=2.0, radius=0.2, density=700.0)
    section = {"level": "auto", "rotation": "auto", "fluid_volume": "body",
               "surface_slope": False, "drag_law": "ganser", "drag_area": "paper",
               "drag_coefficient": 1.0, "linear_drag": 1.0, "torque_force": "total",
               "water_density": 1000.0, "gravity": 9.81, "viscosity": 1e-3}
    level, rot, why = choose_physics(flow, logs, section, False, t_end=20.0)
    assert level == "full" and rot is True, why
    # judged at the release only (the old behaviour), the dry floor said "tracer"
    dry_only = MeshFlowField.from_arrays(mesh, np.zeros(n), [0.0, 1.0], h[:1].repeat(2, 0),
                                         hu[:1].repeat(2, 0), np.zeros((2, n)))
    level, _, why = choose_physics(dry_only, logs, section, False, t_end=1.0)
    assert level == "full" and "no log is in water" in why


def _timed_uniform_flow(u_of_t, times):
    """A uniform flow u(t_k) along x at snapshots t_k on a 2 km x 200 m mesh (1 m deep)."""
    mesh = Mesh.regular_grid(20, 2, 100.0)
    n = mesh.n_faces
    u = np.array([u_of_t(t) for t in times])
    h = np.ones((len(times), n))
    return MeshFlowField.from_arrays(mesh, np.zeros(n), times, h, h * u[:, None],
                                     np.zeros((len(times), n)))


def _tracer_x(flow, dt, end, land, level="tracer", fused=True):
    logs = Logs(np.array([100.0]), np.array([100.0]), 0.0, 0.5, 0.05, 500.0)
    tr = Tracker(flow, logs, PhysicsOptions(level=level, rotation=False), "rk4",
                 StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9,
                             land_on_snapshots=land),
                 t_end=end, output_interval=end, fused=fused)
    tr.run()
    return logs.state[0, 0], tr.stats["substeps"]


def test_steps_across_snapshots():
    """land_on_snapshots = false: sub-steps run across snapshots, each RK4 stage reading the
    pair of snapshots around its own time.  On a uniform flow u(t) RK4 is Simpson's rule on
    the interpolant, step by step: on a flow linear in time (exact under linear interpolation)
    it is exact with steps of three snapshot intervals; on one whose interpolant has a kink
    at every snapshot it is Simpson's rule with the stages on both sides of the kinks (a
    stage read from the wrong pair of snapshots would not be), and landing on the snapshots
    is exact."""
    times = np.arange(0.0, 91.0, 10.0)
    lin = _timed_uniform_flow(lambda t: 0.5 + 0.01 * t, times)
    exact = 100.0 + 0.5 * 90.0 + 0.005 * 90.0 ** 2
    x, steps = _tracer_x(lin, 30.0, 90.0, land=False)
    assert steps == 3 and abs(x - exact) < 1e-10
    x, steps = _tracer_x(lin, 30.0, 90.0, land=True)
    assert steps == 9 and abs(x - exact) < 1e-10
    # kinks: u(t_k) = 1 + sin(2 pi t_k / 60); the exact path of the interpolant, trapezoids
    uk = 1.0 + np.sin(2.0 * np.pi * times / 60.0)
    kinked = _timed_uniform_flow(lambda t: 1.0 + np.sin(2.0 * np.pi * t / 60.0), times)
    exact = 100.0 + np.sum(0.5 * (uk[1:] + uk[:-1]) * 10.0)
    x, _ = _tracer_x(kinked, 10.0, 90.0, land=True)
    assert abs(x - exact) < 1e-10
    for dt in (18.0, 25.0, 7.0):
        t = np.arange(0.0, 90.0, dt)
        h = np.minimum(dt, 90.0 - t)

        def ui(tt):
            return np.interp(tt, times, uk)

        simpson = 100.0 + np.sum(h / 6.0 * (ui(t) + 4.0 * ui(t + h / 2) + ui(t + h)))
        x, steps = _tracer_x(kinked, dt, 90.0, land=False)
        assert steps == t.size and abs(x - simpson) < 1e-10, (dt, x, simpson)
        assert abs(x - exact) > 1e-3  # the kinks inside the steps are felt
    # full physics (a log relaxing to the flow by drag): the fused kernel and the general
    # stage-by-stage path, which samples each stage by its own time too
    a, n = _tracer_x(kinked, 2.5, 90.0, land=False, level="full")
    b, m = _tracer_x(kinked, 2.5, 90.0, land=False, level="full", fused=False)
    c, _ = _tracer_x(kinked, 2.5, 90.0, land=True, level="full")
    # (full physics reads dU/dt, which jumps at each snapshot: a step across one is first
    # order there, 0.13 m off the landing steps' result after 90 s)
    assert n == m and abs(a - b) < 1e-9 and 1e-3 < abs(a - c) < 0.2, (a, b, c)


def test_full_physics_converges_on_snapshots():
    """Full physics reads the flow's dU/dt (pressure gradient, added mass), which jumps at
    every snapshot.  A sub-step's last stage used to read the next pair's dU/dt at the
    snapshot it lands on (a time alone picks the pair that starts there), and the next step
    reused that stage: first order in time, 4.6 mm apart at dt = 1/32 s and 1/16 s over 90 s
    here, 7 mm off at 0.05 s.  Now the step's stages read its own pair and the next step
    samples again: converged to 2e-5 m from dt = 0.5 s, fused and general paths alike."""
    times = np.arange(0.0, 91.0, 10.0)
    kinked = _timed_uniform_flow(lambda t: 1.0 + np.sin(2.0 * np.pi * t / 60.0), times)
    xs = {}
    for dt in (0.5, 0.25, 0.125, 0.0625):
        xs[dt], _ = _tracer_x(kinked, dt, 90.0, land=True, level="full")
        g, _ = _tracer_x(kinked, dt, 90.0, land=True, level="full", fused=False)
        assert g == xs[dt]
    assert max(abs(xs[dt] - xs[0.0625]) for dt in (0.5, 0.25, 0.125)) < 2e-5, xs


def test_steps_across_snapshots_need_the_global_clock():
    flow = _timed_uniform_flow(lambda t: 1.0, np.arange(0.0, 31.0, 10.0))
    logs = Logs(np.array([100.0]), np.array([100.0]), 0.0, 0.5, 0.05, 500.0)
    with pytest.raises(ScenarioError, match="land_on_snapshots"):
        Tracker(flow, logs, PhysicsOptions(level="tracer"), "rk4",
                StepOptions(max_step=5.0, clock="per_log", land_on_snapshots=False), t_end=30.0)


def test_running_file_chunks_sized_to_its_flushes(tmp_path):
    """A running file flushed every record gets small chunks; a resumed run keeps the file's.

    HDF5 compresses the partly filled chunk again at every sync: a coupled run (flushed with
    every flow snapshot) with chunks of OBS_CHUNK observations compressed up to 64k
    observations per variable at each record, whatever its number of logs.
    """
    import netCDF4

    from driftlog import trajectory
    from driftlog.trajectory import MIN_RUNNING_CHUNK, OBS_CHUNK, running_chunk

    assert running_chunk(1000, 1) == MIN_RUNNING_CHUNK  # 4 x 1000 -> 4096
    assert running_chunk(3000, 1) == 16384  # 12,000 -> the next power of two
    assert running_chunk(1000, 10) == OBS_CHUNK  # 40,000 -> 65,536
    assert running_chunk(10**6, 10) == OBS_CHUNK
    assert running_chunk(0, 0) == MIN_RUNNING_CHUNK
    n = 30
    logs = Logs(np.linspace(0.0, 1.0, n), np.zeros(n))
    cols = {name: np.zeros(n, dt) for name, (dt, _) in trajectory.OBS_VARS.items()}
    for every, want in ((True, MIN_RUNNING_CHUNK), (False, running_chunk(n, 10**4))):
        path = tmp_path / f"t{int(every)}.nc"
        w = trajectory.TrajectoryWriter(path, logs, flush_interval=10**4,
                                        flush_every_record=every)
        w.record(0.0, np.arange(n), cols)
        w.flush()
        w.close(finalize=False)
        with netCDF4.Dataset(w.partial) as ds:
            assert {ds[v].chunking()[0] for v in ("time", "x", "trajectory_index")} == {want}
    # resumed with other settings: new obs variables take the file's chunks
    w = trajectory.TrajectoryWriter(tmp_path / "t1.nc", logs, flush_interval=10**4,
                                    resume=True)
    w.record(1.0, np.arange(n), dict(cols, log_density=np.full(n, 700.0)))
    w.flush()
    assert w.ds["log_density"].chunking() == [MIN_RUNNING_CHUNK]
    path = w.close()
    with netCDF4.Dataset(path) as ds:  # the final file as before: every record, in order
        np.testing.assert_array_equal(ds["rowSize"][:], np.full(n, 2))
        assert ds["log_density"][:].size == 2 * n


def test_trajectory_file_chunks_bounded_running_file_fast_compressed(tmp_path, monkeypatch):
    """Observations are stored in chunks of at most OBS_CHUNK, compressed, and read back exact.

    netCDF-C's defaults were 512 observations per chunk in the running file and the whole
    dimension in one chunk in the final file (every block written recompressed all of it).
    """
    import netCDF4

    from driftlog import trajectory

    monkeypatch.setattr(trajectory, "OBS_CHUNK", 64)
    n, nrec = 50, 7  # 350 observations: several chunks, the last one partly filled
    logs = Logs(np.linspace(0.0, 1.0, n), np.zeros(n))
    rng = np.random.default_rng(3)
    records = []
    w = trajectory.TrajectoryWriter(tmp_path / "t.nc", logs, flush_interval=3)
    for k in range(nrec):
        idx = np.sort(rng.choice(n, size=n - k, replace=False))
        cols = {name: rng.normal(size=idx.size).astype(dt) if dt != "i1"
                else np.full(idx.size, 1, np.int8)
                for name, (dt, _) in trajectory.OBS_VARS.items()}
        records.append((float(k), idx, cols))
        w.record(float(k), idx, cols)
    w.flush()
    for name in ("time", "x", "status"):  # a cache of 4 chunks, not netCDF-C's 64 MiB
        v = w.ds[name]
        assert v.get_var_chunk_cache()[0] == 4 * 64 * v.dtype.itemsize
    with netCDF4.Dataset(w.partial) as ds:  # the running file, as a resumed run reads it
        for name in ("trajectory_index", "time", *trajectory.OBS_VARS):
            assert ds[name].chunking() == [64]
            f = ds[name].filters()
            assert f["zstd"] if ds.has_zstd_filter() else f["zlib"], (name, f)
    path = w.close()
    with netCDF4.Dataset(path) as ds:
        ds.set_auto_maskandscale(False)
        for name in trajectory.OBS_VARS:  # zlib in the final file: every reader decodes it
            f = ds[name].filters()
            assert ds[name].chunking() == [64] and f["zlib"] and f["shuffle"], (name, f)
            assert not f["zstd"], (name, f)
        rows = ds["rowSize"][:]
        got = {name: ds[name][:] for name in ("time", "x", "theta", "water_depth")}
    # each log's observations together, in time order, bit for bit
    log = np.concatenate([r[1] for r in records])
    want = {"time": np.concatenate([np.full(r[1].size, r[0]) for r in records])}
    want.update({name: np.concatenate([r[2][name] for r in records])
                 for name in ("x", "theta", "water_depth")})
    order = np.argsort(log, kind="stable")
    np.testing.assert_array_equal(rows, np.bincount(log, minlength=n))
    for name, values in got.items():
        np.testing.assert_array_equal(values, want[name][order])
