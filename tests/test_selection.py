"""Settings are chosen on validation folds of the training persons only."""

import pytest

from humotion_gym.experiments.selection import (
    VALIDATION_SUBJECTS,
    select_observation_setting,
    validation_library,
)
from humotion_gym.mocap.library import TEST_SUBJECTS, synthetic_library


def test_a_fold_never_holds_a_test_person():
    lib = synthetic_library()
    fold = validation_library(None)
    assert not set(fold.subjects) & TEST_SUBJECTS
    assert set(fold.split("test").subjects) == set(fold.held_out)
    assert not set(fold.split("train").subjects) & set(fold.held_out)
    with pytest.raises(ValueError, match="test persons"):
        lib.validation_fold(sorted(TEST_SUBJECTS)[:1])
    with pytest.raises(ValueError, match="not in the training split"):
        lib.validation_fold(["nobody"])


def test_the_real_validation_persons_are_training_persons():
    assert not set(VALIDATION_SUBJECTS) & TEST_SUBJECTS


def test_selection_tracks_the_fold_and_picks_the_lowest_error():
    fold = validation_library(None)
    out = select_observation_setting(
        "SideWalk-v1", "pf-cv", "sharpness", [0.5, 2.0], fold, particles=30, episodes=2
    )
    errors = [r["mean_error_mm"] for r in out["rows"]]
    assert out["chosen"] == out["rows"][errors.index(min(errors))]["value"]
    assert out["validation_subjects"] == sorted(fold.held_out)
    with pytest.raises(ValueError, match="not an ObservationModel setting"):
        select_observation_setting("SideWalk-v1", "pf-cv", "nonsense", [1.0], fold)
    with pytest.raises(ValueError, match="at least one"):
        select_observation_setting("SideWalk-v1", "pf-cv", "sharpness", [], fold)
