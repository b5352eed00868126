"""humotion_gym.threads: the BLAS limit asked for, the user's variables winning, the cores."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import threadpoolctl

from humotion_gym import limit_blas_threads
from humotion_gym.threads import (
    THREAD_ENV_VARS,
    available_cores,
    one_blas_thread,
    single_threaded_blas,
)


@pytest.mark.parametrize("threads", [0, -1, None, True, 2.5, "1"])
def test_a_count_that_is_no_positive_integer_is_refused(threads: object) -> None:
    with pytest.raises(ValueError, match="limit_blas_threads: threads: expected an integer >= 1"):
        limit_blas_threads(threads)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", THREAD_ENV_VARS)
def test_any_one_of_the_variables_is_the_users_choice(monkeypatch, name: str) -> None:
    """One variable set (the others unset) wins: nothing is limited."""
    for other in THREAD_ENV_VARS:
        monkeypatch.delenv(other, raising=False)
    monkeypatch.setenv(name, "3")
    assert limit_blas_threads(1) is False
    with single_threaded_blas(unless_chosen=True) as limiter:
        assert limiter is None  # BLAS left as it is
    monkeypatch.setenv(name, "")  # set but empty: no choice
    with single_threaded_blas(unless_chosen=True) as limiter:
        assert limiter is not None  # limited (and restored on leaving)


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="no CPU affinity here")
def test_available_cores_are_the_affinitys_not_the_machines(monkeypatch) -> None:
    """A process pinned to 1 of the machine's cores has 1 core; an empty answer counts 1."""
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {3})
    assert available_cores() == 1
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 5, 7})
    assert available_cores() == 3
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set())
    assert available_cores() == 1


def test_the_limit_is_the_count_asked_for() -> None:
    """limit_blas_threads(2) gives two threads (where BLAS had as many), then (1) one."""
    code = (
        "import json, numpy, threadpoolctl\n"
        "from humotion_gym import limit_blas_threads\n"
        "def blas():\n"
        "    return sorted({i['num_threads'] for i in threadpoolctl.threadpool_info()"
        " if i['user_api'] == 'blas'})\n"
        "before = blas()\n"
        "assert limit_blas_threads(2) is True\n"
        "two = blas()\n"
        "assert limit_blas_threads(1) is True\n"
        "print(json.dumps([before, two, blas()]))"
    )
    env = {k: v for k, v in os.environ.items() if k not in THREAD_ENV_VARS}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    before, two, one = json.loads(out.stdout)
    assert two == sorted({min(2, b) for b in before}) and one == [1], out.stdout


def _blas_threads() -> set[int]:
    return {i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"}


def test_a_decorated_function_runs_on_one_blas_thread_and_restores_it() -> None:
    """one_blas_thread: one thread inside the call, the caller's threads again after it."""

    @one_blas_thread
    def inside(x: int) -> tuple[int, set[int]]:
        """Its own docstring."""
        return 2 * x, _blas_threads()

    assert inside.__name__ == "inside" and inside.__doc__ == "Its own docstring."
    # the suite runs BLAS on one thread (conftest): two for the caller here
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        if before == {1}:
            pytest.skip("BLAS runs on one thread at most here")
        assert inside(21) == (42, {1})
        assert _blas_threads() == before
