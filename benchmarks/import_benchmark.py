"""Importing flows: time and peak memory to open and convert big sources, and sampling speed
lazily from the source against a converted driftlog flow file.

Cases (generated once under --work, default /tmp/driftlog_import_bench):
  openfoam   1000 x 1000 x 1 cells by blockMesh (1e6 cells, one cell thick, as shallowWaterFoam
             needs), fields h, hU, hTotal and constant/h0 written from Python for 3 times;
             ascii, and binary (foamFormatConvert)
  ugrid      a 1e6-face D-Flow FM-like map file (1000 x 1000 quads, 1-based, -999 fill), 100
             snapshots of mesh2d_s1, mesh2d_waterdepth, mesh2d_ucx, mesh2d_ucy (float32)
  hecras     the real Bald Eagle Creek dam-break plan (../shared/data/hecras: 4,425 cells in
             two 2D areas, 37 outputs, time series in a separate file, bed =
             "min_water_surface"), and a synthetic HEC-RAS 6 layout plan file written with
             h5py (--hecras-n^2 cells of one 2D area, cells by faces with orientation, face
             points, Cells Minimum Elevation; --snapshots outputs of Water Surface per cell
             and Face Velocity per face, float32, Time Date Stamp)

Measured, each step in a fresh process (peak memory = its maximum resident set size):
  open       open_flow_source: mesh and topology, bed; no snapshot read
  snapshot   open + one snapshot read and checked
  import     driftlog import to a flow file (every snapshot)
  sampling   MeshFlowField.sample of 1e5 points at successive times (one new snapshot per
             step), from the source and from the converted flow file

    python benchmarks/import_benchmark.py [--work DIR] [--skip-openfoam] [--snapshots 100]
        [--only hecras] [--hecras-n 1000]

Writes benchmarks/results/import.json and import.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
N = int(os.environ.get("DRIFTLOG_BENCH_N", 1000))  # cells per side: N * N = 1e6


# --------------------------------------------------------------------- generating the inputs
def make_openfoam(work: Path, fmt="ascii", n=None):
    from driftlog.adapters.foam_io import format_list, write_foam_file
    from driftlog.adapters.openfoam_case import foam_env

    N = n or globals()["N"]  # noqa: N806
    case = work / f"openfoam_{fmt}_{N}"
    if (case / "2" / "hU").is_file() or (case / "2" / "hU.gz").is_file():
        return case
    env = foam_env()
    if env is None:
        raise SystemExit("OpenFOAM is needed for the OpenFOAM case (or --skip-openfoam)")
    if fmt == "binary":
        src = make_openfoam(work, "ascii", N)
        subprocess.run(["cp", "-r", str(src), str(case)], check=True)
        ctl = case / "system" / "controlDict"
        ctl.write_text(ctl.read_text().replace("writeFormat ascii;", "writeFormat binary;"))
        subprocess.run(["foamFormatConvert", "-case", str(case)], env=env, check=True,
                       stdout=subprocess.DEVNULL)
        # foamFormatConvert leaves constant/h0 ascii: fine, it is read once
        return case
    write_foam_file(case / "system" / "blockMeshDict", "dictionary", "blockMeshDict", f"""
scale 1;
vertices ((0 0 0) ({N} 0 0) ({N} {N} 0) (0 {N} 0) (0 0 1) ({N} 0 1) ({N} {N} 1) (0 {N} 1));
blocks (hex (0 1 2 3 4 5 6 7) ({N} {N} 1) simpleGrading (1 1 1));
boundary
(
    walls {{ type wall; faces ((3 7 6 2) (1 5 4 0) (0 4 7 3) (2 6 5 1)); }}
    frontAndBack {{ type empty; faces ((0 3 2 1) (4 5 6 7)); }}
);""", "system")
    write_foam_file(case / "system" / "controlDict", "dictionary", "controlDict",
                    "application shallowWaterFoam;\nstartTime 0;\nendTime 2;\ndeltaT 1;\n"
                    "writeControl timeStep;\nwriteInterval 1;\nwriteFormat ascii;\n"
                    "writePrecision 8;\nwriteCompression off;\ntimeFormat general;\n"
                    "timePrecision 6;", "system")
    t0 = time.perf_counter()
    subprocess.run(["blockMesh", "-case", str(case)], env=env, check=True,
                   stdout=subprocess.DEVNULL)
    print(f"  blockMesh {N}x{N}x1: {time.perf_counter() - t0:.1f} s", flush=True)
    i = np.arange(N * N)
    xc, yc = (i % N) + 0.5, (i // N) + 0.5
    bed = 0.001 * xc
    bnd = "boundaryField\n{\n    walls { type zeroGradient; }\n    frontAndBack { type empty; }\n}"
    bndv = "boundaryField\n{\n    walls { type slip; }\n    frontAndBack { type empty; }\n}"

    def scalar(path, obj, vals, loc):
        write_foam_file(path, "volScalarField", obj, "dimensions [0 1 0 0 0 0 0];\n"
                        f"internalField nonuniform List<scalar>\n{format_list(vals, '%.8g')};\n"
                        + bnd, loc)

    scalar(case / "constant" / "h0", "h0", bed, "constant")
    for t in range(3):
        h = 1.0 + 0.1 * np.sin(xc / 50 + t) * np.cos(yc / 70)
        scalar(case / str(t) / "h", "h", h, str(t))
        scalar(case / str(t) / "hTotal", "hTotal", h + bed, str(t))
        hu = np.column_stack([h * 0.5, h * 0.1 * np.cos(xc / 30), np.zeros_like(h)])
        write_foam_file(case / str(t) / "hU", "volVectorField", "hU",
                        "dimensions [0 2 -1 0 0 0 0];\ninternalField nonuniform List<vector>\n"
                        f"{format_list(hu, '%.8g')};\n" + bndv, str(t))
        (case / str(t) / "uniform").mkdir(exist_ok=True)
        (case / str(t) / "uniform" / "time").write_text("// written for the benchmark\n")
    return case


def make_ugrid(work: Path, snapshots: int, n=None):
    import netCDF4

    N = n or globals()["N"]  # noqa: N806
    path = work / f"ugrid_{N}_{snapshots}.nc"
    if path.is_file():
        return path
    t0 = time.perf_counter()
    X, Y = np.meshgrid(np.arange(N + 1.0), np.arange(N + 1.0))
    nid = np.arange((N + 1) ** 2).reshape(N + 1, N + 1)
    fn = np.stack([nid[:-1, :-1], nid[:-1, 1:], nid[1:, 1:], nid[1:, :-1]], -1).reshape(-1, 4)
    xc = (np.arange(N * N) % N) + 0.5
    yc = (np.arange(N * N) // N) + 0.5
    tmp = path.with_suffix(".part")
    with netCDF4.Dataset(tmp, "w") as ds:
        ds.createDimension("mesh2d_nNodes", X.size)
        ds.createDimension("mesh2d_nFaces", N * N)
        ds.createDimension("mesh2d_nMax_face_nodes", 4)
        ds.createDimension("time", None)
        m = ds.createVariable("mesh2d", "i4")
        m.setncatts(dict(cf_role="mesh_topology", topology_dimension=2,
                         node_coordinates="mesh2d_node_x mesh2d_node_y",
                         face_node_connectivity="mesh2d_face_nodes",
                         face_dimension="mesh2d_nFaces"))
        ds.createVariable("mesh2d_node_x", "f8", ("mesh2d_nNodes",))[:] = X.ravel()
        ds.createVariable("mesh2d_node_y", "f8", ("mesh2d_nNodes",))[:] = Y.ravel()
        v = ds.createVariable("mesh2d_face_nodes", "i4", ("mesh2d_nFaces",
                                                          "mesh2d_nMax_face_nodes"),
                              fill_value=-999)
        v.start_index = 1
        v[:] = fn + 1
        bl = ds.createVariable("mesh2d_flowelem_bl", "f8", ("mesh2d_nFaces",))
        bl.setncatts(dict(standard_name="altitude", units="m"))
        bl[:] = 0.001 * xc
        t = ds.createVariable("time", "f8", ("time",))
        t.units = "seconds since 2001-01-01 00:00:00"
        spec = {"mesh2d_s1": "sea_surface_height",
                "mesh2d_waterdepth": "sea_floor_depth_below_sea_surface",
                "mesh2d_ucx": "sea_water_x_velocity", "mesh2d_ucy": "sea_water_y_velocity"}
        for name, std in spec.items():
            v = ds.createVariable(name, "f4", ("time", "mesh2d_nFaces"),
                                  chunksizes=(1, N * N), fill_value=np.float32(-999))
            v.setncatts(dict(standard_name=std, units="m" if "uc" not in name else "m s-1",
                             mesh="mesh2d", location="face"))
        for k in range(snapshots):
            h = 1.0 + 0.1 * np.sin(xc / 50 + 0.1 * k) * np.cos(yc / 70)
            t[k] = 60.0 * k
            ds["mesh2d_waterdepth"][k] = h
            ds["mesh2d_s1"][k] = h + 0.001 * xc
            ds["mesh2d_ucx"][k] = 0.5 + 0.01 * np.cos(yc / 40 + 0.1 * k)
            ds["mesh2d_ucy"][k] = 0.1 * np.cos(xc / 30)
    tmp.rename(path)
    print(f"  ugrid file ({snapshots} snapshots): {time.perf_counter() - t0:.1f} s, "
          f"{path.stat().st_size / 1e9:.2f} GB", flush=True)
    return path


HECRAS_DATA = ROOT.parent / "shared" / "data" / "hecras"


def make_hecras(work: Path, snapshots: int, n: int):
    """A HEC-RAS 6 plan file (HDF5) of one n x n 2D area, in HEC-RAS's own layout."""
    import h5py

    path = work / f"hecras_{n}_{snapshots}.p01.hdf"
    if path.is_file():
        return path
    t0 = time.perf_counter()
    nn = n + 1
    X, Y = np.meshgrid(np.arange(nn) * 10.0, np.arange(nn) * 10.0)
    nid = np.arange(nn * nn).reshape(nn, nn)  # [j, i]
    # faces: horizontal (i, j) -> (i + 1, j), then vertical (i, j) -> (i, j + 1)
    h_a, h_b = nid[:, :-1].ravel(), nid[:, 1:].ravel()
    v_a, v_b = nid[:-1, :].ravel(), nid[1:, :].ravel()
    nh = h_a.size
    faces = np.column_stack([np.r_[h_a, v_a], np.r_[h_b, v_b]]).astype(np.int32)
    hid = np.arange(nh).reshape(nn, n)
    vid = nh + np.arange(v_a.size).reshape(n, nn)
    # each cell's faces counter-clockwise: bottom (+1), right (+1), top (-1), left (-1)
    cf = np.stack([hid[:-1, :], vid[:, 1:], hid[1:, :], vid[:, :-1]], -1).reshape(-1, 4)
    orient = np.broadcast_to(np.array([1, 1, -1, -1]), cf.shape)
    ncell = n * n
    xc = (np.arange(ncell) % n + 0.5) * 10.0
    yc = (np.arange(ncell) // n + 0.5) * 10.0
    bed = 100.0 + 0.001 * xc
    fx = 0.5 * (X.ravel()[faces[:, 0]] + X.ravel()[faces[:, 1]])
    fy = 0.5 * (Y.ravel()[faces[:, 0]] + Y.ravel()[faces[:, 1]])
    d = np.column_stack([X.ravel()[faces[:, 1]] - X.ravel()[faces[:, 0]],
                         Y.ravel()[faces[:, 1]] - Y.ravel()[faces[:, 0]]])
    nrm = np.column_stack([d[:, 1], -d[:, 0]]) / 10.0
    tmp = path.with_suffix(".part")
    with h5py.File(tmp, "w") as f:
        f.attrs["File Type"] = np.bytes_("HEC-RAS Results")
        f.attrs["File Version"] = np.bytes_("HEC-RAS 6.5 (synthetic, driftlog benchmark)")
        f.attrs["Units System"] = np.bytes_("SI Units")
        att = np.zeros(1, dtype=[("Name", "S16"), ("Cell Count", "<i4")])
        att["Name"], att["Cell Count"] = b"Area", ncell
        g = f.create_group("Geometry/2D Flow Areas")
        g["Attributes"] = att
        a = g.create_group("Area")
        a["FacePoints Coordinate"] = np.column_stack([X.ravel(), Y.ravel()])
        a["Faces FacePoint Indexes"] = faces
        a["Cells Face and Orientation Info"] = np.column_stack(
            [np.arange(ncell) * 4, np.full(ncell, 4)]).astype(np.int32)
        a["Cells Face and Orientation Values"] = np.column_stack(
            [cf.ravel(), orient.ravel()]).astype(np.int32)
        a["Faces Perimeter Info"] = np.zeros((faces.shape[0], 2), np.int32)
        a["Faces Perimeter Values"] = np.zeros((0, 2))
        a["Cells Minimum Elevation"] = bed.astype(np.float32)
        ts = f.create_group("Results/Unsteady/Output/Output Blocks/Base Output/"
                            "Unsteady Time Series")
        start = np.datetime64("2024-01-01T00:00:00")
        stamps = [(start + np.timedelta64(600 * k, "s")).astype(object)
                  .strftime("%d%b%Y %H:%M:%S:000").upper() for k in range(snapshots)]
        ts["Time Date Stamp (ms)"] = np.array(stamps, dtype="S22")
        r = ts.create_group("2D Flow Areas/Area")
        ws = r.create_dataset("Water Surface", (snapshots, ncell), "f4", chunks=(1, ncell))
        fv = r.create_dataset("Face Velocity", (snapshots, faces.shape[0]), "f4",
                              chunks=(1, faces.shape[0]))
        for k in range(snapshots):
            ws[k] = bed + 1.0 + 0.1 * np.sin(xc / 500 + 0.1 * k) * np.cos(yc / 700)
            u = 0.5 + 0.01 * np.cos(fy / 400 + 0.1 * k)
            v = 0.1 * np.cos(fx / 300)
            fv[k] = nrm[:, 0] * u + nrm[:, 1] * v
    tmp.rename(path)
    print(f"  hecras file ({ncell} cells, {snapshots} snapshots): "
          f"{time.perf_counter() - t0:.1f} s, {path.stat().st_size / 1e9:.2f} GB", flush=True)
    return path


# --------------------------------------------------------------------- measured steps
def peak_rss_mb():
    """This process's peak resident set size (MB): VmHWM of its own address space.

    Not ``ru_maxrss``: Linux carries the parent's peak into a child over fork and exec, so a
    step started by a parent that had generated a 1 GB input reported the parent's peak.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def step(kind, source, action, out=None, snapshots=None, options=None):
    """Run in this (fresh) process; prints a JSON line with seconds and peak memory."""
    from functools import partial

    from driftlog.adapters import checked_snapshot, import_flow
    from driftlog.adapters import open_flow_source as _open

    options = options or {}
    open_flow_source = partial(_open, **options)

    t0 = time.perf_counter()
    res = {}
    if action == "open":
        f = open_flow_source(kind, source)
        res["faces"] = f.mesh.n_faces
        res["snapshots"] = int(f.times.size)
    elif action == "snapshot":
        f = open_flow_source(kind, source)
        t1 = time.perf_counter()
        checked_snapshot(f, 0)
        res["read_one_s"] = time.perf_counter() - t1
    elif action == "import":
        _, f = import_flow(source, out, kind=kind, **options)
        res["snapshots"] = int(f.times.size)
        res["output_bytes"] = Path(out).stat().st_size
    elif action == "sample":
        f = open_flow_source(kind, source)
        rng = np.random.default_rng(0)
        x0, y0, x1, y1 = f.mesh.bounds
        x = rng.uniform(x0 + 1e-3 * (x1 - x0), x1 - 1e-3 * (x1 - x0), 100_000)
        y = rng.uniform(y0 + 1e-3 * (y1 - y0), y1 - 1e-3 * (y1 - y0), 100_000)
        face = None
        s = f.sample(x, y, float(f.times[0]))  # compile, locate
        face = s.face
        n = min(snapshots or f.times.size, f.times.size) - 1
        t1 = time.perf_counter()
        for k in range(n):  # one new snapshot per step, 4 samples between snapshots
            for a in (0.125, 0.375, 0.625, 0.875):
                tk = f.times[k] + a * (f.times[k + 1] - f.times[k])
                s = f.sample(x, y, float(tk), face=face)
                face = s.face
        el = time.perf_counter() - t1
        res.update(intervals=n, samples=4 * n, sample_loop_s=el,
                   per_interval_s=el / n, points_per_s=4 * n * 1e5 / el)
    res["seconds"] = time.perf_counter() - t0
    res["peak_rss_mb"] = peak_rss_mb()
    print("RESULT " + json.dumps(res), flush=True)


def measure(kind, source, action, out=None, snapshots=None, quiet=False, options=None):
    cmd = [sys.executable, __file__, "--step", kind, str(source), action, str(out or ""),
           str(snapshots or 0), "--options", json.dumps(options or {})]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    if p.returncode != 0 or not line:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}")
    r = json.loads(line[0][7:])
    if quiet:
        return r
    print(f"  {kind:9s} {action:9s} {r['seconds']:8.2f} s  peak {r['peak_rss_mb']:8.0f} MB"
          + (f"  {r['points_per_s'] / 1e6:.2f} M points/s" if "points_per_s" in r else ""),
          flush=True)
    return r


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default="/tmp/driftlog_import_bench")
    ap.add_argument("--snapshots", type=int, default=100)
    ap.add_argument("--skip-openfoam", action="store_true")
    ap.add_argument("--only", choices=("hecras",), help="only this format's cases (the "
                    "results are merged into import.json)")
    ap.add_argument("--hecras-n", type=int, default=N, help="cells per side of the synthetic "
                    "HEC-RAS area")
    ap.add_argument("--step", nargs=5, help=argparse.SUPPRESS)
    ap.add_argument("--options", default="{}", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.step:
        kind, source, action, out, snaps = a.step
        step(kind, source, action, out or None, int(snaps) or None, json.loads(a.options))
        return
    if a.only == "hecras":
        run_hecras(a)
        return
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    results = {"machine": f"{platform.node()} {os.cpu_count()} cores, "
                          f"{platform.python_version()}", "cells": N * N, "cases": {}}
    print("warming the numba caches on small inputs", flush=True)
    small = work / "small"
    small.mkdir(exist_ok=True)
    if not a.skip_openfoam:
        measure("openfoam", make_openfoam(small, "ascii", 20), "open", quiet=True)
    measure("ugrid", make_ugrid(small, 3, 20), "sample", snapshots=3, quiet=True)
    print("generating inputs", flush=True)
    if not a.skip_openfoam:
        for fmt in ("ascii", "binary"):
            case = make_openfoam(work, fmt)
            print(f"openfoam {fmt}", flush=True)
            r = results["cases"][f"openfoam_{fmt}"] = {}
            for action in ("open", "snapshot", "import"):
                r[action] = measure("openfoam", case, action, work / f"of_{fmt}.nc")
    ug = make_ugrid(work, a.snapshots)
    print("ugrid", flush=True)
    r = results["cases"]["ugrid"] = {}
    for action in ("open", "snapshot", "import"):
        r[action] = measure("ugrid", ug, action, work / "ug.nc")
    print("sampling 1e5 points over successive times", flush=True)
    n_s = min(a.snapshots, 21)
    r["sample_lazy_source"] = measure("ugrid", ug, "sample", snapshots=n_s)
    r["sample_flow_file"] = measure("file", work / "ug.nc", "sample", snapshots=n_s)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "import.json").write_text(json.dumps(results, indent=2))
    (RESULTS / "import.md").write_text(report(results))
    print((RESULTS / "import.md").read_text())


def run_hecras(a):
    """The HEC-RAS cases: the real Bald Eagle plan, and a synthetic large plan file."""
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    path = RESULTS / "import.json"
    results = json.loads(path.read_text()) if path.is_file() else {"cases": {}}
    results.setdefault("cases", {})
    machine = f"{platform.node()} {os.cpu_count()} cores, {platform.python_version()}"
    plan = HECRAS_DATA / "BaldEagleDamBrk.p18.hdf"
    opts = {"results": str(HECRAS_DATA / "BaldEagleDamBrk.p18.timeseries.hdf"),
            "bed": "min_water_surface"}
    print("warming the numba caches", flush=True)
    measure("hecras", plan, "sample", snapshots=3, quiet=True, options=opts)
    print("hecras Bald Eagle (real)", flush=True)
    r = results["cases"]["hecras_bald_eagle"] = {"machine": machine}
    for action in ("open", "snapshot", "import"):
        r[action] = measure("hecras", plan, action, work / "be.nc", options=opts)
    r["sample_lazy_source"] = measure("hecras", plan, "sample", snapshots=37, options=opts)
    big = make_hecras(work, a.snapshots, a.hecras_n)
    key = f"hecras_synthetic_{a.hecras_n ** 2}_cells"
    print(f"hecras synthetic ({a.hecras_n ** 2} cells, {a.snapshots} snapshots)", flush=True)
    r = results["cases"][key] = {"machine": machine}
    for action in ("open", "snapshot", "import"):
        r[action] = measure("hecras", big, action, work / "hr.nc")
    r["sample_lazy_source"] = measure("hecras", big, "sample", snapshots=min(a.snapshots, 11))
    r["sample_flow_file"] = measure("file", work / "hr.nc", "sample",
                                    snapshots=min(a.snapshots, 11))
    RESULTS.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=2))
    (RESULTS / "import_hecras.md").write_text(report_hecras(results))
    print((RESULTS / "import_hecras.md").read_text())


def report_hecras(res):
    lines = ["HEC-RAS imports. Each step in a fresh process; peak memory is its maximum "
             "resident set size (Python, numpy, numba, h5py included).", "",
             "| source | step | time (s) | peak memory (MB) | notes |",
             "| --- | --- | ---: | ---: | --- |"]
    for case, r in res["cases"].items():
        if not case.startswith("hecras"):
            continue
        for action in ("open", "snapshot", "import", "sample_lazy_source", "sample_flow_file"):
            if action not in r:
                continue
            m = r[action]
            note = ""
            if action == "open":
                note = f"{m['faces']} mesh faces, {m['snapshots']} snapshots"
            if action == "snapshot":
                note = f"one snapshot read in {m['read_one_s']:.3f} s"
            if action == "import":
                note = f"flow file {m['output_bytes'] / 1e6:.1f} MB"
            if action.startswith("sample"):
                note = (f"1e5 points, {m['intervals']} intervals: "
                        f"{m['per_interval_s']:.3f} s per interval, "
                        f"{m['points_per_s']:.3g} points/s")
            lines.append(f"| {case} | {action} | {m['seconds']:.2f} | "
                         f"{m['peak_rss_mb']:.0f} | {note} |")
        lines.append(f"| {case} | machine | | | {r.get('machine', '')} |")
    return "\n".join(lines) + "\n"


def report(res):
    lines = [f"Machine: {res['machine']}. {res['cells']:.0e} cells / faces. Each step in a "
             "fresh process; peak memory is its maximum resident set size (Python, numpy, "
             "numba included).",
             "", "| source | step | time (s) | peak memory (MB) | notes |",
             "| --- | --- | ---: | ---: | --- |"]
    for case, r in res["cases"].items():
        for action in ("open", "snapshot", "import"):
            if action not in r:
                continue
            m = r[action]
            note = ""
            if action == "snapshot":
                note = f"one snapshot read in {m['read_one_s']:.2f} s"
            if action == "import":
                note = (f"{m['snapshots']} snapshots, flow file "
                        f"{m['output_bytes'] / 1e6:.0f} MB")
            lines.append(f"| {case} | {action} | {m['seconds']:.1f} | {m['peak_rss_mb']:.0f} | "
                         f"{note} |")
    u = res["cases"].get("ugrid", {})
    if "sample_lazy_source" in u:
        lines += ["", "Sampling 1e5 points, 4 times per snapshot interval, each interval "
                      "loading one new snapshot (1e6 faces):", "",
                  "| sampled from | intervals | time per interval (s) | points/s |",
                  "| --- | ---: | ---: | ---: |"]
        for k, label in (("sample_lazy_source", "UGRID map file, lazily"),
                         ("sample_flow_file", "converted driftlog flow file")):
            m = u[k]
            lines.append(f"| {label} | {m['intervals']} | {m['per_interval_s']:.2f} | "
                         f"{m['points_per_s']:.3g} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
