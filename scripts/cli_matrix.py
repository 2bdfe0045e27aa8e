"""The command-line matrix: each ``driftlog`` command that takes a file, on one file of each kind.

Every cell runs ``python -m driftlog ...`` in a fresh interpreter, so that nothing imported by
an earlier cell (the readers of ``driftlog.adapters`` register what ``driftlog.files.sniff``
knows when they are imported) can hide a fault; the files are written first, in this process,
with the tests' own writers (tests/test_adapters_*.py) into a scratch folder.

Files: one of each model's outputs (HEC-RAS geometry and plan, MIKE dfsu, Selafin, a GeoTIFF
series, a LISFLOOD-FP ASCII run, a D-Flow FM map file, an ANUGA .sww, a CF grid, an OpenFOAM
case when OpenFOAM is installed), a driftlog flow file, a trajectory file and the .partial of a
stopped run; and wrong ones: a UGRID mesh without a flow, a meshio mesh, a scenario, a text
file, an empty file, and the first half of each binary file.

Commands: info, import, export (.slf, .dfsu), plot, animate, vtk (with and without --flow),
compare (--flow a=FILE --flow b=FILE), track and scenario check on a scenario whose
``[flow] path`` is the file (source "auto", the reader's own kind, and "file"), track and solve
with the file given as the scenario, ``track --resume`` and ``solve --resume`` with the file
where the ``.partial`` is.

A cell passes when the command exits 0 where a result is expected, or exits 2 with one line
``driftlog: error: ...`` that names the file, where an error is expected; never a traceback,
never an error that calls a file one of driftlog's readers reads "of an unknown layout",
"binary" or "text", never a success where an error is expected.  The table printed gives
command x file -> status and the first line of stderr (or stdout).

Usage::

    python scripts/cli_matrix.py [--work /tmp/driftlog-matrix] [--only REGEX] [--jobs 2]

Run from the repository (it imports ``tests/``); the exit status is 1 if a cell failed.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"
HECRAS = ROOT.parent / "shared" / "data" / "hecras"

# phrases that misclassify a file one of driftlog's readers reads (in what the error says the
# file is: the text before its first "; ")
MISCLASSIFIED = ("unknown layout", "a binary file", "a text file that is not TOML", "not UTF-8",
                 "a directory that is not an OpenFOAM case", "not a readable NetCDF file")
# files known by their suffix: renamed to a .partial (the --resume cells) they are not known
BY_SUFFIX = ("geotiff", "lisflood", "mesh_file")
# refusals that are right: xarray-selafin writes whole seconds, OpenFOAM's times are 0.2 s apart
EXPECT = {("export .slf", "openfoam"): "error"}


@dataclass
class Item:
    """A file of the matrix."""

    name: str
    path: Path
    role: str  # model, flow, traj, partial, other, bad
    source: str = ""  # the reader's kind ([flow] source)
    options: dict = field(default_factory=dict)  # [flow.options] its reader needs
    results: bool = True  # holds a flow (a HEC-RAS geometry file does not)
    seed: tuple = (0.0, 0.0)  # a wet point
    times: tuple = (0.0, 1.0)  # start, end of a short run

    @property
    def readable(self) -> bool:
        """One of driftlog's readers reads it (an error must not misclassify it)."""
        return self.role in ("model", "flow", "traj", "partial") or self.name in ("mesh",
                                                                                "mesh_file")

    @property
    def flows(self) -> bool:
        """A flow can be read from it without options the command line cannot give."""
        return self.role in ("model", "flow") and self.results and not self.options


# ----------------------------------------------------------------------------- the files
def _tests_module(name):
    sys.path.insert(0, str(TESTS))
    try:
        return __import__(name)
    finally:
        sys.path.remove(str(TESTS))


def _seed(path, source, options):
    """A wet face centre and a short time window of a hydro source."""
    import numpy as np
    from driftlog.adapters import open_flow_source

    f = open_flow_source(source, path, **options)
    s = f.snapshot(0)
    h = np.where(np.hypot(s["u"], s["v"]) > 0, s["h"], 0.0)
    i = int(np.argmax(h))
    t0, t1 = float(f.times[0]), float(f.times[-1])
    return (float(f.mesh.face_x[i]), float(f.mesh.face_y[i])), (t0, t0 + min(t1 - t0, 60.0))


def make_files(work: Path) -> dict[str, Item]:
    """Write the matrix's files into ``work``; name -> Item."""
    import netCDF4
    from driftlog.adapters import import_flow
    from driftlog.adapters.openfoam_case import foam_available, foam_env

    data = TESTS / "data"
    items = {}

    def add(item):
        items[item.name] = item

    if (HECRAS / "Muncie.g05.hdf").is_file():
        add(Item("hecras_geom", HECRAS / "Muncie.g05.hdf", "model", "hecras", results=False))
        plan = HECRAS / "BaldEagleDamBrk.p18.hdf"
        opts = {"results": str(HECRAS / "BaldEagleDamBrk.p18.timeseries.hdf"),
                "bed": "min_water_surface"}
        add(Item("hecras_plan", plan, "model", "hecras", opts))
    add(Item("dfsu", _tests_module("test_adapters_mike").write_dfsu(work / "model.dfsu"),
             "model", "dfsu"))
    slf = work / "model.slf"
    _tests_module("test_adapters_selafin").write_slf(slf)
    add(Item("selafin", slf, "model", "selafin"))
    raster = _tests_module("test_adapters_raster")
    tif = raster.write_geotiff(work / "geotiff")
    add(Item("geotiff", tif / "depth_0.tif", "model", "raster"))
    add(Item("geotiff_dir", tif, "model", "raster"))
    add(Item("lisflood", raster.write_lisflood(work / "lisflood"), "model", "raster"))
    add(Item("ugrid", data / "ugrid" / "dflowfm_map.nc", "model", "ugrid"))
    add(Item("sww", data / "anuga" / "channel_centroids.sww", "model", "anuga"))
    add(Item("cfgrid", data / "cf_grid" / "lisflood.nc", "model", "cf_grid"))
    if foam_available():
        case = work / "squarebump"
        if not (case / "1").is_dir():
            shutil.rmtree(case, ignore_errors=True)
            shutil.copytree(data / "openfoam" / "squarebump", case)
            for cmd in ("blockMesh", "setFields", "shallowWaterFoam"):
                subprocess.run([cmd, "-case", str(case)], env=foam_env(), check=True,
                               capture_output=True, timeout=600)
        add(Item("openfoam", case, "model", "openfoam"))
    flow = work / "flow.nc"
    if not flow.is_file():
        import_flow(data / "ugrid" / "dflowfm_map.nc", flow)
    add(Item("flow", flow, "flow", "file"))
    for it in items.values():
        if it.results:
            it.seed, it.times = _seed(it.path, it.source, it.options)
    if "hecras_plan" in items and "hecras_geom" in items:
        items["hecras_geom"].seed = items["hecras_plan"].seed  # (not the same place)

    # a trajectory file and the .partial of a stopped run, on the flow file
    scen = write_scenario(work / "scenarios" / "flow.toml", items["flow"], "file",
                          out=work / "traj.nc")
    traj = work / "traj.nc"
    if not traj.is_file():
        run_driftlog(["track", str(scen), "-o", str(traj), "--quiet"], check=True)
    add(Item("traj", traj, "traj", seed=items["flow"].seed, times=items["flow"].times))
    partial = work / "stopped.nc.partial"
    if not partial.is_file():
        _stop(scen, work / "stopped.nc")
    add(Item("partial", partial, "partial", seed=items["flow"].seed,
             times=items["flow"].times))

    # wrong ones
    from driftlog.flowfile import write_mesh
    from driftlog.mesh import Mesh

    m = Mesh.regular_grid(4, 3, 1.0)
    mesh = work / "mesh.nc"
    with netCDF4.Dataset(mesh, "w") as ds:
        write_mesh(ds, m)
    add(Item("mesh", mesh, "other"))
    import meshio

    vtu = work / "mesh.vtu"
    meshio.write(vtu, meshio.Mesh(list(zip(m.node_x, m.node_y, 0 * m.node_x, strict=True)),
                                  [("quad", m.face_nodes)]))
    add(Item("mesh_file", vtu, "other"))
    add(Item("scenario", scen, "other"))
    text = work / "notes.txt"
    text.write_text("a flood, some logs\n")
    add(Item("text", text, "other"))
    empty = work / "empty.nc"
    empty.write_bytes(b"")
    add(Item("empty", empty, "bad"))
    for name in ("hecras_plan", "dfsu", "selafin", "geotiff", "ugrid", "sww", "cfgrid", "flow",
                 "traj", "partial"):
        if name not in items:
            continue
        src = items[name].path
        cut = work / "truncated" / src.name
        if name == "geotiff":  # the series with its first depth raster cut
            shutil.rmtree(cut.parent.parent / "truncated_geotiff", ignore_errors=True)
            shutil.copytree(src.parent, cut.parent.parent / "truncated_geotiff")
            cut = cut.parent.parent / "truncated_geotiff" / src.name
        cut.parent.mkdir(exist_ok=True)
        b = src.read_bytes()
        cut.write_bytes(b[:len(b) // 2])
        add(Item(f"cut_{name}", cut, "bad"))
    return items


def _stop(scen, out):
    """A run of ``scen`` stopped after its first records: its .partial file."""
    from driftlog.api import track
    from driftlog.tracker import Tracker

    real, n = Tracker._record, [0]

    def stop(self):
        n[0] += 1
        if n[0] > 2:
            raise KeyboardInterrupt
        real(self)

    Tracker._record = stop
    try:
        track(str(scen), output=out)
    except KeyboardInterrupt:
        pass
    finally:
        Tracker._record = real


def write_scenario(path: Path, item: Item, source: str, out=None, seed_from=None) -> Path:
    """A short tracer run of one small log on ``item`` read as ``source``."""
    seed = (seed_from or item)
    (x, y), (t0, t1) = seed.seed, seed.times
    opts = "".join(f"{k} = {v!r}\n" for k, v in item.options.items())
    text = textwrap.dedent(f"""\
        title = "matrix: {item.name} as {source}"
        [flow]
        source = "{source}"
        path = "{item.path}"
        """) + (f"[flow.options]\n{opts}" if opts and source != "file" else "") + \
        textwrap.dedent(f"""\
        [time]
        start = {t0!r}
        end = {t1!r}
        output_interval = {max((t1 - t0) / 4, 1e-3)!r}
        [[logs]]
        x = [{x!r}]
        y = [{y!r}]
        length = 0.05
        radius = 0.005
        density = 500.0
        [physics]
        level = "tracer"
        [output]
        path = "{out or path.with_suffix('.nc')}"
        """)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


SOLVER = """\
title = "matrix: a tiny solver run"
[flow]
source = "solver"
path = "{flow}"
[solver]
mesh = "channel"
channel = [0.0, 0.0, 20.0, 4.0]
cell_size = 2.0
end = 2.0
output_interval = 1.0
[solver.initial]
type = "level"
value = 1.0
[time]
end = 2.0
[[logs]]
x = [5.0]
y = [2.0]
[physics]
level = "tracer"
"""


# ----------------------------------------------------------------------------- the cells
@dataclass
class Cell:
    """One command on one file."""

    command: str
    item: Item
    argv: list
    expect: str  # "ok", "error" or "either"
    must: tuple = ()  # phrases the error must hold (any of them)
    prepare: object = None  # run before the command (puts a .partial in place)


def run_driftlog(argv, check=False, timeout=900):
    """``python -m driftlog ARGV`` in a fresh interpreter (this checkout first on the path)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-m", "driftlog", *map(str, argv)], capture_output=True,
                         text=True, env=env, timeout=timeout, cwd=ROOT)
    if check and out.returncode != 0:
        raise RuntimeError(f"driftlog {' '.join(map(str, argv))}: {out.stderr[-3000:]}")
    return out


def cells(items: dict[str, Item], work: Path) -> list[Cell]:
    """Every command on every file, each with what it must give."""
    out = []
    scen_dir = work / "scenarios"
    o = work / "out"
    flow = items["flow"]
    solver = work / "scenarios" / "solver.toml"
    solver.write_text(SOLVER.format(flow=o / "solver_flow.nc"))
    for it in items.values():
        n = it.name
        d = o / n
        first = len(out)
        model = it.role in ("model", "flow")
        trajs = it.role in ("traj", "partial")
        out.append(Cell("info", it, ["info", it.path],
                        "ok" if it.role != "bad" and it.name != "text" else "error"))
        imp = ["import", it.path, "-o", d / "import.nc"]
        for k, v in it.options.items():
            imp += ["--option", f"{k}={v}"]
        out.append(Cell("import", it, imp, "ok" if model and it.results else "error"))
        for suffix in ("slf", "dfsu"):
            out.append(Cell(f"export .{suffix}", it, ["export", it.path, "-o",
                                                      d / f"export.{suffix}"],
                            "ok" if it.flows else "error",
                            must=("results",) if it.options else ()))
        out.append(Cell("plot", it, ["plot", it.path, "-o", d / "plot.png"],
                        "ok" if trajs else "error"))
        out.append(Cell("animate", it, ["animate", it.path, "-o", d / "anim.gif", "--fps", "4"],
                        "ok" if trajs else "error"))
        out.append(Cell("vtk", it, ["vtk", it.path, "--out", d / "vtk"],
                        "ok" if trajs else "error"))
        out.append(Cell("vtk --flow", it, ["vtk", it.path, "--flow", "--out", d / "vtkflow"],
                        "ok" if trajs or it.flows else "error"))
        # a scenario on this file as its flow (logs at the flow file's seed if it has none)
        seed = it if it.results and model else flow
        auto = write_scenario(scen_dir / f"{n}.auto.toml", it, "auto", out=d / "auto.nc",
                              seed_from=seed)
        good = "ok" if model and it.results else "error"
        out.append(Cell("compare", it, ["compare", auto, "--flow", f"a={it.path}", "--flow",
                                        f"b={it.path}", "--out", d / "compare"],
                        "ok" if it.flows else "error"))
        out.append(Cell("scenario check", it, ["scenario", "check", auto], good))
        out.append(Cell("track auto", it, ["track", auto, "-o", d / "auto.nc", "--quiet"], good))
        if it.source and it.source != "file":
            own = write_scenario(scen_dir / f"{n}.own.toml", it, it.source, out=d / "own.nc",
                                 seed_from=seed)
            out.append(Cell("track own", it, ["track", own, "-o", d / "own.nc", "--quiet"], good))
        as_file = write_scenario(scen_dir / f"{n}.file.toml", it, "file", out=d / "file.nc",
                                 seed_from=seed)
        out.append(Cell("track file", it, ["track", as_file, "-o", d / "file.nc", "--quiet"],
                        "ok" if it.role == "flow" else "error",
                        must=("auto", "import") if it.role == "model" else ()))
        # the file given where a scenario is expected
        if n != "scenario":
            out.append(Cell("track FILE", it, ["track", it.path, "-o", d / "t.nc", "--quiet"],
                            "error"))
            out.append(Cell("scenario check FILE", it, ["scenario", "check", it.path], "error"))
            out.append(Cell("solve FILE", it, ["solve", it.path, "-o", d / "s.nc", "--quiet"],
                            "error"))
        # the file where a stopped run's .partial is
        fscen = scen_dir / "flow.toml"
        if it.path.is_file():
            res = d / "resume" / "traj.nc"
            out.append(Cell("track --resume", it, ["track", fscen, "-o", res, "--resume",
                                                   "--quiet"],
                            "ok" if n == "partial" else "error",
                            prepare=_put_partial(it.path, res)))
            sres = d / "resume" / "solved.nc"
            out.append(Cell("solve --resume", it, ["solve", solver, "-o", sres, "--resume",
                                                   "--quiet"], "error",
                            prepare=_put_partial(it.path, sres)))
        for c in out[first:]:
            c.expect = EXPECT.get((c.command, n), c.expect)
    return out


def _put_partial(src, out):
    def put():
        p = Path(str(out) + ".partial")
        p.parent.mkdir(parents=True, exist_ok=True)
        for f in p.parent.glob(Path(out).name + "*"):
            f.unlink()
        shutil.copy(src, p)
    return put


# ----------------------------------------------------------------------------- judging
def judge(cell: Cell, rc: int, stdout: str, stderr: str) -> tuple[str, str]:
    """(status, why): PASS ok / PASS refused, or FAIL and the reason."""
    if "Traceback (most recent call last)" in stderr:
        last = [ln for ln in stderr.strip().splitlines() if ln.strip()][-1]
        return "FAIL", f"traceback: {last}"
    errors = [ln for ln in stderr.splitlines() if ln.startswith("driftlog: error:")]
    if rc == 0:
        if cell.expect == "error":
            return "FAIL", "exit 0 where an error was expected"
        return "ok", ""
    if rc != 2:
        return "FAIL", f"exit status {rc}"
    if len(errors) != 1:
        return "FAIL", f"{len(errors)} error lines"
    err = errors[0]
    names = {str(cell.item.path), cell.item.path.name}  # or the output it is about
    names |= {str(a) for a in cell.argv if isinstance(a, Path)}
    if not any(s in err for s in names) and cell.command not in ("solve --resume",
                                                                 "track --resume"):
        return "FAIL", "the error does not name the file"
    what = err.split("; ")[0]
    resumed = cell.command.endswith("--resume") and cell.item.name in BY_SUFFIX
    if cell.item.readable and not resumed and any(p in what for p in MISCLASSIFIED):
        return "FAIL", "misclassified"
    if cell.must and not any(p in err for p in cell.must):
        return "FAIL", f"the error does not say {' or '.join(cell.must)}"
    if cell.expect == "ok":
        return "FAIL", "refused where a result was expected"
    return "refused", ""


def run_cell(cell: Cell):
    """Run one cell; (cell, status, why, exit status, line shown, seconds, stderr)."""
    if cell.prepare is not None:
        cell.prepare()
    t0 = time.perf_counter()
    try:
        out = run_driftlog(cell.argv)
        rc, so, se = out.returncode, out.stdout, out.stderr
    except subprocess.TimeoutExpired:
        rc, so, se = -1, "", "timed out"
    status, why = judge(cell, rc, so, se)
    first = next((ln for ln in se.splitlines() if ln.startswith("driftlog: error:")), "") or \
        next((ln for ln in (so + se).splitlines() if ln.strip()), "")
    return cell, status, why, rc, first, time.perf_counter() - t0, se


def main(argv=None) -> int:
    """Write the files, run the cells, print the table; 1 if a cell failed."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", default="/tmp/driftlog-matrix", help="scratch folder")
    ap.add_argument("--only", help="run the cells whose 'command file' matches this regex")
    ap.add_argument("--jobs", type=int, default=2, help="cells run at once")
    ap.add_argument("--width", type=int, default=150, help="characters of the first line shown")
    ap.add_argument("--log", help="write every cell's full stderr to this file")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import driftlog  # noqa: F401 - the adapters' finder

    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    items = make_files(work)
    print(f"files written in {time.perf_counter() - t0:.0f} s: "
          + ", ".join(f"{k} ({v.path})" for k, v in items.items()), flush=True)
    todo = cells(items, work)
    if args.only:
        todo = [c for c in todo if re.search(args.only, f"{c.command} {c.item.name}")]
    shutil.rmtree(work / "out", ignore_errors=True)
    results = []
    with ThreadPoolExecutor(max(1, args.jobs)) as pool:
        for r in pool.map(run_cell, todo):
            cell, status, why, rc, first, dt, _ = r
            results.append(r)
            mark = "FAIL" if status == "FAIL" else "pass"
            print(f"{mark} {cell.command:<20} {cell.item.name:<13} {status:<7} rc={rc:<3} "
                  f"{dt:5.1f}s {why + ': ' if why else ''}{first[:args.width]}", flush=True)
    failed = [r for r in results if r[1] == "FAIL"]
    if args.log:
        with open(args.log, "w") as f:
            for cell, status, why, rc, _, _, se in results:
                f.write(f"=== {cell.command} {cell.item.name} {status} {why} rc={rc}\n"
                        f"$ driftlog {' '.join(map(str, cell.argv))}\n{se}\n")
    print(f"\n{len(results)} cells, {len(failed)} failed, {time.perf_counter() - t0:.0f} s")
    for cell, _, why, _, first, _, _ in failed:
        print(f"  FAIL {cell.command} {cell.item.name}: {why}: {first[:args.width]}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
