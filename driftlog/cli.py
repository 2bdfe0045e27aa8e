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
    p = _sub(sub, "scenario", "list the scenario keys, or check a scenario file",
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
    scen = load_scenario(args.file)
    print(f"{args.file}: valid ({len(scen['logs'])} log groups, flow source "
          f"{scen['flow']['source']!r})")
    return 0


@command
def add_info(sub):
    p = _sub(sub, "info", "describe a flow file, a mesh, or a trajectory file",
             "driftlog info flow.nc")
    p.add_argument("file", help="NetCDF flow or trajectory file, or a mesh file")
    p.set_defaults(run=cmd_info)


def cmd_info(args):
    path = Path(args.file)
    if not path.exists():
        raise DriftlogError(f"{path}: file not found")
    if path.suffix == ".nc":
        import netCDF4

        with netCDF4.Dataset(path) as ds:
            if getattr(ds, "featureType", "") == "trajectory":
                import xarray as xr

                print(xr.open_dataset(path))
                return 0
        from driftlog.flowfile import open_flow

        field = open_flow(path)
        print(field)
        print(field.mesh)
        for k in ("source", "title", "driftlog_version"):
            if k in field.attrs:
                print(f"  {k}: {field.attrs[k]}")
        return 0
    from driftlog.mesh import read_mesh

    print(read_mesh(path))
    return 0


# --------------------------------------------------------------------- import
@command
def add_import(sub):
    p = _sub(sub, "import", "convert another model's flow to a driftlog flow file",
             "driftlog import runs/squareBump -o flow.nc --time-range 0 60\n"
             "  driftlog import FlowFM_map.nc -o flow.nc --var depth=mesh2d_waterdepth\n"
             "  driftlog import damBreak3d -o flow.nc --option raster=0,0,0.1,6,2",
             description="Read a hydro source (OpenFOAM case, UGRID / D-Flow FM map file, "
                         "ANUGA .sww, CF grid NetCDF such as LISFLOOD-FP's) and write it as a "
                         "driftlog flow file (UGRID-1.0 + CF), snapshot by snapshot.  The "
                         "format is detected from the source unless --format is given.")
    p.add_argument("source", help="file, or OpenFOAM case directory")
    p.add_argument("-o", "--output", required=True, help="flow file to write (.nc)")
    p.add_argument("--format", default="auto",
                   choices=("auto", "openfoam", "ugrid", "anuga", "cf_grid", "file"),
                   help="the source's format (default: detected)")
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


# --------------------------------------------------------------------- entry point
def build_parser() -> argparse.ArgumentParser:
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


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help()
        return 1
    try:
        return int(args.run(args) or 0)
    except DriftlogError as exc:
        print(f"driftlog: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("driftlog: interrupted; outputs written so far are kept", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
