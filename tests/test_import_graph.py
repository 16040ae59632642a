"""No import cycle in the package: modules import downwards only, imports inside functions
included (a lazy import hides a cycle; it does not remove it). formats/ and cli/ are
mocapzip.formats and mocapzip.cli, as they install.

Not edges: imports under `if TYPE_CHECKING:` (never run), and a module's import of its own
package or a package above it (`from mocapzip import __version__`): Python runs those first
anyway. A package's `__init__` is otherwise a module like any other."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ROOTS = {"mocapzip": ROOT / "mocapzip", "mocapzip.formats": ROOT / "formats", "mocapzip.cli": ROOT / "cli"}


def modules(roots: dict[str, Path]) -> dict[str, Path]:
    """Dotted module name -> source file, for every .py under each root (a package's is its __init__)."""
    found = {}
    for name, folder in roots.items():
        for path in folder.rglob("*.py"):
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join((name, *parts))] = path
    return found


def imported(module: str, path: Path, known: set[str]) -> set[str]:
    """The modules of `known` that `module` imports, at any depth of its code."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    targets = set()
    for node in _run_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1]) if node.level else ""
            source = ".".join(part for part in (base, node.module) if part)
            targets.update(f"{source}.{alias.name}" if f"{source}.{alias.name}" in known else source
                           for alias in node.names)
    edges = set()
    for target in targets:
        while target and target not in known:  # `import a.b.c` of a name inside a.b.c: the module
            target = target.rpartition(".")[0]
        if target and not (module == target or module.startswith(target + ".")):
            edges.add(target)
    return edges


def _run_nodes(tree: ast.AST):
    """Every node of `tree` but those under `if TYPE_CHECKING:`."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo.extend(node.orelse)
        else:
            todo.extend(ast.iter_child_nodes(node))


def a_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of `graph` (its modules in order, the first again at the end), or None."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                return [*stack[stack.index(nxt):], nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = "done"
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start)
            if found:
                return found
    return None


def graph_of(roots: dict[str, Path]) -> dict[str, set[str]]:
    found = modules(roots)
    return {name: imported(name, path, set(found)) for name, path in found.items()}


def test_the_package_has_no_import_cycle():
    cycle = a_cycle(graph_of(ROOTS))
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_graph_holds_each_kind_of_import():
    graph = graph_of(ROOTS)
    assert "mocapzip.formats.mcz" in graph["mocapzip.archive.reader"]  # from mocapzip.formats.mcz import ...
    assert "mocapzip.legacy.container" in graph["mocapzip.formats.mcz"]  # from mocapzip.legacy import container
    assert "mocapzip.formats.errors" in graph["mocapzip.formats"]  # a package's __init__


def test_a_lazy_cycle_is_found(tmp_path):
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub" / "__init__.py").write_text("")
    (package / "low.py").write_text("from . import top\n")
    (package / "sub" / "mid.py").write_text("def f():\n    from ..low import X\n")
    (package / "top.py").write_text("import pkg.sub.mid\nfrom typing import TYPE_CHECKING\n"
                                    "if TYPE_CHECKING:\n    from pkg import low\n")
    assert a_cycle(graph_of({"pkg": package})) == ["pkg.low", "pkg.top", "pkg.sub.mid", "pkg.low"]
    (package / "low.py").write_text("from pkg import __version__\n")  # its own package: run first anyway
    assert a_cycle(graph_of({"pkg": package})) is None
