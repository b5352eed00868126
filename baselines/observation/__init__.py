"""Observation model: the log-likelihood of one frame for N poses at once.

The model compares each hypothesised pose with the frame through two cues, in
the spirit of the edge and foreground cues of Sidenbladh, Black & Sigal (ECCV
2002) and of Deutscher, Blake & Reid's annealed particle filter (CVPR 2000):

* **edge (oriented chamfer) term**: points sampled along the two silhouette
  lines of every projected cone should lie on image edges of the same
  orientation. The frame's edges (Canny on the blurred frame; on colour frames
  the strongest channel's gradient) are split into ``orientation_bins`` bins of
  gradient orientation, each turned once per frame into a truncated distance
  transform; an outline point reads the map of its cone's orientation (as in
  oriented chamfer matching, Shotton, Blake & Cipolla, PAMI 2008, which makes
  the cue robust to background clutter) and costs
  ``min(d, tau)^2 / (2 sigma^2)``, ``d`` its distance to the nearest such edge.
* **foreground term**: points along each cone's projected axis should fall on
  the figure, not on the background. The background colour is estimated from the
  frame's border (its median), and a pixel's foreground probability grows with
  its colour distance from it.

For a pose ``x``::

    log p(frame | x) = - sum over cones c of [
          mean over c's outline points of min(d, tau)^2 / (2 sigma^2)
        + foreground_weight * mean over c's axis points of (1 - fg) ]

up to a constant, less the optional *floor term* (``floor_below_mm``,
``floor_above_mm``), which is not read from the image: the scene's floor is
flat and the person's lowest ankle keeps near the height it had in the given
first pose, meant to pin the depth the image barely shows (off on every task:
tried on the validation persons and not kept, see ``envs/tasks.py``). Pixel
distances are measured in *reference pixels* (those of
a 128-pixel-high frame), so one set of parameters serves every image size.
Points outside the image cost the truncation value (and count as background).

The model uses the frame, the camera and the subject's known shape only; it has
no access to the ground truth. Everything is vectorised over poses: the
keypoints of all poses come from a specialised float32 forward kinematics
(:func:`humotion_gym.kinematics.fast_forward_kinematics`, checked against
:func:`humotion_gym.body.forward_kinematics`), only the 15 keypoints are
projected, the outline points are built in 2D (the projection of a segment is
a segment) by one small matrix product, and their costs are gathered from a
flat byte table with integer indices.
"""

from __future__ import annotations

import functools
import math
import threading
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import _kernels
from humotion_gym.body import (
    CONE_KEYPOINTS,
    KEYPOINT_NAMES,
    N_CONES,
    N_KEYPOINTS,
    N_PARAMS,
    BodyShape,
    cone_geometry,
    default_shape,
    forward_kinematics,
)
from humotion_gym.camera import Camera
from humotion_gym.envs.tasks import TaskSpec
from humotion_gym.kinematics import (
    _HEAD,
    _TO_INTERNAL,
    _TORSO,
    _batch_kinematics,
    _BatchPoses,
)
from humotion_gym.render import gaussian_blur

FloatArray = NDArray[np.float64]

# ---------------------------------------------------------------------------
# Frame features
# ---------------------------------------------------------------------------


# ObservationModel._free_cones' last answer: (key, shape, result), per process.
_FREE_CONES_CACHE: dict[str, tuple[tuple[bytes, bytes], BodyShape, Any]] = {}


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
        background_color: The estimated background colour (one value per channel).
        cost: Flat uint8 lookup table: the ``B`` padded ``(H + 2, W + 2)`` edge
            cost maps followed by the padded foreground cost map, per point, in
            units of ``cost_unit``; the 1-pixel border holds the cost of a point
            outside the image.
        cost_unit: The cost (nats) of one unit of ``cost``.
        residual: ``(2, E)`` float32 image coordinates (plus the table's
            padding offset) of the edge points the given body does not explain
            (see :class:`GivenBody`), or ``None`` when no body part was given.
        residual_cones: The cones (indices into ``CONE_NAMES``) whose outline
            must explain ``residual``: those that move with the free parameters.
        appearance_cones: The cones whose axis points read their own colour
            map (the maps after the foreground map in ``cost``, in this
            order), or ``None``.
        coverage: ``(2, F)`` float32 image coordinates (plus the padding
            offset) of foreground pixels the free cones must cover (the
            coverage term, see ``ObservationModel.coverage_weight``), or
            ``None``.
        coverage_cones: The cones that may cover them (those that move with
            the free parameters).
        floor: Height (mm, world z) of the lowest ankle in the episode's given
            first pose, for the floor term (``GivenBody.floor``), or ``None``
            where the model has no floor term.
    """

    width: int
    height: int
    edges: NDArray[np.uint8]
    distance: NDArray[np.float32]
    foreground: NDArray[np.float32]
    background_color: NDArray[np.float64]
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
    background, as in the background subtraction Deutscher, Blake & Reid, CVPR
    2000, took their silhouettes from). At the first frame the figure's pose is
    given, so every pixel its silhouette does not cover shows the backdrop.
    Nothing after the first frame is used.

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
        colors: ``(10, C)`` each cone's colour as seen at the episode's first
            frame (:meth:`ObservationModel.cone_colors` with the given initial
            pose), for the appearance term; ``None`` without one.
        backdrop: The scene behind the figure, read at the first frame
            (:meth:`ObservationModel.read_backdrop`), for a model with
            ``backdrop`` on; ``None`` without one.
        floor: Height (mm) of the lowest ankle in the episode's given first
            pose (:meth:`ObservationModel.floor_height`), for a model with a
            floor term; ``None`` without one.
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


# Per-thread scratch buffers of log_likelihood, keyed by (N, points per cone):
# arrays of a few MB that would otherwise be allocated and page-faulted afresh
# on every call (glibc returns freed memory of that size to the system).
_SCRATCH = threading.local()
_SCRATCH_KEEP = 4


def _scratch(n: int, n_points: int) -> dict[str, NDArray]:
    cache: dict[tuple[int, int], dict[str, NDArray]] | None = getattr(_SCRATCH, "cache", None)
    if cache is None:
        cache = {}
        _SCRATCH.cache = cache
    key = (n, n_points)
    work = cache.pop(key, None)
    if work is None:
        f4 = np.float32
        work = {
            # Read and written a pose at a time by the kinematics kernel.
            "params": _kernels.spaced_rows((N_PARAMS,), n),
            "trig": _kernels.spaced_rows((2, N_PARAMS - 3), n),
            "keypoints": _kernels.spaced_rows((3, N_KEYPOINTS), n),
            "camera": np.empty((3, N_KEYPOINTS * n), f4),
            "inverse_depth": np.empty((N_KEYPOINTS * n,), f4),
            "basis": np.empty((8, N_CONES, n), f4),
            "scratch": np.empty((4, N_CONES, n), f4),
            # Flat: _point_costs takes (2 P, K) views for its K columns.
            "points": np.empty(2 * n_points * N_CONES * n, f4),
            "index": np.empty(2 * n_points * N_CONES * n, np.int32),
            "values": np.empty(n_points * N_CONES * n, np.uint8),
        }
        while len(cache) >= _SCRATCH_KEEP:
            cache.pop(next(iter(cache)))
    cache[key] = work  # most recently used last
    return work


#: The largest magnitude of a parameter (mm or radians) a pose may have to be
#: scored: the scorer works in single precision, and beyond this a keypoint's
#: camera coordinates could overflow it (to infinities, then NaNs). Poses past
#: it score ``-inf``, like those with a NaN. It is far beyond any figure that
#: can appear in a frame, and it keeps every cone's image basis finite, which
#: the point costs' kernel relies on to skip the zero coefficients' products.
#: 2^100 (about 1.3e30): the same number in single and double precision, so
#: a pose's dtype does not move the bound.
POSE_LIMIT = 2.0**100

#: At most this many poses are scored in one pass (:func:`_chunk_size`).
_CHUNK_POSES = 3072


def _chunk_size(n: int) -> int:
    """Poses per pass when scoring ``n``: equal passes of at most :data:`_CHUNK_POSES`.

    Each pose is scored on its own, so any split gives the same numbers
    (``tests/test_observation_fast.py``). The scratch of a pass is about 3.4 KB per
    pose; passes of 2,000-3,300 poses ran fastest on the project's machine
    (2 MiB of L2 per core): at 10,000 poses 6.8-6.9 ms per BodyTrack-v1 frame
    against 8.3 in passes of 8,192 (the 1,808 left over the slowest per
    pose). Equal passes also never leave a single pose over, which numpy's
    path would score with a matrix-vector product (the kernels' module
    docstring says why that differs).
    """
    passes = -(-n // _CHUNK_POSES)
    return max(1, -(-n // max(1, passes)))


# Fewer poses than this are scored in one pass even when some cones are the
# same in all of them: the extra bookkeeping (tens of us) would cost about
# what scoring those cones saves.
_SHARED_MIN_POSES = 1000

#: The two ankles (KEYPOINT_NAMES order), whose lower one the floor term watches,
#: and the same in the internal keypoint order of _batch_kinematics.
_ANKLES_PUBLIC = (KEYPOINT_NAMES.index("r_ankle"), KEYPOINT_NAMES.index("l_ankle"))
_ANKLES = tuple(int(_TO_INTERNAL[k]) for k in _ANKLES_PUBLIC)
# Cone ends in the internal keypoint order of _batch_kinematics.
_CONE_START = _TO_INTERNAL[CONE_KEYPOINTS[:, 0]]
_CONE_END = _TO_INTERNAL[CONE_KEYPOINTS[:, 1]]
_DIST_MASK = cv2.DIST_MASK_5  # 5x5 chamfer: within 2% of the exact distance


def _canny(smooth: NDArray[np.uint8], low: float, high: float) -> NDArray[np.uint8]:
    """``cv2.Canny`` of a ``(H, W, C)`` frame (on colour: per pixel, the strongest channel).

    On a colour frame the compiled kernel picks the gradients as OpenCV's
    Canny does (``_kernels.canny_gradients``) and OpenCV finishes from them:
    the same edges in a third of the time.
    """
    if smooth.shape[2] == 3:
        if _kernels.ENABLED and _kernel_canny_as_opencv():
            gradients = _kernels.canny_gradients(smooth)
            if gradients is not None:
                return cv2.Canny(gradients[0], gradients[1], low, high)
        return cv2.Canny(smooth, low, high)
    return cv2.Canny(smooth[:, :, 0], low, high)


@functools.cache
def _kernel_canny_as_opencv() -> bool:
    """Whether Canny from the kernel's gradients gives the installed OpenCV's edges (checked once).

    An OpenCV whose colour Canny chose its channel otherwise would make the
    edges depend on whether numba is installed. So on first use both find the
    edges of noise, blurred noise and flat patches at several thresholds and
    sizes (about 2 ms); where any pixel differs, OpenCV runs alone, with one
    ``RuntimeWarning``.
    """
    rng = np.random.default_rng(20261124)
    for k, (h, w) in enumerate([(128, 128), (96, 160), (9, 13), (64, 48)]):
        img = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
        if k % 2:
            img = cv2.GaussianBlur(img, (0, 0), 1.5)
        img[: h // 3, : w // 3] = rng.integers(0, 256, 3)  # a flat patch: equal channels' ties
        gradients = _kernels.canny_gradients(img)
        if gradients is None:
            return True  # the kernels are off (numba failed and said so): nothing to check
        for low, high in [(40.0, 100.0), (5.0, 20.0), (90.0, 300.0)]:
            if not np.array_equal(
                cv2.Canny(gradients[0], gradients[1], low, high), cv2.Canny(img, low, high)
            ):
                warnings.warn(
                    f"humotion_gym: this OpenCV ({cv2.__version__}) finds other edges from the "
                    "gradient kernel's gradients; its own Canny runs (the other kernels still "
                    "run).",
                    RuntimeWarning,
                    stacklevel=4,
                )
                return False
    return True


@functools.cache
def _kernel_distances_as_opencv() -> bool:
    """Whether the distance kernel gives the installed OpenCV's distances (checked once).

    The kernel copies the float32 sums of the IPP build that OpenCV's wheels
    ship; a build that summed otherwise (OpenCV's own code works in fixed
    point) would make the costs depend on whether numba is installed. So on
    first use both transform maps of scattered points, of lines, and of one
    point, at the kernel's longest reach (about 3 ms); where any distance up
    to it differs, OpenCV runs, with one ``RuntimeWarning``.
    """
    rng = np.random.default_rng(20261124)
    steps = int(_kernels.DISTANCE_LIMIT)
    maps = []
    for k, (h, w) in enumerate([(128, 128), (96, 160), (41, 67), (128, 128), (5, 9)]):
        density = (0.002, 0.02, 0.2, 0.01, 0.1)[k]
        m = np.where(rng.random((4, h, w)) < density, 0, 255).astype(np.uint8)
        for b in range(2, 4):  # lines at every slope
            for _ in range(6):
                ends = rng.integers(-8, max(h, w) + 8, 4)
                cv2.line(m[b], (int(ends[0]), int(ends[1])), (int(ends[2]), int(ends[3])), 0, 1)
        maps.append(m)
    single = np.full((1, 2 * steps + 9, 2 * steps + 9), 255, np.uint8)
    single[0, steps + 4, steps + 4] = 0
    maps.append(single)
    for m in maps:
        found = (m == 0).reshape(m.shape[0], -1).any(axis=1)
        ours = np.empty(m.shape, np.float32)
        if not _kernels.distance_maps(m, found, steps, ours):
            return True  # the kernels are off (numba failed and said so): nothing to check
        for b in range(m.shape[0]):
            theirs = cv2.distanceTransform(m[b], cv2.DIST_L2, _DIST_MASK)
            near = theirs <= steps
            if not found[b] or (
                np.array_equal(ours[b][near], theirs[near]) and (ours[b][~near] > steps).all()
            ):
                continue
            warnings.warn(
                f"humotion_gym: this OpenCV ({cv2.__version__}) gives other edge distances than "
                "the distance kernel; OpenCV computes them (the other kernels still run).",
                RuntimeWarning,
                stacklevel=4,
            )
            return False
    return True


@dataclass(frozen=True)
class ObservationModel:
    """Edge (chamfer) plus foreground likelihood of a frame for N poses.

    One model serves every task and agent; the defaults are tuned on the
    renderer's default scene (clutter, noise) and are what the leaderboard uses.
    Distances are in *reference pixels*: pixels of a frame ``reference_height``
    pixels high, so the same parameters fit every image size.

    The log-likelihood is in nats up to a constant; its scale is set by
    ``edge_sigma`` (per cone, the edge term lies in
    ``[0, edge_truncation**2 / (2 edge_sigma**2)]`` = [0, 2] by default, the
    foreground term in ``[0, foreground_weight]``), so a pose whose whole outline
    is off by ``edge_truncation`` scores about 20 nats below one that fits.
    Particle filters may temper it further.

    Attributes:
        edge_sigma: Standard deviation (reference px, default 1.5) of the
            distance between a model outline point and the image edge it
            explains: the pixel quantisation of edges and of the cone outline
            plus the blur. It sets the likelihood's sharpness (see above).
        edge_truncation: Distance (reference px, default 3.0) beyond which an
            outline point costs no more. The robust truncation of the chamfer
            cost: outline points with no edge (an outline hidden behind another
            limb, a low-contrast edge, a point off the image) cost a bounded
            amount, so the score counts how much of the outline is explained.
            Three reference pixels is 50-100 mm on a body filling a 128-pixel
            frame: tuned on the test of ``tests/test_observation.py`` (true
            pose against poses 5-10 cm off), where 6 px gave 95-97% and 3 px
            99%.
        foreground_weight: Weight (default 0.5) of the foreground term: the
            cost, per cone, of its axis lying wholly on background; a quarter of
            the edge term's range. It holds a pose on the figure where edges are
            missing (low contrast, occluders) without letting the crude border
            colour model (clutter counts as foreground) override the edges.
        foreground_low: Colour distance (grey levels, default 25) from the
            background colour below which a pixel counts as background; above
            the renderer's default noise (sigma 4) after ``edge_blur``.
        foreground_high: Colour distance (grey levels, default 70) above which a
            pixel counts as certain foreground; between the two the probability
            rises linearly.
        border_width: Width in pixels (default 2) of the frame border whose
            median colour estimates the background colour. The figure rarely
            touches the border (cameras are fitted with a margin).
        canny_low: Lower hysteresis threshold of ``cv2.Canny`` (default 40).
        canny_high: Upper hysteresis threshold of ``cv2.Canny`` (default 100):
            well above the gradient of the renderer's noise after ``edge_blur``,
            below the contrast of the figure's colours against a mid-grey wall.
        edge_blur: Gaussian sigma in pixels (default 0.8) of the blur applied
            before edge detection and foreground estimation, to suppress sensor
            noise; 0 turns it off.
        outline_samples: Points per silhouette line of each cone (default 5, at
            the centres of equal parts of the cone's length): 10 outline points
            per cone, 100 per pose. Time grows linearly with the points.
        axis_samples: Points along each cone's projected axis for the foreground
            term (default 3).
        reference_height: Image height (default 128) whose pixels are the unit
            of ``edge_sigma`` and ``edge_truncation``.
        near_mm: Keypoints closer to the camera plane than this (default 10 mm),
            or behind it, are treated as outside the image.
        orientation_bins: Number of edge orientation bins (default 4: 0, 45, 90
            and 135 degrees; every edge pixel counts for its two nearest bins,
            so an outline matches edges within 45 degrees of its own
            orientation). 1 gives plain (unoriented) chamfer matching; 6 and 8
            scored the same as 4 on the tests and cost more distance transforms.
        sharpness: Multiplier of the whole log-likelihood (an inverse
            temperature; default 1). Per-cone costs are means over the cone's
            points, so the default treats each cone, not each point, as one
            observation; ``outline_samples * 2`` would treat points as
            independent. Left at 1 for every agent: a truth-centred particle
            cloud is estimated best at 0.3-1 (BodyTrack: 13 mm at 1, 25 mm at 3,
            54 mm at 10), i.e. sharper weights are overconfident.
        residual_weight: Weight (default 0: off) of the *residual-edge* term,
            the image-to-model direction of the chamfer cost, used where a task
            gives part of the body (:class:`GivenBody`). The given cones'
            outlines are drawn once per frame; the edge pixels they leave
            unexplained within reach of the free cones (the free limbs' own
            edges, and clutter) should lie on a free cone's outline, and each
            such point costs ``min(d, residual_truncation)^2 / (2 sigma^2)``,
            averaged over the points and multiplied by this weight. The
            model-to-image term alone is maximised by any limb laid along edges
            that are there anyway (the torso's side, the other side of the
            limb, clutter); this term asks that the limb explain the edges
            only it can explain. On ArmTrack, a greedy search over arm poses on
            flat-background validation frames went from 264 mm (worse than not
            moving, 191 mm) without it to 87 mm with it.
        residual_truncation: Distance (reference px, default 6) beyond which a
            residual point costs no more.
        residual_points: At most this many residual points per frame (default
            128, an evenly strided subset in raster order: deterministic).
        residual_clearance: Half-width (reference px, default 2) of the band
            around the given cones' outlines whose edges count as explained.
        appearance_weight: Weight (default 0: off) of the *appearance* term,
            used where a task gives part of the body and the colours of the
            cones were read at the first frame (``GivenBody.colors``): the
            axis points of each free cone cost, per cone, up to this weight
            where the pixel's colour differs from that cone's (between
            ``appearance_low`` and ``appearance_high`` grey levels of the
            largest channel difference the cost rises linearly). Clutter and
            the torso rarely share a forearm's colour.
        appearance_low: Colour difference (default 20) below which a pixel
            matches the cone's colour.
        appearance_high: Colour difference (default 60) above which it does
            not match at all.
        backdrop: Whether to use the backdrop read at the first frame
            (default False; :class:`Backdrop`, handed in ``GivenBody.backdrop``).
            Where it is known, a pixel's foreground probability comes from its
            colour distance to the backdrop's pixel instead of to the border's
            median (clutter is backdrop, not figure), and edges farther than
            ``backdrop_reach`` from any foreground pixel are dropped (the
            clutter's edges: the figure's outline borders its foreground).
            Elsewhere (under the initial figure, or without a backdrop) the
            border rule and every edge remain. The threshold rises with the
            frame's sensor noise (measured on the known pixels); where the
            noise hides ``foreground_high`` the border rule is used alone.
        backdrop_margin: Reference pixels (default 2) the initial pose's
            silhouette is grown by before the rest counts as known backdrop:
            the blur and the cones' rounded ends spill past their outline.
        backdrop_reach: Reference pixels (default 3) around the foreground
            within which edges are kept; 0 keeps every edge.
        coverage_weight: Weight (default 0: off) of the *coverage* term, the
            image-to-model direction of the foreground cue (the silhouette
            explained, as in Deutscher, Blake & Reid's silhouette cue and
            Sidenbladh & Black's foreground likelihood, which both count
            foreground the model leaves unexplained). It needs the backdrop:
            the pixels that differ clearly from the known backdrop
            (``foreground_high``) and that the given body's cones do not
            cover are the free limbs' own; each should lie inside a free
            cone's projection, and costs ``min(d, coverage_truncation)^2 /
            (2 sigma^2)`` for ``d`` its distance outside the nearest one,
            averaged over the points and multiplied by this weight. The
            model-to-image foreground term alone is as happy with both legs on
            one leg's pixels as with each on its own.
        coverage_truncation: Distance (reference px, default 4) beyond which
            a coverage point costs no more.
        coverage_points: At most this many coverage points per frame
            (default 96, an evenly strided subset in raster order).
        floor_below_mm: Scale (mm; default ``inf``: off) of the *floor term*'s
            cost for a pose whose lowest ankle is below the height it had in
            the episode's given first pose (``GivenBody.floor``): ``d`` mm below
            costs ``(d / floor_below_mm)^2 / 2`` nats. Not an image cue but
            the scene's: the floor is flat and feet do not sink into it. The
            image barely shows depth (a figure 5 m away grows one pixel in 128
            per 100 mm nearer; on BodyTrack's validation frames the
            log-likelihood of the true pose slid along the camera ray varies
            by under 1.5 nats over +-400 mm), while sliding a figure along its
            ray moves it up or down (the cameras look down on it), so the floor
            was meant to pin the depth; on the validation persons it did not
            help (off on every task; numbers in ``humotion_gym/envs/tasks.py``).
            Added to the log-likelihood after ``sharpness``.
        floor_above_mm: Scale (mm; default ``inf``: off) of the floor term's
            cost for a lowest ankle *above* that height (a person jumps, so it
            is looser than ``floor_below_mm`` where used).
        raster_pad_px: Image pixels (not reference pixels; default 0) added to
            every cone's projected half-width. The renderer fills each cone
            with ``cv2.fillConvexPoly`` (8-connected), which paints every
            pixel its outline passes through: the drawn figure is about half a
            pixel wider on each side than the cone's exact projection (0.48
            px, measured over random strips in ``tests/test_raster_pad.py``).
            A model without it finds the drawn limbs too thick for the true
            depth and prefers the figure nearer the camera (on BodyTrack's test
            frames the true pose slid along the camera ray scores best 151 mm
            in front of the truth; with 0.5, 22 mm behind it). Off by default:
            on the validation persons it tracked no better (worse on the walks;
            numbers in ``humotion_gym/envs/tasks.py``).
    """

    edge_sigma: float = 1.5
    edge_truncation: float = 3.0
    foreground_weight: float = 0.5
    foreground_low: float = 25.0
    foreground_high: float = 70.0
    border_width: int = 2
    canny_low: float = 40.0
    canny_high: float = 100.0
    edge_blur: float = 0.8
    outline_samples: int = 5
    axis_samples: int = 3
    reference_height: int = 128
    near_mm: float = 10.0
    orientation_bins: int = 4
    sharpness: float = 1.0
    residual_weight: float = 0.0
    residual_truncation: float = 6.0
    residual_points: int = 128
    residual_clearance: float = 2.0
    appearance_weight: float = 0.0
    appearance_low: float = 20.0
    appearance_high: float = 60.0
    backdrop: bool = False
    backdrop_margin: float = 2.0
    backdrop_reach: float = 3.0
    coverage_weight: float = 0.0
    coverage_truncation: float = 4.0
    coverage_points: int = 96
    floor_below_mm: float = math.inf
    floor_above_mm: float = math.inf
    raster_pad_px: float = 0.0

    def __post_init__(self) -> None:
        positive = (
            "edge_sigma",
            "edge_truncation",
            "near_mm",
            "residual_truncation",
            "coverage_truncation",
        )
        for name in positive:
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ObservationModel.{name}: expected a positive number")
        if not (math.isfinite(self.sharpness) and self.sharpness > 0):
            raise ValueError("ObservationModel.sharpness: expected a positive number")
        if not (self.foreground_weight >= 0 and math.isfinite(self.foreground_weight)):
            raise ValueError("ObservationModel.foreground_weight: expected a number >= 0")
        if not 0 <= self.foreground_low < self.foreground_high:
            raise ValueError("ObservationModel: expected 0 <= foreground_low < foreground_high")
        if not 0 < self.canny_low <= self.canny_high:
            raise ValueError("ObservationModel: expected 0 < canny_low <= canny_high")
        if not 0 <= self.appearance_low < self.appearance_high:
            raise ValueError("ObservationModel: expected 0 <= appearance_low < appearance_high")
        if not isinstance(self.backdrop, (bool, np.bool_)):
            raise ValueError(f"ObservationModel.backdrop: expected a bool, got {self.backdrop!r}")
        for name in (
            "residual_weight",
            "residual_clearance",
            "appearance_weight",
            "backdrop_margin",
            "backdrop_reach",
            "coverage_weight",
            "raster_pad_px",
        ):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"ObservationModel.{name}: expected a number >= 0")
        for name in ("floor_below_mm", "floor_above_mm"):
            value = float(getattr(self, name))
            if not value > 0:  # inf (off) allowed; NaN and <= 0 refused
                raise ValueError(
                    f"ObservationModel.{name}: expected a positive number (inf: off), got {value}"
                )
        if self.edge_blur < 0:
            raise ValueError("ObservationModel.edge_blur: expected a number >= 0")
        for name in (
            "outline_samples",
            "axis_samples",
            "border_width",
            "reference_height",
            "orientation_bins",
            "residual_points",
            "coverage_points",
        ):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"ObservationModel.{name}: expected a positive integer")
        if 2 * self.outline_samples + self.axis_samples > 257:
            raise ValueError("ObservationModel: at most 257 points per cone (uint16 sums)")

    # -- per frame ---------------------------------------------------------

    def prepare(self, frame: ArrayLike, given: GivenBody | None = None) -> FrameFeatures:
        """Edge distance map and foreground map of one frame.

        Args:
            frame: ``(H, W, 3)``, ``(H, W, 1)`` or ``(H, W)`` uint8 image.
            given: The body part the task gives in this frame; with a positive
                ``residual_weight`` the features then hold the edge points it
                leaves unexplained, with a positive ``appearance_weight`` (and
                ``given.colors``) a colour map per free cone. Ignored otherwise.

        Returns:
            The frame's features, to pass to :meth:`log_likelihood` for any
            number of poses.

        Raises:
            ValueError: If the frame is not a uint8 image of that shape.
        """
        smooth = self._smoothed(frame, "ObservationModel.prepare")
        h, w, channels = smooth.shape
        if h < 8 or w < 8:
            raise ValueError(f"ObservationModel.prepare: frame too small ({w}x{h})")
        scale = h / self.reference_height
        backdrop = None
        if self.backdrop and given is not None and given.backdrop is not None:
            backdrop = given.backdrop
            if backdrop.image.shape != smooth.shape or backdrop.known.shape != (h, w):
                raise ValueError(
                    f"GivenBody.backdrop: expected an image of shape {smooth.shape}, got "
                    f"{backdrop.image.shape} (known {backdrop.known.shape})"
                )
        fg, bg, keep, backdrop = self._foreground(smooth, backdrop, scale)
        edges, bin_maps, found = self._oriented_edges(smooth, keep)
        n_bins = self.orientation_bins
        dist = self._edge_distances(bin_maps, found, scale)
        n_out = 2 * self.outline_samples
        edge_scale = np.float32(1.0 / (2.0 * self.edge_sigma**2 * n_out))
        edge_out = self.edge_truncation**2 * edge_scale

        fg_scale = self.foreground_weight / self.axis_samples

        use_appearance = (
            given is not None and self.appearance_weight > 0 and given.colors is not None
        )
        use_residual = given is not None and self.residual_weight > 0
        use_coverage = backdrop is not None and self.coverage_weight > 0
        free = None
        if given is not None and (use_appearance or use_residual or use_coverage):
            free = self._free_cones(given)
        app_cones = free[0] if use_appearance and free is not None else None
        n_app = 0 if app_cones is None else app_cones.size
        app_scale = self.appearance_weight / self.axis_samples if n_app else 0.0
        app_colors = np.zeros((n_app, channels), np.float32)
        if n_app:
            assert given is not None and given.colors is not None and app_cones is not None
            colors = np.asarray(given.colors, dtype=np.float64)
            if colors.shape != (N_CONES, channels):
                raise ValueError(
                    f"GivenBody.colors: expected shape ({N_CONES}, {channels}), got {colors.shape}"
                )
            app_colors = colors[app_cones].astype(np.float32)
        # Quantise to bytes (a gather of bytes is faster than one of floats):
        # 1/255 of the largest per-point cost is far below anything that matters.
        unit = max(edge_out, fg_scale, app_scale) / 255.0 or 1.0
        table = np.empty((n_bins + 1 + n_app, h + 2, w + 2), np.uint8)
        span = np.float32(1.0 / (self.appearance_high - self.appearance_low))
        compiled = _kernels.cost_table(
            dist, scale != 1.0, np.float32(1.0 / scale), np.float32(self.edge_truncation),
            edge_scale, np.float32(edge_out), fg, np.float32(fg_scale), smooth, app_colors,
            np.float32(self.appearance_low), span, np.float32(app_scale), np.float32(1.0 / unit),
            table,
        )  # fmt: skip
        if not compiled:
            self._cost_maps(
                dist, scale, edge_scale, edge_out, fg, fg_scale, smooth, app_colors, app_scale,
                span, unit, table,
            )  # fmt: skip
        cost = table.reshape(-1)
        residual, cones = None, None
        if use_residual and given is not None and free is not None:
            residual, cones = self._residual_edges(edges, given, scale, free)
        coverage, coverage_cones = None, None
        if use_coverage and given is not None and backdrop is not None and free is not None:
            coverage_cones = free[0]
            coverage = self._coverage_points(fg, backdrop, given, free)
        floor = None
        if self.has_floor_term and given is not None and given.floor is not None:
            floor = float(given.floor)
            if not math.isfinite(floor):
                raise ValueError(f"GivenBody.floor: expected a finite height in mm, got {floor}")
        return FrameFeatures(
            w, h, edges, dist, fg, bg, cost, float(unit), residual, cones, app_cones,
            coverage, coverage_cones, floor,
        )  # fmt: skip

    def _edge_distances(
        self, bin_maps: NDArray[np.uint8], found: NDArray[np.bool_], scale: float
    ) -> NDArray[np.float32]:
        """``(B, H, W)`` each orientation bin's ``cv2.distanceTransform``, as the costs read it.

        The cost table truncates the distances at ``edge_truncation``
        reference pixels. The compiled kernel gives OpenCV's distance wherever
        that is at most a whole number of pixels past the truncation (in this
        frame's pixels) and a larger one elsewhere, so the table is the same;
        :attr:`FrameFeatures.distance` holds them truncated either way.
        OpenCV runs when the kernels are off, the truncation is too far for
        the kernel (``_kernels.DISTANCE_LIMIT``), or this OpenCV's distances
        differ from the kernel's (:func:`_kernel_distances_as_opencv`).
        """
        n_bins, h, w = bin_maps.shape
        dist = np.empty((n_bins, h, w), np.float32)
        steps = math.ceil(self.edge_truncation * scale) + 1
        # The cost table scales a distance by 1 / scale (float32) and truncates
        # it: everything from `steps` on must land on the truncation.
        beyond = scale == 1.0 or np.float32(steps) * np.float32(1.0 / scale) >= np.float32(
            self.edge_truncation
        )
        if (
            beyond
            and _kernels.ENABLED
            and _kernel_distances_as_opencv()
            and _kernels.distance_maps(bin_maps, found, steps, dist)
        ):
            return dist
        for b in range(n_bins):
            if found[b]:
                cv2.distanceTransform(bin_maps[b], cv2.DIST_L2, _DIST_MASK, dst=dist[b])
            else:
                dist[b] = np.inf
        return dist

    def _cost_maps(
        self,
        dist: NDArray[np.float32],
        scale: float,
        edge_scale: np.float32,
        edge_out: np.float32,
        fg: NDArray[np.float32],
        fg_scale: float,
        smooth: NDArray[np.uint8],
        app_colors: NDArray[np.float32],
        app_scale: float,
        span: np.float32,
        unit: float,
        table: NDArray[np.uint8],
    ) -> None:
        """The cost table's maps into ``table`` (the numpy reference of ``_kernels.cost_table``).

        ``dist`` is rescaled by the frame's scale and truncated in place; each
        map is padded by its cost outside the image, then all are quantised to
        ``unit``.
        """
        n_bins, h, w = dist.shape
        if scale != 1.0:  # (a product by 1 changes nothing: skipped)
            dist *= np.float32(1.0 / scale)
        np.minimum(dist, np.float32(self.edge_truncation), out=dist)
        maps = np.empty(table.shape, np.float32)
        maps[:n_bins].fill(edge_out)
        np.multiply(dist, dist, out=maps[:n_bins, 1:-1, 1:-1])
        maps[:n_bins, 1:-1, 1:-1] *= edge_scale
        maps[n_bins].fill(fg_scale)
        np.multiply(1.0 - fg, np.float32(fg_scale), out=maps[n_bins, 1:-1, 1:-1])
        if app_colors.shape[0]:
            pixels = smooth.astype(np.float32)
            for k, color in enumerate(app_colors):
                diff = np.abs(pixels - color)
                # The largest channel, channel by channel: the same maximum as
                # diff.max(axis=2), which reduces three values at a time and
                # took 0.47 ms at 128x128 (this, 0.014).
                mismatch = diff[:, :, 0].copy()
                for c in range(1, diff.shape[2]):
                    np.maximum(mismatch, diff[:, :, c], out=mismatch)
                mismatch -= np.float32(self.appearance_low)
                mismatch *= span
                np.clip(mismatch, 0.0, 1.0, out=mismatch)
                maps[n_bins + 1 + k].fill(app_scale)
                np.multiply(mismatch, np.float32(app_scale), out=maps[n_bins + 1 + k, 1:-1, 1:-1])
        maps *= np.float32(1.0 / unit)
        np.rint(maps, out=maps)
        table[...] = maps  # the cast to bytes (every value lies in [0, 255])

    def _coverage_points(
        self,
        fg: NDArray[np.float32],
        backdrop: Backdrop,
        given: GivenBody,
        free: tuple[NDArray[np.intp], Any],
    ) -> NDArray[np.float32]:
        """The foreground pixels the free cones must cover: ``(2, F)``, x then y (+1.5).

        Pixels of the known backdrop that differ from it clearly (foreground
        probability 1), outside the given cones' silhouettes in this frame.
        """
        free_cones, (geo, _ends, moved) = free
        fixed_cones = np.flatnonzero(~moved.any(axis=1))
        sure = (fg >= 1.0) & backdrop.known
        if fixed_cones.size:
            # The given cones are where _free_cones' probe put them (its first pose).
            covered = _silhouette_mask(
                geo.starts[0], geo.ends[0], given.shape, given.camera, self.near_mm,
                cones=fixed_cones,
            )  # fmt: skip
            covered = _grow(covered, self.backdrop_margin * fg.shape[0] / self.reference_height)
            sure &= covered == 0
        if free_cones.size == 0:
            sure[:] = False
        return _spread_points(sure, self.coverage_points)

    def cone_colors(
        self, frame: ArrayLike, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> NDArray[np.float64]:
        """Each cone's colour in a frame where its pose is known: ``(10, C)``.

        The median of the (blurred) pixels at the middle of each cone's
        projected axis (fractions 0.3-0.7 of its length), where the pose is
        the given initial pose; a cone off the image gets its nearest pixels.
        """
        smooth = self._smoothed(frame, "ObservationModel.cone_colors")
        h, w, _ = smooth.shape
        geo = cone_geometry(np.asarray(pose, dtype=np.float64), shape)
        t = np.linspace(0.3, 0.7, 5)[:, None, None]
        points = geo.starts[None] * (1.0 - t) + geo.ends[None] * t  # (5, 10, 3)
        uv = camera.project(points)
        uv = np.nan_to_num(uv, nan=-1.0)
        x = np.clip(np.rint(uv[..., 0]), 0, w - 1).astype(np.intp)
        y = np.clip(np.rint(uv[..., 1]), 0, h - 1).astype(np.intp)
        return np.median(smooth[y, x].astype(np.float64), axis=0)

    def _free_cones(self, given: GivenBody) -> tuple[NDArray[np.intp], Any]:
        """The cones that move with the free parameters, and the probe's geometry."""
        pose = np.asarray(given.pose, dtype=np.float64)
        free = np.asarray(given.free, dtype=np.intp)
        if pose.shape != (N_PARAMS,):
            raise ValueError(f"GivenBody.pose: expected shape (25,), got {pose.shape}")
        if free.ndim != 1 or (free.size and not (0 <= free.min() and free.max() < N_PARAMS)):
            raise ValueError("GivenBody.free: expected indices of pose parameters (0-24)")
        # The same given pose, free parameters and shape give the same answer:
        # on tasks that give nothing (or the same thing every frame) the probe
        # is worked out once per episode instead of once per frame.
        key = (pose.tobytes(), free.tobytes())
        cached = _FREE_CONES_CACHE.get("last")
        if cached is not None and cached[0] == key and cached[1] is given.shape:
            return cached[2]
        # Two moves of the free parameters tell which cone ends depend on them.
        probe = np.stack([pose, pose, pose])
        probe[1, free] += 0.5
        probe[2, free] -= 0.7
        geo = cone_geometry(probe, given.shape)
        ends = np.stack([geo.starts, geo.ends], axis=2)  # (3, 10, 2, 3)
        moved = np.abs(ends[1:] - ends[0]).max(axis=(0, 3)) > 1e-6  # (10, 2)
        result = (np.flatnonzero(moved.any(axis=1)), (geo, ends, moved))
        for array in (result[0], ends, moved, *geo):
            array.setflags(write=False)  # shared by every frame that hits the cache
        _FREE_CONES_CACHE["last"] = (key, given.shape, result)
        return result

    def _residual_edges(
        self,
        edges: NDArray[np.uint8],
        given: GivenBody,
        scale: float,
        free: tuple[NDArray[np.intp], Any],
    ) -> tuple[NDArray[np.float32], NDArray[np.intp]]:
        """Edge points the given cones do not explain, near the free cones.

        The free cones are those whose ends move when the free parameters do
        (found by moving them); the given cones' outlines and end circles are
        drawn ``residual_clearance`` wide and their edges removed; what remains
        within reach of the free cones' fixed anchors (the sum of the free
        cones' lengths, projected at the nearest depth it can reach) is kept.

        Returns:
            ``(2, E)`` points (x then y, plus the cost table's 1.5 offset) and
            the free cones' indices.
        """
        camera = given.camera
        free_cones, (geo, ends, moved) = free  # _free_cones(given), computed once per frame
        if (camera.width, camera.height) != (edges.shape[1], edges.shape[0]):
            raise ValueError("GivenBody.camera: its image size differs from the frame's")
        h, w = edges.shape
        if free_cones.size == 0:
            return np.zeros((2, 0), np.float32), free_cones
        fixed_cones = np.flatnonzero(~moved.any(axis=1))
        mask = np.zeros((h, w), np.uint8)
        thick = max(1, int(round(2.0 * self.residual_clearance * scale)) + 1)
        starts, stops = geo.starts[0], geo.ends[0]
        radii = given.shape.radii * ((1.0 + given.shape.aspect[:, None]) / 2.0)
        uv_s, uv_e, z, r_s, r_e, normal = _projected_cones(starts, stops, radii, camera)
        for c in fixed_cones.tolist():
            if z[c] < self.near_mm:
                continue
            for side in (1.0, -1.0):
                p0 = np.rint(uv_s[c] + side * r_s[c] * normal[c]).astype(int)
                p1 = np.rint(uv_e[c] + side * r_e[c] * normal[c]).astype(int)
                cv2.line(mask, tuple(p0.tolist()), tuple(p1.tolist()), 255, thick)
            for centre, r in ((uv_s[c], r_s[c]), (uv_e[c], r_e[c])):
                cv2.circle(mask, tuple(np.rint(centre).astype(int).tolist()),
                           max(0, int(round(r))), 255, thick)  # fmt: skip
        ys, xs = np.nonzero((edges > 0) & (mask == 0))
        # Within reach of the anchors: the free cones' ends that do not move.
        anchors = ends[0][free_cones][~moved[free_cones]]  # (K, 3)
        if anchors.size:
            length = np.linalg.norm(stops[free_cones] - starts[free_cones], axis=1).sum()
            z = camera.to_camera(anchors)[:, 2]
            near = np.maximum(z - length, self.near_mm)
            reach = camera.focal * length / near
            centre = camera.project(anchors)
            d2 = (xs[:, None] - centre[None, :, 0]) ** 2 + (ys[:, None] - centre[None, :, 1]) ** 2
            keep = (d2 <= reach[None, :] ** 2).any(axis=1)
            ys, xs = ys[keep], xs[keep]
        if xs.size > self.residual_points:
            pick = np.linspace(0, xs.size - 1, self.residual_points).astype(np.intp)
            ys, xs = ys[pick], xs[pick]
        points = np.stack([xs, ys]).astype(np.float32)
        points += np.float32(1.5)  # the offset _score gives image coordinates
        return points, free_cones

    def _smoothed(self, frame: ArrayLike, where: str) -> NDArray[np.uint8]:
        """The frame as ``(H, W, C)`` uint8, blurred by ``edge_blur``.

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
        smooth = img if self.edge_blur <= 0 else gaussian_blur(img, self.edge_blur)
        return smooth.reshape(img.shape)

    def _oriented_edges(
        self, smooth: NDArray[np.uint8], keep: NDArray[np.uint8] | None = None
    ) -> tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray[np.bool_]]:
        """Canny edges (any channel) and their split into orientation bins.

        ``keep`` (uint8, 255 where edges count), when given, masks the edges.

        Returns:
            The ``(H, W)`` edge map; ``(B, H, W)`` uint8 maps for
            ``cv2.distanceTransform``, map ``b`` 0 at the edge pixels whose
            gradient orientation (modulo pi) lies within ``pi / B`` of ``b pi /
            B`` (so every edge pixel is in its two nearest bins) and 255
            elsewhere; and ``(B,)`` whether each bin holds any edge pixel.
        """
        h, w, channels = smooth.shape
        edges = _canny(smooth, self.canny_low, self.canny_high)
        if keep is not None:
            cv2.bitwise_and(edges, keep, dst=edges)
        n_bins = self.orientation_bins
        if n_bins > 1:
            # The compiled kernels read the gradients at the edge pixels only
            # (two whole-frame Sobel filters and their gathers were most of the
            # split's 100-200 us); the same maps (tests/test_kernels.py).
            compiled = _kernels.orientation_maps(smooth, edges, n_bins)
            if compiled is not None:
                return edges, compiled[0], compiled[1]
        bins = np.zeros((n_bins, h, w), np.uint8)
        if n_bins == 1:
            bins[0] = edges
        else:
            self._bin_edges(smooth, edges, bins)
        return edges, np.bitwise_not(bins), bins.reshape(n_bins, -1).any(axis=1)

    @staticmethod
    def _bin_edges(smooth: NDArray[np.uint8], edges: NDArray[np.uint8], bins: NDArray) -> None:
        """Set each edge pixel to 255 in its two nearest orientation bins (the numpy path)."""
        n_bins, h, w = bins.shape
        channels = smooth.shape[2]
        # The edge pixels in raster order, as np.nonzero lists them (OpenCV's
        # scan is several times faster).
        found = cv2.findNonZero(edges)
        if found is None:
            return
        found = found.reshape(-1, 2)
        ys, xs = found[:, 1], found[:, 0]
        gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3).reshape(h, w, channels)[ys, xs]
        gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3).reshape(h, w, channels)[ys, xs]
        # The channel with the strongest gradient gives the orientation.
        best = np.argmax(gx * gx + gy * gy, axis=1)
        pick = np.arange(ys.size)
        theta = np.arctan2(gy[pick, best], gx[pick, best])  # gradient = outline normal
        q = np.mod(theta, np.pi) * (n_bins / np.pi)
        lo = np.floor(q).astype(np.intp) % n_bins
        bins[lo, ys, xs] = 255
        bins[(lo + 1) % n_bins, ys, xs] = 255

    def _foreground(
        self, smooth: NDArray[np.uint8], backdrop: Backdrop | None = None, scale: float = 1.0
    ) -> tuple[NDArray, NDArray, NDArray[np.uint8] | None, Backdrop | None]:
        """Foreground probability from the colour distance to the background.

        The background is the border's median colour, and, where ``backdrop``
        knows it, the backdrop's pixel. The backdrop's own differences (sensor
        noise: the frame's known pixels mostly show it) set how far a pixel
        must differ from it to count: ``foreground_low`` or 2.5 times their
        median (about their 99.5th percentile), whichever is larger, the
        ramp moved up by as much. Where that passes ``foreground_high`` the
        noise hides what the model counts as certain foreground, and the
        border rule is used alone.

        Returns:
            The ``(H, W)`` float32 probability, the border's median colour,
            with a backdrop used and a positive ``backdrop_reach`` the uint8
            mask of where edges count (within reach of a foreground pixel, or
            where the backdrop is unknown), else None, and the backdrop if it
            was used, else None.
        """
        h, w, channels = smooth.shape
        b = min(self.border_width, h // 4, w // 4)
        bg = _kernels.border_median(smooth, b)
        if bg is None:
            border = np.concatenate(
                [
                    smooth[:b].reshape(-1, channels),
                    smooth[-b:].reshape(-1, channels),
                    smooth[b:-b, :b].reshape(-1, channels),
                    smooth[b:-b, -b:].reshape(-1, channels),
                ]
            )
            bg = np.median(border, axis=0)
        if _kernels.ENABLED:
            compiled = self._compiled_foreground(smooth, bg, backdrop, scale)
            if compiled is not None:
                return compiled
        diff = _channel_max(
            cv2.absdiff(smooth, tuple(float(v) for v in bg) + (0.0,) * (4 - channels)),
            h, w, channels,
        )  # fmt: skip
        keep = None
        if backdrop is not None:
            near = _channel_max(cv2.absdiff(smooth, backdrop.image), h, w, channels)
            low = self._backdrop_low(np.bincount(near[backdrop.known], minlength=256))
            if low is None:
                backdrop = None  # noise hides the figure, or nothing of the backdrop is known
        if backdrop is not None:
            assert low is not None
            shift = low - self.foreground_low
            if shift > 0:  # the ramp moved up: the same probabilities from ``low`` on
                near = cv2.subtract(near, float(shift))
            # Under the initial figure the first frame showed the figure: a
            # pixel still as it was is figure (probability 1); one that changed
            # shows the backdrop the figure left or another part of it (1/2).
            # The border rule there would paint the clutter the figure uncovers
            # as foreground where the figure started: a pull towards ``hold``.
            changed = near > self.foreground_low
            unknown = np.where(changed, 0.5 * (self.foreground_low + self.foreground_high),
                               self.foreground_high)  # fmt: skip
            np.copyto(diff, near, where=backdrop.known)
            np.copyto(diff, np.clip(unknown, 0, 255).astype(np.uint8), where=~backdrop.known)
            if self.backdrop_reach > 0:
                # Edges count near the figure: within reach of a pixel that
                # differs from the known backdrop, or where it is not known.
                found = np.where(backdrop.known, near, 0) > self.foreground_low
                keep = _grow(found.astype(np.uint8) * np.uint8(255), self.backdrop_reach * scale)
                keep[~backdrop.known] = 255
        fg = cv2.subtract(diff, float(self.foreground_low)).astype(np.float32)
        fg *= np.float32(1.0 / (self.foreground_high - self.foreground_low))
        np.minimum(fg, np.float32(1.0), out=fg)
        return fg, bg, keep, backdrop

    def _backdrop_low(self, counts: NDArray[np.int64]) -> float | None:
        """How far a pixel must differ from the backdrop, from the known pixels' histogram.

        ``foreground_low`` or 2.5 times the known pixels' median difference,
        whichever is larger; None where that reaches ``foreground_high`` or no
        pixel is known (the backdrop is then not used).
        """
        low = self.foreground_low
        total = counts.sum()
        if total:
            median = int(np.searchsorted(np.cumsum(counts), 0.5 * total))
            low = max(low, 2.5 * median)
        return None if low >= self.foreground_high or not total else low

    def _compiled_foreground(
        self, smooth: NDArray[np.uint8], bg: NDArray, backdrop: Backdrop | None, scale: float
    ) -> tuple[NDArray, NDArray, NDArray[np.uint8] | None, Backdrop | None] | None:
        """:meth:`_foreground` after the border's colour, by two kernels; None if they failed.

        The same arrays as the numpy path (``tests/test_kernels.py``): OpenCV
        makes a byte of a float colour or threshold by rounding half to even
        and saturating, and so does this.
        """
        h, w, channels = smooth.shape
        background = np.array([_as_byte(v) for v in bg.tolist()], np.uint8)
        diff = np.empty((h, w), np.uint8)
        near = np.empty((h, w), np.uint8)
        counts = np.empty(256, np.int64)
        with_backdrop = backdrop is not None
        smooth = np.ascontiguousarray(smooth)  # (the kernel reads it flat)
        image = np.ascontiguousarray(backdrop.image) if backdrop is not None else smooth
        known = np.ascontiguousarray(backdrop.known) if backdrop is not None else _NOTHING_KNOWN
        if not _kernels.colour_distances(
            smooth, background, image, known, with_backdrop, diff, near, counts
        ):
            return None
        low = self._backdrop_low(counts) if with_backdrop else None
        if low is None:
            backdrop, with_backdrop = None, False
        shift = 0 if low is None else low - self.foreground_low
        lo, hi = self.foreground_low, self.foreground_high
        # np.clip(...).astype(np.uint8) of the two levels: clipped, then truncated.
        unknown = [int(min(max(v, 0.0), 255.0)) for v in (0.5 * (lo + hi), hi)]
        fg = np.empty((h, w), np.float32)
        found = np.empty((h, w), np.uint8)
        if not _kernels.foreground_map(
            diff, near, known, with_backdrop, _as_byte(shift) if shift > 0 else 0, float(lo),
            unknown[0], unknown[1], _as_byte(lo), np.float32(1.0 / (hi - lo)), fg, found,
        ):  # fmt: skip
            return None
        keep = None
        if backdrop is not None and self.backdrop_reach > 0:
            keep = _grow(found, self.backdrop_reach * scale)
            keep[~backdrop.known] = 255
        return fg, bg, keep, backdrop

    def read_first_frame(
        self, frame: ArrayLike, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FirstFrame:
        """What the model keeps of an episode's first frame, with the given initial pose.

        Returns:
            Each cone's colour (:meth:`cone_colors`) where the model has an
            appearance term, the backdrop (:meth:`read_backdrop`) where it uses
            one, the floor height (:meth:`floor_height`) where it has a floor
            term; ``None`` for what it does not use. They go in
            :class:`GivenBody` for every frame of the episode.
        """
        colors = (
            self.cone_colors(frame, pose, shape, camera) if self.appearance_weight > 0 else None
        )
        backdrop = self.read_backdrop(frame, pose, shape, camera) if self.backdrop else None
        floor = self.floor_height(pose, shape) if self.has_floor_term else None
        return FirstFrame(colors, backdrop, floor)

    @property
    def has_floor_term(self) -> bool:
        """Whether the floor term is on (either of its scales finite)."""
        return math.isfinite(self.floor_below_mm) or math.isfinite(self.floor_above_mm)

    @staticmethod
    def floor_height(pose: ArrayLike, shape: BodyShape) -> float:
        """Height (mm, world z) of the lowest ankle of a pose: the floor term's reference.

        Raises:
            ValueError: If the pose is not a finite ``(25,)`` vector.
        """
        p = np.asarray(pose, dtype=np.float64)
        if p.shape != (N_PARAMS,) or not np.all(np.isfinite(p)):
            raise ValueError(
                f"ObservationModel.floor_height: expected a finite pose of shape (25,), "
                f"got {p.shape}"
            )
        keypoints = forward_kinematics(p, shape)
        return float(keypoints[list(_ANKLES_PUBLIC), 2].min())

    def read_backdrop(
        self, frame: ArrayLike, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> Backdrop:
        """The backdrop of an episode from its first frame and the given initial pose.

        Every pixel outside the pose's silhouette (each cone's projected
        outline and end discs, with the larger semi-axis of its section, grown
        by ``backdrop_margin``) shows the backdrop.

        Args:
            frame: The episode's first frame.
            pose: ``(25,)`` the pose in that frame (``info["initial_pose"]``).
            shape: The subject's shape.
            camera: The camera of that frame.

        Raises:
            ValueError: If the frame is not a uint8 image of the camera's size
                or the pose is not a finite ``(25,)`` vector.
        """
        smooth = self._smoothed(frame, "ObservationModel.read_backdrop")
        h, w, _ = smooth.shape
        if (camera.width, camera.height) != (w, h):
            raise ValueError(
                f"ObservationModel.read_backdrop: frame is {w}x{h} but the camera is "
                f"{camera.width}x{camera.height}"
            )
        p = np.asarray(pose, dtype=np.float64)
        if p.shape != (N_PARAMS,) or not np.all(np.isfinite(p)):
            raise ValueError(
                f"ObservationModel.read_backdrop: expected a finite pose of shape (25,), "
                f"got {p.shape}"
            )
        scale = h / self.reference_height
        geo = cone_geometry(p, shape)
        covered = _grow(
            _silhouette_mask(geo.starts, geo.ends, shape, camera, self.near_mm),
            self.backdrop_margin * scale,
        )
        image = smooth.copy()
        image.setflags(write=False)
        known = covered == 0
        known.setflags(write=False)
        return Backdrop(image, known)

    # -- per pose ----------------------------------------------------------

    @functools.cached_property
    def _coefficients(self) -> NDArray[np.float32]:
        return self.sample_coefficients()

    def sample_coefficients(self) -> NDArray[np.float32]:
        """The ``(2 P, 8)`` matrix that places the P points of a cone.

        Columns multiply the cone's basis ``(sx, sy, ex, ey, ax, ay, bx, by)``:
        its projected start ``s`` and end ``e`` and its outline offsets at each
        end ``a = r_s n``, ``b = r_e n`` (``n`` the unit image normal of the
        axis, ``r`` the projected radii). Rows are the x then the y coordinates
        of the outline points (both sides) followed by the axis points.
        """
        m, k = self.outline_samples, self.axis_samples
        t_out = (np.arange(m) + 0.5) / m
        t_axis = (np.arange(k) + 0.5) / k
        t = np.concatenate([t_out, t_out, t_axis])
        side = np.concatenate([np.ones(m), -np.ones(m), np.zeros(k)])
        p = t.size
        coef = np.zeros((2 * p, 8))
        for axis in range(2):  # x rows then y rows
            rows = slice(axis * p, (axis + 1) * p)
            coef[rows, 0 + axis] = 1.0 - t
            coef[rows, 2 + axis] = t
            coef[rows, 4 + axis] = side * (1.0 - t)
            coef[rows, 6 + axis] = side * t
        return coef.astype(np.float32)

    def log_likelihood(
        self,
        frame: ArrayLike | FrameFeatures,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
    ) -> FloatArray:
        """Log-likelihood of the frame for each of N poses.

        Args:
            frame: The frame (uint8 ``(H, W, C)``) or its :meth:`prepare` output
                (prepare once when scoring several batches on one frame).
            params: ``(N, 25)`` poses (any leading shape ``(..., 25)``).
            shape: The subject's (known) shape.
            camera: The camera that took the frame.

        Returns:
            ``(N,)`` log-likelihoods (up to a constant), float64. Poses with a
            parameter that is not finite, or beyond :data:`POSE_LIMIT` (out
            of reach of the single-precision scorer), get ``-inf``.

        Raises:
            ValueError: If shapes disagree with each other or with the camera.
        """
        return self._evaluate(frame, params, shape, camera, "log_likelihood")

    def log_likelihood_partial(
        self,
        frame: ArrayLike | FrameFeatures,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        groups: Sequence[Sequence[int]],
    ) -> FloatArray:
        """Log-likelihoods of the figure built up one group of cones at a time.

        Column ``g`` is the log-likelihood of the figure made of the cones of
        groups ``0..g`` alone: their edge and foreground terms, and the
        coverage and residual terms measured against those cones only (a
        foreground point no cone of theirs covers costs the truncation, as it
        would with the cone missing); the floor term waits for the whole
        figure. When group ``g``'s cones depend only on parameters the earlier
        groups' do and its own, column ``g`` is a function of those
        parameters: the importance functions of partitioned sampling
        (:class:`~baselines.filtering.PartitionedParticleFilter`). The last
        column is :meth:`log_likelihood` itself.

        Args:
            frame: As :meth:`log_likelihood`.
            params: As :meth:`log_likelihood`.
            shape: As :meth:`log_likelihood`.
            camera: As :meth:`log_likelihood`.
            groups: Cone indices (:data:`~humotion_gym.body.CONE_NAMES`
                order) per group, in the order the figure is built.

        Returns:
            ``(..., len(groups) + 1)`` float64; a pose with a parameter
            that is not finite or beyond :data:`POSE_LIMIT` has ``-inf`` in
            every column.

        Raises:
            ValueError: As :meth:`log_likelihood`, or if a group names a cone
                that does not exist or one an earlier group has.
        """
        seen: set[int] = set()
        masks = np.zeros((len(groups), N_CONES), dtype=bool)
        for g, group in enumerate(groups):
            cones = [int(c) for c in group]
            if any(not 0 <= c < N_CONES for c in cones) or seen & set(cones):
                raise ValueError(
                    f"ObservationModel.log_likelihood_partial: groups[{g}] = {cones}: expected "
                    f"cone indices in 0..{N_CONES - 1}, each in one group"
                )
            seen |= set(cones)
            masks[g, cones] = True
        return self._evaluate(
            frame, params, shape, camera, "log_likelihood_partial", np.cumsum(masks, axis=0) > 0
        )

    def _evaluate(
        self,
        frame: ArrayLike | FrameFeatures,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        caller: str,
        prefixes: NDArray[np.bool_] | None = None,
    ) -> FloatArray:
        """Checks, then scores in chunks; ``prefixes`` ``(G, 10)``: the partial figures."""
        feats = frame if isinstance(frame, FrameFeatures) else self.prepare(frame)
        if (feats.width, feats.height) != (camera.width, camera.height):
            raise ValueError(
                f"ObservationModel.{caller}: frame is {feats.width}x{feats.height} "
                f"but the camera is {camera.width}x{camera.height}"
            )
        p = np.asarray(params)
        if p.ndim < 1 or p.shape[-1] != N_PARAMS:
            raise ValueError(
                f"ObservationModel.{caller}: expected poses of shape (N, 25), got {p.shape}"
            )
        lead = p.shape[:-1]
        flat = p.reshape(-1, N_PARAMS)
        if flat.dtype not in (np.float32, np.float64):
            flat = flat.astype(np.float64)
        width = () if prefixes is None else (prefixes.shape[0] + 1,)
        out = np.empty(flat.shape[:1] + width)
        chunk = _chunk_size(flat.shape[0])
        for lo in range(0, flat.shape[0], chunk):
            out[lo : lo + chunk] = self._score(
                feats, flat[lo : lo + chunk], shape, camera, prefixes
            )
        return out.reshape(lead + width)

    def _score(
        self,
        feats: FrameFeatures,
        params: NDArray,
        shape: BodyShape,
        camera: Camera,
        prefixes: NDArray[np.bool_] | None = None,
    ) -> FloatArray:
        """``(n,)`` log-likelihoods; with ``prefixes``, ``(n, G + 1)``.

        The partial figures' columns: see :meth:`log_likelihood_partial`. A
        pose with a value that is not finite or beyond :data:`POSE_LIMIT`
        gets ``-inf`` (scored as zeros, then overwritten).
        """
        n = params.shape[0]
        work = _scratch(n, self._coefficients.shape[0] // 2)
        # One pass over all values first (a NaN fails it); the rows are looked
        # at only when a value is out of bounds. With the kernels the same
        # pass writes the kinematics' parameter rows; numpy's path makes two
        # reductions here and the kinematics copies the rows.
        inside = _kernels.pose_rows(params, _PARAM_ROWS, work["params"], POSE_LIMIT)
        rows_ready = bool(inside)
        if inside is None:
            inside = not n or bool(-POSE_LIMIT <= params.min() and params.max() <= POSE_LIMIT)
        if inside:
            return self._score_rows(feats, params, shape, camera, prefixes, work, rows_ready)
        finite = (np.abs(params) <= POSE_LIMIT).all(axis=1)
        zeroed = np.where(finite[:, None], params, 0.0)
        out = self._score_rows(feats, zeroed, shape, camera, prefixes, work, False)
        out[~finite] = -np.inf
        return out

    def _score_rows(
        self,
        feats: FrameFeatures,
        params: NDArray,
        shape: BodyShape,
        camera: Camera,
        prefixes: NDArray[np.bool_] | None,
        work: dict[str, NDArray],
        rows_ready: bool,
    ) -> FloatArray:
        """:meth:`_score` of poses within bounds (``rows_ready``: ``work["params"]`` filled)."""
        n = params.shape[0]
        f4 = np.float32
        poses = _batch_kinematics(
            params,
            shape,
            f4,
            want_head_axes=shape.aspect[_HEAD] != 1.0,
            work=work,
            rows_ready=rows_ready,
        )
        basis, outline_map = self._cone_basis(feats, poses, shape, camera, work)
        w2, h2 = feats.width + 2, feats.height + 2
        plane = w2 * h2
        # A cone whose parameters are the same in every pose (the body a task
        # gives) costs the same for all: worked out on the first pose only.
        # The others go in runs of consecutive cones. Every step is per point
        # and the matrix product's columns do not depend on their neighbours,
        # so the costs are those of one pass over all points.
        fixed = _fixed_cones(work["params"]) if n >= _SHARED_MIN_POSES else None
        # The map each cone's axis points read: the foreground map, or a free
        # cone's own colour map. One offset for all where every cone reads the
        # foreground and all are scored in one pass (the whole-body tasks).
        foreground = np.int32(self.orientation_bins * plane)
        axis_map = None
        if fixed is not None or feats.appearance_cones is not None:
            axis_map = np.full(N_CONES, foreground, np.int32)
            if feats.appearance_cones is not None:
                for k, cone in enumerate(feats.appearance_cones.tolist()):
                    axis_map[cone] += (1 + k) * plane
        # Each cone's summed point costs, kept only for the partial figures.
        per_cone = None if prefixes is None else np.empty((N_CONES, n))
        # Each pose's summed costs: whole numbers, so exact in any order.
        total = np.zeros(n)
        if fixed is None:  # every cone moves (or too few poses to pay): one pass
            sums = self._point_costs(
                feats,
                basis.reshape(8, -1),
                None if outline_map is None else outline_map.reshape(-1),
                foreground if axis_map is None else np.repeat(axis_map, n),
                work,
                total,
            )
            if per_cone is not None:
                per_cone[:] = sums.reshape(N_CONES, n)
        else:
            assert axis_map is not None
            for c0, c1 in _runs(np.flatnonzero(~fixed)):
                sums = self._point_costs(
                    feats,
                    basis[:, c0:c1].reshape(8, -1),
                    None if outline_map is None else outline_map[c0:c1].reshape(-1),
                    np.repeat(axis_map[c0:c1], n),
                    work,
                    total,
                )
                if per_cone is not None:
                    per_cone[c0:c1] = sums.reshape(c1 - c0, n)
            cones = np.flatnonzero(fixed)
            sums = self._point_costs(
                feats,
                basis[:, cones, 0],
                None if outline_map is None else outline_map[cones, 0],
                axis_map[cones],
                work,
            )
            if per_cone is not None:
                per_cone[cones] = sums[:, None]
            total += sums.sum(dtype=np.float64)
        has_residual = (
            feats.residual is not None and feats.residual.shape[1] > 0 and self.residual_weight > 0
        )
        has_coverage = (
            feats.coverage is not None and feats.coverage.shape[1] > 0 and self.coverage_weight > 0
        )
        # With partial figures the whole figure is one more row of masks, so
        # the terms that span cones are worked out once for all of them.
        rows = None if prefixes is None else np.vstack([prefixes, np.ones((1, N_CONES), bool)])
        residual = self._residual_cost(feats, basis, n, rows) if has_residual else None
        coverage = self._coverage_cost(feats, basis, n, rows) if has_coverage else None
        if not (has_residual or has_coverage):
            total *= -feats.cost_unit * self.sharpness
        else:
            total *= feats.cost_unit
            for term in (residual, coverage):
                if term is not None:
                    total += term if rows is None else term[:, -1]
            total *= -self.sharpness
        if feats.floor is not None and self.has_floor_term:
            total -= self._floor_cost(poses.keypoints, feats.floor)
        if prefixes is None:
            return total
        assert per_cone is not None
        return self._partial(feats, per_cone, prefixes, residual, coverage, total)

    def _cone_basis(
        self,
        feats: FrameFeatures,
        poses: _BatchPoses,
        shape: BodyShape,
        camera: Camera,
        work: dict[str, NDArray],
    ) -> tuple[NDArray[np.float32], NDArray[np.int32] | None]:
        """Each cone's image basis, and the map offset of its outline's orientation.

        Returns:
            ``basis`` ``(8, 10, N)``: rows (s_u, s_v, e_u, e_v) the projected
            axis ends (padded pixel coordinates, +0.5 so that truncation
            rounds), then ``(a_u, a_v, b_u, b_v)`` the outline's offsets at the
            two ends (the image normal times the projected silhouette radius);
            and ``(10, N)`` each outline's map offset in the cost table (None
            with one orientation bin).
        """
        f4 = np.float32
        n = poses.keypoints.shape[2]
        n_bins = self.orientation_bins
        plane = (feats.width + 2) * (feats.height + 2)
        basis, tmp = work["basis"], work["scratch"]
        rot = camera.rotation.astype(f4)
        cx, cy = camera.principal_point
        # +1.5: one pixel of padding, plus 0.5 so that truncation rounds to
        # nearest; a keypoint behind the camera goes far off the image.
        shift_u, shift_v = f4(cx + 1.5), f4(cy + 1.5)
        radii, axes = self._silhouette_axes(shape, poses)
        outline_map = None
        # The compiled kernel (the `fast` extra): the same steps, bit for bit.
        if _kernels.cone_basis(
            rot, camera.translation.astype(f4), poses.keypoints, f4(self.near_mm),
            f4(camera.focal), shift_u, shift_u + f4(1e7), shift_v, _CONE_START, _CONE_END,
            radii, axes, f4(self.raster_pad_px), n_bins == 4, plane,
            work["camera"].reshape(3, N_KEYPOINTS, n), basis, tmp[:2], tmp[2].view(np.int32),
        ):  # fmt: skip
            nx, ny = tmp[0], tmp[1]
            if n_bins == 4:
                return basis, tmp[2].view(np.int32)
        else:
            # World -> camera for the 15 keypoints of every pose at once.
            cam = work["camera"]
            np.matmul(rot, poses.keypoints.reshape(3, -1), out=cam)
            cam += camera.translation.astype(f4)[:, None]
            z = cam[2]
            behind = z < self.near_mm
            np.maximum(z, f4(self.near_mm), out=z)
            inv = work["inverse_depth"]
            np.divide(f4(camera.focal), z, out=inv)
            uv = cam[:2]
            uv *= inv
            uv[0] += shift_u + behind * f4(1e7)
            uv[1] += shift_v
            uv3 = uv.reshape(2, N_KEYPOINTS, n)
            np.take(uv3, _CONE_START, axis=1, out=basis[0:2])
            np.take(uv3, _CONE_END, axis=1, out=basis[2:4])
            dx, dy, norm, rad = tmp
            np.subtract(basis[2], basis[0], out=dx)
            np.subtract(basis[3], basis[1], out=dy)
            np.multiply(dx, dx, out=norm)
            norm += dy * dy
            norm += f4(1e-12)
            np.sqrt(norm, out=norm)
            np.divide(f4(1.0), norm, out=norm)
            # Unit normal n = (dy, -dx) / |d| of each projected axis (its sign
            # does not matter: the outline is sampled on both sides).
            nx, ny = dy, dx
            nx *= norm
            ny *= norm
            ny *= f4(-1.0)
            inv3 = inv.reshape(N_KEYPOINTS, n)
            varying = [
                (cone, _silhouette_factor(rot, ax, ay, aspect, nx[cone], ny[cone]))
                for cone, ax, ay, aspect in axes
            ]
            for k, end_index in enumerate((_CONE_START, _CONE_END)):
                np.take(inv3, end_index, axis=0, out=rad)
                rad *= radii[:, k : k + 1]
                for cone, factor in varying:
                    rad[cone] *= factor
                if self.raster_pad_px:
                    rad += f4(self.raster_pad_px)  # the renderer's fill (see raster_pad_px)
                np.multiply(rad, nx, out=basis[4 + 2 * k])
                np.multiply(rad, ny, out=basis[5 + 2 * k])
        if n_bins > 1:  # each cone's outline reads the map of its orientation
            outline_map = _orientation_bin(nx, ny, n_bins, tmp[2])
            outline_map *= plane
        return basis, outline_map

    def _partial(
        self,
        feats: FrameFeatures,
        per_cone: FloatArray,
        prefixes: NDArray[np.bool_],
        residual: FloatArray | None,
        coverage: FloatArray | None,
        total: FloatArray,
    ) -> FloatArray:
        """``(n, G + 1)``: the partial figures' log-likelihoods, then the whole's (``total``).

        ``residual`` and ``coverage`` are ``(n, G + 1)`` (the last column the
        whole figure's) or None where the term does not apply.
        """
        # (G, n): the cone terms of each partial figure.
        cones = prefixes.astype(np.float64) @ per_cone
        cones *= feats.cost_unit
        for term in (residual, coverage):
            if term is not None:
                cones += term[:, :-1].T
        cones *= -self.sharpness
        return np.column_stack([cones.T, total])

    def _floor_cost(self, keypoints: NDArray, floor: float) -> FloatArray:
        """The floor term (nats) of ``(3, 15, N)`` internal-order world keypoints."""
        lowest = np.minimum(keypoints[2, _ANKLES[0]], keypoints[2, _ANKLES[1]])
        height = lowest.astype(np.float64) - floor
        below = np.minimum(height, 0.0) / self.floor_below_mm
        above = np.maximum(height, 0.0) / self.floor_above_mm
        return 0.5 * (below * below + above * above)

    def _point_costs(
        self,
        feats: FrameFeatures,
        columns: NDArray,
        outline_map: NDArray | None,
        axis_map: NDArray | np.int32,
        work: dict[str, NDArray],
        total: FloatArray | None = None,
    ) -> NDArray[np.uint16]:
        """Summed point costs of cone outlines given by their ``(8, K)`` bases.

        Args:
            feats: The frame's features.
            columns: ``(8, K)`` one cone of one pose per column (the rows of
                ``basis``).
            outline_map: ``(K,)`` offset in the cost table of the map each
                column's outline points read (its orientation's), or None with
                one orientation bin.
            axis_map: ``(K,)`` offset of the map its axis points read (one
                number when the same for all).
            work: The scratch buffers (at least ``K`` columns).
            total: Optional ``(n,)`` float64 that each pose's sums are added
                into, the columns being ``K / n`` runs of ``n`` poses (one
                cone each).

        Returns:
            ``(K,)`` the sum of each column's point costs, in ``cost_unit``.
        """
        f4 = np.float32
        coef = self._coefficients
        n_points = coef.shape[0] // 2
        cols = columns.shape[1]
        w2, h2 = feats.width + 2, feats.height + 2
        n_out = 2 * self.outline_samples
        # The compiled kernel (the `fast` extra) does the same steps in one
        # pass, bit for bit; None where it does not run.
        sums = _kernels.point_costs(
            coef, columns, outline_map, axis_map, feats.cost, w2, h2, n_out, total
        )
        if sums is not None:
            return sums
        points = work["points"][: 2 * n_points * cols].reshape(2 * n_points, cols)
        np.matmul(coef, columns, out=points)
        np.clip(points[:n_points], 0.0, f4(w2 - 1), out=points[:n_points])
        np.clip(points[n_points:], 0.0, f4(h2 - 1), out=points[n_points:])
        index = work["index"][: 2 * n_points * cols].reshape(2 * n_points, cols)
        np.copyto(index, points, casting="unsafe")  # truncation: +0.5 was added
        ix, iy = index[:n_points], index[n_points:]
        iy *= w2
        iy += ix
        iy[n_out:] += axis_map
        if outline_map is not None:
            iy[:n_out] += outline_map
        values = work["values"][: n_points * cols].reshape(n_points, cols)
        np.take(feats.cost, iy, out=values)
        sums = values.sum(axis=0, dtype=np.uint16)
        if total is not None:
            total += sums.reshape(-1, total.size).sum(axis=0, dtype=np.float64)
        return sums

    def _residual_cost(
        self,
        feats: FrameFeatures,
        basis: NDArray,
        n: int,
        prefixes: NDArray[np.bool_] | None = None,
    ) -> FloatArray:
        """Mean truncated squared distance of the residual points to the free outlines.

        Every residual point reads its distance to the nearest outline segment
        (two per free cone, ``s +- a`` to ``e +- b``) of each pose: an
        ``(N, segments, E)`` computation, in chunks of poses. With ``prefixes``
        (``(G, 10)`` cone masks) ``(N, G)``: the nearest segment of each
        partial figure's free cones.
        """
        f4 = np.float32
        assert feats.residual is not None and feats.residual_cones is not None
        cones = feats.residual_cones
        b = basis[:, cones, :]  # (8, C, n)
        s_x, s_y, e_x, e_y, a_x, a_y, b_x, b_y = b
        # Segment starts and directions, (2C, n) each.
        p_x = np.concatenate([s_x + a_x, s_x - a_x])
        p_y = np.concatenate([s_y + a_y, s_y - a_y])
        d_x = np.concatenate([e_x + b_x, e_x - b_x]) - p_x
        d_y = np.concatenate([e_y + b_y, e_y - b_y]) - p_y
        inv_len2 = f4(1.0) / (d_x * d_x + d_y * d_y + f4(1e-6))
        q_x, q_y = feats.residual[0], feats.residual[1]
        scale = feats.height / self.reference_height
        tau = f4(self.residual_truncation * scale)
        unit = self.residual_weight / (2.0 * (self.edge_sigma * scale) ** 2 * q_x.size)
        # The compiled kernel (the `fast` extra): the whole figure's sums, bit for bit.
        sums = None
        if prefixes is None:
            sums = _kernels.residual_sums(p_x, p_y, d_x, d_y, inv_len2, q_x, q_y, tau * tau)
        if sums is not None:
            sums *= unit
            return sums
        # One column per figure: the whole one, or each partial figure's
        # segments (a cone's two outline segments are rows c and C + c).
        masks = None if prefixes is None else np.tile(prefixes[:, cones], 2)
        out = np.empty((n, 1 if prefixes is None else prefixes.shape[0]))
        segments, e = p_x.shape[0], q_x.size
        chunk = max(1, 200_000 // max(1, segments * e))
        # Four (2C, chunk, E) buffers reused by every chunk: the arithmetic of
        # the straightforward version without its temporaries.
        buffers = np.empty((4, segments * min(chunk, n) * e), f4)
        tau2 = tau * tau
        for lo in range(0, n, chunk):
            sl = slice(lo, lo + chunk)
            m = min(chunk, n - lo)
            rx, ry, t, tmp = (buf[: segments * m * e].reshape(segments, m, e) for buf in buffers)
            dx, dy = d_x[:, sl, None], d_y[:, sl, None]
            np.subtract(q_x, p_x[:, sl, None], out=rx)  # (2C, m, E)
            np.subtract(q_y, p_y[:, sl, None], out=ry)
            np.multiply(rx, dx, out=t)
            t += np.multiply(ry, dy, out=tmp)
            t *= inv_len2[:, sl, None]
            np.clip(t, f4(0.0), f4(1.0), out=t)
            rx -= np.multiply(t, dx, out=tmp)
            ry -= np.multiply(t, dy, out=t)
            rx *= rx
            ry *= ry
            rx += ry
            for g, dist2 in enumerate(_nearest(rx, masks, tau2, out=tmp[0])):  # (m, E) each
                np.minimum(dist2, tau2, out=dist2)
                out[sl, g] = dist2.sum(axis=1, dtype=np.float64)
        out *= unit
        return out[:, 0] if prefixes is None else out

    def _coverage_cost(
        self,
        feats: FrameFeatures,
        basis: NDArray,
        n: int,
        prefixes: NDArray[np.bool_] | None = None,
    ) -> FloatArray:
        """Mean truncated squared distance of the coverage points outside the free cones.

        With ``prefixes`` (``(G, 10)`` cone masks) ``(N, G)``: outside each
        partial figure's free cones.

        A cone's projection is taken as its projected axis segment widened by
        the projected radius, interpolated linearly along the axis, with the
        end radii as round caps in the box sense: a point's distance outside
        it is ``max(|p| - r, |a - L/2| - L/2 - r)``, ``p`` its signed distance
        across the axis, ``a`` its position along it from the start, ``L``
        the axis' length and ``r`` the radius at its foot on the axis. ``p``,
        ``a - L/2``, ``r`` and ``L/2 + r`` are linear in the point, so one
        matrix product gives all four for every (cone, pose, point) and three
        passes finish the distance; each point reads the nearest cone of each
        pose. Beyond the ends the radius is extrapolated (by the cone's taper
        over a few pixels: a fraction of a pixel). Chunks of poses keep the
        scratch in cache.
        """
        f4 = np.float32
        assert feats.coverage is not None and feats.coverage_cones is not None
        q = np.vstack([feats.coverage, np.ones((1, feats.coverage.shape[1]), f4)])  # (3, F)
        scale = feats.height / self.reference_height
        tau = f4(self.coverage_truncation * scale)
        e = q.shape[1]
        unit = self.coverage_weight / (2.0 * (self.edge_sigma * scale) ** 2 * e)
        # The compiled kernel (the `fast` extra): the whole figure's sums, bit for bit.
        sums = None
        if prefixes is None:
            sums = _kernels.coverage_sums(basis, feats.coverage_cones, q, tau)
        if sums is not None:
            sums *= unit
            return sums
        b = basis[:, feats.coverage_cones, :]  # (8, C, n)
        s_x, s_y, e_x, e_y, a_x, a_y, b_x, b_y = b
        r_s = np.sqrt(a_x * a_x + a_y * a_y)
        r_e = np.sqrt(b_x * b_x + b_y * b_y)
        d_x, d_y = e_x - s_x, e_y - s_y
        length = np.sqrt(d_x * d_x + d_y * d_y)
        # A cone seen end-on has no axis direction: any will do (x).
        flat = length < f4(1e-3)
        safe = np.maximum(length, f4(1e-3))
        u_x = np.where(flat, f4(1.0), d_x / safe)
        u_y = np.where(flat, f4(0.0), d_y / safe)
        half = f4(0.5) * length
        slope = (r_e - r_s) / safe
        cones = s_x.shape[0]
        # Rows (quantity, cone, pose) of coefficients of (x, y, 1):
        # along - L/2 = q.u - s.u - L/2; across = q.n - s.n with n = (-u_y, u_x);
        # r = r_s + slope (q.u - s.u); L/2 + r.
        coef = np.empty((4, cones, n, 3), f4)
        s_u = s_x * u_x + s_y * u_y
        coef[0, ..., 0], coef[0, ..., 1], coef[0, ..., 2] = u_x, u_y, -s_u - half
        coef[1, ..., 0], coef[1, ..., 1] = -u_y, u_x
        coef[1, ..., 2] = s_x * u_y - s_y * u_x
        coef[2, ..., 0], coef[2, ..., 1] = slope * u_x, slope * u_y
        coef[2, ..., 2] = r_s - slope * s_u
        coef[3, ..., :2] = coef[2, ..., :2]
        coef[3, ..., 2] = coef[2, ..., 2] + half
        masks = None if prefixes is None else prefixes[:, feats.coverage_cones]
        out = np.empty((n, 1 if prefixes is None else prefixes.shape[0]))
        chunk = max(1, 32_768 // max(1, cones * e))
        lin = np.empty(4 * cones * min(chunk, n) * e, f4)
        for lo in range(0, n, chunk):
            m = min(chunk, n - lo)
            rows = coef[:, :, lo : lo + m].reshape(-1, 3)
            work = lin[: 4 * cones * m * e].reshape(4 * cones * m, e)
            np.matmul(rows, q, out=work)
            along, across, radius, reach = work.reshape(4, cones, m, e)
            np.abs(across, out=across)
            across -= radius
            np.abs(along, out=along)
            along -= reach
            np.maximum(across, along, out=across)
            for g, outside in enumerate(_nearest(across, masks, tau)):  # (m, F) each
                np.clip(outside, f4(0.0), tau, out=outside)
                outside *= outside
                out[lo : lo + m, g] = outside.sum(axis=1, dtype=np.float64)
        out *= unit
        return out[:, 0] if prefixes is None else out

    def _silhouette_axes(
        self, shape: BodyShape, poses: _BatchPoses
    ) -> tuple[NDArray[np.float32], list[tuple[int, tuple, tuple, float]]]:
        """Silhouette half-widths (in mm at unit depth scale) of the cones.

        For an elliptical cross-section with semi-axes ``r`` (cone x) and
        ``aspect * r`` (cone y), the silhouette's half-width along the image
        normal ``m`` is ``r * sqrt((x.m)^2 + (aspect y.m)^2)`` (orthographic
        approximation; :func:`_silhouette_factor`). Worked out per pose for the
        torso and the head, whose frames the batched kinematics provides; limbs
        (round in the default shape) use the mean of their two semi-axes.

        Returns:
            ``(10, 2)`` float32 radii at the cones' two ends and a list of
            ``(cone, x axis, y axis, aspect)`` for the cones whose width
            varies (each axis three ``(N,)`` components), whose radii are to
            be multiplied by their factor.
        """
        aspect = shape.aspect
        radii = shape.radii * ((1.0 + aspect[:, None]) / 2.0)
        varying: list[tuple[int, tuple, tuple, float]] = []
        for cone, ax, ay in (
            (_TORSO, poses.torso_x, poses.torso_y),
            (_HEAD, poses.head_x, poses.head_y),
        ):
            if aspect[cone] == 1.0 or ax is None or ay is None:
                continue
            radii[cone] = shape.radii[cone]
            varying.append((cone, ax, ay, float(aspect[cone])))
        return radii.astype(np.float32), varying


def task_model(task: TaskSpec) -> ObservationModel:
    """The likelihood a task's baselines use: the defaults with the task's overrides.

    Args:
        task: The task; its ``observation`` pairs override
            :class:`ObservationModel`'s defaults (chosen on training persons).
    """
    return ObservationModel(**dict(task.observation))


def _silhouette_factor(
    rot: NDArray[np.float32], ax: tuple, ay: tuple, aspect: float, m0: NDArray, m1: NDArray
) -> NDArray[np.float32]:
    """``(N,)`` ``sqrt((x.m)^2 + (aspect y.m)^2)`` (see ``_silhouette_axes``).

    ``rot`` the camera's float32 rotation, ``ax``, ``ay`` the cone's x and y
    axes in the world, ``(m0, m1)`` its image normal.
    """
    f4 = np.float32
    # x.m and y.m with the axes taken to the camera frame (rows 0, 1).
    xm = (rot[0, 0] * ax[0] + rot[0, 1] * ax[1] + rot[0, 2] * ax[2]) * m0
    xm += (rot[1, 0] * ax[0] + rot[1, 1] * ax[1] + rot[1, 2] * ax[2]) * m1
    ym = (rot[0, 0] * ay[0] + rot[0, 1] * ay[1] + rot[0, 2] * ay[2]) * m0
    ym += (rot[1, 0] * ay[0] + rot[1, 1] * ay[1] + rot[1, 2] * ay[2]) * m1
    ym *= f4(aspect)
    xm *= xm
    ym *= ym
    xm += ym
    return np.sqrt(xm, out=xm)


def _nearest(
    values: NDArray, masks: NDArray[np.bool_] | None, missing: Any, out: NDArray | None = None
) -> list[NDArray]:
    """Per mask of rows, the minimum over those rows of ``(K, ...)`` values (``missing`` if none).

    The figures' nearest cone (or outline segment) of a point: with ``masks``
    None, the whole figure's (one minimum over every row, into ``out`` when
    given); per partial figure otherwise, where a figure without any of the
    cones leaves every point at the truncation.
    """
    if masks is None:
        return [np.min(values, axis=0, out=out)]
    return [
        values[rows].min(axis=0) if rows.any() else np.full(values.shape[1:], missing, values.dtype)
        for rows in masks
    ]


def _spread_points(mask: NDArray[np.bool_], most: int) -> NDArray[np.float32]:
    """At most ``most`` of ``mask``'s set pixels, evenly spread: ``(2, F)`` x then y (+1.5).

    The pixels ``np.nonzero(mask)`` gives, in its order, thinned to
    ``np.linspace(0, n - 1, most)``'s picks where there are more; 1.5 is the
    offset ``_score`` gives image coordinates. Through flat indices: a 2-D
    ``np.nonzero``, ``np.linspace`` and a stack took 46 us a 128x128 frame,
    this 13 (the same points; ``tests/test_backdrop.py``).
    """
    flat = np.flatnonzero(mask)
    if flat.size > most:
        flat = flat[_evenly_spread(flat.size, most)]
    points = np.empty((2, flat.size), np.float32)
    np.divmod(flat, mask.shape[1], out=(points[1], points[0]))  # y, then x
    points += np.float32(1.5)
    return points


def _evenly_spread(n: int, m: int) -> NDArray[np.intp]:
    """``np.linspace(0, n - 1, m).astype(np.intp)`` for ``n > m >= 1``: the same indices.

    Written out as numpy's ``linspace`` computes it (``arange(m)`` times the
    step ``(n - 1) / (m - 1)``, the last set to ``n - 1``), without its 15 us
    of argument handling; ``tests/test_backdrop.py`` compares the two.
    """
    if m == 1:
        return np.zeros(1, np.intp)
    spread = np.arange(m, dtype=np.float64)
    spread *= (n - 1) / (m - 1)
    spread[-1] = n - 1
    return spread.astype(np.intp)


def _grow(mask: NDArray[np.uint8], radius: float) -> NDArray[np.uint8]:
    """``mask`` dilated by a disc of ``radius`` pixels (rounded up; none below 1e-9)."""
    r = int(math.ceil(radius - 1e-9))
    if r <= 0:
        return mask
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(mask, kernel)


#: The foreground kernels' ``known`` where there is no backdrop (they do not read it).
_NOTHING_KNOWN = np.zeros((1, 1), np.bool_)


def _as_byte(value: float) -> int:
    """The byte OpenCV makes of a float scalar: rounded half to even, saturated to [0, 255]."""
    return min(max(round(value), 0), 255)  # (Python's round is half to even, as np.rint)


def _channel_max(diff: NDArray[np.uint8], h: int, w: int, channels: int) -> NDArray[np.uint8]:
    """``(H, W)`` the largest channel of a ``(H, W, C)`` absolute difference."""
    diff = diff.reshape(h, w, channels)
    if channels == 3:
        d0, d1, d2 = cv2.split(diff)
        return cv2.max(cv2.max(d0, d1), d2)
    return np.ascontiguousarray(diff[:, :, 0])


def _projected_cones(
    starts: FloatArray, ends: FloatArray, radii: FloatArray, camera: Camera
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Each cone's image geometry from its 3D ends ``(C, 3)`` and end radii ``(C, 2)``.

    Returns:
        The projected start and end ``(C, 2)``, the nearer end's depth ``(C,)``,
        the projected radii at the start and the end ``(C,)`` and the unit image
        normal of the projected axis ``(C, 2)``. Cones with an end behind the
        camera get meaningless values: callers test the depth first.
    """
    uv_s, uv_e = camera.project(starts), camera.project(ends)
    z_s, z_e = camera.to_camera(starts)[:, 2], camera.to_camera(ends)[:, 2]
    d = uv_e - uv_s
    with np.errstate(divide="ignore", invalid="ignore"):
        r_s = camera.focal * radii[:, 0] / z_s
        r_e = camera.focal * radii[:, 1] / z_e
        normal = (
            np.stack([d[:, 1], -d[:, 0]], axis=1) / (np.hypot(d[:, 0], d[:, 1]) + 1e-9)[:, None]
        )
    return uv_s, uv_e, np.minimum(z_s, z_e), r_s, r_e, normal


def _silhouette_mask(
    starts: FloatArray,
    ends: FloatArray,
    shape: BodyShape,
    camera: Camera,
    near_mm: float,
    cones: NDArray[np.intp] | None = None,
) -> NDArray[np.uint8]:
    """``(H, W)`` uint8, 255 on the projected silhouette of one pose (conservative).

    ``starts`` and ``ends`` are the pose's cone ends ``(10, 3)``
    (:func:`~humotion_gym.body.cone_geometry`). Each cone (of ``cones``, every
    cone when None) is the convex quadrilateral of its two outline lines, with
    the larger semi-axis of its section, plus filled discs at its ends; a cone
    with an end nearer the camera than ``near_mm`` covers the whole image (its
    projection is unbounded).
    """
    mask = np.zeros((camera.height, camera.width), np.uint8)
    radii = shape.radii * np.maximum(1.0, shape.aspect)[:, None]
    uv_s, uv_e, z, r_s, r_e, normal = _projected_cones(starts, ends, radii, camera)
    for c in range(N_CONES) if cones is None else cones.tolist():
        if z[c] < near_mm:
            mask[:] = 255
            return mask
        n = normal[c]
        quad = np.stack(
            [uv_s[c] + r_s[c] * n, uv_e[c] + r_e[c] * n, uv_e[c] - r_e[c] * n, uv_s[c] - r_s[c] * n]
        )
        # Far outside the image the int32 corners would overflow: clip first.
        quad = np.clip(quad, -4 * camera.width, 5 * camera.width)
        cv2.fillConvexPoly(mask, np.rint(quad).astype(np.int32), 255)
        for centre, r in ((uv_s[c], r_s[c]), (uv_e[c], r_e[c])):
            centre = np.clip(centre, -4 * camera.width, 5 * camera.width)
            cv2.circle(mask, tuple(np.rint(centre).astype(int).tolist()),
                       int(math.ceil(min(r, 10 * camera.width))), 255, -1)  # fmt: skip
    return mask


def _orientation_bin(nx: NDArray, ny: NDArray, n_bins: int, scratch: NDArray) -> NDArray:
    """Orientation bin of unit normals, ``(10, N)`` int32.

    Bin ``b`` is centred on the normal angle ``b pi / B`` (modulo pi). Works on
    the doubled angle ``(nx^2 - ny^2, 2 nx ny)``, which is the same for ``n`` and
    ``-n``; with four bins, by comparisons only.
    """
    c2 = np.multiply(nx, nx, out=scratch)
    c2 -= ny * ny
    s2 = nx * ny
    if n_bins == 4:
        # Doubled-angle bins at 0, 90, 180, 270 degrees: pick the dominant axis.
        horizontal = np.abs(c2) >= np.abs(s2)
        out = np.where(horizontal, c2 < 0, s2 < 0).astype(np.int32)
        out *= 2
        out += ~horizontal
        return out
    phi = np.arctan2(s2, c2 * np.float32(0.5))  # 2 phi in (-pi, pi]
    phi *= np.float32(n_bins / (2.0 * np.pi))
    np.rint(phi, out=phi)
    out = phi.astype(np.int32)
    out %= n_bins
    return out


@functools.cache
def _cone_parameters() -> NDArray[np.bool_]:
    """``(10, 25)`` True where a parameter moves a cone (its ends or its axes).

    Found by moving each parameter of a generic pose in turn; the kinematic
    tree, not the shape, decides it. A cone's cost depends only on its ends
    and axes, so a cone none of whose parameters differ between poses costs
    the same in all of them.
    """
    shape = default_shape()
    pose = np.full(N_PARAMS, 0.3)
    pose[:3] = (100.0, 200.0, 900.0)
    probes = np.repeat(pose[None], N_PARAMS + 1, axis=0)
    probes[np.arange(1, N_PARAMS + 1), np.arange(N_PARAMS)] += 0.25
    geo = cone_geometry(probes, shape)
    where = np.concatenate(
        [geo.starts, geo.ends, geo.rotations.reshape(N_PARAMS + 1, N_CONES, 9)], axis=2
    )
    return (where[1:] != where[0]).any(axis=2).T


def _fixed_cones(rows: NDArray) -> NDArray[np.bool_] | None:
    """``(10,)`` True for the cones that every pose places the same; None for none.

    Args:
        rows: ``(25, N)`` the poses' parameters as the kinematics reads them
            (single precision, in ``_PARAM_ROWS`` order).

    Every cone hangs from the root (rows 0-5): when the first two poses' roots
    differ (the whole-body tasks), no cone is fixed, which is known without a
    pass over N. Otherwise each parameter's row is compared bit for bit with
    its first value (so ``-0.0`` and ``0.0`` differ).
    """
    if rows.shape[1] >= 2 and rows[0, 0] != rows[0, 1]:
        # The first two poses' root x differ (nearly always, on the whole-body
        # tasks): known from two numbers, where the bit test below reads six
        # rows of a buffer the previous scoring pushed out of cache (1.5 us in
        # cache, 15 out of it).
        return None
    bits = rows.view(np.uint32 if rows.dtype.itemsize == 4 else np.uint64)
    if bits.shape[1] < 2 or (bits[:6, 1] != bits[:6, 0]).any():
        return None
    same = np.empty(N_PARAMS, bool)
    same[_PARAM_ROWS] = (bits == bits[:, :1]).all(axis=1)
    fixed = ~_cone_parameters()[:, ~same].any(axis=1)
    return fixed if fixed.any() else None


# The parameter in each row of the kinematics' parameter rows
# (_batch_kinematics: root and neck, then the four limbs' x, y, z and hinge
# angles, each group in the order r_shoulder, l_shoulder, r_hip, l_hip).
_PARAM_ROWS = np.array(
    list(range(9)) + [9 + angle + 4 * limb for angle in range(4) for limb in range(4)],
    dtype=np.intp,
)


def _runs(cones: NDArray[np.intp]) -> list[tuple[int, int]]:
    """Ranges ``[c0, c1)`` of consecutive cones covering ``cones``."""
    runs: list[tuple[int, int]] = []
    for cone in cones.tolist():
        if runs and runs[-1][1] == cone:
            runs[-1] = (runs[-1][0], cone + 1)
        else:
            runs.append((cone, cone + 1))
    return runs
