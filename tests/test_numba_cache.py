"""numba's cache folder follows the source of the modules that compiled kernels depend on."""

import os
import shutil
from pathlib import Path

from driftlog import _cache

PACKAGE = Path(__file__).resolve().parent.parent / "driftlog"


def _copy_tree(tmp_path):
    dst = tmp_path / "src" / "driftlog"
    shutil.copytree(PACKAGE, dst, ignore=shutil.ignore_patterns("__pycache__"))
    adapters = PACKAGE.parent / "adapters"
    if adapters.is_dir():
        shutil.copytree(adapters, dst.parent / "adapters",
                        ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def test_hash_changes_with_a_module_a_kernel_calls(tmp_path):
    pkg = _copy_tree(tmp_path)
    h0 = _cache._source_hash(pkg)
    assert _cache._source_hash(pkg) == h0  # deterministic
    # the Riemann solver's machine code is in the cached flux kernel of another file: a change
    # must show
    riemann = pkg / "solver" / "riemann.py"
    riemann.write_text(riemann.read_text() + "\n# changed\n")
    h1 = _cache._source_hash(pkg)
    assert h1 != h0
    # the command line holds no kernel and no kernel imports it: the cache stays
    cli = pkg / "cli" / "flows.py"
    cli.write_text(cli.read_text() + "\n# changed\n")
    assert _cache._source_hash(pkg) == h1


def test_cache_dir_set_once_and_user_value_wins(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    folder = _cache.set_numba_cache_dir(PACKAGE)
    assert folder is not None and Path(folder).is_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == folder
    assert Path(folder).name == _cache._source_hash(PACKAGE)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert _cache.set_numba_cache_dir(PACKAGE) is None
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine")


def test_first_run_announces_the_multi_threaded_kernels(tmp_path, monkeypatch):
    # a run of 2,048 logs or more compiles the tracker's parallel kernels the first time, for
    # minutes (652 CPU s measured on a 1e4-log Malpasset run): said once, not after they are
    # cached
    import io

    from driftlog import _numba

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    out = io.StringIO()
    assert _numba.announce_compile(["tracking", "contacts"], out, many=True) == 35
    said = out.getvalue()
    assert "about 35 s (tracking, contacts)" in said and "multi-threaded" in said
    out = io.StringIO()
    assert _numba.announce_compile(["tracking"], out) == 20
    assert "multi-threaded" not in out.getvalue()
    # another checkout of the same sources (the same NUMBA_CACHE_DIR, keyed on their hash)
    # compiled its own kernels: numba keys them on each source folder's path, so this one
    # still compiles and says so
    from numba.core.caching import _CacheLocator

    here = Path(_numba.__file__).resolve().parent
    other = tmp_path / _CacheLocator.get_suitable_cache_subpath("/elsewhere/driftlog/x.py")
    other.mkdir()
    (other / "physics.rhs_kernel-497.py311.nbi").touch()
    out = io.StringIO()
    assert _numba.announce_compile(["tracking"], out) == 20
    # the kernels cached (numba's index files, in numba's folders for these sources)
    sub = tmp_path / _CacheLocator.get_suitable_cache_subpath(str(here / "x.py"))
    sub.mkdir()
    (sub / "physics.rhs_kernel-497.py311.nbi").touch()
    sub = tmp_path / _CacheLocator.get_suitable_cache_subpath(str(here / "contact" / "x.py"))
    sub.mkdir()
    (sub / "geometry.capsule_gap-12.py311.nbi").touch()
    out = io.StringIO()
    assert _numba.announce_compile(["tracking", "contacts"], out, many=True) == 0
    assert " s (" not in out.getvalue() and "multi-threaded" in out.getvalue()
    sub = tmp_path / _CacheLocator.get_suitable_cache_subpath(str(here / "x.py"))
    (sub / "clock_kernel.per_log_mesh_advance_parallel-146.py311.nbi").touch()
    out = io.StringIO()
    assert _numba.announce_compile(["tracking", "contacts"], out, many=True) == 0
    assert out.getvalue() == ""


def test_numba_imported_first_still_caches_in_the_source_keyed_folder(tmp_path):
    # numba reads NUMBA_CACHE_DIR when it is imported: a script or notebook that imports numba
    # before driftlog would otherwise cache driftlog's kernels beside their sources, keyed on
    # each file alone (a kernel inlining another module's changed code then loads stale)
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    code = ("import os, numba, driftlog; from driftlog.flow import sample_mesh_kernel as k; "
            "print(numba.config.CACHE_DIR); print(os.environ['NUMBA_CACHE_DIR']); "
            "print(k.serial._cache._cache_path)")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True, cwd=PACKAGE.parent).stdout.split()
    folder = tmp_path / "driftlog" / "numba" / _cache._source_hash(PACKAGE)
    assert out[0] == out[1] == str(folder)
    assert Path(out[2]).is_relative_to(folder)
