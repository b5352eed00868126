"""The environments' shared parts by hand: argument checks and the batched info."""

from __future__ import annotations

import numpy as np
import pytest

from humotion_gym.envs._batch_info import _add_info, _add_step_info, episode_info
from humotion_gym.envs._checks import FPS_RANGE, check_env_arguments


def _check_fps(fps: float) -> None:
    check_env_arguments({}, {}, {}, {}, {}, fps)


def test_the_frame_rate_range_is_inclusive_at_both_ends() -> None:
    """fps may be either end of FPS_RANGE (1 and 240 Hz), and nothing beyond."""
    low, high = FPS_RANGE
    assert (low, high) == (1.0, 240.0)
    for fps in (low, 1, 30.0, high, 240):
        _check_fps(fps)
    for fps in (np.nextafter(low, 0.0), 0.5, np.nextafter(high, np.inf), 241.0):
        with pytest.raises(ValueError, match=r"^fps: expected 1 to 240 Hz"):
            _check_fps(fps)


def test_naturals_may_be_zero_and_counts_may_not() -> None:
    """occluders=0 (a natural) passes, -1 not; a count of 0 is refused in its own name."""
    check_env_arguments({"views": 1}, {}, {}, {"occluders": 0}, {}, 30.0)
    with pytest.raises(ValueError, match=r"^occluders: expected an integer >= 0, got -1"):
        check_env_arguments({}, {}, {}, {"occluders": -1}, {}, 30.0)
    with pytest.raises(ValueError, match=r"^views: expected an integer >= 1, got 0"):
        check_env_arguments({"views": 0}, {}, {}, {"occluders": 0}, {}, 30.0)


def test_an_episodes_info_is_its_masked_rows_as_python_values() -> None:
    """Each key the mask shows, the row as the single env gives it; no final_obs or final_info."""
    info = {
        "lost": np.array([True, False]),
        "_lost": np.array([True, True]),
        "count": np.array([3, 4], np.int64),
        "_count": np.array([True, True]),
        "frames": np.array([7, 9], np.uint16),
        "_frames": np.array([True, True]),
        "error_mm": np.array([1.5, 2.5]),
        "_error_mm": np.array([False, True]),
        "pose": np.arange(6.0).reshape(2, 3),
        "_pose": np.array([True, True]),
        "clip_id": np.array(["a", None], dtype=object),
        "_clip_id": np.array([True, False]),
        "final_obs": np.array([None, {"frame": 0}], dtype=object),
        "_final_obs": np.array([False, True]),
        "final_info": {"lost": np.array([False, True])},
        "_final_info": np.array([False, True]),
    }
    first = episode_info(info, 0)
    assert set(first) == {"lost", "count", "frames", "pose", "clip_id"}
    assert (first["lost"], first["count"], first["frames"], first["clip_id"]) == (True, 3, 7, "a")
    assert [type(first[k]) for k in ("lost", "count", "frames")] == [bool, int, int]
    np.testing.assert_array_equal(first["pose"], [0.0, 1.0, 2.0])
    second = episode_info(info, 1)
    assert set(second) == {"lost", "count", "frames", "error_mm", "pose"}
    assert second["lost"] is False and second["frames"] == 9 and type(second["frames"]) is int
    assert second["error_mm"] == 2.5 and type(second["error_mm"]) is float


def test_a_new_key_is_batched_in_its_first_values_kind() -> None:
    """Numbers and bools in arrays of their type, arrays stacked, the rest in object arrays."""
    infos: dict = {}
    _add_info(infos, {"ok": True, "n": 2, "x": 0.5, "v": np.ones(2), "s": "a"}, 1, 3)
    assert infos["ok"].dtype == np.bool_ and infos["ok"].tolist() == [False, True, False]
    assert infos["n"].dtype.kind == "i" and infos["n"].tolist() == [0, 2, 0]
    assert infos["x"].dtype == np.float64 and infos["v"].shape == (3, 2)
    assert infos["s"].dtype == object and infos["s"].tolist() == [None, "a", None]
    for key in ("ok", "n", "x", "v", "s"):
        assert infos[f"_{key}"].tolist() == [False, True, False], key


def test_a_steps_info_shows_the_stepped_episodes_only() -> None:
    """Rows of episodes not stepped are zero (None) and masked out; none stepped adds nothing."""
    step_info = {
        "error_mm": np.array([1.0, 2.0, 3.0]),
        "clip_id": np.array(["a", "b", "c"], dtype=object),
    }
    infos: dict = {}
    _add_step_info(infos, step_info, np.array([True, False, True]))
    assert infos["error_mm"].tolist() == [1.0, 0.0, 3.0]
    assert infos["clip_id"].tolist() == ["a", None, "c"]
    assert infos["_error_mm"].tolist() == [True, False, True]
    assert step_info["error_mm"].tolist() == [1.0, 2.0, 3.0]  # the given rows untouched
    every: dict = {}
    _add_step_info(every, step_info, np.ones(3, bool))
    assert every["error_mm"].tolist() == [1.0, 2.0, 3.0] and every["_error_mm"].all()
    none: dict = {}
    _add_step_info(none, step_info, np.zeros(3, bool))
    assert none == {}
