"""Fixtures shared by the whole test suite."""

from __future__ import annotations

import os

# Multi-threaded BLAS fights itself on small matrices on a 2-core machine; one
# thread per process keeps the suite's run time steady.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import shutil
import tempfile
from pathlib import Path

import pytest

# ../shared/mocap beside the project's root (tests/conftest.py -> parents[2]).
_DEFAULT_SHARED = Path(__file__).resolve().parents[2] / "shared" / "mocap"


_CACHE_KEY = pytest.StashKey[str]()


def shared_mocap_dir() -> Path:
    """Where the shared real motion capture lives (HUMOTION_SHARED_MOCAP overrides)."""
    env = os.environ.get("HUMOTION_SHARED_MOCAP")
    return Path(env) if env else _DEFAULT_SHARED


def pytest_configure(config: pytest.Config) -> None:
    # Keep the suite's clip and prior caches out of the user's home, and keep
    # the environments on the synthetic data unless a test asks for real data.
    os.environ["HUMOTION_CACHE"] = tempfile.mkdtemp(prefix="humotion-test-cache-")
    config.stash[_CACHE_KEY] = os.environ["HUMOTION_CACHE"]
    os.environ.pop("HUMOTION_MOCAP", None)


def pytest_unconfigure(config: pytest.Config) -> None:
    # The suite's cache (about 50 MB of parsed clips and fitted priors) goes with it.
    cache = config.stash.get(_CACHE_KEY, None)
    if cache is not None:
        shutil.rmtree(cache, ignore_errors=True)


@pytest.fixture(scope="session")
def shared_mocap() -> Path:
    """The shared real motion capture; skips the test when it is absent."""
    path = shared_mocap_dir()
    if not path.is_dir() and os.environ.get("CI") == "true":
        pytest.fail(f"CI runs the real-data tests: the shared motion capture is absent ({path})")
    if not path.is_dir():
        pytest.skip(
            "../shared/mocap is absent: real-data tests need the shared motion capture "
            f"(looked in {path}; set HUMOTION_SHARED_MOCAP to point elsewhere)"
        )
    return path


@pytest.fixture(scope="session")
def real_library(shared_mocap: Path):
    """Every clip of the shared motion capture, at 30 Hz (parsed once per session)."""
    from humotion_gym.mocap.library import load_library

    return load_library([shared_mocap], fps=30.0, progress=False)


@pytest.fixture
def shared_loads_are_the_sessions(monkeypatch, shared_mocap: Path, real_library):
    """Every load of the whole shared folder at 30 Hz gives the session's parse of it.

    A command line loads the folder (an input check, the command, its
    environment), each time reading the session's cache of the same clips back;
    with this fixture it takes the session's library instead. Other loads (a
    ``--clip`` file) are made as they are.
    """
    from humotion_gym.mocap import library

    load = library.load_library

    def load_library(paths, fps=30.0, **kwargs):
        given = [paths] if isinstance(paths, (str, Path)) else list(paths)
        if (
            [Path(p) for p in given] == [shared_mocap]
            and fps == 30.0
            and set(kwargs) <= {"progress"}
        ):
            return real_library
        return load(paths, fps=fps, **kwargs)

    monkeypatch.setattr(library, "load_library", load_library)
