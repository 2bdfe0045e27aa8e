"""Stability where methods fail, and their remedies (issue 7, item 4): three figures.

1. Stiff drag.  The flume log of the paper's section 3.4 (L 0.2 m, r 4 mm, rho_b 720 kg/m3),
   broadside to a uniform 0.21 m/s flow, released from rest, constant C_D = 1 (docs/model.md
   section 15.C is then exact: u_b(t) = U0 - U0 / (1 + beta U0 t)).  The drag relaxation time
   1/(2 beta U0) is about 0.04 s, the paper's step L/|U_b| about 1 s: explicit Euler and RK4
   blow up or ring; RK4 with the step bounded by integrator.drag_fraction, and the exponential
   integrator, stay stable.  Velocity against time, and the error at t = 5 s against the step.
2. Jam.  cases/bridge_jam (30 logs against a bridge deck, eps = 0.3): the event-driven
   sub-step collapses until ContactJamError; Moreau-Jean's steps stay steady, the pile's
   deepest overlap and its speeds stay bounded.  Steps are recorded by wrapping the contact
   model's ``substep`` (no library change).
3. Dry front.  The Ritter dam break on a dry bed (SWASHES 3 1 2): the solver at its
   positivity-preserving step (cfl <= 1, order 1) keeps h >= 0 and the volume to round-off;
   the same run with steps 2.5 to 4 times that bound (the attribute set past the scenario's
   check, for this demonstration only) makes negative depths that the solver clips to zero, so
   water is created (the bound sums the wave speeds of all the edges of a face, walls included:
   on a one-cell-wide strip it has slack).  A last panel: lake at rest on an emerged bump
   (SWASHES 1 1 5), the solver's hydrostatic reconstruction against a naive centred bed-slope
   source (a few lines of numpy here): velocities at round-off against spurious currents.

    python benchmarks/stability_figures.py [--quick]

writes benchmarks/results/stability_{drag,jam,dry}.png, stability.json and stability.md
(``--quick``: the same names with ``_quick``, so the full-size results are kept).
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import RESULTS, machine, run_recording_first_log

from driftlog.analytic import UniformFlow
from driftlog.columns import UB, VB, X
from driftlog.logs import Logs
from driftlog.physics import PhysicsOptions
from driftlog.tracker import StepOptions, Tracker

SUFFIX = ""  # "_quick" for --quick: the committed full-size results are kept
ROOT = Path(__file__).resolve().parents[1]

# ----------------------------------------------------------------------------- 1. stiff drag
U0, L, R, RHO_B, RHO, CD = 0.21, 0.2, 0.004, 720.0, 1000.0, 1.0
# broadside (alpha = 90 deg): S_eff = 2 r L; V_b = pi r^2 L (docs/model.md section 15.C)
BETA = CD * RHO * 2 * R * L / (2 * (RHO_B + RHO / 2) * np.pi * R * R * L)
TAU = 1.0 / (2 * BETA * U0)  # linearised relaxation time at the start (w = U0)
PAPER_STEP = L / U0
T_DRAG = 5.0
DRAG_PHYSICS = PhysicsOptions(drag_law="constant", drag_coefficient=CD, rotation=False)


def u_exact(t):
    return U0 - U0 / (1 + BETA * U0 * t)


def x_exact(t):
    return U0 * t - np.log(1 + BETA * U0 * t) / BETA


def drag_run(method, step):
    """Velocity history of the flume log; (t, u, x_end or nan, error name or None, substeps)."""
    logs = Logs([0.0], [0.0], np.pi / 2, L, R, RHO_B)
    tr = Tracker(UniformFlow(U0, 0.0, depth=0.1), logs, DRAG_PHYSICS, method, step,
                 t_end=T_DRAG, output_interval=T_DRAG, hydro_step=T_DRAG,
                 initial_velocity="rest")
    ts, us, err = run_recording_first_log(tr, 0.0, 0.0)
    x_end = logs.state[0, X] if err is None else np.nan
    return ts, us, x_end, err, tr.stats["substeps"]


def fixed(dt):
    return StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9, drag_fraction=0.0)


def stiff_drag(plt, quick):
    paper = StepOptions(length_fraction=1.0, drag_fraction=0.0, max_step=PAPER_STEP)
    bounded = StepOptions(length_fraction=1.0, drag_fraction=0.5, max_step=PAPER_STEP)
    runs = [("euler", paper, "explicit Euler, paper's step L/|U_b|"),
            ("rk4", paper, "RK4, paper's step L/|U_b|"),
            ("rk4", bounded, "RK4, step <= drag_fraction 0.5 / lambda_D"),
            ("exponential", paper, "exponential, paper's step L/|U_b|")]
    curves = {lab: drag_run(m, s) for m, s, lab in runs}
    steps = PAPER_STEP / 2.0 ** np.arange(0, 9 if quick else 11, 1.0 if quick else 0.5)
    sweep = {"euler": [], "rk4": [], "rk4 + drag_fraction 0.5": [], "exponential": []}
    for dt in steps:
        for name in sweep:
            method = name.split()[0]
            so = fixed(dt) if "+" not in name else StepOptions(
                max_step=dt, length_fraction=1e9, angle_step=1e9, drag_fraction=0.5)
            _, u, x_end, err, _ = drag_run(method, so)
            bounded_u = np.all(np.abs(u) < 10 * U0)
            e = abs(x_end - x_exact(T_DRAG)) if err is None else np.nan
            sweep[name].append(dict(dt=float(dt), error=float(e), diverged=err is not None
                                    or not bounded_u))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.8))
    tt = np.linspace(0, T_DRAG, 400)
    a1.plot(tt, u_exact(tt), "k-", lw=2, label="exact (docs/model.md section 15.C)")
    rows = []
    for (lab, (t, u, x_end, err, n)), st in zip(curves.items(), ["o--", "s--", "^-", "d-"],
                                                 strict=True):
        uerr = np.max(np.abs(u - u_exact(t)))
        fate = (f"diverges (|u_b| {np.max(np.abs(u)):.1g} m/s), stops with {err}" if err
                else f"max |u_b - exact| {uerr:.2g} m/s")
        a1.plot(t, np.clip(u, -0.5, 0.8), st, ms=4, lw=1, label=f"{lab}: {n} steps, {fate}")
        rows.append(dict(run=lab, steps=int(n), stopped=err or "",
                         max_abs_u=float(np.max(np.abs(u))), max_u_error=float(uerr),
                         x_error=float(abs(x_end - x_exact(T_DRAG)))))
    a1.set_ylim(-0.5, 0.8)
    a1.set_xlabel("time t (s)")
    a1.set_ylabel("log velocity u_b (m/s, clipped to the axes)")
    a1.legend(fontsize=7, loc="lower right")
    a1.grid(alpha=0.3)
    for k, ((name, r), mk) in enumerate(zip(sweep.items(), "os^d", strict=True)):
        dt = np.array([x["dt"] for x in r])
        e = np.array([x["error"] for x in r])
        ok = ~np.array([x["diverged"] for x in r]) & np.isfinite(e)
        line, = a2.loglog(dt[ok], np.maximum(e[ok], 1e-16), mk + "-", label=name)
        if (~ok).any():
            # one row of crosses per method, so that they do not hide each other
            a2.loglog(dt[~ok], np.full((~ok).sum(), 10.0 * 1.8 ** k), "x", ms=8,
                      color=line.get_color())
    for k, ls in ((2.0, ":"), (2.785, "--")):
        a2.axvline(k * TAU, color="0.5", ls=ls, lw=0.9)
    a2.text(2 * TAU, 2e-15, " Euler limit 2 tau", fontsize=7, rotation=90, va="bottom")
    a2.text(2.785 * TAU, 2e-15, " RK4 limit 2.79 tau", fontsize=7, rotation=90, va="bottom")
    a2.axhline(10.0, color="0.8", lw=0.8)
    a2.text(steps[-1], 3.0, "x: diverged (run stopped, or |u_b| > 10 U0)", fontsize=7)
    a2.set_xlabel("step dt (s)  (paper's step L/|U_b| at the right end)")
    a2.set_ylabel(f"position error at t = {T_DRAG:g} s (m)")
    a2.set_ylim(1e-15, 1e2)
    a2.legend(fontsize=8)
    a2.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"Stiff drag (flume log, tau_D = {TAU:.3f} s, paper's step {PAPER_STEP:.2f} s):"
                 " explicit Euler/RK4 blow up; drag_fraction step bound or the exponential "
                 "integrator fix it", fontsize=10)
    fig.tight_layout()
    fig.savefig(RESULTS / f"stability_drag{SUFFIX}.png", dpi=110)
    plt.close(fig)
    limit = {}
    for name, r in sweep.items():
        stable = [x["dt"] for x in r if not x["diverged"] and np.isfinite(x["error"])
                  and x["error"] < 1e-2]
        limit[name] = max(stable) if stable else np.nan
    return dict(beta=BETA, tau=TAU, paper_step=PAPER_STEP, runs=rows, sweep=sweep,
                largest_accurate_step=limit)


# ----------------------------------------------------------------------------- 2. jam
def jam_run(method, tmp):
    from driftlog.api import track
    from driftlog.contact import ContactJamError
    from driftlog.contact import model as model_mod

    rec = dict(t=[], dt=[], overlap=[], speed=[], contacts=[])
    made = []
    orig = model_mod.ContactModel.from_sections.__func__

    def spy(cls, contact, obstacles, mesh=None):
        m = orig(cls, contact, obstacles, mesh)
        sub = m.substep

        def substep(bodies, dt):  # record the step taken, the deepest overlap, the speeds
            t0 = bodies.t
            sub(bodies, dt)
            S = bodies.state
            rec["t"].append(bodies.t)
            rec["dt"].append(bodies.t - t0)
            rmin = float(bodies.radius.min()) if S.shape[0] else 1.0
            E = m.detect(bodies, np.full(S.shape[0], m.tolerance * rmin)) if S.shape[0] else []
            rec["overlap"].append(max(0.0, -float(E.gap.min())) if len(E) else 0.0)
            rec["contacts"].append(len(E))
            rec["speed"].append(float(np.hypot(S[:, UB], S[:, VB]).max()) if S.shape[0] else 0.0)
            return bodies.t - t0

        m.substep = substep
        made.append(m)
        return m

    model_mod.ContactModel.from_sections = classmethod(spy)
    err = None
    t0 = time.perf_counter()
    try:
        track(ROOT / "cases" / "bridge_jam" / "scenario.toml",
              output=Path(tmp) / f"{method}.nc",
              overrides={"contact": {"method": method}})
    except ContactJamError as exc:
        err = str(exc)
    finally:
        model_mod.ContactModel.from_sections = classmethod(orig)
    wall = time.perf_counter() - t0
    out = {k: np.array(v) for k, v in rec.items()}
    return out, err, made[0].stats, wall


def jam(plt):
    with tempfile.TemporaryDirectory() as tmp:
        ev, ev_err, ev_stats, ev_wall = jam_run("event", tmp)
        mj, mj_err, mj_stats, mj_wall = jam_run("moreau", tmp)
    radius = 0.1
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.8))
    t_stop = ev["t"][-1] if ev["t"].size else np.nan
    a1.semilogy(ev["t"], ev["dt"], ".", ms=2, color="C3",
                label=f"event-driven: {ev['t'].size} sub-steps, smallest {ev['dt'].min():.2g} s"
                + (f", ContactJamError at t = {t_stop:.2f} s" if ev_err else ""))
    a1.semilogy(mj["t"], mj["dt"], ".", ms=2, color="C0",
                label=f"Moreau-Jean: {mj['t'].size} steps, smallest {mj['dt'].min():.2g} s, "
                f"runs to t = {mj['t'][-1]:.0f} s")
    if ev_err:
        a1.axvline(t_stop, color="C3", ls="--", lw=0.8)
    a1.set_xlabel("time t (s)")
    a1.set_ylabel("contact sub-step taken (s)")
    a1.legend(fontsize=8, loc="lower left")
    a1.grid(True, which="both", alpha=0.3)
    a2.plot(mj["t"], 100 * mj["overlap"] / radius, "-", color="C0", lw=1,
            label="Moreau-Jean: deepest overlap (% of the radius)")
    a2.set_xlabel("time t (s)")
    a2.set_ylabel("deepest log overlap (% of the radius 0.1 m)")
    a2.grid(alpha=0.3)
    b = a2.twinx()
    b.plot(mj["t"], mj["speed"], "-", color="C2", lw=1, label="Moreau-Jean: fastest log (m/s)")
    b.set_ylabel("fastest log speed (m/s)")
    h1, l1 = a2.get_legend_handles_labels()
    h2, l2 = b.get_legend_handles_labels()
    a2.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper left")
    fig.suptitle("Jam (cases/bridge_jam, 30 logs, eps 0.3): event-driven contact's sub-step "
                 "collapses (ContactJamError); Moreau-Jean holds the pile with steady steps",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(RESULTS / f"stability_jam{SUFFIX}.png", dpi=110)
    plt.close(fig)
    late = mj["t"] > mj["t"][-1] - 1.0
    return dict(event=dict(substeps=int(ev["t"].size), stopped_at=float(t_stop),
                           jam_error=(ev_err or "")[:160], min_dt=float(ev["dt"].min()),
                           events=int(ev_stats["events"]), wall_s=ev_wall),
                moreau=dict(steps=int(mj["t"].size), end=float(mj["t"][-1]),
                            min_dt=float(mj["dt"].min()), median_dt=float(np.median(mj["dt"])),
                            max_overlap=float(mj["overlap"].max()),
                            max_overlap_share=float(mj["overlap"].max() / radius),
                            max_contacts=int(mj_stats["max_contacts"]),
                            pgs_max_iterations=int(mj_stats["pgs_max_iterations"]),
                            max_speed_last_second=float(mj["speed"][late].max()),
                            stopped=mj_err or "", wall_s=mj_wall))


# ----------------------------------------------------------------------------- 3. dry front
def ritter_run(n, cfl_factor):
    """Ritter dam break with the solver (order 1) at cfl_factor times its positivity step.

    Records, each step, the smallest depth the Euler update makes before the solver clips
    negative depths to zero (the same rates and step the solver's ``step`` then uses).
    """
    from driftlog.mesher import channel_mesh
    from driftlog.solver import ShallowWaterSolver

    dx = 10.0 / n
    mesh = channel_mesh(10.0, dx, dx, structured=True)
    s = ShallowWaterSolver(mesh, order=1)
    # past the scenario's check (cfl <= 1), to show what the bound prevents
    s.cfl = s.cfl * cfl_factor
    s.set_state(np.where(mesh.face_x < 5.0, 0.005, 0.0))
    v0 = s.volume()
    hist = dict(t=[0.0], volume_error=[0.0], max_speed=[0.0], min_h=[0.0])
    while s.t < 6.0 - 1e-12:
        rmax = s._rates(s._h, s._hu, s._hv, s.t)  # the internal numbering
        dt = min(s.cfl / rmax, 6.0 - s.t)
        h_min = float((s._h + dt * s._res[0]).min())  # before the clip of euler_stage
        s.step(6.0 - s.t)
        hist["t"].append(s.t)
        hist["min_h"].append(h_min)
        hist["volume_error"].append(s.volume_error() / v0)
        wet = s.h > s.dry_depth
        hist["max_speed"].append(float((np.abs(s.hu[wet]) / s.h[wet]).max()) if wet.any()
                                 else 0.0)
        if not np.all(np.isfinite(s.h)):
            break
    return mesh.face_x, s, {k: np.array(v) for k, v in hist.items()}


def lake_naive(x, z, level, t_end, g=9.81):
    """Lake at rest, first-order Rusanov on (h, hu) with the bed slope as a centred source
    -g h dz/dx (not well balanced); walls at both ends.  Returns (h, u) at t_end."""
    dx = x[1] - x[0]
    h = np.maximum(level - z, 0.0)
    q = np.zeros_like(h)
    zg = np.concatenate([[z[0]], z, [z[-1]]])
    dzdx = (zg[2:] - zg[:-2]) / (2 * dx)
    t = 0.0
    while t < t_end:
        hg = np.concatenate([[h[0]], h, [h[-1]]])
        qg = np.concatenate([[-q[0]], q, [-q[-1]]])  # reflecting walls
        u = np.where(hg > 1e-6, qg / np.maximum(hg, 1e-300), 0.0)
        c = np.abs(u) + np.sqrt(g * hg)
        f1, f2 = qg, qg * u + 0.5 * g * hg * hg
        a = np.maximum(c[:-1], c[1:])
        F1 = 0.5 * (f1[:-1] + f1[1:]) - 0.5 * a * (hg[1:] - hg[:-1])
        F2 = 0.5 * (f2[:-1] + f2[1:]) - 0.5 * a * (qg[1:] - qg[:-1])
        dt = min(0.45 * dx / a.max(), t_end - t)
        h = np.maximum(h - dt / dx * (F1[1:] - F1[:-1]), 0.0)
        q = q - dt / dx * (F2[1:] - F2[:-1]) - dt * g * h * dzdx
        q[h <= 1e-6] = 0.0
        t += dt
    return h, np.where(h > 1e-6, q / np.maximum(h, 1e-300), 0.0)


def lake_solver(n, level, t_end):
    from driftlog.mesher import channel_mesh
    from driftlog.solver import ShallowWaterSolver

    dx = 25.0 / n
    mesh = channel_mesh(25.0, dx, dx, structured=True)
    z = np.maximum(0.0, 0.2 - 0.05 * (mesh.face_x - 10.0) ** 2)
    s = ShallowWaterSolver(mesh, bed=z, order=2)
    s.set_level(level)
    s.run(t_end)
    wet = s.h > s.dry_depth
    u = np.where(wet, s.hu / np.maximum(s.h, 1e-300), 0.0)
    return mesh.face_x, z, s.h, u


FACTORS = (1.0, 2.5, 3.0, 4.0)  # times the solver's positivity-preserving step


def dry_front(plt, quick):
    from driftlog.solver.swashes import swashes_solution

    n = 200 if quick else 400
    exact = swashes_solution(3, 1, 2, n)
    runs = {f: ritter_run(n, f) for f in FACTORS}
    n_lake = 100 if quick else 200
    xl, z, h_ok, u_ok = lake_solver(n_lake, 0.1, 20.0)
    h_bad, u_bad = lake_naive(xl, z, 0.1, 20.0)
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5))
    (a1, a2), (a3, a4) = axes
    a1.plot(exact["x"], exact["h"] * 1000, "k-", lw=2, label="exact (SWASHES Ritter)")
    out = {}
    for (f, (x, s, hist)), st in zip(runs.items(), ["C0", "C2", "C1", "C3"], strict=True):
        lab = f"cfl {s.cfl:.2f} ({f:g} x the solver's positivity step)"
        neg = ~(hist["min_h"] >= 0)  # negative or NaN
        a1.plot(x, s.h * 1000, "-", color=st, lw=1,
                label=lab + ("" if np.all(np.isfinite(s.h)) else ": blew up (NaN)"))
        # a blow-up reaches -1e130 m: the axis stops at -1 m
        a2.plot(hist["t"], np.maximum(hist["min_h"], -1.0) * 1000, ".-", color=st, ms=3,
                lw=0.8, label=lab)
        a3.semilogy(hist["t"][1:], np.maximum(np.abs(hist["volume_error"][1:]), 1e-17), "-",
                    color=st, lw=1, label=lab)
        out[f"cfl_x{f:g}"] = dict(factor=f, cfl=s.cfl, steps=int(hist["t"].size - 1),
                                  l1_h=float(np.mean(np.abs(s.h - exact["h"]))),
                                  min_h_before_clip=float(np.nanmin(hist["min_h"])),
                                  first_negative_at=float(hist["t"][np.argmax(neg)])
                                  if neg.any() else None,
                                  max_rel_volume_error=float(
                                      np.nanmax(np.abs(hist["volume_error"]))),
                                  max_speed=float(np.nanmax(hist["max_speed"])),
                                  finite=bool(np.all(np.isfinite(s.h))))
    a1.set_xlabel("x (m)  (dam at 5 m, 5 mm of water upstream, dry bed downstream)")
    a1.set_ylabel("depth h at t = 6 s (mm)")
    a1.legend(fontsize=8, loc="lower left")
    a1.grid(alpha=0.3)
    a2.set_yscale("symlog", linthresh=1e-6)
    a2.set_xlabel("time t (s)")
    a2.set_ylabel("min depth before clipping (mm)")
    a2.legend(fontsize=8)
    a2.grid(alpha=0.3)
    a3.set_xlabel("time t (s)")
    a3.set_ylabel("|relative volume error| (clipping creates water)")
    a3.set_ylim(1e-17, 1)
    a3.legend(fontsize=8)
    a3.grid(True, which="both", alpha=0.3)
    a4.semilogy(xl, np.maximum(np.abs(u_ok), 1e-18), "C0-", lw=1,
                label=f"solver (hydrostatic reconstruction): max {np.abs(u_ok).max():.1e} m/s")
    a4.semilogy(xl, np.maximum(np.abs(u_bad), 1e-18), "C3-", lw=1,
                label=f"naive centred bed source: max {np.abs(u_bad).max():.1e} m/s")
    a4.set_xlabel("x (m)  (lake at rest, level 0.1 m, bump emerges at 8.6 to 11.4 m)")
    a4.set_ylabel("|u| at t = 20 s (m/s; dry cells 0)")
    a4.set_ylim(1e-18, 10)
    a4.legend(fontsize=8)
    a4.grid(True, which="both", alpha=0.3)
    fig.suptitle("Dry fronts (order 1): steps past the positivity bound give negative depths, "
                 "clipped, so water is created;\nhydrostatic reconstruction keeps a lake at rest "
                 "on an emerged bump where a naive bed source does not", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(RESULTS / f"stability_dry{SUFFIX}.png", dpi=110)
    plt.close(fig)
    out["lake_at_rest"] = dict(cells=n_lake, solver_max_u=float(np.abs(u_ok).max()),
                               naive_max_u=float(np.abs(u_bad).max()))
    out["cells"] = n
    return out


# ----------------------------------------------------------------------------- report
def write_md(res):
    d, j, w = res["drag"], res["jam"], res["dry"]
    clipped = [f for f in FACTORS if not w[f"cfl_x{f:g}"]["min_h_before_clip"] >= 0]  # or NaN
    safe = max([f for f in FACTORS if f not in clipped], default=np.nan)
    unsafe = min(clipped, default=np.nan)
    lines = ["### Stability where methods fail, and the remedies", "",
             f"Measured on {machine()}.  Re-create: `python benchmarks/stability_figures.py"
             f"{' --quick' if res['quick'] else ''}`.", "",
             f"**Stiff drag** (flume log broadside in {U0} m/s, constant C_D {CD}: beta = "
             f"{d['beta']:.1f} 1/m, tau_D = {d['tau']:.3f} s, paper's step "
             f"{d['paper_step']:.3f} s):", "",
             "| run | steps | stopped | max abs u_b (m/s) | max u_b error (m/s) |",
             "|---|---|---|---|---|"]
    for r in d["runs"]:
        lines.append(f"| {r['run'].replace('|', '')} | {r['steps']} | {r['stopped'] or 'no'} | "
                     f"{r['max_abs_u']:.3g} | {r['max_u_error']:.2g} |")
    lines += ["", "Largest max_step (fixed, or capped by drag_fraction) with position error "
              "< 1 cm at t = 5 s: " + ", ".join(
        f"{k} {v:.3g} s" for k, v in d["largest_accurate_step"].items()) + ".", "",
        f"**Jam** (cases/bridge_jam): event-driven takes {j['event']['substeps']} sub-steps down "
        f"to {j['event']['min_dt']:.2g} s and stops with ContactJamError at t = "
        f"{j['event']['stopped_at']:.2f} s; Moreau-Jean runs to t = {j['moreau']['end']:.0f} s "
        f"in {j['moreau']['steps']} steps (smallest {j['moreau']['min_dt']:.2g} s, median "
        f"{j['moreau']['median_dt']:.2g} s), deepest overlap "
        f"{1000 * j['moreau']['max_overlap']:.2f} mm "
        f"({100 * j['moreau']['max_overlap_share']:.1f} % of the radius), up to "
        f"{j['moreau']['max_contacts']} contacts, fastest log in the last second "
        f"{j['moreau']['max_speed_last_second']:.3f} m/s.", "",
        f"**Dry front** (Ritter, {w['cells']} cells, order 1, t = 6 s; the solver's step "
        "bound counts every edge of a face, walls included, so on this one-cell-wide strip "
        f"it has slack: negative depths start between {safe:g} and {unsafe:g} times it):",
        "",
        "| step | cfl | steps | L1 error h (m) | smallest depth before clipping (m) | "
        "max relative volume error | max speed (m/s) | first negative depth at t (s) |",
        "|---|---|---|---|---|---|---|---|"]
    for k in (f"cfl_x{f:g}" for f in FACTORS):
        r = w[k]
        first = "never" if r["first_negative_at"] is None else f"{r['first_negative_at']:.2f}"
        first += "" if r["finite"] else " (NaN at the end)"
        lines.append(f"| {r['factor']:g} x positivity step | {r['cfl']:.2f} | {r['steps']} | "
                     f"{r['l1_h']:.3g} | {r['min_h_before_clip']:.2g} | "
                     f"{r['max_rel_volume_error']:.2g} | {r['max_speed']:.3g} | {first} |")
    la = w["lake_at_rest"]
    lines += ["", f"Lake at rest on the emerged bump ({la['cells']} cells, t = 20 s): largest "
              f"velocity {la['solver_max_u']:.2g} m/s with the solver's hydrostatic "
              f"reconstruction, {la['naive_max_u']:.2g} m/s with a naive centred bed source.", ""]
    text = "\n".join(lines)
    (RESULTS / f"stability{SUFFIX}.md").write_text(text)
    print(text)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps and cells (the report)")
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    global SUFFIX
    SUFFIX = "_quick" if args.quick else ""
    RESULTS.mkdir(parents=True, exist_ok=True)
    res = dict(quick=args.quick)
    for name, fn in (("drag", lambda: stiff_drag(plt, args.quick)), ("jam", lambda: jam(plt)),
                     ("dry", lambda: dry_front(plt, args.quick))):
        t0 = time.perf_counter()
        res[name] = fn()
        print(f"{name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    (RESULTS / f"stability{SUFFIX}.json").write_text(json.dumps(res, indent=1, default=float))
    write_md(res)


if __name__ == "__main__":
    main()
