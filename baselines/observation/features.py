"""Image features of a frame: edges, their distance maps, foreground, backdrop.

Computed once per frame by OpenCV and numpy (``cv2.Canny``, ``cv2.Sobel``,
``cv2.distanceTransform``), then turned into the flat byte table of costs
that the likelihood's terms read for every pose (:mod:`.terms`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.observation.geometry import free_cones, grow, projected_cones, silhouette_mask
from baselines.observation.settings import ObservationSettings
from humotion_gym.body import N_CONES, BodyShape, cone_geometry
from humotion_gym.camera import Camera
from humotion_gym.render import gaussian_blur

#: The distance transform's mask: 5x5 chamfer, within 2% of the exact distance.
_DIST_MASK = cv2.DIST_MASK_5
#: Rows ``y0:y1`` and columns ``x0:x1`` of a frame.
Box = tuple[int, int, int, int]


@dataclass(frozen=True, eq=False)
class FrameFeatures:
    """What the observation model keeps of one frame (computed once per frame).

    Attributes:
        width: Frame width in pixels.
        height: Frame height in pixels.
        edges: ``(H, W)`` uint8 edge map (255 on edges).
        distance: ``(B, H, W)`` float32 distance to the nearest edge of each
            orientation bin (``B = orientation_bins``), in reference pixels,
            truncated at the model's ``edge_truncation``.
        foreground: ``(H, W)`` float32 foreground probability in [0, 1].
        background_color: The estimated background colour (one value per
            channel), or None where the known backdrop was used instead.
        cost: Flat uint8 lookup table (:func:`cost_table`): the ``B`` padded
            ``(H + 2, W + 2)`` edge cost maps, the foreground's, then each
            appearance cone's, in units of ``cost_unit``; the 1-pixel border
            holds the cost of a point outside the image.
        cost_unit: The cost (nats) of one unit of ``cost``.
        residual: ``(2, E)`` float32 image coordinates (plus the table's
            padding offset) of the edge points the given body does not
            explain, or ``None`` when no body part was given.
        residual_cones: The free cones (indices into ``CONE_NAMES``), whose
            outlines must explain ``residual``.
        appearance_cones: The cones whose axis points read their own colour
            map (in this order), or ``None``.
        coverage: ``(2, F)`` float32 image coordinates (plus the padding
            offset) of foreground pixels the free cones must cover, or ``None``.
        coverage_cones: The free cones, which may cover them.
        floor: Height (mm, world z) of the lowest ankle in the episode's given
            first pose (``GivenBody.floor``), or ``None`` without a floor term.
    """

    width: int
    height: int
    edges: NDArray[np.uint8]
    distance: NDArray[np.float32]
    foreground: NDArray[np.float32]
    background_color: NDArray[np.float64] | None
    cost: NDArray[np.uint8]
    cost_unit: float
    residual: NDArray[np.float32] | None = None
    residual_cones: NDArray[np.intp] | None = None
    appearance_cones: NDArray[np.intp] | None = None
    coverage: NDArray[np.float32] | None = None
    coverage_cones: NDArray[np.intp] | None = None
    floor: float | None = None


@dataclass(frozen=True, eq=False)
class Backdrop:
    """The scene behind the figure, read at an episode's first frame.

    The renderer draws each episode's backdrop once, fixed in the image, and
    only sensor noise changes it from frame to frame (a static camera's
    background, as in Deutscher, Blake & Reid's background subtraction, CVPR
    2000). At the first frame the figure's pose is given, so every pixel its
    silhouette does not cover shows the backdrop.

    Attributes:
        image: ``(H, W, C)`` uint8, the first frame blurred by the model's
            ``edge_blur``.
        known: ``(H, W)`` bool, the pixels the initial pose's silhouette (grown
            by ``backdrop_margin``) leaves uncovered, whose backdrop is known.
    """

    image: NDArray[np.uint8]
    known: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class GivenBody:
    """The part of the body a task hands out, for the residual-edge and appearance terms.

    Attributes:
        pose: ``(25,)`` a full pose whose parameters outside ``free`` are the
            given (true) ones of the frame; the values at ``free`` do not matter.
        free: Indices of the parameters the agent estimates.
        shape: The subject's shape.
        camera: The frame's camera.
        colors: ``(10, C)`` each cone's colour at the episode's first frame
            (:meth:`ObservationModel.cone_colors`), or ``None``.
        backdrop: The first frame's :meth:`ObservationModel.read_backdrop`, or ``None``.
        floor: The first frame's :meth:`ObservationModel.floor_height`, or ``None``.
    """

    pose: NDArray[np.float64]
    free: NDArray[np.intp]
    shape: BodyShape
    camera: Camera
    colors: NDArray[np.float64] | None = None
    backdrop: Backdrop | None = None
    floor: float | None = None


class FirstFrame(NamedTuple):
    """What an observation model keeps of an episode's first frame (see :class:`GivenBody`)."""

    colors: NDArray[np.float64] | None
    backdrop: Backdrop | None
    floor: float | None


def smoothed(frame: ArrayLike, blur: float, where: str) -> NDArray[np.uint8]:
    """The frame as ``(H, W, C)`` uint8, blurred by a Gaussian of sigma ``blur``.

    Raises:
        ValueError: Naming ``where``, if the frame is not a uint8 image of
            shape ``(H, W, 3)``, ``(H, W, 1)`` or ``(H, W)``.
    """
    img = np.asarray(frame)
    if img.ndim == 2:
        img = img[:, :, None]
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (1, 3):
        raise ValueError(
            f"{where}: expected a uint8 frame of shape (H, W, 3) or "
            f"(H, W, 1), got {img.dtype} {img.shape}"
        )
    img = np.ascontiguousarray(img)
    out = img if blur <= 0 else gaussian_blur(img, blur)
    return out.reshape(img.shape)


def oriented_edges(
    smooth: NDArray[np.uint8], low: float, high: float, n_bins: int, keep: NDArray | None = None
) -> tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray[np.bool_]]:
    """Canny edges (hysteresis ``low``, ``high``) of the blurred frame, split into ``n_bins``.

    On colour frames, per pixel, the strongest channel's gradient. ``keep``:
    uint8, 255 where edges count (None: everywhere).

    Returns:
        The ``(H, W)`` edge map; ``(B, H, W)`` uint8 maps for
        ``cv2.distanceTransform``, map ``b`` 0 at the edge pixels whose
        gradient orientation (modulo pi) lies within ``pi / B`` of ``b pi /
        B`` (every edge pixel is in its two nearest bins) and 255 elsewhere;
        and ``(B,)`` whether each bin holds an edge pixel.
    """
    h, w, channels = smooth.shape
    image = smooth if channels == 3 else smooth[:, :, 0]
    # Canny's own derivatives (3x3 Sobel, replicated border), handed to its
    # derivative form: the same edges, sooner.
    dx = cv2.Sobel(image, cv2.CV_16S, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    dy = cv2.Sobel(image, cv2.CV_16S, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    edges = cv2.Canny(dx, dy, low, high)
    if keep is not None:
        cv2.bitwise_and(edges, keep, dst=edges)
    bins = np.full((n_bins, h, w), 255, np.uint8)
    found = cv2.findNonZero(edges)  # raster order, as np.nonzero (faster)
    if found is None:
        return edges, bins, np.zeros(n_bins, bool)
    found = found.reshape(-1, 2)
    xs, ys = found[:, 0], found[:, 1]
    if n_bins == 1:
        bins[0, ys, xs] = 0
        return edges, bins, np.ones(1, bool)
    # The orientation reads the gradient with OpenCV's default border
    # (reflected, not replicated). Only the outermost pixels see the border,
    # so Canny's derivatives serve unless an edge lies there. A 3x3 Sobel of
    # bytes is an integer below 2**10: int16 holds it exactly.
    if xs.min() == 0 or ys.min() == 0 or xs.max() == w - 1 or ys.max() == h - 1:
        dx = cv2.Sobel(smooth, cv2.CV_16S, 1, 0, ksize=3)
        dy = cv2.Sobel(smooth, cv2.CV_16S, 0, 1, ksize=3)
    gx, gy = strongest_gradients(dx.reshape(h, w, channels), dy.reshape(h, w, channels), xs, ys)
    theta = np.arctan2(gy, gx)  # float32: the gradient = outline normal
    return edges, bins, mark_bins(np.mod(theta, np.pi) * (n_bins / np.pi), xs, ys, bins)


def strongest_gradients(
    dx: NDArray[np.int16], dy: NDArray[np.int16], xs: NDArray[np.int32], ys: NDArray[np.int32]
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """``(K,)`` float32 x and y gradients at ``(xs, ys)`` of the first channel of largest norm."""
    u, v = dx[ys, xs].astype(np.int32), dy[ys, xs].astype(np.int32)
    best = np.argmax(u * u + v * v, axis=1)
    rows = np.arange(xs.size)
    return u[rows, best].astype(np.float32), v[rows, best].astype(np.float32)


def mark_bins(
    turns: NDArray[np.float32],
    xs: NDArray[np.int32],
    ys: NDArray[np.int32],
    bins: NDArray[np.uint8],
) -> NDArray[np.bool_]:
    """Mark (0) each pixel in ``bins`` ``floor(turns) mod B`` and the next; which bins hold one.

    ``turns``: each pixel's orientation in bin widths, ``[0, B]``.
    """
    n_bins = bins.shape[0]
    lo = np.floor(turns).astype(np.int64) % n_bins
    hi = (lo + 1) % n_bins
    bins[lo, ys, xs] = 0
    bins[hi, ys, xs] = 0
    held = np.zeros(n_bins, np.bool_)
    held[lo] = held[hi] = True
    return held


def edge_distances(
    bins: NDArray[np.uint8], found: NDArray[np.bool_], edges: NDArray[np.uint8], reach: int
) -> tuple[NDArray[np.float32], Box]:
    """``(B, H, W)`` each bin's ``cv2.distanceTransform`` (pixels) up to ``reach``; the box.

    Only the edges' bounding box widened by ``reach`` pixels is transformed
    (the box is returned, ``(y0, y1, x0, x1)``); pixels outside it, and every
    pixel of a bin without edges, get inf. A chamfer distance is at least the
    Chebyshev distance, so a pixel outside is more than ``reach`` from every
    edge; inside, a shortest chamfer path runs within the bounding box of its
    two ends, which the crop holds: the same distances there. ``bins`` and
    ``found`` are :func:`oriented_edges`', ``edges`` its edge map.
    """
    n_bins, h, w = bins.shape
    x, y, bw, bh = cv2.boundingRect(edges)
    x0, y0 = max(x - reach, 0), max(y - reach, 0)
    x1, y1 = min(x + bw + reach, w), min(y + bh + reach, h)
    whole = (x1 - x0) * (y1 - y0) == h * w
    dist = np.empty(bins.shape, np.float32) if whole else np.full(bins.shape, np.inf, np.float32)
    for b in range(n_bins):
        if not found[b]:
            dist[b] = np.inf
        elif whole:
            cv2.distanceTransform(bins[b], cv2.DIST_L2, _DIST_MASK, dst=dist[b])
        else:
            crop = np.ascontiguousarray(bins[b, y0:y1, x0:x1])
            dist[b, y0:y1, x0:x1] = cv2.distanceTransform(crop, cv2.DIST_L2, _DIST_MASK)
    return dist, (y0, y1, x0, x1)


def channel_max(diff: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``(H, W)`` the largest channel of a ``(H, W, C)`` absolute difference."""
    if diff.ndim == 3 and diff.shape[2] == 3:
        d0, d1, d2 = cv2.split(diff)
        return cv2.max(cv2.max(d0, d1), d2)
    return np.ascontiguousarray(diff.reshape(diff.shape[0], diff.shape[1], -1)[:, :, 0])


def _grey(level: float) -> np.uint8:
    """A grey level clipped to 0-255 and truncated, as numpy's cast of a float to uint8."""
    return np.uint8(int(min(max(level, 0.0), 255.0)))


def border_color(smooth: NDArray[np.uint8], width: int) -> NDArray[np.float64]:
    """The median colour of the frame's border ``width`` pixels wide (at most a quarter)."""
    h, w, channels = smooth.shape
    b = min(width, h // 4, w // 4)
    border = np.concatenate(
        [
            smooth[:b].reshape(-1, channels),
            smooth[-b:].reshape(-1, channels),
            smooth[b:-b, :b].reshape(-1, channels),
            smooth[b:-b, -b:].reshape(-1, channels),
        ]
    )
    return np.median(border, axis=0)


def backdrop_low(model: ObservationSettings, counts: NDArray[np.int64]) -> float | None:
    """How far a pixel must differ from the backdrop, from the known pixels' histogram.

    ``foreground_low`` or 2.5 times the known pixels' median difference,
    whichever is larger; None where that reaches ``foreground_high`` or no
    pixel is known (the backdrop is then not used).
    """
    low = model.foreground_low
    total = counts.sum()
    if total:
        median = int(np.searchsorted(np.cumsum(counts), 0.5 * total))
        low = max(low, 2.5 * median)
    return None if low >= model.foreground_high or not total else low


def foreground(
    model: ObservationSettings,
    smooth: NDArray[np.uint8],
    backdrop: Backdrop | None = None,
    scale: float = 1.0,
) -> tuple[NDArray[np.float32], NDArray | None, NDArray[np.uint8] | None, Backdrop | None]:
    """Foreground probability from the colour distance to the background.

    The background is the border's median colour or, with ``backdrop``, the
    backdrop's pixel where it knows it; the backdrop's own differences (sensor
    noise) raise the threshold (:func:`backdrop_low`). Under the initial
    figure the first frame showed the figure: a pixel still as it was is
    figure (probability 1), one that changed shows the backdrop the figure
    left or another part of it (1/2).

    Returns:
        The ``(H, W)`` float32 probability; the border's median colour (None
        where the backdrop was used); with a backdrop and a positive
        ``backdrop_reach``, the uint8 mask of where edges count (near a pixel
        that differs from the known backdrop, or where it is unknown), else
        None; the backdrop if it was used, else None.
    """
    channels = smooth.shape[2]
    bg, keep, low = None, None, None
    if backdrop is not None:
        near = channel_max(cv2.absdiff(smooth, backdrop.image).reshape(smooth.shape))
        # The known pixels' histogram, as np.bincount(near[known]) counts it
        # (float32 counts: exact below 2**24 pixels).
        counts = cv2.calcHist([near], [0], backdrop.known.view(np.uint8), [256], [0, 256])
        low = backdrop_low(model, counts.astype(np.int64).reshape(-1))
        if low is None:
            backdrop = None  # noise hides the figure, or nothing of the backdrop is known
    if backdrop is not None and low is not None:
        shift = low - model.foreground_low
        if shift > 0:  # the ramp moved up: the same probabilities from ``low`` on
            near = cv2.subtract(near, float(shift))
        changed = near > model.foreground_low
        lo, hi = model.foreground_low, model.foreground_high
        unknown = np.where(changed, _grey(0.5 * (lo + hi)), _grey(hi))
        diff = np.where(backdrop.known, near, unknown)
        if model.backdrop_reach > 0:
            found = changed & backdrop.known
            keep = grow(found.view(np.uint8) * np.uint8(255), model.backdrop_reach * scale)
            np.copyto(keep, np.uint8(255), where=~backdrop.known)
    else:  # the border's colour alone
        bg = border_color(smooth, model.border_width)
        scalar = tuple(float(v) for v in bg) + (0.0,) * (4 - channels)
        diff = channel_max(cv2.absdiff(smooth, scalar).reshape(smooth.shape))
    fg = cv2.subtract(diff, float(model.foreground_low)).astype(np.float32)
    fg *= np.float32(1.0 / (model.foreground_high - model.foreground_low))
    np.minimum(fg, np.float32(1.0), out=fg)
    return fg, bg, keep, backdrop


def cost_table(
    model: ObservationSettings,
    dist: NDArray[np.float32],
    box: Box,
    fg: NDArray[np.float32],
    smooth: NDArray[np.uint8],
    app_colors: NDArray[np.float32],
) -> tuple[NDArray[np.uint8], float]:
    """The flat byte table of per-point costs, and its unit (nats).

    Maps, each padded by one pixel holding the cost of a point off the image:
    per orientation bin the edge cost ``min(d, tau)^2 / (2 sigma^2)`` divided
    by the outline's points, the foreground cost ``foreground_weight (1 - fg)``
    divided by the axis points, then each appearance cone's colour mismatch.
    Quantised to bytes (a gather of bytes is faster than one of floats): 1/255
    of the largest per-point cost is far below anything that matters.

    ``dist`` (pixels, finite only inside ``box``: :func:`edge_distances`) is
    rescaled to reference pixels and truncated in place.
    """
    n_bins, h, w = dist.shape
    scale = h / model.reference_height
    edge_scale = 1.0 / (2.0 * model.edge_sigma**2 * 2 * model.outline_samples)
    edge_out = model.edge_truncation**2 * edge_scale
    fg_scale = model.foreground_weight / model.axis_samples
    n_app = app_colors.shape[0]
    app_scale = model.appearance_weight / model.axis_samples if n_app else 0.0
    unit = max(edge_out, fg_scale, app_scale) / 255.0 or 1.0
    f32, inv_unit = np.float32, np.float32(1.0 / unit)
    table = np.empty((n_bins + 1 + n_app, h + 2, w + 2), np.uint8)
    edge_foreground_bytes(
        dist, box, fg, f32(1.0 / scale), f32(model.edge_truncation), f32(edge_scale),
        f32(edge_out), f32(fg_scale), f32(fg_scale), inv_unit, table[: n_bins + 1],
    )  # fmt: skip
    appearance_bytes(
        smooth, np.asarray(app_colors, f32), f32(model.appearance_low),
        f32(1.0 / (model.appearance_high - model.appearance_low)), f32(app_scale), inv_unit,
        table[n_bins + 1 :],
    )  # fmt: skip
    return table.reshape(-1), float(unit)


def edge_foreground_bytes(
    dist: NDArray[np.float32],
    box: Box,
    fg: NDArray[np.float32],
    inv_scale: np.float32,
    truncation: np.float32,
    edge_scale: np.float32,
    edge_out: np.float32,
    fg_scale: np.float32,
    fg_out: np.float32,
    inv_unit: np.float32,
    out: NDArray[np.uint8],
) -> None:
    """The cost table's edge and foreground maps, quantised, into ``out`` ``(B + 1, H + 2, W + 2)``.

    Per orientation bin ``b`` the padded map ``rint(min(d s, tau)^2 e / u)``
    (``d = dist[b]``, pixels, inf outside ``box``, which takes ``min(d s,
    tau)`` in place; ``s = inv_scale``, ``tau = truncation``, ``e =
    edge_scale``, ``1 / u = inv_unit``), then the foreground's ``rint((1 -
    fg) f / u)`` (``f = fg_scale``); the one-pixel border holds ``rint(edge_out
    / u)`` and ``rint(fg_out / u)``, the costs off the image. All in float32,
    in that order.
    """
    n_bins = dist.shape[0]
    y0, y1, x0, x1 = box
    near = dist[:, y0:y1, x0:x1]
    near *= inv_scale
    for b in range(n_bins):  # min(d s, tau), in place (np.minimum takes twice as long)
        cv2.threshold(near[b], float(truncation), 0.0, cv2.THRESH_TRUNC, dst=near[b])
    costs = np.square(near)
    costs *= edge_scale
    costs *= inv_unit
    edges = out[:n_bins]
    edges[:] = np.rint(truncation * truncation * edge_scale * inv_unit)
    edges[:, 1 + y0 : 1 + y1, 1 + x0 : 1 + x1] = np.rint(costs, out=costs)
    for far in (dist[:, :y0], dist[:, y1:], dist[:, y0:y1, :x0], dist[:, y0:y1, x1:]):
        far[:] = truncation
    cover = np.subtract(np.float32(1.0), fg)
    cover *= fg_scale
    cover *= inv_unit
    out[n_bins, 1:-1, 1:-1] = np.rint(cover, out=cover)
    _border(edges, np.rint(edge_out * inv_unit))
    _border(out[n_bins:], np.rint(fg_out * inv_unit))


def appearance_bytes(
    smooth: NDArray[np.uint8],
    colors: NDArray[np.float32],
    low: np.float32,
    span: np.float32,
    scale: np.float32,
    inv_unit: np.float32,
    out: NDArray[np.uint8],
) -> None:
    """The cost table's appearance maps, quantised, into ``out`` ``(K, H + 2, W + 2)``.

    Per colour ``k`` of ``(K, C)`` ``colors`` the padded map ``rint(clip((m -
    low) span, 0, 1) a / u)`` of the largest channel difference ``m = max_c
    |smooth[..., c] - colors[k, c]|`` (``span = 1 / (high - low)``, ``a =
    scale`` the full cost, ``1 / u = inv_unit``); the one-pixel border holds
    ``rint(a / u)`` (a point off the image matches no colour). All in
    float32, in that order.
    """
    if not colors.shape[0]:
        return
    # The cost never falls as the difference grows, so the cost of the largest
    # channel difference is the largest of the channels' costs: a 256-entry
    # table per colour and channel, looked up by OpenCV.
    grey = np.arange(256, dtype=np.float32)[:, None, None]
    ramp = (np.abs(grey - colors[None]) - low) * span  # (256, K, C)
    np.clip(ramp, np.float32(0.0), np.float32(1.0), out=ramp)
    lookup = np.rint(ramp * scale * inv_unit).astype(np.uint8)
    channels = cv2.split(smooth)
    for k in range(colors.shape[0]):
        worst = cv2.LUT(channels[0], lookup[:, k, 0])
        for c in range(1, len(channels)):
            worst = cv2.max(worst, cv2.LUT(channels[c], lookup[:, k, c]))
        out[k, 1:-1, 1:-1] = worst
    _border(out, np.rint(scale * inv_unit))


def _border(maps: NDArray[np.uint8], value: np.floating) -> None:
    """The one-pixel border of padded ``(M, H + 2, W + 2)`` maps: ``value``."""
    maps[:, 0] = maps[:, -1] = value
    maps[:, :, 0] = maps[:, :, -1] = value


def spread_points(mask: NDArray[np.bool_], most: int) -> NDArray[np.float32]:
    """At most ``most`` of ``mask``'s set pixels, evenly spread: ``(2, F)`` x then y (+1.5).

    ``np.nonzero``'s order, thinned to ``np.linspace(0, n - 1, most)``'s
    picks; 1.5 is the cost table's offset (padding, and 0.5 so truncation rounds).
    """
    flat = np.flatnonzero(mask)
    if flat.size > most:
        flat = flat[np.linspace(0, flat.size - 1, most).astype(np.intp)]
    points = np.empty((2, flat.size), np.float32)
    np.divmod(flat, mask.shape[1], out=(points[1], points[0]))  # y, then x
    points += np.float32(1.5)
    return points


def coverage_points(
    model: ObservationSettings,
    fg: NDArray[np.float32],
    backdrop: Backdrop,
    given: GivenBody,
    free: tuple[NDArray[np.intp], Any],
) -> NDArray[np.float32]:
    """The foreground pixels the free cones must cover: ``(2, F)``, x then y (+1.5).

    Pixels of the known backdrop that differ from it clearly (foreground
    probability 1), outside the given cones' silhouettes in this frame.
    """
    cones, (geo, _ends, moved) = free
    fixed = np.flatnonzero(~moved.any(axis=1))
    sure = (fg >= 1.0) & backdrop.known
    if fixed.size:
        # The given cones are where free_cones' probe put them (its first pose).
        covered = silhouette_mask(
            geo.starts[0], geo.ends[0], given.shape, given.camera, model.near_mm, cones=fixed
        )
        covered = grow(covered, model.backdrop_margin * fg.shape[0] / model.reference_height)
        sure &= covered == 0
    if cones.size == 0:
        sure[:] = False
    return spread_points(sure, model.coverage_points)


def residual_edges(
    model: ObservationSettings,
    edges: NDArray[np.uint8],
    given: GivenBody,
    free: tuple[NDArray[np.intp], Any],
) -> tuple[NDArray[np.float32], NDArray[np.intp]]:
    """Edge points the given cones do not explain, near the free cones.

    The given cones' outlines and end circles are drawn ``residual_clearance``
    wide and their edges removed; what remains within reach of the free
    cones' fixed anchors (the sum of the free cones' lengths, projected at
    the nearest depth it can reach) is kept.

    Returns:
        ``(2, E)`` points (:func:`spread_points`, at most ``residual_points``)
        and the free cones' indices.
    """
    camera = given.camera
    cones, (geo, ends, moved) = free
    h, w = edges.shape
    if (camera.width, camera.height) != (w, h):
        raise ValueError("GivenBody.camera: its image size differs from the frame's")
    if cones.size == 0:
        return np.zeros((2, 0), np.float32), cones
    scale = h / model.reference_height
    left = edges.copy()  # the edges, less those the given cones' outlines explain
    thick = max(1, int(round(2.0 * model.residual_clearance * scale)) + 1)
    starts, stops = geo.starts[0], geo.ends[0]
    radii = given.shape.radii * ((1.0 + given.shape.aspect[:, None]) / 2.0)
    uv_s, uv_e, z, r_s, r_e, normal = projected_cones(starts, stops, radii, camera)
    drawn = np.flatnonzero(~moved.any(axis=1) & (z >= model.near_mm))
    # Per drawn cone, in pixels: its two outline sides' ends, its end circles'
    # centres and radii (rounded half to even, as Python's round).
    side_s, side_e = r_s[drawn, None] * normal[drawn], r_e[drawn, None] * normal[drawn]
    s_uv, e_uv = uv_s[drawn], uv_e[drawn]
    pixels = np.rint(
        np.stack([s_uv + side_s, e_uv + side_e, s_uv - side_s, e_uv - side_e, s_uv, e_uv], 1)
    )
    radius = np.maximum(np.rint(np.stack([r_s[drawn], r_e[drawn]], 1)), 0.0)
    for (a, b, c, d, s, e), (r0, r1) in zip(
        pixels.astype(int).tolist(), radius.astype(int).tolist(), strict=True
    ):
        cv2.line(left, tuple(a), tuple(b), 0, thick)
        cv2.line(left, tuple(c), tuple(d), 0, thick)
        cv2.circle(left, tuple(s), r0, 0, thick)
        cv2.circle(left, tuple(e), r1, 0, thick)
    found = cv2.findNonZero(left)  # raster order, as np.nonzero
    xs, ys = found.reshape(-1, 2).T if found is not None else np.zeros((2, 0), np.int32)
    anchors = ends[0][cones][~moved[cones]]  # the free cones' ends that do not move
    if anchors.size:
        length = np.linalg.norm(stops[cones] - starts[cones], axis=1).sum()
        near = np.maximum(camera.to_camera(anchors)[:, 2] - length, model.near_mm)
        reach = camera.focal * length / near
        centre = camera.project(anchors)
        d2 = (xs[:, None] - centre[None, :, 0]) ** 2 + (ys[:, None] - centre[None, :, 1]) ** 2
        keep = (d2 <= reach[None, :] ** 2).any(axis=1)
        left[ys[~keep], xs[~keep]] = 0  # out of the free cones' reach
    return spread_points(left > 0, model.residual_points), cones


def frame_features(
    model: ObservationSettings, frame: ArrayLike, given: GivenBody | None = None
) -> FrameFeatures:
    """The features of one frame (see :meth:`ObservationModel.prepare`)."""
    smooth = smoothed(frame, model.edge_blur, "ObservationModel.prepare")
    h, w, channels = smooth.shape
    if h < 8 or w < 8:
        raise ValueError(f"ObservationModel.prepare: frame too small ({w}x{h})")
    scale = h / model.reference_height
    backdrop = None
    if model.backdrop and given is not None and given.backdrop is not None:
        backdrop = given.backdrop
        if backdrop.image.shape != smooth.shape or backdrop.known.shape != (h, w):
            raise ValueError(
                f"GivenBody.backdrop: expected an image of shape {smooth.shape}, got "
                f"{backdrop.image.shape} (known {backdrop.known.shape})"
            )
    fg, bg, keep, backdrop = foreground(model, smooth, backdrop, scale)
    edges, bins, found = oriented_edges(
        smooth, model.canny_low, model.canny_high, model.orientation_bins, keep
    )
    # Beyond the truncation every distance costs the same (cost_table).
    dist, box = edge_distances(bins, found, edges, math.floor(model.edge_truncation * scale) + 1)
    use_appearance = given is not None and model.appearance_weight > 0 and given.colors is not None
    use_residual = given is not None and model.residual_weight > 0
    use_coverage = backdrop is not None and model.coverage_weight > 0
    free = None
    if given is not None and (use_appearance or use_residual or use_coverage):
        free = free_cones(given.pose, given.free, given.shape)
    app_cones = free[0] if use_appearance and free is not None else None
    app_colors = np.zeros((0, channels), np.float32)
    if app_cones is not None and app_cones.size and given is not None:
        colors = np.asarray(given.colors, dtype=np.float64)
        if colors.shape != (N_CONES, channels):
            raise ValueError(
                f"GivenBody.colors: expected shape ({N_CONES}, {channels}), got {colors.shape}"
            )
        app_colors = colors[app_cones].astype(np.float32)
    cost, unit = cost_table(model, dist, box, fg, smooth, app_colors)
    residual, residual_cones = None, None
    if use_residual and given is not None and free is not None:
        residual, residual_cones = residual_edges(model, edges, given, free)
    coverage, coverage_cones = None, None
    if use_coverage and given is not None and backdrop is not None and free is not None:
        coverage_cones = free[0]
        coverage = coverage_points(model, fg, backdrop, given, free)
    floor = None
    if model.has_floor_term and given is not None and given.floor is not None:
        floor = float(given.floor)
        if not math.isfinite(floor):
            raise ValueError(f"GivenBody.floor: expected a finite height in mm, got {floor}")
    return FrameFeatures(
        w, h, edges, dist, fg, bg, cost, unit, residual, residual_cones, app_cones,
        coverage, coverage_cones, floor,
    )  # fmt: skip


def cone_colors(
    model: ObservationSettings, frame: ArrayLike, pose: ArrayLike, shape: BodyShape, camera: Camera
) -> NDArray[np.float64]:
    """Each cone's colour in a frame where its pose is known: ``(10, C)``.

    The median of the (blurred) pixels at the middle of each cone's projected
    axis (fractions 0.3-0.7 of its length); a cone off the image gets its
    nearest pixels.
    """
    smooth = smoothed(frame, model.edge_blur, "ObservationModel.cone_colors")
    h, w, _ = smooth.shape
    geo = cone_geometry(np.asarray(pose, dtype=np.float64), shape)
    t = np.linspace(0.3, 0.7, 5)[:, None, None]
    points = geo.starts[None] * (1.0 - t) + geo.ends[None] * t  # (5, 10, 3)
    uv = np.nan_to_num(camera.project(points), nan=-1.0)
    x = np.clip(np.rint(uv[..., 0]), 0, w - 1).astype(np.intp)
    y = np.clip(np.rint(uv[..., 1]), 0, h - 1).astype(np.intp)
    return np.median(smooth[y, x].astype(np.float64), axis=0)
