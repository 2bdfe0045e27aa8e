"""Passive particles on an unstructured mesh: driftlog (tracer) vs OceanTracker and Parcels 4.

The drifting Gaussian eddy of ``peers_tracking.py`` (``driftlog.analytic.DriftingEddy``: exact
trajectories) sampled at the nodes of one triangle mesh (a Delaunay triangulation of a
jittered 10 m lattice over 2 km x 1.2 km: 24,321 nodes, 48,000 triangles), snapshots every
10 s.  Every tool interpolates the node values linearly on the triangles (P1, barycentric)
and linearly in time, and advects the same particles with classical RK4 at the same fixed
step, passive (no diffusion, no windage):

- OceanTracker (``oceantracker``, numba): the flow written as a SCHISM-like NetCDF
  (``SCHISM_hgrid_node_x/y``, 1-based ``SCHISM_hgrid_face_nodes``, depth-averaged velocity
  ``dahv`` on the nodes, ``elev``, ``depth``, ``wetdry_elem``) read by its ``SCHISMreader``;
  ``RK_order`` 4, dispersion, resuspension and bottom stress off, one processor.
- Parcels 4: a ``uxarray.UxDataset`` of the same node values (``location = "node"``, flat
  mesh), ``FieldSet.from_ugrid_conventions``, ``AdvectionRK4``, float64 positions.  Parcels
  4.0.2's unstructured interpolators take the snapshot at the time index and do not
  interpolate in time (``UxLinearNodeConstantZC`` reads ``grid_positions["T"]["index"]``
  only), so Parcels runs twice: with its own interpolator ("Parcels (its UGRID
  interpolator)") and with a linear-in-time version of it written here ("Parcels, linear in
  time": the same barycentric sampling at the two snapshots, blended by the time weight).
- driftlog: the same node values written as a TELEMAC Selafin file (double precision) and
  read by ``driftlog.adapters.selafin`` (node-located data, sampled P1 on their nodes),
  tracer physics, ``rk4``; the particles listed along a Hilbert curve through their release
  points, as ``driftlog.api.track`` lists a scenario's logs (``--order-ab``: as seeded and
  by face, without the curve); the positions compared in the order released.

Measured: particle-steps per CPU second of the run alone.  driftlog and Parcels: the CPU
time of ``Tracker.run`` / ``ParticleSet.execute`` after the flow is open.  OceanTracker has
no separate run call (``OceanTracker.run`` reads the file, builds its grid, compiles part of
its numba code again, releases, steps and writes its output file), so its run cost is the
difference between a run of the full duration and the cheaper of two runs of two steps (one
before, one after), divided by the difference in particle-steps.  Accuracy:
each tool's largest and mean position error against the exact trajectories after 900 s, for
several steps.

    python benchmarks/tracer_peers.py [--quick] [--tools driftlog ...] [--repeat 3]

writes benchmarks/results/tracer_peers{,_quick}.{json,md}; with ``--tools`` only those tools
run (driftlog always), into tracer_peers{,_quick}_<tools>.{json,md} (e.g. a rerun of driftlog
alone after a change, beside the peers' figures of the full table).  Each tool's speed is its
fastest of ``--repeat`` runs per size, the tools alternated.  driftlog alone, two versions
in one process: ``--gradients-ab``, ``--snapshots-ab``, ``--order-ab``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numba as nb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, machine  # noqa: E402
from peers_tracking import (  # noqa: E402
    CENTER,
    DEPTH,
    DRIFT,
    OMEGA0,
    SIGMA,
    exact,
    run_driftlog,
    seed,
    velocity,
)

# the mesh: a jittered lattice of SPACING over LX x LY, triangulated (Delaunay)
LX, LY, SPACING = 2000.0, 1200.0, 10.0
SNAPSHOT = 10.0
DURATION = 900.0
ORIGIN = "2000-01-01 00:00:00"
TOOLS = ("driftlog", "OceanTracker", "Parcels", "Parcels (its UGRID interpolator)")


# --------------------------------------------------------------------- mesh and flow
def triangle_mesh(seed_=3):
    """Nodes (x, y) and triangles (n, 3), 0-based: a Delaunay triangulation of the lattice
    with interior nodes moved at random by up to 0.3 SPACING in each direction."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed_)
    nx, ny = int(round(LX / SPACING)) + 1, int(round(LY / SPACING)) + 1
    X, Y = np.meshgrid(np.linspace(0.0, LX, nx), np.linspace(0.0, LY, ny))
    inner = (X > 0) & (X < LX) & (Y > 0) & (Y < LY)
    X = X + np.where(inner, (rng.random(X.shape) - 0.5) * 0.6 * SPACING, 0.0)
    Y = Y + np.where(inner, (rng.random(Y.shape) - 0.5) * 0.6 * SPACING, 0.0)
    x, y = X.ravel(), Y.ravel()
    tri = Delaunay(np.c_[x, y]).simplices.astype(np.int64)
    # counter-clockwise, as UGRID and SCHISM write them
    a = ((x[tri[:, 1]] - x[tri[:, 0]]) * (y[tri[:, 2]] - y[tri[:, 0]])
         - (x[tri[:, 2]] - x[tri[:, 0]]) * (y[tri[:, 1]] - y[tri[:, 0]]))
    tri[a < 0] = tri[a < 0][:, ::-1]
    return x, y, tri


def write_schism(path, x, y, tri, duration=DURATION):
    """The eddy at the nodes as a SCHISM-like 2D NetCDF (what OceanTracker's SCHISMreader
    reads): node coordinates, 1-based triangles, depth, elev, dahv, wetdry_elem."""
    import netCDF4

    times = np.arange(0.0, duration + SNAPSHOT / 2, SNAPSHOT)
    with netCDF4.Dataset(path, "w") as ds:
        ds.title = "Gaussian eddy drifting east at the nodes of a triangle mesh (driftlog " \
                   "benchmarks/tracer_peers.py)"
        ds.createDimension("time", None)
        ds.createDimension("nSCHISM_hgrid_node", x.size)
        ds.createDimension("nSCHISM_hgrid_face", tri.shape[0])
        ds.createDimension("nMaxSCHISM_hgrid_face_nodes", 3)
        ds.createDimension("two", 2)
        tv = ds.createVariable("time", "f8", ("time",))
        tv.units = f"seconds since {ORIGIN}"
        tv[:] = times
        for name, vals in (("SCHISM_hgrid_node_x", x), ("SCHISM_hgrid_node_y", y)):
            v = ds.createVariable(name, "f8", ("nSCHISM_hgrid_node",))
            v.units = "m"
            v[:] = vals
        v = ds.createVariable("SCHISM_hgrid_face_nodes", "i4",
                              ("nSCHISM_hgrid_face", "nMaxSCHISM_hgrid_face_nodes"))
        v.start_index = 1
        v[:] = tri + 1
        v = ds.createVariable("depth", "f8", ("nSCHISM_hgrid_node",))
        v.units = "m"
        v[:] = DEPTH
        elev = ds.createVariable("elev", "f8", ("time", "nSCHISM_hgrid_node"))
        dahv = ds.createVariable("dahv", "f8", ("time", "nSCHISM_hgrid_node", "two"))
        dahv.units = "m s-1"
        wet = ds.createVariable("wetdry_elem", "i4", ("time", "nSCHISM_hgrid_face"))
        for k, t in enumerate(times):
            u, vv = velocity(x, y, t)
            elev[k] = 0.0
            dahv[k, :, 0] = u
            dahv[k, :, 1] = vv
            wet[k] = 0
    return path


def read_schism(path):
    """(x, y, triangles 0-based, times s, u, v) from the SCHISM-like file."""
    import netCDF4

    with netCDF4.Dataset(path) as ds:
        uv = np.asarray(ds["dahv"][:])
        return (np.asarray(ds["SCHISM_hgrid_node_x"][:]), np.asarray(ds["SCHISM_hgrid_node_y"][:]),
                np.asarray(ds["SCHISM_hgrid_face_nodes"][:]) - 1, np.asarray(ds["time"][:]),
                uv[..., 0], uv[..., 1])


# --------------------------------------------------------------------- driftlog
def driftlog_flow(schism, tmp):
    """The SCHISM file's node values as a Selafin file, opened by driftlog's reader."""
    from driftlog.adapters import selafin

    from driftlog.flow import MeshFlowField
    from driftlog.mesh import Mesh

    x, y, tri, times, u, v = read_schism(schism)
    mesh = Mesh(x, y, tri, node_z=np.full(x.size, -DEPTH))
    h = np.full(u.shape, DEPTH)
    field = MeshFlowField.from_arrays(mesh, np.full(x.size, -DEPTH), times, h, h * u, h * v,
                                      location="node",
                                      attrs={"time_reference": f"seconds since {ORIGIN}"})
    path = Path(tmp) / "eddy.slf"
    selafin.write(field, path, precision="double")
    return selafin.open(path)


# --------------------------------------------------------------------- OceanTracker
def _oceantracker(schism, x, y, dt, duration, out, tag):
    """One OceanTracker run; returns (x, y, CPU s, wall s) at ``duration``."""
    import netCDF4
    from oceantracker.main import OceanTracker

    ot = OceanTracker()
    ot.settings(run_output_dir=str(Path(out) / tag), time_step=dt, use_dispersion=False,
                use_resuspension=False, use_bottom_stress=False, write_tracks=True,
                screen_output_time_interval=1e9, processors=1, max_run_duration=duration,
                NUMBA_cache_code=True)
    ot.add_class("reader", input_dir=str(Path(schism).parent), file_mask=Path(schism).name)
    ot.add_class("release_groups", name="disk", points=np.c_[x, y], pulse_size=1)
    ot.add_class("tracks_writer", update_interval=duration)
    c0, w0 = time.process_time(), time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        ot.run()
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    tracks = sorted((Path(out) / tag).glob("tracks_rectangular*.nc"))
    if not tracks:
        raise RuntimeError(f"OceanTracker wrote no tracks in {Path(out) / tag}")
    with netCDF4.Dataset(tracks[-1]) as ds:
        t = np.asarray(ds["time"][:])
        xe = np.asarray(ds["x"][-1])
        x0 = np.asarray(ds["x0"][:])
        status = np.asarray(ds["status"][-1])
    shutil.rmtree(Path(out) / tag, ignore_errors=True)
    if not np.isclose(t[-1] - t[0], duration):
        raise RuntimeError(f"OceanTracker stopped at {t[-1] - t[0]} s, not {duration} s")
    if np.any(status != 10):  # 10: moving
        raise RuntimeError(f"OceanTracker: {np.sum(status != 10)} particles stopped moving")
    # OceanTracker discards release points its initial cell search does not place (a warning
    # 'Discarded k points of n outside domain', though they are inside): NaN for those
    out_x, out_y = np.full(x.size, np.nan), np.full(x.size, np.nan)
    key = {(a, b): i for i, (a, b) in enumerate(zip(x, y, strict=True))}
    for (a, b), (c, d) in zip(x0, xe, strict=True):
        i = key[(a, b)]
        out_x[i], out_y[i] = c, d
    return out_x, out_y, cpu, wall


def run_oceantracker(schism, x, y, dt, duration, out):
    """Positions at ``duration`` and the run's (wall, CPU) seconds: full run minus two steps.

    A two-step run before and after the full one: OceanTracker compiles some of its numba
    functions in each new set-up (they cannot be cached), so the cheaper of the two is the
    fixed cost of a run (set-up, compilation, output) without the compilation the first may
    have done."""
    _, _, cpu1, wall1 = _oceantracker(schism, x, y, dt, 2 * dt, out, "short1")
    xe, ye, cpu, wall = _oceantracker(schism, x, y, dt, duration, out, "full")
    _, _, cpu2, wall2 = _oceantracker(schism, x, y, dt, 2 * dt, out, "short2")
    cpu2, wall2 = min(cpu1, cpu2), min(wall1, wall2)
    steps = duration / dt
    scale = steps / (steps - 2)
    return xe, ye, np.nan, ((wall - wall2) * scale, (cpu - cpu2) * scale)


# --------------------------------------------------------------------- Parcels
def _linear_in_time_interpolator():
    """Parcels' node interpolator (barycentric on the face) at the two snapshots around the
    particle's time, blended linearly by the time weight."""
    import xarray as xr
    from dask import is_dask_collection
    from parcels.interpolators._base import ScalarInterpolator

    class UxLinearNodeLinearTime(ScalarInterpolator):
        def interp(self, particle_positions, grid_positions, field):
            ti, zi, fi = np.broadcast_arrays(grid_positions["T"]["index"],
                                             grid_positions["Z"]["index"],
                                             grid_positions["FACE"]["index"])
            tau = np.broadcast_to(grid_positions["T"]["bcoord"], ti.shape)
            bcoords = xr.DataArray(grid_positions["FACE"]["bcoord"], dims=("points", "nodes"))
            node_ids = field.grid.uxgrid.face_node_connectivity[fi, :].values
            tdim, zdim, ndim = field.data.dims
            last = field.data.sizes[tdim] - 1

            def at(t_index):
                sel = {tdim: xr.DataArray(t_index, dims="points"),
                       zdim: xr.DataArray(zi, dims="points"),
                       ndim: xr.DataArray(node_ids, dims=("points", "nodes"))}
                value = (field.data.isel(sel, ignore_grid=True) * bcoords).sum("nodes").data
                return value.compute() if is_dask_collection(value) else value

            return (1.0 - tau) * at(ti) + tau * at(np.minimum(ti + 1, last))

    return UxLinearNodeLinearTime()


def parcels_fieldset(schism, linear_time=True):
    """A Parcels FieldSet on the SCHISM file's mesh and node values (flat mesh, metres)."""
    import parcels
    import uxarray as ux

    x, y, tri, times, u, v = read_schism(schism)
    grid = ux.Grid.from_topology(node_lon=x, node_lat=y, face_node_connectivity=tri)
    grid.node_lon.values[:] = x
    grid.node_lat.values[:] = y
    grid.attrs["Conventions"] = "UGRID-1.0"
    stamps = np.datetime64(ORIGIN.replace(" ", "T")) + np.round(times * 1e6).astype(
        "timedelta64[us]")
    attrs = dict(units="m/s", location="node", mesh="flat", Conventions="UGRID-1.0")

    def arr(name, vals, zname, z):
        return ux.UxDataArray(data=vals, name=name, uxgrid=grid, dims=["time", zname, "n_node"],
                              coords=dict(time=(["time"], stamps), **{zname: ([zname], z)}),
                              attrs=attrs)

    ds = ux.UxDataset({"U": arr("U", u[:, None, :], "zc", np.array([0.0])),
                       "V": arr("V", v[:, None, :], "zc", np.array([0.0])),
                       "W": arr("W", np.zeros((times.size, 2, x.size)), "zf",
                                np.array([0.0, 1.0]))}, uxgrid=grid)
    fs = parcels.FieldSet.from_ugrid_conventions(ds, mesh="flat")
    if linear_time:
        interp = _linear_in_time_interpolator()
        fs.U.interp_method = interp
        fs.V.interp_method = interp
    return fs


def run_parcels(fs, x, y, dt, duration):
    """AdvectionRK4 with float64 positions; returns (x, y, set-up s, (wall, CPU))."""
    import parcels
    from parcels._core.particle import get_default_particle

    t0 = time.perf_counter()
    pset = parcels.ParticleSet(fs, pclass=get_default_particle(np.float64), x=x, y=y,
                               z=np.zeros(x.size))
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


def versions():
    from importlib.metadata import version

    out = {}
    for name, mod in (("OceanTracker", "oceantracker"), ("Parcels", "parcels")):
        try:
            out[name] = version(mod)
        except Exception as exc:  # noqa: BLE001 - reported, not hidden
            out[name] = f"unavailable: {type(exc).__name__}: {exc}"
    return out


# --------------------------------------------------------------------- measurements
class Tools:
    """The opened flows of every tool (opened once: set-up is not the run)."""

    def __init__(self, schism, tmp, available):
        self.schism, self.tmp = schism, tmp
        self.available = available
        self.flow = driftlog_flow(schism, tmp)
        if "Parcels" in available:
            self.fs = {True: parcels_fieldset(schism, True), False: parcels_fieldset(schism, False)}

    def run(self, tool, x, y, dt, duration, timed=True, curve=True):
        """(x, y, (wall, CPU)) of ``tool`` at ``duration``; ``timed=False``: positions only
        (OceanTracker then runs once, not three times).  ``curve``: driftlog's particles
        listed along a Hilbert curve, as its scenario route lists them (False: as given)."""
        if tool == "driftlog":
            xe, ye, _, wc = run_driftlog(self.flow, x, y, dt, duration, threads=1, curve=curve)
        elif tool == "OceanTracker" and not timed:
            xe, ye, *wc = _oceantracker(self.schism, x, y, dt, duration, self.tmp, "positions")
        elif tool == "OceanTracker":
            xe, ye, _, wc = run_oceantracker(self.schism, x, y, dt, duration, self.tmp)
        else:
            fs = self.fs[tool == "Parcels"]
            xe, ye, _, wc = run_parcels(fs, x, y, dt, duration)
        return xe, ye, wc


def tools_of(available):
    return [t for t in TOOLS if t == "driftlog" or t.split(" ")[0] in available]


def speed(tools, sizes, dt, duration, rng, parcels_max, repeat=1):
    """Each tool's fastest of ``repeat`` runs (in CPU time) per size, the tools alternated.

    OceanTracker's run time is a difference of two runs (``run_oceantracker``), whose noise
    is largest where the run is shortest (1e4 particles): its fastest is the favourable
    estimate of its cost, so the ratio to driftlog is not flattered.
    """
    rows = []
    for n in sizes:
        x, y = seed(n, rng)
        xx, yy = exact(x, y, duration)
        steps = int(round(duration / dt))
        best = {}
        for _ in range(repeat):
            for tool in tools_of(tools.available):
                if tool.startswith("Parcels") and n > parcels_max:
                    continue
                xe, ye, (wall, cpu) = tools.run(tool, x, y, dt, duration)
                print(dict(tool=tool, particles=n, cpu_s=cpu), flush=True)
                if tool not in best or cpu < best[tool][3]:
                    best[tool] = (xe, ye, wall, cpu)
        for tool, (xe, ye, wall, cpu) in best.items():
            rows.append(dict(tool=tool, particles=n, steps=steps, runs=repeat, run_s=wall,
                             cpu_s=cpu, particle_steps_per_s=n * steps / wall,
                             particle_steps_per_cpu_s=n * steps / cpu,
                             max_error_m=float(np.nanmax(np.hypot(xe - xx, ye - yy))),
                             not_placed=int(np.sum(~np.isfinite(xe)))))
            print(rows[-1], flush=True)
    return rows


def accuracy(tools, n, dts, duration, rng):
    x, y = seed(n, rng)
    xx, yy = exact(x, y, duration)
    rows = []
    for tool in tools_of(tools.available):
        for dt in dts:
            xe, ye, _ = tools.run(tool, x, y, dt, duration, timed=False)
            err = np.hypot(xe - xx, ye - yy)
            ok = np.isfinite(err)
            rows.append(dict(tool=tool, dt=dt, max_error_m=float(err[ok].max()),
                             mean_error_m=float(err[ok].mean()), not_placed=int(np.sum(~ok))))
            print(rows[-1], flush=True)
    return rows


def markdown(info, speed_rows, acc_rows, name):
    def g(v):
        return f"{v:.3g}" if isinstance(v, float) else str(v)

    lines = ["### Passive particles on a triangle mesh: driftlog (tracer) vs OceanTracker and "
             "Parcels 4", "", f"Measured on {info['machine']}; {info['versions']}.", "",
             info["scene"], "",
             "Speed, one thread (run only, CPU time of the process; OceanTracker: a full run "
             "minus a two-step run, see the script's docstring; each tool's fastest of "
             f"{info.get('speed_runs', 1)} runs, the tools alternated):", "",
             "| tool | particles | steps | run (s) | run CPU (s) | particle-steps/s "
             "| per CPU second | max error (m) | not placed |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in speed_rows:
        lines.append(f"| {r['tool']} | {r['particles']} | {r['steps']} | {g(r['run_s'])} | "
                     f"{g(r['cpu_s'])} | {g(r['particle_steps_per_s'])} | "
                     f"{g(r['particle_steps_per_cpu_s'])} | {g(r['max_error_m'])} | "
                     f"{r['not_placed']} |")
    best = {}
    for r in speed_rows:
        if r["particles"] == max(q["particles"] for q in speed_rows if q["tool"] == r["tool"]):
            best[r["tool"]] = r
    dl = best.get("driftlog")
    peers = [r for t, r in best.items() if t != "driftlog"]
    if dl and peers:
        fastest = max(peers, key=lambda r: r["particle_steps_per_cpu_s"])
        lines += ["", f"driftlog / fastest peer ({fastest['tool']}, {fastest['particles']} "
                  f"particles) per CPU second: "
                  f"{dl['particle_steps_per_cpu_s'] / fastest['particle_steps_per_cpu_s']:.1f}x "
                  f"(driftlog at {dl['particles']} particles)."]
    lines += ["", "not placed: release points OceanTracker discards at release ('outside "
              "domain', though inside the mesh); its errors are over the others."]
    lines += ["", f"Accuracy ({info['accuracy_particles']} particles, after "
              f"{info['duration']:g} s): error against the exact positions:", "",
              "| tool | dt (s) | max error (m) | mean error (m) | not placed |",
              "|---|---:|---:|---:|---:|"]
    for r in acc_rows:
        lines.append(f"| {r['tool']} | {g(r['dt'])} | {g(r['max_error_m'])} | "
                     f"{g(r['mean_error_m'])} | {r['not_placed']} |")
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{name}.md").write_text(text)
    print(text)


def main(quick=False, only=None, repeat=1):
    nb.set_num_threads(1)
    RESULTS.mkdir(parents=True, exist_ok=True)
    vers = versions()
    available = [t for t in ("OceanTracker", "Parcels") if not vers[t].startswith("unavail")
                 and (only is None or t in only)]
    info = {"machine": machine(), "versions": ", ".join(f"{k} {v}" for k, v in vers.items())}
    rng = np.random.default_rng(11)
    with tempfile.TemporaryDirectory() as tmp:
        x, y, tri = triangle_mesh()
        schism = write_schism(Path(tmp) / "eddy_schism.nc", x, y, tri)
        info["scene"] = (
            f"Flow: Gaussian eddy (sigma {SIGMA:g} m, Omega_0 {OMEGA0:g} rad/s) drifting east at "
            f"{DRIFT:g} m/s, at the {x.size} nodes of a triangle mesh ({tri.shape[0]} triangles, "
            f"Delaunay of a jittered {SPACING:g} m lattice over {LX:g} m x {LY:g} m), snapshots "
            f"every {SNAPSHOT:g} s; particles released over a disk of radius 300 m about the "
            f"centre {CENTER} (driftlog's listed along a Hilbert curve, as its scenario "
            "route lists them).  Every tool: P1 (barycentric) on the node values, linear in "
            "time, classical RK4 at a fixed step.  Re-create: `python benchmarks/"
            f"tracer_peers.py{' --quick' if quick else ''}`.")
        tools = Tools(schism, tmp, available)
        # warm-up: numba compilation and caches of every tool (driftlog's kernels go parallel
        # above 2048 logs: a warm-up below that would leave their compilation in the runs)
        xs, ys = seed(4096, rng)
        for tool in tools_of(available):
            tools.run(tool, xs, ys, SNAPSHOT, 4 * SNAPSHOT, timed=False)
        sizes = [10_000, 100_000] if quick else [10_000, 100_000, 1_000_000]
        speed_duration = 300.0
        speed_rows = speed(tools, sizes, SNAPSHOT, speed_duration, rng,
                           parcels_max=10_000 if quick else 100_000, repeat=repeat)
        dts = [10.0, 5.0] if quick else [10.0, 5.0, 2.5]
        n_acc = 200 if quick else 1000
        acc_rows = accuracy(tools, n_acc, dts, DURATION, rng)
    info.update(duration=DURATION, accuracy_particles=n_acc, speed_duration=speed_duration,
                speed_runs=repeat,
                threads=1, numba_threads_env=os.environ.get("NUMBA_NUM_THREADS"))
    name = "tracer_peers_quick" if quick else "tracer_peers"
    if only is not None:
        name += "_" + "_".join(sorted({"driftlog", *only})).lower()
    (RESULTS / f"{name}.json").write_text(json.dumps(
        {"info": info, "speed": speed_rows, "accuracy": acc_rows}, indent=1))
    markdown(info, speed_rows, acc_rows, name)


def _driftlog_alone(tmp):
    """driftlog's ``Tools`` on the peers' eddy (files in ``tmp``), compiled and warm, for the
    one-process A/B runs below (1 numba thread)."""
    nb.set_num_threads(1)
    x, y, tri = triangle_mesh()
    tools = Tools(write_schism(Path(tmp) / "eddy_schism.nc", x, y, tri), tmp, [])
    xs, ys = seed(4096, np.random.default_rng(1))
    tools.run("driftlog", xs, ys, SNAPSHOT, 4 * SNAPSHOT, timed=False)
    return tools


def _arms_ab(arms, sizes, repeat, column):
    """driftlog alone on the peers' eddy with each of ``arms`` in turn, in one process.

    ``arms``: (name, patch) pairs, ``patch()`` a context manager that sets the arm's code up
    and takes it down.  Best CPU time of ``repeat`` runs each, the arms alternated; the flow
    opened afresh for each run (nothing cached).  Rows: particles, the arm (in ``column``),
    CPU s, particle-steps per CPU s, gain over the first arm, and whether every arm's
    positions equal the first's bit for bit.
    """
    from driftlog.adapters import selafin

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tools = _driftlog_alone(tmp)
        for n in sizes:
            px, py = seed(n, np.random.default_rng(11))
            best, ends = {}, {}
            for _ in range(repeat):
                for arm, patch in arms:
                    with patch():
                        tools.flow = selafin.open(Path(tmp) / "eddy.slf")
                        xe, ye, (_, cpu) = tools.run("driftlog", px, py, SNAPSHOT, 300.0)
                    best[arm] = min(best.get(arm, np.inf), cpu)
                    ends[arm] = (xe, ye)
            first = arms[0][0]
            same = all(np.array_equal(a, b) for arm in best
                       for a, b in zip(ends[arm], ends[first], strict=True))
            for arm, _ in arms:
                rows.append({"particles": n, "steps": 30, column: arm, "cpu_s": best[arm],
                             "per_cpu_s": n * 30 / best[arm], "gain": best[first] / best[arm],
                             "same_positions": same})
                print(rows[-1], flush=True)
    return rows


def _patched(*changes):
    """A context manager setting (owner, name, value) attributes, restored on exit."""
    @contextlib.contextmanager
    def patch():
        old = [(o, k, o.__dict__[k]) for o, k, _ in changes]
        try:
            for o, k, v in changes:
                setattr(o, k, v)
            yield
        finally:
            for o, k, v in old:
                setattr(o, k, v)
    return patch


def gradients_ab(sizes=(10_000, 100_000), repeat=6):
    """driftlog with and without the recovered node gradients (which tracer mode without
    rotation does not read), alternately in one process, best CPU time of ``repeat`` each.

    ``Tracker._tracer_values`` leaves them out of each snapshot it loads; the other arm
    asks for them, as before that change.  The positions must agree bit for bit.  Writes
    ``tracer_peers_gradients_ab.{csv,md}``.
    """
    from _common import write_table

    from driftlog.tracker import Tracker

    def full(self, t):  # the pair's node columns with their gradients
        vi, vj, a, _ = self._kernel.node_values.__self__.node_snapshot_pair(t, True)
        return vi, vj, 0, a

    rows = _arms_ab([("with gradients", _patched((Tracker, "_tracer_values", full))),
                     ("without", _patched())], sizes, repeat, "node_gradients")
    write_table("tracer_peers_gradients_ab", rows,
                ["particles", "steps", "node_gradients", "cpu_s", "per_cpu_s", "gain",
                 "same_positions"],
                "driftlog tracer RK4 with and without the recovered node gradients (1 thread, "
                f"best of {repeat}, alternately in one process)",
                "The scene of the peers' table (Selafin file, 30 steps of 10 s, a snapshot per "
                "step).  per_cpu_s: particle-steps per CPU second of Tracker.run.  Re-create: "
                "`python benchmarks/tracer_peers.py --gradients-ab`.")
    return rows


def snapshots_ab(sizes=(10_000, 100_000), repeat=6):
    """driftlog's snapshot handling in tracer mode as before 2026-12-06 and now, alternately
    in one process, best CPU time of ``repeat`` each.

    Before: each new snapshot pair copied side by side (``MeshFlowField.node_values``) and
    packed from the copy, the face means of node data computed at each load, the Selafin
    frame read through a DataArray.  Now: the pair packed from the two cached snapshots
    (``node_snapshot_pair``), the face means when first read, the frame read from the
    Variable.  The positions must agree bit for bit.  Writes
    ``tracer_peers_snapshots_ab.{csv,md}``.
    """
    from _common import write_table
    from driftlog.adapters.selafin import SelafinSnapshots

    from driftlog.flow import MeshFlowField
    from driftlog.tracker import Tracker

    def side_by_side(self, t):
        vals, a, _ = self._kernel.node_values(t, gradients=False)
        return vals, vals, vals.shape[1] // 2, a

    load = MeshFlowField._load_nodes

    def eager(self, i, gradients=True):
        entry = load(self, i, gradients)
        entry.faces()
        return entry

    def data_array(self, role, i):
        vid = self.roles[role]
        return np.asarray(self.ds[vid].isel(time=i).values, dtype=np.float64) * \
            self.factors[role]

    before = _patched((Tracker, "_tracer_values", side_by_side),
                      (MeshFlowField, "_load_nodes", eager),
                      (SelafinSnapshots, "_get", data_array))
    rows = _arms_ab([("before", before), ("now", _patched())], sizes, repeat, "snapshots")
    write_table("tracer_peers_snapshots_ab", rows,
                ["particles", "steps", "snapshots", "cpu_s", "per_cpu_s", "gain",
                 "same_positions"],
                "driftlog tracer RK4: a snapshot's handling before 2026-12-06 and now (1 "
                f"thread, best of {repeat}, alternately in one process)",
                "The scene of the peers' table (Selafin file, 30 steps of 10 s, a snapshot per "
                "step).  before: the pair copied side by side, face means at each load, the "
                "frame read through a DataArray; now: the pair packed from its two snapshots, "
                "face means when read, the frame from the Variable.  per_cpu_s: particle-steps "
                "per CPU second of Tracker.run.  Re-create: `python benchmarks/tracer_peers.py "
                "--snapshots-ab`.")
    return rows


def order_ab(sizes=(100_000, 1_000_000), repeat=2):
    """driftlog with the particles listed as seeded (at random), sorted by their face, and
    along a Hilbert curve (the order driftlog's scenario route gives them).

    The same particles, the same trajectories (tracer mode: each particle on its own); only
    the order of the rows changes, and with it how often consecutive particles read the same
    node rows.  Alternately in one process, best CPU time of ``repeat``.  Writes
    ``tracer_peers_order_ab.{csv,md}``.
    """
    from _common import write_table

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tools = _driftlog_alone(tmp)
        for n in sizes:
            px, py = seed(n, np.random.default_rng(11))
            o = np.argsort(tools.flow.sample(px, py, 0.0).face, kind="stable")
            best, ends = {}, {}
            for _ in range(repeat):
                for arm, (ax, ay), curve in (("as seeded", (px, py), False),
                                             ("by face", (px[o], py[o]), False),
                                             ("along a Hilbert curve", (px, py), True)):
                    xe, ye, (_, cpu) = tools.run("driftlog", ax, ay, SNAPSHOT, 300.0,
                                                 curve=curve)
                    best[arm] = min(best.get(arm, np.inf), cpu)
                    ends[arm] = (xe, ye)
            back = np.empty(n, np.int64)
            back[o] = np.arange(n)  # the sorted run's rows in the seeded order
            same = all(np.array_equal(a, b[back]) and np.array_equal(a, c) for a, b, c in
                       zip(ends["as seeded"], ends["by face"], ends["along a Hilbert curve"],
                           strict=True))
            for arm in ("as seeded", "by face", "along a Hilbert curve"):
                rows.append(dict(particles=n, steps=30, order=arm, cpu_s=best[arm],
                                 per_cpu_s=n * 30 / best[arm],
                                 gain=best["as seeded"] / best[arm], same_positions=same))
                print(rows[-1], flush=True)
    write_table("tracer_peers_order_ab", rows,
                ["particles", "steps", "order", "cpu_s", "per_cpu_s", "gain", "same_positions"],
                "driftlog tracer RK4 with the particles as seeded, by face and along a Hilbert "
                "curve (1 thread, "
                f"best of {repeat}, alternately in one process)",
                "The scene of the peers' table (Selafin file, 30 steps of 10 s).  per_cpu_s: "
                "particle-steps per CPU second of Tracker.run.  Re-create: `python "
                "benchmarks/tracer_peers.py --order-ab`.")
    return rows


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--gradients-ab", action="store_true",
                   help="only driftlog with and without the recovered node gradients")
    p.add_argument("--snapshots-ab", action="store_true",
                   help="only driftlog's snapshot handling before 2026-12-06 and now")
    p.add_argument("--order-ab", action="store_true",
                   help="only driftlog with the particles as seeded, by face, along a curve")
    p.add_argument("--quick", action="store_true", help="fewer particles and steps")
    p.add_argument("--tools", nargs="+", choices=["driftlog", "OceanTracker", "Parcels"],
                   help="run only these tools (driftlog always)")
    p.add_argument("--repeat", type=int, default=3,
                   help="runs of each tool per size, the fastest kept (default 3)")
    a = p.parse_args()
    if a.gradients_ab:
        gradients_ab()
    elif a.snapshots_ab:
        snapshots_ab()
    elif a.order_ab:
        order_ab()
    else:
        main(a.quick, a.tools, a.repeat)
