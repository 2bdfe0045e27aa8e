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

The integrator arithmetic is ``driftlog.integrators``' own (``euler_row``, ``rk4_stage_row``,
``rk4_final_row``): one RK4 for both paths.
"""

import numba as nb

from driftlog._numba import kernel
from driftlog.columns import NLIN, NVAR, X, Y
from driftlog.flow import sample_point, sample_point_columns
from driftlog.integrators import euler_row, put_row, rk4_final_row, rk4_stage_row, row
from driftlog.physics import O_LEVEL, O_MOTION, O_ROT, TRACER, log_rhs, stage_columns

__all__ = ["euler_mesh_step", "rk4_mesh_step", "FUSED_METHODS"]

FUSED_METHODS = ("euler", "rk4")


@nb.njit(cache=True, inline="always")
def _finish(i, s, hint, out, face, F, flag, D0, lin0, P, opt, want_next, a, inv_dt, vals,
            dry_depth, recovered, loc):
    """Store the new state s, sample the flow there, and the next step's first stage."""
    put_row(out, i, s)
    if opt[O_LEVEL] == TRACER:
        # what tracer mode reads of the flow at the logs: the depth (status), the velocity and
        # its rotation (the synced state), and the slope when the bed friction test needs it
        f, fg, fl = sample_point_columns(s[X], s[Y], hint, a, inv_dt, vals, dry_depth,
                                         recovered, loc, True, opt[O_ROT] > 0.0, False,
                                         opt[O_MOTION] != 0.0, False)
    else:
        f, fg, fl = sample_point(s[X], s[Y], hint, a, inv_dt, vals, dry_depth, recovered, loc)
    face[i] = f
    flag[i] = fg
    for k in range(NVAR):
        F[i, k] = fl[k]
    if want_next:
        d, ln = log_rhs(s, fl, P[i], opt, True)
        put_row(D0, i, d)
        for k in range(NLIN):
            lin0[i, k] = ln[k]


@nb.njit(cache=True, inline="always")
def _rk4_stage(s0, k, dt, d, hint, a, inv_dt, vals, dry_depth, recovered, loc, p, opt):
    """The derivative at RK4 stage k: its state from s0 and d, the flow there, the forces."""
    return _stage_rhs(rk4_stage_row(s0, k, dt, d), hint, a, inv_dt, vals, dry_depth, recovered,
                      loc, p, opt)


@nb.njit(cache=True, inline="always")
def _stage_rhs(s, hint, a, inv_dt, vals, dry_depth, recovered, loc, p, opt):
    """The derivative at stage state s: the flow there (the columns the forces read), forces."""
    depth, rot, full, slope = stage_columns(opt)
    _, _, fl = sample_point_columns(s[X], s[Y], hint, a, inv_dt, vals, dry_depth, recovered,
                                    loc, depth, rot, full, slope, False)
    dk, _ = log_rhs(s, fl, p, opt, False)
    return dk


@kernel
def euler_mesh_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, want_next,
                    a_e, inv_e, vals_e, dry_depth, recovered, loc):
    """Explicit Euler step of every log from states S0 with first stage D0 (eq. 16).

    Writes the new states into ``out``; the flow at the new positions (time t0 + dt, node
    values ``vals_e`` with weight ``a_e``) into ``F``, ``flag``, ``face``; with
    ``want_next``, the derivative and drag linearisation there into ``D0``, ``lin0``.
    """
    for i in nb.prange(S0.shape[0]):
        s = euler_row(row(S0, i), dt, row(D0, i))
        _finish(i, s, face[i], out, face, F, flag, D0, lin0, P, opt, want_next, a_e, inv_e,
                vals_e, dry_depth, recovered, loc)


@kernel
def rk4_mesh_step(S0, D0, lin0, out, face, F, flag, P, opt, dt, want_next,
                  a_m, inv_m, vals_m, a_e, inv_e, vals_e, dry_depth, recovered, loc):
    """Classical RK4 step of every log from states S0 with first stage D0.

    Stages at t0 + dt/2 (node values ``vals_m``, weight ``a_m``) and t0 + dt (``vals_e``,
    ``a_e``); every stage's point location starts from the log's face at t0, as in the
    general path.  Outputs as ``euler_mesh_step``.
    """
    for i in nb.prange(S0.shape[0]):
        hint = face[i]
        p = P[i]
        s0 = row(S0, i)
        d0 = row(D0, i)
        # stages 1 and 2 at t0 + dt/2, stage 3 at t0 + dt (RK4_C)
        d1 = _rk4_stage(s0, 1, dt, d0, hint, a_m, inv_m, vals_m, dry_depth, recovered, loc, p,
                        opt)
        d2 = _rk4_stage(s0, 2, dt, d1, hint, a_m, inv_m, vals_m, dry_depth, recovered, loc, p,
                        opt)
        d3 = _rk4_stage(s0, 3, dt, d2, hint, a_e, inv_e, vals_e, dry_depth, recovered, loc, p,
                        opt)
        s = rk4_final_row(s0, dt, d0, d1, d2, d3)
        _finish(i, s, hint, out, face, F, flag, D0, lin0, P, opt, want_next, a_e, inv_e,
                vals_e, dry_depth, recovered, loc)

