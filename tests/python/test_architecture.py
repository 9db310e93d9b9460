"""The package's shape is part of its contract: folders are layers, every import points down, no
module imports itself back through others, and every public name imports."""

import ast
import importlib
import os

import pytest

import pickplan

PACKAGE_DIR = os.path.dirname(pickplan.__file__)
# rank of each layer; a module imports only from its own layer or a lower rank. Layers of one rank sit
# side by side and neither imports the other: sim and perception; omg and pickup (two applications);
# eval and ros (the ROS 2 node: its modules that import rclpy are imported only when it runs).
LAYERS = {"core": 0, "sim": 1, "perception": 1, "omg": 2, "pickup": 2, "eval": 3, "ros": 3, "cli": 4}


def _modules():
    out = {}
    for dirpath, _, files in os.walk(PACKAGE_DIR):
        for f in files:
            if f.endswith(".py"):
                rel = os.path.relpath(os.path.join(dirpath, f), os.path.dirname(PACKAGE_DIR))[:-3]
                name = rel.replace(os.sep, ".")
                out[name[:-9] if name.endswith(".__init__") else name] = os.path.join(dirpath, f)
    return out


def _is_type_checking(node) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imports(name: str, path: str, known) -> set:
    """pickplan modules that ``name`` imports (anywhere in the file, but under ``if TYPE_CHECKING``)."""
    tree = ast.parse(open(path).read())
    skip = {id(n) for top in ast.walk(tree) if _is_type_checking(top) for n in ast.walk(top)}
    is_pkg = path.endswith("__init__.py")
    found = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = name.split(".") if is_pkg else name.split(".")[:-1]
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in known)
    return {m for m in found if m in known and m != name}


@pytest.fixture(scope="module")
def graph():
    mods = _modules()
    return {m: _imports(m, p, mods) for m, p in mods.items()}


def _layer(module: str):
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in LAYERS) else None


def test_every_import_points_down_the_layers(graph):
    wrong = []
    for mod, deps in graph.items():
        here = _layer(mod)
        for dep in deps:
            there = _layer(dep)
            if here is None or there is None or here == there:
                continue
            if LAYERS[there] > LAYERS[here] or (LAYERS[there] == LAYERS[here]):
                wrong.append(f"{mod} -> {dep}")
    assert not wrong, "imports against the layers: " + ", ".join(sorted(wrong))


def test_no_import_cycles(graph):
    # Tarjan's strongly connected components; a component of more than one module is a cycle
    index, low, on_stack, stack, cycles = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            # a package's __init__ importing its own submodules is not a cycle by itself
            if len(comp) > 1 and not all(c == v or c.startswith(v + ".") for c in comp):
                cycles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_every_public_name_imports():
    for name in pickplan.__all__:
        assert getattr(pickplan, name) is not None, name
    for package in ("core", "sim", "omg", "pickup", "eval", "cli"):
        module = importlib.import_module(f"pickplan.{package}")
        for name in getattr(module, "__all__", ()):
            assert getattr(module, name) is not None, f"pickplan.{package}.{name}"


def test_the_layered_modules_are_the_one_public_surface():
    """The flat module names of earlier releases are gone: one way to reach each module."""
    for flat in ("scenes", "robots", "execution", "omg.planner_old"):
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(f"pickplan.{flat}")
    assert not hasattr(pickplan, "OMGPlanner")
    from pickplan.omg import OMGPlanner

    assert OMGPlanner is importlib.import_module("pickplan.omg.planner").OMGPlanner
