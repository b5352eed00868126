"""Tests of the backdrop read at the first frame and of the coverage term it enables."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from baselines.observation import Backdrop, GivenBody, ObservationModel, features, geometry
from humotion_gym import body
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.render import SceneOptions, make_background, render

SHAPE = body.default_shape()
ALL = np.arange(body.N_PARAMS)
ARM = np.arange(9, 13)  # r_shoulder_x, _y, _z, r_elbow
CLEAN = SceneOptions(noise_sigma=0.0)  # clutter, no sensor noise: exact oracles


def walking_poses(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A standing pose and the same person a step to the side with other limbs."""
    first = body.standing_pose(SHAPE)
    first[3] = rng.uniform(-0.4, 0.4)
    later = first.copy()
    later[0] += 350.0  # the root moves 35 cm across
    later[ARM] = [0.0, -1.3, 0.0, 0.3]  # the right arm raised sideways
    later[body.PARAM_INDEX["l_hip_x"]] = -0.5
    return first, later


@pytest.fixture(scope="module")
def episode():
    rng = np.random.default_rng(11)
    first, later = walking_poses(rng)
    kp = body.forward_kinematics(np.stack([first, later]), SHAPE)
    cam = fit_camera(kp, CLEAN.width, CLEAN.height, 45.0, 30.0, 10.0)
    background = make_background(CLEAN, rng)
    frames = [render(p, SHAPE, cam, CLEAN, rng, background) for p in (first, later)]
    return first, later, cam, background, frames


def test_known_pixels_show_the_backdrop(episode) -> None:
    first, _later, cam, background, frames = episode
    model = ObservationModel(backdrop=True, edge_blur=0.0)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    assert backdrop.known.shape == frames[0].shape[:2]
    assert 0.5 < backdrop.known.mean() < 0.99
    # Without noise or blur, every known pixel is the backdrop's own, and every
    # pixel the figure changed is unknown.
    np.testing.assert_array_equal(frames[0][backdrop.known], background.image[backdrop.known])
    figure = np.any(frames[0] != background.image, axis=2)
    assert figure.any() and not np.any(figure & backdrop.known)
    assert not backdrop.image.flags.writeable and not backdrop.known.flags.writeable


def test_foreground_ignores_clutter_and_edges_keep_near_the_figure(episode) -> None:
    first, later, cam, background, frames = episode
    model = ObservationModel(backdrop=True)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    given = GivenBody(later, ALL, SHAPE, cam, backdrop=backdrop)
    with_backdrop = model.prepare(frames[1], given)
    border = model.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam))
    # Where the backdrop is known and the later frame shows it, nothing is foreground;
    # the border rule calls some of that clutter foreground.
    shows_backdrop = backdrop.known & np.all(frames[1] == background.image, axis=2)
    shows_backdrop = cv2.erode(shows_backdrop.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert with_backdrop.foreground[shows_backdrop].max() == 0.0
    assert border.foreground[shows_backdrop].max() > 0.5
    # Edges of the known backdrop farther than the reach from any foreground are gone.
    scale = frames[1].shape[0] / model.reference_height
    fg = (with_backdrop.foreground > 0) & backdrop.known
    dist = cv2.distanceTransform((~fg).astype(np.uint8), cv2.DIST_L2, 5)
    far = backdrop.known & (dist > model.backdrop_reach * scale + 1.5)
    assert not np.any(with_backdrop.edges[far])
    assert np.any(border.edges[far])
    # What is kept are the border rule's own edges.
    assert not np.any(with_backdrop.edges & ~border.edges)


def test_off_means_bit_identical(episode) -> None:
    first, later, cam, _background, frames = episode
    plain = ObservationModel()
    backdrop = ObservationModel(backdrop=True).read_backdrop(frames[0], first, SHAPE, cam)
    rng = np.random.default_rng(3)
    poses = later + rng.normal(0.0, 0.05, (40, body.N_PARAMS))
    reference = plain.log_likelihood(plain.prepare(frames[1]), poses, SHAPE, cam)
    # A backdrop handed to a model that does not use it changes nothing.
    feats = plain.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam, backdrop=backdrop))
    np.testing.assert_array_equal(plain.log_likelihood(feats, poses, SHAPE, cam), reference)
    # Nor does a model that uses it without one (no given body: the border rule).
    on = ObservationModel(backdrop=True, coverage_weight=2.0)
    np.testing.assert_array_equal(
        on.log_likelihood(on.prepare(frames[1]), poses, SHAPE, cam), reference
    )


def box_outside(q: np.ndarray, start: np.ndarray, end: np.ndarray, r0: float, r1: float):
    """Distance outside one projected cone, by the definition in _coverage_cost (float64)."""
    d = end - start
    length = np.linalg.norm(d)
    u = d / length
    n = np.array([-u[1], u[0]])
    along = (q - start) @ u
    across = np.abs((q - start) @ n)
    beyond = np.abs(along - length / 2) - length / 2
    radius = r0 + (r1 - r0) * along / length  # linear, extrapolated beyond the ends
    return np.maximum(across, beyond) - radius


def test_coverage_cost_matches_its_definition(episode) -> None:
    first, later, cam, _background, frames = episode
    model = ObservationModel(backdrop=True, coverage_weight=1.5, sharpness=1.3)
    off = replace(model, coverage_weight=0.0)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    given = GivenBody(later, ALL, SHAPE, cam, backdrop=backdrop)
    feats = model.prepare(frames[1], given)
    assert feats.coverage is not None and feats.coverage.shape[1] == model.coverage_points
    assert feats.coverage_cones is not None and feats.coverage_cones.size == body.N_CONES
    rng = np.random.default_rng(5)
    poses = later + rng.normal(0.0, 0.08, (12, body.N_PARAMS)) * body.ANGLE_MASK
    got = off.log_likelihood(feats, poses, SHAPE, cam) - model.log_likelihood(
        feats, poses, SHAPE, cam
    )
    q = feats.coverage.T.astype(np.float64) - 1.5
    geo = body.cone_geometry(poses, SHAPE)
    radii = SHAPE.radii * ((1.0 + SHAPE.aspect[:, None]) / 2.0)
    scale = frames[1].shape[0] / model.reference_height
    tau, sigma = model.coverage_truncation * scale, model.edge_sigma * scale
    expected = []
    for k in range(len(poses)):
        ps, pe = cam.project(geo.starts[k]), cam.project(geo.ends[k])
        zs, ze = cam.to_camera(geo.starts[k])[:, 2], cam.to_camera(geo.ends[k])[:, 2]
        outside = np.min(
            [
                box_outside(
                    q,
                    ps[c],
                    pe[c],
                    cam.focal * radii[c, 0] / zs[c],
                    cam.focal * radii[c, 1] / ze[c],
                )  # fmt: skip
                for c in range(body.N_CONES)
            ],
            axis=0,
        )
        expected.append(np.mean(np.clip(outside, 0.0, tau) ** 2) / (2 * sigma**2))
    # The torso's and head's elliptical sections give per-pose radii the
    # round-section oracle does not have: compare where that cannot matter.
    np.testing.assert_allclose(
        got, np.array(expected) * model.coverage_weight * model.sharpness, rtol=0.05, atol=0.02
    )


def test_a_term_without_points_scores_as_no_term(episode) -> None:
    """A frame whose coverage or residual term has no points adds exactly zero.

    The terms are scored whenever the features carry them, points or not (so
    their kernels compile with the first frame scored); with none, the
    log-likelihoods must equal those of the model without the term, bit for
    bit, not NaN from averaging over no points.
    """
    first, later, cam, _background, frames = episode
    model = ObservationModel(backdrop=True, coverage_weight=1.5, residual_weight=0.7)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    feats = model.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam, backdrop=backdrop))
    assert feats.coverage is not None and feats.coverage.shape[1] > 0
    assert feats.residual is not None
    none = np.zeros((2, 0), np.float32)
    empty = replace(feats, coverage=none, residual=none)
    off = replace(model, coverage_weight=0.0, residual_weight=0.0)
    poses = later + np.random.default_rng(6).normal(0.0, 0.08, (7, body.N_PARAMS)) * body.ANGLE_MASK
    got = model.log_likelihood(empty, poses, SHAPE, cam)
    assert np.isfinite(got).all()
    np.testing.assert_array_equal(got, off.log_likelihood(feats, poses, SHAPE, cam))
    # and the terms do count where they have points
    assert not np.array_equal(model.log_likelihood(feats, poses, SHAPE, cam), got)


def test_coverage_points_are_the_set_pixels_evenly_spread() -> None:
    """np.nonzero's pixels of the mask, thinned by np.linspace's picks (the definition)."""
    rng = np.random.default_rng(9)
    masks = [rng.random((h, w)) < p for h, w, p in ((128, 128, 0.1), (64, 96, 0.5), (7, 5, 0.3))]
    masks += [np.zeros((32, 32), bool), np.ones((16, 20), bool)]
    for mask in masks:
        for most in (1, 2, 7, 96, 10_000):
            ys, xs = np.nonzero(mask)
            if xs.size > most:
                pick = np.linspace(0, xs.size - 1, most).astype(np.intp)
                ys, xs = ys[pick], xs[pick]
            want = np.stack([xs, ys]).astype(np.float32) + np.float32(1.5)
            got = features.spread_points(mask, most)
            assert got.dtype == np.float32 and got.shape == want.shape
            np.testing.assert_array_equal(got, want)


def test_foreground_and_coverage_points_follow_their_definitions(episode) -> None:
    # Known pixels: the ramp of their difference from the backdrop. Unknown
    # ones (under the first pose): 1/2 where they changed, else 1. Coverage
    # points: the sure (probability 1) known pixels outside the given cones'
    # grown silhouette in this frame.
    first, later, cam, _background, frames = episode
    model = ObservationModel(backdrop=True, coverage_weight=1.0, coverage_points=10_000)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    feats = model.prepare(frames[1], GivenBody(later, ARM, SHAPE, cam, backdrop=backdrop))
    smooth = features.smoothed(frames[1], model.edge_blur, "test")
    near = np.abs(smooth.astype(int) - backdrop.image.astype(int)).max(axis=2)
    known = backdrop.known
    assert np.median(near[known]) == 0  # no noise: the threshold stays foreground_low
    lo, hi = model.foreground_low, model.foreground_high
    changed = near > lo
    diff = np.where(known, near, np.where(changed, int(0.5 * (lo + hi)), int(hi)))
    want = np.clip((diff - lo) / (hi - lo), 0.0, 1.0)
    np.testing.assert_allclose(feats.foreground, want, atol=1e-6)
    assert (~known & changed).sum() > 20 and (~known & ~changed).sum() > 20
    sure = (feats.foreground >= 1.0) & known
    given_cones = np.setdiff1d(np.arange(body.N_CONES), [2, 3])  # all but the right arm
    geo = body.cone_geometry(later, SHAPE)
    silhouette = geometry.silhouette_mask(
        geo.starts, geo.ends, SHAPE, cam, model.near_mm, cones=given_cones
    )
    covered = (
        geometry.grow(silhouette, model.backdrop_margin * cam.height / model.reference_height) > 0
    )
    assert (sure & covered).sum() > 20  # the given body moved: it would be covered
    assert ((feats.foreground > 0.5) & (feats.foreground < 1.0) & known & ~covered).any()
    np.testing.assert_array_equal(
        feats.coverage, features.spread_points(sure & ~covered, model.coverage_points)
    )


def test_coverage_prefers_the_true_pose_to_a_limb_laid_on_the_body(episode) -> None:
    first, later, cam, _background, frames = episode
    model = ObservationModel(backdrop=True, coverage_weight=2.0, coverage_points=10_000)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    feats = model.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam, backdrop=backdrop))
    piled = later.copy()
    piled[ARM] = 0.0  # the raised arm laid along the torso: on foreground all the same
    off = replace(model, coverage_weight=0.0)
    margin_on = np.diff(model.log_likelihood(feats, np.stack([piled, later]), SHAPE, cam))[0]
    margin_off = np.diff(off.log_likelihood(feats, np.stack([piled, later]), SHAPE, cam))[0]
    assert margin_on > margin_off


def test_given_cones_are_not_coverage_points() -> None:
    rng = np.random.default_rng(2)
    pose = body.standing_pose(SHAPE)
    pose[ARM] = [-1.0, -0.7, 0.0, 0.9]
    kp = body.forward_kinematics(pose, SHAPE)
    cam = fit_camera(kp[None], CLEAN.width, CLEAN.height, 50.0, 20.0, 5.0)
    background = make_background(CLEAN, rng)
    first = render(body.standing_pose(SHAPE), SHAPE, cam, CLEAN, rng, background)
    frame = render(pose, SHAPE, cam, CLEAN, rng, background)
    model = ObservationModel(backdrop=True, coverage_weight=1.0, coverage_points=10_000)
    backdrop = model.read_backdrop(first, body.standing_pose(SHAPE), SHAPE, cam)
    feats = model.prepare(frame, GivenBody(pose, ARM, SHAPE, cam, backdrop=backdrop))
    assert feats.coverage_cones is not None and feats.coverage_cones.tolist() == [2, 3]
    q = feats.coverage.T - 1.5
    assert len(q) > 5
    geo = body.cone_geometry(pose, SHAPE)
    ps, pe = cam.project(geo.starts), cam.project(geo.ends)
    zs = cam.to_camera(geo.starts)[:, 2]
    near_arm = np.min(
        [box_outside(q, ps[c], pe[c], 0.0, 0.0) - cam.focal * 60.0 / zs[c] for c in (2, 3)],
        axis=0,
    )
    assert np.all(near_arm <= 0.0)  # within 60 mm (projected) of the arm's axis


def test_first_frame_keeps_what_the_model_uses(episode) -> None:
    first, _later, cam, _background, frames = episode
    kept = ObservationModel().read_first_frame(frames[0], first, SHAPE, cam)
    assert kept.colors is None and kept.backdrop is None and kept.floor is None
    model = ObservationModel(appearance_weight=1.0, backdrop=True)
    kept = model.read_first_frame(frames[0], first, SHAPE, cam)
    np.testing.assert_array_equal(kept.colors, model.cone_colors(frames[0], first, SHAPE, cam))
    assert kept.backdrop is not None and kept.floor is None
    np.testing.assert_array_equal(
        kept.backdrop.known, model.read_backdrop(frames[0], first, SHAPE, cam).known
    )


@pytest.mark.parametrize("height", [128, 192])
def test_known_pixels_are_outside_the_silhouette_grown_by_the_margin(height: int) -> None:
    # The margin is in reference pixels: 3 of them are 3 pixels at 128 rows, 4.5 at 192.
    rng = np.random.default_rng(7)
    first, _later = walking_poses(rng)
    scene = SceneOptions(width=height, height=height, noise_sigma=0.0)
    cam = fit_camera(body.forward_kinematics(first, SHAPE)[None], height, height, 45.0, 30.0, 10.0)
    frame = render(first, SHAPE, cam, scene, rng, make_background(scene, rng))
    model = ObservationModel(backdrop=True, backdrop_margin=3.0)
    known = model.read_backdrop(frame, first, SHAPE, cam).known
    geo = body.cone_geometry(first, SHAPE)
    silhouette = geometry.silhouette_mask(geo.starts, geo.ends, SHAPE, cam, model.near_mm)
    grown = geometry.grow(silhouette, 3.0 * height / 128)
    np.testing.assert_array_equal(known, grown == 0)
    if height != 128:  # the margin unscaled is another mask
        assert not np.array_equal(known, geometry.grow(silhouette, 3.0) == 0)


def test_bad_input_is_named(episode) -> None:
    first, later, cam, _background, frames = episode
    model = ObservationModel(backdrop=True)
    with pytest.raises(ValueError, match=r"read_backdrop: expected a pose of shape \(25,\)"):
        model.read_backdrop(frames[0], first[:5], SHAPE, cam)
    with pytest.raises(
        ValueError, match="read_backdrop: expected a finite pose, got NaN or infinity"
    ):
        model.read_backdrop(frames[0], np.where(np.arange(25) == 3, np.nan, first), SHAPE, cam)
    with pytest.raises(ValueError, match="read_backdrop: frame is 64x64"):
        model.read_backdrop(frames[0][:64, :64], first, SHAPE, cam)
    small = Backdrop(np.zeros((8, 8, 3), np.uint8), np.ones((8, 8), bool))
    with pytest.raises(ValueError, match="GivenBody.backdrop"):
        model.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam, backdrop=small))
    for bad in (
        {"backdrop": 1.5},
        {"backdrop_margin": -1.0},
        {"backdrop_reach": float("nan")},
        {"coverage_weight": -0.1},
        {"coverage_truncation": 0.0},
        {"coverage_points": 0},
    ):
        with pytest.raises(ValueError, match=next(iter(bad))):
            ObservationModel(**bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("sigma", [24.0, 64.0])
def test_sensor_noise_raises_the_threshold_or_turns_the_backdrop_off(sigma: float) -> None:
    rng = np.random.default_rng(21)
    first, _later = walking_poses(rng)
    scene = SceneOptions(noise_sigma=sigma)
    kp = body.forward_kinematics(first, SHAPE)
    cam = fit_camera(kp[None], scene.width, scene.height, 45.0, 30.0, 10.0)
    background = make_background(scene, rng)
    # The same pose twice: the known pixels differ by sensor noise alone.
    frames = [render(first, SHAPE, cam, scene, rng, background) for _ in range(2)]
    model = ObservationModel(backdrop=True, coverage_weight=2.0)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    feats = model.prepare(frames[1], GivenBody(first, ALL, SHAPE, cam, backdrop=backdrop))
    border = model.prepare(frames[1], GivenBody(first, ALL, SHAPE, cam))
    if sigma == 64.0:
        # The noise passes foreground_high: the border rule alone, as without a backdrop.
        np.testing.assert_array_equal(feats.foreground, border.foreground)
        np.testing.assert_array_equal(feats.edges, border.edges)
        assert feats.coverage is None
    else:
        smooth = [cv2.GaussianBlur(f, (0, 0), model.edge_blur) for f in frames]
        diff = np.abs(smooth[1].astype(int) - smooth[0].astype(int)).max(axis=2)
        known = backdrop.known
        assert np.mean(diff[known] > model.foreground_low) > 0.05  # a fixed threshold fails
        assert np.mean(feats.foreground[known] > 0) < 0.01


def test_gray_frames_other_sizes_and_a_backdrop_with_nothing_known() -> None:
    rng = np.random.default_rng(5)
    first, later = walking_poses(rng)
    scene = SceneOptions(width=256, height=192, color="gray", noise_sigma=0.0)
    kp = body.forward_kinematics(np.stack([first, later]), SHAPE)
    cam = fit_camera(kp, scene.width, scene.height, 45.0, 30.0, 10.0)
    background = make_background(scene, rng)
    frames = [render(p, SHAPE, cam, scene, rng, background) for p in (first, later)]
    assert frames[0].shape == (192, 256, 1)
    model = ObservationModel(backdrop=True, coverage_weight=2.0, edge_blur=0.0)
    backdrop = model.read_backdrop(frames[0], first, SHAPE, cam)
    np.testing.assert_array_equal(frames[0][backdrop.known], background.image[backdrop.known])
    feats = model.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam, backdrop=backdrop))
    assert feats.coverage is not None and feats.coverage.shape[1] > 0
    scores = model.log_likelihood(feats, np.stack([later, first]), SHAPE, cam)
    assert scores[0] > scores[1]
    # Nothing known (a figure filling the frame): the border rule alone.
    blind = Backdrop(backdrop.image, np.zeros_like(backdrop.known))
    border = model.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam))
    none = model.prepare(frames[1], GivenBody(later, ALL, SHAPE, cam, backdrop=blind))
    np.testing.assert_array_equal(none.foreground, border.foreground)
    assert none.coverage is None


def front_camera() -> Camera:
    """95x95 pixels, focal 200 px, looking along world +z from 2.5 m: 0.08 px per mm at z = 0."""
    return Camera(95, 95, math.degrees(2 * math.atan(47.5 / 200.0)), np.eye(3), [0, 0, -2500.0])


def test_silhouette_is_each_cones_quad_and_end_discs() -> None:
    # The torso (semi-axes 150/165 mm and 0.6 of that: the larger counts) at
    # u = 27 and the head (55/85 mm) at u = 67, both from v = 27 to v = 67.
    cam = front_camera()
    starts, ends = np.zeros((body.N_CONES, 3)), np.zeros((body.N_CONES, 3))
    starts[0], ends[0] = (-250.0, -250.0, 0.0), (-250.0, 250.0, 0.0)
    starts[1], ends[1] = (250.0, -250.0, 0.0), (250.0, 250.0, 0.0)
    mask = geometry.silhouette_mask(starts, ends, SHAPE, cam, 10.0, cones=np.array([0, 1]))
    assert mask.dtype == np.uint8 and set(np.unique(mask).tolist()) == {0, 255}
    # The end discs' radii round up: 0.08 * 150 = 12 and 13.2 px (torso), 4.4
    # and 6.8 px (head), so the columns through the axes end 12, 14, 5 and 7
    # pixels past the axis ends.
    assert np.flatnonzero(mask[:, 27]).tolist() == list(range(15, 82))
    assert np.flatnonzero(mask[:, 67]).tolist() == list(range(22, 75))
    # Elsewhere, pixel centres clearly in (one pixel inside the quad or a disc)
    # are set and those clearly out (one pixel outside both) are not.
    v, u = np.mgrid[0:95, 0:95].astype(np.float64)
    sure_in, maybe = np.zeros(mask.shape, bool), np.zeros(mask.shape, bool)
    for u0, (r_s, r_e) in ((27.0, (12.0, 13.2)), (67.0, (4.4, 6.8))):
        t, k = (v - 27.0) / 40.0, np.abs(u - u0)
        for margin, out in ((-1.0, sure_in), (1.0, maybe)):
            quad = (np.abs(t - 0.5) <= 0.5 + margin / 40.0) & (k <= r_s + t * (r_e - r_s) + margin)
            discs = (np.hypot(u - u0, v - 27.0) <= r_s + margin) | (
                np.hypot(u - u0, v - 67.0) <= r_e + margin
            )
            out |= quad | discs
    assert sure_in.sum() > 500 and (mask[sure_in] == 255).all()
    assert (mask[~maybe] == 0).all()
    # A cone with an end nearer the camera than near_mm (5 mm in front of it,
    # or 100 mm behind it) covers the whole image, whichever end it is.
    for start_z, end_z in ((-2495.0, 0.0), (0.0, -2495.0), (-2600.0, 0.0), (0.0, -2600.0)):
        starts[1, 2], ends[1, 2] = start_z, end_z
        near = geometry.silhouette_mask(starts, ends, SHAPE, cam, 10.0, np.array([1]))
        assert (near == 255).all(), (start_z, end_z)


def test_grow_dilates_by_a_disc_of_the_radius_rounded_up() -> None:
    dot = np.zeros((15, 15), np.uint8)
    dot[7, 7] = 255
    for radius, reach in ((0.0, 0), (1e-10, 0), (1.0, 1), (2.2, 3), (3.0, 3)):
        grown = geometry.grow(dot, radius)
        line = list(range(7 - reach, 8 + reach))
        assert np.flatnonzero(grown[7]).tolist() == line, radius
        assert np.flatnonzero(grown[:, 7]).tolist() == line, radius
        # a disc, not a square: the corners of its box stay clear
        assert reach < 2 or grown[7 - reach, 7 - reach] == 0
