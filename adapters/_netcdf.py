"""NetCDF helpers of the adapters: open a file, describe its variables, a lazy face source."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError

from ._common import check_values, time_in_seconds, time_reference_attrs, unit_factor

__all__ = ["open_dataset", "netcdf_matches", "check_netcdf3_size", "netcdf3_expected_size",
           "variable_attrs", "read_times", "time_attrs", "NetCDFSource", "FaceSnapshots",
           "ROLES"]

# role -> (kind of units, standard names, aliases), most specific first
ROLES = {
    "depth": ("length", ("sea_floor_depth_below_sea_surface", "water_depth",
                         "sea_water_depth", "water_thickness"),
              ("mesh2d_waterdepth", "waterdepth", "water_depth", "depth", "h", "mesh2d_h",
               "H", "wd", "depth_c")),
    "level": ("length", ("sea_surface_height", "sea_surface_height_above_geoid",
                         "water_surface_height_above_reference_datum",
                         "sea_surface_height_above_mean_sea_level", "sea_surface_elevation"),
              ("mesh2d_s1", "s1", "water_level", "waterlevel", "water_surface", "wse",
               "eta", "zeta", "stage", "elev", "level")),
    "bed": ("length", ("altitude", "bedrock_altitude", "surface_altitude",
                       "sea_floor_altitude"),
            ("mesh2d_flowelem_bl", "bed_level", "bedlevel", "bed", "zb", "bl", "mesh2d_bl",
             "elevation", "dem", "z", "topography")),
    "u": ("velocity", ("sea_water_x_velocity", "eastward_sea_water_velocity",
                       "x_velocity", "sea_water_x_velocity_depth_averaged"),
          ("mesh2d_ucx", "mesh2d_ucxa", "ucx", "ucxa", "velocity_x", "u", "vx", "Vx",
           "x_velocity")),
    "v": ("velocity", ("sea_water_y_velocity", "northward_sea_water_velocity",
                       "y_velocity", "sea_water_y_velocity_depth_averaged"),
          ("mesh2d_ucy", "mesh2d_ucya", "ucy", "ucya", "velocity_y", "v", "vy", "Vy",
           "y_velocity")),
    "hu": ("unit_discharge", ("x_unit_discharge",),
           ("mesh2d_qx", "hu", "qx", "Qx", "xmomentum", "unit_discharge_x", "discharge_x")),
    "hv": ("unit_discharge", ("y_unit_discharge",),
           ("mesh2d_qy", "hv", "qy", "Qy", "ymomentum", "unit_discharge_y", "discharge_y")),
}
# sea_floor_depth_below_geoid is positive down: a bed given that way is negated
_BED_DOWN = ("sea_floor_depth_below_geoid", "sea_floor_depth_below_mean_sea_level",
             "sea_floor_depth")


def open_dataset(path):
    """Open a NetCDF file with netCDF4 (no masking, scaling on), refusing truncated files.

    A NetCDF-3 file cut short (an interrupted copy or download) opens without complaint and
    netCDF4 then reads the missing bytes as fill values or garbage; its size is checked against
    what its header declares (``netcdf3_expected_size``).
    """
    import netCDF4

    path = Path(path)
    if not path.is_file():
        raise FlowFileError(f"{path}: file not found")
    try:
        ds = netCDF4.Dataset(path)
    except (OSError, RuntimeError) as exc:
        with open(path, "rb") as f:
            head = f.read(8)
        if head == b"\x89HDF\r\n\x1a\n":  # an HDF5 file netCDF4 cannot open
            raise FlowFileError(f"{path}: a NetCDF-4 / HDF5 file that cannot be read: "
                                f"truncated or damaged (an interrupted copy or download?) "
                                f"({exc})") from None
        raise FlowFileError(f"{path}: not a readable NetCDF file ({exc})") from None
    if ds.data_model.startswith("NETCDF3"):
        try:
            check_netcdf3_size(path)
        except BaseException:
            ds.close()
            raise
    ds.set_auto_mask(False)
    ds.set_auto_scale(True)
    return ds


_NC_SIZES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 4, 6: 8, 7: 1, 8: 2, 9: 4, 10: 8, 11: 8}


def netcdf3_expected_size(path):
    """Bytes a NetCDF-3 file (classic, 64-bit offset or CDF-5) must hold by its header.

    Returns (expected size, number of records), or None when the header does not say (a
    streaming file with an unknown record count, or a variable too large for its vsize field).
    """
    import struct

    with open(path, "rb") as f:
        head = f.read(4)
        if head[:3] != b"CDF" or head[3] not in (1, 2, 5):
            return None
        version = head[3]
        data = head + f.read(1 << 20)
        pos = 4

        def more(n):
            nonlocal data
            while pos + n > len(data):
                chunk = f.read(1 << 20)
                if not chunk:
                    raise FlowFileError(f"{path}: truncated NetCDF file: the header itself is "
                                        f"cut short ({len(data)} bytes)")
                data += chunk

        def read_int(size):
            nonlocal pos
            more(size)
            fmt = {4: ">i", 8: ">q"}[size]
            v = struct.unpack_from(fmt, data, pos)[0]
            pos += size
            return v

        isz = 8 if version == 5 else 4

        def name():
            nonlocal pos
            n = read_int(isz)
            more(n + 3)
            pos += (n + 3) // 4 * 4

        def skip_atts():
            nonlocal pos
            tag, n = read_int(4), read_int(isz)
            for _ in range(n if tag else 0):
                name()
                typ, count = read_int(4), read_int(isz)
                nbytes = count * _NC_SIZES.get(typ, 1)
                more(nbytes + 3)
                pos += (nbytes + 3) // 4 * 4

        numrecs = read_int(isz) if version == 5 else read_int(4) & 0xFFFFFFFF
        if numrecs in (0xFFFFFFFF, -1):  # streaming: the count is not in the header
            return None
        tag, ndims = read_int(4), read_int(isz)
        dims = []
        for _ in range(ndims if tag else 0):
            name()
            dims.append(read_int(isz))
        skip_atts()
        tag, nvars = read_int(4), read_int(isz)
        fixed_end, rec = 0, []
        for _ in range(nvars if tag else 0):
            name()
            nd = read_int(isz)
            ids = [read_int(isz) for _ in range(nd)]
            skip_atts()
            typ = read_int(4)
            read_int(isz)  # vsize: saturates over 4 GiB, so the size is computed below
            begin = read_int(4 if version == 1 else 8)
            is_rec = bool(ids) and dims[ids[0]] == 0
            shape = [dims[i] for i in ids[1:]] if is_rec else [dims[i] for i in ids]
            size = int(np.prod(shape, dtype=np.int64)) * _NC_SIZES.get(typ, 1)
            if is_rec:
                rec.append((begin, size, (size + 3) // 4 * 4))
            else:
                fixed_end = max(fixed_end, begin + size)
    end = fixed_end
    if rec and numrecs:
        recsize = rec[0][1] if len(rec) == 1 else sum(r[2] for r in rec)
        end = max(end, max(b + (numrecs - 1) * recsize + sz for b, sz, _ in rec))
    return end, numrecs


def check_netcdf3_size(path):
    """Refuse a NetCDF-3 file shorter than its header declares (a truncated file)."""
    got = Path(path).stat().st_size
    exp = netcdf3_expected_size(path)
    if exp is not None and got < exp[0]:
        raise FlowFileError(f"{path}: truncated NetCDF file: {got} bytes, but its header "
                            f"declares {exp[0]} ({exp[1]} records); the data past byte {got} "
                            "are missing (an interrupted copy or download?): copy the file "
                            "again")


def netcdf_matches(path, test) -> bool:
    """Whether ``path`` is a readable NetCDF file for which ``test(dataset)`` is true.

    The content sniff of the NetCDF readers' ``can_open``: never raises.
    """
    try:
        p = Path(path)
        if not p.is_file():
            return False
        with open_dataset(p) as ds:
            return bool(test(ds))
    except Exception:
        return False


def variable_attrs(ds, dims=None):
    """Name -> attrs of the variables (only those with exactly these dims, if given)."""
    out = {}
    for name, var in ds.variables.items():
        if dims is not None and tuple(var.dimensions) != tuple(dims):
            continue
        out[name] = {k: var.getncattr(k) for k in var.ncattrs()}
    return out


def _time_variable(ds, path, time_dim):
    if time_dim in ds.variables:
        return ds.variables[time_dim]
    for var in ds.variables.values():
        if var.dimensions == (time_dim,) and (
                getattr(var, "standard_name", "") == "time" or getattr(var, "axis", "") == "T"):
            return var
    raise FlowFileError(f"{path}: no time variable for the dimension {time_dim!r}")


def read_times(ds, path, time_dim):
    """Snapshot times (s) of a time dimension, and the time origin if the units give one.

    Any CF calendar (the reference date is checked against the variable's ``calendar``);
    character date stamps are read as seconds since the first one.
    """
    tvar = _time_variable(ds, path, time_dim)
    values = tvar[:]
    if tvar.dtype.kind == "S" and values.ndim == 2:  # char array of date stamps
        import netCDF4

        values = netCDF4.chartostring(values)
    return time_in_seconds(values, getattr(tvar, "units", None), f"{path}: {tvar.name}",
                           calendar=getattr(tvar, "calendar", None))


def time_attrs(ds, path, time_dim, origin) -> dict:
    """Flow attributes keeping the absolute time reference: ``time_reference``, ``calendar``."""
    if not origin:
        return {}
    tvar = _time_variable(ds, path, time_dim)
    return time_reference_attrs(origin, getattr(tvar, "calendar", None))


def fill_value(var):
    for k in ("_FillValue", "missing_value"):
        if k in var.ncattrs():
            return np.asarray(var.getncattr(k)).ravel()[0]
    return None


#: negative depths down to this (m) are round-off (a float32 water level equal to the bed, a
#: model's wetting tolerance) and clipped to 0; deeper ones are refused (``NetCDFSource.read``)
NEGATIVE_DEPTH_TOLERANCE = 1e-3


class NetCDFSource:
    """Base of the lazy NetCDF sources: one file kept open, ``read(i)`` builds (h, hu, hv).

    Negative depths: those down to ``-NEGATIVE_DEPTH_TOLERANCE`` (1 mm) are clipped to 0; a
    deeper one is an error naming the variable, the value, the snapshot and the face.

    Subclasses give ``_get(role, i)``: the face array of a role ('depth' or 'level', 'hu' and
    'hv' or 'u' and 'v') at snapshot i in SI units, NaN where a fill value was accepted as dry;
    ``self.spec`` holds the roles found and ``self.bed`` the bed on faces.
    """

    def __init__(self, ds, path, times, spec, bed, fill="error"):
        self.ds, self.path, self.name = ds, Path(path), str(path)
        self.times, self.spec, self.bed, self.fill = times, spec, bed, fill

    def _values(self, var, i, arr):
        """Check a raw array for NaN and fill values (or turn them into NaN if fill='dry')."""
        fv = fill_value(var)
        if self.fill == "dry":
            bad = ~np.isfinite(arr) if fv is None else (~np.isfinite(arr) | (arr == fv))
            return np.where(bad, np.nan, arr)
        return check_values(arr, fv, f"{self.path}: {var.name} at snapshot {i} "
                                     f"(t = {self.times[i]:g} s)")

    def read(self, i):
        """Face arrays (h, hu, hv) of snapshot i."""
        if "depth" in self.spec:
            h = self._get("depth", i)
        else:
            h = self._get("level", i) - self.bed
        dry = ~np.isfinite(h)
        h = np.where(dry, 0.0, h)
        self._check_negative_depth(h, i)
        h = np.maximum(h, 0.0)
        if "hu" in self.spec:
            hu, hv = self._get("hu", i), self._get("hv", i)
        else:
            hu, hv = h * self._get("u", i), h * self._get("v", i)
        return (h, np.where(np.isfinite(hu) & ~dry, hu, 0.0),
                np.where(np.isfinite(hv) & ~dry, hv, 0.0))

    def _var_name(self, role):
        """The file's variable playing ``role`` (for messages)."""
        spec = self.spec.get(role)
        if isinstance(spec, tuple) and spec and isinstance(spec[0], str):
            return spec[0]
        return getattr(self, "names", {}).get(role, role)

    def _check_negative_depth(self, h, i):
        """Refuse depths below ``-NEGATIVE_DEPTH_TOLERANCE`` (the caller clips the rest).

        The message names the variable, the value, the snapshot and the face.
        """
        k = int(np.argmin(h)) if h.size else 0
        if h.size and h[k] < -NEGATIVE_DEPTH_TOLERANCE:
            what = (repr(self._var_name("depth")) if "depth" in self.spec
                    else f"{self._var_name('level')!r} - bed")
            n = int(np.count_nonzero(h < -NEGATIVE_DEPTH_TOLERANCE))
            raise FlowFileError(f"{self.path}: negative water depth {h[k]:g} m from {what} at "
                                f"snapshot {i} (t = {self.times[i]:g} s), face {k} ({n} faces "
                                f"below -{NEGATIVE_DEPTH_TOLERANCE:g} m); a depth must be >= 0 "
                                f"(values down to -{NEGATIVE_DEPTH_TOLERANCE:g} m are taken as "
                                "round-off and clipped to 0): wrong variable, sign or bed?")

    def close(self):
        """Close the file."""
        if self.ds.isopen():
            self.ds.close()


class FaceSnapshots(NetCDFSource):
    """Lazy source over time-first NetCDF variables of face values (UGRID).

    ``spec``: role -> (variable name, unit factor).
    """

    def _get(self, role, i):
        name, factor = self.spec[role]
        var = self.ds.variables[name]
        return self._values(var, i, np.asarray(var[i], dtype=np.float64)) * factor


def find_roles(variables, mapping, where, need_bed):
    """Pick variables for depth/level, bed, velocity or unit discharge; returns role -> name."""
    from ._common import find_variable

    roles = {}
    for role in ("depth", "level", "u", "v", "hu", "hv"):
        kind, std, alias = ROLES[role]
        roles[role] = find_variable(variables, alias, role, mapping, std, where,
                                    required=False)
    if roles["depth"] is None and roles["level"] is None:
        raise FlowFileError(f"{where}: no water depth nor water level variable (looked for "
                            f"standard_name {ROLES['depth'][1][0]!r} or "
                            f"{ROLES['level'][1][0]!r}, and names like "
                            f"{ROLES['depth'][2][:3]} / {ROLES['level'][2][:3]}); the file has "
                            f"{sorted(variables)}; map them with [flow] variables")
    has_uv = roles["u"] is not None and roles["v"] is not None
    has_q = roles["hu"] is not None and roles["hv"] is not None
    if ("hu" in (mapping or {})) and has_q:
        has_uv = False
    if not has_uv and not has_q:
        raise FlowFileError(f"{where}: no velocity (u, v) nor unit discharge (hu, hv) "
                            f"variables (looked for standard_name 'sea_water_x_velocity' and "
                            f"names like {ROLES['u'][2][:3]} / {ROLES['hu'][2][:3]}); the file "
                            f"has {sorted(variables)}; map them with [flow] variables")
    out = {k: roles[k] for k in (("u", "v") if has_uv else ("hu", "hv"))}
    if roles["depth"] is not None and "level" not in (mapping or {}):
        out["depth"] = roles["depth"]
    else:
        out["level"] = roles["level"]
    return out


def factors(ds, roles, where, notes, units_override=None):
    """Unit factor of each role's variable (converting cm, mm, cm/s... with a note)."""
    spec = {}
    for role, name in roles.items():
        kind = ROLES[role][0]
        units = (units_override or {}).get(role, getattr(ds.variables[name], "units", None))
        f, got = unit_factor(units, kind, f"{where}: {name}", notes)
        spec[role] = (name, f, got)
    return spec


def bed_down(attrs):
    return attrs.get("standard_name") in _BED_DOWN or attrs.get("positive") == "down"
