import pytest

from driftlog.errors import ScenarioError
from driftlog.scenario import describe_keys, load_scenario

BASE = """
title = "t"
[flow]
source = "analytic"
kind = "solid_body_rotation"
[time]
start = 0.0
end = 10.0
[[logs]]
seeding = "list"
x = [1.0, 2.0]
y = [0.0, 0.0]
"""


def test_defaults_filled():
    s = load_scenario(BASE)
    assert s["physics"]["level"] == "full"
    assert s["physics"]["drag_area"] == "paper"
    assert s["integrator"]["method"] == "rk4"
    assert s["logs"][0]["density"] == 720.0
    assert s["obstacles"] == []
    assert "scenario" in s.attrs()


def _bad(text, key, match):
    with pytest.raises(ScenarioError) as exc:
        load_scenario(BASE + text)
    assert exc.value.key == key, str(exc.value)
    assert match in str(exc.value)
    return exc.value


@pytest.mark.parametrize("text,key,match", [
    ("[physics]\nlevle = 'full'\n", "physics.levle", "did you mean 'level'"),
    ("[physics]\nlevel = 'everything'\n", "physics.level",
     "one of 'tracer', 'drag', 'full', 'auto'"),
    ("[physics]\nrotation = 3\n", "physics.rotation", "must be a string"),
    ("[integrator]\nmax_step = 'big'\n", "integrator.max_step", "must be a number"),
    ("[contact]\nenabled = 'yes'\n", "contact.enabled", "true or false"),
    ("[contact]\nrestitution = 1.5\n", "contact.restitution", "<= 1.0"),
    ("[[logs]]\nx = [0.0]\ny = [0.0]\nradius = -0.1\n", "logs[1].radius", "> 0.0"),
    ("[[logs]]\nx = [0.0]\ny = [0.0]\ndensity = 0.0\n", "logs[1].density", "> 0.0"),
    ("[[logs]]\nx = [0.0, 1.0]\ny = [0.0]\n", "logs[1].x", "same length"),
    ("[[logs]]\nseeding = 'line'\nstart = [0.0, 0.0]\ncount = 3\n", "logs[1].end", "required"),
    ("[[logs]]\nseeding = 'polygon'\npolygon = [[0.0, 0.0], [1.0, 0.0]]\n", "logs[1].polygon",
     "at least 3"),
    ("[[obstacles]]\ntype = 'mesh'\npath = 'nowhere.stl'\n", "obstacles[0].path", "file not found"),
    ("[output]\nflush_interval = 1.5\n", "output.flush_interval", "an integer"),
    ("[phsyics]\nx = 1\n", "phsyics", "did you mean 'physics'"),
    ("[integrator]\nmin_step = 1.0\nmax_step = 0.1\n", "integrator.max_step",
     "must be >= min_step"),
    ("[integrator]\nclock = 'per_log'\nmethod = 'exponential'\n", "integrator.clock",
     "euler or rk4 (here 'exponential')"),
    ("[integrator]\nclock = 'per_log'\nland_on_snapshots = false\n",
     "integrator.land_on_snapshots", "needs clock = 'global'"),
    ("[physics]\nwaterlogging = 'exponential'\nwaterlogging_time = 10.0\n"
     "saturated_density = 500.0\n", "physics.saturated_density",
     "below logs[0].density = 720 kg/m3"),
    ("[[obstacles]]\nname = 'A'\ncenter = [5.0, 0.0]\nradius = 0.5\n"
     "[[obstacles]]\nname = 'A'\ncenter = [8.0, 0.0]\nradius = 0.5\n", "obstacles[1].name",
     "is also obstacles[0]'s name"),
    ("[[obstacles]]\nname = 'bridge'\ncenter = [5.0, 0.0]\nradius = 0.5\n"
     "[[obstacles]]\nname = 'pier'\ngroup = 'bridge'\ncenter = [8.0, 0.0]\nradius = 0.5\n",
     "obstacles[0].name", "is also a group's name"),
])
def test_bad_values_name_key_value_and_rule(text, key, match):
    err = _bad(text, key, match)
    assert repr(err.value) in str(err) or err.value is None


def test_time_span_reversed():
    with pytest.raises(ScenarioError, match=r"\[time.end\] = 5.0: must be after time.start"):
        load_scenario(BASE.replace("start = 0.0", "start = 8.0").replace("end = 10.0", "end = 5.0"))


def test_missing_flow_file(tmp_path):
    text = BASE.replace('source = "analytic"', 'source = "file"\npath = "missing.nc"')
    with pytest.raises(ScenarioError, match=r"\[flow.path\].*file not found"):
        load_scenario(text)


def test_file_and_relative_paths(tmp_path):
    (tmp_path / "flow.nc").write_bytes(b"")
    f = tmp_path / "s.toml"
    f.write_text(BASE.replace('source = "analytic"', 'source = "file"\npath = "flow.nc"'))
    s = load_scenario(f)
    assert s["flow"]["path"] == str(tmp_path / "flow.nc")
    assert s.path == f.resolve()


def test_not_toml(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text("[flow\nsource=")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(f)
    with pytest.raises(ScenarioError, match="file not found"):
        load_scenario(tmp_path / "absent.toml")


def test_overrides():
    s = load_scenario(BASE, overrides={"physics": {"level": "tracer"}})
    assert s["physics"]["level"] == "tracer"


def test_describe_keys_lists_everything():
    text = describe_keys()
    for key in ("[physics]", "drag_area", "[[logs]]", "restitution", "kg/m3"):
        assert key in text


def test_resolved_scenario_round_trips():
    import json

    s = load_scenario(BASE)
    again = load_scenario(json.loads(s.to_json()))
    assert again.data == s.data


def test_debris_run_past_the_flows_end_is_refused(tmp_path, capsys):
    # a run past the flow's end ran until the flow ended and stopped there with an error, after
    # all the work before it; the flow itself may be solved shorter (a quick look at its start)
    from driftlog.api import track
    from driftlog.cli import main
    from driftlog.solving import solve_scenario

    solved = BASE.replace('source = "analytic"\nkind = "solid_body_rotation"',
                          f'source = "solver"\npath = "{tmp_path / "f.nc"}"') + (
        '[solver]\nmesh = "channel"\nchannel = [0.0, 0.0, 10.0, 2.0]\ncell_size = 0.5\n'
        'end = 8.0\noutput_interval = 2.0\n')
    f = tmp_path / "s.toml"
    f.write_text(solved)
    assert main(["scenario", "check", str(f)]) == 2
    assert "[time.end] = 10.0: is after the solver's end (8 s" in capsys.readouterr().err
    solve_scenario(load_scenario(f))  # solving alone is fine
    on_file = solved.split("[solver]")[0].replace('source = "solver"', 'source = "file"')
    with pytest.raises(ScenarioError, match=r"\[time.end\] = 10.0: is after the flow's last "
                       r"time \(8 s\)"):
        track(on_file, output=tmp_path / "t.nc")
    assert not (tmp_path / "t.nc.partial").exists()
    assert track(on_file.replace("end = 10.0", "end = 8.0"),
                 output=tmp_path / "t.nc").dataset()["time"].values.max() == 8.0
    held = on_file.replace('source = "file"', 'source = "file"\nsteady_at = 8.0')
    assert track(held, output=tmp_path / "h.nc").dataset()["time"].values.max() == 10.0
