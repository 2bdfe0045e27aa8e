"""Fused tracking steps on mesh flows: one per-log kernel for a whole integrator step.

The general path (``Integrator.step`` with the tracker's ``_rhs``) passes whole arrays
between stages: sample the flow at every log (n, NVAR), evaluate the forces (n, 6), form the
next stage state (n, 6), and so on, four times per RK4 step.  At 1e5 logs and more these
arrays leave the caches and every pass streams them through memory.  Here each log runs all
its stages in registers: for each stage the flow is sampled at the stage position
(``flow.sample_point``: point location walk from the log's face, P1 in space, linear in
time) and the forces evaluated (``physics.log_rhs``), the same inline functions the general
path calls, with the same arithmetic in the same order, so both paths give the same
trajectories bit for bit.  The step also samples the flow at the new position (the tracker's
``F``, ``flag`` and face hints) and evaluates the next step's first stage and drag
linearisation (``D0``, ``lin0``), which the tracker's step bound then reuses.

Within a sub-step the node values do not change except when the step ends on a snapshot
time: there the end-of-step stage uses the next snapshot pair (as the general path does, the
flow's ``node_values`` chooses), so the stage times get their own (node values, weight).
"""

import numba as nb

from driftlog._numba import kernel
from driftlog.flow import NVAR, sample_point
from driftlog.physics import NLIN, log_rhs

__all__ = ["euler_mesh_step", "rk4_mesh_step", "FUSED_METHODS"]

FUSED_METHODS = ("euler", "rk4")


@nb.njit(cache=True, inline="always")
def _axpy6(s, c, d):
    """The 6-tuple s + c d (``integrators._axpy`` for one log)."""
    return (s[0] + c * d[0], s[1] + c * d[1], s[2] + c * d[2], s[3] + c * d[3],
            s[4] + c * d[4], s[5] + c * d[5])


@nb.njit(cache=True, inline="always")
def _row6(A, i):
    return (A[i, 0], A[i, 1], A[i, 2], A[i, 3], A[i, 4], A[i, 5])


@nb.njit(cache=True, inline="always")
def _finish(i, s, hint, out, face, F, flag, D0, lin0, P, opt, want_next, a, inv_dt, vals,
            dry_depth, recovered, face_nodes, face_n, face_nbr, node_x, node_y,
            x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces):
    """Store the new state s, sample the flow there, and the next step's first stage."""
    for k in range(6):
        out[i, k] = s[k]
    f, fg, fl = sample_point(s[0], s[1], hint, a, inv_dt, vals, dry_depth, recovered,
                             face_nodes, face_n, face_nbr, node_x, node_y,
                             x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces)
    face[i] = f
    flag[i] = fg
    for k in range(NVAR):
        F[i, k] = fl[k]
    if want_next:
        d, ln = log_rhs(s, fl, P[i], opt, True)
        for k in range(6):
            D0[i, k] = d[k]
        for k in range(NLIN):
            lin0[i, k] = ln[k]


@kernel
def euler_mesh_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, want_next,
                    a_e, inv_e, vals_e, dry_depth, recovered,
                    face_nodes, face_n, face_nbr, node_x, node_y,
                    x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces):
    """Explicit Euler step of every log from states S0 with first stage D0 (eq. 16).

    Writes the new states into ``out``; the flow at the new positions (time t0 + dt, node
    values ``vals_e`` with weight ``a_e``) into ``F``, ``flag``, ``face``; with
    ``want_next``, the derivative and drag linearisation there into ``D0``, ``lin0``.
    """
    for i in nb.prange(S0.shape[0]):
        s = _axpy6(_row6(S0, i), dt, _row6(D0, i))
        _finish(i, s, face[i], out, face, F, flag, D0, lin0, P, opt, want_next, a_e, inv_e,
                vals_e, dry_depth, recovered, face_nodes, face_n, face_nbr, node_x, node_y,
                x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces)


@kernel
def rk4_mesh_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, want_next,
                  a_m, inv_m, vals_m, a_e, inv_e, vals_e, dry_depth, recovered,
                  face_nodes, face_n, face_nbr, node_x, node_y,
                  x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces):
    """Classical RK4 step of every log from states S0 with first stage D0.

    Stages at t0 + dt/2 (node values ``vals_m``, weight ``a_m``) and t0 + dt (``vals_e``,
    ``a_e``); every stage's point location starts from the log's face at t0, as in the
    general path.  Outputs as ``euler_mesh_step``.
    """
    c = 0.5 * dt
    c6 = dt / 6.0
    for i in nb.prange(S0.shape[0]):
        hint = face[i]
        p = P[i]
        s0 = _row6(S0, i)
        d0 = _row6(D0, i)
        s1 = _axpy6(s0, c, d0)
        _, _, fl = sample_point(s1[0], s1[1], hint, a_m, inv_m, vals_m, dry_depth, recovered,
                                face_nodes, face_n, face_nbr, node_x, node_y,
                                x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces)
        d1, _ = log_rhs(s1, fl, p, opt, False)
        s2 = _axpy6(s0, c, d1)
        _, _, fl = sample_point(s2[0], s2[1], hint, a_m, inv_m, vals_m, dry_depth, recovered,
                                face_nodes, face_n, face_nbr, node_x, node_y,
                                x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces)
        d2, _ = log_rhs(s2, fl, p, opt, False)
        s3 = _axpy6(s0, dt, d2)
        _, _, fl = sample_point(s3[0], s3[1], hint, a_e, inv_e, vals_e, dry_depth, recovered,
                                face_nodes, face_n, face_nbr, node_x, node_y,
                                x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces)
        d3, _ = log_rhs(s3, fl, p, opt, False)
        # integrators._rk4_final, same order of operations
        s = (s0[0] + c6 * (d0[0] + 2.0 * (d1[0] + d2[0]) + d3[0]),
             s0[1] + c6 * (d0[1] + 2.0 * (d1[1] + d2[1]) + d3[1]),
             s0[2] + c6 * (d0[2] + 2.0 * (d1[2] + d2[2]) + d3[2]),
             s0[3] + c6 * (d0[3] + 2.0 * (d1[3] + d2[3]) + d3[3]),
             s0[4] + c6 * (d0[4] + 2.0 * (d1[4] + d2[4]) + d3[4]),
             s0[5] + c6 * (d0[5] + 2.0 * (d1[5] + d2[5]) + d3[5]))
        _finish(i, s, hint, out, face, F, flag, D0, lin0, P, opt, want_next, a_e, inv_e,
                vals_e, dry_depth, recovered, face_nodes, face_n, face_nbr, node_x, node_y,
                x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces)
