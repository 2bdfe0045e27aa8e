import subprocess
import sys
from pathlib import Path

import numpy as np

from driftlog import __version__
from driftlog.cli import build_parser, main


def run(*args):
    return subprocess.run([sys.executable, "-m", "driftlog", *args], capture_output=True, text=True)


def test_version_and_help():
    out = run("--version")
    assert out.stdout.strip() == f"driftlog {__version__}"
    out = run("--help")
    assert out.returncode == 0 and "commands" in out.stdout


def test_every_command_has_help_with_an_example(capsys):
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    assert len(sub.choices) >= 2
    for name, p in sub.choices.items():
        assert "example:" in (p.epilog or ""), f"driftlog {name} --help lacks an example"
        assert f"driftlog {name}" in p.epilog


def test_scenario_keys_and_check(tmp_path, capsys):
    assert main(["scenario", "keys", "--section", "physics"]) == 0
    assert "drag_area" in capsys.readouterr().out
    f = tmp_path / "s.toml"
    f.write_text("[physics]\nlevel = 'wrong'\n")
    assert main(["scenario", "check", str(f)]) == 2
    err = capsys.readouterr().err
    assert "[physics.level] = 'wrong'" in err and "'tracer'" in err


def test_scenario_file_in_place_of_the_action(tmp_path, capsys):
    """``driftlog scenario FILE`` checks FILE (a wrong file fails as with ``check``); an action
    that is neither an action nor a file nor a case is named in the error with what is allowed."""
    f = tmp_path / "s.toml"
    f.write_text("[physics]\nlevel = 'wrong'\n")
    assert main(["scenario", str(f)]) == 2
    assert "[physics.level] = 'wrong'" in capsys.readouterr().err
    assert main(["scenario", "vortex"]) == 0
    assert "valid: the run will start" in capsys.readouterr().out
    assert main(["scenario", "frobnicate"]) == 2
    err = capsys.readouterr().err
    assert "'frobnicate'" in err and "'keys'" in err and "'check'" in err
    assert "unknown case" in err  # and why it is not a case either
    assert main(["scenario", str(tmp_path / "nope.toml")]) == 2
    assert "scenario file not found" in capsys.readouterr().err


def test_ensemble_errors_name_the_file(tmp_path, capsys):
    """A scenario without [ensemble], or a base that is not there: the file in the message."""
    f = tmp_path / "plain.toml"
    f.write_text("[time]\nend = 5.0\n")
    assert main(["ensemble", str(f)]) == 2
    err = capsys.readouterr().err
    assert str(f) in err and "[ensemble] = 'missing'" in err
    e = tmp_path / "e.toml"
    e.write_text("[ensemble]\nbase = 'nothere.toml'\nmembers = 2\n")
    assert main(["ensemble", str(e)]) == 2
    err = capsys.readouterr().err
    assert str(e) in err and "nothere.toml" in err and "file not found" in err


def test_info_missing_file(capsys):
    assert main(["info", "/nonexistent/flow.nc"]) == 2
    assert "not found" in capsys.readouterr().err


def test_run_a_case_end_to_end(tmp_path, capsys):
    assert main(["run", "vortex", "--out", str(tmp_path), "--quiet",
                 "--set", "time.end=20.0", "--set", "physics.level=tracer"]) == 0
    out = capsys.readouterr().out
    for f in ("trajectories.nc", "trajectories.png", "animation"):
        assert f in out
    import xarray as xr

    ds = xr.open_dataset(tmp_path / "trajectories.nc", decode_times=False)
    assert ds.attrs["physics_level"] == "tracer"
    assert ds["time"].values[-1] == 20.0
    # the log stays on its circle of radius 1 m
    np.testing.assert_allclose(np.hypot(ds["x"].values, ds["y"].values), 1.0, atol=1e-6)
    assert (tmp_path / "trajectories.png").stat().st_size > 10_000


def test_run_stopped_then_resumed_with_the_command_it_names(tmp_path, capsys):
    """An interrupted ``driftlog run`` names the command that continues it (``run ...
    --resume``, not ``track``, whose paths would not be the run folder's) and that command
    gives the uninterrupted run's trajectories."""
    import shlex

    from driftlog.trajectory import open_trajectories

    args = ["vortex", "--quiet", "--no-figure", "--no-animation", "--set", "time.end=20.0"]
    assert main(["run", *args, "--out", str(tmp_path / "full")]) == 0
    from driftlog.tracker import Tracker

    real = Tracker._record

    def stop(self):
        if self.t > 12.0:
            raise KeyboardInterrupt
        real(self)

    Tracker._record = stop
    try:
        assert main(["run", *args, "--out", str(tmp_path / "r")]) == 130
    finally:
        Tracker._record = real
    err = capsys.readouterr().err
    hint = err.split("; ")[-1].split(" continues it")[0].strip()
    words = shlex.split(hint)
    assert words[:2] == ["driftlog", "run"] and words[-1] == "--resume"
    assert main(words[1:]) == 0
    a = open_trajectories(tmp_path / "full" / "trajectories.nc")
    b = open_trajectories(tmp_path / "r" / "trajectories.nc")
    for v in ("time", "x", "y", "theta"):
        np.testing.assert_array_equal(a[v].values, b[v].values)


def test_track_draws_what_the_output_section_asks(tmp_path, capsys):
    """``[output] figure`` and ``animation`` (they were read by nothing until 2026-12-07: a
    scenario asking for a figure got none, without a word): ``driftlog track`` draws them
    beside the trajectory file and says where.  ``driftlog run`` draws its own into the run
    folder (once, not again for the keys)."""
    import matplotlib.image as mpimg

    traj = tmp_path / "t.nc"
    assert main(["track", "vortex", "-o", str(traj), "--quiet", "--set", "time.end=10.0",
                 "--set", "physics.level=tracer", "--set", "output.figure=true",
                 "--set", "output.animation=true"]) == 0
    out = capsys.readouterr().out
    png = tmp_path / "t.png"
    anim = [p for p in (tmp_path / "t.mp4", tmp_path / "t.gif") if p.exists()]
    assert f"figure: {png}" in out and len(anim) == 1 and f"animation: {anim[0]}" in out
    img = mpimg.imread(png)
    assert img.shape[0] > 200 and img.shape[1] > 200 and img[..., :3].std() > 0.05  # drawn
    assert anim[0].stat().st_size > 10_000
    # without the keys: the trajectory file alone
    bare = tmp_path / "bare"
    bare.mkdir()
    assert main(["track", "vortex", "-o", str(bare / "t.nc"), "--quiet", "--set",
                 "time.end=10.0", "--set", "physics.level=tracer"]) == 0
    assert sorted(p.name for p in bare.iterdir()) == ["t.nc"]
    # run: its own figure and animation, the keys turned off for the tracking inside it
    capsys.readouterr()
    assert main(["run", "vortex", "--out", str(tmp_path / "r"), "--quiet", "--no-animation",
                 "--set", "time.end=10.0", "--set", "physics.level=tracer",
                 "--set", "output.figure=true", "--set", "output.animation=true"]) == 0
    out = capsys.readouterr().out
    assert out.count("figure:") == 1 and "animation" not in out
    assert sorted(p.name for p in (tmp_path / "r").iterdir()
                  if p.suffix != ".nc") == ["trajectories.png"]


def test_a_solved_case_flow_goes_to_the_run_folder(tmp_path):
    """``driftlog run CASE --out DIR`` (and ``cases run``): the flow the solver computes for a
    shipped case is written in DIR with the trajectories, not in ./driftlog-runs/CASE."""
    from driftlog.api import cases_dir
    from driftlog.cli.common import case_overrides

    beach = cases_dir() / "beach" / "scenario.toml"
    over = case_overrides(beach, "beach", run_dir=tmp_path / "out")
    assert Path(over["flow"]["path"]).parent == (tmp_path / "out").resolve()
    default = case_overrides(beach, "beach")
    assert Path(default["flow"]["path"]).parent == (Path("driftlog-runs") / "beach").resolve()


def test_cases_list(capsys):
    assert main(["cases", "list"]) == 0
    assert "vortex" in capsys.readouterr().out
    assert main(["run", "no_such_case"]) == 2


def test_info_and_vtk_know_other_models_files_in_a_fresh_process(tmp_path):
    """`driftlog info` / `vtk --flow` on a HEC-RAS or MIKE file, each in a new interpreter.

    The readers tell ``driftlog.files.sniff`` about their files when ``driftlog.adapters`` is
    imported; ``info`` sniffed before anything imported it, so a HEC-RAS file was "a NetCDF
    file of an unknown layout" (and a dfsu "binary") in a fresh process, while in a test
    process that had imported the adapters it passed.
    """
    import pytest

    data = Path(__file__).resolve().parents[2] / "shared" / "data" / "hecras"
    muncie = data / "Muncie.g05.hdf"
    if muncie.is_file():
        out = run("info", str(muncie))
        assert out.returncode == 0, out.stderr
        assert "HEC-RAS file" in out.stdout and "2D Interior Area" in out.stdout
    pytest.importorskip("mikeio")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    try:
        from test_adapters_mike import write_dfsu
    finally:
        sys.path.pop(0)
    dfsu = write_dfsu(tmp_path / "model.dfsu")
    out = run("info", str(dfsu))
    assert out.returncode == 0, out.stderr
    assert "MIKE dfsu" in out.stdout
    out = run("vtk", str(dfsu), "--flow", "--out", str(tmp_path / "vtk"))
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "vtk" / "flow.pvd").is_file() or list((tmp_path / "vtk").glob("*.pvd"))


DATA = Path(__file__).resolve().parent / "data"


def test_every_command_knows_other_models_files_in_a_fresh_process(tmp_path):
    """plot, a scenario argument, --resume: each new interpreter sniffs with the readers' probes.

    Only ``info`` and ``vtk`` imported ``driftlog.adapters`` before sniffing (whose readers
    register what ``driftlog.files.sniff`` knows): ``driftlog plot`` took a HEC-RAS file for
    "a NetCDF file of an unknown layout", a dfsu given as a scenario was "a binary file" and a
    truncated sww, whose size check the adapters register too, "another model's output".  The
    first sniff of a process now loads them (``files.register_loader``).
    """
    muncie = Path(__file__).resolve().parents[2] / "shared" / "data" / "hecras" / "Muncie.g05.hdf"
    if muncie.is_file():
        out = run("plot", str(muncie), "-o", str(tmp_path / "p.png"))
        assert out.returncode == 2 and "Traceback" not in out.stderr
        assert f"{muncie}: another model's output" in out.stderr and "(hecras)" in out.stderr
        assert "driftlog vtk --flow" in out.stderr  # what to do with a flow
    dfsu = DATA / "mike" / "HD2D.dfsu"
    out = run("track", str(dfsu), "-o", str(tmp_path / "t.nc"))
    assert out.returncode == 2
    assert f"{dfsu}: another model's output" in out.stderr and "(dfsu), not a scenario file" \
        in out.stderr
    sww = tmp_path / "cut.sww"
    data = (DATA / "anuga" / "channel_centroids.sww").read_bytes()
    sww.write_bytes(data[:len(data) // 2])
    out = run("animate", str(sww), "-o", str(tmp_path / "a.gif"))
    assert out.returncode == 2
    assert f"{sww}: a NetCDF/HDF5 file that cannot be read (truncated or corrupt)" in out.stderr
    assert "header declares" in out.stderr


def test_wrong_flow_sources_say_what_they_are(tmp_path):
    """Flow sources of the wrong kind, each in a fresh process: one line saying what to do.

    ``[flow] source = 'file'`` on a D-Flow FM map file (was: "variable 'water_depth' is
    missing"); ``import`` of a UGRID mesh without a flow (was: "unknown layout"); ``solve
    --resume`` where the .partial is another model's output (was: "not computed from this
    [solver] section (solver_hash differs)"); a GeoTIFF series with a raster cut short.
    """
    ugrid = DATA / "ugrid" / "dflowfm_map.nc"
    s = tmp_path / "s.toml"
    s.write_text(f'[flow]\nsource = "file"\npath = "{ugrid}"\n[time]\nend = 600.0\n'
                 "[[logs]]\nx = [1.0]\ny = [1.0]\n")
    out = run("scenario", "check", str(s))
    assert out.returncode == 2 and out.stderr.count("driftlog: error:") == 1
    assert f"{ugrid}: another model's output (ugrid), not a driftlog flow file: [flow] source " \
           "= 'file' reads driftlog's own flow files; set source = 'auto' (or 'ugrid') to read " \
           f"it, or convert it first: driftlog import {ugrid} -o flow.nc" in out.stderr
    import netCDF4

    from driftlog.flowfile import write_mesh
    from driftlog.mesh import Mesh

    mesh = tmp_path / "mesh.nc"
    with netCDF4.Dataset(mesh, "w") as ds:
        write_mesh(ds, Mesh.regular_grid(4, 3, 1.0))
    out = run("import", str(mesh), "-o", str(tmp_path / "f.nc"))
    assert out.returncode == 2 and "unknown layout" not in out.stderr
    assert f"{mesh}: a UGRID mesh file without a flow (no water_depth); a hydro source must " \
           "be" in out.stderr
    solver = tmp_path / "solver.toml"
    solver.write_text('[flow]\nsource = "solver"\n[solver]\nmesh = "channel"\n'
                      "channel = [0.0, 0.0, 20.0, 4.0]\ncell_size = 2.0\nend = 2.0\n"
                      '[solver.initial]\ntype = "level"\nvalue = 1.0\n[time]\nend = 2.0\n'
                      "[[logs]]\nx = [5.0]\ny = [2.0]\n")
    partial = tmp_path / "flow.nc.partial"
    partial.write_bytes((DATA / "anuga" / "channel_centroids.sww").read_bytes())
    out = run("solve", str(solver), "-o", str(tmp_path / "flow.nc"), "--resume", "--quiet")
    assert out.returncode == 2 and "solver_hash" not in out.stderr
    assert f"{partial}: another model's output" in out.stderr
    assert "the file driftlog solve --resume continues must be a flow file of driftlog solve" \
        in out.stderr
    # a GeoTIFF series with a raster cut short (was: rasterio's traceback, after GDAL's
    # "Warning 1: TIFFReadDirectory" on stderr)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    try:
        from test_adapters_raster import write_geotiff
    finally:
        sys.path.pop(0)
    tif = write_geotiff(tmp_path / "tif") / "depth_60.tif"
    data = tif.read_bytes()
    tif.write_bytes(data[:len(data) // 2])
    out = run("import", str(tif.parent), "-o", str(tmp_path / "g.nc"))
    assert out.returncode == 2 and "Warning" not in out.stderr, out.stderr
    assert f"{tif}: a raster whose values cannot be read: truncated or damaged" in out.stderr


def test_export_a_grid_flow_and_name_the_output(tmp_path):
    """``driftlog export`` of a CF grid to Selafin (was: a traceback from xarray-selafin: the
    grid's cell values written as node values); an error of the writer names the output the
    user gave, not its temporary name (was: ``.x.tmp1234.slf``)."""
    grid = DATA / "cf_grid" / "lisflood.nc"
    slf = tmp_path / "grid.slf"
    out = run("export", str(grid), "-o", str(slf))
    assert out.returncode == 0, out.stderr
    from driftlog.adapters import open_flow_source

    a, b = open_flow_source("auto", grid), open_flow_source("auto", slf)
    x0, y0, x1, y1 = a.mesh.bounds
    x = np.linspace(x0, x1, 9)[2:-2]
    y = np.linspace(y0, y1, 9)[2:-2]
    t = float(a.times[1])
    np.testing.assert_allclose(b.sample(x, y, t).h, a.sample(x, y, t).h, atol=1e-6)
    from driftlog.flowfile import FlowFileWriter
    from driftlog.mesh import Mesh

    m = Mesh.regular_grid(4, 2, 1.0)
    flow = tmp_path / "half.nc"
    with FlowFileWriter(flow, m, np.zeros(m.n_faces)) as w:
        for t in (0.0, 0.5):
            w.write(t, np.ones(m.n_faces), u=np.zeros(m.n_faces), v=np.zeros(m.n_faces))
    out = run("export", str(flow), "-o", str(tmp_path / "half.slf"))
    assert out.returncode == 2 and ".tmp" not in out.stderr
    assert f"{tmp_path / 'half.slf'}: the flow's times are not whole seconds (e.g. 0.5 s)" \
        in out.stderr
