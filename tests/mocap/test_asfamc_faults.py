"""ASF/AMC bounds taken exactly, and regular files the fast reader must not take on trust.

Each bound the reader documents (``humotion_gym.mocap.asfamc``: units 1e-3 to
1e3, limits with ``min <= max``, spans of ``FRAME_SPAN_FACTOR`` per frame plus
``MAX_FRAME_GAP``, frame numbers up to ``MAX_FRAME_NUMBER``) is accepted at
its value and refused one step past it, by both AMC readers. A file whose
every frame repeats the same mistake is regular, so the fast reader sees it
first: it must still be refused, with the general reader's message.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_asfamc import amc_text, asf_text, asf_with, frames_at, random_frames, refused_by_both

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap import asfamc
from humotion_gym.mocap.asfamc import load_amc, load_asf


def both_readers(path: Path, sk, monkeypatch: pytest.MonkeyPatch):
    """Load with the fast reader allowed, then with the general reader only."""
    fast = load_amc(path, sk)
    with monkeypatch.context() as m:
        m.setattr(asfamc, "_amc_regular", lambda *args: None)
        general = load_amc(path, sk)
    return fast, general


@pytest.mark.parametrize(
    ("line", "text"),
    [
        (6, "  length 0.001"),  # MIN_LENGTH_UNIT, taken
        (6, "  length 1000"),  # MAX_LENGTH_UNIT, taken
        (23, "    limits (5.0 5.0)"),  # min == max: a locked axis
        (19, "     direction 0 1e9 0"),  # MAX_ABS_VALUE, taken
    ],
)
def test_asf_bounds_are_inclusive(write_text, line: int, text: str) -> None:
    """The documented bounds themselves are accepted."""
    sk = load_asf(write_text("t.asf", asf_with(line, text)))
    assert sk.point_names[:2] == ("root", "upper")


def test_the_frame_span_bound_is_taken_and_one_more_is_refused(write_text, monkeypatch) -> None:
    """3 frames may span 4 * 3 + 1000 = 1012 frame numbers: 1..1012 loads, 1..1013 does not."""
    sk = load_asf(write_text("t.asf", asf_text()))
    fast, general = both_readers(write_text("a.amc", frames_at([1, 1001, 1012])), sk, monkeypatch)
    assert fast.n_frames == general.n_frames == 1012
    message = refused_by_both(write_text("b.amc", frames_at([1, 1001, 1013])), sk, monkeypatch)
    assert "spanning at most 1012" in message


def test_frame_numbers_above_the_largest_are_refused_by_the_fast_reader(
    write_text, monkeypatch
) -> None:
    """A regular file of frame numbers past MAX_FRAME_NUMBER is refused, not read."""
    sk = load_asf(write_text("t.asf", asf_text()))
    monkeypatch.setattr(asfamc, "MAX_FRAME_NUMBER", 5)
    fast, general = both_readers(write_text("a.amc", frames_at([4, 5])), sk, monkeypatch)
    assert fast.n_frames == general.n_frames == 2
    message = refused_by_both(write_text("b.amc", frames_at([5, 6])), sk, monkeypatch)
    assert "line 8: expected a frame number of at most 5, found '6'" in message


def test_values_shifted_between_bones_in_every_frame_are_refused(write_text, monkeypatch) -> None:
    """'upper' with 2 values and 'lower' with 3 in every frame: as many values, wrong bones."""
    sk = load_asf(write_text("t.asf", asf_text()))
    lines = amc_text(random_frames(seed=1, n=3)).split("\n")
    for k, line in enumerate(lines):
        name, *values = line.split() or [""]
        if name == "upper":
            lines[k] = " ".join(["upper", *values[:2]])
        elif name == "lower":
            lines[k] = " ".join(["lower", "7.5", *values])
    message = refused_by_both(write_text("a.amc", "\n".join(lines)), sk, monkeypatch)
    assert "line 6: expected 3 values for 'upper' (dof rx ry rz), found 2" in message


def test_a_frame_number_with_more_on_its_line_is_no_frame_number(write_text) -> None:
    """'2 7' is not frame 2: a frame line holds the number alone."""
    sk = load_asf(write_text("t.asf", asf_text()))
    lines = amc_text(random_frames(seed=2, n=2)).split("\n")
    assert lines[7] == "2"
    lines[7] = "2 7"
    with pytest.raises(MocapFormatError, match=r"line 8: bone '2' is not defined"):
        load_amc(write_text("a.amc", "\n".join(lines)), sk)


def test_limits_lines_hold_nothing_but_pairs(write_text) -> None:
    """Text beside the '(min max)' pairs is refused, not skipped."""
    with pytest.raises(MocapFormatError, match=r"line 23: expected limits '\(min max\)'"):
        load_asf(write_text("t.asf", asf_with(23, "    limits (-180.0 180.0) x")))
    np.testing.assert_array_equal(
        load_asf(write_text("u.asf", asf_text())).bone_parents, [-1, 0, -1]
    )
