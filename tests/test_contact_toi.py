"""Contact times (conservative advancement vs dichotomy), mesh walls, scenario keys, and
event-driven vs Moreau-Jean on a scene where both work."""

import numpy as np
import pytest

from driftlog.contact import BallisticLogs, ContactModel, Obstacles, run_contacts
from driftlog.errors import ScenarioError


def _grazing(toi):
    """A log broadside at 1 m/s past a pier it clips by 5 cm: with the paper's step bound
    (L / |U| = 1 s) it starts and ends each step clear of the pier."""
    obs = Obstacles()
    obs.add_circle([0.0, 0.5 + 0.1 + 0.3 - 0.05], 0.3, "pier")
    b = BallisticLogs(np.array([[-0.45, 0.0, np.pi / 2, 1.0, 0.0, 0.0]]), 1.0, 0.1)
    m = ContactModel(obs, restitution=1.0, time_of_impact=toi)
    run_contacts(m, b, 3.0)  # the paper's sub-step bound
    return m, b


def test_grazing_contact_dichotomy_misses_conservative_finds():
    m, b = _grazing("dichotomy")
    assert len(m.drain_hits()["time"]) == 0  # passed through the pier: missed
    assert b.state[0, 4] == 0.0
    m, b = _grazing("conservative")
    h = m.drain_hits()
    assert len(h["time"]) == 1 and h["other"][0] == -1
    assert b.state[0, 4] < -0.01 or b.state[0, 5] != 0.0  # deflected
    assert m.stats["min_gap"] >= -m.tolerance * 0.1


@pytest.mark.parametrize("toi", ["conservative", "dichotomy"])
def test_contact_time_within_tolerance_oblique(toi):
    """Oblique approach of two turning logs: the contact is found with the gap within the
    tolerance, at a time that both methods agree on to tolerance / approach speed."""
    S = np.array([[0.0, 0.0, 0.3, 0.5, 0.1, 0.4], [2.2, 0.4, 1.2, -0.6, 0.0, -0.3]])
    b = BallisticLogs(S, 1.5, 0.1)
    m = ContactModel(restitution=0.8, time_of_impact=toi)
    run_contacts(m, b, 3.0, max_step=0.5)
    t = m.drain_hits()["time"]
    # the reference: the first time the exact gap falls to 0, by fine bisection
    from driftlog.contact.geometry import capsule_gap, log_endpoints

    def gap(tt):
        P = S[:, :3] + tt * S[:, 3:]
        return capsule_gap(*log_endpoints(*P[0], 1.5), 0.1, *log_endpoints(*P[1], 1.5), 0.1,
                           np.empty(5))

    ts = np.linspace(0, 3, 30001)
    k = np.argmax([gap(x) <= 0 for x in ts])
    lo, hi = ts[k - 1], ts[k]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) > 0 else (lo, mid)
    assert len(t) >= 1
    assert abs(t[0] - lo) < 1e-3  # tol 1e-5 m at approach speeds ~1 m/s, 1e-3 generous


def test_walls_from_mesh_tags_open_boundaries_let_logs_leave(tmp_path):
    """A channel on a mesh flow: walls (tag wall) reflect, the outflow lets logs leave."""
    from driftlog.analytic import UniformFlow, on_mesh
    from driftlog.logs import LEFT, Logs
    from driftlog.mesh import Mesh
    from driftlog.physics import PhysicsOptions
    from driftlog.scenario import load_scenario
    from driftlog.tracker import Tracker

    mesh = Mesh.regular_grid(40, 6, 1.0, y0=-3.0)
    mesh.tag_boundary("wall", lambda x, y: np.ones_like(x, bool))
    mesh.tag_boundary("outflow", (39.5, -4, 41, 4))
    mesh.tag_boundary("inflow", (-1, -4, 0.5, 4))
    flow = on_mesh(UniformFlow(1.0, 0.3, depth=1.0), mesh)
    scen = load_scenario({"contact": {"enabled": True, "walls": True, "restitution": 0.5}})
    model = ContactModel.from_sections(scen["contact"], scen["obstacles"], mesh=mesh)
    assert model.obstacle_names == ["walls"]
    walls = model.obstacles.capsules
    assert np.all((np.abs(walls[:, 1]) == 3.0) & (walls[:, 1] == walls[:, 3]))  # sides only
    logs = Logs([3.0, 6.0], [0.0, 1.0], [0.0, 0.5], length=1.0, radius=0.1, density=700.0)
    tk = Tracker(flow, logs, PhysicsOptions(), contact=model, t_end=80.0)
    tk.run()
    hits = model.drain_hits()
    assert np.sum(hits["other"] == -1) >= 2  # the flow has v > 0: logs meet the north wall
    assert np.all(logs.status == LEFT)  # through the outflow, not stopped by a wall
    assert np.all(np.abs(hits["y"] - 3.0) < 1e-3)


def test_scenario_obstacle_errors_name_key_value_rule():
    from driftlog.scenario import load_scenario

    bad = load_scenario({"obstacles": [{"type": "circle", "center": [0, 0]}]})
    with pytest.raises(ScenarioError, match=r"obstacles\[0\]\.radius"):
        ContactModel.from_sections(bad["contact"], bad["obstacles"])
    bad = load_scenario({"obstacles": [{"type": "polygon", "points": [[0, 0], [1, 0]]}]})
    with pytest.raises(ScenarioError, match=r"obstacles\[0\]\.points.*at least 3"):
        ContactModel.from_sections(bad["contact"], bad["obstacles"])
    with pytest.raises(ScenarioError, match=r"contact\.rest_speed"):
        load_scenario({"contact": {"rest_speed": -1.0}})
    with pytest.raises(ScenarioError, match=r"contact\.method.*'event', 'moreau'"):
        load_scenario({"contact": {"method": "impulse"}})


def test_event_and_moreau_agree_where_both_work():
    """A few logs thrown at a pier and at each other (eps = 0.5), no persistent contact:
    Moreau-Jean (small steps) and the event-driven method end close to each other."""
    obs = Obstacles()
    obs.add_circle([3.0, 0.0], 0.5, "pier")
    S = np.array([[0.0, 0.2, 0.2, 1.0, 0.0, 0.1],
                  [6.0, -0.6, 1.4, -1.0, 0.1, 0.0],
                  [3.0, 3.0, 0.0, 0.0, -0.8, 0.0]])
    out = {}
    for method in ("event", "moreau"):
        b = BallisticLogs(S, 1.2, 0.1)
        m = ContactModel(obs, method=method, restitution=0.5)
        run_contacts(m, b, 4.0, max_step=0.005 if method == "moreau" else None)
        out[method] = (b.state.copy(), m.drain_hits())
    se, he = out["event"]
    sm, hm = out["moreau"]
    assert len(he["time"]) >= 3
    pairs = [sorted(zip(h["log_id"], h["other"], strict=True)) for h in (he, hm)]
    assert pairs[0] == pairs[1]
    assert np.abs(se[:, :2] - sm[:, :2]).max() < 0.05
    assert np.abs(se[:, 3:5] - sm[:, 3:5]).max() < 0.05
