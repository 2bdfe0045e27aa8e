"""The coupled flow's node values on the region around the logs (docs/model.md 17.5).

The same coupled run three ways: node values on the whole mesh at every step (as the coupling
first did), on the region around the logs (the default), and on a region around the first
log alone, so that the others sample out of it and each step is widened to the whole mesh.
All three must give the same logs and the same water bit for bit, on the fused RK4 path, on
the general (stage by stage) path, and under per-log clocks (a widened interval is done again
from its kept start).
"""

from __future__ import annotations

import numpy as np
import pytest

from driftlog.api import as_scenario, logs_from_scenario
from driftlog.coupling import CoupledTracker, Coupling
from driftlog.physics import PhysicsOptions
from driftlog.solver.config import build_solver
from driftlog.stepping import StepOptions


def _scenario():
    return as_scenario({
        "flow": {"source": "solver"},
        "solver": {"mesh": "channel", "channel": [0.0, 0.0, 16.0, 3.0], "cell_size": 0.4,
                   "end": 10.0,
                   "boundaries": {"inflow": {"type": "discharge", "value": 3.0},
                                  "outflow": {"type": "level", "value": 0.6}},
                   "initial": {"type": "level", "value": 0.6, "velocity": [1.6, 0.0]}},
        "time": {"start": 0.0, "end": 2.5},
        "logs": [{"seeding": "list", "x": [2.0, 3.0, 4.5, 6.0], "y": [0.8, 2.1, 1.4, 0.9],
                  "theta": [0.3, 1.2, 2.0, 0.0], "length": 1.0, "radius": 0.1,
                  "density": 700.0, "velocity": "rest"}],
        "coupling": {"enabled": True},
    })


def _run(method, region, clock="global"):
    scen = _scenario()
    s = build_solver(scen["solver"])
    cp = Coupling(s, points=scen["coupling"]["points"])
    if region == "whole mesh":
        cp.flow.focus = lambda x, y, margin: cp.flow.focus_all()  # every node, every step
    elif region == "first log":
        focus = cp.flow.focus
        cp.flow.focus = lambda x, y, margin: focus(x[:1], y[:1], 0.0)
    phys = PhysicsOptions.from_scenario(scen["physics"], level="full", rotation=True)
    tr = CoupledTracker(cp, logs_from_scenario(scen), phys, method=method, t_start=0.0,
                        t_end=2.5, initial_velocity="rest", step=StepOptions(clock=clock))
    tr.run()
    return s, cp, tr


@pytest.mark.parametrize("method, clock", [("rk4", "global"), ("exponential", "global"),
                                           ("rk4", "per_log")])
def test_region_gives_the_whole_mesh_results_bit_for_bit(method, clock):
    s0, cp0, tr0 = _run(method, "whole mesh", clock)
    s1, cp1, tr1 = _run(method, "region", clock)
    s2, cp2, tr2 = _run(method, "first log", clock)
    n_nodes = s0.mesh.n_nodes
    assert cp0.flow.region_nodes == n_nodes * cp0.solver_steps
    # the region is a small part of the mesh, and wide enough that no step strayed out
    assert cp1.flow.region_nodes < 0.5 * n_nodes * cp1.solver_steps
    assert cp1.flow.widenings == 0
    # the other logs sample out of the first one's region: the steps are widened
    assert cp2.flow.widenings > 0
    assert np.abs(tr0.logs.state[:, 0] - 2.0).max() > 1.0  # the logs travelled
    for s, cp, tr in ((s1, cp1, tr1), (s2, cp2, tr2)):
        assert cp.solver_steps == cp0.solver_steps
        np.testing.assert_array_equal(tr.logs.state, tr0.logs.state)
        np.testing.assert_array_equal(tr.logs.status, tr0.logs.status)
        for a in ("h", "hu", "hv"):
            np.testing.assert_array_equal(getattr(s, a), getattr(s0, a))
        np.testing.assert_allclose(cp.given, cp0.given, rtol=1e-12)
