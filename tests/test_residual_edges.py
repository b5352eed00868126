"""Tests of the residual-edge term (the image-to-model chamfer on what the given body leaves)."""

from __future__ import annotations

import numpy as np
import pytest

from baselines.observation import GivenBody, ObservationModel, geometry
from humotion_gym import body
from humotion_gym.camera import fit_camera
from humotion_gym.render import SceneOptions, make_background, render

SHAPE = body.default_shape()
ARM = np.arange(9, 13)  # r_shoulder_x, _y, _z, r_elbow
FLAT = SceneOptions(background="flat", noise_sigma=0.0)


def arm_pose(rng: np.random.Generator) -> np.ndarray:
    pose = body.standing_pose(SHAPE)
    pose[3] = rng.uniform(-0.6, 0.6)  # heading: the figure faces the camera, roughly
    pose[ARM] = [rng.uniform(-1.2, 0.4), rng.uniform(-1.0, -0.3), rng.uniform(-0.5, 0.5), 0.8]
    return pose


def frame_of(pose: np.ndarray, scene: SceneOptions, rng: np.random.Generator):
    kp = body.forward_kinematics(pose, SHAPE)
    cam = fit_camera(kp[None], scene.width, scene.height, 50.0, 0.0, 5.0)
    return render(pose, SHAPE, cam, scene, rng, make_background(scene, rng)), cam


def outline_segments(poses: np.ndarray, cam, cones) -> np.ndarray:
    """(N, 2 C, 2, 2) outline segments in pixels, the observation model's geometry."""
    g = body.cone_geometry(poses, SHAPE)
    s, e = g.starts[:, cones], g.ends[:, cones]
    ps, pe = cam.project(s), cam.project(e)
    zs, ze = cam.to_camera(s)[..., 2], cam.to_camera(e)[..., 2]
    r = SHAPE.radii[cones] * ((1 + SHAPE.aspect[cones, None]) / 2)
    rs, re = cam.focal * r[:, 0] / zs, cam.focal * r[:, 1] / ze
    d = pe - ps
    n = np.stack([d[..., 1], -d[..., 0]], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    lines = [
        np.stack([ps + sign * rs[..., None] * n, pe + sign * re[..., None] * n], -2)
        for sign in (1.0, -1.0)
    ]
    return np.concatenate(lines, axis=1)


def point_segment_distance(q: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """(E,) distance of each point to the nearest of the (S, 2, 2) segments, by brute force."""
    out = np.full(len(q), np.inf)
    for a, b in seg:
        ab = b - a
        t = np.clip(((q - a) @ ab) / (ab @ ab), 0.0, 1.0)
        out = np.minimum(out, np.linalg.norm(q - (a + t[:, None] * ab), axis=1))
    return out


@pytest.fixture(scope="module")
def arm_scene():
    rng = np.random.default_rng(4)
    pose = arm_pose(rng)
    frame, cam = frame_of(pose, FLAT, rng)
    given = GivenBody(pose, ARM, SHAPE, cam)
    return pose, frame, cam, given


def test_off_by_default_and_without_a_given_body(arm_scene) -> None:
    pose, frame, cam, given = arm_scene
    rng = np.random.default_rng(0)
    poses = np.tile(pose, (20, 1))
    poses[:, ARM] += rng.normal(0.0, 0.3, (20, 4))
    plain = ObservationModel()
    reference = plain.log_likelihood(plain.prepare(frame), poses, SHAPE, cam)
    # Weight 0: a given body changes nothing, bit for bit.
    features = plain.prepare(frame, given)
    assert features.residual is None
    np.testing.assert_array_equal(plain.log_likelihood(features, poses, SHAPE, cam), reference)
    # A positive weight without a given body: nothing to explain, the same scores.
    weighted = ObservationModel(residual_weight=2.0)
    np.testing.assert_array_equal(
        weighted.log_likelihood(weighted.prepare(frame), poses, SHAPE, cam), reference
    )


def test_residual_points_are_the_free_arms_edges(arm_scene) -> None:
    pose, frame, cam, given = arm_scene
    model = ObservationModel(residual_weight=1.0, residual_points=10_000)
    features = model.prepare(frame, given)
    assert features.residual_cones is not None
    assert features.residual_cones.tolist() == [2, 3]  # r_upper_arm, r_forearm
    points = features.residual.T - 1.5
    assert len(points) > 20
    # On a flat background the edges the given body leaves are the arm's own.
    d = point_segment_distance(points, outline_segments(pose[None], cam, [2, 3])[0])
    assert np.mean(d < 3.0) > 0.8


def test_residual_cost_matches_brute_force(arm_scene) -> None:
    pose, frame, cam, given = arm_scene
    rng = np.random.default_rng(1)
    poses = np.tile(pose, (15, 1))
    poses[1:, ARM] += rng.normal(0.0, 0.4, (14, 4))
    model = ObservationModel(residual_weight=2.5, sharpness=1.5)
    off = ObservationModel(residual_weight=0.0, sharpness=1.5)
    features = model.prepare(frame, given)
    got = off.log_likelihood(features, poses, SHAPE, cam) - model.log_likelihood(
        features, poses, SHAPE, cam
    )
    q = features.residual.T.astype(np.float64) - 1.5
    segments = outline_segments(poses, cam, [2, 3])
    scale = frame.shape[0] / model.reference_height
    tau = model.residual_truncation * scale
    sigma = model.edge_sigma * scale
    expected = np.array(
        [
            np.mean(np.minimum(point_segment_distance(q, s), tau) ** 2) / (2 * sigma**2)
            for s in segments
        ]
    )
    expected *= model.residual_weight * model.sharpness
    np.testing.assert_allclose(got, expected, rtol=2e-3, atol=2e-3)


def test_the_true_arm_explains_its_edges_best() -> None:
    rng = np.random.default_rng(7)
    model = ObservationModel(residual_weight=1.0)
    wins = []
    for _ in range(6):
        pose = arm_pose(rng)
        frame, cam = frame_of(pose, FLAT, rng)
        features = model.prepare(frame, GivenBody(pose, ARM, SHAPE, cam))
        poses = np.tile(pose, (40, 1))
        poses[1:, ARM] += rng.normal(0.0, 0.3, (39, 4))
        poses[1:, ARM] = np.clip(poses[1:, ARM], body.PARAM_LOWER[ARM], body.PARAM_UPPER[ARM])
        loglik = model.log_likelihood(features, poses, SHAPE, cam)
        wins.append(loglik[0] > loglik[1:])
    assert np.mean(wins) > 0.9


def test_bad_given_body_raises(arm_scene) -> None:
    pose, frame, cam, _ = arm_scene
    model = ObservationModel(residual_weight=1.0)
    with pytest.raises(ValueError, match="GivenBody.pose"):
        model.prepare(frame, GivenBody(pose[:10], ARM, SHAPE, cam))
    with pytest.raises(ValueError, match="GivenBody.free"):
        model.prepare(frame, GivenBody(pose, np.array([30]), SHAPE, cam))
    with pytest.raises(ValueError, match="residual_weight"):
        ObservationModel(residual_weight=-1.0)


# -- the appearance term ------------------------------------------------------------


def test_cone_colors_read_the_figure(arm_scene) -> None:
    pose, frame, cam, _ = arm_scene
    colors = ObservationModel().cone_colors(frame, pose, SHAPE, cam)
    assert colors.shape == (10, 3)
    wall = np.asarray(FLAT.background_color, dtype=float)
    # The torso and the arms are drawn in their own colours, far from the wall's.
    assert np.all(np.abs(colors[[0, 2, 3]] - wall).max(axis=1) > 25)


def test_cone_colors_are_the_median_of_five_axis_pixels(arm_scene) -> None:
    # Per cone, the median of the pixels nearest the projections of the points
    # at 0.3, 0.4, ..., 0.7 of its axis (clipped into the image). A random
    # frame without blur: any other points give another median.
    pose, _frame, cam, _ = arm_scene
    rng = np.random.default_rng(31)
    frame = rng.integers(0, 256, (cam.height, cam.width, 3)).astype(np.uint8)
    model = ObservationModel(edge_blur=0.0)
    aside = pose.copy()
    aside[0] += 1500.0  # partly off the image
    for p in (pose, aside):
        geo = body.cone_geometry(p, SHAPE)
        want = np.empty((body.N_CONES, 3))
        for c in range(body.N_CONES):
            pixels = []
            for t in (0.3, 0.4, 0.5, 0.6, 0.7):
                u, v = cam.project((1 - t) * geo.starts[c] + t * geo.ends[c])
                x = min(max(int(np.rint(u)), 0), cam.width - 1)
                y = min(max(int(np.rint(v)), 0), cam.height - 1)
                pixels.append(frame[y, x])
            want[c] = np.median(np.array(pixels, dtype=np.float64), axis=0)
        np.testing.assert_array_equal(model.cone_colors(frame, p, SHAPE, cam), want)


def test_appearance_cost_matches_brute_force(arm_scene) -> None:
    import cv2

    pose, frame, cam, given = arm_scene
    # A free cone's axis points read its colour map instead of the foreground
    # map, so compare without the foreground term (as ArmTrack runs);
    # appearance_weight / axis_samples is below the edge term's per-point
    # maximum, so both models quantise costs with the same unit.
    off = ObservationModel(foreground_weight=0.0)
    on = ObservationModel(foreground_weight=0.0, appearance_weight=0.5)
    colors = on.cone_colors(frame, pose, SHAPE, cam)
    with_colors = GivenBody(pose, ARM, SHAPE, cam, colors)
    feats_on, feats_off = on.prepare(frame, with_colors), off.prepare(frame, with_colors)
    assert feats_on.cost_unit == feats_off.cost_unit
    assert feats_on.appearance_cones.tolist() == [2, 3]
    assert feats_off.appearance_cones is None
    rng = np.random.default_rng(3)
    poses = np.tile(pose, (12, 1))
    poses[1:, ARM] += rng.normal(0.0, 0.3, (11, 4))
    got = off.log_likelihood(feats_off, poses, SHAPE, cam) - on.log_likelihood(
        feats_on, poses, SHAPE, cam
    )
    smooth = cv2.GaussianBlur(frame, (0, 0), on.edge_blur).astype(float)
    g = body.cone_geometry(poses, SHAPE)
    t = ((np.arange(on.axis_samples) + 0.5) / on.axis_samples)[:, None, None, None]
    axis = g.starts[None, :, [2, 3]] * (1 - t) + g.ends[None, :, [2, 3]] * t  # (k, N, 2, 3)
    uv = cam.project(axis)
    span = on.appearance_high - on.appearance_low

    def cost(dx: int, dy: int) -> np.ndarray:
        x = np.floor(uv[..., 0] + 0.5).astype(int) + dx
        y = np.floor(uv[..., 1] + 0.5).astype(int) + dy
        inside = (x >= 0) & (x < frame.shape[1]) & (y >= 0) & (y < frame.shape[0])
        pixel = smooth[np.clip(y, 0, frame.shape[0] - 1), np.clip(x, 0, frame.shape[1] - 1)]
        diff = np.abs(pixel - colors[[2, 3]][None, None]).max(axis=-1)
        mismatch = np.where(inside, np.clip((diff - on.appearance_low) / span, 0, 1), 1.0)
        return mismatch * on.appearance_weight / on.axis_samples  # (k, N, 2)

    expected = cost(0, 0).sum(axis=(0, 2))
    # The model projects in float32: a point on a colour boundary may read the
    # next pixel. Every pose lies within its points' neighbourhood bounds, and
    # most match exactly.
    near = np.stack([cost(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    lo, hi = near.min(axis=0).sum(axis=(0, 2)), near.max(axis=0).sum(axis=(0, 2))
    tol = 2 * on.axis_samples * feats_on.cost_unit
    assert np.all((got >= lo - tol) & (got <= hi + tol))
    assert np.mean(np.abs(got - expected) <= tol) >= 0.75
    assert np.ptp(expected) > 10 * tol  # the term does vary between poses


def test_appearance_needs_colors_of_the_right_shape(arm_scene) -> None:
    pose, frame, cam, _ = arm_scene
    model = ObservationModel(appearance_weight=1.0)
    # Without colours the term is off.
    assert model.prepare(frame, GivenBody(pose, ARM, SHAPE, cam)).appearance_cones is None
    with pytest.raises(ValueError, match="GivenBody.colors"):
        model.prepare(frame, GivenBody(pose, ARM, SHAPE, cam, np.zeros((10, 1))))
    with pytest.raises(ValueError, match="appearance_low"):
        ObservationModel(appearance_low=50.0, appearance_high=40.0)


def test_free_cones_cache_gives_the_computed_answer(arm_scene) -> None:
    # free_cones keeps its last answer: the same given pose, free set and
    # shape read it back (read-only), anything else computes afresh, and the
    # answers are those of an empty cache.
    pose, _frame, cam, given = arm_scene

    def fresh(g: GivenBody):
        geometry._FREE_CONES_CACHE.clear()
        return geometry.free_cones(g.pose, g.free, g.shape)

    def same(a, b) -> None:
        np.testing.assert_array_equal(a[0], b[0])
        for x, y in zip((*a[1][0], *a[1][1:]), (*b[1][0], *b[1][1:]), strict=True):
            np.testing.assert_array_equal(x, y)

    first = fresh(given)
    again = geometry.free_cones(pose.copy(), ARM.copy(), SHAPE)
    assert again is first  # a hit: equal bytes, the same shape
    with pytest.raises(ValueError, match="read-only"):
        again[1][2][0, 0] = True
    moved = pose.copy()
    moved[0] += 100.0  # another given pose
    same(
        geometry.free_cones(moved, ARM, SHAPE),
        fresh(GivenBody(moved, ARM, SHAPE, cam)),
    )
    legs = np.arange(16, 20)  # another free set
    got = geometry.free_cones(pose, legs, SHAPE)
    same(got, fresh(GivenBody(pose, legs, SHAPE, cam)))
    assert set(got[0].tolist()) != set(first[0].tolist())
    # An equal shape in another object (as an agent reads one from every
    # observation) hits; another shape computes afresh.
    first = geometry.free_cones(pose, ARM, SHAPE)
    assert geometry.free_cones(pose, ARM, body.BodyShape.from_vector(SHAPE.to_vector())) is first
    longer = SHAPE.replace(forearm_length=SHAPE.forearm_length + 40.0)
    got = geometry.free_cones(pose, ARM, longer)
    assert got is not first
    same(got, fresh(GivenBody(pose, ARM, longer, cam)))
    assert not np.array_equal(got[1][1], first[1][1])  # the ends moved with the forearm
    same(geometry.free_cones(pose, ARM, SHAPE), first)
