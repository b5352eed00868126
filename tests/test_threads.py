"""humotion_gym.limit_blas_threads: refuses a count threadpoolctl would read as no limit."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from humotion_gym import limit_blas_threads
from humotion_gym.threads import THREAD_ENV_VARS


@pytest.mark.parametrize("threads", [0, -1, None, True, 2.5, "1"])
def test_a_count_that_is_not_one_is_refused(threads: object) -> None:
    with pytest.raises(ValueError, match="limit_blas_threads: threads: expected an integer >= 1"):
        limit_blas_threads(threads)  # type: ignore[arg-type]


def test_the_limit_applies_in_a_fresh_process() -> None:
    """In its own process, so that the suite's own BLAS threads stay as they are."""
    code = (
        "import numpy, threadpoolctl\n"
        "from humotion_gym import limit_blas_threads\n"
        "assert limit_blas_threads(1) is True\n"
        "print({i['num_threads'] for i in threadpoolctl.threadpool_info() "
        "if i['user_api'] == 'blas'})"
    )
    env = {k: v for k, v in os.environ.items() if k not in THREAD_ENV_VARS}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "{1}", out.stdout  # numpy's wheels bring OpenBLAS
