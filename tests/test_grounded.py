"""Resting and stranded logs are fixed capsules for the floating ones (docs/model.md 13).

A thin light log floats on 0.3 m of water flowing east at 0.5 m/s; a thick log lies across
its path, too heavy to float on so little water (resting).  The floating log must stop against
it, under both clocks and both contact methods, exactly as against a fixed obstacle of the
resting log's shape; without the option it drifts through.
"""

from __future__ import annotations

import numpy as np
import pytest

from driftlog.analytic import UniformFlow, on_mesh
from driftlog.contact import ContactModel
from driftlog.contact.geometry import log_capsules
from driftlog.contact.obstacles import Obstacles
from driftlog.logs import FLOATING, RESTING, STRANDED, Logs
from driftlog.mesh import Mesh
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

MESH = Mesh.regular_grid(30, 10, 1.0)
FLOW = on_mesh(UniformFlow(0.5, 0.0, depth=0.3), MESH)
HEAVY = dict(x=12.0, y=5.0, theta=np.pi / 2, length=3.0, radius=0.25, density=900.0)
LIGHT = dict(x=5.0, y=5.2, theta=0.3, length=1.0, radius=0.08, density=500.0)
T_END = 30.0


def scene(light_only=False):
    """The two logs (ids 0 heavy, 1 light), or the light one alone (id 1)."""
    rows = [LIGHT] if light_only else [HEAVY, LIGHT]
    logs = Logs(*(np.array([r[k] for r in rows]) for k in ("x", "y", "theta", "length",
                                                           "radius", "density")))
    logs.id[:] = [1] if light_only else [0, 1]
    return logs


def run(clock, method, grounded=True, as_obstacle=False, backend="native"):
    """The light log against the heavy resting one, or against a pier of its shape."""
    obs = Obstacles()
    if as_obstacle:
        h = HEAVY
        obs.add("heavy", "log", log_capsules(np.array([h["x"]]), np.array([h["y"]]),
                                              np.array([h["theta"]]), h["length"],
                                              h["radius"]))
    model = ContactModel(obs, method=method, restitution=0.5, grounded=grounded,
                         backend=backend)
    logs = scene(light_only=as_obstacle)
    tr = Tracker(FLOW, logs, PhysicsOptions(level="full"), "rk4",
                 StepOptions(clock=clock, max_step=0.5), contact=model, t_end=T_END,
                 output_interval=5.0)
    tr.run()
    return tr, logs


def light_gap(logs):
    """Capsule gap of the light log to the heavy log's place (m)."""
    from driftlog.columns import GAP, NRES
    from driftlog.contact.geometry import capsule_pair_gaps

    h, k = HEAVY, int(np.flatnonzero(logs.id == 1)[0])
    heavy = log_capsules(np.array([h["x"]]), np.array([h["y"]]), np.array([h["theta"]]),
                         h["length"], h["radius"])
    s = logs.state[k]
    light = log_capsules(s[:1], s[1:2], s[2:3], logs.length[k], logs.radius[k])
    out = np.empty((1, NRES))
    capsule_pair_gaps(light, heavy, out)
    return float(out[0, GAP])


def test_the_scene_has_a_resting_log_and_a_floating_one():
    tr, logs = run("global", "event", grounded=False)
    assert logs.status[0] == RESTING  # h* of the heavy log > 0.3 m
    assert logs.status[1] == FLOATING
    # without the option the light log drifts through the resting one: 0.5 m/s for 30 s
    assert logs.state[1, 0] > HEAVY["x"] + 2.0


@pytest.mark.parametrize("clock,method", [("global", "event"), ("global", "moreau"),
                                         ("per_log", "event"), ("per_log", "moreau")])
def test_a_floating_log_stops_against_a_resting_one_as_against_an_obstacle(clock, method):
    tr, logs = run(clock, method)
    assert logs.status[0] == RESTING and logs.status[1] == FLOATING
    np.testing.assert_array_equal(logs.state[0, :3], [HEAVY["x"], HEAVY["y"], HEAVY["theta"]])
    tol = tr.contact.tolerance * LIGHT["radius"]
    gap = light_gap(logs)
    assert -2.0 * tol <= gap < 0.02  # held against it, not through it
    hits = tr.contact.drain_hits()
    assert hits["time"].size >= 1
    assert set(hits["other"].tolist()) == {0}  # the resting log's id
    assert set(hits["log_id"].tolist()) == {1}
    # the resting log passes the push on to the bed: downstream, about the drag held for the
    # time the log rests against it
    gx, gy = tr.contact.ground_impulse
    assert gx > 0.0 and abs(gy) < gx
    assert np.all(tr.contact.obstacle_impulse == 0.0)
    # the very same motion as against a fixed obstacle of the resting log's shape
    tr_o, logs_o = run(clock, method, as_obstacle=True)
    np.testing.assert_allclose(logs.state[1], logs_o.state[0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tr.contact.ground_impulse,
                               tr_o.contact.obstacle_impulse.sum(axis=0), rtol=1e-12)
    ho = tr_o.contact.drain_hits()
    np.testing.assert_allclose(hits["time"], ho["time"], rtol=1e-12)
    np.testing.assert_allclose(hits["impulse"], ho["impulse"], rtol=1e-12)


def test_fcl_backend_stops_the_floating_log_too():
    pytest.importorskip("fcl")
    tr, logs = run("global", "event", backend="fcl")
    _, ref = run("global", "event")
    # held at the same place, within the contact tolerance (1e-4 r = 8 um): FCL's distances
    # far from contact and the native ones near it end the steps at other points
    np.testing.assert_allclose(logs.state[1, :2], ref.state[1, :2], atol=2e-5)
    assert set(tr.contact.drain_hits()["other"].tolist()) == {0}


def test_a_stranded_log_is_grounded_and_a_lifted_one_is_not():
    model = ContactModel(Obstacles(), grounded=True)
    logs = scene()
    tr = Tracker(FLOW, logs, PhysicsOptions(level="full"), "rk4", StepOptions(),
                 contact=model, t_end=1.0)
    tr._release()  # classifies the released logs: the heavy one rests
    np.testing.assert_array_equal(model.ground_rows, [0])
    caps0 = model.capsules.copy()
    # stranded: still fixed; lifted (floating): a body, no longer a capsule
    for status, rows in ((STRANDED, [0]), (FLOATING, [])):
        logs.status[0] = status
        tr._set_active(np.flatnonzero(logs.status == FLOATING))
        np.testing.assert_array_equal(model.ground_rows, rows)
    assert model.capsules.shape[0] == 0 and caps0.shape[0] == 1
    assert model.ground_version == 2  # the stranded log at the same place changed nothing


def _stranding_scene():
    """A heavy log across a channel, pushed by a light one behind it, rests in the shallows.

    0.5 m/s over a bed rising from x = 8 m: the depth falls from 0.4 to 0.12 m at x = 12.37 m,
    below the heavy log's flotation depth (0.224 m) from x = 10.75 m; the light log (0.05 m)
    floats on.  Sub-steps of at most 0.05 s, so the heavy log stops within a per-log contact
    window (0.5 median L / |U| = 2.5 s), not at its end.
    """
    from driftlog.flow import InMemorySnapshots, MeshFlowField

    mesh = Mesh.regular_grid(40, 10, 0.5)
    h = np.interp(mesh.face_x, [0.0, 8.0, 12.37, 20.0], [0.4, 0.4, 0.12, 0.12])
    flow = MeshFlowField(mesh, -h, InMemorySnapshots([0.0], h[None], 0.5 * h[None],
                                                     0.0 * h[None]))
    logs = Logs(np.array([6.0, 4.83]), np.array([2.5, 2.5]), np.array([np.pi / 2, 0.0]),
                np.array([3.0, 2.0]), np.array([0.15, 0.05]), np.array([800.0, 500.0]))
    return flow, logs


@pytest.mark.parametrize("clock,method", [("global", "moreau"), ("per_log", "moreau"),
                                          ("global", "event"), ("per_log", "event")])
def test_a_log_that_comes_to_rest_in_a_contact_window_holds_the_one_behind_it(clock, method):
    """A log that stops floating stays a fixed body of its contact island (both kernels).

    Before, under per-log clocks it left its island when it stopped, and the light log behind
    it ran on through it to the window's end (its front end 0.2 m into the heavy log, at the
    heavy log's axis, at the next record), until the grounded capsule pushed it back.
    """
    flow, logs = _stranding_scene()
    model = ContactModel(Obstacles(), method=method, restitution=0.0, grounded=True)
    tr = Tracker(flow, logs, PhysicsOptions(level="full"), "rk4",
                 StepOptions(clock=clock, max_step=0.05), contact=model, t_end=10.0,
                 output_interval=10.0)
    tr.run()
    assert logs.status[0] == RESTING and logs.status[1] == FLOATING
    assert 10.7 < logs.state[0, 0] < 10.8  # resting from x = 10.75 m on, at 9.5 s
    # the light log's front end against the heavy log's upstream face, not into it
    front = logs.state[1, 0] + 0.5 * logs.length[1]
    back = logs.state[0, 0] - logs.radius[0]
    assert -1e-3 < back - front < 0.06
    if method == "moreau":  # (the seeding's 2.4 cm; 0.2 m before)
        assert model.stats["min_gap"] > -0.03
