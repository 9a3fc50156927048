"""The import rules of the house (docs/architecture.md), read from the sources with ``ast``:

1. the solver packages (``solvers/getdp``, ``solvers/dolfinx``) never import the orchestrator nor
   each other — anywhere in a module, also inside functions: each is usable alone;
2. no import cycle among the orchestrator's rooms (its subpackages ``case/``, ``mesh/``, ...) through
   module-level imports, nor among its modules; an import inside a function is how a room reaches
   a heavier one only when needed (``TYPE_CHECKING`` blocks are not imports); the rooms import only
   downwards (:data:`ROOM_LEVEL`), inside functions too;
3. no private name (``_name``) imported from another package of the product;
4. each public class name is defined once in the product (a reader, or a ``grep``, finds one
   ``Material``, one ``Body``, one ``Mechanics``), and no module of the product is over 500 lines.

The rules cover the product (the three installed packages); tests may import private helpers to
test them.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGES = {"pulseform.orchestrator": REPO / "orchestrator", "pulseform.solvers.getdp": REPO / "solvers" / "getdp",
            "pulseform.solvers.dolfinx": REPO / "solvers" / "dolfinx"}
SOLVERS = ("pulseform.solvers.getdp", "pulseform.solvers.dolfinx")
ORCH = "pulseform.orchestrator"
#: the orchestrator's rooms from the bottom up (docs/architecture.md); "(top)": cli and the package
ROOM_LEVEL = {"case": 0, "mesh": 1, "coupling": 2, "em": 3, "mech": 3, "run": 4, "workflows": 5, "(top)": 6}


@dataclass(frozen=True)
class Import:
    importer: str  # module name
    target: str  # the imported module (or package) name
    names: tuple[str, ...]  # names taken from it (from-imports), else ()
    module_level: bool
    line: int


def _modules() -> dict[str, Path]:
    found = {}
    for pkg, root in PACKAGES.items():
        for path in sorted(root.rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join((pkg,) + parts)] = path
    return found


MODULES = _modules()


def _package_of(module: str) -> str:
    """The package a module lives in (a package's ``__init__`` is in the package itself)."""
    path = MODULES[module]
    return module if path.name == "__init__.py" else module.rsplit(".", 1)[0]


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or \
        (isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(module: str) -> list[Import]:
    tree = ast.parse(MODULES[module].read_text(), str(MODULES[module]))
    out: list[Import] = []

    def visit(node: ast.AST, module_level: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                continue
            inner = module_level and not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                out.extend(Import(module, a.name, (), module_level, child.lineno) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = _package_of(module).split(".")
                    base = base[: len(base) - (child.level - 1)]
                    target = ".".join(base + ([child.module] if child.module else []))
                else:
                    target = child.module or ""
                names = tuple(a.name for a in child.names)
                out.append(Import(module, target, names, module_level, child.lineno))
            visit(child, inner)

    visit(tree, True)
    return out


IMPORTS = [imp for m in MODULES for imp in _imports(m)]


def _resolve(imp: Import) -> list[str]:
    """Product modules an import statement loads: the target, and each name that is a submodule."""
    hits = [imp.target] if imp.target in MODULES else []
    hits += [f"{imp.target}.{n}" for n in imp.names if f"{imp.target}.{n}" in MODULES]
    return hits


def _room(module: str) -> str:
    parts = module.split(".")
    return parts[2] if len(parts) > 3 or (len(parts) == 3 and MODULES[module].name == "__init__.py") else "(top)"


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    result: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                strong(w)
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
                result.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            strong(v)
    return result


def test_the_rules_see_the_code():
    """The reader finds the rooms and their imports (a rule over nothing would pass)."""
    rooms = {_room(m) for m in MODULES if m.startswith(ORCH + ".")}
    assert {"case", "mesh", "em", "mech", "coupling", "run", "workflows"} <= rooms
    assert any(i.importer.startswith(ORCH) and i.target.startswith(SOLVERS) for i in IMPORTS)
    assert sum(i.module_level for i in IMPORTS if i.importer.startswith(ORCH) and _resolve(i)) > 50


@pytest.mark.parametrize("solver", SOLVERS)
def test_solver_packages_import_neither_the_orchestrator_nor_each_other(solver):
    other = [s for s in SOLVERS if s != solver][0]
    bad = [f"{MODULES[i.importer].relative_to(REPO)}:{i.line} imports {i.target}" for i in IMPORTS
           if i.importer.startswith(solver) and i.target.startswith((ORCH, other))]
    assert not bad, "\n".join(bad)


def test_no_import_cycle_among_the_orchestrators_rooms():
    edges: dict[str, set[str]] = {}
    for i in IMPORTS:
        if i.module_level and i.importer.startswith(ORCH + "."):
            for t in _resolve(i):
                if t.startswith(ORCH + ".") and _room(t) != _room(i.importer):
                    edges.setdefault(_room(i.importer), set()).add(_room(t))
    assert not _cycles(edges), f"room cycles: {_cycles(edges)}; edges: {edges}"


def test_rooms_import_only_downwards_also_inside_functions():
    bad = []
    for i in IMPORTS:
        if i.importer.startswith(ORCH + "."):
            for t in _resolve(i):
                if t.startswith(ORCH + ".") and ROOM_LEVEL[_room(t)] > ROOM_LEVEL[_room(i.importer)]:
                    bad.append(f"{MODULES[i.importer].relative_to(REPO)}:{i.line}: {_room(i.importer)} imports "
                               f"{t} ({_room(t)})")
    assert not bad, "\n".join(bad)


def test_no_import_cycle_among_modules():
    edges: dict[str, set[str]] = {}
    for i in IMPORTS:
        if i.module_level:
            for t in _resolve(i):
                if t != i.importer and not i.importer.startswith(t + "."):  # a package's own __init__
                    edges.setdefault(i.importer, set()).add(t)
    assert not _cycles(edges), f"module cycles: {_cycles(edges)}"


def test_no_private_name_imported_across_packages():
    bad = []
    for i in IMPORTS:
        if i.target not in MODULES or _package_of(i.target) == _package_of(i.importer):
            continue
        for n in i.names:
            if n.startswith("_") and not n.startswith("__"):
                bad.append(f"{MODULES[i.importer].relative_to(REPO)}:{i.line}: {n} from {i.target}")
        if i.target.rsplit(".", 1)[-1].startswith("_") and not i.target.endswith("__"):
            bad.append(f"{MODULES[i.importer].relative_to(REPO)}:{i.line}: private module {i.target}")
    assert not bad, "\n".join(bad)


def test_each_public_class_name_defined_once():
    where: dict[str, list[str]] = {}
    for module, path in MODULES.items():
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                where.setdefault(node.name, []).append(f"{path.relative_to(REPO)}:{node.lineno}")
    twice = {name: places for name, places in where.items() if len(places) > 1}
    assert not twice, twice


def test_no_module_over_500_lines():
    long = {str(path.relative_to(REPO)): n for path in MODULES.values()
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > 500}
    assert not long, long
