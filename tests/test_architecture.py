"""The layers of docs/architecture.md, read from the package's own imports (``ast``, nothing imported).

An import inside a function counts like one at the top of a module: a circle that only runs when a
function is called is still a circle in the design. Importing ``a.b.c`` also runs the package
``a.b``'s ``__init__`` (unless the importer lives inside ``a.b``), so that counts as an import too.
"""

import ast
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1] / "xtopo"
#: what a kernel may import besides the standard library and ``xtopo._kernels``: numerical libraries, the
#: optional FFT backend, the cache directory's location (FFTW wisdom) and ``xtopo.errors``
KERNEL_MAY_IMPORT = {"numpy", "scipy", "numba", "pyfftw", "platformdirs", "xtopo.errors"}
#: circles another part of issue 25 removes (the contact model interface); delete the entry when it lands
PENDING: list = []  # circles still to break (none)


def _modules() -> dict[str, pathlib.Path]:
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imported(module: str, node, package: bool) -> list[str]:
    """Absolute names an import statement of ``module`` imports (``from p import m`` of a submodule: ``p.m``)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if node.level:
        base = module.split(".") if package else module.split(".")[:-1]
        base = base[:len(base) - node.level + 1]
        source = ".".join(base + ([node.module] if node.module else []))
    else:
        source = node.module
    subs = [f"{source}.{a.name}" for a in node.names if f"{source}.{a.name}" in MODULES]
    return subs if len(subs) == len(node.names) else [source, *subs]


def _imports(module: str) -> set[str]:
    """Every name ``module`` imports, at its top or in a function (``TYPE_CHECKING`` blocks too)."""
    path = MODULES[module]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            out.update(_imported(module, node, path.name == "__init__.py"))
    return out


def _graph() -> dict[str, set[str]]:
    """xtopo module → the xtopo modules (and packages whose ``__init__`` runs) it imports."""
    graph = {}
    for module in MODULES:
        edges = set()
        for name in _imports(module):
            while name not in MODULES and "." in name:  # an attribute of a module: the module
                name = name.rsplit(".", 1)[0]
            if name not in MODULES:
                continue
            parts = name.split(".")
            for k in range(1, len(parts) + 1):
                target = ".".join(parts[:k])
                if target != module and not module.startswith(target + "."):  # own packages are running already
                    edges.add(target)
        graph[module] = edges
    return graph


def _circles(graph) -> list[set[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph)))

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_graph_sees_function_local_and_package_imports():
    graph = _graph()
    assert "xtopo.analysis.acf" in graph["xtopo.analysis.statistical_reliability"]
    assert "xtopo.io" in graph["xtopo.twins"]  # from .io.container import ...: runs xtopo/io/__init__.py
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]


def test_no_import_circles():
    circles = [c for c in _circles(_graph()) if c not in PENDING]
    assert not circles, f"modules that import each other (directly or through others): {circles}"


def test_kernels_import_only_numerics_and_errors():
    stdlib = set(sys.stdlib_module_names)
    bad = {}
    for module in MODULES:
        if not module.startswith("xtopo._kernels"):
            continue
        for name in _imports(module):
            top = name.split(".")[0]
            if top in stdlib or name.startswith("xtopo._kernels") or top in KERNEL_MAY_IMPORT \
                    or name in KERNEL_MAY_IMPORT:
                continue
            bad.setdefault(module, []).append(name)
    assert not bad, f"kernels importing beyond numpy/scipy/numba and xtopo.errors: {bad}"
