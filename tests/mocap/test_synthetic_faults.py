"""The synthetic motion's building blocks against hand-derived values, and its stated bounds.

The clip-level tests (``test_synthetic.py``) check what the motions look like;
these pin down the curves they are built from (smooth floor, time warp,
minimum-jerk path, cycle mean, prefix fitting, arm mirroring) with values
worked out by hand, and the contracts of :func:`synthetic_motions` that only
short or long clips reach (frame counts, the root box, the heading's range).
"""

from __future__ import annotations

import numpy as np
import pytest

from humotion_gym.body import (
    KEYPOINT_INDEX,
    N_PARAMS,
    PARAM_INDEX,
    default_shape,
    forward_kinematics,
)
from humotion_gym.mocap import _synthetic_curves as curves
from humotion_gym.mocap import synthetic
from humotion_gym.mocap.motion import Motion
from humotion_gym.mocap.synthetic import LOCOMOTION_LABELS, MIN_BEND, synthetic_motions

P = PARAM_INDEX


@pytest.fixture(scope="module")
def short_clips() -> list[Motion]:
    return synthetic_motions(n_subjects=6, seconds=2.0)


@pytest.fixture(scope="module")
def long_clips() -> list[Motion]:
    # 20 s of running or skipping is longer than the +-9.8 m box: those clips are cut.
    return synthetic_motions(n_subjects=2, seconds=20.0)


def test_smooth_floor_is_smooth_and_never_below_the_floor() -> None:
    """0.5 (x + f + sqrt((x - f)^2 + w^2)): f + w/2 at x = f, slope 1/2 there, ~x far above."""
    f, w = 0.3, 0.03
    x = np.linspace(-5.0, 5.0, 2001)
    y = curves._smooth_floor(x, f, w)
    assert np.all(y > f)
    assert curves._smooth_floor(np.array([f]), f, w)[0] == pytest.approx(f + w / 2, abs=1e-12)
    h = 1e-6
    slope = (
        curves._smooth_floor(np.array([f + h]), f, w)
        - curves._smooth_floor(np.array([f - h]), f, w)
    ) / (2 * h)
    assert slope[0] == pytest.approx(0.5, abs=1e-6)
    # Far above: x + w^2 / (4 (x - f)) to first order, 2.25e-5 at x - f = 10.
    assert curves._smooth_floor(np.array([f + 10.0]), f, w)[0] == pytest.approx(
        f + 10.0 + 2.25e-5, abs=1e-8
    )
    # The floor the clips use keeps every hinge at MIN_BEND or more, whatever the raw angle.
    assert curves._smooth_floor(x, synthetic._BEND_FLOOR).min() >= MIN_BEND


def test_time_warp_keeps_the_ends_and_advances_the_first_half() -> None:
    """phase + a sin(2 pi phase) / (2 pi): 0 and 1 fixed, +a / (2 pi) at a quarter cycle."""
    a = 0.08
    assert curves._warp(np.array([0.0, 0.5, 1.0]), a) == pytest.approx([0.0, 0.5, 1.0], abs=1e-15)
    assert curves._warp(np.array([0.25]), a)[0] == pytest.approx(0.25 + a / (2 * np.pi), abs=1e-15)
    assert curves._warp(np.array([0.75]), a)[0] == pytest.approx(0.75 - a / (2 * np.pi), abs=1e-15)
    assert np.all(np.diff(curves._warp(np.linspace(0.0, 1.0, 1001), a)) > 0)


def test_minimum_jerk_passes_the_knots_with_the_flash_hogan_profile() -> None:
    """Between knots q0 + (q1 - q0)(10 s^3 - 15 s^4 + 6 s^5): 1/2 at s = 1/2, 0.103515625 at 1/4."""
    knot_t = np.array([0.0, 1.0, 3.0])
    knot_q = np.array([[0.0, 2.0], [1.0, 2.0], [-1.0, 0.0]])
    t = np.array([0.0, 0.25, 0.5, 1.0, 2.0, 2.5, 3.0])
    got = curves._minimum_jerk(t, knot_t, knot_q)
    # s = 1/4: (1/64)(10 - 15/4 + 6/16) = 0.103515625; s = 3/4 of [1, 3]: 0.896484375.
    want_0 = [0.0, 0.103515625, 0.5, 1.0, 0.0, 1.0 - 2.0 * 0.896484375, -1.0]
    want_1 = [2.0, 2.0, 2.0, 2.0, 1.0, 2.0 - 2.0 * 0.896484375, 0.0]
    np.testing.assert_allclose(got[:, 0], want_0, atol=1e-12)
    np.testing.assert_allclose(got[:, 1], want_1, atol=1e-12)
    # Zero velocity at every knot (the profile's derivative vanishes at s = 0 and 1).
    h = 1e-5
    for k in knot_t[1:-1]:
        v = curves._minimum_jerk(np.array([k - h, k + h]), knot_t, knot_q)
        assert np.abs(v[1] - v[0]).max() / (2 * h) < 1e-6


@pytest.mark.parametrize("label", sorted(curves._GAITS))
def test_cycle_mean_is_the_mean_over_one_cycle(label: str) -> None:
    """Against the average of the periodic curve on a fine uniform grid (spectrally exact)."""
    for keys in (curves._GAITS[label].thigh, curves._GAITS[label].knee):
        grid = np.arange(20_000) / 20_000
        assert curves._cycle_mean(keys) == pytest.approx(curves._cycle(keys, grid).mean(), abs=1e-9)


def test_prefix_fits_counts_frames_that_fit_a_movable_box() -> None:
    """A box 2 * half_box wide, placed anywhere: a span of exactly 2 * half_box still fits."""
    x = np.array([0.0, 5.0, 10.0, 15.0, 20.0])
    along_x = np.stack([x, np.zeros(5)], axis=1)
    back_and_forth = np.array([[-5.0, 0.0], [5.0, 0.0], [0.0, 4.0], [0.0, -7.0]])
    paths = np.stack([along_x, along_x[:, ::-1], np.vstack([back_and_forth, [0.0, 0.0]])])
    # 10 mm spans fit a half box of 5; the third path's y span reaches 11 at its 4th frame.
    np.testing.assert_array_equal(curves._prefix_fits(paths, 5.0), [3, 3, 3])
    np.testing.assert_array_equal(curves._prefix_fits(paths, 10.0), [5, 5, 5])


def test_a_mirrored_arm_is_the_mirror_image_of_the_right_arm() -> None:
    """An arm pose written for the right side, mirrored, puts the left arm at (-x, y, z)."""
    rng = np.random.default_rng(0)
    shape = default_shape(1750.0)
    np.testing.assert_array_equal(
        synthetic._mirror_arm(synthetic._rest_arm("r"), "l"), synthetic._rest_arm("l")
    )
    for _ in range(5):
        arm = rng.uniform([-0.5, -1.0, -1.0, 0.3], [1.5, 0.3, 1.0, 1.5])
        params = np.zeros((1, N_PARAMS))
        synthetic._write_arm(params, "r", arm[None])
        synthetic._write_arm(params, "l", synthetic._mirror_arm(arm, "l")[None])
        kp = forward_kinematics(params, shape)[0]
        for joint in ("shoulder", "elbow", "wrist"):
            right, left = kp[KEYPOINT_INDEX[f"r_{joint}"]], kp[KEYPOINT_INDEX[f"l_{joint}"]]
            np.testing.assert_allclose(left, right * [-1.0, 1.0, 1.0], atol=1e-9)


def test_reaches_start_with_both_arms_at_rest(short_clips: list[Motion]) -> None:
    """A reach begins at rest: each shoulder abducted outwards as its side's rest arm.

    The right arm is exactly at rest at t = 0 (a minimum-jerk path starts at its
    first knot); the left is at rest too, or standing with small sway (0.02 rad
    of noise, a few standard deviations well inside 0.08).
    """
    reaches = [m for m in short_clips if m.label == "reach"]
    assert reaches
    right, left = synthetic._rest_arm("r"), synthetic._rest_arm("l")
    assert right[1] < 0 < left[1]  # outwards is -y on the right, +y on the left
    for m in reaches:
        first = m.params[0]
        assert first[P["r_shoulder_y"]] == pytest.approx(right[1], abs=1e-9), m.clip_id
        assert first[P["l_shoulder_y"]] == pytest.approx(left[1], abs=0.08), m.clip_id


@pytest.mark.parametrize(
    ("seconds", "fps", "frames"), [(0.57, 100.0, 57), (2.0, 30.0, 60), (0.1, 24.0, 2)]
)
def test_a_clip_has_seconds_times_fps_frames_rounded(
    seconds: float, fps: float, frames: int
) -> None:
    """round(seconds * fps) frames: 0.57 * 100 is 56.999... in floating point, 57 frames."""
    (walk,) = [
        m for m in synthetic_motions(n_subjects=1, seconds=seconds, fps=fps) if m.label == "walk"
    ]
    assert walk.n_frames == frames


def test_a_clip_of_one_frame_is_refused() -> None:
    """1/30 s at 30 fps is one frame: too short for velocities."""
    with pytest.raises(ValueError, match="need at least 2"):
        synthetic_motions(n_subjects=1, seconds=1.0 / 30.0, fps=30.0)


@pytest.mark.parametrize("clips", ["short_clips", "long_clips"])
def test_locomotion_stays_in_the_root_box_with_its_heading_in_range(
    clips: str, request: pytest.FixtureRequest
) -> None:
    """The root stays within +-9.8 m and the yaw within (-pi, pi) without touching the limits.

    Clipping at body's +-10 m or +-pi would hide a path placed out of the box;
    the limits are never reached when the path is placed right.
    """
    motions: list[Motion] = request.getfixturevalue(clips)
    for m in motions:
        if m.label not in LOCOMOTION_LABELS:
            continue
        assert (
            np.abs(m.params[:, [P["root_x"], P["root_y"]]]).max() <= synthetic._ROOT_BOX + 1e-6
        ), m.clip_id
        assert np.abs(m.params[:, P["root_yaw"]]).max() < np.pi - 1e-6, m.clip_id


def test_long_runs_are_cut_to_the_longest_prefix_that_fits(long_clips: list[Motion]) -> None:
    """A 20 s run cannot fit the box; it is cut short, but no shorter than it has to be."""
    for m in long_clips:
        if m.label != "run":
            continue
        assert 2 < m.n_frames < 600, m.clip_id
        span = np.ptp(m.params[:, [P["root_x"], P["root_y"]]], axis=0)
        # The cut is where a frame more would not fit: the path nearly spans the box (19.6 m)
        # in some direction; a run advances 3 m/s or so, 0.1 m per frame at 30 fps.
        assert span.max() > 2 * synthetic._ROOT_BOX - 500.0, (m.clip_id, span)


def test_a_straight_path_too_long_for_the_box_is_cut_along_a_diagonal() -> None:
    """30 m straight at 100 mm a frame: the longest prefix fits the 19.6 m box diagonally.

    Along an axis 197 frames fit (19.6 m); at 45 degrees (one of the 144 candidate
    headings) a length L needs L / sqrt(2) <= 19.6 m: L <= 27.72 m, 278 frames.
    """
    n = 301
    velocity = np.tile([0.0, 1000.0], (n, 1))  # mm/s in the heading frame, at 10 frames/s
    heading, position, kept = synthetic._place_path(
        velocity, np.zeros(n), 10.0, np.random.default_rng(0)
    )
    assert kept == 278
    assert heading.shape == (kept,) and position.shape == (kept, 2)
    assert np.abs(position).max() <= synthetic._ROOT_BOX
    steps = np.linalg.norm(np.diff(position, axis=0), axis=1)
    np.testing.assert_allclose(steps, 100.0, atol=1e-9)
    assert abs(abs(heading[0]) % (np.pi / 2) - np.pi / 4) < 1e-12


def test_a_path_turning_past_half_a_turn_is_cut_where_the_heading_would_leave_its_range() -> None:
    """A slow circle turning 8 rad fits the box but not the heading's (-pi, pi): it is cut.

    The heading may sweep at most 2 pi - 0.1 (0.05 from either limit); the cut keeps
    the longest prefix that does, to within a candidate's spacing (2 pi / 144).
    """
    n = 801
    turn = np.linspace(0.0, 8.0, n)
    velocity = np.tile([0.0, 50.0], (n, 1))
    heading, _, kept = synthetic._place_path(velocity, turn, 10.0, np.random.default_rng(0))
    assert kept < n
    assert np.all(np.abs(heading) < np.pi - 0.05)
    assert np.ptp(heading) > 2 * np.pi - 0.1 - 2 * np.pi / 144 - 0.01
