"""The 3D route: interFoam (VOF) in a channel with an obstacle, depth-averaged, logs on it.

A flat channel 1.6 m x 0.4 m of 5 cm squares with a 10 cm square block in the middle, 8
layers of 2 cm up to a lid at 16 cm (2,016 hexahedra); water 10 cm deep entering at 6 l/s
(0.15 m/s), the level held at 10 cm at the outflow; 8 s of interFoam, written, run and read
by ``driftlog.adapters.interfoam_case``.  Its depth-averaged flow is checked against driftlog's
own shallow-water solution of the same channel on the same 2D mesh, from the same state (both
frictionless: slip walls and bed in interFoam, no Manning in driftlog):

- discharge: averaged over 4-8 s (the seiches of the 1.6 m basin, period 3.2 s, cancel),
  every cross-section carries the inflow within 3 % in both flows;
- depth: RMS difference under 1 mm (1 % of the depth) at every written time;
- speed: RMS difference under 0.025 m/s (17 % of the mean speed: the VOF solution has a
  vertical profile and its own wake behind the block) at every written time;
- volume: the depth-averaged flow holds interFoam's water volume to round-off;
- logs released upstream (full physics, contacts): the two beside the block's axis arrive
  downstream within 10 % of each other's time on the two flows; the one on the axis is pinned
  on the block's upstream face on both.
"""

import re

import numpy as np
import pytest
from driftlog.adapters.openfoam_case import foam_available

from driftlog.errors import FlowFileError

LENGTH, WIDTH, CELL = 1.6, 0.4, 0.05
BLOCK = (0.75, 0.15, 0.85, 0.25)
LEVEL, Q, END = 0.10, 0.006, 8.0
SECTIONS = (0.1, 0.4, 0.6, 1.0, 1.3, 1.5)
needs_foam = pytest.mark.skipif(not foam_available(),
                                reason="OpenFOAM not installed (Debian: apt-get install openfoam)")


@pytest.fixture(scope="module")
def flows(tmp_path_factory):
    if not foam_available():
        pytest.skip("OpenFOAM not installed (Debian: apt-get install openfoam)")
    from driftlog.adapters.interfoam_case import channel_with_block, run_interfoam_channel

    from driftlog.flowfile import open_flow
    from driftlog.solver.model import ShallowWaterSolver

    tmp = tmp_path_factory.mktemp("vof")
    mesh = channel_with_block(LENGTH, WIDTH, CELL, BLOCK)
    vof = run_interfoam_channel(tmp / "channel", mesh, level=LEVEL, discharge=Q, height=0.16,
                                n_layers=8, end_time=END, write_interval=0.5)
    sw_mesh = channel_with_block(LENGTH, WIDTH, CELL, BLOCK)
    s = ShallowWaterSolver(sw_mesh, order=2, boundaries={
        "inflow": {"type": "discharge", "value": Q}, "outflow": {"type": "level",
                                                                 "value": LEVEL}})
    h = np.full(sw_mesh.n_faces, LEVEL)
    s.set_state(h, h * Q / (WIDTH * LEVEL), 0 * h)
    s.run(END, output=tmp / "sw.nc", output_interval=0.5)
    return tmp, vof, open_flow(tmp / "sw.nc")


def section_discharge(field, x0, t):
    y = np.linspace(0.001, WIDTH - 0.001, 400)
    s = field.sample(np.full(y.size, x0), y, np.full(y.size, t))
    return np.trapezoid(np.where(np.isfinite(s.u), s.h * s.u, 0.0), y)


@needs_foam
@pytest.mark.openfoam
def test_depth_averaged_vof_against_shallow_water(flows):
    tmp, vof, sw = flows
    np.testing.assert_allclose(vof.times, sw.times)
    assert vof.mesh.n_faces == sw.mesh.n_faces == 252
    np.testing.assert_allclose(vof.bed, 0.0)
    late = vof.times >= 4.0 - 1e-9
    for field in (vof, sw):
        for x0 in SECTIONS:
            q = np.mean([section_discharge(field, x0, t) for t in vof.times[late]])
            assert abs(q - Q) < 0.03 * Q, (field.name, x0, q)
    for i in range(1, vof.times.size):
        a, b = vof.snapshot(i), sw.snapshot(i)
        assert np.sqrt(np.mean((a["h"] - b["h"]) ** 2)) < 1e-3
        speed_a, speed_b = np.hypot(a["u"], a["v"]), np.hypot(b["u"], b["v"])
        assert np.sqrt(np.mean((speed_a - speed_b) ** 2)) < 0.025
    # the block: flow around it, slower in its wake than beside it in both
    for f in (vof, sw):
        s = f.snapshot(vof.times.size - 1)
        sp = np.hypot(s["u"], s["v"])
        m = f.mesh
        wake = (m.face_x > 0.85) & (m.face_x < 0.95) & (np.abs(m.face_y - 0.2) < 0.05)
        side = (np.abs(m.face_x - 0.8) < 0.05) & ((m.face_y < 0.15) | (m.face_y > 0.25))
        assert sp[wake].mean() < 0.8 * sp[side].mean()


@needs_foam
@pytest.mark.openfoam
def test_depth_average_keeps_interfoam_volume(flows):
    tmp, vof, _ = flows
    log = (tmp / "channel" / "log.interFoam").read_text()
    frac = float(re.findall(r"Phase-1 volume fraction = ([0-9.e+-]+)", log)[-1])
    area = vof.mesh.face_area
    vol_domain = area.sum() * 0.16
    np.testing.assert_allclose(np.sum(vof.snapshot(vof.times.size - 1)["h"] * area),
                               frac * vol_domain, rtol=1e-8)


@needs_foam
@pytest.mark.openfoam
def test_logs_on_the_vof_flow(flows, tmp_path):
    from driftlog.api import track
    from driftlog.compare import arrival_times
    from driftlog.trajectory import open_trajectories

    _, vof, sw = flows
    scen = {"flow": {"source": "analytic", "kind": "uniform", "velocity": [0.0, 0.0]},
            "time": {"start": 0.0, "end": END, "output_interval": 0.1},
            "logs": [{"x": [0.2, 0.2, 0.2], "y": [0.08, 0.2, 0.32], "theta": [0.0, 0.0, 0.0],
                      "length": 0.04, "radius": 0.004, "density": 700.0}],
            "physics": {"level": "full"}, "contact": {"enabled": True, "method": "moreau"},
            "obstacles": [{"name": "block", "type": "polygon", "points": [
                [BLOCK[0], BLOCK[1]], [BLOCK[2], BLOCK[1]], [BLOCK[2], BLOCK[3]],
                [BLOCK[0], BLOCK[3]]]}]}
    ends = {}
    for name, f in (("vof", vof), ("sw", sw)):
        path = track(scen, flow=f, output=tmp_path / f"{name}.nc").path
        ds = open_trajectories(path)
        x, y = ds["x"].values, ds["y"].values
        # no log's centre enters the block: the middle one is deflected by it
        inside = (x > BLOCK[0]) & (x < BLOCK[2]) & (y > BLOCK[1]) & (y < BLOCK[3])
        assert not inside.any()
        ends[name] = arrival_times(ds, (1.2, 0.0, 1.2, WIDTH))
        # the middle log, on the block's axis, ends pinned on its upstream face
        mid = ds["trajectory_index"].values == 1
        assert BLOCK[0] - 0.05 < x[mid][-1] < BLOCK[0] and abs(y[mid][-1] - 0.2) < 0.01
        assert np.isnan(ends[name][1])
    # the others pass beside it: 1 m in 5-6 s; the two flows agree within 10 %
    for name in ends:
        assert np.all((ends[name][[0, 2]] > 4.0) & (ends[name][[0, 2]] < 7.0))
    np.testing.assert_allclose(ends["vof"][[0, 2]], ends["sw"][[0, 2]], rtol=0.10)


def test_channel_block_errors():
    from driftlog.adapters.interfoam_case import channel_with_block, write_interfoam_channel

    with pytest.raises(FlowFileError, match="removes no cell"):
        channel_with_block(1.0, 0.4, 0.1, (2.0, 0.0, 3.0, 0.1))
    m = channel_with_block(1.0, 0.4, 0.1, (0.4, 0.1, 0.6, 0.3))
    with pytest.raises(FlowFileError, match="level 0.2 m must lie between the bed"):
        write_interfoam_channel("/nonexistent/never", m, level=0.2, discharge=0.01,
                                height=0.1, n_layers=4)
