"""``driftlog`` subcommands of flows: solve, import, export, compare."""

from __future__ import annotations

import sys
from pathlib import Path

from driftlog.cli.common import (
    case_overrides,
    command,
    parse_pairs,
    scenario_path,
    sub_parser,
)
from driftlog.errors import DriftlogError

__all__ = []  # the subcommands register themselves (driftlog.cli.COMMANDS)


@command
def add_solve(sub):
    p = sub_parser(sub, "solve", "compute a flow with driftlog's shallow-water solver ([solver] "
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
    from driftlog.solving import solve_scenario

    path, name = scenario_path(args.scenario)
    raw = read_toml(path)[0]
    if "solver" not in raw:
        raise DriftlogError(f"{path}: has no [solver] section: driftlog solve computes the flow "
                            "that [solver] describes (mesh, bed, boundaries, end time); "
                            "driftlog scenario keys --section solver lists its keys")
    scen = load_scenario(path, overrides=case_overrides(path, name,
                                                         {"flow": {"source": "solver"}}))
    res, path = solve_scenario(scen, output=args.output, resume=args.resume,
                               progress=not args.quiet)
    print(f"flow file: {path}")
    print(res.summary())
    return 0


@command
def add_import(sub):
    p = sub_parser(sub, "import", "convert another model's flow to a driftlog flow file",
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


def cmd_import(args):
    import time

    from tqdm import tqdm

    from driftlog.adapters import VARIABLE_NAMES, import_flow
    from driftlog.errors import ScenarioError
    from driftlog.schema import check_value
    from driftlog.sources import FLOW_SECTION

    variables = {k: str(v) for k, v in parse_pairs(args.var, "--var").items()}
    for k, v in variables.items():
        if k not in VARIABLE_NAMES:
            raise DriftlogError(f"--var {k}={v}: {k!r} is not a name driftlog knows; one of "
                                f"{', '.join(VARIABLE_NAMES)}")
    options = parse_pairs(args.option, "--option")
    key = FLOW_SECTION.by_name["dry_depth"]
    try:  # the rule of the scenario's [flow] dry_depth
        check_value(key, "flow.dry_depth", args.dry_depth, Path.cwd())
    except ScenarioError:
        raise DriftlogError(f"--dry-depth {args.dry_depth:g}: must be a finite number "
                            f"{key.bounds()}, as [flow] dry_depth") from None
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
    p = sub_parser(sub, "export", "write a flow as another model's result file (TELEMAC Selafin, "
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
    from driftlog.files import atomic_output, check_output

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
    # the suffix of the format (mikeio writes .dfsu only), never over the source; a missing
    # folder is created, as import, solve, track and plot create theirs
    check_output(out, f"{fmt} file", inputs=[args.source],
                 suffixes=selafin.SUFFIXES if fmt == "selafin" else mike.SUFFIXES)
    field = open_flow_source("auto", args.source)
    tmp = None
    try:
        with atomic_output(out) as tmp:  # renamed when complete: never a truncated file
            if fmt == "selafin":
                selafin.write(field, tmp, precision=args.precision)
            else:
                mike.write(field, tmp)
    except DriftlogError as exc:  # the file named as the user gave it, not its temporary name
        raise DriftlogError(str(exc).replace(str(tmp), str(out))) from None
    except OSError as exc:
        raise DriftlogError(f"{out}: cannot write the {fmt} file ({exc})") from None
    print(f"{args.source} -> {out} ({fmt}, {field.times.size} snapshots, "
          f"{field.mesh.n_faces} faces)")
    return 0


@command
def add_compare(sub):
    p = sub_parser(sub, "compare",
                   "run the same debris scenario on two or more flows (hydro sources) "
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
        check_line,
        compare_runs,
        compare_trajectories,
        engine_flows,
        final_time_text,
        parse_flow_specs,
        parse_gates,
    )

    if args.line is not None:
        check_line(args.line)

    if len(args.inputs) == 2 and all(i.endswith(".nc") for i in args.inputs) and not args.flow:
        for opt, given in (("--gate", ", ".join(args.gate or ())), ("--engines", args.engines)):
            if given:
                raise DriftlogError(f"driftlog compare: {opt} {given}: not used when two "
                                    "trajectory files are compared (--gate and --engines go "
                                    "with a scenario; two trajectory files take --line and "
                                    "--out)")
        r = compare_trajectories(args.inputs[0], args.inputs[1], args.line)
        print(f"mean distance {final_time_text(r)}: {r['mean_distance'][-1]:.4g} m, max over "
              f"the run: {r['max_distance'].max():.4g} m")
        print(f"final statuses: {r['final_status_reference']} vs {r['final_status_other']}")
        print(f"hits: {json.dumps(r['hits_reference'])} vs {json.dumps(r['hits_other'])}")
        if args.out is not None:
            from driftlog.compare import write_trajectory_comparison

            for f in write_trajectory_comparison(r, args.inputs[0], args.inputs[1], args.out):
                print(f"written: {f}")
        return 0
    lines = parse_gates(args.gate or [])
    if len(args.inputs) == 1 and args.engines:
        if args.flow:
            raise DriftlogError("driftlog compare: give --engines or --flow, not both")
        path, _ = scenario_path(args.inputs[0])
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
    path, _ = scenario_path(args.inputs[0])
    out = Path(args.out or "driftlog-compare")
    compare_runs(path, parse_flow_specs(args.flow), out, args.line,
                 progress=True, lines=lines)
    print((out / "compare.md").read_text())
    print(f"report: {out / 'compare.md'}, {out / 'compare.json'}; figure: {out / 'compare.png'}")
    return 0
