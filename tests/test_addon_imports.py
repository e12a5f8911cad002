"""The Blender add-on's import graph (addon/smooth_ffd, read with `ast`, no Blender needed):
imports of sibling modules go one way, from Blender's entry points down to the state module.

- every sibling import is at module level: none inside a function or method (one there would
  exist to dodge an import circle);
- the graph of sibling imports has no cycle;
- `state`, which holds every modifier's state and every value kept between calls, imports
  no sibling;
- no module but `state` keeps a mutable value at module level: no `global` statement, no
  module-level list, dict or set.
"""
import ast
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ADDON = os.path.join(ROOT, "addon", "smooth_ffd")


def modules(folder=ADDON):
    """{module name: parsed tree} of the package's modules (__init__ left out: it imports every
    module to register the add-on, and no module imports it)."""
    out = {}
    for name in sorted(os.listdir(folder)):
        if name.endswith(".py") and name != "__init__.py":
            with open(os.path.join(folder, name), encoding="utf-8") as f:
                out[name[:-3]] = ast.parse(f.read(), filename=name)
    return out


def sibling_imports(tree, siblings):
    """[(imported sibling, line, inside a function)] of one module: `from . import a, b`,
    `from .a import x`, `import smooth_ffd.a`, wherever they are."""
    found = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                      ast.Lambda))
            if isinstance(child, ast.ImportFrom) and child.level == 1:
                names = [child.module.split(".")[0]] if child.module else \
                    [a.name for a in child.names]
                found.extend((n, child.lineno, in_function) for n in names if n in siblings)
            elif isinstance(child, ast.Import):
                for a in child.names:
                    parts = a.name.split(".")
                    if len(parts) > 1 and parts[0] == "smooth_ffd" and parts[1] in siblings:
                        found.append((parts[1], child.lineno, in_function))
            visit(child, inner)
    visit(tree, False)
    return found


def graph(mods):
    return {name: sorted({m for m, _, _ in sibling_imports(tree, mods)})
            for name, tree in mods.items()}


def find_cycle(edges):
    """One import cycle as a list of modules (first == last), or None."""
    colour, path = {}, []

    def dfs(n):
        colour[n] = "grey"
        path.append(n)
        for m in edges.get(n, ()):
            if colour.get(m) == "grey":
                return path[path.index(m):] + [m]
            if m not in colour:
                cycle = dfs(m)
                if cycle:
                    return cycle
        colour[n] = "black"
        path.pop()
        return None
    for n in sorted(edges):
        if n not in colour:
            cycle = dfs(n)
            if cycle:
                return cycle
    return None


def _mutable(value):
    """A list, dict or set display or comprehension, or a call of list(), dict(), set()."""
    if isinstance(value, (ast.List, ast.Dict, ast.Set, ast.ListComp, ast.DictComp, ast.SetComp)):
        return True
    return isinstance(value, ast.Call) and isinstance(value.func, ast.Name) and \
        value.func.id in ("list", "dict", "set")


def problems(folder=ADDON):
    """Every rule of the module docstring that the package at `folder` breaks, as text."""
    mods = modules(folder)
    out = []
    for name, tree in mods.items():
        for m, line, in_function in sibling_imports(tree, mods):
            if in_function:
                out.append(f"{name}.py:{line}: imports {m} inside a function")
        if name == "state":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Global):
                out.append(f"{name}.py:{node.lineno}: global {', '.join(node.names)}")
        for node in tree.body:
            if isinstance(node, (ast.Assign, ast.AnnAssign)) and _mutable(node.value):
                out.append(f"{name}.py:{node.lineno}: a mutable value at module level")
    edges = graph(mods)
    cycle = find_cycle(edges)
    if cycle:
        out.append("import cycle: " + " -> ".join(cycle))
    if "state" not in mods:
        out.append("no state module")
    elif edges["state"]:
        out.append(f"state imports {', '.join(edges['state'])}")
    return out


def test_addon_import_graph_is_one_way():
    assert problems() == []


def test_the_checks_see_a_cycle_and_an_import_in_a_function(tmp_path):
    """The rules above, each broken once in a small package of their own."""
    (tmp_path / "state.py").write_text("from . import a\n")
    (tmp_path / "a.py").write_text("from . import b\n")
    (tmp_path / "b.py").write_text("import os\n\ndef f():\n    from . import a\n    global x\n\n"
                                   "cache = {}\nNAMES = ('a', 'b')\n")
    found = problems(str(tmp_path))
    assert "b.py:4: imports a inside a function" in found
    assert "b.py:5: global x" in found
    assert "b.py:7: a mutable value at module level" in found
    assert not any(f.startswith("b.py:8") for f in found), found
    assert "state imports a" in found
    assert any(f.startswith("import cycle: ") and "a -> b -> a" in f for f in found), found

