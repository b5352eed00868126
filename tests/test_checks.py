"""``humotion_gym.checks``: what counts as an integer or a real number, asked in one place."""

from __future__ import annotations

import ast
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from humotion_gym.checks import (
    check_at_least_zero,
    check_bool,
    check_count,
    check_positive,
    is_count,
    is_integer,
    is_real,
)

ROOT = Path(__file__).resolve().parents[1]

INTEGERS = [0, -3, 7, np.int64(5), np.uint8(2), np.int32(-1)]
NOT_INTEGERS = [True, False, np.bool_(True), 1.0, np.float64(2.0), "3", None, Fraction(1), [1]]
REALS = [*INTEGERS, 0.5, -2.0, float("nan"), float("inf"), np.float32(1.5), np.float64(-0.25)]
NOT_REALS = [True, np.bool_(False), "1.5", None, 1 + 0j, [0.5]]


@pytest.mark.parametrize("value", INTEGERS)
def test_integers_are_integers_and_reals(value: object) -> None:
    assert is_integer(value) and is_real(value)


@pytest.mark.parametrize("value", NOT_INTEGERS)
def test_bools_floats_and_strings_are_not_integers(value: object) -> None:
    assert not is_integer(value) and not is_count(value, -10)


@pytest.mark.parametrize("value", REALS)
def test_reals(value: object) -> None:
    assert is_real(value)


@pytest.mark.parametrize("value", NOT_REALS)
def test_not_reals(value: object) -> None:
    assert not is_real(value)


def test_count_bound_is_inclusive() -> None:
    assert is_count(3, 3) and not is_count(2, 3) and is_count(np.int8(0), 0)
    assert not is_count(np.int8(-1), 0)


def test_a_count_with_a_ceiling_names_its_range() -> None:
    check_count("n", 100_000, most=100_000)
    check_count("n", np.int64(0), 0, 5)
    for value in (100_001, 0, True, 2.0):
        with pytest.raises(ValueError, match=r"n: expected an integer in \[1, 100,000\], got "):
            check_count("n", value, most=100_000)


def test_checks_name_the_argument_and_what_was_expected() -> None:
    with pytest.raises(ValueError, match=r"episodes: expected an integer >= 1, got True"):
        check_count("episodes", True)
    with pytest.raises(ValueError, match=r"seed: expected an integer >= 0, got -1"):
        check_count("seed", -1, least=0)
    with pytest.raises(ValueError, match=r"noise: expected a positive finite number, got nan"):
        check_positive("noise", float("nan"))
    with pytest.raises(ValueError, match=r"blur: expected a finite number >= 0, got -0.5"):
        check_at_least_zero("blur", -0.5)
    with pytest.raises(ValueError, match=r"floor: expected True or False, got 'no'"):
        check_bool("floor", "no")
    check_count("n", np.int64(4))
    check_positive("x", np.float32(0.1))
    check_at_least_zero("y", 0)
    check_bool("z", np.bool_(False))


def test_count_checks_keep_their_least():
    check_count("seed", 0, least=0)
    check_count("n", 6, least=6)
    with pytest.raises(ValueError, match=r"n: expected an integer >= 6, got 5"):
        check_count("n", 5, least=6)


@pytest.mark.parametrize("value", [float("inf"), -float("inf"), np.float64("inf"), float("nan")])
def test_infinities_are_not_finite_numbers(value: object) -> None:
    with pytest.raises(ValueError, match="finite"):
        check_positive("x", value)
    with pytest.raises(ValueError, match="finite"):
        check_at_least_zero("x", value)


@pytest.mark.parametrize("value", [0, 1, np.int64(1), 1.0, "yes", None])
def test_only_bools_are_bools(value: object) -> None:
    with pytest.raises(ValueError, match="expected True or False"):
        check_bool("flag", value)


def _isinstance_calls(node: ast.AST) -> list[ast.Call]:
    return [
        c for c in ast.walk(node)
        if isinstance(c, ast.Call) and isinstance(c.func, ast.Name) and c.func.id == "isinstance"
        and len(c.args) == 2
    ]  # fmt: skip


def _names(node: ast.AST) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}


def number_tests_outside_checks(source: str, filename: str) -> list[int]:
    """Lines where one expression asks both ``isinstance(x, bool)`` and ``isinstance(x, int...)``.

    That pair is :func:`is_integer`'s or :func:`is_real`'s test written again.
    """
    lines = []
    for node in ast.walk(ast.parse(source, filename)):
        if not isinstance(node, ast.BoolOp):
            continue
        calls = _isinstance_calls(node)
        bools = {ast.dump(c.args[0]) for c in calls if _names(c.args[1]) == {"bool"}}
        kinds = {"int", "float", "integer", "floating", "number"}
        numbers = {ast.dump(c.args[0]) for c in calls if _names(c.args[1]) & kinds}
        if bools & numbers:
            lines.append(node.lineno)
    return lines


def test_no_module_writes_the_number_test_again() -> None:
    """Every package module asks :mod:`humotion_gym.checks` whether a value is a number."""
    found = []
    for pkg in ("humotion_gym", "baselines"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if path == ROOT / "humotion_gym" / "checks.py":
                continue
            for line in number_tests_outside_checks(path.read_text(), str(path)):
                found.append(f"{path.relative_to(ROOT)}:{line}")
    assert found == []


@pytest.mark.parametrize(
    "source",
    [
        "ok = isinstance(v, bool) or not isinstance(v, int) or v < 1",
        "ok = isinstance(v, (int, np.integer)) and not isinstance(v, bool)",
        "ok = not isinstance(v, bool) and isinstance(v, int | float)",
    ],
)
def test_the_scan_finds_a_number_test_written_again(source: str) -> None:
    assert number_tests_outside_checks(source, "<mutant>") == [1]


def test_the_scan_passes_other_uses_of_bool() -> None:
    source = "a = isinstance(v, bool) or isinstance(w, int)\nb = isinstance(v, (bool, np.bool_))"
    assert number_tests_outside_checks(source, "<ok>") == []


def test_float_array_is_numbers_as_float64_or_none():
    from humotion_gym.checks import float_array

    got = float_array([[1, 2], [3, 4]])
    assert got is not None and got.dtype == np.float64 and got.tolist() == [[1, 2], [3, 4]]
    assert float_array(np.float32(0.5)).shape == ()  # type: ignore[union-attr]
    for bad in ("a", [1, "b"], [[1, 2], [3]], {"x": 1}, object()):
        assert float_array(bad) is None, bad
