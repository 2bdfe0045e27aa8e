"""Approximate Riemann solvers of the 2D shallow-water equations in an edge's normal frame.

Each solver is a short function of the left and right states (depth h, normal velocity un,
tangential velocity ut) and gravity g; it returns the numerical flux (mass, normal momentum,
tangential momentum) across the edge, per unit edge length, and the largest wave speed (for
the CFL time step).  The left state is the face the edge normal points out of.

Wave speeds are Toro's two-rarefaction estimates (Toro 2001, eq. 10.22-10.23), with the dry-bed
forms when one side is dry: exact for rarefactions into dry beds, so a front advances at the
right speed.  HLLC (Toro 2001, sect. 10.5) differs from HLL only in the tangential momentum,
which it upwinds with the contact speed instead of smearing it.
"""

from __future__ import annotations

import math

import numba as nb

__all__ = ["wave_speeds", "hll_flux", "hllc_flux", "riemann_flux", "HLL", "HLLC", "RIEMANN"]

HLL, HLLC = 0, 1
RIEMANN = {"hll": HLL, "hllc": HLLC}

# Plain calls, not numba's inline="always" (the boundary flux of solver.boundaries likewise):
# with numba's own inliner, inlining them into the IR of the four flux kernels took 17 s of
# compile per kernel (a second-order run's solver kernels compiled in 11 s instead of 41,
# measured by hand from a cold cache, before driftlog._numba's fix of the inliner's copying),
# while the calls run at the same speed (1e5 triangles, both orders, 1 thread) and give the
# same results bit for bit; `benchmarks/compile_times.py --tests tests/test_solver_scheme.py`
# shows what they compile in now


@nb.njit(cache=True)
def wave_speeds(hL, unL, hR, unR, g):
    """(s_left, s_right): bounds of the wave speeds of the Riemann problem (dry-bed aware)."""
    cL = math.sqrt(g * hL)
    cR = math.sqrt(g * hR)
    if hL <= 0.0:
        return unR - 2.0 * cR, unR + cR
    if hR <= 0.0:
        return unL - cL, unL + 2.0 * cL
    ustar = 0.5 * (unL + unR) + cL - cR
    cstar = 0.5 * (cL + cR) + 0.25 * (unL - unR)
    return min(unL - cL, ustar - cstar), max(unR + cR, ustar + cstar)


@nb.njit(cache=True)
def _hll_mass_normal(hL, unL, hR, unR, sL, sR, g):
    qL = hL * unL
    qR = hR * unR
    fL = qL * unL + 0.5 * g * hL * hL
    fR = qR * unR + 0.5 * g * hR * hR
    if sL >= 0.0:
        return qL, fL
    if sR <= 0.0:
        return qR, fR
    inv = 1.0 / (sR - sL)
    fh = (sR * qL - sL * qR + sL * sR * (hR - hL)) * inv
    fn = (sR * fL - sL * fR + sL * sR * (qR - qL)) * inv
    return fh, fn


@nb.njit(cache=True)
def hll_flux(hL, unL, utL, hR, unR, utR, g):
    """HLL flux (Harten, Lax & van Leer 1983): (f_mass, f_normal, f_tangential, max speed)."""
    if hL <= 0.0 and hR <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    sL, sR = wave_speeds(hL, unL, hR, unR, g)
    fh, fn = _hll_mass_normal(hL, unL, hR, unR, sL, sR, g)
    if sL >= 0.0:
        ft = hL * unL * utL
    elif sR <= 0.0:
        ft = hR * unR * utR
    else:
        ft = (sR * hL * unL * utL - sL * hR * unR * utR
              + sL * sR * (hR * utR - hL * utL)) / (sR - sL)
    return fh, fn, ft, max(abs(sL), abs(sR))


@nb.njit(cache=True)
def hllc_flux(hL, unL, utL, hR, unR, utR, g):
    """HLLC flux: HLL mass and normal momentum, tangential momentum upwinded at the contact."""
    if hL <= 0.0 and hR <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    sL, sR = wave_speeds(hL, unL, hR, unR, g)
    fh, fn = _hll_mass_normal(hL, unL, hR, unR, sL, sR, g)
    den = hR * (unR - sR) - hL * (unL - sL)
    if den != 0.0:
        sstar = (sL * hR * (unR - sR) - sR * hL * (unL - sL)) / den
    else:
        sstar = 0.5 * (sL + sR)
    ft = fh * (utL if sstar >= 0.0 else utR)
    return fh, fn, ft, max(abs(sL), abs(sR))


@nb.njit(cache=True)
def riemann_flux(kind, hL, unL, utL, hR, unR, utR, g):
    """Dispatch on ``kind`` (HLL or HLLC)."""
    if kind == HLLC:
        return hllc_flux(hL, unL, utL, hR, unR, utR, g)
    return hll_flux(hL, unL, utL, hR, unR, utR, g)
