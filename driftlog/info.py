"""``driftlog info``: a few lines on any file driftlog reads or writes.

Kind, mesh, times, variables, value ranges, and for a ``.partial`` trajectory file how far the
run got (its last record against the scenario's end time).  Wrong or unreadable files get the
one-line error of :mod:`driftlog.files`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from driftlog.errors import InputFileError
from driftlog.files import require

__all__ = ["describe"]

READABLE = ("flow", "trajectories", "partial", "ensemble", "mesh", "model_output", "openfoam",
            "scenario", "mesh_file", "netcdf")


def _range(a, unit=""):
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return "no finite values"
    return f"{a.min():.4g} to {a.max():.4g}{(' ' + unit) if unit else ''}"


def _mesh_line(mesh):
    x0, y0, x1, y1 = mesh.bounds
    return f"{mesh!r}\n  extent: x {x0:.6g} to {x1:.6g} m, y {y0:.6g} to {y1:.6g} m"


def _times_line(times):
    t = np.asarray(times, float)
    if t.size == 0:
        return "times: none"
    step = f", every {np.median(np.diff(t)):.4g} s" if t.size > 1 else ""
    return f"times: {t.size} from {t[0]:.6g} to {t[-1]:.6g} s{step}"


def _flow_lines(field, kind_line, sample=12):
    lines = [kind_line, "  " + _mesh_line(field.mesh), "  " + _times_line(field.times)]
    n = field.times.size
    idx = np.unique(np.linspace(0, n - 1, min(n, sample)).round().astype(int))
    hmax, smax, wet = [], [], []
    for i in idx:
        s = field.snapshot(int(i))
        hmax.append(s["h"].max())
        smax.append(np.hypot(s["u"], s["v"]).max())
        wet.append(np.mean(s["h"] > field.dry_depth))
    lines.append(f"  bed: {_range(field.bed, 'm')}")
    lines.append(f"  depth max {_range(hmax, 'm')}, speed max {_range(smax, 'm/s')}, wet "
                 f"fraction {min(wet):.0%} to {max(wet):.0%} (over {idx.size} of {n} snapshots)")
    for k in ("source", "title", "driftlog_version", "imported_from", "import_notes"):
        if field.attrs.get(k):
            lines.append(f"  {k}: {field.attrs[k]}")
    return lines


def _trajectory_lines(fk):
    from driftlog.logs import STATUS_MEANINGS
    from driftlog.trajectory import open_trajectories

    ds = open_trajectories(fk.path)
    names = STATUS_MEANINGS.split()
    n = ds.sizes["trajectory"]
    t = ds["time"].values
    ti = ds["trajectory_index"].values
    kind = "driftlog trajectory file" if fk.kind == "trajectories" else \
        "driftlog trajectory file, PARTIAL (a run in progress or stopped)"
    lines = [f"{fk.path}: {kind}",
             f"  {n} logs, {t.size} observations, " + _times_line(np.unique(t))]
    if t.size:
        order = np.lexsort((t, ti))
        last = order[np.flatnonzero(np.diff(np.append(ti[order], -1)) != 0)]
        st = ds["status"].values[last]
        lines.append("  last status: " + ", ".join(f"{int(np.sum(st == c))} {names[c]}"
                                                   for c in np.unique(st)))
        lines.append(f"  x {_range(ds['x'].values, 'm')}, y {_range(ds['y'].values, 'm')}, "
                     f"speed {_range(np.hypot(ds['u'].values, ds['v'].values), 'm/s')}")
    lines.append(f"  logs: length {_range(ds['length'].values, 'm')}, radius "
                 f"{_range(ds['radius'].values, 'm')}, density "
                 f"{_range(ds['density'].values, 'kg/m3')}")
    nh = ds.sizes.get("hit", 0)
    if nh:
        other = ds["hit_other"].values
        lines.append(f"  contacts: {nh} hits ({int(np.sum(other < 0))} on obstacles, "
                     f"{int(np.sum(other >= 0))} log-log)")
    else:
        lines.append("  contacts: none recorded")
    a = ds.attrs
    lines.append(f"  physics {a.get('physics_level', '?')}, integrator "
                 f"{a.get('integrator', '?')}; flow: {a.get('flow_source', '?')}")
    try:
        end = json.loads(a.get("scenario_resolved", "{}"))["time"]["end"]
    except (ValueError, KeyError, TypeError):
        end = None
    if fk.kind == "partial":
        done = float(t.max()) if t.size else None
        frac = f" ({done / end:.0%} of the run)" if done is not None and end else ""
        lines.append(f"  complete up to t = {done if done is not None else 'nothing'} s of "
                     f"{end} s{frac}; `driftlog track SCENARIO --resume` continues it")
    elif end is not None:
        lines.append(f"  complete: t = {float(t.max()) if t.size else 0:g} s of {end:g} s "
                     "(logs that left the domain stop earlier)")
    return lines


def describe(path) -> str:
    """A few lines on the file at ``path`` (any kind in ``driftlog.files``).

    Raises a ``DriftlogError`` for files driftlog does not read.
    """
    fk = require(path, READABLE, "file for driftlog info",
                 hint="driftlog info reads flow, trajectory (.partial too), mesh, scenario and "
                      "ensemble files, OpenFOAM cases, UGRID, ANUGA and CF grid outputs")
    p = fk.path
    if fk.kind in ("trajectories", "partial"):
        return "\n".join(_trajectory_lines(fk))
    if fk.kind == "flow":
        from driftlog.flowfile import open_flow

        field = open_flow(p)
        lines = _flow_lines(field, f"{p}: driftlog flow file (UGRID-1.0 + CF)")
        if p.name.endswith(".partial"):  # the solver's flow until it reaches its end
            coupled = str(field.attrs.get("coupled", "0")) == "1"
            try:
                end = json.loads(field.attrs.get("scenario_resolved", "{}"))[
                    "time" if coupled else "solver"]["end"]
            except (ValueError, KeyError, TypeError):
                end = None
            if coupled:  # a coupled tracking run's flow: resumed with its trajectories
                lines[0] += (", PARTIAL (the flow of a coupled tracking run in progress or "
                             "stopped)")
                how = ("`driftlog track SCENARIO --resume` continues it with its trajectories "
                       "(their .partial file)")
            else:
                lines[0] += ", PARTIAL (a solver run in progress or stopped)"
                how = "`driftlog solve SCENARIO --resume` continues it"
            lines.append(f"  computed up to t = {field.times[-1]:g} s"
                         + (f" of {end:g} s" if end else "") + f"; {how}")
        return "\n".join(lines)
    if fk.kind in ("model_output", "openfoam"):
        from driftlog.adapters import detect_format, open_flow_source, reader

        fmt = detect_format(p)
        r = reader(fmt)
        if hasattr(r, "describe"):  # the reader's own few lines (header only)
            return "\n".join(r.describe(p))
        field = open_flow_source(fmt, p)
        return "\n".join(_flow_lines(field, f"{p}: {fmt} model output (a hydro source; "
                                            "driftlog import converts it)"))
    if fk.kind in ("mesh", "mesh_file"):
        from driftlog.mesh import read_mesh

        mesh = read_mesh(p)
        z = mesh.node_z
        return "\n".join([f"{p}: mesh file (no flow)", "  " + _mesh_line(mesh),
                          f"  bed at nodes: {_range(z, 'm') if z is not None else 'none'}"])
    if fk.kind == "scenario":
        from driftlog.cli.common import ensemble_section
        from driftlog.scenario import load_scenario

        ens = None
        if ensemble_section(p) is not None:  # its base merged
            from driftlog.ensemble.spec import load_ensemble

            ens = load_ensemble(p)
            scen = ens.scenario
        else:
            scen = load_scenario(p)
        nlogs = len(scen["logs"])
        tm = scen["time"]
        return "\n".join([
            f"{p}: " + ("ensemble file" if ens is not None else "scenario file") + " (valid)",
            f"  title: {scen['title']}",
            *([f"  ensemble: {ens.members} members ({ens.section['sampling']}, seed "
               f"{ens.seed}) varying " + (", ".join(q.path for q in ens.parameters) or "nothing")
               + (f"; base scenario {ens.section['base']}" if ens.section.get("base") else "")
               + f"; run with `driftlog ensemble {p}`"] if ens is not None else []),
            f"  flow: source {scen['flow']['source']!r}"
            + (f", {scen['flow']['path']}" if scen["flow"]["path"] else ""),
            f"  time: {tm['start']:g} to "
            + (f"{tm['end']:g} s" if tm["end"] is not None else "the end of the flow")
            + ", output every "
            f"{tm['output_interval']:g} s",
            f"  {nlogs} log groups, {len(scen['obstacles'])} obstacles, physics "
            f"{scen['physics']['level']}, integrator {scen['integrator']['method']}, contacts "
            f"{'on' if scen['contact']['enabled'] else 'off'}",
            "  (driftlog scenario check runs every check of a run's start)"])
    if fk.kind == "ensemble":
        import netCDF4

        with netCDF4.Dataset(p) as ds:
            dims = ", ".join(f"{k} {len(v)}" for k, v in ds.dimensions.items())
            names = ", ".join(sorted(ds.variables)[:20])
            lines = [f"{p}: driftlog ensemble results", f"  dimensions: {dims}",
                     f"  variables: {names}"]
            for k in ("members", "members_done", "driftlog_version"):
                if k in ds.ncattrs():
                    lines.append(f"  {k}: {ds.getncattr(k)}")
        return "\n".join(lines)
    raise InputFileError(f"{p}: {fk.describe()}; driftlog info cannot describe it "
                         f"(variables: {fk.info.get('variables', [])[:12]})")


if __name__ == "__main__":  # pragma: no cover
    import sys

    print(describe(Path(sys.argv[1])))
