"""Errors split along the camera's line of sight and across it (``baselines.depth``)."""

import json

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import make
from baselines.cli import main
from baselines.depth import (
    markdown_table,
    run_depth,
    split_along_ray,
    summarize_depth,
    track_with_depth,
)
from baselines.leaderboard.evaluation import evaluate
from humotion_gym.body import KEYPOINT_INDEX, forward_kinematics
from humotion_gym.envs.description import read_observation


class _Oracle:
    """Answers the true pose, its root moved ``shift`` mm along the ray through the pelvis."""

    def __init__(self, env: gym.Env, shift: float = 0.0) -> None:
        self.base = env.unwrapped
        self.shift = shift

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        pose = self.base.true_pose()
        pelvis = forward_kinematics(pose, self.base.shape)[KEYPOINT_INDEX["pelvis"]]
        camera = read_observation(obs).camera
        ray = pelvis - camera.position
        pose[:3] += self.shift * ray / np.linalg.norm(ray)
        return self.base.pose_to_action(pose), None


@pytest.fixture(scope="module")
def body_env():
    return gym.make("humotion_gym/BodyTrack-v2", split="test", terminate_on_lost=False)


def test_split_along_ray_is_exact_and_adds_up():
    rng = np.random.default_rng(0)
    centre = np.array([100.0, -4000.0, 1500.0])
    truth = rng.normal(0, 500, (50, 3))
    ray = truth - centre
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    side = np.cross(ray, rng.normal(size=(50, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    a, b = rng.normal(0, 80, 50), rng.uniform(0, 80, 50)
    along, across = split_along_ray(truth + a[:, None] * ray + b[:, None] * side, truth, centre)
    np.testing.assert_allclose(along, a, atol=1e-9)
    np.testing.assert_allclose(across, b, atol=1e-9)
    est = truth + rng.normal(0, 60, (50, 3))
    along, across = split_along_ray(est, truth, centre)
    np.testing.assert_allclose(along**2 + across**2, ((est - truth) ** 2).sum(1), rtol=1e-12)
    with pytest.raises(ValueError, match="one shape"):
        split_along_ray(est[:3], truth, centre)
    with pytest.raises(ValueError, match="camera centre"):
        split_along_ray(est[:1], centre[None], centre)


def test_the_truth_has_no_error_and_follows_all_the_travel(body_env):
    _, ep = track_with_depth(_Oracle(body_env), body_env, seed=3)
    assert max(ep.error_mm) < 0.05 and max(ep.along_abs_mm) < 0.05 and max(ep.across_mm) < 0.05
    np.testing.assert_allclose(ep.estimate_travel_mm, ep.true_travel_mm, atol=0.05)
    assert summarize_depth([ep])["followed"] == pytest.approx(1.0, abs=1e-3)


def test_a_root_moved_along_the_ray_is_an_error_along_it(body_env):
    shift = 100.0
    _, ep = track_with_depth(_Oracle(body_env, shift), body_env, seed=3)
    # the pelvis' distance from the camera grows by exactly the shift (float32 actions)
    gap = np.array(ep.estimate_travel_mm) - np.array(ep.true_travel_mm)
    np.testing.assert_allclose(gap, shift, atol=0.05)
    # every scored keypoint moved 100 mm along nearly its own ray, a little across it
    assert all(95.0 < a <= 100.05 for a in ep.along_mm)
    assert np.allclose(ep.along_mm, ep.along_abs_mm)
    assert max(ep.across_mm) < 25.0
    np.testing.assert_allclose(ep.error_mm, shift, atol=0.05)


def test_hold_never_travels_and_the_errors_are_the_loops(body_env):
    hold = make("hold", body_env)
    result, ep = track_with_depth(hold, body_env, seed=1)
    np.testing.assert_allclose(ep.error_mm, result.errors_mm, rtol=1e-9)
    assert np.abs(ep.estimate_travel_mm).max() < 1e-6  # a static camera, one pose
    out = summarize_depth([ep])
    assert out["followed"] == pytest.approx(0.0, abs=1e-9)
    assert out["estimate_travel_mm"] == pytest.approx(0.0, abs=1e-6)
    assert out["true_travel_mm"] == pytest.approx(ep.true_travel_mm[-1])
    with pytest.raises(ValueError, match="at least one episode"):
        summarize_depth([])


def test_a_given_root_has_no_travel_columns():
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    _, ep = track_with_depth(make("hold", env), env, seed=0)
    assert ep.true_travel_mm == [] and ep.estimate_travel_mm == []
    out = summarize_depth([ep])
    assert out["followed"] is None and out["true_travel_mm"] is None
    env.close()


def test_run_depth_gives_the_leaderboards_errors(body_env):
    out = run_depth("BodyTrack-v2", ["pf-cv"], particles=20, episodes=2, seed=5, progress=False)
    rows = {r["agent"]: r for r in out["rows"]}
    assert list(rows) == ["hold", "pf-cv"]
    agent = make("pf-cv", body_env, n_particles=20, seed=5)
    loop = [r.mean_error_mm for r in evaluate(agent, body_env, 2, seed=5)]
    assert rows["pf-cv"]["mean_error_mm"] == pytest.approx(np.mean(loop), rel=1e-9)
    assert len(rows["pf-cv"]["episodes"]) == 2
    table = markdown_table(out)
    assert "| hold | - |" in table and "| pf-cv | 20 |" in table


def test_cli_depth_prints_json(capsys):
    code = main(["depth", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "10",
                 "--episodes", "1", "--json"])  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert [r["agent"] for r in out["rows"]] == ["hold", "pf-cv"]
    assert out["tracked"] == "test persons" and out["rows"][1]["followed"] is None


def test_cli_depth_on_the_validation_persons(capsys, tmp_path):
    path = tmp_path / "depth.json"
    code = main(["depth", "--task", "BodyTrack-v2", "--agents", "hold", "--episodes", "1",
                 "--validation", "--out", str(path)])  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "validation persons synthetic-03, synthetic-04" in text and "| hold | - |" in text
    assert json.loads(path.read_text())["rows"][0]["episodes"][0]["error_mm"]


def test_real_bodytrack_hold_matches_the_published_table(shared_mocap):
    out = run_depth("BodyTrack-v2", [], episodes=20, seed=0, progress=False,
                    env_kwargs={"data_dir": [str(shared_mocap)]})  # fmt: skip
    hold = out["rows"][0]
    # the README's tables: hold 374 mm on BodyTrack-v2's test persons (seed 0, 20 episodes)
    assert hold["mean_error_mm"] == pytest.approx(373.7, abs=0.1)
    assert hold["followed"] == pytest.approx(0.0, abs=1e-9)
    assert hold["true_travel_mm"] < 0  # on average the test persons come nearer the camera


def test_an_agent_that_cannot_track_the_task_is_refused_before_any_episode(monkeypatch):
    import baselines.depth as depth

    ran = []
    monkeypatch.setattr(depth, "track_with_depth", lambda *args: ran.append(args))
    with pytest.raises(ValueError, match="cannot track 'BodyTrack-v2'"):
        depth.run_depth("BodyTrack-v2", ["pf-cv", "pf-pca"], 10, episodes=1)
    assert not ran  # hold and pf-cv did not run first


def test_a_root_moved_towards_the_camera_is_a_negative_error_along_it(body_env):
    """The signed mean is negative, its absolute mean the same size, positive."""
    shift = -100.0
    _, ep = track_with_depth(_Oracle(body_env, shift), body_env, seed=3)
    gap = np.array(ep.estimate_travel_mm) - np.array(ep.true_travel_mm)
    np.testing.assert_allclose(gap, shift, atol=0.05)
    # every keypoint moved 100 mm towards the camera along nearly its own ray
    assert all(-100.05 <= a < -95.0 for a in ep.along_mm)
    np.testing.assert_allclose(ep.along_abs_mm, -np.array(ep.along_mm), atol=1e-9)
