"""The import structure of driftlog: no circle, and no module importing one downstream of it.

The graph is built from the source with ``ast`` (every ``import`` statement, module-level or
inside a function), with ``adapters/`` mapped to ``driftlog.adapters``; nothing is imported.
Run as a script (``python tests/test_structure.py``) it prints the graph's numbers.

The layers follow the data flow (hydro source -> FlowField -> Tracker -> trajectories ->
analysis), from the bottom up; a module may import modules of its own layer or of a layer
below it.  The flow field *types* (``driftlog.flow``...) are the contract between the hydro
sources, which build them, and the tracker, which samples them: they sit below both, as the
mesh and the base (errors, schema, numba helpers) sit below everything.  The top turns
scenarios into objects and runs them (api, sources, cli, report, the scenario file itself,
ensembles, comparisons of runs, and the figures, which rebuild a run's flow from the scenario
stored in its trajectory file).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

LAYERS = [
    ("base", ["driftlog._version", "driftlog._cache", "driftlog._numba", "driftlog.errors",
              "driftlog.schema", "driftlog.files", "driftlog.resources", "driftlog.columns"]),
    ("mesh", ["driftlog.locate", "driftlog.seams", "driftlog.nodal", "driftlog.mesh",
              "driftlog.mesher"]),
    ("flow field", ["driftlog.flow", "driftlog.gridflow", "driftlog.analytic",
                    "driftlog.protocols"]),
    ("hydro source", ["driftlog.flowfile", "driftlog.adapters", "driftlog.solver",
                      "driftlog.seas", "driftlog.floodsetup", "driftlog.malpasset"]),
    ("tracker", ["driftlog.logs", "driftlog.physics", "driftlog.integrators", "driftlog.fused",
                 "driftlog.contact", "driftlog.tracker", "driftlog.stepping", "driftlog.clocks",
                 "driftlog.clock_kernel", "driftlog.island_kernel", "driftlog.moreau_kernel",
                 "driftlog.coupling_kernels"]),
    ("trajectories", ["driftlog.trajectory"]),
    ("analysis", ["driftlog.ensemble.summary", "driftlog.ensemble.aggregate"]),
    ("top", ["driftlog", "driftlog.__main__", "driftlog.api", "driftlog.sources",
             "driftlog.cli", "driftlog.solving", "driftlog.report", "driftlog.scenario",
             "driftlog.ensemble", "driftlog.compare", "driftlog.plots", "driftlog.coupling"]),
]


def module_files() -> dict[str, Path]:
    """Module name -> file, for driftlog/ and adapters/ (as driftlog.adapters)."""
    out = {}
    for folder, package in ((ROOT / "driftlog", "driftlog"),
                            (ROOT / "adapters", "driftlog.adapters")):
        for f in sorted(folder.rglob("*.py")):
            parts = list(f.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([package] + parts)] = f
    return out


def _resolve(name, files, current, level, is_package):
    if level:
        base = current.split(".") if is_package else current.split(".")[:-1]
        base = base[:len(base) - (level - 1)]
        name = ".".join(base + ([name] if name else []))
    return name


def import_graph() -> dict[str, set[str]]:
    """Module -> the driftlog modules it imports.

    ``from package import name`` counts as an import of the package (its ``__init__`` runs)
    and, when ``name`` is a submodule, of the submodule too; imports under ``TYPE_CHECKING``
    and inside functions count; a parent package imported implicitly by ``import a.b.c``
    does not.
    """
    files = module_files()
    graph = {}
    for mod, path in files.items():
        is_package = path.name == "__init__.py"
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name in files:
                        deps.add(alias.name)
            elif isinstance(node, ast.ImportFrom):
                target = _resolve(node.module, files, mod, node.level, is_package)
                named = target
                while named and named not in files:  # "from driftlog.x import y": driftlog.x
                    named = named.rpartition(".")[0]
                if named:
                    deps.add(named)
                for alias in node.names:
                    sub = f"{target}.{alias.name}"
                    if sub in files:
                        deps.add(sub)
                    elif target in files:
                        deps.add(target)
        deps.discard(mod)
        graph[mod] = deps
    return graph


def cycles(graph) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def layer_of(mod: str) -> int | None:
    """The layer index of a module (longest prefix in LAYERS), None if unplaced."""
    best, best_len = None, -1
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (mod == p or mod.startswith(p + ".")) and len(p) > best_len:
                best, best_len = i, len(p)
    return best


def upward_edges(graph) -> list[tuple[str, str]]:
    """(importer, imported) where the imported module lies in a higher layer."""
    out = []
    for a, deps in sorted(graph.items()):
        for b in sorted(deps):
            la, lb = layer_of(a), layer_of(b)
            if la is not None and lb is not None and lb > la:
                out.append((a, b))
    return out


def stats() -> dict:
    """Numbers of the import graph: modules, edges, cycles, upward edges, largest modules."""
    graph = import_graph()
    files = module_files()
    sizes = sorted(((len(p.read_text().splitlines()), m) for m, p in files.items()),
                   reverse=True)
    return {"modules": len(graph), "edges": sum(len(d) for d in graph.values()),
            "cycles": cycles(graph), "upward": upward_edges(graph), "largest": sizes[:8]}


# --------------------------------------------------------------------- tests
def test_every_module_has_a_layer():
    unplaced = [m for m in module_files() if layer_of(m) is None]
    assert not unplaced, f"place these modules in a layer of LAYERS: {unplaced}"


def test_no_import_cycle():
    found = cycles(import_graph())
    assert not found, "import circles: " + "; ".join(" <-> ".join(c) for c in found)


def test_no_module_imports_one_downstream():
    up = upward_edges(import_graph())
    assert not up, "imports of a downstream layer: " + ", ".join(
        f"{a} ({LAYERS[layer_of(a)][0]}) -> {b} ({LAYERS[layer_of(b)][0]})" for a, b in up)


def test_adapters_import_each_other_relatively():
    """Inside adapters/ (imported as driftlog.adapters by a finder) the readers name each other
    relatively, so that ordinary static tools resolve the imports."""
    bad = []
    for f in sorted((ROOT / "adapters").rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            names = [node.module or ""] if isinstance(node, ast.ImportFrom) else \
                [a.name for a in node.names] if isinstance(node, ast.Import) else []
            if any(n == "driftlog.adapters" or n.startswith("driftlog.adapters.")
                   for n in names) and not getattr(node, "level", 0):
                bad.append(f"{f.relative_to(ROOT)}:{node.lineno}")
    assert not bad, "import the other adapters relatively (from . import x): " + ", ".join(bad)


def test_graph_sees_lazy_and_relative_imports():
    g = import_graph()
    # a function-level import and a relative import inside adapters
    assert "driftlog.flowfile" in g["driftlog.sources"] or "driftlog.adapters" in \
        g["driftlog.sources"]
    assert "driftlog.adapters._common" in g["driftlog.adapters.ugrid"]


if __name__ == "__main__":
    s = stats()
    print(f"modules {s['modules']}, import edges {s['edges']}, cycles {len(s['cycles'])}, "
          f"upward edges {len(s['upward'])}")
    for c in s["cycles"]:
        print("  cycle:", " <-> ".join(c))
    for a, b in s["upward"]:
        print(f"  upward: {a} ({LAYERS[layer_of(a)][0]}) -> {b} ({LAYERS[layer_of(b)][0]})")
    print("largest:", ", ".join(f"{m} {n}" for n, m in s["largest"]))
