"""The learned 2D keypoint detector and its likelihood term (``baselines.detector``)."""

import json
import zipfile
from importlib import resources

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("torch", reason="the detector runs on torch (the rl extra)")

import humotion_gym  # noqa: F401
from baselines.agents import AGENTS, ParticleFilterAgent, make, tracking_env
from baselines.cli import main
from baselines.detector.network import (
    HEATMAP_SIZE,
    Detector,
    HeatmapNet,
    cell_to_pixel,
    decode,
    load_weights,
    pixel_to_cell,
    save_weights,
)
from baselines.detector.settings import DetectorTerm
from baselines.detector.term import (
    SHIPPED_META,
    SHIPPED_WEIGHTS,
    Detections,
    DetectorLikelihood,
    shipped_detector,
    validation_sigmas,
)
from baselines.diagnostics.oracle import OracleObservation, OracleSettings, TruthOracle
from baselines.leaderboard.evaluation import run_episode
from baselines.observation import task_model
from humotion_gym.body import forward_kinematics
from humotion_gym.envs.tasks import get_task

CHECKPOINTS = resources.files("baselines") / "checkpoints"


def _gaussian_logits(x, y, sigma=1.0, size=HEATMAP_SIZE):
    grid = np.arange(size, dtype=np.float64)
    return -((grid[None, :] - x) ** 2 + (grid[:, None] - y) ** 2) / (2 * sigma**2)


def test_decode_recovers_a_known_peak_to_a_fraction_of_a_cell():
    peaks = [(13.3, 17.7), (5.5, 25.2), (20.05, 8.95)]
    maps = np.stack([_gaussian_logits(x, y) for x, y in peaks])
    found = decode(maps[None])[0]
    np.testing.assert_allclose(found, peaks, atol=0.01)
    # the mutation: the peak cell alone (no window) is off by up to half a cell
    assert np.abs(decode(maps, radius=0) - np.array(peaks)).max() > 0.2
    # a second, weaker mode elsewhere does not pull the window's expectation
    two = np.logaddexp(_gaussian_logits(10.2, 10.6), _gaussian_logits(24.0, 20.0) - 1.0)
    np.testing.assert_allclose(decode(two), [10.2, 10.6], atol=0.02)


def test_cells_and_pixels_are_each_others_inverse():
    px = np.array([[0.0, 0.0], [63.5, 100.25], [127.0, 3.0]])
    np.testing.assert_allclose(cell_to_pixel(pixel_to_cell(px)), px)
    # a cell's centre is the middle of its four pixels
    assert cell_to_pixel(np.array([0.0]))[0] == pytest.approx(1.5)


def test_shipped_weights_load_without_pickle_and_detect_deterministically():
    weights = CHECKPOINTS / SHIPPED_WEIGHTS
    with np.load(str(weights), allow_pickle=False) as data:  # no object arrays
        assert all(data[k].dtype != object for k in data.files)
    assert weights.stat().st_size <= 10 * 2**20
    meta = json.loads((CHECKPOINTS / SHIPPED_META).read_text())
    assert meta["command"].startswith("humotion-gym detector train")
    assert "seed" in meta["settings"]
    assert meta["training_persons"] and meta["validation_persons"]
    assert not set(meta["training_persons"]) & set(meta["validation_persons"])
    sigmas = validation_sigmas(meta)
    assert sigmas.shape == (15,) and np.all(sigmas > 0)
    detector, _ = shipped_detector()
    frames = np.random.default_rng(0).integers(0, 256, (3, 128, 128, 3), dtype=np.uint8)
    a, b = detector.detect(frames), detector.detect(frames)
    assert a.shape == (3, 15, 2)
    np.testing.assert_array_equal(a, b)
    # one frame at a time gives the batch's answer
    np.testing.assert_allclose(detector.detect(frames[1:2])[0], a[1], atol=1e-3)
    with pytest.raises(ValueError, match=r"frames: expected \(B, 128, 128, 3\) uint8"):
        detector.detect(frames[:, :64])


def test_weights_round_trip_and_foreign_files_are_refused(tmp_path):
    import torch as th

    th.manual_seed(0)
    net = HeatmapNet(8).eval()
    path = save_weights(net, tmp_path / "d.npz")
    frames = np.random.default_rng(1).integers(0, 256, (2, 128, 128, 3), dtype=np.uint8)
    np.testing.assert_array_equal(Detector(net).logits(frames), Detector.load(path).logits(frames))
    # the memo answers a frame seen before with what the network gave it, and stays bounded
    plain, memo = Detector(net), Detector(net, memo=2)
    three = np.concatenate([frames, frames[:1] ^ 1])
    first = memo.detect(three)
    np.testing.assert_allclose(first, plain.detect(three), atol=1e-6)
    assert len(memo._memo) == 2
    np.testing.assert_array_equal(memo.detect(three[:0:-1]), first[:0:-1])  # remembered
    np.testing.assert_allclose(memo.detect(three[::-1]), first[::-1], atol=1e-6)
    # an object array needs pickle: refused
    np.savez(tmp_path / "bad.npz", a=np.array([{"x": 1}], dtype=object))
    with pytest.raises(ValueError, match="not a detector weights"):
        load_weights(tmp_path / "bad.npz")
    np.savez(tmp_path / "arch.npz", __arch__=np.array([8, 14, 128, 4]))
    with pytest.raises(ValueError, match="15 keypoints"):
        load_weights(tmp_path / "arch.npz")
    with pytest.raises(FileNotFoundError, match="detector train"):
        load_weights(tmp_path / "none.npz")
    assert zipfile.is_zipfile(path)
    # a damaged file, and weights that are not numbers: refused, never tracked with
    data = path.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="not a detector weights"):
        load_weights(tmp_path / "cut.npz")
    with zipfile.ZipFile(path) as archive:  # a byte in the middle of the largest array's data
        info = max(archive.infolist(), key=lambda i: i.compress_size)
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    flipped = bytearray(data)
    flipped[start + info.compress_size // 2] ^= 0xFF
    (tmp_path / "flipped.npz").write_bytes(bytes(flipped))
    with pytest.raises(ValueError, match="not a detector weights"):
        load_weights(tmp_path / "flipped.npz")
    with np.load(path) as stored:
        arrays = {k: stored[k] for k in stored.files}
    first = next(k for k, v in arrays.items() if v.dtype.kind == "f")
    arrays[first] = np.full_like(arrays[first], np.nan)
    np.savez(tmp_path / "nan.npz", **arrays)
    with pytest.raises(ValueError, match=f"non-finite weights in {first}"):
        load_weights(tmp_path / "nan.npz")


@pytest.fixture(scope="module")
def env():
    e = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    e.reset(seed=3)
    yield e
    e.close()


class _Fixed(Detector):
    """A detector that answers given points (the scoring is what is tested)."""

    def __init__(self, points):
        self.points = points

    def detect(self, frames):
        return np.repeat(self.points[None], len(frames), axis=0)


@pytest.mark.parametrize("kind", ["2d", "2d-unlabelled"])
def test_the_keypoint_term_is_the_oracles_scoring(env, kind):
    base = tracking_env(env)
    truth = base.true_pose()
    rng = np.random.default_rng(0)
    poses = np.vstack([truth, truth + rng.normal(0, 0.05, (8, 25)) * np.r_[[200.0] * 3, [1] * 22]])
    points = base.camera.project(forward_kinematics(truth, base.shape))
    points = points + rng.normal(0.0, 2.0, points.shape)
    sigma = 2.5
    term = DetectorTerm(image_weight=0.0, unlabelled=kind == "2d-unlabelled")
    model = DetectorLikelihood(
        task_model(get_task("BodyTrack-v2")), _Fixed(points), np.full(15, sigma), np.arange(15),
        term,
    )  # fmt: skip
    seen = Detections(None, points)
    oracle = TruthOracle(OracleSettings(kind), np.arange(15))
    expected = oracle.log_likelihood(
        OracleObservation(points, sigma), poses, base.shape, base.camera
    )
    got = model.log_likelihood(seen, poses, base.shape, base.camera)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    groups = [[0, 1], [2, 3], [8, 9]]
    np.testing.assert_allclose(
        model.log_likelihood_partial(seen, poses, base.shape, base.camera, groups),
        oracle.log_likelihood_partial(
            OracleObservation(points, sigma), poses, base.shape, base.camera, groups
        ),  # fmt: skip
        rtol=1e-12,
    )
    # the cap bounds each keypoint's cost: a pose far off scores at least -15 caps
    capped = DetectorLikelihood(
        model.image, _Fixed(points), np.full(15, sigma), np.arange(15),
        DetectorTerm(image_weight=0.0, cap=4.0),
    )  # fmt: skip
    far = poses.copy()
    far[:, 0] += 3000.0
    assert np.all(capped.log_likelihood(seen, far, base.shape, base.camera) >= -60.0 - 1e-9)
    assert np.all(model.log_likelihood(seen, far, base.shape, base.camera) < -60.0)  # mutation
    bad = poses[:2].copy()
    bad[1, 4] = np.nan
    assert capped.log_likelihood(seen, bad, base.shape, base.camera)[1] == -np.inf


def test_the_image_weight_adds_the_image_likelihood(env):
    base = tracking_env(env)
    obs, _ = env.reset(seed=3)
    truth = base.true_pose()
    poses = truth[None] + np.zeros((3, 25))
    poses[1:, 0] += [100.0, 300.0]
    points = base.camera.project(forward_kinematics(truth, base.shape))
    image = task_model(get_task("BodyTrack-v2"))

    def model(weight):
        return DetectorLikelihood(
            image,
            _Fixed(points),
            np.full(15, 2.0),
            np.arange(15),
            DetectorTerm(image_weight=weight),
        )

    alone = model(0.0)
    both = model(0.5)
    frame = obs["frame"]
    got = both.log_likelihood(both.prepare(frame), poses, base.shape, base.camera)
    keypoints = alone.log_likelihood(alone.prepare(frame), poses, base.shape, base.camera)
    pictured = image.log_likelihood(frame, poses, base.shape, base.camera)
    np.testing.assert_allclose(got, keypoints + 0.5 * pictured, rtol=1e-9)
    with pytest.raises(TypeError, match="Detections"):
        alone.log_likelihood(frame, poses, base.shape, base.camera)


def test_det_agents_track_end_to_end_on_the_synthetic_data():
    assert {"pf-cv-det", "pf-mix-det", "spf-mix-det"} <= set(AGENTS)
    e = gym.make("humotion_gym/BodyTrack-v2", views=2, episode_frames=4, terminate_on_lost=False)
    agent = make("pf-cv-det", e, n_particles=20, seed=1)
    assert isinstance(agent, ParticleFilterAgent)
    assert isinstance(agent.observation_model, DetectorLikelihood)
    assert not getattr(agent.observation_model, "reads_truth", False)
    result = run_episode(agent, e, seed=2)
    assert len(result.errors_mm) == 4 and np.all(np.isfinite(result.errors_mm))
    e.close()


@pytest.mark.parametrize(
    "argv",
    [
        ["detector", "train", "--frames", "100"],  # no --out
        ["detector", "train", "--out", "OUT", "--frames", "10"],
        ["detector", "train", "--out", "OUT", "--epochs", "0"],
        ["detector", "train", "--out", "OUT", "--lr", "-1"],
    ],  # bare "detector" prints its subcommands (test_cli_bad_inputs)
)
def test_bad_cli_arguments_exit_2(argv, tmp_path, capsys):
    argv = [str(tmp_path / "o") if a == "OUT" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]


def test_settings_refuse_nonsense():
    for kwargs, match in (
        ({"sigma_scale": 0.0}, "sigma_scale"),
        ({"image_weight": -1.0}, "image_weight"),
        ({"cap": 0.0}, "cap"),
    ):
        with pytest.raises(ValueError, match=match):
            DetectorTerm(**kwargs)


def test_rendered_labels_are_the_true_keypoints_projected_and_test_persons_are_refused():
    from baselines.detector.data import render_frames

    frames = render_frames(6, seed=0, sources=[("BodyTrack-v2", 2)], stride=3)
    assert frames.frames.shape == (6, 128, 128, 3) and frames.points.shape == (6, 15, 2)
    # views 0 and 1 of a step: one pose, two cameras, two different projections
    assert not np.allclose(frames.points[0], frames.points[1])
    assert np.all(np.isfinite(frames.points)) and frames.subjects
    with pytest.raises(ValueError, match="test persons"):
        render_frames(4, split="test")
    with pytest.raises(ValueError, match="n_frames"):
        render_frames(0)


def test_the_loss_prefers_the_true_heatmap():
    import torch as th

    from baselines.detector.train import loss_of

    points = np.array([[[40.0, 60.0]] * 15, [[100.0, 20.0]] * 15])
    cells = pixel_to_cell(points)
    right = np.stack([[_gaussian_logits(*c) for c in frame] for frame in cells])
    wrong = np.stack([[_gaussian_logits(*(c + 3.0)) for c in frame] for frame in cells])
    good = float(loss_of(th.from_numpy(right).float(), points))
    bad = float(loss_of(th.from_numpy(wrong).float(), points))
    assert good < bad
    # a keypoint outside the frame carries no loss
    outside = points.copy()
    outside[0] = [-50.0, 400.0]  # the first frame's keypoints all out of it
    only = float(loss_of(th.from_numpy(wrong[1:]).float(), points[1:]))
    assert float(loss_of(th.from_numpy(wrong).float(), outside)) == pytest.approx(only, rel=1e-6)


def test_cli_train_writes_weights_and_their_record(tmp_path):
    out = tmp_path / "det"
    argv = ["detector", "train", "--out", str(out), "--frames", "64", "--validation-frames",
            "16", "--epochs", "1", "--width", "4", "--threads", "1"]  # fmt: skip
    assert main(argv) == 0
    meta = json.loads((out / "detector.json").read_text())
    assert meta["command"].startswith("humotion-gym detector train --out")
    assert meta["settings"]["seed"] == 0 and meta["frames"] == 64
    assert set(meta["validation_error_px"]) >= {"pelvis", "l_wrist", "all"}
    assert not set(meta["training_persons"]) & set(meta["validation_persons"])
    Detector.load(out / "detector.npz")


def test_a_detectors_record_missing_or_damaged_is_named(tmp_path):
    import torch as th

    from baselines.detector.term import _load

    th.manual_seed(0)
    weights = save_weights(HeatmapNet(8).eval(), tmp_path / "d.npz")
    with pytest.raises(FileNotFoundError, match=r"d\.json: the detector's record is missing"):
        _load(str(weights))
    weights.with_suffix(".json").write_text("{cut")
    with pytest.raises(ValueError, match=r"d\.json: not a detector's JSON record"):
        _load(str(weights))


def test_detector_train_refuses_frames_beyond_memory_before_rendering(tmp_path, capsys):
    assert main(["detector", "train", "--out", str(tmp_path / "d"), "--frames", "2000000"]) == 2
    assert "--frames: 2,001,000 frames would take" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_a_training_that_diverges_saves_no_weights(tmp_path, monkeypatch):
    import torch as th

    import baselines.detector.train as training

    def diverged(frames, settings, log=None):
        net = HeatmapNet(8)
        with th.no_grad():
            next(iter(net.parameters())).fill_(float("nan"))
        return net

    monkeypatch.setattr(training, "train", diverged)
    settings = training.TrainSettings(epochs=1, width=8, lr=1e8)
    with pytest.raises(ValueError, match="diverged .*learning rate 1e\\+08.*lower --lr"):
        training.make_detector(tmp_path / "d", 64, settings, validation_frames=16)
    assert not (tmp_path / "d" / "detector.npz").exists()
