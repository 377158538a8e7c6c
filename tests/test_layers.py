"""The package's modules are layered: every import of the package sits at a
module's top level (the command layer, cli.py, may import lazily), and the
modules' imports form no cycle."""

import ast
import unittest
from pathlib import Path

PACKAGE = "regrasp_drake"
PACKAGE_DIR = Path(__file__).resolve().parents[1] / PACKAGE
# The command layer (the command line, its outputs' checks and the scenario's
# options, which the benchmark scripts share): it imports lazily, so that
# `--help` and refusals of bad input answer before torch and Drake are loaded.
COMMAND_LAYER = {f"{PACKAGE}.cli", f"{PACKAGE}.outputs",
                 f"{PACKAGE}.scenario_args"}
# Beside it, the package's __init__ imports the API (api.py) on first use of
# its names: `import regrasp_drake` comes before NumPy (numerics.pin) and
# stays cheap for the command line and its workers.
LAZY = COMMAND_LAYER | {PACKAGE}


def module_name(path: Path, root: Path = PACKAGE_DIR) -> str:
    """The dotted name of a module file under the package directory `root`."""
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_imports(tree: ast.Module, name: str, is_package: bool = False):
    """(module imported, statement, inside a function) for every import of
    the package in a module's syntax tree. `from regrasp_drake.x import y`
    imports regrasp_drake.x.y when y is a module, else regrasp_drake.x: both
    are listed (candidates), and module_graph keeps those that are modules.
    Relative imports are resolved against `name`."""
    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(
                child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                for alias in child.names:
                    if alias.name.split(".")[0] == PACKAGE:
                        yield [alias.name], child, inner
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    here = name.split(".")
                    if not is_package:
                        here.pop()
                    here = here[:len(here) - (child.level - 1)]
                    base = ".".join(here + ([base] if base else []))
                if base.split(".")[0] == PACKAGE:
                    yield ([base] + [f"{base}.{a.name}" for a in child.names],
                           child, inner)
            yield from visit(child, inner)
    yield from visit(tree, False)


def parse_package(root: Path = PACKAGE_DIR) -> dict:
    """{module name: (syntax tree, is a package's __init__)} of every module
    under `root`."""
    return {module_name(path, root): (ast.parse(path.read_text(), str(path)),
                                      path.name == "__init__.py")
            for path in sorted(root.rglob("*.py"))}


def lazy_imports(modules: dict) -> list[str]:
    """`module:line: statement` for every import of the package inside a
    function or method, outside the command layer and the package's
    __init__ (LAZY)."""
    found = []
    for name, (tree, is_package) in modules.items():
        if name in LAZY:
            continue
        for _, node, inner in package_imports(tree, name, is_package):
            if inner:
                found.append(f"{name}:{node.lineno}: {ast.unparse(node)}")
    return found


def module_graph(modules: dict) -> dict[str, set[str]]:
    """{module: the package's modules it imports at its top level}."""
    graph = {}
    for name, (tree, is_package) in modules.items():
        graph[name] = set()
        for candidates, _, inner in package_imports(tree, name, is_package):
            if not inner:
                graph[name] |= {c for c in candidates
                                if c in modules and c != name}
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle (a list of modules, the first repeated at its end) through
    each strongly connected component of more than one module (Tarjan)."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def connect(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                connect(w)
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
                components.append(component)

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return [_cycle_in(graph, component) for component in components]


def _cycle_in(graph, component) -> list[str]:
    """A shortest cycle through the component's first module (breadth
    first, within the component)."""
    start = min(component)
    paths, seen = [[start]], {start}
    while paths:
        path = paths.pop(0)
        for w in sorted(graph[path[-1]] & component):
            if w == start:
                return path + [start]
            if w not in seen:
                seen.add(w)
                paths.append(path + [w])
    raise AssertionError(f"no cycle through {start}")  # a component has one


class LayersTest(unittest.TestCase):
    def setUp(self):
        self.modules = parse_package()

    def test_package_imports_are_at_module_top_level(self):
        found = lazy_imports(self.modules)
        self.assertEqual(found, [], "imports of the package inside a function "
                         f"outside {sorted(LAZY)} (move them to the "
                         "module's "
                         "top; a cycle they would close is a layering to "
                         "fix):\n" + "\n".join(found))

    def test_top_level_imports_form_no_cycle(self):
        cycles = find_cycles(module_graph(self.modules))
        self.assertEqual(cycles, [], "import cycles:\n" + "\n".join(
            " → ".join(c) for c in cycles))

    def test_the_command_layer_is_imported_by_no_module(self):
        graph = module_graph(self.modules)
        importers = sorted(m for m, imported in graph.items()
                           if m not in COMMAND_LAYER and COMMAND_LAYER & imported)
        self.assertEqual(importers, [])

    def test_parameter_space_imports_nothing_from_the_package(self):
        graph = module_graph(self.modules)
        self.assertEqual(graph[f"{PACKAGE}.parameter_space"], set())


class CheckersTest(unittest.TestCase):
    """The checks above find what they are meant to find, on a small
    package written here."""

    def setUp(self):
        import tempfile
        self.tmp = tempfile.TemporaryDirectory()
        self.root = Path(self.tmp.name) / PACKAGE
        files = {
            "__init__.py": "",
            "cli.py": "def main():\n    from regrasp_drake import a\n",
            "a.py": "from regrasp_drake import b\n",
            "b.py": "import regrasp_drake.sub.c\n",
            "sub/__init__.py": "",
            "sub/c.py": ("from .. import a\n\n"
                         "class K:\n"
                         "    def m(self):\n"
                         "        from regrasp_drake.b import x\n"),
            "d.py": "import numpy\n\ndef f():\n    import json\n",
        }
        for rel, text in files.items():
            path = self.root / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        self.modules = parse_package(self.root)

    def tearDown(self):
        self.tmp.cleanup()

    def test_finds_a_method_s_import_but_not_the_command_layer_s(self):
        self.assertEqual(lazy_imports(self.modules), [
            "regrasp_drake.sub.c:5: from regrasp_drake.b import x"])

    def test_finds_and_names_a_cycle_through_a_relative_import(self):
        graph = module_graph(self.modules)
        self.assertEqual(graph["regrasp_drake.cli"], set())
        self.assertEqual(find_cycles(graph), [[
            "regrasp_drake.a", "regrasp_drake.b", "regrasp_drake.sub.c",
            "regrasp_drake.a"]])

    def test_no_cycle_once_it_is_broken(self):
        (self.root / "sub" / "c.py").write_text("import json\n")
        self.assertEqual(find_cycles(module_graph(parse_package(self.root))),
                         [])


if __name__ == "__main__":
    unittest.main()
