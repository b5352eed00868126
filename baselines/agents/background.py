"""One thread per process that reads a frame's features while the filter moves its particles.

A particle filter's frame is two independent halves: the prior's transition
(numba's kernels, which release the GIL) and the frame's features (OpenCV's
passes, which release it too). Neither reads the other's result, so the agent
hands the features to this thread and the filter runs its transition
meanwhile; the likelihood waits for them when it first scores. The numbers are
the ones of doing both in turn, only sooner where a second core is free.

The thread is made on first use in each process: a fork copies the parent's
pool without its thread, and work handed to that copy would wait for ever, so
the child forgets it (:func:`os.register_at_fork`) and makes its own.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")

_pool: ThreadPoolExecutor | None = None
_lock = threading.Lock()


def _forget() -> None:
    """In a forked child: drop the parent's pool (its thread did not come along) and lock."""
    global _pool, _lock
    _pool, _lock = None, threading.Lock()


if hasattr(os, "register_at_fork"):  # POSIX; Windows starts processes afresh
    os.register_at_fork(after_in_child=_forget)


def in_background(function: Callable[..., T], *args: Any) -> Future[T]:
    """``function(*args)`` on this process's features thread; its :class:`Future`.

    Calls from several threads queue on the one thread: each gets its own
    result. An exception of ``function`` is raised by ``Future.result()``.
    Where the thread takes no more work (the interpreter is shutting down,
    as in an ``atexit`` handler), ``function`` runs here and now.
    """
    global _pool
    with _lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(1, thread_name_prefix="humotion-features")
        pool = _pool
    try:
        return pool.submit(function, *args)
    except RuntimeError:  # "cannot schedule new futures after (interpreter) shutdown"
        done: Future[T] = Future()
        try:
            done.set_result(function(*args))
        except Exception as exc:  # raised by result(), as the thread's would be
            done.set_exception(exc)
        return done


def resolved(value: Any) -> Any:
    """``value``'s result where it is a :class:`Future` (waiting for it), else ``value``."""
    return value.result() if isinstance(value, Future) else value
