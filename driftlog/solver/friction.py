"""Explicit Euler stage with semi-implicit Manning friction, and the Heun average.

The friction source ``-g n^2 |q| q / h^(7/3)`` (Manning; Strickler K = 1/n) is stiff where the
water is shallow: explicitly it flips the sign of q once dt g n^2 |q| / h^(7/3) > 1.  Treated
semi-implicitly, q^(n+1) (1 + dt g n^2 |q*| / h^(n+1)^(7/3)) = q*, the factor only ever slows
the flow down, whatever the depth and the step (stable at small depths), and keeps the
direction of q.  Dry faces (h <= dry depth) keep no momentum.
"""

from __future__ import annotations

import numba as nb

from driftlog._numba import kernel

__all__ = ["euler_stage", "heun_average", "manning_factor"]


@nb.njit(cache=True, inline="always")
def manning_factor(dt, gn2, h, qx, qy):
    """1 / (1 + dt g n^2 |q| / h^(7/3)): the semi-implicit friction factor."""
    if gn2 == 0.0:
        return 1.0
    q = (qx * qx + qy * qy) ** 0.5
    return 1.0 / (1.0 + dt * gn2 * q / h ** (7.0 / 3.0))


@kernel
def euler_stage(h0, hu0, hv0, dh, dhu, dhv, dt, gn2, hdry, h, hu, hv):
    """(h, hu, hv) = (h0, hu0, hv0) + dt d/dt(...), then friction; arrays may alias h0..."""
    scalar_n = gn2.shape[0] == 1
    for f in nb.prange(h0.shape[0]):
        hn = h0[f] + dt * dh[f]
        if hn < 0.0:  # round-off only: the CFL bound keeps h >= 0 in exact arithmetic
            hn = 0.0
        if hn <= hdry:
            h[f] = hn
            hu[f] = 0.0
            hv[f] = 0.0
            continue
        qx = hu0[f] + dt * dhu[f]
        qy = hv0[f] + dt * dhv[f]
        k = manning_factor(dt, gn2[0] if scalar_n else gn2[f], hn, qx, qy)
        h[f] = hn
        hu[f] = qx * k
        hv[f] = qy * k


@kernel
def heun_average(h0, hu0, hv0, h, hu, hv):
    """(h, hu, hv) = ((h0, hu0, hv0) + (h, hu, hv)) / 2: Heun's (SSP-RK2) last step."""
    for f in nb.prange(h0.shape[0]):
        h[f] = 0.5 * (h0[f] + h[f])
        hu[f] = 0.5 * (hu0[f] + hu[f])
        hv[f] = 0.5 * (hv0[f] + hv[f])
