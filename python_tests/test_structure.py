"""The code's shape (issue 25): no function of the discovery or the fit package longer than 80
lines, no module of python/tether longer than 800 lines. Measured with ast: a function's length is
end_lineno - lineno + 1 (its decorators aside), and a nested function counts inside its parent as
well as on its own, so a long function cannot hide behind nested ones."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "tether"
DISCOVERY = PACKAGE / "discover"
FIT = PACKAGE / "fit"
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 800


def function_lengths(path: Path) -> dict[str, int]:
    """{qualified name: lines} for every function and method of a module, nested ones included."""
    out: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = f"{prefix}{child.name}"
                out[name] = child.end_lineno - child.lineno + 1
                visit(child, f"{name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(path.read_text()), f"{path.stem}.")
    return out


def test_the_measure_counts_nested_functions_inside_their_parent(tmp_path):
    src = tmp_path / "m.py"
    src.write_text("def outer():\n    x = 1\n\n    def inner():\n        return 2\n\n    return inner\n\n\n"
                   "class C:\n    def method(self):\n        pass\n")
    assert function_lengths(src) == {"m.outer": 7, "m.outer.inner": 2, "m.C.method": 2}


def test_no_function_of_the_discovery_package_is_longer_than_80_lines():
    long = {name: n for f in sorted(DISCOVERY.glob("*.py")) for name, n in function_lengths(f).items()
            if n > MAX_FUNCTION_LINES}
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines in python/tether/discover: {long}"


def test_no_function_of_the_fit_package_is_longer_than_80_lines():
    long = {name: n for f in sorted(FIT.glob("*.py")) for name, n in function_lengths(f).items()
            if n > MAX_FUNCTION_LINES}
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines in python/tether/fit: {long}"


def test_no_module_of_the_package_is_longer_than_800_lines():
    lengths = {str(f.relative_to(PACKAGE)): len(f.read_text().splitlines()) for f in sorted(PACKAGE.rglob("*.py"))}
    assert "discover/search.py" in lengths and "fit/engine.py" in lengths      # the walk sees the subpackages
    long = {name: n for name, n in lengths.items() if n > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines in python/tether: {long}"
