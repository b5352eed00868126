"""Nothing an agent receives at step t depends on the truth after t.

For every registered task: two motions identical up to a frame and different
after it must give bit-identical observations, infos, cameras and action
mappings up to that frame: every key of the observation (frame, initial
pose, given parameters, camera, shape), the info and the action bounds. The second motion moves everything after the cut
(root, heading, every angle), so a camera fitted to the whole episode, a
heading taken from the total travel or bounds from later frames would show.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

from humotion_gym.body import PARAM_INDEX
from humotion_gym.envs import ENV_IDS, get_task
from humotion_gym.envs.description import OBSERVATION_KEYS

CUT = 6  # frames shown identically: the initial pose, then frames 1..CUT


def _changed_after(motion, start: int, cut: int, rng: np.random.Generator):
    params = motion.params.copy()
    after = slice(start + cut + 1, None)
    n = params[after].shape[0]
    params[after, :3] += np.array([1500.0, -900.0, 200.0])  # walks somewhere else
    params[after, PARAM_INDEX["root_yaw"]] += 1.2
    params[after, 6:] += rng.normal(0.0, 0.4, (n, params.shape[1] - 6))
    return dataclasses.replace(
        motion, params=params, velocities=np.gradient(params, axis=0) * motion.fps
    )


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b))
    if dataclasses.is_dataclass(a) and dataclasses.is_dataclass(b):
        return all(_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    return a == b


def _copy(obs):
    """A copy of an observation (a version-2 ``Dict``: every key)."""
    if isinstance(obs, dict):
        return {k: np.array(v, copy=True) for k, v in obs.items()}
    return np.array(obs, copy=True)


def _camera_state(camera) -> tuple:
    return (camera.rotation.tobytes(), camera.translation.tobytes(), camera.focal,
            camera.principal_point)  # fmt: skip


def _run(env_id: str, motion, start: int, steps: int):
    env = gym.make(env_id, terminate_on_lost=False)
    base = env.unwrapped
    obs, info = env.reset(seed=11, options={"motion": motion, "start": start})
    assert isinstance(obs, dict) and set(obs) == set(OBSERVATION_KEYS)
    seen = [(_copy(obs), info, _camera_state(base.camera))]
    bounds = [np.array(base._action_bounds())]
    actions = np.random.default_rng(5).uniform(-1, 1, (steps, *env.action_space.shape))
    for a in actions:
        obs, reward, term, trunc, info = env.step(a.astype(np.float32))
        # What the agent can use at step t: the new frame, the info without
        # the scores of the estimate it already gave, the camera, the mapping.
        given = {k: v for k, v in info.items() if not k.startswith(("error", "reward", "keypoint"))}
        given.pop("lost", None)
        seen.append((_copy(obs), given, _camera_state(base.camera)))
        bounds.append(np.array(base._action_bounds()))
    env.close()
    return seen, bounds


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_nothing_given_depends_on_the_future(env_id):
    env = gym.make(env_id)
    base = env.unwrapped
    span = base.episode_frames * base.frame_skip
    motion = max(base.clips, key=lambda m: m.n_frames)
    env.close()
    start = (motion.n_frames - span) // 2
    changed = _changed_after(motion, start, CUT, np.random.default_rng(0))
    assert not np.allclose(changed.params[start + CUT + 1 :], motion.params[start + CUT + 1 :])
    # reset shows frame 1, each step the next: CUT - 1 steps show frames 1..CUT
    a, bounds_a = _run(env_id, motion, start, CUT - 1)
    b, bounds_b = _run(env_id, changed, start, CUT - 1)
    for t, ((obs_a, info_a, cam_a), (obs_b, info_b, cam_b)) in enumerate(zip(a, b, strict=True)):
        assert obs_a.keys() == obs_b.keys()
        for key in obs_a:
            assert np.array_equal(obs_a[key], obs_b[key]), (
                f"{env_id}: observation[{key!r}] at step {t} depends on later frames"
            )
        assert cam_a == cam_b, f"{env_id}: the camera at step {t} depends on later frames"
        assert _equal(info_a, info_b), f"{env_id}: info at step {t} depends on later frames"
    for t, (ba, bb) in enumerate(zip(bounds_a, bounds_b, strict=True)):
        assert np.array_equal(ba, bb), f"{env_id}: action bounds at step {t} depend on the future"


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_the_test_detects_a_leak(env_id, monkeypatch):
    """A camera fitted to the whole episode (what v0 did) fails the check above."""
    from humotion_gym import camera as camera_module
    from humotion_gym.envs import pose_tracking

    real_fit = camera_module.fit_camera

    def leaky_place_camera(self):
        original_place(self)
        # refit from every frame's keypoints, as v0's static cameras did
        kp = self._geometry[:, :15]
        cam = real_fit(kp, self.scene.width, self.scene.height, self.task.camera.fov_deg)
        self._cameras = [cam] * len(self._cameras)

    original_place = pose_tracking.PoseTrackingEnv._place_camera
    monkeypatch.setattr(pose_tracking.PoseTrackingEnv, "_place_camera", leaky_place_camera)
    with pytest.raises(AssertionError, match="depends on later frames"):
        test_nothing_given_depends_on_the_future(env_id)


@pytest.mark.parametrize("key", ["fixed_params", "camera"])
def test_the_test_detects_a_leak_in_any_observation_key(key, monkeypatch):
    """An observation key read one frame ahead (the frame itself honest) fails the check."""
    from humotion_gym.envs import pose_tracking

    original = pose_tracking.PoseTrackingEnv._observation

    def leaky_observation(self, frame):
        obs = original(self, frame)
        ahead = min(self._k + 1, self.episode_frames)
        if key == "fixed_params":
            obs[key] = self._truth(ahead)[self._fixed]
        else:
            obs[key] = self._cameras[ahead].to_vector()
        return obs

    monkeypatch.setattr(pose_tracking.PoseTrackingEnv, "_observation", leaky_observation)
    with pytest.raises(AssertionError, match=f"observation\\[{key!r}\\]"):
        test_nothing_given_depends_on_the_future("humotion_gym/ArmTrack-v2")


@pytest.mark.mocap
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_nothing_given_depends_on_the_future_on_real_data(env_id, shared_mocap, monkeypatch):
    monkeypatch.setenv("HUMOTION_MOCAP", str(shared_mocap))
    test_nothing_given_depends_on_the_future(env_id)


def _run_vector(env_id: str, motion, start: int, steps: int, n: int = 2):
    """:func:`_run` for the batched vector env: every episode on the same motion."""
    venv = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point",
                        terminate_on_lost=False)  # fmt: skip
    envs = venv.unwrapped.envs
    obs, info = venv.reset(seed=11, options={"motion": motion, "start": start})

    def given(info):
        skip = ("error", "reward", "keypoint", "_error", "_reward", "_keypoint", "lost", "_lost")
        return {k: v for k, v in info.items() if not k.startswith(skip)}

    def state():
        return [(_camera_state(e.camera), np.array(e._action_bounds()).tobytes()) for e in envs]

    assert isinstance(obs, dict) and set(obs) == set(OBSERVATION_KEYS)
    seen = [(_copy(obs), given(info), state())]
    actions = np.random.default_rng(5).uniform(-1, 1, (steps, *venv.action_space.shape))
    for a in actions:
        obs, reward, term, trunc, info = venv.step(a.astype(np.float32))
        seen.append((_copy(obs), given(info), state()))
    venv.close()
    return seen


@pytest.mark.parametrize("env_id", [i for i in ENV_IDS if get_task(i).views == 1])
def test_nothing_the_vector_env_gives_depends_on_the_future(env_id):
    env = gym.make(env_id)
    base = env.unwrapped
    span = base.episode_frames * base.frame_skip
    motion = max(base.clips, key=lambda m: m.n_frames)
    env.close()
    start = (motion.n_frames - span) // 2
    changed = _changed_after(motion, start, CUT, np.random.default_rng(0))
    a = _run_vector(env_id, motion, start, CUT - 1)
    b = _run_vector(env_id, changed, start, CUT - 1)
    for t, ((obs_a, info_a, st_a), (obs_b, info_b, st_b)) in enumerate(zip(a, b, strict=True)):
        assert obs_a.keys() == obs_b.keys()
        for key in obs_a:
            assert np.array_equal(obs_a[key], obs_b[key]), (
                f"{env_id}: observation[{key!r}] at step {t} depends on later frames"
            )
        assert st_a == st_b, f"{env_id}: camera or bounds at step {t} depend on later frames"
        assert _equal(info_a, info_b), f"{env_id}: info at step {t} depends on later frames"
