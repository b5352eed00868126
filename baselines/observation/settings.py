"""The observation model's settings: one frozen dataclass, checked on creation.

The image features (:mod:`.features`) and the terms that score poses
(:mod:`.terms`) read them; :class:`~baselines.observation.ObservationModel`
adds the methods that compose those.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from baselines.observation.geometry import sample_weights
from humotion_gym.checks import check_count, is_real

#: The largest length setting (reference px, px or mm): a million is beyond
#: any frame or scene.
MAX_LENGTH = 1e6

#: The smallest scale setting (``edge_sigma``, reference px; the floor's, mm):
#: far finer than any edge or motion capture, it bounds the squared cost
#: ratios (``(MAX_LENGTH / MIN_SCALE)^2``) within the single-precision scorer.
MIN_SCALE = 1e-3

#: The largest weight of a term or of the whole log-likelihood: it keeps a
#: weight times the largest cost (see :data:`MIN_SCALE`) within single precision.
MAX_WEIGHT = 1e6

#: The largest ``edge_blur`` (image pixels): already flattens a figure in any
#: frame, and OpenCV's kernel (about 6 sigma + 1 taps) grows without end.
MAX_EDGE_BLUR = 100.0

#: The largest ``outline_samples`` and ``axis_samples``: a thousand points on a
#: limb is finer than a pixel on any frame, and time grows linearly with them.
MAX_SAMPLES = 1000

#: The largest ``orientation_bins``: one-degree bins, finer than the Sobel
#: gradient's orientation; each bin costs one distance transform per frame.
MAX_ORIENTATION_BINS = 180

#: The largest of the other counts (pixels, points): a million is beyond any frame.
MAX_COUNT = 1_000_000


@dataclass(frozen=True)
class ObservationSettings:
    """The settings of the observation model (:class:`~baselines.observation.ObservationModel`).

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

    Each setting is checked on creation (:func:`check_settings`): anything out
    of range raises a ValueError naming the setting.

    Attributes:
        edge_sigma: Standard deviation (reference px, default 1.5) of the
            distance between a model outline point and the image edge it
            explains: the pixel quantisation of edges and of the cone outline
            plus the blur. It sets the likelihood's sharpness (see above).
        edge_truncation: Distance (reference px, default 3.0) beyond which an
            outline point costs no more (the chamfer cost's robust truncation:
            an outline point with no edge costs a bounded amount).
        foreground_weight: Weight (default 0.5) of the foreground term, the
            cost per cone of its axis lying wholly on background: it holds a
            pose on the figure where edges are missing, below the edges' range
            (the border colour model counts clutter as foreground).
        foreground_low: Colour distance (grey levels, default 25) from the
            background colour below which a pixel counts as background; above
            the renderer's default noise (sigma 4) after ``edge_blur``.
        foreground_high: Colour distance (grey levels, default 70) above which a
            pixel counts as certain foreground; between the two the probability
            rises linearly.
        border_width: Width in pixels (default 2) of the frame border whose
            median colour estimates the background colour.
        canny_low: Lower hysteresis threshold of ``cv2.Canny`` (default 40).
        canny_high: Upper hysteresis threshold of ``cv2.Canny`` (default 100):
            well above the gradient of the renderer's noise after ``edge_blur``,
            below the contrast of the figure's colours against a mid-grey wall.
        edge_blur: Gaussian sigma in pixels (default 0.8) of the blur applied
            before edge detection and foreground estimation, to suppress sensor
            noise; 0 turns it off.
        outline_samples: Points per silhouette line of each cone (default 5, at
            the centres of equal parts of the cone's length).
        axis_samples: Points along each cone's projected axis for the foreground
            term (default 3).
        reference_height: Image height (default 128) whose pixels are the unit
            of ``edge_sigma`` and ``edge_truncation``.
        near_mm: Keypoints closer to the camera plane than this (default 10 mm),
            or behind it, are treated as outside the image.
        orientation_bins: Number of edge orientation bins (default 4: 0, 45, 90
            and 135 degrees; every edge pixel counts for its two nearest bins,
            so an outline matches edges within 45 degrees of its own
            orientation). 1 gives plain (unoriented) chamfer matching.
        sharpness: Multiplier of the whole log-likelihood (an inverse
            temperature; default 1). Per-cone costs are means over the cone's
            points, so the default treats each cone, not each point, as one
            observation. A task may set its own (ArmTrack's is 3,
            :mod:`humotion_gym.envs.tasks`); ``docs/priors.md`` gives the
            temperature's selection runs.
        residual_weight: Weight (default 0: off) of the *residual-edge* term,
            the image-to-model direction of the chamfer cost, where a task
            gives part of the body (:class:`GivenBody`): the edge pixels the
            given cones leave unexplained near the free cones cost
            ``min(d, residual_truncation)^2 / (2 sigma^2)`` each, ``d`` their
            distance to a free cone's outline, averaged. It asks that a limb
            explain the edges only it can, not lie along any edge there.
        residual_truncation: Distance (reference px, default 6) beyond which a
            residual point costs no more.
        residual_points: At most this many residual points per frame (default
            128, an evenly strided subset in raster order: deterministic).
        residual_clearance: Half-width (reference px, default 2) of the band
            around the given cones' outlines whose edges count as explained.
        appearance_weight: Weight (default 0: off) of the *appearance* term,
            where a task gives part of the body and the cones' colours were
            read at the first frame (``GivenBody.colors``): each free cone's
            axis points cost up to this weight per cone where the pixel's
            colour differs from the cone's (rising linearly from
            ``appearance_low`` to ``appearance_high``).
        appearance_low: Colour difference (default 20) below which a pixel
            matches the cone's colour.
        appearance_high: Colour difference (default 60) above which it does
            not match at all.
        backdrop: Whether to use the backdrop read at the first frame
            (default False; :class:`Backdrop`, in ``GivenBody.backdrop``).
            Where it is known, a pixel's foreground probability comes from its
            colour distance to the backdrop's pixel (clutter is backdrop), and
            edges farther than ``backdrop_reach`` from any foreground pixel
            are dropped; elsewhere the border rule and every edge remain. The
            threshold rises with the sensor noise of the known pixels
            (:func:`~baselines.observation.features.backdrop_low`).
        backdrop_margin: Reference pixels (default 2) the initial pose's
            silhouette is grown by before the rest counts as known backdrop:
            the blur and the cones' rounded ends spill past their outline.
        backdrop_reach: Reference pixels (default 3) around the foreground
            within which edges are kept; 0 keeps every edge.
        coverage_weight: Weight (default 0: off) of the *coverage* term, the
            image-to-model direction of the foreground cue (as Deutscher,
            Blake & Reid's silhouette cue and Sidenbladh & Black's foreground
            likelihood). It needs the backdrop: the pixels that differ clearly
            from it and that the given cones do not cover cost
            ``min(d, coverage_truncation)^2 / (2 sigma^2)`` each, ``d`` their
            distance outside the nearest free cone, averaged; so both legs
            cannot share one leg's pixels.
        coverage_truncation: Distance (reference px, default 4) beyond which
            a coverage point costs no more.
        coverage_points: At most this many coverage points per frame
            (default 96, an evenly strided subset in raster order).
        floor_below_mm: Scale (mm; default ``inf``: off) of the *floor term*'s
            cost for a pose whose lowest ankle is below the height it had in
            the episode's given first pose (``GivenBody.floor``): ``d`` mm below
            costs ``(d / floor_below_mm)^2 / 2`` nats. The scene's cue, not the
            image's: the image barely shows depth, while sliding a figure along
            its camera ray moves it up or down. Off on every task (numbers in
            ``humotion_gym/envs/tasks.py``). Added after ``sharpness``.
        floor_above_mm: Scale (mm; default ``inf``: off) of the floor term's
            cost for a lowest ankle *above* that height (a person jumps, so it
            is looser than ``floor_below_mm`` where used).
        raster_pad_px: Image pixels (not reference pixels; default 0) added to
            every cone's projected half-width: ``cv2.fillConvexPoly`` paints
            every pixel a cone's outline passes through, about half a pixel
            beyond its exact projection (``tests/test_raster_pad.py``), so a
            model without it prefers the figure nearer the camera. Off: it
            tracked no better (numbers in ``humotion_gym/envs/tasks.py``).
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
        check_settings(self)

    @property
    def has_floor_term(self) -> bool:
        """Whether the floor term is on (either of its scales finite)."""
        return math.isfinite(self.floor_below_mm) or math.isfinite(self.floor_above_mm)

    @functools.cached_property
    def sample_weights(self) -> NDArray[np.float32]:
        """``(P, 4)`` each sample point's weights of a cone's ``s``, ``e``, ``a``, ``b``.

        The outline points first (both sides), then the axis points
        (:func:`~baselines.observation.geometry.sample_weights`).
        """
        weights = sample_weights(self.outline_samples, self.axis_samples)
        weights.setflags(write=False)
        return weights


def _ordered(low_name: str, high_name: str, settings: ObservationSettings, strict: bool) -> None:
    """Refuse a pair of thresholds unless ``low < high`` (``<=`` unless ``strict``)."""
    low, high = getattr(settings, low_name), getattr(settings, high_name)
    if (low >= high) if strict else (low > high):
        sign = "<" if strict else "<="
        raise ValueError(
            f"ObservationModel: expected {low_name} {sign} {high_name}, got {low!r} and {high!r}"
        )


#: Each number's range, checked in this order: ``(names, low, high, what,
#: positive)``, ``positive`` refusing ``low`` itself.
_RANGES: tuple[tuple[tuple[str, ...], float, float, str, bool], ...] = (
    (
        ("edge_truncation", "near_mm", "residual_truncation", "coverage_truncation"),
        0.0, MAX_LENGTH, f"a positive length up to {MAX_LENGTH:g}", True,
    ),
    (("edge_sigma",), MIN_SCALE, MAX_LENGTH, f"a length in [{MIN_SCALE:g}, {MAX_LENGTH:g}]", False),
    (
        ("residual_clearance", "backdrop_margin", "backdrop_reach", "raster_pad_px"),
        0.0, MAX_LENGTH, f"a length in [0, {MAX_LENGTH:g}]", False,
    ),
    (
        ("edge_blur",), 0.0, MAX_EDGE_BLUR, f"a blur sigma in [0, {MAX_EDGE_BLUR:g}] pixels",
        False,
    ),
    (
        ("foreground_weight", "residual_weight", "appearance_weight", "coverage_weight"),
        0.0, MAX_WEIGHT, f"a weight in [0, {MAX_WEIGHT:g}]", False,
    ),
    (("sharpness",), 0.0, MAX_WEIGHT, f"a weight in (0, {MAX_WEIGHT:g}]", True),
    (
        ("floor_below_mm", "floor_above_mm"), MIN_SCALE, math.inf,
        f"a scale >= {MIN_SCALE:g} mm (inf: off)", False,
    ),
    (
        (
            "foreground_low", "foreground_high", "canny_low", "canny_high", "appearance_low",
            "appearance_high",
        ),
        0.0, MAX_LENGTH, f"a number of grey levels in [0, {MAX_LENGTH:g}]", False,
    ),
)  # fmt: skip


def check_settings(settings: ObservationSettings) -> None:
    """Refuse any setting out of its range, naming it and what was expected.

    Every number must be a real number (not a bool, not a string), finite
    except the floor's scales (``inf``: off), and within the bounds above, so
    that no setting can hang the model, overflow its single-precision scorer
    or make it fail deep inside OpenCV.

    Raises:
        ValueError: Naming the setting.
    """
    for names, low, high, what, positive in _RANGES:
        for name in names:
            value = getattr(settings, name)
            # NaN fails every comparison; a bool or a string fails is_real
            if not (is_real(value) and low <= value <= high and (value > low or not positive)):
                raise ValueError(f"ObservationModel.{name}: expected {what}, got {value!r}")
    _ordered("foreground_low", "foreground_high", settings, strict=True)
    _ordered("appearance_low", "appearance_high", settings, strict=True)
    _ordered("canny_low", "canny_high", settings, strict=False)
    if not settings.canny_low > 0:
        raise ValueError(
            f"ObservationModel.canny_low: expected a number of grey levels in "
            f"(0, {MAX_LENGTH:g}], got {settings.canny_low!r}"
        )
    if not isinstance(settings.backdrop, (bool, np.bool_)):
        raise ValueError(f"ObservationModel.backdrop: expected a bool, got {settings.backdrop!r}")
    for name, most in (
        ("outline_samples", MAX_SAMPLES),
        ("axis_samples", MAX_SAMPLES),
        ("orientation_bins", MAX_ORIENTATION_BINS),
        ("border_width", MAX_COUNT),
        ("reference_height", MAX_COUNT),
        ("residual_points", MAX_COUNT),
        ("coverage_points", MAX_COUNT),
    ):
        check_count(f"ObservationModel.{name}", getattr(settings, name), most=most)
