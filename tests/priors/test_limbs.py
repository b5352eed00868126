"""One tree prior per body part: the factorised transition, part by part."""

import numpy as np
import pytest

from baselines.filtering import ParticleState
from baselines.priors import limbs, tree
from humotion_gym.body import N_PARAMS, PARAM_INDEX
from humotion_gym.mocap.library import synthetic_library

ALL = np.arange(N_PARAMS)
ARM = np.array(
    [PARAM_INDEX[n] for n in ("r_shoulder_x", "r_shoulder_y", "r_shoulder_z", "r_elbow")]
)


@pytest.fixture(scope="module")
def body():
    walks = synthetic_library().split("train").filter(labels=["walk", "run"])
    parts = [
        (name, tree.fit(walks.motions, free=ALL[cols], rng=np.random.default_rng(0)))
        for name, cols in limbs.part_columns(ALL)
    ]
    return walks[0].params[40], limbs.compose(ALL, parts)


def test_parts_cover_every_free_parameter_once():
    for free in (ALL, ARM, np.array([0, 1, 2, 3, 9, 17, 20])):
        cols = np.concatenate([c for _, c in limbs.part_columns(free)])
        assert np.array_equal(np.sort(cols), np.arange(free.size))
    assert [n for n, _ in limbs.part_columns(ALL)] == list(limbs.PARTS)
    # the right arm alone is one part: the plain tree
    assert [n for n, _ in limbs.part_columns(ARM)] == ["right_arm"]
    # the root's position and heading stay together, in the torso
    torso = set(limbs.PARTS["torso"])
    assert {PARAM_INDEX[n] for n in ("root_x", "root_y", "root_z", "root_yaw")} <= torso


def test_transition_is_each_part_searching_its_own_tree(body):
    pose, prior = body
    s0 = limbs.initial(prior, pose, 64, np.random.default_rng(1))
    assert np.array_equal(s0.pose, np.repeat(pose[None], 64, axis=0))
    keys = ("past", "last", "window")
    assert set(s0.extra) == {f"{n}/{k}" for n in limbs.PARTS for k in keys}
    s1 = limbs.transition(prior, s0, np.random.default_rng(2))
    # oracle: the parts moved one after another by the plain tree, with the same draws
    rng = np.random.default_rng(2)
    for name, cols, part in zip(prior.names, prior.columns, prior.parts, strict=True):
        own = ParticleState(s0.pose[:, cols], {k: s0.extra[f"{name}/{k}"] for k in keys})
        ref = tree.transition(part, own, rng)
        assert np.array_equal(s1.pose[:, cols], ref.pose)
        for k in keys:
            assert np.array_equal(s1.extra[f"{name}/{k}"], ref.extra[k])
    again = limbs.transition(prior, s0, np.random.default_rng(2))
    assert np.array_equal(s1.pose, again.pose)


def test_one_part_is_the_plain_tree():
    walks = synthetic_library().split("train").filter(labels=["walk", "run"])
    t = tree.fit(walks.motions, free=ARM, rng=np.random.default_rng(0))
    prior = limbs.compose(ARM, [("right_arm", t)])
    pose = walks[0].params[40, ARM]
    a = limbs.transition(prior, limbs.initial(prior, pose, 32, np.random.default_rng(5)),
                         np.random.default_rng(6))  # fmt: skip
    b = tree.transition(t, tree.initial(t, pose, 32, np.random.default_rng(5)),
                        np.random.default_rng(6))  # fmt: skip
    assert np.array_equal(a.pose, b.pose)


def test_errors_name_what_is_wrong(body):
    pose, prior = body
    with pytest.raises(ValueError, match="distinct indices"):
        limbs.part_columns([0, 0, 1])
    with pytest.raises(ValueError, match="distinct indices"):
        limbs.part_columns([3, 25])
    with pytest.raises(ValueError, match="one tree for each of the parts"):
        limbs.compose(ALL, list(zip(prior.names, prior.parts, strict=True))[:-1])
    swapped = [("left_arm", prior.parts[1]), ("right_arm", prior.parts[2])]
    rest = list(zip(prior.names, prior.parts, strict=True))
    with pytest.raises(ValueError, match=r"the right_arm tree models the parameters \[13"):
        limbs.compose(ALL, [rest[0], *swapped, *rest[3:]])
    with pytest.raises(ValueError, match="pose must have shape"):
        limbs.initial(prior, pose[:10], 4, np.random.default_rng(0))
