"""Ensembles: specification and sampling, member summaries, aggregation, Dask runs, resume."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from driftlog.analytic import UniformFlow, on_mesh
from driftlog.api import logs_from_scenario
from driftlog.ensemble import (
    Aggregate,
    MemberRecorder,
    clopper_pearson_interval,
    load_ensemble,
    open_member,
    run_ensemble,
    run_member,
    summarize_trajectories,
    wilson_interval,
)
from driftlog.ensemble.summary import sweep_segments
from driftlog.errors import DriftlogError, ScenarioError
from driftlog.flowfile import open_flow, write_flow
from driftlog.logs import FLOATING, LEFT, RESTING, STRANDED
from driftlog.mesh import Mesh
from driftlog.mesher import channel_mesh, circle
from driftlog.scenario import load_scenario
from driftlog.trajectory import TrajectoryWriter

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def flow_file(tmp_path_factory):
    """A 20 m x 10 m channel with a pier (a hole), uniform flow 1 m/s along x."""
    mesh = channel_mesh(20.0, 10.0, 0.6, holes=[circle((12.0, 5.0), 1.0, cell_size=0.4)])
    field = on_mesh(UniformFlow(1.0, 0.0, depth=1.0), mesh, times=[0.0, 50.0])
    return write_flow(tmp_path_factory.mktemp("flow") / "flow.nc", field)


def ensemble_text(flow, out, members=6, sampling="latin_hypercube", vary=None, extra="",
                  logs=None):
    vary = vary if vary is not None else """
"logs.release_time" = { uniform = [0.0, 4.0] }
"logs.count" = { integers = [2, 6] }
"logs.length" = { lognormal = [1.0, 0.3], max = 3.0 }
"physics.level" = { values = ["tracer", "drag"] }
"""
    logs = logs or """
seeding = "random"
polygon = [[1, 1], [4, 1], [4, 9], [1, 9]]
count = 4
radius = 0.1
density = 700.0
"""
    m = f"members = {members}" if members is not None else ""
    return f"""
title = "test ensemble"
[flow]
source = "file"
path = "{flow}"
[time]
end = 15.0
output_interval = 1.0
[[logs]]
{logs}
[physics]
level = "tracer"
[ensemble]
{m}
seed = 11
sampling = "{sampling}"
output = "{out}"
{extra}
[ensemble.vary]
{vary}
"""


def write_ensemble(tmp_path, flow, **kw):
    f = tmp_path / "ensemble.toml"
    f.write_text(ensemble_text(flow, tmp_path / "out", **kw))
    return f


# --------------------------------------------------------------------- specification
def test_monte_carlo_member_depends_on_seed_and_index_alone(tmp_path, flow_file):
    a = load_ensemble(ensemble_text(flow_file, tmp_path, members=10, sampling="monte_carlo"))
    b = load_ensemble(ensemble_text(flow_file, tmp_path, members=500, sampling="monte_carlo"))
    assert a.parameters_of(7) == b.parameters_of(7)
    assert a.fingerprint() == b.fingerprint()  # extendable: the member count is not in it
    u = np.random.default_rng([11, 7]).random(4)
    p = a.parameters_of(7)
    assert p["logs.release_time"] == pytest.approx(4.0 * u[0], rel=1e-15)
    assert p["logs.count"] == 2 + int(u[1] * 5)
    assert p["physics.level"] == ["tracer", "drag"][int(u[3] * 2)]
    # each member's random seeding gets its own seed; the same member the same one
    s7, s8 = a.member_scenario(7), a.member_scenario(8)
    assert s7["logs"][0]["seed"] != s8["logs"][0]["seed"]
    assert b.member_scenario(7).to_json() == s7.to_json()
    # restitution (eps), radius and density vary like any key of their section
    e = load_ensemble(ensemble_text(flow_file, tmp_path, members=3, vary="""
"contact.restitution" = { uniform = [0.2, 0.6] }
"logs.radius" = { values = [0.05, 0.2] }
"logs.density" = { range = [500.0, 900.0, 200.0] }
"""))
    for i, p in enumerate(e.sample(range(3))):
        s = e.member_scenario(i)
        assert 0.2 <= s["contact"]["restitution"] == p["contact.restitution"] <= 0.6
        assert s["logs"][0]["radius"] == p["logs.radius"] in (0.05, 0.2)
        assert s["logs"][0]["density"] == p["logs.density"] in (500.0, 700.0, 900.0)


def test_latin_hypercube_is_stratified_and_grid_is_every_combination(tmp_path, flow_file):
    e = load_ensemble(ensemble_text(flow_file, tmp_path, members=40))
    u = np.array([e.unit_sample(i) for i in range(40)])
    for j in range(u.shape[1]):  # one sample in each of the 40 strata of every parameter
        assert sorted((u[:, j] * 40).astype(int)) == list(range(40))
    g = load_ensemble(ensemble_text(flow_file, tmp_path, members=None, sampling="grid", vary="""
"logs.density" = { values = [500.0, 700.0, 900.0] }
"logs.count" = { range = [2, 6, 2] }
"""))
    assert g.members == 9
    combos = {(p["logs.density"], p["logs.count"]) for p in g.sample(range(9))}
    assert combos == {(d, c) for d in (500.0, 700.0, 900.0) for c in (2, 4, 6)}


def test_distributions(tmp_path, flow_file):
    e = load_ensemble(ensemble_text(flow_file, tmp_path, members=4000, sampling="monte_carlo",
                                    vary="""
"logs.length" = { normal = [2.0, 1.0], min = 0.5, max = 2.5 }
"logs.radius" = { loguniform = [0.01, 1.0] }
"logs.count" = { integers = [1, 3] }
"physics.level" = { values = ["tracer", "drag", "full"], weights = [2, 1, 1] }
"""))
    t = e.parameter_table()
    L, r = t["logs.length"], t["logs.radius"]
    assert L.min() >= 0.5 and L.max() <= 2.5
    from scipy import stats

    # truncated normal: the mean of N(2, 1) on [0.5, 2.5]
    exact = stats.truncnorm(-1.5, 0.5, loc=2.0, scale=1.0).mean()
    assert L.mean() == pytest.approx(exact, abs=0.03)
    assert np.median(np.log10(r)) == pytest.approx(-1.0, abs=0.06)
    assert set(t["logs.count"].astype(int)) == {1, 2, 3}
    share = np.bincount(t["physics.level"], minlength=3) / 4000
    np.testing.assert_allclose(share, [0.5, 0.25, 0.25], atol=0.03)


@pytest.mark.parametrize("vary, extra, key, words", [
    ('"flow.depth" = { uniform = [1, 2] }', "", '"flow.depth"', "one flow"),
    ('"logs.lenght" = { uniform = [1, 2] }', "", '"logs.lenght"', "did you mean 'length'"),
    ('"logs.density" = { uniform = [-5.0, 700.0] }', "", "uniform", "must be > 0"),
    ('"logs.length" = { normal = [1.0, 0.5] }', "", '"logs.length"', "give min"),
    ('"logs.count" = { uniform = [2, 5] }', "", "uniform", "integers = [low, high]"),
    ('"physics.level" = { uniform = [0, 1] }', "", "uniform", "values = [...]"),
    ('"physics.level" = { values = ["tracer", "fast"] }', "", "values[1]", "'drag'"),
    ('"logs.length" = { uniform = [1, 2], min = 0.5 }', "", "min", "applies to normal"),
    ('"logs.length" = { gamma = [1, 2] }', "", "gamma", "unknown entry"),
    ('"logs.length" = { uniform = [1, 2], values = [1] }', "", '"logs.length"',
     "exactly one distribution"),
    ('"logs[3].length" = { uniform = [1, 2] }', "", '"logs[3].length"', "must be < 1"),
    ('"logs.place" = { values = [{ seeding = "line", begin = [0, 0] }] }', "", "begin",
     "not a placement key"),
    ('"logs.length" = { uniform = [1, 2] }', 'sampling = "grid"', '"logs.length"',
     "explicit lists"),
    ('"physics.level" = { values = ["tracer"], weights = [1, 2] }', "", "weights",
     "list of 1"),
    ('"logs.length" = { range = [1, 0.5, 0.1] }', "", "range", "stop >= start"),
    ('"contact.restitution" = { uniform = [0.5, 1.5] }', "", "uniform",
     "must be >= 0.0 and <= 1.0"),
])
def test_bad_ensemble_config_names_key_value_and_rule(tmp_path, flow_file, vary, extra, key,
                                                      words):
    text = ensemble_text(flow_file, tmp_path, vary=vary).replace(
        'sampling = "latin_hypercube"', extra or 'sampling = "latin_hypercube"')
    if extra:
        text = text.replace("members = 6", "")
    with pytest.raises(ScenarioError) as err:
        load_ensemble(text)
    msg = str(err.value)
    assert key in msg and words in msg, msg
    assert msg.startswith("[ensemble.vary.")


def test_bad_ensemble_section_values(tmp_path, flow_file):
    text = ensemble_text(flow_file, tmp_path)
    with pytest.raises(ScenarioError, match=r"\[ensemble.members\] = None: is required"):
        load_ensemble(text.replace("members = 6", ""))
    with pytest.raises(ScenarioError, match=r"\[ensemble.sampling\] = 'latin': must be one of"):
        load_ensemble(text.replace('"latin_hypercube"', '"latin"'))
    with pytest.raises(ScenarioError, match=r"\[ensemble.members\] = 0: must be >= 1"):
        load_ensemble(text.replace("members = 6", "members = 0"))
    with pytest.raises(ScenarioError, match=r"\[ensemble\] = 'missing': an ensemble file needs"):
        load_ensemble(text.split("[ensemble]")[0])
    # the CLI's scenario check validates [ensemble] too
    from driftlog.cli import main

    f = tmp_path / "bad.toml"
    f.write_text(text.replace("members = 6", "members = -1"))
    assert main(["scenario", "check", str(f)]) == 2


def test_bad_ensemble_value_names_the_ensemble_file_and_grid_size_is_positive(tmp_path,
                                                                              flow_file,
                                                                              capsys):
    from driftlog.cli import main

    text = ensemble_text(flow_file, tmp_path)
    f = tmp_path / "bad.toml"
    f.write_text(text.replace("members = 6", "members = 0"))
    with pytest.raises(ScenarioError) as err:
        load_ensemble(f)
    assert str(err.value).startswith(f"{f}: [ensemble.members] = 0: must be >= 1")
    # a negative extent gave a one-cell grid, the maps silently cut to it
    f.write_text(text.replace("seed = 11", "seed = 11\ngrid_cell = 1.0\n"
                              "grid_origin = [0.0, 0.0]\ngrid_size = [-20.0, 10.0]"))
    with pytest.raises(ScenarioError, match=r"\[ensemble.grid_size\[0\]\] = -20.0: must be > 0"):
        load_ensemble(f)
    assert main(["scenario", "check", str(f)]) == 2
    assert f"{f}: [ensemble.grid_size[0]] = -20.0" in capsys.readouterr().err


def test_base_scenario_and_place(tmp_path, flow_file):
    base = tmp_path / "base.toml"
    base.write_text(ensemble_text(flow_file, tmp_path).split("[ensemble]")[0])
    f = tmp_path / "ens.toml"
    f.write_text("""
[time]
end = 12.0
[ensemble]
base = "base.toml"
members = 4
sampling = "latin_hypercube"
[ensemble.vary]
"logs.place" = { values = [{ seeding = "line", start = [2, 2], end = [2, 8], count = 3 },
                           { seeding = "list", x = [3.0], y = [5.0] }] }
"logs.count" = { values = [5] }
""")
    e = load_ensemble(f)
    assert e.scenario["time"]["end"] == 12.0 and e.scenario["flow"]["path"] == str(flow_file)
    assert e.output == tmp_path / "ensemble"  # beside the ensemble file
    kinds = set()
    for i in range(4):
        g = e.member_scenario(i)["logs"][0]
        kinds.add(g["seeding"])
        if g["seeding"] == "line":
            assert g["count"] == 5 and g["polygon"] is None  # logs.count wins over the place
            assert len(logs_from_scenario(e.member_scenario(i))) == 5
    assert kinds == {"line", "list"}


# --------------------------------------------------------------------- one member
def test_sweep_marks_every_face_a_fast_log_crosses():
    mesh = Mesh.regular_grid(10, 4, 1.0)
    keys, times, fb = sweep_segments(mesh, [0], [0.5], [0.5], [0.0], [0], [9.5], [0.5], [9.0])
    # faces 1 .. 9 entered at x = 1 .. 9 (the start face is marked when the log is released)
    np.testing.assert_array_equal(keys, np.arange(1, 10))
    np.testing.assert_allclose(times, [0.5 + k for k in range(9)], rtol=0, atol=1e-12)
    assert fb[0] == 9
    # a diagonal: the faces are those a dense sampling of the segment visits
    a, b = np.array([0.3, 0.2]), np.array([9.7, 3.9])
    keys, times, fb = sweep_segments(mesh, [2], [a[0]], [a[1]], [0.0],
                                     mesh.locate([a[0]], [a[1]]), [b[0]], [b[1]], [1.0])
    s = np.linspace(0, 1, 200001)
    dense = set(mesh.locate(a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])).tolist())
    # the start face is marked when the log is released, not by its first segment
    assert set((keys - 2 * mesh.n_faces).tolist()) | {int(mesh.locate([a[0]], [a[1]])[0])} \
        == dense
    assert np.all(np.diff(times[np.argsort(times)]) >= 0) and times.max() <= 1.0
    # leaving the mesh: the walk stops at the boundary, the end is outside
    keys, times, fb = sweep_segments(mesh, [0], [8.5], [0.5], [0.0], [8], [12.5], [0.5], [4.0])
    np.testing.assert_array_equal(keys, [9])
    assert fb[0] == -1 and times[0] == pytest.approx(0.5)


def scenario_for_hits(tmp_path, flow_file):
    return load_scenario(f"""
[flow]
source = "file"
path = "{flow_file}"
[time]
end = 3.0
[[logs]]
x = [2.0, 2.0, 3.0]
y = [3.0, 6.0, 8.0]
release_time = 0.5
[[obstacles]]
name = "pier_a"
center = [12.0, 5.0]
radius = 1.0
[[obstacles]]
name = "pier_b"
center = [15.0, 5.0]
radius = 0.5
""")


def test_recorder_and_trajectory_file_give_the_same_member(tmp_path, flow_file):
    """Records and hits (written with TrajectoryWriter.hits) summarize identically."""
    scen = scenario_for_hits(tmp_path, flow_file)
    mesh = open_flow(flow_file).mesh
    logs = logs_from_scenario(scen)
    names = ["pier_a", "pier_b"]
    writer = TrajectoryWriter(tmp_path / "t.nc", logs, attrs=scen.attrs(), obstacle_names=names)
    rec = MemberRecorder(mesh, logs, 0.0, names)
    path = [(1.0, [0, 1, 2], [3.1, 3.0, 4.0], [3.0, 6.0, 8.0], [FLOATING] * 3),
            (2.0, [0, 1, 2], [7.9, 4.0, 4.0], [3.5, 6.0, 8.0], [FLOATING, RESTING, FLOATING]),
            (3.0, [0, 1, 2], [25.0, 4.0, 4.5], [3.5, 6.0, 8.0], [LEFT, RESTING, STRANDED])]
    hits = {"time": np.array([1.5, 1.6, 2.0, 2.5]), "log_id": np.array([0, 0, 2, 2]),
            "other": np.array([-1, -1, -2, 1]), "impulse": np.ones(4),
            "x": np.zeros(4), "y": np.zeros(4)}
    for w in (writer, rec):
        for t, idx, x, y, st in path:
            n = len(idx)
            cols = dict(x=np.array(x), y=np.array(y), theta=np.zeros(n), u=np.zeros(n),
                        v=np.zeros(n), omega=np.zeros(n), status=np.array(st, np.int8),
                        water_depth=np.ones(n), flow_u=np.ones(n), flow_v=np.zeros(n))
            w.record(t, np.array(idx), cols)
        w.hits(hits)
    writer.close()
    a = rec.summary(3)
    b = summarize_trajectories(tmp_path / "t.nc", mesh, 3)
    for k in ("faces", "face_logs", "face_arrival", "status_counts", "idle_x", "idle_y",
              "idle_status", "idle_face", "obstacle_hits", "obstacle_logs"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)
    assert a.obstacle_names == b.obstacle_names == names
    np.testing.assert_array_equal(a.obstacle_hits, [2, 1])
    np.testing.assert_array_equal(a.obstacle_logs, [1, 1])
    assert a.log_log_hits == b.log_log_hits == 1
    np.testing.assert_array_equal(a.status_counts, [0, 0, 1, 1, 1])
    # log 0 released at (2, 3) at t = 0.5 reaches x = 3.1 at t = 1: faces in between entered
    start = mesh.locate([2.0], [3.0])[0]
    i = np.searchsorted(a.faces, start)
    assert a.face_arrival[i] == 0.5
    assert a.face_arrival.max() <= 3.0 and a.face_arrival.min() == 0.5
    # a summary survives its file
    a.to_npz(tmp_path / "m.npz")
    c = type(a).from_npz(tmp_path / "m.npz")
    np.testing.assert_array_equal(c.face_arrival, a.face_arrival)
    assert c.obstacle_names == names and c.member == 3


def test_hits_per_obstacle_with_intervals(tmp_path, flow_file):
    """Ten members from trajectory files with hits: the fractions and intervals."""
    scen = scenario_for_hits(tmp_path, flow_file)
    mesh = open_flow(flow_file).mesh
    logs = logs_from_scenario(scen)
    agg = Aggregate(mesh, 10)
    counts = []
    for m in range(10):
        w = TrajectoryWriter(tmp_path / f"m{m}.nc", logs, attrs=scen.attrs(),
                             obstacle_names=["pier_a", "pier_b"])
        n = len(logs)
        w.record(1.0, np.arange(n), dict(x=logs.x + 1, y=logs.y, theta=np.zeros(n),
                                         u=np.ones(n), v=np.zeros(n), omega=np.zeros(n),
                                         status=np.full(n, FLOATING, np.int8),
                                         water_depth=np.ones(n), flow_u=np.ones(n),
                                         flow_v=np.zeros(n)))
        k = m + 1 if m < 7 else 0  # pier_a: hit in 7 members of 10, 1 + ... + 7 times
        other = [-1] * k + ([-2] if m == 0 else [])
        w.hits({"time": np.ones(len(other)), "log_id": np.arange(len(other)) % n,
                "other": np.array(other, np.int64), "impulse": np.ones(len(other)),
                "x": np.zeros(len(other)), "y": np.zeros(len(other))})
        w.close()
        counts.append(k)
        agg.add(summarize_trajectories(tmp_path / f"m{m}.nc", mesh, m))
    path = agg.to_netcdf(tmp_path / "agg.nc")
    import xarray as xr

    ds = xr.open_dataset(path)
    assert list(ds["obstacle_name"].values) == ["pier_a", "pier_b"]
    np.testing.assert_array_equal(ds["members_hit"], [7, 1])
    np.testing.assert_array_equal(ds["hits_total"], [28, 1])
    # Wilson 95% for 7 / 10 and Clopper-Pearson (published values: 0.3968-0.8922, 0.3475-0.9333)
    assert ds["hit_probability"][0] == 0.7
    np.testing.assert_allclose([ds["hit_probability_lower"][0], ds["hit_probability_upper"][0]],
                               [0.3968, 0.8922], atol=1e-4)
    np.testing.assert_allclose([ds["hit_probability_cp_lower"][0],
                                ds["hit_probability_cp_upper"][0]], [0.3475, 0.9333], atol=1e-4)
    from scipy import stats

    c = np.array(counts, float)
    half = stats.t.ppf(0.975, 9) * c.std(ddof=1) / np.sqrt(10)
    assert float(ds["hits_mean"][0]) == pytest.approx(2.8)
    assert float(ds["hits_mean_upper"][0]) == pytest.approx(2.8 + half, rel=1e-12)
    np.testing.assert_allclose(ds["logs_hitting_mean"], [(1 + 2 + 3 * 5) / 10, 0.1])
    lo, hi = wilson_interval(0, 10)
    assert lo == 0 and hi == pytest.approx(0.2775, abs=1e-4)
    lo, hi = clopper_pearson_interval(10, 10)
    assert hi == 1 and lo == pytest.approx(0.6915, abs=1e-4)


# --------------------------------------------------------------------- whole ensembles
def aggregate_one_by_one(ens, mesh, members, tmp_path):
    """The same members run with driftlog.api.track, trajectory files summarized."""
    from driftlog.api import track

    agg = Aggregate(mesh, ens.members, ens.parameters)
    for i in members:
        res = track(ens.member_scenario(i), output=tmp_path / f"alone_{i}.nc")
        agg.add(summarize_trajectories(res.path, mesh, i))
    return agg


def assert_same_aggregate(a, b):
    for k in ("members_passing", "logs_passing", "stranded_logs", "resting_logs",
              "status_counts", "first_arrival", "member_state", "member_logs",
              "member_status"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)
    assert a.total_logs == b.total_logs
    np.testing.assert_allclose(a.arrival_sum, b.arrival_sum, rtol=1e-13)


def test_ensemble_on_two_dask_workers_equals_members_run_one_by_one(tmp_path, flow_file):
    from distributed import Client, LocalCluster

    import driftlog.ensemble.runner as runner

    f = write_ensemble(tmp_path, flow_file, members=6)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        res = run_ensemble(f, client=client, progress=False)
        # each worker opened the flow itself, once, whatever the number of its members
        opened = client.run(lambda: len(runner._FLOWS))
        worker_pids = set(client.run(os.getpid).values())
    assert res.done == 6 and not res.failed and sorted(res.ran) == list(range(6))
    assert all(v <= 1 for v in opened.values()) and sum(opened.values()) >= 1
    pids = {open_member(res.output, i).info["worker_pid"] for i in range(6)}
    assert pids <= worker_pids and os.getpid() not in pids
    ens = load_ensemble(f)
    mesh = open_flow(flow_file).mesh
    alone = aggregate_one_by_one(ens, mesh, range(6), tmp_path)
    assert_same_aggregate(res.aggregate, alone)
    assert res.aggregate.total_logs == sum(p["logs.count"] for p in ens.sample(range(6)))
    # what was written is what was aggregated, and xugrid reads it on the flow mesh
    import xugrid

    uds = xugrid.open_dataset(res.path)
    assert uds.ugrid.grid.n_face == mesh.n_faces
    np.testing.assert_array_equal(uds["members_passing"].values, alone.members_passing)
    p = uds["pass_probability"].values
    assert p.max() <= 1.0 and (p > 0).sum() == (alone.members_passing > 0).sum()
    np.testing.assert_array_equal(uds["parameter_logs_count"].values,
                                  [p["logs.count"] for p in ens.sample(range(6))])
    assert [f.name for f in res.figures] == ["pass_probability.png", "first_arrival.png",
                                             "stranding.png"]
    assert all(f.stat().st_size > 10_000 for f in res.figures)


def test_first_arrival_and_pass_probability_in_uniform_flow(tmp_path, flow_file):
    """Tracers on a line at x = 2 move at 1 m/s: they reach x at release + (x - 2)."""
    f = write_ensemble(tmp_path, flow_file, members=4, extra="workers = 0", logs="""
seeding = "line"
start = [2.0, 2.0]
end = [2.0, 8.0]
count = 3
""", vary='"logs.release_time" = { values = [1.0, 3.0] }')
    res = run_ensemble(f, progress=False, figures=False)
    agg = res.aggregate
    mesh = agg.mesh
    ys = np.array([3.0, 7.0])  # the lines y = 3, 7 of the logs; y = 5 meets the pier
    for x in (5.0, 9.0, 13.0):
        faces = mesh.locate(np.full(2, x), ys)
        assert np.all(agg.members_passing[faces] == 4)  # every member passes there
        assert np.all(agg.logs_passing[faces] == 4)  # one log per member
        lo = mesh.face_xmin[faces] - 2.0 + 1.0  # entry by the face's left edge, released at 1 s
        hi = mesh.face_xmax[faces] - 2.0 + 1.0
        t = agg.first_arrival[faces]
        assert np.all((t >= lo - 1e-9) & (t <= hi + 1e-9)), (x, t, lo, hi)
    # the middle log meets the pier at x = 11: it leaves the domain there
    assert agg.status_counts[LEFT] == 4 and agg.status_counts[FLOATING] == 8
    behind = mesh.locate([14.0], [5.0])
    assert agg.members_passing[behind][0] == 0
    # mean arrival over members released at 1 s and 3 s (two each): 1 s later than earliest
    faces = mesh.locate(np.full(2, 9.0), ys)
    ds = res.dataset()
    np.testing.assert_allclose(ds["first_arrival_mean"].values[faces],
                               agg.first_arrival[faces] + 1.0, rtol=1e-12)


def test_failing_member_is_reported_and_others_finish(tmp_path, flow_file, capsys):
    vary = """
"logs.place" = { values = [{ seeding = "list", x = [2.0], y = [3.0] },
                           { seeding = "list", x = [40.0], y = [3.0] }] }
"""
    f = write_ensemble(tmp_path, flow_file, members=6, sampling="grid", vary=vary,
                       extra="workers = 0").read_text().replace("members = 6", "")
    (tmp_path / "e.toml").write_text(f)
    res = run_ensemble(tmp_path / "e.toml", progress=False, figures=False)
    assert res.members == 2 and res.done == 1
    (bad,) = res.failed
    assert bad["member"] == 1 and bad["parameters"]["logs.place"]["x"] == [40.0]
    assert "outside the flow domain" in bad["error"]
    err = capsys.readouterr().err
    assert "member 1 failed (logs.place = " in err and "40.0" in err
    record = json.loads((res.output / "failed" / "member_000001.json").read_text())
    assert record["parameters"]["logs.place"]["x"] == [40.0] and "Traceback" not in \
        record["error"]
    ds = res.dataset()
    np.testing.assert_array_equal(ds["member_state"], [1, 2])
    assert "outside the flow domain" in str(ds["member_error"].values[1])
    # resume: the failed member is tried again, the finished one is not
    again = run_ensemble(tmp_path / "e.toml", progress=False, figures=False, resume=True)
    assert again.ran == [] and again.resumed == 1 and [m["member"] for m in again.failed] == [1]


def test_resume_after_a_partial_run_repeats_nothing(tmp_path, flow_file):
    f = write_ensemble(tmp_path, flow_file, members=8, sampling="monte_carlo",
                       extra="workers = 0")
    first = run_ensemble(f, members=range(0, 8, 2), progress=False, figures=False)
    assert first.ran == [0, 2, 4, 6] and first.done == 4
    ds = first.dataset()
    np.testing.assert_array_equal(ds["member_state"], [1, 0] * 4)
    with pytest.raises(DriftlogError, match="already holds 4 finished members"):
        run_ensemble(f, progress=False)
    stamps = {p.name: p.stat().st_mtime_ns for p in (first.output / "members").iterdir()}
    rest = run_ensemble(f, resume=True, progress=False, figures=False)
    assert rest.ran == [1, 3, 5, 7] and rest.resumed == 4 and rest.done == 8
    assert {p.name: p.stat().st_mtime_ns for p in (first.output / "members").iterdir()
            if p.name in stamps} == stamps
    fresh = run_ensemble(f, output=tmp_path / "fresh", progress=False, figures=False)
    assert_same_aggregate(rest.aggregate, fresh.aggregate)
    # a Monte Carlo ensemble extends: more members, resume, only the new ones run
    more = run_ensemble(f, resume=True, progress=False, figures=False,
                        overrides={"ensemble": {"members": 10}})
    assert more.ran == [8, 9] and more.done == 10
    # a different ensemble is not mixed into these results
    with pytest.raises(DriftlogError, match="different ensemble"):
        run_ensemble(f, resume=True, progress=False, overrides={"ensemble": {"seed": 12}})


def test_resume_after_the_process_is_killed(tmp_path, flow_file):
    """Kill the CLI mid-run (SIGKILL), resume: nothing lost, nothing run twice."""
    f = write_ensemble(tmp_path, flow_file, members=24, sampling="monte_carlo",
                       extra="workers = 0", vary='"logs.count" = { integers = [60, 80] }')
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-m", "driftlog", "ensemble", str(f), "--quiet",
                             "--no-figures"], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    members = tmp_path / "out" / "members"
    deadline = time.time() + 120  # a cold numba cache compiles first
    while time.time() < deadline and proc.poll() is None:
        if members.is_dir() and len(list(members.glob("member_*.npz"))) >= 2:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = {p.name: p.stat().st_mtime_ns for p in members.glob("member_*.npz")}
    assert 2 <= len(before) < 24, proc.stderr.read().decode()[-2000:]
    res = run_ensemble(f, resume=True, progress=False, figures=False)
    done_before = sorted(int(n[7:13]) for n in before)
    assert res.resumed == len(before) and res.done == 24
    assert sorted(res.ran) == sorted(set(range(24)) - set(done_before))  # repeats nothing
    assert {p.name: p.stat().st_mtime_ns for p in members.glob("member_*.npz")
            if p.name in before} == before
    assert not list(members.glob("*.tmp"))
    fresh = run_ensemble(f, output=tmp_path / "fresh", progress=False, figures=False)
    assert_same_aggregate(res.aggregate, fresh.aggregate)  # loses nothing


def test_member_reproducible_and_cli(tmp_path, flow_file, capsys):
    f = write_ensemble(tmp_path, flow_file, members=3, extra="workers = 0")
    a, b = run_member(f, 2), run_member(f, 2)
    for k in ("faces", "face_logs", "face_arrival", "status_counts"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert a.parameters == load_ensemble(f).parameters_of(2)
    from driftlog.cli import main

    assert main(["ensemble", str(f), "--quiet", "--no-figures"]) == 0
    out = capsys.readouterr().out
    assert "3 of 3 members done" in out and "ensemble.nc" in out
    c = open_member(tmp_path / "out", 2)
    np.testing.assert_array_equal(c.face_arrival, a.face_arrival)
    assert main(["ensemble", str(f), "--quiet"]) == 2
    assert "--resume" in capsys.readouterr().err


def test_kept_trajectory_files_summarize_to_the_member(tmp_path, flow_file):
    f = write_ensemble(tmp_path, flow_file, members=2,
                       extra="workers = 0\nkeep_trajectories = true")
    res = run_ensemble(f, progress=False, figures=False)
    import xarray as xr

    mesh = res.aggregate.mesh
    for i in range(2):
        path = res.output / "trajectories" / f"member_{i:06d}.nc"
        with xr.open_dataset(path) as ds:
            assert ds.attrs["ensemble_member"] == i
            assert json.loads(ds.attrs["ensemble_parameters"]) == \
                load_ensemble(f).parameters_of(i)
        a, b = open_member(res.output, i), summarize_trajectories(path, mesh, i)
        for k in ("faces", "face_logs", "face_arrival", "status_counts", "idle_face"):
            np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)


def test_analytic_flow_needs_an_aggregation_grid(tmp_path):
    text = """
[flow]
source = "analytic"
kind = "uniform"
velocity = [1.0, 0.0]
[time]
end = 5.0
[[logs]]
x = [1.2]
y = [1.2]
[physics]
level = "tracer"
[ensemble]
members = 2
sampling = "latin_hypercube"
workers = 0
output = "{out}"
[ensemble.vary]
"logs.release_time" = {{ values = [0.0, 1.0] }}
""".format(out=tmp_path / "o")
    with pytest.raises(ScenarioError, match=r"\[ensemble.grid_cell\] = None: the flow has no"):
        run_ensemble(text, progress=False)
    res = run_ensemble(text.replace("workers = 0", "workers = 0\ngrid_cell = 0.5\n"
                                    "grid_origin = [0.0, 0.0]\ngrid_size = [10.0, 2.0]"),
                       progress=False, figures=False)
    agg = res.aggregate
    assert agg.mesh.n_faces == 20 * 4
    row = np.arange(20) + 2 * 20  # y in [1, 1.5); released at x = 1.2, at 0 s or 1 s
    np.testing.assert_array_equal(agg.members_passing[row], [0, 0] + [2] * 9 + [1, 1] + [0] * 7)
    # cell k (x from 0.5 k) is entered at 0.5 k - 1.2 s by the log released at 0 s
    np.testing.assert_allclose(agg.first_arrival[row[2:13]],
                               np.r_[0.0, 0.5 * np.arange(3, 13) - 1.2], atol=1e-12)


def test_run_member_on_a_solved_flow(tmp_path):
    """run_member (one member in this process) prepares a solved flow as run_ensemble does."""
    scen = tmp_path / "s.toml"
    scen.write_text(f"""
[flow]
source = "solver"
path = "{tmp_path / 'flow.nc'}"
steady_at = 20.0
[solver]
channel = [0.0, 0.0, 40.0, 8.0]
cell_size = 2.0
manning = 0.03
end = 20.0
[solver.initial]
type = "level"
value = 1.0
velocity = [0.5, 0.0]
[solver.boundaries.inflow]
type = "discharge"
value = 4.0
[solver.boundaries.outflow]
type = "level"
value = 1.0
[time]
end = 20.0
[[logs]]
x = [5.0, 5.0]
y = [3.0, 5.0]
length = 1.0
radius = 0.1
[ensemble]
members = 2
[ensemble.vary]
"logs.density" = {{ uniform = [500.0, 900.0] }}
""")
    summary = run_member(scen, 1)
    mesh = open_flow(tmp_path / "flow.nc").mesh
    assert summary.n_logs == 2 and summary.n_faces == mesh.n_faces  # counted on the flow mesh
    # both logs drift downstream over 20 s: faces passed lie east of the release, up to ~20 m
    x = mesh.face_x[summary.faces]
    assert summary.faces.size >= 4 and x.max() > 8.0
    assert 500.0 <= summary.parameters["logs.density"] <= 900.0


# --------------------------------------------------------------------- clogging odds
def test_wilson_interval_against_known_values():
    """Wilson (1927) score interval: Newcombe (1998) table I, and scipy's binomtest."""
    from scipy import stats

    # Newcombe, Stat. Med. 17 (1998) 857-872, table I: 81/263 -> 0.2553-0.3662 (95%)
    lo, hi = wilson_interval(81, 263)
    assert (lo, hi) == (pytest.approx(0.2553, abs=1e-4), pytest.approx(0.3662, abs=1e-4))
    for k, n in ((0, 10), (3, 7), (10, 10), (15, 148)):
        ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.9, method="wilson")
        np.testing.assert_allclose(wilson_interval(k, n, 0.9), (ci.low, ci.high), atol=1e-12)


@pytest.fixture(scope="module")
def bridge_flow(tmp_path_factory):
    """A 30 m x 10 m channel, uniform flow 0.5 m/s along x, 1 m deep."""
    mesh = channel_mesh(30.0, 10.0, 1.0)
    field = on_mesh(UniformFlow(0.5, 0.0, depth=1.0), mesh, times=[0.0, 100.0])
    return write_flow(tmp_path_factory.mktemp("bridge") / "flow.nc", field)


def test_clogging_odds_of_a_bridge(tmp_path, bridge_flow, capsys):
    """Logs released across the flow in front of a two-pier bridge jam on both piers; logs
    released along the flow beside it pass: the blocked counts are known by construction."""
    import xarray as xr

    from driftlog import cli

    f = tmp_path / "e.toml"
    across = '{ seeding = "list", x = [10.0], y = [5.0], theta = 1.5707963267948966 }'
    along = '{ seeding = "list", x = [10.0], y = [8.5], theta = 0.0 }'
    place = f'"logs.place" = {{ values = [{across}, {along}] }}'
    f.write_text(f"""
[flow]
source = "file"
path = "{bridge_flow}"
[time]
end = 40.0
output_interval = 1.0
[[logs]]
x = [10.0]
y = [5.0]
theta = 1.5707963267948966
length = 2.4
radius = 0.1
density = 600.0
[physics]
level = "drag"
[contact]
enabled = true
method = "moreau"
restitution = 0.0
[[obstacles]]
name = "pier_low"
group = "bridge"
center = [15.0, 4.2]
radius = 0.3
[[obstacles]]
name = "pier_high"
group = "bridge"
center = [15.0, 5.8]
radius = 0.3
[ensemble]
sampling = "grid"
output = "{tmp_path / 'out'}"
workers = 0
blocked_after = 10.0
[ensemble.vary]
{place}
"logs.release_time" = {{ values = [0.0, 3.0] }}
""")
    assert cli.main(["ensemble", str(f), "--workers", "0", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "clogging odds over 4 members" in out and "bridge" in out
    ds = xr.open_dataset(tmp_path / "out" / "ensemble.nc")
    sites = [str(s) for s in ds["site_name"].values]
    assert sites == ["pier_low", "pier_high", "bridge"]
    assert [str(s) for s in ds["site_kind"].values] == ["obstacle", "obstacle", "group"]
    # members 0, 1 release across in front of the bridge (place 0), 2, 3 beside it
    place = ds["parameter_logs_place"].values
    across = place == 0
    assert across.sum() == 2
    held = ds["member_held_seconds"].values[:, :2]
    assert np.all(held[across] >= 20.0) and np.all(held[~across] == 0.0)
    hits = ds["member_hits"].values[:, :2]
    assert np.all(hits[across] >= 1) and np.all(hits[~across] == 0)
    np.testing.assert_array_equal(ds["site_members_hit"], [2, 2, 2])
    np.testing.assert_array_equal(ds["site_members_blocked"], [2, 2, 2])
    np.testing.assert_allclose(ds["site_blocked_probability"], 0.5)
    lo, hi = wilson_interval(2, 4)
    np.testing.assert_allclose(ds["site_blocked_lower"], lo)
    np.testing.assert_allclose(ds["site_blocked_upper"], hi)
    assert float(ds["site_blocked_probability"].attrs["blocked_after"]) == 10.0
    ds.close()
    csv = (tmp_path / "out" / "clogging.csv").read_text().splitlines()
    assert csv[0].startswith("site,kind,obstacles,members,members_hit,hit_probability")
    assert csv[3].startswith("bridge,group,pier_low pier_high,4,2,0.5,")
    assert (tmp_path / "out" / "clogging.png").is_file()
    # a longer hold is asked: hit but not blocked (the aggregate, not the members, decides:
    # a resume with nothing left to run re-aggregates the stored members)
    res = run_ensemble(f, resume=True, progress=False, figures=False,
                       overrides={"ensemble": {"blocked_after": 1000.0}})
    assert res.ran == [] and res.resumed == 4
    t = res.aggregate.clogging_table()
    np.testing.assert_array_equal(t["members_hit"], [2, 2, 2])
    np.testing.assert_array_equal(t["members_blocked"], [0, 0, 0])
    # longer than the 40-s run: no obstacle could count as blocked, said beside the table
    said = res.aggregate.format_clogging()
    assert "note: blocked_after = 1000 s is longer than the run (40 s)" in said
    assert "note:" not in run_ensemble(f, resume=True, progress=False, figures=False,
                                       overrides={"ensemble": {"blocked_after": 30.0}}
                                       ).aggregate.format_clogging()


def test_flow_file_whose_title_says_ensemble_is_a_flow(tmp_path, flow_file):
    """A solved flow takes its scenario's title ("river_piers ensemble: ..."): still a flow."""
    import shutil

    import netCDF4

    from driftlog.files import sniff

    p = shutil.copy(flow_file, tmp_path / "flow.nc")
    with netCDF4.Dataset(p, "a") as ds:
        ds.title = "river_piers ensemble: uncertain logs through the two bridges"
    assert sniff(p).kind == "flow"
