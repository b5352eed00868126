"""One contract test over the table of priors (every prior obeys the interface)."""

import numpy as np
import pytest

from baselines.filtering import ParticleFilter, ParticleState
from baselines.priors import PRIORS, get_prior
from humotion_gym.body import PARAM_INDEX, SAGITTAL_PARAMS
from humotion_gym.mocap.library import synthetic_library

SAGITTAL = np.array([PARAM_INDEX[n] for n in SAGITTAL_PARAMS])


@pytest.fixture(scope="module")
def walks():
    return synthetic_library().split("train").filter(labels=["walk", "run"])


class Gaussian:
    def __init__(self, target):
        self.target = target

    def log_likelihood(self, frame, poses):
        return -0.5 * np.sum((poses - self.target) ** 2, axis=1) / 0.05**2


@pytest.mark.parametrize("name", sorted(PRIORS))
def test_prior_contract(name, walks, tmp_path):
    prior = get_prior(name)
    fitted = prior.fit(walks.motions, free=SAGITTAL, rng=np.random.default_rng(0))
    pose = walks[0].params[40, SAGITTAL]

    def run(seed):
        rng = np.random.default_rng(seed)
        state = prior.initial(fitted, pose, 64, rng)
        return state, prior.transition(fitted, state, rng)

    s0, s1 = run(1)
    # The particles start at the pose they are given: their median within 0.05 rad
    # of it (cyclic PCA's start, projected onto its model, is 0.003 rad off; the
    # others 0.001 or less).
    assert np.abs(np.median(s0.pose, axis=0) - pose).max() < 0.05
    assert isinstance(s1, ParticleState) and s0.pose.shape == s1.pose.shape == (64, 8)
    assert all(v.shape[0] == 64 for v in s1.extra.values())
    assert np.all(np.isfinite(s1.pose))
    t0, t1 = run(1)
    assert np.array_equal(s1.pose, t1.pose)  # same seed, same particles
    assert not np.array_equal(s1.pose, run(2)[1].pose)
    prior.save(fitted, tmp_path / "fitted.npz")
    back = prior.load(tmp_path / "fitted.npz")
    r1 = prior.transition(back, s0, np.random.default_rng(5)).pose
    r2 = prior.transition(fitted, s0, np.random.default_rng(5)).pose
    assert np.allclose(r1, r2)
    with np.load(tmp_path / "fitted.npz", allow_pickle=False) as data:  # no pickle inside
        assert len(data.files) > 1
    # resampling is one fancy index over every per-particle array
    taken = s1.take(np.zeros(64, dtype=np.intp))
    assert np.all(taken.pose == s1.pose[0])
    # Resampled particles move as copies of their rows would (the arrays the
    # take deferred read through the rows, or gathered), bit for bit.
    index = np.sort(np.random.default_rng(9).integers(0, 64, 64))
    deferred = s1.take(index)
    copies = ParticleState(s1.pose[index], {k: v[index] for k, v in s1.extra.items()})
    moved = prior.transition(fitted, deferred, np.random.default_rng(6))
    want = prior.transition(fitted, copies, np.random.default_rng(6))
    np.testing.assert_array_equal(moved.pose, want.pose)
    assert set(moved.extra) == set(want.extra)
    for key in want.extra:
        np.testing.assert_array_equal(moved.extra[key], want.extra[key])
    pf = ParticleFilter(prior, fitted, Gaussian(walks[0].params[41, SAGITTAL]), 64)
    pf.reset(pose, np.random.default_rng(0))
    for _ in range(3):
        est = pf.step(None)
    assert est.shape == (8,) and np.all(np.isfinite(est))
    # one synthesis signature for every prior: (fitted, base_pose, frames, fps, rng)
    base = walks[0].params[40]
    motion = prior.synthesize_motion(fitted, base, 20, 15.0, np.random.default_rng(3))
    again = prior.synthesize_motion(fitted, base, 20, 15.0, np.random.default_rng(3))
    assert motion.shape == (20, 25) and np.all(np.isfinite(motion))
    np.testing.assert_array_equal(motion, again)
    others = np.setdiff1d(np.arange(2, 25), SAGITTAL)  # cyclic PCA walks the root forward
    np.testing.assert_array_equal(motion[:, others], np.broadcast_to(base[others], (20, 15)))
    assert not np.allclose(motion[:, SAGITTAL], motion[0, SAGITTAL])  # it moves
    with pytest.raises(ValueError, match="base_pose"):
        prior.synthesize_motion(fitted, base[:3], 20, 15.0, np.random.default_rng(3))
    # a damaged, cut or foreign file is refused by name, never a zip or pickle error
    saved = (tmp_path / "fitted.npz").read_bytes()
    damaged = {
        "empty.npz": b"",
        "text.npz": b"not an npz\n",
        "cut.npz": saved[: len(saved) // 2],
        "body.npz": saved[:60] + bytes(b ^ 0xFF for b in saved[60:-200]) + saved[-200:],
    }
    for file, data in damaged.items():
        (tmp_path / file).write_bytes(data)
        with pytest.raises(ValueError, match=f"{file}: (not saved|damaged)") as refused:
            prior.load(tmp_path / file)
        assert "pickle" not in str(refused.value)
    (tmp_path / "folder.npz").mkdir()
    with pytest.raises(ValueError, match="folder.npz: not saved"):
        prior.load(tmp_path / "folder.npz")
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(ValueError, match="array.npy: not saved .*a lone .npy array"):
        prior.load(tmp_path / "array.npy")
    with pytest.raises(FileNotFoundError):
        prior.load(tmp_path / "none.npz")


def test_a_prior_fitted_on_other_motion_of_the_same_clips_is_refitted(tmp_path):
    """The cache key hashes the motion: a file rewritten with the same length is refitted."""
    import dataclasses

    from baselines.priors import constant_velocity
    from baselines.priors.fitting import fit_prior

    clips = synthetic_library().split("train").motions[:3]
    said: list[str] = []
    fit_prior(constant_velocity, clips, None, {}, cache_dir=tmp_path, log=said.append)
    fit_prior(constant_velocity, clips, None, {}, cache_dir=tmp_path, log=said.append)
    assert sum("fitting" in line for line in said) == 1  # the second came from the cache
    moved = [dataclasses.replace(clips[0], params=clips[0].params * 1.5), *clips[1:]]
    fit_prior(constant_velocity, moved, None, {}, cache_dir=tmp_path, log=said.append)
    assert sum("fitting" in line for line in said) == 2


#: The fitted priors below only have to be of their kind for the refusals, not converged: one
#: EM iteration of the SLDS instead of its default ten.
_QUICK_FITS = {"slds": {"n_iter": 1}}


@pytest.fixture(scope="module")
def fitted_priors(walks):
    """Every prior fitted on one person's walk and run (the contract test fits all the clips)."""
    clips = walks.motions[:2]
    assert sorted(m.label for m in clips) == ["run", "walk"]
    return {
        name: get_prior(name).fit(
            clips, free=SAGITTAL, rng=np.random.default_rng(0), **_QUICK_FITS.get(name, {})
        )
        for name in sorted(PRIORS)
    }


@pytest.mark.parametrize("name", sorted(PRIORS))
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"free": [-1]}, "free must be distinct integer indices"),
        ({"free": [3, 3]}, "free must be distinct integer indices"),
        ({"free": [[1, 2]]}, "free must be distinct integer indices"),
        ({"free": []}, "free must be distinct integer indices"),
        ({"free": [99]}, "free must be distinct integer indices"),
        ({"free": [1.5]}, "free must be distinct integer indices"),  # was cut to 1
        ({"frame_skip": 0}, "frame_skip: expected an integer >= 1"),
        ({"motions": np.zeros((3, 25))}, "expected a list of Motion clips"),
        ({"motions": []}, "no training motions"),
    ],
)
def test_every_fit_refuses_bad_arguments_by_name(name, kwargs, match, walks):
    prior = get_prior(name)
    args = {"motions": walks.motions, "free": SAGITTAL, **kwargs}
    with pytest.raises(ValueError, match=rf"^{name}\.fit: .*{match}"):
        prior.fit(args.pop("motions"), **args)


@pytest.mark.parametrize("name", sorted(PRIORS))
def test_every_fit_refuses_clips_of_two_rates(name, walks):
    from humotion_gym.mocap.library import synthetic_library

    faster = synthetic_library(fps=60).split("train").filter(labels=["walk", "run"]).motions
    with pytest.raises(ValueError, match=rf"^{name}\.fit: the clips must share one frame rate"):
        get_prior(name).fit([*walks.motions, *faster], free=SAGITTAL)


@pytest.mark.parametrize("name", sorted(PRIORS))
@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"pose": "nan"}, "the pose must be finite"),  # gave particles of NaN
        ({"pose": "short"}, r"expected a pose of shape \(8,\)"),
        ({"n": 0}, "n must be an integer >= 1"),
        ({"n": -1}, "n must be an integer >= 1"),
        ({"rng": None}, "rng must be a numpy.random.Generator"),
    ],
)
def test_every_initial_refuses_bad_arguments_by_name(name, change, match, walks, fitted_priors):
    pose = walks[0].params[40, SAGITTAL].copy()
    args = {"pose": pose, "n": 8, "rng": np.random.default_rng(0), **change}
    if isinstance(args["pose"], str):
        args["pose"] = (
            pose[:4] if args["pose"] == "short" else np.where(np.arange(8) == 2, np.nan, pose)
        )
    with pytest.raises(ValueError, match=rf"^{name}\.initial: {match}"):
        get_prior(name).initial(fitted_priors[name], args["pose"], args["n"], args["rng"])


@pytest.mark.parametrize("name", sorted(PRIORS))
@pytest.mark.parametrize("rng", [None, 0])  # no generator, a seed
def test_every_transition_refuses_what_is_no_generator(name, rng, walks, fitted_priors):
    prior, fitted = get_prior(name), fitted_priors[name]
    state = prior.initial(fitted, walks[0].params[40, SAGITTAL], 4, np.random.default_rng(0))
    with pytest.raises(ValueError, match=rf"^{name}\.transition: rng must be a numpy"):
        prior.transition(fitted, state, rng)


@pytest.mark.parametrize("name", sorted(PRIORS))
def test_synthesis_refuses_a_fraction_of_a_frame_and_a_nan_pose(name, walks, fitted_priors):
    prior, base = get_prior(name), walks[0].params[40].copy()
    with pytest.raises(ValueError, match="frames must be an integer >= 1"):
        prior.synthesize_motion(fitted_priors[name], base, 2.5, 30.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="rng must be a numpy.random.Generator"):
        prior.synthesize_motion(fitted_priors[name], base, 4, 30.0, 0)  # a seed, not a generator
    base[3] = np.nan
    with pytest.raises(ValueError, match="base_pose must be finite"):
        prior.synthesize_motion(fitted_priors[name], base, 4, 30.0, np.random.default_rng(0))


@pytest.mark.parametrize("name", ["tree", "slds", "cyclic_pca"])
@pytest.mark.parametrize(
    ("frames", "rng", "match"),
    [
        (2.5, 0, "frames must be an integer >= 1"),  # numpy's "float object" error before
        (-3, 0, "frames must be an integer >= 1"),  # np.empty's negative dimensions
        (4, None, "rng must be a numpy.random.Generator"),
    ],
)
def test_each_priors_own_synthesize_refuses_bad_arguments_by_name(
    name, frames, rng, match, walks, fitted_priors
):
    from baselines.priors import cyclic_pca, slds, tree

    rng = np.random.default_rng(rng) if rng is not None else 7
    fitted = fitted_priors[name]
    with pytest.raises(ValueError, match=rf"^{name}\.synthesize: {match}"):
        if name == "tree":
            tree.synthesize(fitted, walks[0].params[40, SAGITTAL], frames, 0.05, rng)
        else:
            {"slds": slds, "cyclic_pca": cyclic_pca}[name].synthesize(fitted, frames, rng)


def test_the_trees_synthesis_refuses_a_nan_start(walks, fitted_priors):
    from baselines.priors import tree

    fitted = fitted_priors["tree"]
    history = walks[0].params[40 - fitted.window : 41, SAGITTAL].copy()
    pose = history[-1].copy()
    pose[2] = np.nan
    history[0, 2] = np.nan  # in the past alone: every synthesised frame was NaN
    for start in (pose, history):
        with pytest.raises(ValueError, match=r"^tree\.synthesize: start must be finite"):
            tree.synthesize(fitted, start, 4, 0.05, np.random.default_rng(0))


def test_the_trees_own_depth_fits_one_free_parameter(walks):
    fitted = get_prior("tree").fit(walks.motions, free=[PARAM_INDEX["r_knee"]])
    assert fitted.n_free == 1


@pytest.mark.parametrize("name", sorted(PRIORS))
def test_save_refuses_another_priors_parameters_and_leaves_no_file(name, fitted_priors, tmp_path):
    other = next(n for n in sorted(PRIORS) if n != name)
    with pytest.raises(
        TypeError, match=f"^save: expected .*, got {type(fitted_priors[other]).__name__}"
    ):
        get_prior(name).save(fitted_priors[other], tmp_path / "x.npz")
    with pytest.raises(TypeError, match="^save: expected"):
        get_prior(name).save("x", tmp_path / "x.npz")
    (tmp_path / "a_folder.npz").mkdir()
    with pytest.raises(OSError):
        get_prior(name).save(fitted_priors[name], tmp_path / "a_folder.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_folder.npz"]  # no temporary left


def _rewrite(src, dst, change):
    """``src``'s arrays, changed by ``change(arrays)``, written to ``dst``."""
    with np.load(src) as data:
        arrays = {k: data[k] for k in data.files}
    change(arrays)
    np.savez(dst, **arrays)
    return dst


def _first_float(arrays):
    return next(k for k, v in sorted(arrays.items()) if v.dtype.kind == "f" and v.size > 1)


@pytest.mark.parametrize("name", sorted(PRIORS))
def test_load_refuses_a_file_a_fit_could_not_have_written(name, fitted_priors, tmp_path):
    """NaN, an array of no field, a field of another shape, no kind: refused, the file named."""
    prior = get_prior(name)
    good = tmp_path / "good.npz"
    prior.save(fitted_priors[name], good)
    prior.load(good)  # the round trip itself is the contract test's

    def nan(arrays):
        arrays[_first_float(arrays)].flat[0] = np.nan

    def extra(arrays):
        arrays["surprise"] = np.zeros(3)

    def short(arrays):
        key = _first_float(arrays)
        arrays[key] = arrays[key].reshape(-1)[:1]

    def no_kind(arrays):
        del arrays["__kind__"]

    cases = {"NaN or infinite": nan, "unknown arrays": extra, "": short, "no __kind__": no_kind}
    for says, change in cases.items():
        bad = _rewrite(good, tmp_path / f"bad_{change.__name__}.npz", change)
        with pytest.raises(ValueError, match=rf"bad_{change.__name__}\.npz: .*{says}"):
            prior.load(bad)
