"""Each physics term against exact values (docs/model.md sections 6-9, 15.F-G)."""
import numpy as np
import pytest

from driftlog.analytic import SolidBodyRotation, UniformFlow
from driftlog.columns import L_PAR, L_PERP, NLIN
from driftlog.logs import Logs, flotation_depth, flotation_depths, submerged_volume
from driftlog.physics import (
    PhysicsOptions,
    drag_speed_product,
    effective_area,
    ganser_cd,
    log_parameters,
    rhs_kernel,
)


@pytest.mark.parametrize("rho_b,ratio", [(500.0, 1.000), (720.0, 1.353), (1000.0, 2.000)])
def test_flotation_thresholds(rho_b, ratio):
    assert flotation_depth(0.04, rho_b, 1000.0) / 0.04 == pytest.approx(ratio, abs=6e-4)
    assert flotation_depth(0.04, 1000.0001, 1000.0) == np.inf


def test_flotation_depths_of_many_logs_are_each_logs_own():
    """``flotation_depths`` reuses the log before's depth where radius and density repeat:
    every log still gets exactly its own ``flotation_depth``, in runs of equal logs, where only
    the radius or only the density repeats, for sinking and neutral logs."""
    rng = np.random.default_rng(4)
    radius = np.repeat(rng.choice([0.05, 0.1, 0.2], 60), rng.integers(1, 5, 60))
    density = np.repeat(rng.choice([500.0, 700.0, 1000.0, 1100.0], 60),
                        rng.integers(1, 5, 60))[:radius.size]
    radius = radius[:density.size]
    assert np.any((radius[1:] == radius[:-1]) & (density[1:] != density[:-1]))
    assert np.any((radius[1:] != radius[:-1]) & (density[1:] == density[:-1]))
    want = np.array([flotation_depth(r, d, 1000.0) for r, d in zip(radius, density,
                                                                    strict=True)])
    np.testing.assert_array_equal(flotation_depths(radius, density, 1000.0), want)


def test_beach_log_floats_from_8_cm():
    assert flotation_depth(0.04, 1000.0, 1000.0) == pytest.approx(0.08)


def test_submerged_volume():
    r, L = 0.1, 2.0
    assert submerged_volume(0.0, r, L) == 0.0
    assert submerged_volume(r, r, L) == pytest.approx(0.5 * np.pi * r * r * L)
    assert submerged_volume(2 * r, r, L) == pytest.approx(np.pi * r * r * L)
    assert submerged_volume(5 * r, r, L) == pytest.approx(np.pi * r * r * L)


def test_ganser_sphere_limit_and_high_re():
    # psi = 1 and d_n = d_v give K1 = K2 = 1: the sphere curve
    dv = 0.1
    s_eff = np.pi * dv ** 2 / 4
    for re in (0.1, 10.0, 1e3, 1e5):
        cd = ganser_cd(re, dv, 1.0, 1.0, s_eff)
        sphere = 24 / re * (1 + 0.1118 * re ** 0.6567) + 0.4305 / (1 + 3305 / re)
        assert cd == pytest.approx(sphere, rel=1e-12)
    # C_D -> 0.4305 K2 as Re -> infinity, K2 from the base-10 logarithm
    P = log_parameters([1.0], [0.04], [1000.0], [0.08])[0]
    psi, k2 = P[7], P[8]
    assert k2 == pytest.approx(10 ** (1.8148 * (-np.log10(psi)) ** 0.5743))
    assert ganser_cd(1e12, P[6], psi, k2, 0.01) == pytest.approx(0.4305 * k2, rel=1e-3)
    # the product C_D s is finite at s = 0 (Stokes limit) and matches at s > 0
    s, rho, mu = 0.3, 1000.0, 1e-3
    re = rho * s * P[6] / mu
    assert drag_speed_product(s, P[6], psi, k2, 0.01, rho, mu) == pytest.approx(
        ganser_cd(re, P[6], psi, k2, 0.01) * s, rel=1e-12)
    assert np.isfinite(drag_speed_product(0.0, P[6], psi, k2, 0.01, rho, mu))


def test_effective_area():
    r, L = 0.04, 1.0
    assert effective_area(r, L, 1.0, 0.0) == pytest.approx(np.pi * r * r)
    assert effective_area(r, L, 0.0, 1.0) == pytest.approx(2 * r * L)


def _rhs(flow, logs, **opts):
    n = len(logs)
    S = logs.state.copy()
    s = flow.sample(S[:, 0], S[:, 1], 0.0)
    P = log_parameters(logs.length, logs.radius, logs.density, logs.float_depth)
    D, lin = np.zeros((n, 6)), np.zeros((n, NLIN))
    rhs_kernel(S, s.values, P, PhysicsOptions(**opts).vector(), D, lin)
    return D, lin, P


@pytest.mark.parametrize("area,expected", [
    ("paper", lambda r, L: 2 * r * L),
    ("ganser", lambda r, L: np.pi / 4 * (6 * r * r * L) ** (2 / 3)),
    ("wetted", lambda r, L: L * 0.5 * r)])
def test_drag_force_constant_cd_broadside(area, expected):
    # broadside log at rest in uniform flow of 1 m/s, depth 0.5 r for the wetted area
    r, L = 0.04, 1.0
    flow = UniformFlow(1.0, 0.0, depth=0.5 * r if area == "wetted" else 1.0)
    logs = Logs([0.0], [0.0], np.pi / 2, L, r, 500.0, u=0.0)
    D, lin, P = _rhs(flow, logs, level="drag", drag_law="constant", drag_coefficient=1.2,
                     drag_area=area)
    m_eff = 500.0 * P[0, 3] + 500.0 * P[0, 3]
    force = 0.5 * 1.2 * 1000.0 * expected(r, L) * 1.0
    assert D[0, 3] == pytest.approx(force / m_eff, rel=1e-12)
    # quadratic law: the rate along w is twice the rate across
    assert lin[0, L_PAR] == pytest.approx(2 * lin[0, L_PERP], rel=1e-5)


def test_linear_drag_and_fluid_volume():
    flow = UniformFlow(0.5, 0.0, depth=1.0)
    logs = Logs([0.0], [0.0], 0.0, 1.0, 0.1, 600.0, u=0.0)
    D, _, P = _rhs(flow, logs, level="full", drag_law="linear", linear_drag=3.0)
    m_eff = (600.0 + 500.0) * P[0, 3]
    assert D[0, 3] == pytest.approx(3.0 * 0.5 / m_eff)
    # submerged volume in shallow water: at depth r the fluid volume is half the body
    flow = UniformFlow(0.5, 0.0, depth=0.1)
    D2, _, P = _rhs(flow, logs, level="full", drag_law="linear", linear_drag=3.0,
                    fluid_volume="submerged")
    m_eff2 = 600.0 * P[0, 3] + 500.0 * 0.5 * P[0, 3]
    assert D2[0, 3] == pytest.approx(3.0 * 0.5 / m_eff2)


def test_pressure_gradient_and_added_mass_in_rotation():
    # eq. 7 with the log at rest at (R, 0) in solid-body rotation, no drag
    Om, R = 0.2, 3.0
    flow = SolidBodyRotation(Om)
    logs = Logs([R], [0.0], 0.0, 1.0, 0.1, 700.0)
    D, _, _ = _rhs(flow, logs, level="full", drag_law="linear", linear_drag=0.0, rotation=False)
    # J U_w = -Om^2 (x, y); 1.5 rho V dU/dt = 0; so a = rho J U_w / (rho_b + rho/2)
    assert D[0, 3] == pytest.approx(-1000 * Om ** 2 * R / (700 + 500), rel=1e-12)
    assert D[0, 4] == pytest.approx(0.0, abs=1e-15)
    # surface slope option: -g grad(eta) in place of J U_w: the same on this field
    D2, _, _ = _rhs(flow, logs, level="full", drag_law="linear", linear_drag=0.0, rotation=False,
                    surface_slope=True)
    np.testing.assert_allclose(D2, D, atol=1e-14)


def test_surface_slope_on_sloping_uniform_flow():
    flow = UniformFlow(1.0, 0.0, surface_slope=(-1e-3, 0.0))
    logs = Logs([0.0], [0.0], 0.0, 1.0, 0.1, 700.0, u=1.0)
    D, _, _ = _rhs(flow, logs, level="full", surface_slope=False)
    assert D[0, 3] == 0.0  # DU_w/Dt = 0: no force
    D, _, _ = _rhs(flow, logs, level="full", surface_slope=True)
    assert D[0, 3] == pytest.approx(1000 * 9.81 * 1e-3 / 1200)


def test_torque_signs():
    # centre of pressure on the upstream side: a log at 45 degrees in flow along +x with the
    # drag lever turns it broadside (docs/model.md section 9, known limitation)
    flow = UniformFlow(1.0, 0.0)
    logs = Logs([0.0], [0.0], np.pi / 4, 1.0, 0.05, 700.0, u=0.0)
    D, _, _ = _rhs(flow, logs, level="drag")
    assert D[0, 5] > 0  # towards theta = pi/2 (broadside)
    logs = Logs([0.0], [0.0], -np.pi / 4, 1.0, 0.05, 700.0, u=0.0)
    D, _, _ = _rhs(flow, logs, level="drag")
    assert D[0, 5] < 0
    # resistance torque opposes relative rotation (sign-corrected), whatever its direction
    for om in (0.5, -0.5):
        logs = Logs([0.0], [0.0], 0.0, 1.0, 0.05, 700.0, omega=om)
        D, _, _ = _rhs(UniformFlow(0.0, 0.0), logs, level="full", drag_law="constant")
        assert np.sign(D[0, 5]) == -np.sign(om)
