"""scripts/numba_perf_map.py: the perf map names numba's compiled functions at their addresses."""

import ctypes
import importlib.util
from pathlib import Path

import numba as nb
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "numba_perf_map.py"


def _tool():
    spec = importlib.util.spec_from_file_location("numba_perf_map", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@nb.njit  # compiled in this process (no disk cache): its module can be listed
def _perf_probe(x):
    return 3.0 * x + 1.25


def test_map_entry_is_the_compiled_function(tmp_path):
    assert _perf_probe(1.0) == 4.25
    path = _tool().write_perf_map(tmp_path / "perf-1.map")
    rows = [line.split(" ", 2) for line in Path(path).read_text().splitlines()]
    starts = [int(r[0], 16) for r in rows]
    assert starts == sorted(starts) and len(set(starts)) == len(starts)
    # each size reaches the next start at most: the ranges do not overlap
    ends = [s + int(r[1], 16) for s, r in zip(starts, rows, strict=True)]
    assert all(e <= n for e, n in zip(ends[:-1], starts[1:], strict=True))
    mine = [r for r in rows if r[2].startswith("_ZN13test_perf_map11_perf_probe")]
    assert len(mine) == 1
    # call the address as numba's internal calling convention has it (status, result pointer,
    # exception slot, arguments): it is the function, not merely a name near it
    proto = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                             ctypes.c_void_p, ctypes.c_double)
    fn = proto(int(mine[0][0], 16))
    out = ctypes.c_double(0.0)
    exc = ctypes.c_void_p(0)
    assert fn(ctypes.byref(out), ctypes.addressof(exc), 2.0) == 0
    assert out.value == 7.25


def test_refuses_a_missing_script(capsys):
    assert _tool().main(["no/such/script.py"]) == 2
    assert "no script 'no/such/script.py'" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [[], ["--help"]])
def test_help(argv, capsys):
    assert _tool().main(argv) == (2 if not argv else 0)
    assert "perf record" in capsys.readouterr().out


def test_dead_weak_proxies_are_passed_over(tmp_path):
    """gc lists weak proxies too; one whose object is gone must not stop the map."""
    import gc
    import weakref

    class Thing:
        pass

    t = Thing()
    proxy = weakref.proxy(t)
    del t
    gc.collect()
    assert any(o is proxy for o in gc.get_objects())  # listed, its object gone
    _perf_probe(1.0)
    path = _tool().write_perf_map(tmp_path / "perf-2.map")
    assert "_perf_probe" in Path(path).read_text()
