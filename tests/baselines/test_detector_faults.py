"""The detector's contracts one by one (``baselines.detector``), against hand-made answers.

Each test holds one promise of the detector's docstrings to an oracle written
here: the shipped network finds a rendered figure, the decoding's window at a
map's border, the memo's least-recently-used order, the sigmas of a record,
the likelihood's widths per keypoint, the training loss written out cell by
cell, the training's seeds, and the error table of a few hand-made errors.
"""

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("torch", reason="the detector runs on torch (the rl extra)")

import torch as th
from test_detector import _Fixed  # a detector that answers given points

import humotion_gym  # noqa: F401
from baselines.agents import AGENTS, tracking_env
from baselines.detector import train as training
from baselines.detector.data import FrameSet, render_frames
from baselines.detector.network import (
    HEATMAP_SIZE,
    Detector,
    HeatmapNet,
    decode,
    pixel_to_cell,
    save_weights,
)
from baselines.detector.settings import DetectorTerm
from baselines.detector.term import (
    Detections,
    DetectorLikelihood,
    _load,
    detector_model,
    shipped_detector,
    validation_sigmas,
)
from humotion_gym.body import KEYPOINT_NAMES, default_shape, forward_kinematics, standing_pose
from humotion_gym.camera import fit_camera
from humotion_gym.envs.tasks import get_task

FloatArray = np.ndarray


def _rendered(seed: int, split: str = "train") -> tuple[np.ndarray, FloatArray]:
    """One BodyTrack frame of a split and its 15 true keypoints projected, pixels."""
    env = gym.make("humotion_gym/BodyTrack-v2", views=1, split=split, terminate_on_lost=False)
    obs, _ = env.reset(seed=seed)
    base = tracking_env(env)
    truth = base.camera.project(forward_kinematics(base.true_pose(), base.shape))
    env.close()
    return obs["frame"], truth


def test_the_shipped_detector_finds_rendered_figures() -> None:
    """On rendered frames the shipped network's keypoints lie within a few pixels of the
    truth (its validation median is about 1 px), and a uint8 frame is all it takes."""
    detector = Detector(shipped_detector()[0].net)  # no memo: the network itself
    errors = []
    for seed in (2, 3):
        frame, truth = _rendered(seed)
        errors.append(np.linalg.norm(detector.detect(frame[None])[0] - truth, axis=-1))
    assert np.median(errors) < 5.0
    with pytest.raises(ValueError, match="uint8"):
        detector.detect(frame[None].astype(np.float32))


def _reference_decode(z: FloatArray, radius: int) -> FloatArray:
    """The softmax's expectation over the window about the argmax, cell by cell."""
    h, w = z.shape
    py, px = np.unravel_index(np.argmax(z), z.shape)
    cells = [(y, x) for y in range(py - radius, py + radius + 1)
             for x in range(px - radius, px + radius + 1) if 0 <= y < h and 0 <= x < w]  # fmt: skip
    weights = np.array([np.exp(z[y, x] - z[py, px]) for y, x in cells])
    weights /= weights.sum()
    return np.array([sum(p * x for p, (_, x) in zip(weights, cells, strict=True)),
                     sum(p * y for p, (y, _) in zip(weights, cells, strict=True))])  # fmt: skip


def test_decode_clips_its_window_at_the_maps_border() -> None:
    """Peaks on and beside every border: the window keeps the map's cells alone, once each."""
    rng = np.random.default_rng(0)
    maps = rng.normal(0.0, 1.0, (12, HEATMAP_SIZE, HEATMAP_SIZE))
    last = HEATMAP_SIZE - 1
    peaks = [(0, 0), (last, last), (0, last), (last, 0), (1, 15), (15, last - 1),
             (last - 2, 7), (9, 2), (last, 16), (16, 0), (2, last - 2), (20, 20)]  # fmt: skip
    for m, (y, x) in zip(maps, peaks, strict=True):
        m[y, x] = 3.0  # the argmax; its neighbours' weights stay comparable
    got = decode(maps)
    want = np.array([_reference_decode(m, 3) for m in maps])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_the_memo_forgets_the_least_recently_used_frame() -> None:
    """A frame asked for again stays remembered; the one untouched longest is dropped."""
    th.manual_seed(0)
    detector = Detector(HeatmapNet(4), memo=2)
    asked: list[int] = []
    logits = detector.logits

    def counted(frames: np.ndarray) -> np.ndarray:
        asked.append(len(frames))
        return logits(frames)

    detector.logits = counted  # type: ignore[method-assign]
    a, b, c = np.random.default_rng(0).integers(0, 256, (3, 1, 128, 128, 3), dtype=np.uint8)
    for frames in (a, b, a, c):  # a was used after b: c pushes b out
        detector.detect(frames)
    assert asked == [1, 1, 1]
    detector.detect(a)
    assert asked == [1, 1, 1]  # still remembered
    detector.detect(b)
    assert asked == [1, 1, 1, 1]  # forgotten, asked again


def test_a_records_medians_become_sigmas() -> None:
    """Each keypoint's sigma is its median error over sqrt(2 ln 2) = 1.17741, the median
    distance of a standard 2D Gaussian (checked here by sampling), never its mean."""
    radii = np.linalg.norm(np.random.default_rng(0).standard_normal((200_000, 2)), axis=1)
    assert np.median(radii) == pytest.approx(1.17741, rel=0.01)
    medians = np.linspace(1.0, 3.0, 15)
    meta = {"validation_error_px": {n: {"median": float(m), "mean": 9.0}
                                    for n, m in zip(KEYPOINT_NAMES, medians, strict=True)}}  # fmt: skip
    np.testing.assert_allclose(validation_sigmas(meta), medians / 1.1774100225154747, rtol=1e-12)
    del meta["validation_error_px"]["l_ankle"]
    with pytest.raises(ValueError, match="l_ankle"):
        validation_sigmas(meta)


def _scene():
    """A standing body, a camera that sees it, and its 15 keypoints' pixels."""
    shape = default_shape()
    pose = standing_pose(shape)
    points3d = forward_kinematics(pose, shape)
    camera = fit_camera(points3d[None], 128, 128, 50.0, azimuth_deg=30.0)
    return shape, pose, camera, camera.project(points3d)


def test_each_keypoint_has_its_own_scaled_width() -> None:
    """For a subset of keypoints with different sigmas and a sigma scale, the term is
    ``-sum_k min(|pi(k(x)) - d_k|^2 / (2 (s sigma_k)^2), cap)`` over that subset."""
    shape, pose, camera, points = _scene()
    poses = pose + np.zeros((4, 25))
    poses[1:, 0] += [20.0, 60.0, 400.0]  # 2, 6 and 40 cm to the side
    detected = points + np.random.default_rng(1).normal(0.0, 1.0, points.shape)
    sigmas = np.linspace(1.0, 4.0, 15)
    keypoints = np.array([3, 7, 9, 14])
    term = DetectorTerm(sigma_scale=2.5, image_weight=0.0, cap=30.0)
    model = DetectorLikelihood(None, _Fixed(detected), sigmas, keypoints, term)
    seen = model.prepare(np.zeros((128, 128, 3), np.uint8))
    np.testing.assert_array_equal(seen.points, detected[keypoints])
    got = model.log_likelihood(seen, poses, shape, camera)
    want = np.zeros(4)
    for n, p in enumerate(poses):
        pixels = camera.project(forward_kinematics(p, shape))
        for k in keypoints:
            cost = np.sum((pixels[k] - detected[k]) ** 2) / (2 * (2.5 * sigmas[k]) ** 2)
            want[n] -= min(cost, 30.0)
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert want[3] > -4 * 30.0 - 1e-9 and want[3] < want[1]  # the cap bites, the rest falls


class _Image:
    """An image model stand-in whose scores are known: ``pose[0]`` and its group index."""

    def log_likelihood(self, features, params, shape, camera):
        assert features == "features"
        return params[:, 0].copy()

    def log_likelihood_partial(self, features, params, shape, camera, groups):
        assert features == "features"
        return params[:, :1] + np.arange(len(groups) + 1)[None]


def test_the_partial_figures_add_the_weighted_image_term() -> None:
    """Per group, the partial likelihood is the keypoints' partial term plus
    ``image_weight`` times the image model's partial term."""
    shape, pose, camera, points = _scene()
    poses = pose + np.zeros((3, 25))
    poses[:, 0] += [0.0, 30.0, -50.0]
    groups = [[0, 1], [2, 3], [8, 9]]
    alone = DetectorLikelihood(_Image(), _Fixed(points), np.full(15, 2.0), np.arange(15),
                               DetectorTerm(image_weight=0.0))  # fmt: skip
    both = DetectorLikelihood(_Image(), _Fixed(points), np.full(15, 2.0), np.arange(15),
                              DetectorTerm(image_weight=0.25))  # fmt: skip
    frame = Detections("features", points)
    keypoints = alone.log_likelihood_partial(frame, poses, shape, camera, groups)
    got = both.log_likelihood_partial(frame, poses, shape, camera, groups)
    image = poses[:, :1] + np.arange(4)[None]
    np.testing.assert_allclose(got, keypoints + 0.25 * image, rtol=1e-12)
    whole = both.log_likelihood(frame, poses, shape, camera)
    np.testing.assert_allclose(whole, keypoints[:, -1] + 0.25 * poses[:, 0], rtol=1e-12)


def test_bad_sigmas_and_settings_are_refused() -> None:
    """Sigmas must be 15 finite positives; the term's numbers finite."""
    for sigmas in (np.full(16, 2.0), np.r_[np.full(14, 2.0), np.inf], np.full(14, 2.0)):
        with pytest.raises(ValueError, match="sigmas"):
            DetectorLikelihood(None, _Fixed(np.zeros((15, 2))), sigmas, [0, 1])
    for kwargs in ({"sigma_scale": np.inf}, {"image_weight": np.inf}, {"image_weight": np.nan}):
        with pytest.raises(ValueError, match=next(iter(kwargs))):
            DetectorTerm(**kwargs)


def test_the_det_agents_add_the_whole_image_likelihood() -> None:
    """The +det agents add the detections to the image likelihood, kept whole."""
    assert AGENTS["pf-cv-det"].detector.image_weight == 1.0
    assert DetectorTerm().image_weight == 1.0


def test_the_detector_model_scores_the_tasks_keypoints() -> None:
    """A task's detector likelihood scores that task's error keypoints alone."""
    meta = {"validation_error_px": {n: {"median": 2.0} for n in KEYPOINT_NAMES}}
    task = get_task("ArmTrack-v2")
    model = detector_model(task, DetectorTerm(), (_Fixed(np.zeros((15, 2))), meta))
    np.testing.assert_array_equal(model.scorer.keypoints, task.error_keypoint_indices)
    assert model.scorer.keypoints.size < 15


def test_a_record_that_is_not_an_object_is_refused(tmp_path) -> None:
    """A detector's JSON record must be an object."""
    th.manual_seed(0)
    weights = save_weights(HeatmapNet(4).eval(), tmp_path / "list.npz")
    weights.with_suffix(".json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="expected an object"):
        _load(str(weights))


def test_frames_are_every_strideth_step_with_the_true_keypoints() -> None:
    """The first frame is the episode's first, seeded as documented, labelled with its
    truth projected; a stride of 2 keeps steps 0 and 2 of the stride-1 frames."""
    sources = [("BodyTrack-v2", 1)]
    one = render_frames(3, seed=4, stride=1, sources=sources)
    two = render_frames(2, seed=4, stride=2, sources=sources)
    np.testing.assert_array_equal(two.frames, one.frames[[0, 2]])
    np.testing.assert_array_equal(two.points, one.points[[0, 2]])
    assert not np.array_equal(one.frames[0], one.frames[2])
    frame, truth = _rendered(int(np.random.default_rng(4).integers(2**31)))
    np.testing.assert_array_equal(one.frames[0], frame)
    np.testing.assert_allclose(one.points[0], truth, rtol=1e-12)
    with pytest.raises(ValueError, match="stride"):
        render_frames(2, stride=0)


def test_the_sources_take_turns() -> None:
    """Once the first source's episode ends, the next frame is the second source's."""
    sources = [("ArmTrack-v2", 1), ("BodyTrack-v2", 1)]  # a 30-frame episode first
    two = render_frames(2, seed=1, stride=1000, sources=sources)
    seeds = np.random.default_rng(1).integers(2**31, size=2)
    frame, truth = _rendered(int(seeds[1]))
    np.testing.assert_array_equal(two.frames[1], frame)
    np.testing.assert_allclose(two.points[1], truth, rtol=1e-12)


def test_validation_frames_are_the_validation_splits() -> None:
    """``split="validation"`` renders the validation persons' episode of the drawn seed."""
    held = render_frames(1, seed=6, split="validation", sources=[("BodyTrack-v2", 1)])
    frame, truth = _rendered(int(np.random.default_rng(6).integers(2**31)), "validation")
    np.testing.assert_array_equal(held.frames[0], frame)
    np.testing.assert_allclose(held.points[0], truth, rtol=1e-12)


def test_the_loss_is_cross_entropy_plus_half_the_expectations_l1() -> None:
    """The loss written out cell by cell: a Gaussian target of sigma 1 cell about each
    keypoint, its cross-entropy with the map's softmax plus 0.5 times the L1 distance of
    the map's expectation, averaged over the keypoints inside the frame."""
    rng = np.random.default_rng(0)
    logits = rng.normal(0.0, 2.0, (2, 15, HEATMAP_SIZE, HEATMAP_SIZE))
    points = rng.uniform(5.0, 120.0, (2, 15, 2))
    points[1, :5] = [-3.0, 50.0]  # outside the frame: no loss
    total, count = 0.0, 0
    grid = np.arange(HEATMAP_SIZE, dtype=np.float64)
    for b in range(2):
        for k in range(15):
            if points[b, k, 0] < 0:
                continue
            cx, cy = pixel_to_cell(points[b, k])
            target = np.exp(-((grid[None, :] - cx) ** 2 + (grid[:, None] - cy) ** 2) / 2.0)
            target /= target.sum()
            z = logits[b, k]
            log_p = z - z.max() - np.log(np.exp(z - z.max()).sum())
            p = np.exp(log_p)
            expect = np.array([np.sum(p * grid[None, :]), np.sum(p * grid[:, None])])
            total += -np.sum(target * log_p) + 0.5 * np.abs(expect - [cx, cy]).sum()
            count += 1
    got = float(training.loss_of(th.from_numpy(logits).float(), points))
    assert got == pytest.approx(total / count, rel=1e-4)


def _tiny_frames(n: int) -> FrameSet:
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (n, 128, 128, 3), dtype=np.uint8)
    return FrameSet(frames, rng.uniform(10.0, 110.0, (n, 15, 2)), ("x",))


def test_training_is_its_seed_alone_and_ends_in_evaluation_mode() -> None:
    """Two trainings of one seed give the same weights, another seed others; a last
    batch smaller than the rest is trained on; the network comes back in eval mode."""
    data = _tiny_frames(5)  # batches of 2, 2 and 1

    def weights(seed: int) -> list[th.Tensor]:
        settings = training.TrainSettings(epochs=1, batch=2, width=4, seed=seed, threads=1)
        net = training.train(data, settings)
        assert not net.training
        return list(net.state_dict().values())

    a, b, c = weights(0), weights(0), weights(1)
    assert all(th.equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(th.equal(x, y) for x, y in zip(a, c, strict=True))


def test_pixel_errors_are_distances_and_nan_outside_the_frame() -> None:
    """Each error is the detection's distance to the truth; NaN where the truth is off-frame."""
    points = np.zeros((3, 15, 2)) + 50.0
    points[1, 2] = [130.0, 40.0]
    points[2, 4] = [20.0, -1.0]
    found = np.zeros((15, 2)) + 50.0
    found[0] = [53.0, 54.0]  # 5 px from every frame's keypoint 0
    data = FrameSet(np.zeros((3, 128, 128, 3), np.uint8), points, ("x",))
    errors = training.pixel_errors(_Fixed(found), data, batch=2)
    want = np.zeros((3, 15))
    want[:, 0] = 5.0
    want[1, 2] = want[2, 4] = np.nan
    np.testing.assert_allclose(errors, want, rtol=1e-12)


def test_the_error_table_of_a_few_errors() -> None:
    """Median, mean, RMS and the share over 5 px, NaN left out, for a keypoint and all."""
    errors = np.full((4, 15), 1.0)
    errors[:, 0] = [3.0, 4.0, 5.0, np.nan]
    table = training.error_summary(errors)
    # 3, 4, 5: median 4, mean 4, RMS sqrt(50 / 3) = 4.082, none over 5
    assert table["pelvis"] == {"median": 4.0, "mean": 4.0, "rms": 4.082, "over_5px": 0.0}
    assert table["neck"]["rms"] == 1.0
    # all 59 finite errors: 56 ones and 3, 4, 5; median 1, mean 68 / 59 = 1.153
    assert table["all"]["median"] == 1.0 and table["all"]["mean"] == pytest.approx(1.153)


def test_the_record_measures_the_validation_frames(tmp_path, monkeypatch) -> None:
    """make_detector trains on the training split and measures on the validation split,
    drawn with their own seed: the record's errors are the validation frames'."""
    drawn = []

    def frames(n, seed=0, split="train", data_dir=None):
        drawn.append((split, seed))
        data = _tiny_frames(n)
        offset = 0.0 if split == "train" else 7.0
        return FrameSet(data.frames, data.points + offset, (split,))

    th.manual_seed(0)
    net = HeatmapNet(4).eval()
    monkeypatch.setattr(training, "render_frames", frames)
    monkeypatch.setattr(training, "train", lambda data, settings, log=None: net)
    settings = training.TrainSettings(epochs=1, width=4, seed=3)
    meta = training.make_detector(tmp_path / "d", 4, settings, validation_frames=3)
    assert drawn == [("train", 3), ("validation", training.VALIDATION_SEED)]
    held = frames(3, split="validation")
    want = training.error_summary(training.pixel_errors(Detector(net), held))
    assert meta["validation_error_px"] == want
    assert json.loads((tmp_path / "d" / "detector.json").read_text())["frames"] == 4
