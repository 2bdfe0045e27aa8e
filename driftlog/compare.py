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
from pathlib import Path

import numpy as np

from driftlog.errors import DriftlogError
from driftlog.logs import LEFT, STATUS_MEANINGS
from driftlog.trajectory import open_trajectories

__all__ = ["compare_runs", "compare_trajectories", "arrival_times", "parse_flow_spec",
           "write_trajectory_comparison"]


def parse_flow_spec(spec: str):
    """``NAME=SOURCE`` or ``SOURCE``: a flow file, model output (auto-detected) or 'scenario'."""
    name, _, src = spec.partition("=") if "=" in spec else ("", "", spec)
    return (name or Path(src).stem or src), src


def _open_source(src, scenario):
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
        "arrival_reference": arr_a, "arrival_other": arr_b,
        "arrival_difference": arr_b - arr_a,
        "final_status_reference": finals(a), "final_status_other": finals(b),
        "hits_reference": _hits_per_obstacle(a), "hits_other": _hits_per_obstacle(b),
    }


def compare_runs(scenario, flows: list[tuple[str, str]], out_dir, line=None, progress=False):
    """Track the scenario on each flow; compare each run with the first. Writes a report.

    ``flows``: (name, source) pairs; source is a flow file, a model output, or 'scenario'.
    Returns the report dict (also written as compare.json and compare.md, with compare.png).
    """
    from driftlog.adapters.compare import flow_differences, summarize_differences
    from driftlog.api import as_scenario, track

    if len(flows) < 2:
        raise DriftlogError("driftlog compare needs two flows or more (--flow NAME=SOURCE)")
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
    report = {"reference": ref, "flows": dict(flows), "runs": {k: str(v) for k, v in runs.items()},
              "comparisons": {}}
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
                    f"- mean distance at the end: {data['mean_distance_final']:.4g} m, max over "
                    f"the run: {data['max_distance']:.4g} m",
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
    return "\n".join(lines) + "\n"


def _figure(report, runs, fields, out):
    from driftlog.plots import _mpl

    plt = _mpl()
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8), gridspec_kw={"width_ratios": [1.6, 1, 1]})
    ax = axes[0]
    colors = plt.get_cmap("tab10")
    for k, (name, path) in enumerate(runs.items()):
        ds = open_trajectories(path)
        ti = ds["trajectory_index"].values
        for j in range(ds.sizes["trajectory"]):
            sel = ti == j
            ax.plot(ds["x"].values[sel], ds["y"].values[sel], color=colors(k), lw=1.2,
                    label=name if j == 0 else None)
    mesh = getattr(fields[report["reference"]], "mesh", None)
    if mesh is not None:
        walls = mesh.boundary_segments(["wall"])
        ax.plot(walls[:, [0, 2]].T, walls[:, [1, 3]].T, color="k", lw=0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("trajectories")
    ax.legend(fontsize=8)
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
    axes[1].legend(fontsize=8)
    axes[2].set_xlabel("time (s)")
    axes[2].set_ylabel("RMS flow speed difference at the logs (m/s)")
    axes[2].set_title("flows at the reference logs")
    axes[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
