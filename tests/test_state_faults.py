"""The particles' per-particle arrays (:mod:`baselines.filtering.state`), by hand."""

from __future__ import annotations

import numpy as np

from baselines.filtering import ParticleState, select


def test_select_takes_the_keys_that_start_with_the_prefix_only() -> None:
    """A key holding the prefix further in (a nested prior's) is not the part's."""
    extra = {"a/h": np.arange(4.0), "b/a/h": np.arange(4.0) + 10.0, "ba/h": np.zeros(4)}
    state = ParticleState(np.zeros((4, 2)), extra)
    for given in (state.extra, state.take(np.array([3, 2, 1, 0])).extra):
        part = select(given, "a/")
        assert sorted(part) == ["h"]
    np.testing.assert_array_equal(select(state.extra, "a/")["h"], [0.0, 1.0, 2.0, 3.0])
    taken = state.take(np.array([3, 3, 0, 1]))
    np.testing.assert_array_equal(select(taken.extra, "a/")["h"], [3.0, 3.0, 0.0, 1.0])
    np.testing.assert_array_equal(select(taken.extra, "b/")["a/h"], [13.0, 13.0, 10.0, 11.0])
    assert sorted(select(taken.extra, "b")) == ["/a/h", "a/h"]
