"""Passive particles: driftlog (tracer) vs OpenDrift and Parcels on one CF grid (issue 4).

One regular-grid CF NetCDF flow that all three read: a Gaussian eddy drifting east at a
constant speed c,

    U(x, t) = (c, 0) + Omega(R) (-(y - y_c), x - x_c(t)),  Omega(R) = Omega_0 exp(-R^2 / 2 sigma^2),

R the distance to the centre x_c(t) = x_c0 + c t.  In the frame moving with the eddy the flow
is steady and circular, so every particle circles the moving centre at its own rate
Omega(R): the trajectories are exact, and the field is neither linear in space (each tool's
spatial interpolation shows) nor steady on the grid (time interpolation shows).

Each tool advects the same particles with classical RK4 at the same fixed step over the same
time, passive (no diffusion, no wind, no windage):

- driftlog: ``adapters.cfgrid.open_cf_grid`` on the file, tracer physics, ``rk4``;
- OpenDrift: ``OceanDrift`` with ``reader_netCDF_CF_generic`` on the file,
  ``drift:advection_scheme = runge-kutta4``; its positions are longitude/latitude, so the
  grid carries a transverse Mercator projection (scale 1 on the central meridian: ground and
  grid metres differ by less than 1e-7 on this 2 km domain);
- Parcels v4: a ``FieldSet`` from the same file opened with xarray (A grid, bilinear),
  ``AdvectionRK4``, float64 particle positions (its default particle is float32).

Measured: particle-steps per second (run only; the set-up, i.e. opening the file and building
the field set, is timed apart) for several particle counts, and the trajectories' agreement:
each tool's error against the exact positions, the distance between each pair of tools, and
each tool's time-step error (against its own run at a 16 times smaller step) with the
observed order.  "driftlog (exact field)" is driftlog's integrator on the formula itself (no
grid): its error is the integrator's alone.

    python benchmarks/peers_tracking.py [--quick]

writes benchmarks/results/peers_tracking.{json,md} and peers_tracking.png.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
import warnings
from datetime import datetime, timedelta

import numba as nb
import numpy as np
from _common import RESULTS, machine

from driftlog.analytic import DriftingEddy
from driftlog.columns import X, Y
from driftlog.flow import FlowField
from driftlog.logs import Logs
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

# the scene (SI units): 2 km x 1.2 km grid of 10 m cells, snapshots every 10 s over 900 s
NX, NY, DX = 200, 120, 10.0
SNAPSHOT = 10.0
DURATION = 900.0
CENTER = (600.0, 600.0)
DRIFT = 0.5  # c (m/s)
SIGMA = 150.0
OMEGA0 = 0.01  # rad/s: peak speed Omega_0 sigma e^-1/2 = 0.91 m/s at R = sigma
SEED_RADIUS = 300.0
DEPTH = 2.0
ORIGIN = datetime(2000, 1, 1)
PROJ4 = "+proj=tmerc +lat_0=44 +lon_0=7 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
TOOLS = ("driftlog", "OpenDrift", "Parcels")


# --------------------------------------------------------------------- flow and exact answer
def eddy(snapshot=0.0):
    """The scene's eddy (``driftlog.analytic.DriftingEddy``); ``snapshot`` > 0: linear in time
    between the formula at multiples of it, as every tool does between the grid's snapshots."""
    return DriftingEddy(CENTER, DRIFT, SIGMA, OMEGA0, DEPTH, snapshot)


velocity = eddy().velocity  # (u, v) at points x, y and time t
exact = eddy().exact  # positions at time t of particles released at (x0, y0) at time 0


def seed(n, rng):
    """n particles spread uniformly over the disk of radius SEED_RADIUS about the centre."""
    r = SEED_RADIUS * np.sqrt(rng.random(n))
    a = 2 * np.pi * rng.random(n)
    return CENTER[0] + r * np.cos(a), CENTER[1] + r * np.sin(a)


def write_grid(path, dx=DX):
    """The flow as a CF-1.8 regular grid NetCDF (cell centres, time in seconds since ORIGIN);
    ``dx``: the cell size (the domain stays NX DX by NY DX)."""
    import netCDF4

    nx, ny = int(round(NX * DX / dx)), int(round(NY * DX / dx))
    x = dx * (np.arange(nx) + 0.5)
    y = dx * (np.arange(ny) + 0.5)
    times = np.arange(0.0, DURATION + SNAPSHOT / 2, SNAPSHOT)
    X, Y = np.meshgrid(x, y)
    with netCDF4.Dataset(path, "w") as ds:
        ds.Conventions = "CF-1.8"
        ds.title = "Gaussian eddy drifting east (driftlog benchmarks/peers_tracking.py)"
        ds.createDimension("time", None)
        ds.createDimension("y", ny)
        ds.createDimension("x", nx)
        crs = ds.createVariable("crs", "i4")
        crs.grid_mapping_name = "transverse_mercator"
        crs.latitude_of_projection_origin = 44.0
        crs.longitude_of_central_meridian = 7.0
        crs.scale_factor_at_central_meridian = 1.0
        crs.false_easting = 0.0
        crs.false_northing = 0.0
        crs.semi_major_axis = 6378137.0
        crs.inverse_flattening = 298.257223563
        crs.proj4 = PROJ4
        for name, vals, std in (("x", x, "projection_x_coordinate"),
                                ("y", y, "projection_y_coordinate")):
            v = ds.createVariable(name, "f8", (name,))
            v[:] = vals
            v.standard_name, v.units, v.axis = std, "m", name.upper()
        tv = ds.createVariable("time", "f8", ("time",))
        tv.standard_name, tv.axis = "time", "T"
        tv.units = f"seconds since {ORIGIN:%Y-%m-%d %H:%M:%S}"
        tv.calendar = "standard"
        bed = ds.createVariable("bed", "f8", ("y", "x"))
        bed.standard_name, bed.units, bed.grid_mapping = "altitude", "m", "crs"
        bed[:] = 0.0
        fields = {}
        for name, std in (("depth", "water_depth"), ("u", "sea_water_x_velocity"),
                          ("v", "sea_water_y_velocity")):
            var = ds.createVariable(name, "f8", ("time", "y", "x"))
            var.standard_name, var.grid_mapping = std, "crs"
            var.units = "m" if name == "depth" else "m s-1"
            fields[name] = var
        for k, t in enumerate(times):
            tv[k] = t
            u, v = velocity(X, Y, t)
            fields["u"][k] = u
            fields["v"][k] = v
            fields["depth"][k] = np.full_like(u, DEPTH)
    return path


# --------------------------------------------------------------------- the three tools
def run_driftlog(path_or_flow, x, y, dt, duration, threads=1, curve=False):
    """Tracer-mode RK4 at a fixed step; returns (x, y, set-up s, run s).

    ``curve``: the particles listed along a Hilbert curve through their positions, as
    ``driftlog.api.track`` lists a scenario's logs (no contacts); the positions are returned
    in the order given.
    """
    from driftlog.adapters.cfgrid import open_cf_grid

    from driftlog.logs import spatial_order

    nb.set_num_threads(threads)
    t0 = time.perf_counter()
    flow = path_or_flow if isinstance(path_or_flow, FlowField) else open_cf_grid(path_or_flow)
    order = spatial_order(x, y) if curve else np.arange(np.size(x))
    logs = Logs(np.asarray(x)[order], np.asarray(y)[order], 0.0, 0.5, 0.05, 500.0)
    tr = Tracker(flow, logs, PhysicsOptions(level="tracer", rotation=False), "rk4",
                 StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9, drag_fraction=0.0),
                 t_start=0.0, t_end=duration, output_interval=duration, hydro_step=duration)
    setup = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    tr.run()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    nb.set_num_threads(nb.config.NUMBA_NUM_THREADS)
    if not np.all(logs.status == 1):
        raise RuntimeError(f"driftlog: {np.sum(logs.status != 1)} particles stopped floating")
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    return logs.state[back, X], logs.state[back, Y], setup, (wall, cpu)


def _projection():
    import pyproj

    return pyproj.Proj(PROJ4)


def run_opendrift(path, x, y, dt, duration):
    """OceanDrift, passive (no diffusion, wind or Stokes drift), runge-kutta4."""
    from opendrift.models.oceandrift import OceanDrift
    from opendrift.readers import reader_netCDF_CF_generic

    proj = _projection()
    lon, lat = proj(x, y, inverse=True)
    t0 = time.perf_counter()
    o = OceanDrift(loglevel=50)
    o.add_reader(reader_netCDF_CF_generic.Reader(str(path)))
    for key, value in (("drift:advection_scheme", "runge-kutta4"),
                       ("environment:fallback:horizontal_diffusivity", 0.0),
                       ("drift:vertical_mixing", False),
                       ("drift:vertical_advection", False),
                       ("drift:stokes_drift", False),
                       ("drift:wind_uncertainty", 0.0),
                       ("drift:current_uncertainty", 0.0),
                       ("general:use_auto_landmask", False),
                       ("environment:fallback:land_binary_mask", 0),
                       ("environment:fallback:x_wind", 0.0),
                       ("environment:fallback:y_wind", 0.0),
                       ("general:coastline_action", "none")):
        o.set_config(key, value)
    o.seed_elements(lon=lon, lat=lat, z=0.0, time=ORIGIN, wind_drift_factor=0.0)
    setup = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    o.run(duration=timedelta(seconds=duration), time_step=timedelta(seconds=dt),
          time_step_output=timedelta(seconds=duration), export_variables=["lon", "lat"])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    lon_end = np.asarray(o.result.lon.isel(time=-1))
    lat_end = np.asarray(o.result.lat.isel(time=-1))
    if not np.all(np.isfinite(lon_end)):
        raise RuntimeError(f"OpenDrift: {np.sum(~np.isfinite(lon_end))} particles deactivated")
    xe, ye = proj(lon_end, lat_end)
    return np.asarray(xe), np.asarray(ye), setup, (wall, cpu)


def parcels_fieldset(path):
    """A Parcels v4 FieldSet on the NetCDF grid (A grid: velocities on the grid points)."""
    import parcels
    import parcels._sgrid as sgrid
    import xarray as xr

    src = xr.open_dataset(path)
    ds = xr.Dataset(
        {"U": (("time", "depth", "y", "x"), src["u"].values[:, None]),
         "V": (("time", "depth", "y", "x"), src["v"].values[:, None])},
        coords={"time": ("time", src["time"].values, {"axis": "T"}),
                "depth": ("depth", [0.0], {"axis": "Z"}),
                "lon": ("x", src["x"].values, {"axis": "X"}),
                "lat": ("y", src["y"].values, {"axis": "Y"})})
    src.close()
    ds["grid"] = xr.DataArray(0, attrs=sgrid.SGrid2DMetadata(
        cf_role="grid_topology", topology_dimension=2, node_dimensions=("x", "y"),
        node_coordinates=("lon", "lat"),
        face_dimensions=(sgrid.FaceNodePadding("x_center", "x", sgrid.Padding.LOW),
                         sgrid.FaceNodePadding("y_center", "y", sgrid.Padding.LOW)),
        vertical_dimensions=(sgrid.FaceNodePadding("depth_center", "depth",
                                                   sgrid.Padding.LOW),)).to_attrs())
    return parcels.FieldSet.from_sgrid_conventions(ds, mesh="flat")


def run_parcels(path, x, y, dt, duration):
    """AdvectionRK4 with float64 particle positions (flat mesh: x, y in metres)."""
    import parcels
    from parcels._core.particle import get_default_particle

    t0 = time.perf_counter()
    fs = parcels_fieldset(path)
    pset = parcels.ParticleSet(fs, pclass=get_default_particle(np.float64), x=x, y=y)
    setup = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    pset.execute(parcels.kernels.AdvectionRK4, dt=np.timedelta64(int(round(dt * 1e6)), "us"),
                 runtime=np.timedelta64(int(round(duration * 1e6)), "us"),
                 verbose_progress=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    xe, ye = np.asarray(pset.x, float), np.asarray(pset.y, float)
    if xe.size != x.size or not np.all(np.isfinite(xe)):
        raise RuntimeError(f"Parcels: {x.size - xe.size} particles removed or non-finite")
    return xe, ye, setup, (wall, cpu)


RUNNERS = {"driftlog": run_driftlog, "OpenDrift": run_opendrift, "Parcels": run_parcels}


def versions():
    from importlib.metadata import version

    out = {}
    for name, mod in (("OpenDrift", "opendrift"), ("Parcels", "parcels")):
        try:
            __import__(mod)
            out[name] = version(mod)
        except Exception as exc:  # noqa: BLE001 - reported, not hidden
            out[name] = f"unavailable: {type(exc).__name__}: {exc}"
    return out


# --------------------------------------------------------------------- measurements
def speed(path, sizes, dt, duration, available, rng):
    rows = []
    for n in sizes:
        x, y = seed(n, rng)
        steps = int(round(duration / dt))
        cases = [("driftlog", 1), ("driftlog", 2)] + [(t, 1) for t in TOOLS[1:] if t in available]
        for tool, threads in cases:
            if tool == "driftlog":
                xe, ye, setup, (wall, cpu) = run_driftlog(path, x, y, dt, duration, threads)
            else:
                xe, ye, setup, (wall, cpu) = RUNNERS[tool](path, x, y, dt, duration)
            xx, yy = exact(x, y, duration)
            rows.append(dict(tool=tool, threads=threads, particles=n, steps=steps,
                             setup_s=setup, run_s=wall, cpu_s=cpu,
                             particle_steps_per_s=n * steps / wall,
                             particle_steps_per_cpu_s=n * steps / cpu,
                             max_error_m=float(np.max(np.hypot(xe - xx, ye - yy)))))
            print(rows[-1], flush=True)
    return rows


FORMULA = "driftlog, formula (exact field)"
FORMULA_T = "driftlog, formula linear in time"


def accuracy(path, n, dts, duration, available, rng):
    """Positions at the end for each tool and step, errors, pairwise distances, orders.

    Two driftlog runs on the formula instead of the grid split the error: exact field (the
    integrator's error alone), and the formula interpolated linearly in time between the
    snapshot times (the integrator's and time interpolation's, no spatial interpolation).
    """
    x, y = seed(n, rng)
    xx, yy = exact(x, y, duration)
    tools = [FORMULA, FORMULA_T, "driftlog"] + [t for t in TOOLS[1:] if t in available]
    pos = {}
    for tool in tools:
        for dt in dts:
            if tool == FORMULA:
                xe, ye, _, _ = run_driftlog(eddy(), x, y, dt, duration)
            elif tool == FORMULA_T:
                xe, ye, _, _ = run_driftlog(eddy(SNAPSHOT), x, y, dt, duration)
            else:
                xe, ye, _, _ = RUNNERS[tool](path, x, y, dt, duration)
            pos[tool, dt] = (xe, ye)
            print(tool, dt, "max error", np.max(np.hypot(xe - xx, ye - yy)), flush=True)
    rows = []
    for tool in tools:
        prev = None
        for dt, half in zip(dts, list(dts[1:]) + [None], strict=True):
            xe, ye = pos[tool, dt]
            err = np.hypot(xe - xx, ye - yy)
            # change when the step is halved: the time-step error, without the exact answer
            change = (float(np.max(np.hypot(xe - pos[tool, half][0], ye - pos[tool, half][1])))
                      if half else float("nan"))
            order = float(np.log2(prev / change)) if prev and half else float("nan")
            rows.append(dict(tool=tool, dt=dt, max_error_m=float(err.max()),
                             mean_error_m=float(err.mean()), halving_change_m=change,
                             order=order))
            prev = change
            print(rows[-1], flush=True)
    pairs = []
    grid_tools = [t for t in tools if t not in (FORMULA, FORMULA_T)]
    for dt in (SNAPSHOT, dts[-1]):
        for i, a in enumerate(grid_tools):
            for b in grid_tools[i + 1:]:
                d = np.hypot(pos[a, dt][0] - pos[b, dt][0], pos[a, dt][1] - pos[b, dt][1])
                pairs.append(dict(pair=f"{a} - {b}", dt=dt, max_distance_m=float(d.max()),
                                  mean_distance_m=float(d.mean())))
                print(pairs[-1], flush=True)
    return rows, pairs, pos, (x, y)


COLORS = {"driftlog": "C0", "OpenDrift": "C3", "Parcels": "C2", FORMULA: "0.4",
          FORMULA_T: "C1"}


def figure(speed_rows, acc_rows, pos, start, dt_show, duration):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(17, 5))
    ax = axes[0]
    for tool, mk in (("driftlog", "o-"), ("OpenDrift", "s-"), ("Parcels", "d-")):
        r = [q for q in speed_rows if q["tool"] == tool and q["threads"] == 1]
        if r:
            ax.loglog([q["particles"] for q in r], [q["particle_steps_per_cpu_s"] for q in r],
                      mk, color=COLORS[tool], label=f"{tool} (CPU time)")
            ax.loglog([q["particles"] for q in r], [q["particle_steps_per_s"] for q in r],
                      mk[0] + ":", color=COLORS[tool], alpha=0.6, label=f"{tool} (wall time)")
    ax.set_xlabel("particles")
    ax.set_ylabel("particle-steps per second")
    ax.set_title("Speed, one thread (RK4, run only)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[1]
    tools = list(dict.fromkeys(q["tool"] for q in acc_rows))
    for tool in tools:
        r = [q for q in acc_rows if q["tool"] == tool]
        dts = [q["dt"] for q in r]
        ax.loglog(dts, [q["max_error_m"] for q in r], "o-", color=COLORS[tool], label=tool)
        ax.loglog(dts, [q["halving_change_m"] for q in r], "x:", color=COLORS[tool])
    ax.set_xticks(dts, [f"{d:g}" for d in dts])
    ax.minorticks_off()
    ax.set_xlabel("step dt (s)")
    ax.set_ylabel(f"max position error after {duration:g} s (m)")
    ax.set_title("Accuracy: against the exact trajectories (solid),\n"
                 "time-step error alone (dotted: change when dt is halved)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    ax = axes[2]
    x0, y0 = start
    xx, yy = exact(x0, y0, duration)
    radius = np.hypot(x0 - CENTER[0], y0 - CENTER[1])
    for tool in tools:
        if tool == FORMULA or (tool, dt_show) not in pos:
            continue
        xe, ye = pos[tool, dt_show]
        ax.semilogy(radius, np.hypot(xe - xx, ye - yy), ".", ms=3, color=COLORS[tool],
                    label=tool)
    ax.set_xlabel("release distance R from the eddy centre (m)")
    ax.set_ylabel(f"position error after {duration:g} s (m)")
    ax.set_title(f"Error of each particle (dt = {dt_show:g} s)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, markerscale=3)
    fig.tight_layout()
    fig.savefig(RESULTS / "peers_tracking.png", dpi=110)
    plt.close(fig)


def markdown(info, speed_rows, acc_rows, pairs):
    def g(v):
        return f"{v:.3g}" if isinstance(v, float) else str(v)

    lines = ["### Passive particles: driftlog (tracer) vs OpenDrift and Parcels", "",
             f"Measured on {info['machine']}; {info['versions']}.", "",
             info["scene"], "", "Speed (run only; set-up apart; CPU time of the process, all "
             "threads, which on a shared machine is steadier than wall time):", "",
             "| tool | threads | particles | steps | set-up (s) | run (s) | run CPU (s) "
             "| particle-steps/s | per CPU second | max error (m) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in speed_rows:
        lines.append(f"| {r['tool']} | {r['threads']} | {r['particles']} | {r['steps']} | "
                     f"{g(r['setup_s'])} | {g(r['run_s'])} | {g(r['cpu_s'])} | "
                     f"{g(r['particle_steps_per_s'])} | {g(r['particle_steps_per_cpu_s'])} | "
                     f"{g(r['max_error_m'])} |")
    lines += ["", f"Accuracy ({info['accuracy_particles']} particles, after "
              f"{info['duration']:g} s): error against the exact positions; the change of the "
              "positions when dt is halved (the time-step error alone) and the observed order "
              "log2(change(dt) / change(dt/2)):", "",
              "| tool | dt (s) | max error (m) | mean error (m) | change when halved (m) | order |",
              "|---|---:|---:|---:|---:|---:|"]
    for r in acc_rows:
        lines.append(f"| {r['tool']} | {g(r['dt'])} | {g(r['max_error_m'])} | "
                     f"{g(r['mean_error_m'])} | {g(r['halving_change_m'])} | {g(r['order'])} |")
    lines += ["", "Distance between tools (same particles, same step):", "",
              "| pair | dt (s) | max distance (m) | mean distance (m) |", "|---|---:|---:|---:|"]
    for r in pairs:
        lines.append(f"| {r['pair']} | {g(r['dt'])} | {g(r['max_distance_m'])} | "
                     f"{g(r['mean_distance_m'])} |")
    text = "\n".join(lines) + "\n"
    (RESULTS / "peers_tracking.md").write_text(text)
    print(text)


def main(quick=False):
    import tempfile
    from pathlib import Path

    logging.getLogger("opendrift").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore", module="opendrift")
    RESULTS.mkdir(parents=True, exist_ok=True)
    info = {"machine": machine()}
    vers = versions()
    available = [t for t in TOOLS[1:] if not vers[t].startswith("unavailable")]
    info["versions"] = ", ".join(f"{k} {v}" for k, v in vers.items())
    info["scene"] = (f"Flow: Gaussian eddy (sigma {SIGMA:g} m, Omega_0 {OMEGA0:g} rad/s, peak "
                     f"{OMEGA0 * SIGMA * np.exp(-0.5):.2f} m/s) drifting east at {DRIFT:g} m/s "
                     f"on a {NX} x {NY} grid of {DX:g} m cells, snapshots every {SNAPSHOT:g} s; "
                     f"particles released over a disk of radius {SEED_RADIUS:g} m about the "
                     "centre.  Re-create: `python benchmarks/peers_tracking.py`.")
    rng = np.random.default_rng(7)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_grid(Path(tmp) / "drifting_eddy.nc")
        # warm-up: numba compilation, imports, caches
        xs, ys = seed(64, rng)
        run_driftlog(path, xs, ys, SNAPSHOT, 4 * SNAPSHOT)
        run_driftlog(eddy(SNAPSHOT), xs, ys, SNAPSHOT, 4 * SNAPSHOT)
        for tool in available:
            RUNNERS[tool](path, xs, ys, SNAPSHOT, 4 * SNAPSHOT)
        sizes = [1_000, 10_000] if quick else [1_000, 10_000, 100_000]
        speed_duration = 300.0
        speed_rows = speed(path, sizes, SNAPSHOT, speed_duration, available, rng)
        # driftlog's sub-steps land on the snapshot times: no step longer than SNAPSHOT
        dts = [10.0, 5.0, 2.5] if quick else [10.0, 5.0, 2.5, 1.25]
        n_acc = 200 if quick else 1000
        acc_rows, pairs, pos, start = accuracy(path, n_acc, dts, DURATION, available, rng)
    info.update(duration=DURATION, accuracy_particles=n_acc, speed_duration=speed_duration,
                step=SNAPSHOT, unavailable={t: vers[t] for t in TOOLS[1:] if t not in available})
    (RESULTS / "peers_tracking.json").write_text(json.dumps(
        {"info": info, "speed": speed_rows, "accuracy": acc_rows, "pairs": pairs}, indent=1))
    figure(speed_rows, acc_rows, pos, start, 10.0, DURATION)
    markdown(info, speed_rows, acc_rows, pairs)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="fewer particles and steps")
    main(p.parse_args().quick)
