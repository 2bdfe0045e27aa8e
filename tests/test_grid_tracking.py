"""Tracers on a CF regular grid against exact trajectories (the peers benchmark's flow).

A Gaussian eddy drifting east at speed c: every particle circles the moving centre at the
rate Omega(R) of its distance R, so positions are known exactly.  Read through the cf_grid
adapter, the field is interpolated bilinearly in space (``driftlog.gridflow``) and linearly
in time; both errors are second order, so refining the grid by 2 must divide the error by
about 4, and on the formula itself RK4 must converge at order 4.

On the 20 m grid the bilinear grid field's maximum error is 1.41 m (Parcels, bilinear too,
gives the same positions to 1e-11 m: benchmarks/grid_peers.py); the triangulated mesh path
the reader used before gave 3.47 m.
"""

import numpy as np
import pytest
from driftlog.adapters.cfgrid import open_cf_grid

from driftlog.flow import WET, FlowField, H, U, V
from driftlog.logs import Logs
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

CENTER, DRIFT, SIGMA, OMEGA0 = (400.0, 600.0), 0.5, 150.0, 0.01
SIZE, DURATION, SNAPSHOT = 1200.0, 300.0, 5.0


def velocity(x, y, t):
    dx, dy = x - (CENTER[0] + DRIFT * t), y - CENTER[1]
    om = OMEGA0 * np.exp(-(dx * dx + dy * dy) / (2 * SIGMA ** 2))
    return DRIFT - om * dy, om * dx


def exact(x0, y0, t):
    dx, dy = x0 - CENTER[0], y0 - CENTER[1]
    r = np.hypot(dx, dy)
    a = np.arctan2(dy, dx) + OMEGA0 * np.exp(-r * r / (2 * SIGMA ** 2)) * t
    return CENTER[0] + DRIFT * t + r * np.cos(a), CENTER[1] + r * np.sin(a)


def write_grid(path, dx):
    import netCDF4

    n = int(round(SIZE / dx))
    c = dx * (np.arange(n) + 0.5)
    X, Y = np.meshgrid(c, c)
    times = np.arange(0.0, DURATION + SNAPSHOT / 2, SNAPSHOT)
    with netCDF4.Dataset(path, "w") as ds:
        ds.createDimension("time", times.size)
        for name in ("y", "x"):
            ds.createDimension(name, n)
            v = ds.createVariable(name, "f8", (name,))
            v[:] = c
            v.standard_name, v.units = f"projection_{name}_coordinate", "m"
        tv = ds.createVariable("time", "f8", ("time",))
        tv[:] = times
        tv.units = "seconds since 2000-01-01 00:00:00"
        bed = ds.createVariable("bed", "f8", ("y", "x"))
        bed.standard_name, bed[:] = "altitude", 0.0
        for name, std in (("depth", "water_depth"), ("u", "sea_water_x_velocity"),
                          ("v", "sea_water_y_velocity")):
            var = ds.createVariable(name, "f8", ("time", "y", "x"))
            var.standard_name, var.units = std, "m" if name == "depth" else "m s-1"
        for k, t in enumerate(times):
            u, v = velocity(X, Y, t)
            ds["u"][k], ds["v"][k], ds["depth"][k] = u, v, np.full_like(u, 2.0)
    return path


class Formula(FlowField):
    """The eddy from its formula (tracers need h, u, v only)."""

    time_span = (0.0, DURATION)

    def sample_into(self, x, y, t, face, out, flag):
        face[:] = -1
        out[:] = 0.0
        out[:, H] = 2.0
        out[:, U], out[:, V] = velocity(x, y, t)
        flag[:] = WET


def track(flow, x, y, dt):
    logs = Logs(x, y, 0.0, 0.5, 0.05, 500.0)
    Tracker(flow, logs, PhysicsOptions(level="tracer", rotation=False), "rk4",
            StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9, drag_fraction=0.0),
            t_end=DURATION, output_interval=DURATION, hydro_step=DURATION).run()
    assert np.all(logs.status == 1)
    ex, ey = exact(x, y, DURATION)
    return np.max(np.hypot(logs.state[:, 0] - ex, logs.state[:, 1] - ey))


@pytest.fixture(scope="module")
def seeds():
    rng = np.random.default_rng(5)
    r, a = 200.0 * np.sqrt(rng.random(60)), 2 * np.pi * rng.random(60)
    return CENTER[0] + r * np.cos(a), CENTER[1] + r * np.sin(a)


def test_exact_trajectories_solve_the_flow(seeds):
    """d/dt of the exact positions is the flow's velocity there (central difference)."""
    x, y = seeds
    t, h = 123.0, 1e-3
    x1, y1 = exact(x, y, t + h)
    x0, y0 = exact(x, y, t - h)
    u, v = velocity(*exact(x, y, t), t)
    np.testing.assert_allclose((x1 - x0) / (2 * h), u, atol=1e-7)
    np.testing.assert_allclose((y1 - y0) / (2 * h), v, atol=1e-7)


def test_rk4_order_four_on_the_formula(seeds):
    errors = [track(Formula(), *seeds, dt) for dt in (20.0, 10.0)]
    assert errors[1] < 1e-3
    assert 3.7 < np.log2(errors[0] / errors[1]) < 4.3


def test_grid_interpolation_second_order(seeds, tmp_path):
    """Halving the cell size divides the error (interpolation-dominated) by about 4."""
    errors = [track(open_cf_grid(write_grid(tmp_path / f"eddy_{dx:g}.nc", dx)), *seeds, 5.0)
              for dx in (20.0, 10.0)]
    order = np.log2(errors[0] / errors[1])
    assert errors[0] < 1.45, errors  # bilinear; 3.47 m when the grid was triangulated
    assert errors[1] < 0.37, errors
    assert 1.7 < order < 2.3, (errors, order)
