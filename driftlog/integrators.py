"""Time integrators for the log state (docs/model.md section 12).

- ``euler``: explicit Euler (the paper's eq. 16), order 1.
- ``rk4``: classical Runge-Kutta (the paper), order 4 on smooth fields.
- ``exponential``: exponential time differencing RK4 (Cox & Matthews 2002, ETDRK4).  The drag
  (and rotational resistance) is linearised per log at the start of the step: along and
  across the relative velocity it relaxes at rates lambda_par, lambda_perp (and lambda_R for
  rotation); that linear part is integrated exactly, the rest by the RK4-like stages.  With no
  drag it is classical RK4; with stiff drag (lambda dt >> 1) it is stable and tends to the
  quasi-steady answer, where explicit RK4 blows up (RK4 is stable only for lambda dt < 2.78).

The flow is sampled at the stage times and positions: ``rhs(S, t, D, lin)`` (given by the
tracker) samples it and evaluates the physics.

One RK4.  The per-log arithmetic of a stage (``euler_row``, ``rk4_stage_row``) and of the final
combination (``rk4_final_row``) lives here once, as inline numba functions on one log's state
(a 6-tuple); the whole-array kernels below and the fused per-log steps (``driftlog.fused``)
both call them, so the two paths compute the same numbers in the same order (bit for bit).
Stage k (1 to 3) starts from S0 + RK4_C[k] dt D_{k-1} at time t0 + RK4_C[k] dt.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import (
    L_PAR,
    L_PERP,
    L_ROT,
    L_WX,
    L_WY,
    NLIN,
    NSTATE,
    OMEGA,
    THETA,
    UB,
    VB,
    X,
    Y,
)
from driftlog.schema import Key, Section

__all__ = ["Integrator", "make_integrator", "phi_functions", "METHODS", "RK4_C", "row",
           "put_row", "euler_row", "rk4_stage_row", "rk4_final_row", "rk4_sum_row",
           "add_row", "FUSED_METHODS"]

METHODS = ("euler", "rk4", "exponential")
# classical RK4 nodes: stage k (0 to 3) at t0 + RK4_C[k] dt
RK4_C = (0.0, 0.5, 0.5, 1.0)


# --------------------------------------------------------------------- one log (6-tuples)
@nb.njit(cache=True, inline="always")
def row(A, i):
    """Row i of a state-like array (n, NSTATE) as a 6-tuple."""
    return (A[i, X], A[i, Y], A[i, THETA], A[i, UB], A[i, VB], A[i, OMEGA])


@nb.njit(cache=True, inline="always")
def put_row(A, i, s):
    """Write the 6-tuple s into row i of A."""
    for k in range(NSTATE):
        A[i, k] = s[k]


@nb.njit(cache=True, inline="always")
def _axpy_row(s, c, d):
    """The 6-tuple s + c d."""
    return (s[X] + c * d[X], s[Y] + c * d[Y], s[THETA] + c * d[THETA], s[UB] + c * d[UB],
            s[VB] + c * d[VB], s[OMEGA] + c * d[OMEGA])


@nb.njit(cache=True, inline="always")
def euler_row(s0, dt, d0):
    """Explicit Euler (eq. 16): s0 + dt d0."""
    return _axpy_row(s0, dt, d0)


@nb.njit(cache=True, inline="always")
def rk4_stage_row(s0, k, dt, d):
    """State of RK4 stage k (1 to 3) from s0 and the previous stage's derivative d."""
    return _axpy_row(s0, RK4_C[k] * dt, d)


@nb.njit(cache=True, inline="always")
def _rk4_mix12(s, c6, d0, d12, d3):
    """One component of the RK4 combination from d12 = d1 + d2: s + dt/6 (d0 + 2 d12 + d3)."""
    return s + c6 * (d0 + 2.0 * d12 + d3)


@nb.njit(cache=True, inline="always")
def _rk4_mix(s, c6, d0, d1, d2, d3):
    """One component of the RK4 combination: s + dt/6 (d0 + 2 (d1 + d2) + d3), c6 = dt/6."""
    return _rk4_mix12(s, c6, d0, d1 + d2, d3)


@nb.njit(cache=True, inline="always")
def add_row(a, b):
    """The 6-tuple a + b."""
    return (a[X] + b[X], a[Y] + b[Y], a[THETA] + b[THETA], a[UB] + b[UB], a[VB] + b[VB],
            a[OMEGA] + b[OMEGA])


@nb.njit(cache=True, inline="always")
def rk4_sum_row(s0, dt, d0, d12, d3):
    """The RK4 step's end state from s0, d0, d12 = d1 + d2 (``add_row``) and d3."""
    c6 = dt / 6.0
    return (_rk4_mix12(s0[X], c6, d0[X], d12[X], d3[X]),
            _rk4_mix12(s0[Y], c6, d0[Y], d12[Y], d3[Y]),
            _rk4_mix12(s0[THETA], c6, d0[THETA], d12[THETA], d3[THETA]),
            _rk4_mix12(s0[UB], c6, d0[UB], d12[UB], d3[UB]),
            _rk4_mix12(s0[VB], c6, d0[VB], d12[VB], d3[VB]),
            _rk4_mix12(s0[OMEGA], c6, d0[OMEGA], d12[OMEGA], d3[OMEGA]))


@nb.njit(cache=True, inline="always")
def rk4_final_row(s0, dt, d0, d1, d2, d3):
    """The RK4 step's end state from s0 and the four stage derivatives."""
    return rk4_sum_row(s0, dt, d0, add_row(d1, d2), d3)


# --------------------------------------------------------------------- whole arrays
@kernel
def _euler(S0, dt, D0, out):
    for i in nb.prange(S0.shape[0]):
        put_row(out, i, euler_row(row(S0, i), dt, row(D0, i)))


@kernel
def _rk4_stage(S0, k, dt, D, out):
    for i in nb.prange(S0.shape[0]):
        put_row(out, i, rk4_stage_row(row(S0, i), k, dt, row(D, i)))


@kernel
def _rk4_final(S0, dt, D0, D1, D2, D3, out):
    for i in nb.prange(S0.shape[0]):
        put_row(out, i, rk4_final_row(row(S0, i), dt, row(D0, i), row(D1, i), row(D2, i),
                                      row(D3, i)))


@nb.njit(cache=True)
def phi_functions(z):
    """phi_1, phi_2, phi_3 at z <= 0 (phi_k(z) = sum_j z^j / (j + k)!), without cancellation."""
    if abs(z) < 0.1:
        p1 = p2 = p3 = 0.0
        term = 1.0  # z^j / j!
        for j in range(9):
            # accumulate z^j/(j+k)! = term * j!/(j+k)!
            f1 = 1.0 / (j + 1)
            f2 = f1 / (j + 2)
            f3 = f2 / (j + 3)
            p1 += term * f1
            p2 += term * f2
            p3 += term * f3
            term *= z / (j + 1)
        return p1, p2, p3
    e = np.expm1(z)
    p1 = e / z
    p2 = (p1 - 1.0) / z
    p3 = (p2 - 0.5) / z
    return p1, p2, p3


@nb.njit(cache=True, inline="always")
def _etd_coeffs(lam, h):
    """For a relaxation rate lam over step h (z = -lam h).

    Returns e^{z}, e^{z/2}, (h/2) phi1(z/2), f1, f2, f3.
    """
    z = -lam * h
    e = np.exp(z)
    e2 = np.exp(0.5 * z)
    q1, _, _ = phi_functions(0.5 * z)
    p1, p2, p3 = phi_functions(z)
    return e, e2, 0.5 * h * q1, p1 - 3.0 * p2 + 4.0 * p3, p2 - 2.0 * p3, 4.0 * p3 - p2


@kernel(size_arg=2)
def _etd_stage(stage, h, S0, Sa, lin, N0, Na, Nb, Nc, out):
    """One ETDRK4 stage; N are the nonlinear parts D + M S_vel (M the linearised drag)."""
    for i in nb.prange(S0.shape[0]):
        lp, lq, lr = lin[i, L_PAR], lin[i, L_PERP], lin[i, L_ROT]
        wx, wy = lin[i, L_WX], lin[i, L_WY]
        # positions and angle: no linear part (classical RK4 coefficients)
        for k in range(X, THETA + 1):
            if stage == 1:
                out[i, k] = S0[i, k] + 0.5 * h * N0[i, k]
            elif stage == 2:
                out[i, k] = S0[i, k] + 0.5 * h * Na[i, k]
            elif stage == 3:
                out[i, k] = Sa[i, k] + 0.5 * h * (2.0 * Nb[i, k] - N0[i, k])
            else:
                out[i, k] = _rk4_mix(S0[i, k], h / 6.0, N0[i, k], Na[i, k], Nb[i, k], Nc[i, k])
        # velocity: operators act as c_perp x + (c_par - c_perp)(w.x) w
        ep, e2p, qp, f1p, f2p, f3p = _etd_coeffs(lp, h)
        eq, e2q, qq, f1q, f2q, f3q = _etd_coeffs(lq, h)
        er, e2r, qr, f1r, f2r, f3r = _etd_coeffs(lr, h)
        if stage == 1 or stage == 2:
            base_u, base_v, base_o = S0[i, UB], S0[i, VB], S0[i, OMEGA]
            src = N0 if stage == 1 else Na
            nu, nv, no = src[i, UB], src[i, VB], src[i, OMEGA]
            # e2 base + q N
            dot_b = wx * base_u + wy * base_v
            dot_n = wx * nu + wy * nv
            out[i, UB] = e2q * base_u + (e2p - e2q) * dot_b * wx + qq * nu + (qp - qq) * dot_n * wx
            out[i, VB] = e2q * base_v + (e2p - e2q) * dot_b * wy + qq * nv + (qp - qq) * dot_n * wy
            out[i, OMEGA] = e2r * base_o + qr * no
        elif stage == 3:
            base_u, base_v, base_o = Sa[i, UB], Sa[i, VB], Sa[i, OMEGA]
            nu = 2.0 * Nb[i, UB] - N0[i, UB]
            nv = 2.0 * Nb[i, VB] - N0[i, VB]
            no = 2.0 * Nb[i, OMEGA] - N0[i, OMEGA]
            dot_b = wx * base_u + wy * base_v
            dot_n = wx * nu + wy * nv
            out[i, UB] = e2q * base_u + (e2p - e2q) * dot_b * wx + qq * nu + (qp - qq) * dot_n * wx
            out[i, VB] = e2q * base_v + (e2p - e2q) * dot_b * wy + qq * nv + (qp - qq) * dot_n * wy
            out[i, OMEGA] = e2r * base_o + qr * no
        else:
            u0, v0 = S0[i, UB], S0[i, VB]
            dot0 = wx * u0 + wy * v0
            ru = eq * u0 + (ep - eq) * dot0 * wx
            rv = eq * v0 + (ep - eq) * dot0 * wy
            ro = er * S0[i, OMEGA]
            # h (f1 N0 + 2 f2 (Na + Nb) + f3 Nc), per direction
            for which in range(3):
                if which == 0:
                    nu, nv, no = N0[i, UB], N0[i, VB], N0[i, OMEGA]
                    cp, cq, cr = f1p, f1q, f1r
                elif which == 1:
                    nu = Na[i, UB] + Nb[i, UB]
                    nv = Na[i, VB] + Nb[i, VB]
                    no = Na[i, OMEGA] + Nb[i, OMEGA]
                    cp, cq, cr = 2.0 * f2p, 2.0 * f2q, 2.0 * f2r
                else:
                    nu, nv, no = Nc[i, UB], Nc[i, VB], Nc[i, OMEGA]
                    cp, cq, cr = f3p, f3q, f3r
                dn = wx * nu + wy * nv
                ru += h * (cq * nu + (cp - cq) * dn * wx)
                rv += h * (cq * nv + (cp - cq) * dn * wy)
                ro += h * cr * no
            out[i, UB] = ru
            out[i, VB] = rv
            out[i, OMEGA] = ro


@kernel
def _add_linear(S, D, lin, N):
    """N = D + M S_vel: the nonlinear part, M the drag linearisation frozen at the step start."""
    for i in nb.prange(S.shape[0]):
        for k in range(X, THETA + 1):
            N[i, k] = D[i, k]
        lp, lq, wx, wy = lin[i, L_PAR], lin[i, L_PERP], lin[i, L_WX], lin[i, L_WY]
        u, v = S[i, UB], S[i, VB]
        d = wx * u + wy * v
        N[i, UB] = D[i, UB] + lq * u + (lp - lq) * d * wx
        N[i, VB] = D[i, VB] + lq * v + (lp - lq) * d * wy
        N[i, OMEGA] = D[i, OMEGA] + lin[i, L_ROT] * S[i, OMEGA]


class Integrator:
    """Advance states S over one step, sampling the flow at stage times via ``rhs``.

    ``rhs(S, t, D, lin)`` fills D (n, 6), and lin (n, NLIN) unless it is None (only the first
    stage needs the drag linearisation), for states S at time t.  The first
    stage's derivative may be given (``D0``, ``lin0``) when already known.
    """

    stiff_stable = False

    def __init__(self, name):
        self.name = name
        self._n = -1

    def _buffers(self, n, k):
        if self._n != n:
            self._n = n
            self.D = [np.empty((n, NSTATE)) for _ in range(k)]
            self.lin = [np.empty((n, NLIN)) for _ in range(k)]
            self.stage = [np.empty((n, NSTATE)) for _ in range(3)]
        return self.D, self.lin, self.stage

    def step(self, S0, t0, dt, rhs, out, have_d0=False):
        """Write the state at t0 + dt into ``out``; ``have_d0``: self.D[0], self.lin[0] hold it."""
        raise NotImplementedError

    def prepare(self, n):
        """Buffers for n logs; D[0] and lin[0] are where the first stage's derivative goes."""
        self._buffers(n, 4)
        return self.D[0], self.lin[0]

    def adopt(self, D0, lin0):
        """Take D0 and lin0 (n rows) as the first stage's buffers, the others cut to n rows.

        The tracker compacted its first stage in place (``Tracker._drop_stopped``); the other
        buffers are scratch, views of their first n rows where they are long enough.
        """
        n = D0.shape[0]
        if self._n < n:
            self._buffers(n, 4)
        self._n = n
        self.D = [D0] + [d[:n] for d in self.D[1:]]
        self.lin = [lin0] + [a[:n] for a in self.lin[1:]]
        self.stage = [a[:n] for a in self.stage]
        return D0, lin0


class Euler(Integrator):
    def step(self, S0, t0, dt, rhs, out, have_d0=False):
        D, lin, _ = self._buffers(S0.shape[0], 4)
        if not have_d0:
            rhs(S0, t0, D[0], lin[0])
        _euler(S0, dt, D[0], out)


class RK4(Integrator):
    def step(self, S0, t0, dt, rhs, out, have_d0=False):
        D, lin, st = self._buffers(S0.shape[0], 4)
        if not have_d0:
            rhs(S0, t0, D[0], lin[0])
        for k in (1, 2, 3):
            _rk4_stage(S0, k, dt, D[k - 1], st[k - 1])
            rhs(st[k - 1], t0 + RK4_C[k] * dt, D[k], None)
        _rk4_final(S0, dt, D[0], D[1], D[2], D[3], out)


class ExponentialRK4(Integrator):
    stiff_stable = True

    def __init__(self, name):
        super().__init__(name)
        self._nn = -1

    def step(self, S0, t0, dt, rhs, out, have_d0=False):
        n = S0.shape[0]
        D, lin, st = self._buffers(n, 4)
        if self._nn != n:
            self._nn = n
            self.N = [np.empty((n, NSTATE)) for _ in range(4)]
        N = self.N
        if not have_d0:
            rhs(S0, t0, D[0], lin[0])
        L = lin[0]  # linearisation frozen at the start of the step
        _add_linear(S0, D[0], L, N[0])
        _etd_stage(1, dt, S0, S0, L, N[0], N[0], N[0], N[0], st[0])
        rhs(st[0], t0 + 0.5 * dt, D[1], None)
        _add_linear(st[0], D[1], L, N[1])
        _etd_stage(2, dt, S0, S0, L, N[0], N[1], N[1], N[1], st[1])
        rhs(st[1], t0 + 0.5 * dt, D[2], None)
        _add_linear(st[1], D[2], L, N[2])
        _etd_stage(3, dt, S0, st[0], L, N[0], N[1], N[2], N[2], st[2])
        rhs(st[2], t0 + dt, D[3], None)
        _add_linear(st[2], D[3], L, N[3])
        _etd_stage(4, dt, S0, S0, L, N[0], N[1], N[2], N[3], out)


def make_integrator(method: str) -> Integrator:
    """The integrator named ``method`` (euler, rk4, exponential)."""
    if method == "euler":
        return Euler(method)
    if method == "rk4":
        return RK4(method)
    if method == "exponential":
        return ExponentialRK4(method)
    from driftlog.errors import ScenarioError

    raise ScenarioError("integrator.method", method, "must be one of " + ", ".join(METHODS))


# --------------------------------------------------------------------- the scenario section
# the methods of the fused mesh kernels (``driftlog.fused``; per-log clocks run only in them)
FUSED_METHODS = ("euler", "rk4")


def _check_integrator(t, prefix, scen):
    from driftlog.errors import ScenarioError

    if t["max_step"] is not None and t["max_step"] < t["min_step"]:
        raise ScenarioError(f"{prefix}.max_step", t["max_step"], f"must be >= min_step "
                            f"({t['min_step']:g} s): every sub-step would be below min_step")
    if t["clock"] == "per_log" and t["method"] not in FUSED_METHODS:
        raise ScenarioError(f"{prefix}.clock", "per_log", "per-log clocks run in the fused "
                            f"mesh kernels: they need method {' or '.join(FUSED_METHODS)} "
                            f"(here {t['method']!r}); use clock = 'global' or another method")
    if not t["land_on_snapshots"] and t["clock"] != "global":
        raise ScenarioError(f"{prefix}.land_on_snapshots", False, "needs clock = 'global' "
                            "(per-log clocks meet at every snapshot); set land_on_snapshots = "
                            "true or clock = 'global'")


INTEGRATOR_SECTION = Section("integrator", [
    Key("method", "str", "rk4", "time integrator: explicit Euler, RK4 (the paper), or "
        "exponential (RK4 with drag integrated exactly over the step: stable on stiff drag)",
        choices=("euler", "rk4", "exponential")),
    Key("length_fraction", "float", 1.0, "dt <= length_fraction * L / |U_b| (paper: 1)",
        min=0.0, exclusive_min=True),
    Key("angle_step", "float", math.pi / 4, "dt <= angle_step / |omega_b| (paper: pi/4)", "rad",
        min=0.0, exclusive_min=True),
    Key("drag_fraction", "float", 0.5, "dt <= drag_fraction * tau_D for explicit methods (0: no "
        "bound, as the paper)", min=0.0),
    Key("max_step", "float", None, "upper bound of the sub-step", "s", min=0.0,
        exclusive_min=True),
    Key("min_step", "float", 1e-9, "sub-steps below this are an error (the run stops with a "
        "message)", "s", min=0.0, exclusive_min=True),
    Key("clock", "str", "global", "global: every floating log advances with the smallest "
        "sub-step any needs (the paper's Algorithm 1); per_log: each log with its own sub-steps, "
        "logs meeting at outputs, snapshots, releases and contacts (mesh flows, euler or rk4)",
        choices=("global", "per_log")),
    Key("land_on_snapshots", "bool", True, "true: every sub-step ends at each snapshot of the "
        "flow (the paper: logs advance inside a hydrodynamic step); false: sub-steps run "
        "across snapshots, each stage reading the flow at its own time (linear between "
        "snapshots, as OceanTracker and Parcels step); global clock, not coupled"),
], doc="time integration (docs/model.md sections 11-12)", check=_check_integrator)
