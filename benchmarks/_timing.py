"""What every benchmark script shares (imported as a sibling module).

Importing it limits BLAS to one thread for the process, as the command line
does (see :mod:`humotion_gym.threads`; ``OPENBLAS_NUM_THREADS`` and
``OMP_NUM_THREADS`` still win). A benchmark reports ratios against a reference
measured in the same run, and refuses to run without it (:func:`require`).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from collections.abc import Callable

from humotion_gym.threads import limit_blas_threads

limit_blas_threads()


def no_arguments(doc: str | None) -> None:
    """Parse a benchmark's command line that takes no flags: ``--help`` prints ``doc``.

    Anything else given is refused (argparse's one line, exit 2) before any timing.
    """
    parser = argparse.ArgumentParser(
        description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.parse_args()


def require(module: str, reference: str) -> None:
    """Exit with a message (status 1) unless ``module`` is installed.

    Args:
        module: The import name the reference needs (``pygame``, ``sklearn``).
        reference: What it is needed for, for the message.
    """
    if importlib.util.find_spec(module) is None:
        script = sys.argv[0] or "this benchmark"
        sys.exit(
            f"{script}: the reference ({reference}) needs {module}, which is not installed; "
            "install the bench extra: pip install -e '.[bench]'"
        )


def best_of(fn: Callable[[], object], n: int = 1, repeats: int = 7, warmup: bool = True) -> float:
    """Best mean seconds per call over ``repeats`` runs of ``n`` calls.

    The best run is the one least disturbed by other work on a shared machine.

    Args:
        fn: What to time.
        n: Calls per run.
        repeats: Runs.
        warmup: Call ``fn`` once first, untimed (caches, lazy imports).
    """
    if warmup:
        fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best
