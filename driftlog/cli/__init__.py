"""The ``driftlog`` command: one entry point, one subcommand per task.

Each subcommand is a pair: ``add_<name>(subparsers)`` declares its arguments (with an example
in its help), ``cmd_<name>(args)`` runs it.  Errors about user input (``DriftlogError``) print
one clear line and exit with status 2; anything else is a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import sys

from driftlog._version import __version__
from driftlog.cli import batch, flows, scenes
from driftlog.cli.common import COMMANDS, formatter
from driftlog.errors import DriftlogError

__all__ = ["main", "build_parser"]

_default_showwarning = None


def build_parser() -> argparse.ArgumentParser:
    """The ``driftlog`` argument parser (one sub-command per ``cmd_<name>``)."""
    parser = argparse.ArgumentParser(
        prog="driftlog", formatter_class=formatter,
        description="Large floating debris (logs) on flood flows: transport, contacts with "
                    "bridge piers and banks, ensembles.",
        epilog="examples:\n  driftlog run                      the default demo scene\n"
               "  driftlog run my_scenario.toml     a scenario end to end\n"
               "  driftlog <command> --help         help and an example for each command")
    parser.add_argument("--version", action="version", version=f"driftlog {__version__}")
    sub = parser.add_subparsers(title="commands", metavar="<command>")
    # --help lists the commands module by module, each in the order of its source
    order = [m.__name__ for m in (scenes, flows, batch)]
    for add in sorted(COMMANDS, key=lambda f: (order.index(f.__module__),
                                                f.__code__.co_firstlineno)):
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
        # not foreseen by the estimates made before allocating (driftlog.preflight.estimate_run,
        # solver.config.estimate_mesh), which name the keys and their values
        print("driftlog: error: out of memory; reduce the run's size: the logs ([[logs]] count "
              "or x), the records ([time] output_interval), the mesh ([solver] cell_size), or "
              "use a machine with more memory", file=sys.stderr)
        return 2
    except OSError as exc:
        if exc.filename is None:
            raise  # not about a path: a bug, with its traceback
        where = exc.filename + (f" -> {exc.filename2}" if exc.filename2 else "")
        print(f"driftlog: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
