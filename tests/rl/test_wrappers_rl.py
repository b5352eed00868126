"""The learner wrappers: the Dict observation and the training-only supervision."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import FrameStackObservation

import humotion_gym  # noqa: F401  (registers the tasks)
from humotion_gym.envs import CURRENT_TASKS, ENV_IDS
from humotion_gym.wrappers import (
    LearnerObservation,
    Supervision,
    learner_frame,
    learner_frames,
    learner_observation,
    learner_observation_space,
)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_learner_observation_passes_the_sb3_checker(env_id: str) -> None:
    check_env = pytest.importorskip("stable_baselines3.common.env_checker").check_env

    if "Views" in env_id:  # several cameras: the learners take one
        with pytest.raises(ValueError, match="LearnerObservation: expected one view"):
            LearnerObservation(gym.make(env_id), size=48)
        return
    env = LearnerObservation(gym.make(env_id), size=48)
    check_env(env, warn=False)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    n_free = env.action_space.shape[0]
    assert obs["frame"].shape == (3, 48, 48)
    assert obs["previous"].shape == obs["initial"].shape == (n_free,)


def test_learner_observation_refuses_an_env_that_hides_the_initial_pose() -> None:
    from humotion_gym.wrappers import FrameObservation

    with pytest.raises(ValueError, match="must show the task's 'frame' and 'initial_pose'"):
        LearnerObservation(FrameObservation(gym.make("humotion_gym/ArmTrack-v2")), size=32)


@pytest.mark.parametrize("task", [t.name for t in CURRENT_TASKS])
def test_learner_wrappers_pass_gymnasiums_checker_and_record_their_arguments(task: str) -> None:
    """Gymnasium's check_env and a spec that remakes the wrapped env (RecordConstructorArgs)."""
    from gymnasium.utils.env_checker import check_env

    for make_wrapped in (
        lambda: LearnerObservation(gym.make(f"humotion_gym/{task}", split="train"), size=24),
        lambda: Supervision(gym.make(f"humotion_gym/{task}", split="train")),
    ):
        env = make_wrapped()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "different from the unwrapped version": meant
            check_env(env, skip_render_check=True)
        again = gym.make(env.spec)
        assert type(again) is type(env)
        assert getattr(again, "size", None) == getattr(env, "size", None)
        env.close()
        again.close()


def test_previous_is_the_last_action_and_starts_at_the_initial_pose() -> None:
    env = LearnerObservation(gym.make("humotion_gym/BodyTrack-v2"), size=32)
    base = env.unwrapped
    obs, info = env.reset(seed=1)
    plain_obs, _ = gym.make("humotion_gym/BodyTrack-v2").reset(seed=1)
    assert np.array_equal(plain_obs["initial_pose"], base._motion.params[info["start_frame"]])
    initial = base.pose_to_action(plain_obs["initial_pose"])
    np.testing.assert_array_equal(obs["initial"], initial)
    np.testing.assert_array_equal(obs["previous"], initial)
    rng = np.random.default_rng(0)
    for _ in range(4):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, *_ = env.step(action)
        np.testing.assert_array_equal(obs["previous"], action)
        np.testing.assert_array_equal(obs["initial"], initial)


def test_the_observation_is_the_frame_and_the_agents_own_actions_only() -> None:
    """No truth enters: the wrapper's observation is a function of the plain env's frame,
    the actions taken and the reset's initial pose."""
    plain = gym.make("humotion_gym/WalkTrack-v2")
    wrapped = LearnerObservation(gym.make("humotion_gym/WalkTrack-v2"), size=40)
    given, _ = plain.reset(seed=5)
    frame = given["frame"]
    obs, _ = wrapped.reset(seed=5)
    initial = plain.unwrapped.pose_to_action(given["initial_pose"])
    expected = learner_observation(frame, initial, initial, 40)
    for key in expected:
        np.testing.assert_array_equal(obs[key], expected[key])
    action = np.zeros(plain.action_space.shape, np.float32)
    frame = plain.step(action)[0]["frame"]
    obs, *_ = wrapped.step(action)
    expected = learner_observation(frame, action, initial, 40)
    for key in expected:
        np.testing.assert_array_equal(obs[key], expected[key])


def test_learner_observation_clips_the_estimates_into_their_space() -> None:
    """The saved policy's agent passes its raw last action: both vectors end in [-1, 1]."""
    frame = np.zeros((16, 16, 3), np.uint8)
    wild = np.array([-3.0, -1.0, -0.25, 0.5, 1.0, 2.5])
    obs = learner_observation(frame, wild, wild[::-1], None)
    np.testing.assert_array_equal(obs["previous"], [-1.0, -1.0, -0.25, 0.5, 1.0, 1.0])
    np.testing.assert_array_equal(obs["initial"], [1.0, 1.0, 0.5, -0.25, -1.0, -1.0])
    assert learner_observation_space((16, 16, 3), 6, None).contains(obs)


def test_learner_frame_averages_pixel_blocks() -> None:
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)
    small = learner_frame(frame, 32)
    blocks = frame.reshape(32, 2, 32, 2, 3).astype(float).mean(axis=(1, 3)).transpose(2, 0, 1)
    assert small.shape == (3, 32, 32)
    assert np.max(np.abs(small - blocks)) <= 1.0
    np.testing.assert_array_equal(learner_frame(frame, None), frame.transpose(2, 0, 1))
    with pytest.raises(ValueError, match="uint8"):
        learner_frame(frame.astype(np.float32), 32)


@pytest.mark.parametrize(
    ("shape", "size"),
    [((4, 64, 64, 3), 32), ((3, 64, 64, 1), 32), ((2, 60, 60, 3), 32), ((2, 64, 64, 3), None),
     ((0, 64, 64, 3), 32)],
)  # fmt: skip
def test_learner_frames_are_each_frames_learner_frame(shape: tuple, size: int | None) -> None:
    frames = np.random.default_rng(1).integers(0, 256, shape, dtype=np.uint8)
    batch = learner_frames(frames, size)
    side = shape[1] if size is None else size
    assert batch.shape == (shape[0], shape[3], side, side) and batch.flags.c_contiguous
    for frame, small in zip(frames, batch, strict=True):
        np.testing.assert_array_equal(small, learner_frame(frame, size))
    with pytest.raises(ValueError, match=r"learner_frames: expected \(N, H, W, C\) uint8"):
        learner_frames(frames[..., 0], size)


def test_bad_size_is_refused() -> None:
    with pytest.raises(ValueError, match="size"):
        LearnerObservation(gym.make("humotion_gym/ArmTrack-v2"), size=2)


def test_frame_stacking_through_gymnasium() -> None:
    env = FrameStackObservation(LearnerObservation(gym.make("humotion_gym/ArmTrack-v2"), 32), 3)
    obs, _ = env.reset(seed=0)
    assert obs["frame"].shape == (3, 3, 32, 32)
    assert obs["previous"].shape == (3, 4)
    assert env.observation_space.contains(obs)


def test_supervision_refuses_a_test_split_env() -> None:
    for split in ("test", "validation"):
        with pytest.raises(ValueError, match="split='train'"):
            Supervision(gym.make("humotion_gym/BodyTrack-v2", split=split))
    with pytest.raises(ValueError, match="test"):
        Supervision(LearnerObservation(gym.make("humotion_gym/ArmTrack-v2", split="test")))
    Supervision(gym.make("humotion_gym/BodyTrack-v2"))  # the default split is train


@pytest.mark.parametrize("person", ["synthetic-05", "synthetic-03"])
def test_supervision_checks_the_person_of_every_episode(person: str) -> None:
    # A train env whose clips were (wrongly) given a held-out person's clip:
    # the env alone shows it, Supervision refuses the episode.
    from humotion_gym.mocap.library import MotionLibrary

    env = Supervision(gym.make("humotion_gym/BodyTrack-v2"))
    base = env.unwrapped
    env.reset(seed=0)  # a training person's episode is labelled
    held = tuple(m for m in base.library if m.subject == person)
    base.clips = MotionLibrary(held, base.clips.test_subjects)
    assert base.reset(seed=1)[1]["person"] == person
    with pytest.raises(ValueError, match=person):
        env.reset(seed=1)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_the_true_action_scores_perfectly(env_id: str) -> None:
    env = Supervision(gym.make(env_id, split="train", terminate_on_lost=False))
    _, info = env.reset(seed=2)
    for _ in range(6):
        _, reward, _, _, info_next = env.step(info["true_action"])
        assert info_next["error_mm"] < 1e-3
        assert reward == pytest.approx(1.0, abs=1e-5)
        info = info_next


@pytest.mark.parametrize("size", [0, 7, "64", 64.0, True, 641, 10**5])
def test_every_learner_env_refuses_the_same_frame_sizes(size) -> None:
    pytest.importorskip("stable_baselines3")
    from humotion_gym.sb3 import LearnerVecEnv, learner_vec_env

    with pytest.raises(ValueError, match="LearnerObservation: size must be an integer >= 8"):
        LearnerObservation(gym.make("humotion_gym/ArmTrack-v2"), size=size)
    with pytest.raises(ValueError, match="learner_vec_env: frame_size must be an integer >= 8"):
        learner_vec_env("ArmTrack-v2", 2, frame_size=size)
    venv = learner_vec_env("ArmTrack-v2", 2, frame_size=None).venv
    with pytest.raises(ValueError, match="LearnerVecEnv: frame_size must be an integer >= 8"):
        LearnerVecEnv(venv, size)
    for name, fn, frames in (
        ("learner_frame", learner_frame, np.zeros((16, 16, 3), np.uint8)),
        ("learner_frames", learner_frames, np.zeros((1, 16, 16, 3), np.uint8)),
    ):
        with pytest.raises(ValueError, match=f"{name}: size must be an integer >= 8"):
            fn(frames, size)


@pytest.mark.parametrize("wrapper", ["LearnerObservation", "Supervision"])
def test_an_action_wrapper_inside_a_learner_wrapper_is_refused_naming_it(wrapper: str) -> None:
    """Inside, it would put the previous estimate (or the true action) in two coordinate
    systems at once: a previous estimate of [-1, 1] at the reset and [0, 1] after, a true
    action 480 mm off. Outside, the learner wrapper's actions are the task's."""
    from gymnasium.wrappers import ClipAction, RescaleAction, TransformAction

    wrap = {"LearnerObservation": LearnerObservation, "Supervision": Supervision}[wrapper]

    def task() -> gym.Env:
        return gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)

    low, high = np.zeros(4, np.float32), np.ones(4, np.float32)

    for inner in (
        RescaleAction(task(), low, high),
        ClipAction(task()),
        TransformAction(task(), lambda a: -a, None),  # the same space, other actions
    ):
        name = type(inner).__name__
        with pytest.raises(ValueError, match=rf"{wrapper}: .*but {name} maps them.*"
                           rf"outside, e.g. {name}\({wrapper}\(env\), \.\.\.\)"):  # fmt: skip
            wrap(inner)
    # outside: the hold action (the initial pose) comes back as the previous estimate ...
    env = RescaleAction(LearnerObservation(task(), size=16), low, high)
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs["previous"], obs["initial"])
    obs, *_ = env.step((obs["initial"] + 1) / 2)
    np.testing.assert_allclose(obs["previous"], obs["initial"], atol=1e-6)
    # ... and the true action, in the task's actions, scores 0 mm
    env = Supervision(task())
    _, info = env.reset(seed=0)
    assert env.step(info["true_action"])[-1]["error_mm"] < 1e-3


def test_frames_stacked_inside_the_learner_observation_are_refused_at_construction() -> None:
    """Accepted, it failed at reset deep inside: 'learner_frame: expected an (H, W, C) ...'."""
    for task in ("ArmTrack-v2", "ArmTrack-v1"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)  # version 1: meant
            stacked = FrameStackObservation(gym.make(f"humotion_gym/{task}"), 3)
        with pytest.raises(ValueError, match=r"FrameStackObservation changes them.*"
                           r"FrameStackObservation\(LearnerObservation\(env\), 3\)"):  # fmt: skip
            LearnerObservation(stacked, size=16)


def test_the_observation_wrapper_refused_is_named_as_it_is() -> None:
    from gymnasium.wrappers import FilterObservation, FlattenObservation

    from humotion_gym.wrappers import FrameObservation

    for inner, name in (
        (FlattenObservation(gym.make("humotion_gym/ArmTrack-v2")), "FlattenObservation"),
        (FrameObservation(gym.make("humotion_gym/ArmTrack-v2")), "FrameObservation"),
        (FilterObservation(gym.make("humotion_gym/ArmTrack-v2"), ["frame"]), "FilterObservation"),
    ):
        with pytest.raises(ValueError) as caught:
            LearnerObservation(inner, size=16)
        message = str(caught.value)
        assert f"but {name} changes them" in message
        assert f"not {name} of it" in message
        assert name == "FrameObservation" or "FrameObservation" not in message
    # a wrapper that keeps the frame and the initial pose is no reason to refuse
    kept = FilterObservation(gym.make("humotion_gym/ArmTrack-v2"), ["frame", "initial_pose"])
    assert LearnerObservation(kept, size=16).reset(seed=0)[0]["frame"].shape == (3, 16, 16)
