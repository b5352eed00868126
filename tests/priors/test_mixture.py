"""The mixture of priors: a sample of sum_k w_k p_k, with every component's memory kept."""

import numpy as np
import pytest

from baselines.filtering import ParticleState, select
from baselines.priors import constant_velocity, mixture, tree
from humotion_gym.body import PARAM_INDEX, SAGITTAL_PARAMS
from humotion_gym.mocap.library import synthetic_library

SAGITTAL = np.array([PARAM_INDEX[n] for n in SAGITTAL_PARAMS])


@pytest.fixture(scope="module")
def parts():
    walks = synthetic_library().split("train").filter(labels=["walk", "run"])
    t = tree.fit(walks.motions, free=SAGITTAL, rng=np.random.default_rng(0))
    cv = constant_velocity.fit(walks.motions, free=SAGITTAL, damping=0.5, position_noise=1.0)
    still = constant_velocity.fit(walks.motions, free=SAGITTAL, multiplier=0.0, damping=0.0,
                                  position_noise=0.1)  # fmt: skip
    return walks[0].params[40, SAGITTAL], t, cv, still


def test_one_component_of_weight_one_is_that_prior(parts):
    pose, t, cv, _ = parts
    mix = mixture.compose([(constant_velocity, cv), (tree, t)], [1.0, 0.0])
    s0 = mixture.initial(mix, pose, 50, np.random.default_rng(3))
    assert set(s0.extra) == {"0/velocity", "1/past", "1/last", "1/window"}
    rng = np.random.default_rng(4)
    s1 = mixture.transition(mix, s0, rng)
    # the same draws: the mixture picks components first, then the component moves them
    ref_rng = np.random.default_rng(4)
    ref_rng.choice(2, size=50, p=[1.0, 0.0])
    own = ParticleState(s0.pose, {"velocity": s0.extra["0/velocity"]})
    ref = constant_velocity.transition(cv, own, ref_rng)
    assert np.array_equal(s1.pose, ref.pose)
    assert np.array_equal(s1.extra["0/velocity"], ref.extra["velocity"])
    # the tree's history followed the move: shifted, the new pose last
    h0, h1 = (tree.histories(select(s.extra, "1/")) for s in (s0, s1))
    assert np.array_equal(h1[:, :-1], h0[:, 1:])
    assert np.allclose(h1[:, -1], s1.pose, atol=1e-5)


def test_components_are_picked_by_their_weights(parts):
    pose, t, cv, still = parts
    mix = mixture.compose([(tree, t), (constant_velocity, cv), (constant_velocity, still)],
                          [0.5, 0.3, 0.2])  # fmt: skip
    state = mixture.initial(mix, pose, 4000, np.random.default_rng(0))
    moved = mixture.transition(mix, state, np.random.default_rng(1))
    # a velocity component's memory after any move is the step taken, except for
    # the particles it moved itself (its own damped velocity plus noise)
    step = moved.pose - state.pose
    by_cv = ~np.all(np.isclose(moved.extra["1/velocity"], step), axis=1)
    by_still = ~np.all(np.isclose(moved.extra["2/velocity"], step), axis=1)
    assert not np.any(by_cv & by_still)
    assert abs(by_cv.mean() - 0.3) < 0.04 and abs(by_still.mean() - 0.2) < 0.04
    # same seed, same particles
    again = mixture.transition(mix, state, np.random.default_rng(1))
    assert np.array_equal(moved.pose, again.pose)


def test_compose_refuses_what_it_cannot_mix(parts):
    pose, t, cv, _ = parts
    with pytest.raises(ValueError, match="at least two"):
        mixture.compose([(tree, t)], [1.0])
    with pytest.raises(ValueError, match="sum to 1"):
        mixture.compose([(tree, t), (constant_velocity, cv)], [0.5, 0.6])
    with pytest.raises(ValueError, match="expected 2 weights"):
        mixture.compose([(tree, t), (constant_velocity, cv)], [1.0])
    from baselines.priors import cyclic_pca

    with pytest.raises(ValueError, match="cannot be a component"):
        mixture.compose([(tree, t), (cyclic_pca, cv)], [0.5, 0.5])
    other = constant_velocity.fit(synthetic_library().split("train").motions[:3], free=SAGITTAL[:4])
    with pytest.raises(ValueError, match="models the parameters"):
        mixture.compose([(tree, t), (constant_velocity, other)], [0.5, 0.5])


def test_persistence_keeps_a_particles_component_as_a_markov_chain(parts):
    """P(same component next frame) = p + (1 - p) sum_k w_k^2; the weights stay its law."""
    pose, _, cv, still = parts
    w, p, n = np.array([0.3, 0.7]), 0.8, 40000
    mix = mixture.compose([(constant_velocity, cv), (constant_velocity, still)], w, 0.8)
    state = mixture.initial(mix, pose, n, np.random.default_rng(0))
    first = state.extra[mixture.COMPONENT]
    assert first.shape == (n,) and abs((first == 1).mean() - 0.7) < 0.01
    moved = mixture.transition(mix, state, np.random.default_rng(1))
    second = moved.extra[mixture.COMPONENT]
    kept = (second == first).mean()
    expected = p + (1 - p) * (w**2).sum()
    assert abs(kept - expected) < 5 * np.sqrt(expected * (1 - expected) / n)
    # the stationary law is still the weights, frame after frame
    assert abs((second == 1).mean() - 0.7) < 0.01
    # each particle moved by the component it is labelled with: the walk's
    # particles carry a zero velocity (no velocity: multiplier 0, damping 0)
    walked = np.all(moved.extra["1/velocity"] == 0.0, axis=1)
    assert np.array_equal(walked, second == 1)
    # same seed, same particles and labels
    again = mixture.transition(mix, state, np.random.default_rng(1))
    assert np.array_equal(again.pose, moved.pose)
    assert np.array_equal(again.extra[mixture.COMPONENT], second)


def test_without_persistence_no_label_is_kept(parts):
    pose, t, cv, _ = parts
    mix = mixture.compose([(tree, t), (constant_velocity, cv)], [0.5, 0.5])
    state = mixture.initial(mix, pose, 20, np.random.default_rng(0))
    assert mixture.COMPONENT not in state.extra
    assert mixture.COMPONENT not in mixture.transition(mix, state, np.random.default_rng(1)).extra


def test_resampled_labels_follow_their_particles(parts):
    """The filter's resampling takes every extra array by the same rows, labels included."""
    pose, _, cv, still = parts
    mix = mixture.compose([(constant_velocity, cv), (constant_velocity, still)], [0.5, 0.5], 0.9)
    state = mixture.initial(mix, pose, 200, np.random.default_rng(0))
    rows = np.random.default_rng(1).integers(0, 200, 200)
    taken = state.take(rows)
    assert np.array_equal(taken.extra[mixture.COMPONENT], state.extra[mixture.COMPONENT][rows])
    assert np.array_equal(taken.pose, state.pose[rows])
    for _ in range(5):
        state = mixture.transition(mix, state, np.random.default_rng(2))
        labels = state.extra[mixture.COMPONENT]
        assert labels.dtype.kind == "i" and set(np.unique(labels)) <= {0, 1}


@pytest.mark.parametrize("bad", [1.0, -0.1, float("nan"), True, "0.5x", None])
def test_compose_refuses_a_persistence_outside_0_1(parts, bad):
    _, t, cv, _ = parts
    with pytest.raises(ValueError, match="persistence must be in"):
        mixture.compose([(tree, t), (constant_velocity, cv)], [0.5, 0.5], bad)
