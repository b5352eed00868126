"""The drawing process of :mod:`humotion_gym.envs.frame_stream`: a twin environment, drawn ahead.

Started by :class:`~humotion_gym.envs.frame_stream.FrameStream` as
``python -c "...; serve(fd)"`` with one end of its pipe; the protocol is in
that module's docstring.
"""

from __future__ import annotations

import os
import pickle
import sys
import traceback
from multiprocessing import resource_tracker
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from typing import Any

import numpy as np

from humotion_gym.envs.frame_stream import NAP_S, SharedViews, episode_marks, shared_views
from humotion_gym.envs.vector import PoseTrackingVectorEnv


def serve(fd: int) -> None:
    """The worker: its twin of the learner's vector environment, drawing ahead.

    It steps the twin with zero actions (no action changes its frames), one
    slot at a time while the learner has given slots back, and resets it
    when the learner resets.
    """
    conn = Connection(fd)
    try:
        name, depth, shape, path, config = pickle.loads(conn.recv_bytes())
        sys.path[:0] = [entry for entry in path if entry not in sys.path]
        venv = PoseTrackingVectorEnv(**pickle.loads(config))
        shm = _attach(name)
    except BaseException as exc:
        _fail(conn, exc)
        return
    try:
        _draw_ahead(conn, venv, shared_views(shm.buf, depth, shape))
    except (EOFError, OSError):  # the learner ended: so does its worker
        pass
    except BaseException as exc:
        _fail(conn, exc)
    finally:
        del venv
        shm.close()


def _attach(name: str) -> SharedMemory:
    """The learner's shared memory, which the learner alone unlinks when it closes."""
    if sys.version_info >= (3, 13):
        return SharedMemory(name, track=False)  # type: ignore[call-arg,unused-ignore]
    shm = SharedMemory(name)
    # Before 3.13 attaching registers the memory with this process's resource
    # tracker, which would unlink it when this process ends (CPython gh-82300).
    resource_tracker.unregister(shm._name, "shared_memory")  # type: ignore[attr-defined]
    return shm


def _draw_ahead(conn: Connection, venv: Any, views: SharedViews) -> None:
    frames, finals, marks, taken = views
    depth = frames.shape[0]
    zero = np.zeros(venv.action_space.shape, np.float32)
    parent = os.getppid()
    conn.send_bytes(b"r")
    written, epoch, pending, nap = 0, None, None, NAP_S
    while True:
        # Before the first reset there is nothing to draw: wait for a message.
        while (epoch is None and pending is None) or conn.poll(0):
            message = conn.recv_bytes()
            if message[:1] == b"x":
                return
            if message[:1] == b"z":
                pending = pickle.loads(message[1:])
        if written - int(taken[0]) >= depth:  # every slot waits for the learner
            if os.getppid() != parent:  # the learner is gone (its socket may live on)
                return
            conn.poll(nap)  # a reset or close wakes it early
            nap = min(2 * nap, 8 * NAP_S)
            continue
        nap = NAP_S
        slot = written % depth
        if pending is not None:
            epoch, seeds, states, options = pending
            pending = None
            for env, state in zip(venv.envs, states, strict=True):
                if state is not None:  # go on from the learner's generator, not ours
                    env.np_random.bit_generator.state = state
            shown = venv.reset(seed=seeds, options=options)[0]
        else:
            shown, _, _, _, info = venv.step(zero)
            # The last frames of episodes that ended and started again (SAME_STEP)
            for i in np.flatnonzero(info.get("_final_obs", ())).tolist():
                last = info["final_obs"][i]
                finals[slot, i] = last["frame"] if isinstance(last, dict) else last
        frames[slot] = shown["frame"] if isinstance(shown, dict) else shown
        marks[slot, 0] = epoch
        marks[slot, 1:] = episode_marks(venv).ravel()
        written += 1
        conn.send_bytes(b"s")


def _fail(conn: Connection, exc: BaseException) -> None:
    last = traceback.format_exception_only(type(exc), exc)[-1].strip()
    try:
        conn.send_bytes(b"e" + last.encode())
    except OSError:
        pass
