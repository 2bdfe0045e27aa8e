"""The scenes of cases/, each run at reduced size, checking the numbers their READMEs state."""

import numpy as np
import pytest

from driftlog.api import find_case, track
from driftlog.logs import FLOATING, LEFT, RESTING
from driftlog.trajectory import open_trajectories


def _run(name, tmp_path, **overrides):
    overrides.setdefault("flow", {})["path"] = str(tmp_path / f"{name}_flow.nc")
    res = track(find_case(name), output=tmp_path / "traj.nc", overrides=overrides)
    return res, open_trajectories(res.path)


def _per_log(ds, name):
    ti = ds["trajectory_index"].values
    v = ds[name].values
    return [v[ti == k] for k in range(ds.sizes["trajectory"])]


def test_beach_lift_off_at_two_radii_and_settling(tmp_path):
    # reduced: 4 m cells (750 quads) instead of 2 m
    res, ds = _run("beach", tmp_path, solver={"cell_size": 4.0})
    t, st, h, x = ds["time"].values, ds["status"].values, ds["water_depth"].values, ds["x"].values
    float_depth = 0.08  # 2 r for rho_b = rho (docs/model.md section 6, 15.F)
    assert st[0] == RESTING and h[0] < float_depth
    first = np.flatnonzero(st == FLOATING)[0]
    # lifted in the record interval where the water at the log rose through 2 r
    assert h[first - 1] < float_depth <= h[first] + 1e-9
    assert 30.0 <= t[first] <= 45.0
    # carried landward by the wave, then settling when the water falls back below 2 r
    last = np.flatnonzero(st == FLOATING)[-1]
    assert st[-1] == RESTING and np.all(st[last + 1:] == RESTING)
    assert np.all(h[last + 1:last + 5] < float_depth + 2e-3)
    assert 60.0 <= t[last] <= 95.0
    assert 10.0 <= x[-1] - x[0] <= 40.0


def test_flume_log_zigzags_between_the_obstacles(tmp_path):
    # reduced: 6 cm cells, 30 s of flow
    res, ds = _run("flume", tmp_path, solver={"cell_size": 0.06, "end": 30.0},
                   flow={"steady_at": 30.0})
    x, y, st = ds["x"].values, ds["y"].values, ds["status"].values
    # never inside an obstacle (0.13 m x 0.18 m on alternate banks)
    for x0, bank in ((0.5, 0), (1.3, 1), (2.1, 0), (2.9, 1), (3.7, 0), (4.5, 1)):
        inside = (x > x0) & (x < x0 + 0.13) & ((y < 0.18) if bank == 0 else (y > 0.42))
        assert not inside.any()
    # the path swings from one side to the other around the obstacles
    reach = (x > 0.5) & (x < 4.6)
    side = np.sign(y[reach] - 0.3)
    assert np.count_nonzero(np.diff(side[side != 0])) >= 4
    assert y[reach].max() - y[reach].min() > 0.2
    # and leaves the reach downstream
    assert st[-1] == LEFT and x.max() > 5.5


def test_river_piers_logs_deflect_off_piers_and_collide(tmp_path):
    # reduced: 30 m cells, 600 s of flow (from 0.9 m/s: near the steady state)
    res, ds = _run("river_piers", tmp_path, solver={"cell_size": 30.0, "end": 600.0},
                   flow={"steady_at": 600.0})
    other = ds["hit_other"].values
    piers = other[(other < 0) & (other >= -4)]
    assert piers.size >= 1  # logs meet the piers (obstacles 1 to 4)
    xs = _per_log(ds, "x")
    assert all(x[-1] - x[0] > 300.0 for x in xs)  # carried downstream through the bridges
    st = ds["status"].values
    assert np.all((st == FLOATING) | (st == LEFT))
    assert res.stats["substeps"] > 0


@pytest.mark.slow
def test_river_piers_full_size_has_log_log_collisions(tmp_path):
    res, ds = _run("river_piers", tmp_path)
    other = ds["hit_other"].values
    assert (other >= 0).sum() >= 1 and (other < 0).sum() >= 4
