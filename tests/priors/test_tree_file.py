"""The tree prior's file: the database once, in single precision; the tree recomputed on load."""

from __future__ import annotations

import numpy as np
import pytest
from test_tree import walking_along_y

from baselines.priors import tree
from baselines.priors._io import save_fitted
from humotion_gym import body
from humotion_gym.mocap.library import synthetic_library

ARM = [9, 10, 11, 12]


@pytest.fixture(scope="module")
def train():
    return synthetic_library(seed=0).split("train").motions[:6]


@pytest.fixture(scope="module")
def prior(train):
    return tree.fit(train)


@pytest.fixture(scope="module")
def double_prior(train):
    """The same fit from the clips in double precision (the format before single precision)."""
    mp = pytest.MonkeyPatch()
    mp.setattr(tree, "DATABASE_DTYPE", np.float64)
    try:
        return tree.fit(train)
    finally:
        mp.undo()


def test_database_is_the_clips_in_single_precision(train, prior):
    frames = np.concatenate([m.params for m in train]).astype(np.float32)
    np.testing.assert_array_equal(prior.frames, frames.astype(np.float64))
    assert prior.frames.dtype == np.float64  # arithmetic stays in double


def test_file_holds_the_database_once_in_single_precision(tmp_path, prior):
    path = tmp_path / "tree.npz"
    tree.save(prior, path)
    with np.load(path, allow_pickle=False) as data:
        assert data["frames"].dtype == np.float32
        assert data["frames"].shape == prior.frames.shape
        for derived in ("coefficients", "next_step", "codes", "offsets", "node_flags"):
            assert derived not in data.files
        np.testing.assert_array_equal(
            np.repeat(np.arange(data["clip_lengths"].size), data["clip_lengths"]), prior.frame_clip
        )
    # The derived arrays would take more than the database: the file is far smaller
    # than every array written whole.
    whole = tmp_path / "whole.npz"
    save_fitted(prior, whole)
    assert path.stat().st_size < 0.45 * whole.stat().st_size


@pytest.mark.parametrize("free", [None, ARM])
def test_loaded_prior_equals_the_fitted_one(tmp_path, train, free):
    fitted = tree.fit(train, free=free, replay="velocity")
    path = tmp_path / "tree.npz"
    tree.save(fitted, path)
    loaded = tree.load(path)
    for name in fitted.__dataclass_fields__:
        a, b = getattr(fitted, name), getattr(loaded, name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype, name
            np.testing.assert_array_equal(a, b, err_msg=name)
        else:
            assert a == b, name


def test_a_double_precision_database_is_saved_whole(tmp_path, double_prior):
    path = tmp_path / "tree.npz"
    tree.save(double_prior, path)
    loaded = tree.load(path)
    np.testing.assert_array_equal(loaded.frames, double_prior.frames)
    np.testing.assert_array_equal(loaded.coefficients, double_prior.coefficients)


def test_single_precision_keeps_the_tree_and_the_searches(prior, double_prior):
    """Rounding the database to single precision picks the same windows as the clips."""
    assert prior.n_windows == double_prior.n_windows
    np.testing.assert_array_equal(prior.window_end, double_prior.window_end)
    np.testing.assert_array_equal(prior.codes, double_prior.codes)
    scale = np.abs(double_prior.coefficients).max()
    np.testing.assert_allclose(prior.coefficients, double_prior.coefficients, atol=1e-5 * scale)
    # The same probes and random numbers choose the same windows (descent and eq. 3
    # in the leaf), and the initialisation draws the same windows for a pose.
    probes = double_prior.coefficients[::7] + 0.2 * double_prior.sigma
    a = tree.sample_windows(prior, probes, np.random.default_rng(3))
    b = tree.sample_windows(double_prior, probes, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    pose = double_prior.frames[200]
    np.testing.assert_array_equal(
        tree.initial_windows(prior, pose, 500, np.random.default_rng(4)),
        tree.initial_windows(double_prior, pose, 500, np.random.default_rng(4)),
    )


def test_load_refuses_other_files_clearly(tmp_path, prior):
    old = tmp_path / "old.npz"
    save_fitted(prior, old)  # every field whole, no __format__: the format before 2
    with pytest.raises(ValueError, match=r"old\.npz.*format 1.*fit the prior again"):
        tree.load(old)
    path = tmp_path / "tree.npz"
    tree.save(prior, path)
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    missing = tmp_path / "missing.npz"
    np.savez(missing, **{k: v for k, v in arrays.items() if k != "components"})
    with pytest.raises(ValueError, match=r"missing\.npz: the arrays \['components'\] are missing"):
        tree.load(missing)
    outside = tmp_path / "outside.npz"
    np.savez(outside, **{**arrays, "window_end": arrays["window_end"] + prior.frames.shape[0]})
    with pytest.raises(ValueError, match=r"outside\.npz.*do not fit its"):
        tree.load(outside)
    other = tmp_path / "other.npz"
    np.savez(other, **{**arrays, "__kind__": np.array("SLDSParams")})
    with pytest.raises(ValueError, match="holds SLDSParams parameters, expected TreeParams"):
        tree.load(other)


@pytest.mark.parametrize(("name", "count"), [("window", 3), ("depth", 5)])
def test_fit_prior_takes_counts_given_as_whole_floats(tmp_path, name, count):
    # The command line gives every setting as a number (--grid fit.window=3,4
    # gives 3.0): a whole one reaches the fit, and the cache key, as an int;
    # depth's default is None, so only its annotation (int | None) says it is a count.
    from baselines.priors.fitting import fit_prior

    motions = [walking_along_y(90)]
    free = np.arange(body.N_PARAMS)
    _, as_int = fit_prior("tree", motions, free, {name: count}, cache_dir=tmp_path, log=None)
    _, as_float = fit_prior("tree", motions, free, {name: float(count)}, cache_dir=tmp_path,
                            log=None)  # fmt: skip
    assert getattr(as_float, name) == getattr(as_int, name) == count
    assert len(list((tmp_path / "priors").glob("tree-*.npz"))) == 1  # the same entry
    with pytest.raises(ValueError, match=f"tree prior: the setting {name} must be a whole number"):
        fit_prior("tree", motions, free, {name: count + 0.5}, use_cache=False, log=None)


def test_a_save_that_cannot_write_names_its_path_not_the_temporary_file(tmp_path, prior):
    with pytest.raises(OSError, match=f"cannot write {tmp_path}: Is a directory"):
        tree.save(prior, tmp_path)  # a folder where the file should be
    (tmp_path / "missing").write_text("a file where a folder should be")
    with pytest.raises(OSError, match="missing/dir"):
        tree.save(prior, tmp_path / "missing" / "dir" / "x.npz")
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        ({"free": np.arange(25) + 5}, r"TreeParams: free must be distinct integer indices"),
        ({"free": np.arange(25) * 1.0}, r"TreeParams: free must be distinct integer indices"),
        ({"window": np.array(2.5)}, r"TreeParams: window must be a whole number >= 1"),
        ({"depth": np.array(0)}, r"TreeParams: depth must be a whole number >= 1"),
        ({"proposals": np.array(2.5)}, r"TreeParams: proposals must be a whole number >= 1"),
        ({"beta": np.array(0.0)}, r"TreeParams: beta must be a number > 0"),
        ({"fps": np.array("abc")}, r"TreeParams: fps must be a number > 0, got 'abc'"),
        ({"leaf": np.array(3)}, r"TreeParams: leaf must be one of"),
        ({"window": np.array(3)}, r"TreeParams\.feature_mean has shape"),
        ({"sigma": "zeros"}, r"TreeParams: sigma must be > 0"),
        ({"projection": "a row short"}, r"TreeParams\.projection has shape"),
        ({"clip_lengths": "floats"}, r"'clip_lengths' must be a list of whole numbers >= 0"),
        ({"window_end": "floats"}, r"'window_end' must be a list of whole numbers >= 0"),
    ],
)
def test_load_refuses_what_the_search_and_replay_would_fail_on(tmp_path, prior, edit, says):
    """An edited file is refused when loaded, naming the file and the array, not when used."""
    path = tmp_path / "tree.npz"
    tree.save(prior, path)
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    changes = {
        "zeros": lambda a: np.zeros_like(a),
        "a row short": lambda a: a[:-1],
        "floats": lambda a: a.astype(np.float64),
    }
    for name, value in edit.items():
        arrays[name] = changes[value](arrays[name]) if isinstance(value, str) else value
    edited = tmp_path / "edited.npz"
    np.savez(edited, **arrays)
    with pytest.raises(ValueError, match=rf"edited\.npz: .*{says}"):
        tree.load(edited)
