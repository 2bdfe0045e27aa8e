"""Validation of two-way coupling: backwater of a fixed log array and of a jam at a bridge.

(a) + (c): a fixed array of two logs (1.8 m, 0.15 m radius, broadside, held by posts) across a
4 m channel carrying 1 m2/s on 1 m of water: the rise of the level 3-8 m upstream against the
one-dimensional momentum balance with the logs' drag (docs/model.md eq. (76)), at four mesh
sizes, 1 m to 0.125 m (the test runs the 0.5 m one, tests/test_coupling.py).

(b): cases/bridge_jam/coupled.toml: 30 logs jam at a deck across a 7 m channel; the level
along the channel at the end against the same flow without logs (a figure), the backwater
2-12 m upstream of the deck, the deck's force (contact impulses and the entrained water's,
(73)), and the backwater the momentum balance (76) gives for that force.

(c) on a jam: a packed jam (three rows of two logs, 1.8 m x 0.1 m, held broadside by a deck
across a 4 m channel and by one another through Moreau-Jean contacts) on meshes of 1 m to
0.25 m in steps of sqrt(2): the backwater, the deck's force, the backwater per unit force,
their changes from mesh to mesh and observed orders (the test runs the three coarsest,
tests/test_coupling.py).  Writes coupling_convergence{.md,.csv,.json}.

Exchange intervals (``--only intervals``): (a) on the 0.5 m mesh with the reaction exchanged
every 0.25, 0.5 and 1 s (docs/model.md 17.6), event-driven and Moreau-Jean contacts.  Writes
coupling_intervals{.md,.csv,.json}.

(d) cases/river_piers/coupled.toml: a raft of 9 logs of 44 m held at the deck of the first
bridge (its pier group) of the river; the level upstream of it against the same flow without
logs.  Writes
coupling_river_piers{.md,.json} and coupling_river_piers.png.

Writes benchmarks/results/coupling_validation{.md,.csv,.json} ((a), (b): the rows of the parts
not run are kept from the last run) and coupling_backwater.png.

    python benchmarks/coupling_validation.py             # all
    python benchmarks/coupling_validation.py --skip-fine # without the finest meshes
    python benchmarks/coupling_validation.py --only jam --out DIR [--reuse]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from _common import RESULTS, machine, write_table  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
JAM = ROOT / "cases" / "bridge_jam" / "coupled.toml"
PIERS = ROOT / "cases" / "river_piers" / "coupled.toml"
G = 9.81


def fixed_array(cells):
    """Rows of (a)/(c): measured and predicted backwater at each mesh size."""
    from test_coupling import array_backwater

    rows = []
    for cell in cells:
        t0 = time.perf_counter()
        measured, predicted, force, drag = array_backwater(cell)
        rows.append(dict(case="(a) fixed array of 2 logs", cell_m=cell,
                         measured_mm=1e3 * measured, predicted_mm=1e3 * predicted,
                         error_pct=100 * (measured / predicted - 1), force_N=force, drag_N=drag,
                         wall_s=time.perf_counter() - t0))
        print(rows[-1], flush=True)
    return rows


def exchange_intervals(intervals, cell=0.5):
    """(a) on one mesh with exchange intervals (docs/model.md 17.6), both contact methods.

    Event-driven and Moreau-Jean contacts hold the logs on their posts; with Moreau-Jean also
    with the logs' sub-steps bounded by 0.03 s (``[integrator] max_step``, about the solver's
    step), as 17.6 advises for coupled Moreau-Jean jams, and by 0.01 s.
    """
    from test_coupling import array_backwater

    from driftlog.stepping import StepOptions

    rows = []
    for method, max_step in (("event", None), ("moreau", None), ("moreau", 0.03),
                             ("moreau", 0.01)):
        for interval in intervals:
            t0 = time.perf_counter()
            step = StepOptions(max_step=max_step) if max_step else None
            measured, predicted, force, drag = array_backwater(cell, method=method,
                                                               interval=interval, step=step)
            rows.append(dict(contacts=method, max_step_s=max_step or "-", interval_s=interval,
                             cell_m=cell, measured_mm=1e3 * measured,
                             predicted_mm=1e3 * predicted, ratio=measured / predicted,
                             force_N=force, drag_N=drag, wall_s=time.perf_counter() - t0))
            print(rows[-1], flush=True)
    return rows


def _coupled_and_alone(scen, done, reuse, stored_wall):
    """The coupled run (or, with ``reuse``, the one stored in ``done``) and the same flow
    solved without logs to the run's end: (result, wall s, reference solver, coupled flow).

    ``stored_wall()``: the earlier call's wall time from its results file, or nan."""
    import netCDF4

    from driftlog.api import track
    from driftlog.flowfile import open_flow
    from driftlog.solver.config import build_solver

    if reuse and done.exists():  # the coupled run of an earlier call: only the rest again
        res, wall = _stored_run(done), stored_wall()
    else:
        t0 = time.perf_counter()
        res = track(scen, output=done)
        wall = time.perf_counter() - t0
    ref = build_solver(scen["solver"])
    ref.advance_to(scen["time"]["end"])
    with netCDF4.Dataset(res.path) as ds:
        flow = open_flow(Path(ds.getncattr("coupled_flow")))
    return res, wall, ref, flow


def _stored_wall(name, pick):
    """A function giving the wall time ``pick`` finds in RESULTS/name, or nan."""
    def read():
        prev = RESULTS / name
        return pick(json.loads(prev.read_text())["rows"]) if prev.exists() else float("nan")
    return read


def _stored_run(path):
    """A coupled run's trajectory file as ``track`` returns it: path and the logs' last states."""
    from types import SimpleNamespace

    from driftlog.trajectory import open_trajectories

    with open_trajectories(path) as ds:
        ti, t = ds["trajectory_index"].values, ds["time"].values
        order = np.lexsort((t, ti))
        last = order[np.flatnonzero(np.diff(np.append(ti[order], -1)) != 0)]
        state = np.column_stack([ds[k].values[last]
                                 for k in ("x", "y", "theta", "u", "v", "omega")])
        radius, length = ds["radius"].values[ti[last]], ds["length"].values[ti[last]]
    return SimpleNamespace(path=path, logs=_Logs(state, radius, length))


class _Logs:
    """The last states and sizes of a stored run's logs (what ``jam_quantities`` reads)."""

    def __init__(self, state, radius, length):
        self.state, self.radius, self.length = state, np.asarray(radius), np.asarray(length)

    def __len__(self):
        return len(self.state)


def bridge_jam(out_dir, reuse=False):
    """(b): the coupled bridge_jam case and the same flow without logs; profile figure."""
    import netCDF4

    from driftlog.api import as_scenario

    scen = as_scenario(str(JAM))
    done = out_dir / "bridge_jam_coupled.nc"
    res, wall, ref, flow = _coupled_and_alone(scen, done, reuse, _stored_wall(
        "coupling_validation.json", lambda rows: next(
            (r["wall_s"] for r in rows if r["case"].startswith("(b)")), float("nan"))))
    t1 = scen["time"]["end"]
    snap = flow.snapshot(flow.times.size - 1)
    mesh = flow.mesh
    fx, fy = mesh.face_x, mesh.face_y
    mid = np.abs(fy) < 1.0
    order = np.argsort(fx[mid])
    x = fx[mid][order]
    eta_jam = snap["eta"][mid][order]
    eta_ref = (ref.h + ref.bed)[mid][order]
    up = (fx > 15.0 - 12.0) & (fx < 15.0 - 2.0)
    rise = float((snap["eta"][up] - (ref.h + ref.bed)[up]).mean())
    # the deck's force over the last 60 s: from the trajectory file's contact hits is not a
    # force; the coupled run's momentum given to the water over its last part is
    L = res.logs
    at_deck = int(((L.state[:, 0] > 10.0) & (L.state[:, 0] < 15.0)).sum())
    with netCDF4.Dataset(res.path) as ds:
        given = float(ds.getncattr("coupling_momentum_given_x"))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.plot(x, eta_ref, ".", ms=2, color="0.5", label="without logs")
    ax.plot(x, eta_jam, ".", ms=2, color="C0", label=f"with the jam ({at_deck} logs at the deck)")
    ax.axvspan(15.0, 16.0, color="C3", alpha=0.3, label="deck")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("water level (m), |y| < 1 m")
    ax.set_title(f"bridge_jam, coupled: level at t = {t1:g} s")
    ax.legend(loc="upper right")
    fig.tight_layout()
    RESULTS.mkdir(parents=True, exist_ok=True)
    fig.savefig(RESULTS / "coupling_backwater.png", dpi=130)
    # the jam's force from the level difference it holds, (76) reversed, at the mean depth
    h_up = float(snap["h"][up].mean())
    q = 1.0
    force_from_levels = G * h_up * rise * (1 - q * q / (G * h_up ** 3)) * 1000 * 7.0
    row = dict(case=f"(b) bridge_jam coupled, {len(L)} logs", cell_m=scen["solver"]["cell_size"],
               measured_mm=1e3 * rise, logs_at_deck=at_deck, wall_s=wall,
               momentum_given_x=given, force_from_levels_N=force_from_levels)
    row.update(jam_quantities(L, ref, up, deck_x=15.0, width=7.0, q=q, rise=rise))
    return row


def jam_quantities(logs, ref, up, deck_x, width, q, rise):
    """The quantities flume relations for backwater at wood accumulations are written in.

    Approach flow of the same channel without logs (h0: mean depth over ``up``; U0 = q / h0;
    F0 = U0 / sqrt(g h0)), the relative backwater dh / h0, and the accumulation: the logs held
    upstream of the deck (within 15 m of it, speed below 0.05 m/s), their wood volume
    V = sum pi r^2 L, the accumulation length L_a (deck face to the most upstream end of a held
    log, streamwise), its thickness T (one layer of floating logs: the diameter 2 r; the
    plan-view model has no second layer), the bulk volume W L_a T, the porosity
    1 - V / (W L_a T) and Hartlieb's (2017) compactness T / L_a.
    """
    h0 = float(ref.h[up].mean())
    u0 = q / h0
    x, th = logs.state[:, 0], logs.state[:, 2]
    speed = np.hypot(logs.state[:, 3], logs.state[:, 4])
    held = (x > deck_x - 15.0) & (x < deck_x) & (speed < 0.05)
    r, ln = logs.radius[held], logs.length[held]
    ext = 0.5 * ln * np.abs(np.cos(th[held])) + r * np.abs(np.sin(th[held]))
    la = float(deck_x - (x[held] - ext).min()) if held.any() else 0.0
    thick = float(2 * r.max()) if held.any() else 0.0
    vol = float((np.pi * r * r * ln).sum())
    bulk = width * la * thick
    return dict(h0_m=h0, U0_ms=u0, F0=u0 / np.sqrt(G * h0), dh_over_h0=rise / h0,
                logs_held=int(held.sum()), wood_volume_m3=vol, accumulation_length_m=la,
                thickness_m=thick, porosity=1 - vol / bulk if bulk > 0 else np.nan,
                compactness=thick / la if la > 0 else np.nan)


def packed_jam(cells, half_step=None):
    """(c): the packed jam on each mesh: backwater, deck force, backwater per unit force.

    ``half_step``: a mesh size run once more at half the CFL number (the last row).
    """
    from test_coupling import packed_jam_backwater

    rows = []
    for cell, cfl in [(c, 0.9) for c in cells] + ([(half_step, 0.45)] if half_step else []):
        t0 = time.perf_counter()
        d = packed_jam_backwater(cell, cfl=cfl)
        rows.append(dict(case="(c) packed jam of 6 logs at a deck", cell_m=cell, cfl=cfl,
                         measured_mm=1e3 * d["rise"], deck_force_N=d["force"],
                         mm_per_kN=1e6 * d["per_force"], from_force_mm=1e3 * d["from_force"],
                         from_drag_mm=1e3 * d["from_drag"], log_speed_ms=d["log_speed"],
                         max_log_shift_m=d["moved"], wall_s=time.perf_counter() - t0))
        for k in ("measured_mm", "mm_per_kN"):
            if cfl != 0.9:
                break
            if len(rows) > 1:
                rows[-1][f"change_{k}"] = rows[-1][k] - rows[-2][k]
            if len(rows) > 2:  # (79), cells in a constant ratio
                ratio = rows[-3]["cell_m"] / rows[-2]["cell_m"]
                rows[-1][f"order_{k}"] = (np.log(abs(rows[-2][f"change_{k}"])
                                                 / abs(rows[-1][f"change_{k}"])) / np.log(ratio))
        print(rows[-1], flush=True)
    return rows


def river_piers(out_dir, reuse=False):
    """(d): the coupled river_piers raft; the level upstream of bridge A with and without it."""

    from driftlog.api import as_scenario

    scen = as_scenario(str(PIERS))
    done = out_dir / "river_piers_coupled.nc"
    res, wall, ref, flow = _coupled_and_alone(scen, done, reuse, _stored_wall(
        "coupling_river_piers.json", lambda rows: rows[0].get("wall_s", float("nan"))))
    t1 = scen["time"]["end"]
    snap = flow.snapshot(flow.times.size - 1)
    fx, fy = flow.mesh.face_x, flow.mesh.face_y
    eta_ref = ref.h + ref.bed
    up = (fx > 450.0) & (fx < 580.0)          # the reach upstream of bridge A (x = 585)
    far = (fx > 100.0) & (fx < 300.0)
    down = (fx > 620.0) & (fx < 880.0)        # between the bridges
    rise = float((snap["eta"][up] - eta_ref[up]).mean())
    logs = res.logs
    x, y = logs.state[:, 0], logs.state[:, 1]
    # held at bridge A: still upstream of its piers' axis after 900 s in a 0.9 m/s river (the
    # recorded velocity of a log held by the projected contact solve is not zero: it carries
    # what the drag gave it over the step before the projection)
    at_a = (x > 450.0) & (x < 600.0)

    def discharge(hu, at=300.0):  # mean unit discharge of the faces about x = at, times W
        return float(hu[np.abs(fx - at) < 10.0].mean() * 170.0)

    q_ref, q_jam = discharge(ref.hu), discharge(snap["hu"])
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(2, 1, figsize=(9, 6.4), height_ratios=[1.1, 1])
    band = np.abs(fy - 85.0) < 20.0
    o = np.argsort(fx[band])
    ax.plot(fx[band][o], eta_ref[band][o], ".", ms=2, color="0.5", label="without logs")
    ax.plot(fx[band][o], snap["eta"][band][o], ".", ms=2, color="C0",
            label=f"coupled, {int(at_a.sum())} of {len(logs)} logs held at bridge A")
    for xb in (600.0, 900.0):
        ax.axvspan(xb - 15.0, xb + 15.0, color="C3", alpha=0.2)
    ax.set_ylabel("water level (m), |y - 85| < 20 m")
    ax.set_title(f"river_piers, coupled: level at t = {t1:g} s (piers shaded)")
    ax.legend(loc="upper right")
    d = 1e3 * (snap["eta"] - eta_ref)
    m = bx.scatter(fx, fy, c=d, s=9, marker="s", cmap="RdBu_r", vmin=-np.abs(d).max(),
                   vmax=np.abs(d).max())
    fig.colorbar(m, ax=bx, label="level change (mm)")
    th, ln = logs.state[:, 2], logs.length
    for xi, yi, ti, li in zip(x, y, th, ln, strict=True):
        c, sn = 0.5 * li * np.cos(ti), 0.5 * li * np.sin(ti)
        bx.plot([xi - c, xi + c], [yi - sn, yi + sn], "-", color="k", lw=1.5)
    for cx, cy in ((600.0, 56.67), (600.0, 113.33), (900.0, 42.5), (900.0, 127.5)):
        bx.add_patch(plt.Circle((cx, cy), 15.0, color="0.3"))
    bx.set_xlim(350.0, 1000.0)
    bx.set_aspect("equal")
    bx.set_xlabel("x (m)")
    bx.set_ylabel("y (m)")
    fig.tight_layout()
    RESULTS.mkdir(parents=True, exist_ok=True)
    fig.savefig(RESULTS / "coupling_river_piers.png", dpi=130)
    return dict(case=f"(d) river_piers coupled, raft of {len(logs)} logs",
                cell_m=scen["solver"]["cell_size"], rise_upstream_A_mm=1e3 * rise,
                rise_far_upstream_mm=1e3 * float((snap["eta"][far] - eta_ref[far]).mean()),
                change_between_bridges_mm=1e3 * float((snap["eta"][down]
                                                       - eta_ref[down]).mean()),
                discharge_without_m3s=q_ref, discharge_coupled_m3s=q_jam,
                logs_held_at_A=int(at_a.sum()), logs=len(logs), wall_s=wall)


def _merge(name, rows, parts):
    """Rows of this run, and those of the earlier run for the parts not run now."""
    prev = RESULTS / f"{name}.json"
    if prev.exists():
        kept = [r for r in json.loads(prev.read_text())["rows"] if r["case"][:3] not in parts]
        rows = kept + rows
    return sorted(rows, key=lambda r: r["case"][:3])


def _write(name, rows, cols, title, note):
    """RESULTS/name{.md,.csv} (``write_table``) and name.json (the rows and the machine)."""
    write_table(name, rows, cols, title, note)
    (RESULTS / f"{name}.json").write_text(json.dumps(
        dict(machine=machine(), rows=rows), indent=1, default=float))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-fine", action="store_true", help="no 0.25 m and 0.125 m meshes")
    ap.add_argument("--only", choices=("array", "intervals", "jam", "converge", "piers"),
                    default=None)
    ap.add_argument("--out", type=Path, default=None,
                    help="folder kept for the coupled run's files (default: a temporary one)")
    ap.add_argument("--reuse", action="store_true",
                    help="with --out: take the coupled run already there, redo only the rest")
    a = ap.parse_args(argv)
    import tempfile

    rows, parts = [], set()
    if a.only in (None, "array"):
        rows += fixed_array([1.0, 0.5] + ([] if a.skip_fine else [0.25, 0.125]))
        parts.add("(a)")
    if a.only in (None, "jam"):
        out = a.out or Path(tempfile.mkdtemp(prefix="driftlog-jam-"))
        out.mkdir(parents=True, exist_ok=True)
        rows.append(bridge_jam(out, reuse=a.reuse))
        parts.add("(b)")
        print(rows[-1], flush=True)
    if parts:
        rows = _merge("coupling_validation", rows, parts)
        cols = ["case", "cell_m", "measured_mm", "predicted_mm", "error_pct", "force_N",
                "drag_N", "logs_at_deck", "momentum_given_x", "force_from_levels_N", "h0_m",
                "F0", "dh_over_h0", "logs_held", "wood_volume_m3", "accumulation_length_m",
                "porosity", "compactness", "wall_s"]
        _write("coupling_validation", rows, cols, "Two-way coupling: backwater (issue 16)",
               "Backwater = level with logs minus level without, 3-8 m (a) or 2-12 m (b) "
               "upstream; predicted by the 1D momentum balance docs/model.md (76); "
               "(b): approach flow h0, F0 (77) and the accumulation (78) as flume "
               "relations take them.")
    if a.only in (None, "intervals"):
        rows_i = exchange_intervals([0.0, 0.25, 0.5, 1.0])
        _write("coupling_intervals", rows_i, list(rows_i[0]),
               "Two-way coupling (a) with exchange intervals (issue 16)",
               "The fixed array of (a) on 0.5 m cells (solver steps of about 0.03 s), "
               "its reaction exchanged every solver step (interval 0) or every 0.25, 0.5 "
               "and 1 s (docs/model.md 17.6); ratio: the backwater over the 1D momentum "
               "balance's (76); force: the mean force on the posts, drag: the logs' drag "
               "at the approach velocity; max_step: the logs' sub-steps bounded.")
    if a.only in (None, "converge"):
        conv = packed_jam([1.0, 0.5 ** 0.5, 0.5] + ([] if a.skip_fine else [0.5 ** 1.5, 0.25]),
                          half_step=0.5 ** 0.5)
        cols = ["case", "cell_m", "cfl", "measured_mm", "change_measured_mm", "order_measured_mm",
                "deck_force_N", "mm_per_kN", "change_mm_per_kN", "order_mm_per_kN",
                "from_force_mm", "from_drag_mm", "log_speed_ms", "max_log_shift_m", "wall_s"]
        _write("coupling_convergence", conv, cols,
               "Two-way coupling (c): a packed jam on five meshes (issue 16)",
               "Backwater 3-8 m upstream of the deck, mean over the last 30 s of 90 s "
               "coupled; the deck's mean force over the same 30 s; change from the next "
               "coarser mesh and observed order (79); from_force / from_drag: the rise "
               "(76) gives for the deck's force / for every log's drag at the approach "
               "velocity; log_speed: the held logs' mean speed; the last row: the 0.71 m mesh "
               "at half the step (CFL 0.45).")
    if a.only in (None, "piers"):
        out = a.out or Path(tempfile.mkdtemp(prefix="driftlog-piers-"))
        out.mkdir(parents=True, exist_ok=True)
        row = river_piers(out, reuse=a.reuse)
        cols = list(row)
        _write("coupling_river_piers", [row], cols,
               "Two-way coupling: the backwater of a raft at a pier group (issue 16)",
               "Level change (coupled minus the same flow without logs) at the end, mean "
               "over the faces 450-580 m (upstream of bridge A), 100-300 m and 620-880 m; "
               "discharge through x = 300 m.")


if __name__ == "__main__":
    main()
