"""The Malpasset dam break set up on its mesh, and its observations.

The sea is found from the bed (``driftlog.solver.sea``); ``malpasset_solver`` builds the
Malpasset dam break from the data's README (shared/data/malpasset): reservoir at 100 m in its
polygon, sea at ``sea_level``, Manning n = 0.033, reflective walls except the sea.

    from driftlog.floodsetup import malpasset_solver, read_observations
    solver = malpasset_solver("cases/malpasset/data/malpasset_mesh.nc")
    solver.run(4000.0, output="/tmp/malpasset.nc", output_interval=30.0)
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from driftlog.errors import ScenarioError
from driftlog.mesh import Mesh, read_mesh
from driftlog.solver import ShallowWaterSolver
from driftlog.solver.sea import (  # the sea helpers, re-exported for the Malpasset scripts
    SEA_KEYS,
    apply_sea,
    check_sea,
    fill_sea,
    low_boundary_edges,
    sea_faces,
    tag_sea,
)

__all__ = ["low_boundary_edges", "tag_sea", "sea_faces", "check_sea",
           "apply_sea", "fill_sea", "SEA_KEYS",
           "malpasset_depth", "malpasset_solver", "read_observations",
           "MALPASSET_RESERVOIR", "MALPASSET_DAM", "MALPASSET_LEVEL", "MALPASSET_MANNING"]

# the data README's set-up (after George 2011 and TELEMAC's example), mesh coordinates (m)
MALPASSET_DAM = ((4701.18, 4143.41), (4655.5, 4392.10))
MALPASSET_RESERVOIR = ((4701.18, 4143.41), (4655.5, 4392.10), (3000.0, 7000.0), (0.0, 7000.0),
                       (0.0, 1000.0), (5000.0, 1000.0))
MALPASSET_LEVEL = 100.0     # m: reservoir surface at the failure
MALPASSET_MANNING = 0.033   # s m^-1/3 (Strickler 30)


def malpasset_depth(mesh, bed, sea_edges, sea_level=0.0):
    """Initial depth: reservoir at 100 m in its polygon, sea at ``sea_level``, dry elsewhere."""
    h = np.zeros(mesh.n_faces)
    res = mesh.faces_in_polygon(MALPASSET_RESERVOIR)
    h[res] = np.maximum(MALPASSET_LEVEL - bed[res], 0.0)
    sea = sea_faces(mesh, bed, sea_level, sea_edges) & ~res
    h[sea] = sea_level - bed[sea]
    return h


def malpasset_solver(mesh, order=1, sea_level=0.0, sea="level", **options):
    """The Malpasset dam break, ready to run.

    Parameters
    ----------
    mesh : driftlog.mesh.Mesh or path
        The 46,691-triangle mesh (node bed), or its file; a Mesh gets the ``sea`` tag.
    order : {1, 2}
    sea_level : float
        Sea surface (m): 0 (TELEMAC's example) or -0.5 (GeoClaw).
    sea : {"level", "free"}
        The sea boundary: imposed level ``sea_level`` or zero-gradient outflow.
    **options
        Passed to ``ShallowWaterSolver`` (riemann, cfl, dry_depth, arrival_depth...).
    """
    spec = {"level": float(sea_level), "boundary": sea}
    check_sea(spec, "sea")
    if not isinstance(mesh, Mesh):
        mesh = read_mesh(mesh)
    boundaries = {}
    coast = apply_sea(mesh, spec, boundaries)
    options.setdefault("manning", MALPASSET_MANNING)
    solver = ShallowWaterSolver(mesh, order=order, boundaries=boundaries, **options)
    solver.set_state(malpasset_depth(mesh, solver.bed, coast, sea_level))
    return solver


def read_observations(path):
    """The observations CSV as a list of dicts.

    Keys id, kind, x, y, max_level_m, arrival_s (NaN where not observed).
    """
    path = Path(path)
    rows = []
    with open(path) as f:
        lines = [ln for ln in f if not ln.startswith("#")]
    for r in csv.DictReader(lines):
        rows.append({"id": r["id"], "kind": r["kind"], "x": float(r["x"]), "y": float(r["y"]),
                     "max_level_m": float(r["max_level_m"]) if r["max_level_m"] else np.nan,
                     "arrival_s": float(r["arrival_s"]) if r["arrival_s"] else np.nan})
    if not rows:
        raise ScenarioError("observations", str(path), "a CSV with id, kind, x, y, "
                            "max_level_m, arrival_s rows")
    return rows
