"""Frames drawn ahead in a second process (``draw_ahead=True``) change nothing but who draws.

The vector environment with ``draw_ahead`` and the same one drawing in its
own process are reset with the same seeds (given, and unseeded resets that
go on with each episode's generator) and stepped with the same actions across several episode ends:
observations, rewards, ends, info and ``render()`` must be the same. Then the
failures: settings under which an action could change the frames are refused,
a twin out of step or a worker that died is a clear error, never a wrong frame
or a hang, and ``close`` ends the process and frees its shared memory.
"""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
import signal
import socket
import subprocess
import sys
import threading
import time
import types
from collections.abc import Iterator
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from test_vector_env import _assert_same

from humotion_gym.envs import frame_stream
from humotion_gym.envs._frame_worker import serve
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.envs.vector import PoseTrackingVectorEnv
from humotion_gym.mocap.library import MotionLibrary

TASK = "ArmTrack-v2"
SETTINGS = {"task": TASK, "terminate_on_lost": False, "render_mode": "rgb_array"}


@pytest.fixture(scope="module")
def library() -> MotionLibrary:
    """The synthetic set the environments use by default, given to them explicitly.

    A drawing process given a library unpickles it instead of making the set
    again (about a second a process); the learner vec env's test leaves the
    worker to make its own.
    """
    return PoseTrackingEnv(task=TASK).library


@pytest.fixture(scope="module")
def library_file(library: MotionLibrary, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``library`` pickled, for the learners run as scripts below (``sys.argv[1]``)."""
    path = tmp_path_factory.mktemp("library") / "synthetic.pkl"
    path.write_bytes(pickle.dumps(library))
    return path


def _ahead(library: MotionLibrary, n: int = 2) -> PoseTrackingVectorEnv:
    return PoseTrackingVectorEnv(n, draw_ahead=True, library=library, **SETTINGS)


@pytest.fixture(scope="module")
def _shared_process(library: MotionLibrary) -> Iterator[PoseTrackingVectorEnv]:
    venv = _ahead(library)
    yield venv
    venv.close()


@pytest.fixture
def shared_ahead(_shared_process: PoseTrackingVectorEnv) -> PoseTrackingVectorEnv:
    """One drawing process for the tests whose errors leave it running, shown in step first.

    A test before may have left the episodes out of step: the reset starts
    them all again, and the step shows the twins agree before this test.
    """
    venv = _shared_process
    venv.reset(seed=0)
    venv.step(np.zeros(venv.action_space.shape, np.float32))
    return venv


@contextlib.contextmanager
def _twins(
    library: MotionLibrary, n: int = 3, **kwargs
) -> Iterator[tuple[PoseTrackingVectorEnv, PoseTrackingVectorEnv]]:
    """The vector env drawing in-process and drawing ahead, with the same settings; closed."""
    settings = {"library": library, **SETTINGS, **kwargs}
    with contextlib.closing(PoseTrackingVectorEnv(n, **settings)) as drawn:
        with contextlib.closing(PoseTrackingVectorEnv(n, draw_ahead=True, **settings)) as ahead:
            yield drawn, ahead


def _same_run(a, b, seed: int, steps: int) -> None:
    """Reset both with ``seed`` and step both with the same random actions."""
    _assert_same(a.reset(seed=seed), b.reset(seed=seed), "reset")
    _steps(a, b, np.random.default_rng(seed), steps)


def _steps(a, b, rng: np.random.Generator, count: int) -> None:
    for k in range(count):
        actions = rng.uniform(-1, 1, a.action_space.shape).astype(np.float32)
        _assert_same(a.step(actions), b.step(actions), f"step {k}")
    _assert_same(a.render(), b.render(), "render")


@pytest.mark.parametrize("mode", [AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP])
def test_drawn_ahead_gives_what_drawn_in_process_gives(mode, library):
    with _twins(library, autoreset_mode=mode) as (a, b):
        rng = np.random.default_rng(0)
        frames = a.envs[0].episode_frames
        _assert_same(a.reset(seed=7), b.reset(seed=7), "reset")
        _steps(a, b, rng, 2 * frames + 5)  # two episode ends in every row
        # Unseeded: each episode goes on with its generator, which the
        # worker, drawn ahead, had moved further.
        _assert_same(a.reset(), b.reset(), "unseeded reset")
        _steps(a, b, rng, frames // 2)
        every = {"reset_mask": np.ones(3, bool)}
        _assert_same(a.reset(seed=3, options=every), b.reset(seed=3, options=every), "mask")
        _steps(a, b, rng, frames + 3)
        # Some episodes only: the drawing process has moved the others on.
        with pytest.raises(ValueError, match="reset: the frames are drawn ahead"):
            b.reset(options={"reset_mask": np.array([False, True, False])})
        _steps(a, b, rng, 3)  # refused before anything changed


def test_first_unseeded_reset_draws_one_seed_for_both(library):
    # Entropy from the operating system, drawn once: the worker's twin
    # starts the same episodes (its marks are checked at every step).
    venv = _ahead(library)
    try:
        venv.reset()
        seeds = venv.np_random_seed
        for _ in range(40):
            venv.step(np.zeros(venv.action_space.shape, np.float32))
        assert venv.np_random_seed == seeds and all(s >= 0 for s in seeds)
    finally:
        venv.close()


def test_learner_vec_env_drawn_ahead_gives_the_same_rollouts():
    sb3 = pytest.importorskip("stable_baselines3")
    del sb3
    from humotion_gym.sb3 import learner_vec_env

    ours = learner_vec_env(TASK, 2, "train", 32)
    ahead = learner_vec_env(TASK, 2, "train", 32, draw_ahead=True)
    try:
        for venv in (ours, ahead):
            venv.seed(11)
        _assert_same(ours.reset(), ahead.reset(), "reset")
        rng = np.random.default_rng(1)
        for k in range(70):
            actions = rng.uniform(-1, 1, (2, ours.action_space.shape[0])).astype(np.float32)
            ours.step_async(actions)
            ahead.step_async(actions)
            got, want = ahead.step_wait(), ours.step_wait()
            _assert_same(tuple(want[:3]), tuple(got[:3]), f"step {k}")
            for info_a, info_b in zip(want[3], got[3], strict=True):
                _assert_same(info_a, info_b, f"info {k}")
        # as the batch's own set_attr: the drawing process would not see it (it was set)
        with pytest.raises(ValueError, match=r"set_attr\('clips'\): the frames are drawn ahead"):
            ahead.set_attr("clips", ahead.get_attr("clips", [0])[0], indices=[0])
    finally:
        ours.close()
        ahead.close()


def test_settings_an_action_could_change_are_refused(library, shared_ahead):
    with pytest.raises(ValueError, match="draw_ahead: .*terminate_on_lost=False"):
        PoseTrackingVectorEnv(2, task=TASK, draw_ahead=True)
    with pytest.raises(ValueError, match="draw_ahead: autoreset_mode DISABLED"):
        PoseTrackingVectorEnv(
            2, task=TASK, terminate_on_lost=False, autoreset_mode="Disabled", draw_ahead=True
        )
    unpicklable = _Unpicklable(**vars(library))
    with pytest.raises(ValueError, match="draw_ahead: the environment's arguments must be pick"):
        PoseTrackingVectorEnv(
            2, task=TASK, terminate_on_lost=False, draw_ahead=True, library=unpicklable
        )
    venv = shared_ahead
    with pytest.raises(ValueError, match="set_attr: the frames are drawn ahead"):
        venv.set_attr("terminate_on_lost", True)
    patience = venv.envs[0].lost_patience
    venv.set_attr("lost_patience", 4)  # scores only: allowed
    assert [env.lost_patience for env in venv.envs] == [4, 4]
    venv.set_attr("lost_patience", patience)  # as it was, for the tests sharing it


class _Unpicklable(MotionLibrary):
    def __reduce__(self):
        raise TypeError("not this one")


def test_a_twin_out_of_step_is_an_error_not_a_wrong_frame(shared_ahead):
    venv = shared_ahead
    venv.reset(seed=0)
    zero = np.zeros(venv.action_space.shape, np.float32)
    venv.step(zero)
    venv._t0[1] += 1  # an episode moved behind the batch's back
    with pytest.raises(RuntimeError, match="draw_ahead: .*out of step"):
        venv.step(zero)


def test_a_worker_that_died_is_a_clear_error_and_close_still_works(library):
    venv = _ahead(library)
    stream = venv._stream
    assert stream is not None
    try:
        venv.reset(seed=0)
        stream._process.kill()
        stream._process.wait()
        zero = np.zeros(venv.action_space.shape, np.float32)
        with pytest.raises(RuntimeError, match=r"draw_ahead: the drawing process ended \(exit"):
            for _ in range(2 * stream.depth):  # the slots drawn already, then none
                venv.step(zero)
    finally:
        venv.close()
        venv.close()


def test_a_worker_that_fails_says_why_at_the_first_reset(monkeypatch, library):
    # A library class of a module the drawing process cannot import: pickled
    # here, the worker's unpickling fails and the learner reports its words.
    module = types.ModuleType("humotion_gym_test_nowhere")
    exec(
        "from humotion_gym.mocap.library import MotionLibrary\nclass Nowhere(MotionLibrary): pass",
        module.__dict__,
    )
    monkeypatch.setitem(sys.modules, module.__name__, module)
    venv = _ahead(module.Nowhere(**vars(library)))
    try:
        for _ in range(2):  # and again, the same words
            with pytest.raises(RuntimeError, match=r"drawing process failed: ModuleNotFoundError"):
                venv.reset(seed=0)
    finally:
        venv.close()


def test_a_frame_of_an_earlier_reset_is_an_error(shared_ahead):
    venv = shared_ahead
    venv.reset(seed=0)
    venv._stream._epoch += 1  # as if the worker sent a slot it drew before the last reset
    with pytest.raises(RuntimeError, match="draw_ahead: .* a frame of an earlier reset"):
        venv.step(np.zeros(venv.action_space.shape, np.float32))


def test_close_ends_the_worker_and_frees_its_memory(library):
    venv = _ahead(library)
    stream = venv._stream
    assert stream is not None
    venv.reset(seed=0)
    name = stream._shm.name
    assert Path("/dev/shm", name.lstrip("/")).exists() or not Path("/dev/shm").is_dir()
    venv.close()
    assert stream._process.poll() is not None
    assert not Path("/dev/shm", name.lstrip("/")).exists()


def test_a_closed_environment_says_so_whatever_the_worker_left_unread(library):
    """After close(), a step whose slot message was read ahead failed with 'NoneType' object
    is not subscriptable, one whose was not with 'the drawing process ended (exit code 0)'."""
    from gymnasium.error import ClosedEnvironmentError

    venv = _ahead(library)
    stream = venv._stream
    venv.reset(seed=0)
    zero = np.zeros(venv.action_space.shape, np.float32)
    venv.step(zero)
    venv.close()
    for call in (lambda: venv.step(zero), lambda: venv.reset(seed=0)):
        with pytest.raises(ClosedEnvironmentError, match="vector environment was closed"):
            call()
    # the stream itself, with a slot's message read ahead of the step that takes it
    stream._received += frame_stream._HEADER.pack(1) + b"s"
    with pytest.raises(ClosedEnvironmentError, match="draw_ahead: the frame stream was closed"):
        stream.next(np.zeros(venv._obs.shape, np.uint8), [])


def _shm_exists(name: str) -> bool:
    return Path("/dev/shm", name.lstrip("/")).exists()


@pytest.mark.skipif(not Path("/dev/shm").is_dir(), reason="no /dev/shm to look in")
def test_an_interrupt_while_the_stream_starts_frees_its_memory(monkeypatch, library):
    # A Ctrl-C in the learner after the ring is made, while its settings go out
    # (megabytes pickled): the memory must still be freed, not left to the
    # resource tracker's "leaked shared_memory" warning at exit.
    made: list[str] = []

    class Recorded(frame_stream.SharedMemory):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self.name)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(frame_stream, "SharedMemory", Recorded)
    monkeypatch.setattr(frame_stream.threading, "Thread", interrupted)
    with pytest.raises(KeyboardInterrupt):
        _ahead(library)
    monkeypatch.undo()
    gc.collect()  # the half-made stream's finaliser ends its worker and frees the ring
    assert made and not _shm_exists(made[0])


@pytest.mark.skipif(not Path("/dev/shm").is_dir(), reason="no /dev/shm to look in")
def test_an_interrupt_while_closing_still_frees_the_memory(library):
    venv = _ahead(library)
    stream = venv._stream
    assert stream is not None
    name, process = stream._shm.name, stream._process

    class Interrupted:
        def wait(self, timeout=None):
            raise KeyboardInterrupt

    stream._closer.detach()
    with pytest.raises(KeyboardInterrupt):
        frame_stream._close(Interrupted(), stream._sock, stream._shm)  # type: ignore[arg-type]
    assert not _shm_exists(name)
    assert process.wait(timeout=10) is not None  # its pipe closed: the worker ended too


def test_the_worker_reports_what_stopped_it():
    # The worker's side in this process: a memory name that does not exist.
    ours, theirs = socket.socketpair()
    conn = Connection(ours.detach())
    worker = threading.Thread(target=serve, args=(theirs.detach(),))
    settings = pickle.dumps({"num_envs": 1, "task": TASK, "terminate_on_lost": False})
    conn.send_bytes(pickle.dumps(("no-such-memory-here", 2, (1, 8, 8, 3), [], settings)))
    worker.start()
    worker.join(timeout=60)
    message = conn.recv_bytes()
    assert message.startswith(b"eFileNotFoundError"), message
    conn.close()


def test_an_episode_cut_by_the_step_limit_keeps_its_last_frame(library):
    # SAME_STEP: a cut episode's last frame is drawn by its step alone; the
    # worker sends it with the slot, for final_obs (SB3's terminal_observation).
    cut = {"max_episode_steps": 3, "autoreset_mode": AutoresetMode.SAME_STEP}
    with _twins(library, 2, **cut) as (a, b):
        _same_run(a, b, seed=2, steps=10)


def test_what_the_drawing_process_would_not_see_is_refused(shared_ahead):
    venv = shared_ahead
    with pytest.raises(ValueError, match=r"set_attr\('clips'\): the frames are drawn ahead"):
        venv.set_attr("clips", [list(reversed(env.clips)) for env in venv.envs])
    venv.reset(seed=0)
    venv.envs[1]._motion = venv.envs[0]._motion  # another clip, behind the batch's back
    with pytest.raises(RuntimeError, match="draw_ahead: .*out of step"):
        venv.step(np.zeros(venv.action_space.shape, np.float32))


def test_a_dead_worker_at_reset_and_a_silent_one_are_clear_errors(monkeypatch, library):
    venv = _ahead(library)
    stream = venv._stream
    try:
        venv.reset(seed=0)
        stream._process.kill()
        stream._process.wait()
        for _ in range(2):  # and again, the same words
            with pytest.raises(RuntimeError, match=r"drawing process ended \(exit code -9\)"):
                venv.reset(seed=1)
    finally:
        venv.close()
    venv = _ahead(library)
    stream = venv._stream
    try:
        venv.reset(seed=0)  # (its start is silent for longer than the limit below)
        # Stopped, it sends nothing however long the learner waits.
        monkeypatch.setattr(frame_stream, "_SILENT_S", 0.2)
        monkeypatch.setattr(frame_stream, "_POLL_S", 0.05)
        os.kill(stream._process.pid, signal.SIGSTOP)
        with pytest.raises(RuntimeError, match="drawing process sent nothing for"):
            for _ in range(2 * stream.depth):
                venv.step(np.zeros(venv.action_space.shape, np.float32))
    finally:
        os.kill(stream._process.pid, signal.SIGCONT)
        venv.close()


def test_a_ring_larger_than_the_free_shared_memory_is_refused(monkeypatch):
    small = os.statvfs_result((4096, 4096, 100, 10, 10, 100, 10, 10, 0, 255))
    monkeypatch.setattr(frame_stream.os, "statvfs", lambda path: small)
    with pytest.raises(ValueError, match=r"draw_ahead: the frames ahead need .* MB of shared"):
        PoseTrackingVectorEnv(8, draw_ahead=True, **SETTINGS)


def test_settings_from_a_module_on_the_learners_path_reach_the_worker(
    tmp_path, monkeypatch, library
):
    (tmp_path / "my_library_kind.py").write_text(
        "from humotion_gym.mocap.library import MotionLibrary\n"
        "class MyLibrary(MotionLibrary):\n    pass\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    from my_library_kind import MyLibrary

    with _twins(MyLibrary(**vars(library)), 2) as (a, b):
        _same_run(a, b, seed=4, steps=5)


def test_a_forked_child_leaves_the_parents_stream_alone(library_file):
    # The child's exit runs its finalizers: detached at the fork, they neither
    # close the parent's worker nor free its memory.
    script = """
import os, pickle, sys, atexit
import numpy as np
from humotion_gym.envs.vector import PoseTrackingVectorEnv
with open(sys.argv[1], "rb") as fh:
    library = pickle.load(fh)
venv = PoseTrackingVectorEnv(
    2, task="ArmTrack-v2", terminate_on_lost=False, draw_ahead=True, library=library
)
venv.reset(seed=0)
pid = os.fork()
if pid == 0:
    atexit._run_exitfuncs()
    os._exit(0)
os.waitpid(pid, 0)
for _ in range(40):
    venv.step(np.zeros(venv.action_space.shape, np.float32))
venv.close()
print("stepped on")
"""
    command = [sys.executable, "-W", "ignore", "-c", script, str(library_file)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "stepped on", done.stderr[-2000:]


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc to see the worker")
def test_the_worker_ends_with_a_killed_learner_whose_child_holds_its_socket(tmp_path, library_file):
    # A forked child would inherit the learner's end of the socket and keep the
    # worker from seeing its end: the child closes its copy at the fork, and
    # the worker also watches its parent (with neither, this fails).
    script = """
import os, pickle, signal, sys, time
from humotion_gym.envs.vector import PoseTrackingVectorEnv
with open(sys.argv[1], "rb") as fh:
    library = pickle.load(fh)
venv = PoseTrackingVectorEnv(
    2, task="ArmTrack-v2", terminate_on_lost=False, draw_ahead=True, library=library
)
venv.reset(seed=0)
child = os.fork()
if child == 0:
    time.sleep(30)
    os._exit(0)
print(venv._stream._process.pid, child, flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""
    out = tmp_path / "pids.txt"
    command = [sys.executable, "-W", "ignore", "-c", script, str(library_file)]
    with open(out, "w") as fh:  # a file: the processes left behind hold no pipe of ours
        learner = subprocess.Popen(command, stdout=fh, stderr=subprocess.DEVNULL)
        learner.wait(timeout=120)
    worker, child = (int(pid) for pid in out.read_text().split())
    try:
        deadline = time.monotonic() + 5
        while _running(worker) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _running(worker), "the worker outlived its learner"
    finally:
        os.kill(child, signal.SIGKILL)


def _running(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    return "zombie" not in status.lower()
