"""Tests of v2's figure palettes and of the floor drawn under the figure."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from humotion_gym import body, render_scene
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.render import (
    DEFAULT_FIGURE_COLORS,
    FIGURE_PALETTES,
    SceneOptions,
    figure_sequence,
    figure_sequences,
    make_background,
    render,
    render_frame,
)
from humotion_gym.render_scene import (
    FLOOR_NEAR_MM,
    FLOOR_RADIUS_MM,
    FLOOR_SPACING_MM,
    SHADED_FIGURE_COLORS,
    SIDED_FIGURE_COLORS,
)

SHAPE = body.default_shape()
CONE = {name: i for i, name in enumerate(body.CONE_NAMES)}
LUMA = np.array([0.299, 0.587, 0.114])
LIMBS = ("upper_arm", "forearm", "thigh", "shin")


def luminance(colors) -> np.ndarray:
    return np.asarray(colors, dtype=np.float64) @ LUMA


# -- palettes ---------------------------------------------------------------


def test_palettes_are_named_and_v1_is_the_default() -> None:
    assert FIGURE_PALETTES["v1"] is DEFAULT_FIGURE_COLORS
    assert FIGURE_PALETTES["shaded"] is SHADED_FIGURE_COLORS
    assert FIGURE_PALETTES["sided"] is SIDED_FIGURE_COLORS
    assert SceneOptions().figure_colors == DEFAULT_FIGURE_COLORS
    for name, colors in FIGURE_PALETTES.items():
        assert SceneOptions(palette=name).figure_colors == colors


@pytest.mark.parametrize("name", sorted(FIGURE_PALETTES))
def test_every_figure_colour_is_apart_from_the_wall_in_luminance(name: str) -> None:
    """Gray frames must show the figure: 40 grey levels from the wall (jittered by 20)."""
    wall = luminance(SceneOptions().background_color)
    assert np.all(np.abs(luminance(FIGURE_PALETTES[name]) - wall) >= 40.0)


def test_shaded_sleeves_differ_from_torso_and_forearms_but_not_between_sides() -> None:
    lum = luminance(SHADED_FIGURE_COLORS)
    for side in "rl":
        arm = CONE[f"{side}_upper_arm"]
        assert abs(lum[arm] - lum[CONE["torso"]]) >= 40.0
        assert abs(lum[arm] - lum[CONE[f"{side}_forearm"]]) >= 40.0
    for limb in LIMBS:
        right, left = CONE[f"r_{limb}"], CONE[f"l_{limb}"]
        assert SHADED_FIGURE_COLORS[right] == SHADED_FIGURE_COLORS[left]


def test_sided_limbs_differ_between_sides_in_luminance_and_right_is_warmer() -> None:
    colors = np.asarray(SIDED_FIGURE_COLORS, dtype=np.float64)
    lum = luminance(colors)
    for limb in LIMBS:
        right, left = CONE[f"r_{limb}"], CONE[f"l_{limb}"]
        assert abs(lum[right] - lum[left]) >= 40.0, limb
        # warmth: red minus blue
        assert colors[right, 0] - colors[right, 2] > colors[left, 0] - colors[left, 2], limb
    for side in "rl":
        arm = CONE[f"{side}_upper_arm"]
        assert abs(lum[arm] - lum[CONE["torso"]]) >= 35.0
        assert abs(lum[arm] - lum[CONE[f"{side}_forearm"]]) >= 40.0


def test_palette_wins_over_figure_colors_and_replace_switches_it() -> None:
    own = tuple((10 * i, 20, 30) for i in range(body.N_CONES))
    assert SceneOptions(figure_colors=own).figure_colors == own
    sided = SceneOptions(figure_colors=own, palette="sided")
    assert sided.figure_colors == SIDED_FIGURE_COLORS
    shaded = dataclasses.replace(sided, palette="shaded")
    assert shaded.figure_colors == SHADED_FIGURE_COLORS
    back = dataclasses.replace(shaded, palette=None, figure_colors=own)
    assert back.figure_colors == own


def test_an_unknown_palette_is_refused_naming_the_argument() -> None:
    with pytest.raises(ValueError, match=r"SceneOptions\.palette.*'shaded'.*got 'pastel'"):
        SceneOptions(palette="pastel")
    with pytest.raises(ValueError, match=r"SceneOptions\.floor"):
        SceneOptions(floor="yes")  # type: ignore[arg-type]


def _arm_out_pose() -> np.ndarray:
    pose = body.standing_pose(SHAPE)
    pose[body.PARAM_INDEX["r_shoulder_x"]] = -0.4  # the arm forward, off the torso's outline
    pose[body.PARAM_INDEX["r_shoulder_z"]] = 0.9  # and out to the side
    return pose


def _cone_middle_pixel(pose: np.ndarray, camera: Camera, cone: int) -> tuple[int, int]:
    start, end = body.CONE_KEYPOINTS[cone]
    kp = body.forward_kinematics(pose, SHAPE)
    u, v = camera.project(0.5 * (kp[start] + kp[end]))
    return int(round(v)), int(round(u))


@pytest.mark.parametrize(("palette", "apart"), [("shaded", True), ("v1", False)])
def test_gray_frames_show_the_sleeve_apart_from_the_torso(palette: str, apart: bool) -> None:
    """The rendered upper arm and torso differ in grey level with shaded, not with v1."""
    scene = SceneOptions(
        color="gray", background="flat", noise_sigma=0.0, shading_strips=1, palette=palette
    )
    pose = _arm_out_pose()
    kp = body.forward_kinematics(pose, SHAPE)
    camera = fit_camera(kp[None], scene.width, scene.height, 45.0, 0.0, 10.0, margin=0.05)
    frame = render(pose, SHAPE, camera, scene, np.random.default_rng(0))[..., 0].astype(int)
    arm = frame[_cone_middle_pixel(pose, camera, CONE["r_upper_arm"])]
    torso = frame[_cone_middle_pixel(pose, camera, CONE["torso"])]
    assert bool(abs(arm - torso) >= 30) is apart, (arm, torso)


# -- floor ------------------------------------------------------------------


def _camera(width: int = 128, height: int = 128) -> Camera:
    # Looking slightly down (about 9 degrees): the horizon crosses the image.
    return Camera.look_at((1234.0, -4321.0, 1600.0), (300.0, 200.0, 900.0), width, height, 45.0)


def _above_horizon(camera: Camera, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Whether each pixel's ray misses the floor (points level or up)."""
    cx, cy = camera.principal_point
    rays = np.stack([(cols - cx) / camera.focal, (rows - cy) / camera.focal, np.ones(rows.size)])
    return (camera.rotation.T @ rays)[2] >= 0.0


def _floor_oracle(camera: Camera) -> np.ndarray:
    """Pixels ``(N, 2)`` (row, col) of grid points of z = 0 drawn by the floor, by Camera.project."""
    centre = camera.position[:2]
    ks = np.arange(-40, 41) * FLOOR_SPACING_MM
    s = np.linspace(-FLOOR_RADIUS_MM, FLOOR_RADIUS_MM, 8001)
    lines = []
    for k in np.floor(centre / FLOOR_SPACING_MM) * FLOOR_SPACING_MM + ks[:, None]:
        lines.append(np.stack([np.full_like(s, k[0]), centre[1] + s, 0 * s], -1))  # x = k
        lines.append(np.stack([centre[0] + s, np.full_like(s, k[1]), 0 * s], -1))  # y = k
    points = np.concatenate(lines)
    near = np.linalg.norm(points[:, :2] - centre, axis=1) < FLOOR_RADIUS_MM
    points = points[near & (camera.depth(points) > FLOOR_NEAR_MM)]
    pixels = camera.project(points)
    pixels = pixels[camera.in_image(pixels)]
    return np.unique(np.rint(pixels[:, ::-1]).astype(int), axis=0)


def _frames(camera: Camera, floor: bool, color: str = "rgb") -> tuple[np.ndarray, np.ndarray]:
    """A frame with the figure (and the floor when asked), and its flat background."""
    scene = SceneOptions(
        width=camera.width, height=camera.height, background="flat", noise_sigma=0.0,
        floor=floor, color=color,
    )  # fmt: skip
    rng = np.random.default_rng(3)
    background = make_background(scene, rng)
    pose = body.standing_pose(SHAPE)
    pose[:2] = (300.0, 200.0)
    return render(pose, SHAPE, camera, scene, rng, background), background.image


@pytest.mark.parametrize("size", [(128, 128), (200, 120)])
def test_floor_lines_lie_where_the_camera_puts_the_ground(size: tuple[int, int]) -> None:
    _check_floor_lines(size)


def _check_floor_lines(size: tuple[int, int] = (128, 128)) -> None:
    camera = _camera(*size)
    with_floor, wall = _frames(camera, True)
    without, _ = _frames(camera, False)
    figure = np.any(without != wall, axis=-1)
    change = np.abs(with_floor.astype(int) - without).max(axis=-1)
    drawn = change > 0
    assert drawn.sum() > 500
    oracle = np.zeros_like(drawn)
    oracle[tuple(_floor_oracle(camera).T)] = True
    near_oracle = oracle.copy()  # within one pixel (anti-aliasing)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_oracle |= np.roll(np.roll(oracle, dy, 0), dx, 1)
    # Clearly drawn pixels (beyond the faint anti-aliased fringe), away from
    # the border (where the oracle's points beyond the image are missing).
    clear = change > 8
    clear[:2], clear[-2:], clear[:, :2], clear[:, -2:] = False, False, False, False
    assert not np.any(clear & ~near_oracle), "floor pixels off the projected ground grid"
    grown = figure.copy()
    for dy in (-2, -1, 0, 1, 2):
        for dx in (-2, -1, 0, 1, 2):
            grown |= np.roll(np.roll(figure, dy, 0), dx, 1)
    near_drawn = drawn.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_drawn |= np.roll(np.roll(drawn, dy, 0), dx, 1)
    visible = oracle & ~grown
    assert near_drawn[visible].mean() > 0.97, "ground grid points not drawn"
    # The figure stays in front of the floor, where the grid runs behind it too.
    assert np.any(oracle & figure)
    np.testing.assert_array_equal(with_floor[figure], without[figure])


def test_nothing_is_drawn_above_the_horizon() -> None:
    camera = _camera()
    with_floor, _ = _frames(camera, True, color="gray")
    without, _ = _frames(camera, False, color="gray")
    rows, cols = np.nonzero(with_floor[..., 0] != without[..., 0])
    assert rows.size and not np.any(_above_horizon(camera, rows, cols))
    assert np.any(_above_horizon(camera, *np.nonzero(np.ones((128, 128), bool))))


def test_the_horizon_check_fails_when_the_near_cut_is_removed(monkeypatch) -> None:
    """Mutation: without cutting lines at the camera plane, ground behind it shows above."""
    monkeypatch.setattr(render_scene, "FLOOR_NEAR_MM", -1e9)
    camera = _camera()
    with_floor, _ = _frames(camera, True, color="gray")
    without, _ = _frames(camera, False, color="gray")
    rows, cols = np.nonzero(with_floor[..., 0] != without[..., 0])
    assert np.any(_above_horizon(camera, rows, cols))


def test_the_floor_is_drawn_from_each_frames_camera_and_is_deterministic() -> None:
    scene = SceneOptions(noise_sigma=4.0, floor=True)
    pose = body.standing_pose(SHAPE)
    poses = np.repeat(pose[None], 4, axis=0)
    poses[:, 0] += np.arange(4) * 400.0  # walking along x
    cameras = _camera().shifted(
        np.stack([np.arange(4) * 400.0, 0 * poses[:, 0], 0 * poses[:, 0]], 1)
    )
    figures = figure_sequence(poses, SHAPE, cameras, scene)
    for t in range(4):
        alone = figure_sequence(poses[t : t + 1], SHAPE, cameras[t], scene)
        np.testing.assert_array_equal(figures.floor[t], alone.floor[0])
    # A camera moved by less than a tile sees the grid elsewhere in its image.
    assert not np.array_equal(figures.floor[0], figures.floor[1])
    batched = figure_sequences([(poses, SHAPE, cameras, None)] * 2, scene)
    for seq in batched:
        for a, b in zip(seq.floor, figures.floor, strict=True):
            np.testing.assert_array_equal(a, b)
    joined = figures.concatenated(figures)
    assert len(joined.floor) == 8 and joined.floor[5] is figures.floor[1]
    frames = []
    for _ in range(2):
        rng = np.random.default_rng(9)
        background = make_background(scene, rng)
        frames.append([render_frame(figures, t, rng, background) for t in range(4)])
    for a, b in zip(*frames, strict=True):
        np.testing.assert_array_equal(a, b)


def test_figures_without_floor_lines_are_refused_by_a_floor_scene() -> None:
    scene = SceneOptions(floor=True)
    pose = body.standing_pose(SHAPE)
    figures = figure_sequence(pose[None], SHAPE, _camera(), scene)
    stripped = dataclasses.replace(figures, floor=None)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="prepared without one"):
        render_frame(stripped, 0, rng, make_background(scene, rng))
    plain = figure_sequence(pose[None], SHAPE, _camera(), SceneOptions())
    assert plain.floor is None


def test_the_ground_oracle_fails_for_a_grid_of_another_spacing(monkeypatch) -> None:
    """Mutation: tiles of 450 mm instead of 500 put lines off the projected grid."""
    monkeypatch.setattr(render_scene, "FLOOR_SPACING_MM", 450.0)
    with pytest.raises(AssertionError, match="off the projected ground grid"):
        _check_floor_lines()
