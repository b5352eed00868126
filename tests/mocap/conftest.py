"""Fixtures for the motion-capture parser tests."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture
def write_text(tmp_path: Path):
    """Write a string to a file under tmp_path, byte for byte (no newline translation)."""

    def _write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_bytes(text.encode("utf-8"))
        return path

    return _write


@pytest.fixture
def count_calls():
    """:func:`calls_made`, for tests that check growth by counting work."""
    return calls_made


def calls_made(fn, *args, **kwargs) -> int:
    """Function calls (Python and built-in) made while running ``fn``: a count of work.

    Growth is checked by comparing counts at two sizes, not seconds, so a
    loaded machine cannot fail a test nor a fast one hide a quadratic step.
    An exception ``fn`` raises ends the count and is swallowed (the callers
    check the message separately).
    """
    import sys

    count = 0

    def profile(frame, event, arg):
        nonlocal count
        if event in ("call", "c_call"):
            count += 1

    sys.setprofile(profile)
    try:
        fn(*args, **kwargs)
    except Exception:  # noqa: BLE001, S110 - refusals are the work being counted
        pass
    finally:
        sys.setprofile(None)
    return count
