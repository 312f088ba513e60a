"""No function over 60 lines anywhere in ``src/ident``.

A function is measured with ``ast``: ``end_lineno - lineno + 1`` (its ``def`` line to its last
line, docstring and comments included; nested functions count in their parent too).
"""

import ast

from conftest import REPO_ROOT

MAX_LINES = 60


def _long_functions() -> dict[tuple[str, str], int]:
    """``{(path relative to src/ident, name): lines}`` of every function over the limit."""
    root = REPO_ROOT / "src" / "ident"
    found = {}
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_LINES:
                    found[(path.relative_to(root).as_posix(), node.name)] = lines
    return found


def test_no_function_over_60_lines():
    found = _long_functions()
    assert not found, f"functions over {MAX_LINES} lines (split them): {found}"
