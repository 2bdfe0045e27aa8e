"""What every ``driftlog`` subcommand shares: the registry, parser helpers, scenario paths."""

from __future__ import annotations

import argparse
from pathlib import Path

from driftlog.errors import DriftlogError

__all__ = ["COMMANDS", "command", "formatter", "sub_parser", "overrides", "scenario_path",
           "add_set", "in_cases", "case_overrides", "flow_file", "parse_pairs"]

COMMANDS = []  # parser builders of the subcommands, in the order of --help


def command(add):
    """Register a subcommand from its parser builder; the builder's ``cmd`` runs it."""
    COMMANDS.append(add)
    return add


def formatter(prog):
    """Argparse formatter of every subcommand (examples kept as written)."""
    return argparse.RawDescriptionHelpFormatter(prog, max_help_position=32)


def sub_parser(sub, name, help, example, description=None):
    """A subcommand's parser with its help and an example in the epilog."""
    p = sub.add_parser(name, help=help, description=(description or help),
                       epilog=f"example:\n  {example}", formatter_class=formatter)
    return p


def overrides(pairs):
    """--set physics.level=tracer --set time.end=100: a nested dict for load_scenario.

    In an array of tables, ``logs.density=800`` sets every group, ``logs.1.density=800`` or
    ``logs[1].density=800`` group 1 (``schema.merge``).
    """
    import re
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
        parts = []
        for part in key.strip().split("."):
            m = re.fullmatch(r"(.+)\[(\d+)\]", part)  # logs[1]: group 1 of [[logs]]
            parts += [m[1], m[2]] if m else [part]
        for p in parts[:-1]:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise DriftlogError(f"--set {pair!r}: {p} is given a value by another --set, "
                                    "so it has no keys")
        node[parts[-1]] = value
    return out


def scenario_path(name):
    """(scenario file, run name) of a scenario argument: a file, a case folder or a case name."""
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


def ensemble_section(path):
    """The ``[ensemble]`` table of the TOML file ``path`` (an ensemble file), else None."""
    from driftlog.schema import read_toml

    raw, _, _ = read_toml(path)
    ens = raw.get("ensemble")
    return ens if isinstance(ens, dict) else None


def refuse_ensemble(path, command):
    """An ensemble file given to a command that runs one scenario: one clear error."""
    ens = ensemble_section(path)
    if ens is not None:
        from driftlog.errors import DriftlogError

        base = f" over the base scenario {ens['base']}" if ens.get("base") else ""
        raise DriftlogError(f"{path} is an ensemble file (an [ensemble] section{base}): run it "
                            f"with `driftlog ensemble {path}`; `driftlog {command}` runs one "
                            "scenario" + (f" (e.g. the base, {ens['base']})"
                                          if ens.get("base") else ""))


def add_set(p):
    """The --set SECTION.KEY=VALUE option of the commands that read a scenario."""
    p.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                   help="override a scenario value (repeatable), e.g. --set physics.level=tracer")


def in_cases(path) -> bool:
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


def case_overrides(path, name, over=None, run_dir=None):
    """Overrides that keep a shipped case's outputs out of the clone.

    For a scenario in the repository's cases/ whose flow is computed by the solver, the flow
    file goes to the run folder (``run_dir``, default ``driftlog-runs/<case>/``; reused from
    there), not beside the scenario.
    """
    from driftlog.scenario import read_toml
    from driftlog.schema import merge

    over = dict(over or {})
    if not in_cases(path) or "path" in over.get("flow", {}):
        return over
    flow = read_toml(path)[0].get("flow", {})
    solver = over.get("flow", {}).get("source", flow.get("source") if isinstance(flow, dict)
                                      else None) == "solver"
    if solver:
        name_ = Path((flow.get("path") if isinstance(flow, dict) else None)
                     or "solver_flow.nc").name
        run = (Path(run_dir or Path("driftlog-runs") / name) / name_).resolve()
        over = merge(over, {"flow": {"path": str(run)}})
    return over


def flow_file(scen, trajectories=None):
    """The flow file a scenario reads or computes (None for an analytic flow).

    A coupled run's own flow file when ``trajectories`` (its trajectory file) is given.
    """
    if trajectories is not None and scen["coupling"]["enabled"]:
        from driftlog.coupling import coupled_flow_path

        return coupled_flow_path(scen, trajectories)
    sec = scen["flow"]
    if sec["source"] == "solver":
        from driftlog.solving import default_flow_path

        return default_flow_path(scen)  # with the engine's suffix
    return Path(sec["path"]) if sec["source"] != "analytic" and sec["path"] else None


def parse_pairs(pairs, what):
    """NAME=VALUE arguments (--flow, --option...) as a dict, each value parsed as TOML or JSON."""
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
