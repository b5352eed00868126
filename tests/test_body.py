import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from humotion_gym import body
from humotion_gym.body import (
    KEYPOINT_INDEX as K,
)
from humotion_gym.body import (
    PARAM_INDEX as P,
)
from humotion_gym.body import (
    BodyShape,
    cone_geometry,
    default_shape,
    forward_kinematics,
    standing_pose,
)


def test_layout_is_consistent():
    assert len(body.PARAM_NAMES) == 25 == len(set(body.PARAM_NAMES))
    assert len(body.KEYPOINT_NAMES) == 15 and len(body.CONE_NAMES) == 10
    assert np.all(body.PARAM_LOWER < body.PARAM_UPPER)
    assert body.PARAM_UNITS[:3] == ("mm",) * 3 and set(body.PARAM_UNITS[3:]) == {"rad"}
    assert body.CONE_KEYPOINTS.shape == (10, 2)


def test_rest_pose_keypoints_are_known():
    s = default_shape()
    kp = forward_kinematics(standing_pose(s), s)
    # ankles on the ground, below the hips, limbs straight down
    assert np.allclose(kp[[K["r_ankle"], K["l_ankle"]], 2], 0.0)
    assert np.allclose(kp[K["r_hip"]], [s.hip_half_width, 0, s.thigh_length + s.shin_length])
    assert np.allclose(
        kp[K["r_wrist"]] - kp[K["r_shoulder"]], [0, 0, -(s.upper_arm_length + s.forearm_length)]
    )
    assert np.isclose(kp[K["head_top"], 2], s.standing_height())
    # the subject's right is +x
    assert kp[K["r_shoulder"], 0] > 0 > kp[K["l_shoulder"], 0]
    # mirror symmetric: each left keypoint is its right twin with x negated (also with
    # shoulders and hips set forward, which the default shape leaves at 0)
    for shape in (s, s.replace(shoulder_forward=40.0, hip_forward=-25.0)):
        kp = forward_kinematics(standing_pose(shape), shape)
        for joint in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle"):
            mirrored = kp[K[f"r_{joint}"]] * [-1.0, 1.0, 1.0]
            np.testing.assert_allclose(kp[K[f"l_{joint}"]], mirrored, atol=1e-9, err_msg=joint)
        assert kp[K["l_shoulder"], 1] == pytest.approx(shape.shoulder_forward)


@pytest.mark.parametrize(
    "name, value, joint, expected_dir",
    [
        ("r_elbow", np.pi / 2, ("r_elbow", "r_wrist"), [0, 1, 0]),  # forearm forward
        ("r_knee", np.pi / 2, ("r_knee", "r_ankle"), [0, -1, 0]),  # shin backward
        ("r_shoulder_x", np.pi / 2, ("r_shoulder", "r_elbow"), [0, 1, 0]),  # flexion forward
        ("r_hip_x", np.pi / 2, ("r_hip", "r_knee"), [0, 1, 0]),
        ("r_shoulder_y", -np.pi / 2, ("r_shoulder", "r_elbow"), [1, 0, 0]),  # right arm out
        ("l_shoulder_y", np.pi / 2, ("l_shoulder", "l_elbow"), [-1, 0, 0]),  # left arm out
        ("neck_x", np.pi / 2, ("neck", "head_top"), [0, -1, 0]),  # head tilts back
    ],
)
def test_single_joint_oracles(name, value, joint, expected_dir):
    s = default_shape()
    pose = standing_pose(s)
    pose[P[name]] = value
    kp = forward_kinematics(pose, s)
    d = kp[K[joint[1]]] - kp[K[joint[0]]]
    assert np.allclose(d / np.linalg.norm(d), expected_dir, atol=1e-12)


def test_heading_turns_the_body_about_the_vertical():
    s = default_shape()
    pose = standing_pose(s, yaw=np.pi / 2)
    kp = forward_kinematics(pose, s)
    # yaw +90 degrees takes +x (the right) to +y
    assert np.allclose(kp[K["r_shoulder"], :2], [0, s.shoulder_half_width], atol=1e-9)


def test_twist_only_moves_the_bent_forearm():
    s = default_shape()
    pose = standing_pose(s)
    pose[P["r_elbow"]] = 1.0
    a = forward_kinematics(pose, s)
    pose[P["r_shoulder_z"]] = 0.7
    b = forward_kinematics(pose, s)
    assert np.allclose(a[K["r_elbow"]], b[K["r_elbow"]])
    assert not np.allclose(a[K["r_wrist"]], b[K["r_wrist"]])


def test_batched_equals_single():
    rng = np.random.default_rng(1)
    s = default_shape(1600)
    params = rng.uniform(
        body.PARAM_LOWER.clip(-3, 3), body.PARAM_UPPER.clip(-3, 3), size=(4, 3, 25)
    )
    params[..., :3] = rng.normal(0, 500, size=(4, 3, 3))
    batched = forward_kinematics(params, s)
    assert batched.shape == (4, 3, 15, 3)
    for i in range(4):
        for j in range(3):
            assert np.allclose(batched[i, j], forward_kinematics(params[i, j], s))


def test_limb_lengths_are_preserved():
    rng = np.random.default_rng(2)
    s = default_shape()
    params = rng.uniform(-2, 2, size=(100, 25))
    kp = forward_kinematics(params, s)
    for a, b, length in [
        ("r_shoulder", "r_elbow", s.upper_arm_length),
        ("l_elbow", "l_wrist", s.forearm_length),
        ("r_hip", "r_knee", s.thigh_length),
        ("l_knee", "l_ankle", s.shin_length),
        ("neck", "head_top", s.head_length),
    ]:
        assert np.allclose(np.linalg.norm(kp[:, K[a]] - kp[:, K[b]], axis=-1), length)


def test_euler_conventions_match_scipy():
    rng = np.random.default_rng(3)
    a = rng.uniform(-1.5, 1.5, size=(50, 3))
    assert np.allclose(body.euler_xyz_to_matrix(a), Rotation.from_euler("XYZ", a).as_matrix())
    assert np.allclose(body.euler_zxy_to_matrix(a), Rotation.from_euler("ZXY", a).as_matrix())
    assert np.allclose(body.matrix_to_euler_xyz(body.euler_xyz_to_matrix(a)), a)
    assert np.allclose(body.matrix_to_euler_zxy(body.euler_zxy_to_matrix(a)), a)


def test_cone_geometry_frames():
    rng = np.random.default_rng(4)
    s = default_shape()
    g = cone_geometry(rng.uniform(-1, 1, size=(20, 25)), s)
    assert g.starts.shape == g.ends.shape == (20, 10, 3)
    r = g.rotations
    assert np.allclose(r @ np.swapaxes(r, -1, -2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(r), 1.0)
    # limbs run along -z of their frame
    axis = g.ends[:, 2:] - g.starts[:, 2:]
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    assert np.allclose(axis, -r[:, 2:, :, 2])


def test_shape_vector_round_trip_and_validation():
    s = default_shape(1820)
    assert BodyShape.from_vector(s.to_vector()) == s
    with pytest.raises(ValueError, match="expected"):
        BodyShape.from_vector(np.zeros(5))
    with pytest.raises(ValueError, match="thigh_length"):
        s.replace(thigh_length=-1.0)
    with pytest.raises(ValueError, match=r"\(10, 2\)"):
        s.replace(radii=np.ones((9, 2)))
    with pytest.raises(ValueError, match="height"):
        default_shape(-3)


def test_shape_from_the_same_vector_is_the_same_object():
    # An agent reads a shape from every observation: the same vector gives the
    # last (immutable) object back, another vector a new shape, a bad one raises.
    s = default_shape(1820)
    first = BodyShape.from_vector(s.to_vector())
    assert BodyShape.from_vector(s.to_vector().copy()) is first
    with pytest.raises(ValueError, match="read-only"):
        first.radii[0, 0] = 1.0
    taller = BodyShape.from_vector(default_shape(1900).to_vector())
    assert taller is not first and taller == default_shape(1900) and taller != first
    bad = s.to_vector()
    bad[-1] = -1.0
    with pytest.raises(ValueError, match="aspect"):
        BodyShape.from_vector(bad)
    assert BodyShape.from_vector(default_shape(1900).to_vector()) is taller


def test_bad_params_shape_names_what_was_expected():
    with pytest.raises(ValueError, match=r"\(\.\.\., 25\)"):
        forward_kinematics(np.zeros((3, 24)), default_shape())


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf, 0.0])
def test_an_aspect_that_is_not_finite_and_positive_is_refused(value):
    """A NaN aspect passed the ``<= 0`` test and the figure vanished from the frames."""
    s = default_shape()
    one = s.aspect.copy()
    one[3] = value
    for aspect in (np.full(10, value), one):
        with pytest.raises(ValueError, match=r"^BodyShape: aspect must be finite and positive"):
            s.replace(aspect=aspect)
    bad = s.to_vector()
    bad[-1] = value
    with pytest.raises(ValueError, match="aspect must be finite and positive"):
        BodyShape.from_vector(bad)
    with pytest.raises(ValueError, match=r"^BodyShape: radii must be finite and positive"):
        s.replace(radii=np.full((10, 2), value))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"thigh_length": "430"}, r"^BodyShape.thigh_length: expected a finite number of mm"),
        ({"hip_up": float("nan")}, r"^BodyShape.hip_up: expected a finite number of mm"),
        ({"aspect": ["a"] * 10}, r"^BodyShape.aspect: expected shape \(10,\)"),
        ({"radii": None}, r"^BodyShape.radii: expected shape \(10, 2\)"),
    ],
)
def test_a_shape_field_that_is_not_numbers_is_refused_naming_it(change, message):
    with pytest.raises(ValueError, match=message):
        default_shape().replace(**change)


@pytest.mark.parametrize("height", ["x", None, "1750", [1750.0], True, float("nan")])
def test_default_shape_refuses_a_height_that_is_not_a_number(height):
    with pytest.raises(ValueError, match=r"^default_shape: height must be a positive number"):
        default_shape(height)


def test_default_shape_takes_numpy_numbers():
    assert default_shape(np.float32(1750.0)) == default_shape(np.int64(1750)) == default_shape()


def test_from_vector_refuses_what_is_not_numbers():
    with pytest.raises(ValueError, match=r"^BodyShape.from_vector: expected 43 numbers"):
        BodyShape.from_vector("x" * 43)
