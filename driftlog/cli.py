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
