"""Functions a reader can hold: outside the runtime (``stickslip.core``, kept as it is), no function is longer
than 60 lines (its decorators, signature, docstring and body)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = (ROOT / "src" / "stickslip", ROOT / "fmu_src")
RUNTIME = ROOT / "src" / "stickslip" / "core"
MAX_LINES = 60


def _function_lengths():
    """``{"path:name": lines}`` of every function and method outside the runtime."""
    out = {}
    for folder in FOLDERS:
        for path in sorted(folder.rglob("*.py")):
            if RUNTIME in path.parents:
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    first = min([node.lineno] + [d.lineno for d in node.decorator_list])
                    out[f"{path.relative_to(ROOT).as_posix()}:{node.name}"] = node.end_lineno - first + 1
    return out


def test_no_function_outside_the_runtime_is_longer_than_60_lines():
    lengths = _function_lengths()
    long = {name: n for name, n in lengths.items() if n > MAX_LINES}
    assert not long, f"functions over {MAX_LINES} lines (split them into named helpers): {long}"
