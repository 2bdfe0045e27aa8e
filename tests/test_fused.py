"""The fused per-log steps (driftlog.fused) give the general path's trajectories bit for bit."""
import numpy as np
import pytest
from conftest import draining_channel

from driftlog.analytic import FreeVortex, on_mesh
from driftlog.logs import FLOATING, LEFT, RESTING, STRANDED, Logs
from driftlog.mesh import Mesh
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

MESH = Mesh.regular_grid(30, 10, 1.0)
TIMES = np.arange(0.0, 21.0, 4.0)  # sub-steps land on each snapshot: the node pair switches


FLOW = draining_channel(MESH, TIMES)


def assert_same_runs(tb, b, ta, a):
    """Two trackers' logs the same bit for bit (state, status, face) and their steps too."""
    np.testing.assert_array_equal(b.state, a.state)
    np.testing.assert_array_equal(b.status, a.status)
    np.testing.assert_array_equal(b.face, a.face)
    for k in ("substeps", "rhs_evaluations", "min_dt", "max_dt"):
        assert tb.stats[k] == ta.stats[k], k


def run(level, rotation, method, fused, flow=FLOW, t_end=20.0):
    rng = np.random.default_rng(7)
    n = 200
    logs = Logs(rng.uniform(0.5, 29.5, n), rng.uniform(0.5, 9.5, n), rng.uniform(0, np.pi, n),
                rng.uniform(0.5, 1.5, n), 0.1, rng.uniform(500.0, 900.0, n),
                release_time=rng.choice([0.0, 3.0], n))
    tr = Tracker(flow, logs, PhysicsOptions(level=level, rotation=rotation), method,
                 StepOptions(max_step=0.7), t_end=t_end, output_interval=2.5, fused=fused)
    tr.run()
    return tr, logs


@pytest.mark.parametrize("method", ["euler", "rk4"])
@pytest.mark.parametrize("level,rotation", [("tracer", True), ("tracer", False),
                                            ("drag", True), ("drag", False),
                                            ("full", True), ("full", False)])
def test_fused_step_equals_general_path_bit_for_bit(level, rotation, method):
    general, a = run(level, rotation, method, fused=False)
    fused, b = run(level, rotation, method, fused=True)
    assert fused.fused and not general.fused
    assert_same_runs(fused, b, general, a)
    # the scene exercises what the fused kernel must reproduce: logs left through the outlet,
    # stranded on the dried bank, still floating after crossing many faces
    assert np.sum(b.status == LEFT) > 10
    assert np.sum(b.status == FLOATING) > 10
    if level != "tracer":
        assert np.sum((b.status == STRANDED) | (b.status == RESTING)) > 0
    start = np.random.default_rng(7).uniform(0.5, 29.5, 200)
    assert np.max(b.state[b.status == FLOATING, 0] - start[b.status == FLOATING]) > 8.0


def test_steady_vortex_on_a_mesh_rk4_bit_for_bit():
    """One snapshot (steady), logs circling through many faces for a whole revolution."""
    flow = on_mesh(FreeVortex(20.0, center=(15.0, 5.0), core_radius=1.0, depth=2.0), MESH)
    general, a = run("full", True, "rk4", fused=False, flow=flow, t_end=30.0)
    fused, b = run("full", True, "rk4", fused=True, flow=flow, t_end=30.0)
    np.testing.assert_array_equal(b.state, a.state)
    np.testing.assert_array_equal(b.face, a.face)


def _triangle_channel(gradient):
    """The draining channel on a Delaunay mesh of a jittered lattice (triangles, P1 or
    recovered gradients)."""
    from scipy.spatial import Delaunay

    from driftlog.flow import MeshFlowField

    rng = np.random.default_rng(5)
    gx, gy = np.meshgrid(np.linspace(0.0, 30.0, 41), np.linspace(0.0, 10.0, 15))
    inner = (gx > 0) & (gx < 30) & (gy > 0) & (gy < 10)
    gx = gx + inner * rng.uniform(-0.2, 0.2, gx.shape)
    gy = gy + inner * rng.uniform(-0.2, 0.2, gy.shape)
    tri = Delaunay(np.column_stack([gx.ravel(), gy.ravel()])).simplices
    mesh = Mesh(gx.ravel(), gy.ravel(), tri)
    base = draining_channel(mesh, TIMES)
    return MeshFlowField(mesh, np.zeros(mesh.n_faces), base.source, gradient=gradient)


@pytest.mark.parametrize("method", ["euler", "rk4"])
@pytest.mark.parametrize("gradient", ["p1", "recovered"])
def test_tracer_kernels_on_triangles_bit_for_bit(method, gradient):
    """Tracer mode's own kernels (packed node rows, ``fused.rk4_tracer_step``) on triangles,
    with the rotation from either gradient: the general path's trajectories, statuses and
    faces."""
    flow = _triangle_channel(gradient)
    general, a = run("tracer", True, method, fused=False, flow=flow)
    fused, b = run("tracer", True, method, fused=True, flow=flow)
    assert_same_runs(fused, b, general, a)
    assert np.sum(b.status == LEFT) > 10 and np.sum(b.status == FLOATING) > 10
    assert np.ptp(b.state[b.status == FLOATING, 2]) > 0.0  # the rotation turned them


def test_fused_path_only_where_it_applies():
    logs = Logs([5.0], [5.0])
    assert Tracker(FLOW, logs, method="rk4", t_end=1.0).fused
    assert not Tracker(FLOW, logs, method="exponential", t_end=1.0).fused
    assert not Tracker(FLOW, logs, method="rk4", t_end=1.0, fused=False).fused
    analytic = FreeVortex(20.0, center=(15.0, 5.0), core_radius=1.0, depth=2.0)
    assert not Tracker(analytic, logs, method="rk4", t_end=1.0).fused


@pytest.mark.parametrize("level,method,waterlogging,clock", [
    ("tracer", "rk4", "off", "global"), ("full", "rk4", "off", "global"),
    ("full", "euler", "off", "global"), ("full", "rk4", "exponential", "global"),
    ("tracer", "rk4", "off", "per_log"), ("full", "rk4", "off", "per_log")])
def test_dropping_stopped_logs_in_place_changes_no_number(monkeypatch, level, method,
                                                          waterlogging, clock):
    """Logs that strand or leave are dropped from the compact arrays in place
    (``Tracker._drop_stopped``): the same trajectories, bit for bit, as gathering the
    floating logs again into new arrays, and the in-place path is the one taken where the
    first stage is kept."""
    real = Tracker._drop_stopped

    def go(drop):
        calls = []

        def spy(self, idx):
            done = real(self, idx) if drop else False
            calls.append(done)
            return done

        monkeypatch.setattr(Tracker, "_drop_stopped", spy)
        rng = np.random.default_rng(11)
        n = 300
        logs = Logs(rng.uniform(0.5, 29.5, n), rng.uniform(0.5, 9.5, n),
                    rng.uniform(0, np.pi, n), rng.uniform(0.5, 1.5, n), 0.1,
                    rng.uniform(500.0, 900.0, n), release_time=rng.choice([0.0, 3.0], n))
        physics = PhysicsOptions(level=level)
        if waterlogging != "off":
            physics = PhysicsOptions(level=level, waterlogging=waterlogging,
                                     saturated_density=1100.0, waterlogging_time=30.0)
        tr = Tracker(FLOW, logs, physics, method, StepOptions(max_step=0.7, clock=clock),
                     t_end=20.0, output_interval=2.5)
        tr.run()
        return tr, logs, calls

    gathered, a, c0 = go(False)
    dropped, b, c1 = go(True)
    # waterlogging changes the logs' parameters each sub-step, so their first stage is not
    # kept and the floating logs are gathered again
    assert dropped.fused and not any(c0)
    assert sum(c1) >= (5 if clock == "global" else 1) if waterlogging == "off" else not any(c1)
    assert_same_runs(dropped, b, gathered, a)
    np.testing.assert_array_equal(b.mass, a.mass)
    assert np.sum(b.status == LEFT) > 10 and np.sum(b.status == FLOATING) > 10


@pytest.mark.parametrize("compiled", ["serial", "parallel"])
def test_drop_rows_in_place_equals_a_gather(compiled):
    """``fused.drop_rows`` in place gives ``a[pos]`` for any ascending subset ``pos``: a few
    rows dropped, most of them, the first or last ones, none, all but one."""
    from driftlog.fused import drop_rows

    kernel = getattr(drop_rows, compiled)
    rng = np.random.default_rng(2)
    for n, keep in [(5000, 0.999), (5000, 0.5), (5000, 0.02), (3000, 1.0), (37, 0.7),
                    (1, 1.0)]:
        for cut in ("random", "head", "tail", "one"):
            a = rng.normal(size=(n, 7))
            if cut == "random":
                pos = np.flatnonzero(rng.random(n) < keep)
            elif cut == "head":
                pos = np.arange(n // 3, n)
            elif cut == "tail":
                pos = np.arange(0, n - n // 3)
            else:
                pos = np.array([n - 1])
            want = a[pos].copy()
            kernel(pos.astype(np.int64), a, 16)
            np.testing.assert_array_equal(a[:pos.size], want)


@pytest.mark.parametrize("where", ["face", "node"])
def test_gradients_left_out_until_asked_for(where):
    """``node_values(t, gradients=False)`` leaves the recovered gradient columns out (NaN);
    asked for later, they are the numbers computed at once; the other columns unchanged."""
    from driftlog.flow import Q_UX

    for t in (1.0, 5.0, 6.0, 13.0):
        lean, full = (draining_channel(MESH, TIMES, where) for _ in range(2))
        a, wa, _ = lean.node_values(t, gradients=False)
        b, wb, _ = full.node_values(t)
        assert wa == wb
        nq = a.shape[1] // 2
        cols = np.r_[0:Q_UX, nq:nq + Q_UX]
        np.testing.assert_array_equal(a[:, cols], b[:, cols])
        assert np.isnan(a[:, Q_UX:nq]).all() and np.isfinite(b).all()
        np.testing.assert_array_equal(lean.node_values(t)[0], b)  # now computed: the same


@pytest.mark.parametrize("where", ["face", "node"])
def test_tracer_without_rotation_reads_no_gradients(monkeypatch, where):
    """Tracer mode without rotation takes the flow's node values without the gradients
    (``Tracker._tracer_values``), and the two snapshots apart (``node_snapshot_pair``): the
    same trajectories as the pair's full node values side by side, bit for bit."""
    from driftlog.flow import MeshFlowField
    from driftlog.tracker import Tracker

    pair = MeshFlowField.node_snapshot_pair
    grads = []

    def spy(self, t, gradients=True):
        grads.append(gradients)
        return pair(self, t, gradients)

    monkeypatch.setattr(MeshFlowField, "node_snapshot_pair", spy)
    lean, a = run("tracer", False, "rk4", fused=True, flow=draining_channel(MESH, TIMES, where))
    assert grads and not any(grads)  # asked without the gradients
    real = Tracker._tracer_values
    asked = []

    def always(self, t):
        vi, vj, cj, w = real(self, t)
        asked.append(cj)
        vals, w2, _ = self._kernel.node_values(t)  # with the gradients, side by side
        assert w2 == w
        return vals, vals, vals.shape[1] // 2, w

    monkeypatch.setattr(Tracker, "_tracer_values", always)
    full, b = run("tracer", False, "rk4", fused=True, flow=draining_channel(MESH, TIMES, where))
    assert 0 in asked  # the tracer took the two snapshots apart
    assert_same_runs(full, b, lean, a)
    assert np.sum(b.status == LEFT) > 10


def _tidal_bank(mesh):
    """The draining channel with a bank (12 < x < 20, y > 6) rising 0.25 m per metre to the
    north under a level that falls from 1.2 m to 0.3 m by t = 6 s and is back at 1.2 m at
    t = 12 s (snapshots every 2 s, linear in time): logs strand on the bank as the water
    leaves it, and the flow lifts them again."""
    from driftlog.flow import MeshFlowField

    xc, yc = mesh.face_x, mesh.face_y
    bank = (xc > 12) & (xc < 20) & (yc > 6)
    bed = np.where(bank, 0.25 * (yc - 6.0), 0.0)
    times = np.array([0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 24.0])
    h, hu, hv = [], [], []
    for t, level in zip(times, [1.2, 0.9, 0.6, 0.3, 0.6, 0.9, 1.2, 1.2], strict=True):
        depth = np.where(bank, np.maximum(level - bed, 0.0), 0.6)
        u = 0.5 + 0.3 * np.sin(yc / 2.0) + 0.01 * t
        v = 0.25 * np.cos(xc / 3.0)
        h.append(depth)
        hu.append(depth * u)
        hv.append(depth * v)
    return MeshFlowField.from_arrays(mesh, bed, times, np.array(h), np.array(hu),
                                     np.array(hv))


@pytest.mark.parametrize("level,method", [("tracer", "rk4"), ("tracer", "euler"),
                                          ("full", "rk4"), ("full", "euler")])
@pytest.mark.parametrize("fraction", [1.0 / 16.0, 0.5])
def test_holes_left_by_stopped_logs_change_no_number(monkeypatch, level, method, fraction):
    """Logs that stop leave their rows in the compact arrays as holes (``Tracker._make_holes``,
    skipped by the settling kernels, dropped together later): the same records, final logs
    and steps, bit for bit, as dropping every stopped log's rows at once; also where logs
    stranded in a hole are lifted again by the flow and where logs are released later."""
    from driftlog.trajectory import TrajectoryWriter

    flow = _tidal_bank(MESH)
    made, relifted = [], []
    real_make, real_rows = Tracker._make_holes, Tracker._hole_rows

    def make(self, stopped):
        done = real_make(self, stopped)
        made.append(done)
        return done

    def rows(self, pos):
        hit = real_rows(self, pos)
        relifted.append(hit)
        return hit

    monkeypatch.setattr(Tracker, "_make_holes", make)
    monkeypatch.setattr(Tracker, "_hole_rows", rows)
    monkeypatch.setattr(Tracker, "HOLE_FRACTION", fraction)

    class Keep(TrajectoryWriter):
        def __init__(self):
            self.rows = []

        def record(self, t, index, columns):
            self.rows.append((t, index.copy(), {k: np.array(v) for k, v in columns.items()}))

    def go(lazy):
        rng = np.random.default_rng(3)
        n = 400
        logs = Logs(rng.uniform(0.5, 29.5, n), rng.uniform(0.5, 9.5, n),
                    rng.uniform(0, np.pi, n), rng.uniform(0.5, 1.5, n), 0.1,
                    rng.uniform(500.0, 900.0, n), release_time=rng.choice([0.0, 2.2, 15.0], n))
        w = Keep()
        # no landing on the snapshots: nothing but the releases and the records at 0, 10 and
        # 20 s samples every row again (and drops the holes) between a log's stranding and
        # its lift
        tr = Tracker(flow, logs, PhysicsOptions(level=level), method,
                     StepOptions(max_step=0.4, land_on_snapshots=False), t_end=20.0,
                     output_interval=10.0, writer=w)
        tr.lazy_drop = lazy
        tr.run()
        return tr, logs, w.rows

    ta, a, ra = go(False)
    assert not any(made) and not any(relifted)
    tb, b, rb = go(True)
    assert tb.act.size == np.sum(b.status == FLOATING)  # the holes are gone at the end
    assert sum(made) >= 3  # holes were made
    if fraction == 0.5:  # and logs lifted from their holes (holes kept longer)
        assert any(relifted)
    assert_same_runs(tb, b, ta, a)
    assert len(ra) == len(rb)
    for (t0, i0, c0), (t1, i1, c1) in zip(ra, rb, strict=True):
        assert t0 == t1
        np.testing.assert_array_equal(i0, i1)
        for k in c0:
            np.testing.assert_array_equal(c0[k], c1[k], err_msg=k)
    # the scene: logs left through the outlet, stranded on the bank, lifted and floating
    assert np.sum(b.status == LEFT) > 10 and np.sum(b.status == FLOATING) > 10


@pytest.mark.parametrize("level,method,clock", [
    ("full", "rk4", "global"), ("tracer", "rk4", "global"), ("full", "rk4", "per_log")])
def test_parallel_kernels_give_the_serial_numbers(monkeypatch, level, method, clock):
    """The multi-threaded compilations of the tracker's per-log kernels (taken from
    ``driftlog._numba.PARALLEL_MIN`` logs on; lowered here so that 200 logs take them): they
    compile (numba's parfors analysis refused a nested tuple returned by an inlined RK4 step,
    which no serial run shows) and give the serial kernels' trajectories bit for bit (each
    log is computed on its own)."""
    import driftlog._numba as nbmod

    def go(parallel_min):
        monkeypatch.setattr(nbmod, "PARALLEL_MIN", parallel_min)
        rng = np.random.default_rng(5)
        n = 200
        logs = Logs(rng.uniform(0.5, 29.5, n), rng.uniform(0.5, 9.5, n),
                    rng.uniform(0, np.pi, n), rng.uniform(0.5, 1.5, n), 0.1,
                    rng.uniform(500.0, 900.0, n))
        tr = Tracker(FLOW, logs, PhysicsOptions(level=level), method,
                     StepOptions(max_step=0.7, clock=clock), t_end=8.0, output_interval=4.0)
        tr.run()
        return tr, logs

    serial, a = go(1 << 40)
    parallel, b = go(1)
    assert parallel.fused
    assert_same_runs(parallel, b, serial, a)
    assert np.sum(b.status == FLOATING) > 10
