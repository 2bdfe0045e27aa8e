"""Scenario files (TOML): a self-describing schema, validated up front.

Every key carries its type, default, units, allowed range or choices and a description (as
OpenDrift's configuration does); ``driftlog scenario keys`` prints them all.  Validation names
the key, the value and what is allowed for every bad value, before anything runs.  The
validated scenario (defaults filled in) is written into every output, so a run can be
reproduced from its output alone.

Each part declares its own section beside the object it configures; this module only
assembles them and loads the file (the machinery is ``driftlog.schema``):

===============  ===============================  ======================================
section          declared in                      configures
===============  ===============================  ======================================
``[flow]``       ``driftlog.sources``             the hydro source (readers' options:
                                                  ``driftlog.adapters``)
``[time]``       ``driftlog.tracker``             the time span of the debris run
``[[logs]]``     ``driftlog.logs``                the logs and their seeding
``[physics]``    ``driftlog.physics``             ``PhysicsOptions``
``[integrator]`` ``driftlog.integrators``         the integrator and ``StepOptions``
``[contact]``    ``driftlog.contact.model``       ``ContactModel``
``[[obstacles]]`` ``driftlog.contact.obstacles``  ``Obstacles``
``[output]``     ``driftlog.trajectory``          ``TrajectoryWriter``
``[ensemble]``   ``driftlog.ensemble.vary``       ensembles (``driftlog.ensemble``)
``[solver]``     ``driftlog.solver.config``       driftlog's solver (source = 'solver')
===============  ===============================  ======================================
"""

from __future__ import annotations

import difflib
import json
from dataclasses import dataclass
from pathlib import Path

from driftlog.contact.model import CONTACT_SECTION
from driftlog.contact.obstacles import OBSTACLES_SECTION
from driftlog.coupling import COUPLING_SECTION
from driftlog.ensemble.vary import ENSEMBLE_SECTION
from driftlog.errors import ScenarioError
from driftlog.integrators import INTEGRATOR_SECTION
from driftlog.logs import LOGS_SECTION
from driftlog.physics import PHYSICS_SECTION
from driftlog.schema import (
    Key,
    Section,
    check_tables,
    describe_sections,
    merge,
    read_toml,
    run_checks,
)
from driftlog.solver.config import SOLVER_SECTION
from driftlog.sources import FLOW_SECTION
from driftlog.tracker import TIME_SECTION
from driftlog.trajectory import OUTPUT_SECTION

__all__ = ["Key", "Section", "SECTIONS", "Scenario", "load_scenario", "register_section",
           "describe_keys", "merge", "read_toml"]

# each part declares its section beside the object it configures; the file lists them in
# this order (``driftlog scenario keys``)
SECTIONS: dict[str, Section] = {s.name: s for s in (
    FLOW_SECTION, TIME_SECTION, LOGS_SECTION, PHYSICS_SECTION, INTEGRATOR_SECTION,
    CONTACT_SECTION, OBSTACLES_SECTION, OUTPUT_SECTION, ENSEMBLE_SECTION, SOLVER_SECTION,
    COUPLING_SECTION)}
TOP_KEYS = [
    Key("title", "str", "", "a short name for the scenario"),
    Key("description", "str", "", "what the scenario shows"),
]


def register_section(section: Section) -> Section:
    """Add or replace a section of the schema."""
    SECTIONS[section.name] = section
    return section


# --------------------------------------------------------------------- the scenario
@dataclass
class Scenario:
    """A validated scenario: ``data`` has every section with defaults filled in."""

    data: dict
    path: Path | None = None
    text: str = ""

    @property
    def base_dir(self) -> Path:
        """The folder relative paths of the scenario are taken from."""
        return self.path.parent if self.path else Path.cwd()

    def __getitem__(self, name):
        return self.data[name]

    def get(self, name, default=None):
        """A section (or top key) by name, ``default`` if absent."""
        return self.data.get(name, default)

    def to_json(self) -> str:
        """The validated data as JSON (sorted keys)."""
        return json.dumps(self.data, sort_keys=True, default=str)

    def attrs(self) -> dict:
        """Global attributes that make a run reproducible from its output."""
        return {"scenario": self.text or self.to_json(), "scenario_resolved": self.to_json(),
                "scenario_path": str(self.path) if self.path else ""}


def load_scenario(source, overrides: dict | None = None) -> Scenario:
    """Read and validate a scenario from a TOML file path, TOML text or a dict.

    ``overrides`` is a nested dict merged over the file (used by ensembles and the CLI's --set).
    """
    raw, path, text = read_toml(source)
    try:
        return _validate(raw, path, text, overrides)
    except ScenarioError as exc:
        if exc.source is None and path is not None:  # name the file in the message
            shown = source if isinstance(source, (str, Path)) else path
            raise ScenarioError(exc.key, exc.value, exc.allowed, source=str(shown)) from None
        raise


def _validate(raw, path, text, overrides):
    if overrides:
        raw = merge(raw, overrides)
    base = path.parent if path else Path.cwd()
    sections = list(SECTIONS.values())
    data = check_tables(raw, sections, TOP_KEYS, base)
    scen = Scenario(data, path, text)
    run_checks(sections, data, scen)
    return scen


def describe_keys(section: str | None = None) -> str:
    """A text table of every key: name, type, default, units, rule, description."""
    if section and section not in SECTIONS:
        close = difflib.get_close_matches(section, list(SECTIONS), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ScenarioError("--section", section, f"unknown section{hint}; the sections are: "
                            + ", ".join(SECTIONS))
    return describe_sections(SECTIONS.values(), section)

