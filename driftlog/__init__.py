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

from driftlog._cache import set_numba_cache_dir
from driftlog._version import __version__
from driftlog.errors import DriftlogError, FlowFileError, MeshError, ScenarioError
from driftlog.files import register_loader as _register_loader

set_numba_cache_dir(Path(__file__).resolve().parent)

__all__ = ["__version__", "track", "TrackResult", "load_scenario", "Scenario", "open_flow",
           "write_flow", "open_flow_source", "import_flow", "ShallowWaterSolver", "Mesh",
           "read_mesh", "FlowField", "MeshFlowField", "UniformFlow", "SolidBodyRotation",
           "FreeVortex", "Logs", "PhysicsOptions", "Tracker", "StepOptions", "ContactModel",
           "Obstacles", "open_trajectories", "load_ensemble", "run_ensemble", "DriftlogError",
           "ScenarioError", "FlowFileError", "MeshError"]


# public name -> the module that defines it, imported when the name is first used (by name:
# the package itself imports nothing above the base layer, so no module's import of
# ``driftlog.x`` leads back up to the top; type checkers read ``__init__.pyi``)
_HOMES = {
    "track": "api", "TrackResult": "api",
    "load_scenario": "scenario", "Scenario": "scenario",
    "open_flow": "flowfile", "write_flow": "flowfile",
    "open_flow_source": "adapters", "import_flow": "adapters",
    "ShallowWaterSolver": "solver",
    "Mesh": "mesh", "read_mesh": "mesh",
    "FlowField": "flow", "MeshFlowField": "flow",
    "UniformFlow": "analytic", "SolidBodyRotation": "analytic", "FreeVortex": "analytic",
    "Logs": "logs", "PhysicsOptions": "physics",
    "Tracker": "tracker", "StepOptions": "tracker",
    "ContactModel": "contact", "Obstacles": "contact",
    "open_trajectories": "trajectory",
    "load_ensemble": "ensemble", "run_ensemble": "ensemble",
}


def __getattr__(name):
    """Import the public name ``name`` from its module when it is first used."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'driftlog' has no attribute {name!r}")
    return getattr(importlib.import_module(f"driftlog.{home}"), name)


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


def _load_adapters() -> None:
    """Import ``driftlog.adapters``: its readers tell ``driftlog.files.sniff`` their files."""
    importlib.import_module("driftlog.adapters")


_register_loader(_load_adapters)  # run by the first sniff, not now: import stays cheap
