"""Exact solutions of docs/model.md section 15 (A to D), orders of convergence, stiff failure."""
import numpy as np
import pytest

from driftlog.analytic import FreeVortex, SolidBodyRotation, UniformFlow
from driftlog.integrators import phi_functions
from driftlog.logs import Logs
from driftlog.physics import PhysicsOptions
from driftlog.tracker import IntegrationError, StepOptions, StepTooSmallError, Tracker


def run_one(flow, log, method, dt, t_end, initial="given", **phys):
    """Run one log with a fixed step (the paper's bounds switched off)."""
    tr = Tracker(flow, log, PhysicsOptions(**phys), method=method,
                 step=StepOptions(max_step=dt, length_fraction=1e9, angle_step=1e9,
                                  drag_fraction=0.0),
                 t_end=t_end, output_interval=t_end, hydro_step=t_end, initial_velocity=initial)
    tr.run()
    return log.state[0].copy(), tr


OMEGA = 2 * np.pi / 100  # 100 s period


@pytest.mark.parametrize("method", ["rk4", "exponential"])
def test_A_neutral_log_in_solid_body_rotation(method):
    # docs/model.md section 15.A: RK4 position error over 500 s: about 4e-6, 2.6e-7, 1.6e-8 for
    # dt 1, 0.5, 0.25 s at a start radius of 1 m
    errors = []
    for dt in (1.0, 0.5, 0.25):
        log = Logs([1.0], [0.0], 0.0, 0.5, 0.05, 1000.0)
        S, _ = run_one(SolidBodyRotation(OMEGA, depth=1.0), log, method, dt, 500.0,
                       initial="flow", torque_force="drag")
        a = OMEGA * 500
        errors.append(np.hypot(S[0] - np.cos(a), S[1] - np.sin(a)))
        assert S[2] == pytest.approx(a, abs=1e-6)  # rotates at Omega
        assert S[5] == pytest.approx(OMEGA, abs=1e-8)
    np.testing.assert_allclose(errors, [4.08e-6, 2.55e-7, 1.59e-8], rtol=0.05)
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(orders > 3.9)


def test_A_paper_vortex_relative_error_1e_10():
    # the paper (section 3.1) reports an RK4 relative error of 1e-10 over 500 s; the error is
    # 4.08e-6 dt^4, so it needs dt <= 0.07 s: 1/16 s (8000 steps) gives 6.2e-11
    log = Logs([1.0], [0.0], 0.0, 0.5, 0.05, 1000.0)
    S, _ = run_one(SolidBodyRotation(OMEGA), log, "rk4", 0.0625, 500.0, initial="flow",
                   torque_force="drag")
    err = np.hypot(S[0] - np.cos(OMEGA * 500), S[1] - np.sin(OMEGA * 500))
    assert 3e-11 < err < 1e-10


def test_A_prime_free_vortex():
    gamma, R = 2 * np.pi * 2.0, 4.0
    rate = gamma / (2 * np.pi * R ** 2)
    log = Logs([R], [0.0], 0.3, 0.5, 0.05, 1000.0)
    S, _ = run_one(FreeVortex(gamma), log, "rk4", 0.05, 50.0, initial="flow",
                   torque_force="drag")
    a = rate * 50.0
    assert np.hypot(S[0] - R * np.cos(a), S[1] - R * np.sin(a)) < 3e-8  # RK4 at dt = 0.05 s
    # irrotational: the angle stays (drift 5e-7 rad from the drag torque of the O(dt^4) slip)
    assert S[2] == pytest.approx(0.3, abs=2e-6)


@pytest.mark.parametrize("rho_b", [500.0, 900.0])
def test_B_linear_drag_solid_body_rotation(rho_b):
    k, Om, rho = 20.0, OMEGA, 1000.0
    log = Logs([2.0], [0.0], 0.0, 1.0, 0.1, rho_b, u=0.0, v=0.0)
    V = log.volume[0]
    a = (rho_b + rho / 2) * V
    l1, l2 = np.roots([a, k - 1j * rho * V * Om / 2, rho * V * Om ** 2 - 1j * k * Om])
    z0, dz0 = 2.0 + 0j, 0j
    A2 = (dz0 - l1 * z0) / (l2 - l1)
    A1 = z0 - A2
    T = 60.0
    z = A1 * np.exp(l1 * T) + A2 * np.exp(l2 * T)
    S, _ = run_one(SolidBodyRotation(Om), log, "rk4", 0.05, T, drag_law="linear",
                   linear_drag=k, rotation=False)
    assert abs(S[0] + 1j * S[1] - z) < 1e-7
    S, _ = run_one(SolidBodyRotation(Om), Logs([2.0], [0.0], 0.0, 1.0, 0.1, rho_b), "exponential",
                   0.5, T, drag_law="linear", linear_drag=k, rotation=False)
    assert abs(S[0] + 1j * S[1] - z) < 1e-5


def test_C_quadratic_drag_uniform_flow_from_rest():
    U0, cd, rho, rho_b, r, L = 1.5, 1.1, 1000.0, 600.0, 0.1, 2.0
    log = Logs([0.0], [0.0], 0.0, L, r, rho_b, u=0.0)
    beta = cd * rho * np.pi * r * r / (2 * (rho_b + rho / 2) * log.volume[0])
    T = 20.0
    x_exact = U0 * T - np.log(1 + beta * U0 * T) / beta
    w_exact = U0 / (1 + beta * U0 * T)
    for method, dt, tol in (("rk4", 0.05, 1e-6), ("exponential", 0.05, 1e-6),
                            ("euler", 0.001, 2e-3)):
        log = Logs([0.0], [0.0], 0.0, L, r, rho_b, u=0.0)
        S, _ = run_one(UniformFlow(U0, 0.0), log, method, dt, T, drag_law="constant",
                       drag_coefficient=cd)
        assert S[0] == pytest.approx(x_exact, abs=tol), method
        assert U0 - S[3] == pytest.approx(w_exact, abs=tol), method


def test_D_pure_rotation_at_vortex_centre():
    r, L, rho_b, cd = 0.1, 2.0, 700.0, 1.0
    log = Logs([0.0], [0.0], 0.0, L, r, rho_b, omega=OMEGA + 0.5)
    I = log.inertia[0]
    k = 2 * r * cd * 1000.0 * L ** 4 / 64
    T = 30.0
    dw = 0.5 / (1 + k / I * 0.5 * T)
    S, _ = run_one(SolidBodyRotation(OMEGA), log, "rk4", 0.01, T, drag_law="constant",
                   drag_coefficient=cd)
    assert S[5] - OMEGA == pytest.approx(dw, rel=1e-8)
    assert abs(S[0]) + abs(S[1]) < 1e-12


@pytest.mark.parametrize("method,order", [("euler", 1), ("rk4", 4), ("exponential", 4)])
def test_observed_order_on_analytic_field(method, order):
    # B-type problem (linear drag, rotation): smooth, so the classical orders show
    def err(dt):
        log = Logs([2.0], [0.0], 0.0, 1.0, 0.1, 700.0, u=0.0, v=0.0)
        S, _ = run_one(SolidBodyRotation(OMEGA), log, method, dt, 40.0, drag_law="linear",
                       linear_drag=5.0, rotation=False)
        return S[:2]
    ref = err(0.005)
    dts = [0.8, 0.4, 0.2] if order == 4 else [0.1, 0.05, 0.025]
    e = [np.linalg.norm(err(dt) - ref) for dt in dts]
    p = np.log2(np.array(e[:-1]) / e[1:])
    assert np.all(np.abs(p - order) < 0.3), (method, p)


def test_phi_functions_continuous_and_exact():
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 50
    for z in (-1e-8, -0.05, -0.0999, -0.1001, -0.5, -30.0):
        p = phi_functions(z)
        zz = mpmath.mpf(z)
        e = mpmath.exp(zz)
        exact = ((e - 1) / zz, (e - 1 - zz) / zz ** 2, (e - 1 - zz - zz ** 2 / 2) / zz ** 3)
        for k in range(3):
            assert p[k] == pytest.approx(float(exact[k]), rel=1e-13), (z, k)
    assert phi_functions(0.0) == pytest.approx((1.0, 0.5, 1 / 6))


def flume_log(**kw):
    # the flume log of the paper's section 3.4: tau_D about 0.03 s
    return Logs([0.0], [0.0], 0.3, 0.2, 0.004, 720.0, u=0.0, **kw)


def test_stiff_drag_rk4_at_paper_step_fails_and_remedies_work():
    flow = UniformFlow(0.3, 0.0, depth=0.1)
    # the paper's bound alone: dt = L / |U_b| (about 0.7 s once the log moves); tau_D ~ 0.03 s
    paper = StepOptions(length_fraction=1.0, drag_fraction=0.0, max_step=0.5)
    kw = dict(t_end=20.0, hydro_step=20.0, initial_velocity="rest")
    tr = Tracker(flow, flume_log(), PhysicsOptions(), "rk4", paper, **kw)
    with pytest.raises((IntegrationError, StepTooSmallError)):
        tr.run()
    # remedy 1: bound the step by the drag relaxation time; remedy 2: exponential integrator
    ref = flume_log()
    Tracker(flow, ref, PhysicsOptions(), "rk4", StepOptions(drag_fraction=0.1), **kw).run()
    expo = flume_log()
    tr = Tracker(flow, expo, PhysicsOptions(), "exponential", paper, **kw)
    tr.run()
    assert tr.stats["substeps"] < 60
    # 6 m travelled; the error (4 cm) is made in the first step, where the frozen drag rate
    # (55 1/s at rest) falls to 4 1/s within the step: under a quarter of the log's length
    assert np.hypot(*(expo.state[0, :2] - ref.state[0, :2])) < 0.25 * 0.2
    assert expo.state[0, 3] == pytest.approx(ref.state[0, 3], abs=1e-4)
    # and it converges: at 0.1 s steps (lambda dt up to 5.5) it is within a millimetre
    expo = flume_log()
    Tracker(flow, expo, PhysicsOptions(), "exponential",
            StepOptions(drag_fraction=0.0, max_step=0.1), **kw).run()
    assert np.hypot(*(expo.state[0, :2] - ref.state[0, :2])) < 1e-3
