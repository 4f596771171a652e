"""Small functions (issue 10): no function in src/fdml longer than LIMIT lines unless it says why.

A function's length is its lines from ``def`` to its last line, less its docstring (the
documentation is not what makes a function hard to follow).  A longer function is allowed
when a comment starting ``# long:`` stands on its ``def`` line or in the comment lines just
above it (above its decorators), giving the reason.
"""

import ast
from pathlib import Path

import fdml

SRC = Path(fdml.__file__).parent
LIMIT = 100


def _length(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    n = fn.end_lineno - fn.lineno + 1
    first = fn.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        n -= first.end_lineno - first.lineno + 1
    return n


def _says_why(fn, lines: list[str]) -> bool:
    if "# long:" in lines[fn.lineno - 1]:
        return True
    top = min([fn.lineno] + [d.lineno for d in fn.decorator_list]) - 2  # 0-based line above
    while top >= 0 and lines[top].strip().startswith("#"):
        if lines[top].strip().startswith("# long:"):
            return True
        top -= 1
    return False


def long_functions(root: Path = SRC) -> dict[str, int]:
    """``path name`` -> length of every function over LIMIT lines that does not say why."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = _length(node)
                if n > LIMIT and not _says_why(node, lines):
                    out[f"{path.relative_to(root).as_posix()} {node.name}"] = n
    return out


def test_no_function_is_long_without_saying_why():
    assert long_functions() == {}


def test_the_length_rule(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(LIMIT - 1))
    doc = '    """' + "\n" * 30 + '    """\n'
    (tmp_path / "m.py").write_text(
        f"def short():\n{doc}{body}\n\n\n"  # def + 99 lines of code (and a long docstring): 100, fine
        f"def too_long():\n{body}\n    y = 1\n    return y\n\n\n"  # def + 101 lines: 102, too long
        f"# long: a table of cases, kept whole\n@staticmethod\ndef excused():\n{body}\n    y = 1\n    return y\n"
    )
    assert long_functions(tmp_path) == {"m.py too_long": LIMIT + 2}
