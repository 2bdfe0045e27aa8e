"""driftlog: large floating debris (logs) on flood flows.

The flow is computed once and stored; debris scenarios are rerun on it.
Data flow (DESIGN.md): hydro source -> FlowField -> Tracker -> Trajectories.
"""

import importlib.abc
import importlib.util
import sys
from pathlib import Path

from driftlog._version import __version__

__all__ = ["__version__"]


class _AdaptersFinder(importlib.abc.MetaPathFinder):
    """Import ``driftlog.adapters`` from the repository's top-level ``adapters/`` folder.

    DESIGN.md places the adapters beside the package; an installed wheel maps the
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
