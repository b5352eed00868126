"""How an episode is chosen, by hand: its clip, its start frame and the held-out persons."""

from __future__ import annotations

import dataclasses
import weakref
from collections import OrderedDict

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from humotion_gym.body import KEYPOINT_INDEX, N_KEYPOINTS
from humotion_gym.kinematics import batch_pose_geometry
from humotion_gym.mocap.library import synthetic_library
from humotion_gym.mocap.motion import Motion


def _user_clip(observed: np.ndarray, clip_id: str) -> Motion:
    """A user's clip of ``observed.size`` frames (a training person's motion, relabelled)."""
    m = synthetic_library()[0].slice(0, observed.size)
    mask = np.repeat(observed[:, None], m.params.shape[1], axis=1)
    return dataclasses.replace(
        m, clip_id=clip_id, observed=mask, dataset="user", synthetic=False, subject="user-x"
    )


def _starts(env: gym.Env, motion: Motion, seeds: int = 100) -> set[int]:
    """The start frames resets with ``seeds`` seeds draw for ``motion``."""
    return {env.reset(seed=s, options={"motion": motion})[1]["start_frame"] for s in range(seeds)}


@pytest.fixture(scope="module")
def body() -> gym.Env:
    """BodyTrack: episodes of 30 steps of one frame, so an episode shows 31 frames."""
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False).unwrapped
    assert (env.episode_frames, env.frame_skip) == (30, 1)
    return env


def test_every_clip_of_the_split_is_drawn(body) -> None:
    """Random episodes draw every one of the 12 clips (each misses 200 draws with p < 3e-8)."""
    drawn = {body.reset(seed=s)[1]["clip_id"] for s in range(200)}
    assert drawn == {m.clip_id for m in body.clips} and len(drawn) == 12


def test_a_start_is_refused_only_where_the_episode_would_leave_the_clip(body) -> None:
    """240 frames, episodes of 31: starts 0 to 209 fit (209 ends on frame 239), 210 not."""
    clip = body.clips[0]
    assert clip.n_frames == 240
    _, info = body.reset(seed=0, options={"clip_id": clip.clip_id, "start": 209})
    assert info["start_frame"] == 209
    for bad in (210, 211, -1):
        with pytest.raises(ValueError, match=r"must be in \[0, 210\)"):
            body.reset(seed=0, options={"clip_id": clip.clip_id, "start": bad})


def test_drawn_starts_are_those_whose_every_frame_was_observed(body) -> None:
    """40 frames, the last unobserved: starts 0 to 8 show frames 0 to 38 only."""
    observed = np.ones(40, bool)
    observed[39] = False
    assert _starts(body, _user_clip(observed, "user/last-unobserved")) == set(range(9))


def test_a_clip_never_observed_throughout_draws_any_start_that_fits(body) -> None:
    """No window observed throughout: every start whose episode fits, 0 to 9 of 40 frames."""
    observed = np.ones(40, bool)
    observed[::5] = False  # every window of 31 frames misses some
    assert _starts(body, _user_clip(observed, "user/never-whole")) == set(range(10))


def test_a_new_clip_under_a_known_id_gets_its_own_starts(body) -> None:
    """The starts remembered for a clip id are not another clip's of the same id."""
    assert _starts(body, _user_clip(np.ones(40, bool), "user/again")) == set(range(10))
    observed = np.ones(40, bool)
    observed[35:] = False  # frames 35 to 39 unobserved: starts 0 to 4
    assert _starts(body, _user_clip(observed, "user/again")) == set(range(5))


def _slow_episode_motion(motion: Motion, span: int, skip: int, scored, anchor: int) -> np.ndarray:
    """The docstring's measure, start by start and keypoint by keypoint."""
    kp = batch_pose_geometry(motion.params, motion.shape)[:, :N_KEYPOINTS]
    out = []
    for s in range(motion.n_frames - span):
        per_keypoint = []
        for k in scored:
            at_start = kp[s, k] - kp[s, anchor]
            per_keypoint.append(
                max(
                    float(np.linalg.norm(kp[s + f, k] - kp[s + f, anchor] - at_start))
                    for f in range(0, span + 1, skip)
                )
            )
        out.append(np.mean(per_keypoint))
    return np.array(out)


@pytest.mark.filterwarnings("ignore::FutureWarning")  # v1: the task with min_motion_mm
def test_episode_motion_and_good_starts_match_a_slow_reference() -> None:
    """ArmTrack-v1 with frame_skip 2: moves measured from the anchor, to the episode's last frame."""
    env = gym.make("humotion_gym/ArmTrack-v1", frame_skip=2, episode_frames=10).unwrapped
    task = env.task
    assert task.min_motion_mm > 0 and task.motion_anchor != "pelvis"
    anchor = KEYPOINT_INDEX[task.motion_anchor]
    motion = synthetic_library()["synthetic/reach-01"].slice(0, 60)
    want = _slow_episode_motion(motion, 20, 2, env._err_kp, anchor)
    np.testing.assert_allclose(env._episode_motion(motion), want, rtol=1e-9, atol=1e-9)
    good = [s for s in range(40) if want[s] >= task.min_motion_mm]
    assert 0 < len(good) < 40  # the threshold decides here
    assert env._good_starts(motion).tolist() == good


def test_a_validation_env_refuses_a_clip_its_data_set_holds_out() -> None:
    """A clip from outside the library marked split=test by its data set's rule."""
    outside = dataclasses.replace(
        _user_clip(np.ones(40, bool), "elsewhere/bob"),
        subject="bob",
        meta={"split": "test", "person": "bob", "split_rule": "by hash"},
    )
    for split in ("train", "validation"):
        env = gym.make("humotion_gym/BodyTrack-v2", split=split)
        with pytest.raises(ValueError, match=r"'bob', a held-out person by its data set's rule"):
            env.reset(seed=0, options={"motion": outside})
    test_env = gym.make("humotion_gym/BodyTrack-v2", split="test")
    assert test_env.reset(seed=0, options={"motion": outside})[1]["clip_id"] == "elsewhere/bob"


def test_clip_geometry_is_each_clips_own_and_keeps_the_recently_used(monkeypatch) -> None:
    """The cache gives a clip its own table, and drops the least recently used beyond its size."""
    from humotion_gym.envs import _episode_choice as choice

    monkeypatch.setattr(choice, "_CLIP_GEOMETRY", OrderedDict())
    monkeypatch.setattr(choice, "_CLIP_GEOMETRY_FRAMES", 100)  # two clips of 40 frames fit
    a, b, c, d = (m.slice(0, 40) for m in list(synthetic_library())[:4])
    ga = choice.clip_geometry(a)
    np.testing.assert_array_equal(ga, batch_pose_geometry(a.params, a.shape))
    assert choice.clip_geometry(a) is ga  # read again, not computed again
    gb = choice.clip_geometry(b)
    assert choice.clip_geometry(a) is ga  # a used last: b is the least recently used
    gc = choice.clip_geometry(c)  # 120 frames: b goes
    assert list(choice._CLIP_GEOMETRY) == [id(a), id(c)]
    assert choice.clip_geometry(a) is ga and choice.clip_geometry(c) is gc
    assert choice.clip_geometry(b) is not gb
    # an entry left under a new clip's id by a clip that is gone: d's own table
    choice._CLIP_GEOMETRY[id(d)] = (weakref.ref(a), ga)
    np.testing.assert_array_equal(choice.clip_geometry(d), batch_pose_geometry(d.params, d.shape))
