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
