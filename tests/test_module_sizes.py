"""Modules a reader can hold: at most 800 lines, and no function over 100.

The limits are the code rules of docs/architecture.md; a function's
length counts its signature, docstring and body, as a reader meets them.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("humotion_gym", "baselines")
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 100


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int]]:
    """Every function (methods and nested ones included) longer than ``limit`` lines."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            start = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            length = (node.end_lineno or node.lineno) - start + 1
            if length > limit:
                found.append((node.name, length))
    return found


def modules() -> list[Path]:
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


def test_the_packages_have_modules():
    assert len(modules()) > 100


@pytest.mark.parametrize("limit", [MAX_MODULE_LINES])
def test_no_module_is_over_800_lines(limit):
    over = {
        str(p.relative_to(ROOT)): n
        for p in modules()
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > limit
    }
    assert not over, f"modules over {limit} lines: {over}"


def test_no_function_is_over_100_lines():
    over = {
        f"{p.relative_to(ROOT)}:{name}": n
        for p in modules()
        for name, n in long_functions(p.read_text(encoding="utf-8"))
    }
    assert not over, f"functions over {MAX_FUNCTION_LINES} lines: {over}"


def test_the_check_finds_a_long_function_and_a_long_method():
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    source = f"def short():\n    pass\n\ndef long():\n{body}\nclass A:\n    @staticmethod\n"
    source += "    def method():\n" + "".join(f"        y{i} = {i}\n" for i in range(99))
    assert long_functions(source) == [("long", MAX_FUNCTION_LINES + 1), ("method", 101)]
