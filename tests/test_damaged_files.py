"""Damaged and mismatched files found by a fuzz pass: each gets one clear DriftlogError naming the
file (or key), the value and what is allowed, and a non-zero exit; never a traceback.

Trajectory files without observations, with a broken structure (rowSize, missing variables,
status codes, JSON attributes), a flow file with a NaN node coordinate, a text file as an
obstacle mesh, theta = a list of strings, and ``--resume`` on a ``.partial`` file of another
kind, other logs or another scenario.
"""

import shutil
import textwrap
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from test_robust import UNIFORM, _err  # the bad-input tests' scenario and error check

from driftlog.cli import main
from driftlog.flowfile import FlowFileWriter
from driftlog.mesh import Mesh


def _scenario(path, text=UNIFORM, **replace):
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def traj(tmp_path_factory):
    """A good trajectory file (2 logs, 5 records)."""
    from driftlog.api import track

    out = tmp_path_factory.mktemp("traj") / "traj.nc"
    track(UNIFORM, output=out)
    return out


def _damaged(traj, path, change):
    shutil.copy(traj, path)
    with netCDF4.Dataset(path, "a") as ds:
        change(ds)
    return path


def _set(name, f):
    def change(ds):
        ds[name][:] = f(ds[name][:])
    return change


# ----------------------------------------------------------------- no observations
def test_release_outside_the_run_is_refused_by_check_and_track(tmp_path, capsys):
    """Logs released after [time] end: track said complete with 0 observations, and plot,
    animate and run's figure then failed on the empty file."""
    late = _scenario(tmp_path / "late.toml", UNIFORM + "[output]\npath = 'late.nc'\n",
                     **{"density = 700.0": "density = 700.0\nrelease_time = 100.0"})
    for cmd in (["scenario", "check", late], ["track", late],
                ["run", late, "--out", tmp_path / "run"]):
        err = _err(capsys, cmd)
        assert "[logs[0].release_time] = 100.0: is after time.end (4 s)" in err, err
        assert "between time.start = 0 s and the run's end (4 s)" in err
    assert not list(tmp_path.glob("late.nc*")) and not list(tmp_path.glob("run/*.nc*"))
    early = _scenario(tmp_path / "early.toml",
                      **{"density = 700.0": "density = 700.0\nrelease_time = -1.0"})
    assert "[logs[0].release_time] = -1.0: is before time.start = 0 s" in _err(
        capsys, ["scenario", "check", early])
    inside = _scenario(tmp_path / "in.toml",
                       **{"density = 700.0": "density = 700.0\nrelease_time = 4.0"})
    assert main(["scenario", "check", str(inside)]) == 0


def test_plot_animate_vtk_refuse_a_file_without_observations(traj, tmp_path, capsys):
    import xarray as xr

    empty = tmp_path / "empty_obs.nc"
    with xr.open_dataset(traj, decode_times=False) as ds:
        ds.isel(obs=slice(0, 0)).assign(rowSize=ds.rowSize * 0).to_netcdf(empty)
    for cmd in (["plot", empty], ["animate", empty], ["vtk", empty]):
        err = _err(capsys, cmd)
        assert f"{empty}: the trajectory file holds no observations (2 logs" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty_obs.nc"]  # nothing written
    assert main(["info", str(empty)]) == 0  # info describes it
    assert "2 logs, 0 observations" in capsys.readouterr().out


# ----------------------------------------------------------------- broken structure
DAMAGES = {
    "rowsize_more": (_set("rowSize", lambda a: a + 5),
                     "rowSize sums to 20 observations, the obs dimension holds 10"),
    "rowsize_negative": (_set("rowSize", lambda a: -a), "rowSize[0] = -5: a count of "
                                                        "observations must be >= 0"),
    "rowsize_renamed": (lambda ds: ds.renameVariable("rowSize", "foo"),
                        "neither rowSize (a finished file) nor trajectory_index"),
    "x_renamed": (lambda ds: ds.renameVariable("x", "foo"),
                  "no variable 'x' (one value per observation)"),
    "status_renamed": (lambda ds: ds.renameVariable("status", "foo"), "no variable 'status'"),
    "status_99": (_set("status", lambda a: a * 0 + 99),
                  "status[0] = 99: the status codes are 0 to 4"),
    "obstacle_names": (lambda ds: ds.setncattr("obstacle_names", "not json ["),
                       "the attribute obstacle_names is not JSON"),
    "scenario_resolved": (lambda ds: ds.setncattr("scenario_resolved", "{not json"),
                          "the attribute scenario_resolved is not JSON"),
}


@pytest.mark.parametrize("damage", sorted(DAMAGES))
def test_damaged_trajectory_structure_is_named(traj, tmp_path, capsys, damage):
    change, what = DAMAGES[damage]
    bad = _damaged(traj, tmp_path / f"{damage}.nc", change)
    for cmd in (["info", bad], ["plot", bad], ["vtk", bad], ["compare", traj, bad]):
        err = _err(capsys, cmd)
        assert f"{bad}: a damaged trajectory file: {what}" in err, (cmd, err)
    from driftlog.errors import InputFileError
    from driftlog.trajectory import open_trajectories

    with pytest.raises(InputFileError, match="a damaged trajectory file"):
        open_trajectories(bad)
    assert open_trajectories(traj).sizes["obs"] == 10  # the good one reads


# ----------------------------------------------------------------- flow and obstacle files
def test_flow_file_with_a_nan_node_coordinate(tmp_path, capsys):
    mesh = Mesh.regular_grid(10, 4, 1.0)
    flow = tmp_path / "flow.nc"
    with FlowFileWriter(flow, mesh, np.zeros(mesh.n_faces)) as w:
        for t in (0.0, 10.0):
            w.write(t, np.ones(mesh.n_faces), u=np.full(mesh.n_faces, 0.2),
                    v=np.zeros(mesh.n_faces))
    with netCDF4.Dataset(flow, "a") as ds:
        x = ds["mesh2d_node_x"][:]
        x[3] = np.nan
        ds["mesh2d_node_x"][:] = x
    s = _scenario(tmp_path / "s.toml", **{
        'source = "analytic"\nkind = "uniform"\nvelocity = [0.5, 0.0]\ndepth = 1.0':
            f'source = "file"\npath = "{flow}"', "x = [1.0, 2.0]": "x = [2.0, 3.0]",
        "y = [0.0, 1.0]": "y = [2.0, 2.0]"})
    for cmd in (["info", flow], ["scenario", "check", s], ["track", s]):
        err = _err(capsys, cmd)
        assert f"{flow}: not a driftlog flow file: the node coordinate mesh2d_node_x[3] = " \
               "nan: node coordinates must be finite numbers (1 of 55 are not)" in err, err


def test_text_file_as_an_obstacle_mesh(tmp_path, capsys):
    stl = tmp_path / "x.stl"
    stl.write_text("solid text\n")
    s = _scenario(tmp_path / "s.toml", UNIFORM + textwrap.dedent(f"""
        [contact]
        enabled = true
        [[obstacles]]
        type = "mesh"
        path = "{stl}"
        """))
    for cmd in (["scenario", "check", s], ["track", s]):
        err = _err(capsys, cmd)
        assert f"[obstacles[0].path] = '{stl}': holds no points: not a surface mesh" in err


def test_theta_list_of_strings_is_refused_by_the_schema(tmp_path, capsys):
    s = _scenario(tmp_path / "s.toml",
                  **{"density = 700.0": 'density = 700.0\ntheta = ["a", "b"]'})
    err = _err(capsys, ["scenario", "check", s])
    assert "[logs[0].theta[0]] = 'a': must be a number" in err
    s.write_text(s.read_text().replace('theta = ["a", "b"]', "theta = []"))
    assert "[logs[0].theta] = []: must be a number or a non-empty list" in _err(
        capsys, ["scenario", "check", s])
    from driftlog.scenario import load_scenario

    for good in ("[0.5, 1.0]", "0.5", "'random'"):
        s.write_text(UNIFORM.replace("density = 700.0", f"density = 700.0\ntheta = {good}"))
        assert load_scenario(s)["logs"][0]["theta"] in ([0.5, 1.0], 0.5, "random")


# ----------------------------------------------------------------- resume
def _stopped(scenario, out):
    """A run of ``scenario`` stopped after t = 2 s: its .partial file."""
    from driftlog.api import track
    from driftlog.tracker import Tracker

    real = Tracker._record

    def stop(self):
        if self.t > 2.0:
            raise KeyboardInterrupt
        real(self)

    Tracker._record = stop
    try:
        with pytest.raises(KeyboardInterrupt):
            track(scenario, output=out)
    finally:
        Tracker._record = real
    return Path(str(out) + ".partial")


def test_resume_refuses_a_partial_of_another_kind_logs_or_scenario(tmp_path, capsys):
    s2 = _scenario(tmp_path / "two.toml")
    s3 = _scenario(tmp_path / "three.toml", **{"x = [1.0, 2.0]": "x = [1.0, 2.0, 3.0]",
                                               "y = [0.0, 1.0]": "y = [0.0, 1.0, 2.0]"})
    longer = _scenario(tmp_path / "longer.toml", **{"end = 4.0": "end = 5.0"})
    out = tmp_path / "r.nc"
    # a flow file where the .partial is: not a trajectory file
    flow = tmp_path / "f.nc"
    mesh = Mesh.regular_grid(4, 2, 1.0)
    with FlowFileWriter(flow, mesh, np.zeros(mesh.n_faces)) as w:
        w.write(0.0, np.ones(mesh.n_faces), u=np.zeros(mesh.n_faces), v=np.zeros(mesh.n_faces))
    shutil.copy(flow, str(out) + ".partial")
    err = _err(capsys, ["track", s2, "-o", out, "--resume"])
    assert f"{out}.partial: a driftlog flow file; the file a run resumes from must be the " \
           ".partial trajectory file of a stopped run: rerun it from the start" in err
    # a good partial of 2 logs, resumed with 3 logs or another scenario: refused, untouched
    partial = _stopped(s2, out)
    kept = partial.read_bytes()
    err = _err(capsys, ["track", s3, "-o", out, "--resume"])
    assert f"{partial}: cannot resume the run from it: it holds 2 logs, the scenario seeds " \
           "3; rerun it from the start, without --resume" in err
    err = _err(capsys, ["track", longer, "-o", out, "--resume"])
    assert "it was computed from another scenario (its scenario_resolved differs)" in err
    assert partial.read_bytes() == kept and sorted(tmp_path.glob("r.nc*")) == [partial]
    # its own scenario resumes it
    assert main(["track", str(s2), "-o", str(out), "--resume", "--quiet"]) == 0
    assert out.is_file() and not partial.exists()
