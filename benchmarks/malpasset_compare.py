"""Malpasset: a stored flood run against the observations (tables, statistics, figures).

Used by ``malpasset.py``; reads only the flow file (its per-face extremes) and the
observations, so a stored run can be compared again without recomputing it.
"""

from __future__ import annotations

import json
from pathlib import Path

import netCDF4
import numpy as np

from driftlog.mesh import read_mesh

__all__ = ["compare", "point_results", "extremes_points", "statistics", "headline",
           "observed_reach", "chainage", "versus_table", "DISC"]

# m: the transformers' positions are given to the nearest 100 m (5500, 4400...): their
# arrival is also read as the first arrival within this distance
DISC = 100.0


def chainage(points, observations, dam):
    """Distance (m) down the valley: along the polyline dam centre -> G6 -> ... -> G14 -> C."""
    line = [np.mean(np.asarray(dam, float), axis=0)]
    line += [(o["x"], o["y"]) for o in observations if o["kind"] == "scale_model"]
    line += [(o["x"], o["y"]) for o in observations if o["id"] == "C"]
    line = np.asarray(line)
    seg = np.diff(line, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    start = np.concatenate([[0.0], np.cumsum(seg_len)])
    out = []
    for x, y in points:
        d = np.asarray([x, y]) - line[:-1]
        s = np.clip(np.sum(d * seg, axis=1) / seg_len ** 2, 0.0, 1.0)
        near = line[:-1] + s[:, None] * seg
        i = int(np.argmin(np.hypot(near[:, 0] - x, near[:, 1] - y)))
        out.append(start[i] + s[i] * seg_len[i])
    return np.asarray(out)


def point_results(flow, observations, dam):
    """Per observation point: its face, bed, computed maximum level and arrival time."""
    mesh = read_mesh(flow)
    with netCDF4.Dataset(flow) as ds:
        ds.set_auto_mask(False)
        max_level = np.array(ds.variables["max_water_level"][:])
        max_depth = np.array(ds.variables["max_water_depth"][:])
        arrival = np.array(ds.variables["arrival_time"][:])
        bed = np.array(ds.variables["bed_level"][:])
        end = float(ds.variables["time"][-1])
        arrival_depth = float(ds.getncattr("arrival_depth"))
    return extremes_points(mesh, bed, max_level, max_depth, arrival, observations, dam,
                           arrival_depth, end)


def extremes_points(mesh, bed, max_level, max_depth, arrival, observations, dam,
                    arrival_depth, end):
    """Per observation point, from per-face extremes of any solver on ``mesh``.

    Parameters
    ----------
    mesh : driftlog.mesh.Mesh
        The mesh the extremes are given on (one value per face).
    bed, max_level, max_depth, arrival : arrays (n_faces,)
        Bed (m), maximum water level (m), maximum depth (m) and arrival time (s, NaN: never).
    observations : list of dict
        ``driftlog.floodsetup.read_observations``.
    dam : sequence of two (x, y)
        The dam's ends (the chainage's origin).
    arrival_depth : float
        Depth (m) marking the arrival; a point is wet when its face got deeper than this.
    end : float
        The run's end time (s).

    Returns
    -------
    rows : list of dict
        Per point: face, bed, computed and observed level and arrival, errors (computed minus
        observed; NaN at dry points), ``wet``.
    extra : dict
        mesh, max_depth, end, arrival_depth (for the figures).
    """
    xy = np.array([(o["x"], o["y"]) for o in observations])
    faces = mesh.locate(xy[:, 0], xy[:, 1])
    km = chainage(xy, observations, dam)
    flooded = np.flatnonzero(max_depth > arrival_depth)
    if flooded.size == 0:
        flooded = np.arange(mesh.n_faces)  # nothing flooded: "nearest" reports any face
    rows = []
    for o, f, c in zip(observations, faces, km, strict=True):
        wet = f >= 0 and max_depth[f] > arrival_depth
        r = np.hypot(mesh.face_x - o["x"], mesh.face_y - o["y"])
        near = flooded[np.argmin(r[flooded])]  # the nearest face the flood reached
        disc = r <= DISC
        rows.append({
            "id": o["id"], "kind": o["kind"], "x": o["x"], "y": o["y"], "chainage_m": float(c),
            "face": int(f), "bed_m": float(bed[f]) if f >= 0 else np.nan,
            "observed_level_m": o["max_level_m"],
            "computed_level_m": float(max_level[f]) if wet else np.nan,
            "level_error_m": float(max_level[f] - o["max_level_m"]) if wet else np.nan,
            "max_depth_m": float(max_depth[f]) if f >= 0 else np.nan,
            "observed_arrival_s": o["arrival_s"],
            "computed_arrival_s": float(arrival[f]) if f >= 0 else np.nan,
            "arrival_error_s": float(arrival[f] - o["arrival_s"]) if f >= 0 else np.nan,
            "wet": bool(wet),
            "nearest_flooded_m": float(r[near]), "nearest_flooded_level_m": float(max_level[near]),
            "nearest_flooded_bed_m": float(bed[near]),
            "disc_arrival_s": float(np.nanmin(arrival[disc])) if np.any(
                np.isfinite(arrival[disc])) else np.nan})
    return rows, dict(mesh=mesh, max_depth=max_depth, end=end, arrival_depth=arrival_depth)


def _stats(errors):
    e = np.asarray([v for v in errors if np.isfinite(v)])
    if e.size == 0:
        return {"n": 0, "rmse": np.nan, "mean": np.nan, "max_abs": np.nan}
    return {"n": int(e.size), "rmse": float(np.sqrt(np.mean(e ** 2))),
            "mean": float(np.mean(e)), "max_abs": float(np.max(np.abs(e)))}


def statistics(rows):
    """RMSE, mean error (computed - observed) and largest error of levels and arrival times."""
    lev = {"police points": [r for r in rows if r["kind"] == "field"],
           "gauges": [r for r in rows if r["kind"] == "scale_model"]}
    lev["all"] = lev["police points"] + lev["gauges"]
    arr = {"gauges": [r for r in rows if r["kind"] == "scale_model"],
           "transformers": [r for r in rows if r["kind"] == "transformer"]}
    arr["all"] = arr["gauges"] + arr["transformers"]
    out = {}
    for k, rs in lev.items():
        s = _stats([r["level_error_m"] for r in rs])
        s["dry"] = [r["id"] for r in rs if not r["wet"]]
        out[f"max level, {k} (m)"] = s
    for k, rs in arr.items():
        s = _stats([r["arrival_error_s"] for r in rs if np.isfinite(r["observed_arrival_s"])])
        s["not reached"] = [r["id"] for r in rs if not np.isfinite(r["computed_arrival_s"])]
        out[f"arrival, {k} (s)"] = s
    s = _stats([r["disc_arrival_s"] - r["observed_arrival_s"] for r in arr["transformers"]])
    s["not reached"] = []
    out[f"arrival, transformers, first within {DISC:g} m (s)"] = s
    return out


def headline(rows):
    """The side-by-side numbers of a run: level RMSE, worst point, arrival RMS.

    Computed from ``statistics(rows)`` (the same numbers as the full table): the RMSE of the
    maximum level over the points with an observed level that the run wets (police points and
    gauges), the point with the largest absolute level error (id and signed error), and the
    RMS of the arrival error over the points with an observed arrival time that the run reaches
    (gauges and transformers).

    Parameters
    ----------
    rows : list of dict
        ``extremes_points`` / ``point_results`` rows (possibly a subset).

    Returns
    -------
    dict
        level_rmse_m, level_n, level_mean_m, worst_point, worst_error_m, dry (ids of points
        with an observed level left dry), arrival_rms_s, arrival_n, arrival_mean_s,
        not_reached (ids).
    """
    st = statistics(rows)
    lev, arr = st["max level, all (m)"], st["arrival, all (s)"]
    errs = [(abs(r["level_error_m"]), r["id"], r["level_error_m"]) for r in rows
            if r["kind"] in ("field", "scale_model") and np.isfinite(r["level_error_m"])]
    worst = max(errs) if errs else (np.nan, "-", np.nan)
    return {"level_rmse_m": lev["rmse"], "level_n": lev["n"], "level_mean_m": lev["mean"],
            "worst_point": worst[1], "worst_error_m": worst[2], "dry": list(lev["dry"]),
            "arrival_rms_s": arr["rmse"], "arrival_n": arr["n"], "arrival_mean_s": arr["mean"],
            "not_reached": list(arr["not reached"])}


def observed_reach(rows, t):
    """Points at most as far down the valley as the observed front at time ``t`` (s).

    The front's chainage at ``t`` is interpolated in the observed arrival times (gauges and
    transformers) against chainage; every point up to it is kept, whatever a run computed,
    so that reduced runs of different solvers are compared on the same points.
    """
    timed = sorted((r["observed_arrival_s"], r["chainage_m"]) for r in rows
                   if np.isfinite(r["observed_arrival_s"]))
    if not timed:
        return list(rows)
    ts, km = np.array(timed).T
    reach = float(np.interp(t, ts, np.maximum.accumulate(km), left=km[0], right=np.inf))
    return [r for r in rows if r["chainage_m"] <= reach]


def _fmt(v, nd=1):
    if isinstance(v, float):
        return "-" if not np.isfinite(v) else f"{v:.{nd}f}"
    return str(v)


def _markdown(rows, stats, facts, title, notes):
    lines = [f"### {title}", ""]
    if facts:
        lines += [f"Run: {facts['end_s']:g} s, order {facts['order']}, "
                  f"{facts['faces']} triangles, {facts['steps']} steps in "
                  f"{facts['wall_s']:.0f} s wall ({facts['cell_updates_per_s'] / 1e6:.2f} M "
                  f"cell-updates/s) on {facts['machine']}; volume balance error "
                  f"{facts['volume_error_m3']:.3g} m3 (relative "
                  f"{facts['relative_volume_error']:.2g}), {facts['sea_outflow_m3'] / 1e6:.2f} "
                  f"Mm3 out and {facts['sea_inflow_m3'] / 1e6:.2f} Mm3 in through the sea "
                  f"boundary (level {facts['sea_level_m']:g} m, {facts['sea_boundary']}).", ""]
    lines += ["| statistic | n | RMSE | mean error | largest error | dry / not reached |",
              "|---|---|---|---|---|---|"]
    for k, s in stats.items():
        miss = s.get("dry", s.get("not reached", []))
        lines.append(f"| {k} | {s['n']} | {_fmt(s['rmse'], 2)} | {_fmt(s['mean'], 2)} | "
                     f"{_fmt(s['max_abs'], 2)} | {', '.join(miss) or '-'} |")
    lines += ["", "| point | kind | chainage (km) | bed (m) | observed max level (m) | "
              "computed (m) | error (m) | observed arrival (s) | computed (s) | error (s) | "
              f"first within {DISC:g} m (s) |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        comp = _fmt(r["computed_level_m"], 2) if r["wet"] else (
            f"dry (bed above the observed level; nearest flooded face "
            f"{r['nearest_flooded_m']:.0f} m away: bed {r['nearest_flooded_bed_m']:.1f}, "
            f"max level {r['nearest_flooded_level_m']:.1f})"
            if np.isfinite(r["observed_level_m"]) and r["bed_m"] > r["observed_level_m"]
            else f"dry (nearest flooded face {r['nearest_flooded_m']:.0f} m away: max level "
                 f"{r['nearest_flooded_level_m']:.1f})" if np.isfinite(r["observed_level_m"])
            else "-")
        lines.append(f"| {r['id']} | {r['kind']} | {r['chainage_m'] / 1e3:.2f} | "
                     f"{_fmt(r['bed_m'], 2)} | {_fmt(r['observed_level_m'], 2)} | {comp} | "
                     f"{_fmt(r['level_error_m'], 2)} | {_fmt(r['observed_arrival_s'], 0)} | "
                     f"{_fmt(r['computed_arrival_s'], 0)} | {_fmt(r['arrival_error_s'], 0)} | "
                     f"{_fmt(r['disc_arrival_s'], 0)} |")
    if notes:
        lines += ["", notes]
    return "\n".join(lines) + "\n"


def _figures(rows, extra, observations, stem, results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    # observed vs computed maximum levels
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for kind, mk, lab in (("field", "o", "police points"), ("scale_model", "s", "gauges")):
        rs = [r for r in rows if r["kind"] == kind and r["wet"]]
        ax.plot([r["observed_level_m"] for r in rs], [r["computed_level_m"] for r in rs], mk,
                label=lab, mfc="none")
        for r in rs:
            ax.annotate(r["id"], (r["observed_level_m"], r["computed_level_m"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
    lo, hi = 0.0, 100.0
    ax.plot([lo, hi], [lo, hi], "k-", lw=0.8, label="1:1")
    ax.fill_between([lo, hi], [lo - 3, hi - 3], [lo + 3, hi + 3], color="0.9", label="+/- 3 m")
    ax.set(xlabel="observed maximum level (m)", ylabel="computed maximum level (m)",
           xlim=(lo, hi), ylim=(lo, hi), title="Malpasset: maximum water levels")
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(results / f"{stem}_levels.png", dpi=120)
    plt.close(fig)
    # arrival times down the valley
    fig, ax = plt.subplots(figsize=(7, 4.5))
    rs = [r for r in rows if np.isfinite(r["observed_arrival_s"])]
    ax.plot([r["chainage_m"] / 1e3 for r in rs], [r["observed_arrival_s"] for r in rs], "ko",
            mfc="none", label="observed (gauges G6-G14, transformers A-C)")
    ax.plot([r["chainage_m"] / 1e3 for r in rs], [r["computed_arrival_s"] for r in rs], "r^",
            label=f"computed (depth > {extra['arrival_depth']:g} m)")
    for r in rs:
        ax.annotate(r["id"], (r["chainage_m"] / 1e3, r["observed_arrival_s"]), fontsize=7,
                    xytext=(-14, 4), textcoords="offset points")
    ax.set(xlabel="distance down the valley from the dam (km)", ylabel="arrival time (s)",
           title="Malpasset: arrival of the flood wave")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(results / f"{stem}_arrival.png", dpi=120)
    plt.close(fig)
    # map of maximum depth
    mesh = extra["mesh"]
    tri = Triangulation(mesh.node_x, mesh.node_y, mesh.face_nodes[:, :3])
    depth = np.where(extra["max_depth"] > extra["arrival_depth"], extra["max_depth"], np.nan)
    fig, ax = plt.subplots(figsize=(11, 5))
    bed = ax.tripcolor(tri, facecolors=mesh.face_bed(), cmap="Greys", alpha=0.5)
    wet_tri = Triangulation(mesh.node_x, mesh.node_y, mesh.face_nodes[:, :3],
                            mask=~np.isfinite(depth))
    pc = ax.tripcolor(wet_tri, facecolors=np.nan_to_num(depth, nan=0.0), cmap="Blues",
                      vmin=0, vmax=min(60.0, float(np.nanmax(depth))))
    fig.colorbar(pc, ax=ax, label="maximum depth (m)", shrink=0.8)
    fig.colorbar(bed, ax=ax, label="bed (m)", shrink=0.8)
    for o in observations:
        ax.plot(o["x"], o["y"], "r." if o["kind"] != "transformer" else "m^", ms=4)
        ax.annotate(o["id"], (o["x"], o["y"]), fontsize=6, xytext=(2, 2),
                    textcoords="offset points")
    ax.set(aspect="equal", xlabel="x (m)", ylabel="y (m)",
           title=f"Malpasset: maximum depth over {extra['end']:g} s")
    fig.tight_layout()
    fig.savefig(results / f"{stem}_map.png", dpi=110)
    plt.close(fig)


def versus_table(rows, other, observations, dam):
    """Markdown: arrival times of this run and of another stored run (``other``, e.g. the
    second order over a shorter time) at the points the other run reached."""
    other_rows, extra = point_results(other, observations, dam)
    with netCDF4.Dataset(other) as ds:
        facts = {a: ds.getncattr(a) for a in ("solver_order",) if a in ds.ncattrs()}
    order = facts.get("solver_order", "?")
    lines = [f"Arrival times against a second run ({Path(other).name}: order {order}, "
             f"{extra['end']:g} s), at the points it reached (s; face / first within "
             f"{DISC:g} m):", "",
             "| point | observed | this run | other run |", "|---|---|---|---|"]
    for r, q in zip(rows, other_rows, strict=False):
        if not (np.isfinite(r["observed_arrival_s"]) and np.isfinite(q["computed_arrival_s"])):
            continue
        lines.append(f"| {r['id']} | {r['observed_arrival_s']:.0f} | "
                     f"{r['computed_arrival_s']:.0f} / {r['disc_arrival_s']:.0f} | "
                     f"{q['computed_arrival_s']:.0f} / {q['disc_arrival_s']:.0f} |")
    return "\n".join(lines)


def compare(flow, data, quick, dam, observations, results, notes="", versus=None):
    """Compare the stored run ``flow`` with the observations; write tables and figures."""
    flow = Path(flow)
    rows, extra = point_results(flow, observations, dam)
    facts_path = Path(str(flow) + ".json")
    facts = json.loads(facts_path.read_text()) if facts_path.is_file() else None
    if quick:
        # points the wave reaches in the first half of the run (the peak follows the front)
        km_reached = max([r["chainage_m"] for r in rows
                          if np.isfinite(r["computed_arrival_s"])
                          and r["computed_arrival_s"] <= extra["end"] / 2] or [0.0])
        rows = [r for r in rows if r["chainage_m"] <= km_reached]
    stats = statistics(rows)
    if versus is not None:
        notes = (notes + "\n\n" if notes else "") + versus_table(rows, versus, observations,
                                                               dam)
    stem = "malpasset_quick" if quick else "malpasset"
    title = (f"Malpasset dam break, driftlog solver, first {extra['end']:g} s (points reached "
             f"in the first half)" if quick else "Malpasset dam break, driftlog solver, 4000 s")
    notes = (notes + "\n\n" if notes else "") + (
        f"Computed maximum level: the solver's per-face maximum water level at the face holding "
        f"the point; 'dry' when that face never got deeper than {extra['arrival_depth']:g} m. "
        f"Arrival: first time the face's depth exceeds {extra['arrival_depth']:g} m. Errors are "
        "computed minus observed. Chainage: distance along the polyline dam, G6, ..., G14, C.")
    results.mkdir(parents=True, exist_ok=True)
    text = _markdown(rows, stats, facts, title, notes)
    (results / f"{stem}.md").write_text(text)
    (results / f"{stem}.json").write_text(json.dumps(
        {"run": facts, "statistics": stats, "points": rows}, indent=1, default=float))
    _figures(rows, extra, observations, stem, results)
    print(text)
    return rows, stats
