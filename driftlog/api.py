"""The Python API: load a scenario, get its flow, track its logs, read the results.

>>> import driftlog
>>> result = driftlog.track("cases/vortex/scenario.toml")
>>> ds = result.dataset()          # xarray, CF trajectories
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from driftlog.columns import L_PERP, NLIN, NSTATE, THETA, WET, X, Y
from driftlog.contact import ContactModel
from driftlog.errors import DriftlogError, ScenarioError
from driftlog.files import check_output
from driftlog.logs import Logs, logs_from_groups, spatial_order
from driftlog.physics import PhysicsOptions, log_parameters, rhs_kernel
from driftlog.preflight import (
    check_flow_values,
    check_start,
    count_logs,
    estimate_run,
    run_inputs,
)
from driftlog.scenario import Scenario, load_scenario
from driftlog.sources import flow_from_scenario
from driftlog.tracker import StepOptions, Tracker
from driftlog.trajectory import RenumberedWriter, TrajectoryWriter, open_trajectories, write_vtk

__all__ = ["track", "TrackResult", "choose_physics", "as_scenario", "logs_from_scenario",
           "cases_dir", "find_case", "count_logs", "estimate_run"]


@dataclass
class TrackResult:
    """What a tracking run produced."""

    path: Path
    logs: Logs
    stats: dict
    physics: dict
    scenario: Scenario
    extra_files: list = field(default_factory=list)
    writer: object = None  # what received the records (a TrajectoryWriter, or the given one)
    flow_name: str = ""

    def dataset(self):
        """The trajectories as an xarray Dataset (CF contiguous ragged array)."""
        return open_trajectories(self.path)


def as_scenario(scenario, overrides=None) -> Scenario:
    """A validated Scenario from a path, a case name (``"vortex"``), TOML text, dict or Scenario.

    A folder holding a ``scenario.toml`` stands for that file.
    """
    if isinstance(scenario, Scenario):
        if overrides:
            from driftlog.scenario import merge

            return load_scenario(merge(json.loads(scenario.to_json()), overrides))
        return scenario
    name = str(scenario) if isinstance(scenario, (str, Path)) else ""
    if name and "\n" not in name and len(name) < 1024:  # a path or a name, not TOML text
        looks_like_name = "=" not in name and "/" not in name and not name.endswith(".toml")
        if looks_like_name and not Path(name).exists():
            try:
                scenario = find_case(name)  # a case by name, as on the command line
            except ScenarioError as exc:
                raise ScenarioError("scenario", name, "neither a file (not found), a case name "
                                    f"({exc.allowed.split('; ')[-1]}) nor TOML text") from None
        elif Path(name).is_dir() and (Path(name) / "scenario.toml").is_file():
            scenario = Path(name) / "scenario.toml"
    return load_scenario(scenario, overrides)


def run_clock_origin(flow, start, end) -> float:
    """Where the tracker's clock starts: 0, or ``start`` for a run far from the time axis' zero.

    A run whose absolute times carry float64 round-off above 1e-12 of its span (absolute
    epochs such as 1.7e9 s since 1970, ``time.start = 1e17``) is computed on a clock that
    starts at ``start`` (the flow shifted, ``FlowField.shifted``), so no precision is lost;
    its outputs store times on that clock with the origin as CF ``add_offset``.
    """
    start = float(start)
    if end is None:
        end = flow.time_span[1]
    end = float(end)
    if not (np.isfinite(end) and np.isfinite(start) and end > start):
        return 0.0
    return start if np.spacing(max(abs(start), abs(end))) > 1e-12 * (end - start) else 0.0


def logs_from_scenario(scenario, water_density=None) -> Logs:
    """All [[logs]] groups of a validated scenario as one Logs (``logs.logs_from_groups``)."""
    return logs_from_groups(scenario["logs"],
                            water_density or scenario["physics"]["water_density"],
                            scenario["time"]["start"])


def choose_physics(flow, logs: Logs, section: dict, contact_enabled: bool, t_end=None):
    """Resolve ``auto`` physics level and rotation from dimensionless numbers.

    Stokes number St = tau_D / T_flow, with tau_D the drag relaxation time of a log picking up
    the flow from rest and T_flow = 1 / |J| the time scale of the flow's velocity gradient at
    the release points.  St < 0.01 everywhere (and no contacts, which need the logs' inertia):
    the logs follow the flow, tracer is enough; otherwise the full model.  Rotation is needed
    when contacts are on, or when a log is long against the flow's length scale |U| / |J|
    (L |J| / |U| > 0.1).  Returns (level, rotation, reason).

    The flow is judged where the logs are wet: at their release, and (on flows with snapshots)
    at up to 16 snapshot times until ``t_end``, at the release points: logs released on a dry
    floor before a flood are judged by the flood that lifts them, not by the dry ground.
    With no wet sample at all the full model is chosen.
    """
    level, rotation = section["level"], section["rotation"]
    if level != "auto" and rotation != "auto":
        return level, rotation == "on", ""
    t0 = float(logs.release_time.min())
    times = np.asarray(getattr(flow, "times", ()), float)
    later = times[(times > t0) & (times <= (np.inf if t_end is None else t_end))]
    if later.size > 16:
        later = later[np.linspace(0, later.size - 1, 16).round().astype(int)]
    n = len(logs)
    S = np.zeros((n, NSTATE))
    S[:, X], S[:, Y], S[:, THETA] = logs.x, logs.y, logs.theta
    P = log_parameters(logs.length, logs.radius, logs.density, logs.float_depth)
    opt = PhysicsOptions.from_scenario(section, level="full", rotation=True).vector()
    D, lin = np.zeros((n, NSTATE)), np.zeros((n, NLIN))
    st_all, ratio_all = [], []
    for t in np.concatenate([[t0], later]):
        s = flow.sample(logs.x, logs.y, t)
        wet = s.flag == WET
        if not wet.any():
            continue
        rhs_kernel(S, s.values, P, opt, D, lin)
        tau = np.where(lin[:, L_PERP] > 0, 1.0 / np.maximum(lin[:, L_PERP], 1e-300), np.inf)
        J = np.sqrt((s.jacobian ** 2).sum(axis=(1, 2)))
        speed = np.hypot(s.u, s.v)
        st_all.append(np.where(J > 0, tau * J, 0.0)[wet])
        ratio_all.append(np.where(speed > 0, logs.length * J / np.maximum(speed, 1e-300),
                                  0.0)[wet])
    none_wet = not st_all
    st = np.concatenate(st_all) if st_all else np.empty(0)
    st_max = float(st.max()) if st.size else 0.0
    reasons = []
    if level == "auto" and none_wet:
        level = "full"
        reasons.append("level full: no log is in water at its release nor at the flow's "
                       "snapshots before the end, nothing to judge by")
    elif level == "auto":
        if st_max < 0.01 and not contact_enabled:
            level = "tracer"
            reasons.append(f"level tracer: Stokes number tau_D |J| <= {st_max:.3g} < 0.01, "
                           "logs follow the flow")
        else:
            level = "full"
            why = "contacts need the logs' inertia" if contact_enabled and st_max < 0.01 else \
                f"Stokes number tau_D |J| up to {st_max:.3g} >= 0.01"
            reasons.append(f"level full: {why}")
    if rotation == "auto":
        ratio = np.concatenate(ratio_all) if ratio_all else np.empty(0)
        rmax = float(ratio.max()) if ratio.size else 0.0
        rotation = bool(contact_enabled or rmax > 0.1)
        reasons.append(f"rotation {'on' if rotation else 'off'}: "
                       + ("contacts are on" if contact_enabled else
                          f"log length against flow length scale L |J| / |U| up to {rmax:.3g}"
                          f" ({'>' if rotation else '<='} 0.1)"))
    else:
        rotation = rotation == "on"
    return level, rotation, "; ".join(reasons)


def _contact_model(scen, flow):
    if not scen["contact"]["enabled"]:
        return None
    return ContactModel.from_sections(scen["contact"], scen["obstacles"],
                                      mesh=getattr(flow, "mesh", None))


def track(scenario, flow=None, output=None, progress=False, overrides=None,
          resume=False, writer=None, resume_hint=None) -> TrackResult:
    """Run the debris scenario: flow (given, or from the scenario), logs, tracker, outputs.

    Parameters
    ----------
    scenario : path, TOML text, dict or Scenario
    flow : FlowField, optional
        Use this flow instead of the scenario's [flow] source (e.g. to compare sources).
    output : path, optional
        Trajectory file (default: the scenario's output.path).
    resume : bool
        Continue a stopped run from its ``.partial`` file (its last record) instead of
        starting afresh; the result is the same as an uninterrupted run.  Without a
        ``.partial`` file the run starts afresh, with a ``DriftlogWarning`` saying so.
    writer : callable, optional
        ``writer(path, logs, attrs=, flush_interval=, obstacle_names=)`` returning an object
        with the ``TrajectoryWriter`` interface (``record``, ``hits``, ``flush``, ``set_attrs``,
        ``close``); default ``TrajectoryWriter``.  Ensembles pass a recorder that reduces the
        records as they come instead of (or beside) writing them.
    resume_hint : str, optional
        The command that continues a stopped run, for the note an interrupted run adds to
        its exception (default: ``driftlog track SCENARIO -o OUTPUT --resume``).
    """
    scen = as_scenario(scenario, overrides)
    out = Path(output or scen["output"]["path"])
    if writer is None:
        role = "trajectory file" if output else "trajectory file ([output] path)"
        check_output(out, role, inputs=run_inputs(scen), suffixes=(".nc", ".nc4"))
        estimate_run(scen, out)
    coupling = None
    partial = out.with_name(out.name + ".partial")
    if resume and writer is None and not partial.is_file():
        from driftlog.files import nothing_to_resume

        nothing_to_resume(partial)
    resume = resume and writer is None and partial.is_file()
    if scen["coupling"]["enabled"]:  # the logs act on the flow: solver and tracker together
        from driftlog.coupling import resume_coupling, start_coupling

        if flow is not None:
            raise ScenarioError("coupling.enabled", True, "a coupled run computes its own flow: "
                                "no flow can be given")
        # resumed: the solver at the flow file's restart, not spun up again (which would
        # rewrite the coupled flow file)
        coupling = resume_coupling(scen, out) if resume else start_coupling(scen, out)
        flow = coupling.flow
    logs = logs_from_scenario(scen)
    if resume:  # a stopped run of these logs and this scenario, before anything appends to it
        from driftlog.trajectory import check_resume

        try:
            check_resume(partial, scen, logs)
        except DriftlogError:
            if coupling is not None:  # its flow file as it was (nothing written yet)
                coupling.writer.close(finalize=False)
            raise
    if flow is None:
        flow = flow_from_scenario(scen, progress=progress)
    if writer is None and scen["time"]["end"] is None:  # the run ends with the flow: its size
        estimate_run(scen, out, flow)
    check_start(scen, flow, logs, warn=writer is None)  # outside the mesh, in an obstacle
    if writer is None and not resume and coupling is None:  # every snapshot the run reads
        check_flow_values(flow, scen["time"]["start"], scen["time"]["end"])
    tm = scen["time"]
    origin = run_clock_origin(flow, tm["start"], tm["end"])
    t_start = tm["start"] - origin
    t_end = None if tm["end"] is None else tm["end"] - origin
    if coupling is not None and t_end is None:
        t_end = scen["solver"]["end"]
    if origin:  # the run far from the time axis' zero: computed on a clock starting at origin
        flow = flow.shifted(origin)
        logs.release_time = logs.release_time - origin
    contact = _contact_model(scen, flow)
    level, rotation, reason = choose_physics(flow, logs, scen["physics"], contact is not None,
                                             t_end=t_end)
    if coupling is not None and level == "tracer":
        level = "full"
        reason += "; coupled: full (a tracer exerts no force on the flow)"
    physics = PhysicsOptions.from_scenario(scen["physics"], level=level, rotation=rotation)
    attrs = dict(scen.attrs())
    reference = (getattr(flow, "attrs", None) or {}).get("time_reference")
    if reference:
        attrs["time_units"] = str(reference)
    if origin:
        attrs["time_offset"] = origin
    attrs.update(title=scen["title"] or "driftlog trajectories",
                 physics_level=physics.level, physics_rotation=int(physics.rotation),
                 physics_auto_reason=reason or "not auto: as set in the scenario",
                 physics_options=json.dumps(physics.as_dict()),
                 integrator=scen["integrator"]["method"],
                 flow_source=getattr(flow, "name", str(flow)))
    names = getattr(contact, "obstacle_names", ()) if contact is not None else ()
    kw = dict(resume=True) if resume else {}
    if writer is None and coupling is not None:  # flushed with each flow snapshot
        kw["flush_every_record"] = True
    until = None
    if resume and coupling is not None:  # the logs where the coupled flow's restart is
        until = kw["until"] = coupling.resumed["t"]
    writer = (writer or TrajectoryWriter)(out, logs, attrs=attrs,
                                          flush_interval=scen["output"]["flush_interval"],
                                          obstacle_names=names, **kw)
    initial = np.array([g["velocity"] for g in scen["logs"]])[logs.group]  # no loop per log
    # Logs that move independently (no contacts, no coupling: nothing sums over logs in an
    # order) are tracked listed along a space-filling curve, so that consecutive logs share
    # the mesh rows in the caches (seeded at random they are scattered): each log's numbers
    # are the same bit for bit, and the writer gets every record in the scenario's order
    order = None
    if contact is None and coupling is None and len(logs) > 1:
        order = spatial_order(logs.x, logs.y)
        if np.array_equal(order, np.arange(len(logs))):
            order = None
    tracked = logs if order is None else logs.take(order)
    back = None if order is None else np.argsort(order)  # the scenario's log -> the tracker's
    opts = dict(method=scen["integrator"]["method"],
                step=StepOptions.from_scenario(scen["integrator"]), contact=contact,
                t_start=t_start, t_end=t_end, output_interval=tm["output_interval"],
                hydro_step=tm["hydro_step"], progress=progress,
                writer=writer if order is None else RenumberedWriter(writer, order),
                initial_velocity=initial if order is None else initial[order])
    if coupling is not None:
        from driftlog.coupling import CoupledTracker

        tracker = CoupledTracker(coupling, logs, physics, **opts)
    else:
        tracker = Tracker(flow, tracked, physics, **opts)
    if progress:
        from driftlog._numba import PARALLEL_MIN, announce_compile

        announce_compile((["solver"] if coupling is not None else []) + ["tracking"]
                         + (["contacts"] if contact is not None else []),
                         many=len(logs.state) >= PARALLEL_MIN)
    if resume:
        from driftlog.trajectory import last_states

        state = last_states(partial, until=until)
        if until is not None and (state is None or state[0] != until):
            from driftlog.errors import FlowFileError

            raise FlowFileError(f"{partial}: cannot resume the coupled run: its last record "
                                f"is at {'none' if state is None else state[0]} s, its flow's "
                                f"restart at {until} s ({coupling.writer.partial}); rerun it "
                                "from the start, without --resume")
        if state is not None:
            from driftlog.trajectory import kept_counts

            t_last, index, columns = state
            if order is not None:  # the file's logs -> the tracker's
                index = back[index]
            tracker.resume_from(t_last, index, columns, kept_counts(partial, t_last))
    try:
        tracker.run()
    except BaseException as exc:
        kept_flow = None
        if coupling is not None:  # the coupled flow so far, left at its .partial name
            kept_flow = coupling.writer.close(finalize=False)
        writer.flush()
        kept = writer.close(finalize=False)  # keep the partial file: nothing computed is lost
        end = f"{t_end + origin:g} s" if t_end is not None else "the flow's end"
        if isinstance(kept, Path) and kept.exists():
            how = f"{resume_hint or f'driftlog track SCENARIO -o {out} --resume'} continues it"
            exc.add_note(f"kept {kept}: {getattr(writer, 'nobs', '?')} observations and "
                         f"{getattr(writer, 'nhit', '?')} contact hits up to t = "
                         f"{tracker.t + origin:.6g} s of {end}; {how}")
        if kept_flow is not None and kept_flow.exists():
            exc.add_note(f"kept {kept_flow}: the coupled flow's {coupling.writer.snapshots} "
                         f"snapshots up to t = {coupling.solver.t:.6g} s (incomplete)")
        raise
    if coupling is not None:
        stats = coupling.summary()
        coupling.writer.close(**{f"coupling_{k}": v for k, v in stats.items()})
        writer.set_attrs(coupled_flow=str(coupling.writer.path),
                         **{f"coupling_{k}": v for k, v in stats.items()})
    writer.set_attrs(**{f"stats_{k}": v for k, v in tracker.stats.items()})
    if contact is not None:  # events, rejected steps, deepest overlap, Gauss-Seidel sweeps
        writer.set_attrs(contact_stats=json.dumps({k: float(v) for k, v in
                                                   contact.stats.items()}))
    path = writer.close()
    if contact is not None:
        warn_unconverged_contacts(contact, float(np.min(logs.radius)) if len(logs) else 0.0)
    if coupling is not None:
        warn_long_exchange(coupling)
    if order is not None:  # the logs' final states, in the scenario's order
        logs = tracked.take(back)
    extra = []
    if scen["output"]["vtk"]:
        extra.append(write_vtk(path))
    extra += _output_figures(path, scen["output"])
    result = TrackResult(path, logs, tracker.stats,
                         dict(level=level, rotation=rotation, reason=reason), scen, extra, writer,
                         flow_name=getattr(flow, "name", str(flow)))
    return result


# the deepest overlap, as a share of the smallest log radius, beyond which contact steps that
# stopped at their cap of sweeps are reported (cases/bridge_jam's pile: 2.9 %, most steps
# capped: no warning)
OVERLAP_WARN = 0.1


def warn_unconverged_contacts(contact, radius):
    """A ``DriftlogWarning`` when Moreau-Jean steps stopped at their cap and logs overlap.

    Projected Gauss-Seidel carries a push about one contact per sweep: in a pile many logs
    across it stops at ``[contact] iterations`` unconverged and the logs overlap (the 1e5-log
    Malpasset flood: a raft of 22,465 logs, overlaps of 0.19 m between logs 0.16 m thick;
    BENCHMARKS.md).  ``radius``: the smallest log radius, to put the deepest overlap in scale.
    """
    import warnings

    from driftlog.errors import DriftlogWarning

    st = contact.stats
    n = int(st.get("pgs_capped", 0))
    gap = float(st.get("min_gap", np.inf))
    if contact.method != "moreau" or n == 0 or not -gap > OVERLAP_WARN * radius:
        return
    deep = f"{-gap:.3g} m ({-gap / radius:.0%} of the smallest log radius)"
    warnings.warn(DriftlogWarning(
        f"contacts: the Moreau-Jean solver stopped at its cap of {contact.iterations} "
        f"Gauss-Seidel sweeps without converging in {n:,} of {int(st['substeps']):,} contact "
        f"steps (up to {int(st['max_contacts']):,} contacts in one step); the deepest overlap "
        f"was {deep}: piles of many logs need more sweeps ([contact] iterations) or their logs "
        "overlap"), stacklevel=2)


def _output_figures(path, output):
    """``[output] figure`` and ``animation``: drawn beside the trajectory file; their paths."""
    out = []
    if output["figure"]:
        import matplotlib.pyplot as plt

        from driftlog.plots import plot_trajectories

        png = Path(path).with_suffix(".png")
        plt.close(plot_trajectories(path, out=png))
        out.append(png)
    if output["animation"]:
        from driftlog.plots import animate

        out.append(Path(animate(path, Path(path).with_suffix(".mp4"))))
    return out


def warn_long_exchange(coupling):
    """A ``DriftlogWarning`` when the water under the logs crossed over a cell per exchange.

    The reaction lags by one exchange interval (docs/model.md 17.6): on the validation array
    the backwater is 0.98-0.99 / 1.00 / 1.06-1.11 of the momentum balance's at exchange
    Courant numbers |u| interval / dx of 0.5 / 1 / 2 (event-driven and Moreau-Jean contacts);
    ``coupling.EXCHANGE_COURANT_MAX`` is 1, the advice of 17.6.
    """
    import warnings

    from driftlog.coupling import EXCHANGE_COURANT_MAX
    from driftlog.errors import DriftlogWarning

    c = coupling.exchange_courant
    if not c > EXCHANGE_COURANT_MAX:
        return
    fit = coupling.interval * EXCHANGE_COURANT_MAX / c
    warnings.warn(DriftlogWarning(
        f"[coupling] interval = {coupling.interval:g} s: the water under the logs crossed up "
        f"to {c:.3g} cells in one exchange (|u| interval / cell size); the exchange's lag is "
        f"validated up to {EXCHANGE_COURANT_MAX:g} (docs/model.md 17.6): an interval of "
        f"{fit:.3g} s or less keeps it there"), stacklevel=2)


def cases_dir() -> Path:
    """The folder of the scenes (cases/ at the top of the repository, or DRIFTLOG_CASES)."""
    import os

    env = os.environ.get("DRIFTLOG_CASES")
    d = Path(env) if env else Path(__file__).resolve().parents[1] / "cases"
    if not d.is_dir():
        raise DriftlogError(f"cases folder not found at {d}; set DRIFTLOG_CASES to the "
                            "repository's cases/ folder")
    return d


def find_case(name: str) -> Path:
    """The scenario file of a case by name (a folder of cases/ with a scenario.toml)."""
    d = cases_dir()
    p = d / name / "scenario.toml"
    if not p.is_file():
        known = sorted(c.name for c in d.iterdir() if (c / "scenario.toml").is_file())
        raise ScenarioError("case", name, "unknown case; known cases: " + ", ".join(known))
    return p
