"""The ``driftlog`` command: one entry point, one subcommand per task.

Each subcommand is a pair: ``add_<name>(subparsers)`` declares its arguments (with an example
in its help), ``cmd_<name>(args)`` runs it.  Errors about user input (``DriftlogError``) print
one clear line and exit with status 2; anything else is a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from driftlog._version import __version__
from driftlog.errors import DriftlogError

__all__ = ["main", "build_parser"]

COMMANDS = []  # (add function, run function)
_default_showwarning = None


def command(add):
    """Register a subcommand from its parser builder; the builder's ``cmd`` runs it."""
    COMMANDS.append(add)
    return add


def _formatter(prog):
    return argparse.RawDescriptionHelpFormatter(prog, max_help_position=32)


def _sub(sub, name, help, example, description=None):
    p = sub.add_parser(name, help=help, description=(description or help),
                       epilog=f"example:\n  {example}", formatter_class=_formatter)
    return p


# --------------------------------------------------------------------- scenario, info
@command
def add_scenario(sub):
    p = _sub(sub, "scenario", "list the scenario keys, or check a scenario file (every check "
             "a run makes before it starts: flow readable, logs inside the mesh, obstacles)",
             "driftlog scenario check cases/vortex/scenario.toml")
    p.add_argument("action", choices=("keys", "check"), help="keys: print every key with its "
                   "type, default, units and rule; check: validate a file")
    p.add_argument("file", nargs="?", help="scenario file (for check)")
    p.add_argument("--section", help="only this section (for keys)")
    p.set_defaults(run=cmd_scenario)


def cmd_scenario(args):
    from driftlog.scenario import describe_keys, load_scenario

    if args.action == "keys":
        print(describe_keys(args.section))
        return 0
    if not args.file:
        raise DriftlogError("driftlog scenario check: give the scenario file to check")
    from driftlog.preflight import check_scenario

    path, name = _scenario_path(args.file)
    scen = load_scenario(path, _case_overrides(path, name) or None)
    output = Path("driftlog-runs") / name / Path(scen["output"]["path"]).name \
        if _in_cases(path) else None  # where driftlog track writes
    from driftlog.api import logs_from_scenario
    from driftlog.preflight import estimate_run

    estimate_run(scen, output)  # before seeding: 1e7 logs are refused, not allocated
    notes, done = check_scenario(scen, logs_from_scenario(scen), output=output)
    for n in notes:
        print(f"driftlog: warning: {n}", file=sys.stderr)
    print(f"{path}: valid: the run will start ({len(scen['logs'])} log groups, flow source "
          f"{scen['flow']['source']!r})")
    for d in done:
        print(f"  {d}")
    return 0


@command
def add_info(sub):
    p = _sub(sub, "info", "describe any file driftlog reads or writes: flow, trajectories (and "
             "their .partial), mesh, scenario, ensemble results, another model's output",
             "driftlog info flow.nc\n  driftlog info trajectories.nc.partial\n"
             "  driftlog info runs/squareBump      (an OpenFOAM case)")
    p.add_argument("file", help="a file, or an OpenFOAM case directory")
    p.set_defaults(run=cmd_info)


def cmd_info(args):
    from driftlog.info import describe

    print(describe(args.file))
    return 0


# --------------------------------------------------------------------- tracking
def _overrides(pairs):
    """--set physics.level=tracer --set time.end=100: a nested dict for load_scenario."""
    import tomllib

    out = {}
    for pair in pairs or ():
        if "=" not in pair:
            raise DriftlogError(f"--set {pair!r}: expected SECTION.KEY=VALUE")
        key, value = pair.split("=", 1)
        try:
            value = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            pass  # a bare word: a string
        node = out
        parts = key.strip().split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return out


def _scenario_path(name):
    from driftlog.api import find_case

    if name is None:
        from driftlog.api import cases_dir

        default = "river_piers" if (cases_dir() / "river_piers" / "scenario.toml").is_file() \
            else "vortex"
        return find_case(default), default
    p = Path(name)
    if p.is_dir() and (p / "scenario.toml").is_file():
        p = p / "scenario.toml"
    if p.suffix == ".toml" or p.exists():
        from driftlog.files import read_text

        read_text(p, "scenario file")  # missing, a directory, empty, binary, not UTF-8
        return p, p.stem if p.stem != "scenario" else p.resolve().parent.name
    return find_case(name), name


def _add_set(p):
    p.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                   help="override a scenario value (repeatable), e.g. --set physics.level=tracer")


@command
def add_run(sub):
    p = _sub(sub, "run", "run a scenario end to end: flow (solved or imported if needed), "
             "tracking, a figure and an animation",
             "driftlog run                       # the default demo scene\n"
             "  driftlog run vortex --out runs/v   # a case by name\n"
             "  driftlog run my_scenario.toml --set physics.level=tracer")
    p.add_argument("scenario", nargs="?", help="scenario file or case name (default: the demo)")
    p.add_argument("--out", help="output folder (default: driftlog-runs/<name>)")
    p.add_argument("--no-figure", action="store_true", help="skip the figure")
    p.add_argument("--no-animation", action="store_true", help="skip the animation")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_set(p)
    p.set_defaults(run=cmd_run)


def cmd_run(args):
    from driftlog.api import as_scenario, track
    from driftlog.plots import animate, plot_trajectories

    path, name = _scenario_path(args.scenario)
    from driftlog.files import check_output_dir

    out = check_output_dir(Path(args.out or Path("driftlog-runs") / name), "run folder")
    scen = as_scenario(path, _case_overrides(path, name, _overrides(args.set)))
    print(f"driftlog: running {path}")
    res = track(scen, output=out / "trajectories.nc", progress=not args.quiet)
    flow = _flow_file(scen)
    if flow is not None and flow.exists():
        print(f"  flow: {flow}")
    print(f"  trajectories: {res.path}")
    for f in res.extra_files:
        print(f"  ParaView: {f}")
    if not args.no_figure:
        fig = out / "trajectories.png"
        plot_trajectories(res.path, out=fig)
        print(f"  figure: {fig}")
    if not args.no_animation:
        anim = animate(res.path, out / "animation.mp4")
        print(f"  animation: {anim}")
    s = res.stats
    print(f"  {len(res.logs)} logs, {s['substeps']} sub-steps in {s['wall_seconds']:.2f} s; "
          f"physics {res.physics['level']}" + (f" ({res.physics['reason']})"
                                               if res.physics["reason"] else ""))
    return 0


@command
def add_track(sub):
    p = _sub(sub, "track", "track the logs of a scenario on its flow (an existing flow file, "
             "an imported model output or an analytic field)",
             "driftlog track scenario.toml -o trajectories.nc")
    p.add_argument("scenario", help="scenario file or case name")
    p.add_argument("-o", "--output", help="trajectory file (default: the scenario's output.path)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--resume", action="store_true",
                   help="continue a stopped run from its .partial file")
    _add_set(p)
    p.set_defaults(run=cmd_track)


def _in_cases(path) -> bool:
    """Whether a scenario file lies in the repository's cases/.

    Outputs then go to a run folder, so that running the shipped cases does not write into
    the clone.
    """
    from driftlog.api import cases_dir

    try:
        Path(path).resolve().relative_to(cases_dir().resolve())
        return True
    except (ValueError, DriftlogError):
        return False


def _case_overrides(path, name, over=None):
    """Overrides that keep a shipped case's outputs out of the clone.

    For a scenario in the repository's cases/ whose flow is computed by the solver, the flow
    file goes to the run folder ``driftlog-runs/<case>/`` (and is reused from there), not
    beside the scenario.
    """
    from driftlog.scenario import read_toml
    from driftlog.schema import merge

    over = dict(over or {})
    if not _in_cases(path) or "path" in over.get("flow", {}):
        return over
    flow = read_toml(path)[0].get("flow", {})
    solver = over.get("flow", {}).get("source", flow.get("source") if isinstance(flow, dict)
                                      else None) == "solver"
    if solver:
        name_ = Path((flow.get("path") if isinstance(flow, dict) else None)
                     or "solver_flow.nc").name
        run = (Path("driftlog-runs") / name / name_).resolve()
        over = merge(over, {"flow": {"path": str(run)}})
    return over


def _flow_file(scen):
    """The flow file a scenario reads or computes (None for an analytic flow)."""
    sec = scen["flow"]
    if sec["source"] == "solver":
        from driftlog.solver.config import _default_path

        return _default_path(scen)  # with the engine's suffix
    return Path(sec["path"]) if sec["source"] != "analytic" and sec["path"] else None


def cmd_track(args):
    from driftlog.api import as_scenario, track

    path, name = _scenario_path(args.scenario)
    scen = as_scenario(path, _case_overrides(path, name, _overrides(args.set)))
    output = args.output
    if output is None and _in_cases(path):
        output = Path("driftlog-runs") / name / Path(scen["output"]["path"]).name
    res = track(scen, output=output, progress=not args.quiet, resume=args.resume)
    flow = _flow_file(scen)
    if flow is not None and flow.exists():
        print(f"flow: {flow}")
    print(f"trajectories: {res.path}")
    for f in res.extra_files:
        print(f"ParaView: {f}")
    return 0


@command
def add_plot(sub):
    p = _sub(sub, "plot", "draw the trajectories of a trajectory file over the flow",
             "driftlog plot trajectories.nc -o trajectories.png --background depth")
    p.add_argument("file", help="trajectory file")
    p.add_argument("-o", "--output", help="PNG file (default: beside the trajectory file)")
    p.add_argument("--background", choices=("speed", "depth", "none"), default="speed")
    p.add_argument("--mesh", action="store_true", help="draw the mesh edges")
    p.add_argument("--time", type=float, help="time of the logs drawn to scale (default: last)")
    p.set_defaults(run=cmd_plot)


def cmd_plot(args):
    from driftlog.files import check_output, require
    from driftlog.plots import plot_trajectories

    require(args.file, ("trajectories", "partial"), "trajectory file")
    out = check_output(args.output or Path(args.file).with_suffix(".png"), "figure",
                       inputs=[args.file], suffixes=(".png", ".pdf", ".svg", ".jpg"))
    plot_trajectories(args.file, background=args.background, show_mesh=args.mesh, out=out,
                      time=args.time)
    print(f"figure: {out}")
    return 0


@command
def add_animate(sub):
    p = _sub(sub, "animate", "animate the logs of a trajectory file over the flow (MP4 with "
             "ffmpeg, else GIF)", "driftlog animate trajectories.nc -o logs.mp4")
    p.add_argument("file", help="trajectory file")
    p.add_argument("-o", "--output", help="MP4 or GIF file")
    p.add_argument("--background", choices=("speed", "depth", "none"), default="speed")
    p.add_argument("--fps", type=int, default=20)
    p.set_defaults(run=cmd_animate)


def cmd_animate(args):
    from driftlog.files import check_output, require
    from driftlog.plots import animate

    require(args.file, ("trajectories", "partial"), "trajectory file")
    if not args.fps > 0:
        raise DriftlogError(f"--fps {args.fps}: must be > 0 frames per second")
    out = check_output(args.output or Path(args.file).with_suffix(".mp4"), "animation",
                       inputs=[args.file], suffixes=(".mp4", ".gif"))
    out = animate(args.file, out, background=args.background, fps=args.fps)
    print(f"animation: {out}")
    return 0


@command
def add_vtk(sub):
    p = _sub(sub, "vtk", "write ParaView files: a .pvd time series of the logs of a trajectory "
             "file (radius as point data, for the Tube filter), and with --flow the flow on its "
             "mesh", "driftlog vtk trajectories.nc --out paraview/\n"
             "  driftlog vtk trajectories.nc --flow     (the logs and the flow they ran on)\n"
             "  driftlog vtk --flow flow.nc             (a flow file alone)")
    p.add_argument("file", help="trajectory file, or with --flow a flow file / model output")
    p.add_argument("--out", help="folder (default: beside the file)")
    p.add_argument("--flow", action="store_true", help="also (or, for a flow file, only) "
                   "export the flow: depth, velocity, level and bed on the mesh")
    p.set_defaults(run=cmd_vtk)


def cmd_vtk(args):
    from driftlog.files import sniff
    from driftlog.trajectory import write_flow_vtk, write_vtk

    kind = sniff(args.file).kind
    if args.flow and kind in ("flow", "model_output", "openfoam"):
        print(f"ParaView collection (flow): {write_flow_vtk(args.file, args.out)}")
        return 0
    pvd = write_vtk(args.file, args.out)
    print(f"ParaView collection (logs): {pvd}")
    if args.flow:
        from driftlog.trajectory import open_trajectories

        src = open_trajectories(args.file).attrs.get("flow_source", "")
        if not Path(src).exists():
            raise DriftlogError(f"{args.file}: its flow ({src or 'not named'}) is not a file "
                                "that can be exported (an analytic flow has no mesh)")
        print(f"ParaView collection (flow): {write_flow_vtk(src, pvd.parent / 'flow')}")
    return 0


@command
def add_cases(sub):
    p = _sub(sub, "cases", "list the scenes in cases/, or run one",
             "driftlog cases list\n  driftlog cases run vortex")
    p.add_argument("action", choices=("list", "run"))
    p.add_argument("name", nargs="?", help="case to run")
    p.add_argument("--out", help="output folder (default: driftlog-runs/<name>)")
    p.set_defaults(run=cmd_cases)


def cmd_cases(args):
    from driftlog.api import cases_dir

    if args.action == "list":
        for d in sorted(cases_dir().iterdir()):
            scen = d / "scenario.toml"
            if scen.is_file():
                import tomllib

                title = tomllib.loads(scen.read_text()).get("title", "")
                print(f"{d.name:<14} {title}")
        return 0
    if not args.name:
        raise DriftlogError("driftlog cases run: give the case name (see driftlog cases list)")
    return cmd_run(argparse.Namespace(scenario=args.name, out=args.out, no_figure=False,
                                      no_animation=False, quiet=False, set=None))



# --------------------------------------------------------------------- solve
@command
def add_solve(sub):
    p = _sub(sub, "solve", "compute a flow with driftlog's shallow-water solver ([solver] "
             "section)", "driftlog solve scenario.toml -o flow.nc\n  driftlog solve "
             "scenario.toml -o flow.nc --resume     (continue a stopped run)")
    p.add_argument("scenario", help="scenario file with a [solver] section")
    p.add_argument("-o", "--output", help="flow file to write (default: [flow] path, or "
                   "solver_flow.nc beside the scenario)")
    p.add_argument("--resume", action="store_true", help="continue from the last snapshot "
                   "of the output file")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=cmd_solve)


def cmd_solve(args):
    from driftlog.scenario import load_scenario, read_toml
    from driftlog.solver import solve_scenario

    path, name = _scenario_path(args.scenario)
    raw = read_toml(path)[0]
    if "solver" not in raw:
        raise DriftlogError(f"{path}: has no [solver] section: driftlog solve computes the flow "
                            "that [solver] describes (mesh, bed, boundaries, end time); "
                            "driftlog scenario keys --section solver lists its keys")
    scen = load_scenario(path, overrides=_case_overrides(path, name,
                                                         {"flow": {"source": "solver"}}))
    res, path = solve_scenario(scen, output=args.output, resume=args.resume,
                               progress=not args.quiet)
    print(f"flow file: {path}")
    print(res.summary())
    return 0


# --------------------------------------------------------------------- import
@command
def add_import(sub):
    p = _sub(sub, "import", "convert another model's flow to a driftlog flow file",
             "driftlog import runs/squareBump -o flow.nc --time-range 0 60\n"
             "  driftlog import FlowFM_map.nc -o flow.nc --var depth=mesh2d_waterdepth\n"
             "  driftlog import damBreak3d -o flow.nc --option raster=0,0,0.1,6,2",
             description="Read a hydro source (OpenFOAM case, UGRID / D-Flow FM map file, "
                         "ANUGA .sww, CF grid NetCDF such as LISFLOOD-FP's, TELEMAC Selafin, "
                         "MIKE 21 FM dfsu) and write it as a "
                         "driftlog flow file (UGRID-1.0 + CF), snapshot by snapshot.  The "
                         "format is detected from the source unless --format is given.")
    p.add_argument("source", help="file, or OpenFOAM case directory")
    p.add_argument("-o", "--output", required=True, help="flow file to write (.nc)")
    p.add_argument("--format", "--kind", dest="format", default="auto",
                   help="the source's format: auto (detected), or the kind of a reader of "
                   "driftlog.adapters (file, openfoam, ugrid, anuga, cf_grid, selafin, dfsu...)")
    p.add_argument("--time-range", nargs=2, type=float, metavar=("START", "END"),
                   help="only the snapshots in [START, END] (s)")
    p.add_argument("--var", action="append", default=[], metavar="NAME=VARIABLE",
                   help="map a driftlog name (depth, level, bed, u, v, hu, hv, alpha) to the "
                        "source's variable; repeatable")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="importer option (decomposed=true, mode=vof, raster=x0,y0,dx,nx,ny, "
                        "fill=dry, units.hu=m3 s-1...); repeatable")
    p.add_argument("--dry-depth", type=float, default=1e-3, help="dry below this depth (m)")
    p.add_argument("--no-compress", action="store_true", help="write without zlib compression")
    p.set_defaults(run=cmd_import)


def _parse_pairs(pairs, what):
    import json

    out = {}
    for item in pairs:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise DriftlogError(f"driftlog import: {what} {item!r} must be KEY=VALUE")
        try:
            val = json.loads(value)
        except ValueError:
            val = value
            if "," in value:
                try:
                    val = [json.loads(v) for v in value.split(",")]
                except ValueError:
                    val = value
        if "." in key:  # units.hu=m3 s-1 -> {"units": {"hu": "m3 s-1"}}
            head, _, tail = key.partition(".")
            out.setdefault(head, {})[tail] = val
        else:
            out[key] = val
    return out


def cmd_import(args):
    import time

    from tqdm import tqdm

    from driftlog.adapters import import_flow

    variables = {k: str(v) for k, v in _parse_pairs(args.var, "--var").items()}
    options = _parse_pairs(args.option, "--option")
    t0 = time.perf_counter()
    bar = None

    def progress(i, n):
        nonlocal bar
        if bar is None:
            bar = tqdm(total=n, unit="snapshot", disable=n < 3, file=sys.stderr)
        bar.update(1)

    try:
        out, field = import_flow(args.source, args.output, kind=args.format,
                                 compress=not args.no_compress, progress=progress,
                                 time_range=args.time_range, variables=variables,
                                 dry_depth=args.dry_depth, **options)
    finally:
        if bar is not None:
            bar.close()
    print(f"{args.source} -> {out} ({time.perf_counter() - t0:.1f} s)")
    print(f"  {field.attrs.get('source', '')}: {field.mesh}")
    print(f"  {field.times.size} snapshots from {field.times[0]:g} to {field.times[-1]:g} s")
    for note in filter(None, str(field.attrs.get("import_notes", "")).split("; ")):
        print(f"  note: {note}")
    return 0


@command
def add_export(sub):
    p = _sub(sub, "export", "write a flow as another model's result file (TELEMAC Selafin, "
             "MIKE 21 FM dfsu)",
             "driftlog export flow.nc -o flow.slf\n  driftlog export flow.nc -o flow.dfsu",
             description="Read a flow (any source driftlog reads) and write it with the "
                         "format's own library: Selafin with xarray-selafin (the node values "
                         "driftlog's sampler interpolates), dfsu with mikeio (face values, "
                         "float32).  The format follows the output's suffix unless --format "
                         "is given.")
    p.add_argument("source", help="flow file, or any hydro source driftlog reads")
    p.add_argument("-o", "--output", required=True, help="file to write (.slf or .dfsu)")
    p.add_argument("--format", choices=("selafin", "dfsu"), default=None,
                   help="output format (default: from the suffix: .slf/.srf/.sel/.res "
                        "selafin, .dfsu dfsu)")
    p.add_argument("--precision", choices=("single", "double"), default="single",
                   help="Selafin precision (default single, TELEMAC's SERAFIN)")
    p.set_defaults(run=cmd_export)


def cmd_export(args):
    from driftlog.adapters import mike, open_flow_source, selafin

    out = Path(args.output)
    fmt = args.format
    if fmt is None:
        if out.suffix.lower() in selafin.SUFFIXES:
            fmt = "selafin"
        elif out.suffix.lower() in mike.SUFFIXES:
            fmt = "dfsu"
        else:
            raise DriftlogError(f"{out}: format not known from the suffix {out.suffix!r}: give "
                                "--format selafin or --format dfsu")
    field = open_flow_source("auto", args.source)
    try:
        if fmt == "selafin":
            selafin.write(field, out, precision=args.precision)
        else:
            mike.write(field, out)
    except OSError as exc:
        raise DriftlogError(f"{out}: cannot write the {fmt} file ({exc})") from None
    print(f"{args.source} -> {out} ({fmt}, {field.times.size} snapshots, "
          f"{field.mesh.n_faces} faces)")
    return 0


# --------------------------------------------------------------------- comparison
@command
def add_compare(sub):
    p = _sub(sub, "compare", "run the same debris scenario on two or more flows (hydro sources) "
             "and compare flows at the logs and trajectories; or compare two trajectory files",
             "driftlog compare scenario.toml --flow solver=flow.nc --flow foam=foam_case/ "
             "--out cmp/\n  driftlog compare scenario.toml --engines driftlog,shallowWaterFoam "
             "--gate bridge=600,0,600,170\n  driftlog compare run_a.nc run_b.nc")
    p.add_argument("inputs", nargs="+", help="a scenario (with --flow), or two trajectory files")
    p.add_argument("--flow", action="append", metavar="NAME=SOURCE",
                   help="a flow: flow file, model output (OpenFOAM case, UGRID, sww, CF grid) "
                   "or 'scenario' (the scenario's own); the first is the reference")
    p.add_argument("--engines", metavar="E1,E2",
                   help="compute the scenario's [solver] section with each engine (driftlog, "
                   "shallowWaterFoam; each flow stored and reused) and compare them; the "
                   "first is the reference")
    p.add_argument("--gate", action="append", metavar="NAME=X0,Y0,X1,Y1",
                   help="a named line: arrival times of each log at it, per log")
    p.add_argument("--line", type=float, nargs=4, metavar=("X0", "Y0", "X1", "Y1"),
                   help="arrival line (default: arrival = leaving the domain)")
    p.add_argument("--out", help="output folder (default: driftlog-compare for a scenario; "
                   "two trajectory files: printed only, unless --out is given)")
    p.set_defaults(run=cmd_compare)


def cmd_compare(args):
    import json

    from driftlog.compare import (
        compare_runs,
        compare_trajectories,
        engine_flows,
        parse_flow_spec,
        parse_line_spec,
    )

    if len(args.inputs) == 2 and all(i.endswith(".nc") for i in args.inputs) and not args.flow:
        r = compare_trajectories(args.inputs[0], args.inputs[1], args.line)
        print(f"mean distance at the end: {r['mean_distance'][-1]:.4g} m, max over the run: "
              f"{r['max_distance'].max():.4g} m")
        print(f"final statuses: {r['final_status_reference']} vs {r['final_status_other']}")
        print(f"hits: {json.dumps(r['hits_reference'])} vs {json.dumps(r['hits_other'])}")
        if args.out is not None:
            from driftlog.compare import write_trajectory_comparison

            for f in write_trajectory_comparison(r, args.inputs[0], args.inputs[1], args.out):
                print(f"written: {f}")
        return 0
    lines = dict(parse_line_spec(g) for g in args.gate or [])
    if len(args.inputs) == 1 and args.engines:
        if args.flow:
            raise DriftlogError("driftlog compare: give --engines or --flow, not both")
        path, _ = _scenario_path(args.inputs[0])
        flows = engine_flows(path, args.engines, progress=True)
        out = Path(args.out or "driftlog-compare")
        compare_runs(path, flows, out, args.line, progress=True, lines=lines)
        print((out / "compare.md").read_text())
        print(f"report: {out / 'compare.md'}, {out / 'compare.json'}; figure: "
              f"{out / 'compare.png'}")
        return 0
    if len(args.inputs) != 1 or not args.flow:
        raise DriftlogError("driftlog compare: give one scenario and two --flow NAME=SOURCE or "
                            "more (or --engines E1,E2), or two trajectory files")
    path, _ = _scenario_path(args.inputs[0])
    out = Path(args.out or "driftlog-compare")
    compare_runs(path, [parse_flow_spec(f) for f in args.flow], out, args.line,
                 progress=True, lines=lines)
    print((out / "compare.md").read_text())
    print(f"report: {out / 'compare.md'}, {out / 'compare.json'}; figure: {out / 'compare.png'}")
    return 0


# --------------------------------------------------------------------- report
@command
def add_report(sub):
    p = _sub(sub, "report", "re-create the validation and benchmark results (tables, figures) "
             "that the README shows", "driftlog report --quick\n  driftlog report --only "
             "integrators sampling")
    p.add_argument("--only", nargs="+", metavar="ITEM", help="run only these items")
    p.add_argument("--quick", action="store_true", help="reduced sizes (minutes, not hours)")
    p.add_argument("--list", action="store_true", help="list the items")
    p.set_defaults(run=cmd_report)


def cmd_report(args):
    from driftlog.report import ITEMS, benchmarks_dir, run_report

    if args.list:
        for name, script, _, what in ITEMS:
            there = (benchmarks_dir() / script).is_file()
            print(f"{name:<12} {script:<28} {what}{'' if there else ' (script missing)'}")
        return 0
    status = run_report(args.only, args.quick)
    print(f"report: {benchmarks_dir() / 'results' / 'REPORT.md'}")
    return 0 if all(s.startswith(("ok", "skipped")) for s in status.values()) else 1
# --------------------------------------------------------------------- ensembles
@command
def add_ensemble(sub):
    p = _sub(sub, "ensemble", "run an ensemble: many members (releases, log sizes, densities, "
             "physics...) on one flow, on Dask, reduced to maps of pass probability, first "
             "arrival and stranding, and hits per obstacle",
             "driftlog ensemble ensemble.toml --workers 2\n"
             "  driftlog ensemble ensemble.toml --resume            # after an interruption\n"
             "  driftlog ensemble ensemble.toml --scheduler tcp://head:8786\n"
             "  driftlog scenario keys --section ensemble           # the [ensemble] keys")
    p.add_argument("file", help="ensemble file: a scenario with an [ensemble] section")
    p.add_argument("--workers", type=int, help="local Dask workers (default: [ensemble] "
                   "workers, else the CPU count); 0: in this process, without Dask")
    p.add_argument("--scheduler", metavar="ADDR", help="address of a running Dask scheduler, "
                   "e.g. tcp://head:8786 (default: a LocalCluster)")
    p.add_argument("--resume", action="store_true", help="keep the finished members in the "
                   "output folder and run only the others")
    p.add_argument("--overwrite", action="store_true", help="delete an earlier run's results "
                   "in the output folder first")
    p.add_argument("--out", help="output folder (default: [ensemble] output)")
    p.add_argument("--members", type=int, help="number of members (overrides [ensemble] "
                   "members; raise it and --resume to extend a Monte Carlo ensemble)")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_set(p)
    p.set_defaults(run=cmd_ensemble)


def cmd_ensemble(args):
    from driftlog.ensemble import run_ensemble

    over = _overrides(args.set)
    if args.members is not None:
        over.setdefault("ensemble", {})["members"] = args.members
    res = run_ensemble(args.file, workers=args.workers, scheduler=args.scheduler,
                       resume=args.resume, overwrite=args.overwrite, output=args.out,
                       progress=not args.quiet, figures=not args.no_figures,
                       overrides=over or None)
    t = res.timings
    rate = f", {t['members_per_minute']:.1f} members/min" if "members_per_minute" in t else ""
    print(f"driftlog ensemble: {res.done} of {res.members} members done "
          f"({len(res.ran)} run now, {res.resumed} resumed), {len(res.failed)} failed; "
          f"{t['wall_seconds']:.1f} s{rate}")
    print(f"  aggregated results: {res.path}")
    table = res.aggregate.format_clogging() if res.aggregate is not None else ""
    if table:
        print(table)
        print(f"  clogging table: {res.output / 'clogging.csv'}")
    for f in res.figures:
        print(f"  figure: {f}")
    if res.failed:
        print(f"  failed members: {res.output / 'failed'} (run again with --resume to retry "
              "them)")
    return 1 if res.failed else 0


# --------------------------------------------------------------------- entry point
def build_parser() -> argparse.ArgumentParser:
    """The ``driftlog`` argument parser (one sub-command per ``cmd_<name>``)."""
    parser = argparse.ArgumentParser(
        prog="driftlog", formatter_class=_formatter,
        description="Large floating debris (logs) on flood flows: transport, contacts with "
                    "bridge piers and banks, ensembles.",
        epilog="examples:\n  driftlog run                      the default demo scene\n"
               "  driftlog run my_scenario.toml     a scenario end to end\n"
               "  driftlog <command> --help         help and an example for each command")
    parser.add_argument("--version", action="version", version=f"driftlog {__version__}")
    sub = parser.add_subparsers(title="commands", metavar="<command>")
    for add in COMMANDS:
        add(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    from driftlog.errors import DriftlogWarning

    if issubclass(category, DriftlogWarning):
        print(f"driftlog: warning: {message}", file=sys.stderr)
    else:
        _default_showwarning(message, category, filename, lineno, file, line)


def main(argv=None) -> int:
    """Run the ``driftlog`` command line; returns the exit status.

    ``DriftlogError`` (bad input): one line ``driftlog: error: ...`` and status 2; an ``OSError``
    about a path likewise; Ctrl-C: what was kept, status 130; any other exception is a bug and
    keeps its traceback.
    """
    import warnings

    global _default_showwarning
    if warnings.showwarning is not _show_warning:
        _default_showwarning = warnings.showwarning
        warnings.showwarning = _show_warning
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help()
        return 1
    try:
        return int(args.run(args) or 0)
    except DriftlogError as exc:
        print(f"driftlog: error: {exc}", file=sys.stderr)
        for note in getattr(exc, "__notes__", ()):
            print(f"  {note}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        notes = getattr(exc, "__notes__", ())
        print("driftlog: interrupted" + ("" if notes else "; the files printed above are "
                                          "complete, the one being written was removed (files "
                                          "get their name only when complete)"),
              file=sys.stderr)
        for note in notes:
            print(f"  {note}", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into head: not an error
        sys.stderr.close()
        return 0
    except MemoryError:
        print("driftlog: error: out of memory; reduce the run's size (logs, cells, output "
              "records) or use a machine with more memory", file=sys.stderr)
        return 2
    except OSError as exc:
        if exc.filename is None:
            raise  # not about a path: a bug, with its traceback
        where = exc.filename + (f" -> {exc.filename2}" if exc.filename2 else "")
        print(f"driftlog: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
