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

from driftlog._numba import kernel

__all__ = ["euler_stage", "heun_average", "manning_factor", "thin_layer"]


@nb.njit(cache=True, inline="always")
def manning_factor(dt, gn2, h, qx, qy):
    """1 / (1 + dt g n^2 |q| / h^(7/3)): the semi-implicit friction factor."""
    if gn2 == 0.0:
        return 1.0
    q = (qx * qx + qy * qy) ** 0.5
    if q == 0.0:  # still water: exactly 1, without the power (most of the stage's time)
        return 1.0
    return 1.0 / (1.0 + dt * gn2 * q / h ** (7.0 / 3.0))


@kernel
def euler_stage(h0, hu0, hv0, dh, dhu, dhv, dt, gn2, hdry, thin, h, hu, hv):
    """(h, hu, hv) = (h0, hu0, hv0) + dt d/dt(...), then friction; arrays may alias h0...

    ``thin`` > 0: below that depth the velocity is the desingularised quotient of Kurganov &
    Petrova (2007), u = sqrt(2) h (hu) / sqrt(h^4 + max(h^4, thin^4)), and the discharge is
    reset to h u (a factor sqrt(2) h^2 / sqrt(h^4 + thin^4) <= 1, which is 1 at h = thin).
    """
    scalar_n = gn2.shape[0] == 1
    thin4 = thin * thin * thin * thin
    for f in nb.prange(h0.shape[0]):
        hn = h0[f] + dt * dh[f]
        if hn < 0.0:  # round-off only: the CFL bound keeps h >= 0 in exact arithmetic
            hn = 0.0
        if hn <= hdry:
            h[f] = hn
            hu[f] = 0.0
            hv[f] = 0.0
            continue
        qx0 = hu0[f]
        qy0 = hv0[f]
        qx = qx0 + dt * dhu[f]
        qy = qy0 + dt * dhv[f]
        k = manning_factor(dt, gn2[0] if scalar_n else gn2[f], hn, qx0, qy0)
        if hn < thin:
            h2 = hn * hn
            k *= 1.4142135623730951 * h2 / (h2 * h2 + thin4) ** 0.5
        h[f] = hn
        hu[f] = qx * k
        hv[f] = qy * k


@kernel
def heun_average(h0, hu0, hv0, thin, h, hu, hv):
    """(h, hu, hv) = ((h0, hu0, hv0) + (h, hu, hv)) / 2: Heun's (SSP-RK2) last step.

    Below the depth ``thin`` the averaged discharges are desingularised as in ``euler_stage``.
    """
    thin4 = thin * thin * thin * thin
    for f in nb.prange(h0.shape[0]):
        hn = 0.5 * (h0[f] + h[f])
        h[f] = hn
        hu[f] = 0.5 * (hu0[f] + hu[f])
        hv[f] = 0.5 * (hv0[f] + hv[f])
        if hn < thin:
            h2 = hn * hn
            k = 1.4142135623730951 * h2 / (h2 * h2 + thin4) ** 0.5
            hu[f] *= k
            hv[f] *= k


@kernel
def thin_layer(h, hu, hv, eps):
    """Desingularised velocity in water thinner than ``eps`` (per face).

    u = sqrt(2) h (hu) / sqrt(h^4 + max(h^4, eps^4)) (Kurganov & Petrova 2007, eq. 2.17),
    discharges reset to h u: a factor sqrt(2) h^2 / sqrt(h^4 + eps^4) < 1 below eps.
    """
    for f in nb.prange(h.shape[0]):
        hf = h[f]
        e = eps[f]
        if hf >= e or hf <= 0.0:
            continue
        h2 = hf * hf
        e2 = e * e
        k = 1.4142135623730951 * h2 / (h2 * h2 + e2 * e2) ** 0.5
        hu[f] *= k
        hv[f] *= k
