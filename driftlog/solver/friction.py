"""Explicit Euler stage with semi-implicit Manning friction, and the Heun average.

The friction source ``-g n^2 |q| q / h^(7/3)`` (Manning; Strickler K = 1/n) is stiff where the
water is shallow: explicitly it flips the sign of q once dt g n^2 |q| / h^(7/3) > 1.  Treated
semi-implicitly, q^(n+1) (1 + dt g n^2 |q^n| / h^(n+1)^(7/3)) = q*, with q* the explicit
update, the factor only ever slows the flow down, whatever the depth and the step (stable at
small depths), and keeps the direction of q.  |q| is taken at the start of the stage, not
from q*: then a steady state (q^(n+1) = q^n) balances the fluxes against g n^2 |q| q / h^(7/3)
exactly, whatever dt (with |q*| the steady state carries an O(dt) friction error, which made
MacDonald's channel first order at second order).  Dry faces (h <= dry depth) keep no
momentum.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel

__all__ = ["euler_stage", "manning_factor", "predictor_stage", "corrector_stage"]


@nb.njit(cache=True, inline="always")
def manning_factor(dt, gn2, h, qx, qy):
    """1 / (1 + dt g n^2 |q| / h^(7/3)): the semi-implicit friction factor."""
    if gn2 == 0.0:
        return 1.0
    q = (qx * qx + qy * qy) ** 0.5
    if q == 0.0:  # still water: exactly 1, without the power (most of the stage's time)
        return 1.0
    return 1.0 / (1.0 + dt * gn2 * q / h ** (7.0 / 3.0))


@nb.njit(cache=True, inline="always")
def _euler_state(f, h0, hu0, hv0, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin, thin4):
    """``euler_stage``'s new (h, hu, hv) of face f (no momentum at or below ``hdry``)."""
    hn = h0[f] + dt * dh[f]
    if hn < 0.0:  # round-off only: the CFL bound keeps h >= 0 in exact arithmetic
        hn = 0.0
    if hn <= hdry:
        return hn, 0.0, 0.0
    qx0 = hu0[f]
    qy0 = hv0[f]
    qx = qx0 + dt * dhu[f]
    qy = qy0 + dt * dhv[f]
    k = manning_factor(dt, gn2[0] if scalar_n else gn2[f], hn, qx0, qy0)
    if hn < thin:
        h2 = hn * hn
        k *= 1.4142135623730951 * h2 / (h2 * h2 + thin4) ** 0.5
    return hn, qx * k, qy * k


@nb.njit(cache=True, inline="always")
def _euler_face(f, h0, hu0, hv0, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin, thin4, h, hu, hv):
    """``euler_stage`` on face f."""
    hn, qx, qy = _euler_state(f, h0, hu0, hv0, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin,
                              thin4)
    h[f] = hn
    hu[f] = qx
    hv[f] = qy


@kernel(nrt=False)
def euler_stage(h0, hu0, hv0, dh, dhu, dhv, dt, gn2, hdry, thin, h, hu, hv, runs):
    """(h, hu, hv) = (h0, hu0, hv0) + dt d/dt(...), then friction; arrays may alias h0...

    ``thin`` > 0: below that depth the velocity is the desingularised quotient of Kurganov &
    Petrova (2007), u = sqrt(2) h (hu) / sqrt(h^4 + max(h^4, thin^4)), and the discharge is
    reset to h u (a factor sqrt(2) h^2 / sqrt(h^4 + thin^4) <= 1, which is 1 at h = thin).
    Only the faces of ``runs`` (run k: faces ``runs[k, 0]`` to ``runs[k, 1] - 1``;
    ``layout.face_runs``) are updated: the others must be faces that the stage would leave as
    they are (outside the active set's blocks).
    """
    scalar_n = gn2.shape[0] == 1
    thin4 = thin * thin * thin * thin
    for r in nb.prange(runs.shape[0]):
        for f in range(runs[r, 0], runs[r, 1]):
            # unsigned: no negative-index wraparound (``driftlog.solver.fluxes``)
            _euler_face(np.uint64(f), h0, hu0, hv0, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin,
                        thin4, h, hu, hv)


@nb.njit(cache=True, inline="always")
def _thin_factor(hf, e):
    """The desingularisation factor below the depth e (docs/model.md eq. (68)-(69)).

    u = sqrt(2) h (hu) / sqrt(h^4 + max(h^4, e^4)) (Kurganov & Petrova 2007, eq. 2.17),
    discharges reset to h u: a factor sqrt(2) h^2 / sqrt(h^4 + e^4) < 1 for 0 < h < e.
    """
    h2 = hf * hf
    e2 = e * e
    return 1.4142135623730951 * h2 / (h2 * h2 + e2 * e2) ** 0.5


@nb.njit(cache=True, inline="always")
def _predictor_face(f, h0, hu0, hv0, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin, thin4, eps,
                    h, hu, hv):
    """``predictor_stage`` on face f: ``_euler_face``, then the thin layer.

    (The same products in the same order as in one expression: the same numbers.)
    """
    _euler_face(f, h0, hu0, hv0, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin, thin4, h, hu, hv)
    hn = h[f]
    e = eps[f]
    if hn > hdry and hn < e:
        kt = _thin_factor(hn, e)
        hu[f] *= kt
        hv[f] *= kt


@kernel(nrt=False)
def predictor_stage(h0, hu0, hv0, dh, dhu, dhv, dt, gn2, hdry, thin, eps, h, hu, hv, runs):
    """Heun's first stage: ``euler_stage``, then the thin layer below ``eps`` (per face).

    Discharges are desingularised where 0 < h < eps (``_thin_factor``, eq. (69)), in the same
    pass.  (h, hu, hv) must not alias (h0, hu0, hv0).  Only the faces of ``runs`` are
    written (``euler_stage``): elsewhere (h, hu, hv) must already hold what the stage would
    write there, zeros (``corrector_stage`` keeps them so).
    """
    scalar_n = gn2.shape[0] == 1
    thin4 = thin * thin * thin * thin
    for r in nb.prange(runs.shape[0]):
        for f in range(runs[r, 0], runs[r, 1]):
            _predictor_face(np.uint64(f), h0, hu0, hv0, dh, dhu, dhv, dt, gn2, scalar_n, hdry,
                            thin, thin4, eps, h, hu, hv)


@nb.njit(cache=True, inline="always")
def _corrector_face(f, h1, hu1, hv1, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin, thin4, eps,
                    h, hu, hv):
    """``corrector_stage`` on face f."""
    # U'' = E(U'), as euler_stage
    hn, qx, qy = _euler_state(f, h1, hu1, hv1, dh, dhu, dhv, dt, gn2, scalar_n, hdry, thin,
                              thin4)
    # (U'' + U^n) / 2, Heun's average
    ha = 0.5 * (hn + h[f])
    qx = 0.5 * (qx + hu[f])
    qy = 0.5 * (qy + hv[f])
    if ha < thin:
        h2 = ha * ha
        k = 1.4142135623730951 * h2 / (h2 * h2 + thin4) ** 0.5
        qx *= k
        qy *= k
    # the thin layer (69)
    e = eps[f]
    if ha < e and ha > 0.0:
        kt = _thin_factor(ha, e)
        qx *= kt
        qy *= kt
    h[f] = ha
    hu[f] = qx
    hv[f] = qy
    if ha == 0.0:
        # an empty face: the predicted state the next predictor would write if it ran here
        # (a face outside the next active set is not written by it)
        h1[f] = 0.0
        hu1[f] = 0.0
        hv1[f] = 0.0


@kernel(nrt=False)
def corrector_stage(h1, hu1, hv1, dh, dhu, dhv, dt, gn2, hdry, thin, eps, h, hu, hv, runs):
    """Heun's second stage and average in one pass: (h, hu, hv) = (E(h1, ...) + (h, hu, hv)) / 2.

    E is ``euler_stage`` from the predicted state (h1, hu1, hv1) with its residuals (dh, dhu,
    dhv); below the depth ``thin`` the averaged discharges are desingularised as in
    ``euler_stage``, then below ``eps`` (per face, ``_thin_factor``, eq. (69)).  U'' is never
    stored: the state (h, hu, hv) holds U^n on entry and U^(n+1) on return.  Only the faces
    of ``runs`` are written (those of both stages' active sets); where the average is empty
    the predicted state (h1, hu1, hv1) is zeroed, what the next predictor writes there.
    """
    scalar_n = gn2.shape[0] == 1
    thin4 = thin * thin * thin * thin
    for r in nb.prange(runs.shape[0]):
        for f in range(runs[r, 0], runs[r, 1]):
            _corrector_face(np.uint64(f), h1, hu1, hv1, dh, dhu, dhv, dt, gn2, scalar_n, hdry,
                            thin, thin4, eps, h, hu, hv)
