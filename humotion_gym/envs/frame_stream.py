"""A vector environment's frames drawn ahead in a second process (``draw_ahead=True``).

When episodes run their full length (``terminate_on_lost=False``), actions
change only the scores, never which episodes start or what their frames show.
A second Python process then runs a twin of the vector environment (the same
task, settings and seeds) and draws its frames a few steps ahead into shared
memory, on another core (a learner such as PPO trains meanwhile); the learner's
environment does everything else (episode starts, cameras, scores, info) and
takes each step's frames from the stream. Nothing the agent is given depends on
the truth after its step: the frames ahead wait in memory only the environment reads.

Protocol. Shared memory holds a ring of slots, each one step's frames, the
last frames of the episodes that step ended, its epoch and each episode's
marks (frame index, start frame, episode seed and clip), and a counter of
the slots the learner is done with, which the worker may fill again. A
socket pair carries messages framed as multiprocessing's
``Connection`` frames them, each a tag byte and its payload: the learner's
settings first (pickled), then ``r`` (the worker's twin is made), ``s`` (the
worker filled the next slot), ``z`` + pickled ``(epoch, seeds, states,
options)`` (the learner reset; the worker resets its twin the same way, from
the learner's generator states, and its next slot holds the reset's frames),
``e`` + a message (the worker failed) and ``x`` (close). The learner checks
each slot's episodes against its own: a twin out of step is an error, never
a wrong frame. The learner never writes to the socket between resets: a message
wakes the worker, and a woken process is often run on the waker's core for
a while; a worker with no free slot sleeps a little instead.

Limits: POSIX systems only; the environment's arguments are pickled to the
worker, which must be able to load them (a class defined in ``__main__`` it
cannot: the first reset then fails with the worker's message).
"""

from __future__ import annotations

import os
import pickle
import select
import socket
import struct
import subprocess
import sys
import threading
import time
import weakref
import zlib
from collections.abc import Sequence
from multiprocessing.shared_memory import SharedMemory
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.error import ClosedEnvironmentError
from numpy.typing import NDArray

#: Slots of frames the worker may draw ahead of the learner.
DEPTH = 16
# Seconds between checks that the worker is still alive while waiting for it.
_POLL_S = 1.0
# Seconds without a word from a live worker before the learner gives up on it.
_SILENT_S = 300.0
# Marks per episode in a slot: frame on show, start frame, episode seed, clip.
MARKS = 4
# A message's length, as multiprocessing's Connection frames it.
_HEADER = struct.Struct("!i")
# Seconds a worker with no free slot first sleeps before it looks again; it
# doubles, up to eight times that, while the learner is busy elsewhere.
NAP_S = 0.0005

SharedViews = tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray[np.int64], NDArray[np.int64]]


def shared_views(buffer: memoryview, depth: int, frame_shape: tuple[int, ...]) -> SharedViews:
    """The shared memory's frames and last frames ``(depth, N, H, W, C)``, marks, counter."""
    n, frame_bytes = frame_shape[0], depth * int(np.prod(frame_shape))
    frames = np.ndarray((depth, *frame_shape), np.uint8, buffer[:frame_bytes])
    finals = np.ndarray((depth, *frame_shape), np.uint8, buffer[frame_bytes : 2 * frame_bytes])
    meta_end = 2 * frame_bytes + 8 * depth * (1 + MARKS * n)
    marks = np.ndarray((depth, 1 + MARKS * n), np.int64, buffer[2 * frame_bytes : meta_end])
    return frames, finals, marks, np.ndarray((1,), np.int64, buffer[meta_end : meta_end + 8])


def _shared_bytes(depth: int, frame_shape: tuple[int, ...]) -> int:
    return depth * (2 * int(np.prod(frame_shape)) + 8 * (1 + MARKS * frame_shape[0])) + 8


def _check_room(size: int) -> None:
    """Refuse a ring larger than the shared-memory folder's free space (a container's 64 MB)."""
    folder = Path("/dev/shm")
    if not folder.is_dir():
        return
    stat = os.statvfs(folder)
    free = stat.f_bavail * stat.f_frsize
    if free < size:
        raise ValueError(
            f"draw_ahead: the frames ahead need {size / 2**20:.1f} MB of shared memory, and "
            f"{folder} has {free / 2**20:.1f} MB free (a container's --shm-size sets it); "
            "use fewer episodes or smaller frames, or make the environment without draw_ahead"
        )


#: The streams of this process, detached in a forked child (the child neither
#: holds their worker nor frees their memory).
_LIVE: weakref.WeakSet[FrameStream] = weakref.WeakSet()


def _detach_in_child() -> None:
    for stream in list(_LIVE):
        stream._closer.detach()
        stream._sock.close()


class FrameStream:
    """The worker process and its ring of frame slots, from the learner's side.

    Args:
        settings: The keyword arguments that make the worker's twin
            :class:`~humotion_gym.envs.vector.PoseTrackingVectorEnv`.
        frame_shape: ``(N, H, W, C)`` one step's frames.
        depth: Slots in the ring (steps drawn ahead).
    """

    def __init__(
        self, settings: dict[str, Any], frame_shape: tuple[int, ...], depth: int = DEPTH
    ) -> None:
        if not hasattr(select, "poll") or sys.platform == "win32":
            raise ValueError("draw_ahead: needs a POSIX system (Linux, macOS)")
        try:
            config = pickle.dumps(settings)
        except Exception as exc:
            raise ValueError(
                "draw_ahead: the environment's arguments must be picklable to make the "
                f"drawing process's twin ({type(exc).__name__}: {exc})"
            ) from None
        self.depth = depth
        shape = tuple(int(x) for x in frame_shape)
        _check_room(_shared_bytes(depth, shape))
        self._shm = SharedMemory(create=True, size=_shared_bytes(depth, shape))
        ours: socket.socket | None = None
        try:  # until the finaliser below owns it, an interrupt must not leak the memory
            views = shared_views(self._shm.buf, depth, shape)
            self._frames, self._finals, self._meta, self._taken = views
            self._taken[0] = 0
            ours, theirs = socket.socketpair()
            try:
                self._process = _start_worker(theirs)
            finally:
                theirs.close()
        except BaseException:
            if ours is not None:
                ours.close()
            self._release()
            raise
        self._closer = weakref.finalize(self, _close, self._process, ours, self._shm)
        # The worker's end is a multiprocessing Connection; this end reads and
        # writes its frames (a 4-byte big-endian length, then the bytes) on the
        # socket itself: a Connection's poll builds a selector on every call.
        self._sock = ours
        self._poller = select.poll()
        self._poller.register(ours, select.POLLIN)
        self._received = bytearray()
        # Sent from a thread: the worker reads it once it has imported the
        # package, and the settings (a motion library) can be megabytes.
        # The learner's sys.path goes along: the settings may name modules found there.
        message = pickle.dumps((self._shm.name, depth, shape, sys.path, config))
        self._sending = threading.Thread(target=self._send, args=(message, True), daemon=True)
        self._sending.start()
        self._read = 0
        self._epoch = 0
        self._ready = False
        self._failure: str | None = None
        self._closed = False
        _LIVE.add(self)

    def reset(
        self,
        seeds: list[int | None],
        states: list[dict[str, Any] | None],
        options: dict[str, Any] | None,
        out: NDArray[np.uint8],
    ) -> NDArray[np.int64]:
        """Reset the twin as the learner's environment was; its first frames into ``out``.

        Args:
            seeds: Each episode's seed (or None).
            states: Each episode's generator state to go on from (or None).
            options: The reset's options.
            out: ``(N, H, W, C)`` for the frames.

        Returns:
            ``(MARKS, N)`` the slot's marks (:func:`episode_marks`).
        """
        if not self._ready:
            self._wait_ready()
        self._epoch += 1
        self._send(b"z" + pickle.dumps((self._epoch, seeds, states, options)))
        while True:  # the slots drawn before the reset are dropped
            slot = self._take()
            if self._meta[slot, 0] == self._epoch:
                return self._copy(slot, out)
            self._give_back()

    def next(
        self, out: NDArray[np.uint8], ended: list[int]
    ) -> tuple[NDArray[np.int64], NDArray[np.uint8]]:
        """The next step's frames into ``out``.

        Args:
            out: ``(N, H, W, C)`` for the frames.
            ended: Rows of the episodes the step ended and started again.

        Returns:
            The slot's marks, as :meth:`reset`, and the last frames of the
            ``ended`` episodes, ``(len(ended), H, W, C)``.
        """
        slot = self._take()
        if self._meta[slot, 0] != self._epoch:
            raise RuntimeError("draw_ahead: the drawing process sent a frame of an earlier reset")
        last = self._finals[slot, ended]  # a copy, taken before the slot is given back
        return self._copy(slot, out), last

    def _copy(self, slot: int, out: NDArray[np.uint8]) -> NDArray[np.int64]:
        np.copyto(out, self._frames[slot])
        meta = self._meta[slot, 1:].reshape(MARKS, -1).copy()
        self._give_back()
        return meta

    def _give_back(self) -> None:
        """The oldest slot taken is done with: the worker may fill it again."""
        self._taken[0] = self._read

    def _send(self, message: bytes, quiet: bool = False) -> None:
        """Send ``message``; a worker gone raises why, unless ``quiet`` (then _receive says)."""
        try:
            self._sock.sendall(_HEADER.pack(len(message)) + message)
        except OSError:
            if not quiet:
                self._ended()

    def _ended(self) -> None:
        """Raise why the worker is gone: its own message, else its exit code."""
        if self._failure is None:
            self._failure = f"ended (exit code {self._process.wait()})"
        raise RuntimeError(f"draw_ahead: the drawing process {self._failure}")

    def _receive(self) -> bytes:
        """The worker's next message; a clear error if it failed, ended or fell silent.

        Raises:
            gymnasium.error.ClosedEnvironmentError: After :meth:`close` (the
                messages left unread name slots of memory now freed).
        """
        if self._closed:
            raise ClosedEnvironmentError("draw_ahead: the frame stream was closed (close())")
        if self._failure is not None:
            self._ended()
        buffer = self._received
        silent_since = time.monotonic()
        while len(buffer) < 4 or len(buffer) < 4 + _HEADER.unpack_from(buffer)[0]:
            try:  # one system call when the worker is ahead, as it mostly is
                data = self._sock.recv(1 << 16, socket.MSG_DONTWAIT)
            except BlockingIOError:
                if self._poller.poll(_POLL_S * 1000) or self._process.poll() is None:
                    if time.monotonic() - silent_since > _SILENT_S:
                        self._failure = f"sent nothing for {_SILENT_S:.0f} s (stopped or stuck)"
                        self._ended()
                    continue
                data = b""
            except OSError:  # closed, or the socket reset
                data = b""
            if not data:
                self._ended()
            buffer += data
            silent_since = time.monotonic()
        size = _HEADER.unpack_from(buffer)[0]
        message = bytes(buffer[4 : 4 + size])
        del buffer[: 4 + size]
        if message[:1] == b"e":
            self._failure = f"failed: {message[1:].decode()}"
            self._ended()
        return message

    def _wait_ready(self) -> None:
        self._sending.join()
        if self._receive() != b"r":
            raise RuntimeError("draw_ahead: the drawing process did not start as expected")
        self._ready = True

    def _take(self) -> int:
        if self._receive() != b"s":
            raise RuntimeError("draw_ahead: unexpected message from the drawing process")
        slot = self._read % self.depth
        self._read += 1
        return slot

    def _release(self) -> None:
        self._drop_views()
        self._shm.close()
        self._shm.unlink()

    def _drop_views(self) -> None:
        self._frames = self._finals = self._meta = self._taken = None  # type: ignore[assignment]

    def close(self) -> None:
        """End the worker and free the shared memory (again: nothing)."""
        self._closed = True
        self._drop_views()
        self._closer()


def _start_worker(theirs: socket.socket) -> subprocess.Popen[bytes]:
    """The drawing process, given the socket ``theirs`` (it reads its settings there)."""
    package_root = str(Path(__file__).resolve().parents[2])
    # Warnings off: the learner's environment already showed every one of
    # these settings. Once serve has cleaned up, the worker exits at once:
    # tearing the interpreter down would hold close(), which waits for it.
    code = (
        "import os, sys, warnings; warnings.simplefilter('ignore'); "
        f"sys.path.insert(0, {package_root!r}); "
        f"from humotion_gym.envs._frame_worker import serve; serve({theirs.fileno()}); "
        "sys.stderr.flush(); os._exit(0)"
    )
    # Its own session: a Ctrl-C at the terminal interrupts the learner, which
    # then closes the stream; the worker ends when its pipe does.
    return subprocess.Popen(
        [sys.executable, "-c", code],
        pass_fds=(theirs.fileno(),),
        start_new_session=True,
        stdin=subprocess.DEVNULL,
    )


def _close(process: subprocess.Popen[bytes], sock: socket.socket, shm: SharedMemory) -> None:
    try:
        try:
            sock.sendall(_HEADER.pack(1) + b"x")
        except OSError:
            pass
        sock.close()
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    finally:  # interrupted while the worker ends: it still ends with its pipe, the memory here
        try:
            shm.close()
        except BufferError:  # a view still held: the mapping goes with the process
            pass
        try:
            shm.unlink()
        except FileNotFoundError:
            pass


def episode_marks(venv: Any) -> NDArray[np.int64]:
    """``(MARKS, N)`` what twins share: each episode's frame on show, start, seed and clip.

    The clip as a CRC-32 of its id (stable across processes, unlike ``hash``);
    -1 where an episode has not started.
    """
    marks = np.empty((MARKS, venv.num_envs), np.int64)
    marks[0], marks[1] = venv._k, venv._t0
    marks[2] = [getattr(env, "_episode_seed", None) or -1 for env in venv.envs]
    marks[3] = [
        -1 if env._motion is None else zlib.crc32(env._motion.clip_id.encode()) for env in venv.envs
    ]
    return marks


def twin_seeds(
    envs: Sequence[Any], seeds: list[int | None], rows: list[int]
) -> tuple[list[int | None], list[dict[str, Any] | None]]:
    """What the drawing process's twin needs to start the episodes ``rows`` as ``envs`` do.

    An unseeded first reset takes its seed from the operating system's
    entropy, as Gymnasium's does, here, and both use it. An unseeded later one
    goes on with the episode's generator, which the twin, drawn ahead, has
    moved further: it gets this one's state.

    Returns:
        The seeds and, per episode, its generator's state (or None).
    """
    out, states = list(seeds), [None] * len(seeds)
    for i in rows:
        if out[i] is not None:
            continue
        if envs[i]._np_random is None:
            out[i] = int(np.random.SeedSequence().entropy)  # type: ignore[arg-type]
        else:
            states[i] = envs[i].np_random.bit_generator.state
    return out, states


if hasattr(os, "register_at_fork"):  # POSIX
    os.register_at_fork(after_in_child=_detach_in_child)
