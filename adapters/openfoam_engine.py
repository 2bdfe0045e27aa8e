"""OpenFOAM's shallowWaterFoam as an engine of a scenario's ``[solver]`` section.

``[solver] engine = "shallowWaterFoam"`` computes the section's flow with OpenFOAM instead of
driftlog's solver, from the same mesh, bed, initial state and boundary conditions; the result
is stored as a driftlog flow file (``solver_hash`` of the section, the engine included, in its
attributes) and reused while the section is unchanged, like the driftlog solver's flow.

The flow file of an engine other than driftlog is ``[flow] path`` with ``_<engine>`` added to
its stem (``flow.nc`` -> ``flow_shallowWaterFoam.nc``), and the OpenFOAM case folder beside it
has the same name without the suffix (``flow_shallowWaterFoam/``, kept with its ``log.*``
files): switching engines, or comparing them (``driftlog compare --engines``), never
overwrites the other engine's flow.

What is mapped (driftlog boundary type -> OpenFOAM condition on h, hU):

=========  ==================================================================================
wall       h zeroGradient, hU slip
level      h fixedValue level - bed (a series: uniformFixedValue, needs a flat bed along the
           tag), hU zeroGradient
depth      h fixedValue depth (a series: uniformFixedValue), hU zeroGradient
discharge  hU fixedValue, the unit discharge Q / (tag length) normal to the boundary (driftlog
           shares Q by conveyance h^(5/3): the same on a flat bed at uniform depth); a series:
           flowRateInletVelocity; h zeroGradient
free       h zeroGradient, hU zeroGradient
froude     refused: OpenFOAM has no condition imposing u_n = Fr sqrt(g h)
rating     refused: OpenFOAM has no stage-discharge condition
=========  ==================================================================================

Refused as well, at load time: a dry initial state or any face starting dry (shallowWaterFoam
divides hU by h), a ``[solver.sea]``, and bed friction unless ``openfoam_friction = "omit"``:
shallowWaterFoam (v1912) has no friction term, so a Manning or Strickler coefficient cannot
be honoured; with ``"omit"`` the run is frictionless and the flow's attributes say so.
"""

from __future__ import annotations

import os
import re
import resource
import time
from pathlib import Path

import numpy as np

from driftlog.errors import ScenarioError

__all__ = ["ENGINES", "engine_flow_path", "engine_case_path", "check_engine_section",
           "foam_boundaries", "solve_with_shallow_water_foam"]

ENGINES = ("driftlog", "shallowWaterFoam")
# driftlog boundary type -> why OpenFOAM (shallowWaterFoam) cannot take it
_REFUSED = {
    "froude": "OpenFOAM has no condition imposing the Froude number u_n = Fr sqrt(g h); use "
              "'level' or 'depth' at that outflow",
    "rating": "OpenFOAM has no stage-discharge (rating curve) condition; use 'level' or "
              "'depth' at that outflow",
}


def engine_flow_path(path, engine) -> Path:
    """The flow file of an engine: ``path`` for driftlog, else ``<stem>_<engine><suffix>``."""
    path = Path(path)
    if engine == "driftlog":
        return path
    return path.with_name(f"{path.stem}_{engine}{path.suffix or '.nc'}")


def engine_case_path(path, engine) -> Path:
    """The OpenFOAM case folder of an engine's flow file (its name without the suffix)."""
    p = engine_flow_path(path, engine)
    return p.with_name(p.stem)


def check_engine_section(t, prefix):
    """Load-time checks of a [solver] section computed by OpenFOAM (nothing to check else)."""
    engine = t["engine"]
    if engine == "driftlog":
        return
    friction = [k for k in ("manning", "strickler") if t.get(k)]
    if friction and t["openfoam_friction"] != "omit":
        k = friction[0]
        raise ScenarioError(f"{prefix}.{k}", t[k], f"engine {engine!r}: shallowWaterFoam "
                            "(OpenFOAM v1912) has no bed friction, so this coefficient cannot "
                            "be honoured; remove it, or set openfoam_friction = 'omit' to run "
                            "OpenFOAM frictionless (recorded in the flow's attributes)")
    if t.get("sea"):
        raise ScenarioError(f"{prefix}.sea", "{...}", f"engine {engine!r}: a sea found from "
                            "the bed leaves dry land, and shallowWaterFoam needs water on "
                            "every face; use engine = 'driftlog'")
    ini = t.get("initial") or {}
    if ini.get("type", "dry") == "dry":
        raise ScenarioError(f"{prefix}.initial.type", ini.get("type", "dry"),
                            f"engine {engine!r}: shallowWaterFoam needs water on every face "
                            "(U = hU/h): start from a level, a depth or a flow file")
    if "polygon" in ini:
        raise ScenarioError(f"{prefix}.initial.polygon", "[...]", f"engine {engine!r}: water "
                            "only inside a polygon leaves dry faces, and shallowWaterFoam "
                            "needs water on every face")
    for tag, spec in (t.get("boundaries") or {}).items():
        kind = spec.get("type") if isinstance(spec, dict) else spec
        if kind in _REFUSED:
            raise ScenarioError(f"{prefix}.boundaries.{tag}.type", kind,
                                f"engine {engine!r}: boundary {tag!r}: {_REFUSED[kind]}")


def foam_boundaries(boundaries, engine="shallowWaterFoam", prefix="solver") -> dict:
    """The [solver.boundaries] tables as ``write_shallow_water_case`` conditions.

    Raises ScenarioError naming the boundary and its type when OpenFOAM has no equivalent.
    """
    out = {}
    for tag, spec in (boundaries or {}).items():
        spec = {"type": spec} if isinstance(spec, str) else dict(spec)
        kind = spec.get("type")
        value, series = spec.get("value"), spec.get("series")
        if kind in _REFUSED:
            raise ScenarioError(f"{prefix}.boundaries.{tag}.type", kind,
                                f"engine {engine!r}: boundary {tag!r}: {_REFUSED[kind]}")
        if kind == "wall":
            out[tag] = {"type": "wall"}
        elif kind == "free":
            out[tag] = {"type": "open"}
        elif kind in ("level", "depth"):
            out[tag] = ({"type": "outflow", f"{kind}_series": series} if series is not None
                        else {"type": "outflow", kind: float(value)})
        elif kind == "discharge":
            out[tag] = ({"type": "inflow", "discharge_series": series} if series is not None
                        else {"type": "inflow", "discharge": float(value)})
        else:
            raise ScenarioError(f"{prefix}.boundaries.{tag}.type", kind,
                                f"engine {engine!r}: boundary {tag!r}: no OpenFOAM mapping "
                                "(mapped: wall, level, depth, discharge, free)")
    return out


def _version(log_text, env):
    """'OpenFOAM v1912 (build OPENFOAM=1912 patch=200626)' from the log's banner."""
    build = re.search(r"^Build\s*:\s*(.+?)\s*$", log_text, re.M)
    v = (env or {}).get("WM_PROJECT_VERSION")
    if not v and build:
        m = re.search(r"OPENFOAM=(\d+)", build.group(1))
        v = f"v{m.group(1)}" if m else None
    return f"OpenFOAM {v or 'unknown version'}" + (f" (build {build.group(1)})" if build else "")


def _fail(engine, case, log, what, path):
    from .openfoam_case import OpenFOAMError

    keep = (f"the stored flow {path} is untouched" if Path(path).exists()
            else f"no flow file written ({path})")
    return OpenFOAMError(f"engine {engine!r}: {what}\n  case folder: {case}\n  log: {log}\n"
                         f"  ({keep})")


def solve_with_shallow_water_foam(section, path, attrs, build, progress=False, timeout=None):
    """Compute a validated [solver] section with shallowWaterFoam; write the flow file.

    ``build(section)`` gives driftlog's ``ShallowWaterSolver`` of the section
    (``driftlog.solver.config.build_solver``): its mesh, bed and initial state are the case's.

    The case is written to ``engine_case_path(path)`` and run there (serial, or decomposed
    on ``n_procs`` processes); its snapshots are checked (finite, depth > 0) and written to
    ``path`` through a temporary file, so that a failed run leaves the stored flow as it was.

    Returns a ``SolveResult``; its ``volume_error`` is NaN (OpenFOAM keeps no balance here).
    """
    from driftlog.flowfile import FlowFileWriter
    from driftlog.solver.run import SolveResult

    from .openfoam import open_openfoam
    from .openfoam_case import (
        OpenFOAMError,
        foam_env,
        run_case,
        write_shallow_water_case,
    )

    sec = section
    engine = sec["engine"]
    path = Path(path)
    case = path.with_name(path.stem)
    log = case / "log.shallowWaterFoam"
    env = foam_env()
    if env is None:
        from .openfoam_case import BASHRC

        raise _fail(engine, case, "none (nothing ran)", "OpenFOAM is not installed: no "
                    f"{BASHRC} and no shallowWaterFoam on PATH (Debian: apt-get install "
                    "openfoam; or set DRIFTLOG_OPENFOAM_BASHRC to your OpenFOAM's etc/bashrc)",
                    path)
    s = build(sec)  # the mesh, bed and initial state exactly as driftlog's solver has
    mesh = s.mesh
    h = s.h.copy()
    with np.errstate(invalid="ignore", divide="ignore"):
        vel = np.column_stack([np.where(h > 0, s.hu / h, 0.0), np.where(h > 0, s.hv / h, 0.0)])
    start, end = float(s.t), float(sec["end"])
    interval = sec["output_interval"] or (end - start)
    n_procs = int(sec["n_procs"])
    try:
        info = write_shallow_water_case(
            case, mesh, bed=s.bed, boundaries=foam_boundaries(sec["boundaries"], engine),
            depth=h, velocity=vel, end_time=end - start, write_interval=interval,
            courant=sec["cfl"] or 0.5, gravity=s.gravity, n_procs=n_procs)
    except ScenarioError:
        raise
    except Exception as exc:  # FlowFileError from the case writer: say where and why
        raise _fail(engine, case, "none (nothing ran)", f"cannot write the case: {exc}",
                    path) from None
    wall0, cpu0 = time.perf_counter(), _children_cpu()
    if progress:
        print(f"engine {engine}: running {case} ({mesh.n_faces} cells, dt {info['dt']:.4g} s, "
              f"{n_procs} process{'es' if n_procs > 1 else ''}; log {log})", flush=True)
    watch = _LogProgress(log, end - start) if progress else None
    try:
        run_case(case, n_procs=n_procs, timeout=timeout)
    except OpenFOAMError as exc:
        raise _fail(engine, case, log, f"shallowWaterFoam failed: {exc}", path) from None
    finally:
        if watch is not None:
            watch.stop()
    wall, cpu = time.perf_counter() - wall0, _children_cpu() - cpu0
    log_text = log.read_text(errors="replace") if log.is_file() else ""
    if not re.search(r"^End\s*$", log_text, re.M):
        raise _fail(engine, case, log, "shallowWaterFoam stopped before the end time (no 'End' "
                    "in its log)", path)
    field = open_openfoam(case, dry_depth=sec["dry_depth"], mode="shallow_water",
                          decomposed=n_procs > 1)
    times = field.source.times
    if times[-1] < end - start - 1e-6 * max(1.0, end):
        raise _fail(engine, case, log, f"last written time {times[-1] + start:g} s is before "
                    f"the end {end:g} s", path)
    a = dict(attrs)
    tail = "\n".join(log_text.strip().splitlines()[-25:])
    friction = [k for k in ("manning", "strickler") if sec.get(k)]
    a.update({
        "source": f"{engine} (OpenFOAM), driftlog [solver] engine",
        "engine": engine, "openfoam_version": _version(log_text, env),
        "openfoam_case": str(case.resolve()), "openfoam_log": str(log.resolve()),
        "openfoam_log_tail": tail, "openfoam_dt": info["dt"], "openfoam_n_procs": n_procs,
        "openfoam_friction": (f"none: shallowWaterFoam has no bed friction ({friction[0]} = "
                              f"{sec[friction[0]]} not applied)" if friction else "none"),
        "engine_wall_time": wall, "engine_cpu_time": cpu, "dry_depth": sec["dry_depth"],
        "gravity": s.gravity})
    tmp = path.with_name(path.name + ".part")
    if tmp.exists():
        tmp.unlink()
    w = FlowFileWriter(tmp, mesh, s.bed, attrs=a,
                       extra_series={"volume": dict(long_name="water volume in the domain",
                                                    units="m3")})
    try:
        area = mesh.face_area
        for i, t in enumerate(times):
            hh, hu, hv = field.source.read(i)
            bad = ~(np.isfinite(hh) & np.isfinite(hu) & np.isfinite(hv))
            if np.any(bad) or np.any(hh <= 0):
                what = (f"{bad.sum()} faces not finite" if np.any(bad)
                        else f"{np.sum(hh <= 0)} faces with depth <= 0 (min {hh.min():.3g} m)")
                raise _fail(engine, case, log, f"the run diverged or dried at t = {t + start:g} "
                            f"s: {what}, e.g. face {int(np.flatnonzero(bad | (hh <= 0))[0])}",
                            path)
            w.write(t + start, hh, hu=hu, hv=hv, dry_depth=sec["dry_depth"],
                    volume=float(np.sum(hh * area)))
        w.close()
    except BaseException:
        w.close()
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)
    last = field.source.read(len(times) - 1)[0]
    steps = int(round((times[-1] - times[0]) / info["dt"]))
    return SolveResult(path=path, t_end=float(times[-1] + start), steps=steps, wall_time=wall,
                       cell_updates_per_s=mesh.n_faces * steps / max(wall, 1e-12),
                       volume=float(np.sum(last * mesh.face_area)), volume_error=float("nan"),
                       relative_volume_error=float("nan"), snapshots=len(times))


class _LogProgress:
    """A progress bar of simulated time, read from the solver's log every second."""

    _TIME = re.compile(rb"^\s*Time = ([0-9.eE+-]+)\s*$", re.M)

    def __init__(self, log: Path, total):
        import threading

        from tqdm import tqdm

        self.log, self.done = log, threading.Event()
        self.bar = tqdm(total=float(total), unit="s", unit_scale=True, desc="shallowWaterFoam",
                        leave=False)
        self.thread = threading.Thread(target=self._poll, daemon=True)
        self.thread.start()

    def _poll(self):
        while not self.done.wait(1.0):
            try:
                with open(self.log, "rb") as f:
                    f.seek(max(f.seek(0, 2) - 4096, 0))
                    times = self._TIME.findall(f.read())
            except OSError:
                continue
            if times:
                self.bar.n = min(float(times[-1]), self.bar.total)
                self.bar.refresh()

    def stop(self):
        self.done.set()
        self.thread.join()
        self.bar.close()


def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime

