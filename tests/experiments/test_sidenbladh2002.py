"""Figures 3 and 4 of Sidenbladh, Black & Sigal (2002) for the tree prior."""

from __future__ import annotations

import functools
from types import SimpleNamespace

import numpy as np
import pytest

from baselines.experiments import sidenbladh2002
from baselines.priors import tree
from humotion_gym.mocap.library import synthetic_library


@pytest.fixture(scope="module")
def library():
    return synthetic_library()


@pytest.fixture(scope="module")
def body_prior(library):
    # Subject 1's six clips (walk, run, skip, arm swing, reach, wave), as in the tree's own tests.
    return tree.fit(library.split("train").motions[:6])


def test_fig3_spread_grows_with_beta(library, body_prior):
    test = library.split("test").motions
    walks = [m for m in test if m.label == "walk"]
    histories = np.array([m.params[t - tree.WINDOW : t + 1] for m in walks for t in (40, 120)])
    shapes = [m.shape for m in walks for _ in (40, 120)]
    spread = sidenbladh2002.next_pose_spread(
        body_prior, histories, shapes, (0.01, 0.1, 1.0), np.random.default_rng(9)
    )
    assert np.all(np.diff(spread) > 0), spread


def test_make_figures_and_cli(tmp_path, library):
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    from baselines.cli import build_parser
    from baselines.cli import tree as tree_cli

    small = library.filter(subjects=["synthetic-01", "synthetic-05"])
    paths = sidenbladh2002.make_figures(small, tmp_path, seed=0)
    assert set(paths) == {"fig3", "fig4"}
    for path in paths.values():
        assert path.is_file() and path.read_bytes()[:4] == b"\x89PNG"
    args = build_parser().parse_args(["tree", "figures", "--out-dir", str(tmp_path), "--seed", "3"])
    assert args.func is tree_cli._cmd_figures and args.seed == 3 and args.out_dir == tmp_path


def test_explained_variance_by_features_is_the_svd_of_each_feature_set(body_prior):
    rows = sidenbladh2002.explained_variance_by_features(body_prior, components=4, windows=500)
    assert [(r["features"], r["scaled"]) for r in rows] == [
        (f, s) for f in sidenbladh2002.FEATURE_SETS for s in (True, False)
    ]
    by = {(r["features"], r["scaled"]): r for r in rows}
    # the prior's own features: every free parameter's pose and velocity per frame
    both = by["pose+velocity", True]
    assert both["dimensions"] == by["pose", True]["dimensions"] + by["velocity", True]["dimensions"]
    assert (
        both["dimensions"]
        == body_prior.window * body_prior.components.shape[0] // body_prior.window
    )
    # an oracle: with every window sampled, the unscaled share is the SVD of the
    # prior's own centred windows (database_windows undoes nothing but Gamma)
    every = sidenbladh2002.explained_variance_by_features(
        body_prior, components=4, windows=body_prior.n_windows
    )
    x = tree.database_windows(body_prior) * np.sqrt(
        np.tile(body_prior.feature_var, body_prior.window)
    )
    power = np.linalg.svd(x - x.mean(axis=0), compute_uv=False) ** 2
    assert every[1]["explained"] == pytest.approx(power[:4].sum() / power.sum(), rel=1e-6)
    for r in rows:
        assert 0.0 < r["explained"] <= 1.0 + 1e-12
        assert 1 <= r["components_for_89"] <= r["dimensions"]
    full = sidenbladh2002.explained_variance_by_features(
        body_prior, components=both["dimensions"], windows=500
    )
    assert full[0]["explained"] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="at least 1"):
        sidenbladh2002.explained_variance_by_features(body_prior, components=0)


def test_cli_tree_variance_prints_each_feature_set(capsys):
    from baselines.cli import main

    assert main(["tree", "variance", "--windows", "300"]) == 0
    out = capsys.readouterr().out
    assert "pf-tree's database" in out and out.count("\n") >= 8
    for name in sidenbladh2002.FEATURE_SETS:
        assert name in out


def _frame_of(motion, row: np.ndarray, free: np.ndarray) -> int:
    """The one frame of ``motion`` whose free parameters are ``row``."""
    (found,) = np.flatnonzero(np.all(motion.params[:, free] == row, axis=1))
    return int(found)


def test_probe_histories_are_walking_windows_and_their_next_frame(library):
    """Each probe is d + 1 consecutive frames of a walking clip, and its next pose the frame after."""
    test = library.split("test").motions
    free = np.arange(4, 25)  # the root's position and yaw left out
    fitted = SimpleNamespace(window=5, free=free)
    histories, nexts, shapes = sidenbladh2002._probe_histories(fitted, test, 30, seed=1)
    walks = [m for m in test if m.label == "walk"]
    assert 0 < len(walks) < len(test)
    assert histories.shape == (30, 6, free.size) and nexts.shape == (30, 25)
    for k, (history, following, shape) in enumerate(zip(histories, nexts, shapes, strict=True)):
        clip = walks[k % len(walks)]  # the walking clips in turn, nothing else
        assert shape == clip.shape
        t = _frame_of(clip, history[-1], free)
        np.testing.assert_array_equal(history, clip.params[t - 5 : t + 1, free])
        np.testing.assert_array_equal(following, clip.params[t + 1])


def test_probe_histories_need_a_next_frame_after_the_window(library):
    """A clip of d + 2 frames gives one probe (t = d); one of d + 1 frames none."""
    walk = next(m for m in library.split("test").motions if m.label == "walk")
    fitted = SimpleNamespace(window=5, free=np.arange(25))
    histories, nexts, _ = sidenbladh2002._probe_histories(fitted, [walk.slice(10, 17)], 40, 2)
    np.testing.assert_array_equal(histories, np.repeat(walk.params[None, 10:16], 40, axis=0))
    np.testing.assert_array_equal(nexts, np.repeat(walk.params[None, 16], 40, axis=0))
    with pytest.raises(ValueError, match="long enough"):
        sidenbladh2002._probe_histories(fitted, [walk.slice(10, 16)], 1, 2)


def test_local_keypoints_do_not_depend_on_where_the_body_stands_or_faces(library):
    """Pelvis-relative in the heading frame: moving and turning the root changes nothing."""
    m = library.split("test").motions[0]
    pose = m.params[30].copy()
    local = sidenbladh2002._local_keypoints(pose, m.shape)
    np.testing.assert_allclose(local[0], 0.0, atol=1e-9)  # the pelvis is the origin
    moved = pose.copy()
    moved[:3] += (350.0, -1200.0, 40.0)
    moved[3] += 1.1  # root_yaw
    np.testing.assert_allclose(sidenbladh2002._local_keypoints(moved, m.shape), local, atol=1e-6)
    both = sidenbladh2002._local_keypoints(np.stack([pose, moved]), m.shape)
    np.testing.assert_allclose(both, [local, local], atol=1e-6)


def test_identical_next_poses_have_no_spread(library, monkeypatch):
    """The spread is each keypoint's distance from the samples' mean: 0 for equal samples."""
    walk = next(m for m in library.split("test").motions if m.label == "walk")
    fitted = SimpleNamespace(n_free=25)
    asked = []

    def same(fitted, history, samples, beta, rng):
        asked.append((samples, beta))
        return np.repeat(history[None, -1], samples, axis=0)

    monkeypatch.setattr(sidenbladh2002, "sample_next_poses", same)
    histories = np.stack([walk.params[20:26], walk.params[50:56]])
    spread = sidenbladh2002.next_pose_spread(
        fitted, histories, [walk.shape] * 2, (0.5, 2.0), np.random.default_rng(0), samples=7
    )
    np.testing.assert_allclose(spread, 0.0, atol=1e-9)  # mm
    assert asked == [(7, 0.5), (7, 0.5), (7, 2.0), (7, 2.0)]
    with pytest.raises(ValueError, match="all 25 parameters"):
        sidenbladh2002.next_pose_spread(
            SimpleNamespace(n_free=4), histories, [walk.shape] * 2, (1.0,), np.random.default_rng(0)
        )


def test_next_poses_at_a_vanishing_temperature_are_one_pose_without_noise(library, body_prior):
    """No transition noise: at beta -> 0 the search picks one window, so all samples agree."""
    walk = next(m for m in library.split("test").motions if m.label == "walk")
    history = walk.params[40 - tree.WINDOW : 41]
    drawn = sidenbladh2002.sample_next_poses(
        body_prior, history, 10, 1e-6, np.random.default_rng(3)
    )
    assert drawn.shape == (10, 25)
    np.testing.assert_array_equal(drawn, np.repeat(drawn[:1], 10, axis=0))
    # the next pose follows the history's last pose: nearer it than the window's first
    near = np.abs(drawn[0] - history[-1]).max()
    assert near < np.abs(drawn[0] - history[0]).max() / 3


def test_each_feature_set_and_its_scaled_share(body_prior):
    """Velocities are 25 per frame step; the scaled share is the SVD of standardised windows."""
    every = sidenbladh2002.explained_variance_by_features(
        body_prior, components=4, windows=body_prior.n_windows
    )
    by = {(r["features"], r["scaled"]): r for r in every}
    velocity, pose = by["velocity", True]["dimensions"], by["pose", True]["dimensions"]
    assert velocity == body_prior.window * 25  # d steps between d + 1 frames, every parameter
    assert pose % body_prior.window == 0 and pose < velocity  # the root's place is not a feature
    x = tree.database_windows(body_prior) * np.sqrt(
        np.tile(body_prior.feature_var, body_prior.window)
    )
    x = x - x.mean(axis=0)
    z = x / x.std(axis=0)  # each feature to unit variance (section 4's Gamma^-1/2)
    power = np.linalg.svd(z, compute_uv=False) ** 2
    assert by["pose+velocity", True]["explained"] == pytest.approx(
        power[:4].sum() / power.sum(), rel=1e-6
    )
    # components_for_89: the fewest components whose share reaches 89% (on one sample of windows)
    sample = sidenbladh2002.explained_variance_by_features(body_prior, components=4, windows=400)

    @functools.cache
    def share(k: int) -> dict[tuple[str, bool], float]:
        rows = sidenbladh2002.explained_variance_by_features(body_prior, components=k, windows=400)
        return {(r["features"], r["scaled"]): r["explained"] for r in rows}

    for r in sample:
        k, key = r["components_for_89"], (r["features"], r["scaled"])
        assert share(k)[key] >= 0.89
        assert k == 1 or share(k - 1)[key] < 0.89
