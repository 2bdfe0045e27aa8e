"""Bit-for-bit check of tracking results: sha256 of every output array of reduced-size runs.

Runs every case of cases/ at a reduced size (as tests/test_cases.py and tests/test_malpasset.py
shrink them: coarser solver meshes, shorter floods), an ensemble member summary replayed from
one of them, and direct ``Tracker`` runs on a mesh flow and on analytic flows covering each
integrator (euler, rk4, exponential), the fused and the general path, each physics level, and
both contact methods (event, moreau).  Writes a JSON of sha256 hashes of every array (trajectory
x, y, theta, u, v, omega, status, the flow at the logs, hits; the solver's flow files; the
member summary), so that a refactoring can be checked to change no number:

    PYTHONPATH=$PWD NUMBA_NUM_THREADS=1 python scripts/bitwise_check.py -o before.json
    ... change the code ...
    PYTHONPATH=$PWD NUMBA_NUM_THREADS=1 python scripts/bitwise_check.py --compare before.json

With ``--compare`` the exit code is 1 when any hash differs (the differing arrays are listed).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

# case -> overrides that shrink it (solver meshes coarser, floods shorter); the flow file goes
# to a temporary folder so that the solver runs every time (its output is hashed too)
CASES = {
    "beach": {"solver": {"cell_size": 4.0}},
    "bridge_jam": {"time": {"end": 20.0}},
    "channel_piers": {"time": {"end": 20.0}},
    "flume": {"solver": {"cell_size": 0.06, "end": 30.0}, "flow": {"steady_at": 30.0},
              "time": {"end": 20.0}},
    "malpasset": {"solver": {"end": 120.0, "output_interval": 10.0},
                  "time": {"end": 120.0, "output_interval": 10.0}},
    "river_piers": {"solver": {"cell_size": 30.0, "end": 600.0}, "flow": {"steady_at": 600.0},
                    "time": {"end": 600.0}},
    "vortex": {"time": {"end": 200.0}},
}


def digest(a) -> str:
    """sha256 of an array's dtype, shape and bytes."""
    a = np.ascontiguousarray(np.asarray(a))
    h = hashlib.sha256()
    h.update(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def netcdf_hashes(path) -> dict:
    """Hashes of every variable of a netCDF file (values as stored, no decoding)."""
    import netCDF4

    out = {}
    with netCDF4.Dataset(path) as ds:
        ds.set_auto_mask(False)
        ds.set_auto_scale(False)
        for name, var in ds.variables.items():
            if var.dtype == str:
                continue
            out[name] = digest(var[:])
    return out


def run_cases(tmp: Path, only=None) -> dict:
    """Hashes of every case of cases/ at reduced size (trajectories, stats, flow files)."""
    from driftlog.api import find_case, track
    from driftlog.ensemble import summarize_trajectories
    from driftlog.mesh import read_mesh

    out = {}
    for name, overrides in CASES.items():
        if only and name not in only:
            continue
        if name == "malpasset" and not (REPO / "cases" / "malpasset" / "data").is_dir():
            print("  malpasset: no data, skipped", file=sys.stderr)
            continue
        t0 = time.perf_counter()
        ov = json.loads(json.dumps(overrides))
        d = tmp / name
        d.mkdir()
        res = track(find_case(name), output=d / "traj.nc",
                    overrides={**ov, "flow": {**ov.get("flow", {}),
                                              "path": str(d / "flow.nc")}})
        out[f"case:{name}:trajectories"] = netcdf_hashes(res.path)
        out[f"case:{name}:stats"] = {k: digest(np.float64(v)) for k, v in res.stats.items()
                                     if k != "wall_seconds"}
        flow_file = d / "flow.nc"
        if flow_file.is_file():
            out[f"case:{name}:flow"] = netcdf_hashes(flow_file)
            if name == "river_piers":  # an ensemble member's summary, replayed (mesh sweep)
                s = summarize_trajectories(res.path, read_mesh(flow_file))
                out[f"case:{name}:member_summary"] = {
                    k: digest(getattr(s, k)) for k in (
                        "faces", "face_logs", "face_arrival", "status_counts", "idle_x",
                        "idle_y", "idle_status", "idle_face", "obstacle_hits", "obstacle_logs")}
        print(f"  case {name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return out


def _draining_channel():
    """Sheared, meandering mesh flow over a bank that dries (tests/test_fused.py's scene)."""
    sys.path.insert(0, str(REPO / "tests"))
    from conftest import draining_channel

    from driftlog.mesh import Mesh

    return draining_channel(Mesh.regular_grid(30, 10, 1.0), np.arange(0.0, 21.0, 4.0))


def _tracker_run(flow, level, rotation, method, fused, contact=None, n=120, t_end=20.0,
                 seed=7, max_step=0.7):
    from driftlog.logs import Logs
    from driftlog.physics import PhysicsOptions
    from driftlog.tracker import StepOptions, Tracker

    rng = np.random.default_rng(seed)
    if contact is not None:  # apart at the start: a grid, 2.5 m apart, logs 0.6 to 1 m long
        gx, gy = np.meshgrid(np.arange(n // 3) * 2.5, np.array([-2.5, 0.0, 2.5]))
        x = gx.ravel() + (2.0 if flow.mesh is not None else -12.0) + rng.uniform(0, 0.5, n)
        y = gy.ravel() + (5.0 if flow.mesh is not None else 0.0) + rng.uniform(-0.3, 0.3, n)
        logs = Logs(x, y, rng.uniform(0, np.pi, n), rng.uniform(0.6, 1.0, n), 0.05,
                    rng.uniform(500.0, 900.0, n))
    else:
        x0, x1, y0, y1 = (0.5, 29.5, 0.5, 9.5) if flow.mesh is not None else (-3, 3, -3, 3)
        logs = Logs(rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), rng.uniform(0, np.pi, n),
                    rng.uniform(0.3, 1.0, n), 0.05, rng.uniform(500.0, 900.0, n),
                    release_time=rng.choice([0.0, 3.0], n))
    tr = Tracker(flow, logs, PhysicsOptions(level=level, rotation=rotation), method,
                 StepOptions(max_step=max_step), contact=contact, t_end=t_end,
                 output_interval=2.5, fused=fused)
    tr.run()
    out = {"state": digest(logs.state), "status": digest(logs.status), "face": digest(logs.face)}
    for k in ("substeps", "rhs_evaluations", "min_dt", "max_dt"):
        out[f"stats_{k}"] = digest(np.float64(tr.stats[k]))
    if contact is not None:
        hits = contact.drain_hits()
        for k, v in hits.items():
            out[f"hit_{k}"] = digest(v)
    return out


def run_trackers(only=None) -> dict:
    """Hashes of direct Tracker runs: each integrator, path, physics level and contact method."""
    from driftlog.analytic import FreeVortex, SolidBodyRotation, UniformFlow
    from driftlog.contact import ContactModel
    from driftlog.contact.obstacles import Obstacles

    mesh_flow = _draining_channel()
    out = {}
    runs = {}
    for method in ("euler", "rk4", "exponential"):
        for fused in (True, False):
            for level, rot in (("full", True), ("drag", False), ("tracer", True)):
                runs[f"mesh:{method}:{'fused' if fused else 'general'}:{level}:{rot}"] = (
                    lambda m=method, f=fused, lv=level, r=rot: _tracker_run(mesh_flow, lv, r, m, f))
    for method in ("rk4", "euler", "exponential"):
        runs[f"vortex:{method}:full"] = lambda m=method: _tracker_run(
            FreeVortex(8.0, core_radius=0.5, depth=1.0), "full", True, m, True, n=40)
    runs["solid_body:rk4:tracer"] = lambda: _tracker_run(SolidBodyRotation(0.3), "tracer", True,
                                                          "rk4", True, n=30)

    def contact_run(method, flow_kind, fused, integ):
        obs = Obstacles()
        if flow_kind == "mesh":
            flow = mesh_flow
            obs.add_circle([15.0, 5.0], 1.0, "pier")
            obs.add_walls(mesh_flow.mesh)
        else:
            flow = UniformFlow(1.0, 0.2)
            obs.add_circle([0.0, 0.0], 0.5, "pier")
        cm = ContactModel(obs, method=method, restitution=0.8)
        return _tracker_run(flow, "full", True, integ, fused, contact=cm, n=15,
                            t_end=12.0 if flow_kind == "mesh" else 10.0,
                            max_step=0.5)

    for method in ("event", "moreau"):
        for integ, fused in (("rk4", True), ("rk4", False), ("exponential", False),
                             ("euler", True)):
            runs[f"contact:{method}:mesh:{integ}:{'fused' if fused else 'general'}"] = (
                lambda m=method, i=integ, f=fused: contact_run(m, "mesh", f, i))
        runs[f"contact:{method}:uniform:rk4"] = lambda m=method: contact_run(m, "uniform", True,
                                                                             "rk4")
    for name, fn in runs.items():
        if only and not any(name.startswith(o) or f"tracker:{name}".startswith(o) for o in only):
            continue
        t0 = time.perf_counter()
        out[f"tracker:{name}"] = fn()
        print(f"  tracker {name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return out


def compare(new: dict, old: dict) -> list:
    """Names of the arrays whose hashes differ, or that are in one result only."""
    bad = []
    for run in sorted(set(old) | set(new)):
        a, b = old.get(run), new.get(run)
        if a is None or b is None:
            bad.append(f"{run}: only in {'new' if a is None else 'baseline'}")
            continue
        for k in sorted(set(a) | set(b)):
            if a.get(k) != b.get(k):
                bad.append(f"{run}: {k}")
    return bad


def main(argv=None):
    """Command line: hash the runs, write and/or compare."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("-o", "--output", help="write the hashes to this JSON file")
    p.add_argument("--compare", help="compare with a JSON written before; exit 1 on a difference")
    p.add_argument("--only", nargs="*", help="runs whose name starts with these (cases by name)")
    a = p.parse_args(argv)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        res = {}
        if not a.only or any(o in CASES for o in a.only):
            res.update(run_cases(Path(tmp), a.only))
        if not a.only or any(o not in CASES for o in a.only):
            res.update(run_trackers(a.only))
    n = sum(len(v) for v in res.values())
    print(f"{len(res)} runs, {n} arrays hashed in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    if a.output:
        Path(a.output).parent.mkdir(parents=True, exist_ok=True)
        Path(a.output).write_text(json.dumps(res, indent=1, sort_keys=True) + "\n")
    if a.compare:
        old = json.loads(Path(a.compare).read_text())
        if a.only:
            old = {k: v for k, v in old.items() if k in res}
        bad = compare(res, old)
        if bad:
            print(f"DIFFERENT: {len(bad)} arrays", *bad[:50], sep="\n")
            return 1
        print(f"identical: {len(res)} runs, {n} arrays, bit for bit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
