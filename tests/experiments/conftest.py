"""Fixtures shared by the experiments' tests."""

from __future__ import annotations

import pytest

from humotion_gym.mocap import library
from humotion_gym.mocap.library import MotionLibrary
from humotion_gym.mocap.synthetic import synthetic_motions

#: Clip length of the whole synthetic set below: the person splits and folds need every
#: subject, not the default 8 s of each clip, and decoding costs in proportion to the frames.
SHORT_SECONDS = 2.5


@pytest.fixture
def short_synthetic_library(monkeypatch: pytest.MonkeyPatch) -> float:
    """The CLI's default (synthetic) library, with every subject and activity in short clips.

    Returns:
        The clips' length in seconds.
    """

    def short(seed: int = 0, fps: float = 30.0) -> MotionLibrary:
        return MotionLibrary(tuple(synthetic_motions(seed=seed, fps=fps, seconds=SHORT_SECONDS)))

    # where default_library looks it up when no data folder is configured
    monkeypatch.setattr(library, "synthetic_library", short)
    return SHORT_SECONDS
