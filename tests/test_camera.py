"""Tests of the pinhole camera, its projection and fit_camera."""

from __future__ import annotations

import math
import warnings

import cv2
import numpy as np
import pytest

from humotion_gym import body
from humotion_gym.camera import (
    Camera,
    fit_camera,
    fit_cameras,
    side_view_azimuth,
    view_direction,
)

SHAPE = body.default_shape()


def _camera(width: int = 160, height: int = 120, fov: float = 60.0) -> Camera:
    return Camera.look_at((1000.0, -3000.0, 1500.0), (0.0, 0.0, 900.0), width, height, fov)


def _walk_clip(steps: int = 60, speed_mm: float = 25.0, heading: float = 0.0) -> np.ndarray:
    """Keypoints (T, 15, 3) of a crude walk along the heading."""
    t = np.arange(steps)
    poses = np.tile(body.standing_pose(SHAPE, yaw=heading), (steps, 1))
    direction = np.array([-math.sin(heading), math.cos(heading)])  # facing +y at yaw 0
    poses[:, 0:2] += (speed_mm * t)[:, None] * direction
    swing = 0.5 * np.sin(2 * np.pi * t / 30)
    poses[:, body.PARAM_INDEX["r_hip_x"]] = swing
    poses[:, body.PARAM_INDEX["l_hip_x"]] = -swing
    poses[:, body.PARAM_INDEX["r_knee"]] = 0.6 * np.maximum(0, -swing)
    poses[:, body.PARAM_INDEX["l_knee"]] = 0.6 * np.maximum(0, swing)
    poses[:, body.PARAM_INDEX["r_shoulder_x"]] = -0.6 * swing
    poses[:, body.PARAM_INDEX["l_shoulder_x"]] = 0.6 * swing
    return body.forward_kinematics(poses, SHAPE)


def test_point_on_optical_axis_projects_to_centre() -> None:
    cam = _camera()
    for distance in (500.0, 2000.0, 9000.0):
        point = cam.position + distance * cam.forward
        u, v = cam.project(point)
        assert u == pytest.approx((cam.width - 1) / 2, abs=1e-9)
        assert v == pytest.approx((cam.height - 1) / 2, abs=1e-9)
        assert cam.depth(point) == pytest.approx(distance)


def test_pixel_scale_follows_vertical_fov() -> None:
    cam = Camera(200, 100, 90.0, np.eye(3), np.zeros(3))
    assert cam.focal == pytest.approx(50.0)  # (H / 2) / tan(45 deg)
    # A point at the top edge of the field of view lands on the image's top edge.
    u, v = cam.project(np.array([0.0, -1000.0, 1000.0]))
    assert v == pytest.approx(-0.5)
    assert u == pytest.approx(99.5)
    # 1 mm at 100 mm depth spans focal / 100 pixels.
    assert cam.pixels_per_mm(100.0) == pytest.approx(0.5)
    np.testing.assert_allclose(cam.pixels_per_mm([50.0, 200.0]), [1.0, 0.25])


def test_projection_matches_opencv() -> None:
    cam = _camera()
    rng = np.random.default_rng(0)
    points = rng.uniform([-800, -800, 0], [800, 800, 1800], size=(50, 3))
    rvec, _ = cv2.Rodrigues(cam.rotation)
    expected, _ = cv2.projectPoints(points, rvec, cam.translation, cam.intrinsics, None)
    np.testing.assert_allclose(cam.project(points), expected[:, 0], atol=1e-6)


def test_batched_shapes_and_to_camera() -> None:
    cam = _camera()
    rng = np.random.default_rng(1)
    points = rng.uniform(-500, 500, size=(2, 3, 4, 3)) + np.array([0, 0, 900.0])
    px = cam.project(points)
    assert px.shape == (2, 3, 4, 2)
    assert cam.depth(points).shape == (2, 3, 4)
    cam_pts = cam.to_camera(points)
    assert cam_pts.shape == (2, 3, 4, 3)
    np.testing.assert_allclose(cam_pts[..., 2], cam.depth(points))
    # Projection is the pinhole division of camera coordinates.
    np.testing.assert_allclose(
        px[..., 0], cam.focal * cam_pts[..., 0] / cam_pts[..., 2] + (cam.width - 1) / 2
    )
    # Each point projects the same alone as in the batch.
    np.testing.assert_allclose(cam.project(points[1, 2, 3]), px[1, 2, 3])


def test_points_behind_camera_are_nan() -> None:
    cam = _camera()
    behind = cam.position - 100.0 * cam.forward
    assert np.all(np.isnan(cam.project(behind)))
    assert not cam.in_image(cam.project(behind))
    # depth exactly 0 (beside the camera centre, in its image plane) is "at or behind": nan too
    on_plane = Camera(40, 30, 60.0, np.eye(3), np.zeros(3))
    assert np.all(np.isnan(on_plane.project(np.array([100.0, 50.0, 0.0]))))


def test_in_image_holds_the_edges_of_the_edge_pixels() -> None:
    """Pixel centres 0..W-1: the image spans [-0.5, W - 0.5] x [-0.5, H - 0.5], edges included."""
    cam = Camera(40, 30, 60.0, np.eye(3), np.zeros(3))
    inside = [[-0.5, -0.5], [39.5, 29.5], [-0.5, 29.5], [39.5, -0.5], [19.5, 14.5]]
    outside = [[-0.51, 0.0], [39.51, 0.0], [0.0, -0.51], [0.0, 29.51], [np.nan, 0.0]]
    np.testing.assert_array_equal(cam.in_image(np.array(inside)), True)
    np.testing.assert_array_equal(cam.in_image(np.array(outside)), False)


def test_look_at_is_orthonormal_and_upright() -> None:
    rng = np.random.default_rng(2)
    for _ in range(20):
        eye = rng.uniform(-5000, 5000, 3)
        target = rng.uniform(-500, 500, 3)
        cam = Camera.look_at(eye, target, 64, 48, 40.0)
        r = cam.rotation
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        direction = (target - eye) / np.linalg.norm(target - eye)
        np.testing.assert_allclose(cam.forward, direction, atol=1e-12)
        # World up points up in the image (smaller row), unless looking along it.
        above = cam.project(target + np.array([0.0, 0.0, 10.0]))
        below = cam.project(target)
        if abs(direction[2]) < 0.99:
            assert above[1] < below[1]


def test_look_at_straight_down_uses_fallback_up() -> None:
    cam = Camera.look_at((0.0, 0.0, 5000.0), (0.0, 0.0, 0.0), 64, 64, 50.0)
    np.testing.assert_allclose(cam.rotation @ cam.rotation.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(cam.forward, [0.0, 0.0, -1.0])


def test_look_at_gives_what_the_checked_constructor_accepts() -> None:
    # look_at builds its camera without the constructor's checks (a rotation
    # from orthonormal axes): the constructor accepts it, equal, read-only,
    # and the camera keeps its own copy of the eye.
    rng = np.random.default_rng(4)
    for _ in range(50):
        eye, target = rng.uniform(-5000, 5000, 3), rng.uniform(-500, 500, 3)
        cam = Camera.look_at(eye, target, 96, 64, 45)
        checked = Camera(96, 64, 45.0, cam.rotation, cam.position)
        assert cam == checked and hash(cam) == hash(checked)
        assert isinstance(cam.width, int) and isinstance(cam.fov_deg, float)
        assert not cam.rotation.flags.writeable and not cam.position.flags.writeable
        eye[:] = 0.0
        np.testing.assert_array_equal(cam.position, checked.position)


@pytest.mark.parametrize("eye", [(np.nan, 0.0, 0.0), (np.inf, 0.0, 0.0), (0.0, -np.inf, 1.0)])
def test_look_at_refuses_points_that_are_not_finite(eye: tuple) -> None:
    with pytest.raises(ValueError, match="distinct finite"):
        Camera.look_at(eye, (0.0, 1.0, 0.0), 64, 64, 50.0)
    with pytest.raises(ValueError, match="distinct finite"):
        Camera.look_at((0.0, 1.0, 0.0), eye, 64, 64, 50.0)


def test_fit_camera_looks_along_the_view_direction_from_the_fitted_distance() -> None:
    # fit_camera's camera is look_at's from the box's centre along
    # view_direction; its rotation is the one it measured the points in (to
    # rounding: that one looks from a unit step along the direction).
    pts = np.random.default_rng(5).uniform(-800, 800, (40, 3))
    cam = fit_camera(pts, 128, 96, 45.0, 30.0, 10.0, 0.1, 150.0)
    target = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    direction = view_direction(30.0, 10.0)
    probe = Camera.look_at(target + direction, target, 128, 96, 45.0)
    np.testing.assert_allclose(cam.rotation, probe.rotation, atol=1e-12)
    distance = float(np.linalg.norm(cam.position - target))
    np.testing.assert_allclose(cam.position, target + distance * direction, atol=1e-9)
    assert distance > 500.0


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (((0, 0, 0), (0, 0, 0), 64, 64, 50.0), "distinct"),
        (((0, 0, 0), (0, 1, 0), 0, 64, 50.0), "at least 2 pixels, got 0x64"),
        (((0, 0, 0), (0, 1, 0), 64, -1, 50.0), "at least 2 pixels"),
        (((0, 0, 0), (0, 1, 0), 1, 64, 50.0), "at least 2 pixels, got 1x64"),  # no half-width
        (((0, 0), (0, 1, 0), 64, 64, 50.0), r"eye must be 3 numbers, got \(0, 0\)"),
        (((0, 0, 0), (0, 1), 64, 64, 50.0), "target must be 3 numbers"),
        (((0, 0, 0), (0, 1, 0), 64, 64, "50"), "fov_deg must be a number"),
        (((0, 0, 0), (0, 1, 0), 64, 64, 0.5), "fov"),
        (((0, 0, 0), (0, 1, 0), 64, 64, 179.0), "fov"),
        (((0, 0, 0), (0, 1, 0), 64.5, 64, 50.0), "integers"),
        (((0, 0, 0), (0, 1, 0), 64, True, 50.0), "integers"),  # a bool is no size
    ],
)
def test_bad_arguments_raise(args: tuple, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Camera.look_at(*args)


def test_bad_rotation_raises() -> None:
    with pytest.raises(ValueError, match="rotation"):
        Camera(64, 64, 50.0, np.ones((3, 3)), np.zeros(3))
    with pytest.raises(ValueError, match="rotation"):
        Camera(64, 64, 50.0, -np.eye(3), np.zeros(3))  # a reflection
    with pytest.raises(ValueError, match="depth"):
        _camera().pixels_per_mm(0.0)
    with pytest.raises(ValueError, match="points"):
        _camera().project(np.zeros((4, 2)))


def test_rotation_check_tolerance() -> None:
    # Nearly orthonormal (1e-7 off) passes; 1e-4 off, a shear, fails.
    r = np.eye(3)
    r[0, 1] = 1e-7
    Camera(64, 64, 50.0, r, np.zeros(3))
    r[0, 1] = 1e-4
    with pytest.raises(ValueError, match="rotation"):
        Camera(64, 64, 50.0, r, np.zeros(3))


def test_shifted_cameras_are_moved_copies() -> None:
    base = _camera()
    offsets = np.array([[0.0, 0.0, 0.0], [100.0, -50.0, 20.0], [-3.0, 4.0, 5.0]])
    moved = base.shifted(offsets)
    points = np.array([[10.0, 20.0, 30.0], [-400.0, 100.0, 900.0]])
    for cam, off in zip(moved, offsets, strict=True):
        same = Camera(base.width, base.height, base.fov_deg, base.rotation, base.position + off)
        assert cam == same and hash(cam) == hash(same)
        assert cam.rotation is base.rotation and not cam.position.flags.writeable
        np.testing.assert_allclose(cam.translation, same.translation)
        np.testing.assert_allclose(cam.project(points + off), base.project(points), atol=1e-9)
        assert cam.focal == base.focal and np.array_equal(cam.intrinsics, base.intrinsics)
    for bad in (np.zeros(3), np.zeros((2, 2)), np.array([[0.0, np.nan, 0.0]])):
        with pytest.raises(ValueError, match="offsets"):
            base.shifted(bad)


def test_camera_equality_and_hash() -> None:
    a, b = _camera(), _camera()
    assert a == b and hash(a) == hash(b)
    assert a != _camera(width=161)


@pytest.mark.parametrize(("width", "height"), [(64, 64), (128, 128), (320, 240), (640, 480)])
@pytest.mark.parametrize(("azimuth", "elevation"), [(0.0, 0.0), (30.0, 10.0), (200.0, 45.0)])
def test_fit_camera_keeps_clip_in_frame(
    width: int, height: int, azimuth: float, elevation: float
) -> None:
    clip = _walk_clip(heading=0.4)
    cam = fit_camera(clip, width, height, 50.0, azimuth, elevation, margin=0.1)
    px = cam.project(clip)
    assert np.all(cam.in_image(px))
    assert np.all(cam.depth(clip) > 0)
    # With the margin, points stay at least ~10% of the half-size from the border.
    cx, cy = cam.principal_point
    assert np.abs(px[..., 0] - cx).max() <= 0.9 * cx + 1e-6
    assert np.abs(px[..., 1] - cy).max() <= 0.9 * cy + 1e-6
    # It is not absurdly far: the clip fills a good part of the frame.
    extent = max(np.ptp(px[..., 0]) / width, np.ptp(px[..., 1]) / height)
    assert extent > 0.35


def test_fit_camera_close_up_of_arm() -> None:
    pose = body.standing_pose(SHAPE)
    pose[body.PARAM_INDEX["r_shoulder_x"]] = 1.0
    pose[body.PARAM_INDEX["r_elbow"]] = 1.2
    kp = body.forward_kinematics(pose, SHAPE)
    arm = kp[[body.KEYPOINT_INDEX[n] for n in ("r_shoulder", "r_elbow", "r_wrist")]]
    cam = fit_camera(arm[None], 128, 128, 40.0, azimuth_deg=-90.0, elevation_deg=0.0)
    px = cam.project(arm)
    assert np.all(cam.in_image(px))
    whole = fit_camera(kp[None], 128, 128, 40.0, azimuth_deg=-90.0, elevation_deg=0.0)
    # The close-up is nearer than a view of the whole body.
    assert np.linalg.norm(cam.position - arm.mean(0)) < np.linalg.norm(whole.position - kp.mean(0))


def test_side_view_is_perpendicular_to_walking() -> None:
    for heading in (0.0, 0.7, -2.0):
        clip = _walk_clip(heading=heading)
        pelvis = clip[:, body.KEYPOINT_INDEX["pelvis"]]
        azimuth = side_view_azimuth(pelvis)
        travel = pelvis[-1] - pelvis[0]
        travel /= np.linalg.norm(travel)
        assert abs(view_direction(azimuth, 0.0) @ travel) < 1e-6
        cam = fit_camera(clip, 128, 96, 50.0, azimuth, 5.0)
        assert np.all(cam.in_image(cam.project(clip)))
    assert side_view_azimuth(np.zeros((5, 3))) == 90.0


def test_view_direction_convention() -> None:
    np.testing.assert_allclose(view_direction(0.0, 0.0), [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(view_direction(90.0, 0.0), [-1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(view_direction(0.0, 90.0), [0.0, 0.0, 1.0], atol=1e-12)


def test_fit_camera_bad_arguments() -> None:
    clip = _walk_clip(steps=5)
    with pytest.raises(ValueError, match="margin"):
        fit_camera(clip, 64, 64, 50.0, margin=0.95)
    with pytest.raises(ValueError, match="elevation"):
        fit_camera(clip, 64, 64, 50.0, elevation_deg=90.0)
    with pytest.raises(ValueError, match="finite"):
        fit_camera(np.full((2, 15, 3), np.nan), 64, 64, 50.0)
    # one bad number among finite points, in any column, is found
    for bad in (np.nan, np.inf, -np.inf):
        for column in range(3):
            points = clip.copy()
            points[3, 7, column] = bad
            with pytest.raises(ValueError, match="finite"):
                fit_camera(points, 64, 64, 50.0)
    with pytest.raises(ValueError, match="at least one point"):
        fit_camera(np.zeros((0, 3)), 64, 64, 50.0)
    with pytest.raises(ValueError, match="fov"):
        fit_camera(clip, 64, 64, 200.0)


@pytest.mark.parametrize("seed", range(6))
def test_fit_cameras_are_fit_cameras_bit_for_bit(seed: int) -> None:
    # Sets of every size and spread, anywhere, seen from any azimuth and
    # elevation, with their own pads: each camera is fit_camera's own.
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 24)), int(rng.integers(1, 160))
    points = rng.normal(0.0, rng.uniform(1.0, 3000.0), (n, m, 3))
    points += rng.normal(0.0, 5000.0, (n, 1, 3))
    azimuths, pads = rng.uniform(-720.0, 720.0, n), rng.uniform(0.0, 400.0, n)
    pads[0] = 0.0
    width, height = (int(v) for v in rng.integers(8, 400, 2))
    fov, elevation, margin = rng.uniform(5.0, 170.0), rng.uniform(-89.0, 89.0), rng.uniform(0, 0.9)
    cameras = fit_cameras(points, width, height, fov, azimuths, elevation, margin, pads)
    assert len(cameras) == n
    for j, camera in enumerate(cameras):
        alone = fit_camera(points[j], width, height, fov, azimuths[j], elevation, margin, pads[j])
        np.testing.assert_array_equal(camera.rotation, alone.rotation)
        np.testing.assert_array_equal(camera.position, alone.position)
        assert (camera.width, camera.height, camera.fov_deg) == (width, height, fov)


def test_fit_cameras_take_one_azimuth_and_pad_for_all() -> None:
    points = np.stack([_walk_clip(steps=5).reshape(-1, 3), _walk_clip(steps=7)[:5].reshape(-1, 3)])
    both = fit_cameras(points, 96, 64, 45.0, 30.0, 12.0, 0.2, 80.0)
    for camera, alone in zip(
        both, [fit_camera(p, 96, 64, 45.0, 30.0, 12.0, 0.2, 80.0) for p in points], strict=True
    ):
        np.testing.assert_array_equal(camera.position, alone.position)
    assert fit_cameras(np.zeros((0, 4, 3)), 64, 64, 50.0, []) == []


def test_fit_cameras_bad_arguments() -> None:
    points = np.stack([_walk_clip(steps=5).reshape(-1, 3)] * 3)
    with pytest.raises(ValueError, match=r"\(E, M > 0, 3\)"):
        fit_cameras(points[0], 64, 64, 50.0, 0.0)
    with pytest.raises(ValueError, match=r"\(E, M > 0, 3\)"):
        fit_cameras(np.zeros((2, 0, 3)), 64, 64, 50.0, 0.0)
    with pytest.raises(ValueError, match="one number or 3"):
        fit_cameras(points, 64, 64, 50.0, [0.0, 1.0])
    with pytest.raises(ValueError, match="one number or 3"):
        fit_cameras(points, 64, 64, 50.0, 0.0, pads_mm=[1.0, 2.0])
    with pytest.raises(ValueError, match="azimuths_deg must be finite numbers"):
        fit_cameras(points, 64, 64, 50.0, [0.0, np.nan, 1.0])
    with pytest.raises(ValueError, match="azimuths_deg must be finite numbers"):
        fit_cameras(points, 64, 64, 50.0, ["5", "6", "7"])  # not read as numbers
    with pytest.raises(ValueError, match="pads_mm must be finite numbers >= 0"):
        fit_cameras(points, 64, 64, 50.0, 0.0, pads_mm=[1.0, -1.0, 2.0])
    with pytest.raises(ValueError, match="pads_mm must be finite numbers >= 0"):
        fit_cameras(points, 64, 64, 50.0, 0.0, pads_mm=np.inf)
    with pytest.raises(ValueError, match="fit_cameras: min_distance_mm: expected a positive"):
        fit_cameras(points, 64, 64, 50.0, 0.0, min_distance_mm=np.nan)
    with pytest.raises(ValueError, match="margin"):
        fit_cameras(points, 64, 64, 50.0, 0.0, margin=0.95)
    with pytest.raises(ValueError, match="elevation"):
        fit_cameras(points, 64, 64, 50.0, 0.0, elevation_deg=-90.0)
    with pytest.raises(ValueError, match="fov"):
        fit_cameras(points, 64, 64, 0.5, 0.0)
    for bad in (np.nan, np.inf):
        broken = points.copy()
        broken[2, 11, 1] = bad
        with pytest.raises(ValueError, match="finite"):
            fit_cameras(broken, 64, 64, 50.0, 0.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        # each failed as "Camera.look_at: eye and target must be distinct finite
        # points", arguments the caller never gave (a width of 1 dividing by 0)
        ({"width": 1}, "width and height must be at least 2 pixels, got 1x64"),
        ({"height": 1}, "width and height must be at least 2 pixels, got 64x1"),
        ({"azimuth_deg": float("nan")}, "azimuth_deg must be a finite number, got nan"),
        ({"azimuth_deg": "30"}, "azimuth_deg must be a finite number, got '30'"),
        ({"min_distance_mm": float("inf")}, "min_distance_mm: expected a positive finite"),
        ({"min_distance_mm": 0.0}, "min_distance_mm: expected a positive finite"),
        ({"pad_mm": float("inf")}, "pad_mm: expected a finite number >= 0, got inf"),
        ({"pad_mm": -1.0}, "pad_mm: expected a finite number >= 0"),
        ({"elevation_deg": "10"}, r"elevation_deg must lie in \[-89, 89\], got '10'"),
        ({"margin": "0.1"}, r"margin must lie in \[0, 0.9\], got '0.1'"),
    ],
)
def test_fit_camera_names_the_argument_it_cannot_take(kwargs: dict, message: str) -> None:
    arguments = {"width": 64, "height": 64, "fov_deg": 50.0} | kwargs
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division by zero on the way
        with pytest.raises(ValueError, match=f"^fit_camera: {message}"):
            fit_camera(_walk_clip(steps=3), **arguments)


def test_from_vector_takes_the_size_as_given() -> None:
    camera = _camera()
    vector = camera.to_vector()
    assert Camera.from_vector(vector, np.int64(160), 120) == camera
    # int() cut 160.7 to 160 and read "12" as 12
    for width in (160.7, "12", True):
        with pytest.raises(ValueError, match="Camera.from_vector: width and height must be"):
            Camera.from_vector(vector, width, 120)
    with pytest.raises(ValueError, match="at least 2 pixels"):
        Camera.from_vector(vector, 1, 120)
