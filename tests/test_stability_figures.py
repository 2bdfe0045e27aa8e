"""Numbers the stability figures (benchmarks/stability_figures.py) rely on that other tests do
not check: the broadside log's exact quadratic-drag solution (test_integrators checks the
end-on log), and the dry front's Euler update staying non-negative before the solver's clip
at its positivity step (so the clip is round-off only), and not past it."""
import numpy as np
import pytest

from driftlog.analytic import UniformFlow
from driftlog.logs import Logs
from driftlog.mesher import channel_mesh
from driftlog.physics import PhysicsOptions
from driftlog.solver import ShallowWaterSolver
from driftlog.tracker import StepOptions, Tracker

U0, L, R, RHO_B, RHO, CD = 0.21, 0.2, 0.004, 720.0, 1000.0, 1.0


def _flume_log(method, step, t_end=5.0):
    log = Logs([0.0], [0.0], np.pi / 2, L, R, RHO_B)  # broadside to the flow along x
    Tracker(UniformFlow(U0, 0.0, depth=0.1), log,
            PhysicsOptions(drag_law="constant", drag_coefficient=CD, rotation=False), method,
            step, t_end=t_end, output_interval=t_end, hydro_step=t_end,
            initial_velocity="rest").run()
    return log.state[0]


def test_broadside_flume_log_follows_exact_quadratic_drag():
    # docs/model.md section 15.C with S = 2 r L (alpha = 90 deg) and V_b = pi r^2 L
    beta = CD * RHO * 2 * R * L / (2 * (RHO_B + RHO / 2) * np.pi * R * R * L)
    T = 5.0
    x_exact = U0 * T - np.log(1 + beta * U0 * T) / beta
    u_exact = U0 - U0 / (1 + beta * U0 * T)
    S = _flume_log("rk4", StepOptions(max_step=0.002, length_fraction=1e9, angle_step=1e9,
                                      drag_fraction=0.0))
    assert S[0] == pytest.approx(x_exact, abs=1e-9)
    assert S[3] == pytest.approx(u_exact, abs=1e-9)
    assert S[2] == np.pi / 2 and S[4] == 0.0  # stays broadside, no drift across
    # the exponential integrator at the paper's step L/|U_b| (about 1 s, 25 tau_D): stable
    S = _flume_log("exponential", StepOptions(length_fraction=1.0, drag_fraction=0.0,
                                              max_step=L / U0))
    assert S[3] == pytest.approx(u_exact, abs=2e-3)


def _ritter_min_update(factor, n=100):
    """Smallest depth of the order-1 Euler update (before the clip) over a Ritter dam break."""
    dx = 10.0 / n
    s = ShallowWaterSolver(channel_mesh(10.0, dx, dx, structured=True), order=1)
    s.cfl *= factor  # past the scenario's check, as the figure does
    s.set_state(np.where(s.mesh.face_x < 5.0, 0.005, 0.0))
    v0 = s.volume()
    lowest = np.inf
    while s.t < 6.0:
        rmax = s._rates(s._h, s._hu, s._hv, s.t)  # the internal numbering
        dt = min(s.cfl / rmax, 6.0 - s.t)
        lowest = min(lowest, float((s._h + dt * s._res[0]).min()))
        s.step(6.0 - s.t)
    return lowest, s.volume_error() / v0


def test_dry_front_update_positive_at_the_bound_and_not_past_it():
    lowest, verr = _ritter_min_update(1.0)
    assert lowest >= 0.0 and abs(verr) < 1e-14
    lowest, verr = _ritter_min_update(4.0)
    assert lowest < -1e-6 and verr > 1e-6  # negative depths, clipped: water created
