"""OpenFOAM file I/O: the FoamFile header, dictionaries, lists and fields, ascii and binary, gzip.

A parser of our own rather than a dependency: it needs only numpy (and numba for one loop),
reads the subset that mesh and field files use (``labelList``, ``vectorField``, ``faceList``,
``faceCompactList``, ``polyBoundaryMesh``, ``vol*Field`` internal fields, uniform lists
``N{v}``), and parses ascii lists with one ``numpy.fromstring`` call, so a 1e6-cell mesh reads
in seconds (benchmarks/import_benchmark.py).  Binary lists honour the ``arch`` header
(``label=32|64``, ``scalar=32|64``); ``name.gz`` is read where ``name`` is absent.

Writing (``write_foam_file``) produces ascii files that OpenFOAM v1912 reads (the case writer of
``driftlog.adapters.openfoam_case``).
"""

from __future__ import annotations

import gzip
import io
import re
from pathlib import Path

import numba as nb
import numpy as np

from driftlog.errors import FlowFileError

__all__ = ["FoamFile", "read_foam", "foam_path", "parse_dict", "read_label_list",
           "read_points", "read_faces", "read_boundary", "read_internal_field",
           "write_foam_file", "format_list", "format_faces", "write_polymesh_files"]

_TOKEN = re.compile(rb'\s+|//[^\n]*|/\*.*?\*/|"[^"]*"|[{}();\[\]]|[^\s{}();\[\]"]+', re.S)
_SKIP = re.compile(rb'(?:\s+|//[^\n]*|/\*.*?\*/)*', re.S)
_PARENS_TO_SPACE = bytes.maketrans(b"()", b"  ")
_HEADER = re.compile(rb'FoamFile\s*\{(.*?)\}', re.S)


def foam_path(path) -> Path | None:
    """``path`` or ``path.gz``, whichever exists (None if neither)."""
    p = Path(path)
    if p.is_file():
        return p
    gz = p.with_name(p.name + ".gz")
    return gz if gz.is_file() else None


class FoamFile:
    """A file's header (``FoamFile`` dictionary) and its bytes after the header."""

    def __init__(self, path, data: bytes):
        self.path = Path(path)
        m = _HEADER.search(data[:4096])
        if m is None:
            raise FlowFileError(f"{self.path}: not an OpenFOAM file (no FoamFile header)")
        self.header = parse_dict(m.group(1), self.path)
        self.body = data
        self.start = m.end()
        self.binary = self.header.get("format", "ascii") == "binary"
        arch = str(self.header.get("arch", "label=32;scalar=64"))
        lab = re.search(r"label=(\d+)", arch)
        sca = re.search(r"scalar=(\d+)", arch)
        self.label = np.dtype("<i8" if lab and lab.group(1) == "64" else "<i4")
        self.scalar = np.dtype("<f4" if sca and sca.group(1) == "32" else "<f8")
        if "MSB" in arch:
            self.label, self.scalar = self.label.newbyteorder(">"), self.scalar.newbyteorder(">")

    @property
    def cls(self) -> str:
        """The header's class (volScalarField, faceCompactList...)."""
        return str(self.header.get("class", ""))

    def error(self, what) -> FlowFileError:
        """An error naming this file."""
        return FlowFileError(f"{self.path}: {what}")


def read_foam(path, required=True) -> FoamFile | None:
    """Read an OpenFOAM file (``path`` or ``path.gz``)."""
    p = foam_path(path)
    if p is None:
        if required:
            raise FlowFileError(f"{path}: file not found (nor {Path(path).name}.gz)")
        return None
    try:
        if p.suffix == ".gz":
            with gzip.open(p, "rb") as f:
                data = f.read()
        else:
            data = p.read_bytes()
    except (OSError, EOFError) as exc:
        raise FlowFileError(f"{p}: cannot read ({exc})") from None
    return FoamFile(p, data)


# --------------------------------------------------------------------- dictionaries
def _tokens(text: bytes):
    for m in _TOKEN.finditer(text):
        t = m.group(0)
        if t[:1].isspace() or t.startswith((b"//", b"/*")):
            continue
        yield t.decode("latin-1")


def _value(tokens):
    if len(tokens) == 1:
        t = tokens[0]
        try:
            return int(t)
        except ValueError:
            pass
        try:
            return float(t)
        except ValueError:
            return t.strip('"')
    return tokens


def parse_dict(text: bytes, path="<dict>") -> dict:
    """Parse an OpenFOAM dictionary: ``key value;`` and ``key { ... }`` (nested).

    Values come back as numbers, strings or token lists.
    """
    toks = list(_tokens(text))
    out, _ = _parse_entries(toks, 0, path)
    return out


def _parse_entries(toks, i, path):
    out = {}
    while i < len(toks) and toks[i] != "}":
        key = toks[i].strip('"')
        i += 1
        if i < len(toks) and toks[i] == "{":
            out[key], i = _parse_entries(toks, i + 1, path)
            i += 1  # the closing brace
            continue
        vals, depth = [], 0
        while i < len(toks) and not (toks[i] == ";" and depth == 0):
            if toks[i] in "([":
                depth += 1
            elif toks[i] in ")]":
                depth -= 1
            vals.append(toks[i])
            i += 1
        i += 1  # the semicolon
        out[key] = _value(vals)
    return out, i


# --------------------------------------------------------------------- lists
def _skip(data, pos):
    return _SKIP.match(data, pos).end()


def _read_count(f: FoamFile, pos):
    """The list length at ``pos``; returns (n, position after it)."""
    pos = _skip(f.body, pos)
    m = re.compile(rb"\d+").match(f.body, pos)
    if m is None:
        raise f.error(f"expected a list length at byte {pos}, found "
                      f"{f.body[pos:pos + 20]!r}")
    return int(m.group(0)), m.end()


def _read_list(f: FoamFile, pos, dtype, ncomp, n_expected=None):
    """A list of n items of ``ncomp`` numbers at ``pos``: ``N(...)``, ``N{v}`` or binary.

    Returns (array of shape (n,) or (n, ncomp), position after the list).
    """
    n, pos = _read_count(f, pos)
    if n_expected is not None and n != n_expected:
        raise f.error(f"list of {n} values where {n_expected} were expected (field and mesh "
                      "sizes differ)")
    pos = _skip(f.body, pos)
    opener = f.body[pos:pos + 1]
    shape = (n,) if ncomp == 1 else (n, ncomp)
    if opener == b"{":  # uniform list N{value}
        end = f.body.index(b"}", pos)
        vals = np.fromstring(f.body[pos + 1:end].translate(None, b"()").decode(),
                             dtype=np.float64, sep=" ")
        return np.broadcast_to(vals.astype(dtype), shape).copy(), end + 1
    if opener != b"(":
        raise f.error(f"expected '(' or '{{' after the list length {n} at byte {pos}")
    pos += 1
    if f.binary and n > 0:
        native = f.label if np.dtype(dtype).kind == "i" else f.scalar
        nbytes = n * ncomp * native.itemsize
        raw = f.body[pos:pos + nbytes]
        if len(raw) < nbytes:
            raise f.error(f"truncated binary list: {len(raw)} of {nbytes} bytes")
        arr = np.frombuffer(raw, dtype=native).astype(dtype).reshape(shape)
        end = pos + nbytes
        if f.body[end:end + 1] != b")":
            raise f.error(f"binary list of {n} items does not end with ')' (wrong arch "
                          f"'{f.header.get('arch')}'?)")
        return arr, end + 1
    if n == 0:
        end = f.body.index(b")", pos)
        return np.empty(shape, dtype=dtype), end + 1
    if ncomp == 1:
        end = f.body.index(b")", pos)
        text = f.body[pos:end]
    else:
        end = _nth_close(f, pos, n)
        text = f.body[pos:end].translate(None, b"()")
    arr = np.fromstring(text.decode("latin-1"), dtype=np.float64 if np.dtype(dtype).kind == "f"
                        else np.int64, sep=" ")
    if arr.size != n * ncomp:
        raise f.error(f"list of {n} items holds {arr.size} numbers, expected {n * ncomp}")
    return arr.astype(dtype, copy=False).reshape(shape), end + 1


def _nth_close(f, pos, n):
    """Position of the ')' closing a list of n parenthesised items that starts at pos."""
    buf = np.frombuffer(f.body, dtype=np.uint8, offset=pos)
    closes = np.flatnonzero(buf == ord(")"))
    if closes.size <= n:
        raise f.error(f"truncated list: fewer than {n} items")
    return pos + int(closes[n])


def read_label_list(path, f: FoamFile | None = None) -> np.ndarray:
    """A ``labelList`` file (owner, neighbour, cellProcAddressing...) as int64."""
    f = f or read_foam(path)
    arr, _ = _read_list(f, f.start, np.int64, 1)
    return arr


def read_points(path) -> np.ndarray:
    """A ``vectorField`` file (polyMesh/points) as (n, 3) float64."""
    f = read_foam(path)
    arr, _ = _read_list(f, f.start, np.float64, 3)
    return arr


@nb.njit(cache=True)
def _decode_face_list(seq, n):
    offsets = np.empty(n + 1, np.int64)
    flat = np.empty(seq.size - n, np.int64)
    k = 0
    m = 0
    offsets[0] = 0
    for i in range(n):
        c = seq[k]
        k += 1
        for j in range(c):
            flat[m + j] = seq[k + j]
        k += c
        m += c
        offsets[i + 1] = m
    return offsets, flat[:m]


def read_faces(path):
    """polyMesh/faces (``faceList`` or ``faceCompactList``): (offsets (n+1,), labels)."""
    f = read_foam(path)
    if f.cls == "faceCompactList":
        offsets, pos = _read_list(f, f.start, np.int64, 1)
        flat, _ = _read_list(f, pos, np.int64, 1)
        if offsets.size == 0 or offsets[-1] != flat.size:
            raise f.error("faceCompactList offsets do not match its labels")
        return offsets, flat
    if f.binary:
        raise f.error("binary faceList is not supported (OpenFOAM writes faceCompactList)")
    n, pos = _read_count(f, f.start)
    pos = _skip(f.body, pos)
    if f.body[pos:pos + 1] != b"(":
        raise f.error("expected '(' after the number of faces")
    end = _nth_close(f, pos + 1, n)
    text = f.body[pos + 1:end].translate(_PARENS_TO_SPACE).decode("latin-1")
    seq = np.fromstring(text, dtype=np.int64, sep=" ")
    if seq.size < 2 * n:
        raise f.error(f"faceList of {n} faces is truncated")
    return _decode_face_list(seq, n)


def read_boundary(path) -> list[dict]:
    """polyMesh/boundary as a list of patches: dicts with name, type, nFaces, startFace."""
    f = read_foam(path)
    toks = list(_tokens(f.body[f.start:]))
    try:
        n = int(toks[0])
        assert toks[1] == "("
    except (IndexError, ValueError, AssertionError):
        raise f.error("not a polyBoundaryMesh (expected 'N (' after the header)") from None
    patches, i = [], 2
    for _ in range(n):
        name = toks[i]
        if toks[i + 1] != "{":
            raise f.error(f"patch {name!r} is not followed by '{{'")
        d, i = _parse_entries(toks, i + 2, f.path)
        i += 1
        d["name"] = name
        for k in ("nFaces", "startFace"):
            if not isinstance(d.get(k), int):
                raise f.error(f"patch {name!r} lacks {k}")
        patches.append(d)
    return patches


def read_internal_field(path, n_cells: int, required=True):
    """The internal field of a vol field file: (n,) scalars or (n, 3) vectors, float64.

    ``uniform v`` is broadcast to ``n_cells``; a list of another length is an error.
    """
    f = read_foam(path, required=required)
    if f is None:
        return None
    m = re.compile(rb"\binternalField\b").search(f.body, f.start)
    if m is None:
        raise f.error("no internalField entry")
    pos = _skip(f.body, m.end())
    word = re.compile(rb"[A-Za-z<>]+").match(f.body, pos)
    if word is None:
        raise f.error(f"internalField is neither uniform nor nonuniform at byte {pos}")
    kind = word.group(0)
    pos = word.end()
    vector = "Vector" in f.cls
    if kind == b"uniform":
        end = f.body.index(b";", pos)
        vals = np.fromstring(f.body[pos:end].translate(None, b"()").decode(), dtype=np.float64,
                             sep=" ")
        if vals.size != (3 if vector else 1):
            raise f.error(f"uniform internalField has {vals.size} components")
        shape = (n_cells, 3) if vector else (n_cells,)
        return np.broadcast_to(vals if vector else vals[0], shape).copy()
    if kind != b"nonuniform":
        raise f.error(f"internalField is {kind.decode()!r}, expected uniform or nonuniform")
    pos = _skip(f.body, pos)
    lt = re.compile(rb"List<(\w+)>").match(f.body, pos)
    if lt is None:
        raise f.error("nonuniform internalField without List<type>")
    typ = lt.group(1).decode()
    ncomp = {"scalar": 1, "vector": 3}.get(typ)
    if ncomp is None:
        raise f.error(f"internalField of type List<{typ}> is not supported (scalar, vector)")
    arr, _ = _read_list(f, lt.end(), np.float64, ncomp, n_expected=n_cells)
    return arr


# --------------------------------------------------------------------- writing
_BANNER = """/*--------------------------------*- C++ -*----------------------------------*\\
  written by driftlog (driftlog.adapters.openfoam_case)
\\*---------------------------------------------------------------------------*/
"""


def write_foam_file(path, cls: str, obj: str, body: str, location: str | None = None,
                    note: str | None = None):
    """Write an ascii OpenFOAM file with its FoamFile header."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    head = ["FoamFile", "{", "    version     2.0;", "    format      ascii;",
            f"    class       {cls};"]
    if note:
        head.append(f'    note        "{note}";')
    if location:
        head.append(f'    location    "{location}";')
    head += [f"    object      {obj};", "}", ""]
    path.write_text(_BANNER + "\n".join(head) + "\n" + body + "\n")
    return path


def format_list(values, fmt="%.17g") -> str:
    r"""An ascii OpenFOAM list: ``N\\n(\\n...\\n)``; rows of a 2-D array become ``(a b c)``."""
    a = np.asarray(values)
    buf = io.StringIO()
    if a.ndim == 1:
        np.savetxt(buf, a, fmt=fmt if a.dtype.kind == "f" else "%d")
    else:
        np.savetxt(buf, a, fmt=fmt if a.dtype.kind == "f" else "%d", delimiter=" ",
                   header="", comments="")
        lines = buf.getvalue().splitlines()
        buf = io.StringIO("".join(f"({line})\n" for line in lines))
    return f"{a.shape[0]}\n(\n{buf.getvalue()})"


def format_faces(faces) -> str:
    """An ascii OpenFOAM faceList body: one ``n(a b c ...)`` line per face."""
    return "\n".join(f"{len(f)}({' '.join(map(str, f))})" for f in faces)


def write_polymesh_files(folder, points, faces, owner, neighbour, patches, n_cells):
    """Write ``points``, ``faces``, ``owner``, ``neighbour`` and ``boundary`` of a polyMesh.

    ``faces`` are node lists, internal faces first (ordered by owner then neighbour), then
    each patch's; ``patches`` are (name, type, start face, face count).  Returns the patch
    names in order.
    """
    folder = Path(folder)
    note = (f"nPoints:{len(points)}  nCells:{n_cells}  nFaces:{len(faces)}  "
            f"nInternalFaces:{len(neighbour)}")
    write_foam_file(folder / "points", "vectorField", "points", format_list(points),
                    "constant/polyMesh")
    write_foam_file(folder / "faces", "faceList", "faces",
                    f"{len(faces)}\n(\n{format_faces(faces)}\n)", "constant/polyMesh")
    write_foam_file(folder / "owner", "labelList", "owner", format_list(np.asarray(owner)),
                    "constant/polyMesh", note=note)
    write_foam_file(folder / "neighbour", "labelList", "neighbour",
                    format_list(np.asarray(neighbour)), "constant/polyMesh", note=note)
    body = [f"{len(patches)}", "("]
    for name, typ, start, count in patches:
        body += [f"    {name}", "    {", f"        type {typ};",
                 f"        nFaces {count};", f"        startFace {start};", "    }"]
    body.append(")")
    write_foam_file(folder / "boundary", "polyBoundaryMesh", "boundary", "\n".join(body),
                    "constant/polyMesh")
    return [p[0] for p in patches]
