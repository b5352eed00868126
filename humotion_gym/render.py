"""Frames from poses: shaded cones over a background, with noise and occluders.

Each of the ten truncated cones of :mod:`humotion_gym.body` is drawn as the
filled convex hull of its two projected end ellipses (circles for the limbs,
ellipses of depth-to-width ratio ``aspect`` for the torso), far cones first
(painter's algorithm). A cone is shaded like a lit cylinder: the hull takes the
colour of its visible end cap, and a few strips along its length, each lit by
Lambert's law for the surface normal at that strip's position across the limb,
show the gradient from the lit side to the dark side (cones narrower than six
pixels get one flat shade instead).

The background is made once per episode (:func:`make_background`) from the
episode's random generator and reused every frame: a flat wall colour, or
``clutter``: random textured shapes and lines whose edges compete with the
figure's, as the furniture of a real room would. Occluders (bars and blobs) move
across the image over the episode. Each frame gets sensor noise (and an optional
blur) from the generator passed to :func:`render`.

Every random draw goes through an explicit ``numpy.random.Generator``: the same
pose, scene, background and generator state give the same frame bit for bit.

Two ways to render. :func:`render` draws one pose. For a sequence,
:func:`figure_sequence` computes the projection, silhouettes, shading and depth
order of every frame at once (vectorised over frames, cones and ellipse
points), and :func:`render_frame` then only draws frame ``t``; the frames are
the same bit for bit. The environments prepare each episode this way at reset.

Speed (128x128 RGB, default scene; ``benchmarks/bench_render.py``): about 140
microseconds for one pose with :func:`render`, most of it in some sixty numpy
calls on tiny arrays; about 65 microseconds a frame on the sequence path, of
which the OpenCV drawing calls are about 30 and the episode's preparation,
shared by its 30 frames, about 8.
"""

from __future__ import annotations

import functools
import math
import statistics
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import _kernels, body
from humotion_gym.body import CONE_KEYPOINTS, N_CONES, N_KEYPOINTS, BodyShape
from humotion_gym.camera import Camera
from humotion_gym.kinematics import batch_pose_geometry, single_pose_geometry

Color = tuple[int, int, int]

_SHIRT: Color = (170, 40, 40)
_SKIN: Color = (230, 180, 150)
_TROUSERS: Color = (40, 55, 120)

#: Default colour (RGB) of each cone, in ``body.CONE_NAMES`` order: a red shirt,
#: skin-coloured head and forearms, dark blue trousers.
DEFAULT_FIGURE_COLORS: tuple[Color, ...] = (
    _SHIRT,  # torso
    _SKIN,  # head
    _SHIRT,  # r_upper_arm
    _SKIN,  # r_forearm
    _SHIRT,  # l_upper_arm
    _SKIN,  # l_forearm
    _TROUSERS,  # r_thigh
    _TROUSERS,  # r_shin
    _TROUSERS,  # l_thigh
    _TROUSERS,  # l_shin
)

_MIN_SIZE = (64, 64)
_MAX_SIZE = (640, 480)
_SHIFT = 4  # fixed-point bits for sub-pixel polygon vertices
_ONE = float(1 << _SHIFT)
_NEAR_MM = 1.0  # cones with an end closer to the camera plane are not drawn
_FAR_PX = 1e6  # projected coordinates are clipped to +-1e6 pixels
_ELLIPSE_POINTS = 12
_UNIT_CIRCLE = np.stack(
    [
        np.cos(2 * np.pi * np.arange(_ELLIPSE_POINTS) / _ELLIPSE_POINTS),
        np.sin(2 * np.pi * np.arange(_ELLIPSE_POINTS) / _ELLIPSE_POINTS),
    ]
)  # (2, K)
_CONE_ROWS = np.asarray(CONE_KEYPOINTS)  # rows of each cone's start and end keypoints
# Cones narrower than this (silhouette half-width in pixels at both ends) are
# drawn in one flat shade: strips of less than a pixel would not show.
_STRIP_MIN_HALF_WIDTH_PX = 3.0
_LUMA = np.array([0.299, 0.587, 0.114])  # ITU-R BT.601, as cv2.cvtColor
# Frames prepared per call by figure_sequences (see there).
_CHUNK_FRAMES = 64


@dataclass(frozen=True)
class SceneOptions:
    """How frames look: size, colour, background, noise, blur, occluders, figure.

    The defaults are the leaderboard's default difficulty.

    Attributes:
        width: Image width in pixels (default 128; 64 to 640). Small frames keep
            the environment fast (the papers' frames were 320x240 and larger).
        height: Image height in pixels (default 128; 64 to 480).
        color: ``"rgb"`` (default; frames ``(H, W, 3)``) or ``"gray"`` (frames
            ``(H, W, 1)``, the luminance of the same scene).
        background: ``"clutter"`` (default: random textured shapes and lines, a
            room-like scene whose edges compete with the figure's) or ``"flat"``
            (one wall colour; the easy setting).
        clutter_density: Clutter amount (default 1.0): on average
            ``8 * density`` shapes and ``4 * density`` lines per square of the
            image's short side (shapes are sized relative to it, so the clutter
            looks the same at every size). 0 gives a flat background.
        background_color: RGB wall colour (default (150, 150, 145), a mid grey
            that differs from all three figure colours in luminance). Each
            cluttered episode jitters it by up to 20 grey levels.
        noise_sigma: Standard deviation of the per-pixel Gaussian sensor noise in
            grey levels (default 4.0, a typical well-lit webcam); 0 turns it off.
        blur_sigma: Gaussian blur of every frame in pixels (default 0.0: off;
            about 0.7 mimics a slightly soft lens at twice the cost of a frame).
        occluders: Number of bars and blobs that sweep across the image in
            front of the figure, through its middle third (default 0).
        occluder_period: Frames an occluder takes to cross the image (default
            150, five seconds at 30 fps).
        figure_colors: RGB colour of each cone in ``body.CONE_NAMES`` order
            (default :data:`DEFAULT_FIGURE_COLORS`).
        light_direction: Direction towards the light in the camera frame
            (x right, y down, z forward; default (-0.4, -0.7, -0.6): above, left
            and behind the camera, so fronts are lit).
        ambient: Shade of a surface facing away from the light (default 0.45).
        diffuse: Added shade of a surface facing the light (default 0.6); a
            strip's colour is ``color * (ambient + diffuse * max(0, n.l))``.
        shading_strips: Strips per cone showing the shading across the limb
            (default 3; 1 gives flat per-cone shading). Each costs one filled
            polygon per cone.
    """

    width: int = 128
    height: int = 128
    color: str = "rgb"
    background: str = "clutter"
    clutter_density: float = 1.0
    background_color: Color = (150, 150, 145)
    noise_sigma: float = 4.0
    blur_sigma: float = 0.0
    occluders: int = 0
    occluder_period: float = 150.0
    figure_colors: tuple[Color, ...] = DEFAULT_FIGURE_COLORS
    light_direction: tuple[float, float, float] = (-0.4, -0.7, -0.6)
    ambient: float = 0.45
    diffuse: float = 0.6
    shading_strips: int = 3

    def __post_init__(self) -> None:
        w, h = self.width, self.height
        if not (isinstance(w, (int, np.integer)) and isinstance(h, (int, np.integer))):
            raise ValueError(f"SceneOptions: width and height must be integers, got {w!r}, {h!r}")
        if not (_MIN_SIZE[0] <= w <= _MAX_SIZE[0] and _MIN_SIZE[1] <= h <= _MAX_SIZE[1]):
            raise ValueError(
                f"SceneOptions: image size must be between {_MIN_SIZE[0]}x{_MIN_SIZE[1]} and "
                f"{_MAX_SIZE[0]}x{_MAX_SIZE[1]}, got {w}x{h}"
            )
        if self.color not in ("rgb", "gray"):
            raise ValueError(f"SceneOptions.color: expected 'rgb' or 'gray', got {self.color!r}")
        if self.background not in ("flat", "clutter"):
            raise ValueError(
                f"SceneOptions.background: expected 'flat' or 'clutter', got {self.background!r}"
            )
        for name in ("clutter_density", "noise_sigma", "blur_sigma", "ambient", "diffuse"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"SceneOptions.{name}: expected a finite number >= 0")
        if not (isinstance(self.occluders, (int, np.integer)) and self.occluders >= 0):
            raise ValueError("SceneOptions.occluders: expected an integer >= 0")
        if not self.occluder_period > 0:
            raise ValueError("SceneOptions.occluder_period: expected a positive number of frames")
        if not (isinstance(self.shading_strips, (int, np.integer)) and self.shading_strips >= 1):
            raise ValueError("SceneOptions.shading_strips: expected an integer >= 1")
        colors = np.asarray(self.figure_colors)
        if colors.shape != (N_CONES, 3) or colors.min() < 0 or colors.max() > 255:
            raise ValueError("SceneOptions.figure_colors: expected 10 RGB triples in [0, 255]")
        bg = np.asarray(self.background_color)
        if bg.shape != (3,) or bg.min() < 0 or bg.max() > 255:
            raise ValueError("SceneOptions.background_color: expected an RGB triple in [0, 255]")
        light = np.asarray(self.light_direction, dtype=np.float64)
        if light.shape != (3,) or not np.all(np.isfinite(light)) or np.linalg.norm(light) == 0:
            raise ValueError("SceneOptions.light_direction: expected a non-zero 3-vector")
        object.__setattr__(self, "figure_colors", tuple(tuple(int(v) for v in c) for c in colors))
        object.__setattr__(self, "background_color", tuple(int(v) for v in bg))
        object.__setattr__(self, "light_direction", tuple(float(v) for v in light))
        object.__setattr__(self, "_drawing", _drawing_constants(self))

    @property
    def channels(self) -> int:
        """3 for ``"rgb"``, 1 for ``"gray"``."""
        return 3 if self.color == "rgb" else 1

    @property
    def frame_shape(self) -> tuple[int, int, int]:
        """``(height, width, channels)`` of the frames."""
        return (self.height, self.width, self.channels)


@dataclass(frozen=True, eq=False)
class Background:
    """The per-episode part of the scene, drawn once from the episode's generator.

    Attributes:
        scene: The options it was made for.
        image: ``(H, W, C)`` uint8 background (read-only).
        occluders: ``(K, 7)`` occluder parameters: kind (0 bar, 1 blob), the
            frame at which it crosses the middle, heading of its motion
            (radians), sideways offset of its path from the image centre
            (pixels), speed (pixels per frame), size (pixels) and orientation
            (radians). Each sweeps across the image once per
            ``scene.occluder_period`` frames.
        occluder_colors: ``(K, C)`` occluder colours.
        noise: ``(2, 2H, 2W, C)`` uint8 bank of Gaussian sensor noise (rounded
            to grey levels, tails cut at 2.89 sigma), split into its positive
            and negative parts. Each frame adds the ``(H, W)`` window of the bank
            at an offset drawn from the frame's generator: within a frame the
            noise is i.i.d. per pixel, and a pixel's noise in two frames is
            independent unless their offsets coincide (one chance in
            ``(H + 1)(W + 1)``), though the two frames' noise fields are shifted
            copies of parts of one bank. Drawing fresh Gaussian noise per frame
            would cost more than the rest of the frame. A bank may serve many
            episodes (:func:`noise_bank`): the environments draw one per
            seeded reset.
    """

    scene: SceneOptions
    image: NDArray[np.uint8]
    occluders: NDArray[np.float64]
    occluder_colors: NDArray[np.uint8]
    noise: NDArray[np.uint8] = field(repr=False)


def _to_channels(rgb: ArrayLike, channels: int) -> NDArray[np.float64]:
    c = np.asarray(rgb, dtype=np.float64)
    return c if channels == 3 else (c @ _LUMA)[..., None]


def _bank_shape(scene: SceneOptions) -> tuple[int, int, int, int]:
    """Shape of a scene's noise bank: ``(2, 2H, 2W, C)``, or ``(2, 1, 1, C)`` without noise."""
    h, w, c = scene.frame_shape
    return (2, 2 * h, 2 * w, c) if scene.noise_sigma > 0 else (2, 1, 1, c)


@functools.lru_cache(maxsize=16)
def _noise_tables(sigma: float) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Byte -> positive and negative part of the Gaussian quantile (grey levels)."""
    normal = statistics.NormalDist(0.0, sigma)
    levels = np.array([normal.inv_cdf((k + 0.5) / 256.0) for k in range(256)])
    levels = np.clip(np.rint(levels), -255, 255)
    return np.maximum(levels, 0).astype(np.uint8), np.maximum(-levels, 0).astype(np.uint8)


def _paint_texture(
    region: NDArray[np.uint8],
    inside: NDArray[np.uint8],
    palette: NDArray[np.uint8],
    period: float,
    angle: float,
    checker: bool,
) -> None:
    """Paint a stripe or checker texture of two colours where ``inside``.

    ``region`` is a view of the image (written in place), ``inside`` a uint8
    mask of its size (non-zero inside); ``palette`` the two colours ``(2,
    C)``, ``period`` (pixels) and ``angle`` the stripes', ``checker`` adds
    the stripes across them.
    """
    h, w, channels = region.shape
    # The texture's axes scaled to stripes, in float32 as the pixels' steps are.
    cos_a = np.float32(math.cos(angle) / period)
    sin_a = np.float32(math.sin(angle) / period)
    if _kernels.paint_texture(region, inside, palette, cos_a, sin_a, checker):
        return
    x = np.arange(w, dtype=np.float32)
    y = np.arange(h, dtype=np.float32)[:, None]
    # Stripe (or checker) index along the texture's axes, as a sum of a row
    # and a column term: (h, w) at the cost of one broadcast.
    parity = np.floor(x * cos_a + y * sin_a)
    if checker:
        parity += np.floor(y * cos_a - x * sin_a)
    odd = parity.astype(np.int32)
    odd &= 1
    texture = palette.take(odd, axis=0)  # (h, w, C): the two-colour palette
    cv2.copyTo(texture, inside, region)  # in place, where inside


class ClutterPlan(NamedTuple):
    """A background's clutter, drawn from its generator before any pixel is.

    Attributes:
        shapes: ``(S, 19)`` int64, a row per shape: its kind (0 box, 1 ellipse,
            2 convex polygon); 0 for a plain colour, 1 textured, -1 textured but
            off the image (not drawn); the textured shape's window ``x0, y0,
            x1, y1``; then its geometry: a box's corners ``x0, y0, x1, y1``, an
            ellipse's centre and half-axes, a polygon's vertex count and up to
            six vertices.
        shape_floats: ``(S, 10)`` float64: an ellipse's angle (degrees); the
            plain colour's three draws or the texture's six (two colours); the
            texture's period draw, angle and checker draw.
        lines: ``(L, 9)`` float64, a row per line: start ``x, y``, two normal
            draws (the direction), length, three colour draws, thickness.
    """

    shapes: NDArray[np.int64]
    shape_floats: NDArray[np.float64]
    lines: NDArray[np.float64]


def _clutter_sizes(h: int, w: int, density: float) -> tuple[int, float, float, int]:
    """The short side, the mean numbers of shapes and of lines, and the lines' thickness unit."""
    size = min(h, w)
    # Shapes are sized relative to the short side, so their number grows with
    # the aspect ratio only: the clutter covers the same fraction at any size.
    area = (h * w) / float(size * size)
    return size, 8.0 * density * area, 4.0 * density * area, max(1, size // 128)


def _clutter_plan(
    rng: np.random.Generator, h: int, w: int, density: float, *, kernel: bool = True
) -> ClutterPlan:
    """Every random draw of a background's clutter, in the generator's order.

    The numpy reference of ``_numba_kernels._clutter_plan``, which makes the
    same draws in about a tenth of the time (some seventy scalar draws an
    episode, a microsecond or more each through numpy); ``kernel=False``
    keeps to numpy.
    """
    size, shape_rate, line_rate, unit = _clutter_sizes(h, w, density)
    if kernel and _kernels.ENABLED and _kernel_plans_as_numpy():
        planned = _kernels.clutter_plan(rng, h, w, size, shape_rate, line_rate, unit)
        if planned is not None:
            return ClutterPlan(*planned)
    n_shapes = int(rng.poisson(shape_rate))
    n_lines = int(rng.poisson(line_rate))
    shapes = np.zeros((n_shapes, 19), np.int64)
    floats = np.zeros((n_shapes, 10))
    for i in range(n_shapes):
        kind = int(rng.integers(0, 3))
        # One draw of two for the centre: the same doubles as two scalar draws.
        ux, uy = rng.uniform(-0.1, 1.1, 2).tolist()
        cx, cy = ux * w, uy * h
        rx, ry = rng.uniform(0.05, 0.3, 2).tolist()
        rx, ry = rx * size, ry * size
        # Each kind's geometry and bounding box (lo_x, lo_y, hi_x, hi_y), in
        # Python numbers: the box is only needed for a textured shape.
        shapes[i, 0] = kind
        if kind == 0:
            geometry = [int(cx - rx), int(cy - ry), int(cx + rx), int(cy + ry)]
            box: tuple = tuple(geometry)
        elif kind == 1:
            axes = (int(rx) + 1, int(ry) + 1)
            geometry = [int(cx), int(cy), *axes]
            floats[i, 0] = float(rng.uniform(0, 180))
            reach = axes[0] + axes[1]
            box = (cx - reach, cy - reach, cx + reach, cy + reach)
        else:
            angles = np.sort(rng.uniform(0, 2 * np.pi, int(rng.integers(3, 7))))
            pts = np.stack([cx + rx * np.cos(angles), cy + ry * np.sin(angles)], axis=1)
            polygon = pts.astype(np.int32)
            geometry = [len(polygon), *polygon.reshape(-1).tolist()]
            box = (*polygon.min(axis=0).tolist(), *polygon.max(axis=0).tolist())
        shapes[i, 6 : 6 + len(geometry)] = geometry
        if rng.random() >= 0.4:  # a plain colour
            floats[i, 1:4] = rng.uniform(25, 235, 3)
            continue
        # A textured shape, drawn only over its bounding box.
        x0, y0 = max(math.floor(box[0]) - 1, 0), max(math.floor(box[1]) - 1, 0)
        x1, y1 = min(math.ceil(box[2]) + 2, w), min(math.ceil(box[3]) + 2, h)
        if x1 <= x0 or y1 <= y0:
            shapes[i, 1] = -1
            continue
        shapes[i, 1:6] = (1, x0, y0, x1, y1)
        # The two colours in one draw of six (the same doubles as two draws of
        # three: uniform is elementwise over the generator's stream).
        floats[i, 1:7] = rng.uniform(25, 235, 6)
        floats[i, 7] = rng.uniform(3.0, 12.0)
        floats[i, 8] = rng.uniform(0, np.pi)
        floats[i, 9] = rng.random()
    lines = np.empty((n_lines, 9))
    for i in range(n_lines):
        x0f, y0f = rng.uniform(0, 1, 2).tolist()
        lines[i, :2] = x0f * w, y0f * h
        lines[i, 2:4] = rng.normal(size=2)
        lines[i, 4] = rng.uniform(0.2, 1.0) * size
        lines[i, 5:8] = rng.uniform(20, 240, 3)
        lines[i, 8] = int(rng.integers(1, 3)) * unit
    return ClutterPlan(shapes, floats, lines)


@functools.cache
def _kernel_plans_as_numpy() -> bool:
    """Whether the clutter kernel draws as the installed numpy does (checked once).

    numba's draws are its ports of numpy's algorithms, and the polygons use
    its ``cos`` and ``sin``; a numpy whose draws or trigonometry differed
    would make backgrounds depend on whether numba is installed. So on first
    use both plan the clutter of 20 seeds (about 3 ms); where anything
    differs, numpy plans, with one ``RuntimeWarning``.
    """
    for seed in range(20):
        h, w, density = (128, 128, 1.0) if seed % 2 else (96 + seed, 160, 0.5 + seed / 8)
        ours_rng, theirs_rng = np.random.default_rng(seed), np.random.default_rng(seed)
        ours = _kernels.clutter_plan(ours_rng, h, w, *_clutter_sizes(h, w, density))
        if ours is None:
            return True  # the kernels are off (numba failed and said so): nothing to check
        theirs = _clutter_plan(theirs_rng, h, w, density, kernel=False)
        same = all(np.array_equal(a, b) for a, b in zip(ours, theirs, strict=True))
        if not same or ours_rng.random() != theirs_rng.random():
            warnings.warn(
                f"humotion_gym: this numpy ({np.__version__}) draws the background's clutter "
                "otherwise than the clutter kernel; numpy draws it (the other kernels still run).",
                RuntimeWarning,
                stacklevel=4,
            )
            return False
    return True


def _clutter_shape(target: NDArray[np.uint8], row: list[int], angle: float, color: Any) -> None:
    """Draw one filled clutter shape (a plan's row: box, ellipse or polygon) on ``target``.

    A textured shape's ``target`` is its window's mask, its geometry moved by
    the window's corner.
    """
    kind, textured, ox, oy = row[0], row[1], row[2], row[3]
    if not textured:
        ox = oy = 0
    if kind == 0:  # axis-aligned box (furniture, frames, doors)
        x0, y0, x1, y1 = row[6:10]
        cv2.rectangle(target, (x0 - ox, y0 - oy), (x1 - ox, y1 - oy), color, -1)
    elif kind == 1:  # ellipse
        cx, cy, ax, ay = row[6:10]
        cv2.ellipse(target, (cx - ox, cy - oy), (ax, ay), angle, 0, 360, color, -1)
    else:  # random convex polygon
        n = row[6]
        polygon = np.array(row[7 : 7 + 2 * n], np.int32).reshape(n, 2)
        if textured:
            polygon -= np.array([ox, oy], np.int32)
        cv2.fillConvexPoly(target, polygon, color)


def _clutter_colors(draws: NDArray[np.float64], channels: int) -> list[list[float]]:
    """Each row of RGB draws as the frame's channels, rounded (as OpenCV is given a colour)."""
    if channels == 3:
        return draws.round().tolist()
    # each colour's luminance on its own, as _to_channels gives it
    return [_to_channels(rgb, 1).round().tolist() for rgb in draws]


def _draw_clutter(img: NDArray[np.uint8], scene: SceneOptions, rng: np.random.Generator) -> None:
    h, w, channels = img.shape
    shapes, floats, lines = _clutter_plan(rng, h, w, scene.clutter_density)
    # Every shape's colours at once: a plain shape's one, a textured shape's two.
    colors = _clutter_colors(floats[:, 1:7].reshape(-1, 3), channels)
    if not (
        _kernels.ENABLED
        and _kernel_clutter_as_opencv()
        and _kernels.clutter_shapes(
            img, shapes, floats, _color_table(colors, channels), _opencv_sin_table()
        )
    ):
        _draw_clutter_shapes(img, shapes, floats, colors)
    line_colors = _clutter_colors(lines[:, 5:8], channels)
    for (x0f, y0f, dx, dy, length, *_, thickness), color in zip(
        lines.tolist(), line_colors, strict=True
    ):
        direction = np.array([dx, dy])
        # np.linalg.norm of a real vector is sqrt(x . x): the same bits, without its wrapper.
        norm = math.sqrt(direction.dot(direction)) + 1e-12
        dx, dy = dx / norm, dy / norm
        cv2.line(
            img,
            (int(x0f), int(y0f)),
            (int(x0f + length * dx), int(y0f + length * dy)),
            color,
            int(thickness),
            cv2.LINE_AA,
        )


def _draw_clutter_shapes(
    img: NDArray[np.uint8],
    shapes: NDArray[np.int64],
    floats: NDArray[np.float64],
    colors: list[list[float]],
) -> None:
    """A clutter plan's shapes drawn by OpenCV, in plan order: the shape kernel's reference.

    A plain shape is filled in its colour; a textured one is filled into a
    mask of its window, then painted with its two colours where the mask is
    set. ``colors`` holds two rows per shape (:func:`_clutter_colors`).
    """
    for i, (row, f) in enumerate(zip(shapes.tolist(), floats.tolist(), strict=True)):
        if row[1] < 0:
            continue
        if row[1] == 0:  # a plain colour, drawn directly
            _clutter_shape(img, row, f[0], colors[2 * i])
            continue
        x0, y0, x1, y1 = row[2:6]
        mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
        _clutter_shape(mask, row, f[0], 255)
        # Pixels per stripe, in proportion to the shape's window.
        period = f[7] * max(y1 - y0, x1 - x0) / 128.0 + 2.0
        palette = np.array(colors[2 * i : 2 * i + 2], np.uint8)
        _paint_texture(img[y0:y1, x0:x1], mask, palette, period, f[8], f[9] >= 0.5)


def _color_table(colors: list[list[float]], channels: int) -> NDArray[np.uint8]:
    """:func:`_clutter_colors`' rows as the shape kernel's ``(S, 2, C)`` uint8 table.

    The rows are whole numbers in [0, 255] (rounded draws), so the cast is
    what OpenCV makes of a colour and what the texture's palette holds.
    """
    return np.array(colors, np.uint8).reshape(-1, 2, channels)


@functools.cache
def _opencv_sin_table() -> NDArray[np.float32]:
    """OpenCV's table of the sines of whole degrees 0..450, read from the installed OpenCV.

    ``cv2.ellipse`` takes its polygon's cosines and sines from a float32
    table; the shape kernel needs the same numbers. ``cv2.ellipse2Poly`` of
    an unrotated circle of radius 2^29 in 1-degree steps gives ``2^29`` times
    each entry, rounded, which is exact for every entry of 2^-6 or more (and
    0): ``y`` the sines of 0..360, ``x`` the cosines, which are entries 90..450.
    """
    radius = 1 << 29
    points = np.asarray(cv2.ellipse2Poly((0, 0), (radius, radius), 0, 0, 360, 1), np.float64)
    if points.shape != (361, 2):
        raise ValueError(
            f"cv2.ellipse2Poly of a whole turn in 1-degree steps gave {points.shape[0]} points, "
            "expected 361"
        )
    table = np.empty(451, np.float64)
    table[:361] = points[:, 1] / radius
    table[450:89:-1] = points[:, 0] / radius
    return table.astype(np.float32)


@functools.cache
def _kernel_clutter_as_opencv() -> bool:
    """Whether the shape kernel draws clutter as the installed OpenCV does (checked once).

    The kernel copies OpenCV's integer steps and its sine table; an OpenCV
    release that drew otherwise would make backgrounds depend on whether
    numba is installed. So on first use both draw the shapes of 24 random
    plans (colour and grey, two sizes) and ellipses at every whole angle the
    plans use (about 10 ms); where any pixel differs, OpenCV draws, with one
    ``RuntimeWarning``.
    """
    try:
        table = _opencv_sin_table()
    except ValueError as exc:
        warnings.warn(
            f"humotion_gym: this OpenCV ({cv2.__version__}) does not give its sine table ({exc}); "
            "OpenCV draws the background's shapes (the other kernels still run).",
            RuntimeWarning,
            stacklevel=4,
        )
        return False
    rng = np.random.default_rng(20261125)
    cases = []
    for seed in range(24):
        h, w = (128, 128) if seed % 2 else (96, 160)
        channels = 3 if seed % 3 else 1
        plan = _clutter_plan(np.random.default_rng(seed), h, w, 1.0 + seed / 8, kernel=False)
        cases.append((h, w, channels, plan.shapes, plan.shape_floats))
    # Every rounded angle of an ellipse (0..180) at small and large half-axes.
    n = 181
    ellipses = np.zeros((n, 19), np.int64)
    ellipses[:, 0] = 1
    ellipses[:, 6:8] = rng.integers(-20, 150, (n, 2))
    ellipses[:, 8:10] = rng.choice([1, 2, 5, 12, 40, 90], (n, 2))
    angles = np.zeros((n, 10))
    angles[:, 0] = np.arange(n) + rng.uniform(-0.49, 0.49, n)
    angles[:, 1:4] = rng.uniform(25, 235, (n, 3))
    cases.append((128, 128, 3, ellipses, angles))
    for h, w, channels, shapes, floats in cases:
        colors = _clutter_colors(floats[:, 1:7].reshape(-1, 3), channels)
        ours = np.full((h, w, channels), 7, np.uint8)
        theirs = ours.copy()
        _draw_clutter_shapes(theirs, shapes, floats, colors)
        if not _kernels.clutter_shapes(ours, shapes, floats, _color_table(colors, channels), table):
            return True  # the kernels are off (numba failed and said so): nothing to check
        if not np.array_equal(ours, theirs):
            warnings.warn(
                f"humotion_gym: this OpenCV ({cv2.__version__}) draws the background's shapes "
                "otherwise than the shape kernel; OpenCV draws them (the other kernels still "
                "run).",
                RuntimeWarning,
                stacklevel=4,
            )
            return False
    return True


def noise_bank(scene: SceneOptions, rng: np.random.Generator) -> NDArray[np.uint8]:
    """A bank of sensor noise for :func:`make_background` (see :class:`Background`).

    Drawing it is a third of the cost of a background; the environments draw
    one per seeded reset and reuse it for the episodes that follow (each frame
    still reads its own random window of it).

    Args:
        scene: Scene options (their size, channels and ``noise_sigma``).
        rng: Generator to draw it from (advanced by this call).

    Returns:
        The ``(2, 2H, 2W, C)`` uint8 bank: the positive and negative parts of
        Gaussian noise drawn by inverse transform (each uniform random byte
        ``k`` maps to the quantile at ``(k + 0.5) / 256``, rounded to a grey
        level, so the tails are cut at 2.89 sigma); ``(2, 1, 1, C)`` zeros
        without noise.
    """
    shape = _bank_shape(scene)
    if scene.noise_sigma <= 0:
        return np.zeros(shape, np.uint8)
    _, h2, w2, c = shape
    positive, negative = _noise_tables(scene.noise_sigma)
    raw = np.frombuffer(rng.bytes(h2 * w2 * c), dtype=np.uint8).reshape(h2, w2, c)
    bank = np.empty(shape, np.uint8)
    bank[0] = cv2.LUT(raw, positive).reshape(h2, w2, c)
    bank[1] = cv2.LUT(raw, negative).reshape(h2, w2, c)
    return bank


def make_background(
    scene: SceneOptions, rng: np.random.Generator, noise: NDArray[np.uint8] | None = None
) -> Background:
    """The background of one episode, drawn from the episode's generator.

    Args:
        scene: Scene options.
        rng: The episode's random generator (advanced by this call).
        noise: A bank from :func:`noise_bank` for the same scene options to
            reuse; when None a new one is drawn from ``rng``.

    Returns:
        The :class:`Background` to pass to every :func:`render` call of the
        episode.

    Raises:
        ValueError: If ``noise`` is not a bank of these scene options.
    """
    h, w, channels = scene.frame_shape
    if noise is not None:
        want = _bank_shape(scene)
        if noise.dtype != np.uint8 or noise.shape != want:
            raise ValueError(
                f"make_background: noise must be a uint8 bank of shape {want} for these scene "
                f"options, got {noise.dtype} {noise.shape}"
            )
    base = np.asarray(scene.background_color, dtype=np.float64)
    clutter = scene.background == "clutter" and scene.clutter_density > 0
    if clutter:
        # np.clip's per-call cost is ten times its work on three numbers.
        base = np.minimum(np.maximum(base + rng.uniform(-20, 20), 0.0), 255.0)
    img = np.empty((h, w, channels), np.uint8)
    # Fill one row, then the image from it: broadcasting a colour over every
    # pixel at once is 20 times slower.
    img[0] = _to_channels(base, channels).round().astype(np.uint8)
    img[1:] = img[0]
    if clutter:
        _draw_clutter(img, scene, rng)
    k = scene.occluders
    occ = np.zeros((k, 7))
    if k:
        # Each occluder sweeps across the image along a line through the middle
        # third (where fitted cameras put the figure), once per period.
        size = min(h, w)
        heading = rng.uniform(0, 2 * np.pi, k)
        occ[:, 0] = rng.integers(0, 2, k)
        occ[:, 1] = rng.uniform(0, scene.occluder_period, k)
        occ[:, 2] = heading
        occ[:, 3] = rng.uniform(-1 / 6, 1 / 6, k) * size
        occ[:, 4] = math.hypot(w, h) / scene.occluder_period
        occ[:, 5] = rng.uniform(0.06, 0.15, k) * size
        # Bars lie roughly across their motion (a pole passing by); blobs anyhow.
        across = heading + np.pi / 2 + rng.uniform(-0.35, 0.35, k)
        occ[:, 6] = np.where(occ[:, 0] == 0, across, rng.uniform(0, np.pi, k))
    if k:
        occ_colors = _to_channels(rng.uniform(20, 235, (k, 3)), channels).round().astype(np.uint8)
    else:  # (no draw is made for no occluder: the generator is where it was)
        occ_colors = np.zeros((0, channels), np.uint8)
    img.setflags(write=False)
    if noise is None:
        noise = noise_bank(scene, rng)
    return Background(scene, img, occ, occ_colors, noise)


def _check_camera(camera: Camera, scene: SceneOptions, where: str) -> None:
    if (camera.width, camera.height) != (scene.width, scene.height):
        raise ValueError(
            f"{where}: camera is {camera.width}x{camera.height} but the scene is "
            f"{scene.width}x{scene.height}"
        )


def _check_inputs(params: ArrayLike, camera: Camera, scene: SceneOptions) -> NDArray[np.float64]:
    p = np.asarray(params, dtype=np.float64)
    if p.shape != (body.N_PARAMS,):
        raise ValueError(f"render: expected one pose of shape (25,), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("render: the pose has non-finite parameters")
    _check_camera(camera, scene, "render")
    return p


def _drawing_constants(scene: SceneOptions) -> dict[str, NDArray]:
    """Per-scene arrays of the drawing code (stored on the SceneOptions)."""
    strips = scene.shading_strips
    edges = np.linspace(-1.0, 1.0, strips + 1)
    across = 0.5 * (edges[1:] + edges[:-1])  # lateral position of each strip's centre
    light = np.asarray(scene.light_direction, dtype=np.float64)
    light = light / np.linalg.norm(light)
    # Lambert factors from the cone's (cap . l, m . l, w . l): column 0 the
    # visible cap, column 1 the flat shade of a narrow cone (normal w, facing
    # the camera), then one column per strip: normal = s m + sqrt(1 - s^2) w.
    shading = np.zeros((3, 2 + strips))
    shading[0, 0] = 1.0
    shading[2, 1] = 1.0
    shading[1, 2:] = across
    shading[2, 2:] = np.sqrt(1.0 - across**2)
    # Strip b joins corners (b, start), (b, end), (b + 1, end), (b + 1, start)
    # of each cone's (S + 1) x 2 corner grid.
    quad = np.array([[2 * b, 2 * b + 1, 2 * b + 3, 2 * b + 2] for b in range(strips)])
    quad = quad[None] + (2 * strips + 2) * np.arange(N_CONES)[:, None, None]
    return {
        "edges": edges[:, None],  # (S + 1, 1): broadcast over a cone's two ends
        "shading": shading,
        "light": light,
        "base": _to_channels(scene.figure_colors, scene.channels)[:, None, :],
        "quad_index": quad,
        "cos": _UNIT_CIRCLE[0],
        "sin": _UNIT_CIRCLE[1],
    }


def _clip_far(coords: NDArray[np.float64]) -> None:
    """Clip fixed-point coordinates to +-_FAR_PX pixels in place (valid int32).

    Two ufunc calls: ``np.clip``'s Python wrapper costs more than the work here.
    """
    np.minimum(coords, _FAR_PX * _ONE, out=coords)
    np.maximum(coords, -_FAR_PX * _ONE, out=coords)


def _figure_polygons(
    geometry: NDArray[np.float64], shape: BodyShape, camera: Camera, scene: SceneOptions
) -> tuple[list[list[int]], NDArray[np.int32], NDArray[np.int32], NDArray[np.uint8], list]:
    """Everything the drawing loop needs, for T frames and all ten cones at once.

    Vectorised over frames, cones and ellipse points, component by component
    (every array below is contiguous): a few dozen numpy calls in all, so a
    whole episode costs a few times what one frame does. Pixel coordinates are
    kept in OpenCV's fixed point (``_SHIFT`` fractional bits) throughout.

    Args:
        geometry: ``(T, 35, 3)`` keypoints and cone axes in each frame's camera
            frame (the layout of :func:`~humotion_gym.kinematics.single_pose_geometry`).
        shape: The subject's shape.
        camera: The cameras' intrinsics (every frame's camera has the same).
        scene: Scene options.

    Returns:
        Per frame, the drawing order (far first, only cones in front of the
        camera); end-ellipse points ``(T, 10, 2K, 2)`` and strip quads
        ``(T, 10, S, 4, 2)`` in fixed point; uint8 colours ``(T, 10, 2 + S, C)``
        (cap, flat, strips); whether each cone is wide enough for strips
        (``T x 10`` lists).
    """
    const: dict[str, NDArray] = scene._drawing  # type: ignore[attr-defined]
    n = geometry.shape[0]
    if _kernels.ENABLED:
        out = _compiled_polygons(geometry, shape, camera, scene, const)
        if out is not None:
            return out
    g = geometry.transpose(2, 0, 1)  # (3, T, 35): x, y, z components
    ends = g[:, :, _CONE_ROWS]  # (3, T, 10, 2): start and end of each cone
    ax = g[:, :, N_KEYPOINTS:].reshape(3, n, N_CONES, 2)
    ax_x = ax[..., 0]  # (3, T, 10): the cone's width axis
    ax_y = ax[..., 1] * shape.aspect  # its depth axis, scaled to the ellipse's
    # End ellipses: centre + r (cos t x + aspect sin t y), (3, T, 10, 2, K).
    ring = ax_x[..., None] * const["cos"]
    ring += ax_y[..., None] * const["sin"]
    points = ring[:, :, :, None, :] * shape.radii[:, :, None]
    points += ends[..., None]
    # Pinhole projection in fixed point: u = (f x / z + cx) * 2^shift.
    fx, (cx, cy) = camera.focal * _ONE, camera.principal_point
    scale = np.maximum(points[2], _NEAR_MM)
    np.divide(fx, scale, out=scale)
    ellipse_px = np.empty((n, N_CONES, 2, _ELLIPSE_POINTS, 2), np.int32)
    for i, centre in enumerate((cx, cy)):
        coord = points[i] * scale
        coord += centre * _ONE
        _clip_far(coord)
        np.copyto(ellipse_px[..., i], coord, casting="unsafe")  # truncates, as astype
    ellipse_px = ellipse_px.reshape(n, N_CONES, 2 * _ELLIPSE_POINTS, 2)
    # The cone ends' image points, and the unit image normal (dy, -dx) of the
    # projected axis.
    end_scale = fx / np.maximum(ends[2], _NEAR_MM)  # (T, 10, 2)
    end_u = ends[0] * end_scale + cx * _ONE
    end_v = ends[1] * end_scale + cy * _ONE
    nx = end_v[..., 1] - end_v[..., 0]
    ny = end_u[..., 0] - end_u[..., 1]
    length = np.hypot(nx, ny)
    length += 1e-12
    nx /= length
    ny /= length
    # Silhouette half-width along the normal: r |(x.m, aspect y.m)| in pixels
    # for an elliptical section.
    half = np.hypot(ax_x[0] * nx + ax_x[1] * ny, ax_y[0] * nx + ax_y[1] * ny)
    width = shape.radii * end_scale
    width *= half[..., None]  # (T, 10, 2), fixed point
    # Strip corners: the ends pushed along the normal by the strips' edges,
    # a (S + 1) x 2 grid per cone.
    corners = np.empty((n, N_CONES, len(const["edges"]), 2, 2))
    np.multiply(const["edges"], (width * nx[..., None])[:, :, None], out=corners[..., 0])
    np.multiply(const["edges"], (width * ny[..., None])[:, :, None], out=corners[..., 1])
    corners[..., 0] += end_u[:, :, None]
    corners[..., 1] += end_v[:, :, None]
    _clip_far(corners)
    quads = np.take(corners.astype(np.int32).reshape(n, -1, 2), const["quad_index"], axis=1)
    # Lambert shading: the cone axis a, the image normal m and the normal w
    # facing the camera across the limb (w = (a_z a - e_z) / sqrt(1 - a_z^2)).
    axis = ends[..., 1] - ends[..., 0]  # (3, T, 10)
    axis /= np.sqrt((axis * axis).sum(axis=0)) + 1e-12
    lx, ly, lz = const["light"].tolist()
    a_l = axis[0] * lx + axis[1] * ly + axis[2] * lz
    a_z = axis[2]
    dots = np.empty((n, N_CONES, 3))
    np.multiply(a_l, -np.sign(a_z), out=dots[..., 0])  # the cap that faces the camera
    dots[..., 1] = nx * lx + ny * ly
    dots[..., 2] = (a_z * a_l - lz) / np.sqrt(1.0 - a_z * a_z + 1e-9)
    lambert = dots @ const["shading"]
    np.maximum(lambert, 0.0, out=lambert)
    lambert *= scene.diffuse
    lambert += scene.ambient
    # Rounded and saturated here as OpenCV would when drawing.
    colors = np.rint(const["base"] * lambert[..., None])
    colors = np.minimum(colors, 255.0, out=colors).astype(np.uint8)
    wide = (width.max(axis=-1) >= _STRIP_MIN_HALF_WIDTH_PX * _ONE).tolist()
    # Painter's order, far first; cones whose end spheres reach behind the near
    # plane are skipped (rare: only frames that have one are filtered).
    order = np.argsort(-ends[2].sum(axis=-1), axis=-1, kind="stable").tolist()
    visible = (ends[2] - shape.radii).min(axis=-1) > _NEAR_MM  # (T, 10)
    if not visible.all():
        for t in np.flatnonzero(~visible.all(axis=1)).tolist():
            order[t] = [c for c in order[t] if visible[t, c]]
    return order, ellipse_px, quads, colors, wide


def _compiled_polygons(
    geometry: NDArray[np.float64],
    shape: BodyShape,
    camera: Camera,
    scene: SceneOptions,
    const: dict[str, NDArray],
) -> tuple[list[list[int]], NDArray[np.int32], NDArray[np.int32], NDArray[np.uint8], list] | None:
    """:func:`_figure_polygons` by the compiled kernel (the same numbers), or None."""
    n = geometry.shape[0]
    n_strips = const["quad_index"].shape[1]
    channels = const["base"].shape[2]
    ellipse_px = np.empty((n, N_CONES, 2 * _ELLIPSE_POINTS, 2), np.int32)
    quads = np.empty((n, N_CONES, n_strips, 4, 2), np.int32)
    colors = np.empty((n, N_CONES, n_strips + 2, channels), np.uint8)
    order = np.empty((n, N_CONES), np.int64)
    counts = np.empty(n, np.int64)
    wide = np.empty((n, N_CONES), np.bool_)
    (cx, cy), fx = camera.principal_point, camera.focal * _ONE
    if not _kernels.figure_polygons(
        np.ascontiguousarray(geometry, np.float64), _CONE_ROWS, shape.radii, shape.aspect,
        const["cos"], const["sin"], fx, cx * _ONE, cy * _ONE, _FAR_PX * _ONE, _NEAR_MM,
        np.ascontiguousarray(const["edges"][:, 0]), const["light"], const["shading"],
        np.ascontiguousarray(const["base"][:, 0, :]), float(scene.diffuse), float(scene.ambient),
        _STRIP_MIN_HALF_WIDTH_PX * _ONE, const["quad_index"],
        ellipse_px, quads, colors, order, counts, wide,
    ):  # fmt: skip
        return None
    rows = order.tolist()
    if counts.min() < N_CONES:
        rows = [row[:k] for row, k in zip(rows, counts.tolist(), strict=True)]
    return rows, ellipse_px, quads, colors, wide.tolist()


@dataclass(frozen=True, eq=False)
class FigureSequence:
    """The cone figure of T frames, ready to draw (see :func:`figure_sequence`).

    Attributes:
        scene: The scene options it was prepared for.
        order: Per frame, the cones to draw, far first.
        ellipses: ``(T, 10, 2K, 2)`` int32 end-ellipse points (fixed point).
        quads: ``(T, 10, S, 4, 2)`` int32 shading-strip corners (fixed point).
        colors: ``(T, 10, 2 + S, C)`` uint8 colours of each cone's cap, flat
            shade and strips.
        wide: ``T x 10`` booleans: whether a cone is drawn with strips.
    """

    scene: SceneOptions
    order: list[list[int]] = field(repr=False)
    ellipses: NDArray[np.int32] = field(repr=False)
    quads: NDArray[np.int32] = field(repr=False)
    colors: NDArray[np.uint8] = field(repr=False)
    wide: list = field(repr=False)

    def __len__(self) -> int:
        return len(self.order)

    @functools.cached_property
    def tables(self) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
        """``order`` and ``wide`` as arrays, for the drawing kernel.

        ``(T, 10)`` cone indices, each frame's first :attr:`counts` of them
        its drawing order, and ``(T, 10)`` booleans.
        """
        if min(self.counts) == N_CONES:  # every cone in every frame: the usual case
            order = np.array(self.order, np.intp).reshape(-1, N_CONES)
        else:
            order = np.zeros((len(self.order), N_CONES), np.intp)
            for t, cones in enumerate(self.order):
                order[t, : len(cones)] = cones
        return order, np.array(self.wide, dtype=bool).reshape(-1, N_CONES)

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
    in_camera, first = _in_camera(params, shape, cameras, scene, geometry)
    order, ellipses, quads, colors, wide = _figure_polygons(in_camera, shape, first, scene)
    return FigureSequence(scene, order, ellipses, quads, colors, wide)


def figure_sequences(
    sequences: Sequence[tuple[ArrayLike, BodyShape, Camera | Sequence[Camera], ArrayLike | None]],
    scene: SceneOptions,
) -> list[FigureSequence]:
    """:func:`figure_sequence` of several sequences, prepared in one pass.

    Each sequence's poses are brought into its cameras' frames as
    :func:`figure_sequence` does; then the silhouettes, shading and depth
    order of the frames of every sequence whose figure has the same radii and
    aspect and whose cameras the same intrinsics are computed together (in
    chunks of whole sequences of up to 64 frames, the size that stays in the
    caches). The result is the same, frame for frame and bit for bit, as one call per
    sequence (every step is elementwise over frames); the vector environment
    prepares the episodes it starts in one step this way.

    Args:
        sequences: ``(params, shape, cameras, geometry)`` per sequence, the
            arguments of :func:`figure_sequence`.
        scene: Scene options.

    Returns:
        One :class:`FigureSequence` per sequence, in order.
    """
    prepared = [_in_camera(p, shape, cams, scene, g) for p, shape, cams, g in sequences]
    groups: dict[tuple, list[int]] = {}
    for i, ((_, shape, _, _), (_, cam)) in enumerate(zip(sequences, prepared, strict=True)):
        key = (shape.radii.tobytes(), shape.aspect.tobytes(), cam.focal, cam.principal_point)
        groups.setdefault(key, []).append(i)
    # Each group is prepared in chunks of whole sequences of at most
    # _CHUNK_FRAMES frames (a longer sequence alone): beyond about 64 frames
    # the arrays outgrow the caches and a frame costs twice as much.
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
            )
            start = stop
    return [seq for seq in out if seq is not None]


def _in_camera(
    params: ArrayLike,
    shape: BodyShape,
    cameras: Camera | Sequence[Camera],
    scene: SceneOptions,
    geometry: ArrayLike | None,
) -> tuple[NDArray[np.float64], Camera]:
    """The checked poses' geometry in each frame's camera frame, and the first camera."""
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
    return in_camera, first


def _draw_figure(img: NDArray[np.uint8], figures: FigureSequence, t: int) -> None:
    """Draw frame ``t``'s cones, far first, into ``img`` (``(H, W, C)``, or ``(H, W)``)."""
    if _kernels.ENABLED and _kernel_draws_as_opencv():
        order, wide = figures.tables
        canvas = img.reshape(img.shape[0], img.shape[1], -1)
        if _kernels.draw_figure(
            canvas, figures.ellipses[t], figures.quads[t], figures.colors[t],
            order[t, : figures.counts[t]], wide[t], _SHIFT,
        ):  # fmt: skip
            return
    _draw_with_opencv(
        img, figures.order[t], figures.ellipses[t], figures.quads[t], figures.colors[t],
        figures.wide[t],
    )  # fmt: skip


def _draw_with_opencv(
    img: NDArray[np.uint8],
    order: Sequence[int],
    ellipses: NDArray[np.int32],
    quads: NDArray[np.int32],
    colors: NDArray[np.uint8],
    wide: Sequence[bool] | NDArray[np.bool_],
) -> None:
    """One frame's cones drawn by OpenCV, in ``order``: the drawing kernel's reference.

    Each cone's hull is filled in the cap's colour with its strips over it (a
    wide cone) or in the flat shade.
    """
    colors_l = colors.tolist()  # lists of ints, per frame, for OpenCV
    # Local names: this loop runs some twenty OpenCV calls per frame, and the
    # attribute look-ups would be a tenth of its Python time.
    fill, hull_of, line8 = cv2.fillConvexPoly, cv2.convexHull, cv2.LINE_8
    for c in order:
        color = colors_l[c]
        if wide[c]:
            fill(img, hull_of(ellipses[c]), color[0], line8, _SHIFT)
            cone_quads = quads[c]
            for b in range(len(color) - 2):
                fill(img, cone_quads[b], color[b + 2], line8, _SHIFT)
        else:
            fill(img, hull_of(ellipses[c]), color[1], line8, _SHIFT)


@functools.cache
def _kernel_draws_as_opencv() -> bool:
    """Whether the drawing kernel fills as the installed OpenCV does (checked once).

    The kernel copies OpenCV's integer steps; an OpenCV release that drew
    otherwise would make frames depend on whether numba is installed. So on
    first use both draw the same 20 random figures of 10 hulls and strips
    (about 6 ms); where any pixel differs, OpenCV draws, with one
    ``RuntimeWarning``.
    """
    rng = np.random.default_rng(20261124)
    for _ in range(20):
        ellipses = (rng.integers(0, 2400, (10, 24, 2)) - 600).astype(np.int32)
        ellipses[:, rng.integers(3, 24) :] = ellipses[:, :1]  # fewer distinct points
        quads = (rng.integers(0, 2400, (10, 3, 4, 2)) - 600).astype(np.int32)
        colors = rng.integers(0, 256, (10, 5, 3)).astype(np.uint8)
        order = rng.permutation(10).astype(np.intp)
        wide = rng.random(10) < 0.5
        ours = np.zeros((96, 128, 3), np.uint8)
        theirs = ours.copy()
        _draw_with_opencv(theirs, order.tolist(), ellipses, quads, colors, wide)
        if not _kernels.draw_figure(ours, ellipses, quads, colors, order, wide, _SHIFT):
            return True  # the kernels are off (numba failed and said so): nothing to check
        if not np.array_equal(ours, theirs):
            warnings.warn(
                f"humotion_gym: this OpenCV ({cv2.__version__}) fills polygons otherwise than "
                "the drawing kernel; OpenCV draws the figures (the other kernels still run).",
                RuntimeWarning,
                stacklevel=4,
            )
            return False
    return True


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


def _noise_windows(rng: np.random.Generator, h: int, w: int, count: int) -> NDArray[np.intp]:
    """``(count, 2)`` rows and columns: :func:`_noise_window` called ``count`` times.

    One call of ``rng.integers`` with ``size=count`` gives the numbers that
    ``count`` scalar calls give, in order, and leaves the generator where they
    leave it (numpy bounds each element alone; ``tests/test_render.py``
    checks both). The vector environment draws an episode's windows at its
    start, a frame's draw then costing a table lookup.
    """
    rows, cols = np.divmod(rng.integers(0, (h + 1) * (w + 1), size=count), w + 1)
    return np.stack([rows, cols], axis=1).astype(np.intp)


def _add_noise(
    img: NDArray[np.uint8],
    bank: NDArray[np.uint8],
    rng: np.random.Generator,
    window: tuple[int, int] | None = None,
) -> None:
    """Add the bank's window at ``window``, else at a random one (:func:`_noise_window`)."""
    h, w = img.shape[:2]
    y, x = _noise_window(rng, h, w) if window is None else window
    if _kernels.add_noise(img, bank, y, x):  # the same bytes, in one pass
        return
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
        >>> from humotion_gym import body
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
    p = _check_inputs(params, camera, scene)
    if background is None:
        background = make_background(scene, rng)
    # One pose: the kinematics on Python floats beats the batched version.
    geometry = single_pose_geometry(p, shape, camera.rotation, camera.translation)[None]
    figures = FigureSequence(scene, *_figure_polygons(geometry, shape, camera, scene))
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
    if not (isinstance(t, (int, np.integer)) and 0 <= t < len(figures)):
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
    """Background, figure, occluders, noise and blur: one frame.

    ``out``, when given, is the ``(H, W, C)`` uint8 array to draw into (the
    vector environment draws each frame straight into its row of the batch,
    saving a copy per frame); otherwise a new array. ``window``, when given,
    is the noise window drawn beforehand from ``rng`` (:func:`_noise_windows`);
    otherwise the frame draws it. Returns the frame.
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
    _draw_figure(canvas, figures, t)
    if scene.occluders:
        _draw_occluders(canvas, background, frame_index)
    if scene.noise_sigma > 0:
        _add_noise(canvas, background.noise, rng, window)
    if scene.blur_sigma > 0:
        gaussian_blur(canvas, scene.blur_sigma, dst=canvas)
    return img


def gaussian_blur(img: NDArray[Any], sigma: float, dst: NDArray[Any] | None = None) -> NDArray[Any]:
    """``cv2.GaussianBlur(img, (0, 0), sigma)``: its bytes, by the smallest kernel that gives them.

    For 8-bit images OpenCV takes ``round(6 sigma + 1) | 1`` taps and blurs in
    fixed point, where a small sigma's outer taps round to zero: at sigma 0.8
    (the observation model's ``edge_blur``) 7 taps, of which 5 are not zero.
    OpenCV's paths for 3 and 5 taps run about twice as fast as its general one
    (25 against 52 us for a 128x128 colour frame), so the blur asks for the
    smallest size that gives OpenCV's own bytes (:func:`_blur_size`, checked
    once per sigma). Other dtypes get OpenCV's choice.

    Args:
        img: The image.
        sigma: The Gaussian's standard deviation in pixels (> 0).
        dst: Where to write (``img`` itself for in place), or None.

    Returns:
        The blurred image.
    """
    size = _blur_size(float(sigma)) if img.dtype == np.uint8 else 0
    if dst is None:
        return cv2.GaussianBlur(img, (size, size), sigma)
    return cv2.GaussianBlur(img, (size, size), sigma, dst=dst)


@functools.cache
def _blur_size(sigma: float) -> int:
    """The smallest odd kernel size whose 8-bit blur is OpenCV's own choice's (checked once).

    Both blur random frames of several sizes and channel counts (noise, a
    blurred copy, black and white pixels), borders included; the first size
    from 3 up that gives every byte the same is taken, 0 (OpenCV's choice)
    where none up to 31 does. A linear filter whose fixed-point taps differed
    would differ on noise.
    """
    rng = np.random.default_rng(20261125)
    frames = [
        rng.integers(0, 256, (h, w, c)).astype(np.uint8)
        for h, w, c in ((128, 128, 3), (61, 97, 1), (9, 13, 3), (4, 5, 1), (33, 31, 4))
    ]
    frames.append(cv2.GaussianBlur(frames[0], (0, 0), 2.0))
    frames.append((rng.random((40, 50, 3)) < 0.5).astype(np.uint8) * 255)
    want = [cv2.GaussianBlur(f, (0, 0), sigma) for f in frames]
    for size in range(3, 33, 2):
        if all(
            np.array_equal(cv2.GaussianBlur(f, (size, size), sigma), w)
            for f, w in zip(frames, want, strict=True)
        ):
            return size
    return 0


class FrameBatch:
    """:func:`_compose` for the frames of N episodes at once: the vector environment's frames.

    Holds each episode's background, its noise bank as one signed plane and its
    prepared figures in batch arrays, so that one kernel call draws a frame of
    every episode (``_numba_kernels._draw_frames``): the same bytes as
    :func:`_compose` per episode, without its Python calls, and reading half
    the noise bank's bytes (about 7 us a frame less). Scenes with occluders or
    blur, banks that do not fit a signed byte (``noise_sigma`` above 44) and
    machines without the kernels are drawn frame by frame (:meth:`draw` says
    False).

    Args:
        scene: The episodes' scene options.
        n: Number of episodes.
        frames: Frames per episode (the figures' length at most).
    """

    def __init__(self, scene: SceneOptions, n: int, frames: int) -> None:
        self.scene = scene
        h, w, c = scene.frame_shape
        self._images = np.zeros((n, h, w, c), np.uint8)
        self._noisy = scene.noise_sigma > 0
        self._noise = np.zeros((n, 2 * h, 2 * w * c) if self._noisy else (n, 1, 1), np.int8)
        # The bank each row's plane was made from (a bank serves many episodes).
        self._banks: list[NDArray[np.uint8] | None] = [None] * n
        self._signed = np.zeros(n, np.bool_)
        self._usable = scene.occluders == 0 and scene.blur_sigma <= 0
        self._frames = frames
        self._tables: tuple[NDArray[Any], ...] | None = None  # made at the first figures
        self._window_bytes = np.array([1, c], np.intp)

    def set_background(self, i: int, background: Background) -> None:
        """Row ``i``'s episode now shows on ``background``."""
        self._images[i] = background.image
        bank = background.noise
        if not self._noisy:
            self._signed[i] = True  # no noise to add
            return
        if bank is self._banks[i]:
            return
        self._banks[i] = bank
        plus, minus = bank[0], bank[1]
        # A byte is added or subtracted, never both, and fits a signed byte
        # (tails cut at 2.89 sigma: up to sigma 44), or the row is drawn by _compose.
        fits = not np.minimum(plus, minus).any() and max(int(plus.max()), int(minus.max())) < 128
        self._signed[i] = fits
        if fits:
            plane = self._noise[i].reshape(bank.shape[1:])
            np.subtract(plus.view(np.int8), minus.view(np.int8), out=plane)

    def set_figures(self, i: int, figures: FigureSequence, start: int = 0) -> None:
        """Row ``i``'s figures of frames ``start:start + len(figures)``."""
        order, wide = figures.tables
        counts = np.array(figures.counts, np.intp)
        # The kernel's order: ellipses, quads, colours, orders, counts, wides.
        arrays = (figures.ellipses, figures.quads, figures.colors, order, counts, wide)
        if self._tables is None:
            n = self._images.shape[0]
            self._tables = tuple(np.zeros((n, self._frames, *a.shape[1:]), a.dtype) for a in arrays)
        stop = start + len(figures)
        for table, a in zip(self._tables, arrays, strict=True):
            table[i, start:stop] = a

    def draw(
        self,
        out: NDArray[np.uint8],
        rows: NDArray[np.intp],
        ts: NDArray[np.intp],
        windows: NDArray[np.intp],
    ) -> bool:
        """Frame ``ts[j]`` of episode ``rows[j]`` into ``out[rows[j]]``, noise at ``windows[j]``.

        Args:
            out: ``(N, H, W, C)`` uint8 frames to draw into.
            rows: ``(M,)`` intp episodes.
            ts: ``(M,)`` intp frames, one per episode.
            windows: ``(M, 2)`` intp row and column of each frame's window of
                its noise bank (:func:`_noise_windows`; ignored without noise).

        Returns:
            False, having drawn nothing, where the frames are to be drawn one
            by one (see the class).
        """
        if not (
            self._usable and self._tables is not None and _kernels.ENABLED
            and _kernel_draws_as_opencv() and _frames_kernel_works()
            and self._signed[rows].all()
        ):  # fmt: skip
            return False
        # (the kernel takes a window's column in bytes)
        offsets = windows * self._window_bytes if self._noisy else np.zeros((len(rows), 2), np.intp)
        return _kernels.draw_frames(
            out, rows, ts, self._images, self._noise, offsets, *self._tables, _SHIFT, self._noisy,
        )  # fmt: skip


@functools.cache
def _frames_kernel_works() -> bool:
    """Whether the batched frame kernel runs (compiled once); False turns it off.

    A numba that fails here leaves :meth:`FrameBatch.draw` saying False, so
    the frames are drawn one by one from the start.
    """
    scene = SceneOptions(width=64, height=64, background="flat")
    batch = FrameBatch(scene, 1, 1)
    figures = FigureSequence(
        scene, [[0]], np.zeros((1, N_CONES, 2 * _ELLIPSE_POINTS, 2), np.int32),
        np.zeros((1, N_CONES, scene.shading_strips, 4, 2), np.int32),
        np.zeros((1, N_CONES, 2 + scene.shading_strips, 3), np.uint8), [[False] * N_CONES],
    )  # fmt: skip
    batch.set_figures(0, figures)
    return _kernels.draw_frames(
        np.zeros((1, *scene.frame_shape), np.uint8), np.zeros(1, np.intp), np.zeros(1, np.intp),
        batch._images, batch._noise, np.zeros((1, 2), np.intp), *batch._tables, _SHIFT, False,
    )  # fmt: skip


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
        color: RGB colour of the figure.
        thickness: Line thickness in pixels (joint dots get a radius of
            ``thickness + 1``).
        keypoints: The pose's ``(15, 3)`` world keypoints from
            :func:`~humotion_gym.kinematics.single_pose_geometry`, when the
            caller has them already (the environment scored them in ``step``);
            the same figure is drawn, without the kinematics.

    Returns:
        An ``(H, W, 3)`` copy of the frame with the figure drawn (single-channel
        frames are converted to three channels so the colour shows).
    """
    img = np.asarray(frame)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.dtype != np.uint8 or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
        raise ValueError(f"draw_pose_overlay: expected a uint8 image, got {img.dtype} {img.shape}")
    out = cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if img.ndim == 2 else img.copy()
    if thickness < 1:
        raise ValueError("draw_pose_overlay: thickness must be >= 1")
    p = np.asarray(params, dtype=np.float64)
    if p.shape != (body.N_PARAMS,):
        raise ValueError(f"draw_pose_overlay: expected one pose of shape (25,), got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError("draw_pose_overlay: the pose has non-finite parameters")
    if keypoints is None:
        kp = single_pose_geometry(p, shape)[:N_KEYPOINTS]
    else:
        kp = np.asarray(keypoints, dtype=np.float64)
        if kp.shape != (N_KEYPOINTS, 3):
            raise ValueError(f"draw_pose_overlay: keypoints must be (15, 3), got {kp.shape}")
    px = camera.project(kp)
    ok = np.isfinite(px).all(axis=1)
    shown = ok.tolist()
    if not all(shown):
        # Points behind the camera are not drawn; zeros stand in for them so
        # that the conversion to fixed point stays finite.
        px[~ok] = 0.0
    # Plain ufuncs: np.clip and np.nan_to_num cost more than the drawing here.
    np.minimum(px, 1e5, out=px)
    np.maximum(px, -1e5, out=px)
    px *= _ONE
    points = np.rint(px, out=px).astype(np.int32)
    fixed = points.tolist()
    col = tuple(int(v) for v in color)
    # Each edge as its own two-point curve: one OpenCV call draws them one after
    # the other exactly as cv2.line would (the same anti-aliased segments, in order).
    edges = [edge for edge in body.SKELETON_EDGES if shown[edge[0]] and shown[edge[1]]]
    if edges:
        cv2.polylines(out, list(points[edges]), False, col, thickness, cv2.LINE_AA, _SHIFT)
    radius = int((thickness + 1) * _ONE)
    for k, point in enumerate(fixed):
        if shown[k]:
            cv2.circle(out, point, radius, col, -1, cv2.LINE_AA, _SHIFT)
    return out
