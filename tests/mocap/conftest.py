"""Fixtures for the motion-capture parser tests."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# ../shared/mocap beside the project's root (tests/mocap/conftest.py -> parents[3]).
_DEFAULT_SHARED = Path(__file__).resolve().parents[3] / "shared" / "mocap"


def shared_mocap_dir() -> Path:
    """Where the shared real motion capture lives (HUMOTION_SHARED_MOCAP overrides)."""
    env = os.environ.get("HUMOTION_SHARED_MOCAP")
    return Path(env) if env else _DEFAULT_SHARED


@pytest.fixture(scope="session")
def shared_mocap() -> Path:
    """The shared real motion capture; skips the test when it is absent."""
    path = shared_mocap_dir()
    if not path.is_dir():
        pytest.skip(
            "../shared/mocap is absent: real-data tests need the shared motion capture "
            f"(looked in {path}; set HUMOTION_SHARED_MOCAP to point elsewhere)"
        )
    return path


@pytest.fixture
def write_text(tmp_path: Path):
    """Write a string to a file under tmp_path, byte for byte (no newline translation)."""

    def _write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_bytes(text.encode("utf-8"))
        return path

    return _write
