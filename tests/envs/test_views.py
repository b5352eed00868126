"""Several cameras around the subject: ``views=N`` and the multi-view ids.

Contracts: ``views=1`` (the default) is the monocular task bit for bit;
with N views, view 0 is the monocular task's camera and frames, the other
cameras stand in a ring about the point view 0 looks at (checked against
trigonometry done here), every view is rendered, and the observation,
``render()`` and the description say how many views there are.
"""

from __future__ import annotations

import math

import cv2
import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from humotion_gym.camera import Camera, cameras_around, fit_camera
from humotion_gym.cli import main
from humotion_gym.envs import get_task
from humotion_gym.envs.description import read_observation


def _episode(env_id: str, seed: int = 3, steps: int = 3, **kwargs):
    env = gym.make(env_id, terminate_on_lost=False, **kwargs)
    obs, _ = env.reset(seed=seed)
    seen = [obs]
    for _ in range(steps):
        seen.append(env.step(np.zeros(env.action_space.shape, np.float32))[0])
    return env, seen


def test_views_1_is_the_default_bit_for_bit():
    plain, a = _episode("humotion_gym/BodyTrack-v2")
    one, b = _episode("humotion_gym/BodyTrack-v2", views=1)
    assert plain.observation_space == one.observation_space
    assert plain.observation_space["frame"].shape == (128, 128, 3)
    assert plain.observation_space["camera"].shape == (13,)
    for x, y in zip(a, b, strict=True):
        for key in x:
            assert x[key].shape == y[key].shape and np.array_equal(x[key], y[key]), key
    assert plain.unwrapped.describe().views == 1


@pytest.mark.parametrize(
    "env_id", ["humotion_gym/BodyTrack4Views-v2", "humotion_gym/WalkTrack2Views-v2"]
)
def test_view_0_is_the_monocular_task_and_every_view_is_shown(env_id):
    views = get_task(env_id).views
    task = get_task(env_id).name
    mono_env, mono = _episode(f"humotion_gym/{task}")
    env, multi = _episode(env_id)
    assert env.observation_space["frame"].shape == (views, 128, 128, 3)
    assert env.observation_space["camera"].shape == (views, 13)
    for m, s in zip(mono, multi, strict=True):
        assert env.observation_space.contains(s)
        assert np.array_equal(s["frame"][0], m["frame"])
        assert np.array_equal(s["camera"][0], m["camera"])
        for key in ("initial_pose", "fixed_params", "shape"):
            assert np.array_equal(s[key], m[key]), key
        # the other views show other images (another viewpoint and clutter)
        for v in range(1, views):
            assert not np.array_equal(s["frame"][v], s["frame"][0])
    description = env.unwrapped.describe()
    assert description.views == views and description.name == task
    # static cameras: the same every frame
    assert all(np.array_equal(s["camera"], multi[0]["camera"]) for s in multi)


def _azimuth_elevation_distance(camera: Camera, target: np.ndarray) -> tuple[float, float, float]:
    d = camera.position - target
    return (
        math.degrees(math.atan2(d[1], d[0])),
        math.degrees(math.atan2(d[2], math.hypot(d[0], d[1]))),
        float(np.linalg.norm(d)),
    )


def _ring_errors(cameras: list[Camera], target: np.ndarray) -> tuple[float, float, float, float]:
    """How far cameras are from a ring about ``target``: azimuth step, elevation, distance, aim."""
    first = _azimuth_elevation_distance(cameras[0], target)
    worst = [0.0, 0.0, 0.0, 0.0]
    for k, camera in enumerate(cameras):
        az, el, dist = _azimuth_elevation_distance(camera, target)
        step = (az - first[0] - 360.0 * k / len(cameras) + 180.0) % 360.0 - 180.0
        u, v = camera.project(target[None])[0]
        cx, cy = camera.principal_point
        aim = math.hypot(u - cx, v - cy)
        for i, err in enumerate((abs(step), abs(el - first[1]), abs(dist - first[2]), aim)):
            worst[i] = max(worst[i], err)
    return worst[0], worst[1], worst[2], worst[3]


def test_cameras_around_make_a_ring_about_the_target():
    rng = np.random.default_rng(0)
    points = rng.normal(0, 400, (30, 3)) + [1000.0, -500.0, 900.0]
    camera = fit_camera(points, 128, 128, 45.0, azimuth_deg=30.0, elevation_deg=40.0)
    target = 0.5 * (points.min(axis=0) + points.max(axis=0))
    for views in (1, 2, 3, 4, 7):
        ring = cameras_around(camera, target, views)
        assert len(ring) == views and ring[0] is camera
        assert max(_ring_errors(ring, target)) < 1e-6
        assert all(c.intrinsics.tolist() == camera.intrinsics.tolist() for c in ring)
    # the check fails for a camera turned by another step (a mutation of the ring)
    ring = cameras_around(camera, target, 4)
    wrong = cameras_around(camera, target, 5)
    assert _ring_errors(ring[:3] + [wrong[3]], target)[0] > 1.0


@pytest.mark.parametrize("views", [0, -1, 2.5, True, "4"])
def test_bad_views_are_refused_naming_the_argument(views):
    with pytest.raises(ValueError, match="views"):
        gym.make("humotion_gym/BodyTrack-v2", views=views)
    if not isinstance(views, str):
        with pytest.raises(ValueError, match="views"):
            cameras_around(fit_camera(np.zeros((1, 3)), 64, 64, 45.0), np.zeros(3), views)


def test_the_environment_places_the_ring_about_what_view_0_frames():
    env, seen = _episode("humotion_gym/WalkTrack4Views-v2", steps=1)
    base = env.unwrapped
    points, _, _ = base._camera_request()
    target = 0.5 * (points.min(axis=0) + points.max(axis=0))
    given = read_observation(seen[-1])
    assert len(given.cameras) == 4 and given.camera == given.cameras[0]
    assert max(_ring_errors(list(given.cameras), target)) < 1e-6
    assert [f.shape for f in given.frames] == [(128, 128, 3)] * 4


def test_render_draws_every_view_side_by_side():
    env = gym.make("humotion_gym/BodyTrack2Views-v2", render_mode="rgb_array")
    obs, _ = env.reset(seed=1)
    first = env.render()
    assert first.shape == (128, 256, 3)
    assert np.array_equal(first, np.hstack(list(obs["frame"])))  # no estimate yet
    env.step(np.zeros(env.action_space.shape, np.float32))
    drawn = env.render()
    mono = gym.make("humotion_gym/BodyTrack-v2", render_mode="rgb_array")
    mono.reset(seed=1)
    mono.step(np.zeros(mono.action_space.shape, np.float32))
    assert np.array_equal(drawn[:, :128], mono.render())  # view 0: the monocular overlay
    frame_1 = env.unwrapped._frame[1]
    assert not np.array_equal(drawn[:, 128:], frame_1)  # the estimate drawn on view 1 too


def test_read_observation_refuses_cameras_that_do_not_match_the_views():
    env, seen = _episode("humotion_gym/BodyTrack2Views-v2", steps=0)
    obs = dict(seen[0])
    obs["camera"] = obs["camera"][0]
    with pytest.raises(ValueError, match=r"observation\['camera'\]: expected shape \(2, 13\)"):
        read_observation(obs)


def test_the_render_command_shows_every_view_side_by_side(tmp_path):
    out = tmp_path / "views.mp4"
    assert main(["render", "--task", "WalkTrack2Views-v2", "--frames", "3", "--out", str(out)]) == 0
    sheet = cv2.imread(str(out.with_suffix(".png")))
    single = tmp_path / "one.mp4"
    assert main(["render", "--task", "WalkTrack-v2", "--frames", "3", "--out", str(single)]) == 0
    one = cv2.imread(str(single.with_suffix(".png")))
    assert sheet.shape[0] == one.shape[0] and sheet.shape[1] == 2 * one.shape[1]


def test_messages_name_the_multi_view_id_the_environment_was_made_as():
    """A variant keeps its task's name; its messages still say the id it was made as."""
    from humotion_gym.envs._episode_choice import TooFewFrames

    with pytest.raises(
        TooFewFrames, match=r"^WalkTrack2Views-v2: no train clip of label walk holds 3001 frames"
    ):
        gym.make("humotion_gym/WalkTrack2Views-v2", episode_frames=3000)
    with pytest.raises(TooFewFrames, match=r"^BodyTrack-v2 with views=3: no train clip of any"):
        gym.make("humotion_gym/BodyTrack-v2", views=3, episode_frames=3000)
    description = gym.make("humotion_gym/BodyTrack2Views-v2").unwrapped.describe()
    _, seen = _episode("humotion_gym/BodyTrack-v2", steps=0)
    with pytest.raises(ValueError, match=r"\(2, 128, 128, 3\), BodyTrack2Views-v2's, got"):
        read_observation(seen[0], description)
