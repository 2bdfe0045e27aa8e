"""Moreau-Jean contact islands on several threads (moreau_kernel.moreau_islands_parallel).

The islands of a contact window share no log: run on numba's threads, each writing its hits,
pairs in touch, obstacle impulses and statistics to its own range, then gathered island by
island in order, they give the serial kernel's results bit for bit, for any number of
threads (docs/model.md 11.1).  Checked on a field of clusters of 1 to 13 logs drifting onto
two piers and a wall: many islands of different sizes that merge and split.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pytest

import driftlog.clocks as ck
from driftlog.analytic import UniformFlow, on_mesh
from driftlog.logs import Logs
from driftlog.mesh import Mesh
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

ROOT = Path(__file__).resolve().parent.parent
SIZES = (1, 1, 1, 2, 2, 2, 3, 3, 4, 5, 6, 8, 10, 13)
HITS = ("time", "log_id", "other", "impulse", "x", "y")


def island_field(T=10.0, solver="pgs"):
    """Clusters of SIZES logs (1 m long, 0.1 m radius, side by side 0.19 m apart: each a
    pushing island from the start; each cluster its own density) at random places and angles
    on a current of 0.6 m/s down and 0.25 m/s across the channel, onto two piers and a wall;
    Moreau-Jean, per-log clocks.  Returns the tracker and the logs."""
    from driftlog.contact import ContactModel
    from driftlog.contact.obstacles import Obstacles

    rng = np.random.default_rng(11)
    x, y, th, rho = [], [], [], []
    cx = np.linspace(20.0, 33.0, len(SIZES))
    rng.shuffle(cx)
    for k, c in zip(SIZES, cx, strict=True):
        cy = rng.uniform(3.5, 8.5 - 0.19 * k)
        a = rng.uniform(-0.3, 0.3)
        r = rng.uniform(500.0, 900.0)
        for j in range(k):
            x.append(c + rng.uniform(-0.05, 0.05))
            y.append(cy + 0.19 * j)
            th.append(a + rng.uniform(-0.05, 0.05))
            rho.append(r)
    logs = Logs(np.array(x), np.array(y), np.array(th), 1.0, 0.1, np.array(rho))
    obs = Obstacles()
    obs.add_circle([36.0, 5.4], 0.4, name="pier1")
    obs.add_circle([36.0, 7.0], 0.4, name="pier2")
    obs.add_segments([[0.0, 2.0], [50.0, 2.0]], name="south")
    obs.add_segments([[0.0, 10.0], [50.0, 10.0]], name="north")
    model = ContactModel(obs, method="moreau", restitution=0.3, solver=solver)
    tr = Tracker(on_mesh(UniformFlow(0.6, 0.25, depth=1.0), Mesh.regular_grid(50, 12, 1.0)),
                 logs, PhysicsOptions(level="full"), "rk4", StepOptions(clock="per_log"),
                 contact=model, t_end=T, output_interval=4.0)
    tr.run()
    return tr, logs


def outcome(parallel, room=1.0, solver="pgs"):
    """island_field with the serial or the parallel island kernel: what it computed."""
    saved = ck.ISLANDS_PARALLEL, ck.ISLAND_ROOM
    ck.ISLANDS_PARALLEL, ck.ISLAND_ROOM = parallel, room
    try:
        tr, logs = island_field(solver=solver)
    finally:
        ck.ISLANDS_PARALLEL, ck.ISLAND_ROOM = saved
    hits = tr.contact.drain_hits()
    out = {"state": logs.state, "status": logs.status.astype(np.int64),
           "obstacle_impulse": tr.contact.obstacle_impulse}
    out.update({"hit_" + k: hits[k] for k in HITS})
    stats = {k: v for k, v in tr.stats.items() if k not in ("island_reruns", "wall_seconds")}
    return out, stats, dict(tr.contact.stats), tr.stats.get("island_reruns", 0)


def assert_same(a, b):
    for k in a[0]:
        assert a[0][k].dtype == b[0][k].dtype, k
        np.testing.assert_array_equal(a[0][k], b[0][k], err_msg=k)
        # bit for bit, signed zeros and all
        assert a[0][k].tobytes() == b[0][k].tobytes(), k
    assert a[1] == b[1]
    assert a[2] == b[2]


@pytest.fixture(scope="module")
def serial():
    return outcome(False)


def test_the_field_has_many_islands_of_different_sizes_hits_and_obstacle_impulses(serial):
    out, stats, cstats, _ = serial
    assert stats["islands"] >= 4 * len(SIZES)  # islands of every window, summed
    assert stats["largest_island"] >= 13
    assert np.sum(out["hit_time"] > 0.0) >= 50  # hits after the start's pushes
    assert np.sum(out["hit_other"] < 0) >= 10  # piers and the wall hit
    assert np.abs(out["obstacle_impulse"]).max() > 10.0
    assert cstats["max_contacts"] >= 12


def test_parallel_islands_give_the_serial_kernels_results_bit_for_bit(serial):
    # on this process's threads (one under NUMBA_NUM_THREADS=1: the gathering and its order)
    par = outcome(True)
    assert_same(serial, par)
    assert par[3] == 0  # no island outgrew its range


def test_islands_that_outgrow_their_range_run_again_with_the_same_results(serial):
    # room 0: every island with a hit, a pair in touch or an obstacle impulse fills its range
    # and runs again afterwards, alone, from its saved start
    par = outcome(True, room=0.0)
    assert par[3] >= 10
    assert_same(serial, par)


def test_nncg_islands_in_parallel_give_the_serial_results_bit_for_bit(serial):
    """``[contact] solver = "nncg"``: the same field, serial and parallel kernels bit for bit;
    against the Gauss-Seidel run, fewer sweeps and the same hits on the obstacles (their
    impulses within 1 %)."""
    one = outcome(False, solver="nncg")
    assert_same(one, outcome(True, solver="nncg"))
    assert one[2]["pgs_iterations"] < serial[2]["pgs_iterations"]
    np.testing.assert_allclose(one[0]["obstacle_impulse"], serial[0]["obstacle_impulse"],
                               rtol=0.01, atol=0.01 * np.abs(serial[0]["obstacle_impulse"]).max())


SCRIPT = """
import json, sys
import numpy as np
sys.path.insert(0, {tests!r})
from test_islands_parallel import outcome
import numba
assert numba.get_num_threads() == 2
out, stats, cstats, reruns = outcome(True)
np.savez({npz!r}, **out)
print("RESULT " + json.dumps([stats, cstats, reruns], default=float))
"""


def test_parallel_islands_on_two_threads_bit_for_bit(serial, tmp_path):
    # two threads really running islands side by side (a process of its own when this one
    # has a single thread: NUMBA_NUM_THREADS is read once)
    if numba.config.NUMBA_NUM_THREADS >= 2:
        before = numba.get_num_threads()
        numba.set_num_threads(2)
        try:
            par = outcome(True)
        finally:
            numba.set_num_threads(before)
    else:
        npz = tmp_path / "par.npz"
        env = dict(os.environ, NUMBA_NUM_THREADS="2",
                   PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
        p = subprocess.run([sys.executable, "-c", SCRIPT.format(tests=str(ROOT / "tests"),
                                                                 npz=str(npz))],
                           capture_output=True, text=True, env=env, cwd=ROOT, timeout=1800)
        line = [q for q in p.stdout.splitlines() if q.startswith("RESULT ")]
        assert p.returncode == 0 and line, p.stderr[-3000:]
        stats, cstats, reruns = json.loads(line[-1][7:])
        with np.load(npz) as z:
            par = ({k: z[k] for k in z.files}, stats, cstats, reruns)
    assert_same(serial, par)
