"""The force kernel against the reference formulas it was rewritten from (issue 15 item 2).

``physics.log_rhs`` precomputes per-log constants (``log_parameters``), rearranges Ganser's
law around them and differentiates it analytically for the drag linearisation.  The
reference below is the straightforward evaluation of docs/model.md sections 7-9 that the
kernel used before (plain Python, one log at a time; the linearisation's rate along w by a
central difference).  Every derivative and every linearisation column must agree to 1e-12
relative (of the magnitude of the terms summed) over random states, flows and every option
combination; the analytic slope of Ganser's C_D s must agree with a finite difference to the
difference's truncation error.
"""
import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from driftlog.columns import (
    L_PAR,
    L_PERP,
    L_ROT,
    L_WX,
    L_WY,
    NLIN,
    NSTATE,
    NVAR,
    P_DV,
    P_HSTAR,
    P_INERTIA,
    P_K2,
    P_L,
    P_MASS,
    P_PSI,
    P_QSIDE,
    P_R,
    P_RHOB,
    P_VOL,
)
from driftlog.flow import DETADX, DETADY, DUDT, DUDX, DUDY, DVDT, DVDX, DVDY, ETA, H, U, V
from driftlog.logs import flotation_depth, submerged_volume
from driftlog.physics import PhysicsOptions, _ganser_cds, log_parameters, rhs_kernel

# ----------------------------------------------------------------------------- reference


def ref_area(r, L, ca, sa):
    return math.sqrt((math.pi * r * r * ca) ** 2 + (2.0 * r * L * sa) ** 2)


def ref_cds(s, dv, psi, k2, s_eff, rho, mu):
    """Ganser's C_D s (the old ``drag_speed_product``); returns (value, magnitude of terms)."""
    dn = math.sqrt(4.0 * s_eff / math.pi)
    k1 = 1.0 / (dn / (3.0 * dv) + (2.0 / 3.0) / math.sqrt(psi))
    rk = rho * s * dv / mu * k1 * k2
    stokes = 24.0 * mu / (rho * dv * k1) * (1.0 + 0.1118 * rk ** 0.6567)
    return stokes + 0.4305 * k2 * s * rk / (rk + 3305.0)


def ref_drag(s, ca, sa, h, p, o):
    """The drag factor k (force k w)."""
    r, L = p[P_R], p[P_L]
    if o.drag_law == "linear":
        return o.linear_drag
    s_eff = ref_area(r, L, ca, sa)
    if o.drag_area == "paper":
        area = s_eff
    elif o.drag_area == "ganser":
        area = 0.25 * math.pi * p[P_DV] ** 2
    else:
        hs = min(max(h, 0.0), 2.0 * r)
        d = math.acos(1.0 - hs / r)
        area = L * hs * sa + r * r * (d - math.sin(d) * math.cos(d)) * ca
    if o.drag_law == "constant":
        cds = o.drag_coefficient * s
    else:
        cds = ref_cds(s, p[P_DV], p[P_PSI], p[P_K2], s_eff, o.water_density, o.viscosity)
    return 0.5 * o.water_density * area * cds


def ref_torque(dw, s, p, o):
    r, L = p[P_R], p[P_L]
    if o.drag_law == "linear":
        return o.linear_drag * L * L / 12.0 * dw
    kr = 2.0 * r * o.water_density * L ** 4 / 64.0
    if o.drag_law == "constant":
        return kr * o.drag_coefficient * abs(dw) * dw
    vr = math.sqrt(s * s + (0.25 * L * dw) ** 2)
    if vr == 0.0:
        return 0.0
    cds = ref_cds(vr, p[P_DV], p[P_PSI], p[P_K2], 2.0 * r * L, o.water_density, o.viscosity)
    return kr * cds * (abs(dw) / vr) * dw


def ref_rhs(st, fl, p, o):
    """(D, lin, scale): the reference derivative, linearisation and the size of each's terms."""
    rho, g = o.water_density, o.gravity
    uw, vw, h = fl[U], fl[V], fl[H]
    omega_w = 0.5 * (fl[DVDX] - fl[DUDY])
    lin = np.zeros(NLIN)
    if o.level == "tracer":
        D = np.array([uw, vw, omega_w if o.rotation else 0.0, 0, 0, 0])
        return D, lin, np.abs(D), lin
    ub, vb, th, om = st[3], st[4], st[2], st[5]
    ex, ey = math.cos(th), math.sin(th)
    wx, wy = uw - ub, vw - vb
    s = math.hypot(wx, wy)
    if s > 0:
        ew = ex * wx + ey * wy
        ca, sa, sgn = abs(ew) / s, abs(ex * wy - ey * wx) / s, (1.0 if ew >= 0 else -1.0)
        nwx, nwy = wx / s, wy / s
    else:
        ca, sa, sgn, nwx, nwy = 1.0, 0.0, 1.0, 1.0, 0.0
    vol = p[P_VOL]
    vf = vol if o.fluid_volume == "body" else submerged_volume(h, p[P_R], p[P_L])
    m_eff = p[P_RHOB] * vol + 0.5 * rho * vf
    kd = ref_drag(s, ca, sa, h, p, o)
    fx, fy = kd * wx, kd * wy
    size = abs(kd) * s
    # rate along w: g'(s), g = k(s) s, by a central difference (checked to its truncation)
    ds = 1e-5 * s + 1e-7
    gp = ((s + ds) * ref_drag(s + ds, ca, sa, h, p, o)
          - max(s - ds, 0.0) * ref_drag(max(s - ds, 0.0), ca, sa, h, p, o)) / (s + ds
                                                                               - max(s - ds, 0))
    lin[L_PAR], lin[L_PERP], lin[L_WX], lin[L_WY] = gp / m_eff, kd / m_eff, nwx, nwy
    if o.level == "full":
        ax, ay = 0.5 * ub + uw, 0.5 * vb + vw
        jx = fl[DUDX] * ax + fl[DUDY] * ay
        jy = fl[DVDX] * ax + fl[DVDY] * ay
        if o.surface_slope:
            jx = fl[DUDX] * 0.5 * ub + fl[DUDY] * 0.5 * vb - g * fl[DETADX]
            jy = fl[DVDX] * 0.5 * ub + fl[DVDY] * 0.5 * vb - g * fl[DETADY]
        px, py = rho * vf * (1.5 * fl[DUDT] + jx), rho * vf * (1.5 * fl[DVDT] + jy)
        fx, fy = fx + px, fy + py
        size += math.hypot(px, py) + rho * vf * (1.5 * math.hypot(fl[DUDT], fl[DVDT])
                                                 + abs(fl[DUDX] * ax) + abs(fl[DUDY] * ay)
                                                 + abs(fl[DVDX] * ax) + abs(fl[DVDY] * ay))
    if o.motion == "friction" and h < p[P_HSTAR]:
        wp = g * (p[P_RHOB] * vol - rho * submerged_volume(h, p[P_R], p[P_L]))
        if wp > 0:
            if o.bed_slope == "flat":
                sx = sy = 0.0
                ff = o.bed_friction * wp
            else:
                gx, gy = fl[DETADX], fl[DETADY]
                cs = 1.0 / math.sqrt(1.0 + gx * gx + gy * gy)
                sx, sy, ff = -wp * cs * gx, -wp * cs * gy, o.bed_friction * wp * cs
            fx, fy = fx + sx, fy + sy
            size += math.hypot(sx, sy) + ff
            sp = math.hypot(ub, vb)
            if sp > 0:
                fx, fy = fx - ff * ub / sp, fy - ff * vb / sp
            else:
                f = math.hypot(fx, fy)
                fx, fy = (0.0, 0.0) if f <= ff else (fx - ff * fx / f, fy - ff * fy / f)
    axb, ayb = fx / m_eff, fy / m_eff
    sz_a = size / m_eff
    if not o.rotation:
        D = np.array([ub, vb, 0.0, axb, ayb, 0.0])
        return D, lin, np.array([abs(ub), abs(vb), 0, sz_a, sz_a, 0]), np.abs(lin)
    if o.level == "full" and o.torque_force == "total":
        ftx, fty, fsz = p[P_MASS] * axb, p[P_MASS] * ayb, p[P_MASS] * sz_a
    else:
        ftx, fty, fsz = kd * wx, kd * wy, abs(kd) * s
    arm = -0.25 * p[P_L] * ca ** 3 * sgn
    dw = omega_w - om
    tr = ref_torque(dw, s, p, o)
    tau_d = arm * ex * fty - arm * ey * ftx
    dom = (tau_d + tr) / p[P_INERTIA]
    sz_om = (abs(arm) * fsz * 2 + abs(tr)) / p[P_INERTIA]
    gg = max(abs(dw), 1e-6)
    tg = abs(ref_torque(gg, s, p, o))
    for _ in range(2):
        if tg <= 0.0:
            break
        g2 = max(abs(dw), gg * math.sqrt(abs(tau_d) / tg), 1e-6)
        if g2 == gg:
            break
        gg = g2
        tg = abs(ref_torque(gg, s, p, o))
    lin[L_ROT] = (1.0 if o.drag_law == "linear" else 2.0) * tg / gg / p[P_INERTIA]
    D = np.array([ub, vb, om, axb, ayb, dom])
    return D, lin, np.array([abs(ub), abs(vb), abs(om), sz_a, sz_a, sz_om]), np.abs(lin)


# ----------------------------------------------------------------------------- cases
OPTION_SETS = [dict(level=lv, rotation=rot, drag_law=law, drag_area=area)
               for lv, rot, law, area in itertools.product(
                   ("tracer", "drag", "full"), (True, False), ("ganser", "constant", "linear"),
                   ("paper", "ganser", "wetted"))]
OPTION_SETS += [dict(level="full", fluid_volume="submerged"), dict(level="full",
                                                                  surface_slope=True),
                dict(level="full", torque_force="drag"),
                dict(level="full", motion="friction"),
                dict(level="drag", motion="friction", bed_slope="flat", drag_area="wetted"),
                dict(level="full", water_density=1025.0, viscosity=1.3e-3, gravity=9.8,
                     drag_coefficient=0.8, linear_drag=2.5)]


def random_cases(n, seed):
    """n logs with random geometry, states and flow samples (some degenerate on purpose)."""
    rng = np.random.default_rng(seed)
    L = rng.uniform(0.3, 15.0, n)
    r = rng.uniform(0.02, 0.6, n)
    rho_b = rng.uniform(300.0, 990.0, n)
    hstar = np.array([flotation_depth(ri, di, 1000.0) for ri, di in zip(r, rho_b, strict=True)])
    P = log_parameters(L, r, rho_b, hstar)
    S = np.zeros((n, NSTATE))
    S[:, 0:2] = rng.uniform(-50, 50, (n, 2))
    S[:, 2] = rng.uniform(-4, 4, n)
    S[:, 3:5] = rng.normal(0, 1.5, (n, 2))
    S[:, 5] = rng.normal(0, 0.5, n)
    F = np.zeros((n, NVAR))
    F[:, H] = rng.uniform(0.0, 2.0, n) * (2 * r + 0.5)
    F[:, U], F[:, V] = rng.normal(0, 2.0, n), rng.normal(0, 2.0, n)
    F[:, DUDT:DVDY + 1] = rng.normal(0, 0.05, (n, 6))
    F[:, DETADX:DETADY + 1] = rng.normal(0, 2e-3, (n, 2))
    F[:, ETA] = rng.uniform(0, 10, n)
    # degenerate: log moving with the flow (s = 0), no relative rotation (dw = 0), both
    S[:8, 3], S[:8, 4] = F[:8, U], F[:8, V]
    S[4:12, 5] = 0.5 * (F[4:12, DVDX] - F[4:12, DUDY])
    S[12:16, 3:6] = 0.0
    F[12:16, U:V + 1] = 0.0
    F[12:16, DUDX:DVDY + 1] = 0.0
    return S, F, P


def close(got, ref, size, i, rel=1e-12):
    """|got - ref| <= rel (|ref| + size), elementwise."""
    bad = np.abs(got - ref) > rel * (np.abs(ref) + size)
    assert not bad.any(), (i, got, ref, size)


@pytest.mark.parametrize("opts", OPTION_SETS, ids=lambda o: "-".join(map(str, o.values())))
def test_forces_equal_reference_to_1e12(opts):
    o = PhysicsOptions(**opts)
    S, F, P = random_cases(300, 11)
    n = S.shape[0]
    D, lin = np.empty((n, NSTATE)), np.empty((n, NLIN))
    rhs_kernel(S, F, P, o.vector(), D, lin, True)
    D2, lin2 = np.empty((n, NSTATE)), np.empty((n, NLIN))
    rhs_kernel(S, F, P, o.vector(), D2, lin2, False)
    np.testing.assert_array_equal(D2, D)  # the linearisation does not change the forces
    for i in range(n):
        Dr, lr, size, lsize = ref_rhs(S[i], F[i], P[i], o)
        # per force evaluation: 1e-12 relative to the magnitude of the terms summed (the
        # relative error where they do not cancel)
        close(D[i], Dr, size, i)
        if o.level == "tracer":
            continue
        cols = [L_PERP, L_WX, L_WY, L_ROT]
        close(lin[i, cols], lr[cols], lsize[cols], i)
        # the rate along w: analytic here, a central difference in the reference (its
        # truncation error (ds / s)^2 ~ 1e-10 and round-off ~ 1e-16 s / ds); at s = 0 the
        # Stokes limit, where it equals the rate across
        if S[i, 3] == F[i, U] and S[i, 4] == F[i, V]:
            assert lin[i, L_PAR] == pytest.approx(lr[L_PERP], rel=1e-12, abs=1e-300), i
            continue
        assert lin[i, L_PAR] == pytest.approx(lr[L_PAR], rel=1e-8, abs=1e-300), i


def test_ganser_slope_is_the_derivative():
    """s d(C_D s)/ds analytic against central differences: error falls as ds^2."""
    P = log_parameters([2.0, 8.0, 0.5], [0.2, 0.4, 0.03], [700.0] * 3, [0.3] * 3)
    opt = PhysicsOptions().vector()
    for p in P:
        q = 1.7
        for s in (1e-4, 0.03, 0.7, 4.0):
            def f(x, p=p, q=q):
                return _ganser_cds(x, q, p, opt)[0]

            exact = _ganser_cds(s, q, p, opt)[1] / s
            errs = []
            for ds in (1e-2 * s, 5e-3 * s):
                fd = (f(s + ds) - f(s - ds)) / (2 * ds)
                errs.append(abs(fd - exact) / abs(exact))
            # second-order truncation: halving ds divides the error by 4 (to round-off)
            assert errs[1] < 1e-5
            assert errs[1] == pytest.approx(errs[0] / 4, rel=0.05) or errs[1] < 1e-12
        # and C_D s itself is the reference formula's
        s_eff = 2.0 * p[P_R] * p[P_L]
        for s in (0.0, 0.01, 1.0, 5.0):
            ref = ref_cds(s, p[P_DV], p[P_PSI], p[P_K2], s_eff, 1000.0, 1e-3)
            assert _ganser_cds(s, p[P_QSIDE], p, opt)[0] == pytest.approx(ref, rel=1e-13)


# whole trajectories: the final states of tests/test_fused.py's scene (200 logs, 20 s on a
# draining, meandering channel: logs leave, strand, cross many faces) as the code before issue
# 15 computed them (commit bdea483, with the fix of docs/model.md section 11 applied: a step
# landing on a snapshot takes its last stage's dU/dt from its own pair of snapshots; the
# references were computed again with that fix on bdea483's code).  Where the step sizes
# stay the same (full RK4: the length bound and max_step set them) only round-off separates
# the two; where the drag relaxation
# bound sets the step (drag level) or the exponential integrator integrates the linearised
# drag, the analytic rate along w replaces a forward difference whose relative error was
# ~5e-7, and the trajectories move by that much of their local truncation error.
BEFORE = Path(__file__).parent / "data" / "physics_before_issue15.npz"


@pytest.mark.parametrize("level,method,tol", [("full", "rk4", 1e-9), ("drag", "rk4", 1e-5),
                                              ("full", "exponential", 1e-6)])
def test_trajectories_agree_with_the_code_before(level, method, tol):
    from test_fused import run

    ref = np.load(BEFORE)
    tr, logs = run(level, True, method, fused=True)
    key = f"{level}_{method}"
    assert tr.stats["substeps"] == int(ref[key + "_substeps"])
    np.testing.assert_array_equal(logs.status, ref[key + "_status"])
    np.testing.assert_allclose(logs.state, ref[key + "_state"], rtol=0, atol=tol)
