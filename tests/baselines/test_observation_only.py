"""An agent receives its observations and nothing else: no info, no environment, no truth.

A probe registered through the public API (``register_reference``) records
everything it is given while the leaderboard and the evaluation loop run it;
an agent that would read the truth from whatever it is handed (the clip and
frame that, with the public mocap files, are the whole truth) scores no
better than ``hold`` through the API, and far better when a loop leaks
``info`` to it (the check can fail).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import REFERENCES, make, register_reference
from baselines.leaderboard import run_leaderboard
from baselines.leaderboard.evaluation import run_episode
from humotion_gym.envs.description import OBSERVATION_KEYS, TaskDescription

TASK = "ArmTrack-v2"


class Probe:
    """Records its constructor's arguments and every predict call; answers ``hold``."""

    calls: list[tuple] = []
    built: list[tuple] = []

    def __init__(self, *args, **kwargs):
        Probe.built.append((args, kwargs))
        self.hold = make("hold", args[0])

    def predict(self, *args, **kwargs):
        Probe.calls.append((args, kwargs))
        return self.hold.predict(*args, **kwargs)


class Cheat:
    """Reads the truth from anything it is given that names a clip and a frame.

    With ``info`` (a clip id and frame: the public files then give the pose)
    it answers the truth; given observations only, it finds no clip and
    answers the initial pose.
    """

    def __init__(self, description: TaskDescription, library=None):
        self.description = description
        self.library = library or description.training
        self.initial = None

    def _truth(self, info):
        if info is None or "clip_id" not in info and not hasattr(self, "clip"):
            return None
        if "clip_id" in info:
            self.clip = info["clip_id"]
        if self.clip not in self.library.clip_ids:
            return None
        return self.library[self.clip].params[info["frame"]]

    def predict(self, observation, state=None, episode_start=None, deterministic=True, info=None):
        initial = np.asarray(observation["initial_pose"])
        truth = self._truth(info)
        pose = initial if truth is None else truth
        return self.description.pose_to_action(pose, initial), None


@pytest.fixture(autouse=True)
def _registered():
    register_reference("probe", Probe, "records what it is given")
    Probe.calls.clear()
    Probe.built.clear()
    yield
    REFERENCES.pop("probe", None)


def test_the_probe_is_built_from_the_description_and_sees_observations_only():
    rows = run_leaderboard([TASK], ["probe"], [10], episodes=2, progress=False)
    assert {r["agent"] for r in rows if "summary" in r} == {"hold", "probe"}
    assert Probe.built, "the probe was never built"
    for args, kwargs in Probe.built:
        assert isinstance(args[0], TaskDescription) and set(kwargs) <= {"seed"}
    # what it was shown: exactly the environment's observations, nothing else
    env = gym.make(f"humotion_gym/{TASK}", split="test", terminate_on_lost=False)
    # first the untimed warm-up (evaluation.warm_up): seed 0's first two frames
    warm, shown = Probe.calls[:2], Probe.calls[2:]
    assert len(shown) == 2 * env.unwrapped.episode_frames
    obs, _ = env.reset(seed=0)
    for (args, kwargs), start in zip(warm, (True, False), strict=True):
        assert set(args[0]) == set(OBSERVATION_KEYS) and kwargs["episode_start"].all() == start
        for key in OBSERVATION_KEYS:
            np.testing.assert_array_equal(args[0][key], obs[key])
        obs = env.step(REFERENCES["hold"][0](env).predict(obs)[0])[0]
    k = 0
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        while True:
            args, kwargs = shown[k]
            seen = args[0]
            assert set(seen) == set(OBSERVATION_KEYS)
            for key in OBSERVATION_KEYS:
                np.testing.assert_array_equal(seen[key], obs[key])
            assert set(kwargs) <= {"state", "episode_start", "deterministic"}
            assert all(not isinstance(a, dict) or a is seen for a in args)
            assert not any(isinstance(a, gym.Env) for a in (*args, *kwargs.values()))
            action, _ = REFERENCES["hold"][0](env).predict(obs)
            obs, _, terminated, truncated, _ = env.step(action)
            k += 1
            if terminated or truncated:
                break


def test_the_description_holds_no_test_person():
    env = gym.make(f"humotion_gym/{TASK}", split="test")
    description = env.unwrapped.describe()
    held = env.unwrapped.library.held_out
    assert not held & set(description.training.subjects)
    assert not any(isinstance(v, gym.Env) for v in vars(description).values())


def _leaky_episode(agent, env, seed):
    """The evaluation loop as it must not be: the agent is handed each step's info."""
    obs, info = env.reset(seed=seed)
    errors = []
    while True:
        action, _ = agent.predict(obs, info=info)
        obs, _, terminated, truncated, info = env.step(action)
        errors.append(info["error_mm"])
        if terminated or truncated:
            return float(np.mean(errors))


def test_an_agent_that_reads_the_truth_cannot_beat_hold_through_the_api():
    env = gym.make(f"humotion_gym/{TASK}", split="test", terminate_on_lost=False)
    description = env.unwrapped.describe()
    seeds = range(4)
    hold = [run_episode(make("hold", description), env, s).mean_error_mm for s in seeds]
    honest = [run_episode(Cheat(description), env, s).mean_error_mm for s in seeds]
    assert np.mean(honest) >= np.mean(hold) - 1e-6
    # the same agent handed info (and the library the test clips are in) reads the truth
    leaky = Cheat(description, library=env.unwrapped.library)
    leaked = [_leaky_episode(leaky, env, s) for s in seeds]
    assert np.mean(leaked) < 0.1 * np.mean(hold)


def _other_observations(obs: dict) -> dict[str, tuple[dict, str]]:
    arm, _ = gym.make("humotion_gym/ArmTrack-v2").reset(seed=0)
    nan_pose = obs["initial_pose"].copy()
    nan_pose[3] = np.nan
    return {
        "a smaller frame": ({**obs, "frame": obs["frame"][:64]}, r"'frame'\]: expected shape"),
        "float pixels": ({**obs, "frame": obs["frame"] / 255.0}, "expected uint8 pixels"),
        "another task's": (arm, r"'fixed_params'\]: expected shape \(0,\), BodyTrack-v2's"),
        "a NaN pose": ({**obs, "initial_pose": nan_pose}, r"'initial_pose'\]: expected finite"),
        "an infinite camera": (
            {**obs, "camera": np.full_like(obs["camera"], np.inf)},
            r"'camera'\]: expected finite",
        ),
    }


@pytest.mark.parametrize("name", ["hold", "pf-cv", "bc"])
def test_an_agent_refuses_an_observation_of_another_task_or_shape(name):
    """A frame of another size was read as this task's, and a NaN pose became a NaN action."""
    if name == "bc":
        pytest.importorskip("stable_baselines3", reason="bc needs the rl extra")
    env = gym.make("humotion_gym/BodyTrack-v2")
    obs, _ = env.reset(seed=0)
    agent = make(name, env, n_particles=20, seed=0)
    for bad, match in _other_observations(obs).values():
        with pytest.raises(ValueError, match=match):
            agent.predict(bad, episode_start=True)
    action, _ = agent.predict(obs, episode_start=True)
    assert env.action_space.contains(action)
