"""BLAS threads: where humotion_gym limits them, and how a Python user does.

The hot loops (particle filtering, the priors' fits) multiply small matrices
thousands of times. A multi-threaded BLAS spends longer waking and
synchronising its threads than computing.

The decision:

* The ``humotion-gym`` command line and the benchmarks call
  :func:`limit_blas_threads` once per process (one BLAS thread unless the user
  set ``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS`` or ``MKL_NUM_THREADS``,
  which win).
* The library never changes the process's thread pools on import or in
  ``gymnasium.make``: that would also slow the user's own large matrix
  products (and those of a learning library running beside the environment).
  A Python user who tracks with the particle filters should call
  ``humotion_gym.limit_blas_threads()`` once, or set
  ``OPENBLAS_NUM_THREADS=1`` before starting Python.
* The fits that are slow with threads (:mod:`baselines.priors.cycles`,
  :mod:`baselines.priors.fpca`) limit BLAS to one thread for their own
  duration only (:func:`one_blas_thread`), whatever the process does.
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable
from typing import Any, TypeVar

from threadpoolctl import ThreadpoolController, threadpool_limits

from humotion_gym.checks import check_count

#: Environment variables by which a user chooses the BLAS threads; each wins.
THREAD_ENV_VARS: tuple[str, ...] = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

_CONTROLLER: list[ThreadpoolController] = []

F = TypeVar("F", bound=Callable[..., Any])


def _chosen_by_user() -> bool:
    """Whether the user chose the BLAS threads through :data:`THREAD_ENV_VARS`."""
    return any(os.environ.get(name) for name in THREAD_ENV_VARS)


def limit_blas_threads(threads: int = 1) -> bool:
    """Limit BLAS to ``threads`` threads for the rest of the process.

    Does nothing when the user set one of :data:`THREAD_ENV_VARS`.

    Args:
        threads: Threads to allow, an integer >= 1.

    Returns:
        True if the limit was applied, False if an environment variable decided.

    Raises:
        ValueError: If ``threads`` is not an integer >= 1 (threadpoolctl reads
            0 or None as "no limit").
    """
    check_count("limit_blas_threads: threads", threads)
    if _chosen_by_user():
        return False
    threadpool_limits(limits=threads, user_api="blas")
    return True


def single_threaded_blas(unless_chosen: bool = False) -> contextlib.AbstractContextManager:
    """A context in which BLAS runs on one thread (restored on exit).

    Args:
        unless_chosen: Leave BLAS as it is when the user chose its threads
            through :data:`THREAD_ENV_VARS`, as :func:`limit_blas_threads` does.
    """
    if unless_chosen and _chosen_by_user():
        return contextlib.nullcontext()
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1, user_api="blas")


def one_blas_thread(func: F) -> F:
    """Decorator: run ``func`` inside :func:`single_threaded_blas`."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with single_threaded_blas():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)
