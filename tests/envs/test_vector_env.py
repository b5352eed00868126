"""The batched vector env gives what N single environments give (Gymnasium's sync vector env).

For every registered task and each autoreset mode, ``make_vec(...,
vectorization_mode="vector_entry_point")`` and ``vectorization_mode="sync"``
are reset with the same seeds and stepped with the same actions (near the
truth and far from it, so episodes end by truncation and by lost track), and
must return identical observations, terminations, truncations and batched
info keys, dtypes and ``_key`` masks. Rewards and errors are the same
function of the same numbers computed over a batch instead of one row, so they
may differ in the last bits of a sum: they are compared to 1e-12 relative
(a millionth of a millionth of a reward; a lost-track decision would need an
error within that of the 150 mm threshold).
"""

from __future__ import annotations

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from humotion_gym.camera import Camera
from humotion_gym.envs import ENV_IDS, get_task
from humotion_gym.envs.vector import PoseTrackingVectorEnv
from humotion_gym.mocap.library import synthetic_library

RTOL = 1e-12


def _assert_same(a, b, where: str = "") -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), (where, sorted(a), sorted(b))
        for key in a:
            _assert_same(a[key], b[key], f"{where}/{key}")
    elif isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray), where
        assert a.dtype == b.dtype and a.shape == b.shape, (
            where,
            a.dtype,
            b.dtype,
            a.shape,
            b.shape,
        )
        if a.dtype == object:
            for x, y in zip(a, b, strict=True):
                _assert_same(x, y, where)
        elif a.dtype.kind == "f":
            np.testing.assert_allclose(a, b, rtol=RTOL, atol=0, err_msg=where)
        else:
            assert np.array_equal(a, b), (where, a, b)
    elif isinstance(a, Camera):
        assert isinstance(b, Camera)
        assert np.array_equal(a.rotation, b.rotation) and np.array_equal(a.position, b.position)
        assert (a.focal, a.principal_point) == (b.focal, b.principal_point), where
    elif dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, float):
        assert type(a) is type(b) and a == pytest.approx(b, rel=RTOL, abs=0), (where, a, b)
    else:
        assert type(a) is type(b) and a == b, (where, a, b)


def _rows(obs, index):
    """Rows ``index`` of a batched observation (a version-2 ``Dict``: of every key)."""
    if isinstance(obs, dict):
        return {key: value[index] for key, value in obs.items()}
    return obs[index]


def _assert_row(obs, i: int, single, where: str = "") -> None:
    """Row ``i`` of a batched observation is a single env's observation, key by key."""
    row = _rows(obs, i)
    if isinstance(single, dict):
        assert isinstance(row, dict) and row.keys() == single.keys(), where
        for key in single:
            np.testing.assert_array_equal(row[key], single[key], err_msg=f"{where}/{key}")
    else:
        np.testing.assert_array_equal(row, single, err_msg=where)


def _actions(venv, rng: np.random.Generator, t: int) -> np.ndarray:
    """Near the truth (episodes run to their end), but far from it for six steps (lost)."""
    if 40 <= t < 46:
        return rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32)
    truth = np.stack([env.pose_to_action(env.true_pose()) for env in venv.unwrapped.envs])
    return np.clip(truth + rng.normal(0, 0.01, truth.shape), -1, 1).astype(np.float32)


MONOCULAR_IDS = [env_id for env_id in ENV_IDS if get_task(env_id).views == 1]


@pytest.mark.parametrize("env_id", [i for i in ENV_IDS if i not in MONOCULAR_IDS])
def test_the_vector_env_refuses_several_views_naming_the_argument(env_id):
    with pytest.raises(ValueError, match=r"views: .*views=1.*got views=[24].*sync"):
        PoseTrackingVectorEnv(2, task="BodyTrack-v2", views=2)
    assert gym.spec(env_id).vector_entry_point is None
    # make_vec's default, and what the error points to: single environments in sync
    envs = gym.make_vec(env_id, num_envs=2)
    obs, _ = envs.reset(seed=0)
    assert obs["frame"].shape == (2, get_task(env_id).views, 128, 128, 3)
    envs.close()


@pytest.mark.parametrize("env_id", MONOCULAR_IDS)
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_vector_env_equals_sync_vector_env(env_id, mode):
    n = 3
    kwargs = {"width": 64, "height": 64}
    vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                       **kwargs)  # fmt: skip
    sync = gym.make_vec(env_id, n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)  # fmt: skip
    assert isinstance(vec.unwrapped, PoseTrackingVectorEnv)
    assert vec.metadata["autoreset_mode"] == mode
    assert vec.observation_space == sync.observation_space
    assert vec.action_space == sync.action_space
    _assert_same(vec.reset(seed=7), sync.reset(seed=7), "reset")
    rng = np.random.default_rng(1)
    ends = {"terminated": 0, "truncated": 0}
    steps = 2 * vec.unwrapped.envs[0].episode_frames + 10
    for t in range(steps):
        actions = _actions(vec, rng, t)
        got, want = vec.step(actions), sync.step(actions)
        _assert_same(got, want, f"step {t}")
        ends["terminated"] += int(want[2].sum())
        ends["truncated"] += int(want[3].sum())
    # both ways an episode ends were exercised
    assert ends["terminated"] > 0 and ends["truncated"] > 0, ends
    # a reset with a mask and a list of seeds
    mask = np.array([True, False, True])
    got = vec.reset(seed=[3, 4, 5], options={"reset_mask": mask})
    want = sync.reset(seed=[3, 4, 5], options={"reset_mask": mask.copy()})
    _assert_same(got, want, "masked reset")  # the row not reset goes on showing its frame
    for t in range(3):
        actions = _actions(vec, rng, t)
        _assert_same(vec.step(actions), sync.step(actions), f"step {t} after the masked reset")


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_a_loss_on_the_last_frame_and_a_frame_skip_are_the_sync_envs(mode):
    """Every other frame shown, and episodes lost on their last frame, before it, or never."""
    n, env_id = 3, "humotion_gym/BodyTrack-v2"
    kwargs = {"width": 64, "height": 64, "episode_frames": 4, "lost_patience": 1, "frame_skip": 2}
    vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                       **kwargs)  # fmt: skip
    sync = gym.make_vec(env_id, n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)  # fmt: skip
    obs, info = vec.reset(seed=2)
    _assert_same((obs, info), sync.reset(seed=2), "reset")
    first = info["frame"].copy()
    bad_at = np.array([4, 2, 0])  # the step each row's estimate is far off (0: never)
    for t in range(1, 5):
        truth = np.stack([env.pose_to_action(env.true_pose()) for env in vec.unwrapped.envs])
        actions = np.where((bad_at == t)[:, None], 1.0, truth).astype(np.float32)
        got = vec.step(actions)
        _assert_same(got, sync.step(actions), f"step {t}")
        if t < 4:  # rows 0 and 2 go on: every frame shown is two on from the last one
            assert np.array_equal(got[4]["frame"][[0, 2]], first[[0, 2]] + 2 * t)
    # the last step: row 0 lost (terminated alone), row 2 at its end (truncated)
    assert got[2].tolist() == [True, False, False] and got[3].tolist() == [False, False, True]


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_a_step_limit_cuts_episodes_as_time_limit_does(mode):
    """make_vec(max_episode_steps=m): the episodes drawn at the task's length, cut after m steps."""
    n, env_id = 3, "humotion_gym/BodyTrack-v2"
    kwargs = {"width": 64, "height": 64, "max_episode_steps": 7, "terminate_on_lost": False}
    vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                       **kwargs)  # fmt: skip
    sync = gym.make_vec(env_id, n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)  # fmt: skip
    _assert_same(vec.reset(seed=0), sync.reset(seed=0), "reset")
    rng = np.random.default_rng(2)
    cut = 0
    for t in range(17):
        actions = _actions(vec, rng, t)
        got, want = vec.step(actions), sync.step(actions)
        _assert_same(got, want, f"step {t}")
        cut += int(want[3].sum())
    assert cut >= n  # every episode was cut at least once


@pytest.mark.parametrize("kwargs", [{"occluders": 2}, {"blur": 1.0, "noise": 30.0},
                                    {"color": "gray"}])  # fmt: skip
def test_vector_env_scenes_are_the_sync_envs(kwargs):
    # The frames' noise comes from the windows drawn at each episode's start:
    # the same frames as the single environments', which draw them frame by frame.
    n, env_id = 2, "humotion_gym/BodyTrack-v2"
    kwargs = {"width": 64, "height": 64, "episode_frames": 8, **kwargs}
    vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec(env_id, n, vectorization_mode="sync", **kwargs)
    _assert_same(vec.reset(seed=11), sync.reset(seed=11), "reset")
    rng = np.random.default_rng(2)
    for t in range(2 * 8 + 3):  # through two restarts
        actions = _actions(vec, rng, t)
        _assert_same(vec.step(actions), sync.step(actions), f"step {t}")


def test_vector_env_disabled_autoreset_steps_after_the_end_as_the_single_env():
    """Ended episodes not yet reset give the single env's step after the end.

    (SyncVectorEnv refuses such a step, so the reference is the single envs.)
    """
    n, env_id = 2, "humotion_gym/BodyTrack-v2"
    mode = AutoresetMode.DISABLED
    vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", autoreset_mode=mode)
    singles = [gym.make(env_id).unwrapped for _ in range(n)]
    obs, _ = vec.reset(seed=0)
    for i, env in enumerate(singles):
        _assert_row(obs, i, env.reset(seed=i)[0], "reset")
    far = np.ones(vec.action_space.shape, np.float32)

    def both_step(where: str) -> tuple:
        got = vec.step(far)
        obs, reward, term, trunc, info = got
        for i, env in enumerate(singles):
            w_obs, w_reward, w_term, w_trunc, w_info = env.step(far[i])
            _assert_row(obs, i, w_obs, where)
            assert reward[i] == pytest.approx(w_reward, rel=RTOL, abs=0), where
            assert (term[i], trunc[i]) == (w_term, w_trunc), where
            after = info.get("after_end", np.zeros(n, bool))[i]
            assert bool(after) == w_info.get("after_end", False), where
        return got

    done = np.zeros(n, bool)
    for t in range(vec.unwrapped.envs[0].episode_frames):
        _, _, term, trunc, _ = both_step(f"step {t}")
        done |= term | trunc
        if done.all():
            break
    assert done.all()  # far from the truth: both lose track together
    with pytest.warns(UserWarning, match="after the episode ended"):
        _, reward, term, trunc, info = both_step("after the end")
    assert (reward == 0).all() and info["after_end"].all() and (term | trunc).all()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per episode
        both_step("after the end, again")
    obs, _ = vec.reset(seed=[5, 6], options={"reset_mask": done})
    for i, env in enumerate(singles):
        _assert_row(obs, i, env.reset(seed=5 + i)[0], "masked reset")
    obs, reward, *_ = vec.step(far)
    for i, env in enumerate(singles):
        _assert_row(obs, i, env.step(far[i])[0], "step after the masked reset")


def test_vector_env_refuses_bad_calls():
    with pytest.raises(ValueError, match="num_envs"):
        PoseTrackingVectorEnv(0)
    with pytest.raises(ValueError, match=r"autoreset_mode: expected one of \['NextStep', "):
        PoseTrackingVectorEnv(2, autoreset_mode="same_step")
    vec = PoseTrackingVectorEnv(2, task="SideWalk-v2")
    with pytest.raises(RuntimeError, match="reset"):
        vec.step(np.zeros(vec.action_space.shape, np.float32))
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        vec.step(np.zeros(vec.single_action_space.shape, np.float32))
    with pytest.raises(ValueError, match="finite"):
        vec.step(np.full(vec.action_space.shape, np.nan, np.float32))
    with pytest.raises(ValueError, match="seeds"):
        vec.reset(seed=[1, 2, 3])


def test_a_closed_vector_env_refuses_reset_and_step_as_async_vector_env_does():
    """Drawing in-process it went on after close(); drawing ahead it failed obscurely (its
    worker gone): both now say it was closed (tests/envs/test_frame_stream.py, ahead)."""
    from gymnasium.error import ClosedEnvironmentError

    vec = PoseTrackingVectorEnv(2, task="ArmTrack-v2")
    vec.reset(seed=0)
    zero = np.zeros(vec.action_space.shape, np.float32)
    vec.step(zero)
    vec.close()
    with pytest.raises(ClosedEnvironmentError, match="step: the vector environment was closed"):
        vec.step(zero)
    with pytest.raises(ClosedEnvironmentError, match="reset: the vector environment was closed"):
        vec.reset(seed=0)
    vec.close()  # again: nothing


@pytest.mark.parametrize(
    ("seed", "got"),
    [(1.5, "got 1.5"), (True, "got True"), ("0", "got '0'"), (-1, "got -1"),
     ([1, 2, 3], "got a list of 3 seeds"), ([1.5, 2], r"got 1\.5 in \[1\.5, 2\]"),
     ([None, False], "got False in"), ({0: 1, 1: 2}, "got {0: 1, 1: 2}")],
)  # fmt: skip
def test_a_seed_it_cannot_take_is_refused_naming_seed(seed, got):
    """'float' object is not iterable, 'bool' object is not iterable, or "0" read as a list."""
    vec = PoseTrackingVectorEnv(2, task="ArmTrack-v2")
    takes = r"an integer >= 0, a list of num_envs=2 seeds \(each an integer >= 0 or None\), or None"
    with pytest.raises(ValueError, match=rf"^reset: seed must be {takes}, {got}"):
        vec.reset(seed=seed)
    # what it takes: numpy's integers too, each the seed its int gives
    first = vec.reset(seed=[np.int64(4), None])[0]["initial_pose"][0]
    assert np.array_equal(first, vec.reset(seed=4)[0]["initial_pose"][0])
    assert vec.reset(seed=np.array([4, 5]))[1]["clip_id"].tolist() == (
        vec.reset(seed=(4, 5))[1]["clip_id"].tolist()
    )


def test_vector_env_render_is_each_episodes_render():
    vec = gym.make_vec("humotion_gym/BodyTrack-v2", 2, vectorization_mode="vector_entry_point",
                       render_mode="rgb_array")  # fmt: skip
    vec.reset(seed=0)
    vec.step(vec.action_space.sample())
    frames = vec.render()
    assert len(frames) == 2
    for frame, env in zip(frames, vec.unwrapped.envs, strict=True):
        assert np.array_equal(frame, env.render())


def test_the_vector_env_answers_what_sync_vector_env_answers():
    """render before reset, the episodes' seeds and generators, call, get_attr, set_attr."""
    kwargs = {"width": 64, "height": 64, "render_mode": "rgb_array"}
    vec = gym.make_vec("humotion_gym/BodyTrack-v2", 2, vectorization_mode="vector_entry_point",
                       **kwargs).unwrapped  # fmt: skip
    sync = gym.make_vec("humotion_gym/BodyTrack-v2", 2, vectorization_mode="sync", **kwargs)
    from gymnasium.error import ResetNeeded

    for venv in (vec, sync):  # sync's episodes are gym.make's, which enforce the order
        with pytest.raises(ResetNeeded):
            venv.render()
    vec.reset(seed=3)
    sync.reset(seed=3)
    assert vec.np_random_seed == sync.np_random_seed == (3, 4)
    assert [g.random() for g in vec.np_random] == [g.random() for g in sync.np_random]
    assert vec.get_attr("split") == sync.get_attr("split") == ("train", "train")
    assert vec.call("pose_to_action", np.zeros(25))[0].shape == (25,)
    vec.set_attr("lost_patience", [4, 4])
    assert vec.get_attr("lost_patience") == (4, 4)
    with pytest.raises(ValueError, match="3 values for 2 episodes"):
        vec.set_attr("lost_patience", [1, 2, 3])
    # the batch applies the first episode's: values that differ would be dropped silently
    with pytest.raises(ValueError, match="one 'terminate_on_lost' to all its episodes"):
        vec.set_attr("terminate_on_lost", [True, False])
    with pytest.raises(ValueError, match="'episode_frames' is set when the vector environment"):
        vec.set_attr("episode_frames", 40)
    vec.set_attr("episode_frames", vec.envs[0].episode_frames)  # unchanged: nothing to refuse
    plain = gym.make_vec("humotion_gym/BodyTrack-v2", 2, vectorization_mode="vector_entry_point",
                         width=64, height=64)  # fmt: skip
    plain.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert plain.render() == (None, None)  # no render_mode: an entry per episode, as sync's


@pytest.mark.parametrize("mode", ["vector_entry_point", "sync"])
def test_a_reward_scale_set_on_the_episodes_is_the_reward_made_with_it(mode):
    # the scale was baked into the scoring when the env was made: set_attr was
    # stored, get_attr echoed it, and the reward stayed at the old scale
    kwargs = {"width": 64, "height": 64}
    action = np.full(4, 0.3, np.float32)
    made = gym.make("humotion_gym/ArmTrack-v2", reward_scale_mm=1000.0, **kwargs)
    made.reset(seed=0)
    want = made.step(action)[1]
    venv = gym.make_vec("humotion_gym/ArmTrack-v2", 2, vectorization_mode=mode, **kwargs)
    venv.set_attr("reward_scale_mm", 1000.0)
    venv.reset(seed=0)
    reward = venv.step(np.stack([action, action]))[1]
    assert reward[0] == pytest.approx(want, rel=1e-12) and want > 0.5
    with pytest.raises(ValueError, match="reward_scale_mm: expected a positive"):
        made.unwrapped.reward_scale_mm = 0.0


def test_an_episode_is_not_reset_or_stepped_behind_the_batch():
    vec = PoseTrackingVectorEnv(2, "ArmTrack-v2", width=64, height=64)
    vec.reset(seed=0)
    for name in ("reset", "step"):
        with pytest.raises(ValueError, match=rf"call\('{name}'\): .* use its own {name}\(\)"):
            vec.call(name)
    pytest.importorskip("stable_baselines3")
    from humotion_gym.sb3 import learner_vec_env

    learner = learner_vec_env("ArmTrack-v2", 2, "train", 32)
    with pytest.raises(ValueError, match=r"env_method\('reset'\)"):
        learner.env_method("reset", indices=[1])
    # SB3's set_attr goes through the batch's checks, per episode too
    with pytest.raises(ValueError, match="'episode_frames' is set when the vector environment"):
        learner.set_attr("episode_frames", 40)
    with pytest.raises(ValueError, match="one 'lost_patience' to all its episodes"):
        learner.set_attr("lost_patience", 2, indices=[0])
    learner.set_attr("lost_patience", 2)
    learner.set_attr("note", "mine", indices=[1])  # not a setting: as SB3's other envs
    assert learner.get_attr("lost_patience") == [2, 2] and learner.get_attr("note", [1]) == ["mine"]


@pytest.mark.parametrize("name", ["split", "library"])
def test_the_persons_episodes_show_are_fixed_when_the_batch_is_made(name):
    """set_attr("split", "test") was taken, and get_attr said test; the episodes stayed train's.

    Each episode's clips are chosen from its split and library when it is made.
    """
    pytest.importorskip("stable_baselines3")
    from humotion_gym.sb3 import learner_vec_env

    learner = learner_vec_env("ArmTrack-v2", 2, "train", 32)
    other = {"split": "test", "library": synthetic_library(seed=1)}[name]
    for setter in (learner.set_attr, learner.venv.set_attr):
        with pytest.raises(
            ValueError, match=f"'{name}' is set when the vector environment is made"
        ):
            setter(name, other)
    assert learner.get_attr("split") == ["train", "train"]
    learner.set_attr(name, learner.get_attr(name)[0])  # the same: nothing to refuse
    learner.close()


def test_render_without_a_render_mode_says_so():
    env = gym.make("humotion_gym/ArmTrack-v2", width=64, height=64)
    env.reset(seed=0)
    with pytest.warns(
        UserWarning,
        match='without a render_mode returns None: make it with render_mode="rgb_array"',
    ):
        assert env.render() is None


@pytest.mark.parametrize("mode", ["vector_entry_point", "sync"])
def test_a_longer_episode_needs_max_episode_steps_on_every_path(mode):
    """episode_frames=N alone is cut at the task's length by every path; -1 lifts the limit."""
    kwargs = {"width": 64, "height": 64, "episode_frames": 40, "terminate_on_lost": False}
    for limit, steps in ((None, 30), (40, 40), (-1, 40)):
        extra = {} if limit is None else {"max_episode_steps": limit}
        venv = gym.make_vec("humotion_gym/ArmTrack-v2", 1, vectorization_mode=mode,
                            **kwargs, **extra)  # fmt: skip
        venv.reset(seed=0)
        action = np.zeros(venv.action_space.shape, np.float32)
        ends = [any(venv.step(action)[2:4]) for _ in range(steps)]
        assert ends == [False] * (steps - 1) + [True], (limit, ends.index(True) + 1)
    assert PoseTrackingVectorEnv(1, "ArmTrack-v2", **kwargs)._max_steps == 30  # the spec's


def test_learner_vec_env_equals_dummy_vec_env_of_learner_envs():
    """The SB3 adapter gives what PPO gets today from DummyVecEnv(LearnerObservation envs)."""
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from baselines.rl import make_learner_env
    from humotion_gym.sb3 import learner_vec_env

    n, task = 3, "ArmTrack-v2"
    dummy = DummyVecEnv([lambda: make_learner_env(task, "train", 32)] * n)
    ours = learner_vec_env(task, n, "train", 32)
    dummy.seed(5)
    ours.seed(5)
    _assert_same(dict(dummy.reset()), ours.reset(), "reset")
    rng = np.random.default_rng(0)
    ends = 0
    for t in range(70):
        actions = rng.uniform(-1, 1, (n, *ours.action_space.shape)).astype(np.float32)
        (obs, rewards, dones, infos), want = ours.step(actions), dummy.step(actions)
        _assert_same(obs, dict(want[0]), f"step {t}")
        _assert_same(rewards, want[1], f"step {t}")
        _assert_same(dones, want[2], f"step {t}")
        for got_info, want_info in zip(infos, want[3], strict=True):
            terms = [key for key in got_info if key.startswith("reward_")]
            assert terms
            for key in (
                "TimeLimit.truncated", "error_mm", "error_all_mm", "error_aligned_mm", "lost",
                *terms,
            ):  # fmt: skip
                assert got_info[key] == want_info[key], (t, key)
                assert type(got_info[key]) is type(want_info[key]), (t, key)
            assert ("terminal_observation" in got_info) == ("terminal_observation" in want_info)
            if "terminal_observation" in want_info:
                ends += 1
                _assert_same(got_info["terminal_observation"], want_info["terminal_observation"])
        for got_start, want_start in zip(ours.reset_infos, dummy.reset_infos, strict=True):
            assert got_start == want_start, t  # every key, refreshed at autoreset
            assert [type(v) for v in got_start.values()] == [type(v) for v in want_start.values()]
    assert ends > 0


@pytest.mark.parametrize(
    "items",
    [
        [{"a": 1, "b": np.ones(2), "c": "x"}, {"a": 2, "b": np.zeros(2), "c": None}],
        [{"a": 1.5, "b": True}, {"b": False, "a": 2.5}],  # other key orders
        [{"a": 1}, {"a": 2, "d": {"e": 3}}],  # a nested info
        [{"final_obs": np.zeros(2)}, {"final_obs": np.ones(2)}],
    ],
)
def test_infos_batched_key_by_key_are_infos_added_one_by_one(items):
    from humotion_gym.envs._batch_info import _add_info, _add_infos

    for before in ({}, {"a": np.zeros(4, np.int64), "_a": np.zeros(4, np.bool_)}):
        got = {key: value.copy() for key, value in before.items()}
        want = {key: value.copy() for key, value in before.items()}
        _add_infos(got, [3, 1], items, 4)
        for i, item in zip([3, 1], items, strict=True):
            _add_info(want, item, i, 4)
        _assert_same(got, want)


@pytest.mark.parametrize(
    ("seed", "options"),
    [
        ([3, -1], None),  # the second episode's seed is refused (before any starts)
        (None, {"start": 10_000}),  # every episode refuses its start
    ],
)
def test_a_refused_reset_leaves_every_episode_as_it_was(seed, options):
    def make():
        return gym.make_vec(
            "humotion_gym/BodyTrack-v2", num_envs=2, vectorization_mode="vector_entry_point",
            terminate_on_lost=False, render_mode="rgb_array",
        )  # fmt: skip

    vec, twin = make(), make()
    action = np.zeros(vec.action_space.shape, np.float32)
    for env in (vec, twin):
        env.reset(seed=5)
        env.step(action)
    with pytest.raises((ValueError, gym.error.Error)):  # Gymnasium's error for a seed
        vec.reset(seed=seed, options=options)
    for a, b in zip(vec.unwrapped.envs, twin.unwrapped.envs, strict=True):
        assert a._motion is b._motion and a._t0 == b._t0 and a._frame_index() == b._frame_index()
        assert np.array_equal(a.true_pose(), b.true_pose())
    for _ in range(3):  # the batch goes on with the same episodes, in their own generators
        _assert_same(vec.step(action), twin.step(action))
    _assert_same(vec.render(), twin.render())
    # and a later reset draws what it would have drawn without the refused one
    _assert_same(vec.reset(), twin.reset())


def test_learner_vec_env_episodes_ending_apart_with_options_are_dummy_vec_envs():
    """Episodes lost at different steps (one row's info from its final step, the others'
    from this one), actions beyond the bounds (a lost frame before the end, seen clipped
    as the previous estimate) and reset options: as DummyVecEnv's."""
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from baselines.rl import make_learner_env
    from humotion_gym.sb3 import learner_vec_env

    n, task = 3, "BodyTrack-v2"
    kwargs = {"terminate_on_lost": True, "lost_patience": 2, "episode_frames": 5}
    kwargs |= {"width": 64, "height": 64}
    dummy = DummyVecEnv([lambda: make_learner_env(task, "train", 32, **kwargs)] * n)
    ours = learner_vec_env(task, n, "train", 32, **kwargs)
    for venv in (dummy, ours):
        venv.seed(3)
        venv.set_options({"clip_id": "synthetic/walk-01", "start": 5})
    _assert_same(dict(dummy.reset()), ours.reset(), "reset")
    assert [info["start_frame"] for info in ours.reset_infos] == [5] * n
    bad_from = np.array([2, 3, 9])  # each row's estimate is far off from this step on
    ended = []
    for t in range(1, 6):
        truth = np.stack([env.pose_to_action(env.true_pose()) for env in ours.venv.envs])
        actions = np.where((bad_from <= t)[:, None], -3.0, truth).astype(np.float32)
        (obs, rewards, dones, infos), want = ours.step(actions), dummy.step(actions)
        _assert_same(obs, dict(want[0]), f"step {t}")
        assert obs["previous"].min() >= -1.0
        _assert_same(rewards, want[1], f"step {t}")
        _assert_same(dones, want[2], f"step {t}")
        for got_info, want_info in zip(infos, want[3], strict=True):
            for key in ("TimeLimit.truncated", "error_mm", "error_all_mm", "lost"):
                _assert_same(got_info[key], want_info[key], f"step {t} {key}")
            assert ("terminal_observation" in got_info) == ("terminal_observation" in want_info)
            if "terminal_observation" in want_info:  # its previous estimate clipped
                _assert_same(got_info["terminal_observation"], want_info["terminal_observation"])
        ended.append(dones.tolist())
    assert ended[2] == [True, False, False] and ended[3] == [False, True, False]


def test_learner_vec_env_refuses_options_per_episode_in_set_options_and_keeps_its_own():
    """They were kept and refused by every reset() after, until set_options again."""
    pytest.importorskip("stable_baselines3")
    from humotion_gym.sb3 import learner_vec_env

    venv = learner_vec_env("ArmTrack-v2", n_envs=2, frame_size=16)
    venv.set_options({"start": 3})
    for refused, match in (
        ([{"start": 0}, {"start": 5}], r"same reset options .*episode 1's differ"),
        ([{"start": 0}], r"a list of num_envs=2 dicts"),
        ("start=0", r"options must be a dict, a list of dicts or None"),
    ):
        with pytest.raises(ValueError, match=rf"LearnerVecEnv\.set_options: .*{match}"):
            venv.set_options(refused)
    venv.seed(0)
    venv.reset()
    assert [info["start_frame"] for info in venv.reset_infos] == [3, 3]  # the options kept
    # the same options for every episode, as a list, as SB3's set_options takes them
    venv.set_options([{"start": 4}, {"start": 4}])
    venv.reset()
    assert [info["start_frame"] for info in venv.reset_infos] == [4, 4]
    venv.close()


def test_learner_vec_env_names_what_is_wrong_with_its_arguments():
    pytest.importorskip("stable_baselines3")
    from humotion_gym.sb3 import LearnerVecEnv, learner_vec_env

    sync = gym.make_vec(
        "humotion_gym/ArmTrack-v2", num_envs=2, vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP},
    )  # fmt: skip
    with pytest.raises(TypeError, match=r"LearnerVecEnv: venv must be a humotion_gym "
                       r"PoseTrackingVectorEnv.*vector_entry_point.*got SyncVectorEnv"):  # fmt: skip
        LearnerVecEnv(sync)
    ours = PoseTrackingVectorEnv(2, task="ArmTrack-v2", autoreset_mode=AutoresetMode.SAME_STEP)
    with pytest.raises(TypeError, match="got RecordEpisodeStatistics of PoseTrackingVectorEnv$"):
        LearnerVecEnv(gym.wrappers.vector.RecordEpisodeStatistics(ours))
    # the advice can be followed
    made = gym.make_vec(
        "humotion_gym/ArmTrack-v2", num_envs=2, vectorization_mode="vector_entry_point",
        autoreset_mode="SameStep",
    )  # fmt: skip
    assert LearnerVecEnv(made, 16).num_envs == 2
    with pytest.raises(TypeError, match="learner_vec_env: autoreset_mode is not an argument"):
        learner_vec_env("ArmTrack-v2", 2, autoreset_mode="NextStep")
    with pytest.raises(TypeError, match="learner_vec_env: num_envs is not an argument.*n_envs"):
        learner_vec_env("ArmTrack-v2", 2, num_envs=3)
    with pytest.raises(ValueError, match="task: expected a task name or TaskSpec, got 3"):
        learner_vec_env(3, 2)
    assert learner_vec_env("humotion_gym/ArmTrack-v2", 2).venv.task.name == "ArmTrack-v2"
