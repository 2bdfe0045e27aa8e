import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_subpackage_is_listed_in_pyproject():
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(setuptools["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for p in (ROOT / "driftlog").rglob("__init__.py")}
    found |= {"driftlog.adapters." + ".".join(p.parent.relative_to(ROOT / "adapters").parts)
              for p in (ROOT / "adapters").rglob("__init__.py") if p.parent != ROOT / "adapters"}
    found.add("driftlog.adapters")
    assert found <= listed, f"add {sorted(found - listed)} to [tool.setuptools] packages"


def test_adapters_import_as_driftlog_adapters_only():
    code = ("import importlib.util, driftlog.adapters as a; "
            "assert a.__name__ == 'driftlog.adapters'; "
            "import sys; sys.path[:] = [p for p in sys.path if p not in ('', '.')]; "
            "print(importlib.util.find_spec('adapters') is None)")
    out = subprocess.run([sys.executable, "-c", code], cwd="/", capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"
