from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks

from humotion_gym.body import (
    ANGLE_MASK,
    KEYPOINT_INDEX,
    PARAM_INDEX,
    PARAM_LOWER,
    PARAM_UPPER,
    forward_kinematics,
)
from humotion_gym.mocap import library
from humotion_gym.mocap.motion import Motion
from humotion_gym.mocap.retarget import inverse_kinematics
from humotion_gym.mocap.synthetic import (
    ANKLE_HEIGHT,
    MIN_BEND,
    SYNTHETIC_LABELS,
    SYNTHETIC_TEST_SUBJECTS,
    synthetic_motions,
)

P = PARAM_INDEX
ANKLES = [KEYPOINT_INDEX["r_ankle"], KEYPOINT_INDEX["l_ankle"]]
HINGES = [P["r_elbow"], P["l_elbow"], P["r_knee"], P["l_knee"]]


@pytest.fixture(scope="module")
def motions() -> list[Motion]:
    return synthetic_motions()


def by_label(motions: list[Motion], label: str) -> list[Motion]:
    return [m for m in motions if m.label == label]


def ground_speed(m: Motion) -> float:
    """Mean horizontal speed of the pelvis, m/s."""
    step = np.linalg.norm(np.diff(m.params[:, :2], axis=0), axis=1)
    return float(step.sum() / 1000.0 / ((m.n_frames - 1) / m.fps))


def dominant_frequency(x: np.ndarray, fps: float) -> float:
    spectrum = np.abs(np.fft.rfft(x - x.mean()))
    return float(np.fft.rfftfreq(x.size, 1 / fps)[np.argmax(spectrum)])


def corr(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1])


# -- the set -------------------------------------------------------------------


def test_same_seed_same_clips_other_seed_other_clips():
    a = synthetic_motions(seed=3, n_subjects=2, seconds=2.0)
    b = synthetic_motions(seed=3, n_subjects=2, seconds=2.0)
    c = synthetic_motions(seed=4, n_subjects=2, seconds=2.0)
    for x, y, z in zip(a, b, c, strict=True):
        assert x.clip_id == y.clip_id == z.clip_id
        np.testing.assert_array_equal(x.params, y.params)
        np.testing.assert_array_equal(x.shape.to_vector(), y.shape.to_vector())
        assert not np.allclose(x.params, z.params)


def test_subject_clips_do_not_depend_on_the_number_of_subjects():
    few = synthetic_motions(n_subjects=1, seconds=2.0)
    more = synthetic_motions(n_subjects=3, seconds=2.0)
    for x, y in zip(few, more[: len(few)], strict=True):
        np.testing.assert_array_equal(x.params, y.params)


def test_frame_rates_dividing_120_hz_sample_the_same_motion():
    at30 = synthetic_motions(fps=30.0, n_subjects=1, seconds=2.0)
    at60 = synthetic_motions(fps=60.0, n_subjects=1, seconds=2.0)
    for x, y in zip(at30, at60, strict=True):
        assert (x.n_frames, y.n_frames) == (60, 120)
        np.testing.assert_allclose(x.params, y.params[::2])


def test_labels_subjects_ids_and_metadata(motions):
    assert len(motions) == 6 * len(SYNTHETIC_LABELS)
    assert {m.label for m in motions} == set(SYNTHETIC_LABELS)
    assert sorted({m.subject for m in motions}) == [f"synthetic-{i:02d}" for i in range(1, 7)]
    ids = [m.clip_id for m in motions]
    assert len(set(ids)) == len(ids)
    for m in motions:
        assert m.clip_id == f"synthetic/{m.label}-{m.subject[-2:]}"
        assert m.synthetic and m.dataset == "synthetic" and m.source == "synthetic:seed=0"
        assert "procedural" in m.description
        assert m.fps == 30.0 and m.n_frames == 240
        assert m.observed.all()
        np.testing.assert_allclose(m.velocities, np.gradient(m.params, 1 / 30.0, axis=0))
        np.testing.assert_allclose(m.keypoints, forward_kinematics(m.params, m.shape))


def test_subjects_differ_in_shape_and_the_test_split_is_held_out(motions):
    shapes = {m.subject: m.shape for m in motions}
    heights = [s.standing_height() for s in shapes.values()]
    assert min(heights) > 1400 and max(heights) < 2000  # head top above the ankles, mm
    assert max(heights) - min(heights) > 200
    for s in shapes.values():  # every subject is its own shape, each clip shares it
        assert sum(s == other for other in shapes.values()) == 1
    assert library.SYNTHETIC_TEST_SUBJECTS == SYNTHETIC_TEST_SUBJECTS
    lib = library.MotionLibrary(tuple(motions))
    assert set(lib.split("test").subjects) == set(SYNTHETIC_TEST_SUBJECTS)
    assert not set(lib.split("train").subjects) & set(SYNTHETIC_TEST_SUBJECTS)


def test_bad_arguments_are_refused():
    for kwargs in ({"fps": 0.0}, {"seconds": -1.0}, {"n_subjects": 0}, {"seconds": 0.01}):
        with pytest.raises(ValueError, match="synthetic_motions"):
            synthetic_motions(**kwargs)


# -- every clip ------------------------------------------------------------------


def test_every_clip_is_finite_and_within_the_joint_limits(motions):
    for m in motions:
        assert np.all(np.isfinite(m.params)) and np.all(np.isfinite(m.keypoints))
        assert np.all(m.params >= PARAM_LOWER) and np.all(m.params <= PARAM_UPPER), m.clip_id


def test_elbows_and_knees_stay_bent(motions):
    for m in motions:
        assert m.params[:, HINGES].min() >= MIN_BEND, m.clip_id


def test_keypoints_round_trip_through_inverse_kinematics(motions):
    # Bent limbs make the twists observable, so the retargeting recovers every
    # angle but the neck's twist (the head is a line).
    for m in motions[:6]:
        params, ok = inverse_kinematics(m.keypoints, m.shape)
        assert ok.all()
        diff = params - m.params
        diff[:, ANGLE_MASK] = (diff[:, ANGLE_MASK] + np.pi) % (2 * np.pi) - np.pi
        diff[:, P["neck_z"]] = 0.0
        assert np.abs(diff).max() < 1e-6, m.clip_id


def test_nothing_goes_through_the_floor(motions):
    for m in motions:
        assert m.keypoints[:, ANKLES, 2].min() >= ANKLE_HEIGHT - 1.0, m.clip_id


# -- locomotion ------------------------------------------------------------------


def test_walking_keeps_the_lower_foot_on_the_ground(motions):
    for m in by_label(motions, "walk"):
        lowest = m.keypoints[:, ANKLES, 2].min(axis=1)
        assert np.all(np.abs(lowest - ANKLE_HEIGHT) < 10.0), m.clip_id


def test_the_stance_foot_does_not_slide(motions):
    for label in ("walk", "run", "skip"):
        for m in by_label(motions, label):
            ankles = m.keypoints[:, ANKLES]
            speed = np.linalg.norm(np.gradient(ankles[..., :2], 1 / m.fps, axis=0), axis=-1)
            down = ankles[..., 2] < ANKLE_HEIGHT + 3.0
            assert np.median(speed[down]) < 100.0, m.clip_id  # mm/s, vs >1000 for the pelvis


def test_running_and_skipping_leave_the_ground(motions):
    for label in ("run", "skip"):
        for m in by_label(motions, label):
            lowest = m.keypoints[:, ANKLES, 2].min(axis=1)
            assert np.mean(lowest > ANKLE_HEIGHT + 20.0) > 0.15, m.clip_id


@pytest.mark.parametrize(
    ("label", "lo", "hi"), [("walk", 0.8, 1.8), ("run", 2.0, 4.5), ("skip", 1.0, 3.0)]
)
def test_the_pelvis_advances_at_a_plausible_speed(motions, label, lo, hi):
    for m in by_label(motions, label):
        assert lo < ground_speed(m) < hi, (m.clip_id, ground_speed(m))


def test_hips_move_in_antiphase_and_arms_opposite_to_the_legs(motions):
    for label in ("walk", "run", "skip"):
        for m in by_label(motions, label):
            p = m.params
            assert corr(p[:, P["r_hip_x"]], p[:, P["l_hip_x"]]) < -0.5, m.clip_id
            for side, other in (("r", "l"), ("l", "r")):
                arm = p[:, P[f"{side}_shoulder_x"]]
                assert corr(arm, p[:, P[f"{side}_hip_x"]]) < -0.3, m.clip_id
                assert corr(arm, p[:, P[f"{other}_hip_x"]]) > 0.3, m.clip_id


def test_walking_knee_has_the_two_waves_of_gait(motions):
    # Loading response ~15-20 deg, swing ~60 deg (Winter 2009; Perry 2010).
    for m in by_label(motions, "walk"):
        knee = np.rad2deg(m.params[:, P["r_knee"]])
        peaks, _ = find_peaks(knee, prominence=3.0)
        small, large = knee[peaks][knee[peaks] < 35], knee[peaks][knee[peaks] >= 35]
        assert len(large) >= 6 and abs(len(small) - len(large)) <= 1, m.clip_id
        assert np.all((small > 10) & (small < 28)) and np.all((large > 50) & (large < 80))
    for m in by_label(motions, "run"):
        assert 75 < np.rad2deg(m.params[:, P["r_knee"]]).max() < 125


def test_the_pelvis_bobs_twice_per_stride(motions):
    for m in by_label(motions, "walk"):
        stride = dominant_frequency(m.params[:, P["r_hip_x"]], m.fps)
        assert 0.85 < stride < 1.15
        bob_rate = dominant_frequency(m.params[:, P["root_z"]], m.fps)
        assert bob_rate == pytest.approx(2 * stride, rel=0.1)
        bob = np.ptp(m.params[:, P["root_z"]])
        assert 20.0 < bob < 90.0, m.clip_id  # mm


# -- standing activities ----------------------------------------------------------


def test_arm_clips_stand_still_and_move_the_right_arm_with_visible_twist(motions):
    for label in ("arm_swing", "reach", "wave"):
        for m in by_label(motions, label):
            p = m.params
            drift = np.linalg.norm(p[:, :2] - p[0, :2], axis=1).max()
            assert drift < 60.0, m.clip_id  # postural sway only
            lowest = m.keypoints[:, ANKLES, 2].min(axis=1)
            assert np.all(np.abs(lowest - ANKLE_HEIGHT) < 10.0)
            arms = [p[:, P[f"{s}_shoulder_x"] : P[f"{s}_elbow"] + 1] for s in ("r", "l")]
            # The right arm works in swings and reaches (ArmTrack tracks it); a
            # wave uses the subject's preferred hand.
            arm = arms[0] if label != "wave" else max(arms, key=lambda a: a.std(axis=0).sum())
            assert arm[:, :3].std(axis=0).max() > 0.15, m.clip_id  # it moves,
            assert arm[:, 2].std() > 0.05, m.clip_id  # its twist varies,
            assert arm[:, 3].min() > MIN_BEND  # with the elbow bent
