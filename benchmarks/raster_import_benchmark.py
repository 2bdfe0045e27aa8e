"""Importing regular-grid flows: GeoTIFF series, LISFLOOD-FP ASCII results, CF grid NetCDF.

The same flow on an N x N grid of 1 m cells (N = 1000: 1e6 cells), written with each format's
own library: GeoTIFF (rioxarray / GDAL, float32, depth_<t>.tif, u_<t>.tif, v_<t>.tif and
dem.tif), LISFLOOD-FP (rioxarray / GDAL AAIGrid: res-NNNN.wd, .Vx on the N + 1 faces of each
row, .Vy on the N + 1 faces of each column, dem.asc and run.par) and a CF grid (netCDF4,
float32, time-first).  Steps, each in a fresh process through ``import_benchmark.measure``
(peak memory = the process's maximum resident set size):

  open       open_flow_source (grid, bed; no snapshot read)
  snapshot   open + one snapshot read and checked
  import     driftlog import to a flow file (every snapshot)
  sampling   GridFlowField.sample of 1e5 points at successive times (a new snapshot per
             step, read lazily from the source: the three rasters of that time)

ESRI ASCII is text (about 10 bytes a value) and slow to write and parse; its series is shorter
(``--ascii-snapshots``, default 10): its per-snapshot cost is what the table compares.

    python benchmarks/raster_import_benchmark.py [--work DIR] [--snapshots 100]
        [--ascii-snapshots 10] [--n 1000] [--quick]

Writes benchmarks/results/import_raster.json and import_raster.md (``*_quick`` with --quick).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from _common import machine
from import_benchmark import RESULTS, measure


def fields(n, k):
    """Depth, u, v (float32, rows from the north) and the bed of snapshot k on n x n cells."""
    x = np.arange(n, dtype=np.float32) + 0.5
    y = (n - np.arange(n, dtype=np.float32) - 0.5)[:, None]
    h = 1.0 + 0.1 * np.sin(x / 50 + 0.1 * k) * np.cos(y / 70)
    u = 0.5 + 0.01 * np.cos(y / 40 + 0.1 * k) + 0 * x
    v = 0.1 * np.cos(x / 30) + 0 * y
    return h.astype(np.float32), u.astype(np.float32), v.astype(np.float32)


def _write(arr, x, y, path, driver):
    import rioxarray  # noqa: F401 - the .rio accessor
    import xarray as xr

    da = xr.DataArray(arr, dims=("y", "x"), coords={"x": x, "y": y})
    da.rio.write_nodata(-9999.0, inplace=True)
    da.rio.to_raster(path, driver=driver)


def make_geotiff(work, n, snapshots):
    folder = work / f"geotiff_{n}_{snapshots}"
    done = folder / "done"
    if done.is_file():
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    x = np.arange(n) + 0.5
    y = n - np.arange(n) - 0.5
    _write(np.broadcast_to(0.001 * x, (n, n)).astype(np.float32), x, y, folder / "dem.tif",
           "GTiff")
    for k in range(snapshots):
        for name, arr in zip(("depth", "u", "v"), fields(n, k), strict=True):
            _write(arr, x, y, folder / f"{name}_{60 * k}.tif", "GTiff")
    done.write_text("")
    print(f"  geotiff series ({snapshots} snapshots): {time.perf_counter() - t0:.1f} s, "
          f"{sum(p.stat().st_size for p in folder.iterdir()) / 1e9:.2f} GB", flush=True)
    return folder


def make_lisflood(work, n, snapshots):
    folder = work / f"lisflood_{n}_{snapshots}"
    par = folder / "run.par"
    if par.is_file():
        return par
    res = folder / "results"
    res.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    x = np.arange(n) + 0.5
    y = n - np.arange(n) - 0.5
    xf = np.arange(n + 1.0)
    yf = n - np.arange(n + 1.0)
    _write(np.broadcast_to(0.001 * x, (n, n)).astype(np.float32), x, y, folder / "dem.asc",
           "AAIGrid")
    for k in range(snapshots):
        h, u, v = fields(n, k)
        _write(h, x, y, res / f"res-{k:04d}.wd", "AAIGrid")
        _write(np.hstack([u, u[:, -1:]]), xf, y, res / f"res-{k:04d}.Vx", "AAIGrid")
        _write(-np.vstack([v, v[-1:]]), x, yf, res / f"res-{k:04d}.Vy", "AAIGrid")
    par.write_text("DEMfile dem.asc\nresroot res\ndirroot results\nsaveint 60\n")
    print(f"  lisflood ascii ({snapshots} snapshots): {time.perf_counter() - t0:.1f} s, "
          f"{sum(p.stat().st_size for p in res.iterdir()) / 1e9:.2f} GB", flush=True)
    return par


def make_cf_grid(work, n, snapshots):
    import netCDF4

    path = work / f"cf_grid_{n}_{snapshots}.nc"
    if path.is_file():
        return path
    t0 = time.perf_counter()
    tmp = path.with_suffix(".part")
    with netCDF4.Dataset(tmp, "w") as ds:
        ds.createDimension("time", None)
        for name in ("y", "x"):
            ds.createDimension(name, n)
            var = ds.createVariable(name, "f8", (name,))
            var[:] = np.arange(n) + 0.5
            var.units, var.standard_name = "m", f"projection_{name}_coordinate"
        t = ds.createVariable("time", "f8", ("time",))
        t.units = "seconds since 2001-01-01 00:00:00"
        bed = ds.createVariable("bed", "f4", ("y", "x"))
        bed.standard_name, bed.units = "altitude", "m"
        bed[:] = np.broadcast_to(0.001 * (np.arange(n) + 0.5), (n, n))
        for name, std in (("depth", "water_depth"), ("u", "sea_water_x_velocity"),
                          ("v", "sea_water_y_velocity")):
            var = ds.createVariable(name, "f4", ("time", "y", "x"), chunksizes=(1, n, n))
            var.standard_name, var.units = std, "m" if name == "depth" else "m s-1"
        for k in range(snapshots):
            h, u, v = fields(n, k)
            t[k] = 60.0 * k
            ds["depth"][k], ds["u"][k], ds["v"][k] = h[::-1], u[::-1], v[::-1]
    tmp.rename(path)
    print(f"  cf grid ({snapshots} snapshots): {time.perf_counter() - t0:.1f} s, "
          f"{path.stat().st_size / 1e9:.2f} GB", flush=True)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default="/tmp/driftlog_raster_bench")
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--snapshots", type=int, default=100)
    ap.add_argument("--ascii-snapshots", type=int, default=10)
    ap.add_argument("--quick", action="store_true",
                    help="300 x 300 cells, 10 snapshots (3 ASCII): *_quick result files")
    a = ap.parse_args()
    if a.quick:
        a.n, a.snapshots, a.ascii_snapshots = 300, 10, 3
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    results = {"machine": machine(), "cells": a.n * a.n, "cases": {}}
    print("warming the numba caches on small inputs", flush=True)
    measure("raster", make_geotiff(work / "small", 20, 3), "sample", snapshots=3, quiet=True)
    cases = [("geotiff", "raster", make_geotiff(work, a.n, a.snapshots), a.snapshots),
             ("lisflood_ascii", "raster", make_lisflood(work, a.n, a.ascii_snapshots),
              a.ascii_snapshots),
             ("cf_grid", "cf_grid", make_cf_grid(work, a.n, a.snapshots), a.snapshots)]
    for name, kind, src, snaps in cases:
        print(name, flush=True)
        r = results["cases"][name] = {"snapshots": snaps}
        for action in ("open", "snapshot", "import"):
            r[action] = measure(kind, src, action, work / f"{name}.nc")
        r["sample"] = measure(kind, src, "sample", snapshots=min(snaps, 11))
    RESULTS.mkdir(parents=True, exist_ok=True)
    stem = "import_raster_quick" if a.quick else "import_raster"
    (RESULTS / f"{stem}.json").write_text(json.dumps(results, indent=2))
    text = report(results)
    (RESULTS / f"{stem}.md").write_text(text)
    print(text)


def report(res):
    def g(v):
        return f"{v:.3g}"

    lines = ["### Importing regular-grid flows (GeoTIFF, LISFLOOD-FP ASCII, CF grid)", "",
             f"Measured on {res['machine']}; {res['cells']:.0e} cells; each step in a fresh "
             "process (peak = its maximum resident set size).  Re-create: `python "
             "benchmarks/raster_import_benchmark.py`.", "",
             "| format | snapshots | open (s) | open peak (MB) | one snapshot (s) | import (s) "
             "| import per snapshot (s) | import peak (MB) | flow file (GB) | sampling 1e5 "
             "points (M points/s) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in res["cases"].items():
        imp = r["import"]
        lines.append(f"| {name} | {r['snapshots']} | {g(r['open']['seconds'])} | "
                     f"{r['open']['peak_rss_mb']:.0f} | {g(r['snapshot']['read_one_s'])} | "
                     f"{g(imp['seconds'])} | {g(imp['seconds'] / r['snapshots'])} | "
                     f"{imp['peak_rss_mb']:.0f} | {imp['output_bytes'] / 1e9:.2f} | "
                     f"{r['sample']['points_per_s'] / 1e6:.2f} |")
    lines += ["", "Sampling: 1e5 random points, 4 times between each pair of snapshots, each "
              "new snapshot read lazily from the source (wall time, shared machine)."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    main()
