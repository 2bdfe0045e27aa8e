"""driftlog: large floating debris (logs) on flood flows.

The flow is computed once and stored; debris scenarios are rerun on it.
Data flow: hydro source -> FlowField -> Tracker -> Trajectories.

The public API, imported when first used (``import driftlog`` stays cheap):

>>> import driftlog
>>> result = driftlog.track("cases/vortex/scenario.toml")
>>> scen = driftlog.load_scenario("cases/vortex/scenario.toml")
>>> flow = driftlog.open_flow_source("auto", "map.nc")   # any reader of driftlog.adapters

======================================  =================================================
``track``, ``TrackResult``              run a debris scenario (``driftlog.api``)
``load_scenario``, ``Scenario``         read and validate a scenario file
``open_flow``, ``write_flow``           driftlog's own flow files
``open_flow_source``, ``import_flow``   other models' outputs (``driftlog.adapters``)
``ShallowWaterSolver``                  driftlog's shallow-water solver
``Mesh``, ``read_mesh``                 unstructured meshes
``FlowField``, ``MeshFlowField``        flow fields; ``UniformFlow``, ``SolidBodyRotation``,
                                        ``FreeVortex`` analytic ones
``Logs``, ``PhysicsOptions``,           the logs, the transport model, the tracker
``Tracker``, ``StepOptions``
``ContactModel``, ``Obstacles``         contacts
``open_trajectories``                   read a trajectory file (xarray)
``load_ensemble``, ``run_ensemble``     ensembles
``DriftlogError``, ``ScenarioError``,   the errors every bad input raises
``FlowFileError``, ``MeshError``
======================================  =================================================

Everything else (the modules' own names) is internal.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from driftlog._cache import set_numba_cache_dir
from driftlog._version import __version__
from driftlog.errors import DriftlogError, FlowFileError, MeshError, ScenarioError

set_numba_cache_dir(Path(__file__).resolve().parent)

if TYPE_CHECKING:  # what __getattr__ gives, for static tools
    from driftlog.adapters import import_flow, open_flow_source
    from driftlog.analytic import FreeVortex, SolidBodyRotation, UniformFlow
    from driftlog.api import TrackResult, track
    from driftlog.contact import ContactModel, Obstacles
    from driftlog.ensemble import load_ensemble, run_ensemble
    from driftlog.flow import FlowField, MeshFlowField
    from driftlog.flowfile import open_flow, write_flow
    from driftlog.logs import Logs
    from driftlog.mesh import Mesh, read_mesh
    from driftlog.physics import PhysicsOptions
    from driftlog.scenario import Scenario, load_scenario
    from driftlog.solver import ShallowWaterSolver
    from driftlog.tracker import StepOptions, Tracker
    from driftlog.trajectory import open_trajectories

__all__ = ["__version__", "track", "TrackResult", "load_scenario", "Scenario", "open_flow",
           "write_flow", "open_flow_source", "import_flow", "ShallowWaterSolver", "Mesh",
           "read_mesh", "FlowField", "MeshFlowField", "UniformFlow", "SolidBodyRotation",
           "FreeVortex", "Logs", "PhysicsOptions", "Tracker", "StepOptions", "ContactModel",
           "Obstacles", "open_trajectories", "load_ensemble", "run_ensemble", "DriftlogError",
           "ScenarioError", "FlowFileError", "MeshError"]


def __getattr__(name):
    """Import the public name ``name`` from its module when it is first used."""
    if name in ("track", "TrackResult"):
        from driftlog import api as mod
    elif name in ("load_scenario", "Scenario"):
        from driftlog import scenario as mod
    elif name in ("open_flow", "write_flow"):
        from driftlog import flowfile as mod
    elif name in ("open_flow_source", "import_flow"):
        from driftlog import adapters as mod
    elif name == "ShallowWaterSolver":
        from driftlog import solver as mod
    elif name in ("Mesh", "read_mesh"):
        from driftlog import mesh as mod
    elif name in ("FlowField", "MeshFlowField"):
        from driftlog import flow as mod
    elif name in ("UniformFlow", "SolidBodyRotation", "FreeVortex"):
        from driftlog import analytic as mod
    elif name == "Logs":
        from driftlog import logs as mod
    elif name == "PhysicsOptions":
        from driftlog import physics as mod
    elif name in ("Tracker", "StepOptions"):
        from driftlog import tracker as mod
    elif name in ("ContactModel", "Obstacles"):
        from driftlog import contact as mod
    elif name == "open_trajectories":
        from driftlog import trajectory as mod
    elif name in ("load_ensemble", "run_ensemble"):
        from driftlog import ensemble as mod
    else:
        raise AttributeError(f"module 'driftlog' has no attribute {name!r}")
    return getattr(mod, name)


def __dir__():
    return sorted(set(globals()) | set(__all__))


class _AdaptersFinder(importlib.abc.MetaPathFinder):
    """Import ``driftlog.adapters`` from the repository's top-level ``adapters/`` folder.

    docs/design.md (section 4.3) places the adapters beside the package; an installed wheel maps the
    folder into ``driftlog/adapters`` (pyproject ``package-dir``), a source checkout
    uses this finder.  There is no top-level ``adapters`` import name either way.
    """

    def __init__(self, folder: Path):
        self.folder = folder

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "driftlog.adapters":
            return None
        return importlib.util.spec_from_file_location(
            fullname, self.folder / "__init__.py", submodule_search_locations=[str(self.folder)]
        )


def _mount_adapters() -> None:
    here = Path(__file__).resolve().parent
    if (here / "adapters" / "__init__.py").is_file():
        return  # installed layout: a real subpackage
    folder = here.parent / "adapters"
    if (folder / "__init__.py").is_file() and not any(
        isinstance(f, _AdaptersFinder) for f in sys.meta_path
    ):
        sys.meta_path.insert(0, _AdaptersFinder(folder))


_mount_adapters()
