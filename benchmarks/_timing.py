"""What every benchmark script shares (imported as a sibling module).

Importing it limits BLAS to one thread for the process, as the command line
does (see :mod:`humotion_gym.threads`; ``OPENBLAS_NUM_THREADS`` and
``OMP_NUM_THREADS`` still win). A benchmark reports ratios against a reference
measured in the same run, and refuses to run without it (:func:`require`).
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path

from humotion_gym.threads import limit_blas_threads

limit_blas_threads()

#: The project's file, whose extras say what installs a missing reference.
PYPROJECT = Path(__file__).resolve().parent.parent / "pyproject.toml"
#: Import names whose distribution, as the extras list it, is named otherwise.
_DISTRIBUTIONS = {"sklearn": "scikit-learn"}


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
        extra = extra_of(module)
        how = (
            f"install the {extra} extra: pip install -e '.[{extra}]'"
            if extra
            else f"install it: pip install {_DISTRIBUTIONS.get(module, module)}"
        )
        sys.exit(
            f"{script}: the reference ({reference}) needs {module}, which is not installed; {how}"
        )


def extra_of(module: str) -> str | None:
    """The first extra of pyproject.toml that lists ``module``'s distribution, or None.

    None also where the file cannot be read (an installed copy without it, or
    Python 3.10, which has no TOML reader).
    """
    try:
        import tomllib
    except ImportError:
        return None
    try:
        extras = tomllib.loads(PYPROJECT.read_text())["project"]["optional-dependencies"]
    except (OSError, ValueError, KeyError):
        return None
    wanted = _normalized(_DISTRIBUTIONS.get(module, module))
    for extra, requirements in extras.items():
        # a requirement's name ends where its version or marker begins
        names = [_normalized(re.split(r"[^A-Za-z0-9_.-]", r, maxsplit=1)[0]) for r in requirements]
        if wanted in names:
            return extra
    return None


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


def _normalized(name: str) -> str:
    """A distribution's name as pip compares it: ``stable_baselines3`` is ``stable-baselines3``."""
    return re.sub(r"[-_.]+", "-", name).lower()
