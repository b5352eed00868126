import numpy as np
import pytest

from humotion_gym.body import (
    ANGLE_MASK,
    KEYPOINT_NAMES,
    PARAM_INDEX,
    default_shape,
    forward_kinematics,
)
from humotion_gym.errors import RigError
from humotion_gym.mocap import rigs
from humotion_gym.mocap.retarget import (
    fill_gaps,
    fit_shape,
    inverse_kinematics,
    resample,
    retarget_keypoints,
    velocities,
)

HINGES = [PARAM_INDEX[n] for n in ("r_elbow", "l_elbow", "r_knee", "l_knee")]


def smooth_motion(seed=0, frames=150, fps=30.0, min_bend=0.15):
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / fps
    p = np.zeros((frames, 25))
    for j in range(25):
        f = rng.uniform(0.2, 1.2)
        p[:, j] = rng.uniform(0.1, 0.7) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6))
    p[:, :3] = [150.0, -80.0, 930.0] + 150 * p[:, :3]
    p[:, PARAM_INDEX["root_yaw"]] += np.linspace(0, 9, frames)  # more than a turn
    p[:, HINGES] = np.abs(p[:, HINGES]) + min_bend
    return p


def test_exact_round_trip_of_cone_body_motion():
    shape = default_shape(1830)
    p = smooth_motion()
    kp = forward_kinematics(p, shape)
    params, observed, kp_out, fitted = retarget_keypoints(kp, 30.0, 30.0)
    assert np.abs(fitted.to_vector() - shape.to_vector()).max() < 1e-9
    err = np.linalg.norm(forward_kinematics(params, fitted) - kp, axis=-1)
    assert err.max() < 1e-6  # mm
    # the angles themselves come back too (the neck twist is invisible in keypoints)
    diff = params - p
    diff[:, ANGLE_MASK] = (diff[:, ANGLE_MASK] + np.pi) % (2 * np.pi) - np.pi
    diff[:, PARAM_INDEX["neck_z"]] = 0
    assert np.abs(diff).max() < 1e-8
    assert observed.all()


def test_angles_are_continuous_through_full_turns():
    shape = default_shape()
    p = smooth_motion(seed=1)
    params, _ = inverse_kinematics(forward_kinematics(p, shape), shape)
    steps = np.abs(np.diff(params[:, ANGLE_MASK], axis=0))
    assert steps.max() < 0.5
    yaw = params[:, PARAM_INDEX["root_yaw"]]
    assert yaw[-1] - yaw[0] == pytest.approx(p[-1, 3] - p[0, 3])


def test_straight_limb_keeps_previous_twist():
    shape = default_shape()
    p = smooth_motion(seed=2, frames=90)
    i_el, i_tw = PARAM_INDEX["r_elbow"], PARAM_INDEX["r_shoulder_z"]
    p[30:60, i_el] = 0.0  # the arm goes straight...
    p[30:60, i_tw] = np.linspace(0, 3, 30)  # ...while its (invisible) twist swings
    params, _ = inverse_kinematics(forward_kinematics(p, shape), shape)
    held = params[30:60, i_tw]
    assert np.allclose(held, held[0])
    assert held[0] == pytest.approx(params[29, i_tw])
    # the keypoints are still exact: a straight limb's twist does not move them
    assert np.abs(forward_kinematics(params, shape) - forward_kinematics(p, shape)).max() < 1e-6


def test_missing_frames_are_flagged_and_interpolated_not_zeroed():
    shape = default_shape()
    p = smooth_motion(seed=3, frames=60)
    kp = forward_kinematics(p, shape)
    kp[20:25] = np.nan
    params, observed, kp_out, _ = retarget_keypoints(kp, 30.0, None)
    assert not observed[20:25].any() and observed[:20].all() and observed[25:].all()
    assert np.all(np.isfinite(params))
    root_z = params[20:25, 2]
    lo, hi = sorted([params[19, 2], params[25, 2]])
    assert np.all((root_z >= lo - 1e-9) & (root_z <= hi + 1e-9))
    assert np.isnan(kp_out[20:25]).all()


def test_fill_gaps_interpolates():
    x = np.arange(10.0)[:, None] * np.ones((1, 2))
    ok = np.ones(10, bool)
    ok[3:6] = False
    y = x.copy()
    y[~ok] = np.nan
    assert np.allclose(fill_gaps(y, ok), x)


def test_resample_integer_ratio_picks_frames():
    p = smooth_motion(seed=4, frames=121, fps=120.0)
    obs = np.ones((121, 25), bool)
    kp = forward_kinematics(p, default_shape())
    out, o, k = resample(p, obs, kp, 120.0, 30.0)
    assert out.shape == (31, 25)
    assert np.array_equal(out, p[::4])


def test_resample_slerp_is_exact_for_constant_rotation_rate():
    # A joint turning at a constant rate about a fixed axis: slerp is exact.
    n = 41
    t = np.arange(n) / 60.0
    p = np.zeros((n, 25))
    p[:, 2] = 900
    p[:, PARAM_INDEX["root_yaw"]] = 2.0 * t
    p[:, PARAM_INDEX["r_elbow"]] = 0.3 + 1.0 * t
    kp = forward_kinematics(p, default_shape())
    out, _, _ = resample(p, np.ones((n, 25), bool), kp, 60.0, 25.0)
    t_out = np.arange(out.shape[0]) / 25.0
    assert np.allclose(out[:, PARAM_INDEX["root_yaw"]], 2.0 * t_out)
    assert np.allclose(out[:, PARAM_INDEX["r_elbow"]], 0.3 + t_out)


def test_resample_fractional_ratio_times_mask_and_keypoints():
    # 11 frames at 60 Hz to 25 Hz: new frames at source times 0, 2.4, 4.8, 7.2, 9.6
    # (between frames 0|0, 2|3, 4|5, 7|8, 9|10 with weights 0, .4, .8, .2, .6 on the later)
    n = 11
    t = np.arange(n, dtype=float)
    p = np.zeros((n, 25))
    p[:, :3] = t[:, None] * [1.0, 2.0, 3.0]
    p[:, PARAM_INDEX["r_elbow"]] = 0.1 * t
    observed = np.ones(n, bool)
    observed[[1, 3, 8]] = False  # unobserved source frames carry NaN keypoints
    kp = t[:, None, None] * np.arange(1.0, 46.0).reshape(15, 3)
    kp[~observed] = np.nan
    out, obs, k = resample(p, observed, kp, 60.0, 25.0)
    t_out = np.array([0.0, 2.4, 4.8, 7.2, 9.6])
    assert out.shape == (5, 25) and obs.shape == (5,) and k.shape == (5, 15, 3)
    np.testing.assert_allclose(out[:, :3], t_out[:, None] * [1.0, 2.0, 3.0], atol=1e-9)
    np.testing.assert_allclose(out[:, PARAM_INDEX["r_elbow"]], 0.1 * t_out, atol=1e-9)
    # a new frame is observed when the source frames on both sides are (frame 0
    # falls exactly on source frame 0: unobserved frame 1 does not matter)
    assert obs.tolist() == [True, False, True, False, True]
    want = t_out[:, None, None] * np.arange(1.0, 46.0).reshape(15, 3)
    np.testing.assert_allclose(k[obs], want[obs], atol=1e-9)
    assert np.isnan(k[~obs]).all()
    # a (T, 25) mask resamples the same way
    _, obs2, _ = resample(p, np.repeat(observed[:, None], 25, axis=1), kp, 60.0, 25.0)
    assert obs2.shape == (5, 25) and (obs2 == obs[:, None]).all()


def test_resample_keeps_angles_continuous_across_wraps():
    p = smooth_motion(seed=5, frames=200, fps=60.0)
    p[:, PARAM_INDEX["root_yaw"]] = np.linspace(0, 20, 200)
    kp = forward_kinematics(p, default_shape())
    out, _, _ = resample(p, np.ones((200, 25), bool), kp, 60.0, 24.0)
    assert np.abs(np.diff(out[:, ANGLE_MASK], axis=0)).max() < 0.6
    # the heading keeps its unwrapped branch (no 2 pi jumps back)
    assert out[-1, PARAM_INDEX["root_yaw"]] == pytest.approx(
        20 * (out.shape[0] - 1) * 2.5 / 199, abs=0.05
    )


def test_velocities_of_linear_motion():
    p = np.outer(np.arange(10.0), np.arange(25.0))
    v = velocities(p, 30.0)
    assert np.allclose(v, np.arange(25.0) * 30.0)


def test_fit_shape_needs_a_valid_frame():
    with pytest.raises(ValueError, match="no frame"):
        fit_shape(np.full((5, 15, 3), np.nan))


def test_fit_shape_names_the_source_and_the_keypoints_on_one_point():
    # Both hips on the pelvis and both shoulders on the neck leave the torso no
    # left-right direction: the shape would be NaN (a height of nan mm).
    kp = forward_kinematics(np.zeros(25), default_shape())[None].repeat(3, axis=0)
    k = KEYPOINT_NAMES.index
    kp[:, [k("l_hip"), k("r_hip")]] = kp[:, [k("pelvis")]]
    kp[:, [k("l_shoulder"), k("r_shoulder")]] = kp[:, [k("neck")]]
    with pytest.raises(ValueError) as info:
        retarget_keypoints(kp, 30.0, source="walk.amc (rig auto)")
    msg = str(info.value)
    assert msg.startswith("walk.amc (rig auto): the keypoints give no body to fit")
    assert "pelvis = r_hip = l_hip; neck = r_shoulder = l_shoulder" in msg
    with pytest.raises(ValueError, match="^fit_shape: the keypoints give no body"):
        fit_shape(kp)


@pytest.mark.parametrize("rig", list(rigs.RIGS.values()), ids=list(rigs.RIGS))
def test_every_rig_is_detected_from_its_names(rig):
    names = rig.source_points() + ["SomethingElse"]
    assert rigs.detect_rig(names).name == rig.name


def test_unknown_rig_lists_missing_keypoints():
    names = ["Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "Neck", "Head_End"]
    with pytest.raises(RigError) as info:
        rigs.detect_rig(names, "walk.bvh")
    msg = str(info.value)
    assert "walk.bvh" in msg and "r_hip" in msg and "'cmu-bvh'" in msg


def test_missing_keypoints_come_in_the_profile_order():
    """A profile's own order (right limb, then left), which a user reads its names in."""
    rig = rigs.make_rig({k: k for k in reversed(KEYPOINT_NAMES)})
    assert rig.resolve(["pelvis"])[1] == [k for k in reversed(KEYPOINT_NAMES) if k != "pelvis"]


def test_custom_rig_must_name_all_keypoints():
    mapping = {k: f"J_{k}" for k in KEYPOINT_NAMES}
    rig = rigs.make_rig(mapping)
    assert rigs.detect_rig  # sanity
    assert rig.resolve([f"J_{k}" for k in KEYPOINT_NAMES])[1] == []
    del mapping["pelvis"]
    with pytest.raises(RigError, match="pelvis"):
        rigs.make_rig(mapping)


@pytest.mark.parametrize(
    "leg, unit",
    [(84.0, "cm"), (0.84, "m"), (840.0, "mm"), (33.0, "inch"), (70.0, "cm"), (8.4, "dm"),
     (52.0, "cm"), (45.0, "cm"), (40.0, "inch"), (44.0, "inch"), (2.0, "m"), (5000.0, "mm")],
)  # fmt: skip
def test_unit_guess(leg, unit):
    assert rigs.guess_units_to_mm(leg)[1] == unit
