"""The environment's contract: bad calls refused clearly, atomic resets, Gymnasium's end of episode."""

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from humotion_gym.envs import RESET_OPTIONS
from humotion_gym.wrappers import LearnerObservation


@pytest.fixture
def env():
    e = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False).unwrapped
    yield e
    e.close()


def _truth_action(env):
    return env.pose_to_action(env.library[env._motion.clip_id].params[env._frame_index()])


def _steps_after_the_end(env, action, terminated, truncated, last_obs):
    """Two steps after the end: one warning, the terminal transition again, nothing advances."""
    last = {key: np.array(value, copy=True) for key, value in last_obs.items()}
    np.testing.assert_array_equal(last["frame"], env._frame)
    k, t0 = env._k, env._frame_index()
    with pytest.warns(UserWarning, match="after the episode ended") as record:
        first = env.step(action)
        second = env.step(action)
    assert len([w for w in record if "after the episode ended" in str(w.message)]) == 1
    for obs, reward, term, trunc, info in (first, second):
        assert obs.keys() == last.keys()
        for key in last:  # every key of the last observation again
            np.testing.assert_array_equal(obs[key], last[key], err_msg=key)
        assert reward == 0.0 and (term, trunc) == (terminated, truncated)
        assert info["after_end"] is True and info["frame"] == t0
    assert env._k == k
    # a new episode warns again
    env.reset(seed=1)
    assert "after_end" not in env.step(action)[4]


def test_step_after_the_end_returns_the_terminal_transition(env):
    env.reset(seed=0)
    for _ in range(env.episode_frames):
        obs, _, terminated, truncated, _ = env.step(_truth_action(env))
    assert truncated and not terminated
    _steps_after_the_end(env, _truth_action(env), False, True, obs)


def test_step_after_a_lost_track_returns_the_terminal_transition():
    env = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    env.reset(seed=0)
    far = np.ones(env.action_space.shape, np.float32)
    for _ in range(env.episode_frames):
        obs, _, terminated, truncated, _ = env.step(far)
        if terminated:
            break
    assert terminated
    _steps_after_the_end(env, far, True, False, obs)
    env.close()


def test_step_before_reset_raises(env):
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(env.action_space.shape, np.float32))


def test_a_failed_reset_leaves_the_episode_as_it_was(env):
    obs, info = env.reset(seed=1)
    env.step(_truth_action(env))
    clip, k = env._motion.clip_id, env._k
    rng_state = env.np_random.bit_generator.state
    with pytest.raises(ValueError, match="start"):
        env.reset(seed=5, options={"start": 10**9})
    assert env._motion.clip_id == clip and env._k == k
    assert env.np_random.bit_generator.state == rng_state
    # the episode goes on and still scores the truth perfectly
    _, reward, *_ = env.step(_truth_action(env))
    assert reward == pytest.approx(1.0)


def test_a_failed_first_reset_leaves_an_unstarted_env(env):
    with pytest.raises(ValueError):
        env.reset(seed=0, options={"start": 10**9})
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(env.action_space.shape, np.float32))
    env.reset(seed=0)  # and a good reset still works


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"clip": "x"}, "unknown options"),
        ({"clip_id": "nope/none"}, "not in the library"),
        ({"clip_id": 3}, "not in the library"),
        ({"motion": "walk.bvh"}, "must be a humotion_gym Motion"),
        ({"start": 2.7}, "must be an integer"),
        ({"start": True}, "must be an integer"),
        ({"start": -1}, "must be in"),
        ({"clip_id": "a", "motion": None}, "at most one"),
    ],
)
def test_bad_reset_options_are_refused(env, options, match):
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options=options)


def test_the_valid_options_are_listed():
    assert RESET_OPTIONS == ("clip_id", "file", "motion", "start")


@pytest.mark.parametrize("clips", [0, 2])
def test_a_folder_or_a_number_is_not_a_file(env, tmp_path, clips):
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.library import synthetic_library

    for k, motion in enumerate(list(synthetic_library())[:clips]):  # a folder used its first
        write_motion_bvh(tmp_path / f"c{k}.bvh", motion.params[:40], motion.shape, motion.fps)
    (tmp_path / "notes.txt").write_text("walk\n")
    (tmp_path / "dir.bvh").mkdir()
    for file in (str(tmp_path), tmp_path, 123, tmp_path / "notes.txt", tmp_path / "dir.bvh"):
        with pytest.raises(ValueError, match=r"^reset: options\['file'\] must be the path of one"):
            env.reset(seed=0, options={"file": file})


def test_a_missing_file_is_not_found(env, tmp_path):
    # It was a ValueError ("must be the path of one .bvh or .amc file"), unlike
    # a missing data_dir or load_bvh's FileNotFoundError.
    missing = tmp_path / "missing.bvh"
    with pytest.raises(FileNotFoundError, match=rf"^reset: options\['file'\] {missing}: no such"):
        env.reset(seed=0, options={"file": str(missing)})


def test_a_motion_at_another_rate_is_refused(env):
    from humotion_gym.mocap.library import synthetic_library

    motion = synthetic_library(fps=60)["synthetic/reach-01"]
    with pytest.raises(ValueError, match="is at 60 Hz, the environment's clips at 30 Hz"):
        env.reset(seed=0, options={"motion": motion})


def test_a_start_out_of_range_names_the_clip_and_says_to_choose_it(env):
    with pytest.raises(ValueError, match=r"\) for synthetic/.*; without clip_id the clip is drawn"):
        env.reset(seed=0, options={"start": 10_000})
    clip = env.unwrapped.clips[0].clip_id
    with pytest.raises(ValueError, match=rf"\) for {clip} \(\d+ frames, an episode spans \d+\)$"):
        env.reset(seed=0, options={"clip_id": clip, "start": 10_000})


@pytest.mark.parametrize(
    "action",
    [
        np.zeros(25, dtype=complex),
        np.array(["0.1"] * 25),
        np.zeros(25, dtype=bool),
        np.array([None] * 25, dtype=object),
    ],
)
def test_actions_of_non_real_dtypes_are_refused(env, action):
    env.reset(seed=0)
    with pytest.raises(ValueError, match="real numbers"):
        env.step(action)


def test_a_ragged_action_is_refused_in_the_envs_words(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must be an array of shape \(25,\)"):
        env.step([[0.0] * 24, [0.0]])


def test_ragged_actions_are_refused_by_the_vector_env():
    envs = gym.make_vec(
        "humotion_gym/ArmTrack-v2", num_envs=2, vectorization_mode="vector_entry_point"
    )
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must be an array of shape \(2, 4\)"):
        envs.step([[0.0] * 4, [0.0]])
    envs.close()


def test_integer_actions_are_accepted(env):
    env.reset(seed=0)
    env.step(np.zeros(25, dtype=np.int64))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"lost_threshold_mm": float("nan")},
        {"lost_threshold_mm": -1.0},
        {"reward_scale_mm": float("inf")},
        {"episode_frames": 0},
        {"episode_frames": 2.5},
        {"lost_patience": 0},
        {"frame_skip": 0},
        {"fps": 0.0},
        {"split": "dev"},  # the splits are train, validation and test
        {"fps": 2000.0},  # above the fastest capture a clip only grows
        {"terminate_on_lost": "no"},  # a truthy string, not False
        {"floor": "yes"},
        {"noise": "x"},
        {"blur": -1.0},
        {"occluders": 1.5},
        {"occluders": -1},
        {"data_dir": 123},
        {"data_dir": [1, 2]},
        {"data_dir": ""},  # Path("") is the working folder
        {"library": "x"},
        # None where the default is a value: it was read as False (never lost) or failed in int()
        {"terminate_on_lost": None},
        {"frame_skip": None},
        {"lost_patience": None},
        {"camera_elevation_deg": "40"},
        {"camera_elevation_deg": True},
        {"task": 3},
    ],
)
def test_constructor_arguments_are_range_checked(kwargs):
    name = next(iter(kwargs))
    with pytest.raises(ValueError, match=f"^{name}: expected"):
        gym.make("humotion_gym/ArmTrack-v2", **kwargs)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"terminate_on_lost": np.bool_(False)},
        {"floor": True},
        {"noise": 0},
        {"occluders": np.int64(2)},
        {"fps": 240.0},
    ],
)
def test_the_checks_take_what_the_arguments_take(kwargs):
    gym.make("humotion_gym/ArmTrack-v2", **kwargs).close()


def test_a_data_dir_without_motion_capture_says_so(tmp_path):
    with pytest.raises(ValueError, match=r"^data_dir \[.*\]: no motion capture \(.bvh, .amc\)"):
        gym.make("humotion_gym/ArmTrack-v2", data_dir=str(tmp_path))


def test_pose_to_action_refuses_another_length(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"expected poses of shape \(\.\.\., 25\), got \(24,\)"):
        env.pose_to_action(np.zeros(24))


def test_a_registered_id_refuses_another_familys_task():
    with pytest.raises(ValueError, match="^task: BodyTrackEnv tracks BodyTrack tasks, got Wal"):
        gym.make("humotion_gym/BodyTrack-v2", task="WalkTrack-v2")
    views = gym.make("humotion_gym/BodyTrack2Views-v2").unwrapped  # its own family's variant
    assert views.task.family == "BodyTrack" and views.views == 2


def test_a_given_library_sets_the_frame_rate_and_is_the_only_data():
    from humotion_gym.mocap.library import synthetic_library

    library = synthetic_library(fps=60)
    env = gym.make("humotion_gym/ArmTrack-v2", library=library).unwrapped
    assert env.metadata["render_fps"] == 60.0 and env.describe().fps == 60.0
    env = gym.make("humotion_gym/ArmTrack-v2", library=library, frame_skip=2).unwrapped
    assert env.metadata["render_fps"] == 30.0
    gym.make("humotion_gym/ArmTrack-v2", library=library, fps=60)  # its own rate, said again
    with pytest.raises(ValueError, match=r"^fps=30, but the library's clips are at 60 Hz"):
        gym.make("humotion_gym/ArmTrack-v2", library=library, fps=30)
    with pytest.raises(ValueError, match="^give library or data_dir, not both"):
        gym.make("humotion_gym/ArmTrack-v2", library=library, data_dir="/nonexistent")


def test_version_1_draws_the_held_out_persons_by_default_as_it_did():
    with pytest.warns(FutureWarning):
        v1 = gym.make("humotion_gym/BodyTrack-v1")
        chosen = gym.make("humotion_gym/BodyTrack-v1", split="train")
    assert (v1.unwrapped.split, chosen.unwrapped.split) == ("test", "train")
    assert gym.make("humotion_gym/BodyTrack-v2").unwrapped.split == "train"


@pytest.mark.parametrize("env_id", humotion_gym.ENV_IDS)
def test_every_spec_states_its_episode_length(env_id):
    from humotion_gym.envs import get_task

    spec = gym.spec(env_id)
    frames = get_task(env_id.split("/")[-1]).episode_frames
    assert spec.max_episode_steps == frames
    env = gym.make(env_id, terminate_on_lost=False)
    env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample() * 0)
        assert not terminated
        steps += 1
    assert steps == frames  # the wrapper and the environment end the episode together
    env.close()


def test_the_vector_env_ends_episodes_at_max_episode_steps_as_time_limit_does():
    envs = gym.make_vec(
        "humotion_gym/SideWalk-v2", num_envs=2, vectorization_mode="vector_entry_point",
        max_episode_steps=7, terminate_on_lost=False,
    )  # fmt: skip
    envs.reset(seed=0)
    for step in range(1, 8):
        _, _, terminated, truncated, _ = envs.step(np.zeros(envs.action_space.shape))
        assert not terminated.any()
        assert truncated.all() == (step == 7)
    envs.close()


@pytest.mark.parametrize("env_id", [i for i in humotion_gym.ENV_IDS if "-v1" not in i])
def test_observations_keep_the_order_of_their_space(env_id):
    # spaces.Dict sorts its keys; a flattening or a loop over obs.values() reads
    # the space's order, and the vector envs Gymnasium makes (sync, async) give it.
    env = gym.make(env_id)
    order = list(env.observation_space.spaces)
    obs, _ = env.reset(seed=0)
    assert list(obs) == order
    assert list(env.step(env.action_space.sample())[0]) == order
    env.close()
    if gym.spec(env_id).vector_entry_point is None:  # the multi-view tasks
        return
    learner = LearnerObservation(gym.make(env_id))  # what a learned policy sees (one view)
    learner_order = list(learner.observation_space.spaces)
    assert list(learner.reset(seed=0)[0]) == learner_order
    assert list(learner.step(learner.action_space.sample())[0]) == learner_order
    learner.close()
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    assert list(venv.observation_space.spaces) == order
    obs, _ = venv.reset(seed=0)
    assert list(obs) == order
    assert list(venv.step(venv.action_space.sample())[0]) == order
    venv.close()
