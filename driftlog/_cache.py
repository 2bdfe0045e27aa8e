"""Where numba keeps driftlog's compiled kernels: a folder keyed by the package's source.

numba keys a cached kernel on its own source file only (its path, size and time stamp).  A
kernel that inlines or calls code from another module (``solver.fluxes.edge_fluxes`` inlines
the Riemann solvers, the boundaries and the reconstruction) would load stale machine code
after that other module changed: a silently wrong result.  Pointing ``NUMBA_CACHE_DIR`` at a
folder named by a hash of every source file of driftlog (and its adapters) makes any change
of the source start from a fresh cache.  Set before numba is imported (numba reads it then);
a ``NUMBA_CACHE_DIR`` the user set wins.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import sys
from pathlib import Path

__all__ = ["set_numba_cache_dir", "KEEP", "STALE_DAYS"]

KEEP = 3  # cache folders of earlier source versions kept (switching branches back and forth)
STALE_DAYS = 7  # ... and any folder used in the last week (another checkout may be using it)


_IMPORT = re.compile(r"^\s*(?:from|import)\s+(driftlog(?:\.\w+)*|\.+\w*(?:\.\w+)*)",
                     re.MULTILINE)


def _module_files(package: Path) -> dict[str, Path]:
    """Module name -> file for the package (and a source checkout's adapters beside it)."""
    roots = [(package, "driftlog")]
    adapters = package.parent / "adapters"
    if not (package / "adapters").is_dir() and adapters.is_dir():
        roots.append((adapters, "driftlog.adapters"))
    out = {}
    for root, name in roots:
        for f in root.rglob("*.py"):
            parts = list(f.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([name, *parts])] = f
    return out


def _source_hash(package: Path) -> str:
    """Hash of the modules that hold numba code and of every driftlog module they import.

    Only those can change a compiled kernel (numba freezes the globals it reads, such as column
    constants, into the machine code); editing the command line or the plots keeps the cache.
    """
    files = _module_files(package)
    text = {m: f.read_text("utf-8", "replace") for m, f in files.items()}
    todo = [m for m, t in text.items() if "numba" in t]
    seen = set()
    while todo:
        m = todo.pop()
        if m in seen or m == "driftlog":  # the package's __init__ only re-exports
            continue
        seen.add(m)
        is_pkg = files[m].name == "__init__.py"
        for ref in _IMPORT.findall(text[m]):
            if ref.startswith("."):  # relative: resolve against the module's package
                level = len(ref) - len(ref.lstrip("."))
                base = m.split(".") if is_pkg else m.split(".")[:-1]
                base = base[:len(base) - (level - 1)]
                ref = ".".join(base + ([ref.lstrip(".")] if ref.lstrip(".") else []))
            while ref and ref not in files:  # "from driftlog.x import y": the module x
                ref = ref.rpartition(".")[0]
            if ref:
                todo.append(ref)
    h = hashlib.sha1()
    for m in sorted(seen):
        h.update(m.encode())
        h.update(text[m].encode())
    return h.hexdigest()[:16]


def set_numba_cache_dir(package: Path) -> str | None:
    """Set ``NUMBA_CACHE_DIR`` to ``~/.cache/driftlog/numba/<source hash>``; the folder or None.

    Does nothing when the variable is set already, or when no cache folder can be written
    (numba then caches beside the sources, as it does by default).  numba reads the variable
    once, when it is imported: where it was imported first (``import numba`` before ``import
    driftlog``, as in a notebook or a script that times kernels), its configuration is set
    too, or the kernels would go to numba's default cache beside the sources, keyed on each
    file alone, and a kernel that inlines another module's code could load stale machine code.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    try:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
        base = base / "driftlog" / "numba"
        folder = base / _source_hash(package)
        folder.mkdir(parents=True, exist_ok=True)
        if not os.access(folder, os.W_OK):
            return None
        os.utime(folder)  # most recently used first when pruning
        old = sorted((d for d in base.iterdir() if d.is_dir() and d != folder),
                     key=lambda d: d.stat().st_mtime, reverse=True)
        now = folder.stat().st_mtime
        for d in old[KEEP:]:
            if now - d.stat().st_mtime > STALE_DAYS * 86400:
                shutil.rmtree(d, ignore_errors=True)
    except OSError:
        return None
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.CACHE_DIR = str(folder)
    return str(folder)
