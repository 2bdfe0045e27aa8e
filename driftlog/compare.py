"""Compare hydro sources by what they do to the same debris (``driftlog compare``).

The same debris scenario is tracked on two or more flows (driftlog's solver, OpenFOAM, a
D-Flow FM or ANUGA output...), or two trajectory files are compared directly.  Reported, per
flow against the first (the reference):

- the flows at the logs: depth and velocity differences sampled along the reference
  trajectories (``driftlog.adapters.compare.flow_differences``);
- the trajectories: distance between the same log in the two runs over time (mean and max
  over logs), arrival times (first crossing of a line, or leaving the domain), final
  statuses, and hits per obstacle;
- a figure: trajectories overlaid, distance over time, speed difference at the logs.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from driftlog.errors import DriftlogError
from driftlog.logs import LEFT, STATUS_MEANINGS
from driftlog.trajectory import open_trajectories

__all__ = ["compare_runs", "compare_trajectories", "arrival_times", "parse_flow_spec",
           "parse_flow_specs", "parse_gates", "write_trajectory_comparison"]


def parse_flow_spec(spec: str):
    """``NAME=SOURCE`` or ``SOURCE``: a flow file, model output (auto-detected) or 'scenario'."""
    name, _, src = spec.partition("=") if "=" in spec else ("", "", spec)
    return (name or Path(src).stem or src), src


def parse_flow_specs(specs):
    """``--flow`` arguments -> [(name, source)], each name once.

    A source given without a name is named after its file (``Path(src).stem``); when two such
    names are the same (``d1/flow.nc`` and ``d2/flow.nc``), after their folder and file
    (``d1_flow``, ``d2_flow``).  A name given twice is refused: each run is kept by its name.
    """
    parsed = [(spec, *parse_flow_spec(spec)) for spec in specs]
    named = [("=" in spec, name) for spec, name, _ in parsed]
    out = []
    for spec, name, src in parsed:
        if "=" not in spec and named.count((False, name)) > 1 and Path(src).parent.name:
            name = f"{Path(src).parent.name}_{name}"
        out.append((spec, name, src))
    for i, (spec, name, _) in enumerate(out):
        for spec2, name2, _ in out[:i]:
            if name2 == name:
                raise DriftlogError(f"--flow {spec!r}: the name {name!r} is already the one of "
                                    f"--flow {spec2!r}; give each flow a name of its own: "
                                    "--flow NAME=SOURCE")
    return [(name, src) for _, name, src in out]


def parse_gates(specs):
    """``--gate`` arguments -> {name: (x0, y0, x1, y1)}; a name given twice is refused."""
    lines = {}
    for spec in specs:
        name, vals = parse_line_spec(spec)
        if name in lines:
            raise DriftlogError(f"--gate {spec!r}: the gate {name!r} is given twice (also "
                                f"{name}={','.join(f'{v:g}' for v in lines[name])}); give each "
                                "gate a name of its own")
        lines[name] = vals
    return lines


def engine_flows(scenario, engines, progress=False):
    """The scenario's flow computed by each engine of its ``[solver]`` section.

    ``engines``: names from ``[solver] engine`` (``driftlog``, ``shallowWaterFoam``), or one
    string ``"driftlog,shallowWaterFoam"``.  Each flow is stored beside ``[flow] path`` (with
    ``_<engine>`` added for engines other than driftlog) and reused while the section is
    unchanged.  Returns [(engine, FlowField)], frozen at ``[flow] steady_at`` when set.
    """
    from driftlog.adapters.openfoam_engine import ENGINES
    from driftlog.api import as_scenario
    from driftlog.sources import flow_from_scenario

    if isinstance(engines, str):
        engines = [e.strip() for e in engines.split(",") if e.strip()]
    scen = as_scenario(scenario)
    if scen["flow"]["source"] != "solver":
        raise DriftlogError(f"--engines {','.join(engines)}: the scenario's flow must be "
                            f"computed ([flow] source = 'solver'), not {scen['flow']['source']!r}")
    bad = [e for e in engines if e not in ENGINES]
    if bad or len(engines) < 2 or len(set(engines)) != len(engines):
        raise DriftlogError(f"--engines {','.join(engines)}: give two engines or more, each "
                            f"once, among {', '.join(ENGINES)}")
    out = []
    for e in engines:
        out.append((e, flow_from_scenario(as_scenario(scen, {"solver": {"engine": e}}),
                                          progress=progress)))
    return out


def parse_line_spec(spec: str):
    """``NAME=X0,Y0,X1,Y1`` -> (name, (x0, y0, x1, y1)): a named arrival line."""
    name, sep, coords = spec.partition("=")
    try:
        vals = tuple(float(v) for v in coords.split(","))
    except ValueError:
        vals = ()
    if not sep or not name or len(vals) != 4:
        raise DriftlogError(f"--gate {spec!r}: must be NAME=X0,Y0,X1,Y1 (a named line, m)")
    check_line(vals, f"--gate {spec!r}")
    return name, vals


def check_line(vals, what="--line"):
    """Refuse a line with a non-finite coordinate or of zero length (nothing crosses it)."""
    x0, y0, x1, y1 = vals
    if not all(math.isfinite(v) for v in vals) or (x0 == x1 and y0 == y1):
        raise DriftlogError(f"{what}: {' '.join(f'{v:g}' for v in vals)}: must be a line of "
                            "finite coordinates (m) with two different ends")


def per_log(ref_path, other_path, lines=None):
    """Per log, in both runs: where it ends, its status and hits, its arrival at lines.

    End position, distance between the two ends, status at the end, arrival time at each
    named line (None: never crossed), hits per obstacle.

    Returns a list of dicts (one per log, by trajectory index).
    """
    a, b = open_trajectories(ref_path), open_trajectories(other_path)
    names = STATUS_MEANINGS.split()

    def ends(ds):
        ti, t = ds["trajectory_index"].values, ds["time"].values
        order = np.lexsort((t, ti))
        last = order[np.flatnonzero(np.diff(np.append(ti[order], -1)) != 0)]
        n = ds.sizes["trajectory"]
        x, y, st = np.full(n, np.nan), np.full(n, np.nan), np.full(n, -1)
        x[ti[last]], y[ti[last]] = ds["x"].values[last], ds["y"].values[last]
        st[ti[last]] = ds["status"].values[last]
        return x, y, st

    def hits(ds):
        """Per trajectory index: {obstacle name or 'log-log': contact records}."""
        n = ds.sizes["trajectory"]
        out = [dict() for _ in range(n)]
        if not ds.sizes.get("hit", 0):
            return out
        obst = json.loads(ds.attrs.get("obstacle_names", "[]") or "[]")
        ids = ds["trajectory"].values if "trajectory" in ds.variables else np.arange(n)
        order = np.argsort(ids)

        def index(log_ids):  # hit records name logs by id; rows are trajectory indices
            pos = np.clip(np.searchsorted(ids[order], log_ids), 0, n - 1)
            return np.where(ids[order][pos] == log_ids, order[pos], -1)

        lg, other = index(ds["hit_log"].values), ds["hit_other"].values
        counts = {}
        for k in np.unique(other[other < 0]):
            i = -int(k) - 1
            name = obst[i] if i < len(obst) and obst[i] else f"obstacle {i}"
            sel = (other == k) & (lg >= 0)
            counts[name] = np.bincount(lg[sel], minlength=n)
        pair = other >= 0
        if pair.any():  # one record per pair of logs: counted for both
            both = np.concatenate([lg[pair], index(other[pair])])
            counts["log-log"] = np.bincount(both[both >= 0], minlength=n)
        for name, c in counts.items():
            for row in np.flatnonzero(c):
                out[row][name] = int(c[row])
        return out

    xa, ya, sa = ends(a)
    xb, yb, sb = ends(b)
    arr = {name: (arrival_times(a, ln), arrival_times(b, ln)) for name, ln in
           (lines or {}).items()}
    ha, hb = hits(a), hits(b)
    ids = a["trajectory"].values if "trajectory" in a.coords else np.arange(xa.size)
    rows = []
    for i in range(xa.size):
        rows.append({
            "log": str(ids[i]), "end_reference": [float(xa[i]), float(ya[i])],
            "end_other": [float(xb[i]), float(yb[i])],
            "end_distance": float(np.hypot(xb[i] - xa[i], yb[i] - ya[i])),
            "status_reference": names[sa[i]] if sa[i] >= 0 else "-",
            "status_other": names[sb[i]] if sb[i] >= 0 else "-",
            "arrival": {k: [_num(v[0][i]), _num(v[1][i])] for k, v in arr.items()},
            "hits_reference": ha[i], "hits_other": hb[i]})
    return rows


def _num(v):
    return None if not np.isfinite(v) else float(v)


def _open_source(src, scenario):
    if not isinstance(src, (str, Path)):
        return src  # a FlowField already opened (driftlog compare --engines)
    if src == "scenario":
        from driftlog.sources import flow_from_scenario

        return flow_from_scenario(scenario)
    from driftlog.adapters import open_flow_source

    p = Path(src)
    if not p.exists():
        raise DriftlogError(f"{src}: flow source not found")
    return open_flow_source("auto", p, dry_depth=scenario["flow"]["dry_depth"])


def arrival_times(ds, line=None):
    """Per log, the first time it crosses ``line`` (x0, y0, x1, y1), or leaves the domain."""
    ti, t = ds["trajectory_index"].values, ds["time"].values
    x, y, st = ds["x"].values, ds["y"].values, ds["status"].values
    n = ds.sizes["trajectory"]
    out = np.full(n, np.nan)
    order = np.lexsort((t, ti))
    ti, t, x, y, st = ti[order], t[order], x[order], y[order], st[order]
    same = ti[1:] == ti[:-1]
    if line is not None:
        x0, y0, x1, y1 = line
        side = np.sign((x1 - x0) * (y - y0) - (y1 - y0) * (x - x0))
        # crossing the segment, not only its line: the crossing point lies between the ends
        cross = same & (side[1:] != side[:-1]) & (side[1:] != 0)
        a = np.flatnonzero(cross)
        if a.size:
            d0 = (x1 - x0) * (y[a] - y0) - (y1 - y0) * (x[a] - x0)
            d1 = (x1 - x0) * (y[a + 1] - y0) - (y1 - y0) * (x[a + 1] - x0)
            f = d0 / (d0 - d1)
            px, py = x[a] + f * (x[a + 1] - x[a]), y[a] + f * (y[a + 1] - y[a])
            s = ((px - x0) * (x1 - x0) + (py - y0) * (y1 - y0)) / ((x1 - x0) ** 2 + (y1 - y0) ** 2)
            ok = (s >= 0) & (s <= 1)
            tc = (t[a] + f * (t[a + 1] - t[a]))[ok]
            logs, first = np.unique(ti[a][ok], return_index=True)  # sorted by time: first wins
            out[logs] = tc[first]
        return out
    left = np.flatnonzero(st == LEFT)
    logs, first = np.unique(ti[left], return_index=True)
    out[logs] = t[left][first]
    return out


def _hits_per_obstacle(ds):
    names = json.loads(ds.attrs.get("obstacle_names", "[]") or "[]")
    if not ds.sizes.get("hit", 0):
        return {}
    other = ds["hit_other"].values
    out = {}
    for k in np.unique(other[other < 0]):
        i = -int(k) - 1
        out[names[i] if i < len(names) and names[i] else f"obstacle {i}"] = int(np.sum(other == k))
    # one record per log-log contact (the contact model writes one hit per pair, as the
    # trajectory file, its figure and driftlog info count them)
    out["log-log"] = int(np.sum(other >= 0))
    return out


def compare_trajectories(ref_path, other_path, line=None):
    """Trajectory differences between two runs of the same logs (matched by log id and time)."""
    a, b = open_trajectories(ref_path), open_trajectories(other_path)
    if a.sizes["trajectory"] != b.sizes["trajectory"]:
        raise DriftlogError(f"{other_path}: {b.sizes['trajectory']} logs, the reference "
                            f"{ref_path} has {a.sizes['trajectory']}: not the same scenario")
    # match observations of the same log at the same time (integer keys, no Python loop)
    ta, tb = np.round(a["time"].values, 9), np.round(b["time"].values, 9)
    ut = np.unique(np.concatenate([ta, tb]))
    ka = a["trajectory_index"].values.astype(np.int64) * ut.size + np.searchsorted(ut, ta)
    kb = b["trajectory_index"].values.astype(np.int64) * ut.size + np.searchsorted(ut, tb)
    _, pa, pb = np.intersect1d(ka, kb, assume_unique=True, return_indices=True)
    if pa.size == 0:
        def span(ds):
            t = ds["time"].values
            return f"{t.min():g} to {t.max():g} s" if t.size else "no records"

        raise DriftlogError(f"{other_path}: no record at the same time as the reference "
                            f"{ref_path} (times {span(b)} against {span(a)}): not runs of the "
                            "same scenario and output times")
    dist = np.hypot(a["x"].values[pa] - b["x"].values[pb], a["y"].values[pa] - b["y"].values[pb])
    times = a["time"].values[pa]
    ut = np.unique(times)
    mean_d = np.array([dist[times == tt].mean() for tt in ut])
    max_d = np.array([dist[times == tt].max() for tt in ut])
    arr_a, arr_b = arrival_times(a, line), arrival_times(b, line)
    names = STATUS_MEANINGS.split()

    def finals(ds):
        ti, t, st = ds["trajectory_index"].values, ds["time"].values, ds["status"].values
        order = np.lexsort((t, ti))
        last = order[np.flatnonzero(np.diff(np.append(ti[order], -1)) != 0)]
        return {names[c]: int(np.sum(st[last] == c)) for c in np.unique(st[last])}

    return {
        "times": ut, "mean_distance": mean_d, "max_distance": max_d,
        "end_reference": float(a["time"].values.max()),
        "end_other": float(b["time"].values.max()),
        "arrival_reference": arr_a, "arrival_other": arr_b,
        "arrival_difference": arr_b - arr_a,
        "final_status_reference": finals(a), "final_status_other": finals(b),
        "hits_reference": _hits_per_obstacle(a), "hits_other": _hits_per_obstacle(b),
    }


def final_time_text(result):
    """When ``compare_trajectories``' final distance is taken: the last time both files record.

    "at the end", or, when one file runs on longer than the other, that time and both ends.
    """
    t = float(result["times"][-1])
    ea, eb = result["end_reference"], result["end_other"]
    if ea == eb == t:
        return "at the end"
    return (f"at t = {t:g} s, the last time both record (the reference ends at {ea:g} s, the "
            f"other at {eb:g} s)")


def compare_runs(scenario, flows: list[tuple[str, str]], out_dir, line=None, progress=False,
                 lines=None):
    """Track the scenario on each flow; compare each run with the first. Writes a report.

    ``flows``: (name, source) pairs; source is a flow file, a model output, 'scenario', or a
    FlowField already opened (``engine_flows``).  ``lines``: named arrival lines
    {name: (x0, y0, x1, y1)}, reported per log.
    Returns the report dict (also written as compare.json and compare.md, with compare.png).
    """
    from driftlog.adapters.compare import flow_differences, summarize_differences
    from driftlog.api import as_scenario, track

    if len(flows) < 2:
        raise DriftlogError("driftlog compare needs two flows or more (--flow NAME=SOURCE)")
    names = [name for name, _ in flows]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise DriftlogError(f"driftlog compare: the flow name {twice[0]!r} is given twice; each "
                            "flow needs a name of its own (its run is kept by its name)")
    scen = as_scenario(scenario)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fields, runs = {}, {}
    for name, src in flows:
        fields[name] = _open_source(src, scen)
        runs[name] = track(scen, flow=fields[name], output=out_dir / f"trajectories_{name}.nc",
                           progress=progress).path
    ref = flows[0][0]
    ds_ref = open_trajectories(runs[ref])
    report = {"reference": ref,
              "flows": {k: (v if isinstance(v, (str, Path)) else getattr(v, "name", k))
                        for k, v in flows},
              "runs": {k: str(v) for k, v in runs.items()}, "comparisons": {},
              "lines": {k: list(v) for k, v in (lines or {}).items()}}
    for name, _ in flows[1:]:
        traj = compare_trajectories(runs[ref], runs[name], line)
        diff = flow_differences(fields[ref], fields[name], ds_ref["x"].values,
                                ds_ref["y"].values, ds_ref["time"].values)
        speed_diff = diff["speed"]
        report["comparisons"][name] = {
            "flow_at_logs": summarize_differences(diff),
            "distance_final_mean": float(traj["mean_distance"][-1]),
            "distance_max": float(traj["max_distance"].max()),
            "arrival_difference_mean": _nanmean(traj["arrival_difference"]),
            "arrived_reference": int(np.isfinite(traj["arrival_reference"]).sum()),
            "arrived_other": int(np.isfinite(traj["arrival_other"]).sum()),
            "final_status": {ref: traj["final_status_reference"],
                             name: traj["final_status_other"]},
            "hits": {ref: traj["hits_reference"], name: traj["hits_other"]},
        }
        rows = per_log(runs[ref], runs[name], lines)
        d = np.array([r["end_distance"] for r in rows])
        report["comparisons"][name].update({
            "end_distance_mean": _nanmean(d),
            "end_distance_max": float(np.nanmax(d)) if np.any(np.isfinite(d)) else None,
            "arrival_at_lines": {k: {ref: _count_mean([r["arrival"][k][0] for r in rows]),
                                     name: _count_mean([r["arrival"][k][1] for r in rows])}
                                 for k in (lines or {})},
            "logs": rows})
        report["comparisons"][name]["_series"] = (traj, speed_diff, ds_ref["time"].values)
    _figure(report, runs, fields, out_dir / "compare.png")
    for c in report["comparisons"].values():
        c.pop("_series")
    (out_dir / "compare.json").write_text(json.dumps(report, indent=2, default=_jsonable))
    (out_dir / "compare.md").write_text(_markdown(report))
    return report


def write_trajectory_comparison(result, ref_path, other_path, out_dir):
    """Write a two-file comparison (``compare_trajectories``) as compare.json and compare.md.

    Both go to ``out_dir`` (created); returns their paths.
    """
    from driftlog.files import atomic_output, check_output_dir

    out_dir = check_output_dir(out_dir, "comparison folder")
    data = {"reference": str(ref_path), "other": str(other_path),
            "mean_distance_final": float(result["mean_distance"][-1]),
            "max_distance": float(result["max_distance"].max()),
            "arrival_difference_mean": _nanmean(result["arrival_difference"]),
            "final_status": {"reference": result["final_status_reference"],
                             "other": result["final_status_other"]},
            "hits": {"reference": result["hits_reference"], "other": result["hits_other"]},
            "series": {k: result[k] for k in ("times", "mean_distance", "max_distance")}}
    md = "\n".join(["# Comparison of two trajectory files", "",
                    f"- reference: {ref_path}", f"- other: {other_path}",
                    f"- mean distance {final_time_text(result)}: "
                    f"{data['mean_distance_final']:.4g} m, max over the run: "
                    f"{data['max_distance']:.4g} m",
                    f"- final statuses: {data['final_status']['reference']} vs "
                    f"{data['final_status']['other']}",
                    f"- hits: {data['hits']['reference']} vs {data['hits']['other']}", ""])
    paths = []
    for name, text in (("compare.json", json.dumps(data, indent=2, default=_jsonable)),
                       ("compare.md", md)):
        with atomic_output(out_dir / name) as tmp:
            tmp.write_text(text)
        paths.append(out_dir / name)
    return paths


def _count_mean(values):
    v = np.array([np.nan if x is None else x for x in values], float)
    ok = np.isfinite(v)
    return {"crossed": int(ok.sum()), "mean_time": float(v[ok].mean()) if ok.any() else None}


def _nanmean(a):
    a = np.asarray(a, float)
    return float(np.nanmean(a)) if np.any(np.isfinite(a)) else None


def _jsonable(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def _markdown(report):
    ref = report["reference"]
    lines = [f"# Comparison of hydro sources (reference: {ref})", "",
             "| flow | depth RMS at logs (m) | speed RMS at logs (m/s) | wet mismatch | final mean "
             "distance (m) | max distance (m) | mean arrival difference (s) | arrived |",
             "|---|---|---|---|---|---|---|---|"]
    for name, c in report["comparisons"].items():
        f = c["flow_at_logs"]
        ad = c["arrival_difference_mean"]
        lines.append(f"| {name} | {f['depth_rms']:.3g} | {f['speed_rms']:.3g} | "
                     f"{f['wet_mismatch']} | {c['distance_final_mean']:.3g} | "
                     f"{c['distance_max']:.3g} | {'-' if ad is None else f'{ad:.3g}'} | "
                     f"{c['arrived_other']} vs {c['arrived_reference']} |")
    lines.append("")
    for name, c in report["comparisons"].items():
        lines.append(f"- {name}: final statuses {c['final_status']}, hits {c['hits']}")
    for name, c in report["comparisons"].items():
        gates = list(report.get("lines") or {})
        lines += ["", f"## Per log: {ref} vs {name}", "",
                  f"End distance: mean {_fmt(c['end_distance_mean'])} m, max "
                  f"{_fmt(c['end_distance_max'])} m.", ""]
        for g, v in c.get("arrival_at_lines", {}).items():
            lines.append(f"- line {g}: crossed by {v[ref]['crossed']} ({ref}) and "
                         f"{v[name]['crossed']} ({name}) logs, mean time "
                         f"{_fmt(v[ref]['mean_time'])} s vs {_fmt(v[name]['mean_time'])} s")
        lines += ["", "| log | end (x, y) " + ref + " | end (x, y) " + name + " | distance (m) "
                  "| status | " + " | ".join(f"arrival {g} (s)" for g in gates) +
                  (" | " if gates else "") + "hits " + ref + " | hits " + name + " |",
                  "|---" * (7 + len(gates)) + "|"]
        for r in c["logs"]:
            ea, eb = r["end_reference"], r["end_other"]
            arr = [f"{_fmt(r['arrival'][g][0])} / {_fmt(r['arrival'][g][1])}" for g in gates]
            lines.append(
                f"| {r['log']} | {ea[0]:.1f}, {ea[1]:.1f} | {eb[0]:.1f}, {eb[1]:.1f} | "
                f"{r['end_distance']:.3g} | {r['status_reference']} / {r['status_other']} | "
                + "".join(f"{a} | " for a in arr) + f"{_hits_text(r['hits_reference'])} | "
                f"{_hits_text(r['hits_other'])} |")
    return "\n".join(lines) + "\n"


def _fmt(v):
    return "-" if v is None or not np.isfinite(v) else f"{v:.4g}"


def _hits_text(h):
    return ", ".join(f"{k} {v}" for k, v in sorted(h.items())) or "-"


def _speed_difference_map(ax, fig, report, runs, fields):
    """Under the trajectories: the speed of the first other flow minus the reference's.

    On the reference's faces, at the logs' start time (the flows are sampled there).
    """
    names = list(report["comparisons"])
    ref = fields[report["reference"]]
    mesh = getattr(ref, "mesh", None)
    if not names or mesh is None:
        return
    from driftlog.adapters.compare import flow_differences

    t0 = float(np.nanmin(open_trajectories(runs[report["reference"]])["time"].values))
    x, y = mesh.face_x, mesh.face_y
    d = flow_differences(ref, fields[names[0]], x, y, np.full(x.size, t0))["speed"]
    lim = float(np.nanmax(np.abs(d))) if np.any(np.isfinite(d)) else 1.0
    from matplotlib.collections import PolyCollection

    fn = np.where(mesh.face_nodes >= 0, mesh.face_nodes, mesh.face_nodes[:, :1])
    verts = np.stack([mesh.node_x[fn], mesh.node_y[fn]], axis=-1)
    pc = PolyCollection(verts, array=np.ma.masked_invalid(d), cmap="RdBu_r",
                        edgecolors="face", linewidths=0.0, zorder=0)
    pc.set_clim(-lim, lim)
    ax.add_collection(pc)
    fig.colorbar(pc, ax=ax, shrink=0.9, pad=0.01,
                 label=f"speed (m/s), {names[0]}\nminus {report['reference']}, t = {t0:g} s")


def _figure(report, runs, fields, out):
    from driftlog.plots import _mpl

    plt = _mpl()
    # the map on top, across, at the domain's aspect; the series below
    mesh = getattr(fields[report["reference"]], "mesh", None)
    aspect = 0.6
    if mesh is not None:
        aspect = float(np.ptp(mesh.node_y) / max(np.ptp(mesh.node_x), 1e-300))
    map_h = float(np.clip(12.0 * aspect, 2.2, 8.0))
    fig = plt.figure(figsize=(14, map_h + 4.8))
    gs = fig.add_gridspec(2, 2, height_ratios=[map_h, 4.2])
    axes = [fig.add_subplot(gs[0, :]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[1, 1])]
    ax = axes[0]
    colors = plt.get_cmap("tab10")
    _speed_difference_map(ax, fig, report, runs, fields)
    for k, (name, path) in enumerate(runs.items()):
        ds = open_trajectories(path)
        ti = ds["trajectory_index"].values
        for j in range(ds.sizes["trajectory"]):
            sel = ti == j
            ax.plot(ds["x"].values[sel], ds["y"].values[sel], color=colors(k), lw=1.2,
                    label=name if j == 0 else None)
    if mesh is not None:
        walls = mesh.boundary_segments(["wall"])
        ax.plot(walls[:, [0, 2]].T, walls[:, [1, 3]].T, color="k", lw=0.6)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("trajectories over the difference of the flows' speeds")
    ax.legend(fontsize=8, loc="upper right")
    for k, (name, c) in enumerate(report["comparisons"].items(), start=1):
        traj, speed_diff, t = c["_series"]
        axes[1].plot(traj["times"], traj["mean_distance"], color=colors(k), label=f"{name}: mean")
        axes[1].plot(traj["times"], traj["max_distance"], color=colors(k), ls="--",
                     label=f"{name}: max")
        ut = np.unique(t)
        rms = [np.sqrt(np.nanmean(speed_diff[t == tt] ** 2)) for tt in ut]
        axes[2].plot(ut, rms, color=colors(k), label=name)
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel(f"distance to {report['reference']} run (m)")
    axes[1].set_title("same log, two flows")
    axes[1].legend(fontsize=8, loc="upper left")
    axes[2].set_xlabel("time (s)")
    axes[2].set_ylabel("RMS flow speed difference at the logs (m/s)")
    axes[2].set_title("flows at the reference logs")
    axes[2].legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
