"""Lines of code of Python files: lines holding a token that is not a comment or a docstring
(issue 116's measure: the module's, classes' and functions' docstrings and comments left out,
blank lines too). ``python benchmarks/code_lines.py PATH ...`` prints each file's count and the
total; a folder counts its ``*.py`` files."""

from __future__ import annotations

import ast
import io
import sys
import tokenize
from pathlib import Path

SKIPPED = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENDMARKER}


def docstring_lines(tree: ast.AST) -> set[int]:
    """The lines of every module, class and function docstring of ``tree``."""
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                if isinstance(body[0].value.value, str):
                    lines.update(range(body[0].lineno, body[0].end_lineno + 1))
    return lines


def code_lines(path: Path) -> int:
    """The lines of ``path`` holding a token that is neither a comment nor in a docstring."""
    text = path.read_text()
    docs = docstring_lines(ast.parse(text))
    held = set()
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type in SKIPPED:
            continue
        held.update(line for line in range(tok.start[0], tok.end[0] + 1) if line not in docs)
    return len(held)


def main(argv: list[str]) -> int:
    files = [f for p in map(Path, argv) for f in (sorted(p.rglob("*.py")) if p.is_dir() else [p])]
    total = 0
    for f in files:
        n = code_lines(f)
        total += n
        print(f"{n:6d}  {f}")
    print(f"{total:6d}  total")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
