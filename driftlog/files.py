"""What a file is, before anything reads it; output paths checked before anything is computed.

Every reader of driftlog asks :func:`require` for the kinds it accepts, so that a flow file given
to ``driftlog plot``, a scenario given to ``driftlog animate``, an empty, truncated or binary
file, or a directory is refused with one line naming the file, what it is and what is expected,
instead of a backend's traceback.  :func:`check_output` refuses an output path that cannot be
written (parent is a file, read-only or missing folder, the input itself) before a run starts;
:func:`atomic_output` writes a file under a temporary name and renames it when it is complete,
so that an interrupted write never leaves a truncated file under the final name.
:func:`reopen_partial` makes the ``.partial`` file a killed run left (trajectories, flow) safe
to append to on resume; :func:`nothing_to_resume` says when ``--resume`` found none.

Kinds (``sniff(path).kind``):

================  =================================================================
missing           nothing at that path
directory         a directory (not an OpenFOAM case)
openfoam          an OpenFOAM case directory (a hydro source)
empty             a file of 0 bytes
scenario          a TOML text file (a scenario or ensemble file)
flow              a driftlog flow file (UGRID + water_depth, velocity_x, velocity_y)
trajectories      a driftlog trajectory file (CF featureType = trajectory, contiguous)
partial           the ``.partial`` trajectory file of a running or stopped run
ensemble          a driftlog ensemble result file
mesh              a UGRID NetCDF mesh without a flow
model_output      another model's NetCDF (UGRID map, ANUGA sww, CF grid): a hydro source
netcdf            a readable NetCDF file of another layout
bad_netcdf        a NetCDF / HDF5 file that cannot be opened (truncated, corrupt)
mesh_file         a file meshio reads by its suffix (.msh, .vtu, .2dm...)
text              a UTF-8 text file that is not TOML
binary            anything else (not UTF-8 text, not NetCDF)
================  =================================================================
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from driftlog.errors import DriftlogError, InputFileError, OutputPathError

__all__ = ["FileKind", "sniff", "require", "check_output", "atomic_output", "read_text",
           "DESCRIPTIONS", "register_reader", "register_loader", "nothing_to_resume", "left_open",
           "reopen_partial", "recover_killed"]

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
NETCDF_MAGIC = (b"CDF\x01", b"CDF\x02", b"CDF\x05", HDF5_SIGNATURE)
MESH_SUFFIXES = (".msh", ".vtu", ".vtk", ".2dm", ".ply", ".obj", ".off", ".stl", ".xdmf",
                 ".xmf", ".med", ".mesh", ".inp", ".dat", ".su2", ".h5m", ".bdf", ".f3grid")

DESCRIPTIONS = {
    "missing": "not found",
    "directory": "a directory that is not an OpenFOAM case (no system/controlDict, "
                 "constant/polyMesh or processor*)",
    "openfoam": "an OpenFOAM case directory (a hydro source)",
    "empty": "an empty file (0 bytes)",
    "scenario": "a scenario file (TOML)",
    "flow": "a driftlog flow file",
    "trajectories": "a driftlog trajectory file",
    "partial": "the .partial trajectory file of a running or stopped run",
    "ensemble": "a driftlog ensemble result file",
    "mesh": "a UGRID mesh file without a flow (no water_depth)",
    "model_output": "another model's output (a hydro source: import it with driftlog import, "
                    "or name it in [flow] source)",
    "netcdf": "a NetCDF file of an unknown layout",
    "bad_netcdf": "a NetCDF/HDF5 file that cannot be read (truncated or corrupt)",
    "mesh_file": "a mesh file (read by meshio)",
    "text": "a text file that is not TOML",
    "binary": "a binary file (not UTF-8 text, not NetCDF)",
}

SHORT = {k: v.split(" (")[0] for k, v in DESCRIPTIONS.items()}
SHORT.update(partial="its .partial file", directory="a directory", text="a text file",
             model_output="another model's output", mesh="a UGRID mesh file")

# what to do instead, by (kind given, role expected)
_HINTS = {
    ("flow", "trajectories"): "plot, animate and vtk take the trajectory file written by "
                              "driftlog track or run; for a flow use driftlog info or "
                              "driftlog vtk --flow",
    ("model_output", "trajectories"): "plot, animate and vtk take the trajectory file written "
                                      "by driftlog track or run; for a flow use driftlog info "
                                      "or driftlog vtk --flow",
    ("openfoam", "trajectories"): "plot, animate and vtk take the trajectory file written by "
                                  "driftlog track or run; for a flow use driftlog info or "
                                  "driftlog vtk --flow",
    ("mesh", "trajectories"): "plot, animate and vtk take the trajectory file written by "
                              "driftlog track or run",
    ("scenario", "trajectories"): "run it first: driftlog track SCENARIO, then give the "
                                  "trajectory file it prints",
    ("trajectories", "flow"): "a trajectory file holds logs, not a flow; the flow file is "
                              "the scenario's [flow] path",
    ("mesh", "flow"): "a mesh holds no flow; a flow file is written by driftlog solve or "
                      "driftlog import",
    ("model_output", "flow"): "convert it first (driftlog import SRC -o flow.nc), or set "
                              "[flow] source to its format",
    ("openfoam", "flow"): "convert it first (driftlog import CASE -o flow.nc), or set "
                          "[flow] source = 'openfoam'",
    ("partial", "trajectories"): "",
    ("flow", "scenario"): "a scenario is a TOML file (driftlog scenario keys lists its keys)",
    ("trajectories", "scenario"): "a scenario is a TOML file; the scenario of a run is in "
                                  "the trajectory file's attribute scenario",
    ("directory", "scenario"): "give the scenario file inside it (e.g. DIR/scenario.toml) "
                               "or a case name (driftlog cases list)",
}


@dataclass
class FileKind:
    """What :func:`sniff` found: the kind, the path, and details (reason, attributes)."""

    kind: str
    path: Path
    detail: str = ""
    info: dict = field(default_factory=dict)

    def describe(self) -> str:
        """One phrase: what the file is."""
        d = DESCRIPTIONS[self.kind]
        return f"{d} ({self.detail})" if self.detail else d


def _netcdf_kind(path: Path) -> FileKind:
    import netCDF4

    try:
        ds = netCDF4.Dataset(path)
    except (OSError, RuntimeError, UnicodeError) as exc:
        msg = str(exc).replace(f": {str(path)!r}", "").replace(f": '{path}'", "")
        return FileKind("bad_netcdf", path, f"{path.stat().st_size} bytes; {msg}")
    if ds.data_model.startswith("NETCDF3"):  # opens when cut short: sizes against the header
        for check in CONTENT_CHECKS:
            try:
                check(path)
            except DriftlogError as exc:
                ds.close()
                msg = str(exc).replace(f"{path}: ", "")
                return FileKind("bad_netcdf", path, f"{path.stat().st_size} bytes; {msg}")
    with ds:
        names = set(ds.variables)
        attrs = set(ds.ncattrs())
        info = {"variables": sorted(names), "dimensions": {k: len(v) for k, v in
                                                           ds.dimensions.items()},
                "attributes": sorted(attrs)}
        if getattr(ds, "featureType", "") == "trajectory" or "trajectory_index" in names:
            if "rowSize" in names:
                return FileKind("trajectories", path, info=info)
            return FileKind("partial", path, info=info)
        title = str(getattr(ds, "title", ""))
        # the aggregate's own title (a flow file's title is its scenario's, which may say
        # "ensemble": cases/river_piers/ensemble.toml)
        if "driftlog_version" in attrs and (title.startswith("driftlog ensemble")
                                            or "member_state" in names):
            return FileKind("ensemble", path, info=info)
        topo = [v for v in ds.variables.values()
                if "cf_role" in v.ncattrs() and v.getncattr("cf_role") == "mesh_topology"]
        own = {"water_depth", "velocity_x", "velocity_y", "time"} <= names
        if topo and own and "driftlog_version" in attrs:
            return FileKind("flow", path, info=info)
        if topo and not ({"time"} & names or own):
            return FileKind("mesh", path, info=info)
        sww = {"x", "y", "volumes", "stage"} <= names  # ANUGA
        grid = any(len(v.dimensions) == 1 and (getattr(v, "axis", "") in ("X", "Y") or
                                               v.name in ("x", "y", "lon", "lat"))
                   for v in ds.variables.values())  # a CF grid's 1-D coordinates
        if topo or sww or grid:
            return FileKind("model_output", path, info=info)
        return FileKind("netcdf", path, f"variables: {sorted(names)[:10]}", info=info)


# Registered from above (this module sits at the bottom of the import layers and imports
# nothing of driftlog but its errors): ``driftlog.adapters`` adds its readers' ``can_open``
# probes and the NetCDF-3 size check when it is imported, and the package (``driftlog``'s
# ``__init__``) registers that import as a loader, which the first ``sniff`` runs: every
# process knows other models' files, whatever it imported before.
READER_PROBES = []  # (kind, can_open(path) -> bool), the readers of other models' files
CONTENT_CHECKS = []  # check(path): raises a DriftlogError for a NetCDF-3 file cut short
READER_LOADERS = []  # load(): registers probes and checks; each run once, by the first sniff


def register_reader(kind, can_open):
    """Let :func:`sniff` recognise another model's files (``driftlog.adapters`` does this)."""
    if all(k != kind for k, _ in READER_PROBES):
        READER_PROBES.append((kind, can_open))


def register_loader(load):
    """Have the first :func:`sniff` call ``load()``, which registers readers (``register_reader``).

    The package registers the import of ``driftlog.adapters``: without it a process that had
    not imported the adapters yet took a HEC-RAS file for "a NetCDF file of an unknown layout",
    a dfsu for "a binary file" and a truncated sww for another model's output.
    """
    if load not in READER_LOADERS:
        READER_LOADERS.append(load)


def _load_readers():
    while READER_LOADERS:
        load = READER_LOADERS.pop(0)  # popped first: a loader that sniffs does not recurse
        try:
            load()
        except ImportError:  # a reader's library missing: its files stay unknown
            pass


def _is_openfoam_case(p: Path) -> bool:
    return ((p / "system" / "controlDict").is_file() or (p / "constant" / "polyMesh").is_dir()
            or (p / "processor0").is_dir())


def _reader_of(path) -> str:
    """The first registered reader of other models' files that can open ``path``.

    Selafin, dfsu, rasters, HEC-RAS...: its kind, or '' when none can.
    """
    for kind, can_open in READER_PROBES:
        try:
            if can_open(path):
                return kind
        except Exception:  # noqa: BLE001 - a reader's probe must not break sniffing
            continue
    return ""


def sniff(path) -> FileKind:
    """What the file at ``path`` is (see the module's table of kinds); never raises."""
    _load_readers()
    p = Path(path)
    try:
        if not p.exists():
            return FileKind("missing", p)
        if p.is_dir():
            if _is_openfoam_case(p):
                return FileKind("openfoam", p)
            reader = _reader_of(p)
            return FileKind("model_output", p, reader, info={"reader": reader}) if reader \
                else FileKind("directory", p)
        size = p.stat().st_size
        if size == 0:
            return FileKind("empty", p)
        with open(p, "rb") as f:
            head = f.read(65536)
    except OSError as exc:
        return FileKind("missing" if isinstance(exc, FileNotFoundError) else "binary", p,
                        exc.strerror or str(exc))
    if head.startswith(NETCDF_MAGIC):
        fk = _netcdf_kind(p)
        if fk.kind in ("bad_netcdf", "netcdf"):  # an HDF5 or NetCDF file another reader opens
            reader = _reader_of(p)
            if reader:
                return FileKind("model_output", p, reader, info={"reader": reader})
        return fk
    reader = _reader_of(p)
    if reader:
        return FileKind("model_output", p, reader, info={"reader": reader})
    if p.suffix.lower() in MESH_SUFFIXES:
        return FileKind("mesh_file", p)
    if p.name == "controlDict":
        return FileKind("openfoam", p)
    if b"\0" in head:
        return FileKind("binary", p, "holds NUL bytes")
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if size > len(head) and exc.start > len(head) - 4:
            text = head[:exc.start].decode("utf-8")  # cut inside a character at the end
        else:
            return FileKind("binary", p, f"not UTF-8: byte 0x{head[exc.start]:02x} at offset "
                            f"{exc.start}")
    import tomllib

    if p.suffix.lower() == ".toml":
        return FileKind("scenario", p)
    try:
        tomllib.loads(text if size <= len(head) else p.read_text("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return FileKind("text", p)
    return FileKind("scenario", p)


def require(path, kinds, role: str, hint: str = "", error=InputFileError,
            expected: str = "") -> FileKind:
    """The kind of ``path`` if it is one of ``kinds``, else an ``InputFileError``.

    Parameters
    ----------
    path : path
    kinds : str or tuple of str
        Accepted kinds (see the module's table).
    role : str
        What the file is for, in the message (e.g. ``"trajectory file"``).
    hint : str
        Appended to the message (what to do instead).
    error : DriftlogError subclass
        The exception raised (default ``InputFileError``).
    expected : str
        What the file must be, in words (default: from ``kinds``).
    """
    kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    fk = sniff(path)
    if fk.kind in kinds:
        return fk
    expected = expected or (" or ".join(SHORT[k] for k in kinds) if len(kinds) <= 3 else
                            "a file driftlog reads")
    extra = hint or _HINTS.get((fk.kind, kinds[0]), "")
    raise error(f"{fk.path}: {fk.describe()}; the {role} must be {expected}"
                         + (f": {extra}" if extra else ""))


def _a(noun: str) -> str:
    return ("an " if noun[:1].lower() in "aeiou" else "a ") + noun


def read_text(path, role: str = "scenario file") -> str:
    """The UTF-8 text of a file, or one clear error.

    Missing, a directory, empty, binary, NetCDF, or not UTF-8 (with the offending byte's line
    and column): an ``InputFileError``.
    """
    p = Path(path)
    if p.is_dir():
        raise InputFileError(f"{p}: is a directory; the {role} must be a file"
                             + (f": {_HINTS[('directory', 'scenario')]}"
                                if role.startswith("scenario") else ""))
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise InputFileError(f"{p}: {role} not found") from None
    except OSError as exc:
        raise InputFileError(f"{p}: cannot read the {role} ({exc.strerror or exc})") from None
    if not data.strip():
        raise InputFileError(f"{p}: the {role} is empty ({len(data)} bytes)")
    binary = b"\0" in data[:65536]
    if data.startswith(NETCDF_MAGIC) or binary or p.suffix.lower() != ".toml":
        fk = sniff(p)  # another model's file (a dfsu, a LISFLOOD-FP .par...), a mesh, NetCDF
        if fk.kind not in ("scenario", "text", "binary"):
            raise InputFileError(f"{p}: {fk.describe()}, not {_a(role)} (a TOML text file)"
                                 + (f": {_HINTS.get((fk.kind, 'scenario'))}"
                                    if (fk.kind, "scenario") in _HINTS else ""))
    if binary:
        raise InputFileError(f"{p}: a binary file (NUL bytes), not {_a(role)} (a TOML text "
                             "file)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise InputFileError(f"{p}: the {role} is not UTF-8 text: byte 0x{data[exc.start]:02x} "
                             f"at line {line}, column {col}; save it as UTF-8") from None


def check_output(path, role: str = "output", inputs=(), suffixes=None, create=True) -> Path:
    """Check that ``path`` can be written before anything is computed.

    Refuses (``OutputPathError``): a path that is a directory, a parent that is a file, a
    folder that cannot be created or written, the same file as one of ``inputs``, a suffix not
    in ``suffixes``.  Creates the parent folder (unless ``create`` is false: then the nearest
    existing folder above must be writable).  Returns the path.

    ``inputs``: paths, or (path, what it is) pairs for the message (e.g. ``(flow, "the
    scenario's flow file ([flow] path)")``); one the run will write before it reads it (a
    solver flow not computed yet) counts by its path.
    """
    p = Path(path)
    if p.is_dir():
        raise OutputPathError(f"{p}: is a directory; the {role} must be a file path")
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise OutputPathError(f"{p}: the {role} must end in " + " or ".join(suffixes))
    for src in inputs:
        src, what = src if isinstance(src, tuple) else (src, "the input file itself")
        if src is not None and _same_file(p, src):
            raise OutputPathError(f"{p}: the {role} is {what}; write to another path")
    check_output_dir(p.parent, role, p, create=create)
    return p


def _same_file(a, b) -> bool:
    """Whether two paths name one file: the same file, or the same path if either is missing."""
    a, b = Path(a), Path(b)
    if a.exists() and b.exists():
        try:
            return os.path.samefile(a, b)
        except OSError:
            return False
    return a.resolve() == b.resolve()


def check_output_dir(folder, role: str = "output folder", for_file=None, create=True) -> Path:
    """Create ``folder`` if needed and check a file can be created in it (``OutputPathError``)."""
    d = Path(folder) if str(folder) else Path(".")
    what = f"{for_file}" if for_file is not None else f"{d}"
    for parent in [d, *d.parents]:
        if parent.exists():
            if not parent.is_dir():
                raise OutputPathError(f"{what}: cannot write the {role}: {parent} is a file, "
                                      "not a folder")
            if not create:
                ro = bool(os.statvfs(parent).f_flag & os.ST_RDONLY) if hasattr(os, "statvfs") \
                    else False
                if ro or not os.access(parent, os.W_OK | os.X_OK):
                    raise OutputPathError(f"{what}: cannot write the {role}: {parent} is not "
                                          "writable" + (" (read-only file system)" if ro else ""))
                return d
            break
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPathError(f"{what}: cannot create the folder {d} for the {role} "
                              f"({exc.strerror or exc})") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".driftlog-probe-", dir=d)
    except OSError as exc:
        raise OutputPathError(f"{what}: cannot write the {role} in {d} "
                              f"({exc.strerror or exc})") from None
    os.close(fd)
    os.remove(probe)
    return d


def temporary_name(path) -> Path:
    """Where :func:`atomic_output` writes before renaming: same folder, same suffix."""
    p = Path(path)
    return p.with_name(f".{p.stem}.tmp{os.getpid()}{p.suffix}")


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path beside ``path``; rename it to ``path`` if the block succeeds.

    On an exception (or Ctrl-C) the temporary file is removed and ``path`` is left as it was,
    so no truncated file ever carries the final name.
    """
    p = Path(path)
    tmp = temporary_name(p)
    try:
        yield tmp
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    if not tmp.exists():
        raise DriftlogError(f"{p}: nothing was written")
    os.replace(tmp, p)


def nothing_to_resume(path, what="partial output", start="the run starts from the beginning"):
    """Warn that ``--resume`` found no ``what`` at ``path`` (the CLI prints one line).

    The run starts afresh, as resumable tools do, but not silently: a ``DriftlogWarning``.
    """
    import warnings

    from driftlog.errors import DriftlogWarning

    warnings.warn(DriftlogWarning(f"--resume: no {what} found at {path}; {start}"),
                  stacklevel=3)


# --------------------------------------------------------------------- files a killed run left
def left_open(path):
    """Whether an HDF5 file is marked open for writing (left so by a killed process).

    Read from the superblock's file consistency flags (versions 2 and 3; netCDF-4 writes
    version 2: bit 0 write access, bit 2 SWMR); None for a file without them.  Opening such a
    file for writing may fail (HDF5 refuses a version-3 superblock so marked; HDF5 2.2 opens a
    version-2 one, unless this process already holds the file open for reading), and a failed
    open left an HDF5 file object behind: a later file that the system gave the same inode
    (the killed file's copy, once the killed file was removed) was taken by HDF5 for that
    file, and closing it crashed the process (``nc_close`` reporting the other's open objects;
    tests/test_coupling.py's killed run under pytest-xdist).
    """
    with open(path, "rb") as f:
        head = f.read(12)
    if len(head) < 12 or head[:8] != HDF5_SIGNATURE or head[8] < 2:
        return None
    return bool(head[11] & 0x05)


def reopen_partial(partial, storage=None, prepare=None):
    """Make a ``.partial`` netCDF-4 file writable again; True if a killed process had left it open.

    Such a file (:func:`left_open`) is copied to a fresh one (:func:`recover_killed`, which
    ``storage`` and ``prepare`` go to) without first trying to open it for writing: the
    trajectory writer's and the solver's resume (``driftlog.trajectory``,
    ``driftlog.solver.run``) and a coupled run's flow file call this before appending.
    """
    import netCDF4

    mark = left_open(partial)
    if not mark:  # no flags to read, or the file is open elsewhere in this process: try
        try:
            netCDF4.Dataset(partial, "a").close()
        except OSError:
            mark = True
    if mark:
        recover_killed(partial, storage, prepare)
    return bool(mark)


def recover_killed(partial, storage=None, prepare=None):
    """Copy a ``.partial`` netCDF-4 file left by a killed process into a fresh one, in place.

    HDF5 marks a file open for writing; after a SIGKILL the mark stays and the file can be
    read, but opening it for writing may fail (:func:`left_open`).  Everything readable is
    copied (the records, hits or snapshots up to the last flush), each variable with its own
    chunking and compression, or with ``storage(new dataset, variable)``'s ``createVariable``
    keywords where it returns them (the trajectory file's obs variables); ``prepare(new
    variable)`` is called on each variable created (a chunk cache).  The old file is kept as
    ``.partial.killed`` until the copy is complete, and put back if the copy fails.
    """
    import netCDF4

    partial = Path(partial)
    old = partial.with_name(partial.name + ".killed")
    os.replace(partial, old)
    tmp = partial.with_name(partial.name + ".tmp")
    try:
        with netCDF4.Dataset(old) as a, netCDF4.Dataset(tmp, "w", format="NETCDF4") as b:
            a.set_auto_maskandscale(False)
            b.setncatts({k: a.getncattr(k) for k in a.ncattrs()})
            for name, dim in a.dimensions.items():
                b.createDimension(name, None if dim.isunlimited() else len(dim))
            for name, var in a.variables.items():
                attrs = {k: var.getncattr(k) for k in var.ncattrs() if k != "_FillValue"}
                fill = var.getncattr("_FillValue") if "_FillValue" in var.ncattrs() else None
                kw = storage(b, var) if storage is not None else None
                v = b.createVariable(name, var.dtype, var.dimensions, fill_value=fill,
                                     **(_storage_of(var) if kw is None else kw))
                if prepare is not None:
                    prepare(v)
                v.setncatts(attrs)
                v.set_auto_maskandscale(False)
                if var.size:
                    v[:] = var[:]
    except BaseException:  # unreadable (not netCDF-4), interrupted: the file as it was
        with contextlib.suppress(OSError):
            tmp.unlink()
        os.replace(old, partial)
        raise
    os.replace(tmp, partial)
    os.remove(old)


def _storage_of(var):
    """The chunking and compression of a variable, as ``createVariable`` keywords."""
    kw = {}
    chunks = var.chunking()
    if isinstance(chunks, list):
        kw["chunksizes"] = chunks
    f = var.filters() or {}
    if f.get("zlib"):
        kw.update(zlib=True, complevel=f.get("complevel", 4))
    if f.get("shuffle"):
        kw["shuffle"] = True
    return kw
