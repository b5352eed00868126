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
        with pytest.raises(ValueError, match=f"{file}: (not saved|damaged)"):
            prior.load(tmp_path / file)
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(ValueError, match="array.npy: not saved .*a .npy array"):
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
