"""TELEMAC Selafin and MIKE 21 FM dfsu: import time and memory at 1e6 cells, sampling speed.

Inputs (generated once under --work, default /tmp/driftlog_formats_bench), each written with its
format's own library:
  selafin   N x N squares split in two: 2 N^2 ~ 1e6 triangles (N = 707, 5.0e5 nodes),
            100 frames of WATER DEPTH, VELOCITY U, VELOCITY V, FREE SURFACE, BOTTOM on the
            nodes, single precision (TELEMAC's default), written with xarray-selafin
            (frames computed while writing, from dask arrays)
  dfsu      1000 x 1000 quadrilaterals (1e6 elements), 100 steps of Surface elevation, Total
            water depth, U velocity, V velocity (float32), written with mikeio (to_dfs, then
            Dfsu.append in chunks)

Measured, each step in a fresh process (benchmarks/import_benchmark.py's ``--step``; peak
memory = its maximum resident set size):
  open       open_flow_source('auto'): format detected, mesh and topology, bed
  snapshot   open + one snapshot read and checked
  import     driftlog import to a flow file (every snapshot)
  sampling   MeshFlowField.sample of 1e5 points, 4 times per snapshot interval, one new
             snapshot per interval, lazily from the source

    python benchmarks/model_formats_benchmark.py [--quick] [--work DIR] [--snapshots 100]

--quick: 200 x 200 cells and 10 snapshots (writes model_formats_quick.*).
Writes benchmarks/results/model_formats.json and model_formats.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _common import machine  # noqa: E402
from import_benchmark import measure  # noqa: E402

RESULTS = HERE / "results"


def fields(x, y, k):
    """Depth, velocity and bed of snapshot k at points (x, y) (smooth, time-varying)."""
    h = 1.0 + 0.1 * np.sin(x / 50 + 0.1 * k) * np.cos(y / 70)
    u = 0.5 + 0.01 * np.cos(y / 40 + 0.1 * k)
    v = 0.1 * np.cos(x / 30)
    return h, u, v, 0.001 * x


def make_selafin(work: Path, n: int, snapshots: int) -> Path:
    import dask
    import dask.array as da
    import xarray as xr
    import xarray_selafin.xarray_backend  # noqa: F401

    path = work / f"selafin_{n}_{snapshots}.slf"
    if path.is_file():
        return path
    t0 = time.perf_counter()
    X, Y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0))
    x, y = X.ravel(), Y.ravel()
    nid = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = nid[:-1, :-1].ravel(), nid[:-1, 1:].ravel(), nid[1:, 1:].ravel(), \
        nid[1:, :-1].ravel()
    ikle = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])]) + 1

    def frame(key, block_info=None):
        k = block_info[None]["chunk-location"][0]
        h, u, v, bed = fields(x, y, k)
        val = {"H": h, "U": u, "V": v, "B": bed, "S": h + bed}[key]
        return val.astype(np.float32)[None, :]

    data = {key: (("time", "node"), da.map_blocks(frame, key, dtype=np.float32,
                                                  chunks=((1,) * snapshots, (x.size,)),
                                                  meta=np.empty((0, 0), np.float32)))
            for key in ("H", "U", "V", "S", "B")}
    times = np.datetime64("2020-01-01T00:00:00") + (60 * np.arange(snapshots)).astype(
        "timedelta64[s]")
    ds = xr.Dataset(data, coords={"x": ("node", x), "y": ("node", y),
                                  "time": times.astype("datetime64[ns]")})
    ds.attrs.update(title="driftlog benchmark", float_size=4, ikle2=ikle.astype(np.int32),
                    date_start=(2020, 1, 1, 0, 0, 0),
                    variables={"H": ("WATER DEPTH", "M"), "U": ("VELOCITY U", "M/S"),
                               "V": ("VELOCITY V", "M/S"), "S": ("FREE SURFACE", "M"),
                               "B": ("BOTTOM", "M")})
    tmp = path.with_suffix(".part")
    with dask.config.set(scheduler="synchronous"):
        ds.selafin.write(str(tmp))
    tmp.rename(path)
    print(f"  selafin file ({ikle.shape[0]} triangles, {snapshots} frames): "
          f"{time.perf_counter() - t0:.1f} s, {path.stat().st_size / 1e9:.2f} GB", flush=True)
    return path


def make_dfsu(work: Path, n: int, snapshots: int, chunk: int = 10) -> Path:
    import mikeio
    import pandas as pd

    path = work / f"dfsu_{n}_{snapshots}.dfsu"
    if path.is_file():
        return path
    t0 = time.perf_counter()
    X, Y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0))
    x, y = X.ravel(), Y.ravel()
    nid = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    fn = np.stack([nid[:-1, :-1], nid[:-1, 1:], nid[1:, 1:], nid[1:, :-1]], -1).reshape(-1, 4)
    geom = mikeio.spatial.GeometryFM2D(node_coordinates=np.column_stack([x, y, 0.001 * x]),
                                       element_table=list(fn), projection="NON-UTM")
    xc, yc = (np.arange(n * n) % n) + 0.5, (np.arange(n * n) // n) + 0.5
    E, U = mikeio.EUMType, mikeio.EUMUnit
    items = [mikeio.ItemInfo("Surface elevation", E.Surface_Elevation, U.meter),
             mikeio.ItemInfo("Total water depth", E.Water_Depth, U.meter),
             mikeio.ItemInfo("U velocity", E.u_velocity_component, U.meter_per_sec),
             mikeio.ItemInfo("V velocity", E.v_velocity_component, U.meter_per_sec)]
    stamps = pd.date_range("2020-01-01", periods=snapshots, freq="60s")
    tmp = path.with_name(path.stem + "_part.dfsu")
    dfs = None
    for start in range(0, snapshots, chunk):
        ks = range(start, min(start + chunk, snapshots))
        cols = [[], [], [], []]
        for k in ks:
            h, u, v, bed = fields(xc, yc, k)
            for c, val in zip(cols, (h + bed, h, u, v), strict=True):
                c.append(val.astype(np.float32))
        ds = mikeio.Dataset([mikeio.DataArray(np.array(c), time=stamps[start:start + len(ks)],
                                              geometry=geom if dfs is None else dfs.geometry,
                                              item=it) for c, it in zip(cols, items,
                                                                        strict=True)])
        if dfs is None:
            ds.to_dfs(str(tmp))
            dfs = mikeio.Dfsu(str(tmp))
        else:
            dfs.append(ds)
    tmp.rename(path)
    print(f"  dfsu file ({n * n} quadrilaterals, {snapshots} steps): "
          f"{time.perf_counter() - t0:.1f} s, {path.stat().st_size / 1e9:.2f} GB", flush=True)
    return path


def report(res):
    lines = [f"Machine: {res['machine']}. Each step in a fresh process; peak memory is its "
             "maximum resident set size (Python, numpy, numba, xarray / mikeio included).", "",
             "| source | cells | step | time (s) | peak memory (MB) | notes |",
             "| --- | ---: | --- | ---: | ---: | --- |"]
    for case, r in res["cases"].items():
        for action in ("open", "snapshot", "import"):
            m = r[action]
            note = ""
            if action == "snapshot":
                note = f"one snapshot read in {m['read_one_s']:.2f} s"
            if action == "import":
                note = (f"{m['snapshots']} snapshots, flow file "
                        f"{m['output_bytes'] / 1e6:.0f} MB")
            lines.append(f"| {case} | {r['cells']} | {action} | {m['seconds']:.1f} | "
                         f"{m['peak_rss_mb']:.0f} | {note} |")
    lines += ["", "Sampling 1e5 points, 4 times per snapshot interval, each interval loading "
                  "one new snapshot, lazily from the file:", "",
              "| sampled from | intervals | time per interval (s) | points/s |",
              "| --- | ---: | ---: | ---: |"]
    for case, r in res["cases"].items():
        m = r["sample"]
        lines.append(f"| {case} | {m['intervals']} | {m['per_interval_s']:.2f} | "
                     f"{m['points_per_s']:.3g} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default="/tmp/driftlog_formats_bench")
    ap.add_argument("--snapshots", type=int, default=None)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    nq = 200 if a.quick else 1000
    ntri = 141 if a.quick else 707  # 2 n^2 triangles ~ n_quads^2 ... ~1e6 at full size
    snaps = a.snapshots or (10 if a.quick else 100)
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    res = {"machine": machine(), "snapshots": snaps, "cases": {}}
    print("warming the numba caches on small inputs", flush=True)
    small = work / "small"
    small.mkdir(exist_ok=True)
    measure("auto", make_selafin(small, 10, 3), "sample", snapshots=3, quiet=True)
    measure("auto", make_dfsu(small, 10, 3), "sample", snapshots=3, quiet=True)
    print("generating inputs", flush=True)
    cases = {"selafin": (make_selafin(work, ntri, snaps), 2 * ntri * ntri),
             "dfsu": (make_dfsu(work, nq, snaps), nq * nq)}
    for case, (path, cells) in cases.items():
        print(case, flush=True)
        r = res["cases"][case] = {"cells": cells, "file_bytes": path.stat().st_size}
        for action in ("open", "snapshot", "import"):
            r[action] = measure("auto", path, action, work / f"{case}.nc")
        r["sample"] = measure("auto", path, "sample", snapshots=min(snaps, 21))
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = "model_formats_quick" if a.quick else "model_formats"
    (RESULTS / f"{name}.json").write_text(json.dumps(res, indent=2))
    (RESULTS / f"{name}.md").write_text(report(res))
    print((RESULTS / f"{name}.md").read_text())


if __name__ == "__main__":
    main()
