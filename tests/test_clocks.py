"""Per-log clocks (driftlog.clocks, [integrator] clock = "per_log").

Each log under the per-log clock takes exactly the sub-steps the global clock gives it when it
is alone: a crowd run per log reproduces every single-log global run bit for bit; exact
solutions converge at the integrator's order with per-log steps.
"""
import numpy as np
import pytest
from conftest import draining_channel

from driftlog.analytic import UniformFlow, on_mesh
from driftlog.errors import ScenarioError
from driftlog.logs import FLOATING, LEFT, RESTING, STRANDED, Logs
from driftlog.mesh import Mesh
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

MESH = Mesh.regular_grid(30, 10, 1.0)
TIMES = np.arange(0.0, 21.0, 4.0)


FLOW = draining_channel(MESH, TIMES)
N = 120


def crowd(rows=slice(None)):
    rng = np.random.default_rng(7)
    x, y = rng.uniform(0.5, 29.5, N), rng.uniform(0.5, 9.5, N)
    th, L, rho = rng.uniform(0, np.pi, N), rng.uniform(0.5, 1.5, N), rng.uniform(500.0, 900.0, N)
    return Logs(x[rows], y[rows], th[rows], L[rows], 0.1, rho[rows])


def run(logs, clock, level="full", method="rk4", flow=FLOW, **step):
    tr = Tracker(flow, logs, PhysicsOptions(level=level), method,
                 StepOptions(max_step=step.pop("max_step", 0.7), clock=clock, **step),
                 t_end=20.0, output_interval=2.5)
    tr.run()
    return tr, logs


@pytest.mark.parametrize("method,level", [("rk4", "full"), ("rk4", "tracer"),
                                          ("euler", "drag")])
def test_each_log_of_a_crowd_moves_as_alone_under_the_global_clock(method, level):
    # the draining channel of test_fused: logs leave through the outlet, strand on the drying
    # bank, cross snapshot times (the node pair switches inside a log's own steps)
    tr, b = run(crowd(), "per_log", level, method)
    assert np.sum(b.status == LEFT) > 5 and np.sum(b.status == FLOATING) > 5
    if level != "tracer":
        assert np.sum((b.status == STRANDED) | (b.status == RESTING)) > 0
    # logs meet only at outputs and snapshots (8 outputs and 5 snapshots: 12 distinct times)
    assert tr.stats["substeps"] == 12
    assert tr.stats["log_substeps"] > 20 * tr.stats["substeps"]
    picked = list(np.flatnonzero(b.status == LEFT)[:3]) + list(
        np.flatnonzero(b.status == FLOATING)[:3]) + list(
        np.flatnonzero((b.status == STRANDED) | (b.status == RESTING))[:2])
    for i in picked:
        _, one = run(crowd(slice(i, i + 1)), "global", level, method)
        np.testing.assert_array_equal(one.state[0], b.state[i])
        assert one.status[0] == b.status[i]
        assert one.face[0] == b.face[i]


def test_one_log_same_trajectory_under_both_clocks():
    g, a = run(crowd(slice(3, 4)), "global")
    p, b = run(crowd(slice(3, 4)), "per_log")
    np.testing.assert_array_equal(a.state, b.state)
    assert p.stats["log_substeps"] == g.stats["substeps"]
    assert p.stats["min_dt"] == g.stats["min_dt"] and p.stats["max_dt"] == g.stats["max_dt"]


UNIFORM_MESH = Mesh.regular_grid(40, 6, 1.0)


@pytest.mark.parametrize("method,order", [("rk4", 4), ("euler", 1)])
def test_exact_solution_converges_at_order_with_per_log_steps(method, order):
    # docs/model.md 15.C: quadratic drag from rest in a uniform flow, exact; three log lengths,
    # so three own step sequences (length and drag relaxation bounds) in one per-log run
    U0, cd, rho, rho_b, r = 1.5, 1.1, 1000.0, 600.0, 0.1
    L = np.array([0.5, 1.0, 2.0])
    flow = on_mesh(UniformFlow(U0, 0.0, depth=2.0), UNIFORM_MESH)
    T = 15.0
    errors = []
    fractions = (0.4, 0.2, 0.1) if order == 4 else (0.02, 0.01, 0.005)
    for lf in fractions:
        logs = Logs(np.full(3, 2.0), np.array([1.5, 3.0, 4.5]), 0.0, L, r, rho_b, u=0.0)
        tr = Tracker(flow, logs, PhysicsOptions(drag_law="constant", drag_coefficient=cd),
                     method, StepOptions(length_fraction=lf, drag_fraction=lf,
                                         clock="per_log"),
                     t_end=T, output_interval=T, hydro_step=T, initial_velocity="given")
        tr.run()
        assert tr.stats["substeps"] == 1  # no synchronisation before the end
        assert np.all(logs.status == FLOATING)
        beta = cd * rho * np.pi * r * r / (2 * (rho_b + rho / 2) * logs.volume)
        x = 2.0 + U0 * T - np.log(1 + beta * U0 * T) / beta
        errors.append(np.abs(logs.state[:, 0] - x))
    errors = np.array(errors)
    assert errors[-1].max() < (2e-6 if order == 4 else 3e-3)
    p = np.log2(errors[:-1] / errors[1:])
    assert np.all(np.abs(p - order) < 0.35), p


def test_per_log_clock_needs_the_fused_mesh_kernels():
    with pytest.raises(ScenarioError, match="integrator.clock"):
        Tracker(UniformFlow(1.0, 0.0), Logs([0.0], [0.0]), t_end=1.0,
                step=StepOptions(clock="per_log"))
    with pytest.raises(ScenarioError, match="exponential"):
        Tracker(FLOW, Logs([5.0], [5.0]), method="exponential", t_end=1.0,
                step=StepOptions(clock="per_log"))
    with pytest.raises(ScenarioError, match="must be one of"):
        Tracker(FLOW, Logs([5.0], [5.0]), t_end=1.0, step=StepOptions(clock="local"))


STILL = Mesh.regular_grid(40, 10, 1.0)


def cradle(clock, bystanders=True, mirrored=False):
    """Newton's cradle: five logs end to end, a sixth hits the row at 1 m/s (eps = 1, no
    forces: still water, no drag); bystanders drift and spin far from it."""
    from driftlog.contact import ContactModel

    x = [4.0] + [8.0 + 1.21 * k for k in range(5)]
    y, th, u, om = [5.0] * 6, [0.0] * 6, [1.0] + [0.0] * 5, [0.0] * 6
    if mirrored:  # a second row at y = 2, hit from the right
        x += [24.0 + 1.21 * k for k in range(5)] + [33.0]
        y += [2.0] * 6
        th += [0.0] * 6
        u += [0.0] * 5 + [-1.0]
        om += [0.0] * 6
    if bystanders:
        x += [3.0, 12.0, 20.0, 30.0]
        y += [1.5, 8.5, 1.5, 8.5]
        th += [0.3, 1.0, 2.0, 2.5]
        u += [0.4, 0.1, 0.8, -0.3]
        om += [0.05, -0.02, 0.5, 0.0]
    n = len(x)
    logs = Logs(np.array(x), np.array(y), np.array(th), 1.0, 0.1, 700.0, u=np.array(u),
                v=0.0, omega=np.array(om))
    flow = on_mesh(UniformFlow(0.0, 0.0, depth=1.0), STILL)
    tr = Tracker(flow, logs, PhysicsOptions(level="drag", drag_law="linear", linear_drag=0.0,
                                            rotation=True),
                 "rk4", StepOptions(clock=clock), contact=ContactModel(restitution=1.0,
                                                                      rest_speed=0.0),
                 t_end=16.0, output_interval=2.0, initial_velocity="given")
    assert n == len(logs)
    tr.run()
    return tr, logs


def test_newtons_cradle_keeps_momentum_and_energy_on_per_log_clocks():
    from driftlog.contact.impulses import kinetic_energy, momenta

    results = {}
    for clock in ("global", "per_log"):
        tr, logs = cradle(clock)
        S = logs.state
        m, inertia = logs.mass, logs.inertia
        results[clock] = (tr, S.copy())
        assert np.all(logs.status == FLOATING)
        # the momentum went down the row: the last log moves on at 1 m/s, the others stopped
        np.testing.assert_allclose(S[5, 3], 1.0, atol=1e-9)
        np.testing.assert_allclose(S[:5, 3], 0.0, atol=1e-9)
        e = kinetic_energy(S, m, inertia)
        e0 = 0.5 * m[0] * 1.0 + 0.5 * np.sum(m[6:] * np.array([0.4, 0.1, 0.8, 0.3]) ** 2) + \
            0.5 * np.sum(inertia[6:] * np.array([0.05, -0.02, 0.5, 0.0]) ** 2)
        assert e == pytest.approx(e0, rel=1e-12)
        p = np.array(momenta(S, m, inertia))
        assert p[0] == pytest.approx(m[0] * 1.0 + np.sum(m[6:] * [0.4, 0.1, 0.8, -0.3]),
                                     rel=1e-12)
        assert abs(p[1]) < 1e-12
    g, p = results["global"], results["per_log"]
    # the same collisions: the same end states to round-off; the bystanders on their own
    # clocks, the row of the cradle as a contact set
    np.testing.assert_allclose(p[1], g[1], atol=1e-9)
    assert p[0].stats["contact_set"] == 6
    assert p[0].stats["log_substeps"] > 0
    assert p[0].contact.stats["events"] == g[0].contact.stats["events"] >= 5


def test_two_cradles_are_two_islands_on_their_own_clocks():
    g, a = cradle("global", bystanders=False, mirrored=True)
    p, b = cradle("per_log", bystanders=False, mirrored=True)
    np.testing.assert_allclose(b.state, a.state, atol=1e-9)
    # each row went through: its far end moves on at 1 m/s
    assert b.state[5, 3] == pytest.approx(1.0, abs=1e-9)
    assert b.state[6, 3] == pytest.approx(-1.0, abs=1e-9)
    # the rows never come near each other: two islands in each contact window (at least one
    # per steady-flow hydro step of 1 s)
    assert p.stats["windows"] >= 16
    assert p.stats["islands"] == 2 * p.stats["windows"]
    assert p.stats["largest_island"] == 6
    assert p.stats.get("clock_retries", 0) == 0


def test_island_kernel_records_the_same_hits_and_momentum_as_the_contact_model():
    # the cradles run through island_kernel (event-driven, conservative: one kernel for all
    # islands of a contact window); the hits (log, other body, time, impulse) are those the
    # Python contact model records on the global clock
    g, a = cradle("global", bystanders=True, mirrored=True)
    p, b = cradle("per_log", bystanders=True, mirrored=True)
    hg, hp = g.contact.drain_hits(), p.contact.drain_hits()
    og, op = np.lexsort((hg["other"], hg["log_id"], hg["time"])), np.lexsort(
        (hp["other"], hp["log_id"], hp["time"]))
    assert hg["time"].size == hp["time"].size >= 10
    np.testing.assert_array_equal(hp["log_id"][op], hg["log_id"][og])
    np.testing.assert_array_equal(hp["other"][op], hg["other"][og])
    np.testing.assert_allclose(hp["time"][op], hg["time"][og], atol=1e-9)
    np.testing.assert_allclose(hp["impulse"][op], hg["impulse"][og], rtol=1e-9)
    np.testing.assert_allclose(b.state, a.state, atol=1e-9)
    # the islands were run by the kernel in contact windows, never all logs in one (each
    # row, with a bystander that comes near it)
    assert p.stats["windows"] >= 16 and p.stats["largest_island"] <= 7 < len(b)


def rising_flow(depth0, rate, U0=1.0, T=16.0):
    """A uniform current U0 over a flat bed whose depth rises as depth0 + rate t."""
    from driftlog.flow import MeshFlowField

    times = np.arange(0.0, T + 0.1, 4.0)
    n = UNIFORM_MESH.n_faces
    h = np.array([np.full(n, depth0 + rate * t) for t in times])
    return MeshFlowField.from_arrays(UNIFORM_MESH, np.zeros(n), times, h, U0 * h, 0.0 * h)


@pytest.mark.parametrize("clock", ["global", "per_log"])
def test_a_resting_log_lifts_when_the_level_reaches_its_flotation_depth(clock):
    # docs/model.md 6 and 11.1: a heavy log (800 kg/m3) rests on the bed of a rising current
    # while a light one (200 kg/m3) floats from the start.  The level reaches the heavy log's
    # flotation depth at t* = 9.3 s, between two synchronisation times (outputs every 5 s,
    # snapshots every 4 s); the log must lift then, from rest, under both clocks (the global
    # clock within one of its sub-steps, the per-log clock at t* itself: exact solution of
    # quadratic drag from rest, 15.C).  Before the fix the per-log clock checked idle logs
    # only at the synchronisation times and lifted the log at t = 10 s (0.6 m behind).
    U0, cd, rho, T, t_star = 1.0, 1.1, 1000.0, 16.0, 9.3
    logs = Logs([2.0, 2.0], [2.0, 4.0], 0.0, 1.0, 0.1, [200.0, 800.0], u=0.0)
    h_star = float(logs.float_depth[1])
    depth0 = 0.08
    assert logs.float_depth[0] < depth0 < h_star
    flow = rising_flow(depth0, (h_star - depth0) / t_star, U0, T)
    tr = Tracker(flow, logs, PhysicsOptions(drag_law="constant", drag_coefficient=cd), "rk4",
                 StepOptions(length_fraction=0.1, drag_fraction=0.1, clock=clock),
                 t_end=T, output_interval=5.0)
    tr.run()
    assert np.all(logs.status == FLOATING)
    r, rho_b = 0.1, 800.0
    beta = cd * rho * np.pi * r * r / (2 * (rho_b + rho / 2) * logs.volume[1])
    tau = T - t_star
    x = 2.0 + U0 * tau - np.log(1 + beta * U0 * tau) / beta
    err = abs(logs.state[1, 0] - x)
    if clock == "per_log":
        assert err < 1e-4, err
    else:
        # lifted at the end of the sub-step in which the level crossed h*
        assert err <= U0 * tr.stats["max_dt"], (err, tr.stats["max_dt"])
        assert tr.stats["max_dt"] < 0.15


# ------------------------------------------------ Moreau-Jean islands (driftlog.moreau_kernel)
def moreau_cradle(clock, kernel=True):
    """The cradle above with Moreau-Jean contacts (eps = 1, no forces)."""
    from driftlog.contact import ContactModel

    x = [4.0] + [8.0 + 1.21 * k for k in range(5)] + [3.0, 12.0, 20.0, 30.0]
    y = [5.0] * 6 + [1.5, 8.5, 1.5, 8.5]
    th = [0.0] * 6 + [0.3, 1.0, 2.0, 2.5]
    u = [1.0] + [0.0] * 5 + [0.4, 0.1, 0.8, -0.3]
    om = [0.0] * 6 + [0.05, -0.02, 0.5, 0.0]
    logs = Logs(np.array(x), np.array(y), np.array(th), 1.0, 0.1, 700.0, u=np.array(u), v=0.0,
                omega=np.array(om))
    model = ContactModel(method="moreau", restitution=1.0, rest_speed=0.0)
    model.island_kernel = kernel
    tr = Tracker(on_mesh(UniformFlow(0.0, 0.0, depth=1.0), STILL), logs,
                 PhysicsOptions(level="drag", drag_law="linear", linear_drag=0.0, rotation=True),
                 "rk4", StepOptions(clock=clock), contact=model, t_end=16.0,
                 output_interval=2.0, initial_velocity="given")
    tr.run()
    return tr, logs


def test_moreau_cradle_keeps_momentum_and_energy_in_the_island_kernel():
    from driftlog.contact.impulses import kinetic_energy, momenta

    tr, logs = moreau_cradle("per_log")
    S, m, inertia = logs.state, logs.mass, logs.inertia
    np.testing.assert_allclose(S[5, 3], 1.0, atol=1e-9)  # the momentum went down the row
    np.testing.assert_allclose(S[:5, 3], 0.0, atol=1e-9)
    e0 = 0.5 * m[0] + 0.5 * np.sum(m[6:] * np.array([0.4, 0.1, 0.8, 0.3]) ** 2) + \
        0.5 * np.sum(inertia[6:] * np.array([0.05, -0.02, 0.5, 0.0]) ** 2)
    assert kinetic_energy(S, m, inertia) == pytest.approx(e0, rel=1e-12)
    p = np.array(momenta(S, m, inertia))
    assert p[0] == pytest.approx(m[0] + np.sum(m[6:] * [0.4, 0.1, 0.8, -0.3]), rel=1e-12)
    assert abs(p[1]) < 1e-12
    assert tr.stats["windows"] >= 16 and tr.stats["largest_island"] <= 7
    assert tr.contact.stats["pgs_iterations"] > 0
    # the same islands through the Python contact model: the same numbers; the global clock's
    # Moreau steps: the same collisions
    _, ref = moreau_cradle("per_log", kernel=False)
    np.testing.assert_array_equal(logs.state, ref.state)
    _, glob = moreau_cradle("global")
    np.testing.assert_allclose(logs.state, glob.state, atol=1e-9)


def moreau_pile(kernel, T=20.0, relative=True, iterations=200):
    """14 logs (some seeded overlapping) drift on a current onto two piers between two walls,
    Moreau-Jean with eps = 0.3: islands that merge, split, touch walls and piers."""
    from driftlog.contact import ContactModel
    from driftlog.contact.obstacles import Obstacles

    rng = np.random.default_rng(3)
    n = 14
    logs = Logs(rng.uniform(2, 14, n), rng.uniform(2.5, 7.5, n), rng.uniform(0, np.pi, n),
                1.0, 0.1, 700.0)
    obs = Obstacles()
    obs.add_circle([20.0, 4.6], 0.4, name="pier1")
    obs.add_circle([20.0, 5.8], 0.4, name="pier2")
    obs.add_segments([[0.0, 2.0], [30.0, 2.0]], name="south")
    obs.add_segments([[0.0, 8.0], [30.0, 8.0]], name="north")
    model = ContactModel(obs, method="moreau", restitution=0.3)
    model.island_kernel = kernel
    model.relative_motion = relative
    model.iterations = iterations
    tr = Tracker(on_mesh(UniformFlow(0.6, 0.05, depth=1.0), MESH), logs,
                 PhysicsOptions(level="full"), "rk4", StepOptions(clock="per_log"),
                 contact=model, t_end=T, output_interval=5.0)
    tr.run()
    return tr, logs


def test_moreau_island_kernel_equals_the_contact_model_island_by_island():
    # docs/model.md 11.1: the kernel runs each island with the contact model's Moreau-Jean
    # steps; ContactModel.island_kernel = False runs the very same islands through the
    # Python model.  Same arithmetic, same contact order here (islands of a few logs): the
    # same states, hits, obstacle impulses and statistics.  Bit for bit on the step bound by
    # each log's own motion, whose steps keep at most two contacts of a step apart in order.
    # Sweeps capped at 20, so that some steps stop at the cap (none did at 200 since the
    # velocity pass, docs/model.md eq. (90))
    k, a = moreau_pile(True, relative=False, iterations=20)
    p, b = moreau_pile(False, relative=False, iterations=20)
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.status, b.status)
    hk, hp = k.contact.drain_hits(), p.contact.drain_hits()
    ok, op = (np.lexsort((h["other"], h["log_id"], h["time"])) for h in (hk, hp))
    assert hk["time"].size == hp["time"].size >= 40
    assert np.sum(hk["other"] < 0) >= 5  # piers and walls hit too
    for key in ("time", "log_id", "other", "impulse", "x", "y"):
        np.testing.assert_allclose(hk[key][ok], hp[key][op], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(k.contact.obstacle_impulse, p.contact.obstacle_impulse,
                               rtol=1e-12, atol=1e-9)
    assert np.abs(k.contact.obstacle_impulse[:2]).max() > 10.0  # the piers hold logs
    for key in ("islands", "largest_island", "windows", "clock_retries"):
        assert k.stats[key] == p.stats[key], key
    assert k.stats["clock_retries"] > 0  # the closure was exercised
    for key in ("pgs_max_iterations", "max_contacts", "min_gap"):
        assert k.contact.stats[key] == p.contact.stats[key], key
    # steps whose Gauss-Seidel solve stopped at its cap unconverged, counted by both (the
    # Python model takes more steps: it redoes an island's window where the kernel does not)
    assert 0 < k.contact.stats["pgs_capped"] <= p.contact.stats["pgs_capped"]


def test_moreau_island_kernel_matches_the_contact_model_on_the_relative_bound():
    # with the default bound (81) on the pairs' relative motion, steps are longer and take
    # several contacts together; the kernel sweeps them in the order of its logs, the Python
    # model in the broad phase's: Gauss-Seidel stops at another point within its tolerance
    # (1e-9 of the largest speed), so the states agree to that, until the pile's collisions
    # amplify it (after 10 s here)
    k, a = moreau_pile(True, T=10.0)
    p, b = moreau_pile(False, T=10.0)
    np.testing.assert_allclose(a.state, b.state, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(a.status, b.status)
    hk, hp = k.contact.drain_hits(), p.contact.drain_hits()
    assert hk["time"].size == hp["time"].size >= 5
    np.testing.assert_allclose(np.sort(hk["time"]), np.sort(hp["time"]), rtol=1e-9)
    np.testing.assert_allclose(k.contact.obstacle_impulse, p.contact.obstacle_impulse,
                               rtol=1e-9, atol=1e-9)
    assert np.abs(k.contact.obstacle_impulse).max() > 1.0


def test_island_pairs_are_the_broad_phase_pairs():
    # moreau_kernel.island_pairs (all pairs for small islands, sort and sweep for large ones)
    # finds the pairs of broadphase.grid_pairs and StaticGrid.query, ordered by log then
    # other body
    from driftlog.contact.broadphase import StaticGrid, grid_pairs, log_boxes
    from driftlog.island_kernel import ALL_PAIRS, island_pairs

    rng = np.random.default_rng(11)
    for n, across in ((5, False), (300, False), (300, True)):
        S = np.zeros((n, 6))
        S[:, 0], S[:, 1] = rng.uniform(0, 0.4 * n, n), rng.uniform(0, 6, n)
        S[:, 2] = rng.uniform(0, np.pi, n)
        length, radius = rng.uniform(0.5, 2.0, n), np.full(n, 0.1)
        margin = rng.uniform(0.0, 0.3, n)
        caps = np.array([[0.0, 3.0, 0.4 * n, 3.0, 0.0], [5.0, 1.0, 5.0, 1.0, 0.5],
                         [1.0, 0.0, 1.5, 6.0, 0.05]])
        if across:  # the same scene turned a quarter: the sweep runs along y
            S[:, [0, 1]] = S[:, [1, 0]]
            S[:, 2] = 0.5 * np.pi - S[:, 2]
            caps = caps[:, [1, 0, 3, 2, 4]].copy()
        ocaps = np.array([0, 2], np.int64)
        pairs, nll = island_pairs(S, length, radius, n, margin, caps, ocaps)
        ex, ey = np.empty(n), np.empty(n)
        log_boxes(S, length, radius, margin, ex, ey)
        ll = grid_pairs(S[:, 0].copy(), S[:, 1].copy(), ex, ey)
        ll = ll[np.lexsort((ll[:, 1], ll[:, 0]))]
        lo = StaticGrid(caps, 1.0).query(S[:, 0].copy(), S[:, 1].copy(), ex, ey)
        lo = lo[np.isin(lo[:, 1], ocaps)]
        lo[:, 1] = -(np.searchsorted(ocaps, lo[:, 1]) + 1)
        lo = lo[np.lexsort((-lo[:, 1], lo[:, 0]))]
        assert (n + ocaps.size > ALL_PAIRS) == (n == 300)
        assert nll == len(ll) and (n == 5 or nll > 50)
        np.testing.assert_array_equal(pairs, np.vstack([ll, lo]))


def test_a_resting_log_lifts_within_a_contact_window_with_contacts_on():
    # docs/model.md 11.1 eq. (83): with contacts the idle logs are not sampled at every
    # contact window's end; their lift times are found once per interval and a log lifts at
    # the first window end at or after it (within one window, 0.5 L / |U| = 0.5 s here, of
    # the exact t* = 9.3 s)
    from driftlog.contact import ContactModel

    U0, cd, rho, T, t_star = 1.0, 1.1, 1000.0, 16.0, 9.3
    logs = Logs([2.0, 2.0], [2.0, 4.0], 0.0, 1.0, 0.1, [200.0, 800.0], u=0.0)
    h_star = float(logs.float_depth[1])
    depth0 = 0.08
    flow = rising_flow(depth0, (h_star - depth0) / t_star, U0, T)
    tr = Tracker(flow, logs, PhysicsOptions(drag_law="constant", drag_coefficient=cd), "rk4",
                 StepOptions(length_fraction=0.1, drag_fraction=0.1, clock="per_log"),
                 contact=ContactModel(method="moreau"), t_end=T, output_interval=5.0)
    tr.run()
    assert np.all(logs.status == FLOATING)
    assert tr.stats["lifted"] == 1
    beta = cd * rho * np.pi * 0.01 / (2 * (800.0 + rho / 2) * logs.volume[1])
    x = 2.0 + U0 * (T - t_star) - np.log(1 + beta * U0 * (T - t_star)) / beta
    err = abs(logs.state[1, 0] - x)
    assert err <= 0.5 * U0, err
    assert logs.state[1, 0] < x + 1e-9  # lifted at or after t*, never before


def drifting_raft(clock, speed, relative=True):
    """Three logs side by side, 1 mm apart, carried at the current's own speed (no drag), past
    a wall 2 m to the side: Moreau-Jean, both clocks."""
    from driftlog.contact import ContactModel
    from driftlog.contact.obstacles import Obstacles

    y = 5.0 + 0.201 * np.arange(3)
    logs = Logs(np.full(3, 5.0), y, 0.0, 1.0, 0.1, 700.0, u=speed, v=0.0, omega=0.0)
    obs = Obstacles()
    obs.add_segments([[0.0, 3.0], [400.0, 3.0]], name="bank")
    model = ContactModel(obs, method="moreau", restitution=0.3)
    model.relative_motion = relative
    mesh = Mesh.regular_grid(100, 2, 5.0)
    tr = Tracker(on_mesh(UniformFlow(speed, 0.0, depth=1.0), mesh), logs,
                 PhysicsOptions(level="full"), "rk4",
                 StepOptions(clock=clock, max_step=0.25, length_fraction=1e9, angle_step=1e9),
                 contact=model, t_end=10.0, output_interval=5.0, initial_velocity="given")
    tr.run()
    return tr, logs


@pytest.mark.parametrize("clock", ["global", "per_log"])
def test_moreau_step_near_contacts_follows_the_pairs_relative_motion(clock):
    # docs/model.md eq. (81): what limits a Moreau-Jean step near contacts is how far the two
    # bodies of a pair move against each other (the contact geometry is linearised at the
    # step's start), not how fast the raft drifts: three logs 1 mm apart carried along a bank
    # take the steps of their own bound (max_step 0.25 s; per-log clocks: contact windows of
    # half a length's travel, 0.125 s at 4 m/s), whatever the drift, and keep their places in
    # the raft (Galilean invariance).  Bounding each log's own speed (before 2026-12-02) took
    # 0.25 r per step: 1,600 steps at 4 m/s.
    for speed in (0.5, 4.0):
        tr, logs = drifting_raft(clock, speed)
        np.testing.assert_allclose(logs.state[:, 0], 5.0 + 10.0 * speed, rtol=1e-12)
        np.testing.assert_allclose(logs.state[:, 1], 5.0 + 0.201 * np.arange(3), rtol=1e-12)
        np.testing.assert_allclose(logs.state[:, 3], speed, rtol=1e-12)
        window = 0.5 * 1.0 / speed if clock == "per_log" else np.inf
        assert tr.contact.stats["advances"] <= 10.0 / min(0.25, window) + 2
    tr, _ = drifting_raft(clock, 4.0, relative=False)
    assert tr.contact.stats["advances"] >= 4.0 * 10.0 / (0.25 * 0.1)


@pytest.mark.parametrize("clock,kernel", [("global", True), ("per_log", True),
                                          ("per_log", False)])
def test_moreau_pushes_crossed_logs_apart_not_through(clock, kernel):
    # docs/model.md eq. (86): log A's right end lies 0.05 m across log B's axis (axes crossed,
    # as two logs stranded across each other float again).  The least translation moves A back
    # (-x) and B on (+x); A's end contact across B's axis has the opposite normal and, kept,
    # drove the pair into each other (the overlap grew from 0.25 to 0.40 m over 20 s, and in a
    # crowd the two opposite contacts traded growing impulses).  At rest in still water: apart
    # within the slop, along the least translation, no velocity made
    from driftlog.contact import ContactModel
    from driftlog.contact.geometry import capsule_gap, log_endpoints
    from driftlog.contact.obstacles import Obstacles

    logs = Logs([5.0, 5.45, 7.0], [5.0, 5.0, 5.0], [0.0, np.pi / 2, 0.3], 1.0, 0.1, 700.0)
    model = ContactModel(Obstacles(), method="moreau", restitution=0.3)
    model.island_kernel = kernel
    tr = Tracker(on_mesh(UniformFlow(0.0, 0.0, depth=1.0), Mesh.regular_grid(12, 10, 1.0)),
                 logs, PhysicsOptions(level="full"), "rk4", StepOptions(clock=clock),
                 contact=model, t_end=20.0, output_interval=5.0)
    tr.run()
    S = logs.state
    out = np.empty(5)
    capsule_gap(*log_endpoints(S[0, 0], S[0, 1], S[0, 2], 1.0), 0.1,
                *log_endpoints(S[1, 0], S[1, 1], S[1, 2], 1.0), 0.1, out)
    assert out[0] > -0.01  # from -0.25
    assert S[0, 0] < 4.9 and S[1, 0] > 5.55  # each moved away from the other
    np.testing.assert_allclose(S[:2, 1], 5.0, atol=1e-12)
    np.testing.assert_allclose(S[:2, 2], [0.0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(S[:, 3:], 0.0, atol=1e-12)
    np.testing.assert_array_equal(S[2], [7.0, 5.0, 0.3, 0.0, 0.0, 0.0])


def test_union_is_numpys():
    from driftlog.clocks import _union

    rng = np.random.default_rng(5)
    for n, m in ((0, 0), (0, 3), (5, 0), (1, 1), (200, 40), (3000, 700)):
        a = np.sort(rng.choice(4 * (n + m) + 1, n, replace=False))
        b = np.sort(rng.choice(4 * (n + m) + 1, m, replace=False))  # may repeat a's
        u = _union(a, b)
        assert u.dtype == np.int64 and np.array_equal(u, np.union1d(a, b))
    assert np.array_equal(_union(np.array([3, 9]), np.array([1, 9, 12])), [1, 3, 9, 12])


def test_window_end_first_stage_is_what_the_next_window_would_evaluate(monkeypatch):
    """A contact window leaves the first stage of every compact row (``_d0_window``): the
    free logs' from their last sub-step, the islands' logs' evaluated there; the next window's
    free advance uses it instead of evaluating every row again.  Checked against that full
    evaluation at every window that uses it, on the Moreau pile (islands that merge and
    split, walls, piers) and with event-driven contacts."""
    import driftlog.clocks as ck
    from driftlog.physics import rhs_kernel

    seen = []
    orig = ck._advance_rows

    def checked(tr, stop, rows, *a, **k):
        if rows is None and tr._d0_window and not tr._d0_valid:
            D, lin = np.empty_like(tr.D0), np.empty_like(tr.lin0)
            rhs_kernel(tr.state, tr.F, tr.P, tr.opt, D, lin, True)
            seen.append((tr.D0.shape[0], np.array_equal(D, tr.D0)
                         and np.array_equal(lin, tr.lin0)))
        return orig(tr, stop, rows, *a, **k)

    monkeypatch.setattr(ck, "_advance_rows", checked)
    moreau_pile(True, T=10.0)
    n_moreau = len(seen)
    cradle("per_log")
    assert n_moreau >= 5 and len(seen) > n_moreau  # both scenes used kept stages
    assert all(ok for _, ok in seen)


@pytest.mark.parametrize("method", ["event", "moreau"])
@pytest.mark.parametrize("clock,kernel", [("global", True), ("per_log", True),
                                          ("per_log", False)])
def test_contacts_do_not_turn_logs_tracked_without_rotation(method, clock, kernel):
    # physics.rotation = "off" freezes theta and omega (docs/model.md 9): the contacts treat
    # such a log as of infinite inertia.  Before, an off-centre hit gave it an omega that the
    # water never damped (no torque without rotation) and that the contacts kept seeing: a
    # log held broadside on posts chattered (0.3 m/s) and passed them 549 N of a 505-N drag
    # with sub-steps of 0.01 s (docs/model.md 17.6).  Here a broadside log carried onto a
    # post 0.4 m off its centre: turned with rotation on, not turned with it off
    from driftlog.contact import ContactModel
    from driftlog.contact.obstacles import Obstacles

    def carried(rotation):
        logs = Logs([3.0], [5.0], [np.pi / 2], 1.5, 0.1, 700.0)
        posts = Obstacles()
        posts.add_circle([4.5, 5.4], 0.1, "post")
        model = ContactModel(posts, method=method, restitution=0.0)
        model.island_kernel = kernel
        tr = Tracker(on_mesh(UniformFlow(1.0, 0.0, depth=1.0), Mesh.regular_grid(12, 10, 1.0)),
                     logs, PhysicsOptions(level="full", rotation=rotation), "rk4",
                     StepOptions(clock=clock), contact=model, t_end=6.0, output_interval=2.0)
        tr.run()
        return logs.state[0], model

    S, model = carried(True)
    assert np.abs(model.obstacle_impulse).max() > 1.0  # the post held the log
    assert abs(S[2] - np.pi / 2) > 0.05  # and turned it
    S, model = carried(False)
    assert np.abs(model.obstacle_impulse).max() > 1.0
    assert S[2] == np.pi / 2 and S[5] == 0.0
    assert S[0] < 4.5  # held upstream of the post


def test_event_substeps_reuse_the_first_stage_bit_for_bit(monkeypatch):
    # ContactModel._event: the first stage Tracker.max_step computed at the sub-step's state
    # (or again after impulses changed it) is the step's (Tracker.advance's have_d0): the same
    # trajectories bit for bit as recomputing it, one right-hand side fewer per sub-step
    from driftlog.contact import ContactModel
    from driftlog.contact.obstacles import Obstacles

    def crowd_on_posts():
        rng = np.random.default_rng(3)
        x, y = np.meshgrid([2.0, 3.5], 1.5 + 1.2 * np.arange(6))
        logs = Logs(x.ravel(), y.ravel(), rng.uniform(-0.3, 0.3, 12), 1.0, 0.1, 700.0)
        posts = Obstacles()
        for y in (2.5, 5.0, 7.5):
            posts.add_circle([6.0, y], 0.3, f"post{y}")
        tr = Tracker(on_mesh(UniformFlow(1.0, 0.0, depth=1.0), Mesh.regular_grid(12, 10, 1.0)),
                     logs, PhysicsOptions(level="full"), "rk4", StepOptions(),
                     contact=ContactModel(posts, method="event", restitution=1.0),
                     t_end=4.0, output_interval=2.0)
        tr.run()
        return tr, logs

    tr, logs = crowd_on_posts()
    assert tr.contact.stats["events"] > 10
    advance = Tracker.advance
    monkeypatch.setattr(Tracker, "advance", lambda self, dt, have_d0=False: advance(self, dt))
    tr2, logs2 = crowd_on_posts()
    np.testing.assert_array_equal(logs.state, logs2.state)
    assert tr.stats["substeps"] == tr2.stats["substeps"]
    assert tr.stats["rhs_evaluations"] <= tr2.stats["rhs_evaluations"] - tr.stats["substeps"] + 5
