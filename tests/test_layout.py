"""The package's layout: each layer imports only the layers below it, no module imports itself back through
others (no import circle), and no module imports another project's private names."""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "stickslip"
FMU_SRC = Path(__file__).resolve().parents[1] / "fmu_src"

#: package of stickslip -> the packages it may import (besides itself); "(top)" is stickslip/__init__.py
ALLOWED = {
    "core": set(),
    "reference": set(),  # independent of the runtime: its own laws, stepping and events
    "fmu_src": {"core"},
    "fmu": {"fmu_src"},
    "hosts": {"core", "fmu"},
    "suite": {"core", "reference", "fmu", "hosts"},
    "systems": {"core", "reference", "fmu", "hosts", "chain"},  # chains of blocks (the native master runs the chain engine)
    "analysis": {"core", "reference"},
    "stress": {"core", "reference", "fmu", "hosts", "suite"},
    "chain": {"core", "reference", "fmu", "hosts", "systems", "analysis"},  # the chain engine, ensembles on a pool
    "bench": {"core", "reference", "fmu", "hosts", "suite", "systems", "chain"},  # bench-systems times the masters and the chain engine
    "cli": {"core", "reference", "fmu", "hosts", "suite", "systems", "chain", "analysis", "stress", "bench"},
    "(top)": {"core"},
}


def _modules():
    """``{module name: path}`` of every module of the package (the slaves' sources as ``stickslip.fmu_src``)."""
    out = {}
    for folder, prefix in ((SRC, ("stickslip",)), (FMU_SRC, ("stickslip", "fmu_src"))):
        for path in folder.rglob("*.py"):
            parts = prefix + path.relative_to(folder).with_suffix("").parts
            if folder is SRC and parts[1:2] == ("fmu_src",):
                continue
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


MODULES = _modules()


def _imports(name, path):
    """``(imported module, imported names)`` of every import statement in the module, lazy ones included."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            yield target, tuple(alias.name for alias in node.names)


def _internal_targets(name, path):
    """The stickslip modules ``name`` imports (a name imported from a package counts as its submodule if any)."""
    for target, names in _imports(name, path):
        if not target.startswith("stickslip"):
            continue
        submodules = [f"{target}.{n}" for n in names if f"{target}.{n}" in MODULES]
        yield from submodules or [target]


def _layer(module):
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "(top)"


@pytest.mark.parametrize("name", sorted(MODULES))
def test_a_module_imports_only_the_layers_below_its_own(name):
    layer = _layer(name)
    wrong = sorted({t for t in _internal_targets(name, MODULES[name])
                    if _layer(t) != layer and _layer(t) not in ALLOWED[layer]})
    assert not wrong, f"{name} ({layer}) imports {wrong}; {layer} may import {sorted(ALLOWED[layer])}"


def test_there_is_no_import_circle():
    graph = {name: {t for t in _internal_targets(name, path) if t in MODULES and t != name}
             for name, path in MODULES.items()}
    # a package's __init__ re-exporting its submodules is not a circle: drop the edges from a module to its
    # own packages
    graph = {name: {t for t in targets if not name.startswith(t + ".")} for name, targets in graph.items()}
    state, circles = {}, []

    def visit(node, stack):
        state[node] = "open"
        stack.append(node)
        for target in sorted(graph[node]):
            if state.get(target) == "open":
                circles.append(stack[stack.index(target):] + [target])
            elif target not in state:
                visit(target, stack)
        stack.pop()
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [])
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


def test_no_module_imports_another_projects_private_names():
    private = []
    for name, path in MODULES.items():
        for target, names in _imports(name, path):
            if target.startswith("stickslip") or target == "__future__":
                continue
            if any(part.startswith("_") for part in target.split(".")) or \
                    any(n.startswith("_") for n in names):
                private.append(f"{name}: {target} {names}")
    assert not private, private
