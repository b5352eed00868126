"""Tests of the cone-body renderer."""

from __future__ import annotations

import numpy as np
import pytest

from humotion_gym import body
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.kinematics import batch_pose_geometry
from humotion_gym.render import (
    DEFAULT_FIGURE_COLORS,
    SceneOptions,
    draw_pose_overlay,
    figure_sequence,
    make_background,
    noise_bank,
    render,
    render_frame,
)

SHAPE = body.default_shape()
PI = body.PARAM_INDEX


def _pose() -> np.ndarray:
    pose = body.standing_pose(SHAPE, yaw=0.3)
    pose[PI["r_shoulder_x"]] = 0.8
    pose[PI["r_elbow"]] = 1.0
    pose[PI["l_hip_x"]] = 0.4
    pose[PI["l_knee"]] = 0.7
    return pose


def _camera(scene: SceneOptions, pose: np.ndarray, azimuth: float = 20.0):
    kp = body.forward_kinematics(pose, SHAPE)
    return fit_camera(kp[None], scene.width, scene.height, 50.0, azimuth, 10.0)


def test_same_pose_scene_and_seed_give_the_same_frame() -> None:
    scene = SceneOptions(occluders=2)
    pose = _pose()
    cam = _camera(scene, pose)
    a = render(pose, SHAPE, cam, scene, np.random.default_rng(7))
    b = render(pose, SHAPE, cam, scene, np.random.default_rng(7))
    assert a.dtype == np.uint8 and a.shape == (128, 128, 3)
    np.testing.assert_array_equal(a, b)
    # The same with an explicit background and a sequence of frames.
    frames = []
    for _ in range(2):
        rng = np.random.default_rng(11)
        background = make_background(scene, rng)
        frames.append(
            [render(pose, SHAPE, cam, scene, rng, background, frame_index=k) for k in range(3)]
        )
    for x, y in zip(*frames, strict=True):
        np.testing.assert_array_equal(x, y)


def test_different_seeds_differ_with_clutter_and_noise() -> None:
    pose = _pose()
    clutter = SceneOptions(noise_sigma=0.0)
    cam = _camera(clutter, pose)
    a = render(pose, SHAPE, cam, clutter, np.random.default_rng(1))
    b = render(pose, SHAPE, cam, clutter, np.random.default_rng(2))
    assert np.mean(a != b) > 0.05  # different rooms
    noisy = SceneOptions(background="flat", noise_sigma=4.0)
    a = render(pose, SHAPE, cam, noisy, np.random.default_rng(1))
    b = render(pose, SHAPE, cam, noisy, np.random.default_rng(2))
    assert np.mean(a != b) > 0.3  # different noise
    # Without clutter or noise nothing is random.
    plain = SceneOptions(background="flat", noise_sigma=0.0)
    a = render(pose, SHAPE, cam, plain, np.random.default_rng(1))
    b = render(pose, SHAPE, cam, plain, np.random.default_rng(2))
    np.testing.assert_array_equal(a, b)


def test_noise_frames_change_within_an_episode() -> None:
    scene = SceneOptions(background="flat")
    pose = _pose()
    cam = _camera(scene, pose)
    rng = np.random.default_rng(3)
    background = make_background(scene, rng)
    a = render(pose, SHAPE, cam, scene, rng, background)
    b = render(pose, SHAPE, cam, scene, rng, background)
    assert np.mean(a != b) > 0.3


@pytest.mark.parametrize(
    ("width", "height"), [(64, 64), (128, 128), (160, 120), (256, 256), (640, 480)]
)
@pytest.mark.parametrize("color", ["rgb", "gray"])
def test_every_size_and_colour(width: int, height: int, color: str) -> None:
    scene = SceneOptions(width=width, height=height, color=color, occluders=1)
    pose = _pose()
    cam = _camera(scene, pose)
    frame = render(pose, SHAPE, cam, scene, np.random.default_rng(0))
    assert frame.dtype == np.uint8
    assert frame.shape == (height, width, 3 if color == "rgb" else 1)
    assert frame.flags.c_contiguous


def test_figure_is_drawn_where_the_keypoints_project() -> None:
    scene = SceneOptions(width=256, height=256, background="flat", noise_sigma=0.0)
    pose = _pose()
    cam = _camera(scene, pose)
    frame = render(pose, SHAPE, cam, scene, np.random.default_rng(0))
    background = np.array(scene.background_color)
    geometry = body.cone_geometry(pose, SHAPE)
    mids = cam.project(0.5 * (geometry.starts + geometry.ends))  # cone middles
    for u, v in np.rint(mids).astype(int):
        assert np.abs(frame[v, u].astype(int) - background).max() > 20
    # Far from the figure, the background is untouched.
    np.testing.assert_array_equal(frame[0, 0], background)
    # The figure covers a plausible part of the frame.
    covered = np.abs(frame.astype(int) - background).max(axis=2) > 0
    assert 0.03 < covered.mean() < 0.5


def test_cones_are_shaded_not_flat() -> None:
    scene = SceneOptions(width=320, height=240, background="flat", noise_sigma=0.0)
    pose = body.standing_pose(SHAPE)
    cam = _camera(scene, pose, azimuth=0.0)
    frame = render(pose, SHAPE, cam, scene, np.random.default_rng(0))
    torso_mid = cam.project(body.forward_kinematics(pose, SHAPE)[[0, 7]].mean(axis=0))
    u, v = np.rint(torso_mid).astype(int)
    row = frame[v, u - 15 : u + 16].astype(int)
    # Several shades across the torso, all reddish (the shirt).
    assert len({tuple(c) for c in row}) >= 2
    assert np.all(row[:, 0] > row[:, 2])


def _crossing_arm_pose() -> np.ndarray:
    """The right forearm held across the chest, in front of the torso."""
    pose = body.standing_pose(SHAPE)
    pose[PI["r_shoulder_x"]] = 0.7  # upper arm a little forward
    pose[PI["r_shoulder_z"]] = np.pi / 2  # turn the elbow's bending plane inwards
    pose[PI["r_elbow"]] = np.pi / 2  # forearm across the body, towards the left
    return pose


def test_near_cone_is_drawn_over_far_cone() -> None:
    colors = list(DEFAULT_FIGURE_COLORS)
    colors[body.CONE_NAMES.index("torso")] = (220, 20, 20)  # red torso
    colors[body.CONE_NAMES.index("r_forearm")] = (20, 220, 20)  # green forearm
    scene = SceneOptions(
        width=256, height=256, background="flat", noise_sigma=0.0, figure_colors=tuple(colors)
    )
    pose = _crossing_arm_pose()
    kp = body.forward_kinematics(pose, SHAPE)
    elbow, wrist = kp[body.KEYPOINT_INDEX["r_elbow"]], kp[body.KEYPOINT_INDEX["r_wrist"]]
    forearm_mid = 0.5 * (elbow + wrist)
    # From the front the forearm is nearer than the torso; from behind, farther.
    for azimuth, near_is_forearm in ((0.0, True), (180.0, False)):
        cam = fit_camera(kp[None], 256, 256, 50.0, azimuth, 0.0)
        frame = render(pose, SHAPE, cam, scene, np.random.default_rng(0))
        u, v = np.rint(cam.project(forearm_mid)).astype(int)
        r, g, _ = frame[v, u].astype(int)
        if near_is_forearm:
            assert g > r, f"front view: expected the green forearm, got {frame[v, u]}"
        else:
            assert r > g, f"back view: expected the red torso, got {frame[v, u]}"


def test_occluders_move_across_the_episode() -> None:
    scene = SceneOptions(background="flat", noise_sigma=0.0, occluders=3)
    pose = _pose()
    cam = _camera(scene, pose)
    rng = np.random.default_rng(5)
    background = make_background(scene, rng)
    a = render(pose, SHAPE, cam, scene, rng, background, frame_index=0)
    b = render(pose, SHAPE, cam, scene, rng, background, frame_index=20)
    assert np.mean(a != b) > 0.01
    plain = render(pose, SHAPE, cam, SceneOptions(background="flat", noise_sigma=0.0), rng)
    assert np.mean(a != plain) > 0.01  # occluders are drawn


def test_noise_has_the_requested_sigma() -> None:
    pose = _pose()
    clean_scene = SceneOptions(background="flat", noise_sigma=0.0)
    cam = _camera(clean_scene, pose)
    clean = render(pose, SHAPE, cam, clean_scene, np.random.default_rng(0)).astype(float)
    noisy = render(
        pose, SHAPE, cam, SceneOptions(background="flat", noise_sigma=6.0), np.random.default_rng(0)
    ).astype(float)
    residual = noisy - clean
    assert residual.std() == pytest.approx(6.0, rel=0.15)
    assert abs(residual.mean()) < 0.5


def test_blur_smooths_the_frame() -> None:
    pose = _pose()
    sharp_scene = SceneOptions(background="flat", noise_sigma=0.0)
    cam = _camera(sharp_scene, pose)
    sharp = render(pose, SHAPE, cam, sharp_scene, np.random.default_rng(0)).astype(float)
    blurred = render(
        pose, SHAPE, cam, SceneOptions(background="flat", noise_sigma=0.0, blur_sigma=1.0),
        np.random.default_rng(0),
    ).astype(float)  # fmt: skip
    # Blur spreads the edges: less gradient energy.
    assert np.square(np.diff(blurred, axis=1)).sum() < 0.6 * np.square(np.diff(sharp, axis=1)).sum()


def test_gray_frame_is_the_luminance_of_the_scene() -> None:
    pose = _pose()
    rgb_scene = SceneOptions(background="flat", noise_sigma=0.0)
    gray_scene = SceneOptions(background="flat", noise_sigma=0.0, color="gray")
    cam = _camera(rgb_scene, pose)
    rgb = render(pose, SHAPE, cam, rgb_scene, np.random.default_rng(0)).astype(float)
    gray = render(pose, SHAPE, cam, gray_scene, np.random.default_rng(0)).astype(float)
    luma = rgb @ np.array([0.299, 0.587, 0.114])
    assert np.mean(np.abs(luma - gray[..., 0]) <= 2.0) > 0.97


def test_overlay_draws_a_wire_figure() -> None:
    scene = SceneOptions(background="flat", noise_sigma=0.0)
    pose = _pose()
    cam = _camera(scene, pose)
    frame = render(pose, SHAPE, cam, scene, np.random.default_rng(0))
    before = frame.copy()
    out = draw_pose_overlay(frame, pose, SHAPE, cam, color=(0, 255, 0), thickness=1)
    np.testing.assert_array_equal(frame, before)  # the input is not modified
    assert out.shape == frame.shape
    changed = np.any(out != frame, axis=2)
    assert changed.sum() > 50
    # Joint dots sit on the projected keypoints.
    for u, v in np.rint(cam.project(body.forward_kinematics(pose, SHAPE))).astype(int):
        assert out[v, u, 1] > 150
    gray = render(pose, SHAPE, cam, SceneOptions(color="gray"), np.random.default_rng(0))
    assert draw_pose_overlay(gray, pose, SHAPE, cam).shape == (128, 128, 3)


def test_bad_inputs_raise() -> None:
    scene = SceneOptions()
    pose = _pose()
    cam = _camera(scene, pose)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="shape"):
        render(np.zeros(24), SHAPE, cam, scene, rng)
    with pytest.raises(ValueError, match="non-finite"):
        render(np.full(25, np.nan), SHAPE, cam, scene, rng)
    with pytest.raises(ValueError, match="camera"):
        render(pose, SHAPE, cam, SceneOptions(width=64, height=64), rng)
    other = make_background(SceneOptions(noise_sigma=1.0), rng)
    with pytest.raises(ValueError, match="background"):
        render(pose, SHAPE, cam, scene, rng, other)
    for kwargs in (
        {"width": 32},
        {"height": 481},
        {"color": "bgr"},
        {"background": "room"},
        {"noise_sigma": -1.0},
        {"occluders": -1},
        {"shading_strips": 0},
        {"figure_colors": ((0, 0, 0),)},
    ):
        with pytest.raises(ValueError):
            SceneOptions(**kwargs)
    with pytest.raises(ValueError, match="must be integers, got True, 128"):
        SceneOptions(width=True)  # a bool is no size (True would be read as 1)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        # an infinite period was taken, then make_background failed in numpy
        ({"occluders": 2, "occluder_period": float("inf")}, "occluder_period: expected a finite"),
        ({"occluder_period": "5"}, "occluder_period: expected a finite number of frames >= 1"),
        ({"occluder_period": 0.5}, "occluder_period: expected a finite number of frames >= 1"),
        ({"noise_sigma": "4"}, r"noise_sigma: expected a number in \[0, 255\], got '4'"),
        ({"clutter_density": "1"}, r"clutter_density: expected a number in \[0, 16\], got '1'"),
        ({"blur_sigma": True}, "blur_sigma: expected a number"),
        ({"ambient": float("nan")}, "ambient: expected a number"),
        ({"color": ["rgb"]}, "color: expected 'rgb' or 'gray'"),
        ({"palette": ["v1"]}, "palette: expected one of"),
        ({"background_color": ("1", "2", "3")}, "background_color: expected an RGB triple"),
        ({"background_color": (150.5, 150, 145)}, "background_color: expected an RGB triple"),
        ({"figure_colors": ((1, 2, 3),) * 9 + ((1, 2),)}, "figure_colors: expected 10 RGB"),
        ({"light_direction": ("1", "2", "3")}, "light_direction: expected a non-zero vector"),
        ({"light_direction": (1.0, 2.0)}, "light_direction: expected a non-zero vector"),
    ],
)
def test_scene_options_name_the_field_they_cannot_take(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=f"SceneOptions.{message}"):
        SceneOptions(**kwargs)


def test_overlay_refuses_another_frames_camera_and_bad_colours_or_thickness() -> None:
    pose = _pose()
    cam = _camera(SceneOptions(), pose)  # 128x128
    frame = np.zeros((128, 128, 3), np.uint8)
    # drawn in the wrong places before: the camera's pixels are another frame's
    with pytest.raises(ValueError, match="camera is 128x128 but the frame is 64x64"):
        draw_pose_overlay(np.zeros((64, 64, 3), np.uint8), pose, SHAPE, cam)
    with pytest.raises(ValueError, match="camera is 128x128 but the frame is 128x64"):
        draw_pose_overlay(np.zeros((64, 128), np.uint8), pose, SHAPE, cam)
    for thickness in (2.5, 0, True, 40000):
        with pytest.raises(ValueError, match=r"thickness must be an integer in \[1, 32767\]"):
            draw_pose_overlay(frame, pose, SHAPE, cam, thickness=thickness)
    for color in ("red", (300, -1, 0), (0, 255), 5, (0.5, 0, 0)):
        with pytest.raises(ValueError, match=r"color must be three integers in \[0, 255\]"):
            draw_pose_overlay(frame, pose, SHAPE, cam, color=color)
    numpy_color = draw_pose_overlay(frame, pose, SHAPE, cam, np.array([0, 255, 0], np.uint8))
    np.testing.assert_array_equal(numpy_color, draw_pose_overlay(frame, pose, SHAPE, cam))


def test_render_frame_takes_no_bool_for_a_frame() -> None:
    scene = SceneOptions()
    pose = _pose()
    figures = figure_sequence(np.stack([pose, pose]), SHAPE, _camera(scene, pose), scene)
    rng = np.random.default_rng(0)
    background = make_background(scene, rng)
    with pytest.raises(ValueError, match=r"t must be an integer in \[0, 2\), got True"):
        render_frame(figures, True, rng, background)  # was frame 1
    assert render_frame(figures, np.int64(1), rng, background).shape == (128, 128, 3)


def test_pose_behind_the_camera_is_not_drawn() -> None:
    scene = SceneOptions(background="flat", noise_sigma=0.0)
    pose = _pose()
    cam = _camera(scene, pose)
    behind = pose.copy()
    behind[:3] = cam.position - 1500.0 * cam.forward
    frame = render(behind, SHAPE, cam, scene, np.random.default_rng(0))
    assert np.all(frame == frame[0, 0])


def _walk(n: int) -> np.ndarray:
    """n poses of a figure walking past and swinging its limbs."""
    t = np.arange(n)[:, None]
    poses = np.repeat(_pose()[None], n, axis=0)
    poses[:, :2] += t * np.array([25.0, 10.0])
    for name in ("r_shoulder_x", "l_hip_x", "r_elbow", "l_knee"):
        poses[:, PI[name]] += 0.4 * np.sin(0.3 * t[:, 0] + len(name))
    return poses


@pytest.mark.parametrize("cameras", ["static", "following", "each_its_own"])
def test_figure_sequence_frames_are_render_frames(cameras: str) -> None:
    # The environments' path (prepare the episode's figures at once, then draw
    # frame by frame) gives the frames render() gives, bit for bit.
    scene = SceneOptions(occluders=1)
    poses = _walk(12)
    base = _camera(scene, poses[0])
    if cameras == "static":
        cams = [base] * len(poses)
    elif cameras == "following":
        cams = base.shifted(poses[:, :3] - poses[0, :3])
    else:
        cams = [_camera(scene, p, azimuth=10.0 * k) for k, p in enumerate(poses)]
    figures = figure_sequence(poses, SHAPE, cams if cameras != "static" else base, scene)
    assert len(figures) == len(poses)
    background = make_background(scene, np.random.default_rng(0))
    for t, (pose, cam) in enumerate(zip(poses, cams, strict=True)):
        expected = render(pose, SHAPE, cam, scene, np.random.default_rng(t), background, t)
        got = render_frame(figures, t, np.random.default_rng(t), background)
        assert np.array_equal(got, expected), t


def test_figure_sequence_takes_precomputed_geometry_and_checks_inputs() -> None:
    scene = SceneOptions()
    poses = _walk(4)
    cam = _camera(scene, poses[0])
    a = figure_sequence(poses, SHAPE, cam, scene)
    b = figure_sequence(poses, SHAPE, cam, scene, batch_pose_geometry(poses, SHAPE))
    assert np.array_equal(a.ellipses, b.ellipses) and np.array_equal(a.quads, b.quads)
    with pytest.raises(ValueError, match=r"\(T, 25\)"):
        figure_sequence(poses[0], SHAPE, cam, scene)
    with pytest.raises(ValueError, match="non-finite"):
        figure_sequence(np.full((2, 25), np.inf), SHAPE, cam, scene)
    with pytest.raises(ValueError, match="cameras"):
        figure_sequence(poses, SHAPE, [cam, cam], scene)
    with pytest.raises(ValueError, match="camera is 128x128"):
        figure_sequence(poses, SHAPE, cam, SceneOptions(width=64, height=64))
    wide = Camera(128, 128, 70.0, cam.rotation, cam.position)
    with pytest.raises(ValueError, match="same size and fov"):
        figure_sequence(poses, SHAPE, [cam, cam, wide, cam], scene)
    with pytest.raises(ValueError, match="geometry"):
        figure_sequence(poses, SHAPE, cam, scene, np.zeros((4, 15, 3)))
    background = make_background(scene, np.random.default_rng(0))
    rng = np.random.default_rng(0)
    for t in (-1, 4, 1.5):
        with pytest.raises(ValueError, match="t must be"):
            render_frame(a, t, rng, background)
    with pytest.raises(ValueError, match="background"):
        render_frame(a, 0, rng, make_background(SceneOptions(noise_sigma=1.0), rng))


def test_a_noise_bank_serves_many_backgrounds() -> None:
    scene = SceneOptions()
    bank = noise_bank(scene, np.random.default_rng(1))
    assert bank.shape == (2, 256, 256, 3) and bank.dtype == np.uint8
    a = make_background(scene, np.random.default_rng(2), bank)
    b = make_background(scene, np.random.default_rng(3), bank)
    assert a.noise is bank and b.noise is bank
    assert not np.array_equal(a.image, b.image)  # the room is still each episode's own
    # Reusing the bank leaves the rest of the background as the generator draws it.
    fresh = make_background(scene, np.random.default_rng(2))
    assert np.array_equal(fresh.image, a.image)
    assert noise_bank(SceneOptions(noise_sigma=0.0), np.random.default_rng(0)).shape == (
        2, 1, 1, 3,
    )  # fmt: skip
    with pytest.raises(ValueError, match="noise must be a uint8 bank"):
        make_background(SceneOptions(width=64, height=64), np.random.default_rng(0), bank)
    with pytest.raises(ValueError, match="noise must be a uint8 bank"):
        make_background(scene, np.random.default_rng(0), bank.astype(np.int16))


@pytest.mark.parametrize(("h", "w"), [(128, 128), (80, 96), (1, 1)])
def test_noise_windows_are_the_frames_draws_in_advance(h: int, w: int) -> None:
    # The vector environment draws an episode's windows at its start: they
    # must be the windows its frames would draw one by one, and leave the
    # generator where those draws leave it (frames drawn after still agree).
    from humotion_gym.render import _noise_window, _noise_windows

    for seed, count in [(0, 0), (1, 1), (2, 30), (3, 257)]:
        ahead, one_by_one = np.random.default_rng(seed), np.random.default_rng(seed)
        windows = _noise_windows(ahead, h, w, count)
        assert windows.shape == (count,) and windows.dtype == np.int64
        split = [list(divmod(v, w + 1)) for v in windows.tolist()]
        assert split == [list(_noise_window(one_by_one, h, w)) for _ in range(count)]
        assert ahead.bit_generator.state == one_by_one.bit_generator.state
        assert ((windows >= 0) & (windows < (h + 1) * (w + 1))).all()
        assert _noise_window(ahead, h, w) == _noise_window(one_by_one, h, w)


def _bent_figures(scene: SceneOptions, n: int, seed: int) -> tuple:
    """``n`` poses with random joint angles, their camera, figures, geometry and unit light."""
    poses = np.tile(_pose(), (n, 1))
    poses[:, 6:] += np.random.default_rng(seed).normal(0.0, 0.4, (n, 19))
    cam = _camera(scene, poses[0])
    figures = figure_sequence(poses, SHAPE, cam, scene)
    light = np.array(scene.light_direction) / np.linalg.norm(scene.light_direction)
    return poses, cam, figures, body.cone_geometry(poses, SHAPE), light


def test_figure_polygons_against_the_cones_projected_one_by_one() -> None:
    """The compiled figure pass against its definition, cone by cone.

    A cone's silhouette is the convex hull (``cv2.convexHull``) of its end
    ellipses' points, the camera's projection of ``end + r (cos t x + aspect
    sin t y)`` in 1/16 pixel truncated towards zero (so within one unit, a
    sixteenth of a pixel); colours are Lambert's law on the cone's axis,
    rounded (within one grey level); cones are drawn far first.
    """
    import cv2

    from humotion_gym.render import _ONE

    scene = SceneOptions()
    poses, cam, figures, geometry, light = _bent_figures(scene, 6, 4)
    t_ring = 2 * np.pi * np.arange(12) / 12
    for t in range(len(poses)):
        depth = []
        for c in range(body.N_CONES):
            x, y = geometry.rotations[t, c][:, 0], geometry.rotations[t, c][:, 1]
            ends = (geometry.starts[t, c], geometry.ends[t, c])
            points = np.concatenate([
                end + SHAPE.radii[c, e] * (np.cos(t_ring)[:, None] * x
                                           + SHAPE.aspect[c] * np.sin(t_ring)[:, None] * y)
                for e, end in enumerate(ends)
            ])  # fmt: skip
            fixed = np.trunc(cam.project(points) * _ONE).astype(np.int32)
            want = cv2.convexHull(fixed)[:, 0]
            got = np.unique(figures.ellipses[t, c], axis=0)
            # the same vertices, each within a unit of the oracle's (a rounding apart)
            assert len(got) == len(want) or abs(len(got) - len(want)) <= 2
            for v in want:
                assert np.abs(got - v).max(axis=1).min() <= 1
            axis = cam.rotation @ (ends[1] - ends[0])
            axis /= np.linalg.norm(axis)
            cap = max(0.0, -np.sign(axis[2]) * axis @ light)  # the end facing the camera
            base = np.array(scene.figure_colors[c], float)
            want_cap = base * (scene.ambient + scene.diffuse * cap)
            assert (
                np.abs(figures.colors[t, c, 0].astype(float) - np.minimum(want_cap, 255)).max() <= 1
            )
            depth.append(cam.to_camera(np.array(ends))[:, 2].sum())
        assert figures.order[t] == list(np.argsort(-np.array(depth), kind="stable"))


def _one_occluder(scene: SceneOptions, row: list[float], color: tuple[int, int, int]):
    """The scene's background with one occluder of the given parameters (Background.occluders)."""
    from dataclasses import replace

    background = make_background(scene, np.random.default_rng(0))
    return replace(
        background, occluders=np.array([row]), occluder_colors=np.array([color], np.uint8)
    )


def test_occluders_are_drawn_where_their_paths_put_them_over_the_figure() -> None:
    scene = SceneOptions(width=64, height=64, background="flat", noise_sigma=0.0, occluders=1)
    pose = _pose()
    cam = _camera(scene, pose)
    plain = render(pose, SHAPE, cam, SceneOptions(width=64, height=64, background="flat",
                                                  noise_sigma=0.0), np.random.default_rng(0))  # fmt: skip
    v, u = np.mgrid[0:64, 0:64]
    # A blob moving right (heading 0) at 2 px a frame, its path 10 px below
    # the centre (31.5, 31.5): at frame 5 its centre is (41.5, 41.5); semi-axes
    # 8 px across and 0.6 of that (4.8 px) up and down.
    blob = _one_occluder(scene, [1, 0, 0.0, 10.0, 2.0, 8.0, 0.0], (200, 30, 30))
    frame = render(pose, SHAPE, cam, scene, np.random.default_rng(0), blob, frame_index=5)
    r = np.hypot((u - 41.5) / 8.0, (v - 41.5) / 4.8)
    inside, outside = r <= 1.0 - 1.5 / 8.0, r >= 1.0 + 1.5 / 4.8
    assert inside.sum() > 60
    assert (frame[inside] == (200, 30, 30)).all()  # over the figure too
    assert np.any(plain[inside] != plain[0, 0])  # (the figure is there)
    np.testing.assert_array_equal(frame[outside], plain[outside])
    # A horizontal bar moving down (heading pi/2) at 3 px a frame: at frame 4
    # its centre line is at v = 43.5, int(0.6 x 10) = 6 px thick, image-wide.
    bar = _one_occluder(scene, [0, 0, np.pi / 2, 0.0, 3.0, 10.0, 0.0], (30, 30, 200))
    frame = render(pose, SHAPE, cam, scene, np.random.default_rng(0), bar, frame_index=4)
    assert (frame[42:46] == (30, 30, 200)).all()
    np.testing.assert_array_equal(frame[:40], plain[:40])
    np.testing.assert_array_equal(frame[48:], plain[48:])


@pytest.mark.parametrize(("size", "strips"), [(256, 4), (256, 16), (64, 16)])
def test_each_cone_is_its_silhouette_in_the_cap_colour_under_its_strips(
    size: int, strips: int
) -> None:
    # The drawing's definition, one cone at a time, far first: a wide cone's
    # silhouette in the cap's colour with each strip quad in its own colour
    # over it, a narrow one's in the flat shade.
    import cv2

    from humotion_gym.render import _SHIFT

    scene = SceneOptions(width=size, height=size, background="flat", noise_sigma=0.0,
                         shading_strips=strips)  # fmt: skip
    pose = _pose()
    pose[PI["l_elbow"]] = 1.2
    cam = _camera(scene, pose, azimuth=-30.0)
    figures = figure_sequence(pose[None], SHAPE, cam, scene)
    background = make_background(scene, np.random.default_rng(0))
    want = background.image.copy()
    colors = figures.colors[0].astype(int).tolist()
    for c in figures.order[0]:
        if figures.wide[0][c]:
            cv2.fillConvexPoly(want, figures.ellipses[0, c], colors[c][0], cv2.LINE_8, _SHIFT)
            for b in range(strips):
                quad = figures.quads[0, c, b]
                cv2.fillConvexPoly(want, quad, colors[c][2 + b], cv2.LINE_8, _SHIFT)
        else:
            cv2.fillConvexPoly(want, figures.ellipses[0, c], colors[c][1], cv2.LINE_8, _SHIFT)
    wide = sum(figures.wide[0])
    assert wide == body.N_CONES if size == 256 else 0 < wide < body.N_CONES
    got = render_frame(figures, 0, np.random.default_rng(0), background)
    np.testing.assert_array_equal(got, want)
    # the cap, flat shade and strips are distinct colours (so a mix-up shows)
    assert len({tuple(row) for row in colors[0]}) >= 3


def test_overlay_leaves_out_edges_to_keypoints_behind_the_camera() -> None:
    # A wide camera looking straight down from 600 mm above the ground, beside
    # a standing figure: only the knees and ankles are in front of it, so only
    # the shins are drawn (and four dots).
    import cv2

    pose = body.standing_pose(SHAPE)
    cam = Camera(128, 128, 100.0, np.diag([1.0, -1.0, -1.0]), [0.0, 0.0, 600.0])
    kp = body.forward_kinematics(pose, SHAPE)
    px = cam.project(kp)
    shown = np.isfinite(px).all(axis=1)
    names = [body.KEYPOINT_NAMES[k] for k in np.flatnonzero(shown)]
    assert names == ["r_knee", "r_ankle", "l_knee", "l_ankle"]
    black = np.zeros((128, 128, 3), np.uint8)
    out = draw_pose_overlay(black, pose, SHAPE, cam, thickness=1)
    near = np.zeros((128, 128), np.uint8)
    for a, b in body.SKELETON_EDGES:
        if shown[a] and shown[b]:
            cv2.line(near, tuple(np.rint(px[a]).astype(int)), tuple(np.rint(px[b]).astype(int)),
                     255, 7)  # fmt: skip
    for k in np.flatnonzero(shown):
        cv2.circle(near, tuple(np.rint(px[k]).astype(int)), 5, 255, -1)
    changed = np.any(out != 0, axis=2)
    assert changed.sum() > 20 and not np.any(changed & (near == 0))


@pytest.mark.parametrize("strips", [1, 3, 6])
def test_flat_and_strip_shades_follow_lamberts_law(strips: int) -> None:
    """Each strip lit for the normal ``s m + sqrt(1 - s^2) w`` at its centre ``s`` across.

    ``m`` is the projected axis' unit image normal, ``w`` the normal facing the
    camera, ``(a_z a - e_z) / sqrt(1 - a_z^2)`` for the unit axis ``a`` (camera
    frame); the strips split ``[-1, 1]`` evenly. The flat shade of a narrow
    cone is lit for ``w`` alone. Colours within one grey level.
    """
    scene = SceneOptions(shading_strips=strips, light_direction=(-0.3, -0.5, -0.8))
    poses, cam, figures, geometry, light = _bent_figures(scene, 4, 8)
    edges = np.linspace(-1.0, 1.0, strips + 1)
    centres = (edges[1:] + edges[:-1]) / 2
    for t in range(len(poses)):
        for c in range(body.N_CONES):
            ends = np.stack([geometry.starts[t, c], geometry.ends[t, c]])
            axis = cam.rotation @ (ends[1] - ends[0])
            axis /= np.linalg.norm(axis)
            (u0, v0), (u1, v1) = cam.project(ends)
            m = np.array([v1 - v0, u0 - u1, 0.0]) / np.hypot(v1 - v0, u0 - u1)
            w = (axis[2] * axis - [0.0, 0.0, 1.0]) / np.sqrt(1.0 - axis[2] ** 2)
            normals = [w] + [s * m + np.sqrt(1.0 - s * s) * w for s in centres]
            base = np.array(scene.figure_colors[c], float)
            for k, normal in enumerate(normals):
                lam = scene.ambient + scene.diffuse * max(0.0, normal @ light)
                want = np.minimum(np.rint(base * lam), 255)
                got = figures.colors[t, c, 1 + k].astype(float)
                assert np.abs(got - want).max() <= 1, (t, c, k, got, want)


@pytest.mark.parametrize("checker", [False, True])
@pytest.mark.parametrize("angle", [0.0, np.pi / 2])
def test_textures_are_stripes_or_checkers_of_two_colours_inside_the_mask(
    angle: float, checker: bool
) -> None:
    # Stripes ``period`` pixels wide across the direction ``angle`` (0: columns
    # 0-3, 4-7, ... alternate; pi/2: rows), a checker adds the stripes across
    # them; only where the mask is set.
    from humotion_gym.render_scene import _paint_texture

    region = np.full((12, 16, 3), 7, np.uint8)
    inside = np.full((12, 16), 255, np.uint8)
    inside[5:7, 5:9] = 0
    palette = np.array([[10, 20, 30], [200, 210, 220]], np.uint8)
    _paint_texture(region, inside, palette, 4.0, angle, checker)
    for y in range(12):
        for x in range(16):
            if not inside[y, x]:
                want = [7, 7, 7]
            elif angle == 0.0:
                want = palette[(x // 4 + (y // 4 if checker else 0)) % 2]
            else:
                want = palette[(y // 4 + ((-x) // 4 if checker else 0)) % 2]
            assert region[y, x].tolist() == list(want), (y, x)


def test_a_cluttered_wall_is_jittered_by_at_most_20_grey_levels() -> None:
    shifts = []
    for seed in range(24):
        scene = SceneOptions(noise_sigma=0.0)
        image = make_background(scene, np.random.default_rng(seed)).image.reshape(-1, 3)
        values, counts = np.unique(image, axis=0, return_counts=True)
        wall = values[np.argmax(counts)].astype(int) - scene.background_color  # the most common
        assert np.ptp(wall) <= 1 and np.abs(wall).max() <= 20, (seed, wall)
        shifts.append(wall[0])
    assert np.ptp(shifts) > 20  # the jitter spans the range
    flat = make_background(SceneOptions(background="flat"), np.random.default_rng(0)).image
    assert (flat == SceneOptions().background_color).all()


def test_about_two_clutter_shapes_in_five_are_textured() -> None:
    from humotion_gym.render_scene import _clutter_plan

    kinds = []
    for seed in range(10):
        plan = _clutter_plan(np.random.default_rng(seed), 128, 128, 1.0)
        kinds += plan.shapes[:, 1].tolist()
    textured = np.mean(np.array(kinds) != 0)
    assert len(kinds) > 50 and 0.25 < textured < 0.55


def test_a_clutter_line_runs_its_length_along_its_direction(monkeypatch) -> None:
    # One line of the plan, from (10, 10) along (3, 4) (its normal draws,
    # normalised) for 50 px: it ends at (40, 50).
    from humotion_gym import render_scene

    plan = render_scene.ClutterPlan(
        np.zeros((0, 19), np.int64), np.zeros((0, 10)),
        np.array([[10.0, 10.0, 0.3, 0.4, 50.0, 200.0, 0.0, 0.0, 1.0]]),
    )  # fmt: skip
    monkeypatch.setattr(render_scene, "_clutter_plan", lambda *args: plan)
    scene = SceneOptions(width=64, height=64, noise_sigma=0.0)
    img = np.zeros((64, 64, 3), np.uint8)
    render_scene._draw_clutter(img, scene, np.random.default_rng(0))
    v, u = np.nonzero(img[..., 0] > 100)
    along = np.clip(((u - 10) * 0.6 + (v - 10) * 0.8) / 50.0, 0.0, 1.0)
    off = np.hypot(u - 10 - 30 * along, v - 10 - 40 * along)
    assert off.max() <= 1.0 and np.hypot(u - 40, v - 50).min() <= 1.5 and img[10, 10, 0] > 100
    assert v.size >= 45
