"""Ensemble specifications: the parameters to vary, how they are sampled, and member scenarios.

An ensemble is a scenario file with an ``[ensemble]`` section (declared in
``driftlog.ensemble.vary``).  The file is a whole debris scenario, or names a ``base`` scenario
whose sections it overrides.  ``[ensemble.vary]`` maps a scenario key to what it takes::

    [ensemble]
    base = "scenario.toml"
    members = 500
    sampling = "latin_hypercube"        # monte_carlo, latin_hypercube or grid
    seed = 7

    [ensemble.vary]
    "logs.release_time" = { uniform = [0.0, 600.0] }
    "logs.count" = { integers = [5, 40] }
    "logs.length" = { lognormal = [6.0, 0.4], max = 20.0 }
    "logs[1].density" = { values = [500.0, 720.0, 900.0], weights = [1, 2, 1] }
    "contact.restitution" = { normal = [0.5, 0.15], min = 0.0, max = 1.0 }
    "physics.level" = { values = ["drag", "full"] }
    "logs.place" = { values = [{ seeding = "line", start = [2, 1], end = [2, 9] },
                               { seeding = "polygon", polygon = [[0, 0], [4, 0], [4, 4]] }] }

A key names a section and a key of the scenario schema; ``logs.key`` sets it in every
``[[logs]]`` group, ``logs[i].key`` in group i only.  ``logs.place`` is a table of placement
keys (seeding, x, y, start, end, polygon, count, theta) that replaces the group's placement.
The flow and the outputs cannot vary: an ensemble runs on one flow.

Reproducibility: member i's unit sample u_i (one number per parameter) comes from
``numpy.random.default_rng([seed, i])`` (Monte Carlo: from the seed and the index alone), or is
row i of the Latin hypercube ``scipy.stats.qmc.LatinHypercube(d, rng=seed).random(members)``
(stratified over all members, so it depends on the member count too), or the i-th combination of
the lists (grid).  Values are the distributions' quantiles at u_i.  With ``reseed_logs`` (the
default), the random seeding of group k of member i uses the seed
``SeedSequence([seed, i, k])``, so members also differ in where random logs start.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from driftlog.ensemble.vary import (
    DISTRIBUTIONS,
    PLACE_KEYS,
    SAMPLINGS,
    Parameter,
    check_ensemble_section,
    parse_vary,
)
from driftlog.errors import ScenarioError
from driftlog.scenario import SECTIONS, Scenario, load_scenario
from driftlog.schema import merge, read_toml

__all__ = ["Parameter", "Ensemble", "load_ensemble", "parse_vary", "check_ensemble_section",
           "DISTRIBUTIONS", "SAMPLINGS"]

# --------------------------------------------------------------------- the ensemble
RUNTIME_KEYS = ("workers", "scheduler", "output", "keep_trajectories", "checkpoint_interval",
                "blocked_after")


@dataclass
class Ensemble:
    """A validated ensemble: the base scenario, the varied parameters, the sampling."""

    scenario: Scenario  # the whole file (base merged), [ensemble] included
    parameters: list[Parameter]
    _design: np.ndarray | None = field(default=None, repr=False)

    @property
    def section(self) -> dict:
        """The validated [ensemble] section."""
        return self.scenario["ensemble"]

    @property
    def members(self) -> int:
        """Number of members (grid: the number of combinations)."""
        s = self.section
        if s["sampling"] == "grid":
            return math.prod(len(p.choices) for p in self.parameters) if self.parameters else 1
        return int(s["members"])

    @property
    def seed(self) -> int:
        """Seed of the sampling."""
        return int(self.section["seed"])

    @property
    def output(self) -> Path:
        """Output folder."""
        return Path(self.section["output"])

    def base(self) -> dict:
        """The debris scenario (JSON-able dict) that every member starts from."""
        data = json.loads(self.scenario.to_json())
        data.pop("ensemble", None)
        return data

    def fingerprint(self) -> str:
        """A hash of what determines the members (not where or how they run).

        Monte Carlo members depend on the seed and their index alone, so the member count is
        left out: an ensemble can be extended by raising ``members`` and resuming.
        """
        data = json.loads(self.scenario.to_json())
        ens = {k: v for k, v in data.pop("ensemble").items() if k not in RUNTIME_KEYS}
        if ens["sampling"] == "monte_carlo":
            ens.pop("members")
        data.pop("output", None)
        data.pop("title", None)
        data.pop("description", None)
        text = json.dumps({"ensemble": ens, "base": data}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    # ----------------------------------------------------------------- sampling
    def unit_sample(self, i: int) -> np.ndarray:
        """Member i's unit sample, one number in [0, 1) per parameter."""
        d = len(self.parameters)
        s = self.section["sampling"]
        if s == "monte_carlo":
            return np.random.default_rng([self.seed, int(i)]).random(d)
        if s == "latin_hypercube":
            if self._design is None:
                from scipy.stats import qmc

                try:
                    lhs = qmc.LatinHypercube(d=max(d, 1), rng=self.seed)
                except TypeError:  # scipy < 1.15 names it seed
                    lhs = qmc.LatinHypercube(d=max(d, 1), seed=self.seed)
                self._design = lhs.random(self.members)[:, :d]
            return self._design[i]
        shape = [len(p.choices) for p in self.parameters]
        idx = np.unravel_index(int(i), shape) if shape else ()
        return np.array([(k + 0.5) / n for k, n in zip(idx, shape, strict=True)])

    def parameters_of(self, i: int) -> dict:
        """The varied values of member i, by path."""
        return self.sample([i])[0]

    def sample(self, members) -> list[dict]:
        """The varied values of several members (one dict by path per member)."""
        members = np.asarray(list(members), np.int64)
        if members.size and (members.min() < 0 or members.max() >= self.members):
            bad = int(members[(members < 0) | (members >= self.members)][0])
            raise IndexError(f"member {bad} out of range: the ensemble has {self.members} "
                             "members")
        u = np.array([self.unit_sample(i) for i in members]).reshape(members.size, -1)
        cols = {p.path: p.values(u[:, j]) for j, p in enumerate(self.parameters)}
        return [{k: v[r] for k, v in cols.items()} for r in range(members.size)]

    def parameter_table(self) -> dict:
        """{path: array (members,)}: the value of numeric parameters, else the list index."""
        u = np.array([self.unit_sample(i) for i in range(self.members)]).reshape(
            self.members, -1)
        out = {}
        for j, p in enumerate(self.parameters):
            if p.numeric and p.key != "place":
                out[p.path] = np.asarray(p.values(u[:, j]), float)
            else:
                out[p.path] = p.indices(u[:, j])
        return out

    def member_overrides(self, i: int, base: dict | None = None, values=None) -> dict:
        """Member i as a nested dict of the sections it changes (for ``merge`` on the base)."""
        base = base or self.base()
        values = self.parameters_of(i) if values is None else values
        out: dict = {}
        logs = [dict(g) for g in base["logs"]]
        varied_seed = any(p.section == "logs" and p.key == "seed" for p in self.parameters)
        if self.section["reseed_logs"] and not varied_seed:
            for k, g in enumerate(logs):
                g["seed"] = int(np.random.SeedSequence([self.seed, int(i), k])
                                .generate_state(1)[0])
        # place first, then the other keys: "logs.count" wins over a place's count
        order = sorted(self.parameters, key=lambda p: p.key != "place")
        for p in order:
            v = values[p.path]
            if p.section in ("logs", "obstacles"):
                items = logs if p.section == "logs" else out.setdefault(
                    "obstacles", [dict(o) for o in base["obstacles"]])
                targets = range(len(items)) if p.index is None else [p.index]
                for k in targets:
                    if p.key == "place":
                        for n in PLACE_KEYS:
                            items[k][n] = SECTIONS["logs"].by_name[n].default
                        items[k].update(v)
                    else:
                        items[k][p.key] = v
            else:
                out.setdefault(p.section, {})[p.key] = v
        out["logs"] = logs
        # members write no side files
        out["output"] = {"vtk": False, "figure": False, "animation": False}
        return out

    def member_scenario(self, i: int, base: dict | None = None) -> Scenario:
        """The debris scenario of member i, validated."""
        base = base or self.base()
        try:
            return load_scenario(merge(base, self.member_overrides(i, base)))
        except ScenarioError as exc:
            raise ScenarioError(exc.key, exc.value, exc.allowed,
                                source=f"ensemble member {i} ({_describe(self.parameters_of(i))})"
                                ) from None


def _describe(values: dict) -> str:
    return ", ".join(f"{k} = {_short(v)}" for k, v in values.items()) or "no varied parameters"


def _short(v):
    if isinstance(v, float):
        return f"{v:.6g}"
    return json.dumps(v) if isinstance(v, (dict, list)) else repr(v)


def describe_parameters(values: dict) -> str:
    """``logs.length = 5.2, physics.level = 'drag'``: a member's parameters in one line."""
    return _describe(values)


def _absolute_paths(raw: dict, base_dir: Path) -> dict:
    """Make the ensemble file's relative path keys absolute before merging over a base."""
    out = {}
    for name, value in raw.items():
        sec = SECTIONS.get(name)
        if sec is None:
            out[name] = value
            continue
        items = value if isinstance(value, list) else [value]
        fixed = []
        for t in items:
            if isinstance(t, dict):
                t = dict(t)
                for kname, kv in t.items():
                    k = sec.by_name.get(kname)
                    if k is not None and k.type == "path" and isinstance(kv, str) and kv:
                        p = Path(kv).expanduser()
                        t[kname] = str(p if p.is_absolute() else base_dir / p)
            fixed.append(t)
        out[name] = fixed if isinstance(value, list) else fixed[0]
    return out


def load_ensemble(source, overrides: dict | None = None) -> Ensemble:
    """Read and validate an ensemble file (path, TOML text, dict, Scenario or Ensemble).

    The file's ``[ensemble] base`` scenario, if given, is read first and the file's own
    sections are merged over it (tables key by key; ``[[logs]]`` and other lists replace).
    """
    if isinstance(source, Ensemble):
        if not overrides:
            return source
        source = source.scenario
    if isinstance(source, Scenario):
        raw, file_path = json.loads(source.to_json()), source.path
    else:
        raw, file_path, _ = read_toml(source, "ensemble")
    base_dir = file_path.parent if file_path else Path.cwd()
    if overrides:
        raw = merge(raw, overrides)
    where = str(file_path) if file_path else None
    ens = raw.get("ensemble")
    if not isinstance(ens, dict):
        raise ScenarioError("ensemble", "missing" if ens is None else ens,
                            "an ensemble file needs an [ensemble] section (the parameters to "
                            "vary; see `driftlog scenario keys --section ensemble`)", where)
    raw = _absolute_paths(raw, base_dir)
    ens = raw["ensemble"]
    if ens.get("base"):
        if not Path(ens["base"]).is_file():
            raise ScenarioError("ensemble.base", ens["base"], "file not found", where)
        data = json.loads(load_scenario(ens["base"]).to_json())
        data.pop("ensemble", None)
        raw = merge(data, raw)
    if not ens.get("output"):  # the default folder sits beside the ensemble file
        raw["ensemble"] = dict(ens, output=str(base_dir / "ensemble"))
    try:
        scen = load_scenario(raw)
        scen.path = file_path
        check_ensemble_section(scen["ensemble"], "ensemble", scen)  # also when nothing varies
    except ScenarioError as exc:
        if exc.source is not None or where is None:
            raise
        # name the ensemble file (and its base) that the merged value came from
        base = f" (over its base {ens['base']})" if ens.get("base") else ""
        raise ScenarioError(exc.key, exc.value, exc.allowed, where + base) from None
    ensemble = Ensemble(scen, parse_vary(scen["ensemble"]["vary"]))
    ensemble.member_scenario(0)  # cross-key errors of the members show now, not on a worker
    return ensemble
