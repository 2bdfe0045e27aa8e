"""``driftlog`` subcommands of many runs: report, ensemble."""

from __future__ import annotations

from driftlog.cli.common import (
    add_set,
    command,
    overrides,
    sub_parser,
)

__all__ = []  # the subcommands register themselves (driftlog.cli.COMMANDS)


@command
def add_report(sub):
    p = sub_parser(sub, "report",
                   "re-create the validation and benchmark results (tables, figures) "
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


@command
def add_ensemble(sub):
    p = sub_parser(sub, "ensemble",
                   "run an ensemble: many members (releases, log sizes, densities, "
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
    add_set(p)
    p.set_defaults(run=cmd_ensemble)


def cmd_ensemble(args):
    from driftlog.ensemble import run_ensemble

    over = overrides(args.set)
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
