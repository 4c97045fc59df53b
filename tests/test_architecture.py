"""The import graph of simgap: no circle, and a package's private modules used only inside it.

The layers themselves are pyproject.toml's import-linter contracts (``lint-imports``); these tests
read the source with :mod:`ast` (nothing is imported), so that what they check is what the files
say: the imports a module runs when it is imported (module level, ``if``/``try``/class bodies
included, function bodies not), and separately those it names for type checkers only
(``if TYPE_CHECKING:``).
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"

#: Circles through type-only imports outside this check's first subjects (simgap.analysis,
#: simgap.effects), known and left to their packages: each is one annotation back edge.
KNOWN_TYPE_ONLY_CIRCLES = {
    frozenset({"simgap.core.aruco", "simgap.core.rig"}),
    frozenset({"simgap.diagnosis.camera_truth", "simgap.diagnosis.nuisance"}),
}


def _module(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(("simgap", *(parts[:-1] if parts[-1] == "__init__" else parts)))


MODULES = {_module(p): p for p in SRC.rglob("*.py")}


def _is_type_checking(test: ast.expr) -> bool:
    return "TYPE_CHECKING" in ast.unparse(test)


def _import_nodes(body: list[ast.stmt], type_checking: bool):
    """The import statements a module body runs (and, with ``type_checking``, names for types)."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, ast.If) and _is_type_checking(node.test):
            if type_checking:
                yield from _import_nodes(node.body, type_checking)
            yield from _import_nodes(node.orelse, type_checking)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue  # run when called, not when imported
        else:
            for field in ("body", "orelse", "finalbody", "handlers"):
                yield from _import_nodes(getattr(node, field, None) or [], type_checking)


def _targets(node: ast.Import | ast.ImportFrom, importer: str, is_package: bool) -> set[str]:
    """The simgap modules an import statement needs: the module, and submodules named in it.

    A package is not counted for its submodules (``from package import _module``): Python loads
    a module's parent packages for every import, and a parent may import its own submodules.
    """
    if isinstance(node, ast.Import):
        return {a.name for a in node.names if a.name in MODULES}
    if node.level:
        base = importer.split(".")[: len(importer.split(".")) - node.level + is_package]
        module = ".".join(base + ([node.module] if node.module else []))
    else:
        module = node.module or ""
    named = {f"{module}.{a.name}" for a in node.names}
    if named <= set(MODULES):  # only submodules: the package is their parent, loaded for any
        return named
    return ({module} | named) & set(MODULES)


def _graph(type_checking: bool) -> dict[str, set[str]]:
    graph = {}
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text())
        nodes = _import_nodes(tree.body, type_checking)
        is_package = path.name == "__init__.py"
        graph[name] = {t for n in nodes for t in _targets(n, name, is_package)} - {name}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_checks_find_what_they_look_for():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    tree = ast.parse(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    import x\n"
        "import y\n"
        "def f():\n    import z\n"
    )

    def imported(type_checking: bool) -> list[str]:
        nodes = _import_nodes(tree.body, type_checking)
        return [a.name for n in nodes if isinstance(n, ast.Import) for a in n.names]

    assert imported(False) == ["y"]
    assert imported(True) == ["x", "y"]
    source = "from simgap.analysis.gap._gap import align\nfrom simgap.analysis.gap import Items\n"
    assert _private_imports(source) == [
        "simgap.analysis.gap._gap",
        "simgap.analysis.gap._gap.align",
    ]
    assert _private_imports("from simgap.render.clipping import _holds_unit_square") == []
    assert _owner("simgap.analysis.gap._gap.align") == "simgap.analysis.gap"


def test_no_module_of_simgap_imports_itself_through_a_circle():
    """Importing any module never needs a module that is still being imported."""
    assert _circles(_graph(type_checking=False)) == []


def test_no_circle_even_through_type_only_imports():
    """Type-only imports close no circle either (the shared type lives in the lower module)."""
    circles = _circles(_graph(type_checking=True))
    assert [c for c in circles if frozenset(c) not in KNOWN_TYPE_ONLY_CIRCLES] == []
    assert not any(m.startswith(("simgap.analysis", "simgap.effects")) for c in circles for m in c)


def _is_private(name: str) -> bool:
    """Whether ``name`` is, or lies in, a private module of simgap (a ``_name`` module file)."""
    parts = name.split(".")
    return any(
        ".".join(parts[:i]) in MODULES and parts[i - 1].startswith("_") and parts[i - 1][1] != "_"
        for i in range(2, len(parts) + 1)
    )


def _private_imports(source: str) -> list[str]:
    """The private modules of simgap (or names in them) that a file's import statements name."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        else:
            continue
        out += [n for n in names if _is_private(n)]
    return out


def _owner(private: str) -> str:
    """The package a private module belongs to: the dotted name before its first ``_`` part."""
    parts = private.split(".")
    first = next(i for i, p in enumerate(parts) if p.startswith("_") and not p.startswith("__"))
    return ".".join(parts[:first])


def test_private_modules_are_imported_only_inside_their_package():
    """Other packages, tests, benchmarks, scripts and notebooks import a package's public face."""
    offences = []
    for path in sorted(SRC.rglob("*.py")):
        importer = _module(path)
        for private in _private_imports(path.read_text()):
            if not (importer + ".").startswith(_owner(private) + "."):
                offences.append(f"{path.relative_to(REPO)}: {private}")
    outside = [p for d in ("tests", "benchmarks", "scripts") for p in (REPO / d).rglob("*.py")]
    for path in sorted(outside):
        offences += [f"{path.relative_to(REPO)}: {m}" for m in _private_imports(path.read_text())]
    for path in sorted((REPO / "notebooks").glob("*.ipynb")):
        cells = json.loads(path.read_text())["cells"]
        code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
        code = "\n".join(line for line in code.splitlines() if not line.startswith(("%", "!")))
        offences += [f"{path.relative_to(REPO)}: {m}" for m in _private_imports(code)]
    assert offences == []
