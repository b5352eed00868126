"""The one forward kinematics against a per-joint chain of rotation matrices.

The oracle below is the body's definition (``humotion_gym/body.py``'s module
docstring) written plainly: each joint's frame is its parent's frame times the
joint's rotation matrix, each segment a fixed offset in its joint's frame. The
compiled kinematics writes the same products out entry by entry in another
order, so the two agree to floating-point rounding: about 1e-13 relative per
operation over a chain of five rotations of metre-sized offsets and root
positions up to 10 m, well below the 1e-6 mm allowed here (a thousandth of a
micrometre: a wrong sign or axis moves a keypoint by centimetres).
"""

from __future__ import annotations

import numpy as np
import pytest

from humotion_gym import body
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.kinematics import batch_pose_geometry, kinematics_inputs, single_pose_geometry

SHAPE = body.default_shape()
ATOL_MM = 1e-6


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _oracle(pose: np.ndarray, shape: body.BodyShape) -> tuple[dict, dict]:
    """Keypoints and cone frames of one pose, joint by joint."""
    ix = body.PARAM_INDEX
    root = _rz(pose[ix["root_yaw"]]) @ _rx(pose[ix["root_pitch"]]) @ _ry(pose[ix["root_roll"]])
    pelvis = pose[:3]
    kp = {"pelvis": pelvis}
    frames = {"torso": root}
    neck_off, r_sh, l_sh, r_hip, l_hip = shape.torso_points()
    kp["neck"] = pelvis + root @ neck_off
    neck = root @ _rx(pose[ix["neck_x"]]) @ _ry(pose[ix["neck_y"]]) @ _rz(pose[ix["neck_z"]])
    frames["head"] = neck
    kp["head_top"] = kp["neck"] + neck @ np.array([0.0, 0.0, shape.head_length])
    limbs = (
        ("r", "shoulder", "elbow", "wrist", r_sh, "arm", 1.0),
        ("l", "shoulder", "elbow", "wrist", l_sh, "arm", 1.0),
        ("r", "hip", "knee", "ankle", r_hip, "leg", -1.0),
        ("l", "hip", "knee", "ankle", l_hip, "leg", -1.0),
    )
    for side, joint, hinge, tip, offset, kind, sign in limbs:
        a = [pose[ix[f"{side}_{joint}_{axis}"]] for axis in "xyz"]
        joint_frame = root @ _rx(a[0]) @ _ry(a[1]) @ _rz(a[2])
        upper = shape.upper_arm_length if kind == "arm" else shape.thigh_length
        lower = shape.forearm_length if kind == "arm" else shape.shin_length
        lower_frame = joint_frame @ _rx(sign * pose[ix[f"{side}_{hinge}"]])
        kp[f"{side}_{joint}"] = pelvis + root @ offset
        kp[f"{side}_{hinge}"] = kp[f"{side}_{joint}"] + joint_frame @ np.array([0, 0, -upper])
        kp[f"{side}_{tip}"] = kp[f"{side}_{hinge}"] + lower_frame @ np.array([0, 0, -lower])
        first, second = ("upper_arm", "forearm") if kind == "arm" else ("thigh", "shin")
        frames[f"{side}_{first}"] = joint_frame
        frames[f"{side}_{second}"] = lower_frame
    return kp, frames


def _random_poses(rng: np.random.Generator, n: int) -> np.ndarray:
    poses = rng.uniform(body.PARAM_LOWER, body.PARAM_UPPER, size=(n, 25))
    poses[:, :3] = rng.normal(0.0, 3000.0, (n, 3))
    poses[: n // 4, 3:] *= 3.0  # angles beyond the limits: every angle is periodic
    return poses


@pytest.mark.parametrize("height", [1750.0, 1500.0])
def test_forward_kinematics_equals_the_rotation_chain(height: float) -> None:
    rng = np.random.default_rng(0)
    shape = body.default_shape(height).replace(neck_forward=30.0, hip_forward=-20.0)
    poses = _random_poses(rng, 200)
    geometry = body.pose_geometry(poses, shape)
    keypoints = body.forward_kinematics(poses, shape)
    rotations = body.cone_geometry(poses, shape).rotations
    for n, pose in enumerate(poses):
        kp, frames = _oracle(pose, shape)
        want = np.array([kp[name] for name in body.KEYPOINT_NAMES])
        np.testing.assert_allclose(keypoints[n], want, atol=ATOL_MM, rtol=0)
        for c, cone in enumerate(body.CONE_NAMES):
            # Axes are unit vectors: 1e-12 is a few hundred ulps.
            np.testing.assert_allclose(geometry[n, 15 + 2 * c], frames[cone][:, 0], atol=1e-12)
            np.testing.assert_allclose(geometry[n, 16 + 2 * c], frames[cone][:, 1], atol=1e-12)
            np.testing.assert_allclose(rotations[n, c], frames[cone], atol=1e-12)


def test_any_leading_axes_and_bad_input() -> None:
    poses = _random_poses(np.random.default_rng(1), 24)
    flat = body.forward_kinematics(poses, SHAPE)
    assert body.forward_kinematics(poses.reshape(2, 3, 4, 25), SHAPE).shape == (2, 3, 4, 15, 3)
    np.testing.assert_array_equal(
        body.forward_kinematics(poses.reshape(2, 3, 4, 25), SHAPE).reshape(24, 15, 3), flat
    )
    assert body.forward_kinematics(poses[0], SHAPE).shape == (15, 3)
    with pytest.raises(ValueError, match=r"\(\.\.\., 25\)"):
        body.forward_kinematics(np.zeros((3, 24)), SHAPE)


@pytest.mark.parametrize("n", [6, 150])  # a partial block of poses; whole blocks and one
def test_per_pose_shapes(n: int) -> None:
    poses = _random_poses(np.random.default_rng(2), n)
    shapes = [body.default_shape(1400.0 + 600.0 * i / n) for i in range(n)]
    tables = np.stack([body.shape_table(s) for s in shapes])
    got = body.pose_geometry_of(poses, tables)
    for i, shape in enumerate(shapes):
        np.testing.assert_array_equal(got[i], body.pose_geometry(poses[i], shape))
    with pytest.raises(ValueError, match="shape tables"):
        body.pose_geometry_of(poses, tables[:2])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_blocks_of_poses_are_the_poses_one_by_one(dtype: type) -> None:
    """The kinematics works on blocks of poses: every count around a block's size."""
    rng = np.random.default_rng(3)
    for n in (0, 1, 63, 64, 65, 129, 300):
        poses = _random_poses(rng, n)
        got = body.pose_geometry(poses, SHAPE, dtype)
        assert got.shape == (n, 35, 3) and got.dtype == dtype
        want = np.array([body.pose_geometry(pose, SHAPE, dtype) for pose in poses], dtype)
        np.testing.assert_array_equal(got, want.reshape(n, 35, 3))


def test_single_precision_geometry_is_within_rounding() -> None:
    """float32 geometry (the likelihood's) against float64.

    A keypoint is the root position (rounded once to float32) plus a chain of
    rotated segments under 2 m long, each product and sum rounded at 2^-24
    relative: a few float32 epsilons of ``|x| + 2000 mm``; 2 of them bound it.
    Within 2 m of the origin that is under 1e-3 mm (the likelihood's
    placement needs 1e-2). Unit axes: a few epsilons, 1e-6.
    """
    rng = np.random.default_rng(7)
    shape = body.default_shape(1700.0)
    poses = _random_poses(rng, 2000)
    want = body.pose_geometry(poses, shape)
    got = body.pose_geometry(poses, shape, np.float32)
    assert got.dtype == np.float32
    eps = float(np.finfo(np.float32).eps)
    bound = 2.0 * eps * (np.abs(want[:, :15]) + 2000.0)
    assert np.all(np.abs(got[:, :15] - want[:, :15]) <= bound)
    np.testing.assert_allclose(got[:, 15:], want[:, 15:], atol=1e-6, rtol=0)
    poses[:, :3] = rng.uniform(-1150.0, 1150.0, (2000, 3))  # |root| < 2 m
    near = body.pose_geometry(poses, shape)
    np.testing.assert_allclose(
        body.pose_geometry(poses, shape, np.float32)[:, :15], near[:, :15], atol=1e-3, rtol=0
    )


def test_layouts_of_the_same_geometry() -> None:
    rng = np.random.default_rng(5)
    poses = _random_poses(rng, 12)
    shape = body.default_shape(1600.0).replace(neck_forward=25.0)
    world = body.pose_geometry(poses, shape)
    cams = [
        Camera.look_at(rng.normal(0.0, 3000.0, 3), rng.normal(0.0, 100.0, 3), 64, 64, 50.0)
        for _ in range(12)
    ]
    moving = batch_pose_geometry(
        poses, shape, np.stack([c.rotation for c in cams]), np.stack([c.translation for c in cams])
    )
    for t, cam in enumerate(cams):
        np.testing.assert_allclose(moving[t, :15], cam.to_camera(world[t, :15]), atol=ATOL_MM)
        np.testing.assert_allclose(moving[t, 15:], world[t, 15:] @ cam.rotation.T, atol=1e-12)
        np.testing.assert_allclose(
            single_pose_geometry(poses[t], shape, cam.rotation, cam.translation), moving[t],
            atol=ATOL_MM,
        )  # fmt: skip
    with pytest.raises(ValueError, match=r"\(T, 25\)"):
        batch_pose_geometry(poses[0], shape)
    with pytest.raises(ValueError, match="rotation"):
        batch_pose_geometry(poses, shape, np.eye(3)[None].repeat(5, axis=0))
    with pytest.raises(ValueError, match="translation"):
        batch_pose_geometry(poses, shape, np.eye(3), np.zeros((5, 3)))
    fit_camera(world[:, :15], 64, 64, 50.0)  # the keypoints frame a camera


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.float16, np.complex128, None, "x"])
def test_a_dtype_the_kinematics_has_not_is_refused(dtype: object) -> None:
    """An integer type truncated every angle silently; float16 failed deep inside numba."""
    pose = body.standing_pose(SHAPE)
    pose[3], pose[9] = 0.3, 0.7
    with pytest.raises(ValueError, match=r"^pose_geometry: dtype must be np.float64 or np.float32"):
        body.pose_geometry(pose, SHAPE, dtype=dtype)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^kinematics_inputs: dtype must be np.float64"):
        kinematics_inputs(pose[None], body.shape_table(SHAPE)[None], dtype)  # type: ignore[arg-type]


def test_the_two_dtypes_in_any_spelling() -> None:
    poses = _random_poses(np.random.default_rng(4), 5)
    for kind, spellings in ((np.float32, ["float32", np.dtype(np.float32)]),
                            (np.float64, ["f8", np.dtype(np.float64), float])):  # fmt: skip
        want = body.pose_geometry(poses, SHAPE, kind)
        for dtype in spellings:
            got = body.pose_geometry(poses, SHAPE, dtype)  # type: ignore[arg-type]
            assert got.dtype == kind
            np.testing.assert_array_equal(got, want)


def test_a_translation_alone_moves_the_keypoints() -> None:
    """No rotation is the identity: the translation was dropped without one."""
    poses = _random_poses(np.random.default_rng(6), 4)
    world = body.pose_geometry(poses, SHAPE)
    shift = np.array([0.0, 0.0, 1000.0])
    per_pose = np.arange(12.0).reshape(4, 3)
    for t in (shift, per_pose):
        got = batch_pose_geometry(poses, SHAPE, translation=t)
        np.testing.assert_array_equal(got, batch_pose_geometry(poses, SHAPE, np.eye(3), t))
        np.testing.assert_allclose(got[:, :15], world[:, :15] + np.reshape(t, (-1, 1, 3)))
        np.testing.assert_array_equal(got[:, 15:], world[:, 15:])  # axes are not moved
    np.testing.assert_array_equal(
        single_pose_geometry(poses[0], SHAPE, translation=shift),
        single_pose_geometry(poses[0], SHAPE, np.eye(3), shift),
    )
    for bad in (np.zeros(2), np.zeros((4, 2)), "abc"):
        with pytest.raises(ValueError, match=r"translation must be \(3,\) or \(4, 3\)"):
            batch_pose_geometry(poses, SHAPE, translation=bad)


def test_what_is_not_a_shape_or_its_tables_is_refused() -> None:
    pose = body.standing_pose(SHAPE)
    for call in (body.forward_kinematics, body.pose_geometry, body.cone_geometry):
        with pytest.raises(TypeError, match="shape: expected a BodyShape"):
            call(pose, "x")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="shape: expected a BodyShape"):
        body.standing_pose(None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="shape: expected a BodyShape"):
        body.shape_table(1750.0)  # type: ignore[arg-type]
    for tables in (np.zeros(5), np.zeros((2, 2, 24)), np.zeros(48), [["a"] * 24]):
        with pytest.raises(ValueError, match=r"^pose_geometry_of: tables must be \(24,\) or"):
            body.pose_geometry_of(pose[None], tables)
    table = body.shape_table(SHAPE)
    for tables in (table, table[None]):  # one for all, as documented
        np.testing.assert_array_equal(
            body.pose_geometry_of(pose[None], tables)[0], body.pose_geometry(pose, SHAPE)
        )


def test_mutation_a_wrong_sign_is_caught() -> None:
    """The oracle would see a knee bent forward (the check is not vacuous)."""
    pose = body.standing_pose(SHAPE)
    pose[body.PARAM_INDEX["r_knee"]] = 1.0
    kp, _ = _oracle(pose, SHAPE)
    flipped = pose.copy()
    flipped[body.PARAM_INDEX["r_knee"]] = -1.0
    got = body.forward_kinematics(flipped, SHAPE)[body.KEYPOINT_INDEX["r_ankle"]]
    assert np.linalg.norm(got - kp["r_ankle"]) > 100.0
