"""Suite-wide checks over every registered environment."""

import dataclasses
import pickle
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import humotion_gym
from humotion_gym.body import PARAM_LOWER, PARAM_UPPER
from humotion_gym.envs import ENV_IDS, get_task
from humotion_gym.envs.description import (
    OBSERVATION_KEYS,
    action_bounds,
    action_to_pose,
    pose_to_action,
    read_observation,
)
from humotion_gym.envs.vector import PoseTrackingVectorEnv
from humotion_gym.render_scene import SCENE_MAXIMA, SceneOptions
from humotion_gym.wrappers import FrameObservation

IDS = list(ENV_IDS)


def assert_obs_equal(a, b):
    """Two observations (v2: Dict) are equal, key by key."""
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            assert np.array_equal(a[k], b[k]), k
    else:
        assert np.array_equal(a, b)


def obs_equal(a, b):
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    return np.array_equal(a, b)


def rollout(env_id, seed, steps=8, actions_seed=0, **kwargs):
    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(actions_seed)
    frames, rewards, infos = [obs], [], [info]
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(
            rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        )
        frames.append(obs)
        rewards.append(r)
        infos.append(info)
        if term or trunc:
            break
    env.close()
    return frames, rewards, infos


def test_all_four_tasks_and_their_view_variants_are_registered():
    tasks = ("ArmTrack-v2", "BodyTrack-v2", "WalkTrack-v2", "SideWalk-v2")
    views = ("BodyTrack2Views-v2", "BodyTrack4Views-v2", "WalkTrack2Views-v2", "WalkTrack4Views-v2")
    assert IDS == [f"humotion_gym/{n}" for n in tasks + views]
    for env_id in IDS:
        assert gym.spec(env_id).entry_point == gym.spec(env_id.split("/")[1]).entry_point


def test_module_colon_id_works_from_a_fresh_interpreter():
    code = "import gymnasium as gym; e = gym.make('humotion_gym:ArmTrack-v2'); print(e.reset(seed=0)[0]['frame'].shape)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "(128, 128, 3)"


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_env_checker_passes_without_warnings(env_id):
    env = gym.make(env_id).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=False)


@pytest.mark.parametrize("env_id", IDS)
def test_stable_baselines3_checker_passes_without_warnings(env_id):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id)
    if get_task(env_id).views == 1:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            sb3_checker.check_env(env, warn=True)
        return
    # Several views: the checker passes; it only remarks that the stacked
    # frames (views, H, W, 3) and cameras (views, 13) are neither an image
    # nor a flat vector (SB3's MultiInputPolicy would need a custom
    # extractor). A pixel-only learner takes the views side by side, a
    # conventional image, without a remark.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env, warn=True)
    remarks = {str(w.message).split(" has an unconventional shape")[0] for w in caught}
    assert remarks == {"Your observation frame", "Your observation camera"}, remarks
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(FrameObservation(gym.make(env_id)), warn=True)


@pytest.mark.parametrize("env_id", IDS)
def test_determinism(env_id):
    a = rollout(env_id, seed=3)
    b = rollout(env_id, seed=3)
    for fa, fb in zip(a[0], b[0], strict=True):
        assert_obs_equal(fa, fb)
    assert a[1] == b[1]
    for ia, ib in zip(a[2], b[2], strict=True):
        assert ia.keys() == ib.keys()
        for k in ia:
            va, vb = ia[k], ib[k]
            if isinstance(va, np.ndarray):
                assert np.array_equal(va, vb), k
            elif isinstance(va, float | int | str | bool):
                assert va == vb, k


def test_seeded_reset_after_other_episodes_repeats_a_fresh_env():
    # The noise bank (and everything else) is redrawn at a seeded reset: an env
    # that has run other episodes replays a fresh env's episode exactly.
    used = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    used.reset(seed=11)
    for _ in range(3):
        used.reset()
    fresh = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    action = np.zeros(used.action_space.shape, np.float32)
    for env in (used, fresh):
        env.reset(seed=5)
    for _ in range(4):
        assert_obs_equal(used.step(action)[0], fresh.step(action)[0])
    # Episodes after a seeded one differ from each other (their rooms and noise windows).
    first = fresh.reset()[0]
    assert not np.array_equal(first["frame"], fresh.reset()[0]["frame"])


@pytest.mark.parametrize("env_id", IDS)
def test_different_seeds_give_different_episodes(env_id):
    a = rollout(env_id, seed=1, steps=2)
    b = rollout(env_id, seed=2, steps=2)
    assert not np.array_equal(a[0][0]["frame"], b[0][0]["frame"])


@pytest.mark.parametrize("env_id", IDS)
def test_reward_range_terms_and_no_shared_memory(env_id):
    env = gym.make(env_id)
    obs, info = env.reset(seed=5)
    previous = obs
    rng = np.random.default_rng(0)
    for _ in range(6):
        obs, reward, term, trunc, info = env.step(
            rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        )
        assert 0.0 <= reward <= 1.0
        terms = sum(v for k, v in info.items() if k.startswith("reward_"))
        assert terms == pytest.approx(reward, abs=1e-12)
        for k in obs:  # no key of an observation shares memory with the last one's
            assert not np.shares_memory(obs[k], previous[k]), k
        previous = obs
        if term or trunc:
            break


@pytest.mark.parametrize("env_id", IDS)
def test_true_pose_gives_full_reward_and_episode_length(env_id):
    env = gym.make(env_id).unwrapped
    obs, info = env.reset(seed=0)
    task = get_task(env_id)
    steps, rewards = 0, []
    while True:
        action = env.pose_to_action(env.true_pose())
        obs, r, term, trunc, info = env.step(action)
        rewards.append(r)
        steps += 1
        if term or trunc:
            break
    assert trunc and not term and steps == task.episode_frames
    assert min(rewards) > 0.999 and info["error_mm"] < 0.5


@pytest.mark.parametrize("env_id", IDS)
def test_aligned_error_is_the_pose_wherever_the_body_is(env_id):
    """The truth moved as a whole: error_mm is the shift, error_aligned_mm none of it."""
    env = gym.make(env_id).unwrapped
    env.reset(seed=1)
    free = get_task(env_id).free_indices
    truth = env.true_pose()
    if {0, 1, 2} <= set(free.tolist()):
        shifted = truth.copy()
        shifted[:3] += [30.0, -40.0, 0.0]  # 50 mm across the floor
        _, _, _, _, info = env.step(env.pose_to_action(shifted))
        assert info["error_mm"] == pytest.approx(50.0, abs=0.5)
        assert info["error_aligned_mm"] < 0.5
        truth = env.true_pose()
    # A limb off: both see it; where the root is given they are the same number.
    bent = truth.copy()
    bent[free[-1]] += 0.4
    _, _, _, _, info = env.step(env.pose_to_action(bent))
    assert info["error_mm"] > 5.0 and info["error_aligned_mm"] > 5.0
    if 0 not in free:
        assert info["error_aligned_mm"] == pytest.approx(info["error_mm"], rel=1e-12)


def test_track_lost_terminates_and_can_be_switched_off():
    env = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    env.reset(seed=0)
    bad = np.ones(env.action_space.shape, dtype=np.float32)
    for k in range(1, 10):  # noqa: B007  (k is read after the loop)
        _, _, term, _, info = env.step(bad)
        if term:
            break
    assert term and info["lost"] and k == env.lost_patience
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False).unwrapped
    env.reset(seed=0)
    for _ in range(10):
        _, _, term, _, info = env.step(bad)
    assert not term and info["lost"]


def _shifted_step(env, shift_mm):
    """A step with the truth moved ``shift_mm`` along x: every keypoint is off by it."""
    pose = env.true_pose()
    pose[0] += shift_mm
    return env.step(env.pose_to_action(pose))


@pytest.mark.parametrize(("shift", "lost_at"), [(140.0, None), (160.0, 5)])
def test_reward_and_lost_track_at_known_errors(shift, lost_at):
    """The documented defaults: reward exp(-e / 100 mm); lost once 5 frames are above 150 mm."""
    env = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    env.reset(seed=0)
    for k in range(1, 8):
        _, reward, term, trunc, info = _shifted_step(env, shift)
        assert info["error_mm"] == pytest.approx(shift, abs=0.5)
        assert reward == pytest.approx(np.exp(-info["error_mm"] / 100.0), rel=1e-6)
        assert info["lost"] == (lost_at is not None and k >= lost_at)
        assert (term, trunc) == (info["lost"], False)
        if term:
            break
    assert k == (lost_at or 7)


def test_a_loss_on_the_last_frame_terminates_and_does_not_truncate():
    """The last frame lost: terminated alone (truncated only where tracking went on)."""
    for terminate in (True, False):
        env = gym.make(
            "humotion_gym/BodyTrack-v2", episode_frames=3, lost_patience=1,
            terminate_on_lost=terminate,
        ).unwrapped  # fmt: skip
        env.reset(seed=0)
        for _ in range(2):
            assert _shifted_step(env, 0.0)[2:4] == (False, False)
        _, _, term, trunc, info = _shifted_step(env, 200.0)
        assert info["lost"] and (term, trunc) == (terminate, not terminate)


def test_a_new_episode_counts_its_lost_frames_afresh():
    """Frames above the threshold at one episode's end do not count toward the next's loss."""
    env = gym.make("humotion_gym/BodyTrack-v2", episode_frames=6, terminate_on_lost=False)
    env = env.unwrapped
    env.reset(seed=0)
    lost = [_shifted_step(env, shift)[4]["lost"] for shift in (0, 0, 0, 160, 160, 160)]
    assert lost == [False] * 6  # three frames above 150 mm: not yet lost
    env.reset(seed=1)
    lost = [_shifted_step(env, 160.0)[4]["lost"] for _ in range(6)]
    assert lost == [False] * 4 + [True] * 2  # lost at the fifth frame of this episode


def test_lost_and_reward_follow_the_scored_keypoints_step_by_step():
    """ArmTrack scores the right elbow and wrist: the rules read over its info, step by step."""
    from humotion_gym.body import KEYPOINT_INDEX

    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False).unwrapped
    env.reset(seed=0)
    scored = [KEYPOINT_INDEX["r_elbow"], KEYPOINT_INDEX["r_wrist"]]
    rng = np.random.default_rng(7)
    errors, lost = [], []
    for t in range(30):
        sigma = 0.5 if (t // 6) % 2 else 0.02  # runs of bad and good estimates
        a = env.pose_to_action(env.true_pose()) + rng.normal(0.0, sigma, env.action_space.shape)
        _, reward, _, _, info = env.step(np.clip(a, -1, 1).astype(np.float32))
        e = info["keypoint_errors_mm"][scored]
        assert info["error_mm"] == pytest.approx(e.mean(), rel=1e-12)
        assert reward == pytest.approx(np.exp(-e / 100.0).mean(), rel=1e-12)
        errors.append(info["error_mm"])
        lost.append(info["lost"])
    # the oracle: lost where this and the 4 frames before were all above 150 mm
    want = [t >= 4 and all(e > 150.0 for e in errors[t - 4 : t + 1]) for t in range(30)]
    assert lost == want and any(want) and not all(want)


@pytest.mark.parametrize(
    "bad, match",
    [(np.full(4, np.nan), "finite"), (np.full(4, np.inf), "finite"), (np.zeros(5), "shape")],
)
def test_bad_actions_raise_value_errors(bad, match):
    env = gym.make("humotion_gym/ArmTrack-v2").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(bad)


def test_observation_gives_what_the_agent_needs_and_never_the_truth():
    env = gym.make("humotion_gym/ArmTrack-v2").unwrapped
    obs, info = env.reset(seed=0)
    given = read_observation(obs)
    assert given.initial_pose.shape == (25,) and env.describe().fps == 30.0
    assert given.fixed_params.shape == (21,)
    truth = env.true_pose()
    # the fixed parameters are the truth of the frame on show; the free ones are absent
    assert np.array_equal(obs["fixed_params"], truth[env.task.fixed_indices])
    # the initial pose is the truth of the frame before the first one shown
    assert np.array_equal(obs["initial_pose"], env._motion.params[info["start_frame"]])
    assert np.array_equal(obs["camera"], env.camera.to_vector())
    assert np.array_equal(obs["shape"], env.shape.to_vector())
    for part in (obs, info):
        for key, value in part.items():
            if isinstance(value, np.ndarray) and value.shape == (25,) and key != "initial_pose":
                assert not np.array_equal(value, truth), key


def test_observation_follows_the_frame_on_show_step_by_step():
    """SideWalk's camera moves and it fixes parameters: both are the frame on show's."""
    env = gym.make("humotion_gym/SideWalk-v2").unwrapped
    obs, _ = env.reset(seed=0)
    initial, cameras = obs["initial_pose"].copy(), [obs["camera"]]
    for _ in range(3):
        obs, *_ = env.step(env.pose_to_action(env.true_pose()))
        assert np.array_equal(obs["fixed_params"], env.true_pose()[env.task.fixed_indices])
        assert np.array_equal(obs["camera"], env.camera.to_vector())
        assert np.array_equal(obs["initial_pose"], initial)  # the first frame's, kept
        cameras.append(obs["camera"])
    assert not np.array_equal(cameras[0], cameras[-1])  # a camera that moved


_GIVENS = ("initial_pose", "shape", "camera", "fixed_params", "fps")


@pytest.mark.parametrize("env_id", IDS)
def test_info_holds_no_given_and_the_space_contains_every_observation(env_id):
    env = gym.make(env_id, terminate_on_lost=False).unwrapped
    space = env.observation_space
    assert isinstance(space, gym.spaces.Dict)
    assert set(space.spaces) == set(OBSERVATION_KEYS)
    obs, info = env.reset(seed=2)
    seen = [(obs, info)]
    rng = np.random.default_rng(0)

    def step():
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, _, _, _, info = env.step(action)
        seen.append((obs, info))

    for _ in range(env.episode_frames):
        step()
    with pytest.warns(UserWarning, match="after the episode ended"):
        step()  # one step past the end: the terminal transition again
    assert seen[-1][1]["after_end"]
    for obs, info in seen:
        assert not set(_GIVENS) & set(info), sorted(set(_GIVENS) & set(info))
        assert obs.keys() == space.spaces.keys()
        assert space.contains(obs), {k: space[k].contains(v) for k, v in obs.items()}


def test_the_space_check_catches_a_wrong_observation():
    # mutation: a frame of the wrong dtype, or a missing key, is not in the space
    env = gym.make("humotion_gym/ArmTrack-v2").unwrapped
    obs, _ = env.reset(seed=0)
    assert not env.observation_space.contains({**obs, "frame": obs["frame"].astype(np.float32)})
    assert not env.observation_space.contains({k: v for k, v in obs.items() if k != "camera"})


def test_a_v1_id_still_works_and_warns_that_it_is_deprecated():
    with pytest.warns(FutureWarning, match="ArmTrack-v2"):
        env = gym.make("humotion_gym/ArmTrack-v1").unwrapped
    obs, info = env.reset(seed=0)
    assert isinstance(obs, np.ndarray) and obs.shape == (128, 128, 3) and obs.dtype == np.uint8
    assert env.observation_space.contains(obs)
    assert info["initial_pose"].shape == (25,) and info["fps"] == 30.0
    assert info["fixed_params"].shape == (21,)
    obs, reward, *_ = env.step(env.pose_to_action(env.true_pose()))
    assert obs.shape == (128, 128, 3) and reward > 0.999


@pytest.mark.parametrize("env_id", IDS)
def test_frame_observation_gives_the_frame_and_passes_the_env_checker(env_id):
    env = FrameObservation(gym.make(env_id))
    frame_space = env.unwrapped.observation_space["frame"]
    views = get_task(env_id).views

    def seen(frame):  # several views side by side (an oracle: one view after another)
        return frame if views == 1 else np.hstack([frame[v] for v in range(views)])

    h, w, c = frame_space.shape[-3:]
    assert env.observation_space.shape == (h, views * w, c)
    if views == 1:
        assert env.observation_space == frame_space
    twin = gym.make(env_id)
    obs, _ = env.reset(seed=4)
    full, _ = twin.reset(seed=4)
    assert isinstance(obs, np.ndarray) and np.array_equal(obs, seen(full["frame"]))
    action = np.zeros(env.action_space.shape, np.float32)
    obs, reward, *_ = env.step(action)
    full, twin_reward, *_ = twin.step(action)
    assert np.array_equal(obs, seen(full["frame"])) and reward == twin_reward
    with pytest.raises(ValueError, match="Dict"):
        FrameObservation(env)  # a frame alone is no Dict to take the frame from
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # check_env warns of any wrapper as such; every other warning still fails
        warnings.filterwarnings("ignore", message=".*different from the unwrapped version")
        check_env(FrameObservation(gym.make(env_id).unwrapped), skip_render_check=True)


def _clip_of(library, person):
    return next(m for m in library if m.subject == person)


@pytest.mark.parametrize("person", ["synthetic-05", "synthetic-06", "synthetic-03", "synthetic-04"])
def test_a_train_env_refuses_a_held_out_persons_clip_and_stays_as_it_was(person):
    env = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    twin = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    assert env.split == "train" and env.describe().split == "train"
    assert all(m.subject not in (person,) for m in env.clips)
    action = np.zeros(env.action_space.shape, np.float32)
    for e in (env, twin):
        e.reset(seed=3)
        e.step(action)
    clip = _clip_of(env.library, person)
    shown_by = "test" if person in ("synthetic-05", "synthetic-06") else "validation"
    with pytest.raises(ValueError, match=rf"{person}.*make it with split='{shown_by}'"):
        env.reset(seed=9, options={"clip_id": clip.clip_id})
    # by skeleton: the same person's clip under another name, shown by the matched
    # person's split (not by the name's: someone-else's would be validation)
    renamed = dataclasses.replace(clip, subject="someone-else", clip_id="elsewhere/x")
    same = rf"{person} \(same skeleton as 'someone-else'\).*make it with split='{shown_by}'\)$"
    with pytest.raises(ValueError, match=same):
        env.reset(seed=9, options={"motion": renamed})
    if shown_by == "test":  # a validation env refuses it too, and names the test split
        validation = gym.make("humotion_gym/BodyTrack-v2", split="validation").unwrapped
        with pytest.raises(ValueError, match=same):
            validation.reset(seed=9, options={"motion": renamed})
    # the refused resets changed nothing: the episode goes on as its twin's
    for _ in range(3):
        a, b = env.step(action), twin.step(action)
        assert_obs_equal(a[0], b[0])
        assert a[1:4] == b[1:4] and a[4]["error_mm"] == b[4]["error_mm"]
    assert_obs_equal(env.reset()[0], twin.reset()[0])
    # a test env shows the test persons' clips
    if person in ("synthetic-05", "synthetic-06"):
        test_env = gym.make("humotion_gym/BodyTrack-v2", split="test").unwrapped
        _, info = test_env.reset(seed=0, options={"clip_id": clip.clip_id})
        assert info["person"] == person


def test_pose_action_round_trip():
    env = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    env.reset(seed=4)
    truth = env.true_pose()
    pose = env.action_to_pose(env.pose_to_action(truth))
    kp_err = np.abs(
        humotion_gym.body.forward_kinematics(pose, env.shape)
        - humotion_gym.body.forward_kinematics(truth, env.shape)
    )
    assert kp_err.max() < 0.5  # float32 actions


def test_an_action_is_its_free_parameters_place_in_their_range():
    """Hand-computed actions: a free root is the initial root +- root_range_mm, angles their
    joint limits (wrapped first: a turn more is the same action), in free_indices order."""
    task = get_task("SideWalk-v2")  # free [17, 20, 21, 24, 9, 12, 13, 16]: not sorted
    initial = np.zeros(25)
    pose = np.zeros(25)
    pose[17] = 2.8 * 0.75  # range [-1.5, 2.8] -> (2.1 + 1.5) / 4.3 * 2 - 1
    pose[20] = 1.45  # [0, 2.9]: the middle
    pose[21] = -1.5  # [-1.5, 2.8]: the lower end
    pose[9] = -np.pi / 2 + 2 * np.pi  # [-pi, pi]: wrapped to -pi/2
    pose[12] = 2.9  # [0, 2.9]: the upper end
    want = np.array([3.6 / 4.3 * 2 - 1, 0.0, -1.0, -1.0, -0.5, 1.0, 0.0, -1.0])
    np.testing.assert_allclose(pose_to_action(task, pose, initial), want, atol=1e-6)
    # the root of a whole-body task: the initial root +- root_range_mm (2500 mm)
    body = get_task("BodyTrack-v2")
    initial = np.zeros(25)
    initial[:3] = (100.0, -200.0, 900.0)
    lo, hi = action_bounds(body, initial)
    np.testing.assert_array_equal(lo[:3], initial[:3] - 2500.0)
    np.testing.assert_array_equal(hi[:3], initial[:3] + 2500.0)
    np.testing.assert_array_equal(lo[3:], PARAM_LOWER[3:])
    np.testing.assert_array_equal(hi[3:], PARAM_UPPER[3:])
    pose = initial.copy()
    pose[:3] += (1250.0, -2500.0, 0.0)
    np.testing.assert_allclose(pose_to_action(body, pose, initial)[:3], [0.5, -1.0, 0.0])
    np.testing.assert_allclose(pose_to_action(body, initial, initial)[:3], 0.0, atol=1e-7)
    # and back: the free parameters placed in the base pose, the others the base's
    action = np.array([0.5, 0.0, -1.0, 1.0, 0.0, 0.5, -0.5, 0.0], np.float32)
    base = np.arange(25.0)
    back = action_to_pose(task, action, base, initial)
    lo, hi = PARAM_LOWER[task.free_indices], PARAM_UPPER[task.free_indices]
    np.testing.assert_allclose(back[task.free_indices], lo + (action + 1) / 2 * (hi - lo))
    assert np.array_equal(back[task.fixed_indices], base[task.fixed_indices])


@pytest.mark.parametrize(
    ("call", "match"),
    [
        # a short base gave a (24,) pose silently
        (lambda t, b: action_to_pose(t, np.zeros(4), np.zeros(24)), r"base: .*\(25,\)"),
        (lambda t, b: action_to_pose(t, np.zeros(4), np.zeros(())), r"base: "),
        (lambda t, b: action_to_pose(t, np.zeros((3, 4)), np.zeros((2, 25))), r"base: "),
        # a wrong width failed in numpy's words
        (lambda t, b: action_to_pose(t, np.zeros(5), np.zeros(25)), r"action: .*\(\.\.\., 4\)"),
        (lambda t, b: action_to_pose(t, np.float32(0), np.zeros(25)), r"action: "),
        (lambda t, b: pose_to_action(b, np.zeros(25), np.zeros(2)), r"initial_pose: .*\(25,\)"),
        (lambda t, b: action_to_pose(b, np.zeros(25), np.zeros(25), np.zeros(3)), r"initial_pose"),
    ],
)
def test_the_action_map_refuses_wrong_shapes_by_name(call, match):
    arm, body = get_task("ArmTrack-v2"), get_task("BodyTrack-v2")
    with pytest.raises(ValueError, match=match):
        call(arm, body)


def test_read_observation_names_the_part_of_a_wrong_shape():
    env = gym.make("humotion_gym/ArmTrack-v2").unwrapped
    obs, _ = env.reset(seed=0)
    description = env.describe()
    for desc in (None, description):  # BodyShape.from_vector said "expected 43 numbers"
        with pytest.raises(ValueError, match=r"observation\['shape'\]: expected shape \(43,\)"):
            read_observation(dict(obs, shape=obs["shape"][:40]), desc)
    # a one-view task's frame with a views axis: the frame is wrong, not the camera
    with pytest.raises(ValueError, match=r"observation\['frame'\]: expected shape"):
        read_observation(dict(obs, frame=obs["frame"][None]), description)


def test_the_base_pose_is_the_initial_pose_with_the_given_parameters_put_in():
    env = gym.make("humotion_gym/ArmTrack-v2").unwrapped
    obs, _ = env.reset(seed=0)
    obs = dict(obs, fixed_params=np.arange(21.0) + 0.5)
    base = env.describe().base_pose(read_observation(obs))
    assert np.array_equal(base[env.task.fixed_indices], np.arange(21.0) + 0.5)
    free = env.task.free_indices
    assert np.array_equal(base[free], obs["initial_pose"][free])


def test_options_choose_clip_and_start():
    env = gym.make("humotion_gym/WalkTrack-v2", split="test").unwrapped
    _, info = env.reset(seed=0, options={"clip_id": "synthetic/walk-06", "start": 7})
    assert info["clip_id"] == "synthetic/walk-06" and info["start_frame"] == 7
    with pytest.raises(ValueError, match="start"):
        env.reset(seed=0, options={"clip_id": "synthetic/walk-06", "start": 10_000})


def test_render_before_reset_says_so_wrapped_or_not():
    env = gym.make("humotion_gym/ArmTrack-v2", render_mode="rgb_array")
    for made in (env, env.unwrapped):
        with pytest.raises(gym.error.ResetNeeded):
            made.render()
    env.reset(seed=0)
    assert env.unwrapped.render().ndim == 3


def test_render_overlays_the_estimate():
    env = gym.make("humotion_gym/BodyTrack-v2", render_mode="rgb_array")
    obs, _ = env.reset(seed=0)
    before = env.render()
    assert np.array_equal(before, obs["frame"])
    env.step(np.zeros(25, dtype=np.float32))
    after = env.render()
    assert after.shape == (128, 128, 3) and not np.array_equal(after, env.unwrapped._frame)


def test_vector_env_async_runs():
    envs = gym.make_vec("humotion_gym/ArmTrack-v2", num_envs=4, vectorization_mode="async")
    obs, _ = envs.reset(seed=0)
    assert obs["frame"].shape == (4, 128, 128, 3) and obs["initial_pose"].shape == (4, 25)
    for _ in range(3):
        obs, r, term, trunc, _ = envs.step(envs.action_space.sample())
    assert r.shape == (4,)
    envs.close()


def test_record_video_writes_a_file(tmp_path):
    pytest.importorskip("moviepy", reason="gymnasium's RecordVideo needs moviepy")
    from gymnasium.wrappers import RecordVideo

    folder = tmp_path / "videos"  # a new folder: RecordVideo warns about an existing one
    env = RecordVideo(gym.make("humotion_gym/ArmTrack-v2", render_mode="rgb_array"), str(folder))
    env.reset(seed=0)
    for _ in range(5):
        env.step(env.action_space.sample())
    env.close()
    assert list(folder.glob("*.mp4"))


def test_env_pickles():
    env = gym.make("humotion_gym/SideWalk-v2").unwrapped
    env.reset(seed=0)
    clone = pickle.loads(pickle.dumps(env))
    a = np.zeros(8, dtype=np.float32)
    assert_obs_equal(clone.step(a)[0], env.step(a)[0])


@pytest.mark.mocap
def test_envs_run_on_real_data(shared_mocap):
    for env_id in IDS:
        env = gym.make(env_id, data_dir=str(shared_mocap), split="test").unwrapped
        _, info = env.reset(seed=0)
        assert not info["synthetic"] and env.clips.split("test") is not None
        assert all(m.subject in humotion_gym.mocap.library.TEST_SUBJECTS for m in env.clips)
        env.step(env.pose_to_action(env.true_pose()))


@pytest.mark.parametrize("task", ["BodyTrack-v2", "WalkTrack-v2", "SideWalk-v2"])
def test_the_travel_box_corners_are_the_eight_combinations(task: str) -> None:
    # Every corner of the box the static camera frames: back or forward along
    # the heading, left or right across it, down or up; read again for every
    # heading from the spec's cached distances.
    spec = get_task(task).camera
    back, forward, right, left, down, up = spec.travel_mm
    for heading in (0.0, 1.2, -2.5, 4.0):
        facing = np.array([-np.sin(heading), np.cos(heading), 0.0])
        side = np.array([np.cos(heading), np.sin(heading), 0.0])
        want = [
            a * facing + c * side + v * np.array([0.0, 0.0, 1.0])
            for a in (-back, forward)
            for c in (-left, right)
            for v in (-down, up)
        ]
        np.testing.assert_array_equal(spec.travel_corners(heading), np.array(want))


def test_the_look_options_change_the_frames_and_refuse_bad_values():
    """palette, floor and camera_elevation_deg: opt-in variants of a task's look."""
    plain = gym.make("humotion_gym/SideWalk-v2", split="test")
    varied = gym.make(
        "humotion_gym/SideWalk-v2", split="test", palette="sided", floor=True,
        camera_elevation_deg=30.0,
    )  # fmt: skip
    assert varied.unwrapped.task.camera.elevation_deg == 30.0
    assert plain.unwrapped.task.camera.elevation_deg == 0.0
    assert varied.unwrapped.scene.floor and not plain.unwrapped.scene.floor
    a, _ = plain.reset(seed=0)
    b, _ = varied.reset(seed=0)
    assert np.array_equal(a["initial_pose"], b["initial_pose"])  # the same episode
    assert not np.array_equal(a["frame"], b["frame"])  # seen otherwise
    assert not np.array_equal(a["camera"], b["camera"])
    body = gym.make("humotion_gym/BodyTrack-v2").unwrapped
    assert body.scene.palette == "shaded" and body.task.camera.elevation_deg == 40.0
    with pytest.raises(ValueError, match="palette"):
        gym.make("humotion_gym/SideWalk-v2", palette="pink")
    with pytest.raises(ValueError, match="camera_elevation_deg"):
        gym.make("humotion_gym/SideWalk-v2", camera_elevation_deg=95.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"occluders": 65}, "occluders: expected at most 64, got 65"),
        ({"occluders": 10**7}, "occluders: expected at most 64"),
        ({"noise": 255.5}, "noise: expected at most 255"),
        ({"blur": 64.5}, "blur: expected at most 64"),
    ],
)
def test_scene_settings_past_their_maximum_are_refused_in_the_arguments_name(kwargs, match):
    """A million occluders took five seconds a step: each scene setting has a ceiling."""
    with pytest.raises(ValueError, match=match):
        gym.make("humotion_gym/ArmTrack-v2", **kwargs)
    with pytest.raises(ValueError, match=match):
        PoseTrackingVectorEnv(2, "ArmTrack-v2", **kwargs)
    for name, top in SCENE_MAXIMA.items():  # the scene itself, whoever makes it
        value = int(top) + 1 if name in ("occluders", "shading_strips") else top * 1.01
        with pytest.raises(ValueError, match=rf"SceneOptions\.{name}: expected"):
            SceneOptions(**{name: value})
    gym.make("humotion_gym/ArmTrack-v2", occluders=64, noise=255.0, blur=64.0)


@pytest.mark.mocap
def test_data_with_a_test_persons_copy_under_another_name_is_refused(shared_mocap, tmp_path):
    """A held-out person's files in a training person's folder: gym.make refuses the data."""
    import shutil

    from humotion_gym.mocap.library import SplitError

    source = shared_mocap / "cmu-asfamc" / "03"
    copy = tmp_path / "carol"  # a user's person folder, on the training side of the split
    copy.mkdir()
    shutil.copyfile(source / "03.asf", copy / "carol.asf")
    shutil.copyfile(source / "03_01.amc", copy / "walk_a.amc")
    with pytest.raises(SplitError, match=r"skeleton is also a training person's \(cmu-03 ~ carol"):
        gym.make("humotion_gym/WalkTrack-v2", data_dir=[str(tmp_path), str(source)])
    # the validation folds that training and select build refuse it too
    from baselines.experiments.selection import validation_library

    with pytest.raises(SplitError, match=r"\(cmu-03 ~ carol"):
        validation_library([str(tmp_path), str(source)])
    env = gym.make("humotion_gym/WalkTrack-v2", data_dir=[str(source)], split="test")
    assert {m.subject for m in env.unwrapped.library} == {"cmu-03"}
    # the same clips given as a library: refused as the folders are
    from humotion_gym.mocap.library import load_library

    mixed = load_library([str(tmp_path), str(source)], progress=False)
    with pytest.raises(SplitError, match=r"^library: a held-out .*\(cmu-03 ~ carol"):
        gym.make("humotion_gym/WalkTrack-v2", library=mixed)


@pytest.mark.mocap
def test_a_library_that_tests_a_training_persons_copy_is_refused(shared_mocap, tmp_path):
    """split_by puts a copy of a training person's clip on the test side: refused."""
    import shutil

    from humotion_gym.mocap.library import SplitError, load_library

    bandai = shared_mocap / "bandai-1"
    mine = tmp_path / "myclips"
    mine.mkdir()
    shutil.copyfile(bandai / "dataset-1_walk_normal_001.bvh", mine / "mywalk.bvh")
    lib = load_library([str(bandai), str(mine)], split_by={"myclips": "test"}, progress=False)
    with pytest.raises(SplitError, match=r"myclips ~ bandai-1/normal"):
        gym.make("humotion_gym/BodyTrack-v2", split="test", library=lib)
    apart = load_library([str(mine)], split_by={"myclips": "test"}, progress=False)
    gym.make("humotion_gym/BodyTrack-v2", split="test", library=apart)  # nothing to compare


@pytest.mark.mocap
def test_a_train_env_refuses_a_file_of_a_test_person_from_outside_its_data(shared_mocap, tmp_path):
    """reset(options={"file"}) of a person its library never held: the file's own split."""
    import shutil

    from humotion_gym.mocap.splits import user_split

    # a training person's files (CMU 1's): a test person's skeleton would refuse the data
    source = shared_mocap / "cmu-asfamc" / "01"
    for person in ("alice", "carol"):  # alice is a user test person by hash, carol is not
        folder = tmp_path / person
        folder.mkdir()
        shutil.copyfile(source / "01.asf", folder / f"{person}.asf")
        shutil.copyfile(source / "01_01.amc", folder / "walk.amc")
    assert (user_split("alice"), user_split("carol")) == ("test", "train")
    env = gym.make("humotion_gym/BodyTrack-v2", data_dir=str(tmp_path / "carol")).unwrapped
    with pytest.raises(ValueError, match=r"'alice', a held-out person.*split='test'"):
        env.reset(seed=0, options={"file": str(tmp_path / "alice" / "walk.amc")})
    _, info = env.reset(seed=0, options={"file": str(tmp_path / "carol" / "walk.amc")})
    assert info["clip_id"].endswith("carol/walk")
    # carol's data holds no test person: the message says so, not "the longest has 0"
    # in words any caller can act on: no reset option, no command's flag
    with pytest.raises(
        ValueError,
        match=r"^BodyTrack-v2: the data holds no test person's clip: "
        r"its 1 clips show [^;]*carol[^;]*; test episodes show test persons only$",
    ):
        gym.make("humotion_gym/BodyTrack-v2", data_dir=str(tmp_path / "carol"), split="test")
    # no walking clip: the message names the labels, not "the longest has" some length
    dancing = tmp_path / "other" / "carol"
    dancing.mkdir(parents=True)
    shutil.copyfile(source / "01.asf", dancing / "carol.asf")
    shutil.copyfile(source / "01_01.amc", dancing / "dance.amc")
    with pytest.raises(ValueError, match=r"no train clip is labelled walk \(its 1 train clips"):
        gym.make("humotion_gym/WalkTrack-v2", data_dir=str(dancing)).reset(seed=0)


@pytest.mark.mocap
def test_a_new_env_sees_the_data_as_it_is_on_disk_now(shared_mocap, tmp_path, monkeypatch):
    """Envs kept the library of the first make with the same data_dir string: a person's
    folder added or removed, or "data" from another working folder, went unseen."""
    import os
    import shutil
    from pathlib import Path

    from humotion_gym.mocap.library import SplitError, load_library
    from humotion_gym.mocap.splits import user_split

    walk = shared_mocap / "bandai-1" / "dataset-1_walk_normal_001.bvh"

    def person(root, name):
        (root / name).mkdir(parents=True)
        shutil.copyfile(walk, root / name / "walk.bvh")

    assert {user_split(n) for n in ("carol", "dave", "gina")} == {"train"}
    assert user_split("alice") == "test"
    for name in ("carol", "dave"):
        person(tmp_path / "proj1" / "data", name)
    monkeypatch.chdir(tmp_path / "proj1")

    def clip_ids():
        env = gym.make("humotion_gym/BodyTrack-v2", data_dir="data").unwrapped
        return env, env.library.clip_ids

    first, ids = clip_ids()
    assert ids == ["user/carol/walk", "user/dave/walk"]
    again, _ = clip_ids()
    assert again.library is first.library  # nothing changed: the memo's library
    rewritten = Path("data/carol/walk.bvh")
    ns = rewritten.stat().st_mtime_ns + 10**9
    os.utime(rewritten, ns=(ns, ns))  # the file's date changed: loaded again
    assert clip_ids()[0].library is not first.library
    person(tmp_path / "proj1" / "data", "gina")
    shutil.rmtree("data/dave")
    env, ids = clip_ids()
    assert ids == ["user/carol/walk", "user/gina/walk"]
    assert ids == load_library(["data"], progress=False).clip_ids
    assert {env.reset(seed=s)[1]["clip_id"] for s in range(6)} <= set(ids)
    # the same relative name in another working folder is other data
    person(tmp_path / "proj2" / "data", "dave")
    monkeypatch.chdir(tmp_path / "proj2")
    assert clip_ids()[1] == ["user/dave/walk"]
    # a test person's file copied in later is checked (the same skeleton as dave's)
    person(tmp_path / "proj2" / "data", "alice")
    with pytest.raises(SplitError, match=r"alice ~ dave"):
        clip_ids()


def test_a_library_of_lists_and_sets_is_checked_and_tracked():
    """A library need not be hashable: its persons are checked all the same."""
    from humotion_gym.envs import pose_tracking
    from humotion_gym.mocap.library import MotionLibrary, synthetic_library

    lib = synthetic_library()
    loose = MotionLibrary(list(lib.motions), test_subjects=set(lib.held_out))  # type: ignore[arg-type]
    env = gym.make("humotion_gym/BodyTrack-v2", library=loose)
    env.reset(seed=0)
    assert pose_tracking._CHECKED[id(loose)]() is loose


def test_clips_given_at_reset_are_not_all_kept_alive():
    """Each new clip given to reset was remembered with its motion, 190 KB an episode."""
    from humotion_gym.envs._episode_choice import STARTS_EXTRA

    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    base = env.unwrapped
    library_ids = set(base._own_clips)
    for seed in range(5):  # the library's own clips, remembered
        env.reset(seed=seed)
    own = {k for k in base._starts if k in library_ids}
    clip = base.library.split("train").motions[0]
    for k in range(STARTS_EXTRA + 20):
        env.reset(seed=k, options={"motion": dataclasses.replace(clip, clip_id=f"mine/{k}")})
    given = [k for k in base._starts if k not in library_ids]
    assert given == [f"mine/{k}" for k in range(20, STARTS_EXTRA + 20)]  # the oldest went
    assert own <= set(base._starts)  # and none of the library's
    again = dataclasses.replace(clip, clip_id=f"mine/{STARTS_EXTRA + 19}")
    env.reset(seed=0, options={"motion": again})  # a clip id again: replaced, nothing evicted
    assert [k for k in base._starts if k not in library_ids] == given


def test_a_family_name_is_its_current_version_and_arm_v2_keeps_every_start():
    from humotion_gym.envs.tasks import CURRENT, TASKS

    families = ("ArmTrack", "BodyTrack", "WalkTrack", "SideWalk")
    assert CURRENT == {f: f"{f}-v2" for f in families}
    assert get_task("ArmTrack").name == "ArmTrack-v2"
    assert get_task("humotion_gym/WalkTrack") is TASKS["WalkTrack-v2"]
    # v2 no longer drops ArmTrack starts where the arm rests; v1 still does
    assert get_task("ArmTrack-v2").min_motion_mm == 0.0 < get_task("ArmTrack-v1").min_motion_mm
    with pytest.raises(ValueError, match="episode_frames must be >= 1"):
        dataclasses.replace(get_task("ArmTrack-v2"), episode_frames=0)


def test_the_v1_warning_is_shown_under_python_s_default_filters():
    # A DeprecationWarning raised inside the package (a subclass's __init__, the
    # vector env) is hidden from users by Python's default filters.
    code = "from humotion_gym.envs import BodyTrackEnv; BodyTrackEnv(task='BodyTrack-v1')"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "BodyTrack-v1 is deprecated" in done.stderr, done.stderr


def test_a_v1_task_refuses_more_than_one_view():
    with pytest.raises(ValueError, match=r"views: BodyTrack-v1 shows one view .* views=3"):
        gym.make("humotion_gym/BodyTrack-v1", views=3)
    with pytest.warns(FutureWarning):
        gym.make("humotion_gym/BodyTrack-v1", views=1).close()
