"""The shape of the code, as issue 58 left it: no two files import each other (not even
through imports inside functions), no private name crosses a module of planner/ or
missions/, and a module of theirs over 600 lines says at its top why it is that long.
Read from the sources (ast), not by importing them."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("autopilots", "common", "planner", "missions", "gcs")
#: where a private name may not be imported from another module
NO_PRIVATE_IMPORTS = ("planner", "missions", "gcs", "autopilots", "common")
LONG = 600
#: how a long module starts (the reason follows on the same line)
LONG_SAYS = "# Over 600 lines, knowingly:"


def _modules() -> dict:
    """dotted name -> path of every module of the product."""
    out = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _imports(name: str, path: Path, modules: dict):
    """(imported module, names taken from it) of every import in the file, those in
    functions too; a name that is itself a module is imported as that module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in modules:
                    yield alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")
            base = base[:len(base) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            taken = []
            for alias in node.names:
                if f"{target}.{alias.name}" in modules:
                    yield f"{target}.{alias.name}", ()
                else:
                    taken.append(alias.name)
            if taken and target in modules:
                yield target, tuple(taken)


def _graph() -> dict:
    modules = _modules()
    return {name: {t for t, _ in _imports(name, path, modules)} - {name}
            for name, path in modules.items()}


def _circles(graph) -> list:
    """The strongly connected groups of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

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
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))
    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_two_files_import_each_other():
    assert _circles(_graph()) == []


def test_the_circle_finder_finds_one():
    """Not vacuous: a loop of three and a pair are found, a chain is not."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"e"}, "e": {"d"}, "f": {"a"}}
    assert sorted(_circles(graph)) == [["a", "b", "c"], ["d", "e"]]


@pytest.mark.parametrize("package", NO_PRIVATE_IMPORTS)
def test_no_private_name_crosses_a_module(package):
    modules = _modules()
    crossing = [f"{path.relative_to(ROOT)}: {name} from {target}"
                for module, path in modules.items() if module.split(".")[0] == package
                for target, names in _imports(module, path, modules)
                for name in names if name.startswith("_") and not name.startswith("__")]
    assert crossing == []


@pytest.mark.parametrize("package", NO_PRIVATE_IMPORTS)
def test_a_long_module_says_why(package):
    unsaid = []
    for path in (ROOT / package).rglob("*.py"):
        text = path.read_text()
        if text.count("\n") > LONG and not text.startswith(LONG_SAYS):
            unsaid.append(f"{path.relative_to(ROOT)}: {text.count(chr(10))} lines")
    assert unsaid == []
