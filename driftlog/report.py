"""``driftlog report``: re-create every validation and benchmark result in one go.

Each item is a script of ``benchmarks/`` that writes its tables and figures under
``benchmarks/results/``; the report runs them one after the other (each in its own process,
its output logged), then writes ``benchmarks/results/REPORT.md`` gathering the tables and
figures the README shows.  Scripts that are not there are skipped with a note.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from driftlog.errors import DriftlogError

__all__ = ["ITEMS", "run_report", "benchmarks_dir"]

# name, script, arguments for --quick, what it shows
ITEMS = [
    ("integrators", "integrator_convergence.py", [],
     "integrators against exact solutions: orders, work-precision, stiff drag failure"),
    ("sampling", "sampling_benchmark.py", ["--quick"],
     "point location and flow sampling throughput"),
    ("tracking", "tracking_benchmark.py", ["--quick"], "tracking throughput (log-steps/s)"),
    ("peers", "peers_tracking.py", ["--quick"], "tracer mode vs OpenDrift and Parcels"),
    ("tracer_peers", "tracer_peers.py", ["--quick"],
     "tracer mode vs OceanTracker and Parcels 4 on a triangle mesh"),
    ("swashes", "swashes_validation.py", ["--quick"],
     "shallow-water solver against SWASHES exact solutions"),
    ("malpasset", "malpasset.py", ["--quick"], "the Malpasset dam break against observations"),
    ("solver", "solver_throughput.py", ["--quick"], "solver throughput and peers"),
    ("shallow_water_peers", "solver_peers.py", ["--quick"],
     "the solver beside ANUGA and shallowWaterFoam: same meshes, wall time and error"),
    ("openfoam_engines", "openfoam_engines.py", ["--quick"],
     "river_piers on driftlog's solver and shallowWaterFoam: cost, flows, the logs' fates"),
    ("interfoam_channel", "interfoam_channel.py", ["--quick"],
     "the 3D route: interFoam depth-averaged against driftlog's solver"),
    ("contact", "contact_benchmark.py", ["--quick"], "contact detection and contact times"),
    ("coupling", "coupling_validation.py", ["--only", "intervals"],
     "two-way coupling: backwater against the momentum balance, jams, exchange intervals"),
    ("ensemble", "ensemble_benchmark.py", ["--quick"], "ensembles on Dask: members per minute"),
    ("import", "import_benchmark.py", ["--snapshots", "10", "--skip-openfoam"],
     "importing flows from other models"),
    ("grid_peers", "grid_peers.py", ["--quick"],
     "regular grids: bilinear sampling beside Parcels (error, CPU time, sampling speed)"),
    ("import_raster", "raster_import_benchmark.py", ["--quick"],
     "importing regular grids: GeoTIFF series, LISFLOOD-FP ASCII, CF grid"),
    ("stability", "stability_figures.py", ["--quick"],
     "stability where methods fail (stiff drag, jams, dry fronts) and the remedies"),
    ("compile_times", "compile_times.py",
     ["--tests", "tests/test_fused.py::test_steady_vortex_on_a_mesh_rk4_bit_for_bit"],
     "compile time from an empty numba cache, numba's inliner against driftlog's"),
]


def benchmarks_dir() -> Path:
    """The repository's ``benchmarks`` folder (DriftlogError outside a checkout)."""
    d = Path(__file__).resolve().parents[1] / "benchmarks"
    if not d.is_dir():
        raise DriftlogError(f"benchmarks folder not found at {d}: driftlog report runs from a "
                            "checkout of the repository")
    return d


def run_report(only=None, quick=False, echo=print):
    """Run the report's scripts (all, or those named in ``only``); returns {name: status}."""
    bdir = benchmarks_dir()
    results = bdir / "results"
    logs = results / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    names = [i[0] for i in ITEMS]
    for n in only or ():
        if n not in names:
            raise DriftlogError(f"driftlog report: unknown item {n!r}; items: {', '.join(names)}")
    status = {}
    for name, script, quick_args, what in ITEMS:
        if only and name not in only:
            continue
        path = bdir / script
        if not path.is_file():
            status[name] = "skipped (script not there)"
            echo(f"- {name}: skipped, {script} not found")
            continue
        args = [sys.executable, str(path)] + (quick_args if quick else [])
        echo(f"- {name}: {what} ... ", end="") if echo is print else echo(name)
        t0 = time.perf_counter()
        with open(logs / f"{name}.log", "w") as log:
            rc = subprocess.run(args, cwd=bdir, stdout=log, stderr=subprocess.STDOUT).returncode
        dt = time.perf_counter() - t0
        status[name] = "ok" if rc == 0 else f"failed (exit {rc}, see results/logs/{name}.log)"
        if echo is print:
            print(f"{status[name]} in {dt:.0f} s")
    _write_index(results, status)
    return status


def _write_index(results: Path, status: dict):
    lines = ["# driftlog: validation and benchmark report", "",
             "Re-created by `driftlog report` (each item: `python benchmarks/<script>`).", ""]
    for name, script, _, what in ITEMS:
        lines.append(f"## {name}: {what}")
        lines.append("")
        lines.append(f"Script `benchmarks/{script}`; last run: {status.get(name, 'not run now')}.")
        lines.append("")
        stems = {name, Path(script).stem, Path(script).stem.replace("_benchmark", "")}
        for md in sorted(results.glob("*.md")):
            if md.stem in stems or any(md.stem.startswith(s) for s in stems):
                if md.name != "REPORT.md":
                    lines.append(md.read_text().replace("### ", "#### "))
        for png in sorted(results.glob("*.png")):
            if any(png.stem.startswith(s) for s in stems):
                lines.append(f"![{png.stem}]({png.name})")
        lines.append("")
    (results / "REPORT.md").write_text("\n".join(lines) + "\n")
