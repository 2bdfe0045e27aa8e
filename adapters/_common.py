"""What the adapters share: time selection, unit conversion, variable look-up, lazy sources.

Each adapter opens another model's output and returns a ``MeshFlowField`` whose ``source``
reads one snapshot when asked (the lazy snapshot interface of ``driftlog.flow``:
``times`` and ``read(i) -> (h, hu, hv)`` on faces).
"""

from __future__ import annotations

import re

import numpy as np

from driftlog.errors import FlowFileError, geographic_error
from driftlog.flow import time_in_seconds
from driftlog.mesh import LENGTH_UNITS, geographic_attribute

__all__ = ["select_times", "unit_factor", "SubsetSnapshots", "find_variable",
           "time_in_seconds", "time_reference_attrs", "check_values", "DRIFTLOG_NAMES",
           "reference_epoch", "geographic_error", "geographic_attribute", "wkt_is_geographic",
           "refuse_geographic_wkt", "crs_length_unit"]

#: driftlog's names for the quantities an adapter looks for (keys of ``[flow] variables``)
DRIFTLOG_NAMES = ("depth", "level", "bed", "u", "v", "hu", "hv", "alpha")

# units -> factor to SI, per kind of quantity
_LENGTH = LENGTH_UNITS  # one table with the mesh reader's node coordinates (km, ft...)
_VELOCITY = {"m s-1": 1.0, "m/s": 1.0, "m s^-1": 1.0, "m.s-1": 1.0, "ms-1": 1.0, "m/sec": 1.0,
             "cm s-1": 0.01, "cm/s": 0.01, "cm s^-1": 0.01, "cm.s-1": 0.01,
             "mm s-1": 1e-3, "mm/s": 1e-3, "mm s^-1": 1e-3,
             # US models' exports (the international foot, as HEC-RAS's ft/s) and knots
             "ft s-1": 0.3048, "ft/s": 0.3048, "ft s^-1": 0.3048, "ft.s-1": 0.3048,
             "ft/sec": 0.3048, "fps": 0.3048, "knot": 1852.0 / 3600.0,
             "knots": 1852.0 / 3600.0, "kt": 1852.0 / 3600.0}
_UNIT_DISCHARGE = {"m2 s-1": 1.0, "m2/s": 1.0, "m^2/s": 1.0, "m^2 s^-1": 1.0, "m2.s-1": 1.0,
                   "m**2 s-1": 1.0, "cm2 s-1": 1e-4, "cm2/s": 1e-4,
                   "ft2 s-1": 0.3048 ** 2, "ft2/s": 0.3048 ** 2, "ft^2/s": 0.3048 ** 2}
_DISCHARGE = {"m3 s-1": 1.0, "m3/s": 1.0, "m^3/s": 1.0, "m^3 s^-1": 1.0, "m3.s-1": 1.0,
              "m**3 s-1": 1.0, "cumecs": 1.0, "ft3 s-1": 0.3048 ** 3, "ft3/s": 0.3048 ** 3,
              "ft^3/s": 0.3048 ** 3, "cfs": 0.3048 ** 3}
_KINDS = {"length": _LENGTH, "velocity": _VELOCITY, "unit_discharge": _UNIT_DISCHARGE,
          "discharge": _DISCHARGE, "fraction": {"1": 1.0, "": 1.0, "-": 1.0}}
_SI = {"length": "m", "velocity": "m s-1", "unit_discharge": "m2 s-1", "discharge": "m3 s-1",
       "fraction": "1"}


def _norm_units(u: str) -> str:
    return re.sub(r"\s+", " ", u.strip().lower().replace("**", "^"))


def unit_factor(units, kind: str, where: str, notes: list | None = None):
    """Factor from ``units`` to SI for a quantity of ``kind``; absent units are taken as SI.

    Known non-SI units (cm, mm, cm/s, mm/s...) are converted, with a note appended to
    ``notes``; anything else is refused with an error naming ``where`` and the units found.
    Returns (factor, kind) where kind may switch between discharge and unit discharge.
    """
    if units is None or (isinstance(units, str) and units.strip() == ""):
        return 1.0, kind
    u = _norm_units(str(units))
    table = {_norm_units(k): v for k, v in _KINDS[kind].items()}
    if u in table:
        f = table[u]
        if f != 1.0 and notes is not None:
            notes.append(f"{where}: converted from {units!r} to {_SI[kind]} (x {f:g})")
        return f, kind
    if kind in ("unit_discharge", "discharge"):  # the other one of the pair
        other = "discharge" if kind == "unit_discharge" else "unit_discharge"
        table = {_norm_units(k): v for k, v in _KINDS[other].items()}
        if u in table:
            return table[u], other
    allowed = sorted({_SI[kind]} | {k for k, v in _KINDS[kind].items() if v != 1.0})
    raise FlowFileError(f"{where}: units {units!r} are not units of {kind.replace('_', ' ')} "
                        f"(expected {_SI[kind]}, or one of {', '.join(allowed)})")


def time_reference_attrs(origin, calendar=None) -> dict:
    """The flow attributes that keep a time axis' absolute reference (CF units, calendar)."""
    if not origin:
        return {}
    out = {"time_reference": f"seconds since {origin}"}
    if calendar and str(calendar).strip().lower() not in ("standard", "gregorian"):
        out["calendar"] = str(calendar).strip()
    return out


def select_times(times, time_range, where):
    """Indices of the snapshots inside ``time_range`` = (start, end) (inclusive; None: all)."""
    times = np.asarray(times, dtype=np.float64)
    if time_range is None:
        return np.arange(times.size)
    a, b = (float(v) for v in time_range)
    if not b >= a:
        raise FlowFileError(f"{where}: time range [{a}, {b}] is reversed")
    # round-off of the bounds: relative to the spans, never to |t| (1e-9 |t| is 1.7 s at 1.7e9)
    span = max(b - a, float(times.max() - times.min()) if times.size else 0.0)
    eps = 1e-9 * span + 4.0 * float(np.spacing(max(abs(a), abs(b))))
    idx = np.flatnonzero((times >= a - eps) & (times <= b + eps))
    if idx.size == 0:
        raise FlowFileError(f"{where}: no snapshot in the time range [{a}, {b}] s (the file "
                            f"has {times.size} from {times.min():g} to {times.max():g} s)")
    return idx


class SubsetSnapshots:
    """A lazy source restricted to some of another source's snapshots (a time range)."""

    def __init__(self, source, index):
        self.source = source
        self.index = np.asarray(index, dtype=np.int64)
        self.times = np.asarray(source.times)[self.index]
        self.name = getattr(source, "name", "flow")
        self.location = getattr(source, "location", "face")

    def read(self, i):
        return self.source.read(int(self.index[i]))

    def close(self):
        if hasattr(self.source, "close"):
            self.source.close()


def find_variable(variables, candidates, role, mapping=None, standard_names=(),
                  where="file", required=True):
    """Name of the variable playing ``role``.

    The user's mapping first, then standard_name, then known aliases.  ``variables``: dict
    name -> attrs (dict).
    """
    mapping = mapping or {}
    if role in mapping:
        name = mapping[role]
        if name not in variables:
            raise FlowFileError(f"{where}: variable {name!r} (given for {role!r} in [flow] "
                                f"variables) is missing; the file has "
                                f"{', '.join(sorted(variables))}")
        return name
    for name, attrs in variables.items():
        if attrs.get("standard_name") in standard_names:
            return name
    lower = {n.lower(): n for n in variables}
    for c in candidates:
        if c in variables:
            return c
        if c.lower() in lower:
            return lower[c.lower()]
    if required:
        raise FlowFileError(f"{where}: no variable for {role} (looked for standard_name "
                            f"{list(standard_names)} and names {list(candidates)}); map it "
                            f"with [flow] variables = {{{role} = \"NAME\"}}")
    return None


def check_values(arr, fill, where):
    """Refuse NaN and fill values in a field read from a file, naming where they are."""
    bad = ~np.isfinite(arr)
    what = "NaN"
    if fill is not None:
        isfill = arr == fill
        if np.any(isfill):
            bad |= isfill
            what = f"fill value {fill}"
    if np.any(bad):
        idx = np.flatnonzero(bad.ravel())
        raise FlowFileError(f"{where}: {idx.size} {what} values (first at flat index "
                            f"{idx[:5].tolist()}); driftlog needs a value on every face (pass "
                            "fill='dry' to treat them as dry)")
    return arr


def reference_epoch(attrs, where="flow"):
    """The epoch of a field's ``time_reference`` attribute, or None when it has none.

    ``attrs["time_reference"]``: 'seconds since 2024-01-01 00:00:00' (CF style); the epoch is
    returned as a numpy datetime64[us].
    """
    ref = (attrs or {}).get("time_reference")
    if not ref:
        return None
    unit, _, origin = str(ref).partition(" since ")
    if unit.strip().lower() not in ("s", "sec", "second", "seconds") or not origin.strip():
        raise FlowFileError(f"{where}: time_reference {ref!r} is not 'seconds since DATE'")
    text = origin.strip().replace(" ", "T", 1).rstrip("Z")
    for tz in ("+00:00", "+0000", "UTC"):
        text = text.replace(tz, "")
    try:
        return np.datetime64(text.strip("T "), "us")
    except ValueError:
        raise FlowFileError(f"{where}: time_reference {ref!r}: date {origin!r} not "
                            "understood (expected ISO 8601, e.g. 2024-01-01 00:00:00)") from None


def wkt_is_geographic(wkt) -> bool:
    """Whether a CRS given as WKT (OGC, ESRI, WKT2) is geographic (longitude/latitude).

    ``pyproj.CRS.from_wkt(...).is_geographic`` (a compound CRS: its horizontal part); text
    pyproj cannot parse is geographic only if it starts with GEOGCS / GEOGCRS.  Anything
    else (empty, a projected CRS, a MIKE name such as 'UTM-32') is not.
    """
    text = str(wkt or "").strip()
    if not text:
        return False
    try:
        from pyproj import CRS

        return bool(CRS.from_wkt(text).is_geographic)
    except Exception:  # noqa: BLE001 - not WKT pyproj reads: its first keyword says
        return text.upper().startswith(("GEOGCS[", "GEOGCRS[", "GEOGRAPHICCRS["))


def refuse_geographic_wkt(wkt, where, what):
    """Raise ``geographic_error`` if the WKT ``wkt`` (``what``: where it was read) is geographic."""
    if wkt_is_geographic(wkt):
        raise geographic_error(where, what, wkt)


def crs_length_unit(crs):
    """(unit name, metres per unit) of a projected CRS's horizontal coordinates, or None.

    ``crs``: WKT text (OGC, ESRI, WKT2), or a CRS object ``pyproj.CRS.from_user_input`` takes
    (rioxarray's ``rio.crs``).  The unit is pyproj's: ``axis_info[0]`` (a compound CRS: its
    horizontal part first; a bound CRS: its source).  None where there is nothing to say:
    no CRS, text that is not WKT (a MIKE name such as 'UTM-32'), a CRS pyproj cannot read, a
    geographic one (refused on its own), or axes without a unit: the coordinates are then
    taken as metres.  Metadata only: the coordinates are never looked at.
    """
    if crs is None or (isinstance(crs, str) and not crs.strip()):
        return None
    try:
        from pyproj import CRS

        c = CRS.from_wkt(crs.strip()) if isinstance(crs, str) else CRS.from_user_input(crs)
        if c.is_geographic or not c.axis_info:
            return None
        axis = c.axis_info[0]
        factor = float(axis.unit_conversion_factor)
    except Exception:  # noqa: BLE001 - not a CRS pyproj reads: nothing said of its unit
        return None
    if not np.isfinite(factor) or factor <= 0.0:
        return None
    return str(axis.unit_name), factor
