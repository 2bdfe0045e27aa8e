"""[solver] engine = "shallowWaterFoam": one scenario, two engines, one comparison.

The river_piers scene of ``cases/river_piers/compare_engines.toml`` at a reduced size (50 m
triangles, 2400 s of flow, 400 s of logs) on driftlog's solver and on OpenFOAM's
shallowWaterFoam; then what is refused, and what a failed OpenFOAM run leaves behind.
"""

import os
import stat
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from driftlog.adapters.openfoam_case import OpenFOAMError, foam_available

from driftlog.errors import ScenarioError
from driftlog.scenario import load_scenario

CASE = Path(__file__).resolve().parents[1] / "cases" / "river_piers" / "compare_engines.toml"
needs_foam = pytest.mark.skipif(not foam_available(),
                                reason="OpenFOAM not installed (Debian: apt-get install openfoam)")
Q = 760.0  # m3/s, the inflow of compare_engines.toml


def reduced(tmp, **solver):
    ov = {"flow": {"path": str(tmp / "flow.nc")},
          "solver": dict({"cell_size": 50.0, "end": 2400.0, "output_interval": 1200.0},
                         **solver),
          "time": {"end": 400.0}}
    return load_scenario(CASE, overrides=ov)


def discharge(field, x0, t):
    """Discharge through the cross-section x = x0 (m3/s), the piers left out."""
    y = np.linspace(0.25, 169.75, 680)
    s = field.sample(np.full(y.size, x0), y, np.full(y.size, t))
    return np.trapezoid(np.where(np.isfinite(s.u), s.h * s.u, 0.0), y)


@pytest.fixture(scope="module")
def engines(tmp_path_factory):
    if not foam_available():
        pytest.skip("OpenFOAM not installed (Debian: apt-get install openfoam)")
    from driftlog.compare import engine_flows

    tmp = tmp_path_factory.mktemp("engines")
    scen = reduced(tmp)
    return tmp, scen, dict(engine_flows(scen, "driftlog,shallowWaterFoam"))


@needs_foam
@pytest.mark.openfoam
def test_same_scene_on_both_engines(engines):
    """Same mesh, bed and initial state; both carry the imposed discharge at steady state."""
    tmp, scen, flows = engines
    d, f = flows["driftlog"], flows["shallowWaterFoam"]
    assert d.mesh.n_faces == f.mesh.n_faces
    np.testing.assert_array_equal(d.mesh.face_x, f.mesh.face_x)
    np.testing.assert_array_equal(d.bed, f.bed)
    np.testing.assert_allclose(f.times, [2400.0])  # frozen: steady_at = 2400 s
    # the OpenFOAM run started from the scenario's initial state, exactly
    with netCDF4.Dataset(tmp / "flow_shallowWaterFoam.nc") as ds:
        np.testing.assert_allclose(ds["water_depth"][0], 5.0, rtol=1e-12)
        np.testing.assert_allclose(ds["velocity_x"][0], 0.9, rtol=1e-12)
        assert ds["time"][0] == 0.0
    # steady: each engine carries the inflow through every cross-section, between the bridges too
    for name, field in flows.items():
        for x0 in (2.0, 300.0, 450.0, 750.0, 1050.0, 1200.0, 1400.0):
            q = discharge(field, x0, 2400.0)
            assert abs(q - Q) < 0.03 * Q, (name, x0, q)
    # same mean state: shallowWaterFoam, frictionless, differs by the friction head only
    sd, sf = d.snapshot(0), f.snapshot(0)
    a = d.mesh.face_area
    assert abs(np.sum(sf["h"] * a) / np.sum(sd["h"] * a) - 1.0) < 0.01


@needs_foam
@pytest.mark.openfoam
def test_provenance_and_reuse(engines):
    tmp, scen, flows = engines
    from driftlog.solver.config import solver_hash
    from driftlog.solving import flow_from_scenario

    path = tmp / "flow_shallowWaterFoam.nc"
    with netCDF4.Dataset(path) as ds:
        a = {k: ds.getncattr(k) for k in ds.ncattrs()}
    assert a["engine"] == "shallowWaterFoam"
    assert a["openfoam_version"].startswith("OpenFOAM v1912")
    log = Path(a["openfoam_log"])
    assert log.is_file() and log.parent == tmp / "flow_shallowWaterFoam"
    assert "End" in a["openfoam_log_tail"]
    assert "manning = 0.01 not applied" in a["openfoam_friction"]
    assert a["solver_hash"] == solver_hash(reduced(tmp, engine="shallowWaterFoam")["solver"])
    assert float(a["engine_cpu_time"]) > 0
    # the driftlog engine's flow is a separate file, with its own hash
    with netCDF4.Dataset(tmp / "flow.nc") as ds:
        assert ds.getncattr("solver_hash") != a["solver_hash"]
        assert ds.getncattr("source") == "driftlog solver"
    # unchanged section: reused, not rerun
    before = path.stat().st_mtime_ns, log.stat().st_mtime_ns
    flow_from_scenario(reduced(tmp, engine="shallowWaterFoam"))
    assert (path.stat().st_mtime_ns, log.stat().st_mtime_ns) == before


@needs_foam
@pytest.mark.openfoam
def test_decomposed_run_matches_serial(tmp_path):
    """Two processes (decomposePar, mpirun) give the serial run's flow; 40 s of it."""
    from driftlog.solving import flow_from_scenario

    short = dict(engine="shallowWaterFoam", end=40.0, output_interval=20.0)
    serial = flow_from_scenario(reduced(tmp_path / "serial", **short))
    par = flow_from_scenario(reduced(tmp_path / "par", n_procs=2, **short))
    assert (tmp_path / "par" / "flow_shallowWaterFoam" / "processor1").is_dir()
    with netCDF4.Dataset(tmp_path / "par" / "flow_shallowWaterFoam.nc") as ds:
        assert int(ds.getncattr("openfoam_n_procs")) == 2
    np.testing.assert_allclose(par.times, serial.times)
    s, p = serial.snapshot(serial.times.size - 1), par.snapshot(par.times.size - 1)
    assert np.abs(s["u"] - 0.9).max() > 0.05  # the flow has moved away from the start
    np.testing.assert_allclose(p["h"], s["h"], atol=2e-3)
    np.testing.assert_allclose(p["u"], s["u"], atol=2e-2)


@needs_foam
@pytest.mark.openfoam
def test_compare_engines_reports_per_log(engines):
    from driftlog.compare import compare_runs

    tmp, scen, flows = engines
    gates = {"bridge_A": (600.0, 0.0, 600.0, 170.0), "x450": (450.0, 0.0, 450.0, 170.0)}
    rep = compare_runs(scen, list(flows.items()), tmp / "cmp", lines=gates)
    c = rep["comparisons"]["shallowWaterFoam"]
    assert len(c["logs"]) == 8
    for r in c["logs"]:
        xa, ya = r["end_reference"]
        xb, yb = r["end_other"]
        assert r["end_distance"] == pytest.approx(np.hypot(xb - xa, yb - ya))
        assert r["status_reference"] == "floating" and r["status_other"] == "floating"
        # every log crosses x = 450 m in both runs, within a minute of each other
        ta, tb = r["arrival"]["x450"]
        assert ta is not None and tb is not None and abs(ta - tb) < 60.0
    assert c["arrival_at_lines"]["x450"]["driftlog"]["crossed"] == 8
    assert c["end_distance_max"] == pytest.approx(max(r["end_distance"] for r in c["logs"]))
    md = (tmp / "cmp" / "compare.md").read_text()
    assert "## Per log: driftlog vs shallowWaterFoam" in md and "arrival bridge_A (s)" in md
    assert (tmp / "cmp" / "compare.png").stat().st_size > 10_000


# --------------------------------------------------------------------- refused, failed
def test_boundaries_and_states_without_an_openfoam_equivalent(tmp_path):
    with pytest.raises(ScenarioError, match=r"solver\.boundaries\.outflow\.type.*froude.*"
                       r"engine 'shallowWaterFoam': boundary 'outflow'"):
        reduced(tmp_path, engine="shallowWaterFoam",
                boundaries={"outflow": {"type": "froude", "value": 0.2}})
    with pytest.raises(ScenarioError, match=r"solver\.boundaries\.outflow\.type.*rating"):
        reduced(tmp_path, engine="shallowWaterFoam",
                boundaries={"outflow": {"type": "rating", "table": [[4, 0], [6, 900]]}})
    with pytest.raises(ScenarioError, match=r"solver\.manning.*no bed friction.*"
                       "openfoam_friction = 'omit'"):
        reduced(tmp_path, engine="shallowWaterFoam", openfoam_friction="refuse")
    with pytest.raises(ScenarioError, match=r"solver\.initial\.type.*water on every face"):
        reduced(tmp_path, engine="shallowWaterFoam", initial={"type": "dry"})
    # the driftlog engine takes them all
    reduced(tmp_path, boundaries={"outflow": {"type": "froude", "value": 0.2}})


def test_openfoam_not_installed(tmp_path, monkeypatch):
    import driftlog.adapters.openfoam_case as oc

    from driftlog.solving import flow_from_scenario

    (tmp_path / "flow_shallowWaterFoam.nc").write_bytes(b"kept")
    monkeypatch.setattr(oc, "foam_env", lambda: None)
    with pytest.raises(OpenFOAMError) as err:
        flow_from_scenario(reduced(tmp_path, engine="shallowWaterFoam"))
    msg = str(err.value)
    assert "engine 'shallowWaterFoam': OpenFOAM is not installed" in msg
    assert f"case folder: {tmp_path / 'flow_shallowWaterFoam'}" in msg and "log: none" in msg
    assert (tmp_path / "flow_shallowWaterFoam.nc").read_bytes() == b"kept"


def _fake_solver(tmp_path, script):
    import driftlog.adapters.openfoam_case as oc

    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    exe = bin_dir / "shallowWaterFoam"
    exe.write_text("#!/bin/sh\n" + script)
    exe.chmod(exe.stat().st_mode | stat.S_IEXEC)
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ.get('PATH', '')}")
    return oc, env


def test_failing_solver_keeps_the_stored_flow(tmp_path, monkeypatch):
    from driftlog.solving import flow_from_scenario

    oc, env = _fake_solver(tmp_path, 'echo "--> FOAM FATAL ERROR: cannot find patch"\nexit 1\n')
    monkeypatch.setattr(oc, "foam_env", lambda: env)
    stored = tmp_path / "flow_shallowWaterFoam.nc"
    stored.write_bytes(b"an earlier flow")
    with pytest.raises(OpenFOAMError) as err:
        flow_from_scenario(reduced(tmp_path, engine="shallowWaterFoam"))
    msg = str(err.value)
    case = tmp_path / "flow_shallowWaterFoam"
    assert msg.startswith("engine 'shallowWaterFoam': shallowWaterFoam failed")
    assert "FOAM FATAL ERROR: cannot find patch" in msg
    assert f"case folder: {case}" in msg and f"log: {case / 'log.shallowWaterFoam'}" in msg
    assert f"the stored flow {stored} is untouched" in msg
    assert stored.read_bytes() == b"an earlier flow"
    assert (case / "system" / "controlDict").is_file()  # the case is there to inspect


@needs_foam
@pytest.mark.openfoam
def test_diverging_run_is_reported(tmp_path):
    """A 1 cm sheet of water fed 760 m3/s: shallowWaterFoam blows up (or dries a face)."""
    from driftlog.solving import flow_from_scenario

    scen = reduced(tmp_path, engine="shallowWaterFoam", end=60.0, output_interval=30.0,
                   initial={"type": "level", "value": 0.01, "velocity": [0.0, 0.0]},
                   boundaries={"inflow": {"type": "discharge", "value": Q},
                               "outflow": {"type": "level", "value": 0.01}})
    with pytest.raises(OpenFOAMError) as err:
        flow_from_scenario(scen)
    msg = str(err.value)
    assert msg.startswith("engine 'shallowWaterFoam': ")
    assert ("failed" in msg) or ("diverged or dried" in msg)
    assert "log: " + str(tmp_path / "flow_shallowWaterFoam" / "log.shallowWaterFoam") in msg
    assert not (tmp_path / "flow_shallowWaterFoam.nc").exists()
    assert not (tmp_path / "flow_shallowWaterFoam.nc.part").exists()


def test_compare_engines_command_line_errors(tmp_path, capsys):
    from driftlog.cli import main

    assert main(["compare", str(CASE), "--engines", "driftlog"]) == 2
    assert "give two engines or more, each once, among driftlog, shallowWaterFoam" in \
        capsys.readouterr().err
    assert main(["compare", str(CASE), "--engines", "driftlog,telemac"]) == 2
    assert "--engines driftlog,telemac" in capsys.readouterr().err
    assert main(["compare", str(CASE), "--engines", "driftlog,shallowWaterFoam",
                 "--gate", "bridge=600,0,600"]) == 2
    assert "--gate 'bridge=600,0,600': must be NAME=X0,Y0,X1,Y1" in capsys.readouterr().err
    analytic = tmp_path / "a.toml"
    analytic.write_text('[flow]\nsource = "analytic"\nkind = "uniform"\nvelocity = [1.0, 0.0]\n'
                        '[time]\nend = 1.0\n[[logs]]\nx = [0.0]\ny = [0.0]\n')
    assert main(["compare", str(analytic), "--engines", "driftlog,shallowWaterFoam"]) == 2
    assert "[flow] source = 'solver'" in capsys.readouterr().err


@needs_foam
@pytest.mark.openfoam
def test_case_folder_given_relative(tmp_path, monkeypatch):
    """The tools run inside the case folder: a relative path must not be doubled."""
    from driftlog.adapters.openfoam_case import run_shallow_water

    from driftlog.mesh import Mesh

    monkeypatch.chdir(tmp_path)
    m = Mesh.regular_grid(8, 2, 0.5)
    m.tag_boundary("inflow", lambda x, y: x < 1e-9)
    m.tag_boundary("outflow", lambda x, y: x > 4.0 - 1e-9)
    f = run_shallow_water("rel", m, depth=1.0, end_time=1.0, write_interval=1.0,
                          boundaries={"inflow": {"type": "inflow", "discharge": 0.5},
                                      "outflow": {"type": "outflow", "level": 1.0}})
    assert (tmp_path / "rel" / "log.shallowWaterFoam").is_file()
    np.testing.assert_allclose(f.times, [0.0, 1.0])


@needs_foam
@pytest.mark.openfoam
def test_time_series_boundaries_on_openfoam(tmp_path):
    """A discharge series (flowRateInletVelocity) and a level series (uniformFixedValue):
    the OpenFOAM run follows both."""
    from driftlog.solving import flow_from_scenario

    scen = load_scenario({
        "flow": {"source": "solver", "path": str(tmp_path / "flow.nc")},
        "solver": {"engine": "shallowWaterFoam", "channel": [0.0, 0.0, 10.0, 2.0],
                   "cell_size": 0.5, "end": 20.0, "output_interval": 2.0,
                   "initial": {"type": "level", "value": 0.5},
                   "boundaries": {"inflow": {"type": "discharge",
                                             "series": [[0.0, 0.0], [10.0, 0.4], [20.0, 0.4]]},
                                  "outflow": {"type": "level",
                                              "series": [[0.0, 0.5], [20.0, 0.45]]}}},
        "time": {"end": 1.0}, "logs": [{"x": [1.0], "y": [1.0]}]})
    f = flow_from_scenario(scen)
    m = f.mesh
    inner = m.edge_faces[m.edges_with_tag("inflow"), 0]
    outer = m.edge_faces[m.edges_with_tag("outflow"), 0]
    for i, t in enumerate(f.times):
        s = f.snapshot(i)
        q = np.mean(s["h"][inner] * s["u"][inner]) * 2.0  # unit discharge x width
        q_in = np.interp(t, [0.0, 10.0, 20.0], [0.0, 0.4, 0.4])
        assert abs(q - q_in) < 0.025  # the first cells lag the ramp by a fraction of a second
        # the cells next to the outflow follow the imposed level to a few mm
        assert abs(np.mean(s["eta"][outer]) - np.interp(t, [0.0, 20.0], [0.5, 0.45])) < 6e-3
    assert abs(np.mean(f.snapshot(f.times.size - 1)["h"][inner] *
                       f.snapshot(f.times.size - 1)["u"][inner]) * 2.0 - 0.4) < 0.004
