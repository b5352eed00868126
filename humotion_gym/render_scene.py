"""The scene of the frames: their options, and each episode's background.

:class:`SceneOptions` says how frames look; :func:`make_background` draws an
episode's :class:`Background` once from the episode's generator: a flat wall
colour, or ``clutter``: random textured shapes and lines whose edges compete
with the figure's, as the furniture of a real room would; the occluders that
will cross the image; and a bank of sensor noise (:func:`noise_bank`) from
which each frame reads a random window. Every draw goes through an explicit
``numpy.random.Generator`` and every pixel is OpenCV's: the same generator
state gives the same background.

The figure's colours are data: :data:`FIGURE_PALETTES` names the palettes
(v1's, v2's ``"shaded"`` with sleeves apart from the torso, and the easier
``"sided"``), and :func:`floor_segments` gives the optional floor's grid
lines in the image of each frame's camera.
"""

from __future__ import annotations

import functools
import math
import statistics
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.body import CONE_NAMES, N_CONES
from humotion_gym.checks import check_count, is_integer, is_real

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


def _recoloured(**colors: Color) -> tuple[Color, ...]:
    """:data:`DEFAULT_FIGURE_COLORS` with the cones named (``body.CONE_NAMES``) recoloured."""
    return tuple(
        colors.get(name, own) for name, own in zip(CONE_NAMES, DEFAULT_FIGURE_COLORS, strict=True)
    )


_SLEEVE: Color = (0, 60, 20)

#: v2's palette: :data:`DEFAULT_FIGURE_COLORS` with dark green sleeves, so
#: that the upper arms stand apart from the torso in hue and in luminance
#: (gray frames show them too) while left and right limbs stay alike. Dark and
#: saturated, they stay far from the grey wall at every shade, where white
#: sleeves shaded into it (docs/v2_limbs.md).
SHADED_FIGURE_COLORS: tuple[Color, ...] = _recoloured(r_upper_arm=_SLEEVE, l_upper_arm=_SLEEVE)

#: The opt-in easier palette: left and right limbs differ, the right ones warm
#: and light, the left ones cool, in luminance as well (so gray frames tell
#: the sides apart too). A tracker no longer has to resolve the
#: left-right ambiguity of a silhouette (Sminchisescu and Triggs, "Kinematic
#: jump processes for monocular 3D human tracking", 2003) from motion alone.
SIDED_FIGURE_COLORS: tuple[Color, ...] = _recoloured(
    r_upper_arm=(255, 240, 200),  # a cream sleeve
    l_upper_arm=(20, 35, 90),  # a navy sleeve
    l_forearm=(235, 245, 255),  # a pale blue glove
    r_thigh=(230, 205, 150),  # khaki
    r_shin=(230, 205, 150),
)

#: The figure palettes by name (:attr:`SceneOptions.palette`): ``"v1"`` the
#: benchmark's first, ``"shaded"`` v2's (sleeves apart from the torso),
#: ``"sided"`` the easier one (left and right apart).
FIGURE_PALETTES: dict[str, tuple[Color, ...]] = {
    "v1": DEFAULT_FIGURE_COLORS,
    "shaded": SHADED_FIGURE_COLORS,
    "sided": SIDED_FIGURE_COLORS,
}

#: RGB colour of the floor's grid lines: darker than the wall, lighter than the shirt and
#: trousers of the default palettes.
FLOOR_COLOR: Color = (112, 112, 108)
#: Spacing of the floor's grid lines (mm): half a metre, a large tile.
FLOOR_SPACING_MM = 500.0
#: The floor is drawn within this distance (mm) of the point under the camera:
#: farther lines would crowd the horizon.
FLOOR_RADIUS_MM = 10000.0
#: Floor lines are cut where they come nearer than this (mm) to the camera
#: plane, so their projections stay finite.
FLOOR_NEAR_MM = 100.0
#: The smallest and the largest frame, ``(width, height)`` in pixels.
MIN_IMAGE_SIZE = (64, 64)
MAX_IMAGE_SIZE = (640, 480)
#: The largest of each scene setting taken: more would only make a frame slow or all noise.
SCENE_MAXIMA: dict[str, float] = {
    "clutter_density": 16.0, "noise_sigma": 255.0, "blur_sigma": 64.0, "ambient": 1.0,
    "diffuse": 1.0, "occluders": 64, "shading_strips": 16,
}  # fmt: skip
_ELLIPSE_POINTS = 12
_UNIT_CIRCLE = np.stack(
    [
        np.cos(2 * np.pi * np.arange(_ELLIPSE_POINTS) / _ELLIPSE_POINTS),
        np.sin(2 * np.pi * np.arange(_ELLIPSE_POINTS) / _ELLIPSE_POINTS),
    ]
)  # (2, K)
_LUMA = np.array([0.299, 0.587, 0.114])  # ITU-R BT.601, as cv2.cvtColor


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
            150, five seconds at 30 fps; a finite number >= 1).
        figure_colors: RGB colour of each cone in ``body.CONE_NAMES`` order
            (default :data:`DEFAULT_FIGURE_COLORS`).
        palette: A name in :data:`FIGURE_PALETTES` (``"v1"``, ``"shaded"``,
            ``"sided"``), or None (default) to keep ``figure_colors``. A
            palette sets ``figure_colors`` to its colours, whatever was given
            for them (so ``dataclasses.replace(scene, palette="sided")``
            switches palettes; pass ``palette=None`` with ``figure_colors``
            for colours of one's own).
        floor: Draw the ground plane ``z = 0`` as a grid of lines
            (:data:`FLOOR_SPACING_MM` apart, within :data:`FLOOR_RADIUS_MM` of
            the point under the camera, in :data:`FLOOR_COLOR`), seen from
            each frame's camera, over the background and behind the figure:
            where a foot meets the floor, and the perspective of the plane,
            cue the figure's depth (default False).
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
    palette: str | None = None
    floor: bool = False

    def __post_init__(self) -> None:
        w, h = self.width, self.height
        if not (is_integer(w) and is_integer(h)):  # a bool is no size
            raise ValueError(f"SceneOptions: width and height must be integers, got {w!r}, {h!r}")
        (w0, h0), (w1, h1) = MIN_IMAGE_SIZE, MAX_IMAGE_SIZE
        if not (w0 <= w <= w1 and h0 <= h <= h1):
            raise ValueError(
                f"SceneOptions: image size must be between {w0}x{h0} and {w1}x{h1}, got {w}x{h}"
            )
        if not (isinstance(self.color, str) and self.color in ("rgb", "gray")):
            raise ValueError(f"SceneOptions.color: expected 'rgb' or 'gray', got {self.color!r}")
        if not (isinstance(self.background, str) and self.background in ("flat", "clutter")):
            raise ValueError(
                f"SceneOptions.background: expected 'flat' or 'clutter', got {self.background!r}"
            )
        for name in ("clutter_density", "noise_sigma", "blur_sigma", "ambient", "diffuse"):
            value, top = getattr(self, name), SCENE_MAXIMA[name]
            if not (is_real(value) and math.isfinite(value) and 0 <= value <= top):
                raise ValueError(
                    f"SceneOptions.{name}: expected a number in [0, {top:g}], got {value!r}"
                )
        for name, low in (("occluders", 0), ("shading_strips", 1)):
            check_count(f"SceneOptions.{name}", getattr(self, name), low, int(SCENE_MAXIMA[name]))
        period = self.occluder_period
        # Under a frame the occluders' speed (the image's diagonal per period)
        # overflows: a crossing quicker than a frame is never seen moving.
        if not (is_real(period) and math.isfinite(period) and period >= 1):
            raise ValueError(
                f"SceneOptions.occluder_period: expected a finite number of frames >= 1, "
                f"got {period!r}"
            )
        if self.palette is not None:
            if not (isinstance(self.palette, str) and self.palette in FIGURE_PALETTES):
                raise ValueError(
                    f"SceneOptions.palette: expected one of {sorted(FIGURE_PALETTES)} or None, "
                    f"got {self.palette!r}"
                )
            object.__setattr__(self, "figure_colors", FIGURE_PALETTES[self.palette])
        if not isinstance(self.floor, (bool, np.bool_)):
            raise ValueError(f"SceneOptions.floor: expected a bool, got {self.floor!r}")
        colors = _numbers(self.figure_colors, "iu")
        if colors is None or colors.shape != (N_CONES, 3) or colors.min() < 0 or colors.max() > 255:
            raise ValueError(
                f"SceneOptions.figure_colors: expected {N_CONES} RGB triples of integers in "
                f"[0, 255], got {self.figure_colors!r}"
            )
        bg = _numbers(self.background_color, "iu")
        if bg is None or bg.shape != (3,) or bg.min() < 0 or bg.max() > 255:
            raise ValueError(
                "SceneOptions.background_color: expected an RGB triple of integers in [0, 255], "
                f"got {self.background_color!r}"
            )
        light = _numbers(self.light_direction, "iuf")
        if (
            light is None
            or light.shape != (3,)
            or not np.all(np.isfinite(light))
            or np.linalg.norm(light) == 0
        ):
            raise ValueError(
                "SceneOptions.light_direction: expected a non-zero vector of 3 finite numbers, "
                f"got {self.light_direction!r}"
            )
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
            at an offset drawn from the frame's generator: i.i.d. per pixel
            within a frame, and independent between two frames unless their
            offsets coincide (one chance in ``(H + 1)(W + 1)``); fresh noise
            per frame would cost more than the rest of the frame. A bank may
            serve many episodes (:func:`noise_bank`).
    """

    scene: SceneOptions
    image: NDArray[np.uint8]
    occluders: NDArray[np.float64]
    occluder_colors: NDArray[np.uint8]
    noise: NDArray[np.uint8] = field(repr=False)


def _numbers(value: Any, kinds: str) -> NDArray[Any] | None:
    """``value`` as an array if its dtype's kind is in ``kinds`` (``"iuf"``), else None.

    Text, bools and ragged nestings give None (a conversion would read ``"5"`` as 5).
    """
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):  # a ragged nesting
        return None
    return array if array.dtype.kind in kinds else None


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
    """Paint stripes (``checker``: and stripes across them) of ``palette``'s two colours.

    Written in place into the image view ``region`` where the mask ``inside`` is non-zero.
    """
    h, w, channels = region.shape
    # The texture's axes scaled to stripes, in float32 as the pixels' steps are.
    cos_a = np.float32(math.cos(angle) / period)
    sin_a = np.float32(math.sin(angle) / period)
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
            colour draws (a plain shape's first three, a texture's two
            colours); the texture's period draw, angle and checker draw.
        lines: ``(L, 9)`` float64, a row per line: start ``x, y``, two normal
            draws (the direction), length, three colour draws, thickness.
    """

    shapes: NDArray[np.int64]
    shape_floats: NDArray[np.float64]
    lines: NDArray[np.float64]


def _clutter_box(kind: int, geometry: list[int], cx: float, cy: float) -> tuple[float, ...]:
    """A clutter shape's bounding box ``(lo_x, lo_y, hi_x, hi_y)`` from its plan geometry."""
    if kind == 0:
        return tuple(geometry)
    if kind == 1:
        reach = geometry[2] + geometry[3]
        return (cx - reach, cy - reach, cx + reach, cy + reach)
    xs, ys = geometry[1::2], geometry[2::2]
    return (min(xs), min(ys), max(xs), max(ys))


def _clutter_plan(rng: np.random.Generator, h: int, w: int, density: float) -> ClutterPlan:
    """Every random draw of a background's clutter, each for every shape (or line) at once.

    A draw is made for a shape whether its kind uses it or not.
    """
    size = min(h, w)
    # Shapes are sized relative to the short side, so their number grows with
    # the aspect ratio only: the clutter covers the same fraction at any size.
    area = (h * w) / float(size * size)
    n_shapes = int(rng.poisson(8.0 * density * area))
    n_lines = int(rng.poisson(4.0 * density * area))
    kinds = rng.integers(0, 3, n_shapes).tolist()
    centres = (rng.uniform(-0.1, 1.1, (n_shapes, 2)) * (w, h)).tolist()
    half_axes = (rng.uniform(0.05, 0.3, (n_shapes, 2)) * size).tolist()
    floats = np.zeros((n_shapes, 10))
    floats[:, 0] = rng.uniform(0, 180, n_shapes)  # an ellipse's angle
    # A polygon's k vertices: the first k of six angle draws, sorted.
    n_vertices = rng.integers(3, 7, n_shapes).tolist()
    angles = rng.uniform(0, 2 * np.pi, (n_shapes, 6)).tolist()
    textured = (rng.random(n_shapes) < 0.4).tolist()
    floats[:, 1:7] = rng.uniform(25, 235, (n_shapes, 6))  # one colour, or a texture's two
    floats[:, 7] = rng.uniform(3.0, 12.0, n_shapes)  # the texture's period,
    floats[:, 8] = rng.uniform(0, np.pi, n_shapes)  # its angle
    floats[:, 9] = rng.random(n_shapes)  # and whether it is a checker
    rows = []
    for i in range(n_shapes):
        (cx, cy), (rx, ry), kind = centres[i], half_axes[i], kinds[i]
        # Each kind's geometry, in Python numbers (int() truncates as OpenCV
        # is given integers).
        if kind == 0:
            geometry = [int(cx - rx), int(cy - ry), int(cx + rx), int(cy + ry)]
        elif kind == 1:
            geometry = [int(cx), int(cy), int(rx) + 1, int(ry) + 1]
        else:
            geometry = [n_vertices[i]]
            for a in sorted(angles[i][: n_vertices[i]]):
                geometry += (int(cx + rx * math.cos(a)), int(cy + ry * math.sin(a)))
        if textured[i]:  # drawn only over its bounding box, where it meets the image
            x0, y0, x1, y1 = _clutter_box(kind, geometry, cx, cy)
            x0, y0 = max(math.floor(x0) - 1, 0), max(math.floor(y0) - 1, 0)
            x1, y1 = min(math.ceil(x1) + 2, w), min(math.ceil(y1) + 2, h)
            window = [1, x0, y0, x1, y1] if x1 > x0 and y1 > y0 else [-1, 0, 0, 0, 0]
        else:
            window = [0, 0, 0, 0, 0]
        rows.append([kind, *window, *geometry] + [0] * (13 - len(geometry)))
    shapes = np.array(rows, np.int64).reshape(n_shapes, 19)
    lines = np.empty((n_lines, 9))
    lines[:, :2] = rng.uniform(0, 1, (n_lines, 2)) * (w, h)
    lines[:, 2:4] = rng.normal(size=(n_lines, 2))
    lines[:, 4] = rng.uniform(0.2, 1.0, n_lines) * size
    lines[:, 5:8] = rng.uniform(20, 240, (n_lines, 3))
    lines[:, 8] = rng.integers(1, 3, n_lines) * max(1, size // 128)  # thickness
    return ClutterPlan(shapes, floats, lines)


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
    _draw_clutter_shapes(img, shapes, floats, colors)
    line_colors = _clutter_colors(lines[:, 5:8], channels)
    for (x0f, y0f, dx, dy, length, *_, thickness), color in zip(
        lines.tolist(), line_colors, strict=True
    ):
        norm = math.sqrt(dx * dx + dy * dy) + 1e-12
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
    """A clutter plan's shapes drawn by OpenCV, in plan order.

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


def noise_bank(scene: SceneOptions, rng: np.random.Generator) -> NDArray[np.uint8]:
    """A bank of sensor noise for :func:`make_background` (see :class:`Background`).

    The environments draw one per seeded reset and reuse it for the episodes
    that follow (each frame still reads its own random window of it).

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
        base = np.minimum(np.maximum(base + rng.uniform(-20, 20), 0.0), 255.0)  # np.clip is slower
    img = np.empty((h, w, channels), np.uint8)
    # One row, then the image from it (faster than broadcasting the colour).
    img[0] = _to_channels(base, channels).round().astype(np.uint8)
    img[1:] = img[0]
    if clutter:
        _draw_clutter(img, scene, rng)
    k = scene.occluders
    occ = np.zeros((k, 7))
    occ_colors = np.zeros((0, channels), np.uint8)  # no draw for no occluder
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
        occ_colors = _to_channels(rng.uniform(20, 235, (k, 3)), channels).round().astype(np.uint8)
    img.setflags(write=False)
    if noise is None:
        noise = noise_bank(scene, rng)
    return Background(scene, img, occ, occ_colors, noise)


def floor_segments(
    rotation: NDArray[np.float64],
    translation: NDArray[np.float64],
    focal: float,
    principal_point: tuple[float, float],
    shift: int,
) -> tuple[NDArray[np.int32], NDArray[np.bool_]]:
    """The floor's grid lines (:attr:`SceneOptions.floor`) in the image of each of T cameras.

    The lines ``x = k s`` and ``y = k s`` of the plane ``z = 0`` (``s`` =
    :data:`FLOOR_SPACING_MM`) are fixed in the world, so the grid slides
    under a following camera as the ground does; each is cut to the disc of
    radius :data:`FLOOR_RADIUS_MM` about the point under its frame's camera
    (the cut ends move continuously with the camera), then to the half-space
    at least :data:`FLOOR_NEAR_MM` in front of the camera, and projected.
    Every point drawn is a projected point of the floor, so none lies above
    the horizon. Vectorised over cameras and lines.

    Args:
        rotation: ``(3, 3)`` or ``(T, 3, 3)`` world-to-camera rotations.
        translation: ``(3,)`` or ``(T, 3)`` translations (``x_cam = R x + t``).
        focal: Focal length in pixels.
        principal_point: ``(cx, cy)`` in pixels.
        shift: Fractional bits of the fixed-point pixel coordinates.

    Returns:
        Segment end points ``(T, L, 2, 2)`` int32 in fixed point, and
        ``(T, L)`` whether each is drawn (T is 1 for one camera).
    """
    rot = np.asarray(rotation, dtype=np.float64).reshape(-1, 3, 3)
    trans = np.asarray(translation, dtype=np.float64).reshape(-1, 3)
    n = max(rot.shape[0], trans.shape[0])
    rot, trans = np.broadcast_to(rot, (n, 3, 3)), np.broadcast_to(trans, (n, 3))
    centre = -np.einsum("tji,tj->ti", rot, trans)[:, :2]  # (T, 2): under the camera
    spacing, radius = FLOOR_SPACING_MM, FLOOR_RADIUS_MM
    reach = math.ceil(radius / spacing)
    # Per frame and axis, the 2 * reach + 1 grid lines nearest the centre.
    k = np.floor(centre / spacing)[:, :, None] + np.arange(-reach, reach + 1)  # (T, 2, K)
    across = k * spacing - centre[:, :, None]  # the line's offset from the centre
    half = np.sqrt(np.maximum(radius**2 - across**2, 0.0))  # half its chord in the disc
    along = centre[:, ::-1, None]  # lines x = ks run along y, and y = ks along x
    world = np.zeros(k.shape + (2, 3))  # (T, 2, K, 2 ends, 3)
    ends = np.stack([along - half, along + half], axis=-1)  # (T, 2, K, 2)
    world[:, 0, :, :, 0] = (k * spacing)[:, 0, :, None]
    world[:, 0, :, :, 1] = ends[:, 0]
    world[:, 1, :, :, 1] = (k * spacing)[:, 1, :, None]
    world[:, 1, :, :, 0] = ends[:, 1]
    world = world.reshape(n, -1, 2, 3)
    cam = world @ np.swapaxes(rot, -1, -2)[:, None] + trans[:, None, None]
    z = cam[..., 2]
    near = FLOOR_NEAR_MM
    shown = (np.abs(across) < radius).reshape(n, -1) & (z.max(axis=-1) > near)
    # Cut each segment where it crosses the near plane: its end behind moves
    # along the segment to depth ``near``.
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.clip((near - z) / (z[..., ::-1] - z), 0.0, 1.0)[..., None]
    cam = np.where((z < near)[..., None], cam + frac * (cam[..., ::-1, :] - cam), cam)
    cx, cy = principal_point
    scale = float(1 << shift)
    z = np.maximum(cam[..., 2], near)
    pixels = np.empty(cam.shape[:-1] + (2,))
    pixels[..., 0] = (focal * cam[..., 0] / z + cx) * scale
    pixels[..., 1] = (focal * cam[..., 1] / z + cy) * scale
    pixels[~shown] = 0.0
    return np.rint(pixels).astype(np.int32), shown


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
    return {
        "edges": edges,
        "shading": shading,
        "light": light,
        "base": np.ascontiguousarray(_to_channels(scene.figure_colors, scene.channels)),
        "ring": _UNIT_CIRCLE,
    }
