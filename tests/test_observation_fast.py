"""The filter's inner loop, fast paths against plain references: the same bits.

Issue 15 made scoring poses and the particle filter faster without changing
any result: the leaderboard's tables must come out the same. Each fast path
(the observation model's point pipeline taken a few cones at a time, the tree
prior's table-driven descent and leaf choice, the filter's log-sum-exp and
resampling copy) is checked here against a straightforward implementation of
the same arithmetic kept in this file, with ``np.array_equal``, on random
poses, frames and tasks (whole body, the arm task's residual-edge and
appearance terms).
"""

from __future__ import annotations

import cv2
import gymnasium as gym
import numpy as np
import pytest
from scipy.special import log_ndtr, logsumexp

from baselines.filtering import (
    ParticleFilter,
    ParticleState,
    log_sum_exp,
    systematic_resample,
    temper_for_survival,
    tempered_weights,
)
from baselines.observation import (
    _CHUNK_POSES,
    _CONE_END,
    _CONE_START,
    _PARAM_ROWS,
    _SHARED_MIN_POSES,
    POSE_LIMIT,
    FrameFeatures,
    GivenBody,
    ObservationModel,
    _chunk_size,
    _cone_parameters,
    _orientation_bin,
    _silhouette_factor,
)
from baselines.priors import tree
from humotion_gym import _kernels, body
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.kinematics import _HEAD, _batch_kinematics
from humotion_gym.mocap.library import synthetic_library
from humotion_gym.render import SceneOptions, render

SHAPE = body.default_shape()
ARM = np.array([9, 10, 11, 12])  # right shoulder and elbow: the arm task's free parameters


# -- the observation model ----------------------------------------------------


def reference_log_likelihood(
    model: ObservationModel,
    feats: FrameFeatures,
    params: np.ndarray,
    shape: body.BodyShape,
    camera: Camera,
) -> np.ndarray:
    """The model's score in one pass over all points, fancy indexing, no scratch buffers.

    The same float32 operations in the same order as the model: projected
    keypoints, each cone's basis ``(s, e, a, b)``, the points as one matrix
    product, clipped and truncated to pixels, then one lookup per point in the
    cost table.
    """
    f4 = np.float32
    p = np.asarray(params, dtype=np.float64).reshape(-1, body.N_PARAMS)
    finite = (np.abs(p) <= POSE_LIMIT).all(axis=1)  # NaN fails too
    p = np.where(finite[:, None], p, 0.0)
    n = p.shape[0]
    poses = _batch_kinematics(p, shape, f4, want_head_axes=shape.aspect[_HEAD] != 1.0)
    cam = camera.rotation.astype(f4) @ poses.keypoints.reshape(3, -1)
    cam += camera.translation.astype(f4)[:, None]
    behind = cam[2] < model.near_mm
    cam[2] = np.maximum(cam[2], f4(model.near_mm))
    inv = f4(camera.focal) / cam[2]
    uv = cam[:2] * inv
    cx, cy = camera.principal_point
    uv[0] += f4(cx + 1.5) + behind * f4(1e7)
    uv[1] += f4(cy + 1.5)
    uv = uv.reshape(2, body.N_KEYPOINTS, n)
    start, end = uv[:, _CONE_START], uv[:, _CONE_END]  # (2, 10, n)
    dx, dy = end[0] - start[0], end[1] - start[1]
    norm = dx * dx
    norm += dy * dy
    norm += f4(1e-12)
    norm = f4(1.0) / np.sqrt(norm)
    nx, ny = dy * norm, dx * norm
    ny *= f4(-1.0)
    radii, axes = model._silhouette_axes(shape, poses)
    rot = camera.rotation.astype(f4)
    varying = [
        (cone, _silhouette_factor(rot, ax, ay, aspect, nx[cone], ny[cone]))
        for cone, ax, ay, aspect in axes
    ]
    inv = inv.reshape(body.N_KEYPOINTS, n)
    offsets = []
    for k, ends in enumerate((_CONE_START, _CONE_END)):
        rad = inv[ends] * radii[:, k : k + 1]
        for cone, factor in varying:
            rad[cone] *= factor
        if model.raster_pad_px:
            rad = rad + f4(model.raster_pad_px)
        offsets += [rad * nx, rad * ny]
    basis = np.stack([start[0], start[1], end[0], end[1], *offsets])  # (8, 10, n)
    coef = model.sample_coefficients()
    points = coef @ basis.reshape(8, -1)
    m = points.shape[0] // 2
    w2, h2 = feats.width + 2, feats.height + 2
    x = np.clip(points[:m], 0.0, f4(w2 - 1)).astype(np.int64)
    y = np.clip(points[m:], 0.0, f4(h2 - 1)).astype(np.int64)
    plane = w2 * h2
    maps = np.empty((m, body.N_CONES, n), np.int64)
    n_out = 2 * model.outline_samples
    maps[n_out:] = model.orientation_bins
    if feats.appearance_cones is not None:
        for k, cone in enumerate(feats.appearance_cones):
            maps[n_out:, cone] += 1 + k
    if model.orientation_bins > 1:
        maps[:n_out] = _orientation_bin(nx, ny, model.orientation_bins, np.empty_like(nx))
    else:
        maps[:n_out] = 0
    flat = maps.reshape(m, -1) * plane + y * w2 + x
    total = feats.cost[flat].sum(axis=0).reshape(body.N_CONES, n).sum(axis=0).astype(np.float64)
    if feats.residual is None or not feats.residual.shape[1] or model.residual_weight <= 0:
        total *= -feats.cost_unit * model.sharpness
    else:
        total *= feats.cost_unit
        total += model._residual_cost(feats, basis, n)
        total *= -model.sharpness
    total[~finite] = -np.inf
    return total


def random_poses(rng: np.random.Generator, n: int) -> np.ndarray:
    """Poses near standing, any heading, with a few far off and behind the camera."""
    poses = np.tile(body.standing_pose(SHAPE), (n, 1))
    poses[:, :3] += rng.normal(0.0, 150.0, (n, 3))
    poses[:, 3] = rng.uniform(-np.pi, np.pi, n)
    poses[:, 4:] += rng.normal(0.0, 0.5, (n, 21))
    far = rng.random(n) < 0.05
    poses[far, :3] += rng.normal(0.0, 5000.0, (int(far.sum()), 3))
    return poses


def scene(seed: int, size: int = 96) -> tuple[np.ndarray, Camera, np.ndarray]:
    rng = np.random.default_rng(seed)
    pose = random_poses(rng, 1)[0]
    pose[:3] = body.standing_pose(SHAPE)[:3]
    kp = body.forward_kinematics(pose, SHAPE)
    cam = fit_camera(kp[None], size, size, 50.0, rng.uniform(0, 360), rng.uniform(0, 20))
    frame = render(pose, SHAPE, cam, SceneOptions(width=size, height=size), rng)
    return frame, cam, pose


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("n", [1, 5, 300, 821, 3000, 9000])
def test_scores_match_the_one_pass_reference(seed: int, n: int) -> None:
    frame, cam, pose = scene(seed)
    model = ObservationModel()
    feats = model.prepare(frame)
    rng = np.random.default_rng(100 + seed)
    poses = pose + rng.normal(0.0, 0.1, (n, 25)) * (rng.random((n, 1)) < 0.7)
    poses[: n // 3] = random_poses(rng, n // 3)
    if n > 3:
        poses[1, 7] = np.nan
        poses[2, 2] = -1e5  # far behind the camera
    if n > 4:
        poses[3, 20] = -np.inf  # non-finite rows score -inf, the others as always
    if n > 6:
        poses[4, 0] = POSE_LIMIT  # scored: its cones' bases are huge but finite
        poses[5, 1] = -2 * POSE_LIMIT  # beyond the limit: -inf
        poses[6, 8] = 2 * POSE_LIMIT  # an angle too
    fast = model.log_likelihood(feats, poses, SHAPE, cam)
    np.testing.assert_array_equal(fast, reference_log_likelihood(model, feats, poses, SHAPE, cam))
    # Single precision poses take the same path.
    fast32 = model.log_likelihood(feats, poses.astype(np.float32), SHAPE, cam)
    ref32 = reference_log_likelihood(model, feats, poses.astype(np.float32), SHAPE, cam)
    np.testing.assert_array_equal(fast32, ref32)


@pytest.mark.parametrize("bins", [1, 4, 6])
@pytest.mark.parametrize("pad", [0.0, 0.5])
def test_other_model_settings_match_the_reference(bins: int, pad: float) -> None:
    frame, cam, pose = scene(7, size=64)
    model = ObservationModel(
        orientation_bins=bins, outline_samples=3, axis_samples=4, raster_pad_px=pad
    )
    feats = model.prepare(frame)
    poses = pose + np.random.default_rng(8).normal(0.0, 0.2, (1500, 25))
    fast = model.log_likelihood(feats, poses, SHAPE, cam)
    np.testing.assert_array_equal(fast, reference_log_likelihood(model, feats, poses, SHAPE, cam))


@pytest.mark.parametrize("seed", [3, 4])
def test_arm_terms_match_the_reference(seed: int) -> None:
    # The arm task's model: residual edges and each free cone's colour map.
    frame, cam, pose = scene(seed)
    model = ObservationModel(residual_weight=1.0, appearance_weight=1.0)
    colors = model.cone_colors(frame, pose, SHAPE, cam)
    feats = model.prepare(frame, GivenBody(pose, ARM, SHAPE, cam, colors))
    assert feats.appearance_cones is not None and feats.residual is not None
    rng = np.random.default_rng(seed)
    for n in (7, 300, 2000):
        poses = np.tile(pose, (n, 1))
        poses[:, ARM] += rng.normal(0.0, 0.4, (n, ARM.size))
        fast = model.log_likelihood(feats, poses, SHAPE, cam)
        ref = reference_log_likelihood(model, feats, poses, SHAPE, cam)
        np.testing.assert_array_equal(fast, ref)


@pytest.mark.parametrize(
    "free",
    [
        np.array([9, 10, 11, 12]),  # the arm task's: the right arm's two cones move
        np.array([17, 20, 21, 24, 9, 12, 13, 16]),  # the side-walk task's: torso and head fixed
        np.array([7]),  # the neck alone: only the head moves
        np.array([], dtype=np.intp),  # every pose the same
        np.array([0]),  # the root: every cone moves
    ],
)
@pytest.mark.parametrize("pad", [0.0, 0.5])
def test_cones_the_poses_share_match_the_reference(free: np.ndarray, pad: float) -> None:
    # Cones whose parameters are equal in every pose are scored on one pose.
    assert _SHARED_MIN_POSES <= 1200
    frame, cam, pose = scene(11)
    model = ObservationModel(raster_pad_px=pad)
    feats = model.prepare(frame)
    rng = np.random.default_rng(12)
    poses = np.tile(pose, (1200, 1))  # at least _SHARED_MIN_POSES
    poses[:, free] += rng.normal(0.0, 0.3, (1200, free.size))
    fast = model.log_likelihood(feats, poses, SHAPE, cam)
    np.testing.assert_array_equal(fast, reference_log_likelihood(model, feats, poses, SHAPE, cam))
    # -0.0 and 0.0 are different bits: the cone they touch is not shared.
    poses[:, 6] = 0.0
    poses[::2, 6] = -0.0
    fast = model.log_likelihood(feats, poses, SHAPE, cam)
    np.testing.assert_array_equal(fast, reference_log_likelihood(model, feats, poses, SHAPE, cam))


def test_scores_do_not_depend_on_how_the_poses_are_split() -> None:
    # Many poses are scored in equal passes of at most _CHUNK_POSES; each pose
    # on its own, so one call and calls on pieces give the same bits, with the
    # whole-body tasks' backdrop and coverage terms too.
    for n in (1, 2, 3071, 3072, 3073, 6145, 10_000, 25_000):
        size = _chunk_size(n)
        passes = -(-n // size)
        assert size <= _CHUNK_POSES and n - (passes - 1) * size >= min(n, size - passes + 1)
        assert passes == -(-n // _CHUNK_POSES)
    env = gym.make("humotion_gym/BodyTrack-v1", terminate_on_lost=False)
    obs, info = env.reset(seed=4)  # a skip: the figure leaves its first place at once
    base = env.unwrapped
    model = base.observation_model
    assert model.backdrop and model.coverage_weight > 0
    pose = info["initial_pose"]
    free = base.task.free_indices
    colors, backdrop, floor = model.read_first_frame(obs, pose, base.shape, info["camera"])
    for _ in range(base.episode_frames):  # a frame where the figure left its first place
        frame, *_, step_info = env.step(np.zeros(env.action_space.shape, np.float32))
        given = GivenBody(pose, free, base.shape, step_info["camera"], colors, backdrop, floor)
        feats = model.prepare(frame, given)
        if feats.coverage is not None and feats.coverage.shape[1] > 20:
            break
    assert feats.coverage is not None and feats.coverage.shape[1] > 20
    rng = np.random.default_rng(5)
    poses = pose + rng.normal(0.0, 0.1, (7001, 25))
    poses[:, :3] = pose[:3] + rng.normal(0.0, 80.0, (7001, 3))
    whole = model.log_likelihood(feats, poses, base.shape, step_info["camera"])
    assert np.isfinite(whole).all() and np.unique(whole).size > 1000
    for cuts in ((3500,), (1200, 4000), (3072, 6144)):
        parts = [
            model.log_likelihood(feats, piece, base.shape, step_info["camera"])
            for piece in np.split(poses, cuts)
        ]
        np.testing.assert_array_equal(np.concatenate(parts), whole)
    env.close()


def test_parameter_rows_are_the_kinematics_order() -> None:
    # _fixed_cones reads the kinematics' (25, N) single-precision rows.
    params = np.random.default_rng(13).normal(size=(50, 25))
    work = {
        "params": np.empty((25, 50), np.float32),
        "trig": np.empty((2, 22, 50), np.float32),
        "keypoints": np.empty((3, 15, 50), np.float32),
    }
    _batch_kinematics(params, SHAPE, np.float32, work=work)
    np.testing.assert_array_equal(work["params"], params[:, _PARAM_ROWS].T.astype(np.float32))


def test_cone_parameters_follow_the_kinematic_tree() -> None:
    moves = _cone_parameters()
    names = body.CONE_NAMES
    assert moves[:, :6].all()  # the root moves every cone
    assert moves.sum(axis=0)[6:9].tolist() == [1, 1, 1]  # the neck only the head
    assert moves[names.index("head"), 6:9].all()
    elbow = body.PARAM_NAMES.index("r_elbow")
    assert np.flatnonzero(moves[:, elbow]).tolist() == [names.index("r_forearm")]


def reference_edge_distance(model: ObservationModel, frame: np.ndarray) -> np.ndarray:
    """Each orientation bin's truncated edge distance, with np.nonzero and no shortcut."""
    smooth = model._smoothed(frame, "test")
    h, w, channels = smooth.shape
    edges = cv2.Canny(smooth if channels == 3 else smooth[:, :, 0], 40.0, 100.0)
    n_bins = model.orientation_bins
    bins = np.zeros((n_bins, h, w), np.uint8)
    ys, xs = np.nonzero(edges)
    if ys.size:
        gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3).reshape(h, w, channels)[ys, xs]
        gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3).reshape(h, w, channels)[ys, xs]
        best = np.argmax(gx * gx + gy * gy, axis=1)
        pick = np.arange(ys.size)
        theta = np.arctan2(gy[pick, best], gx[pick, best])
        lo = np.floor(np.mod(theta, np.pi) * (n_bins / np.pi)).astype(np.intp) % n_bins
        bins[lo, ys, xs] = 255
        bins[(lo + 1) % n_bins, ys, xs] = 255
    dist = np.full((n_bins, h, w), np.inf, np.float32)
    for b in range(n_bins):
        if bins[b].any():
            dist[b] = cv2.distanceTransform(255 - bins[b], cv2.DIST_L2, cv2.DIST_MASK_5)
    dist *= np.float32(1.0 / (h / model.reference_height))
    return np.minimum(dist, np.float32(model.edge_truncation))


@pytest.mark.parametrize("size", [64, 96, 128])
def test_frame_features_match_the_reference(size: int) -> None:
    # Edge pixels listed by OpenCV, no product by 1 at the reference height.
    model = ObservationModel()
    frame, _, _ = scene(size, size=size)
    for image in (frame, frame[:, :, :1], np.full_like(frame, 90)):
        feats = model.prepare(image)
        np.testing.assert_array_equal(feats.distance, reference_edge_distance(model, image))


# -- the tree prior -------------------------------------------------------------


@pytest.fixture(scope="module")
def priors() -> dict[str, tree.TreeParams]:
    motions = synthetic_library().split("train").motions[:6]
    return {"body": tree.fit(motions), "arm": tree.fit(motions, free=ARM)}


def reference_descend(
    fitted: tree.TreeParams, coefficients: np.ndarray, beta: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 7's descent one level at a time (the per-level rule), with the log probability."""
    n, b = coefficients.shape
    scaled = coefficients.T / (np.sqrt(beta) * fitted.sigma[:, None])
    wanted = (rng.standard_normal((b, n)) > -scaled).astype(np.int64)
    prefix = np.zeros(n, dtype=np.int64)
    log_prob = np.zeros(n)
    for level in range(b):
        flags = fitted.node_flags[prefix + (1 << level) - 1]
        bit = np.where(flags == 3, wanted[level], flags == 2).astype(np.int64)
        both = flags == 3
        log_prob[both] += log_ndtr((2 * bit[both] - 1) * scaled[level, both])
        prefix = 2 * prefix + bit
    return fitted.offsets[prefix], fitted.offsets[prefix + 1], log_prob


def reference_choose(
    fitted: tree.TreeParams,
    coefficients: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    beta: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 3 in each leaf, by fancy indexing over every member of every leaf.

    One running sum over all leaves' weights, laid end to end, as the prior's
    vectorised draw uses (so its rounding is the same).
    """
    sizes = hi - lo
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    owner = np.repeat(np.arange(lo.size), sizes)
    member = lo[owner] + np.arange(sizes.sum()) - starts[owner]
    diff = (fitted.coefficients[member] - coefficients[owner]) / fitted.sigma
    logw = np.zeros(member.size)
    for j in range(diff.shape[1]):  # the squares summed component by component, in order
        logw += diff[:, j] * diff[:, j]
    logw *= -0.5 / beta
    peak = np.maximum.reduceat(logw, starts)
    cum = np.cumsum(np.exp(logw - peak[owner]))
    before = np.concatenate([[0.0], cum])[starts]
    mass = cum[starts + sizes - 1] - before
    pick = np.searchsorted(cum, before + rng.random(lo.size) * mass, side="right")
    chosen = np.clip(pick, starts, starts + sizes - 1) - starts + lo
    return chosen, peak + np.log(np.maximum(mass, np.finfo(float).tiny))


@pytest.mark.parametrize("kernels", [True, False], ids=["compiled", "numpy"])
@pytest.mark.parametrize("which", ["body", "arm"])
@pytest.mark.parametrize("beta", [0.3, 1.0, 5.0])
def test_tree_descent_and_leaf_choice_match_the_reference(
    priors, which, beta, kernels, monkeypatch
) -> None:
    # The compiled descent and leaf kernels (the `fast` extra) and the numpy
    # path both give the reference's leaves, windows and masses, bit for bit.
    from humotion_gym import _kernels

    if kernels and not _kernels.enabled():
        pytest.skip("the compiled kernels are off (numba missing or HUMOTION_NUMBA=0)")
    if not kernels:
        monkeypatch.setattr(_kernels, "ENABLED", False)
    fitted = priors[which]
    rng = np.random.default_rng(int(beta * 10))
    c = rng.normal(0.0, 1.5, (4000, fitted.depth)) * fitted.sigma
    for want_log_prob in (False, True):
        ours, theirs = np.random.default_rng(1), np.random.default_rng(1)
        lo, hi, log_prob = tree._descend(fitted, c, beta, ours, want_log_prob)
        ref_lo, ref_hi, ref_log_prob = reference_descend(fitted, c, beta, theirs)
        assert ours.random() == theirs.random()  # the generator left where numpy leaves it
        np.testing.assert_array_equal(lo, ref_lo)
        np.testing.assert_array_equal(hi, ref_hi)
        if want_log_prob:
            np.testing.assert_array_equal(log_prob, ref_log_prob)
        else:
            assert log_prob is None
    many = np.flatnonzero(hi - lo > 1)
    assert many.size > 100  # the draw has leaves to choose in
    chosen, log_mass = tree._choose_ragged(
        fitted, c[many], lo[many], hi[many], beta, np.random.default_rng(2)
    )
    ref_chosen, ref_log_mass = reference_choose(
        fitted, c[many], lo[many], hi[many], beta, np.random.default_rng(2)
    )
    np.testing.assert_array_equal(chosen, ref_chosen)
    np.testing.assert_array_equal(log_mass, ref_log_mass)
    # The whole choice, leaves of one window included (the compiled one finds
    # the others itself), and the generator left where the reference leaves it.
    ours, theirs = np.random.default_rng(3), np.random.default_rng(3)
    chosen, no_mass = tree._choose_weighted(fitted, c, lo, hi, beta, ours)
    want = lo.copy()
    want[many] = reference_choose(fitted, c[many], lo[many], hi[many], beta, theirs)[0]
    assert no_mass is None and ours.random() == theirs.random()
    np.testing.assert_array_equal(chosen, want)


def test_descent_tables_cover_depths_that_are_not_multiples_of_eight(priors) -> None:
    # Random node flags (1: only the negative child holds windows, 2: only the
    # positive one, 3: both) for trees of 1 to 17 levels: tables of 8 levels
    # and a shorter last one.
    rng = np.random.default_rng(5)
    for depth in (1, 3, 8, 11, 16, 17):
        flags = rng.integers(1, 4, (1 << depth) - 1).astype(np.uint8)
        tables = tree._descent_tables(flags, depth)
        wanted = rng.random((depth, 3000)) < 0.5
        prefix = np.zeros(3000, dtype=np.int64)
        for level in range(depth):
            node = flags[prefix + (1 << level) - 1]
            bit = np.where(node == 3, wanted[level], node == 2)
            prefix = 2 * prefix + bit
        np.testing.assert_array_equal(tree._descend_by_table(tables, wanted), prefix)
        if _kernels.enabled():  # the compiled descent walks the same tables, packed
            c = rng.normal(0.0, 1.0, (3000, depth))
            scale = rng.uniform(0.5, 2.0, depth)
            draws = np.random.default_rng(depth).standard_normal((depth, 3000))
            wanted = draws > -(c.T / scale[:, None])
            offsets = np.arange((1 << depth) + 1, dtype=np.intp)
            packed = tree._packed_tables(flags, depth)
            lo, hi = _kernels.tree_descend(c, scale, np.random.default_rng(depth), packed, offsets)
            np.testing.assert_array_equal(lo, tree._descend_by_table(tables, wanted))
            np.testing.assert_array_equal(hi, lo + 1)


# -- the filter -------------------------------------------------------------------


def test_log_sum_exp_is_scipys() -> None:
    rng = np.random.default_rng(0)
    for trial in range(3000):
        n = int(rng.choice([1, 2, 3, 17, 300, 3000]))
        a = rng.normal(rng.uniform(-50, 50), rng.uniform(0.01, 30), n)
        if trial % 3 == 0:
            a = np.round(a)  # ties at the maximum
        if trial % 5 == 0:
            a[rng.random(n) < 0.3] = -np.inf
        if trial % 97 == 0:
            a[:] = -np.inf
        if trial % 89 == 0:
            a[rng.integers(n)] = np.nan
        expected = logsumexp(a)
        got = log_sum_exp(a)
        assert (np.isnan(got) and np.isnan(expected)) or got == expected
    loglik = rng.normal(-5.0, 3.0, 500)
    loglik[::7] = -np.inf
    expected = np.exp(2.0 * (loglik - loglik.max()))
    np.testing.assert_allclose(tempered_weights(loglik, 2.0), expected / expected.sum())


def test_resampling_copies_the_same_rows() -> None:
    rng = np.random.default_rng(1)
    state = ParticleState(
        rng.normal(size=(500, 25)),
        {
            "history": rng.normal(size=(500, 11, 25)).astype(np.float32),
            "window": rng.integers(0, 100, 500),
            "fortran": np.asfortranarray(rng.normal(size=(500, 3))),
        },
    )
    weights = rng.random(500)
    index = systematic_resample(weights / weights.sum(), rng)
    moved = state.take(index)
    np.testing.assert_array_equal(moved.pose, state.pose[index])
    for key, value in state.extra.items():
        np.testing.assert_array_equal(moved.extra[key], value[index])
        assert moved.extra[key].dtype == value.dtype
    mask = rng.random(500) < 0.5  # a mask selects rows, as fancy indexing does
    np.testing.assert_array_equal(state.take(mask).pose, state.pose[mask])


def test_filter_step_matches_a_plain_step(priors) -> None:
    # One CONDENSATION step written out with scipy's logsumexp and fancy indexing.
    fitted = priors["arm"]

    class Quadratic:
        def log_likelihood(self, frame, poses):
            return -0.5 * np.sum((poses - frame) ** 2, axis=1) / 0.01

    start = fitted.frames[fitted.window_end[50]]
    pf = ParticleFilter(tree, fitted, Quadratic(), 400, np.ones(ARM.size, bool))
    pf.reset(start, np.random.default_rng(3))
    state, log_w = pf.state, pf.log_weights
    estimate = pf.step(start + 0.05)
    rng = np.random.default_rng(3)
    tree.initial(fitted, start, 400, rng)
    moved = tree.transition(fitted, state, rng)
    log_w = log_w + Quadratic().log_likelihood(start + 0.05, moved.pose)
    log_w = log_w - logsumexp(log_w)
    weights = np.exp(log_w)
    ang = moved.pose[:, np.ones(ARM.size, bool)]  # a mask's copy: its layout sets BLAS's order
    circ = np.arctan2(weights @ np.sin(ang), weights @ np.cos(ang))
    lin = weights @ moved.pose
    expected = circ + 2 * np.pi * np.round((lin - circ) / (2 * np.pi))
    # The filter's circular mean takes single-precision sines of the offsets
    # from the linear mean (weighted_mean): the same angle to 1e-6 of the spread.
    spread = float(np.sqrt(weights @ (moved.pose - lin) ** 2).max())
    np.testing.assert_allclose(estimate, expected, rtol=0, atol=1e-6 * spread)
    index = systematic_resample(weights, rng)
    np.testing.assert_array_equal(pf.state.pose, moved.pose[index])
    np.testing.assert_array_equal(pf.state.extra["history"], moved.extra["history"][index])


def reference_temper(loglik: np.ndarray, alpha: float, iterations: int = 60):
    """temper_for_survival's bisection written with a fresh array per round."""
    n = loglik.shape[0]
    ok = np.isfinite(loglik)
    if not ok.any():
        return 1.0, np.full(n, 1.0 / n)
    centred = np.where(ok, loglik - loglik[ok].max(), -np.inf)

    def weights(beta):
        w = np.exp(beta * centred)
        return w / w.sum()

    spread = float(-centred[ok].min())
    if spread <= 0.0 or ok.sum() <= alpha * n:
        return 1.0, weights(1.0)
    lo, hi = np.log(1e-8 / spread), np.log(1e8 / spread)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if float(1.0 / np.sum(np.square(weights(float(np.exp(mid)))))) > alpha * n:
            lo = mid
        else:
            hi = mid
    beta = float(np.exp(0.5 * (lo + hi)))
    return beta, weights(beta)


def test_annealing_exponents_match_the_reference() -> None:
    rng = np.random.default_rng(4)
    for trial in range(300):
        n = int(rng.choice([1, 5, 300, 3000]))
        loglik = rng.normal(-10.0, rng.uniform(0.01, 20.0), n)
        if trial % 4 == 0:
            loglik[rng.random(n) < 0.3] = -np.inf
        if trial % 25 == 0:
            loglik[:] = -3.0
        alpha = float(rng.uniform(0.05, 0.95))
        beta, weights = temper_for_survival(loglik, alpha)
        ref_beta, ref_weights = reference_temper(loglik, alpha)
        assert beta == ref_beta
        np.testing.assert_array_equal(weights, ref_weights)
