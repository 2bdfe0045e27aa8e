"""Event-driven impulses (docs/model.md section 13.2; the paper's eq. 11-15).

For a contact between body 1 and body 2 at point C with normal n (from 2 to 1), r_i = C - G_i:

    v_rel = (U_1 + omega_1 x r_1) - (U_2 + omega_2 x r_2);   nothing happens if v_rel . n >= 0
    j = -(1 + eps) v_rel . n / (1/m_1 + 1/m_2 + (r_1 x n)^2 / I_1 + (r_2 x n)^2 / I_2)
    U_1 += j n / m_1, U_2 -= j n / m_2, omega_1 += (r_1 x n) j / I_1, omega_2 -= (r_2 x n) j / I_2

A wall, pier or bank has 1/m_2 = 1/I_2 = 0 (body index -1).  Masses are the logs' own m_b and
I_b (docs/model.md eq. (31)), as in the paper: added mass is a property of the fluid's reaction to
acceleration over a time scale, not of an instantaneous collision, and leaving it out keeps the
impulse exactly conservative between logs.

Option (not in the paper): approach speeds below ``rest_speed`` do not bounce.  A log held
against a pier by the flow otherwise bounces at ever smaller speeds, an infinity of impacts in
finite time (Zeno); without bounce the contact rests.  0 (the default) is the paper.

Several simultaneous contacts are resolved one at a time, sweeping over them in a fixed order
until none approaches (sequential impulses): each single impulse conserves momentum (and, with
eps = 1, kinetic energy) exactly, so the sweep does too.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog.columns import CX, CY, GAP, NX, NY, OMEGA, UB, VB, X, Y
from driftlog.contact.islands import island_labels, island_runs

__all__ = ["resolve_impulses", "resolve_islands", "pair_impulse", "separate_resting",
           "kinetic_energy", "momenta"]


@nb.njit(cache=True, inline="always")
def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


@nb.njit(cache=True)
def pair_impulse(S, inv_m, inv_i, b1, b2, nx, ny, cx, cy, eps, vtol, rest_speed=0.0):
    """Apply the impulse of one contact to S (in place); returns j (0 if not approaching).

    ``b2 < 0``: the other body is fixed (a wall or an obstacle).  Approach speeds below
    ``rest_speed`` are resting contact: no bounce (eps = 0).
    """
    r1x, r1y = cx - S[b1, X], cy - S[b1, Y]
    v1x = S[b1, UB] - S[b1, OMEGA] * r1y  # U + omega x r, with omega x r = omega (-r_y, r_x)
    v1y = S[b1, VB] + S[b1, OMEGA] * r1x
    rn1 = _cross(r1x, r1y, nx, ny)
    k = inv_m[b1] + rn1 * rn1 * inv_i[b1]
    vx, vy = v1x, v1y
    rn2 = 0.0
    if b2 >= 0:
        r2x, r2y = cx - S[b2, X], cy - S[b2, Y]
        vx -= S[b2, UB] - S[b2, OMEGA] * r2y
        vy -= S[b2, VB] + S[b2, OMEGA] * r2x
        rn2 = _cross(r2x, r2y, nx, ny)
        k += inv_m[b2] + rn2 * rn2 * inv_i[b2]
    vn = vx * nx + vy * ny
    if vn >= -vtol or k <= 0.0:
        return 0.0
    e = eps if vn < -rest_speed else 0.0
    j = -(1.0 + e) * vn / k  # docs/model.md (50)
    S[b1, UB] += j * nx * inv_m[b1]
    S[b1, VB] += j * ny * inv_m[b1]
    S[b1, OMEGA] += rn1 * j * inv_i[b1]
    if b2 >= 0:
        S[b2, UB] -= j * nx * inv_m[b2]
        S[b2, VB] -= j * ny * inv_m[b2]
        S[b2, OMEGA] -= rn2 * j * inv_i[b2]
    return j


@nb.njit(cache=True)
def resolve_impulses(S, inv_m, inv_i, body1, body2, normal_point, eps, vtol, max_events,
                     impulse, rest_speed=0.0):
    """Sweep the contacts, applying impulses until none approaches.

    Parameters
    ----------
    S : (n, 6) state, velocities changed in place.
    inv_m, inv_i : (n,) inverse masses and inertias (0 for immovable).
    body1, body2 : (k,) bodies of each contact (body2 < 0: a fixed obstacle).
    normal_point : (k, >= 5) columns gap, nx, ny, cx, cy (``geometry`` results).
    eps : restitution.
    vtol : approach speeds below this are contact at rest (no impulse).
    max_events : stop after this many impulses.
    impulse : (k,) accumulated impulse of each contact (output, added to).
    rest_speed : approach speeds below this do not bounce (0: the paper, eps everywhere).

    Returns
    -------
    int
        Number of impulses applied, or -1 when ``max_events`` was reached with contacts still
        approaching (the event-driven method stalls: a jam).
    """
    events = 0
    while True:
        applied = 0
        for c in range(body1.size):
            j = pair_impulse(S, inv_m, inv_i, body1[c], body2[c], normal_point[c, NX],
                             normal_point[c, NY], normal_point[c, CX], normal_point[c, CY], eps,
                             vtol, rest_speed)
            if j != 0.0:
                impulse[c] += j
                applied += 1
                events += 1
                if events >= max_events:
                    return -1
        if applied == 0:
            return events


@nb.njit(cache=True)
def separate_resting(S, inv_m, body1, body2, normal_point, rest_speed):
    """Move apart, along their normal, resting contacts that overlap (positions only).

    A contact at rest (relative normal speed below ``rest_speed``) that a steady force keeps
    pushing (a log held on a wall by the flow) would otherwise creep to the overlap
    tolerance and stall the step there; translating the bodies out of the overlap (a few
    tolerances at most, centre of mass kept) leaves velocities untouched.  Returns how many
    contacts were moved.
    """
    moved = 0
    for c in range(body1.size):
        gap = normal_point[c, GAP]
        if gap >= 0.0:
            continue
        i, j = body1[c], body2[c]
        nx, ny, cx, cy = normal_point[c, NX], normal_point[c, NY], normal_point[c, CX], \
            normal_point[c, CY]
        vx = S[i, UB] - S[i, OMEGA] * (cy - S[i, Y])
        vy = S[i, VB] + S[i, OMEGA] * (cx - S[i, X])
        w = inv_m[i]
        if j >= 0:
            vx -= S[j, UB] - S[j, OMEGA] * (cy - S[j, Y])
            vy -= S[j, VB] + S[j, OMEGA] * (cx - S[j, X])
            w += inv_m[j]
        if abs(vx * nx + vy * ny) > rest_speed or w <= 0.0:
            continue
        d = -gap / w
        S[i, X] += d * inv_m[i] * nx
        S[i, Y] += d * inv_m[i] * ny
        if j >= 0:
            S[j, X] -= d * inv_m[j] * nx
            S[j, Y] -= d * inv_m[j] * ny
        moved += 1
    return moved


@nb.njit(cache=True)
def resolve_islands(S, inv_m, inv_i, body1, body2, normal_point, eps, vtol, max_events,
                    impulse, rest_speed=0.0):
    """``resolve_impulses`` island by island (``islands.island_labels`` of the contacts).

    Each island is swept until none of its contacts approaches, its contacts in their given
    order: the same impulses, bit for bit, as the sweep over all contacts (an island whose
    sweep applies nothing is left unchanged by the further sweeps the others need), at the
    cost of the sweeps each island needs instead of the most any island needs.  Same
    arguments and return value (``max_events`` counts the impulses of all islands).
    """
    labels, count = island_labels(S.shape[0], body1, body2)
    order, start = island_runs(labels, count, body1)
    events = 0
    for q in range(count):
        if start[q + 1] == start[q]:
            continue
        while True:
            applied = 0
            for a in range(start[q], start[q + 1]):
                c = order[a]
                j = pair_impulse(S, inv_m, inv_i, body1[c], body2[c], normal_point[c, NX],
                                 normal_point[c, NY], normal_point[c, CX], normal_point[c, CY],
                                 eps, vtol, rest_speed)
                if j != 0.0:
                    impulse[c] += j
                    applied += 1
                    events += 1
                    if events >= max_events:
                        return -1
            if applied == 0:
                break
    return events


def kinetic_energy(S, mass, inertia):
    """Kinetic energy of translation and rotation, sum over logs."""
    return float(0.5 * np.sum(mass * (S[:, UB] ** 2 + S[:, VB] ** 2)
                              + inertia * S[:, OMEGA] ** 2))


def momenta(S, mass, inertia):
    """Linear momentum (px, py) and angular momentum about the origin (orbital + spin)."""
    px, py = np.sum(mass * S[:, UB]), np.sum(mass * S[:, VB])
    lz = np.sum(mass * (S[:, X] * S[:, VB] - S[:, Y] * S[:, UB]) + inertia * S[:, OMEGA])
    return float(px), float(py), float(lz)
