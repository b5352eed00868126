"""Frames from poses: shaded cones over a background, with noise and occluders.

Each of the ten truncated cones of :mod:`humotion_gym.body` is drawn as the
filled convex hull of its two projected end ellipses (circles for the limbs,
ellipses of depth-to-width ratio ``aspect`` for the torso), far cones first
(painter's algorithm). A cone is shaded like a lit cylinder: the hull takes the
colour of its visible end cap, and a few strips along its length, each lit by
Lambert's law for the surface normal at that strip's position across the limb,
show the gradient from the lit side to the dark side (cones narrower than six
pixels get one flat shade instead).

The background is made once per episode (:func:`make_background`, in
:mod:`humotion_gym.render_scene`) from the episode's random generator and
reused every frame. Occluders (bars and blobs) move across the image over the
episode. With ``SceneOptions.floor`` the ground plane's grid lines, seen from
each frame's camera, are drawn over the background and behind the figure.
Each frame gets sensor noise (and an optional blur) from the
generator passed to :func:`render`. Every pixel is drawn by OpenCV.

Every random draw goes through an explicit ``numpy.random.Generator``: the same
pose, scene, background and generator state give the same frame bit for bit.

Two ways to render. :func:`render` draws one pose. For a sequence,
:func:`figure_sequence` computes the projection, silhouettes, shading and depth
order of every frame at once (vectorised over frames, cones and ellipse
points), and :func:`render_frame` then only draws frame ``t``; the frames are
the same up to a vertex's rounding. The environments prepare each episode this
way at reset (``benchmarks/bench_render.py`` times both).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import _compiled, body
from humotion_gym.body import CONE_KEYPOINTS, N_CONES, N_KEYPOINTS, BodyShape
from humotion_gym.camera import Camera
from humotion_gym.checks import is_integer
from humotion_gym.kinematics import batch_pose_geometry, single_pose_geometry
from humotion_gym.render_scene import (
    _ELLIPSE_POINTS,
    DEFAULT_FIGURE_COLORS,
    FIGURE_PALETTES,
    FLOOR_COLOR,
    Background,
    Color,
    SceneOptions,
    _to_channels,
    floor_segments,
    make_background,
    noise_bank,
)

__all__ = [
    "DEFAULT_FIGURE_COLORS",
    "FIGURE_PALETTES",
    "Background",
    "FigureSequence",
    "SceneOptions",
    "draw_pose_overlay",
    "figure_sequence",
    "figure_sequences",
    "gaussian_blur",
    "make_background",
    "noise_bank",
    "render",
    "render_frame",
]

_SHIFT = 4  # fixed-point bits for sub-pixel polygon vertices
_ONE = float(1 << _SHIFT)
_MAX_THICKNESS = 32767  # OpenCV's largest line thickness
#: The skeleton's edges as rows of keypoint pairs (one fancy index draws them all).
_EDGES = np.array(body.SKELETON_EDGES, np.intp).reshape(-1, 2)
_NEAR_MM = 1.0  # cones with an end closer to the camera plane are not drawn
_FAR_PX = 1e6  # projected coordinates are clipped to +-1e6 pixels
# Cones narrower than this (silhouette half-width in pixels at both ends) are
# drawn in one flat shade: strips of less than a pixel would not show.
_STRIP_MIN_HALF_WIDTH_PX = 3.0
_CHUNK_FRAMES = 64  # frames prepared per call by figure_sequences


def _check_camera(camera: Camera, scene: SceneOptions, where: str) -> None:
    if (camera.width, camera.height) != (scene.width, scene.height):
        raise ValueError(
            f"{where}: camera is {camera.width}x{camera.height} but the scene is "
            f"{scene.width}x{scene.height}"
        )


def _figure_polygons(
    geometry: NDArray[np.float64], shape: BodyShape, camera: Camera, scene: SceneOptions
) -> tuple[list[list[int]], NDArray[np.int32], NDArray[np.int32], NDArray[np.uint8], list]:
    """A :class:`FigureSequence`'s fields but ``floor``, after its scene, for T frames.

    One compiled pass (:func:`humotion_gym._compiled.figure_polygons`) over
    ``geometry``, ``(T, 35, 3)`` in each frame's camera frame; ``camera``
    gives the intrinsics every frame's camera shares.
    """
    const: dict[str, NDArray] = scene._drawing  # type: ignore[attr-defined]
    n = geometry.shape[0]
    n_strips = scene.shading_strips
    ellipses = np.empty((n, N_CONES, 2 * _ELLIPSE_POINTS, 2), np.int32)
    quads = np.empty((n, N_CONES, n_strips, 4, 2), np.int32)
    colors = np.empty((n, N_CONES, n_strips + 2, scene.channels), np.uint8)
    order = np.empty((n, N_CONES), np.int64)
    counts = np.empty(n, np.int64)
    wide = np.empty((n, N_CONES), np.bool_)
    (cx, cy), fx = camera.principal_point, camera.focal * _ONE
    intrinsics = np.array([fx, cx * _ONE, cy * _ONE, _NEAR_MM, _FAR_PX * _ONE])
    lighting = np.array([scene.ambient, scene.diffuse, _STRIP_MIN_HALF_WIDTH_PX * _ONE])
    _compiled.figure_polygons(
        np.ascontiguousarray(geometry, np.float64), CONE_KEYPOINTS, shape.radii, shape.aspect,
        const["ring"], intrinsics, const["edges"], const["light"], const["shading"],
        const["base"], lighting, ellipses, quads, colors, order, counts, wide,
    )  # fmt: skip
    rows = order.tolist()
    if counts.min() < N_CONES:
        rows = [row[:k] for row, k in zip(rows, counts.tolist(), strict=True)]
    return rows, ellipses, quads, colors, wide.tolist()


@dataclass(frozen=True, eq=False)
class FigureSequence:
    """The cone figure of T frames, ready to draw (see :func:`figure_sequence`).

    Attributes:
        scene: The scene options it was prepared for.
        order: Per frame, the cones to draw, far first.
        ellipses: ``(T, 10, 2K, 2)`` int32 silhouettes (fixed point): the
            convex hull of the cone's two end ellipses, padded with its first
            vertex.
        quads: ``(T, 10, S, 4, 2)`` int32 shading-strip corners (fixed point).
        colors: ``(T, 10, 2 + S, C)`` uint8 colours of each cone's cap, flat
            shade and strips.
        wide: ``T x 10`` booleans: whether a cone is drawn with strips.
        floor: Per frame, the ``(M, 2, 2)`` int32 end points (fixed point) of
            the floor's grid lines to draw when the scene has a floor
            (:func:`~humotion_gym.render_scene.floor_segments`); None without.
    """

    scene: SceneOptions
    order: list[list[int]] = field(repr=False)
    ellipses: NDArray[np.int32] = field(repr=False)
    quads: NDArray[np.int32] = field(repr=False)
    colors: NDArray[np.uint8] = field(repr=False)
    wide: list = field(repr=False)
    floor: list | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.order)

    def concatenated(self, rest: FigureSequence) -> FigureSequence:
        """The figures of this sequence's frames followed by ``rest``'s (same scene)."""
        floor = None if self.floor is None or rest.floor is None else self.floor + rest.floor
        return FigureSequence(
            self.scene,
            self.order + rest.order,
            np.concatenate([self.ellipses, rest.ellipses]),
            np.concatenate([self.quads, rest.quads]),
            np.concatenate([self.colors, rest.colors]),
            self.wide + rest.wide,
            floor,
        )

    @functools.cached_property
    def counts(self) -> list[int]:
        """Per frame, how many cones are drawn."""
        return [len(cones) for cones in self.order]


def figure_sequence(
    params: ArrayLike,
    shape: BodyShape,
    cameras: Camera | Sequence[Camera],
    scene: SceneOptions,
    geometry: ArrayLike | None = None,
) -> FigureSequence:
    """Prepare the figure of a whole sequence of frames at once.

    The projection, silhouettes, shading and depth order of every frame are
    computed together (vectorised over frames and cones), so an episode's
    figures cost about what one frame's do; :func:`render_frame` then only
    draws. This is how the environments render.

    Args:
        params: ``(T, 25)`` poses, one per frame.
        shape: The subject's shape.
        cameras: One camera for every frame, or a sequence of T cameras (of the
            scene's size, all with the same field of view).
        scene: Scene options.
        geometry: The poses' world-frame keypoints and cone axes from
            :func:`~humotion_gym.kinematics.batch_pose_geometry`, when already
            computed (``(T, 35, 3)``).

    Returns:
        The prepared figures.

    Raises:
        ValueError: For malformed poses, cameras of another size or field of
            view, or a sequence of cameras of the wrong length.
    """
    return figure_sequences([(params, shape, cameras, geometry)], scene)[0]


def _floor_lines(
    pose: tuple[NDArray[np.float64], NDArray[np.float64]],
    camera: Camera,
    scene: SceneOptions,
    n: int,
) -> list[NDArray[np.int32]] | None:
    """Each of ``n`` frames' floor segments to draw (``pose``: the cameras' R and t), or None."""
    if not scene.floor:
        return None
    segments, shown = floor_segments(*pose, camera.focal, camera.principal_point, _SHIFT)
    lines = [segs[keep] for segs, keep in zip(segments, shown, strict=True)]
    return lines * n if len(lines) == 1 else lines


def figure_sequences(
    sequences: Sequence[tuple[ArrayLike, BodyShape, Camera | Sequence[Camera], ArrayLike | None]],
    scene: SceneOptions,
) -> list[FigureSequence]:
    """:func:`figure_sequence` of several sequences, prepared in one pass.

    The frames of sequences whose figures have the same radii and aspect and
    whose cameras the same intrinsics are prepared together, in chunks of
    whole sequences of up to 64 frames (what stays in the caches): the same
    result, bit for bit, as one call per sequence. The vector environment
    prepares the episodes it starts this way.

    Args:
        sequences: ``(params, shape, cameras, geometry)`` per sequence, the
            arguments of :func:`figure_sequence`.
        scene: Scene options.

    Returns:
        One :class:`FigureSequence` per sequence, in order.
    """
    prepared = [_in_camera(p, shape, cams, scene, g) for p, shape, cams, g in sequences]
    groups: dict[tuple, list[int]] = {}
    for i, ((_, shape, _, _), (_, cam, _)) in enumerate(zip(sequences, prepared, strict=True)):
        key = (shape.radii.tobytes(), shape.aspect.tobytes(), cam.focal, cam.principal_point)
        groups.setdefault(key, []).append(i)
    # Chunks of whole sequences of at most _CHUNK_FRAMES frames (a longer one alone).
    chunks: list[list[int]] = []
    for members in groups.values():
        chunk: list[int] = []
        frames = 0
        for i in members:
            length = prepared[i][0].shape[0]
            if chunk and frames + length > _CHUNK_FRAMES:
                chunks.append(chunk)
                chunk, frames = [], 0
            chunk.append(i)
            frames += length
        chunks.append(chunk)
    out: list[FigureSequence | None] = [None] * len(sequences)
    for members in chunks:
        first = members[0]
        shape, camera = sequences[first][1], prepared[first][1]
        stacked = np.concatenate([prepared[i][0] for i in members])
        order, ellipses, quads, colors, wide = _figure_polygons(stacked, shape, camera, scene)
        start = 0
        for i in members:
            stop = start + prepared[i][0].shape[0]
            out[i] = FigureSequence(
                scene,
                order[start:stop],
                ellipses[start:stop],
                quads[start:stop],
                colors[start:stop],
                wide[start:stop],
                _floor_lines(prepared[i][2], camera, scene, stop - start),
            )
            start = stop
    return [seq for seq in out if seq is not None]


def _in_camera(
    params: ArrayLike,
    shape: BodyShape,
    cameras: Camera | Sequence[Camera],
    scene: SceneOptions,
    geometry: ArrayLike | None,
) -> tuple[NDArray[np.float64], Camera, tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Checked poses' geometry in each frame's camera frame, the first camera, and the R, t.

    The cameras' rotation and translation: one, or one per frame.
    """
    p = np.asarray(params, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != body.N_PARAMS or p.shape[0] == 0:
        raise ValueError(f"figure_sequence: expected poses of shape (T, 25), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("figure_sequence: the poses have non-finite parameters")
    n = p.shape[0]
    cams = [cameras] if isinstance(cameras, Camera) else list(cameras)
    if len(cams) not in (1, n):
        raise ValueError(f"figure_sequence: expected 1 or {n} cameras, got {len(cams)}")
    first = cams[0]
    _check_camera(first, scene, "figure_sequence")
    for cam in cams[1:]:
        if cam is not first and (cam.width, cam.height, cam.fov_deg) != (
            first.width, first.height, first.fov_deg
        ):  # fmt: skip
            raise ValueError("figure_sequence: every camera must have the same size and fov")
    if all(cam is first for cam in cams):
        rotation, translation = first.rotation, first.translation
    elif all(cam.rotation is first.rotation for cam in cams):  # a following camera
        rotation = first.rotation
        translation = np.stack([cam.position for cam in cams]) @ -rotation.T
    else:
        rotation = np.stack([cam.rotation for cam in cams])
        translation = np.stack([cam.translation for cam in cams])
    if geometry is None:
        world = batch_pose_geometry(p, shape)
    else:
        world = np.asarray(geometry, dtype=np.float64)
        if world.shape != (n, N_KEYPOINTS + 2 * N_CONES, 3):
            raise ValueError(
                f"figure_sequence: geometry must have shape ({n}, 35, 3), got {world.shape}"
            )
    # x_cam = R x + t for the keypoints, R a for the cone axes.
    in_camera = world @ np.swapaxes(rotation, -1, -2)
    in_camera[:, :N_KEYPOINTS] += translation[:, None] if translation.ndim == 2 else translation
    return in_camera, first, (rotation, translation)


def _draw_floor(img: NDArray[np.uint8], figures: FigureSequence, t: int) -> None:
    """Draw frame ``t``'s floor lines into ``img`` (anti-aliased, one pixel wide)."""
    if figures.floor is None:
        raise ValueError(
            "render: the scene draws a floor but its figures were prepared without one "
            "(prepare them with figure_sequence; join sequences with FigureSequence.concatenated)"
        )
    lines = figures.floor[t]
    if len(lines):
        color = _to_channels(FLOOR_COLOR, figures.scene.channels).round().tolist()
        cv2.polylines(img, list(lines), False, color, 1, cv2.LINE_AA, _SHIFT)


def _draw_figure(img: NDArray[np.uint8], figures: FigureSequence, t: int) -> None:
    """Draw frame ``t``'s cones, far first, into ``img`` (``(H, W, C)``, or ``(H, W)``).

    Each cone's silhouette is filled in the cap's colour with its strips over
    it (a wide cone) or in the flat shade.
    """
    colors_l = figures.colors[t].tolist()  # lists of ints, for OpenCV
    ellipses, quads, wide = figures.ellipses[t], figures.quads[t], figures.wide[t]
    # Local names: the attribute look-ups would show in this hot loop.
    fill, line8 = cv2.fillConvexPoly, cv2.LINE_8
    for c in figures.order[t]:
        color = colors_l[c]
        if wide[c]:
            fill(img, ellipses[c], color[0], line8, _SHIFT)
            cone_quads = quads[c]
            for b in range(len(color) - 2):
                fill(img, cone_quads[b], color[b + 2], line8, _SHIFT)
        else:
            fill(img, ellipses[c], color[1], line8, _SHIFT)


def _draw_occluders(img: NDArray[np.uint8], background: Background, frame_index: int) -> None:
    h, w = img.shape[:2]
    occ = background.occluders
    colors = background.occluder_colors.tolist()
    diag = math.hypot(w, h)
    for k in range(occ.shape[0]):
        kind, t0, heading, offset, speed, size, angle = occ[k].tolist()
        # Distance travelled past the middle, wrapped to one crossing of the image.
        span = diag + 2 * size
        along = ((frame_index - t0) * speed + span / 2) % span - span / 2
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        x = (w - 1) / 2 + along * cos_h - offset * sin_h
        y = (h - 1) / 2 + along * sin_h + offset * cos_h
        if kind == 0:  # a bar through (x, y), as long as the image is wide
            dx, dy = math.cos(angle) * diag, math.sin(angle) * diag
            p0 = (int((x - dx) * _ONE), int((y - dy) * _ONE))
            p1 = (int((x + dx) * _ONE), int((y + dy) * _ONE))
            cv2.line(img, p0, p1, colors[k], max(1, int(size * 0.6)), cv2.LINE_8, _SHIFT)
        else:
            axes = (int(size * _ONE), int(size * 0.6 * _ONE))
            centre = (int(x * _ONE), int(y * _ONE))
            cv2.ellipse(
                img, centre, axes, math.degrees(angle), 0, 360, colors[k], -1, cv2.LINE_8, _SHIFT
            )


def _noise_window(rng: np.random.Generator, h: int, w: int) -> tuple[int, int]:
    """The row and column of a frame's window of the noise bank: one of (H + 1)(W + 1)."""
    return divmod(int(rng.integers(0, (h + 1) * (w + 1))), w + 1)


def _noise_windows(rng: np.random.Generator, h: int, w: int, count: int) -> NDArray[np.int64]:
    """``(count,)`` flat windows (row ``v // (W + 1)``, column ``v % (W + 1)``).

    The same numbers, and generator state, as ``count`` calls of
    :func:`_noise_window` (``tests/test_render.py``).
    """
    return rng.integers(0, (h + 1) * (w + 1), size=count)


def _add_noise(
    img: NDArray[np.uint8],
    bank: NDArray[np.uint8],
    rng: np.random.Generator,
    window: tuple[int, int] | None = None,
) -> None:
    """Add the bank's window at ``window``, else at a random one (:func:`_noise_window`)."""
    h, w = img.shape[:2]
    y, x = _noise_window(rng, h, w) if window is None else window
    cv2.add(img, bank[0, y : y + h, x : x + w].reshape(img.shape), dst=img)
    cv2.subtract(img, bank[1, y : y + h, x : x + w].reshape(img.shape), dst=img)


def render(
    params: ArrayLike,
    shape: BodyShape,
    camera: Camera,
    scene: SceneOptions,
    rng: np.random.Generator,
    background: Background | None = None,
    frame_index: int = 0,
) -> NDArray[np.uint8]:
    """Render one frame of the cone figure.

    Args:
        params: ``(25,)`` pose parameters.
        shape: The subject's shape.
        camera: The camera (its size must match the scene's).
        scene: Scene options.
        rng: Generator for this frame's sensor noise (and for the background
            when none is given).
        background: The episode's background from :func:`make_background`; when
            None one is drawn from ``rng`` first (slow: pass it in a loop).
        frame_index: Frame number within the episode; moves the occluders.

    Returns:
        ``(H, W, 3)`` (rgb) or ``(H, W, 1)`` (gray) uint8 frame. The same pose,
        scene, background and generator state give the same frame bit for bit.

    Raises:
        ValueError: For a malformed pose, a camera of another size or a
            background made for other scene options.

    Example:
        >>> import numpy as np
        >>> from humotion_gym import _compiled, body
        >>> from humotion_gym.camera import fit_camera
        >>> from humotion_gym.render import SceneOptions, make_background, render
        >>> shape = body.default_shape()
        >>> pose = body.standing_pose(shape)
        >>> scene = SceneOptions()
        >>> camera = fit_camera(body.forward_kinematics(pose, shape)[None], 128, 128, 50.0)
        >>> rng = np.random.default_rng(0)
        >>> background = make_background(scene, rng)  # once per episode
        >>> render(pose, shape, camera, scene, rng, background).shape
        (128, 128, 3)
    """
    p = body.checked_pose(params, "render")
    _check_camera(camera, scene, "render")
    if background is None:
        background = make_background(scene, rng)
    geometry = single_pose_geometry(p, shape, camera.rotation, camera.translation)[None]
    floor = _floor_lines((camera.rotation, camera.translation), camera, scene, 1)
    figures = FigureSequence(scene, *_figure_polygons(geometry, shape, camera, scene), floor)
    return _compose(figures, 0, rng, background, frame_index, "render")


def render_frame(
    figures: FigureSequence,
    t: int,
    rng: np.random.Generator,
    background: Background,
    frame_index: int | None = None,
) -> NDArray[np.uint8]:
    """Render frame ``t`` of a sequence prepared by :func:`figure_sequence`.

    The same frame :func:`render` gives for that frame's pose and camera (up to
    the rounding of a vertex to 1/16 pixel, the kinematics being computed in
    another order), at the cost of the drawing alone.

    Args:
        figures: The prepared sequence.
        t: Frame number in the sequence (``0 <= t < len(figures)``).
        rng: Generator for this frame's sensor noise.
        background: The episode's background (made for ``figures.scene``).
        frame_index: Frame number within the episode (moves the occluders);
            ``t`` when None.

    Returns:
        The ``(H, W, C)`` uint8 frame.

    Raises:
        ValueError: If ``t`` is out of range or the background was made for
            other scene options.
    """
    if not (is_integer(t) and 0 <= t < len(figures)):  # a bool is no frame
        raise ValueError(f"render_frame: t must be an integer in [0, {len(figures)}), got {t!r}")
    return _compose(
        figures, int(t), rng, background, t if frame_index is None else frame_index, "render_frame"
    )


def _compose(
    figures: FigureSequence,
    t: int,
    rng: np.random.Generator,
    background: Background,
    frame_index: int,
    where: str,
    out: NDArray[np.uint8] | None = None,
    window: tuple[int, int] | None = None,
) -> NDArray[np.uint8]:
    """Background, figure, occluders, noise and blur: one frame, drawn into ``out`` if given.

    ``window``: the noise window drawn beforehand (:func:`_noise_windows`), else drawn here.
    """
    scene = figures.scene
    if background.scene is not scene and background.scene != scene:
        raise ValueError(f"{where}: the background was made for other scene options")
    if out is None:
        img = background.image.copy()
    else:
        img = out
        np.copyto(img, background.image)
    canvas = img if scene.channels == 3 else img.reshape(scene.height, scene.width)
    if scene.floor:
        _draw_floor(canvas, figures, t)
    _draw_figure(canvas, figures, t)
    if scene.occluders:
        _draw_occluders(canvas, background, frame_index)
    if scene.noise_sigma > 0:
        _add_noise(canvas, background.noise, rng, window)
    if scene.blur_sigma > 0:
        gaussian_blur(canvas, scene.blur_sigma, dst=canvas)
    return img


def gaussian_blur(img: NDArray[Any], sigma: float, dst: NDArray[Any] | None = None) -> NDArray[Any]:
    """``cv2.GaussianBlur(img, (0, 0), sigma)``: OpenCV's kernel size for ``sigma``.

    Args:
        img: The image.
        sigma: The Gaussian's standard deviation in pixels (> 0).
        dst: Where to write (``img`` itself for in place), or None.

    Returns:
        The blurred image.
    """
    return cv2.GaussianBlur(img, (0, 0), sigma, dst=dst)


#: The colour tuple :func:`_rgb` checked last and its ints (environments pass one every frame).
_LAST_COLOR: list[Any] = [None, None]


def _rgb(color: Any) -> Color:
    """``color`` as three ints, refused unless integers in [0, 255] (OpenCV would saturate)."""
    if color is _LAST_COLOR[0]:
        return _LAST_COLOR[1]
    try:
        r, g, b = color
    except (TypeError, ValueError):  # not three things
        r = g = b = None
    if not (is_integer(r) and is_integer(g) and is_integer(b)) or not (
        0 <= r <= 255 and 0 <= g <= 255 and 0 <= b <= 255
    ):
        raise ValueError(
            f"draw_pose_overlay: color must be three integers in [0, 255], got {color!r}"
        )
    checked = (int(r), int(g), int(b))
    if type(color) is tuple:
        _LAST_COLOR[:] = [color, checked]
    return checked


def draw_pose_overlay(
    frame: ArrayLike,
    params: ArrayLike,
    shape: BodyShape,
    camera: Camera,
    color: Color = (0, 255, 0),
    thickness: int = 1,
    keypoints: ArrayLike | None = None,
) -> NDArray[np.uint8]:
    """Draw the wire figure of a pose (skeleton edges and joint dots) on a frame.

    Args:
        frame: ``(H, W, 3)``, ``(H, W, 1)`` or ``(H, W)`` uint8 frame (not modified).
        params: ``(25,)`` pose to draw.
        shape: The subject's shape.
        camera: The frame's camera.
        color: RGB colour of the figure: three integers in [0, 255].
        thickness: Line thickness in pixels, an integer in [1, 32767] (joint
            dots get a radius of ``thickness + 1``).
        keypoints: The pose's ``(15, 3)`` world keypoints from
            :func:`~humotion_gym.kinematics.single_pose_geometry`, when the
            caller has them already (the environment scored them in ``step``);
            the same figure is drawn, without the kinematics.

    Returns:
        An ``(H, W, 3)`` copy of the frame with the figure drawn (single-channel
        frames are converted to three channels so the colour shows).

    Raises:
        ValueError: Naming the argument, for one that is not as described
            above (the camera: made for another frame size).
    """
    img = np.asarray(frame)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.dtype != np.uint8 or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
        raise ValueError(f"draw_pose_overlay: expected a uint8 image, got {img.dtype} {img.shape}")
    h, w = img.shape[:2]
    if (camera.width, camera.height) != (w, h):  # its pixels would be another frame's
        raise ValueError(
            f"draw_pose_overlay: camera is {camera.width}x{camera.height} but the frame is {w}x{h}"
        )
    if not (type(thickness) is int or is_integer(thickness)) or not (
        1 <= thickness <= _MAX_THICKNESS
    ):
        raise ValueError(
            f"draw_pose_overlay: thickness must be an integer in [1, {_MAX_THICKNESS}], "
            f"got {thickness!r}"
        )
    col = _rgb(color)
    out = cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if img.ndim == 2 else img.copy()
    p = body.checked_pose(params, "draw_pose_overlay")
    if keypoints is None:
        kp = single_pose_geometry(p, shape)[:N_KEYPOINTS]
    else:
        kp = np.asarray(keypoints, dtype=np.float64)
        if kp.shape != (N_KEYPOINTS, 3):
            raise ValueError(f"draw_pose_overlay: keypoints must be (15, 3), got {kp.shape}")
    px = camera.project(kp)
    ok = np.isfinite(px).all(axis=1)
    shown = ok.tolist()
    every = all(shown)
    if not every:
        # Points behind the camera are not drawn; zeros stand in for them so
        # that the conversion to fixed point stays finite.
        px[~ok] = 0.0
    # Plain ufuncs: np.clip and np.nan_to_num cost more than the drawing here.
    np.minimum(px, 1e5, out=px)
    np.maximum(px, -1e5, out=px)
    px *= _ONE
    points = np.rint(px, out=px).astype(np.int32)
    fixed = points.tolist()
    # Each edge as its own two-point curve: one OpenCV call draws them one after
    # the other exactly as cv2.line would (the same anti-aliased segments, in order).
    edges = _EDGES if every else _EDGES[ok[_EDGES].all(axis=1)]
    if edges.size:
        cv2.polylines(out, points[edges], False, col, thickness, cv2.LINE_AA, _SHIFT)
    radius = int((thickness + 1) * _ONE)
    for k, point in enumerate(fixed):
        if shown[k]:
            cv2.circle(out, point, radius, col, -1, cv2.LINE_AA, _SHIFT)
    return out
