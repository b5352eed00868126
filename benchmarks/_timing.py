"""The timing helper every benchmark script shares (imported as a sibling module)."""

from __future__ import annotations

import time
from collections.abc import Callable


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
