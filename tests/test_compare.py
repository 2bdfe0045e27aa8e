"""driftlog compare: the same debris on two hydro sources."""
import numpy as np
import pytest

from driftlog.analytic import UniformFlow, on_mesh
from driftlog.cli import main
from driftlog.compare import arrival_times, compare_runs, compare_trajectories
from driftlog.flowfile import write_flow
from driftlog.mesh import Mesh
from driftlog.trajectory import open_trajectories

SCEN = """
title = "compare"
[flow]
source = "file"
path = "{a}"
[time]
end = 40.0
output_interval = 1.0
[[logs]]
seeding = "line"
start = [2.0, 1.0]
end = [2.0, 3.0]
count = 3
length = 0.5
radius = 0.05
density = 700.0
[physics]
level = "tracer"
"""


@pytest.fixture
def flows(tmp_path):
    mesh = Mesh.regular_grid(60, 4, 1.0)
    mesh.tag_boundary("outflow", lambda x, y: x > 59.999)
    a = write_flow(tmp_path / "a.nc", on_mesh(UniformFlow(1.0, 0.0, depth=1.0), mesh))
    b = write_flow(tmp_path / "b.nc", on_mesh(UniformFlow(1.1, 0.0, depth=1.1), mesh))
    scen = tmp_path / "s.toml"
    scen.write_text(SCEN.format(a=a))
    return scen, a, b


def test_same_flow_twice_gives_no_difference(tmp_path, flows):
    scen, a, _ = flows
    rep = compare_runs(scen, [("a", str(a)), ("a_again", "scenario")], tmp_path / "cmp")
    c = rep["comparisons"]["a_again"]
    assert c["distance_max"] == 0.0
    assert c["flow_at_logs"]["speed_rms"] == 0.0


def test_faster_flow_moves_logs_further_and_earlier(tmp_path, flows):
    scen, a, b = flows
    rep = compare_runs(scen, [("slow", str(a)), ("fast", str(b))], tmp_path / "cmp",
                       line=(30.0, 0.0, 30.0, 4.0))
    c = rep["comparisons"]["fast"]
    assert c["flow_at_logs"]["speed_rms"] == pytest.approx(0.1, rel=1e-9)
    assert c["flow_at_logs"]["depth_rms"] == pytest.approx(0.1, rel=1e-9)
    # tracer logs: distance 0.1 t until the fast run leaves the mesh at x = 60 (t = 52.7 s)
    r = compare_trajectories(tmp_path / "cmp" / "trajectories_slow.nc",
                             tmp_path / "cmp" / "trajectories_fast.nc", (30.0, 0.0, 30.0, 4.0))
    np.testing.assert_allclose(r["mean_distance"], 0.1 * r["times"], atol=1e-9)
    np.testing.assert_allclose(r["arrival_reference"], 28.0, atol=1e-9)  # (30 - 2) / 1.0
    np.testing.assert_allclose(r["arrival_other"], 28.0 / 1.1, atol=1e-9)
    assert c["arrival_difference_mean"] == pytest.approx(28.0 / 1.1 - 28.0)
    for f in ("compare.png", "compare.md", "compare.json"):
        assert (tmp_path / "cmp" / f).is_file()
    # each table's delimiter row has its header's columns (the per-log table had one less, so
    # that Markdown did not draw it)
    rows = (tmp_path / "cmp" / "compare.md").read_text().splitlines()
    for head, delim in zip(rows, rows[1:], strict=False):
        if delim.startswith("|---"):
            assert delim.count("|") == head.count("|"), (head, delim)


def test_arrival_by_leaving_the_domain(tmp_path, flows):
    scen, a, _ = flows
    from driftlog.api import track

    res = track(scen, output=tmp_path / "t.nc", overrides={"time": {"end": 70.0}})
    arr = arrival_times(open_trajectories(res.path))
    # x = 2 + t passes x = 60 at t = 58; recorded as left at the next output time
    np.testing.assert_allclose(arr, 59.0)


def test_cli_compare(tmp_path, flows, capsys):
    scen, a, b = flows
    assert main(["compare", str(scen), "--flow", f"slow={a}", "--flow", f"fast={b}",
                 "--out", str(tmp_path / "c")]) == 0
    assert "fast" in capsys.readouterr().out
    assert main(["compare", str(tmp_path / "c" / "trajectories_slow.nc"),
                 str(tmp_path / "c" / "trajectories_fast.nc")]) == 0
    assert main(["compare", str(scen)]) == 2


def test_cli_compare_refuses_mismatched_files_and_unused_options(tmp_path, flows, capsys):
    from driftlog.api import track

    scen, a, _ = flows
    early = track(scen, output=tmp_path / "early.nc", overrides={"time": {"end": 5.0}}).path
    late = track(scen, output=tmp_path / "late.nc",
                 overrides={"time": {"start": 10.0, "end": 15.0}}).path
    capsys.readouterr()
    # no record at a common time: was an IndexError traceback
    assert main(["compare", str(early), str(late)]) == 2
    err = capsys.readouterr().err
    assert "late.nc: no record at the same time" in err and "10 to 15 s" in err
    # --gate was silently ignored with two trajectory files
    assert main(["compare", str(early), str(early), "--gate", "g=1,0,1,4"]) == 2
    assert "--gate g=1,0,1,4: not used" in capsys.readouterr().err
    # a line of zero length: nothing crosses it, every arrival silently NaN
    assert main(["compare", str(early), str(early), "--line", "3", "1", "3", "1"]) == 2
    assert "--line: 3 1 3 1: must be a line" in capsys.readouterr().err
    assert main(["compare", str(scen), "--flow", f"a={a}", "--flow", f"b={a}",
                 "--gate", "g=1,1,1,1"]) == 2
    assert "--gate 'g=1,1,1,1'" in capsys.readouterr().err
    # runs of different lengths: the final distance is at the last time both record, said so
    # (it read "at the end")
    longer = track(scen, output=tmp_path / "longer.nc", overrides={"time": {"end": 8.0}}).path
    capsys.readouterr()
    assert main(["compare", str(early), str(longer)]) == 0
    said = capsys.readouterr().out
    assert "mean distance at t = 5 s, the last time both record (the reference ends at 5 s, " \
        "the other at 8 s): 0 m" in said
    assert main(["compare", str(early), str(early)]) == 0
    assert "mean distance at the end: 0 m" in capsys.readouterr().out
