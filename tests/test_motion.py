"""Beyond the paper (issue 16, docs/model.md 6.1-6.2): initial motion on the bed, waterlogging.

Exact cases: Braudrick and Grant's (2000) entrainment threshold for a log on the bed of a
uniform flow (both orientations, flat and sloping bed) and the sliding speed it then reaches;
a log whose density rises by the exponential law, in still water, stops floating at the
predicted time.
"""
import numpy as np
import pytest
from conftest import breaking_after

from driftlog.analytic import UniformFlow
from driftlog.errors import ScenarioError
from driftlog.logs import FLOATING, RESTING, Logs, submerged_volume
from driftlog.physics import PhysicsOptions
from driftlog.scenario import load_scenario
from driftlog.tracker import Tracker
from driftlog.trajectory import TrajectoryWriter

RHO, G = 1000.0, 9.81
L, R, RHO_B, DEPTH, MU_BED, CD = 2.0, 0.1, 900.0, 0.1, 0.6, 1.2


def threshold_speed(theta, slope):
    """Closed form: 0.5 rho C_d u^2 (L h sin t + A_sub cos t) = g (rho_b V_b - rho V_sub)
    (mu cos a_s - sin a_s), flow along x down a surface (= bed) slope ``slope``."""
    vb = np.pi * R * R * L
    vsub = submerged_volume(DEPTH, R, L)
    a_sub = vsub / L
    area = L * DEPTH * abs(np.sin(theta)) + a_sub * abs(np.cos(theta))
    a_s = np.arctan(slope)
    wprime = G * (RHO_B * vb - RHO * vsub)
    return np.sqrt(2.0 * wprime * (MU_BED * np.cos(a_s) - np.sin(a_s)) / (RHO * CD * area))


def run_bed_log(u, theta, slope, motion="friction", t_end=20.0, method="rk4"):
    flow = UniformFlow(u, 0.0, DEPTH, surface_slope=(-slope, 0.0))
    logs = Logs([0.0], [0.0], theta, L, R, RHO_B)
    ph = PhysicsOptions(rotation=False, drag_law="constant", drag_coefficient=CD,
                        drag_area="wetted", motion=motion, bed_friction=MU_BED)
    Tracker(flow, logs, ph, method, t_end=t_end, output_interval=t_end, hydro_step=0.5).run()
    return logs


@pytest.mark.parametrize("slope", [0.0, 0.02])
@pytest.mark.parametrize("theta", [0.0, np.pi / 2])
def test_log_on_bed_moves_just_above_the_friction_threshold(theta, slope):
    assert DEPTH < 1.5 * R  # the log lies on the bed: its flotation depth is deeper
    uc = threshold_speed(theta, slope)
    below = run_bed_log(0.99 * uc, theta, slope)
    assert below.status[0] == RESTING
    assert below.state[0, 0] == 0.0 and below.state[0, 3] == 0.0
    above = run_bed_log(1.01 * uc, theta, slope)
    assert above.status[0] == FLOATING  # transported, on the bed
    assert above.state[0, 0] > 0.0 and above.state[0, 3] > 0.0
    # the paper's condition (the default): a log below its flotation depth never moves
    paper = run_bed_log(1.5 * uc, theta, slope, motion="floating")
    assert paper.status[0] == RESTING and paper.state[0, 0] == 0.0


@pytest.mark.parametrize("method", ["euler", "rk4", "exponential"])
@pytest.mark.parametrize("theta", [0.0, np.pi / 2])
def test_sliding_log_reaches_the_speed_where_drag_balances_friction(theta, method):
    # drag 0.5 rho C_d A w^2 = friction mu W': the relative speed w is the threshold speed,
    # so a log on a flat bed slides at u - u_c
    uc = threshold_speed(theta, 0.0)
    logs = run_bed_log(1.5 * uc, theta, 0.0, t_end=200.0, method=method)
    assert logs.status[0] == FLOATING
    assert logs.state[0, 3] == pytest.approx(0.5 * uc, rel=1e-6)
    assert abs(logs.state[0, 4]) < 1e-12


def soak_run(depth, tau=100.0, rho0=700.0, rho_sat=1100.0, t_end=150.0, dt_out=0.5):
    flow = UniformFlow(0.0, 0.0, depth)
    logs = Logs([0.0], [0.0], 0.0, 1.0, 0.1, rho0)
    ph = PhysicsOptions(waterlogging="exponential", saturated_density=rho_sat,
                        waterlogging_time=tau)
    rec = []

    class Spy(TrajectoryWriter):
        def __init__(self):
            pass

        def record(self, t, index, columns):
            rec.append((t, int(columns["status"][0]), float(logs.density[0])))

    Tracker(flow, logs, ph, "rk4", t_end=t_end, output_interval=dt_out, hydro_step=dt_out,
            writer=Spy()).run()
    t, st, rho_b = (np.array(c) for c in zip(*rec, strict=True))
    return t, st, rho_b, logs


@pytest.mark.parametrize("depth", [1.0, 0.15])
def test_waterlogged_log_stops_floating_at_the_predicted_time(depth):
    tau, rho0, rho_sat = 100.0, 700.0, 1100.0
    t, st, rho_b, logs = soak_run(depth, tau, rho0, rho_sat)
    # the density follows the closed form while wet (floating, then resting on the bed)
    exact = rho_sat - (rho_sat - rho0) * np.exp(-t / tau)
    assert np.max(np.abs(rho_b - exact)) < 1e-9
    assert logs.mass[0] == pytest.approx(rho_b[-1] * np.pi * 0.01, rel=1e-14)
    # it floats while rho V_sub(depth) >= rho_b V_b: in deep water until rho_b = rho
    rho_crit = RHO * submerged_volume(depth, 0.1, 1.0) / (np.pi * 0.01)
    t_star = tau * np.log((rho_sat - rho0) / (rho_sat - rho_crit))
    assert 0.0 < t_star < t[-1]
    assert np.all(st[t < t_star] == FLOATING)
    # statuses are judged at the end of every sub-step: the first record after t* rests
    assert np.all(st[t > t_star] == RESTING)


def test_waterlogging_needs_its_time_constant():
    scen = """
[flow]
source = "analytic"
kind = "uniform"
[time]
end = 10.0
[[logs]]
x = [0.0]
y = [0.0]
[physics]
waterlogging = "exponential"
"""
    with pytest.raises(ScenarioError, match="waterlogging_time"):
        load_scenario(scen)
    s = load_scenario(scen + "waterlogging_time = 3600.0\nmotion = \"friction\"\n")
    ph = PhysicsOptions.from_scenario(s["physics"])
    assert ph.waterlogging_time == 3600.0 and ph.motion == "friction"
    assert ph.bed_friction == 0.5 and ph.bed_slope == "surface"


def bed_channel():
    """A shallow channel: depth 0.15-0.45 m across, speed 0.1-1.1 m/s along, changing in time."""
    from driftlog.flow import MeshFlowField
    from driftlog.mesh import Mesh

    mesh = Mesh.regular_grid(30, 10, 1.0)
    xc, yc = mesh.face_x, mesh.face_y
    times = np.arange(0.0, 21.0, 4.0)
    h = np.array([0.15 + 0.03 * yc + 0.002 * t + 0.0 * xc for t in times])
    u = np.array([0.1 + 0.1 * yc + 0.01 * t + 0.05 * np.sin(xc / 3.0) for t in times])
    v = np.array([0.05 * np.cos(xc / 3.0) + 0.0 * t for t in times])
    return MeshFlowField.from_arrays(mesh, np.zeros(mesh.n_faces), times, h, h * u, h * v)


@pytest.mark.parametrize("method", ["euler", "rk4"])
def test_fused_path_carries_bed_friction_and_waterlogging_bit_for_bit(method):
    flow = bed_channel()
    runs = []
    for fused in (True, False):
        rng = np.random.default_rng(3)
        n = 120
        logs = Logs(rng.uniform(1.0, 20.0, n), rng.uniform(0.5, 9.5, n), rng.uniform(0, np.pi, n),
                    1.0, 0.2, rng.uniform(600.0, 1000.0, n), release_time=rng.choice([0.0, 3.0], n))
        ph = PhysicsOptions(motion="friction", bed_friction=0.8, waterlogging="exponential",
                            saturated_density=1050.0, waterlogging_time=30.0)
        tr = Tracker(flow, logs, ph, method, t_end=20.0, output_interval=2.5, fused=fused)
        assert tr.fused == fused
        tr.run()
        h = flow.sample(logs.x, logs.y, 20.0).h
        runs.append((logs.state.copy(), logs.status.copy(), logs.density.copy(), h,
                     logs.float_depth.copy()))
    (s1, st1, d1, h, hstar), (s2, st2, d2, _, _) = runs
    assert np.array_equal(s1, s2) and np.array_equal(st1, st2) and np.array_equal(d1, d2)
    # all three kinds are there: floating, moving on the bed, held on the bed
    on_bed = h < hstar
    assert np.any((st1 == FLOATING) & ~on_bed)
    assert np.any((st1 == FLOATING) & on_bed)
    assert np.any(st1 == RESTING)
    assert np.all(d1 > 600.0) and np.all(d1 < 1050.0)


def test_scenario_run_sinks_a_waterlogged_log_and_friction_holds_it(tmp_path):
    from driftlog.api import track
    from driftlog.trajectory import open_trajectories

    scen = """
[flow]
source = "analytic"
kind = "uniform"
velocity = [0.0, 0.0]
depth = 1.0
[time]
end = 200.0
output_interval = 1.0
[[logs]]
x = [0.0]
y = [0.0]
length = 1.0
radius = 0.1
density = 700.0
[physics]
motion = "friction"
waterlogging = "exponential"
saturated_density = 1100.0
waterlogging_time = 100.0
"""
    track(scen, output=tmp_path / "t.nc")
    ds = open_trajectories(tmp_path / "t.nc")
    t, st = ds["time"].values, ds["status"].values  # one log: one record per time
    t_star = 100.0 * np.log(4.0)  # rho_b reaches rho = 1000 kg/m3
    assert np.all(st[t < t_star] == FLOATING) and np.all(st[t > t_star] == RESTING)
    assert np.all(ds["x"].values == 0.0)  # still water: held on the bed by friction


def test_a_waterlogged_run_resumes_bit_for_bit_with_its_densities(tmp_path):
    from driftlog.api import track
    from driftlog.scenario import load_scenario
    from driftlog.sources import flow_from_scenario

    scen = """
[flow]
source = "analytic"
kind = "free_vortex"
circulation = 4.0
core_radius = 0.5
depth = 0.3
[time]
end = 40.0
output_interval = 1.0
[[logs]]
seeding = "line"
start = [1.0, 0.0]
end = [3.0, 0.0]
count = 3
length = 0.4
radius = 0.1
density = 600.0
release_time = 2.5
[physics]
waterlogging = "exponential"
waterlogging_time = 20.0
[output]
flush_interval = 1
"""
    full = track(scen, output=tmp_path / "full.nc").dataset()
    flow = flow_from_scenario(load_scenario(scen))

    broken = breaking_after(flow, 21.3)
    with pytest.raises(KeyboardInterrupt):
        track(scen, flow=broken, output=tmp_path / "r.nc")
    again = track(scen, output=tmp_path / "r.nc", resume=True).dataset()
    for name in ("time", "x", "status", "log_density"):
        np.testing.assert_array_equal(again[name].values, full[name].values)
    # the logs sink on the way (h* rises past 0.3 m), so the densities mattered
    st = full["status"].values
    assert np.any(st == FLOATING) and np.any(st == RESTING)


def test_a_waterlogged_run_without_density_records_is_not_resumed():
    logs = Logs([0.0], [0.0], 0.0, 1.0, 0.1, 700.0)
    ph = PhysicsOptions(waterlogging="exponential", waterlogging_time=100.0)
    tr = Tracker(UniformFlow(0.0, 0.0, 1.0), logs, ph, "rk4", t_end=10.0)
    cols = {k: np.zeros(1) for k in ("x", "y", "theta", "u", "v", "omega")}
    cols["status"] = np.array([FLOATING], np.int8)
    with pytest.raises(ScenarioError, match="physics.waterlogging.*no log_density"):
        tr.resume_from(5.0, np.array([0]), cols)
