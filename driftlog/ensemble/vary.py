"""The ``[ensemble]`` section: the parameters to vary and how they are sampled.

See ``driftlog.ensemble.spec`` for the ensemble file (an example, the reproducibility rules)
and the members built from it.  A key of ``[ensemble.vary]`` names a section and a key of the
scenario schema; the sections that can vary are declared beside their objects (``[[logs]]`` in
``driftlog.logs``, ``[physics]`` in ``driftlog.physics``...).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from driftlog.contact.model import CONTACT_SECTION
from driftlog.contact.obstacles import OBSTACLES_SECTION
from driftlog.errors import ScenarioError
from driftlog.integrators import INTEGRATOR_SECTION
from driftlog.logs import LOGS_SECTION
from driftlog.physics import PHYSICS_SECTION
from driftlog.schema import Key, Section, check_value
from driftlog.tracker import TIME_SECTION

__all__ = ["Parameter", "parse_vary", "check_ensemble_section", "ENSEMBLE_SECTION",
           "DISTRIBUTIONS", "SAMPLINGS", "VARIABLE_SECTIONS", "PLACE_KEYS"]

SAMPLINGS = ("monte_carlo", "latin_hypercube", "grid")
# what each distribution takes
DISTRIBUTIONS = {
    "values": "an explicit list (drawn with equal probability, or by weights)",
    "range": "[start, stop, step]: the list start, start + step, ... up to stop (inclusive)",
    "uniform": "[low, high]",
    "loguniform": "[low, high], both > 0",
    "normal": "[mean, standard deviation], truncated by min and max if given",
    "lognormal": "[median, sigma of the logarithm], truncated by min and max if given",
    "integers": "[low, high]: integers from low to high inclusive, equally likely",
}
LISTS = ("values", "range")
MODIFIERS = {"weights": ("values",), "min": ("normal", "lognormal"),
             "max": ("normal", "lognormal")}
SECTIONS = {s.name: s for s in (LOGS_SECTION, PHYSICS_SECTION, INTEGRATOR_SECTION,
                                 CONTACT_SECTION, TIME_SECTION, OBSTACLES_SECTION)}
VARIABLE_SECTIONS = tuple(SECTIONS)  # logs, physics, integrator, contact, time, obstacles
PLACE_KEYS = ("seeding", "x", "y", "start", "end", "polygon", "count", "theta")
_PATH = re.compile(r"^([a-z_]+)(?:\[(\d+)\])?\.([a-z_]+)$")


@dataclass
class Parameter:
    """One varied scenario key and its distribution."""

    path: str  # as written: "logs.length", "logs[1].density", "physics.level"
    section: str
    index: int | None  # group of a repeated section, None for all groups
    key: str
    kind: str  # one of DISTRIBUTIONS
    args: list
    weights: list | None = None
    low: float | None = None  # truncation of normal / lognormal
    high: float | None = None
    integer: bool = False

    @property
    def name(self) -> str:
        """A variable-name form of the path: logs_1_density."""
        return re.sub(r"[^a-z0-9]+", "_", self.path.lower()).strip("_")

    @property
    def choices(self) -> list | None:
        """The explicit list (values, range), or None for a distribution."""
        if self.kind == "values":
            return self.args
        if self.kind == "range":
            start, stop, step = self.args
            n = int(math.floor((stop - start) / step + 1e-9)) + 1
            vals = [start + k * step for k in range(n)]
            return [int(round(v)) for v in vals] if self.integer else vals
        return None

    @property
    def numeric(self) -> bool:
        """True when every value is a number."""
        c = self.choices
        return c is None or all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                for v in c)

    def value(self, u: float):
        """The value at unit sample u in [0, 1): a quantile of the distribution."""
        return self.values(np.array([u]))[0]

    def values(self, u) -> list:
        """Values at unit samples u (array in [0, 1)), as Python numbers or list entries."""
        u = np.clip(np.asarray(u, float), 0.0, 1.0 - 1e-16)
        c = self.choices
        if c is not None:
            return [c[j] for j in self.indices(u)]
        a = self.args
        if self.kind == "uniform":
            v = a[0] + u * (a[1] - a[0])
        elif self.kind == "loguniform":
            v = a[0] * (a[1] / a[0]) ** u
        elif self.kind == "integers":
            v = np.minimum(a[0] + np.floor(u * (a[1] - a[0] + 1)), a[1]).astype(np.int64)
        else:
            from scipy import stats

            dist = (stats.norm(loc=a[0], scale=a[1]) if self.kind == "normal"
                    else stats.lognorm(s=a[1], scale=a[0]))
            # truncated: the quantile of u within [F(low), F(high)]
            f_lo = dist.cdf(self.low) if self.low is not None else 0.0
            f_hi = dist.cdf(self.high) if self.high is not None else 1.0
            p = f_lo + np.maximum(u, 1e-12) * (f_hi - f_lo)
            v = dist.ppf(np.clip(p, 1e-300, 1.0 - 1e-16))
            v = np.clip(v, self.low if self.low is not None else -np.inf,
                        self.high if self.high is not None else np.inf)
        return [x.item() for x in np.asarray(v)]

    def indices(self, u) -> np.ndarray:
        """For list parameters: the index of the entry taken at unit samples u."""
        n = len(self.choices)
        u = np.clip(np.asarray(u, float), 0.0, 1.0 - 1e-16)
        if self.weights is None:
            return np.minimum((u * n).astype(np.int64), n - 1)
        cw = np.cumsum(self.weights) / np.sum(self.weights)
        return np.minimum(np.searchsorted(cw, u, side="right"), n - 1)


# --------------------------------------------------------------------- parsing [ensemble.vary]
def _target(path, prefix, base_logs=None):
    """Section, group index and key of a varied path; the schema Key (None for logs.place)."""
    m = _PATH.match(path) if isinstance(path, str) else None
    if m is None:
        raise ScenarioError(prefix, path, "must be 'section.key' or 'section[i].key', e.g. "
                            "'logs.length', 'logs[1].density', 'physics.level'")
    section, index, key = m.group(1), m.group(2), m.group(3)
    if section in ("flow", "solver"):
        raise ScenarioError(prefix, path, "an ensemble runs on one flow: [flow] and [solver] "
                            "cannot vary (run one ensemble per flow)")
    if section not in VARIABLE_SECTIONS:
        raise ScenarioError(prefix, path, "only keys of " + ", ".join(
            f"[{s}]" for s in VARIABLE_SECTIONS) + " can vary")
    sec = SECTIONS[section]
    if index is not None and not sec.repeated:
        raise ScenarioError(prefix, path, f"[{section}] is a single table: no [i] index")
    if section == "logs" and key == "place":
        return section, None if index is None else int(index), key, None
    k = sec.by_name.get(key)
    if k is None:
        import difflib

        close = difflib.get_close_matches(key, sorted(sec.by_name), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ScenarioError(prefix, path, f"[{section}] has no key {key!r}{hint}; its keys are: "
                            + ", ".join(sorted(sec.by_name)))
    return section, None if index is None else int(index), key, k


def _numbers(prefix, value, n=None):
    ok = isinstance(value, list) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        for v in value)
    if not ok or (n is not None and len(value) != n):
        raise ScenarioError(prefix, value, f"must be a list of {n or 'some'} finite numbers")
    return [float(v) if isinstance(v, float) else v for v in value]


def _check_in_key(k, prefix, value, what):
    """A bound or value of a distribution must be allowed for the key it sets."""
    try:
        check_value(k, prefix, value, Path.cwd())
    except ScenarioError as exc:
        raise ScenarioError(prefix, value, f"{what} must be a valid {k.name}: {exc.allowed}"
                            ) from None


def parse_vary(table: dict, prefix: str = "ensemble.vary") -> list[Parameter]:
    """Validate ``[ensemble.vary]``: one Parameter per key, errors naming key, value and rule."""
    if not isinstance(table, dict):
        raise ScenarioError(prefix, table, "must be a table of 'section.key' = {distribution}")
    params = []
    for path, spec in table.items():
        pre = f'{prefix}."{path}"'
        section, index, key, k = _target(path, pre)
        if not isinstance(spec, dict):
            raise ScenarioError(pre, spec, "must be a table with one of " + ", ".join(
                DISTRIBUTIONS) + ", e.g. { uniform = [1.0, 2.0] }")
        kinds = [n for n in spec if n in DISTRIBUTIONS]
        for n in spec:
            if n not in DISTRIBUTIONS and n not in MODIFIERS:
                raise ScenarioError(f"{pre}.{n}", spec[n], "unknown entry; a distribution ("
                                    + ", ".join(DISTRIBUTIONS) + ") and its modifiers ("
                                    + ", ".join(MODIFIERS) + ")")
        if len(kinds) != 1:
            raise ScenarioError(pre, spec, "must give exactly one distribution: "
                                + "; ".join(f"{n} = {d}" for n, d in DISTRIBUTIONS.items()))
        kind = kinds[0]
        for n in spec:
            if n in MODIFIERS and kind not in MODIFIERS[n]:
                raise ScenarioError(f"{pre}.{n}", spec[n], f"applies to {', '.join(MODIFIERS[n])}"
                                    f", not to {kind}")
        args = spec[kind]
        ktype = "table" if k is None else k.type
        integer = ktype == "int"
        numeric_key = ktype in ("float", "int", "float_or_str")
        p = Parameter(path, section, index, key, kind, args, integer=integer)
        pk = f"{pre}.{kind}"
        if kind in ("uniform", "loguniform", "normal", "lognormal", "integers", "range") \
                and not numeric_key:
            raise ScenarioError(pk, args, f"{path} is not a number ({ktype}): give its "
                                "possible values as values = [...]")
        if integer and kind in ("uniform", "loguniform", "normal", "lognormal"):
            raise ScenarioError(pk, args, f"{path} is an integer: use integers = [low, high], "
                                "values or range")
        if kind == "values":
            if not isinstance(args, list) or not args:
                raise ScenarioError(pk, args, "must be a non-empty list")
            for j, v in enumerate(args):
                if k is None:
                    _check_place(f"{pk}[{j}]", v)
                else:
                    _check_in_key(k, f"{pk}[{j}]", v, "each value")
            if "weights" in spec:
                w = _numbers(f"{pre}.weights", spec["weights"], len(args))
                if min(w) < 0 or sum(w) <= 0:
                    raise ScenarioError(f"{pre}.weights", w, "must be >= 0 with a positive sum")
                p.weights = w
        elif kind == "range":
            a = _numbers(pk, args, 3)
            if not a[2] > 0 or a[1] < a[0]:
                raise ScenarioError(pk, args, "must be [start, stop, step] with step > 0 and "
                                    "stop >= start")
            if integer and not all(float(v).is_integer() for v in a):
                raise ScenarioError(pk, args, f"{path} is an integer: start, stop and step "
                                    "must be integers")
            p.args = a
            for v in (p.choices[0], p.choices[-1]):
                _check_in_key(k, pk, v, "every value of the range")
        else:
            a = _numbers(pk, args, 2)
            p.args = a
            if kind in ("uniform", "loguniform", "integers"):
                if a[1] < a[0]:
                    raise ScenarioError(pk, args, "must be [low, high] with high >= low")
                if kind == "loguniform" and not a[0] > 0:
                    raise ScenarioError(pk, args, "loguniform needs low > 0")
                if kind == "integers":
                    if not all(float(v).is_integer() for v in a):
                        raise ScenarioError(pk, args, "must be two integers")
                    p.args = [int(v) for v in a]
                for v in p.args:
                    _check_in_key(k, pk, v, "low and high")
            else:
                if not a[1] > 0:
                    spread = "standard deviation" if kind == "normal" else "sigma"
                    raise ScenarioError(pk, args, f"the {spread} must be > 0")
                if kind == "lognormal" and not a[0] > 0:
                    raise ScenarioError(pk, args, "the median of a lognormal must be > 0")
                for side in ("min", "max"):
                    if side in spec:
                        v = _numbers(f"{pre}.{side}", [spec[side]], 1)[0]
                        _check_in_key(k, f"{pre}.{side}", v, side)
                        setattr(p, "low" if side == "min" else "high", float(v))
                if p.low is not None and p.high is not None and not p.high > p.low:
                    raise ScenarioError(f"{pre}.max", p.high, f"must be > min = {p.low}")
                # an unbounded tail must not leave the key's allowed range
                lo = p.low if p.low is not None else (0.0 if kind == "lognormal" else -math.inf)
                if k.min is not None and lo < k.min:
                    raise ScenarioError(pre, spec, f"a {kind} distribution reaches {lo} but "
                                        f"{path} must be {'>' if k.exclusive_min else '>='} "
                                        f"{k.min}: give min = ... to truncate it")
                hi = p.high if p.high is not None else math.inf
                if k.max is not None and hi > k.max:
                    raise ScenarioError(pre, spec, f"a {kind} distribution reaches {hi} but "
                                        f"{path} must be <= {k.max}: give max = ... to truncate it")
        params.append(p)
    return params


def _check_place(prefix, value):
    """A ``logs.place`` value: a table of placement keys of [[logs]]."""
    if not isinstance(value, dict) or not value:
        raise ScenarioError(prefix, value, "must be a table of placement keys ("
                            + ", ".join(PLACE_KEYS) + "), e.g. { seeding = 'line', "
                            "start = [0, 0], end = [0, 10] }")
    sec = SECTIONS["logs"]
    for n, v in value.items():
        if n not in PLACE_KEYS:
            raise ScenarioError(f"{prefix}.{n}", v, "not a placement key; allowed: "
                                + ", ".join(PLACE_KEYS))
        check_value(sec.by_name[n], f"{prefix}.{n}", v, Path.cwd())


def check_ensemble_section(t: dict, prefix: str, scen) -> None:
    """Cross-key checks of [ensemble] (the ``check`` of ENSEMBLE_SECTION, on the Scenario)."""
    params = parse_vary(t["vary"], f"{prefix}.vary")
    n_groups = len(scen["logs"])
    for p in params:
        if p.index is not None:
            n = n_groups if p.section == "logs" else len(scen[p.section])
            if p.index >= n:
                raise ScenarioError(f'{prefix}.vary."{p.path}"', p.path,
                                    f"the scenario has {n} [[{p.section}]] table(s): index "
                                    f"must be < {n}")
        elif p.section == "obstacles" and not scen["obstacles"]:
            raise ScenarioError(f'{prefix}.vary."{p.path}"', p.path,
                                "the scenario has no [[obstacles]]")
    if t["sampling"] == "grid":
        for p in params:
            if p.kind not in LISTS:
                raise ScenarioError(f'{prefix}.vary."{p.path}"', p.kind,
                                    "sampling = 'grid' combines explicit lists: give values "
                                    "or range (or use monte_carlo / latin_hypercube)")
        size = math.prod(len(p.choices) for p in params) if params else 1
        if t["members"] is not None and t["members"] != size:
            raise ScenarioError(f"{prefix}.members", t["members"],
                                f"sampling = 'grid' runs every combination of the lists: "
                                f"{size} members (leave members out)")
    elif t["members"] is None:
        raise ScenarioError(f"{prefix}.members", None, f"is required for sampling = "
                            f"{t['sampling']!r}: the number of members")
    names = [p.path for p in params]
    for a in names:
        m = _PATH.match(a)
        if m.group(2) is not None and f"{m.group(1)}.{m.group(3)}" in names:
            raise ScenarioError(f'{prefix}.vary."{a}"', a, f"also set for every group by "
                                f'"{m.group(1)}.{m.group(3)}": vary one or the other')


# --------------------------------------------------------------------- the scenario section
def _check_ensemble(t, prefix, scen):
    if not t["vary"] and t["members"] is None:
        return  # not an ensemble: a plain scenario
    check_ensemble_section(t, prefix, scen)


ENSEMBLE_SECTION = Section("ensemble", [
    Key("base", "path", "", "base debris scenario; the other sections of this file are merged "
        "over it (leave empty when this file is the whole scenario)", must_exist=True),
    Key("members", "int", None, "number of members (for grid sampling: the number of "
        "combinations, leave it out)", min=1),
    Key("sampling", "str", "monte_carlo", "how the varied parameters are drawn: independently "
        "per member (monte_carlo), stratified (latin_hypercube, scipy.stats.qmc), or every "
        "combination of explicit lists (grid)", choices=("monte_carlo", "latin_hypercube",
                                                        "grid")),
    Key("seed", "int", 0, "seed of the sampling: member i is reproducible from the seed and i",
        min=0),
    Key("vary", "table", {}, "parameters to vary: \"section.key\" (every [[logs]] group) or "
        "\"logs[i].key\" = { values | range | uniform | loguniform | normal | lognormal | "
        "integers = [...] } (see driftlog.ensemble.spec)"),
    Key("reseed_logs", "bool", True, "give each member's random seeding its own seed, from "
        "(seed, member, group)"),
    Key("output", "path", "", "output folder (default: 'ensemble' beside the ensemble file)"),
    Key("workers", "int", None, "workers of the local Dask cluster (default: the CPU count; "
        "0: the members one after the other in this process, without Dask)", min=0),
    Key("scheduler", "str", "", "address of a running Dask scheduler (tcp://host:8786); "
        "empty: start a LocalCluster"),
    Key("keep_trajectories", "bool", False, "also write each member's trajectory file "
        "(output/trajectories/; on a cluster the workers need the shared filesystem)"),
    Key("confidence", "float", 0.95, "confidence level of the intervals", min=0.5, max=0.9999),
    Key("grid_cell", "float", None, "aggregate on a regular grid of this cell size instead of "
        "the flow mesh (required for analytic flows, which have no mesh)", "m", min=0.0,
        exclusive_min=True),
    Key("grid_origin", "point", None, "lower-left corner of the aggregation grid", "m"),
    Key("grid_size", "point", None, "extent of the aggregation grid (width, height)", "m",
        min=0.0, exclusive_min=True),
    Key("blocked_after", "float", 60.0, "an obstacle is blocked in a member when a log is in "
        "contact with it (within blocked_gap) at every record for at least this long (the "
        "clogging table; driftlog.ensemble.summary)", "s", min=0.0, exclusive_min=True),
    Key("blocked_gap", "float", 0.1, "a log whose gap to an obstacle is at most this share "
        "of its radius is in contact with it (for blocked_after)", min=0.0),
    Key("checkpoint_interval", "float", 60.0, "seconds between rewrites of the aggregated "
        "results while the ensemble runs", "s", min=0.0, exclusive_min=True),
], doc="ensembles: many members on one flow (driftlog ensemble)", check=_check_ensemble)
