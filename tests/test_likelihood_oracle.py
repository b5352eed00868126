"""The likelihood against slow, plainly written oracles.

The oracle scores one pose at a time in double precision, a loop over the
cones: project each cone's ends (the reference kinematics,
:func:`humotion_gym.body.cone_geometry`), sample its outline and axis, look
each point up in the frame's distance and foreground maps, and sum the
model's formula; the residual and coverage terms loop over their points and
the cones. The frame's features are checked against the OpenCV calls they
are defined by.

Tolerances. The model keeps each point's cost as a byte (the nearest multiple
of ``cost_unit``, 1/255 of the largest per-point cost), so a pose's point
costs differ from the oracle's by at most half a unit per point. It places
the points in single precision (about 1e-5 px from the double-precision
oracle on a 128-pixel frame), so a point within that of a pixel boundary may
read the neighbouring pixel: such poses are rare, and at most 2% of them may
differ by more than the quantisation bound. The residual and coverage terms
are single-precision sums of squared distances: relative 1e-3.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from baselines.observation import FrameFeatures, GivenBody, ObservationModel, features, geometry
from baselines.observation.features import mark_bins, strongest_gradients
from humotion_gym import body
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.render import SceneOptions, make_background, render

SHAPE = body.default_shape()
ARM = np.array([9, 10, 11, 12])  # right shoulder and elbow: the arm task's free parameters


# -- the oracles ------------------------------------------------------------------


def project(model: ObservationModel, camera: Camera, point: np.ndarray) -> tuple:
    """Image ``(u, v)`` and inverse depth of a world point (off the image when too near)."""
    x, y, z = camera.to_camera(point[None])[0]
    behind = z < model.near_mm
    inv = camera.focal / max(z, model.near_mm)
    cx, cy = camera.principal_point
    return x * inv + cx + (1e7 if behind else 0.0), y * inv + cy, inv


def cone_outlines(model: ObservationModel, pose: np.ndarray, camera: Camera) -> list:
    """Per cone: image ends ``s``, ``e``, offsets ``a``, ``b`` and its unit normal."""
    geo = body.cone_geometry(pose, SHAPE)
    cones = []
    for c in range(body.N_CONES):
        u_s, v_s, inv_s = project(model, camera, geo.starts[c])
        u_e, v_e, inv_e = project(model, camera, geo.ends[c])
        d = np.array([u_e - u_s, v_e - v_s])
        normal = np.array([d[1], -d[0]]) / math.sqrt(d @ d + 1e-12)
        aspect = SHAPE.aspect[c]
        if aspect == 1.0:
            width, radii = 1.0, SHAPE.radii[c]
        else:  # an elliptical section: r sqrt((x.m)^2 + (aspect y.m)^2), orthographic
            rows = camera.rotation[:2]
            x_m = (rows @ geo.rotations[c][:, 0]) @ normal
            y_m = (rows @ geo.rotations[c][:, 1]) @ normal
            width, radii = math.hypot(x_m, aspect * y_m), SHAPE.radii[c]
        r_s = inv_s * radii[0] * width + model.raster_pad_px
        r_e = inv_e * radii[1] * width + model.raster_pad_px
        cones.append((np.array([u_s, v_s]), np.array([u_e, v_e]), r_s * normal, r_e * normal))
    return cones


def lookup(image: np.ndarray, point: np.ndarray, outside: float) -> float:
    """The pixel nearest ``point`` (image coordinates), or ``outside`` off the image."""
    x, y = math.floor(point[0] + 0.5), math.floor(point[1] + 0.5)
    h, w = image.shape[:2]
    return float(image[y, x]) if 0 <= x < w and 0 <= y < h else outside


def outline_bin(normal: np.ndarray, n_bins: int) -> int:
    """The bin whose centre ``b pi / B`` is nearest the normal's angle (modulo pi)."""
    theta = math.atan2(normal[1], normal[0]) % math.pi
    return round(theta * n_bins / math.pi) % n_bins


def oracle_point_costs(
    model: ObservationModel,
    feats: FrameFeatures,
    pose: np.ndarray,
    camera: Camera,
    smooth: np.ndarray,
    colors: dict[int, np.ndarray],
) -> np.ndarray:
    """``(10,)`` each cone's summed point costs (nats), one point at a time."""
    m, k = model.outline_samples, model.axis_samples
    tau, sigma = model.edge_truncation, model.edge_sigma
    costs = np.zeros(body.N_CONES)
    for c, (s, e, a, b) in enumerate(cone_outlines(model, pose, camera)):
        distance = feats.distance[
            outline_bin(a / (np.linalg.norm(a) + 1e-30), model.orientation_bins)
        ]
        for side in (1.0, -1.0):
            for i in range(m):
                t = (i + 0.5) / m
                point = (1 - t) * (s + side * a) + t * (e + side * b)
                d = lookup(distance, point, tau)
                costs[c] += min(d, tau) ** 2 / (2 * sigma**2) / (2 * m)
        for i in range(k):
            t = (i + 0.5) / k
            point = (1 - t) * s + t * e
            if c in colors:  # the appearance term replaces the foreground term
                diff = np.abs(smooth.astype(np.float64) - colors[c]).max(axis=2)
                span = model.appearance_high - model.appearance_low
                mismatch = np.clip((diff - model.appearance_low) / span, 0.0, 1.0)
                costs[c] += model.appearance_weight / k * lookup(mismatch, point, 1.0)
            else:
                fg = lookup(feats.foreground, point, 0.0)
                costs[c] += model.foreground_weight / k * (1.0 - fg)
    return costs


def segment_distance(q: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> float:
    d = p1 - p0
    t = min(max(((q - p0) @ d) / (d @ d + 1e-6), 0.0), 1.0)
    return float(np.linalg.norm(q - p0 - t * d))


def oracle_residual(model, feats, outlines, cones) -> float:
    """The residual-edge term (nats) of one figure: its free cones ``cones``."""
    scale = feats.height / model.reference_height
    tau = model.residual_truncation * scale
    total = 0.0
    for q in feats.residual.T - 1.5:
        d = tau
        for c in cones:
            s, e, a, b = outlines[c]
            d = min(d, segment_distance(q, s + a, e + b), segment_distance(q, s - a, e - b))
        total += d * d
    n = feats.residual.shape[1]
    return model.residual_weight * total / (2 * (model.edge_sigma * scale) ** 2 * n)


def oracle_coverage(model, feats, outlines, cones) -> float:
    """The coverage term (nats) of one figure: its free cones ``cones``."""
    scale = feats.height / model.reference_height
    tau = model.coverage_truncation * scale
    total = 0.0
    for q in feats.coverage.T - 1.5:
        d = tau
        for c in cones:
            s, e, a, b = outlines[c]
            r_s, r_e = np.linalg.norm(a), np.linalg.norm(b)
            length = np.linalg.norm(e - s)
            u = (e - s) / length if length >= 1e-3 else np.array([1.0, 0.0])
            along = (q - s) @ u
            across = abs((q - s) @ np.array([-u[1], u[0]]))
            radius = r_s + (r_e - r_s) / max(length, 1e-3) * along
            outside = max(across - radius, abs(along - length / 2) - length / 2 - radius)
            d = min(d, max(outside, 0.0))
        total += d * d
    n = feats.coverage.shape[1]
    return model.coverage_weight * total / (2 * (model.edge_sigma * scale) ** 2 * n)


def oracle_log_likelihood(model, feats, pose, camera, smooth, colors=None, cones=None) -> float:
    """The log-likelihood of one pose, or of the figure of ``cones`` alone."""
    cones = list(range(body.N_CONES)) if cones is None else list(cones)
    colors = colors or {}
    costs = oracle_point_costs(model, feats, pose, camera, smooth, colors)[cones].sum()
    outlines = cone_outlines(model, pose, camera)
    if feats.residual is not None and feats.residual.shape[1] and model.residual_weight > 0:
        free = [c for c in feats.residual_cones.tolist() if c in cones]
        costs += oracle_residual(model, feats, outlines, free)
    if feats.coverage is not None and feats.coverage.shape[1] and model.coverage_weight > 0:
        free = [c for c in feats.coverage_cones.tolist() if c in cones]
        costs += oracle_coverage(model, feats, outlines, free)
    return -model.sharpness * costs


def quantisation_bound(model: ObservationModel, feats: FrameFeatures) -> float:
    """Half a table unit per point: the most a pose's byte costs differ from the exact ones."""
    points = body.N_CONES * (2 * model.outline_samples + model.axis_samples)
    return model.sharpness * points * feats.cost_unit / 2 + 1e-9


# -- the scenes -------------------------------------------------------------------


def scene(seed: int, size: int = 128, shift_mm: float = 0.0):
    """A frame of a random pose, a first frame where the figure stood ``shift_mm`` aside, poses."""
    rng = np.random.default_rng(seed)
    truth = body.standing_pose(SHAPE)
    truth[3] = rng.uniform(-np.pi, np.pi)
    truth[6:] += rng.normal(0.0, 0.3, 19)
    truth = np.clip(truth, body.PARAM_LOWER, body.PARAM_UPPER)
    options = SceneOptions(width=size, height=size)
    camera = fit_camera(body.forward_kinematics(truth, SHAPE)[None], size, size, 50.0, 30.0, 10.0)
    background = make_background(options, rng)
    start = truth.copy()
    start[0] -= shift_mm
    first = render(start, SHAPE, camera, options, rng, background)
    frame = render(truth, SHAPE, camera, options, rng, background)
    # 140 poses: whole blocks of the scorer's passes (64 and 128 poses) and partial ones.
    poses = truth + rng.normal(0.0, 0.1, (140, body.N_PARAMS))
    poses[:, :3] = truth[:3] + rng.normal(0.0, 60.0, (140, 3))
    return start, camera, first, frame, poses


def check_against_oracle(model, frame, camera, poses, given=None, colors=None) -> None:
    feats = model.prepare(frame, given)
    got = model.log_likelihood(feats, poses, SHAPE, camera)
    smooth = cv2.GaussianBlur(frame, (0, 0), model.edge_blur)
    want = np.array([oracle_log_likelihood(model, feats, p, camera, smooth, colors) for p in poses])
    off = np.abs(got - want) > quantisation_bound(model, feats) + 1e-3 * np.abs(want)
    assert off.mean() <= 0.02, (np.flatnonzero(off), got[off], want[off])


# -- the likelihood ---------------------------------------------------------------


@pytest.mark.parametrize("seed, size", [(0, 128), (1, 96)])
def test_log_likelihood_is_the_oracles(seed: int, size: int) -> None:
    _, camera, _, frame, poses = scene(seed, size)
    check_against_oracle(ObservationModel(), frame, camera, poses)


@pytest.mark.parametrize("bins, pad", [(1, 0.0), (8, 0.5)])
def test_other_settings_are_the_oracles(bins: int, pad: float) -> None:
    _, camera, _, frame, poses = scene(2)
    model = ObservationModel(orientation_bins=bins, raster_pad_px=pad, outline_samples=4)
    check_against_oracle(model, frame, camera, poses)


def test_whole_body_task_terms_are_the_oracles() -> None:
    model, camera, frame, poses, given = whole_body_case()
    coverage = model.prepare(frame, given).coverage
    assert coverage is not None and coverage.shape[1] >= 20
    check_against_oracle(model, frame, camera, poses, given)


def arm_case():
    truth, camera, first, frame, _ = scene(4)
    rng = np.random.default_rng(5)
    poses = np.tile(truth, (60, 1))
    poses[:, ARM] += rng.normal(0.0, 0.3, (60, ARM.size))
    model = ObservationModel(
        sharpness=3.0, foreground_weight=0.0, orientation_bins=8, residual_weight=1.0,
        appearance_weight=1.0, backdrop=True, coverage_weight=2.0,
    )  # fmt: skip
    kept = model.read_first_frame(first, truth, SHAPE, camera)
    given = GivenBody(truth, ARM, SHAPE, camera, kept.colors, kept.backdrop)
    return model, camera, frame, poses, given


def test_arm_task_terms_are_the_oracles() -> None:
    model, camera, frame, poses, given = arm_case()
    feats = model.prepare(frame, given)
    assert feats.residual is not None and feats.residual.shape[1] > 0
    assert feats.appearance_cones is not None and feats.appearance_cones.size
    colors = {int(c): given.colors[c] for c in feats.appearance_cones}
    check_against_oracle(model, frame, camera, poses, given, colors)


def test_partial_figures_are_the_oracles() -> None:
    model, camera, frame, poses, given = arm_case()
    feats = model.prepare(frame, given)
    groups = [[0, 1], [2, 4], [3, 5, 6, 7, 8, 9]]
    got = model.log_likelihood_partial(feats, poses[:20], SHAPE, camera, groups)
    smooth = cv2.GaussianBlur(frame, (0, 0), model.edge_blur)
    colors = {int(c): given.colors[c] for c in feats.appearance_cones}
    np.testing.assert_array_equal(
        got[:, -1], model.log_likelihood(feats, poses[:20], SHAPE, camera)
    )
    for g in range(len(groups)):
        cones = [c for group in groups[: g + 1] for c in group]
        want = [
            oracle_log_likelihood(model, feats, p, camera, smooth, colors, cones)
            for p in poses[:20]
        ]
        off = np.abs(got[:, g] - want) > quantisation_bound(model, feats) + 1e-3 * np.abs(want)
        assert off.mean() <= 0.05, (g, got[off, g], np.array(want)[off])


def test_the_oracle_check_catches_a_wrong_orientation() -> None:
    # A mutation: outlines reading the map of the bin next to theirs.
    _, camera, _, frame, poses = scene(0)
    model = ObservationModel()
    feats = model.prepare(frame)
    turned = FrameFeatures(**{**feats.__dict__, "distance": np.roll(feats.distance, 1, axis=0)})
    smooth = cv2.GaussianBlur(frame, (0, 0), model.edge_blur)
    got = model.log_likelihood(feats, poses, SHAPE, camera)
    want = np.array([oracle_log_likelihood(model, turned, p, camera, smooth) for p in poses])
    assert (np.abs(got - want) > quantisation_bound(model, feats)).mean() > 0.5


def whole_body_case(size: int = 128, residual_weight: float = 0.0):
    start, camera, first, frame, poses = scene(3, size, shift_mm=300.0)
    model = ObservationModel(
        backdrop=True, coverage_weight=4.0, coverage_points=32, residual_weight=residual_weight
    )
    given = GivenBody(
        start, np.arange(body.N_PARAMS), SHAPE, camera,
        backdrop=model.read_backdrop(first, start, SHAPE, camera),
    )  # fmt: skip
    return model, camera, frame, poses, given


def test_partial_whole_body_figures_at_another_size_are_the_oracles() -> None:
    # A 96-pixel frame rescales the truncations; each partial figure's coverage
    # and residual terms measure its own cones only.
    model, camera, frame, poses, given = whole_body_case(96, residual_weight=1.0)
    feats = model.prepare(frame, given)
    assert feats.coverage is not None and feats.coverage.shape[1] >= 20
    assert feats.residual is not None and feats.residual.shape[1] >= 20
    groups = [[0, 1], [2, 4], [3, 5, 6, 7, 8, 9]]
    got = model.log_likelihood_partial(feats, poses[:10], SHAPE, camera, groups)
    smooth = cv2.GaussianBlur(frame, (0, 0), model.edge_blur)
    for g in range(len(groups)):
        cones = [c for group in groups[: g + 1] for c in group]
        want = np.array(
            [
                oracle_log_likelihood(model, feats, p, camera, smooth, None, cones)
                for p in poses[:10]
            ]
        )
        off = np.abs(got[:, g] - want) > quantisation_bound(model, feats) + 1e-3 * np.abs(want)
        assert off.sum() <= 1, (g, got[off, g], want[off])  # one pose may read a pixel apart


@pytest.mark.parametrize("terms", ["plain", "whole body"])
def test_scores_are_deterministic_and_do_not_depend_on_the_split(terms: str) -> None:
    model, camera, frame, poses, given = whole_body_case()
    if terms == "plain":
        model, given = ObservationModel(), None
    feats = model.prepare(frame, given)
    many = np.repeat(poses, 30, axis=0)  # 4,200 poses: two passes
    many += np.random.default_rng(8).normal(0.0, 0.01, many.shape)
    whole = model.log_likelihood(feats, many, SHAPE, camera)
    assert np.unique(whole).size > 1000
    np.testing.assert_array_equal(whole, model.log_likelihood(feats, many, SHAPE, camera))
    parts = [model.log_likelihood(feats, part, SHAPE, camera) for part in np.split(many, [1, 1500])]
    np.testing.assert_array_equal(whole, np.concatenate(parts))


def test_cone_parameters_follow_the_kinematic_tree() -> None:
    moves = geometry.cone_parameters()
    names = body.CONE_NAMES
    assert moves[:, :6].all()  # the root moves every cone
    assert moves.sum(axis=0)[6:9].tolist() == [1, 1, 1]  # the neck only the head
    assert moves[names.index("head"), 6:9].all()
    elbow = body.PARAM_NAMES.index("r_elbow")
    assert np.flatnonzero(moves[:, elbow]).tolist() == [names.index("r_forearm")]


def test_shared_cones_are_scored_as_the_rest() -> None:
    # Many poses that differ only in the arm: the given cones are scored once.
    model, camera, frame, poses, given = arm_case()
    many = np.repeat(poses, 20, axis=0)  # 1,200 poses
    feats = model.prepare(frame, given)
    together = model.log_likelihood(feats, many, SHAPE, camera)
    alone = np.concatenate([model.log_likelihood(feats, p[None], SHAPE, camera) for p in poses])
    np.testing.assert_array_equal(together, np.repeat(alone, 20))


# -- the frame's features against OpenCV -----------------------------------------


@pytest.mark.parametrize("seed, size, bins", [(0, 128, 4), (7, 96, 4), (4, 128, 8)])
def test_features_are_opencvs(seed: int, size: int, bins: int) -> None:
    _, _, _, frame, _ = scene(seed, size)
    model = ObservationModel(orientation_bins=bins)
    feats = model.prepare(frame)
    smooth = cv2.GaussianBlur(frame, (0, 0), model.edge_blur)
    edges = cv2.Canny(smooth, model.canny_low, model.canny_high)
    np.testing.assert_array_equal(feats.edges, edges)
    # Each edge pixel in the two bins nearest its strongest channel's gradient
    # (the angle in single precision, as the gradients: a pixel on a bin's
    # boundary goes where the model's float32 arithmetic puts it).
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
    scale = size / model.reference_height
    n_bins = model.orientation_bins
    bins = np.full((n_bins, size, size), 255, np.uint8)
    pixels = list(zip(*np.nonzero(edges), strict=True))
    strongest = [int(np.argmax(gx[y, x] ** 2 + gy[y, x] ** 2)) for y, x in pixels]
    theta = np.arctan2(
        np.array([gy[y, x, c] for (y, x), c in zip(pixels, strongest, strict=True)]),
        np.array([gx[y, x, c] for (y, x), c in zip(pixels, strongest, strict=True)]),
    )
    assert theta.dtype == np.float32
    for (y, x), angle in zip(pixels, np.mod(theta, np.pi) * (n_bins / np.pi), strict=True):
        lo = math.floor(angle) % n_bins
        bins[lo, y, x] = bins[(lo + 1) % n_bins, y, x] = 0
    for b in range(n_bins):
        want = cv2.distanceTransform(bins[b], cv2.DIST_L2, cv2.DIST_MASK_5) / np.float32(scale)
        np.testing.assert_allclose(
            feats.distance[b], np.minimum(want, model.edge_truncation), rtol=1e-6
        )
    # Foreground: the colour distance to the border's median colour, ramped.
    border = np.concatenate([smooth[:2].reshape(-1, 3), smooth[-2:].reshape(-1, 3),
                             smooth[2:-2, :2].reshape(-1, 3), smooth[2:-2, -2:].reshape(-1, 3)])  # fmt: skip
    background = np.median(border, axis=0)
    diff = np.abs(smooth.astype(np.float64) - np.rint(background)).max(axis=2)
    span = model.foreground_high - model.foreground_low
    fg = np.clip((diff - model.foreground_low) / span, 0.0, 1.0)
    np.testing.assert_allclose(feats.foreground, fg, atol=1e-6)
    # The cost table: each map's exact cost, to half a unit.
    w2, h2 = size + 2, size + 2
    table = feats.cost.reshape(n_bins + 1, h2, w2) * feats.cost_unit
    sigma, tau, m = model.edge_sigma, model.edge_truncation, 2 * model.outline_samples
    for b in range(n_bins):
        exact = np.full((h2, w2), tau**2 / (2 * sigma**2 * m))
        exact[1:-1, 1:-1] = feats.distance[b] ** 2 / (2 * sigma**2 * m)
        assert np.abs(table[b] - exact).max() <= feats.cost_unit / 2 + 1e-7
    exact = np.full((h2, w2), model.foreground_weight / model.axis_samples)
    exact[1:-1, 1:-1] = (1 - feats.foreground) * model.foreground_weight / model.axis_samples
    assert np.abs(table[n_bins] - exact).max() <= feats.cost_unit / 2 + 1e-7


def _clustered_bins(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A one-bin map of a few edge pixels in a cluster somewhere in a frame, and its edges."""
    h, w = (int(v) for v in rng.integers(12, 90, 2))
    bins = np.full((1, h, w), 255, np.uint8)
    k = int(rng.integers(1, 15))
    cx, cy = rng.integers(0, w), rng.integers(0, h)
    xs = np.clip(cx + rng.integers(-10, 11, k), 0, w - 1)
    ys = np.clip(cy + rng.integers(-10, 11, k), 0, h - 1)
    bins[0, ys, xs] = 0
    return bins, np.where(bins[0] == 0, 255, 0).astype(np.uint8)


@pytest.mark.parametrize("scale", [0.5, 0.75, 1.0, 2.0])
def test_cropped_distances_are_opencvs_up_to_the_truncation(scale: float) -> None:
    # The distance transform runs on the edges' box widened by the truncation's
    # reach: truncated, exactly OpenCV's transform of the whole map; a reach
    # two pixels short gives other distances (the check can fail).
    rng = np.random.default_rng(int(scale * 4))
    tau = np.float32(3.0)
    reach = math.floor(3.0 * scale) + 1
    short = 0
    for _ in range(400):
        bins, edges = _clustered_bins(rng)
        whole = cv2.distanceTransform(bins[0], cv2.DIST_L2, cv2.DIST_MASK_5)
        want = np.minimum(whole / np.float32(scale), tau)
        got, _ = features.edge_distances(bins, np.array([True]), edges, reach)
        np.testing.assert_array_equal(np.minimum(got[0] / np.float32(scale), tau), want)
        got, _ = features.edge_distances(bins, np.array([True]), edges, math.ceil(3.0 * scale) - 2)
        short += not np.array_equal(np.minimum(got[0] / np.float32(scale), tau), want)
    assert short > 0
    empty, _ = features.edge_distances(bins, np.array([False]), edges, reach)
    assert np.isinf(empty).all()


def test_backdrop_task_distances_are_opencvs() -> None:
    # With a backdrop the edges lie near the figure and the transform is
    # cropped; the features' distances are still OpenCV's on the whole map.
    model, _, frame, _, given = whole_body_case()
    assert given.backdrop is not None
    smooth = features.smoothed(frame, model.edge_blur, "test")
    _, _, keep, _ = features.foreground(model, smooth, given.backdrop)
    edges, bins, found = features.oriented_edges(
        smooth, model.canny_low, model.canny_high, model.orientation_bins, keep
    )
    x, y, w, h = cv2.boundingRect(edges)
    assert 0 < (w + 8) * (h + 8) < 128 * 128 * 0.6  # the crop leaves much of the frame
    feats = model.prepare(frame, given)
    for b in np.flatnonzero(found):
        whole = cv2.distanceTransform(bins[b], cv2.DIST_L2, cv2.DIST_MASK_5)
        np.testing.assert_array_equal(
            feats.distance[b], np.minimum(whole, np.float32(model.edge_truncation))
        )


def test_strongest_gradients_and_bins_follow_their_definitions() -> None:
    # Per pixel: the first channel of largest dx^2 + dy^2, and the pixel zeroed
    # in bins floor(t) mod B and the next. Integers and floor: exact equality.
    rng = np.random.default_rng(11)
    h, w, channels, n_bins = 9, 7, 3, 4
    dx = rng.integers(-1020, 1021, (h, w, channels)).astype(np.int16)
    dy = rng.integers(-1020, 1021, (h, w, channels)).astype(np.int16)
    dx[0, 0], dy[0, 0] = (3, 4, 0), (4, 3, 5)  # a tie of three: the first wins, as np.argmax
    ys, xs = np.nonzero(rng.random((h, w)) < 0.5)
    ys, xs = np.r_[0, ys].astype(np.int32), np.r_[0, xs].astype(np.int32)
    gx, gy = strongest_gradients(dx, dy, xs, ys)
    for i, (y, x) in enumerate(zip(ys, xs, strict=True)):
        strength = [int(dx[y, x, c]) ** 2 + int(dy[y, x, c]) ** 2 for c in range(channels)]
        best = strength.index(max(strength))
        assert (gx[i], gy[i]) == (dx[y, x, best], dy[y, x, best])
    turns = rng.uniform(0.0, n_bins, ys.size).astype(np.float32)
    turns[:2] = [0.0, n_bins]  # both ends of the range
    bins = np.full((n_bins, h, w), 255, np.uint8)
    held = mark_bins(turns, xs, ys, bins)
    want = np.full_like(bins, 255)
    for t, y, x in zip(turns, ys, xs, strict=True):
        lo = math.floor(t) % n_bins
        want[lo, y, x] = want[(lo + 1) % n_bins, y, x] = 0
    assert np.array_equal(bins, want)
    assert np.array_equal(held, (want == 0).any(axis=(1, 2)))


def _boxes_frame(rng: np.random.Generator, inside: bool) -> np.ndarray:
    """A blurred 64x80 colour frame of six boxes: all inside, or some cut by the border."""
    img = np.full((64, 80, 3), 90, np.uint8)
    for _ in range(6):
        x0 = int(rng.integers(8, 40) if inside else rng.integers(-20, 70))
        y0 = int(rng.integers(8, 26) if inside else rng.integers(-20, 56))
        size = (int(rng.integers(8, 30)), int(rng.integers(8, 30)))
        color = tuple(int(c) for c in rng.integers(0, 256, 3))
        cv2.rectangle(img, (x0, y0), (x0 + size[0], y0 + size[1]), color, -1)
    return cv2.GaussianBlur(img, (0, 0), 1.0)


def _orientation_bins(
    smooth: np.ndarray, edges: np.ndarray, n_bins: int, border: int
) -> np.ndarray:
    """Per edge pixel, its Sobel gradient's orientation bins, one pixel at a time."""
    h, w, c = smooth.shape
    dx = cv2.Sobel(smooth, cv2.CV_16S, 1, 0, ksize=3, borderType=border).reshape(h, w, c)
    dy = cv2.Sobel(smooth, cv2.CV_16S, 0, 1, ksize=3, borderType=border).reshape(h, w, c)
    bins = np.full((n_bins, h, w), 255, np.uint8)
    for y, x in zip(*np.nonzero(edges), strict=True):
        strength = [int(dx[y, x, k]) ** 2 + int(dy[y, x, k]) ** 2 for k in range(c)]
        k = strength.index(max(strength))
        theta = np.arctan2(np.float32(dy[y, x, k]), np.float32(dx[y, x, k]))
        lo = math.floor(np.mod(theta, np.float32(np.pi)) * np.float32(n_bins / np.pi)) % n_bins
        bins[lo, y, x] = bins[(lo + 1) % n_bins, y, x] = 0
    return bins


def test_orientation_bins_read_the_default_border_gradient() -> None:
    # Each edge pixel's bins come from the strongest channel's Sobel gradient
    # with OpenCV's default (reflected) border, whether or not an edge lies on
    # the image's outermost pixels, where Canny's replicated border differs. The
    # replicated gradient's bins differ on some frames (the check can fail).
    rng = np.random.default_rng(12)
    on_border = differs = 0
    for inside in [True] * 10 + [False] * 10:
        smooth = _boxes_frame(rng, inside)
        edges, bins, found = features.oriented_edges(smooth, 20.0, 60.0, 4)
        ys, xs = np.nonzero(edges)
        touches = bool(np.any((xs == 0) | (ys == 0) | (xs == 79) | (ys == 63)))
        assert touches != inside
        on_border += touches
        want = _orientation_bins(smooth, edges, 4, cv2.BORDER_REFLECT_101)
        assert np.array_equal(bins, want)
        assert np.array_equal(found, (want == 0).any(axis=(1, 2)))
        replicated = _orientation_bins(smooth, edges, 4, cv2.BORDER_REPLICATE)
        differs += not np.array_equal(replicated, want)
    assert on_border == 10 and differs > 0


@pytest.mark.parametrize("box", [(0, 5, 0, 6), (1, 4, 2, 5), (0, 0, 0, 0)])
def test_edge_foreground_bytes_follow_their_definition(box: tuple[int, int, int, int]) -> None:
    # Per entry of the padded maps, in float32 scalars and the formula's order:
    # the same roundings, so equal bytes (and the distances truncated in place).
    # Outside the box the distances are inf (edge_distances'), costs the truncation's.
    rng = np.random.default_rng(12)
    n_bins, h, w = 2, 5, 6
    dist = np.full((n_bins, h, w), np.inf, np.float32)
    y0, y1, x0, x1 = box
    dist[0, y0:y1, x0:x1] = rng.uniform(0.0, 30.0, (y1 - y0, x1 - x0))
    fg = rng.uniform(0.0, 1.0, (h, w)).astype(np.float32)
    f32 = np.float32
    s, tau, e, e_out, f, f_out, inv_u = map(f32, (0.5, 8.0, 0.3, 19.2, 2.5, 2.5, 10.0))
    maps = np.empty((n_bins + 1, h + 2, w + 2), np.uint8)
    truncated = dist.copy()
    features.edge_foreground_bytes(truncated, box, fg, s, tau, e, e_out, f, f_out, inv_u, maps)
    for m in range(n_bins + 1):
        for y in range(h + 2):
            for x in range(w + 2):
                inside = 0 < y <= h and 0 < x <= w
                if m < n_bins and inside:
                    d = min(dist[m, y - 1, x - 1] * s, tau)
                    assert truncated[m, y - 1, x - 1] == d
                    v = d * d * e * inv_u
                elif m < n_bins:
                    v = e_out * inv_u
                elif inside:
                    v = (f32(1.0) - fg[y - 1, x - 1]) * f * inv_u
                else:
                    v = f_out * inv_u
                assert maps[m, y, x] == np.uint8(np.rint(v))


@pytest.mark.parametrize("channels", [1, 3])
def test_appearance_bytes_follow_their_definition(channels: int) -> None:
    # Per entry of the padded maps, in float32 scalars and the kernel's order:
    # the same roundings, so equal bytes. Colours on the grid of bytes and
    # between, differences below, inside and above the ramp.
    rng = np.random.default_rng(13)
    h, w = 5, 6
    smooth = rng.integers(0, 256, (h, w, channels)).astype(np.uint8)
    colors = rng.uniform(0.0, 255.0, (3, channels)).astype(np.float32)
    colors[0] = smooth[2, 3]  # a pixel that matches exactly: cost 0
    f32 = np.float32
    low, span, a, inv_u = map(f32, (20.0, 1.0 / 60.0, 0.4, 600.0))
    maps = np.empty((3, h + 2, w + 2), np.uint8)
    features.appearance_bytes(smooth, colors, low, span, a, inv_u, maps)
    assert maps[0, 3, 4] == 0
    for k in range(3):
        for y in range(h + 2):
            for x in range(w + 2):
                if 0 < y <= h and 0 < x <= w:
                    pixel = smooth[y - 1, x - 1].astype(np.float32)
                    m = max(abs(pixel[c] - colors[k, c]) for c in range(channels))
                    v = min(max((m - low) * span, f32(0.0)), f32(1.0)) * a * inv_u
                else:
                    v = a * inv_u
                assert maps[k, y, x] == np.uint8(np.rint(v))
    assert len(set(maps[1:, 1:-1, 1:-1].ravel().tolist())) > 2  # the ramp is exercised
