"""The contact model: conservation over thousands of collisions, no interpenetration in a
10,000-log run, a channel with bridge piers through ``driftlog.api.track``, the jam."""

import numpy as np
import pytest

from driftlog.contact import BallisticLogs, ContactJamError, ContactModel, Obstacles, run_contacts
from driftlog.contact.geometry import capsule_gap
from driftlog.contact.impulses import kinetic_energy, momenta


def _grid_logs(rng, g, spacing, L=1.0, r=0.08, speed=1.0, density=720.0):
    xs = (np.arange(g) - (g - 1) / 2) * spacing
    X, Y = np.meshgrid(xs, xs)
    n = g * g
    S = np.zeros((n, 6))
    S[:, 0], S[:, 1] = X.ravel(), Y.ravel()
    S[:, 2] = rng.uniform(0, np.pi, n)
    S[:, 3:5] = rng.normal(0, speed, (n, 2))
    S[:, 5] = rng.normal(0, 1, n)
    return BallisticLogs(S, L, r, density)


@pytest.mark.parametrize("backend", ["native", "fcl"])
def test_closed_box_conserves_energy(rng, backend):
    """eps = 1 in a closed box (walls: infinite mass): a thousand collisions and more, kinetic
    energy (translation + rotation) to round-off.  FCL (a Python loop): a smaller box."""
    g, side, t_end, least = (7, 10.0, 20.0, 1000) if backend == "native" else (3, 4.5, 8.0, 60)
    b = _grid_logs(rng, g, 1.35)
    b.state[:, :2] += side / 2
    obs = Obstacles()
    obs.add_polygon([[0, 0], [side, 0], [side, side], [0, side]], name="box")
    # the paper: eps at every speed
    m = ContactModel(obs, restitution=1.0, rest_speed=0.0, backend=backend)
    e0 = kinetic_energy(b.state, b.mass, b.inertia)
    run_contacts(m, b, t_end)
    h = m.drain_hits()
    assert len(h["time"]) > least
    assert (h["other"] == -1).sum() > least // 7 and (h["other"] >= 0).sum() > least // 2
    assert kinetic_energy(b.state, b.mass, b.inertia) == pytest.approx(e0, rel=1e-12)
    assert m.stats["min_gap"] >= -m.tolerance * 0.08
    assert np.abs(b.state[:, :2] - side / 2).max() < side / 2


def test_free_cloud_conserves_momenta(rng):
    """eps = 1, no walls, logs of different densities converging: energy, linear and angular
    momentum to round-off over thousands of collisions."""
    b = _grid_logs(rng, 9, 1.3, density=rng.uniform(500, 900, 81))
    b.state[:, 3:5] -= 0.8 * b.state[:, :2]  # converge on the centre
    m = ContactModel(restitution=1.0, rest_speed=0.0)
    e0, p0 = kinetic_energy(b.state, b.mass, b.inertia), np.array(momenta(b.state, b.mass,
                                                                           b.inertia))
    run_contacts(m, b, 10.0)
    assert m.stats["events"] > 1000
    assert kinetic_energy(b.state, b.mass, b.inertia) == pytest.approx(e0, rel=1e-12)
    p1 = np.array(momenta(b.state, b.mass, b.inertia))
    assert np.abs(p1 - p0).max() < 1e-12 * np.abs(p0).max() * 100


def _all_gaps(S, L, r):
    """Independent check: every pair with centres within L + 2r (scipy KD-tree)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(S[:, :2]).query_pairs(L + 2 * r, output_type="ndarray")
    out = np.empty(5)
    h = 0.5 * L
    c, s = np.cos(S[:, 2]) * h, np.sin(S[:, 2]) * h
    g = [capsule_gap(S[i, 0] - c[i], S[i, 1] - s[i], S[i, 0] + c[i], S[i, 1] + s[i], r,
                     S[j, 0] - c[j], S[j, 1] - s[j], S[j, 0] + c[j], S[j, 1] + s[j], r, out)
         for i, j in pairs]
    return np.array(g + [np.inf])


def test_no_interpenetration_10000_logs(rng):
    """10,000 logs packed 0.02 m apart: no pair overlaps by more than the tolerance at any
    accepted step (the model's own check at every step; an independent KD-tree check every
    50 steps).  With one sub-step for all logs, each collision cuts the step: 300 sub-steps
    see a few tens of collisions (see BENCHMARKS.md, Contacts)."""
    b = _grid_logs(rng, 100, 1.12, L=1.0, r=0.05)
    m = ContactModel(restitution=0.5)
    tol = m.tolerance * 0.05
    worst = _all_gaps(b.state, 1.0, 0.05).min()
    assert worst > 0  # packed, but apart at the start
    for k in range(300):
        m.substep(b, min(b.max_step(), 0.2))
        if k % 50 == 49:
            worst = min(worst, _all_gaps(b.state, 1.0, 0.05).min())
    assert m.stats["events"] >= 10
    assert worst >= -tol
    assert m.stats["min_gap"] >= -tol


def _channel(method, n, piers, t_end, extra=None, eps=0.5, tmp=None, count_x=(-25, 10),
             rest_speed=0.01, tolerance=1e-4):
    scen = {
        "flow": {"source": "analytic", "kind": "uniform", "velocity": [1.0, 0.0], "depth": 1.0},
        "time": {"start": 0.0, "end": t_end, "output_interval": 1.0},
        "logs": [{"seeding": "grid", "count": n, "theta": "random", "seed": 3,
                  "polygon": [[count_x[0], -3], [count_x[1], -3], [count_x[1], 3],
                              [count_x[0], 3]],
                  "length": 1.5, "radius": 0.1, "density": 700.0}],
        "contact": {"enabled": True, "method": method, "restitution": eps,
                    "max_events": 2000, "rest_speed": rest_speed, "tolerance": tolerance},
        "obstacles": piers + [
            {"name": "left_bank", "type": "segments", "points": [[-30, 3.5], [60, 3.5]]},
            {"name": "right_bank", "type": "segments", "points": [[-30, -3.5], [60, -3.5]]}],
        "output": {"path": str(tmp / f"{method}.nc")},
    }
    if extra:
        scen.update(extra)
    return scen


def test_channel_with_piers_track(tmp_path):
    """Logs in a uniform channel flow meet three circular piers (eps = 1, the paper's value):
    they deflect, collide, and the hits are counted per obstacle in the trajectory file."""
    from driftlog.api import track

    piers = [{"name": f"pier_{k}", "type": "circle", "center": [15.0, y], "radius": 0.4}
             for k, y in enumerate((-2.0, 0.0, 2.0))]
    res = track(_channel("event", 30, piers, 40.0, tmp=tmp_path, count_x=(-12, 10), eps=1.0,
                         tolerance=0.01, rest_speed=0.0))
    ds = res.dataset()
    names = __import__("json").loads(ds.attrs["obstacle_names"])
    assert names[:3] == ["pier_0", "pier_1", "pier_2"]
    stats = __import__("json").loads(ds.attrs["contact_stats"])
    assert stats["events"] > 0 and stats["min_gap"] >= -0.01 * 0.1 * 1.01
    other = ds.hit_other.values
    on_piers = np.isin(other, [-1, -2, -3])
    assert on_piers.sum() >= 3 and (other >= 0).sum() >= 1
    # contact points lie on the pier surfaces (within the log radius of it)
    for k, y in enumerate((-2.0, 0.0, 2.0)):
        sel = other == -(k + 1)
        d = np.hypot(ds.hit_x.values[sel] - 15.0, ds.hit_y.values[sel] - y)
        assert np.all(np.abs(d - 0.4) < 1e-3)
    # no log ever overlaps a pier at a record, and every log passed the bridge
    x, y, th = ds.x.values, ds.y.values, ds.theta.values
    out = np.empty(5)
    for yc in (-2.0, 0.0, 2.0):
        g = [capsule_gap(xi - 0.75 * np.cos(t), yi - 0.75 * np.sin(t), xi + 0.75 * np.cos(t),
                         yi + 0.75 * np.sin(t), 0.1, 15.0, yc, 15.0, yc, 0.4, out)
             for xi, yi, t in zip(x, y, th, strict=True)]
        assert min(g) > -0.01 * 0.1 * 1.01
    last = ds.time.values == ds.time.values.max()
    assert np.all(x[last] > 16.0)
    # logs that hit a pier were deflected: they left the straight line y = y0
    hit_logs = np.unique(ds.hit_log.values[on_piers])
    first = ds.time.values == 0.0
    tid = ds.trajectory_index.values if "trajectory_index" in ds else np.repeat(
        np.arange(ds.sizes["trajectory"]), ds.rowSize.values)
    dy = np.array([abs(y[last & (tid == i)][0] - y[first & (tid == i)][0]) for i in hit_logs])
    assert np.median(dy) > 0.05


def _bridge_deck():
    return [{"name": "deck", "type": "polygon",
             "points": [[15, -3.5], [16, -3.5], [16, 3.5], [15, 3.5]]}]


def test_jam_event_driven_stops_with_message(tmp_path):
    """Logs piling against a bridge deck with eps < 1: event-driven impulses stall; the
    method detects it and stops with a message naming logs, time and the remedy."""
    from driftlog.api import track

    with pytest.raises(ContactJamError) as exc:
        track(_channel("event", 30, _bridge_deck(), 40.0, eps=0.3, tmp=tmp_path))
    msg = str(exc.value)
    assert "stalls at t =" in msg and "logs [" in msg and 'contact.method = "moreau"' in msg
    t = float(msg.split("t = ")[1].split(" s")[0])
    assert 5.0 < t < 40.0  # when the first logs reach the deck, not at the start


def test_jam_moreau_keeps_the_pile(tmp_path):
    """The same jam with Moreau-Jean: the pile holds upstream of the deck, overlaps stay
    bounded, iterations are capped, the logs come to rest."""
    from driftlog.api import track
    from driftlog.contact import model as model_mod

    made = []
    orig = model_mod.ContactModel.from_sections.__func__

    def spy(cls, contact, obstacles, mesh=None):
        m = orig(cls, contact, obstacles, mesh)
        made.append(m)
        return m

    model_mod.ContactModel.from_sections = classmethod(spy)
    try:
        res = track(_channel("moreau", 30, _bridge_deck(), 40.0, eps=0.3, tmp=tmp_path))
    finally:
        model_mod.ContactModel.from_sections = classmethod(orig)
    m = made[0]
    ds = res.dataset()
    last = ds.time.values == ds.time.values.max()
    x = ds.x.values[last]
    assert np.all(x < 15.0)  # held by the deck
    assert np.hypot(ds.u.values[last], ds.v.values[last]).max() < 0.3  # the pile rests
    assert m.stats["min_gap"] > -0.1 * 0.1  # overlaps below 10 % of the radius
    # the velocity solve's sweeps, and the velocity pass's (eq. (90)), a tenth of them at most
    assert m.stats["pgs_max_iterations"] <= m.iterations + m.iterations // 10


@pytest.mark.parametrize("iterations,warned", [(3, True), (200, False)])
def test_moreau_steps_stopped_at_the_sweep_cap_are_reported(tmp_path, iterations, warned):
    """Steps whose Gauss-Seidel solve stopped at ``[contact] iterations`` unconverged are
    counted (``pgs_capped``, in the file's contact statistics); with the logs overlapping by
    more than a tenth of their radius the run warns, naming the cap, the counts and the
    overlap.  The jam at the deck: 3 sweeps let the logs sink into each other (a warning); at
    the default 200 many steps still stop at the cap (the tolerance is 1e-9 of the speeds),
    but the overlaps stay at a few millimetres (no warning)."""
    import json
    import warnings

    import netCDF4

    from driftlog.api import track
    from driftlog.errors import DriftlogWarning

    scen = _channel("moreau", 30, _bridge_deck(), 20.0, eps=0.3, tmp=tmp_path)
    scen["contact"]["iterations"] = iterations
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = track(scen)
    with netCDF4.Dataset(res.path) as ds:
        cs = json.loads(ds.getncattr("contact_stats"))
    assert 0 < cs["pgs_capped"] <= cs["substeps"]
    ours = [str(w.message) for w in caught if issubclass(w.category, DriftlogWarning)
            and "Gauss-Seidel" in str(w.message)]
    if not warned:
        assert cs["min_gap"] > -0.01 and not ours
        return
    assert len(ours) == 1 and cs["min_gap"] < -0.01
    assert (f"cap of {iterations} Gauss-Seidel sweeps without converging in "
            f"{int(cs['pgs_capped']):,} of {int(cs['substeps']):,} contact steps") in ours[0]
    assert f"{-cs['min_gap']:.3g} m" in ours[0]


def _wedge(rng, eps):
    """One Moreau-Jean step of a log (0.8 x 0.08 m, along x) touching two fixed discs, one
    above at x = a, one below at x = b, with a random velocity; its free step consistent."""
    from driftlog.contact.geometry import log_endpoints
    from driftlog.contact.moreau import moreau_solve

    L, r, m = 0.8, 0.08, 11.26
    inertia = m * L * L / 12.0
    a, b = rng.uniform(-0.4, 0.4, 2)
    S0 = np.zeros((1, 6))
    S0[0, 3:] = rng.normal(0.0, 1.0, 3) * [1.0, 1.0, 10.0]
    S = S0.copy()
    S[0, :3] += 1e-3 * S0[0, 3:]
    res = np.zeros((2, 5))
    ends = log_endpoints(0.0, 0.0, 0.0, L)
    for c, (cx, cy) in enumerate(((a, r + 0.08), (b, -r - 0.08))):
        capsule_gap(*ends, r, cx, cy, cx, cy, 0.08, res[c])
    P = np.zeros(2)
    moreau_solve(S0, S, np.array([1.0 / m]), np.array([1.0 / inertia]), np.zeros(2, np.int64),
                 -np.ones(2, np.int64), res, 1e-3, eps, 1e-3, 1e-3, 1e-12, 200, P)
    energy = lambda s: 0.5 * (m * (s[3] ** 2 + s[4] ** 2) + inertia * s[5] ** 2)  # noqa: E731
    u = [(S0[0, 4] + S0[0, 5] * a) * -1.0, S0[0, 4] + S0[0, 5] * b]  # normal speeds at start
    return energy(S[0]) / energy(S0[0]), P, u


def test_moreau_restitution_never_makes_energy_at_simultaneous_contacts():
    # docs/model.md eq. (87): Newton's law u+ >= -eps u- at two contacts at once (a log
    # spinning between two fixed bodies, as between two grounded logs) gave up to 11.5 times
    # the kinetic energy in one step (omega -21 -> +52 rad/s): on the 1e4-log Malpasset flood
    # logs spun up step after step until the step bound fell below integrator.min_step.  An
    # island whose impulses raise its energy is solved again without restitution
    rng = np.random.default_rng(1)
    ratios, bounced = [], 0
    for _ in range(3000):
        ratio, P, u = _wedge(rng, 0.5)
        ratios.append(ratio)
        bounced += ratio < 1.0 and min(u) < -0.5 and (P > 0).all()
    assert max(ratios) <= 1.0 + 1e-9
    assert bounced > 300  # both contacts push in many steps: the law still acts


def test_moreau_single_contact_keeps_newtons_law():
    # one contact: Newton's law makes no energy, so eq. (87) never steps in; u+ = -eps u-
    from driftlog.contact.moreau import moreau_solve

    m, inertia = 2.0, 0.3
    S0 = np.array([[0.0, 0.0, 0.0, 0.0, -1.5, 0.0]])
    S = S0.copy()
    S[0, :3] += 1e-3 * S0[0, 3:]
    res = np.array([[0.0, 0.0, 1.0, 0.0, -0.1]])  # wall below, normal +y, contact under centre
    P = np.zeros(1)
    moreau_solve(S0, S, np.array([1.0 / m]), np.array([1.0 / inertia]), np.zeros(1, np.int64),
                 -np.ones(1, np.int64), res, 1e-3, 0.5, 1e-3, 1e-3, 1e-12, 200, P)
    assert S[0, 4] == pytest.approx(0.75, rel=1e-12)
    assert P[0] == pytest.approx(m * 2.25, rel=1e-12)


@pytest.mark.parametrize("dt", [0.01, 0.18])
def test_moreau_log_pressed_on_a_wall_is_held_at_rest(dt):
    # docs/model.md eq. (90): a log pressed on a wall by a steady force stays where it is, at
    # rest, and the wall bears the whole force, whatever the step.  Before, the solve held the
    # gap only: the log ended every step moving into the wall at a dt / 2 (its position pinned
    # by the gap), and the next step's free motion (the drag) started from that speed
    from driftlog.contact.moreau import moreau_solve

    m, inertia, a, slop = 2.0, 0.3, -0.7, 1e-3
    res = np.array([[-slop, 0.0, 1.0, 0.0, -0.1]])  # wall below, normal +y, under the centre
    S0 = np.zeros((1, 6))
    impulses = []
    for _ in range(20):
        S = S0.copy()
        S[0, 4] += a * dt  # the free step: a steady force toward the wall
        S[0, 1] += S0[0, 4] * dt + 0.5 * a * dt * dt
        P = np.zeros(1)
        res[0, 0] = -slop + S0[0, 1]
        moreau_solve(S0, S, np.array([1.0 / m]), np.array([1.0 / inertia]),
                     np.zeros(1, np.int64), -np.ones(1, np.int64), res, dt, 0.0, 1e-3, slop,
                     1e-12, 200, P)
        impulses.append(P[0])
        S0 = S
    assert abs(S0[0, 4]) < 1e-12 and abs(S0[0, 1]) < 1e-12  # at rest, where it started
    assert np.allclose(impulses, -m * a * dt, rtol=1e-12)  # the wall bears m |a| per second


@pytest.mark.parametrize("eps", [0.0, 0.5])
def test_moreau_log_reaching_a_wall_within_the_step_ends_on_it(eps):
    # a log 2 mm off a wall, approaching at 1 m/s, steps 10 ms: it reaches the wall within the
    # step and ends the step touching it, with Newton's law on its approach speed (eq. (90)).
    # Before, the impulse was taken at the step's start: it ended where it began, 2 mm off
    from driftlog.contact.moreau import moreau_solve

    m, inertia, dt, slop = 2.0, 0.3, 0.01, 1e-5
    S0 = np.array([[0.0, 0.0, 0.0, 0.0, -1.0, 0.0]])
    S = S0.copy()
    S[0, 1] -= dt
    res = np.array([[2e-3, 0.0, 1.0, 0.0, -0.1]])  # wall 2 mm below, normal +y
    P = np.zeros(1)
    moreau_solve(S0, S, np.array([1.0 / m]), np.array([1.0 / inertia]), np.zeros(1, np.int64),
                 -np.ones(1, np.int64), res, dt, eps, slop, slop, 1e-12, 200, P)
    assert S[0, 1] == pytest.approx(-2e-3 - slop, abs=1e-12)  # on the wall
    assert S[0, 4] == pytest.approx(eps, abs=1e-12)  # u+ = -eps u-
    assert P[0] == pytest.approx(m * (1.0 + eps), rel=1e-12)
