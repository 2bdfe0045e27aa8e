"""Ensemble specifications: the parameters to vary, how they are sampled, and member scenarios.

An ensemble is a scenario file with an ``[ensemble]`` section (registered in
``driftlog.scenario``).  The file is a whole debris scenario, or names a ``base`` scenario whose
sections it overrides.  ``[ensemble.vary]`` maps a scenario key to what it takes::

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
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from driftlog.errors import ScenarioError
from driftlog.scenario import SECTIONS, Scenario, load_scenario
from driftlog.schema import check_value, merge, read_toml

__all__ = ["Parameter", "Ensemble", "load_ensemble", "parse_vary", "check_ensemble_section",
           "DISTRIBUTIONS", "SAMPLINGS"]

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
VARIABLE_SECTIONS = ("logs", "physics", "integrator", "contact", "time", "obstacles")
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


def check_ensemble_section(t: dict, prefix: str, scen: Scenario) -> None:
    """Cross-key checks of [ensemble] (the ``check`` of its Section in driftlog.scenario)."""
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


# --------------------------------------------------------------------- the ensemble
RUNTIME_KEYS = ("workers", "scheduler", "output", "keep_trajectories", "checkpoint_interval")


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
        out["output"] = {"vtk": False}  # members write no side files
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
    ens = raw.get("ensemble")
    if not isinstance(ens, dict):
        raise ScenarioError("ensemble", ens, "an ensemble file needs an [ensemble] section "
                            "(the parameters to vary; see `driftlog scenario keys --section "
                            "ensemble`)")
    raw = _absolute_paths(raw, base_dir)
    ens = raw["ensemble"]
    if ens.get("base"):
        if not Path(ens["base"]).is_file():
            raise ScenarioError("ensemble.base", ens["base"], "file not found")
        data = json.loads(load_scenario(ens["base"]).to_json())
        data.pop("ensemble", None)
        raw = merge(data, raw)
    if not ens.get("output"):  # the default folder sits beside the ensemble file
        raw["ensemble"] = dict(ens, output=str(base_dir / "ensemble"))
    scen = load_scenario(raw)
    scen.path = file_path
    check_ensemble_section(scen["ensemble"], "ensemble", scen)  # also when nothing varies
    ensemble = Ensemble(scen, parse_vary(scen["ensemble"]["vary"]))
    ensemble.member_scenario(0)  # cross-key errors of the members show now, not on a worker
    return ensemble
