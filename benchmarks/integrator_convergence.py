"""Integrators: observed orders, work-precision, and where explicit schemes fail (issue 4).

1. Solid-body rotation, neutrally buoyant log (docs/model.md section 15.A, exact): position
   error after 500 s against the exact circle.
2. Quadratic drag from rest in uniform flow (docs/model.md section 15.C, exact): position
   after 20 s.
3. A free vortex interpolated on an unstructured triangle mesh (P1 in space): error against the
   same mesh field integrated with a tiny step.  The velocity gradient jumps at face edges, so
   RK4's fourth order is lost there (measured, not assumed).
4. The flume log of the paper's section 3.4 (L 0.2 m, r 4 mm, rho_b 720) released from rest:
   explicit RK4 at the paper's step L/|U_b| diverges; bounding the step by the drag relaxation
   time, or the exponential integrator at the paper's step, are the remedies.

Times (work-precision) are the CPU time of ``N_LOGS`` identical copies of each log, best of
``REPEAT`` runs, so that they measure the integrator's kernels rather than the per-step Python
overhead of a one-log run (and not the other jobs of a shared machine); the error is that of
one copy.

    python benchmarks/integrator_convergence.py

writes benchmarks/results/integrators.{csv,md}, integrators_order.png,
integrators_work_precision.png and stiff_drag.png.
"""

import time

import numpy as np
from _common import RESULTS, run_recording_first_log, write_table

from driftlog.analytic import FreeVortex, SolidBodyRotation, UniformFlow, on_mesh
from driftlog.logs import Logs
from driftlog.mesher import polygon_mesh, rectangle
from driftlog.physics import PhysicsOptions
from driftlog.tracker import IntegrationError, StepOptions, StepTooSmallError, Tracker

METHODS = ("euler", "rk4", "exponential")
N_LOGS = 256  # identical copies per run: timings of the kernels, not of the Python loop
REPEAT = 2
OMEGA = 2 * np.pi / 100


def fixed(dt):
    return StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9, drag_fraction=0.0)


def run(flow, logs, method, dt, t_end, physics, initial):
    tr = Tracker(flow, logs, physics, method, fixed(dt), t_end=t_end, output_interval=t_end,
                 hydro_step=t_end, initial_velocity=initial)
    # CPU time: on a shared machine steadier than wall time (the kernels run serially here)
    t0 = time.process_time()
    tr.run()
    return logs.state[0].copy(), time.process_time() - t0


def problem_A(method, dt):
    logs = Logs(np.ones(N_LOGS), 0.0, 0.0, 0.5, 0.05, 1000.0)
    S, w = run(SolidBodyRotation(OMEGA), logs, method, dt, 500.0,
               PhysicsOptions(torque_force="drag"), "flow")
    a = OMEGA * 500
    return np.hypot(S[0] - np.cos(a), S[1] - np.sin(a)), w


def problem_C(method, dt):
    U0, cd, rho, rho_b, r, L = 1.5, 1.1, 1000.0, 600.0, 0.1, 2.0
    logs = Logs(np.zeros(N_LOGS), 0.0, 0.0, L, r, rho_b, u=0.0)
    beta = cd * rho * np.pi * r * r / (2 * (rho_b + rho / 2) * logs.volume[0])
    T = 20.0
    x_exact = U0 * T - np.log(1 + beta * U0 * T) / beta
    S, w = run(UniformFlow(U0, 0.0), logs, method, dt, T,
               PhysicsOptions(drag_law="constant", drag_coefficient=cd), "given")
    return abs(S[0] - x_exact), w


_MESH = {}
# translation only: isolates the effect of the P1 kinks on the order
MESH_PHYSICS = PhysicsOptions(rotation=False)


def problem_mesh(method, dt):
    if not _MESH:
        mesh = polygon_mesh(rectangle(-10, -10, 10, 10), 0.5)
        _MESH["flow"] = on_mesh(FreeVortex(5.0, core_radius=1.0), mesh)
        logs = Logs([4.0], [0.0], 0.3, 0.5, 0.05, 800.0)
        _MESH["ref"] = run(_MESH["flow"], logs, "rk4", 0.001, 30.0, MESH_PHYSICS, "flow")[0]
    logs = Logs(np.full(N_LOGS, 4.0), 0.0, 0.3, 0.5, 0.05, 800.0)
    S, w = run(_MESH["flow"], logs, method, dt, 30.0, MESH_PHYSICS, "flow")
    return np.hypot(*(S[:2] - _MESH["ref"][:2])), w


PROBLEMS = {
    "A: solid-body rotation (exact)": (problem_A, {"euler": [0.5, 0.25, 0.125, 0.0625],
                                                    "rk4": [4.0, 2.0, 1.0, 0.5, 0.25],
                                                    "exponential": [4.0, 2.0, 1.0, 0.5, 0.25]}),
    "C: quadratic drag from rest (exact)": (problem_C, {"euler": [0.04, 0.02, 0.01, 0.005],
                                                         "rk4": [0.4, 0.2, 0.1, 0.05],
                                                         "exponential": [1.6, 0.8, 0.4, 0.2,
                                                                         0.1, 0.05]}),
    "free vortex on a triangle mesh (P1)": (problem_mesh, {
        "euler": [0.1, 0.05, 0.025, 0.0125],
        "rk4": [0.4, 0.2, 0.1, 0.05, 0.025, 0.0125],
        "exponential": [0.4, 0.2, 0.1, 0.05, 0.025, 0.0125]}),
}


def stiff_figure(plt):
    flow = UniformFlow(0.3, 0.0, depth=0.1)
    kw = dict(t_end=5.0, hydro_step=5.0, output_interval=5.0, initial_velocity="rest")
    curves = {}

    def trace(method, step, label):
        logs = Logs([0.0], [0.0], 0.3, 0.2, 0.004, 720.0)
        tr = Tracker(flow, logs, PhysicsOptions(), method, step, **kw)
        t, u, err = run_recording_first_log(tr)
        curves[label] = (t, u, err, tr.stats["substeps"])

    paper = StepOptions(length_fraction=1.0, drag_fraction=0.0, max_step=0.5)
    trace("rk4", paper, "RK4, paper's step L/|U_b|")
    trace("rk4", StepOptions(drag_fraction=0.5), "RK4, step <= tau_D / 2")
    trace("exponential", paper, "exponential, paper's step")
    trace("rk4", StepOptions(drag_fraction=0.01), "reference (RK4, tau_D / 100)")
    fig, ax = plt.subplots(figsize=(8, 4.5))
    styles = ["o-", "s-", "d-", "k-"]
    for (label, (t, u, err, n)), style in zip(curves.items(), styles, strict=True):
        lab = f"{label}: {n} steps" + (f", diverges (u_b = {u[-1]:.3g} m/s after {len(u)} "
                                       f"step), stops with {err}" if err else "")
        ax.plot(np.concatenate([[0], t]), np.concatenate([[0], u]), style, ms=4, lw=1.2,
                label=lab)
    ax.set_ylim(-0.2, 0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("log velocity u_b (m/s)")
    ax.set_title("Flume log (L 0.2 m, r 4 mm, rho_b 720) released from rest in 0.3 m/s flow\n"
                 "drag relaxation time tau_D about 0.03 s")
    ax.axhline(0.3, color="0.6", lw=0.8)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "stiff_drag.png", dpi=120)
    plt.close(fig)
    return {k: (v[2], v[3]) for k, v in curves.items()}


def main():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = []
    for pname, (fn, dts) in PROBLEMS.items():
        for method in METHODS:
            fn(method, dts[method][0])  # compile
            prev = None
            for dt in dts[method]:
                try:
                    err, wall = fn(method, dt)
                    for _ in range(REPEAT - 1):
                        wall = min(wall, fn(method, dt)[1])
                except (IntegrationError, StepTooSmallError) as exc:
                    print(f"{pname} {method} dt={dt}: fails ({exc})")
                    err, wall = np.nan, np.nan
                order = np.log2(prev / err) if prev else np.nan
                rows.append(dict(problem=pname, integrator=method, dt=dt, error=err,
                                 seconds=wall, order=order))
                print(rows[-1])
                prev = err
    write_table("integrators", rows, ["problem", "integrator", "dt", "error", "seconds", "order"],
                "Integrators: error against exact (or fine-step) solutions, observed order",
                f"order = log2(error(2 dt) / error(dt)); seconds: CPU time of {N_LOGS} identical "
                f"logs, best of {REPEAT} runs. Re-create: "
                "`python benchmarks/integrator_convergence.py`.")
    for kind, xkey, xlabel, fname in (("order", "dt", "step dt (s)", "integrators_order.png"),
                                      ("wp", "seconds", f"CPU time for {N_LOGS} logs (s)",
                                       "integrators_work_precision.png")):
        fig, axes = plt.subplots(1, len(PROBLEMS), figsize=(15, 4.2))
        for ax, pname in zip(axes, PROBLEMS, strict=True):
            for method, mk in zip(METHODS, "osd", strict=True):
                r = [x for x in rows if x["problem"] == pname and x["integrator"] == method]
                ax.loglog([x[xkey] for x in r], [max(x["error"], 1e-16) for x in r], mk + "-",
                          label=method)
            ax.set_title(pname, fontsize=10)
            ax.set_xlabel(xlabel)
            ax.set_ylabel("position error (m)")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
        fig.suptitle("Observed orders" if kind == "order" else
                     "Work-precision: error against CPU time (lower left is better)")
        fig.tight_layout()
        fig.savefig(RESULTS / fname, dpi=120)
        plt.close(fig)
    print(stiff_figure(plt))


if __name__ == "__main__":
    main()
