"""OpenFOAM case directories as the two readers see them (``openfoam``, ``openfoam_vof``).

A case's written time directories, serial or decomposed (``FoamCase``), the arrays of a
``polyMesh`` directory (``PolyMesh``), and whether a case ran (``check_ran``).
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np

from driftlog.errors import FlowFileError

from .foam_io import foam_path, read_boundary, read_faces, read_label_list, read_points

__all__ = ["NUMBER", "clean_case", "is_openfoam_case", "time_dirs", "processor_dirs", "PolyMesh",
           "FoamCase", "check_ran"]

NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def is_openfoam_case(path) -> bool:
    """Whether a directory looks like an OpenFOAM case."""
    p = Path(path)
    return p.is_dir() and ((p / "system" / "controlDict").is_file()
                           or (p / "constant" / "polyMesh").is_dir()
                           or (p / "processor0").is_dir())


def time_dirs(folder: Path):
    """(value, name) of the time directories in a folder, sorted by time."""
    out = []
    if not folder.is_dir():
        return out
    for d in folder.iterdir():
        if d.is_dir() and NUMBER.match(d.name):
            out.append((float(d.name), d.name))
    return sorted(out)


def processor_dirs(case: Path):
    dirs = [d for d in case.iterdir() if d.is_dir() and re.fullmatch(r"processor\d+", d.name)]
    return sorted(dirs, key=lambda d: int(d.name[9:]))


class PolyMesh:
    """The arrays of a polyMesh directory (points, faces, owner, boundary), read once."""

    def __init__(self, folder: Path):
        self.folder = folder
        if not folder.is_dir():
            raise FlowFileError(f"{folder}: no polyMesh directory (run blockMesh first?)")
        for name in ("points", "faces", "owner", "boundary"):
            if foam_path(folder / name) is None:
                raise FlowFileError(f"{folder}: polyMesh file {name!r} is missing")
        self.points = read_points(folder / "points")
        self.offsets, self.labels = read_faces(folder / "faces")
        self.owner = read_label_list(folder / "owner")
        self.patches = read_boundary(folder / "boundary")
        self.n_faces = self.offsets.size - 1
        self.n_cells = int(self.owner.max()) + 1 if self.owner.size else 0
        if self.owner.size != self.n_faces:
            raise FlowFileError(f"{folder}: owner has {self.owner.size} entries for "
                                f"{self.n_faces} faces")
        self._neighbour = None

    @property
    def neighbour(self):
        if self._neighbour is None:
            self._neighbour = read_label_list(self.folder / "neighbour")
            self.n_cells = max(self.n_cells, int(self._neighbour.max(initial=-1)) + 1)
        return self._neighbour

    def face_table(self, faces):
        """Padded (n, kmax) node table of the given faces, and their node counts."""
        start, stop = self.offsets[faces], self.offsets[faces + 1]
        count = stop - start
        kmax = int(count.max(initial=0))
        k = np.arange(kmax)
        idx = start[:, None] + np.minimum(k[None, :], np.maximum(count[:, None] - 1, 0))
        table = self.labels[idx]
        table[k[None, :] >= count[:, None]] = -1
        return table, count

    def patch_faces(self, types=None, names=None):
        out = []
        for p in self.patches:
            if (types is None or p.get("type") in types) and (names is None or p["name"] in names):
                out.append(np.arange(p["startFace"], p["startFace"] + p["nFaces"]))
        return np.concatenate(out) if out else np.empty(0, np.int64)


class FoamCase:
    """An OpenFOAM case directory: its time directories, serial or decomposed.

    Parameters
    ----------
    path : path
        The case directory.
    decomposed : bool or None
        Read the ``processor*`` directories (True), the case root (False), or whichever has
        more written times holding ``field`` (None).
    field : str
        A field that a written time must hold to count.
    """

    def __init__(self, path, decomposed=None, field="h"):
        self.path = Path(path)
        if not self.path.is_dir():
            raise FlowFileError(f"{self.path}: OpenFOAM case directory not found")
        self.processors = processor_dirs(self.path)
        self.field = field
        root_times = [t for t in time_dirs(self.path)
                      if foam_path(self.path / t[1] / field)]
        proc_times = []
        if self.processors:
            proc_times = [t for t in time_dirs(self.processors[0])
                          if foam_path(self.processors[0] / t[1] / field)]
        if decomposed is None:
            decomposed = bool(self.processors) and len(proc_times) > len(root_times)
        if decomposed and not self.processors:
            raise FlowFileError(f"{self.path}: decomposed = True but there are no processor* "
                                "directories")
        self.decomposed = bool(decomposed)
        self.time_entries = proc_times if self.decomposed else root_times
        if not self.time_entries:
            where = self.processors[0] if self.decomposed else self.path
            others = [n for _, n in time_dirs(where)]
            raise FlowFileError(
                f"{where}: no time directory holds the field {field!r} " +
                (f"(time directories: {others}) " if others else "(no time directories) ") +
                "— the case never ran, or wrote other fields")

    @property
    def times(self) -> np.ndarray:
        """The written times (s)."""
        return np.array([t for t, _ in self.time_entries])

    def time_name(self, i) -> str:
        """The directory name of written time i."""
        return self.time_entries[i][1]

    def parts(self):
        """The folders that hold meshes and fields: the processors, or the case itself."""
        return self.processors if self.decomposed else [self.path]


def check_ran(case: FoamCase, solver):
    """Ran: more than one written time, or a time written by a solver (with uniform/time)."""
    part = case.parts()[0]
    written = any((part / name / "uniform" / "time").is_file() for _, name in case.time_entries)
    if len(case.time_entries) < 2 and not written:
        names = [n for _, n in case.time_entries]
        raise FlowFileError(f"{part}: only initial fields (time directory {names[0]}, not "
                            f"written by a solver): the case never ran; run {solver} first, "
                            "or pass allow_initial_only=True to import the initial fields")


def clean_case(case: Path):
    """Remove the results of an earlier run: time and processor directories, logs."""
    if not case.is_dir():
        return
    for d in case.iterdir():
        if d.is_dir() and (NUMBER.match(d.name) or d.name.startswith("processor")):
            shutil.rmtree(d)
        elif d.is_file() and d.name.startswith("log."):
            d.unlink()
    poly = case / "constant" / "polyMesh"
    if poly.is_dir():
        shutil.rmtree(poly)
