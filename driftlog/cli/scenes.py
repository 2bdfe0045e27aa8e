"""``driftlog`` subcommands of a scenario: scenario, info, run, track, plot, animate, vtk, cases."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from driftlog.cli.common import (
    add_set,
    case_overrides,
    command,
    ensemble_section,
    flow_file,
    in_cases,
    overrides,
    refuse_ensemble,
    scenario_path,
    sub_parser,
)
from driftlog.errors import DriftlogError

__all__ = []  # the subcommands register themselves (driftlog.cli.COMMANDS)


@command
def add_scenario(sub):
    p = sub_parser(sub, "scenario", "list the scenario keys, or check a scenario file (every check "
             "a run makes before it starts: flow readable, logs inside the mesh, obstacles)",
             "driftlog scenario check cases/vortex/scenario.toml")
    p.add_argument("action", metavar="{keys,check}", help="keys: print every key with its "
                   "type, default, units and rule; check: validate a file (a file or case "
                   "given instead of the action is checked: driftlog scenario FILE)")
    p.add_argument("file", nargs="?", help="scenario file (for check)")
    p.add_argument("--section", help="only this section (for keys)")
    p.set_defaults(run=cmd_scenario)


def cmd_scenario(args):
    from driftlog.scenario import describe_keys, load_scenario

    if args.action not in ("keys", "check"):  # driftlog scenario FILE (or CASE): check it
        wrong = (f"driftlog scenario: action {args.action!r}: must be 'keys' (print every key) "
                 "or 'check' (check a file: driftlog scenario check FILE)")
        if args.file is not None:
            raise DriftlogError(wrong)
        try:
            scenario_path(args.action)
        except DriftlogError as e:
            raise DriftlogError(f"{wrong}; as a scenario file or case: {e}") from None
        args.action, args.file = "check", args.action
    if args.action == "keys":
        print(describe_keys(args.section))
        return 0
    if not args.file:
        raise DriftlogError("driftlog scenario check: give the scenario file to check")
    from driftlog.preflight import check_scenario

    path, name = scenario_path(args.file)
    ens = None
    if ensemble_section(path) is not None:  # the base merged, every member's keys checked
        from driftlog.ensemble.spec import load_ensemble

        ens = load_ensemble(path)
        scen = ens.scenario
    else:
        scen = load_scenario(path, case_overrides(path, name) or None)
    output = Path("driftlog-runs") / name / Path(scen["output"]["path"]).name \
        if in_cases(path) else None  # where driftlog track writes
    from driftlog.api import logs_from_scenario
    from driftlog.preflight import estimate_run

    estimate_run(scen, output)  # before seeding: 1e7 logs are refused, not allocated
    notes, done = check_scenario(scen, logs_from_scenario(scen), output=output)
    for n in notes:
        print(f"driftlog: warning: {n}", file=sys.stderr)
    print(f"{path}: valid: the run will start ({len(scen['logs'])} log groups, flow source "
          f"{scen['flow']['source']!r})")
    if ens is not None:
        print(f"  ensemble of {ens.members} members ({ens.section['sampling']}) varying "
              + (", ".join(p.path for p in ens.parameters) or "nothing")
              + f"; run it with `driftlog ensemble {path}`")
    for d in done:
        print(f"  {d}")
    return 0


@command
def add_info(sub):
    p = sub_parser(sub, "info",
                   "describe any file driftlog reads or writes: flow, trajectories (and "
             "their .partial), mesh, scenario, ensemble results, another model's output",
             "driftlog info flow.nc\n  driftlog info trajectories.nc.partial\n"
             "  driftlog info runs/squareBump      (an OpenFOAM case)")
    p.add_argument("file", help="a file, or an OpenFOAM case directory")
    p.set_defaults(run=cmd_info)


def cmd_info(args):
    from driftlog.info import describe

    print(describe(args.file))
    return 0


@command
def add_run(sub):
    p = sub_parser(sub, "run", "run a scenario end to end: flow (solved or imported if needed), "
             "tracking, a figure and an animation",
             "driftlog run                       # the default demo scene\n"
             "  driftlog run vortex --out runs/v   # a case by name\n"
             "  driftlog run my_scenario.toml --set physics.level=tracer")
    p.add_argument("scenario", nargs="?", help="scenario file or case name (default: the demo)")
    p.add_argument("--out", help="output folder (default: driftlog-runs/<name>)")
    p.add_argument("--no-figure", action="store_true", help="skip the figure")
    p.add_argument("--no-animation", action="store_true", help="skip the animation")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--resume", action="store_true",
                   help="continue a stopped run from its folder's trajectories.nc.partial")
    add_set(p)
    p.set_defaults(run=cmd_run)


def cmd_run(args):
    from driftlog.api import as_scenario, track
    from driftlog.plots import animate, plot_trajectories

    path, name = scenario_path(args.scenario)
    refuse_ensemble(path, "run")
    from driftlog.files import check_output_dir

    out = check_output_dir(Path(args.out or Path("driftlog-runs") / name), "run folder")
    # a shipped case's solved flow goes to the run folder too (--out); run draws its own
    # figure and animation into the run folder (--no-figure, --no-animation), not [output]'s
    over = overrides(args.set)
    over.setdefault("output", {}).update(figure=False, animation=False)
    scen = as_scenario(path, case_overrides(path, name, over, run_dir=out))
    print(f"driftlog: running {path}")
    import shlex

    again = shlex.join(["driftlog", "run", *([args.scenario] if args.scenario else []),
                        "--out", str(out), *(w for a in args.set or () for w in ("--set", a)),
                        "--resume"])
    res = track(scen, output=out / "trajectories.nc", progress=not args.quiet,
                resume=args.resume, resume_hint=again)
    flow = flow_file(scen, res.path)
    if flow is not None and flow.exists():
        print(f"  flow: {flow}")
    print(f"  trajectories: {res.path}")
    for f in res.extra_files:
        print(f"  {extra_label(f)}: {f}")
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


def extra_label(f):
    """What a side file of a run is, by its suffix: a figure, an animation or ParaView's."""
    return {".png": "figure", ".mp4": "animation", ".gif": "animation"}.get(Path(f).suffix,
                                                                         "ParaView")


@command
def add_track(sub):
    p = sub_parser(sub, "track", "track the logs of a scenario on its flow (an existing flow file, "
             "an imported model output or an analytic field)",
             "driftlog track scenario.toml -o trajectories.nc")
    p.add_argument("scenario", help="scenario file or case name")
    p.add_argument("-o", "--output", help="trajectory file (default: the scenario's output.path)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--resume", action="store_true",
                   help="continue a stopped run from its .partial file")
    add_set(p)
    p.set_defaults(run=cmd_track)


def cmd_track(args):
    from driftlog.api import as_scenario, track

    path, name = scenario_path(args.scenario)
    refuse_ensemble(path, "track")
    scen = as_scenario(path, case_overrides(path, name, overrides(args.set)))
    output = args.output
    if output is None and in_cases(path):
        output = Path("driftlog-runs") / name / Path(scen["output"]["path"]).name
    res = track(scen, output=output, progress=not args.quiet, resume=args.resume)
    flow = flow_file(scen, res.path)
    if flow is not None and flow.exists():
        print(f"flow: {flow}")
    print(f"trajectories: {res.path}")
    for f in res.extra_files:
        print(f"{extra_label(f)}: {f}")
    return 0


@command
def add_plot(sub):
    p = sub_parser(sub, "plot", "draw the trajectories of a trajectory file over the flow",
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
    p = sub_parser(sub, "animate", "animate the logs of a trajectory file over the flow (MP4 with "
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
    p = sub_parser(sub, "vtk",
                   "write ParaView files: a .pvd time series of the logs of a trajectory "
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
    p = sub_parser(sub, "cases", "list the scenes in cases/, or run one",
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
