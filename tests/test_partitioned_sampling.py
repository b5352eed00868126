"""Tests of partitioned sampling (MacCormick & Isard 2000) and the partial figures it weighs by."""

from __future__ import annotations

import numpy as np
import pytest

from baselines.agents import PART_CONES, body_part_stages
from baselines.filtering import (
    ParticleFilter,
    PartitionedParticleFilter,
    Stage,
)
from baselines.observation import GivenBody, ObservationModel
from humotion_gym import body
from humotion_gym.camera import fit_camera
from humotion_gym.envs.tasks import get_task
from humotion_gym.render import SceneOptions, make_background, render
from tests.filter_toys import Peaks, RandomWalk, assert_tracks_as_the_particle_filter

SHAPE = body.default_shape()
ALL = np.arange(body.N_PARAMS)
#: The figure's groups in the order the body-part stages build it.
GROUPS = [
    [body.CONE_NAMES.index(c) for c in cones] for cones in PART_CONES.values()
]  # torso, right arm, left arm, right leg, left leg


def scene(seed: int, task: str = "BodyTrack-v2"):
    """A frame of a perturbed standing pose, the task's model and the prepared features."""
    rng = np.random.default_rng(seed)
    pose = body.standing_pose(SHAPE)
    pose[6:] += rng.normal(0.0, 0.3, 19)
    pose = np.clip(pose, body.PARAM_LOWER, body.PARAM_UPPER)
    cam = fit_camera(body.forward_kinematics(pose, SHAPE)[None], 128, 128, 50.0, 30.0, 10.0)
    scene_options = SceneOptions()
    background = make_background(scene_options, rng)
    first = pose.copy()
    first[0] -= 300.0
    first_frame = render(first, SHAPE, cam, scene_options, rng, background)
    frame = render(pose, SHAPE, cam, scene_options, rng, background)
    model = ObservationModel(**dict(get_task(task).observation))
    colors, backdrop, floor = model.read_first_frame(first_frame, first, SHAPE, cam)
    free = get_task(task).free_indices
    feats = model.prepare(frame, GivenBody(pose, free, SHAPE, cam, colors, backdrop, floor))
    return model, feats, cam, pose, rng


@pytest.mark.parametrize("task", ["BodyTrack-v2", "ArmTrack-v2", "WalkTrack-v2"])
@pytest.mark.parametrize("n", [40, 1200])  # 1200: the path that scores shared cones once
def test_the_last_column_is_the_likelihood(task: str, n: int) -> None:
    model, feats, cam, pose, rng = scene(1, task)
    poses = np.tile(pose, (n, 1))
    free = get_task(task).free_indices
    poses[:, free] += rng.normal(0.0, 0.2, (n, free.size))
    partial = model.log_likelihood_partial(feats, poses, SHAPE, cam, GROUPS)
    assert partial.shape == (n, len(GROUPS) + 1)
    np.testing.assert_array_equal(partial[:, -1], model.log_likelihood(feats, poses, SHAPE, cam))


def test_each_column_depends_only_on_the_parts_placed_so_far() -> None:
    # Column g is an importance function of the stages up to g: moving a
    # part's joints leaves every earlier column exactly as it was.
    model, feats, cam, pose, rng = scene(2)
    poses = np.tile(pose, (60, 1)) + rng.normal(0.0, 0.1, (60, body.N_PARAMS))
    before = model.log_likelihood_partial(feats, poses, SHAPE, cam, GROUPS)
    stages = body_part_stages(ALL)
    assert [s.group for s in stages] == [tuple(g) for g in GROUPS]
    for g, stage in enumerate(stages[1:], start=1):
        moved = poses.copy()
        moved[:, stage.dims] += rng.normal(0.0, 0.4, (60, stage.dims.size))
        after = model.log_likelihood_partial(feats, moved, SHAPE, cam, GROUPS)
        np.testing.assert_array_equal(after[:, :g], before[:, :g])
        assert np.any(after[:, g] != before[:, g])


def test_a_figure_of_every_cone_is_the_whole_figure() -> None:
    model, feats, cam, pose, rng = scene(3)
    assert not model.has_floor_term
    poses = np.tile(pose, (30, 1)) + rng.normal(0.0, 0.1, (30, body.N_PARAMS))
    partial = model.log_likelihood_partial(feats, poses, SHAPE, cam, [list(range(body.N_CONES))])
    np.testing.assert_allclose(partial[:, 0], partial[:, 1], rtol=1e-12)


def test_non_finite_poses_and_bad_groups() -> None:
    model, feats, cam, pose, _ = scene(4)
    poses = np.tile(pose, (3, 1))
    poses[1, 12] = np.nan
    partial = model.log_likelihood_partial(feats, poses, SHAPE, cam, GROUPS)
    assert np.all(partial[1] == -np.inf) and np.all(np.isfinite(partial[[0, 2]]))
    for groups in ([[0, 1], [1, 2]], [[0, 10]], [[-1]]):
        with pytest.raises(ValueError, match="log_likelihood_partial: groups"):
            model.log_likelihood_partial(feats, poses, SHAPE, cam, groups)


def test_the_stages_of_each_task() -> None:
    names = [s.name for s in body_part_stages(get_task("BodyTrack-v2").free_indices)]
    assert names == ["torso", "right_arm", "left_arm", "right_leg", "left_leg"]
    arm = body_part_stages(get_task("ArmTrack-v2").free_indices)
    assert [s.name for s in arm] == ["right_arm"] and arm[0].dims.tolist() == [0, 1, 2, 3]
    side = body_part_stages(get_task("SideWalk-v2").free_indices)
    covered = np.sort(np.concatenate([s.dims for s in side]))
    assert covered.tolist() == list(range(get_task("SideWalk-v2").free_indices.size))


# -- the filter on a problem whose answer is known ------------------------------------


def stages(d: int, size: int) -> list[Stage]:
    return [Stage(np.arange(k, k + size), tuple(range(k, k + size))) for k in range(0, d, size)]


def test_one_stage_is_the_particle_filter() -> None:
    prior, like = RandomWalk(0.1), Peaks(0.2)
    ppf = PartitionedParticleFilter(prior, None, like, 200, stages(3, 3))
    assert_tracks_as_the_particle_filter(ppf, prior, like, 200)


def test_partitions_find_a_narrow_peak_in_many_dimensions() -> None:
    # Ten dimensions, each with its own narrow factor: searching two at a time
    # finds the peak that the plain filter, with as many evaluations per frame,
    # misses (MacCormick & Isard 2000, section 4).
    d, frames = 10, [np.full(10, 0.3)] * 6
    errors = {}
    for name in ("pf", "ppf"):
        like = Peaks(0.03)
        if name == "pf":
            f = ParticleFilter(RandomWalk(0.15), None, like, 1000)
        else:
            f = PartitionedParticleFilter(RandomWalk(0.15), None, like, 200, stages(d, 2))
        f.reset(np.zeros(d), np.random.default_rng(0))
        for y in frames:
            estimate = f.step(y)
        errors[name] = float(np.abs(estimate - frames[-1]).max())
        if name == "ppf":
            assert like.calls == 5 * len(frames)  # 5 stages x 200 = the filter's 1,000
    assert errors["ppf"] < 0.05 < errors["pf"], errors


def test_invalid_poses_never_survive() -> None:
    lower, upper = np.array([-0.2, -1.0]), np.array([0.2, 1.0])
    ppf = PartitionedParticleFilter(
        RandomWalk(0.3), None, Peaks(0.1), 300, stages(2, 1), lower=lower, upper=upper
    )
    ppf.reset(np.zeros(2), np.random.default_rng(1))
    for _ in range(5):
        estimate = ppf.step(np.array([0.6, 0.0]))  # the peak lies outside the limits
        assert np.all(ppf.state.pose >= lower) and np.all(ppf.state.pose <= upper)
        assert estimate[0] <= 0.2
    assert len(ppf.stage_survival) == 2


def test_same_seed_same_run() -> None:
    runs = []
    for _ in range(2):
        ppf = PartitionedParticleFilter(RandomWalk(0.1), None, Peaks(0.2), 100, stages(4, 2))
        ppf.reset(np.zeros(4), np.random.default_rng(9))
        runs.append([ppf.step(np.full(4, 0.1 * t)) for t in range(5)])
    np.testing.assert_array_equal(runs[0], runs[1])


def test_bad_arguments() -> None:
    prior, like = RandomWalk(0.1), Peaks(0.2)
    with pytest.raises(ValueError, match="at least one stage"):
        PartitionedParticleFilter(prior, None, like, 10, [])
    with pytest.raises(ValueError, match="none searched by an earlier stage"):
        PartitionedParticleFilter(
            prior, None, like, 10, [Stage(np.array([0, 1]), (0,)), Stage(np.array([1]), (1,))]
        )
    with pytest.raises(ValueError, match="diffusion"):
        PartitionedParticleFilter(prior, None, like, 10, stages(2, 1), diffusion=-1.0)
    ppf = PartitionedParticleFilter(prior, None, like, 10, stages(2, 1))
    with pytest.raises(RuntimeError, match="before reset"):
        ppf.step(np.zeros(2))


def test_stage_dimensions_are_indices_within_the_pose() -> None:
    """A stage's dimension beyond D failed with an IndexError at the first step; a
    float one with numpy's "arrays used as indices"; 2-D dims with "unhashable
    type"; a negative one slipped past the overlap check (-2 is 0 when D = 2)."""
    prior, like = RandomWalk(0.1), Peaks(0.2)
    first = Stage(np.array([0]), (0,), "a")
    for dims in ([1.5], [[1]], [-2], [], np.array([True])):
        with pytest.raises(
            ValueError, match=r"^PartitionedParticleFilter: stage 'b': dims must be a non-empty"
        ):
            PartitionedParticleFilter(prior, None, like, 10, [first, Stage(dims, (1,), "b")])
    stages = [first, Stage(np.array([5]), (1,), "b")]
    ppf = PartitionedParticleFilter(prior, None, like, 10, stages)
    with pytest.raises(ValueError, match=r"stage 'b' searches dimension 5, expected one in 0\.\.1"):
        ppf.reset(np.zeros(2), np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"stage 'b' searches dimension 5, .*\(min_std's D = 2\)"):
        PartitionedParticleFilter(prior, None, like, 10, stages, min_std=[0.1, 0.1])
    # a list of indices is taken, as before
    ppf = PartitionedParticleFilter(prior, None, like, 10, [first, Stage([1], (1,), "b")])
    ppf.reset(np.zeros(2), np.random.default_rng(0))
    assert ppf.step(np.zeros(2)).shape == (2,)


def test_a_partitioned_agent_tracks_end_to_end_and_by_seed(monkeypatch) -> None:
    # The agent table's hook (AgentSpec.partitioned): the constant-velocity prior
    # searched one body part at a time, on the built-in data.
    import dataclasses

    import gymnasium as gym

    from baselines import agents
    from baselines.leaderboard.evaluation import run_episode

    spec = dataclasses.replace(agents.AGENTS["pf-cv"], partitioned=True, diffusion=0.3)
    monkeypatch.setitem(agents.AGENTS, "ppf-cv", spec)
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    runs = []
    for _ in range(2):
        agent = agents.make("ppf-cv", env, n_particles=60, seed=1)
        assert isinstance(agent.filter, PartitionedParticleFilter)
        assert agent.filter.diffusion == 0.3 and len(agent.filter.stages) == 5
        runs.append(run_episode(agent, env, seed=2))
    assert runs[0].errors_mm == runs[1].errors_mm and np.isfinite(runs[0].mean_error_mm)
    assert len(agent.filter.stage_survival) == 5
    with pytest.raises(ValueError, match="no annealing layers"):
        agents.ParticleFilterAgent(env, agent.prior, agent.fitted, 10, layers=3, partitioned=True)
