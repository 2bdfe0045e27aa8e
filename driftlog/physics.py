"""Forces and torques on a log (docs/model.md sections 5-10), as numba kernels over flat arrays.

``rhs_kernel`` turns the log state (x, y, theta, u, v, omega) and the flow sampled at the log
centres into the time derivative of the state, and the linearisation of drag that the
exponential integrator and the explicit step bound use (drag relaxation rates).

Options (``PhysicsOptions``) follow docs/model.md's [choice] items; each default is the paper's
reading.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import (
    DETADX,
    DETADY,
    DUDT,
    DUDX,
    DUDY,
    DVDT,
    DVDX,
    DVDY,
    ETA,
    NLIN,
    NPARAM,
    NSTATE,
    OMEGA,
    P_AEND,
    P_AGANSER,
    P_ASIDE,
    P_DV,
    P_DVK2,
    P_HSTAR,
    P_INERTIA,
    P_INV3DV,
    P_K2,
    P_KSPH,
    P_KTORQUE,
    P_L,
    P_MASS,
    P_PSI,
    P_QSIDE,
    P_R,
    P_RHOB,
    P_VOL,
    THETA,
    UB,
    VB,
    H,
    U,
    V,
    X,
    Y,
)
from driftlog.errors import ScenarioError
from driftlog.logs import flotation_depth, submerged_volume
from driftlog.schema import Key, Section

__all__ = ["PhysicsOptions", "log_parameters", "rhs_kernel", "log_rhs", "ganser_cd",
           "drag_speed_product", "effective_area", "rest_drive", "bed_weight", "soak_kernel",
           "sample_row", "stage_columns",
           "TRACER", "DRAG", "FULL", "NPARAM", "NLIN"]

TRACER, DRAG, FULL = 0, 1, 2
LEVELS = {"tracer": TRACER, "drag": DRAG, "full": FULL}
GANSER, CONSTANT, LINEAR = 0, 1, 2
DRAG_LAWS = {"ganser": GANSER, "constant": CONSTANT, "linear": LINEAR}
AREA_PAPER, AREA_GANSER, AREA_WETTED = 0, 1, 2
DRAG_AREAS = {"paper": AREA_PAPER, "ganser": AREA_GANSER, "wetted": AREA_WETTED}

# per-log parameter columns: driftlog.columns P_L ... P_HSTAR, NPARAM
# option vector
(O_LEVEL, O_ROT, O_SUBMERGED, O_SLOPE, O_LAW, O_AREA, O_CD, O_KLIN, O_RHO, O_G, O_MU,
 O_TORQUE_DRAG, O_MOTION, O_MU_BED, O_BED_SLOPE) = range(15)
NOPT = 15
# initial motion (docs/model.md 6.1): a log moves only when it floats (the paper), or also on the
# bed when the flow's forces overcome bed friction (Braudrick and Grant 2000)
MOTION_FLOATING, MOTION_FRICTION = 0, 1
MOTIONS = {"floating": MOTION_FLOATING, "friction": MOTION_FRICTION}
BED_SLOPES = {"flat": 0, "surface": 1}
# linearisation columns: driftlog.columns L_PAR ... L_ROT, NLIN


@dataclass
class PhysicsOptions:
    """The log transport model's options (docs/model.md sections 7-10); defaults are the paper's."""

    level: str = "full"
    rotation: bool = True
    fluid_volume: str = "body"
    surface_slope: bool = False
    drag_law: str = "ganser"
    drag_area: str = "paper"
    drag_coefficient: float = 1.0
    linear_drag: float = 1.0
    water_density: float = 1000.0
    gravity: float = 9.81
    viscosity: float = 1.0e-3
    torque_force: str = "total"
    motion: str = "floating"
    bed_friction: float = 0.5
    bed_slope: str = "surface"
    waterlogging: str = "off"
    saturated_density: float = 1100.0
    waterlogging_time: float | None = None
    _LATER = ("motion", "bed_friction", "bed_slope", "waterlogging", "saturated_density",
              "waterlogging_time")

    @classmethod
    def from_scenario(cls, section: dict, level=None, rotation=None):
        """From a validated [physics] section; ``level``/``rotation`` replace an 'auto' choice."""
        lv = level or section["level"]
        rot = rotation if rotation is not None else section["rotation"] == "on"
        return cls(level=lv, rotation=rot, fluid_volume=section["fluid_volume"],
                   surface_slope=section["surface_slope"], drag_law=section["drag_law"],
                   drag_area=section["drag_area"], drag_coefficient=section["drag_coefficient"],
                   linear_drag=section["linear_drag"], water_density=section["water_density"],
                   gravity=section["gravity"], viscosity=section["viscosity"],
                   torque_force=section["torque_force"],
                   # beyond the paper (docs/model.md 6.1-6.2): a hand-made section may omit them
                   **{k: section[k] for k in cls._LATER if k in section})

    def vector(self) -> np.ndarray:
        """The options as the float vector the kernels read."""
        o = np.zeros(NOPT)
        o[O_LEVEL] = LEVELS[self.level]
        o[O_ROT] = 1.0 if self.rotation else 0.0
        o[O_SUBMERGED] = 1.0 if self.fluid_volume == "submerged" else 0.0
        o[O_SLOPE] = 1.0 if self.surface_slope else 0.0
        o[O_LAW] = DRAG_LAWS[self.drag_law]
        o[O_AREA] = DRAG_AREAS[self.drag_area]
        o[O_CD] = self.drag_coefficient
        o[O_KLIN] = self.linear_drag
        o[O_RHO] = self.water_density
        o[O_G] = self.gravity
        o[O_MU] = self.viscosity
        o[O_TORQUE_DRAG] = 1.0 if self.torque_force == "drag" else 0.0
        o[O_MOTION] = MOTIONS[self.motion]
        o[O_MU_BED] = self.bed_friction
        o[O_BED_SLOPE] = BED_SLOPES[self.bed_slope]
        return o

    def as_dict(self):
        """The options as a plain dict (written to trajectory files)."""
        return asdict(self)


def log_parameters(length, radius, density, float_depth) -> np.ndarray:
    """Per-log constants (n, NPARAM): geometry, mass, inertia and Ganser's shape factors.

    Besides the log's own quantities (``driftlog.columns`` P_L ... P_HSTAR), the constants
    that the force kernels would otherwise recompute at every evaluation from the geometry
    alone: the end-on and broadside areas, the sphericity term and 1 / (3 d_v) of Ganser's
    K1, d_v K2, Ganser's reference area, 1 / K1 at the broadside area (the resistance
    torque's, docs/model.md section 9) and the torque's lever integral r L^4 / 32.
    """
    L = np.asarray(length, float)
    r = np.asarray(radius, float)
    rho_b = np.asarray(density, float)
    n = L.size
    P = np.empty((n, NPARAM))
    vol = np.pi * r ** 2 * L
    mass = rho_b * vol
    dv = (6.0 * r ** 2 * L) ** (1.0 / 3.0)  # volume-equivalent sphere diameter
    area = 2 * np.pi * r * L + 2 * np.pi * r ** 2
    psi = np.pi * dv ** 2 / area  # sphericity
    P[:, P_L], P[:, P_R], P[:, P_RHOB] = L, r, rho_b
    P[:, P_VOL], P[:, P_MASS] = vol, mass
    P[:, P_INERTIA] = mass * (L ** 2 / 12.0 + r ** 2 / 4.0)
    P[:, P_DV], P[:, P_PSI] = dv, psi
    # base-10 logarithm (Ganser 1993 eq. 18; public codes often use ln by mistake)
    P[:, P_K2] = 10.0 ** (1.8148 * (-np.log10(np.minimum(psi, 1.0))) ** 0.5743)
    P[:, P_HSTAR] = float_depth
    P[:, P_AEND] = np.pi * r * r
    P[:, P_ASIDE] = 2.0 * r * L
    P[:, P_INV3DV] = 1.0 / (3.0 * dv)
    P[:, P_KSPH] = (2.0 / 3.0) / np.sqrt(psi)
    P[:, P_DVK2] = dv * P[:, P_K2]
    P[:, P_AGANSER] = 0.25 * np.pi * dv * dv
    # 1 / K1 = d_n / (3 d_v) + (2/3) / sqrt(psi), d_n = sqrt(4 S / pi) at the broadside area
    P[:, P_QSIDE] = np.sqrt(P[:, P_ASIDE] * (4.0 / np.pi)) * P[:, P_INV3DV] + P[:, P_KSPH]
    P[:, P_KTORQUE] = r * L ** 4 / 32.0  # 2 r L^4 / 64: T_R = rho P_KTORQUE C_D s |dw| dw
    return P


# --------------------------------------------------------------------- drag (docs/model.md 8)
@nb.njit(cache=True, inline="always")
def effective_area(r, L, cos_a, sin_a):
    """S_eff = sqrt((pi r^2 cos a)^2 + (2 r L sin a)^2), the paper's projected area."""
    a = np.pi * r * r * cos_a
    b = 2.0 * r * L * sin_a
    return np.sqrt(a * a + b * b)


@nb.njit(cache=True)
def ganser_cd(re, dv, psi, k2, s_eff):
    """Ganser's C_D (eq. 18) at Reynolds number re for projected area s_eff."""
    dn = np.sqrt(4.0 * s_eff / np.pi)
    k1 = 1.0 / (dn / (3.0 * dv) + (2.0 / 3.0) / np.sqrt(psi))
    rk = re * k1 * k2
    return 24.0 / (re * k1) * (1.0 + 0.1118 * rk ** 0.6567) + 0.4305 * k2 / (1.0 + 3305.0 / rk)


@nb.njit(cache=True)
def drag_speed_product(s, dv, psi, k2, s_eff, rho, mu):
    """C_D * s for Ganser's law, finite as s -> 0 (the Stokes limit) where C_D is not."""
    dn = np.sqrt(4.0 * s_eff / np.pi)
    k1 = 1.0 / (dn / (3.0 * dv) + (2.0 / 3.0) / np.sqrt(psi))
    re = rho * s * dv / mu
    rk = re * k1 * k2
    stokes = 24.0 * mu / (rho * dv * k1) * (1.0 + 0.1118 * rk ** 0.6567)
    return stokes + 0.4305 * k2 * s * rk / (rk + 3305.0)


@nb.njit(cache=True, inline="always")
def _ganser_cds(s, q, p, opt):
    """Ganser's C_D s at speed s and its slope s d(C_D s)/ds, for 1 / K1 = q.

    The arithmetic of ``drag_speed_product`` rearranged around the per-log constants
    (``log_parameters``): two divisions and one fractional power.  With Re K1 K2 = r_k,
    C_D s = 24 (mu / rho) q / d_v (1 + 0.1118 r_k^0.6567) + 0.4305 K2 s r_k / (r_k + 3305),
    and its slope reuses the power: s d(C_D s)/ds = 24 (mu / rho) q / d_v 0.1118 0.6567
    r_k^0.6567 + 0.4305 K2 s r_k / (r_k + 3305) (1 + 3305 / (r_k + 3305)).
    """
    nu = opt[O_MU] / opt[O_RHO]
    rk = s * p[P_DVK2] / (nu * q)  # Re K1 K2
    pw = rk ** 0.6567
    stokes = 72.0 * nu * q * p[P_INV3DV]  # 24 mu / (rho d_v K1)
    t = 1.0 / (rk + 3305.0)
    newton = 0.4305 * p[P_K2] * s * rk * t
    return stokes + stokes * 0.1118 * pw + newton, \
        stokes * (0.1118 * 0.6567) * pw + newton * (1.0 + 3305.0 * t)


@nb.njit(cache=True, inline="always")
def _drag_coef(s, cos_a, sin_a, h, p, opt):
    """Drag factor k (the drag force is k w: w relative velocity, s = |w|) and dg/ds.

    g(s) = k(s) s is the drag's magnitude at fixed direction; its derivative g'(s) (exact:
    Ganser's law differentiated, no finite difference) is the drag linearisation's rate
    along w (times the effective mass).
    """
    law = opt[O_LAW]
    if law == LINEAR:
        return opt[O_KLIN], opt[O_KLIN]
    area_kind = opt[O_AREA]
    ae = p[P_AEND] * cos_a
    asd = p[P_ASIDE] * sin_a
    s_eff = np.sqrt(ae * ae + asd * asd)  # effective_area
    if area_kind == AREA_PAPER:
        area = s_eff
    elif area_kind == AREA_GANSER:
        area = p[P_AGANSER]
    else:
        r = p[P_R]
        hs = min(max(h, 0.0), 2.0 * r)
        d = np.arccos(1.0 - hs / r)
        area = p[P_L] * hs * sin_a + r * r * (d - np.sin(d) * np.cos(d)) * cos_a
    half = 0.5 * opt[O_RHO] * area
    if law == CONSTANT:
        k = half * (opt[O_CD] * s)
        return k, 2.0 * k
    q = np.sqrt(s_eff * (4.0 / np.pi)) * p[P_INV3DV] + p[P_KSPH]  # 1 / K1
    cds, slope = _ganser_cds(s, q, p, opt)
    return half * cds, half * (cds + slope)


@nb.njit(cache=True, inline="always")
def _torque(dw, s, p, opt):
    """Resistance torque T_R for relative rotation dw = omega_w - omega_b (sign corrected)."""
    law = opt[O_LAW]
    if law == LINEAR:
        L = p[P_L]
        return opt[O_KLIN] * L * L / 12.0 * dw  # k/L per unit length, lever s, integrated
    kr = p[P_KTORQUE] * opt[O_RHO]  # 2 r rho L^4 / 64
    if law == CONSTANT:
        return kr * opt[O_CD] * abs(dw) * dw
    # [choice] Ganser's C_D at the relative speed of translation and of the rod's mean
    # rotational speed L |dw| / 4, so that C_D stays finite when the log does not translate;
    # at the broadside area (a rotating rod moves across its axis): 1 / K1 = P_QSIDE
    ld = 0.25 * p[P_L] * dw
    vr = np.sqrt(s * s + ld * ld)
    if vr == 0.0:
        return 0.0
    cds, _ = _ganser_cds(vr, p[P_QSIDE], p, opt)
    return kr * cds * (abs(dw) / vr) * dw


# ------------------------------------------------------------ bed friction (docs/model.md 6.1)
@nb.njit(cache=True, inline="always")
def bed_weight(h, gx, gy, p, opt):
    """Bed terms of a log on the bed: (downslope weight force x, y; friction limit).

    W' = g (rho_b V_b - rho V_sub(h)) is the buoyancy-reduced weight (> 0 below the flotation
    depth); the bed slope a_s is the free-surface slope (gx, gy) (``bed_slope = "surface"``) or
    zero (``"flat"``).  The weight pulls W' sin(a_s) downslope; friction resists up to
    mu_bed W' cos(a_s).
    """
    wp = opt[O_G] * (p[P_RHOB] * p[P_VOL] - opt[O_RHO] * submerged_volume(h, p[P_R], p[P_L]))
    if wp <= 0.0:
        return 0.0, 0.0, 0.0
    if opt[O_BED_SLOPE] == 0.0:
        return 0.0, 0.0, opt[O_MU_BED] * wp
    cos_s = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
    # W' sin(a_s) along -grad / |grad|: sin(a_s) = |grad| cos(a_s)
    return -wp * cos_s * gx, -wp * cos_s * gy, opt[O_MU_BED] * wp * cos_s


@nb.njit(cache=True)
def rest_drive(th, fl, p, opt):
    """The force that would move a log lying still on the bed, and the friction that holds it.

    Returns (fx, fy, ff): the flow's forces at U_b = 0, omega_b = 0 (drag at w = U_w and, at
    the full level, the pressure-gradient force) plus the downslope weight (``bed_weight``);
    ff = mu_bed W' cos(a_s).  The log moves when |(fx, fy)| >= ff (docs/model.md 6.1): with
    ``drag_law = "constant"`` and ``drag_area = "wetted"`` on a bed sloping down the flow this
    is Braudrick and Grant's (2000) threshold.
    """
    h = fl[H]
    wx, wy = fl[U], fl[V]
    s = np.sqrt(wx * wx + wy * wy)
    ex, ey = np.cos(th), np.sin(th)
    if s > 0.0:
        cos_a = abs(ex * wx + ey * wy) / s
        sin_a = abs(ex * wy - ey * wx) / s
    else:
        cos_a, sin_a = 1.0, 0.0
    kd, _ = _drag_coef(s, cos_a, sin_a, h, p, opt)
    fx, fy = kd * wx, kd * wy
    if opt[O_LEVEL] == FULL:
        rho = opt[O_RHO]
        vf = p[P_VOL] if opt[O_SUBMERGED] == 0.0 else submerged_volume(h, p[P_R], p[P_L])
        if opt[O_SLOPE] > 0.0:
            jx, jy = -opt[O_G] * fl[DETADX], -opt[O_G] * fl[DETADY]
        else:
            jx = fl[DUDX] * wx + fl[DUDY] * wy
            jy = fl[DVDX] * wx + fl[DVDY] * wy
        fx += rho * vf * (1.5 * fl[DUDT] + jx)
        fy += rho * vf * (1.5 * fl[DVDT] + jy)
    sx, sy, ff = bed_weight(h, fl[DETADX], fl[DETADY], p, opt)
    return fx + sx, fy + sy, ff


@nb.njit(cache=True, inline="always")
def _bed_friction(fx, fy, ub, vb, fl, p, opt):
    """Add the downslope weight and the bed friction to the force (fx, fy) on a log on the bed.

    Sliding (U_b != 0): Coulomb friction mu_bed W' cos(a_s) against U_b.  At rest: the
    friction holds the log while the other forces stay below its limit (static friction).
    """
    sx, sy, ff = bed_weight(fl[H], fl[DETADX], fl[DETADY], p, opt)
    fx += sx
    fy += sy
    sp = np.sqrt(ub * ub + vb * vb)
    if sp > 0.0:
        return fx - ff * ub / sp, fy - ff * vb / sp
    f = np.sqrt(fx * fx + fy * fy)
    if f <= ff:
        return 0.0, 0.0
    return fx - ff * fx / f, fy - ff * fy / f


@nb.njit(cache=True, inline="always")
def log_rhs(s_, fl, p, opt, want_lin):
    """Time derivative of one log's state and its drag linearisation (docs/model.md 7-9, 12.3).

    ``s_``: the state (x, y, theta, u, v, omega) as a tuple; ``fl``: the flow sampled at the
    log, the NVAR columns of ``driftlog.flow`` as a tuple; ``p``: the log's parameter row.
    Returns (D, lin): D the 6 derivatives, lin the NLIN linearisation columns (zeros unless
    ``want_lin``).  The per-log body of ``rhs_kernel``, shared with the fused tracking
    kernels (``driftlog.fused``) so that both compute the same numbers.
    """
    level = opt[O_LEVEL]
    rot = opt[O_ROT] > 0.0
    rho = opt[O_RHO]
    h = fl[H]
    uw, vw = fl[U], fl[V]
    dudx, dudy, dvdx, dvdy = fl[DUDX], fl[DUDY], fl[DVDX], fl[DVDY]
    omega_w = 0.5 * (dvdx - dudy)
    lp = lq = lwx = lwy = lr = 0.0
    if level == TRACER:  # U_b = U_w: positions follow the flow; velocities are synced
        return (uw, vw, omega_w if rot else 0.0, 0.0, 0.0, 0.0), (lp, lq, lwx, lwy, lr)
    ub, vb = s_[UB], s_[VB]
    th = s_[THETA]
    ex, ey = np.cos(th), np.sin(th)
    wx, wy = uw - ub, vw - vb
    s = np.sqrt(wx * wx + wy * wy)
    if s > 0.0:
        inv_s = 1.0 / s
        nwx, nwy = wx * inv_s, wy * inv_s
        ew = ex * nwx + ey * nwy
        cos_a = abs(ew)
        sin_a = abs(ex * nwy - ey * nwx)
        sgn = 1.0 if ew >= 0.0 else -1.0
    else:
        cos_a, sin_a, sgn = 1.0, 0.0, 1.0
        nwx, nwy = 1.0, 0.0
    vol = p[P_VOL]
    vf = vol if opt[O_SUBMERGED] == 0.0 else submerged_volume(h, p[P_R], p[P_L])
    m_eff = p[P_RHOB] * vol + 0.5 * rho * vf  # added mass, C_m = 1/2 (docs/model.md (33))
    kd, gprime = _drag_coef(s, cos_a, sin_a, h, p, opt)
    fx, fy = kd * wx, kd * wy  # drag (docs/model.md (35))
    if want_lin:
        # drag linearisation: F = g(s) w/s, dF/dw = g'(s) w w^T/s^2 + g(s)/s (I - w w^T/s^2),
        # g'(s) from Ganser's law differentiated (``_drag_coef``)
        inv_m = 1.0 / m_eff
        lp = gprime * inv_m
        lq = kd * inv_m
        lwx = nwx
        lwy = nwy
    if level == FULL:
        # pressure gradient + added mass (docs/model.md (34)):
        # 3/2 rho V dU_w/dt + rho V J (U_b/2 + U_w)
        ax_, ay_ = 0.5 * ub + uw, 0.5 * vb + vw
        jx = dudx * ax_ + dudy * ay_
        jy = dvdx * ax_ + dvdy * ay_
        if opt[O_SLOPE] > 0.0:
            # [choice] -g grad(eta) in place of the steady part J U_w of DU_w/Dt
            jx = dudx * 0.5 * ub + dudy * 0.5 * vb - opt[O_G] * fl[DETADX]
            jy = dvdx * 0.5 * ub + dvdy * 0.5 * vb - opt[O_G] * fl[DETADY]
        fx += rho * vf * (1.5 * fl[DUDT] + jx)
        fy += rho * vf * (1.5 * fl[DVDT] + jy)
    if opt[O_MOTION] == MOTION_FRICTION and h < p[P_HSTAR]:
        # a log moving on the bed (docs/model.md 6.1): downslope weight and Coulomb friction
        fx, fy = _bed_friction(fx, fy, ub, vb, fl, p, opt)
    inv_m = 1.0 / m_eff
    axb, ayb = fx * inv_m, fy * inv_m
    if not rot:
        return (ub, vb, 0.0, axb, ayb, 0.0), (lp, lq, lwx, lwy, lr)
    # force at the centre of pressure (docs/model.md section 9): the total hydrodynamic force
    # m_b dU_b/dt, or the drag alone (drag level, or torque_force = "drag": volume forces act at G)
    if level == FULL and opt[O_TORQUE_DRAG] == 0.0:
        ftx, fty = p[P_MASS] * axb, p[P_MASS] * ayb
    else:
        ftx, fty = kd * wx, kd * wy
    # centre of pressure on the axis, on the side facing the relative flow (docs/model.md (41))
    arm = -0.25 * p[P_L] * cos_a * cos_a * cos_a * sgn
    gpx, gpy = arm * ex, arm * ey
    om = s_[OMEGA]
    dw = omega_w - om
    tr = _torque(dw, s, p, opt)
    tau_d = gpx * fty - gpy * ftx
    dom = (tau_d + tr) / p[P_INERTIA]
    if want_lin:
        # rotational relaxation rate d T_R / d omega_b / I.  T_R is quadratic in dw, so its
        # slope vanishes at dw = 0 although the driving torque tau_d is about to spin the log
        # up to where T_R balances it: take the slope at that balance |dw*| when it is larger
        # (a few fixed-point steps on the local quadratic model T_R(x) ~ T_R(g) (x / g)^2).
        g = max(abs(dw), 1e-6)
        # T_R is odd in dw: |T_R(|dw|)| is the |tr| just computed
        tg = abs(tr) if g == abs(dw) else abs(_torque(g, s, p, opt))
        for _ in range(2):
            if tg <= 0.0:
                break
            g2 = max(abs(dw), g * np.sqrt(abs(tau_d) / tg), 1e-6)
            if g2 == g:
                break
            g = g2
            tg = abs(_torque(g, s, p, opt))
        # slope of T_R at g: T_R / g for the linear law, 2 T_R / g for a quadratic one (exact
        # for a constant C_D; Ganser's C_D falls with speed, so this bounds the slope above)
        lr = (1.0 if opt[O_LAW] == LINEAR else 2.0) * tg / g / p[P_INERTIA]
    return (ub, vb, om, axb, ayb, dom), (lp, lq, lwx, lwy, lr)


@nb.njit(cache=True, inline="always")
def stage_columns(opt):
    """Which flow columns ``log_rhs`` reads under options ``opt`` (the stage sampling's set).

    Returns (depth, rotation, full, slope): the depth H (submerged volume, wetted area, bed
    friction), the gradient terms DUDY and DVDX of the flow's rotation, the full model's
    DUDT, DVDT, DUDX, DVDY, and the free-surface slope DETADX, DETADY; U and V are always
    read, ETA never.  Tracer mode reads U, V and the rotation only.
    """
    level = opt[O_LEVEL]
    rot = opt[O_ROT] > 0.0
    if level == TRACER:
        return False, rot, False, False
    friction = opt[O_MOTION] == MOTION_FRICTION
    depth = opt[O_SUBMERGED] != 0.0 or opt[O_AREA] == AREA_WETTED or friction
    full = level == FULL
    return depth, rot or full, full, (full and opt[O_SLOPE] > 0.0) or friction


@nb.njit(cache=True, inline="always")
def sample_row(F, i):
    """Row i of a flow sample (n, NVAR) as the tuple ``log_rhs`` and ``rest_drive`` read."""
    return (F[i, H], F[i, U], F[i, V], F[i, DUDT], F[i, DVDT], F[i, DUDX], F[i, DUDY],
            F[i, DVDX], F[i, DVDY], F[i, DETADX], F[i, DETADY], F[i, ETA])


@kernel(nrt=False)
def rhs_kernel(S, F, P, opt, D, lin, want_lin=True):
    """Time derivative D of the states S (n, 6) given flow samples F (n, NVAR).

    With ``want_lin``, also fills ``lin`` (n, NLIN): the drag relaxation rates (1/s) along and
    across the relative velocity, its direction, and the rotational relaxation rate; the
    exponential integrator treats these exactly and the explicit ones bound their step by them
    (only the first stage of a step needs them: they cost as much as the forces).
    """
    for i in nb.prange(S.shape[0]):
        s_ = (S[i, X], S[i, Y], S[i, THETA], S[i, UB], S[i, VB], S[i, OMEGA])
        fl = sample_row(F, i)
        d, ln = log_rhs(s_, fl, P[i], opt, want_lin)
        for k in range(NSTATE):
            D[i, k] = d[k]
        if want_lin:
            for k in range(NLIN):
                lin[i, k] = ln[k]


# ------------------------------------------------------------ waterlogging (docs/model.md 6.2)
@kernel
def soak_kernel(idx, dt, rho_sat, tau, rho, density, volume, length, radius, mass, inertia,
                float_depth, P):
    """Waterlog the logs ``idx`` over dt: rho_b <- rho_sat - (rho_sat - rho_b) exp(-dt / tau).

    The exact solution of d rho_b / dt = (rho_sat - rho_b) / tau over the step; updates the
    mass, inertia, flotation depth and the logs' parameter rows P in place.
    """
    f = np.exp(-dt / tau)
    for k in nb.prange(idx.size):
        i = idx[k]
        d = rho_sat - (rho_sat - density[i]) * f
        density[i] = d
        m = d * volume[i]
        mass[i] = m
        inertia[i] = m * (length[i] ** 2 / 12.0 + radius[i] ** 2 / 4.0)
        float_depth[i] = flotation_depth(radius[i], d, rho)
        P[i, P_RHOB] = d
        P[i, P_MASS] = m
        P[i, P_INERTIA] = inertia[i]
        P[i, P_HSTAR] = float_depth[i]


# --------------------------------------------------------------------- the scenario section
PHYSICS_LEVELS = ("tracer", "drag", "full", "auto")


def _check_physics(t, prefix, scen):
    if t["waterlogging"] != "off" and t["waterlogging_time"] is None:
        raise ScenarioError(f"{prefix}.waterlogging_time", None,
                            f"is required for waterlogging = {t['waterlogging']!r} (the time "
                            "constant of the density's approach, s > 0)")
    if t["waterlogging"] != "off":
        for i, g in enumerate(scen.get("logs") or []):
            if g.get("density") is not None and g["density"] > t["saturated_density"]:
                raise ScenarioError(f"{prefix}.saturated_density", t["saturated_density"],
                                    f"is below logs[{i}].density = {g['density']:g} kg/m3: "
                                    "waterlogging raises a log's density towards it; give a "
                                    "saturated density >= the logs' densities")

PHYSICS_SECTION = Section("physics", [
    Key("level", "str", "full", "tracer (U_b = U_w), drag only, the full reference model, or "
        "auto (chosen from the drag relaxation time against the flow time scale)",
        choices=PHYSICS_LEVELS),
    Key("rotation", "str", "on", "rotation of the logs (docs/model.md section 9)",
        choices=("on", "off", "auto")),
    Key("fluid_volume", "str", "body", "volume in the pressure-gradient and added-mass terms: "
        "the paper's V_b, or the submerged volume", choices=("body", "submerged")),
    Key("surface_slope", "bool", False, "add -rho g V grad(eta) in place of the steady part of "
        "DU_w/Dt"),
    Key("drag_law", "str", "ganser", "drag coefficient: Ganser (1993), constant, or linear F = k w",
        choices=("ganser", "constant", "linear")),
    Key("drag_area", "str", "paper", "reference area of C_D: the paper's S_eff, Ganser's "
        "pi d_v^2 / 4, or the wetted projected area", choices=("paper", "ganser", "wetted")),
    Key("drag_coefficient", "float", 1.0, "C_D when drag_law = constant", min=0.0),
    Key("linear_drag", "float", 1.0, "k when drag_law = linear", "kg/s", min=0.0),
    Key("torque_force", "str", "total", "force applied at the centre of pressure "
        "(docs/model.md section 9): the total hydrodynamic force, or the drag alone "
        "(pressure-gradient and added-mass forces then act at the centre of mass; well posed "
        "when the log moves with the flow)", choices=("total", "drag")),
    Key("motion", "str", "floating", "when a log moves: only when it floats (the paper), or "
        "also on the bed when the flow's forces overcome bed friction (Braudrick and Grant "
        "2000; docs/model.md 6.1)", choices=tuple(MOTIONS)),
    Key("bed_friction", "float", 0.5, "bed friction coefficient mu_bed", min=0.0,
        when="motion = friction"),
    Key("bed_slope", "str", "surface", "bed slope a_s under a log: the free-surface slope (equal "
        "to the bed's in uniform flow), or flat", choices=tuple(BED_SLOPES),
        when="motion = friction"),
    Key("waterlogging", "str", "off", "log density rising while wet: off, or an exponential "
        "approach to saturated_density (docs/model.md 6.2)", choices=("off", "exponential")),
    Key("saturated_density", "float", 1100.0, "density a log tends to while wet", "kg/m3",
        min=0.0, exclusive_min=True, when="waterlogging = exponential"),
    Key("waterlogging_time", "float", None, "time constant of the density's approach",
        "s", min=0.0, exclusive_min=True, when="waterlogging = exponential"),
    Key("water_density", "float", 1000.0, "rho", "kg/m3", min=0.0, exclusive_min=True),
    Key("gravity", "float", 9.81, "g", "m/s2", min=0.0, exclusive_min=True),
    Key("viscosity", "float", 1.0e-3, "dynamic viscosity mu", "Pa s", min=0.0,
        exclusive_min=True),
], doc="the log transport model (docs/model.md sections 6-10)", check=_check_physics)
