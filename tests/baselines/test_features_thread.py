"""The agent reads each frame's features on a second thread while its prior moves the particles.

Oracle: the same agent with the features read in turn, on the calling thread
before the filter's step, gives the same actions bit for bit (the two halves
of a frame read nothing of each other). Contracts: the features are read off
the calling thread; an error reading them reaches the caller; a forked child
makes its own thread (the parent's does not come along with a fork); where
the thread takes no more work, the caller does it.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from concurrent.futures import Future
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import background, make
from baselines.agents import filters as agent_filters


def _in_turn(function: Any, *args: Any) -> Future[Any]:
    """The features read at once, on the calling thread: a future already done."""
    done: Future[Any] = Future()
    done.set_result(function(*args))
    return done


def _episode(env: gym.Env, steps: int = 6) -> list[dict[str, Any]]:
    obs, _ = env.reset(seed=3)
    action = np.zeros(env.action_space.shape, np.float32)
    return [obs] + [env.step(action)[0] for _ in range(steps)]


def _actions(agent: Any, observations: list[dict[str, Any]]) -> np.ndarray:
    out = [agent.predict(observations[0], episode_start=True)[0]]
    out += [agent.predict(obs)[0] for obs in observations[1:]]
    return np.array(out)


@pytest.mark.parametrize("name", ["pf-tree", "apf-cv", "spf-cv"])
def test_the_actions_are_those_of_reading_the_features_in_turn(monkeypatch, name):
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    observations = _episode(env)
    overlapped = _actions(make(name, env, n_particles=60, seed=4), observations)
    monkeypatch.setattr(agent_filters, "in_background", _in_turn)
    in_turn = _actions(make(name, env, n_particles=60, seed=4), observations)
    np.testing.assert_array_equal(overlapped, in_turn)


class _Recording:
    """An observation model that notes the thread of each ``prepare`` (or raises there)."""

    def __init__(self, model: Any, fail: bool = False) -> None:
        self.model, self.fail = model, fail
        self.threads: list[str] = []

    def prepare(self, frame: Any, given: Any = None) -> Any:
        self.threads.append(threading.current_thread().name)
        if self.fail:
            raise ValueError("prepare: this frame cannot be read")
        return self.model.prepare(frame, given)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.model, name)


def test_the_features_are_read_off_the_calling_thread():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    agent = make("pf-cv", env, n_particles=40, seed=0)
    recording = _Recording(agent.likelihood.model)
    agent.likelihood.model = recording
    _actions(agent, _episode(env, 3))
    assert len(recording.threads) == 4
    here = threading.current_thread().name
    assert all(t.startswith("humotion-features") and t != here for t in recording.threads)


def test_an_error_reading_the_features_reaches_the_caller():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    agent = make("pf-cv", env, n_particles=40, seed=0)
    agent.likelihood.model = _Recording(agent.likelihood.model, fail=True)
    with pytest.raises(ValueError, match="this frame cannot be read"):
        agent.predict(_episode(env, 0)[0], episode_start=True)


def test_a_thread_that_takes_no_more_work_leaves_the_work_to_the_caller(monkeypatch):
    closed = background.ThreadPoolExecutor(1)
    closed.shutdown()  # as at the interpreter's exit
    monkeypatch.setattr(background, "_pool", closed)
    assert background.in_background(threading.get_ident).result() == threading.get_ident()
    with pytest.raises(ZeroDivisionError):
        background.in_background(divmod, 1, 0).result()


def _child(queue: Any) -> None:
    queue.put(background.in_background(os.getpid).result(timeout=30))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is POSIX only")
def test_a_forked_child_makes_its_own_features_thread():
    assert background.in_background(os.getpid).result() == os.getpid()  # the parent's made
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_child, args=(queue,))
    child.start()
    child.join(60)
    if child.is_alive():  # the parent's pool, whose thread stayed behind: it waits for ever
        child.kill()
        child.join()
    assert child.exitcode == 0
    assert queue.get(timeout=5) == child.pid
