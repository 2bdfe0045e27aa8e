"""The scenario schema machinery: keys, sections, value checking, TOML reading, merging.

A scenario file is a set of sections (TOML tables); each part of driftlog declares its own
section beside the object it configures (``physics.PHYSICS_SECTION`` beside ``PhysicsOptions``,
a reader's ``OPTIONS`` beside its ``open``...).  This module knows nothing of any section: it
checks a value against a :class:`Key`, a table against a :class:`Section`, reads TOML, merges
nested tables, lists keys and suggests the closest name for a misspelt one.  ``driftlog.scenario``
assembles the sections into the scenario file.

Every bad value raises one :class:`driftlog.errors.ScenarioError` naming the key, the value and
what is allowed.
"""

from __future__ import annotations

import difflib
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from driftlog.errors import ScenarioError

__all__ = ["REQUIRED", "Key", "Section", "check_value", "check_table", "check_tables",
           "read_toml", "merge", "describe_sections", "did_you_mean"]

REQUIRED = object()
"""Default of a key that must be given."""


@dataclass
class Key:
    """One scenario key: type, default, units, rules and description.

    ``type`` is one of float, int, bool, str, path, floats, point, points, table,
    float_or_str, numbers_or_str (a number, a list of numbers or one of ``choices``), any.
    """

    name: str
    type: str
    default: Any = None
    doc: str = ""
    units: str = ""
    choices: tuple = ()
    min: float | None = None
    max: float | None = None
    exclusive_min: bool = False
    length: int | None = None  # exact list length for floats
    must_exist: bool = False  # path keys: the file must exist
    when: str | None = None  # documentation: which setting the key applies to

    def describe(self):
        """The key's rule in words (choices, bounds), '' when it has none."""
        rule = []
        if self.choices:
            rule.append("one of " + ", ".join(repr(c) for c in self.choices))
        if self.min is not None:
            rule.append(f"{'>' if self.exclusive_min else '>='} {self.min}")
        if self.max is not None:
            rule.append(f"<= {self.max}")
        return "; ".join(rule)

    def bounds(self) -> str:
        """The key's allowed range with its units (``> 0.0 and <= 1.0 m``), '' without bounds."""
        rule = []
        if self.min is not None:
            rule.append(f"{'>' if self.exclusive_min else '>='} {self.min}")
        if self.max is not None:
            rule.append(f"<= {self.max}")
        return " and ".join(rule) + (f" {self.units}" if rule and self.units else "")


@dataclass
class Section:
    """A table of the scenario file; ``repeated`` for arrays of tables ([[logs]]).

    ``check(table, prefix, scenario)`` is the section's cross-key rule, run on the validated
    table once every section is filled in.
    """

    name: str
    keys: list[Key]
    doc: str = ""
    repeated: bool = False
    check: Any = None
    by_name: dict = field(init=False)

    def __post_init__(self):
        self.by_name = {k.name: k for k in self.keys}


def did_you_mean(name, allowed) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``allowed``, or ''."""
    close = difflib.get_close_matches(name, list(allowed), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


# --------------------------------------------------------------------- checking values
def _type_error(key, value, what):
    return ScenarioError(key, value, f"must be {what}")


def _check_number(k: Key, key, value, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _type_error(key, value, "an integer" if integer else "a number")
    if integer and not isinstance(value, int):
        raise _type_error(key, value, "an integer")
    if not math.isfinite(value):
        raise _type_error(key, value, "a finite number")
    below = k.min is not None and (value <= k.min if k.exclusive_min else value < k.min)
    if below or (k.max is not None and value > k.max):  # the whole range when it has two ends
        raise ScenarioError(key, value, f"must be {k.bounds()}")
    return int(value) if integer else float(value)


def check_value(k: Key, key: str, value, base_dir: Path):
    """Check ``value`` against key ``k`` and normalise it.

    Numbers become float/int, paths absolute against ``base_dir``; ``key`` is the dotted
    name used in the error message.
    """
    t = k.type
    if t == "any":
        return value
    if t == "float":
        return _check_number(k, key, value)
    if t == "int":
        return _check_number(k, key, value, integer=True)
    if t == "bool":
        if not isinstance(value, bool):
            raise _type_error(key, value, "true or false")
        return value
    if t == "str":
        if not isinstance(value, str):
            raise _type_error(key, value, "a string")
        if k.choices and value not in k.choices:
            raise ScenarioError(key, value, "must be one of "
                                + ", ".join(repr(c) for c in k.choices)
                                + did_you_mean(value, k.choices))
        return value
    if t == "float_or_str":
        if isinstance(value, str):
            if k.choices and value not in k.choices:
                raise ScenarioError(key, value, "must be a number or one of "
                                    + ", ".join(repr(c) for c in k.choices))
            return value
        return _check_number(k, key, value)
    if t == "numbers_or_str":
        if isinstance(value, str):
            if value not in k.choices:
                raise ScenarioError(key, value, "must be a number, a list of numbers or one of "
                                    + ", ".join(repr(c) for c in k.choices))
            return value
        if isinstance(value, list):
            if not value:
                raise _type_error(key, value, "a number or a non-empty list of numbers")
            for i, v in enumerate(value):
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ScenarioError(f"{key}[{i}]", v, "must be a number (the list "
                                        f"{value!r} must hold numbers only)")
            return [_check_number(k, f"{key}[{i}]", v) for i, v in enumerate(value)]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _type_error(key, value, "a number, a list of numbers or one of "
                              + ", ".join(repr(c) for c in k.choices))
        return _check_number(k, key, value)
    if t == "path":
        if not isinstance(value, str) or not value:
            raise _type_error(key, value, "a file path (string)")
        p = Path(value).expanduser()
        p = p if p.is_absolute() else (base_dir / p)
        if k.must_exist and not p.exists():
            raise ScenarioError(key, value, f"file not found (looked for {p})")
        return str(p)
    if t in ("floats", "point"):
        if not isinstance(value, list) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise _type_error(key, value, "a list of numbers")
        n = 2 if t == "point" else k.length
        if n is not None and len(value) != n:
            raise _type_error(key, value, f"a list of {n} numbers")
        return [_check_number(k, f"{key}[{i}]", v) for i, v in enumerate(value)]
    if t == "points":
        if not isinstance(value, list) or not all(
                isinstance(p, list) and len(p) == 2
                and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in p)
                for p in value):
            raise _type_error(key, value, "a list of [x, y] pairs")
        if k.length is not None and len(value) < k.length:
            raise _type_error(key, value, f"at least {k.length} [x, y] pairs")
        return [[float(a), float(b)] for a, b in value]
    if t == "table":
        if not isinstance(value, dict):
            raise _type_error(key, value, "a table")
        return value
    raise AssertionError(f"unknown key type {t}")


def check_table(section: Section, table, prefix: str, base_dir: Path, fill: bool = True):
    """Check a table against a section.

    Unknown keys are refused (with the closest name), values checked; with ``fill`` the keys
    not given take their defaults (a REQUIRED key missing is an error).
    """
    if not isinstance(table, dict):
        raise _type_error(prefix, table, "a table")
    out = {}
    for name, value in table.items():
        k = section.by_name.get(name)
        if k is None:
            allowed = sorted(section.by_name)
            raise ScenarioError(f"{prefix}.{name}", value,
                                f"unknown key{did_you_mean(name, allowed)}; the keys of "
                                f"[{section.name}] are: " + ", ".join(allowed))
        if value is None or (k.type == "path" and value == "" and k.default == ""):
            out[name] = k.default  # unset (from a resolved scenario written into an output)
            continue
        out[name] = check_value(k, f"{prefix}.{name}", value, base_dir)
    if not fill:
        return out
    for k in section.keys:
        if k.name not in out:
            if k.default is REQUIRED:
                raise ScenarioError(f"{prefix}.{k.name}", None, "is required: " + k.doc)
            out[k.name] = k.default
            if k.type == "path" and k.default:
                out[k.name] = check_value(k, f"{prefix}.{k.name}", k.default, base_dir)
    return out


def check_tables(raw: dict, sections, top_keys, base_dir: Path) -> dict:
    """Check a whole file: ``top_keys`` (plain keys) and every section of ``sections``.

    Sections not given are filled with defaults; repeated sections are lists.
    """
    by_name = {s.name: s for s in sections}
    data = {}
    for k in top_keys:
        data[k.name] = (check_value(k, k.name, raw[k.name], base_dir) if k.name in raw
                        else k.default)
    for name, value in raw.items():
        if name in data:
            continue
        sec = by_name.get(name)
        if sec is None:
            allowed = sorted(list(by_name) + [k.name for k in top_keys])
            raise ScenarioError(name, value if not isinstance(value, dict) else "{...}",
                                f"unknown section{did_you_mean(name, allowed)}; allowed: "
                                + ", ".join(allowed))
        if sec.repeated:
            if isinstance(value, dict) and any(str(k).isdigit() for k in value):
                i = next(k for k in value if str(k).isdigit())
                raise ScenarioError(f"{name}[{i}]", "{...}", f"no such table: the scenario has "
                                    f"no [[{name}]] tables to change")
            items = value if isinstance(value, list) else [value]
            data[name] = [check_table(sec, t, f"{name}[{i}]", base_dir)
                          for i, t in enumerate(items)]
        else:
            data[name] = check_table(sec, value, name, base_dir)
    for sec in sections:
        if sec.name not in data:
            data[sec.name] = [] if sec.repeated else check_table(sec, {}, sec.name, base_dir)
    return data


def run_checks(sections, data: dict, scenario) -> None:
    """Run every section's cross-key ``check(table, prefix, scenario)``."""
    for sec in sections:
        if sec.check is not None:
            items = data[sec.name] if sec.repeated else [data[sec.name]]
            for i, t in enumerate(items):
                sec.check(t, f"{sec.name}[{i}]" if sec.repeated else sec.name, scenario)


# --------------------------------------------------------------------- files and merging
def read_toml(source, what: str = "scenario"):
    """(raw dict, resolved path or None, text) of a TOML file path, TOML text or a dict."""
    path, text = None, ""
    if isinstance(source, dict):
        return json.loads(json.dumps(source)), None, ""
    src = str(source)
    p = Path(src) if ("\n" not in src and len(src) < 4096) else None
    if p is not None and (p.suffix == ".toml" or p.exists()):
        if not p.exists():
            raise ScenarioError(what, str(p), "file not found")
        from driftlog.files import read_text

        path, text = p.resolve(), read_text(p, f"{what} file")
    else:
        text = src
    try:
        return tomllib.loads(text), path, text
    except tomllib.TOMLDecodeError as exc:
        if path is None and p is not None and "=" not in src and "[" not in src:
            raise ScenarioError(what, src, "neither a file (not found), a case name (driftlog "
                                "cases list) nor TOML text") from None
        raise ScenarioError(what, str(path or "<text>"), f"is not valid TOML: {exc}") from None


def merge(base: dict, over: dict, path: str = "") -> dict:
    """Nested merge of ``over`` into a copy of ``base`` (lists and scalars replace).

    A table merged over an array of tables goes into each of its tables, a key 'i' (digits)
    into table i only: ``--set logs.density=800`` changes every [[logs]] group,
    ``--set logs.1.density=800`` (or ``logs[1].density``) group 1; over an empty array (or no
    array) the table is the one table.  ``path``: the dotted name of ``base``, for messages.
    """
    out = dict(base)
    for k, v in over.items():
        where = f"{path}.{k}" if path else str(k)
        old = out.get(k)
        if isinstance(v, dict) and isinstance(old, dict):
            out[k] = merge(old, v, where)
        elif (isinstance(v, dict) and isinstance(old, list) and old
              and all(isinstance(g, dict) for g in old)):
            out[k] = _merge_groups(old, v, where)
        else:
            out[k] = v
    return out


def _merge_groups(groups: list, over: dict, where: str) -> list:
    """``over`` merged into every table of ``groups``, its digit keys into those tables only."""
    common = {k: v for k, v in over.items() if not str(k).isdigit()}
    out = [merge(g, common, f"{where}[{i}]") for i, g in enumerate(groups)]
    for k, v in over.items():
        if not str(k).isdigit():
            continue
        i = int(k)
        if i >= len(out):
            raise ScenarioError(f"{where}[{i}]", "{...}" if isinstance(v, dict) else v,
                                f"no such table: [[{where}]] has {len(out)} (indices 0 to "
                                f"{len(out) - 1})")
        if not isinstance(v, dict):
            raise _type_error(f"{where}[{i}]", v, "a table")
        out[i] = merge(out[i], v, f"{where}[{i}]")
    return out


def describe_sections(sections, section: str | None = None) -> str:
    """A text table of every key: name, type, default, units, rule, description."""
    lines = []
    for sec in sections:
        if section and sec.name != section:
            continue
        head = f"[[{sec.name}]]" if sec.repeated else f"[{sec.name}]"
        lines.append(f"{head}  {sec.doc}")
        for k in sec.keys:
            default = "(required)" if k.default is REQUIRED else repr(k.default)
            rule = k.describe()
            units = f" [{k.units}]" if k.units else ""
            when = f" ({k.when})" if k.when else ""
            lines.append(f"  {k.name:<22} {k.type:<8} default {default}{units}{when}")
            if k.doc:
                lines.append(f"      {k.doc}" + (f"; {rule}" if rule else ""))
        lines.append("")
    return "\n".join(lines)
