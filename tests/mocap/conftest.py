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
