"""Malpasset: how the computed arrival times depend on the depth that marks the arrival.

The benchmarks (``malpasset.py``, ``malpasset_peers.py``) take the arrival at a point as the
first time the depth of the face holding it exceeds the solver's arrival depth, 0.05 m, and
compare it with the scale model's arrival times (gauges G6-G14, 1:400, prototype units) and
the transformers' cut-off times (A, B, C).  Neither observation is a 5-cm depth: a 1:400
model's gauge reads millimetres (1 mm there is 0.4 m here) and a transformer fails when the
water reaches its equipment.  This runs the flood once (``--order``, the set-up of
``malpasset.py``) and records the depth at the 12 timed points after every step, then tables
the arrival time at each point for a range of arrival depths, and the arrival RMS over the 12.
Whether the computed front is a bore (the arrival hardly depends on the depth) or a thin
tongue (it does) at each point shows here.

    python benchmarks/malpasset_arrival_depth.py                # order 2, 1800 s
    python benchmarks/malpasset_arrival_depth.py --order 1
    python benchmarks/malpasset_arrival_depth.py --thin-fraction 0 --speeds   # films' speeds
    python benchmarks/malpasset_arrival_depth.py --order 1 --refine 1 --end 4000  # 186,764

writes benchmarks/results/malpasset_arrival_depth_o<order>.{md,json}.
"""

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import RESULTS, machine, write_table  # noqa: E402
from malpasset import data_dir  # noqa: E402

from driftlog.floodsetup import (  # noqa: E402
    MALPASSET_DAM,
    malpasset_solver,
    read_observations,
)
from driftlog.mesh import Mesh, read_mesh  # noqa: E402

DEPTHS = (0.001, 0.01, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0)  # m


def arrivals(times, depth, thresholds):
    """First time (s) each series' depth exceeds each threshold: (n_thresholds, n_points),
    NaN where never."""
    out = np.full((len(thresholds), depth.shape[1]), np.nan)
    for i, d in enumerate(thresholds):
        over = depth > d
        hit = over.any(0)
        out[i, hit] = times[over.argmax(0)[hit]]
    return out


def split4(mesh):
    """Each triangle into four through its edge midpoints (node bed: a midpoint's elevation is
    the mean of the edge's nodes, so the piecewise-linear bed surface is the same)."""
    if np.any(mesh.face_n != 3):
        raise SystemExit("split4: triangles only")
    t = mesh.face_nodes[:, :3]
    pairs = np.sort(np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], 1), axis=2)
    uniq, inv = np.unique(pairs.reshape(-1, 2), axis=0, return_inverse=True)
    mid = mesh.n_nodes + inv.reshape(-1, 3)  # m01, m12, m20
    x = np.concatenate([mesh.node_x, mesh.node_x[uniq].mean(1)])
    y = np.concatenate([mesh.node_y, mesh.node_y[uniq].mean(1)])
    z = np.concatenate([mesh.node_z, mesh.node_z[uniq].mean(1)])
    m01, m12, m20 = mid.T
    faces = np.concatenate([np.stack([t[:, 0], m01, m20], 1), np.stack([t[:, 1], m12, m01], 1),
                            np.stack([t[:, 2], m20, m12], 1), np.stack([m01, m12, m20], 1)])
    return Mesh(x, y, faces, node_z=z)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--order", type=int, default=2, choices=(1, 2))
    p.add_argument("--end", type=float, default=1800.0,
                   help="end time (s); the last observed arrival is C at 1420 s")
    p.add_argument("--thin-fraction", type=float, default=None,
                   help="order 2: docs/model.md (69)'s k (default: the solver's)")
    p.add_argument("--refine", type=int, default=0, help="split every triangle into four this "
                   "many times (the same bed surface, half the cell size each time)")
    p.add_argument("--speeds", action="store_true", help="also the largest speed in faces "
                   "under 1 mm deep and the flow's fastest wave over the run (slower)")
    a = p.parse_args(argv)
    obs = [o for o in read_observations(data_dir() / "observations.csv")
           if np.isfinite(o["arrival_s"])]
    opts = {} if a.thin_fraction is None else {"thin_fraction": a.thin_fraction}
    mesh = read_mesh(data_dir() / "malpasset_mesh.nc")
    for _ in range(a.refine):
        mesh = split4(mesh)
    s = malpasset_solver(mesh, order=a.order, **opts)
    faces = s.mesh.locate(np.array([o["x"] for o in obs]), np.array([o["y"] for o in obs]))
    if np.any(faces < 0):
        raise SystemExit("a timed point lies outside the mesh")
    # the solver's internal numbering (renumbered for locality): public[f] = internal[inv[f]]
    idx = s._inv[faces] if not s._identity else faces
    h0 = s.h.copy()
    s.step(1e-3)  # compile or load the kernels
    s.set_state(h0)
    times, depth = [0.0], [s._h[idx].copy()]
    # the largest speed in faces under 1 mm deep (a film) and the flow's fastest wave
    # |u| + sqrt(g h) over the faces deeper than 1 cm, over the run, and when
    fastest_film, fastest_wave = (0.0, 0.0), (0.0, 0.0)
    cpu = time.process_time()
    while s.t < a.end:
        s.step(a.end - s.t)
        times.append(s.t)
        depth.append(s._h[idx].copy())
        if a.speeds:
            h = s._h
            u = np.hypot(s._hu, s._hv) / np.maximum(h, s.dry_depth)
            film = (h > s.dry_depth) & (h < 1e-3)
            if film.any() and u[film].max() > fastest_film[0]:
                fastest_film = (float(u[film].max()), s.t)
            wet = h > 1e-2
            w = float(np.max(u[wet] + np.sqrt(s.gravity * h[wet])))
            if w > fastest_wave[0]:
                fastest_wave = (w, s.t)
    cpu = time.process_time() - cpu
    times, depth = np.array(times), np.array(depth)
    arr = arrivals(times, depth, DEPTHS)
    observed = np.array([o["arrival_s"] for o in obs])
    err = arr - observed
    rows = []
    for j, o in enumerate(obs):
        row = {"point": o["id"], "observed_s": o["arrival_s"],
               "max_depth_m": float(depth[:, j].max())}
        for i, d in enumerate(DEPTHS):
            row[f"err_{d:g}m_s"] = err[i, j]
        rows.append(row)
    rms = {f"err_{d:g}m_s": float(np.sqrt(np.nanmean(err[i] ** 2))) for i, d in enumerate(DEPTHS)}
    rows.append({"point": "RMS (12)", "observed_s": np.nan, "max_depth_m": np.nan, **rms})
    # the rise: seconds from 0.05 m to 1 m deep at each point (a bore: a step or two)
    i05, i1 = DEPTHS.index(0.05), DEPTHS.index(1.0)
    rise = arr[i1] - arr[i05]
    stem = f"malpasset_arrival_depth_o{a.order}" + (
        "" if a.thin_fraction is None else f"_k{a.thin_fraction:g}") + (
        f"_refine{a.refine}" if a.refine else "")
    levels, level_errors = "", None
    if a.end >= 4000.0:  # every level observation has peaked: the level RMSE as malpasset.py
        from malpasset_compare import extremes_points, headline

        ex = s.extremes.arrays()
        pts, _ = extremes_points(s.mesh, s.bed, ex["max_water_level"], ex["max_water_depth"],
                                 ex["arrival_time"], read_observations(
                                     data_dir() / "observations.csv"), MALPASSET_DAM,
                                 s.arrival_depth, a.end)
        head = headline(pts)
        g9 = next(r["level_error_m"] for r in pts if r["id"] == "G9")
        level_errors = {r["id"]: r["level_error_m"] for r in pts}
        levels = (f" Maximum level (4000 s): RMSE {head['level_rmse_m']:.2f} m over the "
                  f"{head['level_n']} wetted points, worst {head['worst_point']} "
                  f"{head['worst_error_m']:+.1f} m, G9 {g9:+.1f} m.")
    notes = (f"Malpasset, order {a.order}" + (f" (k = {a.thin_fraction:g})" if opts else "")
             + (f", every triangle split in four {a.refine}x ({s.mesh.n_faces} triangles)"
                if a.refine else "")
             + f", {a.end:g} s, {s.steps} steps, {cpu:.0f} CPU s, depth at the 12 timed "
             "points after every step. err_<d>: computed arrival (first time the depth of the "
             "face holding the point exceeds d) minus observed (s); the benchmarks use "
             "d = 0.05 m. Rise from 0.05 m to 1 m deep (s): "
             + ", ".join(f"{o['id']} {r:.0f}" for o, r in zip(obs, rise, strict=True)) + "."
             + (f" Largest speed in faces under 1 mm deep over the run: {fastest_film[0]:.2f} "
                f"m/s (t = {fastest_film[1]:.0f} s); the flow's fastest wave |u| + sqrt(g h) "
                f"(faces over 1 cm): {fastest_wave[0]:.2f} m/s (t = {fastest_wave[1]:.0f} s)."
                if a.speeds else "") + levels)
    columns = ["point", "observed_s", "max_depth_m"] + [f"err_{d:g}m_s" for d in DEPTHS]
    write_table(stem, rows, columns, f"Malpasset: arrival against the arrival depth "
                f"(order {a.order})", notes)
    (RESULTS / f"{stem}.json").write_text(json.dumps(
        {"order": a.order, "thin_fraction": s.thin_fraction, "end_s": a.end,
         "steps": s.steps, "cpu_s": cpu, "depths_m": list(DEPTHS), "faces": s.mesh.n_faces,
         "refine": a.refine, "levels": levels, "level_errors_m": level_errors,
         "points": [o["id"] for o in obs], "observed_s": observed.tolist(),
         "arrival_s": arr.tolist(), "rms_s": rms, "rise_005_to_1m_s": rise.tolist(),
         "fastest_film_m_s": fastest_film if a.speeds else None,
         "fastest_wave_m_s": fastest_wave if a.speeds else None,
         "machine": machine()}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
